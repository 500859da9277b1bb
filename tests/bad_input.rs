//! Bad input on the command line, end to end: counts past their documented
//! bounds, setting names that do not exist, scene paths that cannot be
//! read, scenes nested too deeply, an interrupted render, and driver
//! noise. Each refusal is exit status 1 with one message naming the bound
//! or the file, never a panic, and leaves no output file behind.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use celray::render::{RenderMode, ToneMap, MAX_BOUNCES, MAX_IMAGE_SAMPLES, MAX_SPP};
use celray::sampling::PixelPattern;
use celray::scene::{MAX_IMAGE_SIZE, MAX_NESTING};

mod common;

use common::cli::{celray, command, stderr};

fn scratch(name: &str) -> PathBuf {
    common::cli::scratch("bad_input", name)
}

/// The names of the files in `dir`, sorted.
fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Runs each case in an empty folder and checks: exit status 1, a message
/// containing the needle (the bound or the file), no panic, no file written.
fn assert_refused(dir: &Path, cases: &[(Vec<String>, String)]) {
    for (args, needle) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = celray(&args, dir);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains(needle.as_str()),
            "{args:?}: message {err:?} should name {needle:?}"
        );
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
        assert_eq!(
            err.trim_end().lines().count(),
            1,
            "{args:?}: one message: {err}"
        );
        assert!(
            files_in(dir).is_empty(),
            "{args:?} wrote {:?}",
            files_in(dir)
        );
    }
}

fn case(args: &[&str], needle: impl ToString) -> (Vec<String>, String) {
    (
        args.iter().map(|a| a.to_string()).collect(),
        needle.to_string(),
    )
}

#[test]
fn counts_past_their_bounds_are_refused_naming_the_bound() {
    let dir = scratch("bounds");
    let over_spp = (MAX_SPP + 1).to_string();
    // A 4096 x 4096 image (2^24 pixels) at one sample more than the
    // per-image bound allows.
    let side: u64 = 4096;
    let spp_over_image = (MAX_IMAGE_SAMPLES / (side * side) + 1).to_string();
    let over_size = (MAX_IMAGE_SIZE + 1).to_string();
    let over_bounces = (MAX_BOUNCES + 1).to_string();
    let mut cases = vec![
        case(&["render", "-o", "x.png", "--spp", "4294967295"], MAX_SPP),
        case(&["render", "-o", "x.png", "--spp", &over_spp], MAX_SPP),
        case(
            &[
                "render",
                "-o",
                "x.png",
                "--width",
                "4096",
                "--height",
                "4096",
                "--spp",
                &spp_over_image,
            ],
            MAX_IMAGE_SAMPLES,
        ),
        case(
            &["render", "-o", "x.png", "--width", &over_size],
            MAX_IMAGE_SIZE,
        ),
        case(
            &["render", "-o", "x.png", "--max-bounces", &over_bounces],
            MAX_BOUNCES,
        ),
        case(&["compare", "-o", "x.png", "--spp", &over_spp], MAX_SPP),
        // The sampling experiment's 1024-sample reference at a size whose
        // square is just past the per-image bound.
        case(
            &[
                "experiment",
                "sampling",
                "-o",
                "x.png",
                "--size",
                &((MAX_IMAGE_SAMPLES / 1024).isqrt() + 1).to_string(),
            ],
            MAX_IMAGE_SAMPLES,
        ),
        case(&["bench", "--frames", "0"], "1 to 1000"),
        case(&["bench", "--frames", "1001"], "1 to 1000"),
        case(&["bench", "--frames", "4294967295"], "1 to 1000"),
        case(&["bench", "scene"], "--scene FILE"),
        case(&["bench", "raster", "--scene", "x.ron"], "suite `scene`"),
        case(
            &["bench", "raster", "--export-rays", "rays.bin"],
            "suite `rays` or `all`",
        ),
        case(
            &["bench", "rays", "--export-rays", "no-such-folder/rays.bin"],
            "no-such-folder does not exist",
        ),
        case(
            &["bench", "floor", "--shaders", "no-such-folder"],
            "--shaders no-such-folder: not a folder",
        ),
        case(
            &["bench", "raster", "--compare-shaders", "."],
            "suites `scene`",
        ),
        // A folder holding no shader file: an error, not the built-in
        // shaders timed under another name.
        case(
            &["bench", "floor", "--shaders", "."],
            "--shaders .: holds no shader file",
        ),
    ];
    if cfg!(feature = "app") {
        // Refused before any window is opened.
        cases.extend([
            case(&["view", "--spp", &over_spp], MAX_SPP),
            case(&["view", "--exit-after-frames", "0"], "1 to 100000"),
            case(&["view", "--exit-after-frames", "100001"], "1 to 100000"),
        ]);
    }
    assert_refused(&dir, &cases);
}

