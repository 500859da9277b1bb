//! The window's surface: opening it (window, instance, adapter, format),
//! configuring and acquiring frames, composing a frame (the views' images
//! copied in, egui's overlay drawn over them) and reading the window's
//! content back for screenshots.

use std::sync::Arc;

use egui::Rect;
use winit::event_loop::ActiveEventLoop;
use winit::window::Window;

use super::layout::Layout;
use super::overlay::OverlayDraw;
use super::AppError;
use crate::gpu::{AdapterChoice, Gpu, GpuError};

/// Format of each view's image when egui draws it (the fallback for
/// surfaces that cannot be copied into). egui 0.37 treats textures as
/// holding sRGB-encoded ("gamma") values, so it is not an sRGB format and
/// the resolve pass encodes in the shader.
const EGUI_VIEW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// The window and the surface it presents.
pub(super) struct WindowSurface {
    pub window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    pub config: wgpu::SurfaceConfiguration,
    present_modes: Vec<wgpu::PresentMode>,
    /// Views are copied into the surface (else drawn by egui).
    pub direct: bool,
    /// The format of the views' images.
    pub view_format: wgpu::TextureFormat,
    pub minimized: bool,
}

/// What asking the surface for a frame gave.
pub(super) enum Acquired {
    Frame {
        texture: wgpu::SurfaceTexture,
        suboptimal: bool,
    },
    /// No frame now; a redraw is requested. `idle`: the wait is not a frame
    /// interval; `error`: a message for the panel.
    Retry { idle: bool, error: Option<String> },
}

/// A copy of (part of) a view's image into the window.
pub(super) struct Placement<'a> {
    pub texture: &'a wgpu::Texture,
    pub src: (u32, u32),
    pub dst: (u32, u32),
    pub size: (u32, u32),
}

impl WindowSurface {
    /// Opens a window titled `title` of `size` logical pixels and a device
    /// on an adapter (`choice`) that can present to it.
    pub fn open(
        event_loop: &ActiveEventLoop,
        title: &str,
        size: (u32, u32),
        choice: &AdapterChoice,
    ) -> Result<(WindowSurface, Gpu), AppError> {
        let attributes = Window::default_attributes()
            .with_title(title)
            .with_inner_size(winit::dpi::LogicalSize::new(size.0.max(1), size.1.max(1)));
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
        let adapter = crate::gpu::pick_adapter(adapters, choice)?;
        let gpu = Gpu::from_adapter(instance, adapter)?;
        let caps = surface.get_capabilities(&gpu.adapter);
        let config = surface_config(&caps, window.inner_size())?;
        let direct = config.usage.contains(wgpu::TextureUsages::COPY_DST);
        let minimized = config.width == 0 || config.height == 0;
        let config = wgpu::SurfaceConfiguration {
            width: config.width.max(1),
            height: config.height.max(1),
            ..config
        };
        Ok((
            WindowSurface {
                window,
                surface,
                view_format: if direct {
                    config.format
                } else {
                    EGUI_VIEW_FORMAT
                },
                config,
                present_modes: caps.present_modes,
                direct,
                minimized,
            },
            gpu,
        ))
    }

