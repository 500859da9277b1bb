//! The live app in a real window under Xvfb: `celray view
//! --exit-after-frames N --screenshot PATH` must show the scene and the
//! egui panel. The test starts its own Xvfb on a free display number
//! (`-displayfd`); without Xvfb it fails and says how to install it.
#![cfg(feature = "app")]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// An Xvfb server, killed when dropped.
struct Xvfb {
    child: Child,
    display: String,
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start_xvfb() -> Xvfb {
    let mut child = Command::new("Xvfb")
        .args([
            "-displayfd",
            "1",
            "-screen",
            "0",
            "1600x1000x24",
            "-nolisten",
            "tcp",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap_or_else(|e| {
            panic!(
                "cannot start Xvfb ({e}): the window test needs an X server; \
                 install it with `apt-get install -y xvfb xauth` (.ci/run does this)"
            )
        });
    // Xvfb picks a free display number and writes it when it is ready.
    let stdout = child.stdout.take().expect("piped stdout");
    let mut line = String::new();
    BufReader::new(stdout)
        .read_line(&mut line)
        .expect("read Xvfb's display number");
    let number = line.trim();
    assert!(
        !number.is_empty() && number.chars().all(|c| c.is_ascii_digit()),
        "Xvfb did not report a display number (got {line:?})"
    );
    Xvfb {
        display: format!(":{number}"),
        child,
    }
}

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("app")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs celray with a time limit (a hung window must not hang the suite).
fn run_celray(args: &[&str], display: Option<&str>, cwd: &Path) -> Output {
    run_celray_env(args, display, cwd, &[])
}

fn run_celray_env(
    args: &[&str],
    display: Option<&str>,
    cwd: &Path,
    env: &[(&str, &str)],
) -> Output {
    let mut child = celray_command(args, display, cwd, env)
        .spawn()
        .expect("run celray");
    let deadline = Instant::now() + Duration::from_secs(300);
    loop {
        if child.try_wait().expect("wait for celray").is_some() {
            return child.wait_with_output().expect("celray output");
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let out = child.wait_with_output().expect("celray output");
            panic!(
                "celray view did not exit within 300 s:\n{}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The celray command, on `display` (none: no display at all), the
/// software adapter unless CELRAY_ADAPTER says otherwise.
fn celray_command(
    args: &[&str],
    display: Option<&str>,
    cwd: &Path,
    env: &[(&str, &str)],
) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_celray"));
    cmd.envs(env.iter().copied());
    cmd.args(args)
        .current_dir(cwd)
        .env_remove("WAYLAND_DISPLAY")
        .env("NODEVICE_SELECT", "1")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    match display {
        Some(d) => cmd.env("DISPLAY", d),
        None => cmd.env_remove("DISPLAY"),
    };
    if std::env::var_os("CELRAY_ADAPTER").is_none() {
        cmd.env("CELRAY_ADAPTER", "software");
    }
    cmd
}

/// CPU time (user + system) process `pid` has used, in clock ticks
/// (`/proc/PID/stat` fields 14 and 15).
fn cpu_ticks(pid: u32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The fields after the command name, which is in parentheses: the
    // state is field 3, so utime (14) and stime (15) are 11 and 12 here.
    let rest: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    Some(rest.get(11)?.parse::<u64>().ok()? + rest.get(12)?.parse::<u64>().ok()?)
}

/// Once its views have converged and nothing moves, the window draws no
/// more frames, so the process stops using the CPU. egui-winit answers
/// every redraw request with `repaint`, and redrawing on that kept a
/// converged window drawing at full speed (about 1.2 CPU-seconds a
/// second). The bound: under 15 clock ticks (0.15 s at Linux's 100 a
/// second) in 3 s, a twentieth of one core, where a drawing window uses
/// more than a core.
#[test]
fn a_converged_window_goes_idle() {
    let x = start_xvfb();
    let dir = scratch("idle");
    let args = [
        "view",
        "--width",
        "320",
        "--height",
        "180",
        "--spp",
        "2",
        "--no-watch",
    ];
    let mut child = celray_command(&args, Some(&x.display), &dir, &[])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("run celray");
    let pid = child.id();
    let deadline = Instant::now() + Duration::from_secs(180);
    let mut samples: Vec<(Instant, u64)> = Vec::new();
    let idle = loop {
        std::thread::sleep(Duration::from_millis(250));
        if let Some(status) = child.try_wait().expect("wait for celray") {
            panic!("celray view exited by itself ({status})");
        }
        let now = Instant::now();
        samples.push((now, cpu_ticks(pid).expect("read /proc/PID/stat")));
        let window = samples
            .iter()
            .rev()
            .find(|(at, _)| now.duration_since(*at) >= Duration::from_secs(3));
        if let Some(&(_, before)) = window {
            let used = samples.last().unwrap().1 - before;
            if used < 15 {
                break true;
            }
        }
        if now > deadline {
            break false;
        }
    };
    let _ = child.kill();
    let _ = child.wait();
    let last: Vec<u64> = samples.iter().rev().take(13).map(|s| s.1).collect();
    assert!(
        idle,
        "the converged window kept using the CPU: ticks every 0.25 s, newest first: {last:?}"
    );
}

/// The views' pipelines are compiled ahead on the warm-up thread, which
/// the first frame starts: so the window shows a frame (the panel) before
/// the views' first image, however fast the compile. Were they compiled
/// inside the first frame, both would be the same frame. Reads the
/// `startup:` line of `--report-frame-times`.
fn assert_window_answered_before_the_views(stdout: &[u8]) {
    let stdout = String::from_utf8_lossy(stdout);
    let startup = stdout
        .lines()
        .find(|l| l.starts_with("startup:"))
        .unwrap_or_else(|| panic!("no startup line in:\n{stdout}"));
    let ms_after = |what: &str| -> f64 {
        let rest = &startup[startup.find(what).expect(what) + what.len()..];
        rest.split(" ms")
            .next()
            .unwrap()
            .trim()
            .parse()
            .expect(startup)
    };
    let (first, shown) = (
        ms_after("first window frame after"),
        ms_after("every view shown after"),
    );
    assert!(
        first < shown,
        "the first window frame waited for the views: {startup}"
    );
}

/// The window times one frame in four (`app::timing::TIMED_EVERY`):
/// timing every frame costs lavapipe about 2% of a frame. Of `frames`
/// frames that sample (perhaps one more, before the count starts), at
/// most ceil((frames + 1) / 4) are timed; timing every frame whose
/// predecessor's read-back is in times about half of them or more (12 of
/// 12 with the constant set to 1). At least one timed frame's read-back
/// comes in before the last. Reads the `GPU per frame` line of
/// `--report-frame-times`.
fn assert_one_frame_in_four_timed(stdout: &[u8], frames: u32) {
    let stdout = String::from_utf8_lossy(stdout);
    let timed: u32 = stdout
        .split("GPU per frame (mean of ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no GPU pass times in:\n{stdout}"));
    let most = (frames + 1).div_ceil(4);
    assert!(
        (1..=most).contains(&timed),
        "{timed} of {frames} frames timed (1 to {most} expected):\n{stdout}"
    );
}

fn luma(p: &image::Rgb<u8>) -> f32 {
    0.2126 * f32::from(p[0]) + 0.7152 * f32::from(p[1]) + 0.0722 * f32::from(p[2])
}

#[test]
fn window_screenshot_shows_the_scene_and_the_panel() {
    let x = start_xvfb();
    let dir = scratch("screenshot");
    let out = run_celray(
        &[
            "view",
            "--width",
            "960",
            "--height",
            "540",
            "--exit-after-frames",
            "8",
            "--screenshot",
            "window.png",
            "--no-watch",
            "--report-frame-times",
        ],
        Some(&x.display),
        &dir,
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "celray view failed:\n{stderr}");
    assert_window_answered_before_the_views(&out.stdout);
    assert_one_frame_in_four_timed(&out.stdout, 8);
    let img = image::open(dir.join("window.png"))
        .expect("the screenshot was written")
        .to_rgb8();
    // Xvfb has a scale factor of 1: the window is the size asked for.
    assert_eq!((img.width(), img.height()), (960, 540));

    // The panel (egui's dark theme) on the left: mostly dark, with text.
    let panel: Vec<&image::Rgb<u8>> = (0..540)
        .flat_map(|y| (0..240).map(move |x| (x, y)))
        .map(|(x, y)| img.get_pixel(x, y))
        .collect();
    let dark = panel.iter().filter(|p| luma(p) < 60.0).count();
    let text = panel.iter().filter(|p| luma(p) > 140.0).count();
    assert!(
        dark > panel.len() * 6 / 10,
        "panel not dark: {dark} of {}",
        panel.len()
    );
    assert!(text > 500, "no panel text: {text} light pixels");
    // The panel draws no fill of its own: the window is cleared to the
    // theme's panel colour. Its most common pixel is that colour exactly
    // (an 8-bit clear and a copy: no rounding to allow for).
    let mut counts = std::collections::HashMap::new();
    for p in &panel {
        *counts.entry(p.0).or_insert(0usize) += 1;
    }
    let (common, _) = counts.iter().max_by_key(|(_, n)| **n).unwrap();
    let fill = egui::Visuals::dark().panel_fill;
    assert_eq!(
        *common,
        [fill.r(), fill.g(), fill.b()],
        "the panel's colour is not egui's dark panel fill"
    );

    // The scene on the right: the sky colour at the top (background
    // (0.6, 0.7, 0.85) linear is about (203, 218, 237) in sRGB), many
    // colours, and the red ball.
    let sky = img.get_pixel(900, 20).0;
    let want = [203u8, 218, 237];
    for c in 0..3 {
        assert!(
            (i32::from(sky[c]) - i32::from(want[c])).abs() <= 4,
            "sky is {sky:?}, expected about {want:?}"
        );
    }
    let scene: Vec<[u8; 3]> = (0..540)
        .flat_map(|y| (400..960).map(move |x| (x, y)))
        .map(|(x, y)| img.get_pixel(x, y).0)
        .collect();
    let distinct: std::collections::BTreeSet<[u8; 3]> = scene.iter().copied().collect();
    assert!(
        distinct.len() > 200,
        "only {} colours in the view",
        distinct.len()
    );
    let red = scene
        .iter()
        .filter(|p| p[0] > 150 && p[1] < 90 && p[2] < 90)
        .count();
    assert!(red > 200, "no red ball: {red} red pixels");
}

/// Four views in a grid, drawn the second way the app can show views: as
/// egui images (what it does where the surface cannot be copied into).
#[test]
fn four_views_in_a_grid_are_labelled() {
    let x = start_xvfb();
    let dir = scratch("grid");
    let out = run_celray_env(
        &[
            "view",
            "--views",
            "blinn-phong,toon:2,toon:4,scene",
            "--width",
            "960",
            "--height",
            "540",
            "--exit-after-frames",
            "3",
            "--screenshot",
            "grid.png",
            "--no-watch",
        ],
        Some(&x.display),
        &dir,
        &[("CELRAY_EGUI_VIEWS", "1")],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(dir.join("grid.png")).unwrap().to_rgb8();
    // Each quadrant of the view area shows sky at its top right corner and
    // a dark label box at its top left.
    let (x0, w, h) = (330u32, 960 - 330, 540u32);
    for (qx, qy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let left = x0 + qx * w / 2;
        let top = qy * h / 2;
        let sky = img.get_pixel(left + w / 2 - 12, top + 6).0;
        assert!(
            sky[2] > 200 && sky[0] > 170,
            "quadrant ({qx}, {qy}) sky {sky:?}"
        );
        let label = img.get_pixel(left + 6, top + 12).0;
        assert!(
            label.iter().all(|&c| c < 110),
            "quadrant ({qx}, {qy}) label {label:?}"
        );
    }
}

#[test]
fn without_a_display_view_fails_with_a_message() {
    let dir = scratch("no-display");
    let out = run_celray(
        &["view", "--exit-after-frames", "1", "--no-watch"],
        None,
        &dir,
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("cannot open a window"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn bad_view_arguments_fail_before_opening_a_window() {
    let dir = scratch("bad-args");
    for (args, needle) in [
        (vec!["view", "--views", "toon:4,nope"], "view 2"),
        (
            vec!["view", "--views", "toon,toon,toon,toon,toon"],
            "at most 4",
        ),
        (vec!["view", "--layout", "diagonal"], "--layout"),
        (vec!["view", "nothere.ron"], "nothere.ron"),
    ] {
        let out = run_celray(&args, None, &dir);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

/// `view --camera-path`: the path turns the camera from the scene to the
/// sky by frame 2 and holds it, so the last of 6 frames shows only the
/// background colour where the default camera shows the red ball.
#[test]
fn camera_path_drives_the_view() {
    let x = start_xvfb();
    let dir = scratch("camera_path");
    std::fs::write(
        dir.join("path.ron"),
        "(version: 1, keys: [(frame: 0, eye: (0.0, 2.2, 7.0), target: (0.0, 0.6, 0.5)), \
         (frame: 2, eye: (0.0, 2.2, 7.0), target: (0.0, 40.0, 6.0))])",
    )
    .unwrap();
    let out = run_celray(
        &[
            "view",
            "--width",
            "640",
            "--height",
            "360",
            "--camera-path",
            "path.ron",
            "--exit-after-frames",
            "6",
            "--screenshot",
            "window.png",
            "--no-watch",
            "--report-frame-times",
        ],
        Some(&x.display),
        &dir,
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "celray view failed:\n{stderr}");
    assert_window_answered_before_the_views(&out.stdout);
    let img = image::open(dir.join("window.png"))
        .expect("the screenshot was written")
        .to_rgb8();
    // The view, right of the panel: all sky, about (203, 218, 237) sRGB.
    let view: Vec<[u8; 3]> = (0..360)
        .flat_map(|y| (400..640).map(move |x| (x, y)))
        .map(|(x, y)| img.get_pixel(x, y).0)
        .collect();
    let sky = view
        .iter()
        .filter(|p| {
            [203i32, 218, 237]
                .iter()
                .zip(p.iter())
                .all(|(w, g)| (w - i32::from(*g)).abs() <= 4)
        })
        .count();
    assert!(
        sky > view.len() * 9 / 10,
        "the view is not the sky: {sky} of {} pixels",
        view.len()
    );
}
