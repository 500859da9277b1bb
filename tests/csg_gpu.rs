//! CSG on lavapipe: the WGSL interval evaluator against the CPU reference on
//! random trees and rays, and rendered images against closed forms (a hole's
//! silhouette, a carved face's shading and material, a shadow through a
//! hole, no truncated pixels in the shipped CSG scenes).

mod common;

use celray::gpu::twins::GpuRay;
use celray::render::ray_batch::RayBatch;
use celray::render::{RenderMode, RenderSettings};
use celray::sampling::uniform;
use celray::scene::{tessellate, Csg, CsgLeaf, CsgNode, Instance, Scene, Shape};
use common::*;
use glam::{DVec3, EulerRot, Mat4, Quat, Vec3};

fn settings(scene: &Scene, mode: RenderMode) -> RenderSettings {
    RenderSettings {
        mode,
        ..pixel_centre_settings(scene)
    }
}

/// A deterministic random tree over analytic leaves (from `uniform`), at
/// most `depth` levels.
fn random_tree(seed: u32, counter: &mut u32, depth: u32) -> CsgNode {
    let mut r = || {
        *counter += 1;
        uniform(seed, 99, *counter)
    };
    if depth <= 1 || r() < 0.3 {
        let shape = match (r() * 4.0) as u32 {
            0 => Shape::Sphere {
                radius: 0.3 + 0.7 * r(),
            },
            1 => Shape::Box {
                half_extents: Vec3::new(0.2 + 0.8 * r(), 0.2 + 0.8 * r(), 0.2 + 0.8 * r()),
            },
            2 => Shape::Cylinder {
                radius: 0.2 + 0.8 * r(),
                height: 0.4 + 1.6 * r(),
            },
            _ => Shape::Cone {
                radius: 0.2 + 0.8 * r(),
                height: 0.4 + 1.6 * r(),
            },
        };
        let m = Mat4::from_scale_rotation_translation(
            Vec3::new(0.5 + r(), 0.5 + r(), 0.5 + r()),
            Quat::from_euler(EulerRot::XYZ, r() * 6.3, r() * 6.3, r() * 6.3),
            Vec3::new(r(), r(), r()) * 1.6 - Vec3::splat(0.8),
        );
        let material = (r() < 0.3).then_some(1);
        return CsgNode::Leaf(CsgLeaf {
            shape,
            csg_from_leaf: m,
            material,
        });
    }
    let kind = (r() * 3.0) as u32;
    let n = 1 + (r() * 3.0) as u32;
    match kind {
        0 => CsgNode::Union(
            (0..n)
                .map(|_| random_tree(seed, counter, depth - 1))
                .collect(),
        ),
        1 => CsgNode::Intersection(
            (0..n)
                .map(|_| random_tree(seed, counter, depth - 1))
                .collect(),
        ),
        _ => CsgNode::Difference(
            Box::new(random_tree(seed, counter, depth - 1)),
            Box::new(random_tree(seed, counter, depth - 1)),
        ),
    }
}

