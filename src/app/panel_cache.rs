//! egui's panel drawn once and copied into each window frame.
//!
//! On a CPU driver egui's overlay costs about what its triangles do (the
//! side panel's text is some 6,000 of them: 2.6 ms a frame on lavapipe),
//! though between two runs of the UI ([`super::live`] runs it a few times
//! a second) it draws the same paint jobs again. So the jobs that lie
//! outside the views' images are drawn, when they change, into a texture
//! of the window's size (cleared to the window's background, as the window
//! is), and every frame copies that texture's part outside the views into
//! the window: a copy of the panel's pixels instead of drawing them, and no
//! clear of the window, whose every pixel is then a view's or the cache's.
//! The jobs left (labels over the views, the wipe line) are drawn over the
//! window as before.
//!
//! The window's pixels are the same bytes either way: a cached job draws
//! the same triangles onto the same background in the same order, only
//! into another texture of the same format, and it may be cached only
//! where its scissor rectangle (egui-wgpu's, rounded as egui-wgpu rounds
//! it) misses every view, and where no job drawn before it and left
//! uncached may touch the cache's pixels (else that job would end up
//! under it). Where that does not hold, nothing is cached ([`split`]).

use egui::epaint::Primitive;
use egui::ClippedPrimitive;

use super::surface::window_texture;

/// A rectangle of window pixels, `[x0, x1) x [y0, y1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct PxRect {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl PxRect {
    /// The rectangle of `size` pixels whose top left corner is `at`.
    pub fn at(at: (u32, u32), size: (u32, u32)) -> PxRect {
        PxRect {
            x0: at.0,
            y0: at.1,
            x1: at.0 + size.0,
            y1: at.1 + size.1,
        }
    }

    fn is_empty(self) -> bool {
        self.x0 >= self.x1 || self.y0 >= self.y1
    }

    fn overlaps(self, o: PxRect) -> bool {
        !self.is_empty()
            && !o.is_empty()
            && self.x0 < o.x1
            && o.x0 < self.x1
            && self.y0 < o.y1
            && o.y0 < self.y1
    }

    fn contains(self, o: PxRect) -> bool {
        self.x0 <= o.x0 && o.x1 <= self.x1 && self.y0 <= o.y0 && o.y1 <= self.y1
    }
}

/// The pixels egui-wgpu lets a job with `clip` draw to (its scissor
/// rectangle: the clip rectangle in pixels, each side rounded to the
/// nearest pixel edge, clamped to the target of `size`).
pub(super) fn scissor(clip: egui::Rect, pixels_per_point: f32, size: [u32; 2]) -> PxRect {
    let px = |v: f32| (pixels_per_point * v).round() as u32;
    let x0 = px(clip.min.x).min(size[0]);
    let y0 = px(clip.min.y).min(size[1]);
    PxRect {
        x0,
        y0,
        x1: px(clip.max.x).clamp(x0, size[0]),
        y1: px(clip.max.y).clamp(y0, size[1]),
    }
}

/// Which of `jobs` to draw into the cache, on a window of `size` pixels
/// whose views' images fill `views`: every mesh of egui's own textures
/// whose scissor misses every view, provided no job before the last of
/// them that is left out may draw outside the views. `None` when nothing
/// is to be cached, or that proviso fails (then every job is drawn over
/// the window, as without a cache).
pub(super) fn split(
    jobs: &[ClippedPrimitive],
    pixels_per_point: f32,
    size: [u32; 2],
    views: &[PxRect],
) -> Option<Vec<bool>> {
    let scissors: Vec<PxRect> = jobs
        .iter()
        .map(|j| scissor(j.clip_rect, pixels_per_point, size))
        .collect();
    let cached: Vec<bool> = jobs
        .iter()
        .zip(&scissors)
        .map(|(job, s)| {
            let own_texture = match &job.primitive {
                Primitive::Mesh(mesh) => matches!(mesh.texture_id, egui::TextureId::Managed(_)),
                Primitive::Callback(_) => false,
            };
            own_texture && !s.is_empty() && !views.iter().any(|v| v.overlaps(*s))
        })
        .collect();
    let last = cached.iter().rposition(|&c| c)?;
    // A job left out before the last cached one must stay inside one view
    // (or draw nothing), so that the cache's pixels never cover it.
    let inside_views = |s: &PxRect| s.is_empty() || views.iter().any(|v| v.contains(*s));
    let ordered = (cached[..last].iter().zip(&scissors)).all(|(&c, s)| c || inside_views(s));
    ordered.then_some(cached)
}

