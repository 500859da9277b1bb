//! The live app: everything a running window holds ([`LiveApp`]) and one
//! frame of it, as a short sequence of steps: acquire the surface's frame,
//! move the fly camera, run the UI, apply what it changed to the views,
//! render samples, draw and present, collect timings, save what was asked.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use egui::Rect;
use winit::event_loop::{ActiveEventLoop, EventLoopProxy};

use super::controller::{self, NavMode};
use super::event_loop::{window_title, AppEvent};
use super::layout;
use super::model::Model;
use super::overlay::{self, Overlay, OverlayFrame};
use super::panel::{self, PanelInfo};
use super::panel_cache::PxRect;
use super::reload::HotReload;
use super::screenshot;
use super::surface::{self, read_rgba8, Acquired, WindowSurface};
use super::timing::{FrameStats, FrameTimer, PassTimes, Startup};
use super::view_ui::{views_ui, ViewArea};
use super::views::ViewSlots;
use super::{AppError, RunReport, ViewOptions};
use crate::gpu::Gpu;
use crate::scene::{Camera, CameraPath};

/// How long the run goes and what it keeps (from the command line).
struct RunLimits {
    /// Render this many frames, then exit.
    exit_after: Option<u64>,
    /// With `exit_after`: save the window content here at the end.
    screenshot: Option<PathBuf>,
    /// Keep every frame time and pass time for the report.
    keep_times: bool,
}

/// How long the panel may show the same figures (frame time, samples)
/// while no input arrives: the UI runs again at least this often. Between
/// runs a frame draws the last run's shapes again, which spares egui's CPU
/// work (its UI and tessellation, about 2 ms a frame on lavapipe's
/// 2-core machines) that runs before the frame's sample is submitted.
const UI_REFRESH: Duration = Duration::from_millis(250);

/// What the UI shows of state it does not change itself: which views
/// still compile their first pipelines and how many warm up a change,
/// whether any still converges, the error and status lines, and the
/// surface's size.
#[derive(PartialEq, Debug, Default)]
struct UiShown {
    compiling: Vec<bool>,
    converging: bool,
    warming: usize,
    error: Option<String>,
    status: Option<String>,
    size: [u32; 2],
}

/// The last run of the UI, drawn again while nothing changes it.
struct UiRun {
    frame: OverlayFrame,
    /// The view area it laid out, without its click.
    area: ViewArea,
    at: Instant,
    shown: UiShown,
}

/// Whether the UI must run again, `since` its `last` run: input arrived
/// since (`input`), an error is shown, egui asked to run again by now,
/// what it shows changed (`shown`), or its figures are [`UI_REFRESH`] old.
fn ui_due(last: Option<&UiRun>, since: Duration, input: bool, shown: &UiShown) -> bool {
    let Some(last) = last else {
        return true;
    };
    input
        || shown.error.is_some()
        || since >= UI_REFRESH.min(last.frame.repaint_delay)
        || last.shown != *shown
}

/// The state of a running window.
pub(super) struct LiveApp {
    pub surface: WindowSurface,
    pub gpu: Gpu,
    pub overlay: Overlay,
    /// What the panel edits: scene, camera, views, settings.
    pub model: Model,
    pub views: ViewSlots,
    timer: Option<FrameTimer>,
    stats: FrameStats,
    /// GPU pass times of the timed frames, for `--report-frame-times`.
    pass_times: Vec<PassTimes>,
    pub reload: HotReload,
    pub mods: winit::keyboard::ModifiersState,
    /// When egui asked to be drawn again.
    pub repaint_at: Option<Instant>,
    /// Where F12 and the panel's buttons save.
    screenshot_dir: PathBuf,
    /// `--camera-path`: the path and the camera it starts from.
    camera_path: Option<(CameraPath, Camera)>,
    run: RunLimits,
    /// When the app started, and how its first frames went.
    started: Instant,
    startup: Startup,
    /// The UI's last run, and whether input arrived since.
    last_ui: Option<UiRun>,
    pub ui_input: bool,
}

