//! The window's frame statistics: CPU frame times, and GPU pass times per
//! frame gathered from the views' renderers (their passes) and the window's
//! own [`GpuTimer`] (the views' resolves and egui), read back without
//! stalling the frame.

use std::time::{Duration, Instant};

use crate::gpu::timer::{GpuTimer, Span};
use crate::gpu::Gpu;

/// GPU milliseconds of one frame's passes, summed over the views.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PassTimes {
    pub raster_ms: f64,
    /// The trace pass (zero in raster mode).
    pub trace_ms: f64,
    /// The accumulate (with outlines) and reproject passes.
    pub accumulate_ms: f64,
    pub resolve_ms: f64,
    /// The views' images copied into the window, with egui's panel cache
    /// outside them or else the window's clear (where it can be copied
    /// into; where egui draws the views, that is in `egui_ms`).
    pub copy_ms: f64,
    /// egui drawing the panel and labels over the window: the jobs the
    /// panel cache does not give, and on the frames that redraw it, the
    /// cache's (`panel_cache`).
    pub egui_ms: f64,
    /// Views that rendered a timed sample in that frame.
    pub views_sampled: u32,
}

/// The window times one frame in this many. Timing is not free on
/// lavapipe: with every frame timed, a frame of the default scene took
/// 1.02x as long (93.6 against 91.7 ms, alternating every 10 frames in one
/// run; docs/performance.md). The panel's figures still change a few times
/// a second, and `--report-frame-times` gives the mean of the timed frames.
pub const TIMED_EVERY: u32 = 4;

/// The window's GPU timing: its own spans (the views' resolves, egui)
/// and, added in by [`FrameTimer::add_view_times`], what each view's
/// renderer timed of its sample. One frame in [`TIMED_EVERY`] is timed,
/// and one in flight at a time: a frame that starts while the previous
/// read-back is pending is not timed, and the next one is tried.
pub struct FrameTimer {
    timer: GpuTimer,
    resolve: Span,
    copy: Span,
    egui: Span,
    /// egui's jobs drawn into the panel cache.
    panel: Span,
    /// Each view slot's pass times read back since the last frame result
    /// (a later sample's replace an earlier one's: one sample per view).
    views: Vec<Option<PassTimes>>,
    timing_this_frame: bool,
    /// Frames begun since the last timed one.
    frames_since_timed: u32,
    pub latest: Option<PassTimes>,
}

impl FrameTimer {
    /// `None` when the device lacks timestamp queries inside encoders.
    pub fn new(gpu: &Gpu) -> Option<FrameTimer> {
        let (timer, [resolve, copy, egui, panel]) =
            GpuTimer::new(gpu, "window frame", ["resolve", "copy", "egui", "panel"])?;
        if !timer.stamps_inside_encoders() {
            return None;
        }
        Some(FrameTimer {
            timer,
            resolve,
            copy,
            egui,
            panel,
            views: Vec::new(),
            timing_this_frame: false,
            // The first frame is timed.
            frames_since_timed: TIMED_EVERY - 1,
            latest: None,
        })
    }

    /// Starts a frame; returns whether this frame is timed: one in
    /// [`TIMED_EVERY`], once the last timed frame's read-back is in.
    pub fn begin_frame(&mut self) -> bool {
        self.frames_since_timed += 1;
        self.timing_this_frame = self.frames_since_timed >= TIMED_EVERY && self.timer.begin();
        if self.timing_this_frame {
            self.frames_since_timed = 0;
        }
        self.timing_this_frame
    }

    pub fn resolve_begin(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.timer.stamp_begin(encoder, self.resolve);
    }
    pub fn resolve_end(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.timer.stamp_end(encoder, self.resolve);
    }
    pub fn copy_begin(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.timer.stamp_begin(encoder, self.copy);
    }
    pub fn copy_end(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.timer.stamp_end(encoder, self.copy);
    }
    pub fn egui_begin(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.timer.stamp_begin(encoder, self.egui);
    }
    pub fn egui_end(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.timer.stamp_end(encoder, self.egui);
    }
    pub fn panel_begin(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.timer.stamp_begin(encoder, self.panel);
    }
    pub fn panel_end(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.timer.stamp_end(encoder, self.panel);
    }

    /// Records the read-back; call at the end of the frame's last encoder.
    pub fn finish(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.timer.finish(encoder);
    }

