//! The compute ray tracer on lavapipe against closed forms and against the
//! CPU reference traversal.

mod common;

use celray::render::ray_batch::RayBatch;
use celray::render::{RenderMode, RenderSettings};
use celray::scene::Scene;
use common::*;
use glam::{DMat4, DVec3, Mat4, Vec3};

fn settings(scene: &Scene, mode: RenderMode) -> RenderSettings {
    RenderSettings {
        mode,
        ..pixel_centre_settings(scene)
    }
}

/// Where the ray (o, d) meets the unit sphere mapped by `m` (an ellipsoid),
/// solved in f64 independently of the renderer: |L o + t L d|^2 = 1 with
/// L = m^-1. Returns t.
fn ray_ellipsoid(m: Mat4, o: Vec3, d: Vec3) -> Option<f64> {
    let l = m.as_dmat4().inverse();
    let (o, d) = (
        l.transform_point3(o.as_dvec3()),
        l.transform_vector3(d.as_dvec3()),
    );
    let (a, b, c) = (d.dot(d), o.dot(d), o.dot(o) - 1.0);
    let disc = b * b - a * c;
    (disc >= 0.0)
        .then(|| (-b - disc.sqrt()) / a)
        .filter(|t| *t > 0.0)
}

/// The unit outward normal of the ellipsoid {p : |L p|^2 = 1} at p: the
/// gradient of the implicit function, 2 A^T (L p), with A the linear part of L.
fn ellipsoid_normal(m: Mat4, p: DVec3) -> DVec3 {
    let l: DMat4 = m.as_dmat4().inverse();
    let q = l.transform_point3(p);
    let a_t = glam::DMat3::from_mat4(l).transpose();
    (a_t * q).normalize()
}

fn ellipsoid_scene(transform: &str) -> String {
    format!(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 6.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 35.0, width: 200, height: 200),
            ambient: (0.05, 0.05, 0.05), background: (0.0, 0.0, 0.0),
            lights: [Directional(direction: (-1.0, -1.0, -1.0), color: (1.0, 1.0, 1.0), intensity: 0.9)],
            materials: {{ "m": (base_color: (0.3, 0.6, 0.9), specular_color: (0.4, 0.4, 0.4), shininess: 16.0, model: BlinnPhong, outline_width_px: 0.0) }},
            shapes: {{ "ball": Sphere(radius: 1.0) }},
            instances: [(shape: "ball", material: "m", transform: {transform})],
        )"#
    )
}

/// An ellipsoid made by scaling and rotating a unit sphere instance, and a
/// sheared one: the silhouette matches the analytic projection within 1 px
/// and the shading matches Blinn-Phong with the analytic ellipsoid normal
/// within 2/255 at every interior pixel sampled.
#[test]
fn instanced_ellipsoids_match_the_analytic_silhouette_and_normal() {
    let gpu = gpu();
    let transforms = [
        "(translate: (0.2, -0.1, 0.0), rotate_deg: (20.0, 0.0, 30.0), scale: (1.6, 0.8, 1.0))",
        "Matrix(((1.0, 0.6, 0.0, 0.1), (0.0, 1.0, 0.0, 0.0), (0.3, 0.0, 0.8, 0.0), (0.0, 0.0, 0.0, 1.0)))",
    ];
    for transform in transforms {
        for mode in [RenderMode::Raytrace, RenderMode::Hybrid] {
            let scene = scene(&ellipsoid_scene(transform));
            let m = scene.instances[0].world_from_object;
            let (w, h) = (scene.camera.width, scene.camera.height);
            let r = rendered(&gpu, scene.clone(), settings(&scene, mode));
            let img = r.read_srgb8(&gpu).unwrap();
            let ids = r.read_ids(&gpu).unwrap();
            let cam = r.sample_camera(0);

            let mut want = Vec::new();
            let mut hit_t = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    let (o, d) = cam.pixel_ray((w, h), x, y);
                    let t = ray_ellipsoid(m, o, d);
                    want.push(t.is_some());
                    hit_t.push(t.map(|t| (o.as_dvec3() + d.as_dvec3() * t, d.as_dvec3())));
                }
            }
            let got: Vec<bool> = ids.iter().map(|&id| id != 0).collect();
            let bad = mismatches_off_boundary(&got, &want, w, h);
            assert!(
                bad.is_empty(),
                "{transform} {mode:?}: silhouette off by more than 1 px at {:?}",
                &bad[..bad.len().min(5)]
            );
            assert!(
                want.iter().filter(|&&v| v).count() > 2000,
                "the ellipsoid covers a good part of the image"
            );

            let kd = DVec3::new(0.3, 0.6, 0.9);
            let ks = DVec3::splat(0.4);
            let l = -DVec3::new(-1.0, -1.0, -1.0).normalize();
            let mut compared = 0;
            for y in (0..h).step_by(7) {
                for x in (0..w).step_by(7) {
                    if !want[(y * w + x) as usize] || !interior(&want, w, h, x, y, 2) {
                        continue;
                    }
                    let (p, d) = hit_t[(y * w + x) as usize].unwrap();
                    let n = ellipsoid_normal(m, p);
                    let v = -d.normalize();
                    let n_dot_l = n.dot(l);
                    let spec = if n_dot_l > 0.0 {
                        n.dot((l + v).normalize()).max(0.0).powf(16.0)
                    } else {
                        0.0
                    };
                    let c = kd * 0.05 + (kd * n_dot_l.max(0.0) + ks * spec) * 0.9;
                    let expected = [srgb8(c.x as f32), srgb8(c.y as f32), srgb8(c.z as f32)];
                    let got = rgb_at(&img, w, x, y);
                    for ch in 0..3 {
                        let diff = (i32::from(got[ch]) - i32::from(expected[ch])).abs();
                        assert!(
                            diff <= 2,
                            "{transform} {mode:?} ({x},{y}): got {got:?}, analytic {expected:?}"
                        );
                    }
                    compared += 1;
                }
            }
            assert!(compared >= 50, "only {compared} pixels compared");
        }
    }
}

/// 1,000 instances of every kind of shape (the spot mesh included) under
/// random rotations and non-uniform scales, and 10,000 random rays: the GPU
/// finds the same instance as the CPU reference and t within 1e-4 relative.
/// A ray may disagree only where it grazes an edge: the CPU reference itself
/// changes its answer when the ray moves by 1e-4 of the scene size. Both
/// walks: the packet walk (lavapipe's default for ray batches) and each ray
/// on its own (the trace pass's; GPUs' for batches too).
#[test]
fn gpu_traversal_matches_cpu_reference_on_random_rays() {
    let gpu = gpu();
    let renderer = buffers_only(&gpu, random_instances(false));
    let buffers = renderer.scene_buffers();
    let accel = &buffers.accel;

    let rays = random_rays(10_000);
    for packet in [true, false] {
        gpu.set_packet_walk(packet);
        let hits = RayBatch::new(&gpu)
            .unwrap()
            .trace(&gpu, buffers, &rays)
            .unwrap();
        assert_hits_match_cpu(accel, &rays, &hits, &format!("GPU (packet {packet})"));
    }
}

/// The any-hit ray batch (the shadow-ray query) against the CPU reference:
/// the rays of [`random_rays`], cut at a t_max drawn uniformly in 10-35
/// units (their aim points lie 0-43 units away), so some are blocked
/// before t_max and some are not. A ray must report a hit exactly when the
/// CPU finds any hit in (0, t_max), and the reported hit may be any one,
/// but never nearer than the closest (t at least the CPU's closest t,
/// within 1e-4 relative) nor past t_max. Grazing rays (the CPU answer
/// changes when the origin moves by 3e-3) may disagree: at most 10 of
/// 10,000, as in the closest-hit check. Both answers must be common (over
/// 2,000 rays each), or the check would prove little. And the batch must
/// stop early: fewer traversal steps in all than the closest-hit batch
/// takes on the same rays (a closest-hit search would pass the rest). Both
/// walks, as in the closest-hit check.
#[test]
fn gpu_any_hit_matches_cpu_occlusion() {
    let gpu = gpu();
    for packet in [true, false] {
        gpu.set_packet_walk(packet);
        check_any_hit(&gpu);
    }
}