/// The window's pixels outside `views` (clipped to `size`), as disjoint
/// rectangles: the cells of the grid the views' edges cut the window
/// into that no view covers, merged along each row of cells.
pub(super) fn outside(views: &[PxRect], size: [u32; 2]) -> Vec<PxRect> {
    let edges = |lo: fn(&PxRect) -> u32, hi: fn(&PxRect) -> u32, end: u32| {
        let mut e: Vec<u32> = views.iter().flat_map(|v| [lo(v), hi(v)]).collect();
        e.extend([0, end]);
        e.iter_mut().for_each(|x| *x = (*x).min(end));
        e.sort_unstable();
        e.dedup();
        e
    };
    let xs = edges(|v| v.x0, |v| v.x1, size[0]);
    let ys = edges(|v| v.y0, |v| v.y1, size[1]);
    let mut out = Vec::new();
    for row in ys.windows(2) {
        let mut open: Option<PxRect> = None;
        for col in xs.windows(2) {
            let cell = PxRect {
                x0: col[0],
                y0: row[0],
                x1: col[1],
                y1: row[1],
            };
            if views.iter().any(|v| v.contains(cell)) {
                out.extend(open.take());
            } else {
                let r = open.get_or_insert(cell);
                r.x1 = cell.x1;
            }
        }
        out.extend(open);
    }
    out
}

/// Whether two lists of jobs draw the same: the same meshes under the
/// same clip rectangles (a callback is never the same).
fn same_jobs(a: &[ClippedPrimitive], b: &[ClippedPrimitive]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(a, b)| {
            a.clip_rect == b.clip_rect
                && matches!((&a.primitive, &b.primitive),
                    (Primitive::Mesh(x), Primitive::Mesh(y)) if x == y)
        })
}

/// The jobs whose `cached` flag is `which`, in order.
pub(super) fn pick(
    jobs: &[ClippedPrimitive],
    cached: &[bool],
    which: bool,
) -> super::overlay::PaintJobs {
    let picked = jobs.iter().zip(cached).filter(|&(_, &c)| c == which);
    picked.map(|(j, _)| j.clone()).collect()
}

/// The cache: its own egui renderer (whose buffers hold the cached jobs,
/// while the overlay's hold the others), the texture and what it holds.
pub(super) struct PanelCache {
    pub renderer: egui_wgpu::Renderer,
    texture: Option<wgpu::Texture>,
    /// What `texture` holds; `None` until drawn.
    holds: Option<Held>,
}

/// What the cache's texture holds: the jobs drawn into it, over which
/// background, at which scale; and the last tessellation (its number and
/// which of its jobs were cached) found to hold the same.
struct Held {
    jobs: super::overlay::PaintJobs,
    background: wgpu::Color,
    pixels_per_point: f32,
    seen: (u64, Vec<bool>),
}

/// This frame's use of the cache.
pub(super) struct PanelDraw {
    /// The jobs to draw into the cache first, where it does not hold them.
    pub redraw: Option<super::overlay::PaintJobs>,
    /// The window's pixels the cache gives (outside the views).
    pub copies: Vec<PxRect>,
}

impl PanelCache {
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> PanelCache {
        PanelCache {
            renderer: super::overlay::egui_renderer(device, format),
            texture: None,
            holds: None,
        }
    }

    /// Makes the cache ready for tessellation `generation`'s `jobs` of
    /// which `cached` are cached, over `background`, on a window of
    /// `screen`'s size; returns the jobs to draw into it where it does not
    /// hold the same already (uploaded into its renderer's buffers). A new
    /// tessellation of the same jobs (the UI runs a few times a second,
    /// and every frame while input arrives) draws nothing.
    pub fn prepare(
        &mut self,
        (gpu, encoder): (&crate::gpu::Gpu, &mut wgpu::CommandEncoder),
        (generation, jobs, cached): (u64, &[ClippedPrimitive], &[bool]),
        (screen, background): (&egui_wgpu::ScreenDescriptor, wgpu::Color),
        format: wgpu::TextureFormat,
    ) -> Option<super::overlay::PaintJobs> {
        let size = screen.size_in_pixels.map(|n| n.max(1));
        let fits = |t: &wgpu::Texture| t.width() == size[0] && t.height() == size[1];
        if !self.texture.as_ref().is_some_and(fits) {
            let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
            let texture = window_texture(gpu, "egui panel cache", size, format, usage);
            self.texture = Some(texture);
            self.holds = None;
        }
        let seen = (generation, cached.to_vec());
        let ppp = screen.pixels_per_point;
        let same_frame = |h: &Held| h.background == background && h.pixels_per_point == ppp;
        if let Some(held) = self.holds.as_mut().filter(|h| same_frame(h)) {
            if held.seen == seen {
                return None;
            }
            let picked = pick(jobs, cached, true);
            if same_jobs(&held.jobs, &picked) {
                held.seen = seen;
                return None;
            }
        }
        let picked = pick(jobs, cached, true);
        // No callbacks among them, so no command buffers come back.
        let _ = (self.renderer).update_buffers(&gpu.device, &gpu.queue, encoder, &picked, screen);
        self.holds = Some(Held {
            jobs: picked.clone(),
            background,
            pixels_per_point: ppp,
            seen,
        });
        Some(picked)
    }

