//! Accumulation-buffer effects on lavapipe against closed forms:
//! anti-aliased edge coverage, the thin-lens circle of confusion, motion
//! streak length, and glossy blur growing with roughness.

mod common;

use celray::fixtures::slanted_card;
use celray::render::{RenderMode, RenderSettings};
use celray::sampling::PixelPattern;
use common::*;
use glam::{DVec2, Vec2};

/// Area of the unit pixel square [x, x+1] x [y, y+1] on the side of the line
/// a*px + b*py + c >= 0, by clipping the square against the half-plane.
fn covered_area(x: f64, y: f64, a: f64, b: f64, c: f64) -> f64 {
    let square = [
        DVec2::new(x, y),
        DVec2::new(x + 1.0, y),
        DVec2::new(x + 1.0, y + 1.0),
        DVec2::new(x, y + 1.0),
    ];
    let f = |p: DVec2| a * p.x + b * p.y + c;
    let mut poly = Vec::new();
    for i in 0..4 {
        let (p, q) = (square[i], square[(i + 1) % 4]);
        let (fp, fq) = (f(p), f(q));
        if fp >= 0.0 {
            poly.push(p);
        }
        if (fp >= 0.0) != (fq >= 0.0) {
            poly.push(p + (q - p) * (fp / (fp - fq)));
        }
    }
    let n = poly.len();
    (0..n)
        .map(|i| poly[i].perp_dot(poly[(i + 1) % n]))
        .sum::<f64>()
        .abs()
        * 0.5
}

/// The card's right edge (object x = 1) in image pixels, as the line
/// a*x + b*y + c = 0 with the white (uncovered) side positive, and its two
/// end points, projected by the unjittered pinhole camera.
fn card_edge(scene: &celray::scene::Scene) -> ((f64, f64, f64), DVec2, DVec2) {
    let (w, h) = (scene.camera.width, scene.camera.height);
    let m = scene.instances[0].world_from_object;
    let depth = celray::render::camera::depth_range(&scene.camera, scene.bounds());
    let cam = celray::render::camera::sample_camera(
        &scene.camera,
        (w, h),
        Vec2::splat(0.5),
        Vec2::ZERO,
        depth,
    );
    let to_px = |p: glam::Vec3| {
        let c = cam.clip_from_world * m.transform_point3(p).extend(1.0);
        DVec2::new(
            (f64::from(c.x / c.w) + 1.0) * 0.5 * f64::from(w),
            (1.0 - f64::from(c.y / c.w)) * 0.5 * f64::from(h),
        )
    };
    let (p, q) = (
        to_px(glam::Vec3::new(1.0, 0.0, -1.0)),
        to_px(glam::Vec3::new(1.0, 0.0, 1.0)),
    );
    let centre = to_px(glam::Vec3::ZERO);
    let (mut a, mut b) = (q.y - p.y, p.x - q.x);
    let mut c = -(a * p.x + b * p.y);
    if a * centre.x + b * centre.y + c > 0.0 {
        (a, b, c) = (-a, -b, -c);
    }
    ((a, b, c), p, q)
}

/// Linear luminance (red channel) of pixel (x, y).
fn lum(linear: &[f32], w: u32, x: u32, y: u32) -> f64 {
    f64::from(linear[((y * w + x) * 4) as usize])
}