fn check_any_hit(gpu: &celray::gpu::Gpu) {
    let renderer = buffers_only(gpu, random_instances(false));
    let buffers = renderer.scene_buffers();
    let accel = &buffers.accel;
    let rays: Vec<_> = random_rays(10_000)
        .into_iter()
        .enumerate()
        .map(|(i, mut ray)| {
            ray.dir[3] = 10.0 + 25.0 * celray::sampling::uniform(i as u32, 3, 0);
            ray
        })
        .collect();
    let hits = RayBatch::any_hit(gpu)
        .unwrap()
        .trace(gpu, buffers, &rays)
        .unwrap();
    let closest = RayBatch::new(gpu)
        .unwrap()
        .trace(gpu, buffers, &rays)
        .unwrap();
    let steps =
        |h: &[celray::gpu::twins::GpuHit]| h.iter().map(|h| u64::from(h.steps)).sum::<u64>();
    assert!(
        steps(&hits) < steps(&closest),
        "any-hit took {} steps, closest-hit {}: the any-hit batch does not stop early",
        steps(&hits),
        steps(&closest)
    );
    let (mut blocked, mut grazing) = (0, 0);
    for (i, (ray, hit)) in rays.iter().zip(&hits).enumerate() {
        let (o, d, t_max) = (
            Vec3::from_slice(&ray.origin),
            Vec3::from_slice(&ray.dir),
            ray.dir[3],
        );
        let cpu = accel.closest_hit(o, d, 0.0, t_max);
        assert!(!cpu.overflow && hit.overflow == 0, "ray {i}: overflow");
        let gpu_blocked = hit.instance != u32::MAX;
        if let (true, Some(closest)) = (gpu_blocked, cpu.hit) {
            assert!(
                hit.t >= closest.t * (1.0 - 1e-4) && hit.t < t_max,
                "ray {i}: any hit at t = {} outside [{}, {t_max})",
                hit.t,
                closest.t
            );
        }
        if gpu_blocked != cpu.hit.is_some() {
            let wobble = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z]
                .map(|e| accel.closest_hit(o + e * 3e-3, d, 0.0, t_max).hit.is_some());
            assert!(
                wobble.iter().any(|&w| w != cpu.hit.is_some()),
                "ray {i}: GPU blocked {gpu_blocked}, CPU {cpu:?}, and the ray is not grazing"
            );
            grazing += 1;
        }
        blocked += usize::from(cpu.hit.is_some());
    }
    assert!(
        blocked > 2000 && rays.len() - blocked > 2000,
        "{blocked} of 10,000 rays blocked: the test would prove little"
    );
    assert!(grazing <= 10, "{grazing} grazing disagreements");
}

/// Hybrid (meshes rasterized, the rest traced) against raytrace (everything
/// traced) on every shipped scene. Both sample the same pixel centres and
/// shade with the same functions, so pixels agree within 2/255 per channel
/// except where float rounding flips a mesh silhouette or a shadow edge
/// pixel between two valid answers: at most 0.5% of the pixels.
#[test]
fn hybrid_matches_raytrace_on_every_scene() {
    let gpu = gpu();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("ron") {
            continue;
        }
        let scene = Scene::load(&path).unwrap();
        let size = RenderSettings {
            width: 240,
            height: 135,
            ..settings(&scene, RenderMode::Hybrid)
        };
        let hybrid = rendered(&gpu, scene.clone(), size.clone())
            .read_srgb8(&gpu)
            .unwrap();
        let raytrace = rendered(
            &gpu,
            scene,
            RenderSettings {
                mode: RenderMode::Raytrace,
                ..size
            },
        )
        .read_srgb8(&gpu)
        .unwrap();
        let differing = hybrid
            .chunks(4)
            .zip(raytrace.chunks(4))
            .filter(|(a, b)| (0..3).any(|c| (i32::from(a[c]) - i32::from(b[c])).abs() > 2))
            .count();
        let fraction = differing as f64 / (240.0 * 135.0);
        assert!(
            fraction <= 0.005,
            "{}: {:.2}% of pixels differ by more than 2/255",
            path.display(),
            fraction * 100.0
        );
    }
}

/// A sphere of radius 0.5 above a floor, the sun straight overhead: the
/// shadow on the floor is the disk x^2 + z^2 < 0.5^2 under the sphere.
#[test]
fn shadow_lands_under_the_sphere() {
    let gpu = gpu();
    let ron = r#"(version: 1,
        camera: (eye: (0.0, 5.0, 4.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 160, height: 120),
        ambient: (0.2, 0.2, 0.2), background: (0.0, 0.0, 0.0),
        lights: [Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 0.8)],
        materials: { "floor": (base_color: (0.5, 0.5, 0.5), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong),
                     "ball": (base_color: (0.9, 0.1, 0.1), model: BlinnPhong) },
        shapes: { "floor": Plane(Quad(half_size: (5.0, 5.0))), "ball": Sphere(radius: 0.5) },
        instances: [(shape: "floor", material: "floor"), (shape: "ball", material: "ball", transform: (translate: (0.0, 1.5, 0.0)))],
    )"#;
    let scene = scene(ron);
    let (w, h) = (scene.camera.width, scene.camera.height);
    for mode in [RenderMode::Hybrid, RenderMode::Raytrace] {
        let r = rendered(&gpu, scene.clone(), settings(&scene, mode));
        let img = r.read_srgb8(&gpu).unwrap();
        let cam = r.sample_camera(0);
        let lit = srgb8(0.5 * 0.2 + 0.5 * 0.8);
        let shadowed = srgb8(0.5 * 0.2);
        let (mut floor_px, mut want_shadow, mut got_shadow) = (Vec::new(), Vec::new(), Vec::new());
        for y in 0..h {
            for x in 0..w {
                let (o, d) = cam.pixel_ray((w, h), x, y);
                let t = -o.y / d.y;
                let p = o + d * t;
                // Floor pixels not covered by the sphere itself.
                let sees_ball = celray::accel::intersect::sphere(
                    o - Vec3::new(0.0, 1.5, 0.0),
                    d,
                    0.5,
                    0.0,
                    f32::MAX,
                )
                .is_some();
                let on_floor = t > 0.0 && p.x.abs() < 5.0 && p.z.abs() < 5.0 && !sees_ball;
                floor_px.push(on_floor);
                want_shadow.push(on_floor && p.x * p.x + p.z * p.z < 0.25);
                let g = rgb_at(&img, w, x, y)[0];
                if on_floor {
                    assert!(
                        g.abs_diff(lit) <= 2 || g.abs_diff(shadowed) <= 2,
                        "{mode:?} ({x},{y}): {g} is neither lit {lit} nor shadowed {shadowed}"
                    );
                }
                got_shadow.push(on_floor && g.abs_diff(shadowed) <= 2);
            }
        }
        let bad = mismatches_off_boundary(&got_shadow, &want_shadow, w, h);
        assert!(
            bad.is_empty(),
            "{mode:?}: shadow differs from the analytic disk at {:?}",
            &bad[..bad.len().min(5)]
        );
        assert!(
            want_shadow.iter().filter(|&&s| s).count() > 100,
            "the shadow should be visible"
        );
    }
}

/// A live edit of a light's shadows (`Renderer::update_scene`, as the
/// panel's checkbox does) takes effect, although the trace pipeline keeps
/// testing the lights it tested before (`TracePass::variant_for_edit`). The
/// scene of `shadow_lands_under_the_sphere` with its light casting no
/// shadows, raytraced: the floor pixel nearest the point below the ball's
/// centre is lit (0.5 x (0.2 + 0.8)), shadowed (0.5 x 0.2) once the light
/// casts shadows (a pipeline with the shadow code), lit again once it
/// stops (the same pipeline) and shadowed again, within 2/255 each time.
#[test]
fn toggling_a_lights_shadows_takes_effect() {
    let gpu = gpu();
    let mut scene = scene(
        r#"(version: 1,
        camera: (eye: (0.0, 5.0, 4.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 80, height: 60),
        ambient: (0.2, 0.2, 0.2), background: (0.0, 0.0, 0.0),
        lights: [Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 0.8, cast_shadows: false)],
        materials: { "floor": (base_color: (0.5, 0.5, 0.5), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong),
                     "ball": (base_color: (0.9, 0.1, 0.1), model: BlinnPhong) },
        shapes: { "floor": Plane(Quad(half_size: (5.0, 5.0))), "ball": Sphere(radius: 0.5) },
        instances: [(shape: "floor", material: "floor"), (shape: "ball", material: "ball", transform: (translate: (0.0, 1.5, 0.0)))],
    )"#,
    );
    let mut r = rendered(&gpu, scene.clone(), settings(&scene, RenderMode::Raytrace));
    let (w, h) = (scene.camera.width, scene.camera.height);
    let cam = r.sample_camera(0);
    let ball = Vec3::new(0.0, 1.5, 0.0);
    // The floor pixel nearest the shadow's centre, its ray clear of the ball.
    let (x, y) = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let (o, d) = cam.pixel_ray((w, h), x, y);
            celray::accel::intersect::sphere(o - ball, d, 0.5, 0.0, f32::MAX).is_none()
        })
        .min_by(|&(ax, ay), &(bx, by)| {
            let floor = |x, y| {
                let (o, d) = cam.pixel_ray((w, h), x, y);
                (o + d * (-o.y / d.y)).length()
            };
            floor(ax, ay).total_cmp(&floor(bx, by))
        })
        .unwrap();
    let (lit, shadowed) = (srgb8(0.5 * (0.2 + 0.8)), srgb8(0.5 * 0.2));
    let check = |r: &celray::render::Renderer, want: u8, when: &str| {
        let g = rgb_at(&r.read_srgb8(&gpu).unwrap(), w, x, y)[0];
        assert!(
            g.abs_diff(want) <= 2,
            "{when}: ({x},{y}) is {g}, want {want}"
        );
    };
    check(&r, lit, "as loaded");
    for (casts, want, when) in [
        (true, shadowed, "shadows on"),
        (false, lit, "shadows off"),
        (true, shadowed, "shadows on again"),
    ] {
        *scene.lights[0].cast_shadows_mut() = casts;
        r.update_scene(&gpu, scene.clone()).unwrap();
        r.render_sample(&gpu).unwrap();
        check(&r, want, when);
    }
}