    /// The cache's texture (once prepared).
    pub fn texture(&self) -> Option<&wgpu::Texture> {
        self.texture.as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job(min: (f32, f32), max: (f32, f32), texture: egui::TextureId) -> ClippedPrimitive {
        ClippedPrimitive {
            clip_rect: egui::Rect::from_min_max(egui::pos2(min.0, min.1), egui::pos2(max.0, max.1)),
            primitive: Primitive::Mesh(egui::epaint::Mesh::with_texture(texture)),
        }
    }

    const OWN: egui::TextureId = egui::TextureId::Managed(0);

    /// The rectangles outside two views are disjoint, miss both views and
    /// cover the rest of the window: their areas add up to the window's
    /// less the views' (which are disjoint here), 100 x 50 - 30 x 50 -
    /// 40 x 20 = 2,700 pixels.
    #[test]
    fn outside_is_the_window_less_the_views_in_disjoint_rectangles() {
        let views = [
            PxRect {
                x0: 10,
                y0: 0,
                x1: 40,
                y1: 50,
            },
            PxRect {
                x0: 60,
                y0: 10,
                x1: 100,
                y1: 30,
            },
        ];
        let rects = outside(&views, [100, 50]);
        let area = |r: &PxRect| u64::from(r.x1 - r.x0) * u64::from(r.y1 - r.y0);
        assert_eq!(rects.iter().map(area).sum::<u64>(), 2_700);
        for (i, a) in rects.iter().enumerate() {
            assert!(!views.iter().any(|v| v.overlaps(*a)), "{a:?} meets a view");
            assert!(
                !rects[i + 1..].iter().any(|b| b.overlaps(*a)),
                "{a:?} meets another"
            );
        }
        // A view that overhangs the window: clipped; none at all: one
        // rectangle, the window.
        let over = [PxRect {
            x0: 50,
            y0: 0,
            x1: 150,
            y1: 50,
        }];
        assert_eq!(
            outside(&over, [100, 50]),
            [PxRect {
                x0: 0,
                y0: 0,
                x1: 50,
                y1: 50
            }]
        );
        assert_eq!(
            outside(&[], [100, 50]),
            [PxRect {
                x0: 0,
                y0: 0,
                x1: 100,
                y1: 50
            }]
        );
    }

    /// A job of egui's own textures is cached where its scissor (rounded
    /// to the nearest pixel edge) misses the views; a job left out that
    /// comes before a cached one must lie inside a view, else nothing is
    /// cached.
    #[test]
    fn split_caches_the_panels_jobs_unless_an_earlier_one_could_end_up_under_them() {
        let size = [100, 50];
        let views = [PxRect {
            x0: 11,
            y0: 0,
            x1: 100,
            y1: 50,
        }];
        let panel = job((0.0, 0.0), (10.4, 50.0), OWN);
        let label = job((20.0, 5.0), (60.0, 20.0), OWN);
        let line = job((0.0, 0.0), (100.0, 50.0), OWN);
        let split = |jobs: &[ClippedPrimitive]| split(jobs, 1.0, size, &views);
        let all = [panel.clone(), label.clone(), line.clone()];
        assert_eq!(split(&all), Some(vec![true, false, false]));
        assert_eq!(
            split(&[label.clone(), panel.clone()]),
            Some(vec![false, true])
        );
        assert_eq!(
            split(&[line.clone(), panel.clone()]),
            None,
            "the line would end up under"
        );
        assert_eq!(
            split(&[label.clone(), line.clone()]),
            None,
            "nothing to cache"
        );
        // 10.6 rounds to 11, the view's first column: still outside; 11.6
        // rounds to 12, inside.
        assert_eq!(
            split(&[job((0.0, 0.0), (10.6, 50.0), OWN)]),
            Some(vec![true])
        );
        assert_eq!(split(&[job((0.0, 0.0), (11.6, 50.0), OWN)]), None);
        // At 2 pixels per point, 5.4 points end at pixel edge 11.
        assert_eq!(
            super::split(&[job((0.0, 0.0), (5.4, 25.0), OWN)], 2.0, size, &views),
            Some(vec![true])
        );
        // A user texture (a view drawn by egui) is never cached.
        let user = job((0.0, 0.0), (10.0, 50.0), egui::TextureId::User(1));
        assert_eq!(
            split(&[user, panel]),
            None,
            "the user job is outside the views"
        );
    }
}
