//! Base-colour textures and the checker pattern on lavapipe, against the
//! UV mapping's closed form.

mod common;

use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use celray::render::camera::primary_ray;
use celray::render::{RenderMode, RenderSettings};
use celray::sampling::PixelPattern;
use celray::scene::{srgb_to_linear, Scene, MAX_TEXTURES};
use common::*;

/// A fresh folder for one test's files, removed with them when the test
/// ends.
struct TempDir(PathBuf);

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn temp_dir(test: &str) -> TempDir {
    let dir = std::env::temp_dir().join(format!("celray-textures-{test}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    TempDir(dir)
}

fn write_png(path: &Path, w: u32, h: u32, texel: impl Fn(u32, u32) -> [u8; 4]) {
    let img = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(texel(x, y)));
    img.save(path).unwrap();
}

/// Texel (x, y) of the 4x4 test image: every texel a different colour.
fn texel4(x: u32, y: u32) -> [u8; 4] {
    [
        (x * 60 + 20) as u8,
        (y * 60 + 20) as u8,
        if (x + y) % 2 == 1 { 200 } else { 40 },
        255,
    ]
}

fn load(dir: &Path, ron: &str) -> Scene {
    let path = dir.join("scene.ron");
    std::fs::write(&path, ron).unwrap();
    Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// A unit quad (half size 1) seen head-on from 4 units with a field of
/// view of 2 atan(1/2): the view is 4 units wide, the quad fills the middle
/// half of a 64 px image, 32 px, and each of its 4 texels an exact 8 px
/// block. Ambient 1 and no lights: a pixel shows its texel's colour.
fn head_on_quad(dir: &Path, material: &str, lights: &str, ambient: f32) -> Scene {
    write_png(&dir.join("t.png"), 4, 4, texel4);
    let fov = 2.0 * 0.5f64.atan().to_degrees();
    load(
        dir,
        &format!(
            "(version: 1,
              camera: (eye: (0.0, 4.0, 0.0), target: (0.0, 0.0, 0.0), up: (0.0, 0.0, -1.0),
                       fov_y_deg: {fov}, width: 64, height: 64),
              ambient: ({ambient}, {ambient}, {ambient}), background: (0.0, 0.0, 1.0),
              lights: [{lights}],
              materials: {{ \"t\": (base_color: (0.5, 0.5, 0.5), {material},
                                 base_color_texture: \"t.png\", texture_filter: Nearest) }},
              shapes: {{ \"q\": Plane(Quad(half_size: (1.0, 1.0))) }},
              instances: [(shape: \"q\", material: \"t\")])"
        ),
    )
}

/// The camera looks down -y with image up = -z: image x runs along +x and
/// image y along +z, so pixel (px, py) of the quad (pixels 16..48) shows
/// texel ((px - 16) / 8, (py - 16) / 8) by the quad's mapping
/// u = (x + 1) / 2, v = (z + 1) / 2.
fn expected_texel(px: u32, py: u32) -> Option<(u32, u32)> {
    ((16..48).contains(&px) && (16..48).contains(&py)).then(|| ((px - 16) / 8, (py - 16) / 8))
}

/// Every pixel centre shows the texel the mapping predicts, in all three
/// modes. Tolerance 1/255 per channel: sRGB decode, a float16 colour
/// target and the resolve's re-encoding round once each.
#[test]
fn head_on_quad_shows_each_texel_in_every_mode() {
    let gpu = gpu();
    let dir = temp_dir("head-on");
    let scene = head_on_quad(&dir, "model: BlinnPhong", "", 1.0);
    for mode in [RenderMode::Raster, RenderMode::Hybrid, RenderMode::Raytrace] {
        let settings = RenderSettings {
            mode,
            ..pixel_centre_settings(&scene)
        };
        let (img, _) = render(&gpu, scene.clone(), settings);
        for py in 0..64 {
            for px in 0..64 {
                let got = rgb_at(&img, 64, px, py);
                let want = match expected_texel(px, py) {
                    Some((tx, ty)) => {
                        let t = texel4(tx, ty);
                        [t[0], t[1], t[2]]
                    }
                    None => [0, 0, 255],
                };
                for c in 0..3 {
                    assert!(
                        got[c].abs_diff(want[c]) <= 1,
                        "{mode:?}: pixel ({px}, {py}) is {got:?}, expected {want:?}"
                    );
                }
            }
        }
    }
}

/// Toon on a texture: one directional light at N.L = 0.6 puts the whole
/// quad in one band of 4 even bands (thresholds 0.25, 0.5, 0.75: band 2,
/// level 3/4), and the band keeps the texture's detail: every pixel is its
/// texel's linear colour times 3/4 (no ambient, no specular colour, no
/// outline).
/// The band quantizes the light, never the texture.
#[test]
fn toon_band_keeps_texture_detail() {
    let gpu = gpu();
    let dir = temp_dir("toon");
    // Light travelling along (0.8, -0.6, 0): N.L = 0.6 on the +y quad.
    let scene = head_on_quad(
        &dir,
        "model: Toon(bands: 4), outline_width_px: 0.0, specular_color: (0.0, 0.0, 0.0)",
        "Directional(direction: (0.8, -0.6, 0.0), intensity: 1.0)",
        0.0,
    );
    let settings = RenderSettings {
        mode: RenderMode::Raster,
        ..pixel_centre_settings(&scene)
    };
    let (img, _) = render(&gpu, scene, settings);
    let mut distinct = std::collections::HashSet::new();
    for py in 16..48 {
        for px in 16..48 {
            let (tx, ty) = expected_texel(px, py).unwrap();
            let t = texel4(tx, ty);
            let want: Vec<u8> = (0..3).map(|c| srgb8(0.75 * srgb_to_linear(t[c]))).collect();
            let got = rgb_at(&img, 64, px, py);
            distinct.insert(got);
            for c in 0..3 {
                assert!(
                    got[c].abs_diff(want[c]) <= 1,
                    "pixel ({px}, {py}) is {got:?}, expected {want:?}"
                );
            }
        }
    }
    // All 16 texels stay distinguishable inside the one band.
    assert_eq!(distinct.len(), 16);
}

/// Where the primary ray through pixel centre (px, py) meets the plane y = 0.
fn plane_hit(scene: &Scene, px: f32, py: f32) -> Option<Vec3> {
    let cam = &scene.camera;
    let (o, d) = primary_ray(cam, (cam.width, cam.height), Vec2::new(px, py));
    let t = -o.y / d.y;
    (t > 0.0).then(|| o + d * t)
}

const CHECKER_A: f32 = 0.8;
const CHECKER_B: f32 = 0.2;

/// A large checker floor (cells `size` wide) seen from 1.5 units up,
/// looking 8.5 degrees down: from ~4 px per 0.05 cell at the bottom of the
/// image to many cells per pixel towards the horizon. Ambient 1, no lights:
/// a pixel shows the pattern.
fn checker_floor(size: f32) -> Scene {
    scene(&format!(
        "(version: 1,
          camera: (eye: (0.0, 1.5, 0.0), target: (0.0, 0.0, -10.0), up: (0.0, 1.0, 0.0),
                   fov_y_deg: 40.0, width: 320, height: 180),
          ambient: (1.0, 1.0, 1.0), background: (0.0, 0.0, 1.0),
          materials: {{ \"c\": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong,
              base_color_pattern: Checker(a: ({CHECKER_A}, {CHECKER_A}, {CHECKER_A}),
                                          b: ({CHECKER_B}, {CHECKER_B}, {CHECKER_B}),
                                          size: {size})) }},
          shapes: {{ \"floor\": Plane(Quad(half_size: (100.0, 100.0))) }},
          instances: [(shape: \"floor\", material: \"c\")])"
    ))
}

/// Along a pixel row, the number of colour changes equals the number of
/// cell edges x = (k + 1/2) size the row's line on the floor crosses. The
/// camera has no roll or yaw, so a row's rays meet the floor on a line of
/// constant z: the closed form is |floor(x_right / s + 1/2) -
/// floor(x_left / s + 1/2)| between the first and last pixel centres.
/// Checked on rows where a cell is at least 2 px wide (so no two edges
/// fall between neighbouring pixel centres), in raster and raytrace modes.
/// The trace pass unprojects its rays through the inverse matrix, so they
/// may differ from the CPU's by float error: a small smooth shift of the
/// edges cannot add or remove a change between the row's ends, only move
/// an edge across an end pixel's centre, so a row end whose centre lies
/// within 0.25 px of an edge allows one change more or less.
#[test]
fn checker_edges_along_a_row_match_the_projection() {
    let gpu = gpu();
    const CHECKER_SIZE: f32 = 0.05;
    let scene = checker_floor(CHECKER_SIZE);
    let (w, h) = (scene.camera.width, scene.camera.height);
    for mode in [RenderMode::Raster, RenderMode::Raytrace] {
        let settings = RenderSettings {
            mode,
            ..pixel_centre_settings(&scene)
        };
        let (img, _) = render(&gpu, scene.clone(), settings);
        let mut rows_checked = 0;
        for py in 0..h {
            let y = py as f32 + 0.5;
            let (Some(left), Some(right)) = (
                plane_hit(&scene, 0.5, y),
                plane_hit(&scene, w as f32 - 0.5, y),
            ) else {
                continue;
            };
            let cells_per_pixel = (right.x - left.x) / (w - 1) as f32 / CHECKER_SIZE;
            if cells_per_pixel > 0.5 {
                continue;
            }
            let cell = |x: f32| (x / CHECKER_SIZE + 0.5).floor() as i64;
            let expected = (cell(right.x) - cell(left.x)).unsigned_abs();
            let near_edge = |x: f32| {
                let c = x / CHECKER_SIZE + 0.5;
                (c - c.round()).abs() / cells_per_pixel < 0.25
            };
            let allowed = u64::from(near_edge(left.x)) + u64::from(near_edge(right.x));
            let bright = |px: u32| rgb_at(&img, w, px, py)[0] > 128;
            let changes = (1..w).filter(|&px| bright(px) != bright(px - 1)).count() as u64;
            assert!(
                changes.abs_diff(expected) <= allowed,
                "{mode:?}: row {py} has {changes} colour changes, the projection gives {expected}"
            );
            assert!(expected >= 10, "row {py}: too few cells to test");
            rows_checked += 1;
        }
        assert!(
            rows_checked >= 20,
            "only {rows_checked} rows were near enough"
        );
    }
}

/// Far rows converge to the mean colour, without moire. With N jittered
/// samples a pixel's value is the mean of N draws of a or b, whose variance
/// is at most (a - b)^2 / (4N); the exact pixel average itself differs
/// from (a + b) / 2 by at most (a - b) / (2 W H) where the footprint spans
/// W x H cells (the checker's signed area over a W x H rectangle is at most
/// one cell). So across a far row (W, H >= 4) of n pixels the variance of
/// the linear values is at most s2 = (a - b)^2 / (4N) + ((a - b) / (2 W H))^2
/// plus the 8-bit rounding; the sample variance of n values scatters around
/// its expectation with relative standard deviation sqrt(2 / (n - 1)), so
/// the bound allows four of those: s2 (1 + 4 sqrt(2 / (n - 1))). One sample
/// per pixel (or a moire) would give ~(a - b)^2 / 4, 60 times more.
#[test]
fn checker_far_rows_converge_to_the_mean() {
    let gpu = gpu();
    const CHECKER_SIZE: f32 = 0.02;
    let scene = checker_floor(CHECKER_SIZE);
    let (w, h) = (scene.camera.width, scene.camera.height);
    let spp = 64;
    let settings = RenderSettings {
        mode: RenderMode::Raster,
        spp,
        pattern: PixelPattern::Jittered,
        ..pixel_centre_settings(&scene)
    };
    let (img, _) = render(&gpu, scene.clone(), settings);
    let contrast = CHECKER_A - CHECKER_B;
    let mut rows_checked = 0;
    for py in 0..h - 1 {
        let y = py as f32 + 0.5;
        let (Some(left), Some(right), Some(next)) = (
            plane_hit(&scene, 0.5, y),
            plane_hit(&scene, w as f32 - 0.5, y),
            plane_hit(&scene, 0.5, y + 1.0),
        ) else {
            continue;
        };
        if left.z < -99.0 || left.x < -99.0 {
            continue; // beyond the floor's edge
        }
        let cells_w = (right.x - left.x) / (w - 1) as f32 / CHECKER_SIZE;
        let cells_h = (left.z - next.z).abs() / CHECKER_SIZE;
        if cells_w < 4.0 || cells_h < 4.0 {
            continue;
        }
        let values: Vec<f32> = (0..w)
            .map(|px| srgb_to_linear(rgb_at(&img, w, px, py)[0]))
            .collect();
        let mean = values.iter().sum::<f32>() / w as f32;
        let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / w as f32;
        // One 8-bit step near 0.5 linear is ~0.0045 in linear: rounding adds
        // at most that squared over 12.
        let scatter = 1.0 + 4.0 * (2.0 / (w - 1) as f32).sqrt();
        let bound = (contrast * contrast / (4.0 * spp as f32)
            + (contrast / (2.0 * cells_w * cells_h)).powi(2))
            * scatter
            + 0.0045f32.powi(2) / 12.0;
        assert!(
            variance < bound,
            "row {py} ({cells_w:.1} x {cells_h:.1} cells per pixel): variance {variance:.5} >= bound {bound:.5}"
        );
        let target = 0.5 * (CHECKER_A + CHECKER_B);
        assert!(
            (mean - target).abs() < bound.sqrt(),
            "row {py}: mean {mean:.4}, expected {target:.4}"
        );
        rows_checked += 1;
    }
    assert!(rows_checked >= 5, "only {rows_checked} far rows");
}

/// The sphere's longitude/latitude mapping puts a marked texel where the
/// closed form says: an 8 x 4 grey image with texel (5, 1) red covers
/// longitudes u in [5/8, 6/8) (u = atan2(z, x) / 2 pi + 1/2) and
/// v = polar angle / pi in [1/4, 2/4). The camera looks at the texel's
/// centre; a pixel is red exactly where its ray's hit point maps into the
/// texel (CPU ray-sphere intersection), except next to the texel's edge
/// (raster mode tessellates the sphere).
#[test]
fn sphere_marked_texel_lands_at_its_longitude_and_latitude() {
    let gpu = gpu();
    let dir = temp_dir("sphere");
    write_png(&dir.join("m.png"), 8, 4, |x, y| {
        if (x, y) == (5, 1) {
            [255, 0, 0, 255]
        } else {
            [128, 128, 128, 255]
        }
    });
    let (u, v) = (5.5f32 / 8.0, 1.5f32 / 4.0);
    let (phi, theta) = ((u - 0.5) * std::f32::consts::TAU, v * std::f32::consts::PI);
    let eye = 4.0
        * Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
        );
    let scene = load(
        &dir,
        &format!(
            "(version: 1,
              camera: (eye: ({}, {}, {}), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0),
                       fov_y_deg: 40.0, width: 96, height: 96),
              ambient: (1.0, 1.0, 1.0), background: (0.0, 0.0, 1.0),
              materials: {{ \"m\": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong,
                                 base_color_texture: \"m.png\", texture_filter: Nearest) }},
              shapes: {{ \"ball\": Sphere(radius: 1.0) }},
              instances: [(shape: \"ball\", material: \"m\")])",
            eye.x, eye.y, eye.z
        ),
    );
    let (w, h) = (96, 96);
    let want: Vec<bool> = (0..w * h)
        .map(|i| {
            let p = Vec2::new((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            ray_sphere(&scene, p, Vec3::ZERO, 1.0).is_some_and(|q| {
                let u = q.z.atan2(q.x) / std::f32::consts::TAU + 0.5;
                let v = q.y.clamp(-1.0, 1.0).acos() / std::f32::consts::PI;
                ((u * 8.0).floor(), (v * 4.0).floor()) == (5.0, 1.0)
            })
        })
        .collect();
    assert!(want.iter().filter(|&&r| r).count() > 100);
    for mode in [RenderMode::Raytrace, RenderMode::Raster] {
        let settings = RenderSettings {
            mode,
            ..pixel_centre_settings(&scene)
        };
        let (img, _) = render(&gpu, scene.clone(), settings);
        let got: Vec<bool> = (0..w * h)
            .map(|i| {
                let c = rgb_at(&img, w, i % w, i / w);
                c[0] > 200 && c[1] < 60
            })
            .collect();
        let bad = mismatches_off_boundary(&got, &want, w, h);
        assert!(
            bad.is_empty(),
            "{mode:?}: red where not predicted or missing at {bad:?}"
        );
    }
}

#[test]
fn texture_errors_name_the_file_and_the_material() {
    let dir = temp_dir("errors");
    let scene_with = |texture: &str| {
        format!(
            "(version: 1,
              camera: (eye: (0.0, 1.0, 4.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0),
                       fov_y_deg: 40.0, width: 32, height: 32),
              materials: {{ \"wood\": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong,
                                    base_color_texture: \"{texture}\") }},
              shapes: {{ \"q\": Plane(Quad(half_size: (1.0, 1.0))) }},
              instances: [(shape: \"q\", material: \"wood\")])"
        )
    };
    let path = dir.join("scene.ron");
    let error = |ron: &str| {
        std::fs::write(&path, ron).unwrap();
        Scene::load(&path).unwrap_err().to_string()
    };
    // A missing file.
    let e = error(&scene_with("nowhere.png"));
    assert!(e.contains("nowhere.png") && e.contains("\"wood\""), "{e}");
    // A corrupt PNG: the right signature, then garbage.
    let mut bytes = b"\x89PNG\r\n\x1a\n".to_vec();
    bytes.extend(std::iter::repeat_n(7u8, 64));
    std::fs::write(dir.join("corrupt.png"), &bytes).unwrap();
    let e = error(&scene_with("corrupt.png"));
    assert!(
        e.contains("corrupt.png") && e.contains("\"wood\"") && e.contains("decode"),
        "{e}"
    );
    // One image more than the limit: the first one over it is named.
    let mut materials = String::new();
    let mut instances = String::new();
    for i in 0..=MAX_TEXTURES {
        write_png(&dir.join(format!("t{i}.png")), 2, 2, |_, _| {
            [i as u8, 0, 0, 255]
        });
        materials.push_str(&format!(
            "\"m{i}\": (base_color: (1.0, 1.0, 1.0), model: BlinnPhong, base_color_texture: \"t{i}.png\"),"
        ));
        instances.push_str(&format!("(shape: \"q\", material: \"m{i}\"),"));
    }
    let e = error(&format!(
        "(version: 1,
          camera: (eye: (0.0, 1.0, 4.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0),
                   fov_y_deg: 40.0, width: 32, height: 32),
          materials: {{ {materials} }},
          shapes: {{ \"q\": Plane(Quad(half_size: (1.0, 1.0))) }},
          instances: [{instances}])"
    ));
    let last = format!("t{MAX_TEXTURES}.png");
    assert!(
        e.contains(&last)
            && e.contains("too many textures")
            && e.contains(&MAX_TEXTURES.to_string()),
        "{e}"
    );
    // The same image used by many materials counts once.
    let mut materials = String::new();
    for i in 0..=MAX_TEXTURES {
        materials.push_str(&format!(
            "\"m{i}\": (base_color: (1.0, 1.0, 1.0), model: BlinnPhong, base_color_texture: \"t0.png\"),"
        ));
    }
    std::fs::write(
        &path,
        format!(
            "(version: 1,
              camera: (eye: (0.0, 1.0, 4.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0),
                       fov_y_deg: 40.0, width: 32, height: 32),
              materials: {{ {materials} }},
              shapes: {{ \"q\": Plane(Quad(half_size: (1.0, 1.0))) }},
              instances: [{instances}])"
        ),
    )
    .unwrap();
    Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
}

/// A glTF quad written here: 2 triangles with TEXCOORD_1 (the material's
/// texCoord set; TEXCOORD_0 is a decoy), an 8 x 8 image embedded as a
/// data: URI and a baseColorFactor. Seen head-on as in the 4 x 4 test, the
/// UV map is affine, so every texture point is weighted alike: the mean of
/// the model's pixels is the mean of the bilinearly filtered image over one
/// period, which with repeat wrapping is the texels' mean, times the
/// factor. Sampling that at 32 x 32 pixel centres over 8 x 8 texels of a
/// piecewise-linear function adds at most a few thousandths; the bound is
/// 0.01 in linear per channel.
#[test]
fn gltf_texture_mean_colour_in_every_mode() {
    use base64::Engine;
    let gpu = gpu();
    let dir = temp_dir("gltf");
    let texel = |x: u32, y: u32| -> [u8; 4] {
        let h = (x * 7 + y * 13) % 8;
        [
            (40 + h * 25) as u8,
            (200 - h * 20) as u8,
            (90 + (x * y) % 5 * 30) as u8,
            255,
        ]
    };
    let mut png = Vec::new();
    image::RgbaImage::from_fn(8, 8, |x, y| image::Rgba(texel(x, y)))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let factor = [0.9f32, 0.6, 1.0];
    // Buffer: positions, normals, decoy uvs, uvs, indices.
    let corners = [[-1.0f32, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    let mut bin: Vec<u8> = Vec::new();
    for c in corners {
        for v in [c[0], 0.0, c[1]] {
            bin.extend(v.to_le_bytes());
        }
    }
    for _ in corners {
        for v in [0.0f32, 1.0, 0.0] {
            bin.extend(v.to_le_bytes());
        }
    }
    for _ in corners {
        for v in [0.5f32, 0.5] {
            bin.extend(v.to_le_bytes());
        }
    }
    for c in corners {
        for v in [(c[0] + 1.0) / 2.0, (c[1] + 1.0) / 2.0] {
            bin.extend(v.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend(i.to_le_bytes());
    }
    let b64 = base64::engine::general_purpose::STANDARD;
    let gltf = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
  "nodes": [{{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2, "TEXCOORD_1": 3}},
                               "indices": 4, "material": 0}}]}}],
  "materials": [{{"name": "painted", "pbrMetallicRoughness": {{
      "baseColorTexture": {{"index": 0, "texCoord": 1}}, "baseColorFactor": [{}, {}, {}, 1.0]}}}}],
  "textures": [{{"source": 0}}],
  "images": [{{"uri": "data:image/png;base64,{}"}}],
  "buffers": [{{"byteLength": {}, "uri": "data:application/octet-stream;base64,{}"}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 48}},
                  {{"buffer": 0, "byteOffset": 96, "byteLength": 32}}, {{"buffer": 0, "byteOffset": 128, "byteLength": 32}},
                  {{"buffer": 0, "byteOffset": 160, "byteLength": 12}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, 0, -1], "max": [1, 0, 1]}},
    {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"}},
    {{"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"}},
    {{"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC2"}},
    {{"bufferView": 4, "componentType": 5123, "count": 6, "type": "SCALAR"}}]}}"#,
        factor[0],
        factor[1],
        factor[2],
        b64.encode(&png),
        bin.len(),
        b64.encode(&bin)
    );
    std::fs::write(dir.join("quad.gltf"), gltf).unwrap();
    let fov = 2.0 * 0.5f64.atan().to_degrees();
    let scene = load(
        &dir,
        &format!(
            "(version: 1,
              camera: (eye: (0.0, 4.0, 0.0), target: (0.0, 0.0, 0.0), up: (0.0, 0.0, -1.0),
                       fov_y_deg: {fov}, width: 64, height: 64),
              ambient: (1.0, 1.0, 1.0), background: (0.0, 0.0, 1.0),
              materials: {{ \"m\": (base_color: (0.1, 0.1, 0.1), model: BlinnPhong) }},
              shapes: {{ \"q\": Mesh(path: \"quad.gltf\") }},
              instances: [(shape: \"q\", material: \"m\")])"
        ),
    );
    let mut want = [0.0f32; 3];
    for y in 0..8 {
        for x in 0..8 {
            for c in 0..3 {
                want[c] += srgb_to_linear(texel(x, y)[c]) * factor[c] / 64.0;
            }
        }
    }
    for mode in [RenderMode::Raster, RenderMode::Hybrid, RenderMode::Raytrace] {
        let settings = RenderSettings {
            mode,
            ..pixel_centre_settings(&scene)
        };
        let (img, _) = render(&gpu, scene.clone(), settings);
        let mut mean = [0.0f32; 3];
        for py in 16..48 {
            for px in 16..48 {
                let p = rgb_at(&img, 64, px, py);
                for c in 0..3 {
                    mean[c] += srgb_to_linear(p[c]) / 1024.0;
                }
            }
        }
        for c in 0..3 {
            assert!(
                (mean[c] - want[c]).abs() < 0.01,
                "{mode:?}: mean {mean:?}, texture mean times factor {want:?}"
            );
        }
    }
}

/// An OBJ whose .mtl names a missing map_Kd: the error names the image and
/// the OBJ material; with the image present the map is the mesh's own.
#[test]
fn obj_map_kd_is_loaded_and_a_missing_one_is_an_error() {
    let dir = temp_dir("obj");
    std::fs::write(
        dir.join("q.obj"),
        "mtllib q.mtl\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 1\nvt 1 1\nvt 1 0\nvt 0 0\n\
         usemtl brick\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("q.mtl"),
        "newmtl brick\nKd 1 1 1\nmap_Kd brick.png\n",
    )
    .unwrap();
    let ron = "(version: 1,
        camera: (eye: (0.0, 4.0, 0.0), target: (0.0, 0.0, 0.0), up: (0.0, 0.0, -1.0),
                 fov_y_deg: 40.0, width: 32, height: 32),
        materials: { \"m\": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong) },
        shapes: { \"q\": Mesh(path: \"q.obj\") },
        instances: [(shape: \"q\", material: \"m\")])";
    let path = dir.join("scene.ron");
    std::fs::write(&path, ron).unwrap();
    let e = Scene::load(&path).unwrap_err().to_string();
    assert!(e.contains("brick.png") && e.contains("\"brick\""), "{e}");

    write_png(&dir.join("brick.png"), 2, 2, |x, _| {
        [200, 50 * x as u8, 10, 255]
    });
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let celray::scene::Shape::Mesh(mesh) = &scene.shapes[0] else {
        panic!("not a mesh")
    };
    assert_eq!(mesh.textures.len(), 1);
    assert_eq!((mesh.textures[0].width, mesh.textures[0].height), (2, 2));
    assert!(mesh.vertex_textures.iter().all(|&t| t == 0));
    // OBJ's v grows upwards; celray's downwards from the top row.
    assert_eq!(mesh.uvs.len(), mesh.positions.len());
    assert!(mesh.uvs.iter().any(|uv| *uv == Vec2::new(0.0, 0.0)));
}

/// The Fox's map comes from its .glb's own buffer, the helmet's five from
/// files beside it.
#[test]
fn shipped_models_bring_their_maps() {
    let scene = Scene::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/scenes/textured_models.ron"
    )))
    .unwrap_or_else(|e| panic!("{e}"));
    let maps = |name: &str| match &scene.shapes[scene.shape_id(name).unwrap()] {
        celray::scene::Shape::Mesh(m) => (m.textures.len(), m.uvs.len() == m.positions.len()),
        _ => panic!("{name} is not a mesh"),
    };
    assert_eq!(maps("fox"), (1, true));
    assert_eq!(maps("helmet"), (5, true));
}

/// Writes `quad.gltf` in `dir`: the unit quad (x and z from -1 to 1 at
/// y = 0, facing +y) with texture coordinates running linearly from
/// (lo, lo) at (-1, -1) to (hi, hi) at (1, 1), textured with the 4x4
/// `texel4` image (a data: URI) through a sampler with the given JSON
/// fields.
fn write_sampler_quad(dir: &Path, lo: f32, hi: f32, sampler: &str) {
    use base64::Engine;
    let mut png = Vec::new();
    image::RgbaImage::from_fn(4, 4, |x, y| image::Rgba(texel4(x, y)))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let corners = [[-1.0f32, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    let mut bin: Vec<u8> = Vec::new();
    for c in corners {
        for v in [c[0], 0.0, c[1]] {
            bin.extend(v.to_le_bytes());
        }
    }
    for _ in corners {
        for v in [0.0f32, 1.0, 0.0] {
            bin.extend(v.to_le_bytes());
        }
    }
    let at = |c: f32| lo + (hi - lo) * (c + 1.0) / 2.0;
    for c in corners {
        for v in [at(c[0]), at(c[1])] {
            bin.extend(v.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend(i.to_le_bytes());
    }
    let b64 = base64::engine::general_purpose::STANDARD;
    let gltf = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
  "nodes": [{{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}},
                               "indices": 3, "material": 0}}]}}],
  "materials": [{{"name": "sampled", "pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0}}}}}}],
  "textures": [{{"source": 0, "sampler": 0}}],
  "samplers": [{{{sampler}}}],
  "images": [{{"uri": "data:image/png;base64,{}"}}],
  "buffers": [{{"byteLength": {}, "uri": "data:application/octet-stream;base64,{}"}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 48}},
                  {{"buffer": 0, "byteOffset": 96, "byteLength": 32}}, {{"buffer": 0, "byteOffset": 128, "byteLength": 12}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, 0, -1], "max": [1, 0, 1]}},
    {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"}},
    {{"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"}},
    {{"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}}]}}"#,
        b64.encode(&png),
        bin.len(),
        b64.encode(&bin)
    );
    std::fs::write(dir.join("quad.gltf"), gltf).unwrap();
}

/// The quad of [`write_sampler_quad`] (texture coordinates `lo`..`hi`,
/// glTF sampler fields `sampler`) rendered with [`sampler_quad_scene`] in
/// raster and in raytrace mode at pixel centres: (mode, RGBA8 image) each.
fn sampler_quad_renders(
    gpu: &celray::gpu::Gpu,
    tag: &str,
    lo: f32,
    hi: f32,
    sampler: &str,
) -> Vec<(RenderMode, Vec<u8>)> {
    let dir = temp_dir(tag);
    write_sampler_quad(&dir, lo, hi, sampler);
    let scene = sampler_quad_scene(&dir);
    [RenderMode::Raster, RenderMode::Raytrace]
        .into_iter()
        .map(|mode| {
            let settings = RenderSettings {
                mode,
                ..pixel_centre_settings(&scene)
            };
            (mode, render(gpu, scene.clone(), settings).0)
        })
        .collect()
}

/// The glTF quad of [`write_sampler_quad`] seen head-on from 4 units up
/// with a view 64/30 units wide in a 64 px image: the quad (2 units)
/// covers pixels 2..62 on both axes, 30 px per unit, image x along +x and
/// image y along +z. Ambient 1, no lights: a pixel shows its base colour.
fn sampler_quad_scene(dir: &Path) -> Scene {
    let fov = 2.0 * (32.0f64 / 30.0 / 4.0).atan().to_degrees();
    load(
        dir,
        &format!(
            "(version: 1,
              camera: (eye: (0.0, 4.0, 0.0), target: (0.0, 0.0, 0.0), up: (0.0, 0.0, -1.0),
                       fov_y_deg: {fov}, width: 64, height: 64),
              ambient: (1.0, 1.0, 1.0), background: (0.0, 0.0, 1.0),
              materials: {{ \"m\": (base_color: (0.1, 0.1, 0.1), model: BlinnPhong) }},
              shapes: {{ \"q\": Mesh(path: \"quad.gltf\") }},
              instances: [(shape: \"q\", material: \"m\")])"
        ),
    )
}

/// The glTF wrap rules in texel units for an image `n` texels wide: the
/// texel shown at continuous texel coordinate c (texel k spans [k, k+1)).
/// Repeat: c - n floor(c / n) (fract of u); clamp to edge: the edge texel
/// beyond the image; mirrored repeat: period 2n, the second half reflected.
fn wrapped_texel(mode: &str, c: f32, n: u32) -> u32 {
    let n = n as f32;
    let k = match mode {
        "REPEAT" => (c - n * (c / n).floor()).floor(),
        "CLAMP_TO_EDGE" => c.floor().clamp(0.0, n - 1.0),
        "MIRRORED_REPEAT" => {
            let m = c - 2.0 * n * (c / (2.0 * n)).floor();
            if m < n {
                m.floor()
            } else {
                (2.0 * n - m).floor()
            }
        }
        _ => unreachable!(),
    };
    k as u32
}

/// glTF sampler wrap modes: texture coordinates run from -1 to 2 across
/// the quad, so the 4x4 image spans 12 texel cells of 5 px each, cell i
/// covering pixels 2 + 5i .. 7 + 5i. Each cell's middle pixel centre lies
/// on the cell's texel centre (continuous texel coordinate i - 4 + 1/2), so
/// even the default bilinear filter shows one texel there: the one the
/// glTF rule (wrapped_texel) predicts, in raster and raytrace. The three
/// cases give every mode on each axis (wrapS != wrapT, so the axes are
/// independent). Magnified 5x: mip level 0. Tolerance 2 per channel: the
/// 1 of the head-on test's rounding plus bilinear weights that float error
/// moves off exactly 0 at a texel centre. (Clamp and mirror would show a
/// 50/50 blend with the opposite edge at the clamped cells if the
/// sampler's own repeat addressing leaked in.)
#[test]
fn gltf_wrap_modes_show_the_wrapped_texel() {
    let gpu = gpu();
    let cases = [
        ("REPEAT", 10497, "CLAMP_TO_EDGE", 33071),
        ("CLAMP_TO_EDGE", 33071, "MIRRORED_REPEAT", 33648),
        ("MIRRORED_REPEAT", 33648, "REPEAT", 10497),
    ];
    for (s_name, s, t_name, t) in cases {
        let tag = format!("wrap-{s_name}");
        for (mode, img) in sampler_quad_renders(
            &gpu,
            &tag,
            -1.0,
            2.0,
            &format!(r#""wrapS": {s}, "wrapT": {t}"#),
        ) {
            for j in 0..12u32 {
                for i in 0..12u32 {
                    let (px, py) = (4 + 5 * i, 4 + 5 * j);
                    let tx = wrapped_texel(s_name, i as f32 - 4.0 + 0.5, 4);
                    let ty = wrapped_texel(t_name, j as f32 - 4.0 + 0.5, 4);
                    let want = texel4(tx, ty);
                    let got = rgb_at(&img, 64, px, py);
                    for c in 0..3 {
                        assert!(
                            got[c].abs_diff(want[c]) <= 2,
                            "{mode:?} wrapS {s_name} wrapT {t_name}: cell ({i}, {j}) at pixel \
                             ({px}, {py}) is {got:?}, expected texel ({tx}, {ty}) {want:?}"
                        );
                    }
                }
            }
        }
    }
}

/// glTF magFilter NEAREST: the 4x4 image over the quad (coordinates 0..1)
/// is magnified 15x, and every pixel of the quad shows exactly one texel's
/// colour, the texel under its centre ((px - 2) / 15, (py - 2) / 15; texel
/// edges fall on pixel edges, so no centre is ambiguous): hard edges, in
/// raster and raytrace (tolerance 1, the head-on test's rounding). The same
/// quad with magFilter LINEAR must show blended pixels at those edges
/// (colours at least 8 from every texel's in some channel), or the check
/// above could not fail.
#[test]
fn gltf_nearest_mag_filter_gives_hard_texel_edges() {
    let gpu = gpu();
    let texels: Vec<[u8; 4]> = (0..16).map(|k| texel4(k % 4, k / 4)).collect();
    for (filter, nearest) in [(9728, true), (9729, false)] {
        let tag = format!("mag-{filter}");
        for (mode, img) in
            sampler_quad_renders(&gpu, &tag, 0.0, 1.0, &format!(r#""magFilter": {filter}"#))
        {
            let mut blended = 0;
            for py in 2..62u32 {
                for px in 2..62u32 {
                    let got = rgb_at(&img, 64, px, py);
                    if nearest {
                        let want = texel4((px - 2) / 15, (py - 2) / 15);
                        for c in 0..3 {
                            assert!(
                                got[c].abs_diff(want[c]) <= 1,
                                "{mode:?} NEAREST: pixel ({px}, {py}) is {got:?}, expected {want:?}"
                            );
                        }
                    } else if texels
                        .iter()
                        .all(|t| (0..3).any(|c| got[c].abs_diff(t[c]) >= 8))
                    {
                        blended += 1;
                    }
                }
            }
            if !nearest {
                assert!(blended > 0, "{mode:?} LINEAR: no blended pixel");
            }
        }
    }
}

/// glTF minFilter: coordinates 0..32 put 128 texels of the 4x4 image
/// across the quad's 60 px, a footprint of 128/60 texels per pixel
/// (uniform on a plane facing the camera), mip level log2(128/60) = 1.09.
/// minFilter NEAREST (no mipmaps) reads level 0's nearest texel: every
/// pixel is one of the image's 16 colours. NEAREST_MIPMAP_NEAREST reads
/// level 1 (1.09 rounds to 1): every pixel is one of the 4 colours of the
/// library's level 1 (`mip_chain`). Tolerance 1 (rounding, as above). The
/// default (trilinear, between levels 1 and 2) shows pixels that are
/// neither, so both checks could fail.
#[test]
fn gltf_min_filter_picks_level_and_texel() {
    let gpu = gpu();
    let image = celray::scene::Texture {
        source: "texel4".into(),
        path: PathBuf::new(),
        width: 4,
        height: 4,
        rgba8: (0..16).flat_map(|k| texel4(k % 4, k / 4)).collect(),
    };
    let chain = celray::render::textures::mip_chain(&image, 4);
    let palette = |level: usize| -> Vec<[u8; 3]> {
        chain[level]
            .1
            .chunks_exact(4)
            .map(|t| [t[0], t[1], t[2]])
            .collect()
    };
    let matches = |got: [u8; 3], colours: &[[u8; 3]]| {
        colours
            .iter()
            .any(|t| (0..3).all(|c| got[c].abs_diff(t[c]) <= 1))
    };
    for (filter, level) in [(9728, Some(0)), (9984, Some(1)), (9987, None)] {
        let tag = format!("min-{filter}");
        for (mode, img) in
            sampler_quad_renders(&gpu, &tag, 0.0, 32.0, &format!(r#""minFilter": {filter}"#))
        {
            let mut off_palette = 0;
            for py in 2..62u32 {
                for px in 2..62u32 {
                    let got = rgb_at(&img, 64, px, py);
                    match level {
                        Some(l) => assert!(
                            matches(got, &palette(l)),
                            "{mode:?} minFilter {filter}: pixel ({px}, {py}) is {got:?}, \
                             not a level-{l} texel {:?}",
                            palette(l)
                        ),
                        None => {
                            if !matches(got, &palette(0)) && !matches(got, &palette(1)) {
                                off_palette += 1;
                            }
                        }
                    }
                }
            }
            if level.is_none() {
                assert!(
                    off_palette > 0,
                    "{mode:?} trilinear: every pixel is a texel"
                );
            }
        }
    }
}
