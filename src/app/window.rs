//! The window: winit's event loop, the surface, egui, and the frame loop
//! that drives one renderer per view.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use egui::{Align2, Color32, FontId, Id, PointerButton, Pos2, Rect, Sense, Stroke};
use winit::application::ApplicationHandler;
use winit::event::{ElementState, KeyEvent, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop, EventLoopProxy};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use super::controller::{self, AxisView, DragButton, Gesture, Mods, NavMode};
use super::layout::{self, Layout};
use super::model::Model;
use super::panel::{self, PanelInfo};
use super::screenshot;
use super::timing::{self, FrameStats, GpuTimer};
use super::watch::{self, Changed};
use super::{AppError, RunReport, ViewOptions};
use crate::compare::{settings_label, ViewSpec};
use crate::gpu::shader::ShaderOverrides;
use crate::gpu::{Gpu, GpuError};
use crate::render::resolve::ResolvePass;
use crate::render::{RenderSettings, Renderer};
use crate::scene::{Camera, Scene};

/// Format of each view's image when egui draws it (the fallback for
/// surfaces that cannot be copied into). egui 0.37 treats textures as
/// holding sRGB-encoded ("gamma") values, so it is not an sRGB format and
/// the resolve pass encodes in the shader.
const EGUI_VIEW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// Wait this long after a file change before reloading (editors write in steps).
const RELOAD_DELAY: Duration = Duration::from_millis(120);

#[derive(Debug)]
enum AppEvent {
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

pub fn run(options: ViewOptions) -> Result<RunReport, AppError> {
    drop_stale_wayland_display();
    let event_loop = EventLoop::<AppEvent>::with_user_event()
        .build()
        .map_err(|e| AppError::EventLoop(e.to_string()))?;
    let mut app = App {
        proxy: event_loop.create_proxy(),
        options,
        running: None,
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
    }))
}

struct App {
    proxy: EventLoopProxy<AppEvent>,
    options: ViewOptions,
    running: Option<Running>,
    fatal: Option<AppError>,
    report: Option<RunReport>,
}

/// What a view was last given, to tell what changed.
#[derive(Clone, PartialEq)]
struct Applied {
    spec: ViewSpec,
    scene_rev: u64,
    camera: Camera,
    settings: RenderSettings,
}

/// One of the four view slots: the texture the view is resolved into and,
/// while the layout shows the slot, a renderer drawing into it. The texture
/// is copied into the window (fast on a CPU driver), or, where the surface
/// cannot be copied into, drawn by egui under `tex_id` (which never changes).
struct ViewSlot {
    tex_id: Option<egui::TextureId>,
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    renderer: Option<(Renderer, ResolvePass)>,
    applied: Option<Applied>,
    /// Samples in the texture (resolved), to skip resolving unchanged images.
    shown: Option<u32>,
}