/// What the app's views do before applying a change (`render::warmup`):
/// the renderer predicts the pipelines the change will draw with, and a
/// renderer on a second device compiles exactly those ahead. Each
/// prediction is checked against the renderer after the change: a colour
/// edit needs nothing new; a light's first shadows need a new trace
/// variant, which the renderer has not built until the edit; turning them
/// off again keeps that variant (an edit keeps testing the lights the
/// pipeline tests), which a fresh renderer of that scene would not choose,
/// so the warm-up is handed the keys and must draw with them; a bounce
/// count changes the trace variant (the ball reflects); temporal
/// reprojection adds the reproject pass, which runs only on a moving
/// frame, so the warm-up must draw one; a first outline adds the
/// accumulate pass's outline kernels, and a 6 px one its 16 px tiles,
/// which the warm-up, drawing at 16 x 16 px, must keep, while no outline
/// at all needs only the kernel every sample runs; a switch from hybrid to raster may
/// change what rays walk, and an added light uploads the scene again, so
/// neither is predicted.
#[test]
fn pipeline_keys_predict_a_change_and_the_warm_up_draws_with_them() {
    use celray::render::warmup::Warmer;
    let gpu = gpu();
    let mut scene = scene(
        r#"(version: 1,
        camera: (eye: (0.0, 5.0, 4.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 32, height: 24),
        lights: [Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 0.8, cast_shadows: false)],
        materials: { "floor": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong),
                     "ball": (base_color: (0.9, 0.1, 0.1), model: BlinnPhong, reflectivity: 0.5) },
        shapes: { "floor": Plane(Quad(half_size: (5.0, 5.0))), "ball": Sphere(radius: 0.5) },
        instances: [(shape: "floor", material: "floor"), (shape: "ball", material: "ball", transform: (translate: (0.0, 1.5, 0.0)))],
    )"#,
    );
    let hybrid = settings(&scene, RenderMode::Hybrid);
    let mut r = rendered(&gpu, scene.clone(), hybrid.clone());
    let start = r.pipeline_keys();

    scene.materials[0].base_color = Vec3::new(0.3, 0.6, 0.3);
    assert_eq!(r.keys_for_edit(&scene), Some(start), "a colour edit");
    assert!(r.has_pipelines(&start));

    *scene.lights[0].cast_shadows_mut() = true;
    let on = r.keys_for_edit(&scene).expect("written in place");
    assert_ne!(on, start, "first shadows need the shadow code");
    assert!(!r.has_pipelines(&on), "not built before the edit");
    r.update_scene(&gpu, scene.clone()).unwrap();
    assert_eq!(r.pipeline_keys(), on);
    assert!(r.has_pipelines(&on));

    *scene.lights[0].cast_shadows_mut() = false;
    let off = r.keys_for_edit(&scene).expect("written in place");
    assert_eq!(off, on, "turning shadows off keeps the pipeline");
    let fresh = celray::render::Renderer::new(&gpu, scene.clone(), hybrid.clone()).unwrap();
    assert_ne!(
        fresh.pipeline_keys(),
        off,
        "a fresh renderer chooses otherwise"
    );
    drop(fresh);
    let mut warmer = Warmer::new(&gpu);
    // The pipelines a warm-up of this change drew with, once it is done.
    let mut warm = |scene: &celray::scene::Scene, settings: &RenderSettings, keys| {
        let job = warmer
            .request(&gpu, scene.clone(), settings.clone(), Some(keys))
            .expect("a warm-up thread");
        loop {
            if let Some(outcome) = warmer.outcome(&job) {
                break outcome.unwrap_or_else(|e| panic!("warm-up failed: {e}"));
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    };
    assert_eq!(
        warm(&scene, &hybrid, off),
        Some(off),
        "the warm-up draws with the keys it is given"
    );
    r.update_scene(&gpu, scene.clone()).unwrap();
    assert_eq!(r.pipeline_keys(), off);

    let no_bounces = RenderSettings {
        max_bounces: 0,
        ..hybrid.clone()
    };
    let flat = r.keys_for_settings(&no_bounces).expect("same structures");
    assert_ne!(flat, off, "no reflection code without bounces");
    r.set_settings(&gpu, no_bounces.clone()).unwrap();
    assert_eq!(r.pipeline_keys(), flat);

    let temporal = RenderSettings {
        temporal: celray::render::Temporal::Reproject,
        ..no_bounces
    };
    let reprojecting = r.keys_for_settings(&temporal).expect("same structures");
    assert_ne!(reprojecting, flat, "reprojection adds a pass");
    assert!(
        !r.has_pipelines(&reprojecting),
        "not built before the switch"
    );
    assert_eq!(
        warm(&scene, &temporal, reprojecting),
        Some(reprojecting),
        "the warm-up draws a moving frame, through the reproject pass"
    );
    r.set_settings(&gpu, temporal.clone()).unwrap();
    assert_eq!(r.pipeline_keys(), reprojecting);
    assert!(r.has_pipelines(&reprojecting));

    // A first outline runs the accumulate pass's outline kernels, and one
    // of 4 px or more its larger tiles: kernels this renderer has not run.
    let mut keys_by_width = Vec::new();
    for width in [1.5, 6.0] {
        scene.materials[1].outline_width_px = width;
        let outlined = r.keys_for_edit(&scene).expect("written in place");
        assert!(
            !r.has_pipelines(&outlined),
            "{width} px: not run before the edit"
        );
        assert_eq!(
            warm(&scene, &temporal, outlined),
            Some(outlined),
            "{width} px: the warm-up keeps the view's tiles at its own size"
        );
        r.update_scene(&gpu, scene.clone()).unwrap();
        assert_eq!(r.pipeline_keys(), outlined);
        r.render_sample(&gpu).unwrap();
        keys_by_width.push(outlined);
    }
    assert_ne!(keys_by_width[0], keys_by_width[1], "other tiles");
    scene.materials[1].outline_width_px = 1.5;
    assert_eq!(r.keys_for_edit(&scene), Some(keys_by_width[0]));
    assert!(r.has_pipelines(&keys_by_width[0]), "run before");
    // A renderer that has drawn only with outlines: without them only the
    // `main` kernel runs, which its samples ran too.
    let outlined = rendered(&gpu, scene.clone(), temporal.clone());
    scene.materials[1].outline_width_px = 0.0;
    let plain = outlined.keys_for_edit(&scene).expect("written in place");
    assert_ne!(plain, keys_by_width[0]);
    assert!(outlined.has_pipelines(&plain), "main ran with the outlines");
    let raster = settings(&scene, RenderMode::Raster);
    assert_eq!(r.keys_for_settings(&raster), None);
    let mut more_lights = scene.clone();
    more_lights.lights.push(scene.lights[0].clone());
    assert_eq!(r.keys_for_edit(&more_lights), None);
}

/// A definition no instance shows (a CSG solid with a mesh leaf and a toon
/// leaf material, a glossy mirror material, an outlined toon material)
/// chooses no code: the pipelines, the kernels' private array sizes and
/// the uploaded triangles are those of a scene whose unused definitions
/// are a sphere and plain materials. Showing the
/// mirror on the ball does choose other code (reflections), so the keys
/// tell such scenes apart.
#[test]
fn definitions_no_instance_shows_choose_no_code() {
    use celray::render::Renderer;
    let gpu = gpu();
    let ron = |shapes: &str, materials: &str, ball: &str| {
        format!(
            r#"(version: 1,
            camera: (eye: (0.0, 3.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 16, height: 16),
            lights: [Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 0.8)],
            materials: {{ "floor": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong){materials} }},
            shapes: {{ "floor": Plane(Quad(half_size: (5.0, 5.0))), "ball": Sphere(radius: 0.5){shapes} }},
            instances: [(shape: "floor", material: "floor"), (shape: "ball", material: "{ball}", transform: (translate: (0.0, 1.0, 0.0)))],
        )"#
        )
    };
    let shapes = r#", "solid": Difference(Mesh(path: "assets/models/spot/spot_triangulated.obj"), Cylinder(radius: 0.2, height: 3.0, material: "toon"))"#;
    let materials = r#", "mirror": (base_color: (0.9, 0.9, 0.9), model: BlinnPhong, reflectivity: 0.8, roughness: 0.2),
        "toon": (base_color: (0.2, 0.4, 0.8), model: Toon(bands: 5), outline_width_px: 3.0)"#;
    // The plain scene defines as many shapes and materials (the material
    // table's size is part of the keys), of kinds its instances show.
    let plain = scene(&ron(
        r#", "solid": Sphere(radius: 0.5)"#,
        r#", "mirror": (base_color: (0.9, 0.9, 0.9), model: BlinnPhong),
        "toon": (base_color: (0.2, 0.4, 0.8), model: BlinnPhong)"#,
        "floor",
    ));
    let unused = scene(&ron(shapes, materials, "floor"));
    let mirrored = scene(&ron(shapes, materials, "mirror"));
    for mode in [RenderMode::Raster, RenderMode::Raytrace] {
        let chosen = |s: &Scene| {
            let r = Renderer::new(&gpu, s.clone(), settings(s, mode)).unwrap();
            let accel = &r.scene_buffers().accel;
            (r.pipeline_keys(), accel.sizes, accel.triangles.len())
        };
        let plain = chosen(&plain);
        assert_eq!(chosen(&unused), plain, "{mode:?}: unused definitions");
        if mode != RenderMode::Raster {
            assert_ne!(chosen(&mirrored).0, plain.0, "{mode:?}: a mirror shown");
        }
    }
}

