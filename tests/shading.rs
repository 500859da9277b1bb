//! Shading on lavapipe against closed forms: toon band count and band edge
//! positions, and Blinn-Phong colours against a CPU evaluation.

mod common;

use std::collections::BTreeSet;

use celray::render::{RenderMode, RenderSettings};
use common::*;
use glam::{Vec2, Vec3};

/// A unit sphere seen head-on from z = 5 by a 256 x 256 camera, lit by one
/// directional light travelling along -x (so N.L = n.x), no ambient.
fn band_scene(bands: u32) -> String {
    format!(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 256, height: 256),
            ambient: (0.0, 0.0, 0.0), background: (0.0, 0.0, 1.0),
            lights: [Directional(direction: (-1.0, 0.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 1.0)],
            materials: {{ "m": (base_color: (0.9, 0.6, 0.3), specular_color: (0.0, 0.0, 0.0), model: Toon(bands: {bands})) }},
            shapes: {{ "ball": Sphere(radius: 1.0) }},
            instances: [(shape: "ball", material: "m")],
        )"#
    )
}

#[test]
fn toon_sphere_shows_n_bands_with_edges_where_n_dot_l_crosses_thresholds() {
    let gpu = gpu();
    let base = Vec3::new(0.9, 0.6, 0.3);
    // 2, 4, 7 and 13 bands fill 1, 1, 2 and 3 vec4s of thresholds: the
    // trace kernel is built for as many as the scene fills.
    for (bands, mode) in [2u32, 4, 7, 13]
        .into_iter()
        .flat_map(|b| RenderMode::ALL.map(|m| (b, m)))
    {
        let scene = scene(&band_scene(bands));
        let (w, h) = (scene.camera.width, scene.camera.height);
        let settings = RenderSettings {
            mode,
            ..pixel_centre_settings(&scene)
        };
        let (img, ids) = render(&gpu, scene.clone(), settings);
        let bands_label = format!("{bands} bands, {} mode", mode.name());
        let bands_label = bands_label.as_str();

        // Band b's colour: base * (b + 1) / N, sRGB-encoded.
        let band_colours: Vec<[u8; 3]> = (0..bands)
            .map(|b| {
                let c = base * (b + 1) as f32 / bands as f32;
                [srgb8(c.x), srgb8(c.y), srgb8(c.z)]
            })
            .collect();

        // 1. Every pixel of the sphere (by id) shows one of N colours, and
        // all N appear (outlines sit outside the silhouette). Colours match
        // within 1/255 per channel: the G-buffer holds colour as f16 (relative
        // error 2^-11, under 0.4 of an 8-bit sRGB step), so only the final
        // rounding can differ; distinct bands differ by 10 or more.
        let band_of = |rgb: [u8; 3]| {
            band_colours
                .iter()
                .position(|c| (0..3).all(|i| (i32::from(c[i]) - i32::from(rgb[i])).abs() <= 1))
        };
        let mut seen = BTreeSet::new();
        for y in 0..h {
            for x in 0..w {
                if ids[(y * w + x) as usize] != 0 {
                    let rgb = rgb_at(&img, w, x, y);
                    let band = band_of(rgb).unwrap_or_else(|| {
                        panic!("{bands_label}: colour {rgb:?} at ({x},{y}) is no band's")
                    });
                    seen.insert(band);
                }
            }
        }
        assert_eq!(
            seen,
            (0..bands as usize).collect::<BTreeSet<_>>(),
            "{bands_label}: bands seen on the sphere"
        );

        // 2. Along the middle scanline, each change of band sits where the
        // analytic N.L = n.x crosses i/N, within 1.5 px. The analytic crossing
        // is found by bisection on the continuous image x coordinate.
        let y = h / 2;
        let py = y as f32 + 0.5;
        let n_dot_l = |x: f32| ray_sphere(&scene, Vec2::new(x, py), Vec3::ZERO, 1.0).map(|p| p.x);
        let mut checked = 0;
        for x in 0..w - 1 {
            let (a, b) = (
                band_of(rgb_at(&img, w, x, y)),
                band_of(rgb_at(&img, w, x + 1, y)),
            );
            let (Some(a), Some(b)) = (a, b) else { continue };
            if a == b {
                continue;
            }
            assert_eq!(b, a + 1, "bands increase by one towards the light");
            let threshold = b as f32 / bands as f32;
            // Bisection for n.x(xc) = threshold over a window around the edge.
            let (mut lo, mut hi) = (x as f32 - 4.0, x as f32 + 6.0);
            for _ in 0..40 {
                let mid = 0.5 * (lo + hi);
                match n_dot_l(mid) {
                    Some(v) if v >= threshold => hi = mid,
                    _ => lo = mid,
                }
            }
            let edge_analytic = 0.5 * (lo + hi);
            let edge_image = (x + 1) as f32; // between pixel x and x + 1
            assert!(
                (edge_image - edge_analytic).abs() <= 1.5,
                "{bands_label}, threshold {threshold}: edge at x = {edge_image}, analytic {edge_analytic}"
            );
            checked += 1;
        }
        assert_eq!(
            checked,
            (bands - 1) as usize,
            "{bands_label}: every band edge found on the scanline"
        );
    }
}

/// The toon highlight: a black toon sphere with a white specular colour,
/// seen head-on, under one directional light from upper right and behind
/// the camera, shows white exactly where (N.H)^shininess exceeds the
/// material's specular_threshold (and N.L > 0), that is where N.H exceeds
/// the threshold's shininess-th root: 0.5^(1/32) = 0.9786 and
/// 0.2^(1/4) = 0.6687 here. N and H are computed per pixel centre from the
/// analytic sphere and the eye. Pixels whose N.H lies within 0.0025 of the
/// root are not judged: that is about one pixel's change of N.H at these
/// edges, which covers the raster pass's tessellated normals; the
/// highlight must also cover a fair part of the sphere, so the check has
/// pixels on both sides of the edge.
#[test]
fn toon_highlight_shows_where_n_dot_h_to_the_shininess_passes_the_threshold() {
    let gpu = gpu();
    for (threshold, shininess, mode) in [(0.5f32, 32.0f32), (0.2, 4.0)]
        .into_iter()
        .flat_map(|(t, s)| RenderMode::ALL.map(|m| (t, s, m)))
    {
        let ron = format!(
            r#"(version: 1,
                camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 160, height: 160),
                ambient: (0.0, 0.0, 0.0), background: (0.0, 0.0, 1.0),
                lights: [Directional(direction: (-0.3, -0.2, -1.0), color: (1.0, 1.0, 1.0), intensity: 1.0)],
                materials: {{ "m": (base_color: (0.0, 0.0, 0.0), specular_color: (1.0, 1.0, 1.0), shininess: {shininess},
                    model: Toon(bands: 2, specular_threshold: {threshold}), outline_width_px: 0.0) }},
                shapes: {{ "ball": Sphere(radius: 1.0) }},
                instances: [(shape: "ball", material: "m")],
            )"#
        );
        let scene = scene(&ron);
        let (w, h) = (scene.camera.width, scene.camera.height);
        let settings = RenderSettings {
            mode,
            ..pixel_centre_settings(&scene)
        };
        let (img, ids) = render(&gpu, scene.clone(), settings);
        let label = format!(
            "threshold {threshold}, shininess {shininess}, {} mode",
            mode.name()
        );
        let root = f64::from(threshold).powf(1.0 / f64::from(shininess));
        let l = Vec3::new(0.3, 0.2, 1.0).normalize();
        let eye = scene.camera.eye;
        let (mut lit, mut judged) = (0, 0);
        for y in 0..h {
            for x in 0..w {
                if ids[(y * w + x) as usize] == 0 {
                    continue;
                }
                let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let Some(p) = ray_sphere(&scene, centre, Vec3::ZERO, 1.0) else {
                    continue;
                };
                let n = p.normalize();
                let hv = (l + (eye - p).normalize()).normalize();
                let n_dot_h = f64::from(n.dot(hv));
                if (n_dot_h - root).abs() < 0.0025 {
                    continue;
                }
                let want = n.dot(l) > 0.0 && n_dot_h > root;
                let rgb = rgb_at(&img, w, x, y);
                let white = rgb[1] > 128;
                assert_eq!(
                    white, want,
                    "{label}: pixel ({x}, {y}) {rgb:?}, N.H {n_dot_h:.5} against {root:.5}"
                );
                judged += 1;
                lit += usize::from(want);
            }
        }
        assert!(
            lit > 50 && lit * 4 < judged * 3,
            "{label}: {lit} of {judged} judged pixels lit"
        );
    }
}

/// A Blinn-Phong sphere under a directional and a point light matches the
/// formula evaluated on the CPU, in every mode, within 2/255 a channel.
///
/// The raster and trace pipelines fix the light count and each light's kind for
/// scenes of at most `MAX_FIXED_LIGHTS` lights and loop over
/// `frame.light_count` beyond: the scene is also rendered with that many
/// dark lights of both kinds in front of its two, which must add exactly
/// nothing, through the other loop.
#[test]
fn blinn_phong_matches_cpu_formula() {
    let gpu = gpu();
    let lit = "Directional(direction: (-1.0, -1.0, -1.0), color: (1.0, 0.9, 0.8), intensity: 0.8),
            Point(position: (-2.0, 3.0, 4.0), color: (0.6, 0.7, 1.0), intensity: 15.0),";
    let dark: String = (0..celray::render::scene_buffers::MAX_FIXED_LIGHTS)
        .map(|i| {
            if i % 2 == 0 {
                "Point(position: (1.0, 2.0, 3.0), color: (1.0, 1.0, 1.0), intensity: 0.0),"
            } else {
                "Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 0.0),"
            }
        })
        .collect();
    for lights in [lit.to_string(), format!("{dark}{lit}")] {
        blinn_phong_matches_cpu_formula_with(&gpu, &lights);
    }
}

