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

#[test]
fn adapters_lists_the_cpu_adapter() {
    let o = celray(&["adapters"], Path::new("."));
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("Cpu"),
        "lavapipe should be listed as a Cpu adapter: {out}"
    );
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
