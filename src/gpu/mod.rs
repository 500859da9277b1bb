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