/// A white background and a black quad whose edge crosses the image at a
/// slant: each pixel cut by the edge converges to its uncovered fraction.
/// 256 jittered samples (16 x 16 strata): only the strata the edge cuts add
/// variance, at most 2 x 16 of them with Bernoulli variance <= 1/4 each and
/// weight 1/256, so the standard deviation is at most sqrt(32/4)/256 = 0.011;
/// the tolerance 0.045 is four of those.
#[test]
fn edge_pixels_converge_to_their_covered_fraction() {
    let gpu = gpu();
    let scene = slanted_card(64, 1.0, 20.0).unwrap();
    let (w, h) = (64u32, 64u32);
    for mode in [RenderMode::Raster, RenderMode::Hybrid] {
        let settings = RenderSettings {
            mode,
            spp: 256,
            pattern: PixelPattern::Jittered,
            ..pixel_centre_settings(&scene)
        };
        let r = rendered(&gpu, scene.clone(), settings);
        let linear = r.read_linear(&gpu).unwrap();
        let ((a, b, c), p, q) = card_edge(&scene);
        let mut checked = 0;
        // Rows well inside the edge segment, away from the card's other edges.
        let (y0, y1) = (p.y.min(q.y) + 3.0, p.y.max(q.y) - 3.0);
        for y in (y0.max(1.0) as u32)..(y1.min(f64::from(h) - 1.0) as u32) {
            for x in 4..w - 4 {
                let white = covered_area(f64::from(x), f64::from(y), a, b, c);
                if white > 0.05 && white < 0.95 {
                    let got = lum(&linear, w, x, y);
                    assert!(
                        (got - white).abs() < 0.045,
                        "{mode:?} pixel ({x},{y}): {got:.3}, covered {white:.3}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 20, "{mode:?}: only {checked} edge pixels");
    }
}

/// Intensity-weighted centroid and mean squared distance from it.
fn moments(linear: &[f32], w: u32, h: u32, region: (u32, u32, u32, u32)) -> (DVec2, f64) {
    let (mut sum, mut c) = (0.0, DVec2::ZERO);
    for y in region.1..region.3.min(h) {
        for x in region.0..region.2.min(w) {
            let v = lum(linear, w, x, y);
            sum += v;
            c += DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5) * v;
        }
    }
    c /= sum;
    let mut m2 = 0.0;
    for y in region.1..region.3.min(h) {
        for x in region.0..region.2.min(w) {
            m2 += lum(linear, w, x, y)
                * (DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5) - c).length_squared();
        }
    }
    (c, m2 / sum)
}

/// Thin lens: a point at depth d seen through an aperture of radius R focused
/// at F spreads into a disk of radius R |1/F - 1/d| / tan(fov/2) * H/2 pixels
/// (the sheared projection moves it by that much per unit of lens offset).
/// A uniform disk of radius r blurred over a small sphere image of radius s
/// has mean squared radius (r^2 + s^2) / 2, which gives r from the image.
/// Tolerance 1 px. A sphere on the focal plane stays sharp (r ~ 0).
#[test]
fn defocused_sphere_spreads_into_the_circle_of_confusion() {
    let gpu = gpu();
    let ron = r#"(version: 1,
        camera: (eye: (0.0, 0.0, 0.0), target: (0.0, 0.0, -1.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 240, height: 160,
                 aperture_radius: 0.15, focus_distance: 8.0),
        ambient: (1.0, 1.0, 1.0), background: (0.0, 0.0, 0.0),
        lights: [],
        materials: { "glow": (base_color: (1.0, 1.0, 1.0), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong) },
        shapes: { "dot": Sphere(radius: 0.03) },
        instances: [
            (shape: "dot", material: "glow", transform: (translate: (-0.8, 0.0, -4.0))),
            (shape: "dot", material: "glow", transform: (translate: (2.4, 0.0, -8.0), scale: (2.0, 2.0, 2.0))),
        ],
    )"#;
    let scene = scene(ron);
    let (w, h) = (240u32, 160u32);
    let tan_half = (15.0f64).to_radians().tan();
    let px = |world_radius: f64, depth: f64| world_radius / depth / tan_half * f64::from(h) / 2.0;
    for mode in [RenderMode::Raster, RenderMode::Hybrid] {
        let settings = RenderSettings {
            mode,
            spp: 256,
            ..pixel_centre_settings(&scene)
        };
        let r = rendered(&gpu, scene.clone(), settings);
        let linear = r.read_linear(&gpu).unwrap();
        // Near sphere (d = 4) in the left half, focused sphere (d = 8) right.
        let (_, m2_near) = moments(&linear, w, h, (0, 0, w / 2, h));
        let s_near = px(0.03, 4.0);
        let r_expected = 0.15 * (1.0 / 8.0 - 1.0 / 4.0f64).abs() / tan_half * f64::from(h) / 2.0;
        let r_measured = (2.0 * m2_near - s_near * s_near).max(0.0).sqrt();
        assert!(
            (r_measured - r_expected).abs() <= 1.0,
            "{mode:?}: circle of confusion {r_measured:.2} px, thin lens says {r_expected:.2}"
        );
        let (_, m2_far) = moments(&linear, w, h, (w / 2, 0, w, h));
        let s_far = px(0.06, 8.0);
        let r_far = (2.0 * m2_far - s_far * s_far).max(0.0).sqrt();
        assert!(
            r_far <= 1.0,
            "{mode:?}: the sphere on the focal plane blurs by {r_far:.2} px"
        );
    }
}

/// A sphere moving 1 unit across the view over the shutter, 5 units away:
/// its centre travels L = 1 / 5 / tan(15 deg) * H/2 pixels. Along its path the
/// streak's profile rises over one sphere diameter at each end and is flat
/// between, so the half-maximum points are exactly L apart (tolerance 1 px),
/// and the middle third is flat. A still sphere keeps a sharp edge.
#[test]
fn moving_sphere_leaves_a_streak_of_its_projected_length() {
    let gpu = gpu();
    let ron = r#"(version: 1,
        camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 240, height: 160,
                 shutter_open_s: 0.0, shutter_close_s: 0.02),
        ambient: (1.0, 1.0, 1.0), background: (0.0, 0.0, 0.0),
        lights: [],
        materials: { "glow": (base_color: (1.0, 1.0, 1.0), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong) },
        shapes: { "ball": Sphere(radius: 0.1) },
        instances: [
            (shape: "ball", material: "glow", transform: (translate: (-0.8, 0.3, 0.0)), transform_end: (translate: (0.2, 0.3, 0.0))),
            (shape: "ball", material: "glow", transform: (translate: (0.8, -0.5, 0.0))),
        ],
    )"#;
    let scene = scene(ron);
    let (w, h) = (240u32, 160u32);
    let tan_half = (15.0f64).to_radians().tan();
    let streak = 1.0 / 5.0 / tan_half * f64::from(h) / 2.0;
    for mode in [RenderMode::Raster, RenderMode::Hybrid] {
        let settings = RenderSettings {
            mode,
            spp: 256,
            ..pixel_centre_settings(&scene)
        };
        let r = rendered(&gpu, scene.clone(), settings);
        let linear = r.read_linear(&gpu).unwrap();
        // The moving sphere's row: y of its centre, projected.
        let row = (f64::from(h) / 2.0 - 0.3 / 5.0 / tan_half * f64::from(h) / 2.0) as u32;
        let profile: Vec<f64> = (0..w).map(|x| lum(&linear, w, x, row)).collect();
        let peak = profile[..w as usize / 2 + 20]
            .iter()
            .cloned()
            .fold(0.0, f64::max);
        let half = peak / 2.0;
        let crossing = |range: Box<dyn Iterator<Item = usize>>| {
            let mut prev: Option<usize> = None;
            for x in range {
                if let Some(p) = prev {
                    let (a, b) = (profile[p], profile[x]);
                    if (a < half) != (b < half) {
                        // Linear interpolation between the pixel centres.
                        return p as f64 + 0.5 + (x as f64 - p as f64) * (half - a) / (b - a);
                    }
                }
                prev = Some(x);
            }
            f64::NAN
        };
        let left = crossing(Box::new(0..w as usize));
        let right = crossing(Box::new((0..w as usize / 2 + 30).rev()));
        assert!(
            ((right - left) - streak).abs() <= 1.0,
            "{mode:?}: streak {:.2} px between half-maximum points, projection says {streak:.2}",
            right - left
        );
        // Flat middle: the middle third of the streak within 0.05 of its mean
        // (each pixel there is covered for the same fraction of the shutter;
        // 256 stratified times leave an error well under 0.02).
        let third = ((right - left) / 3.0) as usize;
        let mid: Vec<f64> = profile[left as usize + third..right as usize - third].to_vec();
        let mean = mid.iter().sum::<f64>() / mid.len() as f64;
        assert!(
            mid.iter().all(|v| (v - mean).abs() < 0.05),
            "{mode:?}: streak middle not flat: {mid:?}"
        );
        // The still sphere: its edge rises from 10% to 90% within 2 px.
        let still_row = (f64::from(h) / 2.0 + 0.5 / 5.0 / tan_half * f64::from(h) / 2.0) as u32;
        let still: Vec<f64> = (w / 2..w).map(|x| lum(&linear, w, x, still_row)).collect();
        let first_10 = still.iter().position(|&v| v > 0.1).unwrap();
        let first_90 = still.iter().position(|&v| v > 0.9).unwrap();
        assert!(
            first_90 - first_10 <= 2,
            "{mode:?}: still sphere edge spans {} px",
            first_90 - first_10
        );
    }
}