    /// Configures the surface at its size, with the present mode `vsync` asks for.
    pub fn configure(&mut self, gpu: &Gpu, vsync: bool) {
        let wanted = if vsync {
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
        self.surface.configure(&gpu.device, &self.config);
    }

    /// The window's new size (a zero size minimizes: nothing is drawn).
    pub fn resize(&mut self, gpu: &Gpu, size: winit::dpi::PhysicalSize<u32>, vsync: bool) {
        self.minimized = size.width == 0 || size.height == 0;
        if !self.minimized {
            self.config.width = size.width;
            self.config.height = size.height;
            self.configure(gpu, vsync);
        }
    }

    /// The next frame to draw into, or why there is none now (having
    /// reconfigured or recreated the surface where that helps).
    pub fn acquire(&mut self, gpu: &Gpu, vsync: bool) -> Result<Acquired, AppError> {
        let retry = |idle, error| Acquired::Retry { idle, error };
        let acquired = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(texture) => Acquired::Frame {
                texture,
                suboptimal: false,
            },
            wgpu::CurrentSurfaceTexture::Suboptimal(texture) => Acquired::Frame {
                texture,
                suboptimal: true,
            },
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                retry(true, None)
            }
            wgpu::CurrentSurfaceTexture::Outdated => {
                self.configure(gpu, vsync);
                retry(false, None)
            }
            wgpu::CurrentSurfaceTexture::Lost => {
                self.surface = gpu
                    .instance
                    .create_surface(self.window.clone())
                    .map_err(|e| AppError::Surface(e.to_string()))?;
                self.configure(gpu, vsync);
                retry(false, None)
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                let e = gpu.take_errors().err();
                let message = format!("surface: {}", e.map_or_else(String::new, |e| e.to_string()));
                self.configure(gpu, vsync);
                retry(false, Some(message))
            }
        };
        if matches!(acquired, Acquired::Retry { .. }) {
            self.window.request_redraw();
        }
        Ok(acquired)
    }

    /// A texture like the surface's, to compose the window into and read back.
    pub fn screenshot_texture(&self, gpu: &Gpu) -> wgpu::Texture {
        let size = [self.config.width, self.config.height];
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::COPY_SRC
            | wgpu::TextureUsages::COPY_DST;
        window_texture(gpu, "window screenshot", size, self.config.format, usage)
    }

    /// Where each shown view's image goes in the window, in pixels: one
    /// copy per view, two parts under a wipe, clipped to the surface.
    /// `images[i]` is view i's image, when it shows one.
    pub fn placements<'a>(
        &self,
        layout: Layout,
        wipe: f32,
        rects: &[Rect],
        ppp: f32,
        images: &[(&'a wgpu::Texture, bool)],
    ) -> Vec<Placement<'a>> {
        let surface = (self.config.width, self.config.height);
        let mut out = Vec::new();
        let mut push = |texture, src: (u32, u32), dst: (u32, u32), size: (u32, u32)| {
            let w = size.0.min(surface.0.saturating_sub(dst.0));
            let h = size.1.min(surface.1.saturating_sub(dst.1));
            if w > 0 && h > 0 {
                out.push(Placement {
                    texture,
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
        let size = |t: &wgpu::Texture| (t.width(), t.height());
        if layout == Layout::Wipe {
            let (Some(r), [(left, _), (right, _), ..]) = (rects.first(), images) else {
                return out;
            };
            let dst = origin(r);
            let (w, h) = size(left).min(size(right));
            let split = ((w as f32 * wipe).round() as u32).min(w);
            push(*left, (0, 0), dst, (split, h));
            push(*right, (split, 0), (dst.0 + split, dst.1), (w - split, h));
        } else {
            for (r, (texture, shown)) in rects.iter().zip(images) {
                if *shown {
                    push(*texture, (0, 0), origin(r), size(texture));
                }
            }
        }
        out
    }

    /// The window's content into `target`: the views (copied, when the
    /// surface allows it) under egui's panel, labels and wipe line.
    pub fn compose(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::Texture,
        placements: &[Placement],
        overlay: &OverlayDraw,
    ) {
        let load = compose_views(self.direct, encoder, target, placements, overlay);
        compose_overlay(encoder, target, load, overlay);
    }
}

/// The first half of [`WindowSurface::compose`]: where the views are
/// copied in (`direct`), copies them and the panel cache's pixels
/// outside them, or where the panel is not cached, clears `target` to the
/// background first; returns how the overlay pass is to load `target`.
pub(super) fn compose_views(
    direct: bool,
    encoder: &mut wgpu::CommandEncoder,
    target: &wgpu::Texture,
    placements: &[Placement],
    overlay: &OverlayDraw,
) -> wgpu::LoadOp<wgpu::Color> {
    if !direct {
        return wgpu::LoadOp::Clear(overlay.background);
    }
    if overlay.panel.is_none() {
        let view = target.create_view(&Default::default());
        drop(encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("clear window"),
            color_attachments: &[Some(color_attachment(
                &view,
                wgpu::LoadOp::Clear(overlay.background),
            ))],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        }));
    }
    for p in placements {
        copy_placement(encoder, p, target);
    }
    // Every pixel outside the views, from the cache (which holds the
    // background where no panel job drew).
    if let Some((cache, copies)) = overlay.panel {
        for r in copies {
            let p = Placement {
                texture: cache,
                src: (r.x0, r.y0),
                dst: (r.x0, r.y0),
                size: (r.x1 - r.x0, r.y1 - r.y0),
            };
            copy_placement(encoder, &p, target);
        }
    }
    wgpu::LoadOp::Load
}

/// The second half of [`WindowSurface::compose`]: egui's pass over
/// `target` (the jobs the panel cache does not give), loaded as
/// [`compose_views`] said.
pub(super) fn compose_overlay(
    encoder: &mut wgpu::CommandEncoder,
    target: &wgpu::Texture,
    load: wgpu::LoadOp<wgpu::Color>,
    overlay: &OverlayDraw,
) {
    let mut pass = egui_pass(encoder, target, load, "egui pass");
    overlay
        .renderer
        .render(&mut pass, overlay.paint_jobs, overlay.screen);
}

/// The surface's configuration: a non-sRGB format (egui wants one; the
/// resolve pass encodes for it) and, where the surface can be copied into,
/// `COPY_DST` so that the views are copied in (far cheaper than drawing
/// them as egui images on a CPU driver). CELRAY_EGUI_VIEWS=1 forces the
/// egui path (tests cover both).
fn surface_config(
    caps: &wgpu::SurfaceCapabilities,
    size: winit::dpi::PhysicalSize<u32>,
) -> Result<wgpu::SurfaceConfiguration, AppError> {
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
    let direct = caps.usages.contains(wgpu::TextureUsages::COPY_DST)
        && std::env::var_os("CELRAY_EGUI_VIEWS").is_none();
    Ok(wgpu::SurfaceConfiguration {
        usage: if direct {
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_DST
        } else {
            wgpu::TextureUsages::RENDER_ATTACHMENT
        },
        format,
        width: size.width,
        height: size.height,
        present_mode: wgpu::PresentMode::Fifo,
        desired_maximum_frame_latency: 2,
        alpha_mode: caps
            .alpha_modes
            .first()
            .copied()
            .unwrap_or(wgpu::CompositeAlphaMode::Auto),
        view_formats: vec![],
        color_space: wgpu::SurfaceColorSpace::Auto,
    })
}

/// A 2D texture of `size` pixels (at least 1 x 1) in `format`.
pub(super) fn window_texture(
    gpu: &Gpu,
    label: &str,
    size: [u32; 2],
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    let [w, h] = size.map(|n| n.max(1));
    crate::render::targets::texture(gpu, label, w, h, format, usage)
}

/// A render pass over all of `target`, loaded as `load`, for egui to
/// draw into.
pub(super) fn egui_pass(
    encoder: &mut wgpu::CommandEncoder,
    target: &wgpu::Texture,
    load: wgpu::LoadOp<wgpu::Color>,
    label: &str,
) -> wgpu::RenderPass<'static> {
    let view = target.create_view(&Default::default());
    encoder
        .begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(label),
            color_attachments: &[Some(color_attachment(&view, load))],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        })
        .forget_lifetime()
}

fn color_attachment(
    view: &wgpu::TextureView,
    load: wgpu::LoadOp<wgpu::Color>,
) -> wgpu::RenderPassColorAttachment<'_> {
    wgpu::RenderPassColorAttachment {
        view,
        depth_slice: None,
        resolve_target: None,
        ops: wgpu::Operations {
            load,
            store: wgpu::StoreOp::Store,
        },
    }
}

fn copy_placement(encoder: &mut wgpu::CommandEncoder, p: &Placement, target: &wgpu::Texture) {
    let at = |(x, y): (u32, u32)| wgpu::Origin3d { x, y, z: 0 };
    encoder.copy_texture_to_texture(
        wgpu::TexelCopyTextureInfo {
            texture: p.texture,
            mip_level: 0,
            origin: at(p.src),
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyTextureInfo {
            texture: target,
            mip_level: 0,
            origin: at(p.dst),
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::Extent3d {
            width: p.size.0,
            height: p.size.1,
            depth_or_array_layers: 1,
        },
    );
}

/// Reads a texture of `format` back as RGBA8 (swizzling BGRA).
pub(super) fn read_rgba8(
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
