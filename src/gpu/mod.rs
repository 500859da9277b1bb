//! The GPU layer: device and adapter, shader composition (with the limits
//! header generated from Rust constants), the Rust twins of WGSL structs,
//! bind-group layout helpers, the GPU timer and readback. Imports wgpu, and
//! from `scene` and `accel` only the constants, plain Pod layouts and
//! texture-sampler types it hands to WGSL; never a scene, a pass, winit or
//! egui.

mod context;
pub mod layout;
pub mod readback;
pub mod shader;
pub mod timer;
pub mod twins;
pub mod uniform_tables;

pub use context::{list_adapters, pick_adapter, AdapterChoice, AdapterSummary, Gpu};

/// Writes `words` at the start of `buffer` unless `written` (what the
/// buffer was last given) already holds them, and remembers them: for
/// tables made on the CPU for every sample (the primary tiles, the
/// outline source tiles) that rarely change from one sample to the next.
pub fn write_if_changed(gpu: &Gpu, buffer: &wgpu::Buffer, written: &mut Vec<u32>, words: Vec<u32>) {
    if words != *written {
        gpu.queue
            .write_buffer(buffer, 0, bytemuck::cast_slice(&words));
        *written = words;
    }
}

/// What can go wrong on the GPU side.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("{0}")]
    NoAdapter(String),
    #[error("could not create a device: {0}")]
    Device(String),
    #[error("wgpu validation error: {0}")]
    Validation(String),
    #[error("shader: {0}")]
    Shader(String),
    #[error("readback failed: {0}")]
    Readback(String),
    #[error("{what} is {value}, over this adapter's limit of {limit}")]
    Limit {
        what: String,
        value: u64,
        limit: u64,
    },
    /// A request no device can serve (an empty image, a BVH deeper than the
    /// traversal stack), said in the message.
    #[error("{0}")]
    Unsupported(String),
}