/// A glossy floor reflecting a black/white wall edge: the reflected edge's
/// 10-90% width grows with roughness, and roughness 0 is a mirror (its
/// reflected edge is as sharp as anti-aliasing allows).
#[test]
fn glossy_blur_grows_with_roughness() {
    let gpu = gpu();
    let widths: Vec<f64> = [0.0, 0.1, 0.3]
        .iter()
        .map(|roughness| {
            let ron = format!(
                r#"(version: 1,
                    camera: (eye: (0.0, 0.6, 4.0), target: (0.0, 0.2, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 160, height: 120),
                    ambient: (1.0, 1.0, 1.0), background: (0.0, 0.0, 0.0),
                    lights: [],
                    materials: {{
                        "floor": (base_color: (0.0, 0.0, 0.0), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong, reflectivity: 1.0, roughness: {roughness}),
                        "white": (base_color: (1.0, 1.0, 1.0), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong),
                    }},
                    shapes: {{ "floor": Plane(Quad(half_size: (20.0, 20.0))), "panel": Plane(Quad(half_size: (2.0, 1.0))) }},
                    instances: [
                        (shape: "floor", material: "floor"),
                        (shape: "panel", material: "white", transform: (translate: (2.0, 1.0, -1.0), rotate_deg: (90.0, 0.0, 0.0))),
                    ],
                )"#
            );
            let scene = scene(&ron);
            let settings = RenderSettings { mode: RenderMode::Raytrace, spp: 128, ..pixel_centre_settings(&scene) };
            let r = rendered(&gpu, scene.clone(), settings);
            let linear = r.read_linear(&gpu).unwrap();
            // A row through the reflection (below the horizon, on the floor):
            // the white panel's reflected left edge at x = 0.
            let y = 100;
            let profile: Vec<f64> = (0..160).map(|x| lum(&linear, 160, x, y)).collect();
            let p10 = profile.iter().position(|&v| v > 0.1).expect("reflection visible");
            let p90 = profile.iter().position(|&v| v > 0.9 * profile[159]).expect("reflection visible");
            (p90 - p10) as f64
        })
        .collect();
    assert!(
        widths[0] <= 2.0,
        "roughness 0 should be a mirror, edge width {}",
        widths[0]
    );
    assert!(
        widths[1] > widths[0] && widths[2] > widths[1],
        "edge widths should grow with roughness: {widths:?}"
    );
}

