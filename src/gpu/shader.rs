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
    ("raster.wgsl", include_str!("../../shaders/raster.wgsl")),
    (
        "accumulate.wgsl",
        include_str!("../../shaders/accumulate.wgsl"),
    ),
    ("resolve.wgsl", include_str!("../../shaders/resolve.wgsl")),
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

/// Shader files read from a `shaders/` folder on disk (for hot reload),
/// by their path relative to it. Files it lacks come from the embedded copies.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ShaderOverrides {
    /// The folder the files were read from.
    pub dir: std::path::PathBuf,
    files: Vec<(String, String)>,
}

impl ShaderOverrides {
    /// Reads every file of [`SHADER_FILES`] that exists under `dir`.
    pub fn read_dir(dir: &std::path::Path) -> Result<ShaderOverrides, GpuError> {
        let mut files = Vec::new();
        for (name, _) in SHADER_FILES {
            let path = dir.join(name);
            if path.is_file() {
                let text = std::fs::read_to_string(&path).map_err(|e| {
                    GpuError::Shader(format!("cannot read {}: {e}", path.display()))
                })?;
                files.push((name.to_string(), text));
            }
        }
        Ok(ShaderOverrides {
            dir: dir.to_path_buf(),
            files,
        })
    }

    /// The text of shader file `name`: from disk when read, else embedded.
    pub fn source_of(&self, name: &str) -> Option<&str> {
        self.files
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, s)| s.as_str())
            .or_else(|| source_of(name))
    }
}

/// Expands the `#include "..."` lines of pass `name`. Each piece is included
/// once, however many files ask for it; a missing piece or a cycle is an error.
pub fn compose(name: &str) -> Result<String, GpuError> {
    compose_from(name, &|n| source_of(n))
}

/// [`compose`] over the files of `overrides` (disk first, then embedded).
pub fn compose_with(name: &str, overrides: &ShaderOverrides) -> Result<String, GpuError> {
    compose_from(name, &|n| overrides.source_of(n))
}

fn compose_from<'a>(
    name: &str,
    lookup: &dyn Fn(&str) -> Option<&'a str>,
) -> Result<String, GpuError> {
    let mut out = String::new();
    let mut included = Vec::new();
    expand(name, lookup, &mut out, &mut included, &mut Vec::new())?;
    Ok(out)
}

fn expand<'a>(
    name: &str,
    lookup: &dyn Fn(&str) -> Option<&'a str>,
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
    let src = lookup(name).ok_or_else(|| GpuError::Shader(format!("no shader file {name:?}")))?;
    stack.push(name.to_string());
    for line in src.lines() {
        if let Some(rest) = line.trim().strip_prefix("#include") {
            let inc = rest.trim().trim_matches('"');
            if !included.iter().any(|i| i == inc) {
                included.push(inc.to_string());
                expand(inc, lookup, out, included, stack)?;
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
    let source = match gpu.shader_overrides() {
        Some(overrides) => compose_with(name, &overrides)?,
        None => compose(name)?,
    };
    gpu.scoped(|| {
        gpu.device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(name),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            })
    })
    .map_err(|e| GpuError::Shader(format!("{name}: {e}")))
}
