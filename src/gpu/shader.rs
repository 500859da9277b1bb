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
    (
        "lib/trace_bvh.wgsl",
        include_str!("../../shaders/lib/trace_bvh.wgsl"),
    ),
    (
        "lib/trace_rq.wgsl",
        include_str!("../../shaders/lib/trace_rq.wgsl"),
    ),
    ("lib/csg.wgsl", include_str!("../../shaders/lib/csg.wgsl")),
    (
        "lib/random.wgsl",
        include_str!("../../shaders/lib/random.wgsl"),
    ),
    (
        "lib/texture.wgsl",
        include_str!("../../shaders/lib/texture.wgsl"),
    ),
    ("raster.wgsl", include_str!("../../shaders/raster.wgsl")),
    (
        "accumulate.wgsl",
        include_str!("../../shaders/accumulate.wgsl"),
    ),
    ("resolve.wgsl", include_str!("../../shaders/resolve.wgsl")),
    (
        "reproject.wgsl",
        include_str!("../../shaders/reproject.wgsl"),
    ),
    ("trace.wgsl", include_str!("../../shaders/trace.wgsl")),
    (
        "ray_batch.wgsl",
        include_str!("../../shaders/ray_batch.wgsl"),
    ),
    (
        "bench_floor.wgsl",
        include_str!("../../shaders/bench_floor.wgsl"),
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

/// How a pass that traces rays walks the scene: which file serves
/// `lib/trace_bvh.wgsl`'s `trace` function.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Traversal {
    /// celray's own two-level BVH, walked in WGSL (any adapter).
    #[default]
    Software,
    /// The driver's acceleration structures through wgpu ray queries
    /// (`lib/trace_rq.wgsl`; needs `Features::EXPERIMENTAL_RAY_QUERY`).
    Driver,
}

impl Traversal {
    /// The include this traversal puts in place of `lib/trace_bvh.wgsl`,
    /// and the `enable` line it needs at the top of the module.
    fn swap(self) -> Option<(&'static str, &'static str)> {
        match self {
            Traversal::Software => None,
            Traversal::Driver => Some(("lib/trace_rq.wgsl", "enable wgpu_ray_query;")),
        }
    }
}

/// Expands the `#include "..."` lines of pass `name`. Each piece is included
/// once, however many files ask for it; a missing piece or a cycle is an error.
pub fn compose(name: &str) -> Result<String, GpuError> {
    compose_from(name, &|n| source_of(n), Traversal::Software)
}

/// [`compose`] with the given traversal (the driver variant swaps in
/// `lib/trace_rq.wgsl` and enables ray queries).
pub fn compose_variant(name: &str, traversal: Traversal) -> Result<String, GpuError> {
    compose_from(name, &|n| source_of(n), traversal)
}

/// [`compose`] over the files of `overrides` (disk first, then embedded).
pub fn compose_with(
    name: &str,
    overrides: &ShaderOverrides,
    traversal: Traversal,
) -> Result<String, GpuError> {
    compose_from(name, &|n| overrides.source_of(n), traversal)
}

fn compose_from<'a>(
    name: &str,
    lookup: &dyn Fn(&str) -> Option<&'a str>,
    traversal: Traversal,
) -> Result<String, GpuError> {
    compose_mapped(name, lookup, traversal).map(|(text, _)| text)
}

/// The composed text and, for each of its lines, the file and line
/// (1-based) it came from.
fn compose_mapped<'a>(
    name: &str,
    lookup: &dyn Fn(&str) -> Option<&'a str>,
    traversal: Traversal,
) -> Result<(String, Vec<(String, usize)>), GpuError> {
    let mut out = String::new();
    let mut origins = Vec::new();
    let mut included = Vec::new();
    let swap = traversal.swap();
    if let Some((_, enable)) = swap {
        // Enable directives must come before any declaration.
        out.push_str(enable);
        out.push('\n');
        origins.push(("(driver variant)".to_string(), 1));
    }
    let swapped = |n: &str| match swap {
        Some((to, _)) if n == "lib/trace_bvh.wgsl" => lookup(to),
        _ => lookup(n),
    };
    expand(
        name,
        &swapped,
        &mut out,
        &mut origins,
        &mut included,
        &mut Vec::new(),
    )?;
    if let Some((to, _)) = swap {
        for (file, _) in origins.iter_mut() {
            if file == "lib/trace_bvh.wgsl" {
                *file = to.to_string();
            }
        }
    }
    Ok((out, origins))
}

