//! Helpers shared by the GPU tests: a lavapipe device, small scenes, CPU
//! evaluations of the same math the shaders do, and checks more than one
//! test file runs (the mirror check, GPU hits against the CPU reference).
#![allow(dead_code)]

pub mod cli;

use glam::{DVec3, Vec2, Vec3};

use celray::gpu::{AdapterChoice, Gpu};
use celray::render::{camera::primary_ray, RenderMode, RenderSettings, Renderer};
use celray::sampling::PixelPattern;
use celray::scene::Scene;

/// The adapter the tests use: $CELRAY_ADAPTER if set, else lavapipe.
pub fn gpu() -> Gpu {
    Gpu::new_headless(&AdapterChoice::for_tests()).unwrap_or_else(|e| panic!("{e}"))
}

pub fn scene(ron: &str) -> Scene {
    Scene::from_ron_str(ron, "test.ron", std::path::Path::new("."))
        .unwrap_or_else(|e| panic!("{e}"))
}

/// One sample at each pixel centre (regular pattern, spp 1).
pub fn pixel_centre_settings(scene: &Scene) -> RenderSettings {
    RenderSettings {
        width: scene.camera.width,
        height: scene.camera.height,
        spp: 1,
        pattern: PixelPattern::Regular,
        ..RenderSettings::default()
    }
}

/// Renders to convergence; returns the sRGB image and the id buffer.
pub fn render(gpu: &Gpu, scene: Scene, settings: RenderSettings) -> (Vec<u8>, Vec<u32>) {
    let mut r = Renderer::new(gpu, scene, settings).unwrap_or_else(|e| panic!("{e}"));
    r.render_to_convergence(gpu, |_, _| {}).unwrap();
    (r.read_srgb8(gpu).unwrap(), r.read_ids(gpu).unwrap())
}

/// Where the ray through image point `pixel` meets the sphere (centre c,
/// radius r): the hit point, or None.
pub fn ray_sphere(scene: &Scene, pixel: Vec2, c: Vec3, r: f32) -> Option<Vec3> {
    let cam = &scene.camera;
    let (o, d) = primary_ray(cam, (cam.width, cam.height), pixel);
    let oc = o - c;
    let b = oc.dot(d);
    let disc = b * b - (oc.length_squared() - r * r);
    if disc < 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    (t > 0.0).then(|| o + d * t)
}

/// Linear to sRGB 8-bit, as the resolve pass encodes.
pub fn srgb8(linear: f32) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

pub fn rgb_at(img: &[u8], width: u32, x: u32, y: u32) -> [u8; 3] {
    let i = ((y * width + x) * 4) as usize;
    [img[i], img[i + 1], img[i + 2]]
}

/// 3 samples at 164 x 92 in `mode`: partial 8 px tiles at the right and
/// bottom edges, for tests that compare two ways of making the same sums.
pub fn small_settings(mode: RenderMode) -> RenderSettings {
    RenderSettings {
        width: 164,
        height: 92,
        spp: 3,
        mode,
        ..RenderSettings::default()
    }
}

/// A renderer that has accumulated `settings.spp` samples of `scene`.
pub fn rendered(gpu: &Gpu, scene: Scene, settings: RenderSettings) -> Renderer {
    let mut r = Renderer::new(gpu, scene, settings).unwrap_or_else(|e| panic!("{e}"));
    r.render_to_convergence(gpu, |_, _| {}).unwrap();
    r
}

/// The accumulator of `r`, each pixel's sums and count as their f32 bits,
/// to compare bit for bit.
pub fn accumulator_bits(gpu: &Gpu, r: &Renderer) -> Vec<[u32; 4]> {
    (r.read_accumulator(gpu).unwrap().iter())
        .map(|a| a.map(f32::to_bits))
        .collect()
}

/// Pixels where `got` and `want` disagree and no 8-neighbour of the pixel
/// has the opposite `want` value: disagreements away from a boundary.
pub fn mismatches_off_boundary(got: &[bool], want: &[bool], w: u32, h: u32) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            if got[i] == want[i] {
                continue;
            }
            let near_boundary = (-1i32..=1).any(|dy| {
                (-1i32..=1).any(|dx| {
                    let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                    nx >= 0
                        && ny >= 0
                        && nx < w as i32
                        && ny < h as i32
                        && want[(ny as u32 * w + nx as u32) as usize] != want[i]
                })
            });
            if !near_boundary {
                out.push((x, y));
            }
        }
    }
    out
}