/// Scene fields of the effects: f-number with focal length gives the
/// aperture radius f / (2N) (50 mm at f/2.8: 8.93 mm), and a moving
/// instance's transform at mid-shutter has the mean translation, the mean
/// scale and the half-way rotation.
#[test]
fn lens_and_motion_fields_parse_to_their_physical_meaning() {
    let ron = r#"(version: 1,
        camera: (eye: (1.6, -1.5, 1.0), target: (0.0, 4.0, 0.5), up: (0.0, 0.0, 1.0), fov_y_deg: 23.0, width: 64, height: 36,
                 f_number: 2.8, focal_length_mm: 50.0, focus_distance: 5.75, aperture: Polygon(blades: 6, rotation_deg: 10.0),
                 shutter_open_s: 0.0, shutter_close_s: 0.01, eye_end: (1.7, -1.5, 1.0)),
        lights: [],
        materials: { "m": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong) },
        shapes: { "ball": Sphere(radius: 0.5) },
        instances: [(shape: "ball", material: "m", transform: (translate: (0.0, 7.0, 0.5), rotate_deg: (0.0, 0.0, 0.0), scale: (1.0, 1.0, 1.0)),
                     transform_end: (translate: (1.0, 7.0, 0.5), rotate_deg: (0.0, 0.0, 90.0), scale: (2.0, 2.0, 2.0)))],
    )"#;
    let scene = scene(ron);
    assert!(
        (scene.camera.aperture_radius - 0.05 / 5.6).abs() < 1e-6,
        "{}",
        scene.camera.aperture_radius
    );
    assert!((scene.camera.at(0.5).eye.x - 1.65).abs() < 1e-6);
    let mid = scene.instances[0].world_from_object_at(0.5);
    let (scale, rotation, translation) = mid.to_scale_rotation_translation();
    assert!((translation - glam::Vec3::new(0.5, 7.0, 0.5)).length() < 1e-5);
    assert!((scale - glam::Vec3::splat(1.5)).length() < 1e-5);
    let (axis, angle) = rotation.to_axis_angle();
    assert!(
        (angle - std::f32::consts::FRAC_PI_4).abs() < 1e-4 && axis.z > 0.999,
        "{axis} {angle}"
    );
}

/// RMS error of edge pixels against their exact coverage, for a pattern
/// and sample count (raster mode, 128 x 128, the slanted card edge).
fn edge_rms_error(gpu: &celray::gpu::Gpu, pattern: PixelPattern, spp: u32, seed: u32) -> f64 {
    let scene = slanted_card(128, 3.0, 17.0).unwrap();
    let (w, h) = (128u32, 128u32);
    let settings = RenderSettings {
        mode: RenderMode::Raster,
        spp,
        pattern,
        seed,
        ..pixel_centre_settings(&scene)
    };
    let linear = rendered(gpu, scene.clone(), settings)
        .read_linear(gpu)
        .unwrap();
    let ((a, b, c), _, _) = card_edge(&scene);
    let (mut sum, mut n) = (0.0, 0);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let white = covered_area(f64::from(x), f64::from(y), a, b, c);
            if white > 0.02 && white < 0.98 {
                sum += (lum(&linear, w, x, y) - white).powi(2);
                n += 1;
            }
        }
    }
    assert!(n > 100, "only {n} edge pixels");
    (sum / f64::from(n)).sqrt()
}