/// The GPU evaluators (ray-batch kernel, the trace pass's own traversal and
/// CSG code: the truth table for trees of up to 8 convex leaves, interval
/// lists for the others) against the CPU reference (interval lists): 40
/// random trees of up to 5 levels,
/// 200 instances of them, 10,000 random rays. Every ray finds the same
/// instance as the CPU with t within 1e-4 relative; a ray may disagree
/// only where it grazes (the CPU's own answer changes when the origin moves
/// by 1e-4 of the scene size), at most 0.2% of rays.
#[test]
fn gpu_csg_matches_cpu_reference_on_random_trees_and_rays() {
    let gpu = gpu();
    let mut scene = scene(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 30.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 8, height: 8),
            materials: { "m": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong), "leaf": (base_color: (0.1, 0.9, 0.1), model: BlinnPhong) },
        )"#,
    );
    let mut seed = 0;
    while scene.shapes.len() < 40 {
        seed += 1;
        let mut counter = 0;
        let csg = Csg {
            root: Box::new(random_tree(seed, &mut counter, 5)),
        };
        if csg.check().is_ok() && csg.root.depth() >= 2 {
            scene.shapes.push(Shape::Csg(csg));
            scene.shape_names.push(format!("tree {seed}"));
        }
    }
    let mesh_trees = scene.shapes.len();
    // Two trees with closed-mesh leaves (tessellated box and sphere).
    let mesh_leaf = |shape: &Shape, m: Mat4| {
        CsgNode::Leaf(CsgLeaf {
            shape: Shape::Mesh(tessellate(shape)),
            csg_from_leaf: m,
            material: Some(1),
        })
    };
    let analytic_leaf = |shape: Shape, m: Mat4| {
        CsgNode::Leaf(CsgLeaf {
            shape,
            csg_from_leaf: m,
            material: None,
        })
    };
    for csg in [
        CsgNode::Difference(
            Box::new(mesh_leaf(
                &Shape::Box {
                    half_extents: Vec3::new(0.8, 0.6, 0.7),
                },
                Mat4::from_rotation_y(0.5),
            )),
            Box::new(analytic_leaf(
                Shape::Sphere { radius: 0.75 },
                Mat4::from_translation(Vec3::new(0.3, 0.3, 0.0)),
            )),
        ),
        CsgNode::Intersection(vec![
            mesh_leaf(&Shape::Sphere { radius: 0.9 }, Mat4::IDENTITY),
            analytic_leaf(
                Shape::Cylinder {
                    radius: 0.6,
                    height: 3.0,
                },
                Mat4::from_rotation_x(1.0),
            ),
        ]),
    ] {
        let csg = Csg {
            root: Box::new(csg),
        };
        csg.check().unwrap();
        scene.shapes.push(Shape::Csg(csg));
        scene.shape_names.push("mesh leaf tree".into());
    }
    let deepest = scene
        .shapes
        .iter()
        .map(|s| match s {
            Shape::Csg(c) => c.root.depth(),
            _ => 0,
        })
        .max()
        .unwrap();
    assert!(deepest >= 4, "the random trees should reach depth 4");
    for i in 0..200u32 {
        let r = |k: u32| uniform(i, 17, k);
        scene.instances.push(Instance {
            shape: i as usize % scene.shapes.len(),
            material: 0,
            world_from_object: Mat4::from_scale_rotation_translation(
                Vec3::splat(0.6 + r(0)),
                Quat::from_euler(EulerRot::XYZ, r(1) * 6.3, r(2) * 6.3, r(3) * 6.3),
                Vec3::new(r(4), r(5), r(6)) * 20.0 - Vec3::splat(10.0),
            ),
            world_from_object_end: None,
        });
    }
    scene.validate().unwrap();
    let renderer = buffers_only(&gpu, scene);
    let buffers = renderer.scene_buffers();
    let accel = &buffers.accel;
    let rays: Vec<GpuRay> = (0..10_000u32)
        .map(|i| {
            let o = Vec3::new(uniform(i, 1, 0), uniform(i, 1, 1), uniform(i, 1, 2)) * 30.0
                - Vec3::splat(15.0);
            // Aim at an instance so most rays meet a tree.
            let (m, _, _) = accel.instances[i as usize % accel.instances.len()];
            let aim = m.transform_point3(
                Vec3::new(uniform(i, 2, 0), uniform(i, 2, 1), uniform(i, 2, 2)) * 1.6
                    - Vec3::splat(0.8),
            );
            GpuRay {
                origin: o.extend(0.0).to_array(),
                dir: (aim - o).normalize().extend(1e30).to_array(),
            }
        })
        .collect();
    let hits = RayBatch::new(&gpu)
        .unwrap()
        .trace(&gpu, buffers, &rays)
        .unwrap();
    let (mut hit_count, mut grazing, mut leaf_material_hits, mut mesh_hits) = (0, 0, 0, 0);
    // Hits on trees evaluated by their truth table, and on the analytic
    // trees too large for it, which the interval lists evaluate.
    let (mut table_hits, mut large_hits) = (0, 0);
    for (i, (ray, g)) in rays.iter().zip(&hits).enumerate() {
        let (o, d) = (Vec3::from_slice(&ray.origin), Vec3::from_slice(&ray.dir));
        let cpu = accel.closest_hit(o, d, 0.0, 1e30);
        assert!(!cpu.overflow && g.overflow == 0, "ray {i}: overflow");
        let same = match cpu.hit {
            None => g.instance == u32::MAX,
            Some(h) => {
                // The normal follows the hit point: t agrees to 1e-4
                // relative (1.5e-3 at t = 15), and the smallest radius of
                // curvature is ~0.1, so normals agree to ~1.5e-2; a flipped
                // normal is off by 2.
                let normal_ok = (Vec3::from(g.normal) - h.normal).length() < 3e-2;
                h.instance == g.instance && (h.t - g.t).abs() <= 1e-4 * h.t.max(1e-3) && normal_ok
            }
        };
        if let Some(h) = cpu.hit {
            hit_count += 1;
            leaf_material_hits += usize::from(h.leaf_material.is_some());
            let shape = accel.instances[h.instance as usize].2 as usize;
            mesh_hits += usize::from(shape >= mesh_trees);
            let by_table = accel.shapes[shape].csg_fast != 0;
            table_hits += usize::from(by_table);
            large_hits += usize::from(!by_table && shape < mesh_trees);
        }
        if !same {
            let wobble = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z].map(|e| {
                accel
                    .closest_hit(o + e * 3e-3, d, 0.0, 1e30)
                    .hit
                    .map(|h| (h.instance, (h.t * 100.0).round()))
            });
            let here = cpu.hit.map(|h| (h.instance, (h.t * 100.0).round()));
            assert!(
                wobble.iter().any(|w| *w != here),
                "ray {i}: GPU {g:?} but CPU {cpu:?}, and the ray is not grazing"
            );
            grazing += 1;
        }
    }
    eprintln!(
        "{hit_count} hits, {grazing} grazing, {mesh_hits} on mesh-leaf trees, \
         {table_hits} on trees evaluated by their truth table, {large_hits} on larger ones"
    );
    assert!(
        table_hits > 1000,
        "truth-table trees barely hit ({table_hits})"
    );
    assert!(
        large_hits > 1000,
        "interval-list trees barely hit ({large_hits})"
    );
    assert!(hit_count > 3000, "only {hit_count} of 10,000 rays hit");
    assert!(mesh_hits > 50, "mesh-leaf trees barely hit ({mesh_hits})");
    assert!(leaf_material_hits > 100, "leaf materials barely hit");
    assert!(grazing <= 20, "{grazing} grazing disagreements (> 0.2%)");
}