/// Pixels at least `margin` pixels (Chebyshev) from any pixel of the other class.
pub fn interior(mask: &[bool], w: u32, h: u32, x: u32, y: u32, margin: i32) -> bool {
    let v = mask[(y * w + x) as usize];
    (-margin..=margin).all(|dy| {
        (-margin..=margin).all(|dx| {
            let (nx, ny) = (x as i32 + dx, y as i32 + dy);
            nx >= 0
                && ny >= 0
                && nx < w as i32
                && ny < h as i32
                && mask[(ny as u32 * w + nx as u32) as usize] == v
        })
    })
}

/// The mirror check: `scene` is one red solid (ambient 1, no lights) over a
/// mirror floor at y = 0 under a blue background, and `meets(o, d)` says,
/// solved in f64, whether the ray (o, d) meets the solid. In hybrid and
/// raytrace, a floor pixel (one whose primary ray misses the solid and
/// meets y = 0 in front of the eye) shows red exactly where its ray,
/// reflected about y = 0, meets the solid, else the background; pixels on a
/// boundary of the expected reflection or of the solid's own silhouette are
/// not judged. More than 200 pixels must show the reflection. `what` names
/// the solid in messages ("mirrored geometry").
pub fn assert_mirror_shows(
    gpu: &Gpu,
    scene: &Scene,
    what: &str,
    meets: impl Fn(DVec3, DVec3) -> bool,
) {
    let (w, h) = (scene.camera.width, scene.camera.height);
    for mode in [RenderMode::Hybrid, RenderMode::Raytrace] {
        let settings = RenderSettings {
            mode,
            ..pixel_centre_settings(scene)
        };
        let r = rendered(gpu, scene.clone(), settings);
        let img = r.read_srgb8(gpu).unwrap();
        let cam = r.sample_camera(0);
        let (mut want, mut got, mut direct_mask) = (Vec::new(), Vec::new(), Vec::new());
        let mut reflected = 0;
        for y in 0..h {
            for x in 0..w {
                let (o, d) = cam.pixel_ray((w, h), x, y);
                let (o, d) = (o.as_dvec3(), d.as_dvec3());
                let direct = meets(o, d);
                let t = -o.y / d.y;
                let mirror_hit = !direct && t > 0.0;
                direct_mask.push(direct);
                let in_reflection = mirror_hit && {
                    let p = o + d * t;
                    meets(p, DVec3::new(d.x, -d.y, d.z))
                };
                reflected += usize::from(in_reflection);
                let rgb = rgb_at(&img, w, x, y);
                want.push(in_reflection);
                got.push(mirror_hit && rgb[0] > 200 && rgb[2] < 50);
            }
        }
        // Pixels on the solid's own silhouette are excluded too.
        let mut bad = mismatches_off_boundary(&got, &want, w, h);
        bad.retain(|&(x, y)| interior(&direct_mask, w, h, x, y, 1));
        assert!(
            bad.is_empty(),
            "{mode:?}: reflection differs from the {what} at {:?}",
            &bad[..bad.len().min(5)]
        );
        assert!(
            reflected > 200,
            "the reflection should be visible ({reflected} px)"
        );
    }
}

/// Checks GPU closest hits against the CPU reference traversal, ray by ray:
/// the same instance and t within 1e-4 relative, except where the ray
/// grazes an edge (the CPU answer itself changes when the origin moves by
/// 1e-4 of the 30-unit scene), at most 10 such rays (0.1%); and more than
/// 3,000 of the 10,000 rays must hit, or the check would prove little.
/// `who` names the GPU path in messages.
pub fn assert_hits_match_cpu(
    accel: &celray::accel::SceneAccel,
    rays: &[celray::gpu::twins::GpuRay],
    hits: &[celray::gpu::twins::GpuHit],
    who: &str,
) {
    let mut hit_count = 0;
    let mut grazing = 0;
    for (i, (ray, gpu_hit)) in rays.iter().zip(hits).enumerate() {
        let (o, d) = (Vec3::from_slice(&ray.origin), Vec3::from_slice(&ray.dir));
        let cpu = accel.closest_hit(o, d, 0.0, 1e30);
        assert!(
            !cpu.overflow && gpu_hit.overflow == 0,
            "ray {i}: traversal overflow"
        );
        let same = match cpu.hit {
            None => gpu_hit.instance == u32::MAX,
            Some(h) => {
                h.instance == gpu_hit.instance && ((h.t - gpu_hit.t).abs() <= 1e-4 * h.t.max(1e-3))
            }
        };
        if cpu.hit.is_some() {
            hit_count += 1;
        }
        if !same {
            let wobble = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z].map(|e| {
                accel
                    .closest_hit(o + e * 3e-3, d, 0.0, 1e30)
                    .hit
                    .map(|h| h.instance)
            });
            let ambiguous = wobble.iter().any(|w| *w != cpu.hit.map(|h| h.instance));
            assert!(
                ambiguous,
                "ray {i}: {who} {gpu_hit:?} but CPU {cpu:?}, and the ray is not grazing"
            );
            grazing += 1;
        }
    }
    assert!(
        hit_count > 3000,
        "only {hit_count} of 10,000 rays hit: the test would prove little"
    );
    assert!(
        grazing <= 10,
        "{grazing} grazing disagreements, more than 0.1% of rays"
    );
}