/// Least-squares slope of log(error) against log(spp).
fn log_slope(points: &[(u32, f64)]) -> f64 {
    let xs: Vec<f64> = points.iter().map(|(s, _)| f64::from(*s).ln()).collect();
    let ys: Vec<f64> = points.iter().map(|(_, e)| e.ln()).collect();
    let (mx, my) = (
        xs.iter().sum::<f64>() / xs.len() as f64,
        ys.iter().sum::<f64>() / ys.len() as f64,
    );
    let num: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let den: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    num / den
}

/// Convergence on edge pixels: independent random offsets give the Monte
/// Carlo rate, error ~ spp^-0.5; stratified (jittered) offsets converge
/// faster on an edge (only the strata the edge cuts contribute variance:
/// ~ spp^-0.75). Slopes fitted over 4..256 samples, each error the RMS over
/// 100+ edge pixels averaged over three seeds; the random slope must lie
/// within 0.15 of -0.5, and jittered must be steeper by more than 0.1.
#[test]
fn jittered_converges_faster_than_random_on_edges() {
    let gpu = gpu();
    let slope = |pattern| {
        let points: Vec<(u32, f64)> = [4u32, 16, 64, 256]
            .iter()
            .map(|&spp| {
                (
                    spp,
                    (1..=3)
                        .map(|seed| edge_rms_error(&gpu, pattern, spp, seed))
                        .sum::<f64>()
                        / 3.0,
                )
            })
            .collect();
        (log_slope(&points), points)
    };
    let (random, rp) = slope(PixelPattern::Random);
    let (jittered, jp) = slope(PixelPattern::Jittered);
    assert!(
        (random + 0.5).abs() < 0.15,
        "random slope {random:.2} ({rp:?})"
    );
    assert!(
        jittered < random - 0.1,
        "jittered slope {jittered:.2} vs random {random:.2} ({jp:?})"
    );
}

/// Bokeh takes the aperture's shape: a bright dot far out of focus, seen
/// through a 6-blade aperture, blurs into a regular hexagon, whose radius
/// r(theta) = apothem / cos(angle to the nearest edge normal) has a strong
/// 6-fold Fourier component; a disk aperture's blur has none. The radius is
/// measured along 72 directions where the 5 x 5-averaged intensity falls to
/// half its plateau; the relative 6-fold amplitude |sum r e^(6 i theta)| /
/// sum r must be within 40% of the ideal hexagon's (noise from the ~3% of
/// 1024 samples that see the dot moves each crossing by about a pixel on a
/// 56 px radius), and the disk's must stay below 30% of it.
#[test]
fn six_blade_aperture_gives_a_hexagonal_highlight() {
    let gpu = gpu();
    let six_fold = |r: &[f64]| {
        let (mut re, mut im) = (0.0, 0.0);
        for (k, v) in r.iter().enumerate() {
            let t = 6.0 * (k as f64 * 5.0).to_radians();
            re += v * t.cos();
            im += v * t.sin();
        }
        (re * re + im * im).sqrt() / r.iter().sum::<f64>()
    };
    let amplitude = |aperture: &str| {
        let ron = format!(
            r#"(version: 1,
                camera: (eye: (0.0, 0.0, 0.0), target: (0.0, 0.0, -1.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 320, height: 320,
                         aperture_radius: 0.25, focus_distance: 8.0, aperture: {aperture}),
                ambient: (1.0, 1.0, 1.0), background: (0.0, 0.0, 0.0),
                lights: [],
                materials: {{ "glow": (base_color: (1.0, 1.0, 1.0), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong) }},
                shapes: {{ "dot": Sphere(radius: 0.03) }},
                instances: [(shape: "dot", material: "glow", transform: (translate: (0.0, 0.0, -2.0)))],
            )"#
        );
        let scene = scene(&ron);
        let settings = RenderSettings {
            mode: RenderMode::Raster,
            spp: 1024,
            ..pixel_centre_settings(&scene)
        };
        let linear = rendered(&gpu, scene.clone(), settings)
            .read_linear(&gpu)
            .unwrap();
        let w = 320;
        let (c, _) = moments(&linear, w, w, (0, 0, w, w));
        let smooth = |x: u32, y: u32| {
            (0..25)
                .map(|i| lum(&linear, w, x + i % 5 - 2, y + i / 5 - 2))
                .sum::<f64>()
                / 25.0
        };
        let mut inner = Vec::new();
        for y in (c.y as u32 - 20)..(c.y as u32 + 20) {
            for x in (c.x as u32 - 20)..(c.x as u32 + 20) {
                if (DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5) - c).length() < 20.0 {
                    inner.push(lum(&linear, w, x, y));
                }
            }
        }
        let plateau = inner.iter().sum::<f64>() / inner.len() as f64;
        let radii: Vec<f64> = (0..72)
            .map(|k| {
                let dir = DVec2::from_angle(f64::from(k) * 5f64.to_radians());
                let mut r = 20.0;
                while r < 150.0
                    && smooth((c + dir * r).x as u32, (c + dir * r).y as u32) >= plateau * 0.5
                {
                    r += 0.25;
                }
                r
            })
            .collect();
        six_fold(&radii)
    };
    // The ideal hexagon's radius function, sampled the same way.
    let ideal: Vec<f64> = (0..72)
        .map(|k| {
            let a = (k as f64 * 5.0).rem_euclid(60.0) - 30.0;
            30f64.to_radians().cos() / a.to_radians().cos()
        })
        .collect();
    let ideal = six_fold(&ideal);
    let hexagon = amplitude("Polygon(blades: 6, rotation_deg: 0.0)");
    let disk = amplitude("Disk");
    assert!(
        (hexagon - ideal).abs() < 0.4 * ideal,
        "hexagon 6-fold amplitude {hexagon:.4}, ideal {ideal:.4}"
    );
    assert!(
        disk < 0.3 * ideal,
        "disk 6-fold amplitude {disk:.4} (hexagon's ideal {ideal:.4})"
    );
}