    /// After the frame's submit: starts the read-back.
    pub fn after_submit(&mut self) {
        self.timer.after_submit();
    }

    /// Records view slot `slot`'s sample pass times (from
    /// [`crate::render::Renderer::collect_pass_times`]) for the next result.
    pub fn add_view_times(&mut self, slot: usize, times: &[(&'static str, f64)]) {
        let mut view = PassTimes {
            views_sampled: 1,
            ..PassTimes::default()
        };
        for (name, ms) in times {
            match *name {
                "raster" => view.raster_ms += ms,
                "trace" => view.trace_ms += ms,
                "outline_tiles" | "accumulate" | "reproject" => view.accumulate_ms += ms,
                other => log::warn!("window timing: a renderer pass {other:?} not counted"),
            }
        }
        if self.views.len() <= slot {
            self.views.resize(slot + 1, None);
        }
        self.views[slot] = Some(view);
    }

    /// The views' latest sample times summed (each view once), taken.
    fn take_view_times(&mut self) -> PassTimes {
        let mut sum = PassTimes::default();
        for view in self.views.iter_mut().filter_map(Option::take) {
            sum.raster_ms += view.raster_ms;
            sum.trace_ms += view.trace_ms;
            sum.accumulate_ms += view.accumulate_ms;
            sum.views_sampled += view.views_sampled;
        }
        sum
    }

    /// Reads a finished frame result into [`FrameTimer::latest`] (call once
    /// a frame, after a non-blocking device poll and the views' times) and
    /// returns it when one came in. A timed frame that sampled no view
    /// clears [`FrameTimer::latest`].
    pub fn collect(&mut self, sampled: bool) -> Option<PassTimes> {
        let mut came_in = None;
        if self.timer.collect().is_some() {
            let times = PassTimes {
                resolve_ms: self.timer.span_ms(self.resolve).unwrap_or(0.0),
                copy_ms: self.timer.span_ms(self.copy).unwrap_or(0.0),
                egui_ms: [self.egui, self.panel]
                    .map(|span| self.timer.span_ms(span).unwrap_or(0.0))
                    .iter()
                    .sum(),
                ..self.take_view_times()
            };
            self.latest = Some(times);
            came_in = Some(times);
        }
        if !sampled && self.timing_this_frame {
            self.latest = None;
        }
        self.timing_this_frame = false;
        came_in
    }
}

/// How the window started, in ms from the app's start (before its window
/// and device open): its first presented frame, the
/// first that showed every view (their first pipelines compiled), and the
/// longest wait between presented frames up to then (a stall of the
/// window, as its user sees it).
#[derive(Debug, Clone, Default)]
pub struct Startup {
    pub first_frame_ms: Option<f64>,
    pub views_shown_ms: Option<f64>,
    pub longest_wait_ms: f64,
    last_present_ms: Option<f64>,
}

impl Startup {
    /// Records a frame presented at `ms` (from the start); `views_shown`:
    /// every view drew in it.
    pub fn presented(&mut self, ms: f64, views_shown: bool) {
        if self.views_shown_ms.is_some() {
            return;
        }
        let since = self.last_present_ms.unwrap_or(0.0);
        self.longest_wait_ms = self.longest_wait_ms.max(ms - since);
        self.last_present_ms = Some(ms);
        self.first_frame_ms.get_or_insert(ms);
        if views_shown {
            self.views_shown_ms = Some(ms);
        }
    }
}

/// `smoothed` moved a tenth of the way towards `next` (the panel's steady
/// figures); `next` itself while `smoothed` is still 0.
fn smooth(smoothed: f64, next: f64) -> f64 {
    if smoothed == 0.0 {
        next
    } else {
        smoothed * 0.9 + next * 0.1
    }
}

/// CPU frame times: the interval between consecutive presented frames, and
/// the window's own CPU work in each (running egui's UI and preparing its
/// paint: tessellation and uploads). Presenting is not counted there: on
/// the CPU driver its call also waits for the frame's GPU work.
#[derive(Debug, Default)]
pub struct FrameStats {
    last: Option<Instant>,
    /// Every interval, for `--report-frame-times`.
    pub intervals_ms: Vec<f64>,
    /// Exponential average of the interval, for the stats line.
    pub smoothed_ms: f64,
    /// Every frame's egui CPU ms, for `--report-frame-times`.
    pub ui_ms: Vec<f64>,
    /// Exponential average of egui's CPU ms, for the panel.
    pub smoothed_ui_ms: f64,
    pub frames: u64,
}

impl FrameStats {
    /// Records a presented frame whose egui work took `ui_ms` of CPU.
    pub fn tick(&mut self, keep_all: bool, ui_ms: f64) {
        let now = Instant::now();
        if let Some(last) = self.last {
            let ms = now.duration_since(last).as_secs_f64() * 1e3;
            self.smoothed_ms = smooth(self.smoothed_ms, ms);
            if keep_all {
                self.intervals_ms.push(ms);
            }
        }
        self.smoothed_ui_ms = smooth(self.smoothed_ui_ms, ui_ms);
        if keep_all {
            self.ui_ms.push(ui_ms);
        }
        self.last = Some(now);
        self.frames += 1;
    }

    /// Forgets the last frame's time (after an idle wait, so that the wait
    /// is not counted as a frame).
    pub fn pause(&mut self) {
        self.last = None;
    }

    /// Time since the last frame, at most `max`.
    pub fn since_last(&self, max: Duration) -> Duration {
        self.last
            .map(|l| l.elapsed().min(max))
            .unwrap_or(Duration::ZERO)
    }
}

/// Mean GPU milliseconds per pass over `times` (frames that sampled).
pub fn mean_pass_times(times: &[PassTimes]) -> Option<PassTimes> {
    let sampled: Vec<&PassTimes> = times.iter().filter(|t| t.views_sampled > 0).collect();
    if sampled.is_empty() {
        return None;
    }
    let n = sampled.len() as f64;
    let mean = |f: fn(&PassTimes) -> f64| sampled.iter().map(|t| f(t)).sum::<f64>() / n;
    Some(PassTimes {
        raster_ms: mean(|t| t.raster_ms),
        trace_ms: mean(|t| t.trace_ms),
        accumulate_ms: mean(|t| t.accumulate_ms),
        resolve_ms: mean(|t| t.resolve_ms),
        copy_ms: mean(|t| t.copy_ms),
        egui_ms: mean(|t| t.egui_ms),
        views_sampled: sampled[0].views_sampled,
    })
}

/// Mean, median, 95th percentile and maximum of `ms`, skipping the first
/// `warmup` values.
pub fn summarize(ms: &[f64], warmup: usize) -> Option<(f64, f64, f64, f64)> {
    let mut v: Vec<f64> = ms.iter().skip(warmup).copied().collect();
    if v.is_empty() {
        return None;
    }
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    v.sort_by(f64::total_cmp);
    let pick = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    Some((mean, pick(0.5), pick(0.95), v[v.len() - 1]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_statistics() {
        let ms = [100.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        let (mean, median, p95, max) = summarize(&ms, 1).unwrap();
        assert_eq!(mean, 3.0);
        assert_eq!(median, 3.0);
        assert_eq!(p95, 5.0);
        assert_eq!(max, 5.0);
        assert!(summarize(&ms, 6).is_none());
    }

    /// The panel's figures start at the first frame's and then move a
    /// tenth of the way to each next; the report keeps every frame's.
    #[test]
    fn frame_stats_smooth_the_egui_time() {
        let mut stats = FrameStats::default();
        stats.tick(true, 4.0);
        assert_eq!(stats.smoothed_ui_ms, 4.0);
        stats.tick(true, 14.0);
        assert!((stats.smoothed_ui_ms - 5.0).abs() < 1e-12);
        assert_eq!(stats.ui_ms, [4.0, 14.0]);
        assert_eq!(
            stats.intervals_ms.len(),
            1,
            "the first frame has no interval"
        );
    }

    /// A start: the window's first frame at 300 ms, two frames waiting
    /// for the views (the longest wait 400 ms), the views at 1,000 ms;
    /// frames after that change nothing.
    #[test]
    fn startup_records_the_first_frames() {
        let mut s = Startup::default();
        s.presented(300.0, false);
        s.presented(700.0, false);
        s.presented(1000.0, true);
        s.presented(5000.0, true);
        assert_eq!(s.first_frame_ms, Some(300.0));
        assert_eq!(s.views_shown_ms, Some(1000.0));
        assert_eq!(s.longest_wait_ms, 400.0);
    }
}