/// A unit sphere minus a square prism |x|, |y| < 0.35 along z, seen along
/// -z: the background shows through the hole exactly where the pixel's ray
/// misses the solid, solved independently here in f64 (ray-sphere interval
/// minus ray-prism interval). Mask from the id buffer; every mismatch must
/// lie on the analytic boundary (within 1 px). Raytrace and hybrid.
#[test]
fn sphere_minus_box_shows_the_background_through_the_hole() {
    let gpu = gpu();
    let scene = scene(
        r#"(version: 1,
            camera: (eye: (0.3, 0.2, 4.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 35.0, width: 160, height: 120),
            background: (0.0, 0.0, 1.0),
            lights: [Directional(direction: (0.0, 0.0, -1.0))],
            materials: { "m": (base_color: (0.8, 0.2, 0.1), model: Toon(bands: 3)) },
            shapes: { "holed": Difference(Sphere(radius: 1.0), Box(half_extents: (0.35, 0.35, 3.0))) },
            instances: [(shape: "holed", material: "m", transform: (rotate_deg: (0.0, 0.0, 10.0)))],
        )"#,
    );
    let (w, h) = (scene.camera.width, scene.camera.height);
    let object_from_world = Mat4::from_rotation_z(10f32.to_radians())
        .inverse()
        .as_dmat4();
    for mode in [RenderMode::Raytrace, RenderMode::Hybrid] {
        let r = rendered(&gpu, scene.clone(), settings(&scene, mode));
        let ids = r.read_ids(&gpu).unwrap();
        let cam = r.sample_camera(0);
        let (mut want, mut got) = (Vec::new(), Vec::new());
        let mut hole_px = 0;
        for y in 0..h {
            for x in 0..w {
                let (o, d) = cam.pixel_ray((w, h), x, y);
                let o = object_from_world.transform_point3(o.as_dvec3());
                let d = object_from_world.transform_vector3(d.as_dvec3());
                // Sphere interval.
                let b = o.dot(d) / d.dot(d);
                let c = (o.length_squared() - 1.0) / d.dot(d);
                let disc = b * b - c;
                let solid = disc > 0.0 && {
                    let (s0, s1) = (-b - disc.sqrt(), -b + disc.sqrt());
                    let half = DVec3::new(0.35, 0.35, 3.0);
                    let t1 = (-half - o) / d;
                    let t2 = (half - o) / d;
                    let b0 = t1.min(t2).max_element();
                    let b1 = t1.max(t2).min_element();
                    // The solid is hit unless the prism covers the whole
                    // sphere span.
                    !(b0 <= b1 && b0 <= s0 && b1 >= s1)
                };
                hole_px += usize::from(disc > 0.0 && !solid);
                want.push(!solid);
                got.push(ids[(y * w + x) as usize] == 0);
            }
        }
        let bad = mismatches_off_boundary(&got, &want, w, h);
        assert!(
            bad.is_empty(),
            "{mode:?}: background mask differs from the analytic hole at {:?}",
            &bad[..bad.len().min(5)]
        );
        assert!(hole_px > 150, "the hole should be visible ({hole_px} px)");
    }
}