/// Aliasing: black bars 0.55 px apart (above the Nyquist rate of a 2 x 2
/// grid) on white. With 4 samples, the regular grid folds them into a
/// low-frequency moire (period 1 / (2 - 1/0.55) = 5.5 px). Low-pass the error
/// against a 1024-sample reference over 8 x 8 blocks: noise averages away,
/// aliasing does not. The accumulation buffer jitters whole frames (one
/// offset per sample for all pixels), so jittering does not remove the
/// moire but scrambles its phase: the alias is the mean of 4 unit phasors
/// with nearly uniform random phases (the 0.5 px strata span 0.91 periods),
/// whose expected length is sqrt(pi) / 4 = 0.44 of regular's. The test asks
/// for regular's low-frequency error to exceed jittered's by 1.3x or more.
#[test]
fn regular_sampling_aliases_where_jittered_does_not() {
    let gpu = gpu();
    // At 4 units with a 30 degree field of view over 128 px, a pixel spans
    // 2 * 4 * tan(15 deg) / 128 = 0.01675 units.
    let pixel = 2.0 * 4.0 * 15f64.to_radians().tan() / 128.0;
    let period = 0.55 * pixel;
    let bars: String = (0..260)
        .map(|i| {
            format!(
                "(shape: \"bar\", material: \"black\", transform: (translate: ({:.6}, 0.0, 0.0), rotate_deg: (90.0, 0.0, 0.0))),\n",
                (f64::from(i) - 130.0) * period
            )
        })
        .collect();
    let ron = format!(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 4.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: 128, height: 128),
            ambient: (0.0, 0.0, 0.0), background: (1.0, 1.0, 1.0),
            lights: [],
            materials: {{ "black": (base_color: (0.0, 0.0, 0.0), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong) }},
            shapes: {{ "bar": Plane(Quad(half_size: ({half:.6}, 1.5))) }},
            instances: [{bars}],
        )"#,
        half = period / 4.0
    );
    let scene = scene(&ron);
    let render = |pattern, spp| {
        let settings = RenderSettings {
            mode: RenderMode::Raster,
            pattern,
            spp,
            ..pixel_centre_settings(&scene)
        };
        rendered(&gpu, scene.clone(), settings)
            .read_linear(&gpu)
            .unwrap()
    };
    let reference = render(PixelPattern::Jittered, 1024);
    let low_pass_error = |img: &[f32]| {
        let mut sum = 0.0;
        for by in 0..16u32 {
            for bx in 0..16u32 {
                let mut e = 0.0;
                for y in by * 8..by * 8 + 8 {
                    for x in bx * 8..bx * 8 + 8 {
                        e += lum(img, 128, x, y) - lum(&reference, 128, x, y);
                    }
                }
                sum += (e / 64.0).powi(2);
            }
        }
        (sum / 256.0).sqrt()
    };
    let regular = low_pass_error(&render(PixelPattern::Regular, 4));
    let jittered = low_pass_error(&render(PixelPattern::Jittered, 4));
    assert!(
        regular > 1.3 * jittered,
        "low-frequency error: regular {regular:.4}, jittered {jittered:.4}"
    );
}

