//! Frame statistics (CPU frame times) and GPU pass times from timestamp
//! queries, read back without stalling the frame.

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::gpu::Gpu;

/// Timestamp slots: 3 per view (before raster, after raster, after
/// accumulate), then 2 around the view resolves and 2 around egui.
pub const MAX_VIEWS: usize = 4;
const RESOLVE_SLOT: u32 = 3 * MAX_VIEWS as u32;
const EGUI_SLOT: u32 = RESOLVE_SLOT + 2;
const SLOTS: u32 = EGUI_SLOT + 2;
/// Groups of slots written together: (first slot, count). Each group is
/// resolved on its own, to an offset aligned as resolving requires.
const GROUPS: [(u32, u32); MAX_VIEWS + 2] = [
    (0, 3),
    (3, 3),
    (6, 3),
    (9, 3),
    (RESOLVE_SLOT, 2),
    (EGUI_SLOT, 2),
];
const GROUP_STRIDE: u64 = wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT;
const BUFFER_SIZE: u64 = GROUP_STRIDE * GROUPS.len() as u64;

/// Where slot `s` lands in the resolve buffer, in u64 units.
fn slot_index(s: u32) -> usize {
    let (g, (first, _)) = GROUPS
        .iter()
        .enumerate()
        .find(|(_, (first, count))| (*first..first + count).contains(&s))
        .expect("every slot is in a group");
    (g as u64 * GROUP_STRIDE / 8) as usize + (s - first) as usize
}

/// GPU milliseconds of one frame's passes, summed over the views.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PassTimes {
    pub raster_ms: f64,
    pub accumulate_ms: f64,
    pub resolve_ms: f64,
    pub egui_ms: f64,
    /// Views that rendered a sample in that frame.
    pub views_sampled: u32,
}

const IDLE: u8 = 0;
const MAPPING: u8 = 1;
const MAPPED: u8 = 2;

/// Timestamp queries for the passes of a frame. One frame in flight at a
/// time: frames that start while the previous read-back is pending are
/// simply not timed.
pub struct GpuTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    period_ns: f64,
    state: Arc<AtomicU8>,
    written: [bool; SLOTS as usize],
    in_flight: [bool; SLOTS as usize],
    timing_this_frame: bool,
    pub latest: Option<PassTimes>,
}

