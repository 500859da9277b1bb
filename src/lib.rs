//! celray: toon shading, ray-traced CSG and instancing, and accumulation-buffer
//! effects, in real time on any Vulkan device (lavapipe included).
//!
//! Layers (docs/architecture.md): `scene` (CPU model and files) and
//! `sampling` (pure math) at the bottom, `accel` (CPU BVHs, exact
//! intersections, CSG programs, the reference tracer), `gpu` (wgpu
//! plumbing), `render` (the passes), `capture` (headless images), `view`
//! (what one view of a comparison or a window slot shows) and `compare`
//! (side-by-side comparison), and, behind the `app` feature, the window.
//! `fixtures` holds small scenes with closed-form answers that tests and
//! experiments share.

pub mod accel;
#[cfg(feature = "app")]
pub mod app;
pub mod capture;
pub mod compare;
pub mod fixtures;
pub mod gpu;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod view;
