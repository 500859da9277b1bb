//! `celray compare` end to end: a labelled contact sheet, one line (or JSON
//! object) per pair of views, and clear errors with a non-zero exit.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;

fn celray(args: &[&str], cwd: &Path) -> Output {
    common::cli::command(args, cwd)
        .env("NODEVICE_SELECT", "1")
        .output()
        .expect("run celray")
}

fn scratch(name: &str) -> PathBuf {
    common::cli::scratch("compare", name)
}

const SIZE: [&str; 4] = ["--width", "120", "--height", "68"];

#[test]
fn writes_a_contact_sheet_and_one_line_per_pair() {
    let dir = scratch("text");
    let mut args = vec![
        "compare",
        "-o",
        "sheet.png",
        "--views",
        "blinn-phong,toon:4,toon:7",
        "--spp",
        "2",
    ];
    args.extend(SIZE);
    let o = celray(&args, &dir);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 3, "{stdout}");
    assert!(lines[0].starts_with("blinn-phong vs toon:4: FLIP mean "));
    assert!(lines[2].starts_with("toon:4 vs toon:7: FLIP mean "));
    assert!(stdout.contains("PSNR") && stdout.contains(" dB"));
    // Three views of 120 x 68 in a row, each under a label bar.
    let sheet = image::open(dir.join("sheet.png")).unwrap().to_rgb8();
    let bar = celray::compare::LABEL_BAR_PX;
    assert_eq!(sheet.width(), 3 * 120 + 4 * 4);
    assert_eq!(sheet.height(), 68 + bar + 2 * 4);
    // The first view's image is the headless render of the same view.
    let scene = celray::scene::Scene::builtin_default();
    let settings = celray::render::RenderSettings {
        width: 120,
        height: 68,
        spp: 2,
        ..Default::default()
    };
    let gpu = celray::gpu::Gpu::new_headless(&celray::gpu::AdapterChoice::for_tests()).unwrap();
    let view = celray::compare::ViewSpec::parse("blinn-phong").unwrap();
    let frames =
        celray::compare::render_views(&gpu, &scene, &settings, &[view], |_, _, _| {}).unwrap();
    let expected = frames[0].to_rgba8();
    for (x, y) in [(10, 10), (60, 34), (110, 60)] {
        let got = sheet.get_pixel(4 + x, 4 + bar + y).0;
        let want = expected.get_pixel(x, y).0;
        assert_eq!(got, [want[0], want[1], want[2]], "pixel ({x}, {y})");
    }
}

#[test]
fn json_report_has_every_pair_and_null_psnr_for_identical_views() {
    let dir = scratch("json");
    let mut args = vec![
        "compare",
        "-o",
        "sheet.png",
        "--views",
        "toon:3,toon:3,blinn-phong",
        "--spp",
        "1",
        "--json",
    ];
    args.extend(SIZE);
    let o = celray(&args, &dir);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("stdout is JSON");
    let pairs = json["pairs"].as_array().unwrap();
    assert_eq!(pairs.len(), 3);
    // Same model twice: identical images, FLIP 0 and no finite PSNR.
    assert_eq!(pairs[0]["a"], "toon:3");
    assert_eq!(pairs[0]["b"], "toon:3");
    assert_eq!(pairs[0]["flip_mean"].as_f64(), Some(0.0));
    assert!(pairs[0]["psnr_db"].is_null());
    // Different models differ.
    let flip = pairs[1]["flip_mean"].as_f64().unwrap();
    let psnr = pairs[1]["psnr_db"].as_f64().unwrap();
    assert!(flip > 0.0 && flip < 1.0, "{flip}");
    assert!(psnr > 5.0 && psnr < 60.0, "{psnr}");
    assert_eq!(json["views"].as_array().unwrap().len(), 3);
}

#[test]
fn bad_input_is_a_clear_message_and_a_non_zero_exit() {
    let dir = scratch("errors");
    let cases: [(&[&str], &str); 4] = [
        (
            &["compare", "-o", "s.png", "--views", "toon:4,phong"],
            "view 2",
        ),
        (&["compare", "-o", "s.png", "--views", ""], "no views"),
        (&["compare", "missing.ron", "-o", "s.png"], "missing.ron"),
        (&["compare", "-o", "s.jpg"], "s.jpg"),
    ];
    for (args, needle) in cases {
        let o = celray(args, &dir);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    assert!(!dir.join("s.png").exists());
}
