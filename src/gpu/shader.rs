//! Shader composition: pass files in `shaders/` pull in pieces from
//! `shaders/lib/` with `#include "lib/NAME.wgsl"` lines. Every file is
//! embedded in the binary, so celray runs from any directory.

use crate::gpu::GpuError;

/// Every shader source file, by its path relative to `shaders/`.
pub const SHADER_FILES: &[(&str, &str)] = &[
    (
        "lib/types.wgsl",
        include_str!("../../shaders/lib/types.wgsl"),
    ),
    (
        "lib/color.wgsl",
        include_str!("../../shaders/lib/color.wgsl"),
    ),
    (
        "lib/shading.wgsl",
        include_str!("../../shaders/lib/shading.wgsl"),
    ),
    (
        "lib/intersect.wgsl",
        include_str!("../../shaders/lib/intersect.wgsl"),
    ),
    (
        "lib/traverse.wgsl",
        include_str!("../../shaders/lib/traverse.wgsl"),
    ),
    ("lib/csg.wgsl", include_str!("../../shaders/lib/csg.wgsl")),
    ("raster.wgsl", include_str!("../../shaders/raster.wgsl")),
    (
        "accumulate.wgsl",
        include_str!("../../shaders/accumulate.wgsl"),
    ),
    ("resolve.wgsl", include_str!("../../shaders/resolve.wgsl")),
    ("trace.wgsl", include_str!("../../shaders/trace.wgsl")),
    (
        "ray_batch.wgsl",
        include_str!("../../shaders/ray_batch.wgsl"),
    ),
];

/// The pass files (those that are not include-only pieces).
pub fn pass_files() -> impl Iterator<Item = &'static str> {
    SHADER_FILES
        .iter()
        .map(|(name, _)| *name)
        .filter(|name| !name.starts_with("lib/"))
}

fn source_of(name: &str) -> Option<&'static str> {
    SHADER_FILES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, s)| *s)
}

/// Expands the `#include "..."` lines of pass `name`. Each piece is included
/// once, however many files ask for it; a missing piece or a cycle is an error.
pub fn compose(name: &str) -> Result<String, GpuError> {
    let mut out = String::new();
    let mut included = Vec::new();
    expand(name, &mut out, &mut included, &mut Vec::new())?;
    Ok(out)
}

fn expand(
    name: &str,
    out: &mut String,
    included: &mut Vec<String>,
    stack: &mut Vec<String>,
) -> Result<(), GpuError> {
    if stack.iter().any(|s| s == name) {
        return Err(GpuError::Shader(format!(
            "include cycle: {} -> {name}",
            stack.join(" -> ")
        )));
    }
    let src =
        source_of(name).ok_or_else(|| GpuError::Shader(format!("no shader file {name:?}")))?;
    stack.push(name.to_string());
    for line in src.lines() {
        if let Some(rest) = line.trim().strip_prefix("#include") {
            let inc = rest.trim().trim_matches('"');
            if !included.iter().any(|i| i == inc) {
                included.push(inc.to_string());
                expand(inc, out, included, stack)?;
            }
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    stack.pop();
    Ok(())
}

/// Composes pass `name` and creates its module inside a validation scope.
pub fn create_module(gpu: &crate::gpu::Gpu, name: &str) -> Result<wgpu::ShaderModule, GpuError> {
    let source = compose(name)?;
    gpu.scoped(|| {
        gpu.device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(name),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            })
    })
    .map_err(|e| GpuError::Shader(format!("{name}: {e}")))
}