/// A sphere cut flat by a box carrying its own material: the carved face is
/// the plane z = 0.3 with outward normal +z (out of the solid, into where the
/// box was). Ray batch: rays into the face report t and that normal.
/// Shading: Blinn-Phong without specular or ambient, light travelling
/// (0, -0.6, -0.8): the face shows the box's colour times N.L = 0.8, while
/// the sphere's own surface keeps the instance's colour.
#[test]
fn carved_face_has_outward_normal_and_the_cutting_material() {
    let gpu = gpu();
    let scene = scene(
        r#"(version: 1,
            camera: (eye: (0.0, 2.0, 3.5), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 35.0, width: 120, height: 120),
            ambient: (0.0, 0.0, 0.0), background: (0.0, 0.0, 0.0),
            lights: [Directional(direction: (0.0, -0.6, -0.8))],
            materials: {
                "body": (base_color: (0.9, 0.1, 0.1), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong),
                "cut": (base_color: (0.1, 0.7, 0.2), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong),
            },
            shapes: { "cut sphere": Difference(Sphere(radius: 1.0),
                Box(half_extents: (2.0, 2.0, 1.0), transform: (translate: (0.0, 0.0, 1.3)), material: "cut")) },
            instances: [(shape: "cut sphere", material: "body")],
        )"#,
    );
    let (w, h) = (scene.camera.width, scene.camera.height);
    let r = rendered(&gpu, scene.clone(), settings(&scene, RenderMode::Raytrace));

    // Ray batch: straight down -z onto the face at (x, y) with x^2 + y^2 < 0.9^2.
    let rays: Vec<GpuRay> = (0..64)
        .map(|i| {
            let a = i as f32 * 0.3;
            let rad = 0.85 * (i as f32 / 64.0).sqrt();
            GpuRay {
                origin: [rad * a.cos(), rad * a.sin(), 5.0, 0.0],
                dir: [0.0, 0.0, -1.0, 1e30],
            }
        })
        .collect();
    let hits = RayBatch::new(&gpu)
        .unwrap()
        .trace(&gpu, r.scene_buffers(), &rays)
        .unwrap();
    for (i, g) in hits.iter().enumerate() {
        assert_eq!(g.instance, 0, "ray {i} missed");
        assert!((g.t - 4.7).abs() < 1e-4, "ray {i}: t {} not 4.7", g.t);
        assert!(
            (Vec3::from(g.normal) - Vec3::Z).length() < 1e-5,
            "ray {i}: normal {:?} is not +z (out of the solid)",
            g.normal
        );
    }

    // Shading: the face (a disk of radius 0.9 at z = 0.3) and the rim of the
    // sphere around it.
    let img = r.read_srgb8(&gpu).unwrap();
    let cam = r.sample_camera(0);
    let face = [srgb8(0.1 * 0.8), srgb8(0.7 * 0.8), srgb8(0.2 * 0.8)];
    let mut face_px = 0;
    let mut body_px = 0;
    let mut red_px = 0;
    for y in 0..h {
        for x in 0..w {
            let (o, d) = cam.pixel_ray((w, h), x, y);
            let t = (0.3 - o.z) / d.z;
            let p = o + d * t;
            let rr = p.x * p.x + p.y * p.y;
            let rgb = rgb_at(&img, w, x, y);
            if rr < 0.85 * 0.85 {
                face_px += 1;
                for c in 0..3 {
                    assert!(
                        rgb[c].abs_diff(face[c]) <= 2,
                        "({x},{y}) on the carved face: {rgb:?}, want {face:?}"
                    );
                }
            } else {
                // On the unit sphere below the cut (z < 0.25), away from
                // its silhouette (the ray also meets the sphere of 0.97).
                let b = o.dot(d);
                let disc = b * b - (o.length_squared() - 1.0);
                let disc_in = b * b - (o.length_squared() - 0.97 * 0.97);
                if disc_in > 0.0 && (o + d * (-b - disc.sqrt())).z < 0.25 {
                    body_px += 1;
                    assert!(
                        rgb[1] <= rgb[0],
                        "({x},{y}) on the sphere should be the body's red, got {rgb:?}"
                    );
                    red_px += usize::from(u32::from(rgb[0]) > 2 * u32::from(rgb[1]) + 10);
                }
            }
        }
    }
    assert!(
        face_px > 1000 && body_px > 200 && red_px > 100,
        "face {face_px}, body {body_px}, red {red_px} px"
    );
}

