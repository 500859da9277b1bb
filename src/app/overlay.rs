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
    /// The paint jobs last tessellated and uploaded into `renderer`'s
    /// buffers, and the surface size they were uploaded for.
    last_paint: Option<(PaintJobs, [u32; 2])>,
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
    /// The last frame's paint jobs again, instead of `shapes`.
    again: bool,
}

impl OverlayFrame {
    /// The same frame drawn again: [`Overlay::prepare`] draws the paint
    /// jobs it last tessellated and uploaded, and nothing is left to free
    /// (the run that made them freed its textures).
    pub fn again(&self) -> OverlayFrame {
        OverlayFrame {
            shapes: Vec::new(),
            pixels_per_point: self.pixels_per_point,
            to_free: Vec::new(),
            repaint_delay: self.repaint_delay,
            again: true,
        }
    }

    /// A frame with no shapes that asks to be drawn again after
    /// `repaint_delay`.
    #[cfg(test)]
    pub fn empty(repaint_delay: Duration) -> OverlayFrame {
        OverlayFrame {
            shapes: Vec::new(),
            pixels_per_point: 1.0,
            to_free: Vec::new(),
            repaint_delay,
            again: false,
        }
    }
}

/// Tessellated paint jobs, shared between the frame that drew them and
/// the frames that draw them again.
type PaintJobs = std::sync::Arc<[egui::ClippedPrimitive]>;

/// An [`OverlayFrame`] tessellated and uploaded, ready to draw.
pub(super) struct OverlayPaint {
    pub paint_jobs: PaintJobs,
    pub screen: egui_wgpu::ScreenDescriptor,
    /// Command buffers egui's callbacks recorded, submitted before the frame's.
    pub extra: Vec<wgpu::CommandBuffer>,
    to_free: Vec<egui::TextureId>,
    /// The window's clear colour ([`background`]).
    pub background: wgpu::Color,
}

/// The paint jobs of `shapes` on `screen`, tessellated and uploaded into
/// `renderer`'s buffers, and the command buffers egui's callbacks recorded;
/// `last` is the last upload. Drawn `again` on a screen of the same size,
/// the last upload's jobs, which the buffers still hold.
fn paint(
    ctx: &egui::Context,
    renderer: &mut egui_wgpu::Renderer,
    last: &mut Option<(PaintJobs, [u32; 2])>,
    (gpu, encoder): (&Gpu, &mut wgpu::CommandEncoder),
    shapes: Vec<egui::epaint::ClippedShape>,
    again: bool,
    screen: &egui_wgpu::ScreenDescriptor,
) -> (PaintJobs, Vec<wgpu::CommandBuffer>) {
    match last {
        Some((jobs, size)) if again && *size == screen.size_in_pixels => (jobs.clone(), Vec::new()),
        _ => {
            let jobs: PaintJobs = ctx.tessellate(shapes, screen.pixels_per_point).into();
            let extra = renderer.update_buffers(&gpu.device, &gpu.queue, encoder, &jobs, screen);
            *last = Some((jobs.clone(), screen.size_in_pixels));
            (jobs, extra)
        }
    }
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
            last_paint: None,
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
            again: false,
        }
    }

    /// Tessellates `frame` for a surface of `size_px` and records the
    /// upload of its buffers into `encoder`; a frame drawn [`again`]
    /// (OverlayFrame::again) on a surface of the same size reuses the last
    /// upload, which the renderer's buffers still hold.
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        frame: OverlayFrame,
        size_px: [u32; 2],
    ) -> OverlayPaint {
        let ppp = frame.pixels_per_point;
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: size_px,
            pixels_per_point: ppp,
        };
        let (paint_jobs, extra) = paint(
            &self.ctx,
            &mut self.renderer,
            &mut self.last_paint,
            (gpu, encoder),
            frame.shapes,
            frame.again,
            &screen,
        );
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::AdapterChoice;

    /// A frame drawn again from the last upload shows the same pixels as
    /// its first draw, text included, though it is neither tessellated nor
    /// uploaded again.
    #[test]
    fn a_frame_drawn_again_shows_the_same_pixels() {
        let gpu = Gpu::new_headless(&AdapterChoice::for_tests()).unwrap();
        let format = wgpu::TextureFormat::Rgba8Unorm;
        let mut renderer =
            egui_wgpu::Renderer::new(&gpu.device, format, egui_wgpu::RendererOptions::default());
        let ctx = egui::Context::default();
        let size = [160u32, 48];
        let raw = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(
                egui::Pos2::ZERO,
                egui::vec2(size[0] as f32, size[1] as f32),
            )),
            ..Default::default()
        };
        let mut full = ctx.run_ui(raw, |ui| {
            ui.label("celray 1234");
        });
        for (id, deltas) in full.textures_delta.set.drain() {
            for delta in &deltas {
                renderer.update_texture(&gpu.device, &gpu.queue, id, delta);
            }
        }
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: size,
            pixels_per_point: 1.0,
        };
        let mut last = None;
        let mut draw = |shapes: Vec<egui::epaint::ClippedShape>, again: bool| {
            let target = gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("overlay test"),
                size: wgpu::Extent3d {
                    width: size[0],
                    height: size[1],
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            });
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            let (jobs, _) = paint(
                &ctx,
                &mut renderer,
                &mut last,
                (&gpu, &mut encoder),
                shapes,
                again,
                &screen,
            );
            let view = target.create_view(&Default::default());
            let mut pass = encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("overlay test"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                })
                .forget_lifetime();
            renderer.render(&mut pass, &jobs, &screen);
            drop(pass);
            gpu.queue.submit([encoder.finish()]);
            super::super::surface::read_rgba8(&gpu, &target, format).unwrap()
        };
        let first = draw(full.shapes, false);
        let again = draw(Vec::new(), true);
        let lit = first.chunks_exact(4).filter(|p| p[0] > 100).count();
        assert!(lit > 20, "the label drew {lit} light pixels");
        assert!(first == again, "the frame drawn again differs");
    }
}