impl LiveApp {
    /// Opens the window and everything it draws with.
    pub fn start(
        event_loop: &ActiveEventLoop,
        o: &ViewOptions,
        proxy: &EventLoopProxy<AppEvent>,
    ) -> Result<LiveApp, AppError> {
        let started = Instant::now();
        let title = window_title(o.scene_path.as_deref());
        let (mut surface, gpu) =
            WindowSurface::open(event_loop, &title, o.window_size, &o.adapter)?;
        let mut overlay = Overlay::new(&gpu, &surface.window, surface.config.format);
        let timer = FrameTimer::new(&gpu);
        let egui_views = (!surface.direct).then_some(&mut overlay.painter.renderer);
        let views = ViewSlots::new(&gpu, surface.view_format, egui_views, timer.is_some());
        let mut model = Model::new(
            o.scene.clone(),
            o.scene_path.clone(),
            &o.views,
            o.layout,
            o.settings.clone(),
        );
        model.vsync = o.vsync;
        surface.configure(&gpu, model.vsync);
        let mut live = LiveApp {
            surface,
            gpu,
            overlay,
            model,
            views,
            timer,
            stats: FrameStats::default(),
            pass_times: Vec::new(),
            reload: HotReload::new(o.watch),
            mods: Default::default(),
            repaint_at: None,
            screenshot_dir: o.screenshot_dir.clone(),
            camera_path: o.camera_path.clone().map(|p| (p, o.scene.camera.clone())),
            run: RunLimits {
                exit_after: o.exit_after_frames,
                screenshot: o.screenshot.clone(),
                keep_times: o.report_frame_times,
            },
            started,
            startup: Startup::default(),
            last_ui: None,
            ui_input: true,
        };
        if o.watch {
            live.rewatch(proxy);
        }
        let c = &live.surface.config;
        log::info!(
            "window: {}x{} {:?}, adapter {}",
            c.width,
            c.height,
            c.format,
            live.gpu.summary
        );
        Ok(live)
    }

    /// What the run measured.
    pub fn report(&self) -> RunReport {
        RunReport {
            adapter: self.gpu.summary.to_string(),
            frames: self.stats.frames,
            frame_ms: self.stats.intervals_ms.clone(),
            surface_size: (self.surface.config.width, self.surface.config.height),
            views: self.model.layout.view_count(),
            samples: self.views.samples(self.model.layout.view_count()),
            pass_times: self.pass_times.clone(),
            startup: self.startup.clone(),
            ui_ms: self.stats.ui_ms.clone(),
        }
    }

    /// One frame. Returns true when the run should end.
    pub fn redraw(&mut self) -> Result<bool, AppError> {
        if self.surface.minimized {
            self.stats.pause();
            return Ok(false);
        }
        let (frame, suboptimal) = match self.surface.acquire(&self.gpu, self.model.vsync)? {
            Acquired::Frame {
                texture,
                suboptimal,
            } => (texture, suboptimal),
            Acquired::Retry { idle, error } => {
                if idle {
                    self.stats.pause();
                }
                if error.is_some() {
                    self.model.error = error;
                }
                return Ok(false);
            }
        };
        self.fly();
        let vsync_before = self.model.vsync;
        let ui_start = Instant::now();
        let (ui, area) = self.run_ui_when_due();
        let mut ui_ms = ui_start.elapsed().as_secs_f64() * 1e3;
        self.apply_edits(&area, ui.pixels_per_point, vsync_before);
        let sampled = self.sample_views();
        // Frames before every shown view draws (its first pipelines still
        // compiling ahead, render::warmup) are not counted: the frame count
        // of `--exit-after-frames` and the frame times are of frames that
        // show the views. A view that cannot be built (its error shown)
        // does not hold the count back.
        let compiling_first = (self.views)
            .compiling_first(self.model.layout.view_count())
            .contains(&true);
        let counted = self.model.error.is_some() || !compiling_first;
        let last_frame =
            counted && (self.run.exit_after).is_some_and(|n| self.stats.frames + 1 >= n);
        let want_shot = std::mem::take(&mut self.model.requests.screenshot)
            || (last_frame && self.run.screenshot.is_some());
        let repaint_delay = ui.repaint_delay;
        let (shot, prepare_ms) = self.draw_and_present(frame, ui, &area.rects, want_shot);
        ui_ms += prepare_ms;
        let since_start = self.started.elapsed().as_secs_f64() * 1e3;
        self.startup.presented(since_start, counted);
        if suboptimal {
            self.surface.configure(&self.gpu, self.model.vsync);
        }
        self.collect_times(sampled);
        if counted {
            self.stats.tick(self.run.keep_times, ui_ms);
        } else {
            self.stats.pause();
        }
        self.save_requested(shot, last_frame)?;
        if self.run.exit_after.is_some_and(|n| self.stats.frames >= n) {
            return Ok(true);
        }
        self.schedule_next(repaint_delay, compiling_first);
        if self
            .last_ui
            .as_ref()
            .is_some_and(|l| l.shown != self.ui_shown())
        {
            // Something the UI shows changed after it ran (an error from
            // applying its edits or from a sample, a warm-up's end, the
            // views' last sample, whose figures the UI drew before it):
            // one more frame shows it, though nothing else would draw one.
            self.surface.window.request_redraw();
        }
        Ok(false)
    }