fn blinn_phong_matches_cpu_formula_with(gpu: &celray::gpu::Gpu, lights: &str) {
    let ron = format!(
        r#"(version: 1,
        camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 200, height: 200),
        ambient: (0.05, 0.05, 0.05), background: (0.0, 0.0, 0.0),
        lights: [{lights}],
        materials: {{ "m": (base_color: (0.6, 0.3, 0.2), specular_color: (0.5, 0.5, 0.5), shininess: 20.0, model: BlinnPhong, outline_width_px: 0.0) }},
        shapes: {{ "ball": Sphere(radius: 1.0) }},
        instances: [(shape: "ball", material: "m")],
    )"#
    );
    let scene = scene(&ron);
    let (w, h) = (scene.camera.width, scene.camera.height);
    for mode in RenderMode::ALL {
        let settings = RenderSettings {
            mode,
            ..pixel_centre_settings(&scene)
        };
        let (img, _) = render(gpu, scene.clone(), settings);

        let kd = Vec3::new(0.6, 0.3, 0.2);
        let ks = Vec3::splat(0.5);
        let ambient = Vec3::splat(0.05);
        let sun_to_light = -Vec3::new(-1.0, -1.0, -1.0).normalize();
        let sun = Vec3::new(1.0, 0.9, 0.8) * 0.8;
        let point_pos = Vec3::new(-2.0, 3.0, 4.0);
        let point = Vec3::new(0.6, 0.7, 1.0) * 15.0;
        let eye = scene.camera.eye;
        let term = |n: Vec3, v: Vec3, l: Vec3, radiance: Vec3| {
            let n_dot_l = n.dot(l);
            let hv = (l + v).normalize();
            let spec = if n_dot_l > 0.0 {
                n.dot(hv).max(0.0).powf(20.0)
            } else {
                0.0
            };
            (kd * n_dot_l.max(0.0) + ks * spec) * radiance
        };

        let mut compared = 0;
        let mut worst = 0i32;
        // A 12 x 12 grid of pixels; those whose pixel centre hits the sphere at
        // least 3 px inside the silhouette are compared (the 1 px tessellation
        // margin is far smaller: 192 segments sag 1e-4 of the radius).
        for gy in 0..12 {
            for gx in 0..12 {
                let (x, y) = (30 + gx * 12, 30 + gy * 12);
                let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let inside = (-3..=3).all(|d| {
                    ray_sphere(&scene, centre + Vec2::new(d as f32, 0.0), Vec3::ZERO, 1.0).is_some()
                        && ray_sphere(&scene, centre + Vec2::new(0.0, d as f32), Vec3::ZERO, 1.0)
                            .is_some()
                });
                if !inside {
                    continue;
                }
                let p = ray_sphere(&scene, centre, Vec3::ZERO, 1.0).unwrap();
                let n = p.normalize();
                let v = (eye - p).normalize();
                let to_point = point_pos - p;
                let c = ambient * kd
                    + term(n, v, sun_to_light, sun)
                    + term(
                        n,
                        v,
                        to_point.normalize(),
                        point / to_point.length_squared(),
                    );
                let expected = [srgb8(c.x), srgb8(c.y), srgb8(c.z)];
                let got = rgb_at(&img, w, x, y);
                for ch in 0..3 {
                    let diff = (i32::from(got[ch]) - i32::from(expected[ch])).abs();
                    worst = worst.max(diff);
                    assert!(
                        diff <= 2,
                        "pixel ({x},{y}): got {got:?}, CPU formula {expected:?}"
                    );
                }
                compared += 1;
            }
        }
        let _ = h;
        assert!(compared >= 50, "only {compared} pixels compared");
        eprintln!(
            "Blinn-Phong, {} mode, {} lights: {compared} pixels, worst channel difference {worst}/255",
            mode.name(),
            scene.lights.len()
        );
    }
}

/// A toon sphere with a magenta outline of 3 px on black: along the middle
/// scanline, the outline outside the silhouette is exactly 3 pixels wide
/// (pixel centres 1, 2 and 3 px from the nearest sphere pixel) at every
/// resolution, because the width is in pixels, not in scene units.
#[test]
fn outline_width_is_in_pixels_at_any_resolution() {
    let gpu = gpu();
    for size in [128u32, 256, 512] {
        let ron = format!(
            r#"(version: 1,
                camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: {size}, height: {size}),
                ambient: (0.2, 0.2, 0.2), background: (0.0, 0.0, 0.0),
                lights: [Directional(direction: (0.0, 0.0, -1.0), color: (1.0, 1.0, 1.0), intensity: 1.0)],
                materials: {{ "m": (base_color: (0.2, 0.8, 0.2), specular_color: (0.0, 0.0, 0.0), model: Toon(bands: 3),
                               outline_color: (1.0, 0.0, 1.0), outline_width_px: 3.0) }},
                shapes: {{ "ball": Sphere(radius: 1.0) }},
                instances: [(shape: "ball", material: "m")],
            )"#
        );
        let scene = scene(&ron);
        let settings = RenderSettings {
            mode: RenderMode::Raster,
            ..pixel_centre_settings(&scene)
        };
        let (img, ids) = render(&gpu, scene.clone(), settings);
        let y = size / 2;
        let first_sphere = (0..size)
            .find(|&x| ids[(y * size + x) as usize] != 0)
            .expect("sphere on the scanline");
        let outline: Vec<u32> = (0..first_sphere)
            .filter(|&x| rgb_at(&img, size, x, y) == [255, 0, 255])
            .collect();
        assert_eq!(
            outline,
            vec![first_sphere - 3, first_sphere - 2, first_sphere - 1],
            "{size}px image: outline pixels left of the silhouette"
        );
    }
}

/// A toon sphere with an 8 px magenta outline on black, in an image whose
/// size is no multiple of the accumulate pass's 16 px tiles (an 8 px
/// outline takes the larger tiles), with the
/// sphere near its corner. On the background the outline rule is exact
/// and needs only the id buffer: a background pixel is outlined iff some
/// sphere pixel lies within 8 px of it (dx^2 + dy^2 <= 64; the sphere is
/// the only object). The ring crosses tiles that hold no sphere pixel
/// (only the tile's halo does) and the image's edges, where the pass skips
/// tiles that nothing outlines (shaders/outline_tiles.wgsl): no pixel of
/// the ring may go missing, and none outside it may appear. Exact match.
#[test]
fn wide_outline_ring_is_whole_across_tiles_and_image_edges() {
    let gpu = gpu();
    let (w, h) = (122u32, 90u32);
    let ron = format!(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: {w}, height: {h}),
            ambient: (0.2, 0.2, 0.2), background: (0.0, 0.0, 0.0),
            lights: [Directional(direction: (0.0, 0.0, -1.0), color: (1.0, 1.0, 1.0), intensity: 1.0)],
            materials: {{ "m": (base_color: (0.2, 0.8, 0.2), specular_color: (0.0, 0.0, 0.0), model: Toon(bands: 3),
                           outline_color: (1.0, 0.0, 1.0), outline_width_px: 8.0) }},
            shapes: {{ "ball": Sphere(radius: 0.35) }},
            instances: [(shape: "ball", material: "m", transform: (translate: (1.3, 0.85, 0.0)))],
        )"#
    );
    let scene = scene(&ron);
    for mode in [RenderMode::Raster, RenderMode::Raytrace] {
        let settings = RenderSettings {
            mode,
            ..pixel_centre_settings(&scene)
        };
        let (img, ids) = render(&gpu, scene.clone(), settings);
        let sphere: Vec<(i64, i64)> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| ids[(y * w + x) as usize] != 0)
            .map(|(x, y)| (i64::from(x), i64::from(y)))
            .collect();
        assert!(sphere.len() > 100, "{}: the sphere is in view", mode.name());
        let (mut ring, mut touches_edge) = (0, false);
        for y in 0..h {
            for x in 0..w {
                if ids[(y * w + x) as usize] != 0 {
                    continue;
                }
                let near = sphere.iter().any(|&(sx, sy)| {
                    let (dx, dy) = (sx - i64::from(x), sy - i64::from(y));
                    dx * dx + dy * dy <= 64
                });
                let expected = if near { [255, 0, 255] } else { [0, 0, 0] };
                assert_eq!(
                    rgb_at(&img, w, x, y),
                    expected,
                    "{}: background pixel ({x},{y}), outlined: {near}",
                    mode.name()
                );
                if near {
                    ring += 1;
                    touches_edge |= x == w - 1 || y == 0;
                }
            }
        }
        assert!(ring > 300, "{}: {ring} ring pixels", mode.name());
        assert!(
            touches_edge,
            "{}: the ring reaches the image's edge",
            mode.name()
        );
    }
}

/// Crease angle of the accumulate pass's outline rule (shaders/accumulate.wgsl,
/// `CREASE_COS`): normals more than 60 degrees apart.
const CREASE_COS: f32 = 0.5;

