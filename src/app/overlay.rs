//! The egui overlay: egui's context, its winit input state and its wgpu
//! renderer, and one frame of it from running the UI to the paint jobs.

use std::time::Duration;

use winit::window::Window;

use crate::gpu::Gpu;

/// egui, as the window uses it.
pub(super) struct Overlay {
    pub ctx: egui::Context,
    pub state: egui_winit::State,
    pub renderer: egui_wgpu::Renderer,
}

/// egui's part of a frame, ready to draw.
pub(super) struct OverlayDraw<'a> {
    pub renderer: &'a egui_wgpu::Renderer,
    pub paint_jobs: &'a [egui::ClippedPrimitive],
    pub screen: &'a egui_wgpu::ScreenDescriptor,
    /// What the window is cleared to: the theme's panel colour (the panel
    /// itself draws no fill, see [`background`]).
    pub background: wgpu::Color,
}

/// One frame of the UI, after it ran: what to draw and when to draw again.
pub(super) struct OverlayFrame {
    shapes: Vec<egui::epaint::ClippedShape>,
    pub pixels_per_point: f32,
    /// Textures to free once the frame is presented.
    to_free: Vec<egui::TextureId>,
    /// When egui wants to be drawn again.
    pub repaint_delay: Duration,
}

/// An [`OverlayFrame`] tessellated and uploaded, ready to draw.
pub(super) struct OverlayPaint {
    pub paint_jobs: Vec<egui::ClippedPrimitive>,
    pub screen: egui_wgpu::ScreenDescriptor,
    /// Command buffers egui's callbacks recorded, submitted before the frame's.
    pub extra: Vec<wgpu::CommandBuffer>,
    to_free: Vec<egui::TextureId>,
    /// The window's clear colour ([`background`]).
    pub background: wgpu::Color,
}

/// The side panel's frame: the theme's, without its fill. The window is
/// cleared to the fill's colour instead ([`background`]), so egui does not
/// draw the panel's area a second time: on a CPU driver that fill was 0.3
/// of egui's GPU time (docs/performance.md).
pub(super) fn panel_frame(style: &egui::Style) -> egui::Frame {
    egui::Frame::side_top_panel(style).fill(egui::Color32::TRANSPARENT)
}

/// The clear colour that stores `fill`'s bytes in the window's 8-bit
/// non-sRGB targets, where egui writes its (sRGB-encoded) colours as they
/// are.
pub(super) fn background(fill: egui::Color32) -> wgpu::Color {
    let [r, g, b, _] = fill.to_normalized_gamma_f32().map(f64::from);
    wgpu::Color { r, g, b, a: 1.0 }
}

impl Overlay {
    pub fn new(gpu: &Gpu, window: &Window, format: wgpu::TextureFormat) -> Overlay {
        let ctx = egui::Context::default();
        let state = egui_winit::State::new(
            ctx.clone(),
            egui::ViewportId::ROOT,
            window,
            Some(window.scale_factor() as f32),
            window.theme(),
            Some(gpu.device.limits().max_texture_dimension_2d as usize),
        );
        let renderer = egui_wgpu::Renderer::new(
            &gpu.device,
            format,
            // Dithering costs 40% of egui's GPU time on a CPU driver, for
            // no visible gain on an 8-bit panel.
            egui_wgpu::RendererOptions {
                dithering: false,
                ..Default::default()
            },
        );
        Overlay {
            ctx,
            state,
            renderer,
        }
    }

    /// Runs the UI (`build`) on the window's input, applies egui's texture
    /// changes at once (they must not be lost, whatever happens later in
    /// the frame) and its platform output.
    pub fn run(
        &mut self,
        gpu: &Gpu,
        window: &Window,
        build: impl FnMut(&mut egui::Ui),
    ) -> OverlayFrame {
        let raw = self.state.take_egui_input(window);
        let mut full = self.ctx.run_ui(raw, build);
        for (id, deltas) in full.textures_delta.set.drain() {
            for delta in &deltas {
                self.renderer
                    .update_texture(&gpu.device, &gpu.queue, id, delta);
            }
        }
        let to_free = full.textures_delta.free.drain().collect();
        self.state
            .handle_platform_output(window, full.platform_output);
        let repaint_delay = full
            .viewport_output
            .get(&egui::ViewportId::ROOT)
            .map(|v| v.repaint_delay)
            .unwrap_or(Duration::MAX);
        OverlayFrame {
            shapes: full.shapes,
            pixels_per_point: full.pixels_per_point,
            to_free,
            repaint_delay,
        }
    }

    /// Tessellates `frame` for a surface of `size_px` and records the
    /// upload of its buffers into `encoder`.
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        frame: OverlayFrame,
        size_px: [u32; 2],
    ) -> OverlayPaint {
        let ppp = frame.pixels_per_point;
        let paint_jobs = self.ctx.tessellate(frame.shapes, ppp);
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: size_px,
            pixels_per_point: ppp,
        };
        let extra =
            self.renderer
                .update_buffers(&gpu.device, &gpu.queue, encoder, &paint_jobs, &screen);
        OverlayPaint {
            paint_jobs,
            screen,
            extra,
            to_free: frame.to_free,
            background: background(self.ctx.global_style().visuals.panel_fill),
        }
    }

    /// Frees the textures egui let go of in `paint`'s frame (once presented).
    pub fn free_textures(&mut self, paint: &OverlayPaint) {
        for id in &paint.to_free {
            self.renderer.free_texture(id);
        }
    }
}