fn view_texture(
    gpu: &Gpu,
    size: (u32, u32),
    format: wgpu::TextureFormat,
) -> (wgpu::Texture, wgpu::TextureView) {
    let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("view image"),
        size: wgpu::Extent3d {
            width: size.0,
            height: size.1,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let view = texture.create_view(&Default::default());
    (texture, view)
}

/// A copy of (part of) a view's texture into the window.
struct Placement {
    slot: usize,
    src: (u32, u32),
    dst: (u32, u32),
    size: (u32, u32),
}

struct Running {
    window: Arc<Window>,
    /// Views are copied into the surface (else drawn by egui).
    direct: bool,
    view_format: wgpu::TextureFormat,
    gpu: Gpu,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    present_modes: Vec<wgpu::PresentMode>,
    minimized: bool,
    egui_ctx: egui::Context,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
    model: Model,
    slots: Vec<ViewSlot>,
    /// Pixel size of each shown view, from the last layout.
    view_sizes: Vec<(u32, u32)>,
    timer: Option<GpuTimer>,
    stats: FrameStats,
    mods: winit::keyboard::ModifiersState,
    shader_dir: Option<PathBuf>,
    watcher: Option<watch::Watcher>,
    pending_reload: Option<(Instant, bool, bool)>,
    /// When egui asked to be drawn again.
    repaint_at: Option<Instant>,
    /// Where F12 and the panel's buttons save.
    screenshot_dir: PathBuf,
    /// GPU pass times of the timed frames, for `--report-frame-times`.
    pass_times: Vec<timing::PassTimes>,
    /// `--camera-path`: the path and the camera it starts from.
    camera_path: Option<(crate::scene::CameraPath, crate::scene::Camera)>,
}

impl App {
    fn start(&mut self, event_loop: &ActiveEventLoop) -> Result<Running, AppError> {
        let o = &self.options;
        let attributes = Window::default_attributes()
            .with_title(window_title(o.scene_path.as_deref()))
            .with_inner_size(winit::dpi::LogicalSize::new(
                o.window_size.0.max(1),
                o.window_size.1.max(1),
            ));
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .map_err(|e| AppError::Window(e.to_string()))?,
        );
        let mut desc = wgpu::InstanceDescriptor::new_with_display_handle_from_env(Box::new(
            event_loop.owned_display_handle(),
        ));
        if std::env::var_os("WGPU_BACKEND").is_none() {
            desc.backends = wgpu::Backends::PRIMARY;
        }
        let instance = wgpu::Instance::new(desc);
        let surface = instance
            .create_surface(window.clone())
            .map_err(|e| AppError::Surface(e.to_string()))?;
        let adapters: Vec<wgpu::Adapter> =
            pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()))
                .into_iter()
                .filter(|a| a.is_surface_supported(&surface))
                .collect();
        let adapter = crate::gpu::pick_adapter(adapters, &o.adapter)?;
        let gpu = Gpu::from_adapter(instance, adapter)?;
        let caps = surface.get_capabilities(&gpu.adapter);
        // egui wants a non-sRGB target; the resolve pass encodes for it.
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| {
                matches!(
                    f,
                    wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Rgba8Unorm
                )
            })
            .or_else(|| caps.formats.first().copied())
            .ok_or_else(|| AppError::Surface("the surface offers no format".into()))?;
        let size = window.inner_size();
        // Copying the views into the surface costs far less than drawing
        // them as egui images on a CPU driver; it needs COPY_DST.
        // CELRAY_EGUI_VIEWS=1 forces the egui path (tests cover both).
        let direct = caps.usages.contains(wgpu::TextureUsages::COPY_DST)
            && std::env::var_os("CELRAY_EGUI_VIEWS").is_none();
        let view_format = if direct { format } else { EGUI_VIEW_FORMAT };
        let config = wgpu::SurfaceConfiguration {
            usage: if direct {
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_DST
            } else {
                wgpu::TextureUsages::RENDER_ATTACHMENT
            },
            format,
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode: wgpu::PresentMode::Fifo,
            desired_maximum_frame_latency: 2,
            alpha_mode: caps
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: vec![],
            color_space: wgpu::SurfaceColorSpace::Auto,
        };
        let egui_ctx = egui::Context::default();
        let egui_state = egui_winit::State::new(
            egui_ctx.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            window.theme(),
            Some(gpu.device.limits().max_texture_dimension_2d as usize),
        );
        let mut egui_renderer = egui_wgpu::Renderer::new(
            &gpu.device,
            format,
            // Dithering costs 40% of egui's GPU time on a CPU driver, for
            // no visible gain on an 8-bit panel.
            egui_wgpu::RendererOptions {
                dithering: false,
                ..Default::default()
            },
        );
        let slots = (0..timing::MAX_VIEWS)
            .map(|_| {
                let (texture, view) = view_texture(&gpu, (1, 1), view_format);
                let tex_id = (!direct).then(|| {
                    egui_renderer.register_native_texture(
                        &gpu.device,
                        &view,
                        wgpu::FilterMode::Nearest,
                    )
                });
                ViewSlot {
                    tex_id,
                    texture,
                    view,
                    renderer: None,
                    applied: None,
                    shown: None,
                }
            })
            .collect();
        let mut model = Model::new(
            o.scene.clone(),
            o.scene_path.clone(),
            &o.views,
            o.layout,
            o.settings.clone(),
        );
        model.vsync = o.vsync;
        let shader_dir = if o.watch { watch::shader_dir() } else { None };
        let mut running = Running {
            timer: GpuTimer::new(&gpu),
            present_modes: caps.present_modes,
            direct,
            view_format,
            window,
            gpu,
            surface,
            config,
            minimized: size.width == 0 || size.height == 0,
            egui_ctx,
            egui_state,
            egui_renderer,
            model,
            slots,
            view_sizes: Vec::new(),
            stats: FrameStats::default(),
            mods: Default::default(),
            shader_dir,
            watcher: None,
            pending_reload: None,
            repaint_at: None,
            screenshot_dir: o.screenshot_dir.clone(),
            pass_times: Vec::new(),
            camera_path: o.camera_path.clone().map(|p| (p, o.scene.camera.clone())),
        };
        running.configure();
        if o.watch {
            running.rewatch(&self.proxy);
        }
        log::info!(
            "window: {}x{} {:?}, adapter {}",
            running.config.width,
            running.config.height,
            running.config.format,
            running.gpu.summary
        );
        Ok(running)
    }

    fn finish(&mut self, event_loop: &ActiveEventLoop) {
        if let Some(r) = &self.running {
            self.report = Some(RunReport {
                adapter: r.gpu.summary.to_string(),
                frames: r.stats.frames,
                frame_ms: r.stats.intervals_ms.clone(),
                surface_size: (r.config.width, r.config.height),
                views: r.model.layout.view_count(),
                samples: r.samples_shown(),
                pass_times: r.pass_times.clone(),
            });
        }
        event_loop.exit();
    }
}

fn window_title(path: Option<&Path>) -> String {
    match path {
        Some(p) => format!("celray - {}", p.display()),
        None => "celray - built-in default scene".to_string(),
    }
}

