//! The command line end to end: images of the requested size, identical bytes
//! for identical inputs, and clear errors with a non-zero exit on bad input.

use std::path::Path;

mod common;

use common::cli::{celray, stderr};

fn scratch(name: &str) -> std::path::PathBuf {
    common::cli::scratch("cli", name)
}

#[test]
fn renders_builtin_default_scene_from_any_directory() {
    let dir = scratch("default");
    let o = celray(
        &[
            "render",
            "-o",
            "frame.png",
            "--width",
            "96",
            "--height",
            "54",
            "--spp",
            "2",
            "--quiet",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(dir.join("frame.png")).unwrap();
    assert_eq!((img.width(), img.height()), (96, 54));
    // Not a blank frame: the default scene has several colours.
    let rgb = img.to_rgb8();
    let distinct: std::collections::BTreeSet<_> = rgb.pixels().map(|p| p.0).collect();
    assert!(distinct.len() > 10, "only {} colours", distinct.len());
}

#[test]
fn same_inputs_give_identical_bytes() {
    let dir = scratch("determinism");
    let args = |out: &'static str| {
        [
            "render", "-o", out, "--width", "80", "--height", "60", "--spp", "4", "--seed", "7",
            "--quiet",
        ]
    };
    assert!(celray(&args("a.png"), &dir).status.success());
    assert!(celray(&args("b.png"), &dir).status.success());
    let (a, b) = (
        std::fs::read(dir.join("a.png")).unwrap(),
        std::fs::read(dir.join("b.png")).unwrap(),
    );
    assert!(
        a == b,
        "two renders of the same scene, settings and seed differ"
    );
}

#[test]
fn exr_output_is_linear_float() {
    let dir = scratch("exr");
    let o = celray(
        &[
            "render",
            "-o",
            "frame.exr",
            "--width",
            "32",
            "--height",
            "24",
            "--spp",
            "1",
            "--quiet",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(dir.join("frame.exr")).unwrap();
    assert_eq!((img.width(), img.height()), (32, 24));
    assert!(matches!(img, image::DynamicImage::ImageRgba32F(_)));
}

#[test]
fn scene_typo_reports_file_line_and_column() {
    let dir = scratch("typo");
    let scene = dir.join("typo.ron");
    let text = "(\n    version: 1,\n    camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 64, height: 64),\n    lightz: [],\n)\n";
    std::fs::write(&scene, text).unwrap();
    let o = celray(&["render", "typo.ron", "-o", "out.png", "--quiet"], &dir);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains("typo.ron:4:"),
        "message should name file and line 4: {err}"
    );
    assert!(
        err.contains("lightz"),
        "message should name the unknown field: {err}"
    );
    assert!(!dir.join("out.png").exists());
    assert_eq!(
        std::fs::read_to_string(&scene).unwrap(),
        text,
        "the input file is never modified"
    );
}

#[test]
fn bad_input_gives_clear_errors() {
    let dir = scratch("bad");
    let cases: &[(&[&str], &str)] = &[
        (&["render", "missing.ron", "-o", "x.png"], "missing.ron"),
        (&["render", "-o", "x.png", "--width", "0"], "width"),
        (&["render", "-o", "x.jpg"], ".png"),
        (&["render", "-o", "x.png", "--shading", "toon:0"], "toon"),
        (
            &["render", "-o", "x.png", "--pattern", "spiral"],
            "jittered",
        ),
        (
            &["render", "-o", "x.png", "--set", "camera.fov_y_deg"],
            "KEY=VALUE",
        ),
        (
            &["render", "-o", "x.png", "--set", "camera.nonsense=3"],
            "camera.nonsense",
        ),
        (
            &["render", "-o", "x.png", "--adapter", "no-such-gpu-xyz"],
            "no-such-gpu-xyz",
        ),
        (
            &["render", "-o", "x.png", "--accel", "warp"],
            "auto, software or driver",
        ),
    ];
    for (args, needle) in cases {
        let o = celray(args, &dir);
        assert!(!o.status.success(), "{args:?} should fail");
        let err = stderr(&o);
        assert!(
            err.contains(needle),
            "{args:?}: message {err:?} should mention {needle:?}"
        );
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    }
    assert!(!dir.join("x.png").exists());
}

#[test]
fn refuses_to_overwrite_the_scene_file() {
    let dir = scratch("overwrite");
    let scene = dir.join("scene.png");
    std::fs::write(&scene, "(version: 1)").unwrap();
    let o = celray(&["render", "scene.png", "-o", "scene.png", "--quiet"], &dir);
    assert!(!o.status.success());
    assert_eq!(std::fs::read_to_string(&scene).unwrap(), "(version: 1)");
}

/// A render or a contact sheet whose output is an image the scene reads (a
/// material's texture) is refused, naming the image, and the image keeps
/// its bytes; the same scene renders to another name, so the refusal is
/// the output's, not the scene's.
#[test]
fn refuses_to_overwrite_an_image_the_scene_reads() {
    let dir = scratch("overwrite_image");
    let texture = dir.join("t.png");
    image::RgbaImage::from_pixel(4, 4, image::Rgba([200, 30, 30, 255]))
        .save(&texture)
        .unwrap();
    let before = std::fs::read(&texture).unwrap();
    std::fs::write(
        dir.join("s.ron"),
        "(version: 1, \
         camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), \
                  fov_y_deg: 40.0, width: 16, height: 16), \
         lights: [], \
         materials: { \"m\": (base_color: (1.0, 1.0, 1.0), model: Toon(bands: 3), \
                               base_color_texture: \"t.png\") }, \
         shapes: { \"b\": Sphere(radius: 1.0) }, \
         instances: [(shape: \"b\", material: \"m\")])",
    )
    .unwrap();
    let cases: [&[&str]; 2] = [
        &["render", "s.ron", "-o", "t.png", "--spp", "1", "--quiet"],
        &[
            "compare", "s.ron", "-o", "./t.png", "--spp", "1", "--views", "toon",
        ],
    ];
    for args in cases {
        let o = celray(args, &dir);
        assert!(!o.status.success(), "{args:?} should be refused");
        let err = stderr(&o);
        assert!(
            err.contains("is an image the scene reads") && err.contains("t.png"),
            "{args:?}: {err}"
        );
        assert_eq!(std::fs::read(&texture).unwrap(), before, "{args:?}");
    }
    let o = celray(
        &[
            "render",
            "s.ron",
            "-o",
            "other.png",
            "--spp",
            "1",
            "--quiet",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.join("other.png").exists());
}

/// `celray adapters` lists the adapter the tests render on: lavapipe, a
/// `Cpu` adapter, or the one `CELRAY_ADAPTER` names (by part of its name).
#[test]
fn adapters_lists_the_test_adapter() {
    let o = celray(&["adapters"], Path::new("."));
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    match celray::gpu::AdapterChoice::for_tests() {
        celray::gpu::AdapterChoice::Named(part) => assert!(
            out.lines()
                .any(|l| l.to_lowercase().contains(&part.to_lowercase())),
            "CELRAY_ADAPTER={part} should be listed: {out}"
        ),
        _ => assert!(
            out.lines().any(|l| l.split('\t').nth(2) == Some("Cpu")),
            "lavapipe should be listed as a Cpu adapter: {out}"
        ),
    }
}

/// `render --camera-path --frame K`: with reprojection the frame differs
/// from one fresh sample (`--temporal off`), repeats byte for byte, and
/// equals a plain render once the path has held still for `--spp` frames
/// (exact accumulation restarts). Bad paths and flags are refused.
#[test]
fn camera_path_renders_a_frame_of_the_path() {
    let dir = scratch("camera_path");
    std::fs::write(
        dir.join("path.ron"),
        "(version: 1, keys: [(frame: 0, eye: (0.0, 2.2, 7.0), target: (0.0, 0.6, 0.5)), \
         (frame: 4, eye: (0.4, 2.2, 7.0), target: (0.0, 0.6, 0.5))])",
    )
    .unwrap();
    let run = |out: &str, frame: &str, temporal: &str| {
        let o = celray(
            &[
                "render",
                "-o",
                out,
                "--width",
                "48",
                "--height",
                "32",
                "--spp",
                "4",
                "--camera-path",
                "path.ron",
                "--frame",
                frame,
                "--temporal",
                temporal,
                "--quiet",
            ],
            &dir,
        );
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read(dir.join(out)).unwrap()
    };
    let reproject = run("r.png", "4", "reproject");
    assert_eq!(reproject, run("r2.png", "4", "reproject"));
    assert_ne!(reproject, run("off.png", "4", "off"));
    // Frames 5..=8 hold the last key: 4 exact samples of that view.
    let held = run("held.png", "8", "reproject");
    let o = celray(
        &[
            "render",
            "-o",
            "plain.png",
            "--width",
            "48",
            "--height",
            "32",
            "--spp",
            "4",
            "--set",
            "camera.eye=(0.4, 2.2, 7.0)",
            "--quiet",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(held, std::fs::read(dir.join("plain.png")).unwrap());

    std::fs::write(dir.join("bad.ron"), "(version: 1, keys: [])").unwrap();
    for args in [
        &[
            "render",
            "-o",
            "x.png",
            "--camera-path",
            "bad.ron",
            "--frame",
            "1",
        ][..],
        &[
            "render",
            "-o",
            "x.png",
            "--camera-path",
            "missing.ron",
            "--frame",
            "1",
        ][..],
        &["render", "-o", "x.png", "--temporal", "reproject"][..],
        &[
            "render",
            "-o",
            "x.png",
            "--camera-path",
            "path.ron",
            "--frame",
            "1",
            "--temporal",
            "sideways",
        ][..],
    ] {
        let o = celray(args, &dir);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).starts_with("error: "),
            "{args:?}: {}",
            stderr(&o)
        );
    }
    assert!(!dir.join("x.png").exists());
}

/// Pixels whose traversal hits one of its limits are never silent: besides
/// their magenta, `render` warns with their count. A CSG mesh leaf of five
/// boxes in a row (one closed mesh) crossed along the row meets 10 surfaces,
/// over the 8 a mesh leaf may hold per ray, so the pixels looking down the
/// row overflow; seen from the side (2 crossings per box) none does, and
/// there is no warning.
#[test]
fn render_warns_when_pixels_hit_a_traversal_limit() {
    let dir = scratch("overflow");
    let mut obj = String::new();
    // Corner i of box b: x, y, z from bits 0, 1, 2 (0.3 either side of its
    // centre, the centres 1 apart along z); faces wound outwards.
    for b in 0..5 {
        for i in 0..8 {
            let s = |bit: u32| if i >> bit & 1 == 1 { 0.3 } else { -0.3 };
            obj += &format!("v {} {} {}\n", s(0), s(1), s(2) + b as f64 - 2.0);
        }
        for q in [
            [0, 4, 6, 2],
            [1, 3, 7, 5],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 2, 3, 1],
            [4, 5, 7, 6],
        ] {
            let v = q.map(|k| 8 * b + k + 1);
            obj += &format!(
                "f {} {} {}\nf {} {} {}\n",
                v[0], v[1], v[2], v[0], v[2], v[3]
            );
        }
    }
    std::fs::write(dir.join("row.obj"), obj).unwrap();
    let scene = |eye: &str| {
        format!(
            r#"(version: 1,
            camera: (eye: {eye}, target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 20.0, width: 48, height: 48),
            materials: {{ "m": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong) }},
            shapes: {{ "row": Difference(Mesh(path: "row.obj"), Sphere(radius: 0.1, transform: (translate: (5.0, 0.0, 0.0)))) }},
            instances: [(shape: "row", material: "m")],
        )"#
        )
    };
    for (name, eye, overflows) in [
        ("along.ron", "(0.05, 0.02, 8.0)", true),
        ("across.ron", "(8.0, 0.02, 0.05)", false),
    ] {
        std::fs::write(dir.join(name), scene(eye)).unwrap();
        let o = celray(
            &[
                "render", name, "-o", "out.png", "--mode", "raytrace", "--spp", "1", "--quiet",
            ],
            &dir,
        );
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        std::fs::remove_file(dir.join("out.png")).unwrap();
        let warned = stderr(&o).contains("hit a traversal limit");
        assert_eq!(warned, overflows, "{name}: {}", stderr(&o));
    }
}

