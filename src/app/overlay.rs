//! The egui overlay: egui's context, its winit input state and its wgpu
//! renderer, and one frame of it from running the UI to the paint jobs.

use std::time::Duration;

use winit::window::Window;

use super::panel_cache::{self, PanelCache, PanelDraw, PxRect};
use crate::gpu::Gpu;

/// egui, as the window uses it.
pub(super) struct Overlay {
    pub ctx: egui::Context,
    pub state: egui_winit::State,
    pub painter: Painter,
}

/// egui's drawing, apart from its input: the renderer, the last
/// tessellation, what the renderer's buffers hold, and the panel cache.
pub(super) struct Painter {
    pub renderer: egui_wgpu::Renderer,
    format: wgpu::TextureFormat,
    /// The paint jobs last tessellated.
    last: Option<Tessellated>,
    /// What `renderer`'s buffers hold: the tessellation's number, which
    /// of its jobs the cache took (`None`: none) and the jobs left.
    uploaded: Option<(u64, Option<Vec<bool>>, PaintJobs)>,
    pub panel: PanelCache,
}

/// One tessellation of the UI's shapes, for a surface of `size` pixels;
/// `generation` counts them.
#[derive(Clone)]
struct Tessellated {
    jobs: PaintJobs,
    size: [u32; 2],
    generation: u64,
}

/// egui's part of a frame, ready to draw.
pub(super) struct OverlayDraw<'a> {
    pub renderer: &'a egui_wgpu::Renderer,
    /// The jobs drawn over the window (those the panel cache does not
    /// give).
    pub paint_jobs: &'a [egui::ClippedPrimitive],
    pub screen: &'a egui_wgpu::ScreenDescriptor,
    /// What the window is cleared to: the theme's panel colour (the panel
    /// itself draws no fill, see [`background`]).
    pub background: wgpu::Color,
    /// The panel cache's texture and the window's pixels it gives (all
    /// those outside the views), where the panel is cached.
    pub panel: Option<(&'a wgpu::Texture, &'a [PxRect])>,
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
pub(super) type PaintJobs = std::sync::Arc<[egui::ClippedPrimitive]>;

/// An [`OverlayFrame`] tessellated and uploaded, ready to draw.
pub(super) struct OverlayPaint {
    /// The jobs drawn over the window (all, where the panel is not cached).
    pub paint_jobs: PaintJobs,
    pub screen: egui_wgpu::ScreenDescriptor,
    /// Command buffers egui's callbacks recorded, submitted before the frame's.
    pub extra: Vec<wgpu::CommandBuffer>,
    to_free: Vec<egui::TextureId>,
    /// The window's clear colour ([`background`]).
    pub background: wgpu::Color,
    /// The panel cache's part in this frame, where the panel is cached.
    pub panel: Option<PanelDraw>,
}