/// Shadow rays go only to the lights that cast shadows, each to its own
/// light, past the first 32 lights too (the trace kernel loops over a
/// per-pipeline mask of lights 0-31 and tests lights from 32 on one by
/// one). The floor and ball of the test above, Blinn-Phong floor with no
/// specular (kd 0.5), ambient 0.2, and 34 directional lights: light 0
/// straight down (0.3, casts none), light 1 straight down (0.3, casts),
/// lights 2-31 off (intensity 0, cast none), light 32 from 45 degrees in z
/// (0.1, casts none, N.L = cos 45), light 33 from 45 degrees in x (0.2,
/// casts). A floor pixel is 0.5 (0.2 + 0.3 + 0.1 cos45 + 0.3 v1 + 0.2 cos45
/// v33), with v1 and v33 whether the ray from its floor point towards that
/// light misses the ball (closed form), within 2/255, and the four shadow
/// classes must match the closed form off their boundaries. Light 32's
/// would-be shadow must cover over 100 floor pixels, so that a shadow it
/// wrongly cast would show.
#[test]
fn shadows_come_from_each_casting_light_past_the_32nd() {
    let gpu = gpu();
    let off = "Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 0.0, cast_shadows: false),\n".repeat(30);
    let ron = format!(
        r#"(version: 1,
        camera: (eye: (0.0, 5.0, 4.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 160, height: 120),
        ambient: (0.2, 0.2, 0.2), background: (0.0, 0.0, 0.0),
        lights: [
            Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 0.3, cast_shadows: false),
            Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 0.3),
            {off}
            Directional(direction: (0.0, -1.0, 1.0), color: (1.0, 1.0, 1.0), intensity: 0.1, cast_shadows: false),
            Directional(direction: (-1.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 0.2),
        ],
        materials: {{ "floor": (base_color: (0.5, 0.5, 0.5), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong),
                     "ball": (base_color: (0.9, 0.1, 0.1), model: BlinnPhong) }},
        shapes: {{ "floor": Plane(Quad(half_size: (5.0, 5.0))), "ball": Sphere(radius: 0.5) }},
        instances: [(shape: "floor", material: "floor"), (shape: "ball", material: "ball", transform: (translate: (0.0, 1.5, 0.0)))],
    )"#
    );
    let scene = scene(&ron);
    assert_eq!(scene.lights.len(), 34);
    let (w, h) = (scene.camera.width, scene.camera.height);
    let ball = Vec3::new(0.0, 1.5, 0.0);
    let blocked = |p: Vec3, to_light: Vec3| {
        celray::accel::intersect::sphere(p - ball, to_light, 0.5, 0.0, f32::MAX).is_some()
    };
    let slant = Vec3::new(1.0, 1.0, 0.0).normalize();
    let side = Vec3::new(0.0, 1.0, -1.0).normalize();
    let value = |v1: bool, v33: bool| {
        srgb8(
            0.5 * (0.2
                + 0.3
                + 0.1 * side.y
                + 0.3 * f32::from(u8::from(v1))
                + 0.2 * slant.y * f32::from(u8::from(v33))),
        )
    };
    for mode in [RenderMode::Hybrid, RenderMode::Raytrace] {
        let r = rendered(&gpu, scene.clone(), settings(&scene, mode));
        let img = r.read_srgb8(&gpu).unwrap();
        let cam = r.sample_camera(0);
        let mut want = [Vec::new(), Vec::new()];
        let mut got = [Vec::new(), Vec::new()];
        let mut under_light_32 = 0;
        for y in 0..h {
            for x in 0..w {
                let (o, d) = cam.pixel_ray((w, h), x, y);
                let t = -o.y / d.y;
                let p = o + d * t;
                let sees_ball =
                    celray::accel::intersect::sphere(o - ball, d, 0.5, 0.0, f32::MAX).is_some();
                let on_floor = t > 0.0 && p.x.abs() < 5.0 && p.z.abs() < 5.0 && !sees_ball;
                let (s1, s33) = (blocked(p, Vec3::Y), blocked(p, slant));
                want[0].push(on_floor && s1);
                want[1].push(on_floor && s33);
                under_light_32 += usize::from(on_floor && blocked(p, side));
                let g = rgb_at(&img, w, x, y)[0];
                // The class (v1, v33) this pixel's value is within 2 of.
                let class = [(true, true), (false, true), (true, false), (false, false)]
                    .into_iter()
                    .find(|&(v1, v33)| g.abs_diff(value(v1, v33)) <= 2);
                if on_floor {
                    assert!(
                        class.is_some(),
                        "{mode:?} ({x},{y}): {g} is no sum of the lights"
                    );
                }
                let (v1, v33) = class.unwrap_or((true, true));
                got[0].push(on_floor && !v1);
                got[1].push(on_floor && !v33);
            }
        }
        assert!(
            under_light_32 > 100,
            "light 32's would-be shadow covers {under_light_32} pixels"
        );
        for (k, light) in [(0, 1), (1, 33)] {
            let bad = mismatches_off_boundary(&got[k], &want[k], w, h);
            assert!(
                bad.is_empty(),
                "{mode:?}: light {light}'s shadow differs from the closed form at {:?}",
                &bad[..bad.len().min(5)]
            );
            assert!(
                want[k].iter().filter(|&&s| s).count() > 100,
                "light {light}'s shadow should be visible"
            );
        }
    }
}

/// A red sphere over a mirror floor: a floor pixel shows red exactly where
/// its ray, reflected about y = 0, hits the sphere (else the blue background).
#[test]
fn mirror_reflection_lands_where_the_geometry_says() {
    let gpu = gpu();
    let ron = r#"(version: 1,
        camera: (eye: (0.0, 1.2, 6.0), target: (0.0, 0.3, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 35.0, width: 160, height: 120),
        ambient: (1.0, 1.0, 1.0), background: (0.0, 0.0, 1.0),
        lights: [],
        materials: { "mirror": (base_color: (0.0, 0.0, 0.0), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong, reflectivity: 1.0),
                     "red": (base_color: (1.0, 0.0, 0.0), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong, outline_width_px: 0.0) },
        shapes: { "floor": Plane(Quad(half_size: (20.0, 20.0))), "ball": Sphere(radius: 0.6) },
        instances: [(shape: "floor", material: "mirror"), (shape: "ball", material: "red", transform: (translate: (0.4, 0.9, 0.0)))],
    )"#;
    let scene = scene(ron);
    // The renderer's own CPU twin of the sphere test, in f32.
    let centre = Vec3::new(0.4, 0.9, 0.0).as_dvec3();
    assert_mirror_shows(&gpu, &scene, "mirrored geometry", |o, d| {
        celray::accel::intersect::sphere((o - centre).as_vec3(), d.as_vec3(), 0.6, 0.0, f32::MAX)
            .is_some()
    });
}

#[test]
fn sizes_over_gpu_limits_fail_with_the_limit_named() {
    let gpu = gpu();
    let scene = Scene::builtin_default();
    let huge = RenderSettings {
        width: 16384,
        height: 16384,
        ..RenderSettings::default()
    };
    let err = celray::render::Renderer::new(&gpu, scene.clone(), huge)
        .err()
        .expect("16384 x 16384 must not fit")
        .to_string();
    assert!(
        err.contains("accumulation buffer") && err.contains("limit"),
        "{err}"
    );

    // Enough instances that their matrices overflow the storage-buffer
    // binding limit (128 MiB on lavapipe; computed from the device).
    let per_instance = std::mem::size_of::<celray::gpu::twins::GpuInstance>() as u64;
    let count = gpu.device.limits().max_storage_buffer_binding_size / per_instance + 1;
    let mut big = scene;
    let one = big.instances[0].clone();
    big.instances = vec![one; count as usize];
    let err = celray::render::Renderer::new(
        &gpu,
        big,
        RenderSettings {
            width: 8,
            height: 8,
            ..Default::default()
        },
    )
    .err()
    .expect("too many instances must be refused")
    .to_string();
    assert!(
        err.contains("instance buffer") && err.contains("limit"),
        "{err}"
    );
}