/// 1,000 instances of every kind of analytic shape and the spot mesh, and
/// with `with_csg` also a CSG shape with a closed-mesh leaf, under random
/// rotations and non-uniform scales (the same scene for the same flag).
pub fn random_instances(with_csg: bool) -> Scene {
    let mut shapes = vec!["ball", "crate", "can", "cone", "quad", "disk", "cow"];
    let mut carved = "";
    if with_csg {
        shapes.push("carved");
        carved = r#",
                      "carved": Difference(Box(half_extents: (0.6, 0.6, 0.6)), Mesh(path: "assets/models/spot/spot_triangulated.obj", transform: (scale: (1.2, 1.2, 1.2))))"#;
    }
    let mut instances = String::new();
    for i in 0..1000u32 {
        let r = |k: u32| celray::sampling::uniform(i, 17, k);
        let shape = shapes[(r(0) * shapes.len() as f32) as usize % shapes.len()];
        instances += &format!(
            "(shape: \"{shape}\", material: \"m\", transform: (translate: ({:.4}, {:.4}, {:.4}), rotate_deg: ({:.2}, {:.2}, {:.2}), scale: ({:.3}, {:.3}, {:.3}))),\n",
            r(1) * 20.0 - 10.0, r(2) * 20.0 - 10.0, r(3) * 20.0 - 10.0,
            r(4) * 360.0, r(5) * 360.0, r(6) * 360.0,
            0.3 + r(7) * 1.2, 0.3 + r(8) * 1.2, 0.3 + r(9) * 1.2,
        );
    }
    let ron = format!(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 30.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 64, height: 64),
            lights: [Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 1.0)],
            materials: {{ "m": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong) }},
            shapes: {{ "ball": Sphere(radius: 0.7), "crate": Box(half_extents: (0.5, 0.3, 0.6)), "can": Cylinder(radius: 0.4, height: 1.2),
                      "cone": Cone(radius: 0.5, height: 1.0), "quad": Plane(Quad(half_size: (0.8, 0.5))), "disk": Plane(Disk(radius: 0.6)),
                      "cow": Mesh(path: "assets/models/spot/spot_triangulated.obj"){carved} }},
            instances: [{instances}],
        )"#
    );
    Scene::from_ron_str(
        &ron,
        "random.ron",
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")),
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

/// A renderer of `scene` at 8 x 8 pixels: for tests that only need its
/// scene buffers (ray batches against the CPU reference).
pub fn buffers_only(gpu: &Gpu, scene: Scene) -> Renderer {
    Renderer::new(
        gpu,
        scene,
        RenderSettings {
            width: 8,
            height: 8,
            ..Default::default()
        },
    )
    .unwrap()
}

/// `n` rays from random points of a 30-unit cube around the origin, each
/// aimed at a random point of [`random_instances`]' 20-unit cloud so that
/// most of them hit (unbounded: t_max 1e30).
pub fn random_rays(n: u32) -> Vec<celray::gpu::twins::GpuRay> {
    use celray::sampling::uniform;
    (0..n)
        .map(|i| {
            let o = Vec3::new(uniform(i, 1, 0), uniform(i, 1, 1), uniform(i, 1, 2)) * 30.0
                - Vec3::splat(15.0);
            let aim = Vec3::new(uniform(i, 2, 0), uniform(i, 2, 1), uniform(i, 2, 2)) * 20.0
                - Vec3::splat(10.0);
            let d = (aim - o).normalize();
            celray::gpu::twins::GpuRay {
                origin: o.extend(0.0).to_array(),
                dir: d.extend(1e30).to_array(),
            }
        })
        .collect()
}