/// The outline rule of shaders/accumulate.wgsl (`outline_at`) evaluated on
/// the CPU from read-back G-buffers, for scenes whose objects all have
/// outlines `width` px wide: pixel p is outlined iff some object pixel q
/// with dx^2 + dy^2 <= width^2 makes an edge with p (p is background; q is
/// DEPTH_JUMP in front; q is another object and nearer; or the normals are
/// over 60 degrees apart and q is not behind). `None` where a comparison
/// lies so near its threshold that the GPU's rounding (a fused dot
/// product, 1e-7 relative) could decide it either way: 1e-4 in the dot
/// product and 1e-5 relative in depth are far wider than that.
fn outline_rule(ids: &[u32], nd: &[[f32; 4]], w: u32, h: u32, width: f32) -> Vec<Option<bool>> {
    let r = width.floor() as i64;
    let front = 1.0 - celray::gpu::twins::DEPTH_JUMP;
    let mut out = Vec::with_capacity(ids.len());
    for y in 0..i64::from(h) {
        for x in 0..i64::from(w) {
            let p = (y * i64::from(w) + x) as usize;
            let (id_p, nd_p) = (ids[p], nd[p]);
            let (mut edge, mut unsure) = (false, false);
            for dy in -r..=r {
                for dx in -r..=r {
                    let (qx, qy) = (x + dx, y + dy);
                    if qx < 0 || qy < 0 || qx >= i64::from(w) || qy >= i64::from(h) {
                        continue;
                    }
                    let q = (qy * i64::from(w) + qx) as usize;
                    if ids[q] == 0 || (dx * dx + dy * dy) as f32 > width * width {
                        continue;
                    }
                    if id_p == 0 {
                        edge = true;
                        continue;
                    }
                    let nd_q = nd[q];
                    let jump = nd_p[3] * front;
                    let dot = nd_q[0] * nd_p[0] + nd_q[1] * nd_p[1] + nd_q[2] * nd_p[2];
                    edge |= nd_q[3] < jump
                        || (ids[q] != id_p && nd_q[3] < nd_p[3])
                        || (dot < CREASE_COS && nd_q[3] <= nd_p[3]);
                    unsure |= (nd_q[3] - jump).abs() <= 1e-5 * nd_p[3]
                        || ((dot - CREASE_COS).abs() <= 1e-4 && nd_q[3] <= nd_p[3]);
                }
            }
            out.push(if edge || !unsure { Some(edge) } else { None });
        }
    }
    out
}

/// Renders `ron` (objects with 3 px magenta outlines on black, shading
/// that never makes magenta) at one sample per pixel centre and checks
/// every pixel against [`outline_rule`]. Returns what more checks need:
/// the renderer, the read-back ids and normal + depth, and the number of
/// outlined pixels inside objects (crease and depth edges, not
/// silhouettes).
struct OutlineCheck {
    renderer: celray::render::Renderer,
    ids: Vec<u32>,
    normal_depth: Vec<[f32; 4]>,
    inside: usize,
}

fn assert_outlines_follow_the_rule(
    gpu: &celray::gpu::Gpu,
    ron: &str,
    mode: RenderMode,
) -> OutlineCheck {
    let scene = scene(ron);
    let (w, h) = (scene.camera.width, scene.camera.height);
    let width_px = (scene.materials.iter()).fold(0.0f32, |w, m| w.max(m.outline_width_px));
    let settings = RenderSettings {
        mode,
        ..pixel_centre_settings(&scene)
    };
    let r = rendered(gpu, scene, settings);
    let img = r.read_srgb8(gpu).unwrap();
    let ids = r.read_ids(gpu).unwrap();
    let nd = r.read_normal_depth(gpu).unwrap();
    let rule = outline_rule(&ids, &nd, w, h, width_px);
    let (mut inside, mut unsure) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let Some(expected) = rule[i] else {
                unsure += 1;
                continue;
            };
            let outlined = rgb_at(&img, w, x, y) == [255, 0, 255];
            assert_eq!(
                outlined,
                expected,
                "{}: pixel ({x},{y}) (id {}) outlined {outlined}, the rule says {expected}",
                mode.name(),
                ids[i]
            );
            inside += usize::from(expected && ids[i] != 0);
        }
    }
    assert!(
        unsure * 1000 < rule.len(),
        "{}: {unsure} pixels too near a threshold to check",
        mode.name()
    );
    OutlineCheck {
        renderer: r,
        ids,
        normal_depth: nd,
        inside,
    }
}