/// A deep scene: FlightHelmet (94,722 triangles) instanced 10,000 times on a
/// 100 x 100 grid between two facing mirrors over a mirror floor, traced with
/// up to 8 bounces. No pixel may exhaust its traversal budget (lavapipe
/// would otherwise cut the loops silently), and every pixel's primary hit is
/// the CPU reference's (the only exceptions: rays that graze an edge).
#[test]
fn deep_scene_has_no_truncated_pixels() {
    let gpu = gpu();
    let ron = r#"(version: 1,
        camera: (eye: (-0.5, 2.0, -0.5), target: (10.0, 0.0, 10.0), up: (0.0, 1.0, 0.0), fov_y_deg: 50.0, width: 64, height: 48),
        lights: [Directional(direction: (-0.3, -1.0, -0.4), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: {
            "helmet": (base_color: (0.7, 0.6, 0.5), model: Toon(bands: 3), reflectivity: 0.3),
            "mirror": (base_color: (0.1, 0.1, 0.1), model: BlinnPhong, reflectivity: 0.9),
        },
        shapes: { "helmet": Mesh(path: "assets/models/FlightHelmet/FlightHelmet.gltf"), "wall": Plane(Quad(half_size: (60.0, 60.0))) },
        instances: [
            (shape: "wall", material: "mirror"),
            (shape: "wall", material: "mirror", transform: (translate: (0.0, 0.0, -1.0), rotate_deg: (90.0, 0.0, 0.0))),
            (shape: "wall", material: "mirror", transform: (translate: (0.0, 0.0, 40.0), rotate_deg: (-90.0, 0.0, 0.0))),
        ],
    )"#;
    let mut scene = Scene::from_ron_str(
        ron,
        "deep.ron",
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")),
    )
    .unwrap();
    let helmet = celray::scene::Instance {
        shape: 0,
        material: 0,
        world_from_object: Mat4::IDENTITY,
        world_from_object_end: None,
    };
    for i in 0..10_000 {
        let (gx, gz) = ((i % 100) as f32, (i / 100) as f32);
        scene.instances.push(celray::scene::Instance {
            world_from_object: Mat4::from_translation(Vec3::new(gx * 0.4, 0.0, gz * 0.4))
                * Mat4::from_scale(Vec3::splat(0.6)),
            ..helmet.clone()
        });
    }
    let (w, h) = (scene.camera.width, scene.camera.height);
    let settings = RenderSettings {
        max_bounces: 8,
        ..settings(&scene, RenderMode::Raytrace)
    };
    let r = rendered(&gpu, scene, settings);
    assert_eq!(
        r.overflow_pixels(&gpu).unwrap(),
        0,
        "pixels ran out of traversal steps"
    );
    let ids = r.read_ids(&gpu).unwrap();
    let cam = r.sample_camera(0);
    let accel = &r.scene_buffers().accel;
    let mut grazing = 0;
    let mut helmets = 0;
    for y in 0..h {
        for x in 0..w {
            let (o, d) = cam.pixel_ray((w, h), x, y);
            let cpu = accel.closest_hit(o, d, 0.0, 3e38);
            assert!(!cpu.overflow);
            let want = cpu.hit.map_or(0, |h| h.instance + 1);
            let got = ids[(y * w + x) as usize];
            helmets += usize::from(
                cpu.hit
                    .is_some_and(|h| accel.instances[h.instance as usize].2 == 0),
            );
            if got != want {
                let moved = accel
                    .closest_hit(o + Vec3::splat(1e-3), d, 0.0, 3e38)
                    .hit
                    .map_or(0, |h| h.instance + 1);
                assert!(
                    moved != want,
                    "pixel ({x},{y}): GPU instance {got}, CPU {want}, not a grazing ray"
                );
                grazing += 1;
            }
        }
    }
    assert!(
        helmets > 500,
        "the helmets should fill much of the view ({helmets} px)"
    );
    assert!(grazing <= 3, "{grazing} grazing pixels");
}

/// A scene without instances shows its background and nothing else, in
/// every mode: every pixel the same colour (exactly: one constant linear
/// colour through the same passes), that colour the background's sRGB
/// value within one 8-bit level per channel (0.25, 0.5 and 0.75 pass the
/// half-float G-buffer exactly, but the driver's sRGB store rounds 0.5 to
/// 187 where the formula gives 188), and no pixel ran out of traversal
/// steps. The camera looks at the origin from inside the unit cube, where
/// the empty top level's root box once lay (an inverted box the slab test
/// entered), which filled the view with the overflow colour.
#[test]
fn an_empty_scene_shows_only_its_background() {
    let gpu = gpu();
    let ron = r#"(
        version: 1,
        camera: (eye: (0.0, 0.2, 0.5), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 60.0, width: 64, height: 36),
        ambient: (0.1, 0.1, 0.1),
        background: (0.25, 0.5, 0.75),
        lights: [],
        materials: {},
        shapes: {},
        instances: [],
    )"#;
    let scene = Scene::from_ron_str(ron, "empty.ron", std::path::Path::new(".")).unwrap();
    let want = [0.25f32, 0.5, 0.75].map(srgb8);
    for mode in [RenderMode::Raster, RenderMode::Hybrid, RenderMode::Raytrace] {
        let r = rendered(&gpu, scene.clone(), settings(&scene, mode));
        assert_eq!(r.overflow_pixels(&gpu).unwrap(), 0, "{mode:?}: overflow");
        let img = r.read_srgb8(&gpu).unwrap();
        let first = &img[..4];
        let other = img.chunks_exact(4).filter(|p| *p != first).count();
        assert_eq!(other, 0, "{mode:?}: {other} pixels differ from {first:?}");
        assert!(
            (0..3).all(|c| first[c].abs_diff(want[c]) <= 1),
            "{mode:?}: background {first:?}, want {want:?}"
        );
    }
}

/// The uniform copies of the small scene tables (gpu::uniform_tables) draw
/// exactly what the storage buffers draw: the same image byte for byte, in
/// raster, hybrid and raytrace mode, on a scene whose every table has a copy
/// (csg_textbook: CSG programs and leaves), one whose mesh BVH is too big
/// for one, so that only the top-level tree's nodes are copied (the default
/// scene), and one whose instances are rewritten every
/// sample (anchor_dof_motion, motion blur); then again after a material
/// edit, written in place into both copies (the edit must change the
/// image, or the second check would prove nothing). Any wrong offset in a
/// copy's packing (two CSG instructions to a
/// vec4) or a copy left stale moves some pixel. With every table in storage
/// the trace pass walks the BVH as packets where the device can (lavapipe;
/// `SceneBuffers::packet_trace`), so the same comparison also holds the
/// packet walk to the per-ray walk's images, byte for byte.
#[test]
fn uniform_table_copies_draw_what_the_storage_buffers_draw() {
    use celray::gpu::uniform_tables::Table;
    let gpu = gpu();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    // (scene, the tables copied whole, whether the top-level tree's nodes
    // alone are copied)
    let cases = [
        ("csg_textbook.ron", Table::ALL.to_vec(), false),
        (
            "default.ron",
            Table::ALL
                .into_iter()
                .filter(|&t| t != Table::Nodes)
                .collect(),
            true,
        ),
        ("anchor_dof_motion.ron", Table::ALL.to_vec(), false),
    ];
    for (file, uniform, top_nodes) in cases {
        let scene = Scene::load(&dir.join(file)).unwrap();
        for mode in [RenderMode::Raster, RenderMode::Hybrid, RenderMode::Raytrace] {
            let settings = RenderSettings {
                width: 96,
                height: 54,
                spp: 2,
                mode,
                ..RenderSettings::default()
            };
            let mut edited = scene.clone();
            for m in &mut edited.materials {
                m.base_color = glam::Vec3::new(0.9, 0.1, 0.6);
            }
            let draw = |on: bool| {
                gpu.set_uniform_tables(on);
                let mut r = rendered(&gpu, scene.clone(), settings.clone());
                let tables = r.scene_buffers().tables;
                // Without the copies the trace pass walks packets where the
                // device can: the two walks must draw the same image too.
                assert_eq!(
                    r.scene_buffers().packet_trace,
                    !on && gpu.packet_walk(),
                    "{file}: the walk the trace pass chose"
                );
                let before = r.read_srgb8(&gpu).unwrap();
                r.update_scene(&gpu, edited.clone()).unwrap();
                r.render_to_convergence(&gpu, |_, _| {}).unwrap();
                (tables, before, r.read_srgb8(&gpu).unwrap())
            };
            let (tables, copies, copies_edited) = draw(true);
            let (none, storage, storage_edited) = draw(false);
            gpu.set_uniform_tables(true);
            for t in Table::ALL {
                assert_eq!(
                    tables.contains(t),
                    uniform.contains(&t),
                    "{file}: {t:?} read from its uniform copy"
                );
                assert!(!none.contains(t), "{file}: storage only, yet {t:?} copied");
            }
            assert_eq!(
                tables.top_nodes_only(),
                top_nodes,
                "{file}: top-level nodes"
            );
            assert!(
                !none.top_nodes_only(),
                "{file}: storage only, yet nodes copied"
            );
            assert!(
                copies == storage,
                "{file} {mode:?}: the copies draw another image"
            );
            assert!(
                copies_edited == storage_edited,
                "{file} {mode:?}: after a material edit the copies draw another image"
            );
            assert!(
                copies_edited != copies,
                "{file} {mode:?}: the material edit changed nothing"
            );
        }
    }
}