impl OverlayPaint {
    /// The frame's drawing, with `painter`'s renderer and cache.
    pub fn draw<'a>(&'a self, painter: &'a Painter) -> OverlayDraw<'a> {
        let texture = painter.panel.texture();
        OverlayDraw {
            renderer: &painter.renderer,
            paint_jobs: &self.paint_jobs,
            screen: &self.screen,
            background: self.background,
            panel: (self.panel.as_ref()).and_then(|p| Some((texture?, &p.copies[..]))),
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
        Overlay {
            ctx,
            state,
            painter: Painter::new(&gpu.device, format),
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
                self.painter.update_texture(gpu, id, delta);
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

    /// Tessellates `frame` for a surface of `size_px` (or takes the last
    /// tessellation, for a frame drawn [`again`](OverlayFrame::again) on
    /// a surface of the same size) and records the uploads it needs into
    /// `encoder`. `views`: the window's pixels its views' images fill,
    /// where they are copied in (the panel cache's case, see
    /// [`super::panel_cache`]); `None` where egui draws them.
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        frame: OverlayFrame,
        size_px: [u32; 2],
        views: Option<&[PxRect]>,
    ) -> OverlayPaint {
        let background = background(self.ctx.global_style().visuals.panel_fill);
        (self.painter).prepare(
            &self.ctx,
            (gpu, encoder),
            frame,
            size_px,
            (views, background),
        )
    }

    /// Frees the textures egui let go of in `paint`'s frame (once presented).
    pub fn free_textures(&mut self, paint: &OverlayPaint) {
        for id in &paint.to_free {
            self.painter.renderer.free_texture(id);
            self.painter.panel.renderer.free_texture(id);
        }
    }
}

/// A renderer for egui's jobs into targets of `format`.
pub(super) fn egui_renderer(
    device: &wgpu::Device,
    format: wgpu::TextureFormat,
) -> egui_wgpu::Renderer {
    egui_wgpu::Renderer::new(
        device,
        format,
        // Dithering costs 40% of egui's GPU time on a CPU driver, for
        // no visible gain on an 8-bit panel.
        egui_wgpu::RendererOptions {
            dithering: false,
            ..Default::default()
        },
    )
}

impl Painter {
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Painter {
        Painter {
            renderer: egui_renderer(device, format),
            format,
            last: None,
            uploaded: None,
            panel: PanelCache::new(device, format),
        }
    }

    /// Applies one of egui's texture changes (to both renderers).
    pub fn update_texture(
        &mut self,
        gpu: &Gpu,
        id: egui::TextureId,
        delta: &egui::epaint::ImageDelta,
    ) {
        for r in [&mut self.renderer, &mut self.panel.renderer] {
            r.update_texture(&gpu.device, &gpu.queue, id, delta);
        }
    }

    /// [`Overlay::prepare`], given egui's context and the window's
    /// background colour.
    pub fn prepare(
        &mut self,
        ctx: &egui::Context,
        (gpu, encoder): (&Gpu, &mut wgpu::CommandEncoder),
        frame: OverlayFrame,
        size_px: [u32; 2],
        (views, background): (Option<&[PxRect]>, wgpu::Color),
    ) -> OverlayPaint {
        let ppp = frame.pixels_per_point;
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: size_px,
            pixels_per_point: ppp,
        };
        let tess = match &self.last {
            Some(last) if frame.again && last.size == size_px => last.clone(),
            _ => Tessellated {
                jobs: ctx.tessellate(frame.shapes, ppp).into(),
                size: size_px,
                generation: self.last.as_ref().map_or(0, |l| l.generation + 1),
            },
        };
        self.last = Some(tess.clone());
        let split = views.and_then(|v| Some((panel_cache::split(&tess.jobs, ppp, size_px, v)?, v)));
        let cached = split.as_ref().map(|(mask, _)| mask.clone());
        let mut extra = Vec::new();
        let paint_jobs = match &self.uploaded {
            Some((g, c, jobs)) if *g == tess.generation && *c == cached => jobs.clone(),
            _ => {
                let jobs: PaintJobs = match &cached {
                    Some(mask) => panel_cache::pick(&tess.jobs, mask, false),
                    None => tess.jobs.clone(),
                };
                extra = (self.renderer).update_buffers(
                    &gpu.device,
                    &gpu.queue,
                    encoder,
                    &jobs,
                    &screen,
                );
                self.uploaded = Some((tess.generation, cached.clone(), jobs.clone()));
                jobs
            }
        };
        let panel = split.map(|(mask, views)| {
            let job_set = (tess.generation, &tess.jobs[..], &mask[..]);
            let target = (&screen, background);
            PanelDraw {
                redraw: (self.panel).prepare((gpu, encoder), job_set, target, self.format),
                copies: panel_cache::outside(views, size_px),
            }
        });
        OverlayPaint {
            paint_jobs,
            screen,
            extra,
            to_free: frame.to_free,
            background,
            panel,
        }
    }

    /// Draws into the panel cache the jobs `paint` says it lacks, over the
    /// window's background (nothing where it holds them already).
    pub fn draw_panel(&self, encoder: &mut wgpu::CommandEncoder, paint: &OverlayPaint) {
        let (Some(texture), Some(jobs)) = (
            self.panel.texture(),
            (paint.panel.as_ref()).and_then(|p| p.redraw.as_ref()),
        ) else {
            return;
        };
        let load = wgpu::LoadOp::Clear(paint.background);
        let mut pass = super::surface::egui_pass(encoder, texture, load, "egui panel cache");
        self.panel.renderer.render(&mut pass, jobs, &paint.screen);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::AdapterChoice;

    /// egui's input for a screen of `size` pixels at 1 pixel per point.
    fn input(size: [u32; 2]) -> egui::RawInput {
        egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(
                egui::Pos2::ZERO,
                egui::vec2(size[0] as f32, size[1] as f32),
            )),
            ..Default::default()
        }
    }