    /// Fly movement, by the time since the last frame.
    fn fly(&mut self) {
        let dt = self
            .stats
            .since_last(Duration::from_millis(100))
            .as_secs_f32();
        let m = &mut self.model;
        if m.nav == NavMode::Fly && m.move_keys.any() {
            m.scene.camera =
                controller::fly(&m.scene.camera, m.world_up, m.move_keys, m.fly_speed, dt);
        }
    }

    /// The UI when it is due ([`ui_due`]); else the last run's shapes and
    /// view area again.
    fn run_ui_when_due(&mut self) -> (OverlayFrame, ViewArea) {
        let shown = self.ui_shown();
        let last = self.last_ui.as_ref();
        let since = last.map_or(Duration::ZERO, |l| l.at.elapsed());
        // The frame that ends a run (and may save the window) shows
        // current figures.
        let ending = (self.run.exit_after).is_some_and(|n| self.stats.frames + 1 >= n);
        let input = self.ui_input || ending;
        if let Some(last) = last.filter(|l| !ui_due(Some(l), since, input, &shown)) {
            return (last.frame.again(), last.area.clone());
        }
        let at = Instant::now();
        let (frame, area) = self.run_ui();
        self.ui_input = false;
        self.last_ui = Some(UiRun {
            frame: frame.again(),
            area: ViewArea {
                click: None,
                ..area.clone()
            },
            at,
            shown,
        });
        (frame, area)
    }

    fn ui_shown(&self) -> UiShown {
        UiShown {
            compiling: (self.views).compiling_first(self.model.layout.view_count()),
            converging: self.views.converging(),
            warming: self.views.warming(),
            error: self.model.error.clone(),
            status: self.model.status.clone(),
            size: [self.surface.config.width, self.surface.config.height],
        }
    }

    /// The UI: panel, views, camera gestures.
    fn run_ui(&mut self) -> (OverlayFrame, ViewArea) {
        let info = PanelInfo {
            adapter: &self.gpu.summary.name,
            backend: &self.gpu.summary.backend,
            driver: &self.gpu.summary.driver,
            frame_ms: self.stats.smoothed_ms,
            samples: self.views.samples(self.model.layout.view_count()),
            pass_times: self.timer.as_ref().and_then(|t| t.latest),
            has_timer: self.timer.is_some(),
            shader_dir: (self.reload.shader_dir.as_ref()).map(|d| d.display().to_string()),
            accel: self.views.accel_info(),
            warming: self.views.warming(),
            compiling: (self.views).compiling_first(self.model.layout.view_count()),
            ui_ms: self.stats.smoothed_ui_ms,
        };
        let textures = self.views.texture_ids();
        let model = &mut self.model;
        let mut area = ViewArea {
            rects: Vec::new(),
            click: None,
        };
        let frame = self.overlay.run(&self.gpu, &self.surface.window, |ui| {
            egui::Panel::left("panel")
                .frame(overlay::panel_frame(ui.style()))
                .default_size(330.0)
                .show(ui, |ui| panel::side_panel(ui, model, &info));
            let rect = ui.available_rect_before_wrap();
            area = views_ui(ui, rect, model, &textures, &info.samples, &info.compiling);
        });
        (frame, area)
    }