/// Outlines inside one object, where the accumulate pass's tile marks
/// (shaders/outline_tiles.wgsl) decide whether a tile's search may be
/// skipped from bounds on its depths and normals: the textbook CSG solid
/// (box edges are 90-degree creases, the bores' far walls lie over 5%
/// deeper than the faces around them) and a box turned to show three
/// faces, every pixel against the rule. A skip that ignored normals or
/// depths would lose these outlines.
#[test]
fn outlines_inside_one_object_follow_the_rule() {
    let gpu = gpu();
    let ron = r#"(version: 1,
        camera: (eye: (0.0, 6.0, 19.0), target: (0.0, 0.3, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 10.0, width: 320, height: 240),
        ambient: (0.2, 0.2, 0.2), background: (0.0, 0.0, 0.0),
        lights: [Directional(direction: (-0.3, -1.0, -0.5), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: {
            "solid": (base_color: (0.85, 0.25, 0.15), specular_color: (0.0, 0.0, 0.0), model: Toon(bands: 4),
                      outline_color: (1.0, 0.0, 1.0), outline_width_px: 3.0),
            "bore": (base_color: (0.2, 0.45, 0.85), specular_color: (0.0, 0.0, 0.0), model: Toon(bands: 4)),
        },
        shapes: {
            "textbook": Difference(
                Intersection([Box(half_extents: (0.8, 0.8, 0.8)), Sphere(radius: 1.05)]),
                Union([
                    Cylinder(radius: 0.45, height: 2.0, material: "bore"),
                    Cylinder(radius: 0.45, height: 2.0, transform: (rotate_deg: (90.0, 0.0, 0.0)), material: "bore"),
                    Cylinder(radius: 0.45, height: 2.0, transform: (rotate_deg: (0.0, 0.0, 90.0)), material: "bore"),
                ]),
            ),
            "box": Box(half_extents: (0.5, 0.5, 0.5)),
        },
        instances: [
            (shape: "textbook", material: "solid", transform: (translate: (-1.0, 0.3, 0.0), rotate_deg: (0.0, 30.0, 0.0))),
            (shape: "box", material: "solid", transform: (translate: (1.3, 0.3, 0.0), rotate_deg: (25.0, 40.0, 0.0))),
        ],
    )"#;
    for mode in [RenderMode::Raster, RenderMode::Raytrace] {
        let inside = assert_outlines_follow_the_rule(&gpu, ron, mode).inside;
        // Raster mode draws the box alone (it draws nothing for CSG): its
        // three visible edges, 3 px on one side, some 60 px long each.
        assert!(
            inside > 200,
            "{}: {inside} outlined pixels inside objects",
            mode.name()
        );
    }
    // A depth edge alone: one CSG union of two boxes seen head-on, a small
    // one 2 units in front of a wide one. Every visible face faces the
    // camera (normal +z), and the front face lies at depth 19.5 against
    // the back one's 21.5 (0.907 of it, past the 0.95 of an edge), so only
    // the depth bound can tell the tiles along the small box's border from
    // the quiet ones.
    let stacked = r#"(version: 1,
        camera: (eye: (0.0, 0.0, 20.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 10.0, width: 256, height: 192),
        ambient: (0.2, 0.2, 0.2), background: (0.0, 0.0, 0.0),
        lights: [Directional(direction: (0.0, 0.0, -1.0), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: { "solid": (base_color: (0.85, 0.25, 0.15), specular_color: (0.0, 0.0, 0.0), model: Toon(bands: 4),
                               outline_color: (1.0, 0.0, 1.0), outline_width_px: 3.0) },
        shapes: { "stacked": Union([
            Box(half_extents: (0.4, 0.4, 0.5)),
            Box(half_extents: (1.2, 1.0, 0.5), transform: (translate: (0.0, 0.0, -2.0))),
        ]) },
        instances: [(shape: "stacked", material: "solid")],
    )"#;
    let inside = assert_outlines_follow_the_rule(&gpu, stacked, RenderMode::Raytrace).inside;
    // The small box's square border, 3 px wide on the wide box's face,
    // some 60 px a side.
    assert!(
        inside > 400,
        "stacked boxes: {inside} outlined pixels inside the union"
    );
}

/// A unit sphere seen head-on from z = 5 (fov 20 degrees, 384 x 288: about
/// 167 px across its radius) with a 3 px outline: every pixel follows the
/// rule, and the tiles in the middle of its disc are skipped. The marks
/// (shaders/outline_tiles.wgsl) skip a tile that is all one object when
/// neighbouring texels' view depths are within 0.96^(1/6) = 0.9932 of each
/// other and their normals within 54/6 = 9 degrees (paths of 2r = 6
/// steps). Where every texel of a tile and its 3 px halo is the sphere
/// with normal.z >= 0.95, the surface is the cap within 18.2 degrees of
/// the view axis: one pixel (1/167 unit) turns the normal by at most
/// 1/(167 * 0.95) rad = 0.36 degrees and moves the depth (about 4) by at
/// most 0.33/167 = 0.002, 0.05% of it. Such a tile can take no outline,
/// and its search must be skipped (a mark that bounded too loosely would
/// not). Tiles that hold both the sphere and the background must be
/// searched.
#[test]
fn the_quiet_middle_of_a_sphere_skips_the_outline_search() {
    let gpu = gpu();
    let (w, h, halo) = (384u32, 288u32, 3i64);
    let ron = outlined_sphere(w, h, 3.0);
    for mode in [RenderMode::Raster, RenderMode::Raytrace] {
        let OutlineCheck {
            renderer: r,
            ids,
            normal_depth: nd,
            ..
        } = assert_outlines_follow_the_rule(&gpu, &ron, mode);
        let marks = r.read_outline_tile_marks(&gpu).unwrap();
        // A 3 px outline: the smaller tiles.
        let tile = r.outline_tile_px();
        assert_eq!(tile, celray::gpu::twins::ACCUMULATE_TILES[0]);
        let tiles_x = w.div_ceil(tile);
        assert_eq!(marks.len() as u32, tiles_x * h.div_ceil(tile));
        let (mut quiet, mut silhouette) = (0, 0);
        for (t, &mark) in marks.iter().enumerate() {
            let (tx, ty) = (t as u32 % tiles_x, t as u32 / tiles_x);
            let texels = |margin: i64| {
                let x0 = i64::from(tx * tile) - margin;
                let y0 = i64::from(ty * tile) - margin;
                let span = i64::from(tile) + 2 * margin;
                (y0..y0 + span)
                    .flat_map(move |y| (x0..x0 + span).map(move |x| (x, y)))
                    .filter(|&(x, y)| x >= 0 && y >= 0 && x < i64::from(w) && y < i64::from(h))
                    .map(|(x, y)| (y * i64::from(w) + x) as usize)
            };
            if texels(halo).all(|i| ids[i] != 0 && nd[i][2] >= 0.95) {
                quiet += 1;
                assert_eq!(
                    mark,
                    0,
                    "{}: tile ({tx},{ty}) is quiet but searched",
                    mode.name()
                );
            }
            let mut core = texels(0).map(|i| ids[i] != 0);
            let first = core.next().unwrap();
            if core.any(|s| s != first) {
                silhouette += 1;
                assert_eq!(
                    mark,
                    1,
                    "{}: tile ({tx},{ty}) on the silhouette was skipped",
                    mode.name()
                );
            }
        }
        assert!(
            quiet >= 4 && silhouette >= 20,
            "{}: {quiet} quiet, {silhouette} silhouette tiles",
            mode.name()
        );
    }
}

/// A sphere filling the middle of a `w` x `h` view, with magenta outlines
/// `outline_px` wide, on a black background.
fn outlined_sphere(w: u32, h: u32, outline_px: f32) -> String {
    format!(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 20.0, width: {w}, height: {h}),
            ambient: (0.2, 0.2, 0.2), background: (0.0, 0.0, 0.0),
            lights: [Directional(direction: (-0.5, -0.5, -1.0), color: (1.0, 1.0, 1.0), intensity: 1.0)],
            materials: {{ "m": (base_color: (0.2, 0.8, 0.2), specular_color: (0.0, 0.0, 0.0), model: Toon(bands: 3),
                           outline_color: (1.0, 0.0, 1.0), outline_width_px: {outline_px:?}) }},
            shapes: {{ "ball": Sphere(radius: 1.0) }},
            instances: [(shape: "ball", material: "m")],
        )"#
    )
}

/// Where the CPU proves a tile and its halo the smooth inside of one
/// sphere (`accel::screen_tiles::smooth_sphere_tiles`), the outline marks
/// leave it unread and the trace pass adds its colour itself. The image
/// must be the one the marks' own texel-by-texel proof gives: after 3
/// samples, the accumulator's sums bit for bit, the 8-bit image and the
/// last sample's ids equal with the proof on and off. And the proof must
/// agree with the marks: every trace tile that accumulates only with it
/// on lies in an accumulate tile that the marks, with it off, proved
/// smooth (marked 0, not OUTLINE_MARK_SEARCH); with it on there are such
/// tiles (with 1.5 px outlines at least 50: the ball's disc is about 200
/// px across here).
/// A ball rests on a floor (which no ray meets before the ball's visible
/// cap), a small crate hides part of it, and the cow stands beside it (a
/// rasterized mesh in hybrid mode), seen through a small lens (each
/// sample's eye a point on it). Outlines 1.5 px (search radius 1, 8 px
/// tiles) and 4 px (radius 4, 16 px tiles), in raytrace and hybrid mode.
#[test]
fn tiles_the_cpu_proves_the_smooth_inside_of_a_sphere_give_the_same_image() {
    use celray::gpu::twins::{OUTLINE_MARK_SEARCH, TILE_TRACE_ACCUMULATES, TRACE_WORKGROUP};
    let gpu = gpu();
    for width in [1.5, 4.0] {
        let ball = scene(&format!(
            r#"(version: 1,
            camera: (eye: (0.5, 2.0, 4.0), target: (0.0, 1.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 384, height: 216,
                     aperture_radius: 0.03, focus_distance: 4.0),
            lights: [Directional(direction: (-0.5, -1.0, -0.6), color: (1.0, 1.0, 1.0), intensity: 1.0)],
            materials: {{
                "floor": (base_color: (0.6, 0.6, 0.6), model: Toon(bands: 3), outline_width_px: 0.0),
                "m": (base_color: (0.8, 0.3, 0.2), model: Toon(bands: 4), outline_width_px: {width}),
            }},
            shapes: {{
                "floor": Plane(Quad(half_size: (20.0, 20.0))),
                "ball": Sphere(radius: 1.0),
                "crate": Box(half_extents: (0.06, 0.06, 0.06)),
                "cow": Mesh(path: "assets/models/spot/spot_triangulated.obj"),
            }},
            instances: [
                (shape: "floor", material: "floor"),
                (shape: "ball", material: "m", transform: (translate: (0.0, 1.0, 0.0))),
                (shape: "crate", material: "m", transform: (translate: (0.6, 1.55, 2.2))),
                (shape: "cow", material: "m", transform: (translate: (-1.8, 0.74, -0.5))),
            ],
        )"#
        ));
        for mode in [RenderMode::Raytrace, RenderMode::Hybrid] {
            let settings = RenderSettings {
                spp: 3,
                mode,
                ..pixel_centre_settings(&ball)
            };
            let (w, h) = (settings.width, settings.height);
            let count = (w.div_ceil(TRACE_WORKGROUP) * h.div_ceil(TRACE_WORKGROUP)) as usize;
            let run = |on: bool| {
                gpu.set_smooth_tiles(on);
                let r = rendered(&gpu, ball.clone(), settings.clone());
                gpu.set_smooth_tiles(true);
                let words = r.read_primary_tiles(&gpu).unwrap();
                let adds: Vec<bool> = words[words.len() - count..]
                    .iter()
                    .map(|w| w & TILE_TRACE_ACCUMULATES != 0)
                    .collect();
                let marks = r.read_outline_tile_words(&gpu).unwrap();
                let image = (
                    accumulator_bits(&gpu, &r),
                    r.read_srgb8(&gpu).unwrap(),
                    r.read_ids(&gpu).unwrap(),
                );
                (image, adds, marks, r.outline_tile_px())
            };
            let (proved, adds_on, _, tile) = run(true);
            let (marked, adds_off, marks_off, _) = run(false);
            let name = format!("{width} px outlines, {mode:?}");
            assert!(
                proved.0 == marked.0,
                "{name}: the accumulator's sums differ"
            );
            assert!(proved.1 == marked.1, "{name}: the 8-bit images differ");
            assert!(proved.2 == marked.2, "{name}: the ids differ");
            let (trace_x, tiles_x) = (w.div_ceil(TRACE_WORKGROUP), w.div_ceil(tile));
            let per = tile / TRACE_WORKGROUP;
            let mut gained = 0;
            for t in 0..count {
                assert!(
                    adds_on[t] || !adds_off[t],
                    "{name}: trace tile {t} adds only with the proof off"
                );
                if adds_on[t] && !adds_off[t] {
                    gained += 1;
                    let (x, y) = (t as u32 % trace_x, t as u32 / trace_x);
                    let mark = marks_off[((y / per) * tiles_x + x / per) as usize];
                    assert_ne!(
                        mark, OUTLINE_MARK_SEARCH,
                        "{name}: trace tile ({x}, {y}) proved smooth on the CPU, searched by the marks"
                    );
                }
            }
            // Radius 4 bounds each step to an eighth of the end-to-end
            // bounds, so few 16 px tiles pass at this size.
            let least = if width < 2.0 { 50 } else { 1 };
            assert!(
                gained >= least,
                "{name}: {gained} trace tiles proved smooth on the CPU"
            );
        }
    }
}

/// Where the CPU proves a tile and its halo the smooth inside of one quad
/// or disk (`accel::screen_tiles::smooth_plane_tiles`), the tile's source
/// word is 0: the outline marks leave it unread and (traced modes) the
/// trace pass adds its colour itself. The image must be the one the
/// marks' own texel-by-texel proof gives: after 3 samples, the
/// accumulator's sums bit for bit, the 8-bit image and the last sample's
/// ids equal with the proof on and off. And the proof must agree with the
/// marks: every tile whose source word only the proof clears is one the
/// marks, with it off, proved smooth (not OUTLINE_MARK_SEARCH). An
/// outlined floor quad with its far edge in view, a crate on it (a box,
/// whose faces the proof covers too) and a tilted, stretched disk,
/// through a small lens, 1.5 px outlines (8 px
/// tiles, 48 x 27 of them), in raster mode (quads only: the raster pass
/// draws a disk as a polygon), hybrid and raytrace. The floor fills about
/// half of the view, and at least 100 tiles are cleared by the proof in
/// each mode.
#[test]
fn tiles_the_cpu_proves_the_smooth_inside_of_a_plane_give_the_same_image() {
    use celray::gpu::twins::OUTLINE_MARK_SEARCH;
    let gpu = gpu();
    let floor = scene(
        r#"(version: 1,
        camera: (eye: (0.5, 4.5, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 45.0, width: 384, height: 216,
                 aperture_radius: 0.03, focus_distance: 6.7),
        lights: [Directional(direction: (-0.5, -1.0, -0.6), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: {
            "floor": (base_color: (0.6, 0.6, 0.6), model: Toon(bands: 3), outline_width_px: 1.5),
            "m": (base_color: (0.8, 0.3, 0.2), model: Toon(bands: 4), outline_width_px: 1.5),
        },
        shapes: {
            "floor": Plane(Quad(half_size: (6.0, 6.0))),
            "crate": Box(half_extents: (0.5, 0.5, 0.5)),
            "disk": Plane(Disk(radius: 1.0)),
        },
        instances: [
            (shape: "floor", material: "floor"),
            (shape: "crate", material: "m", transform: (translate: (-0.5, 0.5, -1.0), rotate_deg: (0.0, 25.0, 0.0))),
            (shape: "disk", material: "m", transform: (translate: (-2.5, 1.3, 1.0), rotate_deg: (70.0, 30.0, 0.0), scale: (1.5, 1.0, 0.7))),
        ],
    )"#,
    );
    for mode in [RenderMode::Raster, RenderMode::Hybrid, RenderMode::Raytrace] {
        let settings = RenderSettings {
            spp: 3,
            mode,
            ..pixel_centre_settings(&floor)
        };
        let run = |on: bool| {
            gpu.set_smooth_tiles(on);
            let r = rendered(&gpu, floor.clone(), settings.clone());
            gpu.set_smooth_tiles(true);
            let image = (
                accumulator_bits(&gpu, &r),
                r.read_srgb8(&gpu).unwrap(),
                r.read_ids(&gpu).unwrap(),
            );
            let marks = r.read_outline_tile_words(&gpu).unwrap();
            (image, r.source_tiles().to_vec(), marks)
        };
        let (proved, sources_on, _) = run(true);
        let (marked, sources_off, marks_off) = run(false);
        let name = format!("{mode:?}");
        assert!(
            proved.0 == marked.0,
            "{name}: the accumulator's sums differ"
        );
        assert!(proved.1 == marked.1, "{name}: the 8-bit images differ");
        assert!(proved.2 == marked.2, "{name}: the ids differ");
        assert_eq!(sources_on.len(), 48 * 27, "{name}: source tiles");
        let mut gained = 0;
        for (t, (&on, &off)) in sources_on.iter().zip(&sources_off).enumerate() {
            assert!(
                on <= off,
                "{name}: tile {t} a source only with the proof on"
            );
            if on < off {
                gained += 1;
                assert_ne!(
                    marks_off[t], OUTLINE_MARK_SEARCH,
                    "{name}: tile {t} proved smooth on the CPU, searched by the marks"
                );
            }
        }
        assert!(
            gained >= 100,
            "{name}: {gained} tiles proved smooth on the CPU"
        );
    }
}

/// In hybrid and raytrace mode the trace pass adds the colour of the 8 x 8
/// tiles that no outline can reach to the accumulator itself (the outline
/// marks' source tiles are 0 there, or no outline is 1 px wide), the
/// outline marks flag the accumulate tiles holding them
/// OUTLINE_MARK_TRACED, and the accumulate pass leaves those alone (its
/// `main` runs over a list of the others). Both passes add the same
/// half-rounded colour with the same add, one per sample, so the sums
/// after 3 samples (jittered: sample indices 1 and 2 add to a sum) must be
/// equal bit for bit to those of the accumulate pass doing every pixel: a
/// tile added by both passes counts 6 samples, one added by neither 0 or
/// a stale sum. Cases: the default scene in hybrid and raytrace mode at
/// 164 x 92 (8 px accumulate tiles, partial ones at the edges); the
/// depth-of-field and motion scene, which has no outline 1 px wide, so
/// that the trace pass adds every pixel and no accumulate pass runs; and
/// a sphere with 5 px outlines, whose 16 px accumulate tiles hold 2 x 2
/// trace tiles each (390 x 290: partial tiles of both sizes).
#[test]
fn the_trace_pass_accumulates_the_tiles_no_outline_reaches_with_the_same_sums() {
    use celray::gpu::twins::{
        OUTLINE_MARK_TRACED, PRIMARY_TILE_WORDS, TILE_TRACE_ACCUMULATES, TRACE_WORKGROUP,
    };
    let gpu = gpu();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    let load = |file: &str| celray::scene::Scene::load(&dir.join(file)).unwrap();
    let small = small_settings;
    // A small sphere right of centre, its 5 px outline magenta.
    let sphere = scene(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 12.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 390, height: 290),
            ambient: (0.2, 0.2, 0.2), background: (0.0, 0.0, 0.0),
            lights: [Directional(direction: (-0.5, -0.5, -1.0), color: (1.0, 1.0, 1.0), intensity: 1.0)],
            materials: { "m": (base_color: (0.2, 0.8, 0.2), model: Toon(bands: 3),
                               outline_color: (1.0, 0.0, 1.0), outline_width_px: 5.0) },
            shapes: { "ball": Sphere(radius: 1.0) },
            instances: [(shape: "ball", material: "m", transform: (translate: (2.0, 0.5, 0.0)))],
        )"#,
    );
    let cases = [
        (
            "default hybrid",
            load("default.ron"),
            small(RenderMode::Hybrid),
            Some(8),
        ),
        (
            "default raytrace",
            load("default.ron"),
            small(RenderMode::Raytrace),
            Some(8),
        ),
        (
            "dof + motion",
            load("anchor_dof_motion.ron"),
            small(RenderMode::Raytrace),
            None,
        ),
        (
            "5 px outlines",
            sphere.clone(),
            RenderSettings {
                spp: 3,
                mode: RenderMode::Raytrace,
                ..pixel_centre_settings(&sphere)
            },
            Some(16),
        ),
    ];
    // Per case, the accumulate tiles' edge where some outline is 1 px wide.
    for (name, scene, settings, outline_tile) in cases {
        let (w, h) = (settings.width, settings.height);
        let mut sums = Vec::new();
        for on in [true, false] {
            gpu.set_trace_accumulates(on);
            let r = rendered(&gpu, scene.clone(), settings.clone());
            gpu.set_trace_accumulates(true);
            let bits = accumulator_bits(&gpu, &r);
            assert!(
                bits.iter().all(|a| f32::from_bits(a[3]) == 3.0),
                "{name} (trace accumulates: {on}): a pixel does not count 3 samples"
            );
            sums.push(bits);
            // Which trace tiles the kernel read as its own to add.
            let words = r.read_primary_tiles(&gpu).unwrap();
            let count = (w.div_ceil(TRACE_WORKGROUP) * h.div_ceil(TRACE_WORKGROUP)) as usize;
            assert_eq!(words.len(), count * (PRIMARY_TILE_WORDS as usize + 1));
            let flags = &words[words.len() - count..];
            let traced = |t: usize| flags[t] & TILE_TRACE_ACCUMULATES != 0;
            let added = (0..count).filter(|&t| traced(t)).count();
            if !on {
                assert_eq!(added, 0, "{name}: switched off, yet the trace pass adds");
            } else if outline_tile.is_none() {
                assert_eq!(added, count, "{name}: no outline, yet some tile is left");
            } else {
                assert!(
                    added > 0 && added < count,
                    "{name}: the trace pass adds {added} of {count} tiles"
                );
                // The marks agree with the tile words: an accumulate tile
                // is marked traced exactly where its trace tiles are.
                let marks = r.read_outline_tile_words(&gpu).unwrap();
                let tile = r.outline_tile_px();
                assert_eq!(Some(tile), outline_tile, "{name}: the accumulate tiles");
                let per = tile / TRACE_WORKGROUP;
                let (tiles_x, trace_x) = (w.div_ceil(tile), w.div_ceil(TRACE_WORKGROUP));
                for t in 0..count as u32 {
                    let (x, y) = (t % trace_x, t / trace_x);
                    let mark = marks[((y / per) * tiles_x + x / per) as usize];
                    assert_eq!(
                        mark == OUTLINE_MARK_TRACED,
                        traced(t as usize),
                        "{name}: trace tile ({x}, {y}) and its {tile} px mark {mark}"
                    );
                }
            }
        }
        let differ = (0..sums[0].len())
            .filter(|&i| sums[0][i] != sums[1][i])
            .count();
        assert_eq!(
            differ, 0,
            "{name}: {differ} pixels sum otherwise when the trace pass adds"
        );
    }
}

/// The trace pass does not store the normal, depth and id of the tiles
/// that no pass of the sample reads (`TILE_GBUFFER_SKIPS`: the trace pass
/// adds the tile's colour itself, and no tile whose outline marks or
/// search run lies within the outline radius of it). Those texels keep an
/// earlier sample's values, so a tile flagged wrongly would show stale
/// texels to the outline search. Here the stale texels are the worst kind:
/// the first 3 samples see an outlined sphere filling the image (a source
/// texel across the middle two thirds of the image's width, outline
/// 1.5 px, 3 px, or 5 px for the 16 px accumulate tiles); then the camera
/// backs away, so the sphere covers the middle third, and 3 more samples
/// are taken. A background pixel of a marked tile within the outline's
/// width of a stale sphere texel would take the outline (the search takes
/// any source within its width). At 1.5 px (radius 1) the halo is one
/// texel, so a flagging one texel short leaves out the tiles left of and
/// above each read tile. The sums must
/// equal, bit for bit, those of a renderer that made the far camera's
/// samples alone with the trace pass adding nothing (every texel stored).
/// The G-buffer read back after them must be whole too (the read-back
/// first stores what the last sample left: `Renderer::complete_gbuffer`).
#[test]
fn unstored_gbuffer_texels_are_never_read() {
    use celray::gpu::twins::{TILE_GBUFFER_SKIPS, TILE_TRACE_ACCUMULATES, TRACE_WORKGROUP};
    use celray::scene::Scene;
    let gpu = gpu();
    let (w, h) = (164, 92);
    for outline_px in [1.5, 3.0, 5.0] {
        let near = scene(&outlined_sphere(w, h, outline_px));
        let mut far = near.camera.clone();
        far.eye = Vec3::new(0.0, 0.0, 15.0);
        let settings = RenderSettings {
            width: w,
            height: h,
            spp: 3,
            mode: RenderMode::Raytrace,
            ..RenderSettings::default()
        };
        let mut reused = rendered(&gpu, near.clone(), settings.clone());
        reused.set_camera(far.clone());
        reused.render_to_convergence(&gpu, |_, _| {}).unwrap();
        let words = reused.read_primary_tiles(&gpu).unwrap();
        let count = (w.div_ceil(TRACE_WORKGROUP) * h.div_ceil(TRACE_WORKGROUP)) as usize;
        let flags = &words[words.len() - count..];
        let skipped = flags
            .iter()
            .filter(|&&f| f & TILE_GBUFFER_SKIPS != 0)
            .count();
        let stored = flags
            .iter()
            .filter(|&&f| f & TILE_TRACE_ACCUMULATES == 0)
            .count();
        assert!(
            skipped > 0 && stored > 0,
            "{outline_px} px: {skipped} of {count} tiles skip, {stored} are the outline's"
        );
        gpu.set_trace_accumulates(false);
        let fresh = rendered(
            &gpu,
            Scene {
                camera: far,
                ..near
            },
            settings,
        );
        gpu.set_trace_accumulates(true);
        let (got, want) = (
            accumulator_bits(&gpu, &reused),
            accumulator_bits(&gpu, &fresh),
        );
        let differ = (0..got.len()).filter(|&i| got[i] != want[i]).count();
        assert_eq!(differ, 0, "{outline_px} px: {differ} pixels sum otherwise");
        let (ids, want_ids) = (
            reused.read_ids(&gpu).unwrap(),
            fresh.read_ids(&gpu).unwrap(),
        );
        let (nd, want_nd) = (
            reused.read_normal_depth(&gpu).unwrap(),
            fresh.read_normal_depth(&gpu).unwrap(),
        );
        let differ = (0..ids.len())
            .filter(|&i| ids[i] != want_ids[i] || (ids[i] != 0 && nd[i] != want_nd[i]))
            .count();
        assert_eq!(
            differ, 0,
            "{outline_px} px: {differ} G-buffer texels differ"
        );
    }
}

/// On a CPU adapter the trace pass and the accumulate pass's two kernels
/// dispatch a few workgroups, each looping over every n-th tile (of the
/// image, or of the marks' lists: `Gpu::set_looping_groups`), instead of
/// one workgroup per tile. Any count must give the same sums, bit for bit:
/// a tile left out or added twice would leave its pixels counting 0 or 6
/// samples after 3. At 164 x 92 (21 x 12 = 252 tiles): 1, 5 and 20
/// workgroups (5 and 20 do not divide 252; every other test runs with the
/// default, one per driver thread) against one per tile. The
/// default scene's 1.5 px outlines take every accumulate path: raster
/// (`main` over every tile, skipping the marked ones), hybrid (both
/// kernels over their lists; the trace pass adds the rest), and hybrid
/// with the lists off (both kernels over every tile).
#[test]
fn looping_workgroups_change_no_sum() {
    let gpu = gpu();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    let load = |file: &str| celray::scene::Scene::load(&dir.join(file)).unwrap();
    let cases = [
        ("default raster", "default.ron", RenderMode::Raster, true),
        ("default hybrid", "default.ron", RenderMode::Hybrid, true),
        (
            "default hybrid, no list",
            "default.ron",
            RenderMode::Hybrid,
            false,
        ),
        (
            "default raytrace",
            "default.ron",
            RenderMode::Raytrace,
            true,
        ),
        (
            "mirrors raytrace",
            "mirrors.ron",
            RenderMode::Raytrace,
            true,
        ),
    ];
    for (name, file, mode, listed) in cases {
        let scene = load(file);
        let settings = small_settings(mode);
        gpu.set_outline_tile_list(listed);
        let sums = |v: u32| {
            gpu.set_looping_groups(v);
            accumulator_bits(&gpu, &rendered(&gpu, scene.clone(), settings.clone()))
        };
        let expected = sums(0);
        assert!(
            expected.iter().all(|a| f32::from_bits(a[3]) == 3.0),
            "{name}: a pixel does not count 3 samples with a workgroup per tile"
        );
        for v in [1, 5, 20] {
            let got = sums(v);
            let differ = (0..got.len()).filter(|&i| got[i] != expected[i]).count();
            assert_eq!(
                differ, 0,
                "{name}: {differ} pixels sum otherwise with {v} looping workgroups"
            );
        }
    }
}

/// The accumulate pass searches for outlines in a kernel of its own, over
/// the list of marked tiles (one indirect dispatch); where an image has
/// more tiles than one dispatch can count (over about 4096 x 4096 pixels
/// on most devices) it runs over every tile instead, the unmarked ones
/// stopping at once, and `main` takes every unmarked tile. So each pixel
/// must be summed by exactly one of the two kernels each sample: after 3
/// samples, every pixel's count (the accumulator's w) is exactly 3 on
/// both paths (a pixel left to neither holds 0, one taken by both 5), and
/// both paths hold the same sums, bit for bit. The image is 390 x 290, so
/// the last column and row of tiles are partial. At one sample per pixel
/// centre, both paths also follow the outline rule. Both tile edges: 3 px
/// outlines take the 8 px tiles, 5 px ones (raytrace mode only, to keep
/// the test short) the 16 px tiles.
#[test]
fn each_pixel_is_summed_once_over_the_tile_list_and_over_every_tile() {
    let gpu = gpu();
    for (mode, outline_px, tile_px) in [
        (RenderMode::Raster, 3.0, 8),
        (RenderMode::Raytrace, 3.0, 8),
        (RenderMode::Raytrace, 5.0, 16),
    ] {
        let ron = outlined_sphere(390, 290, outline_px);
        let mut sums = Vec::new();
        for listed in [true, false] {
            gpu.set_outline_tile_list(listed);
            let check = assert_outlines_follow_the_rule(&gpu, &ron, mode);
            assert_eq!(
                check.renderer.outline_search_listed(),
                listed,
                "{}",
                mode.name()
            );
            let scene = scene(&ron);
            let settings = RenderSettings {
                mode,
                spp: 3,
                ..pixel_centre_settings(&scene)
            };
            let r = rendered(&gpu, scene, settings);
            assert_eq!(r.outline_search_listed(), listed, "{}", mode.name());
            assert_eq!(r.outline_tile_px(), tile_px, "{outline_px} px outlines");
            let accum = r.read_accumulator(&gpu).unwrap();
            let marks = r.read_outline_tile_marks(&gpu).unwrap();
            assert!(
                marks.iter().filter(|&&m| m != 0).count() >= 20,
                "{}: too few marked tiles for the test to mean anything",
                mode.name()
            );
            let miscounted: Vec<usize> = (0..accum.len()).filter(|&i| accum[i][3] != 3.0).collect();
            assert!(
                miscounted.is_empty(),
                "{} (tile list {listed}): {} pixels do not count 3 samples, the first {:?} with {}",
                mode.name(),
                miscounted.len(),
                miscounted.first(),
                miscounted.first().map_or(0.0, |&i| accum[i][3])
            );
            sums.push(accum);
        }
        assert!(
            sums[0] == sums[1],
            "{}: the dispatch over every tile sums other colours than the tile list",
            mode.name()
        );
    }
    gpu.set_outline_tile_list(true);
}

/// The outline marks have a timer span of their own ("outline_tiles"),
/// beside the accumulation's, wherever some outline reaches another pixel
/// (1 px or wider), and none where every outline is narrower: the default
/// scene as shipped, then with every outline 0.5 px wide. Raytrace mode
/// runs no raster pass (nothing reads its targets there), hybrid both,
/// except in a scene without triangle meshes, where hybrid traces
/// everything (its raster pass would draw nothing) and must give raytrace
/// mode's image, byte for byte.
#[test]
fn the_outline_marks_are_timed_as_a_pass_of_their_own() {
    let gpu = gpu();
    let pass_names = |scene: celray::scene::Scene, mode: RenderMode| {
        let mut renderer = celray::render::Renderer::new(
            &gpu,
            scene,
            RenderSettings {
                width: 64,
                height: 48,
                mode,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(
            renderer.enable_pass_timing(&gpu),
            "lavapipe has timestamp queries"
        );
        renderer.render_sample(&gpu).unwrap();
        let times = renderer.pass_times(&gpu).unwrap();
        for (name, ms) in &times {
            assert!(ms.is_finite() && *ms >= 0.0, "{name}: {ms} ms");
        }
        times.iter().map(|(n, _)| *n).collect::<Vec<_>>()
    };
    let shipped = celray::scene::Scene::builtin_default();
    assert_eq!(
        pass_names(shipped.clone(), RenderMode::Raster),
        ["raster", "outline_tiles", "accumulate"]
    );
    assert_eq!(
        pass_names(shipped.clone(), RenderMode::Hybrid),
        ["raster", "trace", "outline_tiles", "accumulate"]
    );
    assert_eq!(
        pass_names(shipped.clone(), RenderMode::Raytrace),
        ["trace", "outline_tiles", "accumulate"]
    );
    let mut no_meshes = shipped.clone();
    no_meshes
        .instances
        .retain(|i| !matches!(shipped.shapes[i.shape], celray::scene::Shape::Mesh(_)));
    assert!(no_meshes.instances.len() >= 3 && no_meshes.instances.len() < shipped.instances.len());
    assert_eq!(
        pass_names(no_meshes.clone(), RenderMode::Hybrid),
        ["trace", "outline_tiles", "accumulate"]
    );
    let image = |mode| {
        let settings = RenderSettings {
            width: 64,
            height: 48,
            spp: 2,
            mode,
            ..Default::default()
        };
        render(&gpu, no_meshes.clone(), settings).0
    };
    assert!(
        image(RenderMode::Hybrid) == image(RenderMode::Raytrace),
        "hybrid without meshes differs from raytrace"
    );
    let mut thin = shipped;
    for m in &mut thin.materials {
        m.outline_width_px = m.outline_width_px.min(0.5);
    }
    assert_eq!(
        pass_names(thin, RenderMode::Raster),
        ["raster", "accumulate"]
    );
}

/// The resolve pass's tone maps and sRGB encoding follow their formulas.
/// An empty view shows the background, linear (2.0, 0.5, 0.02): clamped,
/// (1.0, 0.5, 0.02); Reinhard's c / (1 + c), (2/3, 1/3, 0.0196). Each is
/// resolved into the capture target (an sRGB format, which encodes as it
/// stores) and into an `Rgba8Unorm` target (the shader encodes, its
/// `ENCODE_SRGB` pipeline), and must be the formula's sRGB byte within 1
/// (the rounding of two 8-bit encoders). Unencoded, 0.5 would read 128
/// rather than 188.
#[test]
fn resolve_tone_maps_and_encodes_srgb_by_the_formulas() {
    use celray::gpu::readback;
    use celray::render::{Renderer, ToneMap};
    let gpu = gpu();
    let ron = r#"(version: 1,
        camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 16, height: 16),
        background: (2.0, 0.5, 0.02),
        lights: [],
        materials: { "m": (base_color: (1.0, 1.0, 1.0), model: BlinnPhong) },
        shapes: { "ball": Sphere(radius: 1.0) },
        instances: [(shape: "ball", material: "m", transform: (translate: (0.0, 0.0, 20.0)))],
    )"#;
    let scene = scene(ron);
    let background = Vec3::new(2.0, 0.5, 0.02);
    for (tone_map, linear) in [
        (ToneMap::Clamp, background.min(Vec3::ONE)),
        (ToneMap::Reinhard, background / (Vec3::ONE + background)),
    ] {
        let settings = RenderSettings {
            tone_map,
            ..pixel_centre_settings(&scene)
        };
        let mut r = Renderer::new(&gpu, scene.clone(), settings).unwrap();
        r.render_to_convergence(&gpu, |_, _| {}).unwrap();
        let unorm = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("unorm target"),
            size: wgpu::Extent3d {
                width: 16,
                height: 16,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8Unorm,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        r.resolve_into(&gpu, &mut encoder, &unorm).unwrap();
        gpu.queue.submit([encoder.finish()]);
        let expected = [srgb8(linear.x), srgb8(linear.y), srgb8(linear.z)];
        for (target, img) in [
            ("sRGB capture", r.read_srgb8(&gpu).unwrap()),
            (
                "Rgba8Unorm",
                readback::read_texture(&gpu, &unorm, 4).unwrap(),
            ),
        ] {
            for (x, y) in [(0, 0), (8, 8), (15, 15)] {
                let got = rgb_at(&img, 16, x, y);
                for ch in 0..3 {
                    let diff = (i32::from(got[ch]) - i32::from(expected[ch])).abs();
                    assert!(
                        diff <= 1,
                        "{} into {target}, pixel ({x},{y}): got {got:?}, formula {expected:?}",
                        tone_map.name()
                    );
                }
            }
        }
    }
}

/// The trace pass writes its colour into a buffer, as half floats rounded
/// toward zero by `half_bits_toward_zero` (lib/color.wgsl), and copies it
/// into the `Rgba16Float` colour texture: the bits must be those a store
/// into that texture writes, or traced images would change. Checked on the
/// GPU against a reference built without bit tricks (every finite half
/// decoded exactly, in f64; the largest one not above |x|, with x's sign),
/// over exact halves, values just above and below them, halfway points,
/// subnormals, the overflow range and pseudo-random values; and, on
/// lavapipe, against what its own texture store wrote for the same values.
#[test]
fn traced_colour_halves_are_rounded_toward_zero_as_a_texture_store_does() {
    use celray::gpu::{readback, shader};
    let gpu = gpu();
    let mut inputs: Vec<f32> = vec![
        0.0,
        -0.0,
        1.0,
        1.0 + 2f32.powi(-11),
        1.0 + 3.0 * 2f32.powi(-12),
        0.1,
        1.0 / 3.0,
        0.5 - 2f32.powi(-25),
        65504.0,
        65519.0,
        65520.0,
        65535.99,
        1.0e6,
        f32::INFINITY,
        2f32.powi(-14),
        0.75 * 2f32.powi(-14),
        2f32.powi(-24),
        1.5 * 2f32.powi(-24),
        2f32.powi(-25),
        1.0e-30,
        -2.75,
        -1.0e-6,
    ];
    let mut state = 0x1234_5678u32;
    for _ in 0..2000 {
        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        // Exponents from 2^-27 to 2^18, any significand, either sign.
        let exponent = (state >> 26) % 46;
        let bits = ((exponent + 100) << 23) | (state & 0x007f_ffff) | (state & 0x8000_0000);
        inputs.push(f32::from_bits(bits));
    }
    let n = inputs.len() as u32;

    // The reference: the finite halves in increasing order, decoded exactly.
    let decode = |h: u16| {
        let e = i32::from((h >> 10) & 0x1f);
        let m = f64::from(h & 0x3ff);
        if e == 0 {
            m * 2f64.powi(-24)
        } else {
            (1.0 + m / 1024.0) * 2f64.powi(e - 15)
        }
    };
    let positives: Vec<(u16, f64)> = (0u16..0x7c00).map(|h| (h, decode(h))).collect();
    let reference = |x: f32| -> u16 {
        let sign = if x.is_sign_negative() { 0x8000 } else { 0 };
        if x.is_infinite() {
            return sign | 0x7c00;
        }
        let a = f64::from(x.abs());
        let k = positives.partition_point(|&(_, v)| v <= a);
        sign | positives[k - 1].0
    };

    let source = format!(
        "{}\n{}\n{}",
        shader::compose("lib/types.wgsl").unwrap(),
        shader::compose("lib/color.wgsl").unwrap(),
        r#"
@group(0) @binding(0) var<storage, read> inputs: array<f32>;
@group(0) @binding(1) var<storage, read_write> bits: array<u32>;
@group(0) @binding(2) var stored: texture_storage_2d<rgba16float, write>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) g: vec3<u32>) {
    let i = g.x;
    if i >= arrayLength(&inputs) {
        return;
    }
    bits[i] = half_bits_toward_zero(inputs[i]);
    textureStore(stored, vec2<i32>(i32(i), 0), vec4<f32>(inputs[i]));
}
"#
    );
    let device = &gpu.device;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("half test"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("half test"),
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    let input_buffer = wgpu::util::DeviceExt::create_buffer_init(
        device,
        &wgpu::util::BufferInitDescriptor {
            label: Some("inputs"),
            contents: bytemuck::cast_slice(&inputs),
            usage: wgpu::BufferUsages::STORAGE,
        },
    );
    let bits_buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("bits"),
        size: u64::from(n) * 4,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("stored"),
        size: wgpu::Extent3d {
            width: n,
            height: 1,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba16Float,
        usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let view = texture.create_view(&Default::default());
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("half test"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: input_buffer.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: bits_buffer.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::TextureView(&view),
            },
        ],
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(n.div_ceil(64), 1, 1);
    }
    gpu.queue.submit([encoder.finish()]);
    let bits = readback::copy_and_read(&gpu, &bits_buffer, u64::from(n) * 4, "bits").unwrap();
    let bits: &[u32] = bytemuck::cast_slice(&bits);
    let texels = readback::read_texture(&gpu, &texture, 8).unwrap();
    let stored: &[u16] = bytemuck::cast_slice(&texels);
    let lavapipe = gpu.summary.name.contains("llvmpipe");
    for (i, &x) in inputs.iter().enumerate() {
        let want = reference(x);
        assert_eq!(
            bits[i],
            u32::from(want),
            "half_bits_toward_zero({x:e}) = {:#06x}, want {want:#06x}",
            bits[i]
        );
        if lavapipe {
            assert_eq!(
                stored[4 * i],
                want,
                "lavapipe stored {x:e} as {:#06x}, the function gives {want:#06x}",
                stored[4 * i]
            );
        }
    }
}

/// A warm-up renders a 16 x 16 image of the view's scene; where no keys
/// say which accumulate tiles the view will use, it takes those of the
/// view's own size (`Renderer::use_tiles_of_size`): with 3 px outlines,
/// 16 px tiles for 3840 x 2160 (129,600 tiles of 8 px, past one
/// dispatch's 65,535), 8 px for 1280 x 720. A sample drawn with the
/// larger tiles over a 16 x 16 image marks one tile.
#[test]
fn a_small_warm_up_draws_with_a_large_views_tiles() {
    let gpu = gpu();
    let scene = scene(&outlined_sphere(16, 16, 3.0));
    let settings = pixel_centre_settings(&scene);
    let mut r = celray::render::Renderer::new(&gpu, scene, settings).unwrap();
    assert_eq!(r.outline_tile_px(), 8, "its own size");
    r.use_tiles_of_size(3840, 2160);
    assert_eq!(r.outline_tile_px(), 16, "a 4K view's");
    r.render_sample(&gpu).unwrap();
    assert_eq!(r.read_outline_tile_marks(&gpu).unwrap().len(), 1);
    r.use_tiles_of_size(1280, 720);
    assert_eq!(r.outline_tile_px(), 8, "a 720p view's");
}

/// The raster pass does not clear its normal + depth target (a clear is a
/// pass over the image's memory on lavapipe), so where nothing is drawn
/// the target keeps an earlier sample's values. Every reader (outline
/// marks, accumulate, reproject, the hybrid trace pass) must read a
/// texel's normal and depth only where its id is not 0. Here a renderer
/// first fills the whole target with the floor (a camera that sees no
/// sky), then turns to a view with sky around outlined objects; its image
/// must equal, byte for byte, that of a fresh renderer (whose target was
/// zeroed) at the second view, in raster and in hybrid mode.
#[test]
fn a_stale_normal_depth_target_changes_no_pixel() {
    let gpu = gpu();
    let mut scene = celray::scene::Scene::builtin_default();
    scene.camera.width = 96;
    scene.camera.height = 54;
    let mut floor_only = scene.camera.clone();
    floor_only.eye = Vec3::new(0.0, 1.5, 3.0);
    floor_only.target = Vec3::new(0.0, 0.0, 0.0);
    let mut with_sky = scene.camera.clone();
    with_sky.eye = Vec3::new(0.0, 0.3, 5.0);
    with_sky.target = Vec3::new(0.0, 1.0, 0.0);
    for mode in [RenderMode::Raster, RenderMode::Hybrid] {
        let settings = RenderSettings {
            mode,
            spp: 4,
            seed: 3,
            ..pixel_centre_settings(&scene)
        };
        let mut reused =
            celray::render::Renderer::new(&gpu, scene.clone(), settings.clone()).unwrap();
        reused.set_camera(floor_only.clone());
        reused.render_to_convergence(&gpu, |_, _| {}).unwrap();
        let ids = reused.read_ids(&gpu).unwrap();
        assert!(
            ids.iter().all(|&id| id != 0),
            "{}: the first view must cover every pixel",
            mode.name()
        );
        reused.set_camera(with_sky.clone());
        reused.render_to_convergence(&gpu, |_, _| {}).unwrap();

        let mut fresh_scene = scene.clone();
        fresh_scene.camera = with_sky.clone();
        let fresh = rendered(&gpu, fresh_scene, settings.clone());
        let ids = fresh.read_ids(&gpu).unwrap();
        let sky = ids.iter().filter(|&&id| id == 0).count();
        // At least a fifth of the image is sky, next to the objects'
        // outlines: where the reused renderer's target still holds floor.
        assert!(
            sky * 5 >= ids.len() && sky < ids.len(),
            "{}: {sky} of {} pixels are sky",
            mode.name(),
            ids.len()
        );
        if mode == RenderMode::Raster {
            // The stale values are there to be misread (raster mode reads
            // back the raster target): sky texels that differ between the
            // two renderers' targets.
            let (a, b) = (
                reused.read_normal_depth(&gpu).unwrap(),
                fresh.read_normal_depth(&gpu).unwrap(),
            );
            let stale = (0..ids.len())
                .filter(|&i| ids[i] == 0 && a[i] != b[i])
                .count();
            assert!(stale * 2 >= sky, "only {stale} of {sky} sky texels differ");
        }
        assert_eq!(reused.read_ids(&gpu).unwrap(), ids, "{}", mode.name());
        assert!(
            reused.read_srgb8(&gpu).unwrap() == fresh.read_srgb8(&gpu).unwrap(),
            "{}: the image depends on stale normal + depth texels",
            mode.name()
        );
    }
}

/// Raster mode writes each fragment's id into the colour target's alpha, a
/// half float, and draws no id target, where the scene has at most
/// `MAX_IDS_IN_COLOR` (2,048) instances and temporal reprojection is off
/// (`raster::ids_in_color`). A half holds every integer up to 2,048
/// exactly (11 significant bits), so a grid of exactly 2,048 outlined
/// spheres must give the same ids, outline marks, sums (bit for bit) and
/// image as the same still frames drawn with the id target (temporal
/// reprojection on: with the camera still no reproject pass runs), and
/// the last sphere's id, 2,048, must be among them. Ids past 2,048 would
/// round to even halves (2,049 reads 2,048), so one instance more takes
/// the id target.
#[test]
fn raster_ids_in_the_colour_alpha_match_the_id_target() {
    use celray::render::raster::{ids_in_color, MAX_IDS_IN_COLOR};
    use celray::render::Temporal;

    let gpu = gpu();
    // 64 x 32 spheres 1 unit apart fill a 2:1 view 44 units away (half of
    // the 32 rows over tan 20 degrees), about 8 px a sphere at 512 x 256.
    let (cols, rows) = (64, 32);
    assert_eq!(cols * rows, MAX_IDS_IN_COLOR);
    let mut instances = String::new();
    for j in 0..rows {
        for i in 0..cols {
            let (x, y) = (i as f32 - 31.5, j as f32 - 15.5);
            let m = ["a", "b"][(i + j) % 2];
            instances += &format!(
                "(shape: \"ball\", material: \"{m}\", transform: (translate: ({x}, {y}, 0.0))),\n"
            );
        }
    }
    let grid = scene(&format!(
        r#"(
            version: 1,
            camera: (eye: (0.0, 0.0, 44.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 512, height: 256),
            lights: [Directional(direction: (-0.3, -0.5, -1.0), color: (1.0, 1.0, 1.0), intensity: 1.0)],
            materials: {{
                "a": (base_color: (0.8, 0.2, 0.1), model: Toon(bands: 3), outline_width_px: 1.5),
                "b": (base_color: (0.1, 0.3, 0.8), model: BlinnPhong, outline_width_px: 1.5),
            }},
            shapes: {{ "ball": Sphere(radius: 0.4) }},
            instances: [{instances}],
        )"#
    ));
    let with = |temporal| RenderSettings {
        spp: 2,
        mode: RenderMode::Raster,
        temporal,
        ..pixel_centre_settings(&grid)
    };
    let (alpha, target) = (with(Temporal::Off), with(Temporal::Reproject));
    assert!(ids_in_color(MAX_IDS_IN_COLOR, &alpha));
    assert!(!ids_in_color(MAX_IDS_IN_COLOR + 1, &alpha));
    assert!(!ids_in_color(MAX_IDS_IN_COLOR, &target));
    let run = |settings: RenderSettings| {
        let r = rendered(&gpu, grid.clone(), settings);
        (
            r.read_ids(&gpu).unwrap(),
            r.read_outline_tile_words(&gpu).unwrap(),
            accumulator_bits(&gpu, &r),
            r.read_srgb8(&gpu).unwrap(),
        )
    };
    let (a, b) = (run(alpha), run(target));
    let shown: BTreeSet<u32> = b.0.iter().copied().collect();
    assert!(
        shown.contains(&(MAX_IDS_IN_COLOR as u32)) && shown.contains(&0),
        "the id target shows the background and the last sphere"
    );
    assert_eq!(shown.len(), MAX_IDS_IN_COLOR + 1, "every sphere is seen");
    assert!(a.0 == b.0, "the ids differ");
    assert!(a.1 == b.1, "the outline marks differ");
    assert!(a.2 == b.2, "the accumulator's sums differ");
    assert!(a.3 == b.3, "the 8-bit images differ");
}