    /// A frame drawn again from the last upload shows the same pixels as
    /// its first draw, text included, though it is neither tessellated nor
    /// uploaded again.
    #[test]
    fn a_frame_drawn_again_shows_the_same_pixels() {
        let gpu = Gpu::new_headless(&AdapterChoice::for_tests()).unwrap();
        let format = wgpu::TextureFormat::Rgba8Unorm;
        let mut painter = Painter::new(&gpu.device, format);
        let ctx = egui::Context::default();
        let size = [160u32, 48];
        let raw = input(size);
        let mut full = ctx.run_ui(raw, |ui| {
            ui.label("celray 1234");
        });
        for (id, deltas) in full.textures_delta.set.drain() {
            for delta in &deltas {
                painter.update_texture(&gpu, id, delta);
            }
        }
        let mut draw = |shapes: Vec<egui::epaint::ClippedShape>, again: bool| {
            let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
            let target =
                super::super::surface::window_texture(&gpu, "overlay test", size, format, usage);
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            let frame = OverlayFrame {
                shapes,
                pixels_per_point: 1.0,
                to_free: Vec::new(),
                repaint_delay: Duration::MAX,
                again,
            };
            let paint = painter.prepare(
                &ctx,
                (&gpu, &mut encoder),
                frame,
                size,
                (None, wgpu::Color::BLACK),
            );
            let load = wgpu::LoadOp::Clear(wgpu::Color::BLACK);
            let mut pass =
                super::super::surface::egui_pass(&mut encoder, &target, load, "overlay test");
            painter
                .renderer
                .render(&mut pass, &paint.paint_jobs, &paint.screen);
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
    /// A window composed with the panel cache is the same bytes as one
    /// composed without it (cleared, the view copied in, every job drawn
    /// over it), on the frame that draws the cache and on the next, which
    /// only copies it; and the cache did take the panel's text and left
    /// the view's label and the panel's edge line (drawn over the whole
    /// window after the panel) to the overlay pass.
    #[test]
    fn the_panel_cache_gives_the_same_window() {
        use super::super::surface::{self, Placement};
        let gpu = Gpu::new_headless(&AdapterChoice::for_tests()).unwrap();
        let format = wgpu::TextureFormat::Rgba8Unorm;
        let size = [320u32, 120];
        let texture = |label, usage| surface::window_texture(&gpu, label, size, format, usage);
        // The view's image: a gradient, so that a misplaced copy shows.
        let image = texture(
            "view",
            wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::COPY_DST,
        );
        let texels: Vec<u8> = (0..size[0] * size[1])
            .flat_map(|i| [(i % 251) as u8, (i / 320) as u8, 200, 255])
            .collect();
        gpu.queue.write_texture(
            image.as_image_copy(),
            &texels,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(size[0] * 4),
                rows_per_image: None,
            },
            wgpu::Extent3d {
                width: size[0],
                height: size[1],
                depth_or_array_layers: 1,
            },
        );
        let ctx = egui::Context::default();
        // The UI: a panel of five labels numbered from `first`, and a
        // label over the view.
        let run = |first: usize| {
            ctx.run_ui(input(size), |ui| {
                egui::Panel::left("panel")
                    .frame(panel_frame(ui.style()))
                    .default_size(120.0)
                    .show(ui, |ui| {
                        for i in first..first + 5 {
                            ui.label(format!("celray {i}"));
                        }
                    });
                let rect = ui.available_rect_before_wrap();
                let white = egui::Color32::WHITE;
                let centre = egui::Align2::CENTER_CENTER;
                (ui.painter_at(rect)).text(
                    rect.center(),
                    centre,
                    "view",
                    Default::default(),
                    white,
                );
            })
        };
        let mut painters = [
            Painter::new(&gpu.device, format),
            Painter::new(&gpu.device, format),
        ];
        let shapes_of = |mut full: egui::FullOutput, painters: &mut [Painter; 2]| {
            for (id, deltas) in full.textures_delta.set.drain() {
                for delta in &deltas {
                    painters
                        .iter_mut()
                        .for_each(|p| p.update_texture(&gpu, id, delta));
                }
            }
            full.shapes
        };
        let background = background(ctx.global_style().visuals.panel_fill);
        let shapes = shapes_of(run(0), &mut painters);
        let frame = |shapes: Vec<egui::epaint::ClippedShape>, again| OverlayFrame {
            shapes,
            pixels_per_point: 1.0,
            to_free: Vec::new(),
            repaint_delay: Duration::MAX,
            again,
        };
        // The view fills the window right of the panel (egui's panel is
        // 120 points wide here, its edge line at x = 120); later a smaller
        // one, moved.
        let fill = ((121, 0), (size[0] - 121, size[1]));
        let moved = ((150, 20), (120, 80));
        type At = ((u32, u32), (u32, u32));
        let compose = |painter: &mut Painter, frame: OverlayFrame, cached: bool, view: At| {
            let (view_at, view_size) = view;
            let views = [PxRect::at(view_at, view_size)];
            let target = texture(
                "window",
                wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::COPY_SRC
                    | wgpu::TextureUsages::COPY_DST,
            );
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            let views = cached.then_some(&views[..]);
            let paint =
                painter.prepare(&ctx, (&gpu, &mut encoder), frame, size, (views, background));
            painter.draw_panel(&mut encoder, &paint);
            let placements = [Placement {
                texture: &image,
                src: (0, 0),
                dst: view_at,
                size: view_size,
            }];
            let overlay = paint.draw(painter);
            let load = surface::compose_views(true, &mut encoder, &target, &placements, &overlay);
            surface::compose_overlay(&mut encoder, &target, load, &overlay);
            gpu.queue.submit([encoder.finish()]);
            let redrawn = (paint.panel.as_ref()).map(|p| p.redraw.is_some());
            let window = super::super::surface::read_rgba8(&gpu, &target, format).unwrap();
            (window, redrawn, paint.paint_jobs.len())
        };
        let [plain, cached] = &mut painters;
        let (want, _, all_jobs) = compose(plain, frame(shapes.clone(), false), false, fill);
        let (first, redrawn, left) = compose(cached, frame(shapes.clone(), false), true, fill);
        let (again, redrawn_again, _) = compose(cached, frame(Vec::new(), true), true, fill);
        // The same shapes tessellated anew (the UI ran again): the cache
        // holds their jobs already.
        let (anew, redrawn_anew, _) = compose(cached, frame(shapes, false), true, fill);
        // The view moved and shrunk, the jobs the same: the window outside
        // it now comes from the cache too.
        let (want_moved, _, _) = compose(plain, frame(Vec::new(), true), false, moved);
        let (got_moved, _, _) = compose(cached, frame(Vec::new(), true), true, moved);
        // Other text in the panel: drawn into the cache again.
        let other = shapes_of(run(5), &mut painters);
        let [plain, cached] = &mut painters;
        let (want_other, _, _) = compose(plain, frame(other.clone(), false), false, fill);
        let (got_other, redrawn_other, _) = compose(cached, frame(other, false), true, fill);
        assert_eq!(
            redrawn_other,
            Some(true),
            "other jobs are drawn into the cache"
        );
        assert!(want_other != want, "the other text shows");
        assert!(
            got_other == want_other,
            "the window with other text differs"
        );
        assert_eq!(redrawn, Some(true), "the first frame draws the cache");
        assert_eq!(redrawn_again, Some(false), "the next only copies it");
        assert_eq!(redrawn_anew, Some(false), "the same jobs tessellated anew");
        assert!(anew == want, "the window after a new tessellation differs");
        assert!(want_moved != want, "the moved view shows");
        assert!(
            got_moved == want_moved,
            "the window with the view moved differs"
        );
        assert!(
            0 < left && left < all_jobs,
            "{left} of {all_jobs} jobs drawn over the window"
        );
        let panel_lit = (want.chunks_exact(4).enumerate())
            .filter(|(i, p)| (*i as u32 % size[0]) < 120 && p[0] > 100)
            .count();
        assert!(
            panel_lit > 50,
            "the panel's text drew {panel_lit} light pixels"
        );
        assert!(first == want, "the window drawn with the cache differs");
        assert!(again == want, "the window copied from the cache differs");
    }
}