/// A ray's origin, its direction (the aim point minus the origin) and what
/// it is aimed at ("vertex" or "edge").
type AimedRay = (Vec3, Vec3, &'static str);

/// A height field over [-1, 1]^2 in x and z (6 x 6 cells, heights in
/// [0, 0.3), each cell split along alternating diagonals, every triangle
/// wound with its normal up), with the rays of
/// [`rays_through_edges_and_vertices_never_slip_through`]: each aimed from 3-4 units
/// above and up to 1 unit aside at a vertex or a point on an inner edge.
/// Such a ray descends at a slope of at least 3 / sqrt(2), steeper than
/// any cell's (at most 0.3 over 1/3), so it crosses the surface exactly
/// once, at its aim point: t = 1, since dir = aim - origin. The field is
/// turned so that its up axis is +y, -y, +x, -x, +z or -z by `turn`, so
/// that every axis leads a ray's direction, either way.
fn height_field_and_rays(turn: u32) -> (Vec<[Vec3; 3]>, Vec<AimedRay>) {
    use celray::sampling::uniform;
    const N: u32 = 6;
    let turned = |p: Vec3| -> Vec3 {
        match turn {
            0 => p,
            1 => Vec3::new(p.x, -p.y, -p.z),
            2 => Vec3::new(p.y, p.z, p.x),
            3 => Vec3::new(-p.y, p.z, -p.x),
            4 => Vec3::new(p.z, p.x, p.y),
            _ => Vec3::new(p.z, -p.x, -p.y),
        }
    };
    let vertex = |i: u32, j: u32| {
        Vec3::new(
            -1.0 + 2.0 * i as f32 / N as f32,
            0.3 * uniform(i, j, 40 + turn),
            -1.0 + 2.0 * j as f32 / N as f32,
        )
    };
    let mut triangles = Vec::new();
    for i in 0..N {
        for j in 0..N {
            let [a, b, c, d] = [
                vertex(i, j),
                vertex(i + 1, j),
                vertex(i + 1, j + 1),
                vertex(i, j + 1),
            ];
            let halves = if (i + j) % 2 == 0 {
                [[a, b, c], [a, c, d]]
            } else {
                [[a, b, d], [b, c, d]]
            };
            for [p, q, r] in halves {
                let up = (q - p).cross(r - p).y > 0.0;
                triangles.push(if up { [p, q, r] } else { [p, r, q] });
            }
        }
    }
    let inner = |p: Vec3| p.x.abs() < 0.999 && p.z.abs() < 0.999;
    let mut rays = Vec::new();
    let mut aim = |target: Vec3, what: &'static str| {
        let k = rays.len() as u32;
        let o = target
            + Vec3::new(
                2.0 * uniform(k, 41, turn) - 1.0,
                3.0 + uniform(k, 42, turn),
                2.0 * uniform(k, 43, turn) - 1.0,
            );
        rays.push((turned(o), turned(target) - turned(o), what));
    };
    for i in 1..N {
        for j in 1..N {
            aim(vertex(i, j), "vertex");
        }
    }
    for (n, tri) in triangles.iter().enumerate() {
        for e in 0..3 {
            let (p, q) = (tri[e], tri[(e + 1) % 3]);
            if inner(p) || inner(q) || inner((p + q) * 0.5) {
                let s = 0.05 + 0.9 * uniform(n as u32, e as u32, 44 + turn);
                aim(p + (q - p) * s, "edge");
            }
        }
    }
    let triangles = triangles.into_iter().map(|t| t.map(turned)).collect();
    (triangles, rays)
}