/// Adds the original file and line to each `wgsl:LINE:COL` that a shader
/// error names in the composed text of pass `name`, e.g.
/// `wgsl:146:12 (lib/shading.wgsl:40:12)`, and drops the box-drawing
/// characters of naga's report (many UI fonts lack them).
pub fn annotate_error(message: &str, name: &str, overrides: Option<&ShaderOverrides>) -> String {
    annotate_error_variant(message, name, overrides, Traversal::Software)
}

/// [`annotate_error`] for the pass composed with `traversal`.
pub fn annotate_error_variant(
    message: &str,
    name: &str,
    overrides: Option<&ShaderOverrides>,
    traversal: Traversal,
) -> String {
    let lookup = |n: &str| match overrides {
        Some(o) => o.source_of(n),
        None => source_of(n),
    };
    let origins = match compose_mapped(name, &lookup, traversal) {
        Ok((_, origins)) => origins,
        Err(_) => return message.to_string(),
    };
    let mut out = String::new();
    let mut rest = message;
    while let Some(at) = rest.find("wgsl:") {
        let (before, from) = rest.split_at(at + "wgsl:".len());
        out.push_str(before);
        let digits = |t: &str| t.chars().take_while(char::is_ascii_digit).count();
        let n_line = digits(from);
        let after_line = &from[n_line..];
        let n_col = after_line
            .strip_prefix(':')
            .map(digits)
            .filter(|&n| n > 0)
            .unwrap_or(0);
        if n_line == 0 || n_col == 0 {
            rest = from;
            continue;
        }
        let line: usize = from[..n_line].parse().unwrap_or(0);
        let col = &after_line[1..1 + n_col];
        out.push_str(&from[..n_line + 1 + n_col]);
        if let Some((file, l)) = line.checked_sub(1).and_then(|i| origins.get(i)) {
            out.push_str(&format!(" ({file}:{l}:{col})"));
        }
        rest = &after_line[1 + n_col..];
    }
    out.push_str(rest);
    out.replace(['┌', '─', '│', '└', '╭', '╰'], " ")
}

fn expand<'a>(
    name: &str,
    lookup: &dyn Fn(&str) -> Option<&'a str>,
    out: &mut String,
    origins: &mut Vec<(String, usize)>,
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
    for (i, line) in src.lines().enumerate() {
        if let Some(rest) = line.trim().strip_prefix("#include") {
            let inc = rest.trim().trim_matches('"');
            if !included.iter().any(|i| i == inc) {
                included.push(inc.to_string());
                expand(inc, lookup, out, origins, included, stack)?;
            }
        } else {
            out.push_str(line);
            out.push('\n');
            origins.push((name.to_string(), i + 1));
        }
    }
    stack.pop();
    Ok(())
}

/// Composes pass `name` and creates its module inside a validation scope.
pub fn create_module(gpu: &crate::gpu::Gpu, name: &str) -> Result<wgpu::ShaderModule, GpuError> {
    create_module_variant(gpu, name, Traversal::Software)
}

/// [`create_module`] with the given traversal.
pub fn create_module_variant(
    gpu: &crate::gpu::Gpu,
    name: &str,
    traversal: Traversal,
) -> Result<wgpu::ShaderModule, GpuError> {
    let overrides = gpu.shader_overrides();
    let source = match &overrides {
        Some(o) => compose_with(name, o, traversal)?,
        None => compose_variant(name, traversal)?,
    };
    gpu.scoped(|| {
        gpu.device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(name),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            })
    })
    .map_err(|e| {
        let message = annotate_error_variant(&e.to_string(), name, overrides.as_deref(), traversal);
        GpuError::Shader(format!("{name}: {message}"))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_name_the_original_file_and_line() {
        let (text, origins) =
            compose_mapped("resolve.wgsl", &source_of, Traversal::Software).unwrap();
        assert_eq!(text.lines().count(), origins.len());
        // The first line of resolve.wgsl's own code comes after its includes.
        let own = origins
            .iter()
            .position(|(f, _)| f == "resolve.wgsl")
            .unwrap();
        let n = own + 1;
        let msg = format!("error\n   ┌─ wgsl:{n}:7\n   │\nmore wgsl: text");
        let annotated = annotate_error(&msg, "resolve.wgsl", None);
        assert!(
            annotated.contains(&format!("wgsl:{n}:7 (resolve.wgsl:{}:7)", origins[own].1)),
            "{annotated}"
        );
        assert!(!annotated.contains('┌') && annotated.ends_with("more wgsl: text"));
        let lib = origins
            .iter()
            .position(|(f, _)| f.starts_with("lib/"))
            .unwrap();
        let annotated = annotate_error(&format!("wgsl:{}:1", lib + 1), "resolve.wgsl", None);
        assert!(
            annotated.contains(&format!("({}:", origins[lib].0)),
            "{annotated}"
        );
    }
}