#[test]
fn exported_rays_never_overwrite_a_file() {
    let dir = scratch("export");
    std::fs::write(dir.join("rays.bin"), b"mine").unwrap();
    let o = celray(&["bench", "rays", "--export-rays", "rays.bin"], &dir);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("rays.bin already exists"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(std::fs::read(dir.join("rays.bin")).unwrap(), b"mine");
}

#[test]
fn unknown_setting_names_are_refused_listing_every_name() {
    let dir = scratch("names");
    // The lists come from the enums' own name tables, so a name added to
    // an enum must show up here without touching the CLI.
    let list = |names: Vec<&str>| names.join(", ");
    let cases = [
        (
            "--mode",
            list(RenderMode::ALL.iter().map(|m| m.name()).collect()),
        ),
        (
            "--pattern",
            list(PixelPattern::ALL.iter().map(|p| p.name()).collect()),
        ),
        (
            "--tone-map",
            list(ToneMap::ALL.iter().map(|t| t.name()).collect()),
        ),
    ];
    for (flag, names) in cases {
        // clap's usage message: several lines, the possible values among them.
        let o = celray(&["render", flag, "sideways", "-o", "out.png"], &dir);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{flag}: {err}");
        assert!(err.contains("sideways"), "{flag}: {err}");
        assert!(
            err.contains(&names),
            "{flag}: {err:?} should list {names:?}"
        );
        assert!(!err.contains("panicked"), "{flag} panicked: {err}");
        assert!(files_in(&dir).is_empty(), "{flag} wrote a file");
    }
}

#[test]
fn unreadable_scene_paths_name_the_file_and_the_cause_once() {
    let dir = scratch("unreadable");
    std::fs::create_dir(dir.join("scenes.ron")).unwrap();
    // Not UTF-8: reading it fails with an I/O error like a missing permission.
    std::fs::write(dir.join("binary.ron"), [0xff, 0xfe, b'(']).unwrap();
    for (scene, cause) in [("scenes.ron", "folder"), ("binary.ron", "UTF-8")] {
        let o = celray(&["render", scene, "-o", "out.png"], &dir);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{scene}: {err}");
        assert!(err.contains(scene), "{scene}: should name the file: {err}");
        assert_eq!(
            err.matches(cause).count(),
            1,
            "{scene}: the cause {cause:?} once: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
        assert!(!dir.join("out.png").exists());
    }
    assert_eq!(
        std::fs::read(dir.join("binary.ron")).unwrap(),
        [0xff, 0xfe, b'('],
        "the input file is never modified"
    );
}

#[test]
fn too_deep_nesting_names_the_limit_and_where() {
    let dir = scratch("deep");
    // 100 CSG levels: each costs at least one level of RON nesting, so the
    // file is deeper than the limit (128) wherever ron counts.
    let levels = 100;
    assert!(levels * 2 > MAX_NESTING);
    let prefix = "    shapes: { \"deep\": ";
    let text = format!(
        "(version: 1, camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 64, height: 64),\n\
         {prefix}{}Sphere(radius: 1.0){} }},\n\
         )\n",
        "Union([".repeat(levels),
        "])".repeat(levels)
    );
    std::fs::write(dir.join("deep.ron"), &text).unwrap();
    let o = celray(&["render", "deep.ron", "-o", "out.png"], &dir);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains(&MAX_NESTING.to_string()), "{err}");
    assert!(err.contains("nested too deeply"), "{err}");
    assert!(
        !err.contains("recursion_limit") && !err.contains("serde_stacker"),
        "advice for whoever builds celray, not the user: {err}"
    );
    // file:line:col, the column inside the run of `Union([` on line 2.
    let position = err
        .split("deep.ron:")
        .nth(1)
        .and_then(|rest| {
            let mut it = rest.split(':');
            Some((
                it.next()?.parse::<usize>().ok()?,
                it.next()?.parse::<usize>().ok()?,
            ))
        })
        .unwrap_or_else(|| panic!("no deep.ron:LINE:COL in {err}"));
    let first_union = prefix.len() + 1;
    let leaf = first_union + "Union([".len() * levels;
    assert_eq!(position.0, 2, "{err}");
    assert!(
        (first_union..=leaf).contains(&position.1),
        "column {} should be within the nesting, {first_union}..={leaf}: {err}",
        position.1
    );
    assert!(!dir.join("out.png").exists());
}

/// Kills the child if the test fails before it exits.
struct KillOnDrop(std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[cfg(unix)]
#[test]
fn ctrl_c_writes_the_samples_so_far_with_their_count() {
    let dir = scratch("interrupt");
    // About 2-7 ms a sample on lavapipe: minutes for all of them, so the
    // estimate is printed and the render is still running when interrupted.
    let spp = MAX_SPP.to_string();
    let child = command(
        &[
            "render", "-o", "part.png", "--width", "64", "--height", "48", "--spp", &spp,
        ],
        &dir,
    )
    .stderr(Stdio::piped())
    .spawn()
    .expect("run celray");
    let mut child = KillOnDrop(child);
    let mut lines = BufReader::new(child.0.stderr.take().unwrap()).lines();
    let mut seen = Vec::new();
    // The estimate comes after the first samples are timed.
    loop {
        let line = lines
            .next()
            .unwrap_or_else(|| panic!("exited before estimating: {seen:?}"))
            .unwrap();
        let estimate = line.contains("left (Ctrl+C");
        seen.push(line);
        if estimate {
            break;
        }
    }
    let pid = child.0.id().to_string();
    assert!(Command::new("kill")
        .args(["-INT", &pid])
        .status()
        .unwrap()
        .success());
    let status = child.0.wait().unwrap();
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    let said = rest.join("\n");
    assert_eq!(status.code(), Some(130), "{seen:?} {said}");
    // "interrupted after K of N samples: wrote part.png (64x48, K spp)"
    let done: u32 = said
        .split("interrupted after ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|k| k.parse().ok())
        .unwrap_or_else(|| panic!("no sample count in {said:?}"));
    assert!(
        said.contains(&format!(
            "of {spp} samples: wrote part.png (64x48, {done} spp)"
        )),
        "{said}"
    );
    // The estimate needs two timed samples; it was printed before the end.
    assert!((2..MAX_SPP).contains(&done), "{said}");
    let img = image::open(dir.join("part.png")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (64, 48));
    let distinct: std::collections::BTreeSet<_> = img.pixels().map(|p| p.0).collect();
    assert!(
        distinct.len() > 10,
        "a rendered image, {} colours",
        distinct.len()
    );
}

/// Mesa's device-select layer prints "error: XDG_RUNTIME_DIR is invalid or
/// not set" when it cannot reach a Wayland compositor. With an X display set
/// (here one that does not exist) celray keeps the layer, which says it:
/// the setup shows the noise. Without one the layer is off, the noise gone,
/// and the render still succeeds.
#[cfg(target_os = "linux")]
#[test]
fn no_driver_noise_without_xdg_runtime_dir() {
    let dir = scratch("xdg");
    let run = |display: Option<&str>| {
        let mut cmd = command(
            &[
                "render", "-o", "x.png", "--width", "16", "--height", "12", "--spp", "1", "--quiet",
            ],
            &dir,
        );
        cmd.env_remove("XDG_RUNTIME_DIR")
            .env_remove("NODEVICE_SELECT")
            .env_remove("MESA_VK_DEVICE_SELECT")
            .env_remove("MESA_VK_DEVICE_SELECT_FORCE_DEFAULT_DEVICE")
            .env_remove("DRI_PRIME")
            .env("WAYLAND_DISPLAY", "wayland-0");
        match display {
            Some(d) => cmd.env("DISPLAY", d),
            None => cmd.env_remove("DISPLAY"),
        };
        cmd.output().expect("run celray")
    };
    let noise = "XDG_RUNTIME_DIR";
    let with_display = run(Some(":4321"));
    assert!(with_display.status.success(), "{}", stderr(&with_display));
    // Only where Mesa's layer is installed (not on a machine with the NVIDIA
    // driver alone) can the setup show the noise.
    let layer = [
        "/usr/share/vulkan/implicit_layer.d",
        "/etc/vulkan/implicit_layer.d",
    ]
    .iter()
    .filter_map(|d| std::fs::read_dir(d).ok())
    .flatten()
    .flatten()
    .any(|e| e.file_name().to_string_lossy().contains("device_select"));
    if layer {
        assert!(
            stderr(&with_display).contains(noise),
            "the layer should run when an X display is set: {}",
            stderr(&with_display)
        );
    } else {
        eprintln!("Mesa's device-select layer is not installed: only the quiet run is checked");
    }
    let without_display = run(None);
    assert!(
        without_display.status.success(),
        "{}",
        stderr(&without_display)
    );
    assert!(
        !stderr(&without_display).contains(noise),
        "{}",
        stderr(&without_display)
    );
    assert!(dir.join("x.png").exists());
}