    /// Applies what the UI changed: view sizes, a click's focus, camera
    /// requests and path, panel edits, vsync; then brings the views in step.
    fn apply_edits(&mut self, area: &ViewArea, ppp: f32, vsync_before: bool) {
        self.views.sizes = area
            .rects
            .iter()
            .map(|r| layout::pixel_size(*r, ppp))
            .collect();
        if let Some(&(w, h)) = self.views.sizes.first() {
            self.model.view_aspect = w as f32 / h.max(1) as f32;
        }
        if let Some((view, uv)) = area.click {
            self.focus_at_click(view, uv);
        }
        self.model.apply_camera_requests();
        // A scripted camera path drives the camera, frame by frame.
        if let Some((path, base)) = &self.camera_path {
            let frame = u32::try_from(self.stats.frames).unwrap_or(u32::MAX);
            self.model.scene.camera = path.camera_at(base, frame);
        }
        self.model.commit_edits();
        if self.model.vsync != vsync_before {
            self.surface.configure(&self.gpu, self.model.vsync);
        }
        if let Err(e) = self
            .views
            .sync(&self.gpu, &self.model, &mut self.overlay.painter.renderer)
        {
            self.model.error = Some(e.to_string());
        }
    }

    /// A click on view `view` at `uv` focuses the lens on what is under it,
    /// found in that view's renderer's acceleration structure.
    fn focus_at_click(&mut self, view: usize, uv: glam::Vec2) {
        let Some(renderer) = self.views.renderer(view) else {
            return;
        };
        let camera = &self.model.scene.camera;
        if let Some(distance) = controller::focus_at(camera, uv, |o, d| renderer.pick(o, d)) {
            self.model.scene.camera.focus_distance = Some(distance);
        }
    }

    /// Samples: every shown view that has not converged. True if any ran.
    fn sample_views(&mut self) -> bool {
        let timed = self.timer.as_mut().is_some_and(FrameTimer::begin_frame);
        let (sampled, error) = (self.views).sample(&self.gpu, self.model.samples_per_frame, timed);
        if let Some(e) = error {
            self.model.error = Some(e.to_string());
        }
        sampled
    }