/// Raster mode draws a sphere at the coarsest tessellation level whose
/// silhouette stays within `MAX_SILHOUETTE_ERROR_PX` (half a pixel) of the
/// true one. A unit sphere scaled to project to a circle of R px (centred,
/// 10 units away; R = f rho / sqrt(d^2 - rho^2), f the focal length in
/// pixels), black on white, no lights: the image's dark area is the
/// coverage of the drawn silhouette, 64 jittered samples a pixel. Every
/// level lies inside the true sphere, so the area is at most pi R^2, and
/// its silhouette lies within half a pixel of the true circle, so it is at
/// least pi R^2 less the perimeter times 0.5 px. The noise: about 2 pi R
/// pixels cut by the edge, each with standard deviation <= 1/16 (64 strata,
/// at most 8 cut, Bernoulli variance <= 1/4 each, weight 1/64), so about
/// sqrt(2 pi R) / 16 px^2 in all, under 2 px^2 at R = 100: the tolerance is
/// 8 px^2.
///
/// The level: a level with n segments reaches r (1 - cos(sqrt(2) pi / n))
/// inside the sphere (the circumradius of an equatorial triangle, half the
/// diagonal of a square 2 pi / n a side), 0.0383 r, 0.0096 r, 0.0024 r and
/// 0.0006 r for 16, 32, 64 and 128, so R = 10 px takes 16 segments (0.38
/// px), R = 40 px 32 (0.38 px; 16 would stray 1.5 px) and R = 100 px 64
/// (0.24 px; 32 would stray 0.96 px).
#[test]
fn raster_spheres_are_drawn_at_the_coarsest_level_within_half_a_pixel() {
    use celray::scene::SPHERE_LEVELS;
    let gpu = gpu();
    let (size, d) = (256u32, 10.0f64);
    let f = f64::from(size) / 2.0 / 20.0f64.to_radians().tan();
    for (r_px, segments) in [(10.0f64, 16u32), (40.0, 32), (100.0, 64)] {
        let rho = r_px * d / (f * f + r_px * r_px).sqrt();
        let ron = format!(
            r#"(version: 1,
            camera: (eye: (0.0, 0.0, {d}), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: {size}, height: {size}),
            ambient: (0.0, 0.0, 0.0), background: (1.0, 1.0, 1.0),
            lights: [],
            materials: {{ "ink": (base_color: (0.0, 0.0, 0.0), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong, outline_width_px: 0.0) }},
            shapes: {{ "ball": Sphere(radius: 1.0) }},
            instances: [(shape: "ball", material: "ink", transform: (rotate_deg: (20.0, 30.0, 0.0), scale: ({rho}, {rho}, {rho})))],
        )"#
        );
        let scene = scene(&ron);
        let settings = RenderSettings {
            mode: RenderMode::Raster,
            spp: 64,
            pattern: PixelPattern::Jittered,
            ..pixel_centre_settings(&scene)
        };
        let r = rendered(&gpu, scene, settings);
        let drawn = r.raster_levels(0);
        assert_eq!(drawn.len(), 1, "one draw");
        assert_eq!(
            SPHERE_LEVELS[drawn[0]], segments,
            "R = {r_px} px: drawn at {} segments",
            SPHERE_LEVELS[drawn[0]]
        );
        let linear = r.read_linear(&gpu).unwrap();
        let covered: f64 = (0..size)
            .flat_map(|y| (0..size).map(move |x| (x, y)))
            .map(|(x, y)| 1.0 - lum(&linear, size, x, y))
            .sum();
        let (disk, perimeter) = (
            std::f64::consts::PI * r_px * r_px,
            2.0 * std::f64::consts::PI * r_px,
        );
        let bound = perimeter * f64::from(celray::scene::MAX_SILHOUETTE_ERROR_PX);
        assert!(
            covered <= disk + 8.0 && covered >= disk - bound - 8.0,
            "R = {r_px} px: covers {covered:.1} px^2; the true disk {disk:.1}, at least {:.1}",
            disk - bound
        );
    }
}