impl GpuTimer {
    /// `None` when the device lacks timestamp queries inside encoders.
    pub fn new(gpu: &Gpu) -> Option<GpuTimer> {
        let needed =
            wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS;
        if !gpu.device.features().contains(needed) {
            return None;
        }
        let size = BUFFER_SIZE;
        Some(GpuTimer {
            set: gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: SLOTS,
            }),
            resolve: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp resolve"),
                size,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            readback: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp readback"),
                size,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            }),
            period_ns: f64::from(gpu.queue.get_timestamp_period()),
            state: Arc::new(AtomicU8::new(IDLE)),
            written: [false; SLOTS as usize],
            in_flight: [false; SLOTS as usize],
            timing_this_frame: false,
            latest: None,
        })
    }

    /// Starts a frame; returns whether this frame is timed.
    pub fn begin_frame(&mut self) -> bool {
        self.written = [false; SLOTS as usize];
        self.timing_this_frame = self.state.load(Ordering::Acquire) == IDLE;
        self.timing_this_frame
    }

    /// The query set and first slot for view `i`'s sample, if timed.
    pub fn view_slots(&mut self, i: usize) -> Option<(&wgpu::QuerySet, u32)> {
        if !self.timing_this_frame || i >= MAX_VIEWS {
            return None;
        }
        let first = 3 * i as u32;
        for s in first..first + 3 {
            self.written[s as usize] = true;
        }
        Some((&self.set, first))
    }

    fn stamp(&mut self, encoder: &mut wgpu::CommandEncoder, slot: u32) {
        if self.timing_this_frame {
            encoder.write_timestamp(&self.set, slot);
            self.written[slot as usize] = true;
        }
    }

    pub fn resolve_begin(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.stamp(encoder, RESOLVE_SLOT);
    }
    pub fn resolve_end(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.stamp(encoder, RESOLVE_SLOT + 1);
    }
    pub fn egui_begin(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.stamp(encoder, EGUI_SLOT);
    }
    pub fn egui_end(&mut self, encoder: &mut wgpu::CommandEncoder) {
        self.stamp(encoder, EGUI_SLOT + 1);
    }

    /// Resolves the written slots (in runs) and copies them for read-back.
    /// Call at the end of the frame's last encoder.
    pub fn finish(&mut self, encoder: &mut wgpu::CommandEncoder) {
        if !self.timing_this_frame {
            return;
        }
        for (g, (first, count)) in GROUPS.iter().enumerate() {
            if (*first..first + count).all(|s| self.written[s as usize]) {
                encoder.resolve_query_set(
                    &self.set,
                    *first..first + count,
                    &self.resolve,
                    g as u64 * GROUP_STRIDE,
                );
            } else {
                for s in *first..first + count {
                    self.written[s as usize] = false;
                }
            }
        }
        encoder.copy_buffer_to_buffer(&self.resolve, 0, &self.readback, 0, BUFFER_SIZE);
    }

    /// After the frame's submit: starts mapping the read-back buffer.
    pub fn after_submit(&mut self) {
        if !self.timing_this_frame {
            return;
        }
        self.in_flight = self.written;
        self.state.store(MAPPING, Ordering::Release);
        let state = self.state.clone();
        self.readback
            .slice(..)
            .map_async(wgpu::MapMode::Read, move |result| {
                state.store(
                    if result.is_ok() { MAPPED } else { IDLE },
                    Ordering::Release,
                );
            });
        self.timing_this_frame = false;
    }

    /// Reads finished results into [`GpuTimer::latest`]. Call once a frame
    /// (after a non-blocking device poll). True when a result came in.
    pub fn collect(&mut self) -> bool {
        if self.state.load(Ordering::Acquire) != MAPPED {
            return false;
        }
        let ticks: Vec<u64> = match self.readback.slice(..).get_mapped_range() {
            Ok(view) => bytemuck::cast_slice(&view).to_vec(),
            Err(_) => Vec::new(),
        };
        self.readback.unmap();
        self.state.store(IDLE, Ordering::Release);
        if ticks.len() < (BUFFER_SIZE / 8) as usize {
            return false;
        }
        let ms = |a: u32, b: u32| -> f64 {
            let (ta, tb) = (ticks[slot_index(a)], ticks[slot_index(b)]);
            if self.in_flight[a as usize] && self.in_flight[b as usize] && tb >= ta {
                (tb - ta) as f64 * self.period_ns * 1e-6
            } else {
                0.0
            }
        };
        let mut times = PassTimes::default();
        for v in 0..MAX_VIEWS as u32 {
            if self.in_flight[(3 * v) as usize] {
                times.views_sampled += 1;
                times.raster_ms += ms(3 * v, 3 * v + 1);
                times.accumulate_ms += ms(3 * v + 1, 3 * v + 2);
            }
        }
        times.resolve_ms = ms(RESOLVE_SLOT, RESOLVE_SLOT + 1);
        times.egui_ms = ms(EGUI_SLOT, EGUI_SLOT + 1);
        self.latest = Some(times);
        true
    }
}

/// CPU frame times: the interval between consecutive presented frames.
#[derive(Debug, Default)]
pub struct FrameStats {
    last: Option<Instant>,
    /// Every interval, for `--report-frame-times`.
    pub intervals_ms: Vec<f64>,
    /// Exponential average of the interval, for the stats line.
    pub smoothed_ms: f64,
    pub frames: u64,
}

impl FrameStats {
    /// Records a presented frame.
    pub fn tick(&mut self, keep_all: bool) {
        let now = Instant::now();
        if let Some(last) = self.last {
            let ms = now.duration_since(last).as_secs_f64() * 1e3;
            self.smoothed_ms = if self.smoothed_ms == 0.0 {
                ms
            } else {
                self.smoothed_ms * 0.9 + ms * 0.1
            };
            if keep_all {
                self.intervals_ms.push(ms);
            }
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
        accumulate_ms: mean(|t| t.accumulate_ms),
        resolve_ms: mean(|t| t.resolve_ms),
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
}