/// A sphere of radius 0.5 with a square hole |x|, |z| < 0.15 along y, above a
/// floor, the sun overhead: the shadow is the disk x^2 + z^2 < 0.25 minus the
/// square, exactly (both modes).
#[test]
fn shadow_of_a_csg_solid_shows_its_hole() {
    let gpu = gpu();
    let scene = scene(
        r#"(version: 1,
            camera: (eye: (0.0, 5.0, 4.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 160, height: 120),
            ambient: (0.2, 0.2, 0.2), background: (0.0, 0.0, 0.0),
            lights: [Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 0.8)],
            materials: { "floor": (base_color: (0.5, 0.5, 0.5), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong),
                         "ball": (base_color: (0.9, 0.1, 0.1), model: BlinnPhong) },
            shapes: { "floor": Plane(Quad(half_size: (5.0, 5.0))),
                      "holed": Difference(Sphere(radius: 0.5), Box(half_extents: (0.15, 1.0, 0.15))) },
            instances: [(shape: "floor", material: "floor"), (shape: "holed", material: "ball", transform: (translate: (0.0, 1.5, 0.0)))],
        )"#,
    );
    let (w, h) = (scene.camera.width, scene.camera.height);
    for mode in [RenderMode::Hybrid, RenderMode::Raytrace] {
        let r = rendered(&gpu, scene.clone(), settings(&scene, mode));
        let img = r.read_srgb8(&gpu).unwrap();
        let ids = r.read_ids(&gpu).unwrap();
        let cam = r.sample_camera(0);
        let lit = srgb8(0.5 * 0.2 + 0.5 * 0.8);
        let shadowed = srgb8(0.5 * 0.2);
        let (mut want, mut got, mut floor_mask) = (Vec::new(), Vec::new(), Vec::new());
        for y in 0..h {
            for x in 0..w {
                let (o, d) = cam.pixel_ray((w, h), x, y);
                let t = -o.y / d.y;
                let p = o + d * t;
                // Floor pixels, by the id buffer (the solid's own pixels
                // are not floor); the floor is GPU instance 0 or 1.
                let id = ids[(y * w + x) as usize];
                let on_floor = t > 0.0
                    && p.x.abs() < 5.0
                    && p.z.abs() < 5.0
                    && id != 0
                    && r.scene_buffers().instance_order[id as usize - 1] == 0;
                floor_mask.push(on_floor);
                let in_shadow =
                    p.x * p.x + p.z * p.z < 0.25 && !(p.x.abs() < 0.15 && p.z.abs() < 0.15);
                want.push(on_floor && in_shadow);
                let g = rgb_at(&img, w, x, y)[0];
                if on_floor {
                    assert!(
                        g.abs_diff(lit) <= 2 || g.abs_diff(shadowed) <= 2,
                        "{mode:?} ({x},{y}): {g} is neither lit {lit} nor shadowed {shadowed}"
                    );
                }
                got.push(on_floor && g.abs_diff(shadowed) <= 2);
            }
        }
        let mut bad = mismatches_off_boundary(&got, &want, w, h);
        bad.retain(|&(x, y)| interior(&floor_mask, w, h, x, y, 1));
        assert!(
            bad.is_empty(),
            "{mode:?}: shadow differs from disk-minus-square at {:?}",
            &bad[..bad.len().min(5)]
        );
        // The hole's light patch inside the shadow is visible.
        let lit_hole = (0..(w * h) as usize)
            .filter(|&i| floor_mask[i] && !got[i])
            .filter(|&i| {
                let (o, d) = cam.pixel_ray((w, h), i as u32 % w, i as u32 / w);
                let p = o + d * (-o.y / d.y);
                p.x.abs() < 0.1 && p.z.abs() < 0.1
            })
            .count();
        assert!(
            lit_hole > 20,
            "{mode:?}: light through the hole ({lit_hole} px)"
        );
    }
}