impl ApplicationHandler<AppEvent> for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.running.is_some() {
            return;
        }
        match self.start(event_loop) {
            Ok(r) => {
                r.window.request_redraw();
                self.running = Some(r);
            }
            Err(e) => {
                self.fatal = Some(e);
                event_loop.exit();
            }
        }
    }

    fn user_event(&mut self, _event_loop: &ActiveEventLoop, event: AppEvent) {
        let Some(r) = &mut self.running else { return };
        let AppEvent::FilesChanged(what) = event;
        let (mut scene, mut shaders) = r
            .pending_reload
            .map(|(_, a, b)| (a, b))
            .unwrap_or((false, false));
        scene |= what == Changed::Scene;
        shaders |= what == Changed::Shaders;
        r.pending_reload = Some((Instant::now() + RELOAD_DELAY, scene, shaders));
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        let Some(r) = &mut self.running else { return };
        let now = Instant::now();
        let mut wake: Option<Instant> = None;
        if let Some((at, scene, shaders)) = r.pending_reload {
            if now >= at {
                r.pending_reload = None;
                if scene {
                    r.reload_scene(None, &self.proxy);
                }
                if shaders {
                    r.reload_shaders();
                }
                r.window.request_redraw();
            } else {
                wake = Some(at);
            }
        }
        if let Some(at) = r.repaint_at {
            if now >= at {
                r.repaint_at = None;
                r.window.request_redraw();
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
        let Some(r) = &mut self.running else { return };
        let response = r.egui_state.on_window_event(&r.window, &event);
        if response.repaint {
            r.window.request_redraw();
        }
        match event {
            WindowEvent::CloseRequested => self.finish(event_loop),
            WindowEvent::Resized(size) => {
                r.minimized = size.width == 0 || size.height == 0;
                if !r.minimized {
                    r.config.width = size.width;
                    r.config.height = size.height;
                    r.configure();
                }
                r.window.request_redraw();
            }
            WindowEvent::ScaleFactorChanged { .. } => r.window.request_redraw(),
            WindowEvent::Focused(false) => r.model.move_keys = Default::default(),
            WindowEvent::ModifiersChanged(m) => {
                r.mods = m.state();
                r.model.move_keys.fast = r.mods.shift_key();
            }
            WindowEvent::DroppedFile(path) => {
                r.reload_scene(Some(path), &self.proxy);
                r.window.request_redraw();
            }
            WindowEvent::KeyboardInput { event, .. } => {
                let egui_has_keys = response.consumed || r.egui_ctx.egui_wants_keyboard_input();
                r.key(&event, egui_has_keys);
                r.window.request_redraw();
            }
            WindowEvent::RedrawRequested => {
                let exit_at = self.options.exit_after_frames;
                let capture = self.options.screenshot.clone();
                match r.redraw(exit_at, capture.as_deref(), self.options.report_frame_times) {
                    Ok(done) => {
                        if done {
                            self.finish(event_loop);
                        }
                    }
                    Err(e) => {
                        self.fatal = Some(e);
                        self.finish(event_loop);
                    }
                }
            }
            _ => {}
        }
    }
}

fn numpad_digit(code: KeyCode) -> Option<u32> {
    match code {
        KeyCode::Numpad1 | KeyCode::Digit1 => Some(1),
        KeyCode::Numpad3 | KeyCode::Digit3 => Some(3),
        KeyCode::Numpad7 | KeyCode::Digit7 => Some(7),
        _ => None,
    }
}

/// Reads a texture of `format` back as RGBA8 (swizzling BGRA).
fn read_rgba8(
    gpu: &Gpu,
    texture: &wgpu::Texture,
    format: wgpu::TextureFormat,
) -> Result<Vec<u8>, GpuError> {
    let mut bytes = crate::gpu::readback::read_texture(gpu, texture, 4)?;
    if matches!(
        format,
        wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
    ) {
        for p in bytes.chunks_exact_mut(4) {
            p.swap(0, 2);
        }
    }
    for p in bytes.chunks_exact_mut(4) {
        p[3] = 255;
    }
    Ok(bytes)
}

impl Running {
    fn configure(&mut self) {
        let wanted = if self.model.vsync {
            vec![wgpu::PresentMode::Fifo]
        } else {
            vec![
                wgpu::PresentMode::Immediate,
                wgpu::PresentMode::Mailbox,
                wgpu::PresentMode::Fifo,
            ]
        };
        self.config.present_mode = wanted
            .into_iter()
            .find(|m| self.present_modes.contains(m))
            .unwrap_or(wgpu::PresentMode::Fifo);
        self.surface.configure(&self.gpu.device, &self.config);
    }

    fn rewatch(&mut self, proxy: &EventLoopProxy<AppEvent>) {
        let proxy = proxy.clone();
        let images: Vec<PathBuf> = crate::render::textures::scene_images(&self.model.scene)
            .iter()
            .map(|t| t.path.clone())
            .collect();
        let result = watch::watch_with_images(
            self.model.scene_path.as_deref(),
            self.shader_dir.as_deref(),
            &images,
            move |c| {
                let _ = proxy.send_event(AppEvent::FilesChanged(c));
            },
        );
        match result {
            Ok(w) => self.watcher = Some(w),
            Err(e) => {
                self.watcher = None;
                self.model.error = Some(format!("cannot watch files for changes: {e}"));
            }
        }
    }

    fn samples_shown(&self) -> Vec<u32> {
        self.slots[..self.model.layout.view_count()]
            .iter()
            .map(|s| s.renderer.as_ref().map_or(0, |(r, _)| r.samples()))
            .collect()
    }

    /// Loads `path` (a dropped file) or reloads the current scene file.
    /// A failure keeps the last good scene and shows the error.
    fn reload_scene(&mut self, path: Option<PathBuf>, proxy: &EventLoopProxy<AppEvent>) {
        let dropped = path.is_some();
        let Some(path) = path.or_else(|| self.model.scene_path.clone()) else {
            return;
        };
        if dropped
            && !path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("ron"))
        {
            self.model.error = Some(format!(
                "{}: not a scene file (celray opens .ron scene files)",
                path.display()
            ));
            return;
        }
        match Scene::load(&path) {
            Ok(scene) => {
                self.model.replace_scene(scene, Some(path.clone()));
                self.model.error = None;
                self.model.status = Some(format!("loaded {}", path.display()));
                self.window
                    .set_title(&window_title(self.model.scene_path.as_deref()));
                // A new file, or new images to watch.
                if self.watcher.is_some() {
                    self.rewatch(proxy);
                }
            }
            Err(e) => {
                self.model.error = Some(format!("{e}\n(keeping the last good scene)"));
            }
        }
    }

    /// Rebuilds every renderer with the shaders on disk; a shader that
    /// fails keeps the old renderers and shows the error.
    fn reload_shaders(&mut self) {
        let Some(dir) = self.shader_dir.clone() else {
            return;
        };
        let overrides = match ShaderOverrides::read_dir(&dir) {
            Ok(o) => o,
            Err(e) => {
                self.model.error = Some(e.to_string());
                return;
            }
        };
        let previous = self.gpu.shader_overrides();
        self.gpu.set_shader_overrides(Some(overrides));
        let mut rebuilt = Vec::new();
        for slot in &self.slots {
            let Some((old, _)) = &slot.renderer else {
                rebuilt.push(None);
                continue;
            };
            let built = Renderer::new(&self.gpu, old.scene().clone(), old.settings().clone())
                .and_then(|r| {
                    let pass = r.new_resolve_pass(&self.gpu, self.view_format)?;
                    Ok((r, pass))
                });
            match built {
                Ok(pair) => rebuilt.push(Some(pair)),
                Err(e) => {
                    self.gpu
                        .set_shader_overrides(previous.map(|p| (*p).clone()));
                    let _ = self.gpu.take_errors();
                    self.model.error = Some(format!(
                        "shader reload failed, keeping the previous shaders:\n{e}"
                    ));
                    return;
                }
            }
        }
        for (slot, new) in self.slots.iter_mut().zip(rebuilt) {
            if let Some(pair) = new {
                slot.renderer = Some(pair);
                slot.shown = None;
            }
        }
        self.model.error = None;
        self.model.status = Some(format!("shaders reloaded from {}", dir.display()));
    }

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

    /// Makes each shown view's renderer match the model; returns an error
    /// message for the panel if a renderer could not be made.
    fn sync_views(&mut self) -> Result<(), GpuError> {
        let count = self.model.layout.view_count();
        for i in 0..self.slots.len() {
            if i >= count {
                let slot = &mut self.slots[i];
                slot.renderer = None;
                slot.applied = None;
                slot.shown = None;
                continue;
            }
            let size = self.view_sizes.get(i).copied().unwrap_or((1, 1));
            let want = Applied {
                spec: self.model.views[i].clone(),
                scene_rev: self.model.scene_rev,
                camera: self.model.scene.camera.clone(),
                settings: RenderSettings {
                    width: size.0,
                    height: size.1,
                    ..self.model.settings.clone()
                },
            };
            let slot = &mut self.slots[i];
            if (slot.texture.width(), slot.texture.height()) != size {
                let (texture, view) = view_texture(&self.gpu, size, self.view_format);
                if let Some(id) = slot.tex_id {
                    self.egui_renderer.update_egui_texture_from_wgpu_texture(
                        &self.gpu.device,
                        &view,
                        wgpu::FilterMode::Nearest,
                        id,
                    );
                }
                slot.texture = texture;
                slot.view = view;
                slot.shown = None;
            }
            if slot.applied.as_ref() == Some(&want) {
                continue;
            }
            match (&mut slot.renderer, &slot.applied) {
                (Some((renderer, pass)), Some(had)) if had.spec == want.spec => {
                    if had.settings != want.settings {
                        renderer.set_settings(&self.gpu, want.settings.clone())?;
                        renderer.prepare_resolve(&self.gpu, pass);
                    }
                    if had.scene_rev != want.scene_rev {
                        let mut scene = want.spec.apply(&self.model.scene);
                        scene.camera = want.camera.clone();
                        renderer.update_scene(&self.gpu, scene)?;
                    } else if had.camera != want.camera {
                        renderer.set_camera(want.camera.clone());
                    }
                }
                _ => {
                    slot.renderer = None;
                    let renderer = Renderer::new(
                        &self.gpu,
                        want.spec.apply(&self.model.scene),
                        want.settings.clone(),
                    )?;
                    let pass = renderer.new_resolve_pass(&self.gpu, self.view_format)?;
                    slot.renderer = Some((renderer, pass));
                }
            }
            slot.applied = Some(want);
            slot.shown = None;
        }
        Ok(())
    }

    /// One frame. Returns true when the run should end.
    fn redraw(
        &mut self,
        exit_after: Option<u64>,
        capture: Option<&Path>,
        keep_times: bool,
    ) -> Result<bool, AppError> {
        if self.minimized {
            self.stats.pause();
            return Ok(false);
        }
        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) => (t, false),
            wgpu::CurrentSurfaceTexture::Suboptimal(t) => (t, true),
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                self.stats.pause();
                self.window.request_redraw();
                return Ok(false);
            }
            wgpu::CurrentSurfaceTexture::Outdated => {
                self.configure();
                self.window.request_redraw();
                return Ok(false);
            }
            wgpu::CurrentSurfaceTexture::Lost => {
                self.surface = self
                    .gpu
                    .instance
                    .create_surface(self.window.clone())
                    .map_err(|e| AppError::Surface(e.to_string()))?;
                self.configure();
                self.window.request_redraw();
                return Ok(false);
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                let e = self.gpu.take_errors().err();
                self.model.error = Some(format!(
                    "surface: {}",
                    e.map_or_else(String::new, |e| e.to_string())
                ));
                self.configure();
                self.window.request_redraw();
                return Ok(false);
            }
        };
        let (surface_texture, suboptimal) = frame;

        // Fly movement, by the time since the last frame.
        let dt = self
            .stats
            .since_last(Duration::from_millis(100))
            .as_secs_f32();
        if self.model.nav == NavMode::Fly && self.model.move_keys.any() {
            self.model.scene.camera = controller::fly(
                &self.model.scene.camera,
                self.model.world_up,
                self.model.move_keys,
                self.model.fly_speed,
                dt,
            );
        }

        // The UI: panel, views, camera gestures.
        let vsync_before = self.model.vsync;
        let info = PanelInfo {
            adapter: &self.gpu.summary.name,
            backend: &self.gpu.summary.backend,
            driver: &self.gpu.summary.driver,
            frame_ms: self.stats.smoothed_ms,
            samples: self.samples_shown(),
            pass_times: self.timer.as_ref().and_then(|t| t.latest),
            has_timer: self.timer.is_some(),
            shader_dir: self.shader_dir.as_ref().map(|d| d.display().to_string()),
            accel: self
                .slots
                .iter()
                .find_map(|s| s.renderer.as_ref())
                .map(|(r, _)| (r.accel_in_use(), r.accel_notice().map(str::to_string))),
        };
        let textures: Vec<Option<egui::TextureId>> = self.slots.iter().map(|s| s.tex_id).collect();
        let raw = self.egui_state.take_egui_input(&self.window);
        let model = &mut self.model;
        let mut rects = Vec::new();
        let full = self.egui_ctx.run_ui(raw, |ui| {
            egui::Panel::left("panel")
                .default_size(330.0)
                .show(ui, |ui| panel::side_panel(ui, model, &info));
            let area = ui.available_rect_before_wrap();
            rects = views_ui(ui, area, model, &textures, &info.samples);
        });
        let mut full = full;
        // Apply egui's texture changes at once: they must not be lost,
        // whatever happens later in this frame.
        for (id, deltas) in full.textures_delta.set.drain() {
            for delta in &deltas {
                self.egui_renderer
                    .update_texture(&self.gpu.device, &self.gpu.queue, id, delta);
            }
        }
        let to_free: Vec<egui::TextureId> = full.textures_delta.free.drain().collect();
        self.egui_state
            .handle_platform_output(&self.window, full.platform_output);
        let ppp = full.pixels_per_point;
        self.view_sizes = rects.iter().map(|r| layout::pixel_size(*r, ppp)).collect();
        if let Some(&(w, h)) = self.view_sizes.first() {
            self.model.view_aspect = w as f32 / h.max(1) as f32;
        }
        self.model.apply_camera_requests();
        // A scripted camera path drives the camera, frame by frame.
        if let Some((path, base)) = &self.camera_path {
            let frame = u32::try_from(self.stats.frames).unwrap_or(u32::MAX);
            self.model.scene.camera = path.camera_at(base, frame);
        }
        self.model.commit_edits();
        if self.model.vsync != vsync_before {
            self.configure();
        }
        if let Err(e) = self.sync_views() {
            self.model.error = Some(e.to_string());
        }

        // Samples: every shown view that has not converged.
        let timed = self.timer.as_mut().is_some_and(|t| t.begin_frame());
        let mut sampled = false;
        for (i, slot) in self.slots.iter_mut().enumerate() {
            let Some((renderer, _)) = &mut slot.renderer else {
                continue;
            };
            for k in 0..self.model.samples_per_frame {
                if renderer.converged() {
                    break;
                }
                let stamps = if timed && k == 0 {
                    self.timer.as_mut().and_then(|t| t.view_slots(i))
                } else {
                    None
                };
                if let Err(e) = renderer.render_sample_timed(&self.gpu, stamps) {
                    self.model.error = Some(e.to_string());
                    break;
                }
                sampled = true;
            }
        }

        // Resolve changed views, then draw egui (which shows them).
        let mut encoder = self
            .gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("window frame"),
            });
        if let Some(t) = &mut self.timer {
            t.resolve_begin(&mut encoder);
        }
        for slot in &mut self.slots {
            if let Some((renderer, pass)) = &slot.renderer {
                if slot.shown != Some(renderer.samples()) {
                    renderer.encode_resolve(pass, &mut encoder, &slot.view);
                    slot.shown = Some(renderer.samples());
                }
            }
        }
        if let Some(t) = &mut self.timer {
            t.resolve_end(&mut encoder);
        }
        let placements = if self.direct {
            self.placements(&rects, ppp)
        } else {
            Vec::new()
        };
        let paint_jobs = self.egui_ctx.tessellate(full.shapes, ppp);
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [self.config.width, self.config.height],
            pixels_per_point: ppp,
        };
        let extra = self.egui_renderer.update_buffers(
            &self.gpu.device,
            &self.gpu.queue,
            &mut encoder,
            &paint_jobs,
            &screen,
        );
        let target = surface_texture.texture.create_view(&Default::default());
        if let Some(t) = &mut self.timer {
            t.egui_begin(&mut encoder);
        }
        self.compose(
            &mut encoder,
            &surface_texture.texture,
            &target,
            &paint_jobs,
            &screen,
            &placements,
        );
        if let Some(t) = &mut self.timer {
            t.egui_end(&mut encoder);
        }
        // The window's content, again, into a texture we can read.
        let last_frame = exit_after.is_some_and(|n| self.stats.frames + 1 >= n);
        let want_window_shot = std::mem::take(&mut self.model.requests.screenshot)
            || (last_frame && capture.is_some());
        let shot = want_window_shot.then(|| {
            let texture = self.gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("window screenshot"),
                size: wgpu::Extent3d {
                    width: self.config.width,
                    height: self.config.height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: self.config.format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::COPY_SRC
                    | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            let view = texture.create_view(&Default::default());
            self.compose(
                &mut encoder,
                &texture,
                &view,
                &paint_jobs,
                &screen,
                &placements,
            );
            texture
        });
        if let Some(t) = &mut self.timer {
            t.finish(&mut encoder);
        }
        self.gpu
            .queue
            .submit(extra.into_iter().chain([encoder.finish()]));
        if let Some(t) = &mut self.timer {
            t.after_submit();
        }
        self.window.pre_present_notify();
        self.gpu.queue.present(surface_texture);
        for id in &to_free {
            self.egui_renderer.free_texture(id);
        }
        if suboptimal {
            self.configure();
        }

        let _ = self.gpu.device.poll(wgpu::PollType::Poll);
        if let Some(t) = &mut self.timer {
            if t.collect() && keep_times {
                if let Some(times) = t.latest {
                    self.pass_times.push(times);
                }
            }
            if !sampled && timed {
                t.latest = None;
            }
        }
        self.stats.tick(keep_times);

        if let Some(texture) = shot {
            let to_file = if last_frame { capture } else { None };
            self.save_window(&texture, to_file)?;
        }
        if std::mem::take(&mut self.model.requests.save_views) {
            self.save_views();
        }

        if exit_after.is_some_and(|n| self.stats.frames >= n) {
            return Ok(true);
        }
        // Keep drawing while anything is moving or converging.
        let converging = self
            .slots
            .iter()
            .any(|s| s.renderer.as_ref().is_some_and(|(r, _)| !r.converged()));
        let flying = self.model.nav == NavMode::Fly && self.model.move_keys.any();
        let egui_delay = full
            .viewport_output
            .get(&egui::ViewportId::ROOT)
            .map(|v| v.repaint_delay)
            .unwrap_or(Duration::MAX);
        if converging || flying || exit_after.is_some() || egui_delay.is_zero() {
            self.window.request_redraw();
        } else {
            self.stats.pause();
            if egui_delay < Duration::from_secs(3600) {
                self.repaint_at = Some(Instant::now() + egui_delay);
            }
        }
        Ok(false)
    }

    /// Where each shown view's texture goes in the window, in pixels: one
    /// copy per view, two parts under a wipe, clipped to the surface.
    fn placements(&self, rects: &[Rect], ppp: f32) -> Vec<Placement> {
        let surface = (self.config.width, self.config.height);
        let mut out = Vec::new();
        let mut push = |slot: usize, src: (u32, u32), dst: (u32, u32), size: (u32, u32)| {
            let w = size.0.min(surface.0.saturating_sub(dst.0));
            let h = size.1.min(surface.1.saturating_sub(dst.1));
            if w > 0 && h > 0 {
                out.push(Placement {
                    slot,
                    src,
                    dst,
                    size: (w, h),
                });
            }
        };
        let origin = |r: &Rect| {
            (
                (r.min.x * ppp).round().max(0.0) as u32,
                (r.min.y * ppp).round().max(0.0) as u32,
            )
        };
        let tex_size = |i: usize| {
            let t = &self.slots[i].texture;
            (t.width(), t.height())
        };
        if self.model.layout == Layout::Wipe {
            let Some(r) = rects.first() else {
                return out;
            };
            let dst = origin(r);
            let (w, h) = tex_size(0).min(tex_size(1));
            let split = ((w as f32 * self.model.wipe).round() as u32).min(w);
            push(0, (0, 0), dst, (split, h));
            push(1, (split, 0), (dst.0 + split, dst.1), (w - split, h));
        } else {
            for (i, r) in rects.iter().enumerate().take(self.slots.len()) {
                if self.slots[i].renderer.is_some() {
                    push(i, (0, 0), origin(r), tex_size(i));
                }
            }
        }
        out
    }

    /// The window's content into `target`: the views (copied, when the
    /// surface allows it) under egui's panel, labels and wipe line.
    fn compose(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target_texture: &wgpu::Texture,
        target: &wgpu::TextureView,
        paint_jobs: &[egui::ClippedPrimitive],
        screen: &egui_wgpu::ScreenDescriptor,
        placements: &[Placement],
    ) {
        let background = wgpu::Color {
            r: 0.02,
            g: 0.02,
            b: 0.025,
            a: 1.0,
        };
        let load = if self.direct {
            // Clear, copy the views in, then draw egui over them.
            drop(encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("clear window"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(background),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            }));
            for p in placements {
                encoder.copy_texture_to_texture(
                    wgpu::TexelCopyTextureInfo {
                        texture: &self.slots[p.slot].texture,
                        mip_level: 0,
                        origin: wgpu::Origin3d {
                            x: p.src.0,
                            y: p.src.1,
                            z: 0,
                        },
                        aspect: wgpu::TextureAspect::All,
                    },
                    wgpu::TexelCopyTextureInfo {
                        texture: target_texture,
                        mip_level: 0,
                        origin: wgpu::Origin3d {
                            x: p.dst.0,
                            y: p.dst.1,
                            z: 0,
                        },
                        aspect: wgpu::TextureAspect::All,
                    },
                    wgpu::Extent3d {
                        width: p.size.0,
                        height: p.size.1,
                        depth_or_array_layers: 1,
                    },
                );
            }
            wgpu::LoadOp::Load
        } else {
            wgpu::LoadOp::Clear(background)
        };
        let mut pass = encoder
            .begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("egui pass"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load,
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            })
            .forget_lifetime();
        self.egui_renderer.render(&mut pass, paint_jobs, screen);
    }

    /// Saves the window content: to `path` (for `--screenshot`), else to a
    /// new timestamped file in the screenshot folder.
    fn save_window(
        &mut self,
        texture: &wgpu::Texture,
        path: Option<&Path>,
    ) -> Result<(), AppError> {
        let rgba = read_rgba8(&self.gpu, texture, self.config.format)?;
        let (w, h) = (texture.width(), texture.height());
        match path {
            Some(p) => screenshot::save_png(p, w, h, &rgba).map_err(|e| AppError::Screenshot {
                path: p.display().to_string(),
                reason: e.to_string(),
            }),
            None => {
                let dir = self.screenshot_dir.clone();
                let stem = format!("celray-{}", screenshot::timestamp());
                match screenshot::save_new_png(&dir, &stem, w, h, &rgba) {
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
        }
    }

    /// Saves each shown view's image (full size, even under a wipe).
    fn save_views(&mut self) {
        let dir = self.screenshot_dir.clone();
        let stamp = screenshot::timestamp();
        let mut saved = Vec::new();
        for (i, slot) in self.slots.iter().enumerate() {
            let Some((renderer, pass)) = &slot.renderer else {
                continue;
            };
            let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
            renderer.encode_resolve(pass, &mut encoder, &slot.view);
            self.gpu.queue.submit([encoder.finish()]);
            let label = self.model.views[i].label();
            let stem = format!("celray-{stamp}-view{}-{}", i + 1, screenshot::slug(&label));
            let result = read_rgba8(&self.gpu, &slot.texture, self.view_format)
                .map_err(|e| e.to_string())
                .and_then(|rgba| {
                    screenshot::save_new_png(
                        &dir,
                        &stem,
                        slot.texture.width(),
                        slot.texture.height(),
                        &rgba,
                    )
                    .map_err(|e| e.to_string())
                });
            match result {
                Ok(p) => saved.push(p.display().to_string()),
                Err(e) => {
                    self.model.error = Some(format!("cannot save view {}: {e}", i + 1));
                    return;
                }
            }
        }
        self.model.status = Some(format!("saved {}", saved.join(", ")));
    }
}

/// The view area: images, labels, the wipe line, and the camera gestures
/// of pointer input that egui did not take. Returns the view rectangles.
fn views_ui(
    ui: &mut egui::Ui,
    area: Rect,
    model: &mut Model,
    textures: &[Option<egui::TextureId>],
    samples: &[u32],
) -> Vec<Rect> {
    let ppp = ui.ctx().pixels_per_point();
    let area = layout::snap(area, ppp);
    let rects = layout::view_rects(model.layout, area, ppp);
    // Camera gestures: only drags that start on the views and wheel turns
    // over them; a drag that starts on the panel or the wipe line is egui's.
    let response = ui.interact(area, Id::unique("celray views"), Sense::click_and_drag());
    let full_uv = Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0));
    let painter = ui.painter_at(area);
    if model.layout == Layout::Wipe {
        let parts = layout::wipe_parts(rects[0], model.wipe);
        for (i, (rect, uv)) in parts.iter().enumerate() {
            if let Some(id) = textures[i] {
                painter.image(id, *rect, *uv, Color32::WHITE);
            }
        }
    } else {
        for (i, rect) in rects.iter().enumerate() {
            if let Some(id) = textures[i] {
                painter.image(id, *rect, full_uv, Color32::WHITE);
            }
        }
    }
    let settings = settings_label(&model.settings);
    for (i, rect) in rects.iter().enumerate() {
        let text = format!(
            "{}  {} / {} spp  ({})",
            model.views[i].label(),
            samples.get(i).copied().unwrap_or(0),
            model.settings.spp,
            settings
        );
        let right = model.layout == Layout::Wipe && i == 1;
        let (anchor, pos) = if right {
            (Align2::RIGHT_TOP, rect.right_top() + egui::vec2(-8.0, 8.0))
        } else {
            (Align2::LEFT_TOP, rect.left_top() + egui::vec2(8.0, 8.0))
        };
        let galley_rect = painter.text(
            pos,
            anchor,
            &text,
            FontId::proportional(13.0),
            Color32::TRANSPARENT,
        );
        painter.rect_filled(galley_rect.expand(4.0), 3.0, Color32::from_black_alpha(170));
        painter.text(
            pos,
            anchor,
            &text,
            FontId::proportional(13.0),
            Color32::WHITE,
        );
    }
    if model.layout == Layout::Wipe {
        let x = area.min.x + area.width() * model.wipe;
        let handle = Rect::from_center_size(
            Pos2::new(x, area.center().y),
            egui::vec2(14.0, area.height()),
        );
        let wipe = ui
            .interact(handle, Id::unique("celray wipe line"), Sense::drag())
            .on_hover_cursor(egui::CursorIcon::ResizeHorizontal);
        if wipe.dragged() {
            model.wipe = (model.wipe + wipe.drag_delta().x / area.width().max(1.0)).clamp(0.0, 1.0);
        }
        let x = area.min.x + area.width() * model.wipe;
        painter.line_segment(
            [Pos2::new(x, area.min.y), Pos2::new(x, area.max.y)],
            Stroke::new(2.0, Color32::WHITE),
        );
        painter.circle_filled(Pos2::new(x, area.center().y), 7.0, Color32::WHITE);
    }
    camera_gestures(
        ui,
        &response,
        model,
        rects.first().map_or(1.0, |r| r.height()),
    );
    // A click (not a drag) on a view focuses the lens on what is under it.
    if response.clicked() {
        if let Some(pos) = response.interact_pointer_pos() {
            if let Some(rect) = rects.iter().find(|r| r.contains(pos)) {
                let uv = (pos - rect.min) / rect.size();
                if let Some(distance) =
                    controller::focus_at(&model.scene, glam::Vec2::new(uv.x, uv.y))
                {
                    model.scene.camera.focus_distance = Some(distance);
                }
            }
        }
    }
    rects
}

