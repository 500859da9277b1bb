//! The one GPU timer: timestamp queries around named spans (a render or
//! compute pass, or any stretch of an encoder), resolved and read back
//! either without stalling (a window's frame) or by waiting (a benchmark).
//!
//! A span is addressed by the [`Span`] its timer handed out when it was
//! made, never by name, so a misspelt pass cannot land in another's slot.

use std::sync::atomic::{AtomicU32, AtomicU8, Ordering};
use std::sync::Arc;

use crate::gpu::{Gpu, GpuError};

/// One timed span of a [`GpuTimer`]: made only by [`GpuTimer::new`], which
/// hands out one per name, and good only for the timer that made it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Span {
    timer: u32,
    index: u32,
}

const IDLE: u8 = 0;
const MAPPING: u8 = 1;
const MAPPED: u8 = 2;

/// Each span's two timestamps are resolved on their own, to an offset
/// aligned as resolving requires (spans not written are not resolved: a
/// query never written has no value to copy).
const SPAN_STRIDE_BYTES: u64 = wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT;

/// Tells timers apart, so that a [`Span`] of one is refused by another.
static NEXT_TIMER_ID: AtomicU32 = AtomicU32::new(0);

/// Timestamp queries for a fixed list of named spans, two timestamps each.
///
/// One round in flight at a time: [`GpuTimer::begin`] starts a round when
/// the last one has been read back (else the round is not timed and every
/// write is skipped); spans are written with [`GpuTimer::render_writes`],
/// [`GpuTimer::compute_writes`] or [`GpuTimer::stamp_begin`] /
/// [`GpuTimer::stamp_end`]; [`GpuTimer::finish`] records the resolve,
/// [`GpuTimer::after_submit`] starts the read-back, and
/// [`GpuTimer::collect`] (non-blocking) or [`GpuTimer::wait`] takes the
/// result.
pub struct GpuTimer {
    id: u32,
    set: wgpu::QuerySet,
    resolved: wgpu::Buffer,
    readback: wgpu::Buffer,
    names: Vec<&'static str>,
    period_ns: f64,
    /// Whether the device can stamp between passes (`stamp_begin`/`stamp_end`).
    inside_encoders: bool,
    state: Arc<AtomicU8>,
    /// Timestamps written this round, two per span (begin, end).
    written: Vec<bool>,
    /// Those of the round being read back.
    in_flight: Vec<bool>,
    timing: bool,
    /// The last round read back: milliseconds per span fully written.
    latest: Option<Vec<(&'static str, f64)>>,
    /// The same, by span index.
    latest_by_span: Vec<Option<f64>>,
}

impl GpuTimer {
    /// A timer for the spans `names`, and one [`Span`] per name in the
    /// same order; `None` when the device lacks `TIMESTAMP_QUERY`.
    pub fn new<const N: usize>(
        gpu: &Gpu,
        label: &str,
        names: [&'static str; N],
    ) -> Option<(GpuTimer, [Span; N])> {
        let features = gpu.device.features();
        if !features.contains(wgpu::Features::TIMESTAMP_QUERY) || N == 0 {
            return None;
        }
        let id = NEXT_TIMER_ID.fetch_add(1, Ordering::Relaxed);
        let size = SPAN_STRIDE_BYTES * N as u64;
        let timer = GpuTimer {
            id,
            set: gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some(&format!("{label} timestamps")),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * N as u32,
            }),
            resolved: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(&format!("{label} timestamps resolved")),
                size,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            readback: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(&format!("{label} timestamps readback")),
                size,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            }),
            names: names.to_vec(),
            period_ns: f64::from(gpu.queue.get_timestamp_period()),
            inside_encoders: features.contains(wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS),
            state: Arc::new(AtomicU8::new(IDLE)),
            written: vec![false; 2 * N],
            in_flight: vec![false; 2 * N],
            timing: false,
            latest: None,
            latest_by_span: vec![None; N],
        };
        let spans = std::array::from_fn(|i| Span {
            timer: id,
            index: i as u32,
        });
        Some((timer, spans))
    }

    /// Whether [`GpuTimer::stamp_begin`] / [`GpuTimer::stamp_end`] can write
    /// (the device has `TIMESTAMP_QUERY_INSIDE_ENCODERS`).
    pub fn stamps_inside_encoders(&self) -> bool {
        self.inside_encoders
    }

    /// Starts a round; returns whether it is timed (the last round has been
    /// read back).
    pub fn begin(&mut self) -> bool {
        self.written.fill(false);
        self.timing = self.state.load(Ordering::Acquire) == IDLE;
        self.timing
    }

    /// The first query of `span`, when this round is timed. A span of
    /// another timer is a bug: said loudly in the log, and not written.
    fn first_query(&self, span: Span) -> Option<u32> {
        if span.timer != self.id || span.index as usize >= self.names.len() {
            log::error!(
                "GPU timer: span {} of timer {} used on timer {} ({}): not timed",
                span.index,
                span.timer,
                self.id,
                self.names.join(", ")
            );
            debug_assert!(false, "a span used on a timer that did not make it");
            return None;
        }
        self.timing.then_some(2 * span.index)
    }

    /// Timestamp writes for a render pass timed as `span` (None when this
    /// round is not timed).
    pub fn render_writes(&mut self, span: Span) -> Option<wgpu::RenderPassTimestampWrites<'_>> {
        let first = self.first_query(span)?;
        self.written[first as usize] = true;
        self.written[first as usize + 1] = true;
        Some(wgpu::RenderPassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(first),
            end_of_pass_write_index: Some(first + 1),
        })
    }

    /// Timestamp writes for a compute pass timed as `span` (None when this
    /// round is not timed).
    pub fn compute_writes(&mut self, span: Span) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        let first = self.first_query(span)?;
        self.written[first as usize] = true;
        self.written[first as usize + 1] = true;
        Some(wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(first),
            end_of_pass_write_index: Some(first + 1),
        })
    }

    /// Writes `span`'s first timestamp into `encoder` (between passes).
    pub fn stamp_begin(&mut self, encoder: &mut wgpu::CommandEncoder, span: Span) {
        self.stamp(encoder, span, 0);
    }

    /// Writes `span`'s second timestamp into `encoder` (between passes).
    pub fn stamp_end(&mut self, encoder: &mut wgpu::CommandEncoder, span: Span) {
        self.stamp(encoder, span, 1);
    }

    fn stamp(&mut self, encoder: &mut wgpu::CommandEncoder, span: Span, which: u32) {
        if !self.inside_encoders {
            return;
        }
        if let Some(first) = self.first_query(span) {
            encoder.write_timestamp(&self.set, first + which);
            self.written[(first + which) as usize] = true;
        }
    }

    /// Records the resolve of this round's written spans and their copy for
    /// read-back; call at the end of the round's last encoder.
    pub fn finish(&mut self, encoder: &mut wgpu::CommandEncoder) {
        if !self.timing {
            return;
        }
        for span in 0..self.names.len() as u32 {
            let first = 2 * span;
            if self.written[first as usize] && self.written[first as usize + 1] {
                encoder.resolve_query_set(
                    &self.set,
                    first..first + 2,
                    &self.resolved,
                    u64::from(span) * SPAN_STRIDE_BYTES,
                );
            }
        }
        encoder.copy_buffer_to_buffer(&self.resolved, 0, &self.readback, 0, self.resolved.size());
    }

    /// After the round's last submit: starts mapping the read-back buffer.
    pub fn after_submit(&mut self) {
        if !self.timing {
            return;
        }
        self.in_flight.clone_from(&self.written);
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
        self.timing = false;
    }

    /// Takes a finished read-back, without waiting (call after a device
    /// poll): milliseconds per span written in that round, in the order of
    /// the names. `None` while nothing new has come in.
    pub fn collect(&mut self) -> Option<&[(&'static str, f64)]> {
        if self.state.load(Ordering::Acquire) != MAPPED {
            return None;
        }
        let ticks: Vec<u64> = match self.readback.slice(..).get_mapped_range() {
            Ok(view) => bytemuck::cast_slice(&view).to_vec(),
            Err(_) => Vec::new(),
        };
        self.readback.unmap();
        self.state.store(IDLE, Ordering::Release);
        let per_span = (SPAN_STRIDE_BYTES / 8) as usize;
        let mut times = Vec::new();
        for (k, name) in self.names.iter().enumerate() {
            let (a, b) = (k * per_span, k * per_span + 1);
            self.latest_by_span[k] = None;
            if !(self.in_flight[2 * k] && self.in_flight[2 * k + 1]) || b >= ticks.len() {
                continue;
            }
            let ms = ticks[b].saturating_sub(ticks[a]) as f64 * self.period_ns * 1e-6;
            self.latest_by_span[k] = Some(ms);
            times.push((*name, ms));
        }
        self.latest = Some(times);
        self.latest.as_deref()
    }

    /// Milliseconds of `span` in the last round read back, if it was written.
    pub fn span_ms(&self, span: Span) -> Option<f64> {
        if span.timer != self.id {
            log::error!(
                "GPU timer: span of timer {} read on timer {}",
                span.timer,
                self.id
            );
            return None;
        }
        self.latest_by_span
            .get(span.index as usize)
            .copied()
            .flatten()
    }

    /// Waits for the round in flight and returns its times; empty when no
    /// round is in flight (the last round was not timed because an earlier
    /// one was still being read back), so a caller never counts one round
    /// twice.
    pub fn wait(&mut self, gpu: &Gpu) -> Result<Vec<(&'static str, f64)>, GpuError> {
        if self.state.load(Ordering::Acquire) == MAPPING {
            gpu.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| GpuError::Readback(e.to_string()))?;
        }
        Ok(self.collect().map(<[_]>::to_vec).unwrap_or_default())
    }
}