/// The shipped CSG scenes render in raytrace mode without a single pixel
/// running out of its step budget or interval storage (which would be
/// magenta and counted), and the CSG solids cover a good part of the frame.
#[test]
fn shipped_csg_scenes_render_without_overflow() {
    let gpu = gpu();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    for name in ["csg_textbook.ron", "csg_deep.ron", "csg_grid.ron"] {
        let mut scene = Scene::load(&dir.join(name)).unwrap();
        scene.camera.width = 320;
        scene.camera.height = 180;
        let r = rendered(&gpu, scene.clone(), settings(&scene, RenderMode::Raytrace));
        assert_eq!(r.overflow_pixels(&gpu).unwrap(), 0, "{name}");
        let ids = r.read_ids(&gpu).unwrap();
        let order = &r.scene_buffers().instance_order;
        let csg_px = ids
            .iter()
            .filter(|&&id| {
                id != 0
                    && matches!(
                        scene.shapes[scene.instances[order[id as usize - 1]].shape],
                        Shape::Csg(_)
                    )
            })
            .count();
        assert!(
            csg_px > 320 * 180 / 20,
            "{name}: CSG covers only {csg_px} px"
        );
    }
}

/// Raster mode has no ray tracing, and CSG is never tessellated: a scene of
/// a CSG shape and a sphere renders the sphere only (documented choice).
#[test]
fn raster_mode_draws_nothing_for_csg() {
    let gpu = gpu();
    let scene = scene(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 6.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 64, height: 48),
            materials: { "m": (base_color: (0.8, 0.2, 0.1), model: Toon(bands: 3)) },
            shapes: { "holed": Difference(Sphere(radius: 1.0), Box(half_extents: (0.3, 0.3, 3.0))), "ball": Sphere(radius: 0.5) },
            instances: [(shape: "holed", material: "m", transform: (translate: (-1.2, 0.0, 0.0))),
                        (shape: "ball", material: "m", transform: (translate: (1.2, 0.0, 0.0)))],
        )"#,
    );
    let r = rendered(&gpu, scene.clone(), settings(&scene, RenderMode::Raster));
    let ids = r.read_ids(&gpu).unwrap();
    let order = &r.scene_buffers().instance_order;
    let drawn: Vec<usize> = ids
        .iter()
        .filter(|&&id| id != 0)
        .map(|&id| order[id as usize - 1])
        .collect();
    assert!(drawn.len() > 50, "the sphere should be drawn");
    assert!(
        drawn.iter().all(|&i| i == 1),
        "only the sphere is rasterized"
    );
    assert!(
        r.scene_buffers().draws.iter().all(|d| d.shape != 0),
        "no draw for the CSG shape"
    );
}

/// Does the ray (o, d) (object space of a unit sphere minus the prism
/// |x|, |y| < 0.35 along z) meet the solid? Solved in f64: the sphere's
/// span minus the prism's span is not empty.
fn meets_holed_sphere(o: DVec3, d: DVec3) -> bool {
    let b = o.dot(d) / d.dot(d);
    let c = (o.length_squared() - 1.0) / d.dot(d);
    let disc = b * b - c;
    if disc <= 0.0 {
        return false;
    }
    let (s0, s1) = (-b - disc.sqrt(), -b + disc.sqrt());
    let half = DVec3::new(0.35, 0.35, 3.0);
    let t1 = (-half - o) / d;
    let t2 = (half - o) / d;
    let (b0, b1) = (t1.min(t2).max_element(), t1.max(t2).min_element());
    s1 > 0.0 && !(b0 <= b1 && b0 <= s0.max(0.0) && b1 >= s1)
}