fn camera_gestures(ui: &egui::Ui, response: &egui::Response, model: &mut Model, view_h: f32) {
    let (mods, lines) = ui.input(|i| {
        // Wheel steps, from the raw events (egui's own scroll delta is
        // smoothed and turned into zoom when Ctrl is held).
        let lines: f32 = i
            .raw
            .events
            .iter()
            .map(|e| match e {
                egui::Event::MouseWheel { unit, delta, .. } => match unit {
                    egui::MouseWheelUnit::Line => delta.y,
                    egui::MouseWheelUnit::Point => delta.y / 50.0,
                    egui::MouseWheelUnit::Page => delta.y * 10.0,
                },
                _ => 0.0,
            })
            .sum();
        (
            Mods {
                shift: i.modifiers.shift,
                ctrl: i.modifiers.ctrl || i.modifiers.command,
                alt: i.modifiers.alt,
            },
            lines,
        )
    });
    let up = model.world_up;
    let cam = &model.scene.camera;
    let delta = response.drag_delta();
    let d = glam::Vec2::new(delta.x, delta.y);
    let buttons = [
        (PointerButton::Primary, DragButton::Left),
        (PointerButton::Secondary, DragButton::Right),
        (PointerButton::Middle, DragButton::Middle),
    ];
    if d != glam::Vec2::ZERO {
        if let Some((_, button)) = buttons.iter().find(|(b, _)| response.dragged_by(*b)) {
            model.scene.camera = match controller::drag_gesture(model.nav, *button, mods) {
                Gesture::Orbit => controller::orbit(cam, up, d, view_h),
                Gesture::Pan => controller::pan(cam, up, d, view_h),
                Gesture::Zoom => controller::dolly(cam, controller::drag_zoom_factor(d.y, view_h)),
                Gesture::Look => controller::look(cam, up, d, view_h),
            };
        }
    }
    if response.hovered() && lines != 0.0 {
        match model.nav {
            NavMode::Orbit => {
                model.scene.camera =
                    controller::dolly(&model.scene.camera, controller::wheel_zoom_factor(lines))
            }
            NavMode::Fly => {
                model.fly_speed = controller::fly_speed_after_wheel(model.fly_speed, lines)
            }
        }
    }
}