/// The raster pass draws front to back (the nearest draw first, so hidden
/// fragments fail the depth test before they are shaded), yet keeps the
/// image the scene's order gives, exact ties included: where fragments of
/// several draws or instances have exactly the same depth, the one first in
/// the scene's order stays. Here three boxes are one box: two instances of
/// shape "a" (red, then green) and one of shape "b" (blue), the same
/// triangles under the same matrix, so their depths tie at every pixel; a
/// small ball listed last sits nearer the eye, so it is drawn first and the
/// boxes after it, backward. The red box (GPU instance 0, id 1) must win
/// every tie: drawn in the scene's order with `Less` it would; a plain
/// front-to-back sort would show blue, and drawing a draw's instances in
/// one call with `LessEqual`, green.
#[test]
fn front_to_back_raster_draws_keep_the_scene_orders_ties() {
    let gpu = gpu();
    let size = 64u32;
    let scene = scene(&format!(
        r#"(version: 1,
        camera: (eye: (0.0, 0.0, 6.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: {size}, height: {size}),
        ambient: (1.0, 1.0, 1.0), background: (0.0, 0.0, 0.0),
        lights: [],
        materials: {{
            "red": (base_color: (1.0, 0.0, 0.0), model: BlinnPhong, outline_width_px: 0.0),
            "green": (base_color: (0.0, 1.0, 0.0), model: BlinnPhong, outline_width_px: 0.0),
            "blue": (base_color: (0.0, 0.0, 1.0), model: BlinnPhong, outline_width_px: 0.0),
        }},
        shapes: {{
            "a": Box(half_extents: (1.0, 1.0, 1.0)),
            "b": Box(half_extents: (1.0, 1.0, 1.0)),
            "ball": Sphere(radius: 0.1),
        }},
        instances: [
            (shape: "a", material: "red", transform: (rotate_deg: (10.0, 20.0, 0.0))),
            (shape: "a", material: "green", transform: (rotate_deg: (10.0, 20.0, 0.0))),
            (shape: "b", material: "blue", transform: (rotate_deg: (10.0, 20.0, 0.0))),
            (shape: "ball", material: "green", transform: (translate: (1.6, 1.6, 3.0))),
        ],
    )"#
    ));
    let r = rendered_in_raster_mode(&gpu, scene);
    // Draws in the scene's shape order: a (instances 0 and 1), b (2), ball (3).
    assert_eq!(
        r.raster_sequence(0),
        vec![
            (2, 3..4, false),
            (1, 2..3, true),
            (0, 1..2, true),
            (0, 0..1, true)
        ],
        "the ball first, then the boxes backward, one instance a call"
    );
    let ids = r.read_ids(&gpu).unwrap();
    let img = r.read_srgb8(&gpu).unwrap();
    let mut box_pixels = 0;
    for (i, &id) in ids.iter().enumerate() {
        let (x, y) = (i as u32 % size, i as u32 / size);
        if id == 0 || id == 4 {
            continue; // background or the ball
        }
        box_pixels += 1;
        assert_eq!(
            id,
            1,
            "pixel ({x}, {y}) shows GPU instance {}, not the red box",
            id - 1
        );
        let [red, green, blue] = rgb_at(&img, size, x, y);
        assert!(
            red > 200 && green < 30 && blue < 30,
            "pixel ({x}, {y}) is {red}, {green}, {blue}"
        );
    }
    // The box spans about a third of the view: far more than a few pixels.
    assert!(box_pixels > 200, "only {box_pixels} box pixels");
}

/// A draw of many instances is never made backward (one call per instance):
/// 65 small boxes listed before a nearer ball go first, forward, and the
/// ball after them, though front to back would start with the ball.
#[test]
fn raster_draws_of_many_instances_go_forward() {
    let gpu = gpu();
    let boxes: Vec<String> = (0..65)
        .map(|i| {
            let (x, y) = (f64::from(i % 13) - 6.0, f64::from(i / 13) - 2.0);
            format!(r#"(shape: "a", material: "m", transform: (translate: ({x}, {y}, -4.0), scale: (0.2, 0.2, 0.2)))"#)
        })
        .collect();
    let scene = scene(&format!(
        r#"(version: 1,
        camera: (eye: (0.0, 0.0, 6.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 60.0, width: 32, height: 32),
        ambient: (1.0, 1.0, 1.0), background: (0.0, 0.0, 0.0),
        lights: [],
        materials: {{ "m": (base_color: (1.0, 1.0, 1.0), model: BlinnPhong, outline_width_px: 0.0) }},
        shapes: {{ "a": Box(half_extents: (1.0, 1.0, 1.0)), "ball": Sphere(radius: 0.5) }},
        instances: [{}, (shape: "ball", material: "m", transform: (translate: (0.0, 0.0, 2.0)))],
    )"#,
        boxes.join(", ")
    ));
    let r = rendered_in_raster_mode(&gpu, scene);
    assert_eq!(
        r.raster_sequence(0),
        vec![(0, 0..65, false), (1, 65..66, false)]
    );
}

/// One sample at each pixel centre in raster mode.
fn rendered_in_raster_mode(
    gpu: &celray::gpu::Gpu,
    scene: celray::scene::Scene,
) -> celray::render::Renderer {
    let settings = RenderSettings {
        mode: RenderMode::Raster,
        ..pixel_centre_settings(&scene)
    };
    rendered(gpu, scene, settings)
}