/// A red holed sphere (sphere minus a prism along z) over a mirror floor: a
/// floor pixel shows red exactly where its ray, reflected about y = 0, meets
/// the solid (solved in f64), blue background elsewhere, the hole included.
#[test]
fn csg_solid_appears_in_a_mirror_where_the_geometry_says() {
    let gpu = gpu();
    let scene = scene(
        r#"(version: 1,
            camera: (eye: (0.0, 1.0, 6.0), target: (0.0, 0.2, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 35.0, width: 160, height: 120),
            ambient: (1.0, 1.0, 1.0), background: (0.0, 0.0, 1.0),
            lights: [],
            materials: { "mirror": (base_color: (0.0, 0.0, 0.0), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong, reflectivity: 1.0),
                         "red": (base_color: (1.0, 0.0, 0.0), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong, outline_width_px: 0.0) },
            shapes: { "floor": Plane(Quad(half_size: (20.0, 20.0))),
                      "holed": Difference(Sphere(radius: 1.0), Box(half_extents: (0.35, 0.35, 3.0))) },
            instances: [(shape: "floor", material: "mirror"),
                        (shape: "holed", material: "red", transform: (translate: (0.0, 1.1, 0.0)))],
        )"#,
    );
    let centre = DVec3::new(0.0, 1.1, 0.0);
    assert_mirror_shows(&gpu, &scene, "mirrored CSG solid", |o, d| {
        meets_holed_sphere(o - centre, d)
    });
}

/// A mesh leaf that a ray crosses more than K = 8 times (five disjoint boxes
/// in a row, one closed mesh: 10 crossings) is never silently truncated:
/// the CPU reference reports an overflow, and the GPU paints those pixels
/// magenta and counts them; rays that cross fewer times are fine.
#[test]
fn mesh_leaf_over_k_crossings_is_reported_not_truncated() {
    let gpu = gpu();
    let mut row = celray::scene::Mesh::default();
    for i in 0..5 {
        let b = tessellate(&Shape::Box {
            half_extents: Vec3::splat(0.3),
        });
        let base = row.positions.len() as u32;
        row.positions.extend(
            b.positions
                .iter()
                .map(|p| *p + Vec3::new(0.0, 0.0, i as f32 - 2.0)),
        );
        row.normals.extend(&b.normals);
        row.indices.extend(b.indices.iter().map(|k| k + base));
    }
    let csg = Csg {
        root: Box::new(CsgNode::Difference(
            Box::new(CsgNode::Leaf(CsgLeaf {
                shape: Shape::Mesh(row),
                csg_from_leaf: Mat4::IDENTITY,
                material: None,
            })),
            Box::new(CsgNode::Leaf(CsgLeaf {
                shape: Shape::Sphere { radius: 0.1 },
                csg_from_leaf: Mat4::from_translation(Vec3::new(5.0, 0.0, 0.0)),
                material: None,
            })),
        )),
    };
    csg.check().unwrap();
    let program = celray::accel::csg::CompiledCsg::new(&csg).unwrap();
    // Along the row: 10 crossings. Across one box: 2.
    assert!(program
        .intervals(Vec3::new(0.05, 0.02, 9.0), Vec3::NEG_Z)
        .is_err());
    assert_eq!(
        program
            .intervals(Vec3::new(9.0, 0.02, 0.05), Vec3::NEG_X)
            .unwrap()
            .len(),
        2
    );

    let mut scene = scene(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 8.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 20.0, width: 64, height: 64),
            materials: { "m": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong) },
        )"#,
    );
    scene.shapes.push(Shape::Csg(csg));
    scene.shape_names.push("row".into());
    scene.instances.push(Instance {
        shape: 0,
        material: 0,
        world_from_object: Mat4::IDENTITY,
        world_from_object_end: None,
    });
    let r = rendered(&gpu, scene.clone(), settings(&scene, RenderMode::Raytrace));
    let img = r.read_srgb8(&gpu).unwrap();
    let overflow = r.overflow_pixels(&gpu).unwrap();
    // The camera looks down the row: the box's 0.6 x 0.6 face spans
    // ~0.6 / (2 * 6.3 * tan 10 deg) * 64 = 17 px, so ~280 pixels overflow.
    assert!(overflow > 100, "only {overflow} pixels reported overflow");
    let magenta = img
        .chunks(4)
        .filter(|p| p[0] == 255 && p[1] == 0 && p[2] == 255)
        .count();
    assert_eq!(magenta as u32, overflow, "each overflowed pixel is magenta");
}