/// `bench rays --compare-shaders DIR` pairs the ray-batch kernel of the
/// built-in shaders (A) with DIR's (B) on each ray case: one JSON line with
/// both fastest times and the median ratio per case, and a skipped line
/// for helmet_rays when the models are missing. (Tiny images: this checks
/// the report, not the speed.)
#[test]
fn bench_rays_compare_shaders_reports_each_ray_case() {
    let dir = scratch("rays_ab");
    let shaders = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let o = celray(
        &[
            "bench",
            "rays",
            "--compare-shaders",
            shaders.to_str().unwrap(),
            "--width",
            "64",
            "--height",
            "36",
            "--frames",
            "2",
            "--models",
            dir.to_str().unwrap(),
            "--json",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    let case = |name: &str| lines.iter().find(|l| l["case"] == name);
    assert!(case("helmet_rays").is_some_and(|l| l["skipped"].is_string()));
    let ab = case("rays_ab").expect("a rays_ab line");
    assert_eq!(ab["pairs"], 2);
    for name in ["spot_10000_rays", "spheres_100_rays"] {
        for key in ["a_min", "b_min", "ratio"] {
            let v = ab[key][name].as_f64().unwrap_or(0.0);
            assert!(v > 0.0, "{key}.{name} = {}", ab[key][name]);
        }
    }
}

#[test]
fn a_reader_that_stops_early_ends_the_command_quietly() {
    // `celray adapters | head -0`: standard output is a pipe whose reader is
    // closed before celray starts, so its first line fails with a broken
    // pipe. That ends the command with success and no panic message.
    let dir = scratch("closed_pipe");
    let (reader, writer) = std::io::pipe().expect("a pipe");
    drop(reader);
    let o = common::cli::command(&["adapters"], &dir)
        .stdout(writer)
        .output()
        .expect("run celray");
    let err = stderr(&o);
    assert!(o.status.success(), "{:?}: {err}", o.status);
    assert!(!err.contains("panicked"), "{err}");
}
