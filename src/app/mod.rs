//! The live app: a winit window, an egui panel, camera controls and up to
//! four views side by side, each drawn by its own [`crate::render::Renderer`]
//! (the same renderer `celray render` uses), sharing one camera.
//!
//! Where things are: [`event_loop`] (winit's handler) drives [`live`] (the
//! running app's state and its frame, step by step), which uses [`surface`]
//! (window, present, compose, screenshots), [`overlay`] (egui),
//! [`views`] (the view slots and their renderers), [`view_ui`] (the view
//! area's UI and gestures), [`reload`] (hot reload), [`timing`] (frame
//! statistics over [`crate::gpu::timer::GpuTimer`]), and the plain-data
//! pieces [`model`], [`panel`], [`controller`], [`layout`], [`watch`],
//! [`screenshot`].
//!
//! Layers: this module imports render, view (views and labels), gpu,
//! scene, sampling, winit, egui, notify and jiff; nothing below it imports
//! this module.

pub mod controller;
mod event_loop;
pub mod layout;
mod live;
pub mod model;
mod overlay;
pub mod panel;
mod panel_cache;
mod reload;
pub mod screenshot;
mod surface;
pub mod timing;
mod view_ui;
mod views;
pub mod watch;

use std::path::PathBuf;

use crate::gpu::AdapterChoice;
use crate::render::RenderSettings;
use crate::scene::Scene;
use crate::view::ViewSpec;
pub use layout::Layout;
pub use views::WINDOW_VIEW_SLOTS;

/// The controls, as shown in the panel and in README.md.
pub const CONTROLS: &[(&str, &str)] = &[
    ("orbit", "left drag (Alt + left drag)"),
    (
        "pan",
        "right drag, Shift + left drag, Shift + middle drag (Alt + Shift + left)",
    ),
    (
        "zoom",
        "wheel, middle drag, Ctrl + middle drag (Alt + Ctrl + left)",
    ),
    ("fly mode on / off", "Tab (or the navigation box)"),
    ("fly: look", "hold the right mouse button and move"),
    ("fly: move", "W A S D, Q down, E up, Shift faster"),
    ("fly: speed", "wheel"),
    ("frame the whole scene", "F or Home"),
    (
        "front / right / top view",
        "numpad 1 / 3 / 7 (or 1 / 3 / 7)",
    ),
    ("back / left / bottom view", "Ctrl + numpad 1 / 3 / 7"),
    ("screenshot of the window", "F12 (or the Screenshot button)"),
    ("open a scene", "drop a .ron file on the window"),
    (
        "focus the lens on a point",
        "click it (sets the focus distance)",
    ),
];

/// How `celray view` was asked to run.
pub struct ViewOptions {
    pub scene: Scene,
    /// The file `scene` came from (watched for changes); `None` for the
    /// built-in scene.
    pub scene_path: Option<PathBuf>,
    /// Views given with `--views` (at most 4); the rest keep defaults.
    pub views: Vec<ViewSpec>,
    pub layout: Layout,
    /// Shared render settings; width and height follow each view.
    pub settings: RenderSettings,
    /// Window inner size in logical pixels.
    pub window_size: (u32, u32),
    pub vsync: bool,
    pub adapter: AdapterChoice,
    /// Render this many frames, then exit.
    pub exit_after_frames: Option<u64>,
    /// With `exit_after_frames`: save the window content here at the end.
    pub screenshot: Option<PathBuf>,
    /// Print frame-time statistics at exit.
    pub report_frame_times: bool,
    /// Where F12 and the panel's buttons save screenshots.
    pub screenshot_dir: PathBuf,
    /// Watch the scene file and shaders for changes.
    pub watch: bool,
    /// A scripted camera path: frame N shows the path's camera at frame N.
    pub camera_path: Option<crate::scene::CameraPath>,
}

#[derive(Debug, thiserror::Error)]
pub enum AppError {
    #[error("cannot open a window: {0}. celray view needs a display (X11 or Wayland); for headless use try `celray render` or `celray compare`")]
    EventLoop(String),
    #[error("cannot create the window: {0}")]
    Window(String),
    #[error("cannot draw into the window: {0}")]
    Surface(String),
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
    #[error("cannot write the screenshot {path}: {reason}")]
    Screenshot { path: String, reason: String },
}

/// What a run measured, for `--report-frame-times`.
#[derive(Debug, Clone)]
pub struct RunReport {
    pub adapter: String,
    pub frames: u64,
    /// Interval between presented frames, in ms, in order.
    pub frame_ms: Vec<f64>,
    /// Physical size of the window's surface.
    pub surface_size: (u32, u32),
    pub views: usize,
    pub samples: Vec<u32>,
    /// GPU pass times of the frames that were timed (empty without
    /// timestamp queries).
    pub pass_times: Vec<timing::PassTimes>,
    /// How the window started.
    pub startup: timing::Startup,
    /// egui's CPU ms (running the UI, preparing its paint) per frame.
    pub ui_ms: Vec<f64>,
}

/// Opens the window and runs until it is closed (or `exit_after_frames`).
pub fn run(options: ViewOptions) -> Result<RunReport, AppError> {
    event_loop::run(options)
}

#[cfg(test)]
mod tests {
    /// The controls table of README.md lists exactly [`super::CONTROLS`].
    #[test]
    fn docs_list_the_controls() {
        let doc = include_str!("../../README.md").replace(['*', '`'], "");
        for (action, input) in super::CONTROLS {
            let row = format!("| {action} | {input} |");
            assert!(doc.contains(&row), "README.md lacks the row {row:?}");
        }
        let rows = doc
            .lines()
            .skip_while(|l| !l.starts_with("| action | input |"))
            .skip(2)
            .take_while(|l| l.starts_with('|'))
            .count();
        assert_eq!(rows, super::CONTROLS.len());
    }
}