/// Faces that coincide in two leaves, through the GPU's truth-table
/// evaluator: a cube with a square tunnel whose ends are flush with two of
/// its faces, and two cubes side by side sharing a face. Parallel rays,
/// answers from the geometry: through the tunnel no hit (no film of the
/// flush faces at t = 4 or 6), elsewhere the front face at t = 4 with
/// normal +z; a ray starting inside the pair leaves it through the far face
/// (t = 1.25), not the shared face (t = 0.25), with the outward normal.
/// Coincident ends differ only by rounding (~1e-7 relative), far below the
/// CSG epsilon (1e-5 relative), so every ray must agree: t to 1e-4 relative
/// and the axis normal to 1e-3, with rays kept 0.02 from the tunnel's walls.
#[test]
fn coincident_faces_leave_no_slivers_on_the_gpu() {
    let gpu = gpu();
    let scene = scene(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 30.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 8, height: 8),
            materials: { "m": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong) },
            shapes: {
                "tunnel": Difference(Box(half_extents: (1.0, 1.0, 1.0)), Box(half_extents: (0.5, 0.5, 1.0))),
                "pair": Union([
                    Box(half_extents: (0.5, 0.5, 0.5), transform: (translate: (-0.5, 0.0, 0.0))),
                    Box(half_extents: (0.5, 0.5, 0.5), transform: (translate: (0.5, 0.0, 0.0))),
                ]),
            },
            instances: [
                (shape: "tunnel", material: "m"),
                (shape: "pair", material: "m", transform: (translate: (0.0, 10.0, 0.0))),
            ],
        )"#,
    );
    let renderer = buffers_only(&gpu, scene);
    let buffers = renderer.scene_buffers();
    let accel = &buffers.accel;
    assert!(
        accel.shapes.iter().all(|s| s.csg_fast != 0),
        "both trees should take the truth-table evaluator"
    );
    // Each ray with its expected hit (instance, t, normal), or None.
    type Case = (GpuRay, Option<(u32, f32, Vec3)>);
    let mut cases: Vec<Case> = Vec::new();
    let ray = |o: Vec3, d: Vec3| GpuRay {
        origin: o.extend(0.0).to_array(),
        dir: d.extend(1e30).to_array(),
    };
    let steps: Vec<f32> = (0..39).map(|i| -0.95 + 0.05 * i as f32).collect();
    let near_wall = |v: f32| (v.abs() - 0.5).abs() < 0.02;
    for &x in &steps {
        for &y in &steps {
            if near_wall(x) || near_wall(y) {
                continue;
            }
            let tunnel = x.abs() < 0.5 && y.abs() < 0.5;
            let want = (!tunnel).then_some((0, 4.0, Vec3::Z));
            cases.push((ray(Vec3::new(x, y, 5.0), -Vec3::Z), want));
        }
    }
    for &y in &steps[2..37] {
        for &z in &steps[2..37] {
            let (p, q) = (10.0 + 0.5 * y, 0.5 * z);
            cases.push((ray(Vec3::new(5.0, p, q), -Vec3::X), Some((1, 4.0, Vec3::X))));
            cases.push((
                ray(Vec3::new(0.25, p, q), -Vec3::X),
                Some((1, 1.25, -Vec3::X)),
            ));
            cases.push((
                ray(Vec3::new(-0.25, p, q), Vec3::X),
                Some((1, 1.25, Vec3::X)),
            ));
        }
    }
    let rays: Vec<GpuRay> = cases.iter().map(|c| c.0).collect();
    let hits = RayBatch::new(&gpu)
        .unwrap()
        .trace(&gpu, buffers, &rays)
        .unwrap();
    for (i, ((ray, want), got)) in cases.iter().zip(&hits).enumerate() {
        match want {
            None => assert_eq!(
                got.instance,
                u32::MAX,
                "ray {i} from {:?} should pass through the tunnel: {got:?}",
                ray.origin
            ),
            Some((instance, t, n)) => assert!(
                got.instance == *instance
                    && (got.t - t).abs() <= 1e-4 * t
                    && (Vec3::from(got.normal) - *n).length() < 1e-3,
                "ray {i} from {:?}: want instance {instance} at t = {t} with normal {n}, got {got:?}",
                ray.origin
            ),
        }
    }
}