/// Watertight triangles: a ray through a shared edge or vertex of a mesh
/// finds a triangle there, never none (a crack the ray slips through), and
/// never one elsewhere. On the CPU reference every triangle is tested: at
/// least one must hit, and every hit must lie at t = 1 within 1e-4 (the aim
/// point is rounded to f32, about 1e-7 of the field's size, and t is a
/// ratio of such values; two triangles may share the hit). The CPU BVH walk
/// and the GPU ray batch must find t = 1 too, the batch both with exact
/// edge comparisons (lavapipe's default) and with the tolerance (GPUs'
/// default, `Gpu::set_edge_tolerance`). What fails it: Möller-Trumbore
/// in the CPU reference (a ray through a vertex hit no triangle), BVH box tests
/// without slack (a ray through a vertex on a box face; CPU and lavapipe),
/// and on an NVIDIA H200 the triangle test without a tolerance (2 of 217
/// edge rays of the first field missed), as Möller-Trumbore missed the
/// diagonal of a head-on quad there.
#[test]
fn rays_through_edges_and_vertices_never_slip_through() {
    use celray::accel::intersect::{triangle, TriangleRay};
    let gpu = gpu();
    let dir = std::env::temp_dir().join(format!("celray-watertight-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for turn in 0..6 {
        let (triangles, rays) = height_field_and_rays(turn);
        let gpu_triangles: Vec<_> = triangles
            .iter()
            .map(|t| celray::accel::layout::GpuTriangle {
                p0: t[0].extend(0.0).to_array(),
                p1: t[1].extend(0.0).to_array(),
                p2: t[2].extend(0.0).to_array(),
                n0: [0.0; 4],
                n1: [0.0; 4],
                n2: [0.0; 4],
            })
            .collect();
        let corners = triangles.iter().flatten();
        let lo = corners
            .clone()
            .fold(Vec3::splat(f32::MAX), |m, p| m.min(*p));
        let hi = corners.fold(Vec3::splat(f32::MIN), |m, p| m.max(*p));
        for (i, (o, d, what)) in rays.iter().enumerate() {
            let ray = TriangleRay::new(*o, *d, lo, hi);
            let hits: Vec<f32> = gpu_triangles
                .iter()
                .filter_map(|t| triangle(&ray, t, 0.0, f32::INFINITY).map(|h| h.t))
                .collect();
            assert!(
                !hits.is_empty() && hits.iter().all(|t| (t - 1.0).abs() < 1e-4),
                "turn {turn}, ray {i} at a {what}: CPU hits at t = {hits:?}, want them at 1"
            );
        }

        let mut obj = String::new();
        for t in &triangles {
            for p in t {
                obj += &format!("v {:?} {:?} {:?}\n", p.x, p.y, p.z);
            }
        }
        for k in 0..triangles.len() {
            obj += &format!("f {} {} {}\n", 3 * k + 1, 3 * k + 2, 3 * k + 3);
        }
        std::fs::write(dir.join("field.obj"), obj).unwrap();
        let path = dir.join("field.ron");
        std::fs::write(
            &path,
            r#"(version: 1,
                camera: (eye: (0.0, 8.0, 0.0), target: (0.0, 0.0, 0.0), up: (0.0, 0.0, -1.0),
                         fov_y_deg: 30.0, width: 8, height: 8),
                materials: { "m": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong) },
                shapes: { "field": Mesh(path: "field.obj") },
                instances: [(shape: "field", material: "m")])"#,
        )
        .unwrap();
        let renderer = buffers_only(&gpu, Scene::load(&path).unwrap());
        for (i, (o, d, what)) in rays.iter().enumerate() {
            let hit = renderer
                .scene_buffers()
                .accel
                .closest_hit(*o, *d, 0.0, 1e30)
                .hit;
            assert!(
                hit.is_some_and(|h| (h.t - 1.0).abs() < 1e-4),
                "turn {turn}, ray {i} at a {what}: the CPU BVH walk found {hit:?}, want t = 1"
            );
        }
        let gpu_rays: Vec<_> = rays
            .iter()
            .map(|(o, d, _)| celray::gpu::twins::GpuRay {
                origin: o.extend(0.0).to_array(),
                dir: d.extend(1e30).to_array(),
            })
            .collect();
        // Both triangle tests: exact edge comparisons (lavapipe's default)
        // and with the tolerance (GPUs' default); both walks (the packet
        // walk where the device has it, and each ray on its own).
        for (tolerance, packet) in [(false, true), (false, false), (true, true), (true, false)] {
            gpu.set_edge_tolerance(tolerance);
            gpu.set_packet_walk(packet);
            let hits = RayBatch::new(&gpu)
                .unwrap()
                .trace(&gpu, renderer.scene_buffers(), &gpu_rays)
                .unwrap();
            let bad: Vec<_> = hits
                .iter()
                .zip(&rays)
                .enumerate()
                .filter(|(_, (h, _))| h.instance != 0 || (h.t - 1.0).abs() >= 1e-4)
                .map(|(i, (h, r))| (i, r.2, h.instance as i64, h.t))
                .collect();
            assert!(
                bad.is_empty(),
                "turn {turn}, tolerance {tolerance}, packet {packet}: {} of {} GPU rays missed their aim point (ray, aimed at, instance, t): {:?}",
                bad.len(),
                rays.len(),
                &bad[..bad.len().min(5)]
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Shadow rays answered by their receiver's occluder list
/// (`accel::shadow_cull`) give the picture the BVH walk gives, byte for
/// byte: 576 close-packed spheres, boxes, cylinders and cones at uneven
/// heights under a slanted sun, which shade one another, in hybrid and
/// raytrace mode, with
/// lists (`Gpu::set_shadow_lists`) and without. The shadows are there
/// (against the same scene without shadows, many pixels darken), there is
/// no floor, so every shadow falls on a solid, and most solids' rays use a
/// list (the CPU build of the same data). A list that missed an occluder
/// would lose a shadow; one that held a wrong instance, or a receiver
/// tested against itself, would add one. The instances are too many for
/// their uniform copy, so the list test first checks each occluder's world
/// bounding sphere (trace.wgsl, `may_meet_sphere`): with the spheres'
/// radii at 0.7 of their size, 66 bytes differed (hybrid mode).
#[test]
fn occluder_lists_draw_what_the_walk_draws() {
    let gpu = gpu();
    let kinds = ["ball", "crate", "post", "cone", "egg"];
    let side = 24;
    let instances: Vec<String> = (0..side * side)
        .map(|i| {
            let (x, z) = ((i % side) as f32 * 1.1, (i / side) as f32 * 1.1);
            let y = 0.3 * ((i * 7 % 5) as f32);
            let turn = (i * 37 % 90) as f32;
            format!(
                r#"(shape: "{}", material: "m", transform: (translate: ({x}, {y}, {z}), rotate_deg: ({turn}, {turn}, 0.0)))"#,
                kinds[i % kinds.len()]
            )
        })
        .collect();
    let ron = |shadows: bool| {
        format!(
            r#"(version: 1,
            camera: (eye: (12.65, 16.0, 36.0), target: (12.65, 0.5, 12.65), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 192, height: 128),
            ambient: (0.2, 0.2, 0.2), background: (0.0, 0.0, 0.0),
            lights: [Directional(direction: (-0.6, -1.0, -0.4), color: (1.0, 1.0, 1.0), intensity: 1.0, cast_shadows: {shadows})],
            materials: {{ "m": (base_color: (0.8, 0.7, 0.6), model: BlinnPhong) }},
            shapes: {{
                "ball": Sphere(radius: 0.5), "egg": Sphere(radius: 0.4),
                "crate": Box(half_extents: (0.4, 0.3, 0.35)),
                "post": Cylinder(radius: 0.3, height: 1.2), "cone": Cone(radius: 0.4, height: 1.0),
            }},
            instances: [{}],
        )"#,
            instances.join(",\n")
        )
    };
    let lit = scene(&ron(true));
    for mode in [RenderMode::Hybrid, RenderMode::Raytrace] {
        let settings = RenderSettings {
            width: 192,
            height: 128,
            spp: 2,
            mode,
            ..RenderSettings::default()
        };
        let draw = |lists: bool, scene: &Scene| {
            gpu.set_shadow_lists(lists);
            let r = rendered(&gpu, scene.clone(), settings.clone());
            gpu.set_shadow_lists(true);
            assert_eq!(r.scene_buffers().shadow_lists, lists);
            assert!(!r
                .scene_buffers()
                .tables
                .contains(celray::gpu::uniform_tables::Table::Instances));
            assert_eq!(
                r.trace_variant().shadow_lists(),
                lists && scene.lights[0].casts_shadows(),
                "{mode:?}: whether the kernel holds the list test"
            );
            (r.read_srgb8(&gpu).unwrap(), r)
        };
        let (with_lists, r) = draw(true, &lit);
        let (walked, _) = draw(false, &lit);
        let (unshadowed, _) = draw(true, &scene(&ron(false)));
        let differ = with_lists
            .iter()
            .zip(&walked)
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(differ, 0, "{mode:?}: {differ} bytes differ with lists");
        let darker = with_lists
            .chunks(4)
            .zip(unshadowed.chunks(4))
            .filter(|(a, b)| u16::from(a[0]) + 10 < u16::from(b[0]))
            .count();
        // At least 1% of the image (about 1.7% when written).
        assert!(
            darker > 192 * 128 / 100,
            "{mode:?}: {darker} pixels in shadow"
        );
        let accel = &r.scene_buffers().accel;
        let cull = celray::accel::shadow_cull::build(accel, &lit.lights, true);
        let listed = (0..accel.instances.len() as u32)
            .filter(|&k| {
                celray::accel::shadow_cull::occluder_list(&cull.lights[0], &cull.cells, k)
                    .is_some_and(|(list, _)| list.len() >= 2)
            })
            .count();
        assert!(
            listed >= side * side / 3,
            "{listed} of {} solids have lists of 2 or more",
            side * side
        );
    }
}

/// Small tables read by selection (`gpu::uniform_tables::SelectedTables`:
/// a tree of branches over constant indices; forced on here, on by default
/// on lavapipe from Mesa 25) draw what
/// the reads at each invocation's index draw, byte for byte, ids too. The
/// generated scenes give every instance its own place and colour and use
/// every material (some reflect, so materials are read at reflected hits
/// too), so a tree leaf that loads the wrong element shows: 16 of each
/// (every leaf of the full tree), 11 instances and 7 materials (trees cut
/// by their counts). Then the default scene in hybrid mode (the cow's
/// material from the raster G-buffer's instance). A table past the limit
/// is read at its index (a unit test of `SelectedTables::of`).
#[test]
fn selected_tables_draw_what_indexed_reads_draw() {
    use celray::gpu::uniform_tables::MAX_SELECTED;
    let gpu = gpu();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    const { assert!(MAX_SELECTED >= 16, "the 16 x 16 case tests a full tree") };
    let grid = |instances: usize, materials: usize| {
        let materials_ron: String = (0..materials)
            .map(|k| {
                let t = k as f32 / materials as f32;
                let model = match k % 3 {
                    0 => "Toon(bands: 3)".to_string(),
                    1 => "BlinnPhong".to_string(),
                    _ => format!("Toon(bands: {})", 2 + k % 4),
                };
                format!(
                    "\"m{k}\": (base_color: ({t}, {}, {}), model: {model}, reflectivity: {}),",
                    1.0 - t,
                    (k % 4) as f32 / 3.0,
                    if k % 5 == 4 { 0.5 } else { 0.0 },
                )
            })
            .collect();
        let instances_ron: String = (0..instances)
            .map(|k| {
                let (x, y) = ((k % 5) as f32 * 2.4 - 4.8, (k / 5) as f32 * 1.5 - 2.2);
                let s = 0.45 + 0.05 * (k % 3) as f32;
                format!(
                    "(shape: \"ball\", material: \"m{}\", transform: (translate: ({x}, {y}, 0.0), scale: ({s}, {s}, {s}))),",
                    k % materials
                )
            })
            .collect();
        scene(&format!(
            r#"(version: 1,
                camera: (eye: (0.0, 0.0, 10.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 164, height: 92),
                lights: [Directional(direction: (-0.4, -1.0, -0.7), color: (1.0, 1.0, 1.0), intensity: 1.0)],
                materials: {{ {materials_ron} }},
                shapes: {{ "ball": Sphere(radius: 1.0) }},
                instances: [{instances_ron}],
            )"#
        ))
    };
    let cases = [
        ("16 x 16", grid(16, 16), RenderMode::Raytrace),
        ("11 x 7", grid(11, 7), RenderMode::Raytrace),
        (
            "default",
            Scene::load(&dir.join("default.ron")).unwrap(),
            RenderMode::Hybrid,
        ),
    ];
    for (name, scene, mode) in cases {
        let draw = |on: bool| {
            gpu.set_select_tables(on);
            let r = rendered(&gpu, scene.clone(), small_settings(mode));
            gpu.set_select_tables(true);
            let selected = r.scene_buffers().selected;
            let image = (r.read_srgb8(&gpu).unwrap(), r.read_ids(&gpu).unwrap());
            (selected, image)
        };
        let (selected, (image, ids)) = draw(true);
        let (none, (indexed, indexed_ids)) = draw(false);
        let instances = scene.instances.len();
        assert_eq!(
            selected.materials() as usize,
            scene.materials.len(),
            "{name}: materials selected"
        );
        assert_eq!(
            selected.instances() as usize,
            instances,
            "{name}: instances selected"
        );
        assert_eq!(
            (none.materials(), none.instances()),
            (0, 0),
            "{name}: selection off"
        );
        let differ = image.iter().zip(&indexed).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{name}: {differ} bytes differ with selection");
        assert!(ids == indexed_ids, "{name}: ids differ with selection");
        // Every instance shows (its id in the G-buffer).
        if name.contains(" x ") {
            for k in 1..=instances as u32 {
                assert!(ids.contains(&k), "{name}: instance {k} not in the image");
            }
        }
    }
}

/// The samples of a still camera on a pinhole lens share one set of
/// tiles, made for the unjittered camera (`Renderer::sample_tiles`), and
/// every change makes them again: after an edit that widens the
/// outlines to 3 px (the same tile size, but more tiles an outline
/// reaches, so fewer the trace pass accumulates itself) and after a
/// camera move, the kernel reads the tiles of the edited scene, which
/// differ from the ones before.
#[test]
fn an_edit_remakes_the_shared_tiles() {
    let gpu = gpu();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    let mut scene = Scene::load(&dir.join("default.ron")).unwrap();
    let mode = RenderMode::Raytrace;
    let settings = small_settings(mode);
    let mut r = rendered(&gpu, scene.clone(), settings.clone());
    let first = r.read_primary_tiles(&gpu).unwrap();
    for k in 0..settings.spp {
        assert!(first == r.primary_tiles(k, mode), "sample {k}'s tiles");
    }
    for m in &mut scene.materials {
        if m.outline_width_px > 0.0 {
            m.outline_width_px = 3.0;
        }
    }
    r.update_scene(&gpu, scene.clone()).unwrap();
    r.render_sample(&gpu).unwrap();
    let widened = r.read_primary_tiles(&gpu).unwrap();
    assert!(
        widened == r.primary_tiles(0, mode),
        "the edited scene's tiles"
    );
    assert!(widened != first, "the outlines' edit changed no tile");
    let mut camera = scene.camera.clone();
    camera.eye += Vec3::new(0.5, 0.2, 0.0);
    r.set_camera(camera);
    r.render_sample(&gpu).unwrap();
    let moved = r.read_primary_tiles(&gpu).unwrap();
    assert!(
        moved == r.primary_tiles(0, mode),
        "the moved camera's tiles"
    );
    assert!(moved != widened, "the camera's move changed no tile");
}

/// Scenes of at most `FLAT_TOP_LEVEL_MAX` instances test every instance
/// in turn where a ray would walk the top-level tree (reflection and
/// shadow rays, primary rays of untiled pixels): the same sums, bit for
/// bit, and the same primary hits as the walk, in a scene of 5 instances
/// of four shape kinds whose rays reflect off a floor and a sphere and
/// cast shadows on each other. (Rays into a mesh tested in turn are
/// checked against the driver's traversal in tests/driver_accel.rs: the
/// shipped scenes of up to 6 instances, the cow among them.) A row of one
/// more instance than the bound walks.
#[test]
fn flat_top_level_draws_what_the_walk_draws() {
    use celray::render::scene_buffers::FLAT_TOP_LEVEL_MAX;
    let gpu = gpu();
    let scene = common::scene(
        r#"(version: 1,
        camera: (eye: (0.0, 1.6, 4.0), target: (0.0, 0.4, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 45.0, width: 64, height: 64),
        lights: [Directional(direction: (-0.4, -1.0, -0.5), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: {
            "floor": (base_color: (0.5, 0.5, 0.45), model: Toon(bands: 3), reflectivity: 0.3),
            "mirror": (base_color: (0.9, 0.9, 0.9), model: BlinnPhong, reflectivity: 0.8),
            "toon": (base_color: (0.8, 0.3, 0.2), model: Toon(bands: 4)),
        },
        shapes: {
            "floor": Plane(Quad(half_size: (6.0, 6.0))),
            "ball": Sphere(radius: 0.5),
            "box": Box(half_extents: (0.3, 0.3, 0.3)),
            "post": Cylinder(radius: 0.2, height: 0.9),
        },
        instances: [
            (shape: "floor", material: "floor"),
            (shape: "ball", material: "mirror", transform: (translate: (-0.7, 0.5, -0.4))),
            (shape: "box", material: "toon", transform: (translate: (0.9, 0.3, -0.2), rotate_deg: (0.0, 30.0, 0.0))),
            (shape: "post", material: "toon", transform: (translate: (0.2, 0.45, 0.6))),
            (shape: "ball", material: "toon", transform: (translate: (0.3, 0.25, -1.5), scale: (0.5, 0.5, 0.5))),
        ],
    )"#,
    );
    let instances = scene.instances.len();
    let draw = |on: bool| {
        gpu.set_flat_top_level(on);
        let r = rendered(&gpu, scene.clone(), small_settings(RenderMode::Raytrace));
        gpu.set_flat_top_level(true);
        let want = if on { instances as u32 } else { 0 };
        assert_eq!(r.trace_variant().flat_top_level(), want, "the variant");
        (accumulator_bits(&gpu, &r), r.read_ids(&gpu).unwrap())
    };
    let (flat, flat_ids) = draw(true);
    let (walked, walked_ids) = draw(false);
    let differ = flat.iter().zip(&walked).filter(|(a, b)| a != b).count();
    assert_eq!(differ, 0, "{differ} pixels differ");
    assert!(flat_ids == walked_ids, "ids differ");
    let row: String = (0..=FLAT_TOP_LEVEL_MAX)
        .map(|k| {
            format!(
                "(shape: \"ball\", material: \"m\", transform: (translate: ({k}.0, 0.0, 0.0))),"
            )
        })
        .collect();
    let many = common::scene(&format!(
        r#"(version: 1,
        camera: (eye: (4.0, 3.0, 9.0), target: (4.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 64, height: 64),
        lights: [Directional(direction: (-0.4, -1.0, -0.5), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: {{ "m": (base_color: (0.8, 0.3, 0.2), model: Toon(bands: 4)) }},
        shapes: {{ "ball": Sphere(radius: 0.45) }},
        instances: [{row}],
    )"#
    ));
    let r = rendered(&gpu, many, small_settings(RenderMode::Raytrace));
    assert_eq!(
        r.trace_variant().flat_top_level(),
        0,
        "more than the bound walks"
    );
}

/// Primary rays that test only their screen tile's instances
/// (`accel::screen_tiles`) draw the picture the BVH walk draws, byte for
/// byte: the default scene (hybrid, whose primary rays skip the
/// rasterized cow, and raytrace), the depth-of-field and motion-blur
/// scene (every sample's lens point and shutter time give other tiles)
/// and the CSG scene, at a size whose last row and column of tiles are
/// cut; the G-buffer's ids (the last sample's primary hits) are the same
/// too. And the tiles are used: the kernel read the CPU's tiles of the
/// last sample, and most of them hold a list, shorter than the scene's
/// instance count. A ball against the sky is a fifth case: its tiles
/// list the ball alone or nothing, which the kernel takes from the
/// tile's flag word (the record's summary) without reading the record.
/// The floors of the default and CSG scenes have tiles the CPU proves
/// unshadowed (`TILE_UNSHADOWED`, whose primary hits cast no shadow ray;
/// the walk reads no flags and casts them all), and tiles it does not.
#[test]
fn primary_tiles_draw_what_the_walk_draws() {
    let gpu = gpu();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    let ball = r#"(version: 1,
        camera: (eye: (0.6, 0.8, 1.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 64, height: 64),
        lights: [Directional(direction: (-0.4, -1.0, -0.5), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: { "m": (base_color: (0.8, 0.3, 0.2), model: Toon(bands: 4)) },
        shapes: { "ball": Sphere(radius: 0.45) },
        instances: [(shape: "ball", material: "m")],
    )"#;
    let cases = [
        ("default.ron", RenderMode::Hybrid),
        ("default.ron", RenderMode::Raytrace),
        ("anchor_dof_motion.ron", RenderMode::Raytrace),
        ("csg_textbook.ron", RenderMode::Raytrace),
        ("a ball", RenderMode::Raytrace),
    ];
    // Tiles whose record's summary is 0 (no instance) and k + 1 (one).
    let (mut none, mut one) = (0, 0);
    for (file, mode) in cases {
        let scene = if file == "a ball" {
            Scene::from_ron_str(ball, file, &dir).unwrap()
        } else {
            Scene::load(&dir.join(file)).unwrap()
        };
        let settings = small_settings(mode);
        let draw = |on: bool| {
            gpu.set_primary_tiles(on);
            let r = rendered(&gpu, scene.clone(), settings.clone());
            gpu.set_primary_tiles(true);
            assert_eq!(r.trace_variant().primary_tiles(), on, "{file}: the variant");
            let image = (r.read_srgb8(&gpu).unwrap(), r.read_ids(&gpu).unwrap());
            (image, r)
        };
        let ((tiled, tiled_ids), r) = draw(true);
        let ((walked, walked_ids), _) = draw(false);
        let differ = tiled.iter().zip(&walked).filter(|(a, b)| a != b).count();
        assert_eq!(
            differ, 0,
            "{file} {mode:?}: {differ} bytes differ with tiles"
        );
        // The same instances too (the last sample's primary hits).
        assert!(tiled_ids == walked_ids, "{file} {mode:?}: ids differ");
        // The kernel read the CPU's tiles of the last sample.
        let tiles = r.primary_tiles(settings.spp - 1, mode);
        assert!(
            r.read_primary_tiles(&gpu).unwrap() == tiles,
            "{file}: the tiles the kernel read"
        );
        // Per tile a record, then one word: whether a rasterized mesh may
        // show (hybrid mode), where the kernel reads the raster G-buffer,
        // and above TILE_RECORD_SHIFT the record's summary, from which
        // the kernel tests a tile of no instance or one without reading
        // its record (tallied for the end: both kinds must occur, so
        // that the pictures above compare that path with the walk too).
        use celray::gpu::twins::{
            PRIMARY_TILE_WORDS, TILE_MESH_MAY_SHOW, TILE_RECORD_READ, TILE_RECORD_SHIFT,
            TILE_UNSHADOWED,
        };
        let count = tiles.len() / (PRIMARY_TILE_WORDS as usize + 1);
        assert_eq!(count, 21 * 12, "{file}: 8 x 8 tiles over 164 x 92");
        let flags = &tiles[tiles.len() - count..];
        if file != "a ball" {
            let unshadowed = flags.iter().filter(|&&f| f & TILE_UNSHADOWED != 0).count();
            assert!(
                unshadowed > 0 && unshadowed < count,
                "{file} {mode:?}: {unshadowed} of {count} tiles proven unshadowed"
            );
        }
        let summaries: Vec<u32> = flags.iter().map(|f| f >> TILE_RECORD_SHIFT).collect();
        for (t, &s) in summaries.iter().enumerate() {
            let record = &tiles[t * PRIMARY_TILE_WORDS as usize..][..PRIMARY_TILE_WORDS as usize];
            let want = celray::accel::screen_tiles::record_summary(record);
            assert_eq!(s, want, "{file}: tile {t}'s summary of {record:?}");
        }
        none += summaries.iter().filter(|&&s| s == 0).count();
        one += summaries
            .iter()
            .filter(|&&s| s != 0 && s != TILE_RECORD_READ)
            .count();
        let meshes = flags
            .iter()
            .filter(|&&m| m & TILE_MESH_MAY_SHOW != 0)
            .count();
        if mode == RenderMode::Hybrid {
            // The cow covers some tiles, not all.
            assert!(
                meshes > 0 && meshes < count / 2,
                "{file}: {meshes} mesh tiles"
            );
        } else {
            assert_eq!(meshes, 0, "{file}: raytrace mode rasterizes nothing");
        }
        let lists: Vec<&[u32]> = (0..count)
            .filter_map(|t| celray::accel::screen_tiles::tile_list(&tiles, t))
            .collect();
        let instances = scene.instances.len();
        assert!(
            lists.len() * 2 > count,
            "{file}: {} of {count} tiles listed",
            lists.len()
        );
        assert!(
            lists.iter().any(|l| l.len() < instances),
            "{file}: every list holds all {instances} instances"
        );
    }
    assert!(
        none > 0 && one > 0,
        "tiles of no instance ({none}) and of one ({one})"
    );
}
