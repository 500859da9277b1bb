//! GPU time per pass from timestamp queries, where the adapter has them.

use crate::gpu::{readback, Gpu, GpuError};

/// Two timestamps (begin, end) per named pass.
pub struct PassTimer {
    set: wgpu::QuerySet,
    resolved: wgpu::Buffer,
    readback: wgpu::Buffer,
    names: Vec<&'static str>,
    period_ns: f32,
}

impl PassTimer {
    /// A timer for these passes, or None when the device lacks TIMESTAMP_QUERY.
    pub fn new(gpu: &Gpu, names: &[&'static str]) -> Option<PassTimer> {
        if !gpu
            .device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
        {
            return None;
        }
        let count = names.len() as u32 * 2;
        let size = u64::from(count) * 8;
        Some(PassTimer {
            set: gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count,
            }),
            resolved: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("pass timestamps resolved"),
                size,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            readback: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("pass timestamps readback"),
                size,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            }),
            names: names.to_vec(),
            period_ns: gpu.queue.get_timestamp_period(),
        })
    }

    fn index(&self, pass: &str) -> u32 {
        self.names.iter().position(|n| *n == pass).unwrap_or(0) as u32 * 2
    }

    pub fn render_writes(&self, pass: &str) -> wgpu::RenderPassTimestampWrites<'_> {
        let i = self.index(pass);
        wgpu::RenderPassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(i),
            end_of_pass_write_index: Some(i + 1),
        }
    }

    pub fn compute_writes(&self, pass: &str) -> wgpu::ComputePassTimestampWrites<'_> {
        let i = self.index(pass);
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(i),
            end_of_pass_write_index: Some(i + 1),
        }
    }

    /// Records the copy of all timestamps; call after the timed passes.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.resolve_query_set(&self.set, 0..self.names.len() as u32 * 2, &self.resolved, 0);
        encoder.copy_buffer_to_buffer(&self.resolved, 0, &self.readback, 0, self.resolved.size());
    }

    /// Milliseconds per pass of the last resolved submission (blocks).
    pub fn read(&self, gpu: &Gpu) -> Result<Vec<(&'static str, f64)>, GpuError> {
        let bytes = readback::read_buffer(gpu, &self.readback)?;
        let ticks: &[u64] = bytemuck::cast_slice(&bytes);
        Ok(self
            .names
            .iter()
            .enumerate()
            .map(|(k, name)| {
                let dt = ticks[2 * k + 1].saturating_sub(ticks[2 * k]);
                (*name, dt as f64 * f64::from(self.period_ns) * 1e-6)
            })
            .collect())
    }
}
