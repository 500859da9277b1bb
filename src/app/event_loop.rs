//! The event loop: winit's [`ApplicationHandler`] for the window, which
//! starts the [`LiveApp`] when the app resumes, routes window events to it
//! (resize, keys, dropped files, redraws), wakes it for hot reloads and
//! egui's repaints, and ends the run with its report.

use std::path::{Path, PathBuf};
use std::time::Instant;

use winit::application::ApplicationHandler;
use winit::event::{ElementState, KeyEvent, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop, EventLoopProxy};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::WindowId;

use super::controller::{AxisView, NavMode};
use super::live::LiveApp;
use super::watch::Changed;
use super::{AppError, RunReport, ViewOptions};

/// What the watcher thread tells the event loop.
#[derive(Debug)]
pub(super) enum AppEvent {
    FilesChanged(Changed),
}

/// A `WAYLAND_DISPLAY` whose socket is gone makes winit panic instead of
/// trying X11: forget it (with a warning) when its socket does not exist.
fn drop_stale_wayland_display() {
    let Some(name) = std::env::var_os("WAYLAND_DISPLAY") else {
        return;
    };
    let path = PathBuf::from(&name);
    let socket = if path.is_absolute() {
        path
    } else {
        match std::env::var_os("XDG_RUNTIME_DIR") {
            Some(dir) => PathBuf::from(dir).join(path),
            None => path,
        }
    };
    if !socket.exists() {
        log::warn!(
            "WAYLAND_DISPLAY={} has no socket at {}; using X11",
            name.to_string_lossy(),
            socket.display()
        );
        std::env::remove_var("WAYLAND_DISPLAY");
    }
}

/// Opens the window and runs until it is closed (or `exit_after_frames`).
pub(super) fn run(options: ViewOptions) -> Result<RunReport, AppError> {
    drop_stale_wayland_display();
    let event_loop = EventLoop::<AppEvent>::with_user_event()
        .build()
        .map_err(|e| AppError::EventLoop(e.to_string()))?;
    let mut app = WindowApp {
        proxy: event_loop.create_proxy(),
        options,
        live: None,
        fatal: None,
        report: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| AppError::EventLoop(e.to_string()))?;
    if let Some(e) = app.fatal {
        return Err(e);
    }
    Ok(app.report.unwrap_or(RunReport {
        adapter: String::new(),
        frames: 0,
        frame_ms: Vec::new(),
        surface_size: (0, 0),
        views: 0,
        samples: Vec::new(),
        pass_times: Vec::new(),
        startup: Default::default(),
        ui_ms: Vec::new(),
    }))
}

/// The handler winit calls: the options, the live app once started, and
/// how the run ended.
struct WindowApp {
    proxy: EventLoopProxy<AppEvent>,
    options: ViewOptions,
    live: Option<LiveApp>,
    fatal: Option<AppError>,
    report: Option<RunReport>,
}

impl WindowApp {
    fn finish(&mut self, event_loop: &ActiveEventLoop) {
        if let Some(live) = &self.live {
            self.report = Some(live.report());
        }
        event_loop.exit();
    }
}

pub(super) fn window_title(path: Option<&Path>) -> String {
    match path {
        Some(p) => format!("celray - {}", p.display()),
        None => "celray - built-in default scene".to_string(),
    }
}