    /// Resolves the changed views, composes the window (and, when wanted,
    /// its copy for a screenshot), submits and presents. Returns the copy,
    /// and the CPU ms egui's paint preparation took (tessellation and
    /// uploads).
    fn draw_and_present(
        &mut self,
        frame: wgpu::SurfaceTexture,
        ui: OverlayFrame,
        rects: &[Rect],
        want_shot: bool,
    ) -> (Option<wgpu::Texture>, f64) {
        let mut encoder = self
            .gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("window frame"),
            });
        self.resolve_views(&mut encoder);
        let ppp = ui.pixels_per_point;
        let size = [self.surface.config.width, self.surface.config.height];
        let images = self.views.images();
        let placements = if self.surface.direct {
            let m = &self.model;
            (self.surface).placements(m.layout, m.wipe, rects, ppp, &images)
        } else {
            Vec::new()
        };
        let views: Vec<PxRect> = (placements.iter())
            .map(|p| PxRect::at(p.dst, p.size))
            .collect();
        let views = self.surface.direct.then_some(&views[..]);
        let prepare_start = Instant::now();
        let mut paint = self
            .overlay
            .prepare(&self.gpu, &mut encoder, ui, size, views);
        let prepare_ms = prepare_start.elapsed().as_secs_f64() * 1e3;
        if let Some(t) = &mut self.timer {
            t.panel_begin(&mut encoder);
        }
        self.overlay.painter.draw_panel(&mut encoder, &paint);
        if let Some(t) = &mut self.timer {
            t.panel_end(&mut encoder);
            t.copy_begin(&mut encoder);
        }
        let overlay = paint.draw(&self.overlay.painter);
        let direct = self.surface.direct;
        let load =
            surface::compose_views(direct, &mut encoder, &frame.texture, &placements, &overlay);
        if let Some(t) = &mut self.timer {
            t.copy_end(&mut encoder);
            t.egui_begin(&mut encoder);
        }
        surface::compose_overlay(&mut encoder, &frame.texture, load, &overlay);
        if let Some(t) = &mut self.timer {
            t.egui_end(&mut encoder);
        }
        // The window's content, again, into a texture we can read.
        let shot = want_shot.then(|| {
            let texture = self.surface.screenshot_texture(&self.gpu);
            (self.surface).compose(&mut encoder, &texture, &placements, &overlay);
            texture
        });
        if let Some(t) = &mut self.timer {
            t.finish(&mut encoder);
        }
        let extra = std::mem::take(&mut paint.extra);
        self.gpu
            .queue
            .submit(extra.into_iter().chain([encoder.finish()]));
        if let Some(t) = &mut self.timer {
            t.after_submit();
        }
        self.surface.window.pre_present_notify();
        self.gpu.queue.present(frame);
        self.overlay.free_textures(&paint);
        (shot, prepare_ms)
    }

    /// Records the resolve of every view whose image changed.
    fn resolve_views(&mut self, encoder: &mut wgpu::CommandEncoder) {
        if let Some(t) = &mut self.timer {
            t.resolve_begin(encoder);
        }
        if let Err(e) = self.views.resolve_changed(&self.gpu, encoder) {
            self.model.error = Some(e.to_string());
        }
        if let Some(t) = &mut self.timer {
            t.resolve_end(encoder);
        }
    }

    /// Takes the GPU times read back since the last frame (no waiting).
    fn collect_times(&mut self, sampled: bool) {
        let _ = self.gpu.device.poll(wgpu::PollType::Poll);
        let Some(timer) = &mut self.timer else {
            return;
        };
        self.views.collect_pass_times(timer);
        if let Some(times) = timer.collect(sampled) {
            if self.run.keep_times {
                self.pass_times.push(times);
            }
        }
    }

    /// Saves the window copy `shot` (to `--screenshot` on the last frame)
    /// and the views' images, when asked.
    fn save_requested(
        &mut self,
        shot: Option<wgpu::Texture>,
        last_frame: bool,
    ) -> Result<(), AppError> {
        if let Some(texture) = shot {
            let to_file = if last_frame {
                self.run.screenshot.clone()
            } else {
                None
            };
            self.save_window(&texture, to_file.as_deref())?;
        }
        if std::mem::take(&mut self.model.requests.save_views) {
            self.save_views();
        }
        Ok(())
    }

    /// Whether a camera path still has frames to drive: it counts window
    /// frames, so its holds must not let the window idle.
    fn path_moves(&self) -> bool {
        (self.camera_path.as_ref())
            .is_some_and(|(path, _)| self.stats.frames < u64::from(path.last_frame()))
    }

    /// Keeps drawing while anything is moving or converging; else waits
    /// (until egui's `repaint_delay`, when it asked for one).
    fn schedule_next(&mut self, repaint_delay: Duration, compiling_first: bool) {
        let flying = self.model.nav == NavMode::Fly && self.model.move_keys.any();
        if compiling_first && !flying && !self.views.converging() {
            // Nothing to draw but the panel until the views' first
            // pipelines are compiled (render::warmup): leave the cores to
            // the compile, and look again shortly.
            self.repaint_at = Some(Instant::now() + Duration::from_millis(50));
        } else if self.views.converging()
            || flying
            || self.run.exit_after.is_some()
            || repaint_delay.is_zero()
            || self.path_moves()
        {
            self.surface.window.request_redraw();
        } else if self.views.warming() > 0 {
            // Converged on the old state: look again shortly for the end
            // of the change's warm-up (render::warmup).
            self.repaint_at = Some(Instant::now() + Duration::from_millis(100));
        } else {
            self.stats.pause();
            if repaint_delay < Duration::from_secs(3600) {
                self.repaint_at = Some(Instant::now() + repaint_delay);
            }
        }
    }

    /// Saves the window content: to `path` (for `--screenshot`), else to a
    /// new timestamped file in the screenshot folder.
    fn save_window(
        &mut self,
        texture: &wgpu::Texture,
        path: Option<&Path>,
    ) -> Result<(), AppError> {
        let rgba = read_rgba8(&self.gpu, texture, self.surface.config.format)?;
        let (w, h) = (texture.width(), texture.height());
        if let Some(p) = path {
            return screenshot::save_png(p, w, h, &rgba).map_err(|e| AppError::Screenshot {
                path: p.display().to_string(),
                reason: e.to_string(),
            });
        }
        let dir = &self.screenshot_dir;
        let stem = format!("celray-{}", screenshot::timestamp());
        match screenshot::save_new_png(dir, &stem, w, h, &rgba) {
            Ok(p) => self.model.status = Some(format!("saved {}", p.display())),
            Err(e) => {
                self.model.error = Some(format!(
                    "cannot save a screenshot in {}: {e}",
                    dir.display()
                ))
            }
        }
        Ok(())
    }

    /// Saves each shown view's image (full size, even under a wipe).
    fn save_views(&mut self) {
        let labels: Vec<String> = self.model.views.iter().map(|v| v.label()).collect();
        let stamp = screenshot::timestamp();
        match (self.views).save(&self.gpu, &self.screenshot_dir, &stamp, &labels) {
            Ok(saved) => {
                let names: Vec<String> = saved.iter().map(|p| p.display().to_string()).collect();
                self.model.status = Some(format!("saved {}", names.join(", ")));
            }
            Err(e) => self.model.error = Some(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shown(compiling: bool) -> UiShown {
        UiShown {
            compiling: vec![compiling],
            converging: true,
            ..UiShown::default()
        }
    }

    fn run(repaint_delay: Duration) -> UiRun {
        UiRun {
            frame: OverlayFrame::empty(repaint_delay),
            area: ViewArea {
                rects: Vec::new(),
                click: None,
            },
            at: Instant::now(),
            shown: shown(false),
        }
    }

    /// The UI runs on its first frame, on input, while an error shows, when
    /// egui's repaint delay or the refresh period has passed and when the
    /// views change; a frame with none of these draws the last run again.
    #[test]
    fn the_ui_runs_again_only_when_something_can_change_it() {
        let idle = run(Duration::MAX);
        let short = Duration::from_millis(10);
        let seen = shown(false);
        assert!(ui_due(None, Duration::ZERO, false, &seen));
        assert!(!ui_due(Some(&idle), short, false, &seen));
        assert!(!ui_due(Some(&idle), UI_REFRESH - short, false, &seen));
        assert!(ui_due(Some(&idle), UI_REFRESH, false, &seen));
        assert!(ui_due(Some(&idle), short, true, &seen));
        assert!(ui_due(Some(&idle), short, false, &shown(true)));
        let changed = [
            UiShown {
                converging: false,
                ..shown(false)
            },
            UiShown {
                warming: 1,
                ..shown(false)
            },
            UiShown {
                status: Some("saved shot.png".into()),
                ..shown(false)
            },
            UiShown {
                size: [640, 360],
                ..shown(false)
            },
        ];
        for now in &changed {
            assert!(ui_due(Some(&idle), short, false, now), "{now:?}");
        }
        // An error shown: every frame, though it stays the same.
        let error = UiShown {
            error: Some("no such mesh".into()),
            ..shown(false)
        };
        let erring = UiRun {
            shown: UiShown {
                error: error.error.clone(),
                ..shown(false)
            },
            ..run(Duration::MAX)
        };
        assert!(ui_due(Some(&erring), short, false, &error));
        // egui asked for another run within the refresh period.
        let animating = run(Duration::from_millis(5));
        assert!(!ui_due(
            Some(&animating),
            Duration::from_millis(4),
            false,
            &seen
        ));
        assert!(ui_due(Some(&animating), short, false, &seen));
        assert!(ui_due(
            Some(&run(Duration::ZERO)),
            Duration::ZERO,
            false,
            &seen
        ));
    }
}