impl ApplicationHandler<AppEvent> for WindowApp {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.live.is_some() {
            return;
        }
        match LiveApp::start(event_loop, &self.options, &self.proxy) {
            Ok(live) => {
                live.surface.window.request_redraw();
                self.live = Some(live);
            }
            Err(e) => {
                self.fatal = Some(e);
                event_loop.exit();
            }
        }
    }

    fn user_event(&mut self, _event_loop: &ActiveEventLoop, event: AppEvent) {
        let Some(live) = &mut self.live else { return };
        let AppEvent::FilesChanged(what) = event;
        live.reload.changed(what);
        live.ui_input = true;
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        let Some(live) = &mut self.live else { return };
        let now = Instant::now();
        let mut wake: Option<Instant> = None;
        match live.reload.due(now) {
            Ok(Some(reload)) => {
                live.reload(reload, &self.proxy);
                live.ui_input = true;
                live.surface.window.request_redraw();
            }
            Ok(None) => {}
            Err(at) => wake = Some(at),
        }
        if let Some(at) = live.repaint_at {
            if now >= at {
                live.repaint_at = None;
                live.surface.window.request_redraw();
            } else {
                wake = Some(wake.map_or(at, |w| w.min(at)));
            }
        }
        event_loop.set_control_flow(match wake {
            Some(at) => ControlFlow::WaitUntil(at),
            None => ControlFlow::Wait,
        });
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(live) = &mut self.live else { return };
        let window = live.surface.window.clone();
        let response = live.overlay.state.on_window_event(&window, &event);
        let input = is_input(&event);
        live.ui_input |= input;
        if response.repaint && input {
            window.request_redraw();
        }
        match event {
            WindowEvent::CloseRequested => self.finish(event_loop),
            WindowEvent::Resized(size) => {
                live.surface.resize(&live.gpu, size, live.model.vsync);
                window.request_redraw();
            }
            WindowEvent::ScaleFactorChanged { .. } => window.request_redraw(),
            WindowEvent::Focused(false) => live.model.move_keys = Default::default(),
            WindowEvent::ModifiersChanged(m) => {
                live.mods = m.state();
                live.model.move_keys.fast = live.mods.shift_key();
            }
            WindowEvent::DroppedFile(path) => {
                live.reload_scene(Some(path), &self.proxy);
                window.request_redraw();
            }
            WindowEvent::KeyboardInput { event, .. } => {
                let egui_has_keys =
                    response.consumed || live.overlay.ctx.egui_wants_keyboard_input();
                live.key(&event, egui_has_keys);
                window.request_redraw();
            }
            WindowEvent::RedrawRequested => match live.redraw() {
                Ok(false) => {}
                Ok(true) => self.finish(event_loop),
                Err(e) => {
                    self.fatal = Some(e);
                    self.finish(event_loop);
                }
            },
            _ => {}
        }
    }
}

/// Whether `event` is news for the UI: every window event but the redraw
/// request itself. egui-winit answers a redraw request with `repaint`
/// too; redrawing on that would draw frames forever, at full CPU, after
/// the views converged.
fn is_input(event: &WindowEvent) -> bool {
    !matches!(event, WindowEvent::RedrawRequested)
}

fn numpad_digit(code: KeyCode) -> Option<u32> {
    match code {
        KeyCode::Numpad1 | KeyCode::Digit1 => Some(1),
        KeyCode::Numpad3 | KeyCode::Digit3 => Some(3),
        KeyCode::Numpad7 | KeyCode::Digit7 => Some(7),
        _ => None,
    }
}

impl LiveApp {
    /// A key: movement keys (held or released), then shortcuts.
    fn key(&mut self, event: &KeyEvent, egui_has_keys: bool) {
        let PhysicalKey::Code(code) = event.physical_key else {
            return;
        };
        let down = event.state == ElementState::Pressed;
        let keys = &mut self.model.move_keys;
        // Releases always count, so that no key stays held.
        let held = down && !egui_has_keys;
        match code {
            KeyCode::KeyW => keys.forward = held,
            KeyCode::KeyS => keys.back = held,
            KeyCode::KeyA => keys.left = held,
            KeyCode::KeyD => keys.right = held,
            KeyCode::KeyQ => keys.down = held,
            KeyCode::KeyE => keys.up = held,
            _ => {}
        }
        if !down || egui_has_keys || event.repeat {
            return;
        }
        match code {
            KeyCode::KeyF | KeyCode::Home => self.model.requests.frame_all = true,
            KeyCode::F12 => self.model.requests.screenshot = true,
            KeyCode::Tab => {
                self.model.nav = match self.model.nav {
                    NavMode::Orbit => NavMode::Fly,
                    NavMode::Fly => NavMode::Orbit,
                }
            }
            other => {
                if let Some(d) = numpad_digit(other) {
                    self.model.requests.axis_view =
                        AxisView::from_numpad(d, self.mods.control_key());
                }
            }
        }
    }
}
