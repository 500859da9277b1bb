//! Shader composition: pass files in `shaders/` pull in pieces from
//! `shaders/lib/` with `#include "lib/NAME.wgsl"` lines. Every file is
//! embedded in the binary, so celray runs from any directory.
//!
//! One include is not a file: [`LIMITS_INCLUDE`] is generated here from the
//! Rust constants ([`limits_header`]), so every limit WGSL shares with Rust
//! (stack sizes, step budgets, CSG limits and epsilons, far values, outline
//! radius, workgroup sizes) has one home, in Rust, and cannot drift. A
//! second, [`SELECT_INCLUDE`], holds the selection trees of the small
//! tables ([`select_tables_source`]), too regular to write by hand.

use std::sync::OnceLock;

use crate::accel::PrivateSizes;
use crate::gpu::twins;
use crate::gpu::uniform_tables::{Table, MAX_SELECTED, TOP_NODES_BIT, TOP_NODES_NAME};
use crate::gpu::GpuError;

/// The include [`compose`] generates from Rust constants rather than reads
/// (no file on disk or embedded; hot reload cannot replace it).
pub const LIMITS_INCLUDE: &str = "lib/limits.wgsl";

/// The include [`compose`] generates with the selection trees
/// (lib/scene_bindings.wgsl includes it).
pub const SELECT_INCLUDE: &str = "lib/select_tables.wgsl";

/// A `u32` limit of the generated header: its WGSL name and value.
type U32Limit = (&'static str, u32);
/// An `f32` limit of the generated header.
type F32Limit = (&'static str, f32);

/// Every `u32` constant of [`limits_header`], by its WGSL name.
pub fn u32_limits() -> Vec<U32Limit> {
    use crate::scene::{CSG_MAX_INTERVALS, CSG_MESH_MAX_CROSSINGS, CSG_STACK};
    let mut limits = vec![
        ("TRAVERSAL_STACK", twins::TRAVERSAL_STACK),
        // The traversal stack's length in this module:
        // [`create_module_sized`] rewrites this line.
        ("TRACE_STACK", twins::TRAVERSAL_STACK),
        ("MAX_TRAVERSAL_STEPS", twins::MAX_TRAVERSAL_STEPS),
        ("MAX_INVOCATION_STEPS", twins::MAX_INVOCATION_STEPS),
        ("CSG_MAX_INTERVALS", CSG_MAX_INTERVALS),
        ("CSG_STACK", CSG_STACK),
        ("CSG_MESH_MAX_CROSSINGS", CSG_MESH_MAX_CROSSINGS),
        ("CSG_FAST_MAX_LEAVES", twins::CSG_FAST_MAX_LEAVES),
        ("CSG_FAST_COUNT_SHIFT", twins::CSG_FAST_COUNT_SHIFT),
        // The CSG evaluator's lengths in this module, the same way.
        ("CSG_EVAL_STACK", CSG_STACK),
        ("CSG_EVAL_INTERVALS", CSG_MAX_INTERVALS),
        ("MAX_TOON_BANDS", crate::scene::MAX_TOON_BANDS),
        ("MAX_OUTLINE_RADIUS", twins::MAX_OUTLINE_RADIUS),
        (
            "TILE_TEXELS",
            (twins::MAX_ACCUMULATE_TILE + 2 * twins::MAX_OUTLINE_RADIUS).pow(2),
        ),
        (
            "TILE_ROW_TEXELS",
            (twins::MAX_ACCUMULATE_TILE + 2 * twins::MAX_OUTLINE_RADIUS)
                * twins::MAX_ACCUMULATE_TILE,
        ),
        ("TRACE_WORKGROUP", twins::TRACE_WORKGROUP),
        ("TRACED_ROW_ALIGN_PX", twins::TRACED_ROW_ALIGN_PX),
        ("LIGHTS_DYNAMIC", twins::LIGHTS_DYNAMIC),
        ("MAX_CULL_PLANES", twins::MAX_CULL_PLANES),
        ("SHADOW_LIST_WORDS", twins::SHADOW_LIST_WORDS),
        ("SHADOW_LIST_WALK", twins::SHADOW_LIST_WALK),
        ("SHADOW_LIST_CONVEX", twins::SHADOW_LIST_CONVEX),
        ("CULL_CELL_LIST", twins::CULL_CELL_LIST),
        ("CELL_LIST_TRIANGLE_SHIFT", twins::CELL_LIST_TRIANGLE_SHIFT),
        ("PRIMARY_TILE_WORDS", twins::PRIMARY_TILE_WORDS),
        ("INSTANCE_ID_BITS", twins::INSTANCE_ID_BITS),
        ("PRIMARY_TILE_WALK", twins::PRIMARY_TILE_WALK),
        ("TILE_MESH_MAY_SHOW", twins::TILE_MESH_MAY_SHOW),
        ("TILE_TRACE_ACCUMULATES", twins::TILE_TRACE_ACCUMULATES),
        ("TILE_GBUFFER_SKIPS", twins::TILE_GBUFFER_SKIPS),
        ("TILE_UNSHADOWED", twins::TILE_UNSHADOWED),
        ("TILE_RECORD_SHIFT", twins::TILE_RECORD_SHIFT),
        ("TILE_RECORD_READ", twins::TILE_RECORD_READ),
        ("OUTLINE_MARK_SEARCH", twins::OUTLINE_MARK_SEARCH),
        ("OUTLINE_MARK_TRACED", twins::OUTLINE_MARK_TRACED),
        ("MAIN_DISPATCH_WORD", twins::MAIN_DISPATCH_WORD),
        ("OUTLINE_DISPATCH_WORDS", twins::OUTLINE_DISPATCH_WORDS),
        ("RAY_BATCH_WORKGROUP", twins::RAY_BATCH_WORKGROUP),
        ("MAX_ACCUMULATE_TILE", twins::MAX_ACCUMULATE_TILE),
        ("OUTLINE_TILES_WORKGROUP", twins::OUTLINE_TILES_WORKGROUP),
        ("REPROJECT_WORKGROUP", twins::REPROJECT_WORKGROUP),
    ];
    for table in Table::ALL {
        limits.push((table.bit_name(), table.bit()));
        limits.push((table.length_name(), table.uniform_length()));
    }
    limits.push((TOP_NODES_NAME, TOP_NODES_BIT));
    limits
}

/// Every `f32` constant of [`limits_header`], by its WGSL name.
pub fn f32_limits() -> Vec<F32Limit> {
    use crate::accel::csg::{CSG_EPS_ABS, CSG_EPS_REL, CSG_FAR};
    use crate::accel::intersect::{BOX_EXIT_SLACK, EDGE_SLACK};
    use crate::accel::shadow_cull::PLANE_MARGIN;
    vec![
        ("BOX_EXIT_SLACK", BOX_EXIT_SLACK),
        ("EDGE_SLACK", EDGE_SLACK),
        ("PLANE_MARGIN", PLANE_MARGIN),
        ("CSG_FAR", CSG_FAR),
        ("CSG_EPS_ABS", CSG_EPS_ABS),
        ("CSG_EPS_REL", CSG_EPS_REL),
        ("FAR_DEPTH", twins::FAR_DEPTH),
        ("DEPTH_JUMP", twins::DEPTH_JUMP),
    ]
}

/// The text of [`LIMITS_INCLUDE`]: one `const` per Rust limit. Floats are
/// written with Rust's shortest round-trip form and the `f` suffix, so WGSL
/// reads back the very same `f32`.
pub fn limits_header() -> &'static str {
    static HEADER: OnceLock<String> = OnceLock::new();
    HEADER.get_or_init(|| {
        let mut s = String::from(
            "// Generated by src/gpu/shader.rs (limits_header) from the Rust constants:\n\
             // change them there, never here.\n",
        );
        for (name, value) in u32_limits() {
            s.push_str(&format!("const {name}: u32 = {value}u;\n"));
        }
        for (name, value) in f32_limits() {
            s.push_str(&format!("const {name}: f32 = {value:?}f;\n"));
        }
        s
    })
}

/// The text of [`SELECT_INCLUDE`]: for each table that may be read by
/// selection ([`crate::gpu::uniform_tables::SelectedTables`]), a function
/// returning its element i (< n, the table's override constant) from a
/// binary tree of branches whose leaves load one element each at a constant
/// index. The tree spans [`MAX_SELECTED`] leaves; a split at m is tested
/// only where n > m (an override expression), so for a table of n elements
/// the tree is about log2(n) deep and leaves from n on are not compiled.
pub fn select_tables_source() -> &'static str {
    const _: () = assert!(MAX_SELECTED.is_power_of_two());
    static SOURCE: OnceLock<String> = OnceLock::new();
    SOURCE.get_or_init(|| {
        let mut s = String::from(
            "// Generated by src/gpu/shader.rs (select_tables_source): element i of a\n\
             // small table read at constant indices, one branch per tree level.\n",
        );
        for (name, ty, count, load) in [
            (
                "select_material",
                "GpuMaterial",
                "SELECT_MATERIALS",
                "load_material_at",
            ),
            (
                "select_instance",
                "GpuInstance",
                "SELECT_INSTANCES",
                "load_instance_at",
            ),
        ] {
            s.push_str(&format!("fn {name}(i: u32) -> {ty} {{\n    var e: {ty};\n"));
            select_node(&mut s, count, load, 0, MAX_SELECTED, 1);
            s.push_str("    return e;\n}\n");
        }
        s
    })
}

/// The subtree of [`select_tables_source`] over elements `lo` to
/// `lo + size - 1`, at indentation `depth`.
fn select_node(s: &mut String, count: &str, load: &str, lo: u32, size: u32, depth: usize) {
    let pad = "    ".repeat(depth);
    if size == 1 {
        s.push_str(&format!("{pad}e = {load}({lo}u);\n"));
        return;
    }
    let mid = lo + size / 2;
    s.push_str(&format!("{pad}if {count} > {mid}u && i >= {mid}u {{\n"));
    select_node(s, count, load, mid, size / 2, depth + 1);
    s.push_str(&format!("{pad}}} else {{\n"));
    select_node(s, count, load, lo, size / 2, depth + 1);
    s.push_str(&format!("{pad}}}\n"));
}

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
    (
        "lib/trace_packet.wgsl",
        include_str!("../../shaders/lib/trace_packet.wgsl"),
    ),
    ("lib/csg.wgsl", include_str!("../../shaders/lib/csg.wgsl")),
    (
        "lib/outline.wgsl",
        include_str!("../../shaders/lib/outline.wgsl"),
    ),
    (
        "lib/scene_bindings.wgsl",
        include_str!("../../shaders/lib/scene_bindings.wgsl"),
    ),
    (
        "lib/random.wgsl",
        include_str!("../../shaders/lib/random.wgsl"),
    ),
    (
        "lib/texture.wgsl",
        include_str!("../../shaders/lib/texture.wgsl"),
    ),
    (
        "lib/gbuffer.wgsl",
        include_str!("../../shaders/lib/gbuffer.wgsl"),
    ),
    (
        "lib/accum.wgsl",
        include_str!("../../shaders/lib/accum.wgsl"),
    ),
    ("raster.wgsl", include_str!("../../shaders/raster.wgsl")),
    (
        "accumulate.wgsl",
        include_str!("../../shaders/accumulate.wgsl"),
    ),
    (
        "outline_tiles.wgsl",
        include_str!("../../shaders/outline_tiles.wgsl"),
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

    /// [`ShaderOverrides::read_dir`] for a folder given to replace the
    /// built-in shaders: one holding none of them (a mistyped folder, or
    /// the project's root instead of its `shaders/`) is an error, not a
    /// silent run of the built-in ones. `flag` names the option.
    pub fn read_given_dir(dir: &std::path::Path, flag: &str) -> Result<ShaderOverrides, GpuError> {
        let read = ShaderOverrides::read_dir(dir)?;
        if read.files.is_empty() {
            return Err(GpuError::Shader(format!(
                "{flag} {}: holds no shader file (each is read by its path under shaders/, e.g. {})",
                dir.display(),
                dir.join("trace.wgsl").display()
            )));
        }
        Ok(read)
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
/// `lib/trace_bvh.wgsl`'s functions (`trace_converged`, `trace_masked`,
/// `any_lane`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Traversal {
    /// celray's own two-level BVH, walked in WGSL (any adapter).
    #[default]
    Software,
    /// The driver's acceleration structures through wgpu ray queries
    /// (`lib/trace_rq.wgsl`; needs `Features::EXPERIMENTAL_RAY_QUERY`).
    Driver,
    /// celray's own BVH, walked by each subgroup of 8 invocations together
    /// (`lib/trace_packet.wgsl`; needs `Features::SUBGROUP` and subgroups
    /// of 8: [`crate::gpu::Gpu::packet_walk`]). The ray batch uses it where
    /// it can run.
    Packet,
}

impl Traversal {
    /// The include this traversal puts in place of `lib/trace_bvh.wgsl`,
    /// and the `enable` line it needs at the top of the module.
    fn swap(self) -> Option<(&'static str, Option<&'static str>)> {
        match self {
            Traversal::Software => None,
            Traversal::Driver => Some(("lib/trace_rq.wgsl", Some("enable wgpu_ray_query;"))),
            // naga (wgpu 30) takes subgroup built-ins without a directive
            // and rejects `enable subgroups;`.
            Traversal::Packet => Some(("lib/trace_packet.wgsl", None)),
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
    if let Some((_, Some(enable))) = swap {
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
    let src = match name {
        LIMITS_INCLUDE => limits_header(),
        SELECT_INCLUDE => select_tables_source(),
        _ => lookup(name).ok_or_else(|| GpuError::Shader(format!("no shader file {name:?}")))?,
    };
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
    create_module_sized(gpu, name, traversal, PrivateSizes::FULL)
}

/// The generated header's lines giving the private arrays' lengths.
fn size_lines(sizes: PrivateSizes) -> [String; 3] {
    [
        ("TRACE_STACK", sizes.trace_stack),
        ("CSG_EVAL_STACK", sizes.csg_stack),
        ("CSG_EVAL_INTERVALS", sizes.csg_intervals),
    ]
    .map(|(name, n)| format!("const {name}: u32 = {n}u;"))
}

/// `source` (a composed pass) with its private arrays of `sizes` (each 1
/// to its full length) in place of the header's full lengths (a pass
/// without the header only at the full lengths). The line count stays, so
/// error lines still map to their files.
pub fn with_sizes(source: &str, sizes: PrivateSizes) -> Result<String, GpuError> {
    let full = PrivateSizes::FULL;
    for (n, most, what) in [
        (
            sizes.trace_stack,
            full.trace_stack,
            "traversal stack entries",
        ),
        (sizes.csg_stack, full.csg_stack, "CSG stack entries"),
        (sizes.csg_intervals, full.csg_intervals, "CSG intervals"),
    ] {
        if !(1..=most).contains(&n) {
            return Err(GpuError::Shader(format!("{n} {what} (1 to {most})")));
        }
    }
    if sizes == full {
        return Ok(source.to_string());
    }
    let mut out = source.to_string();
    for (from, to) in size_lines(full).iter().zip(size_lines(sizes)) {
        if !out.contains(from.as_str()) {
            return Err(GpuError::Shader(format!(
                "no line {from:?} in the composed pass"
            )));
        }
        out = out.replacen(from.as_str(), &to, 1);
    }
    Ok(out)
}

/// One pass's modules by traversal and private-array lengths
/// ([`create_module_sized`]), each made the first time it is asked for.
pub struct SizedModules {
    name: &'static str,
    modules: std::collections::HashMap<(Traversal, PrivateSizes), wgpu::ShaderModule>,
}

impl SizedModules {
    /// None made yet, for pass `name`.
    pub fn new(name: &'static str) -> SizedModules {
        SizedModules {
            name,
            modules: Default::default(),
        }
    }

    /// The module with `traversal` and `sizes`, made now if not yet.
    pub fn get(
        &mut self,
        gpu: &crate::gpu::Gpu,
        traversal: Traversal,
        sizes: PrivateSizes,
    ) -> Result<&wgpu::ShaderModule, GpuError> {
        use std::collections::hash_map::Entry;
        Ok(match self.modules.entry((traversal, sizes)) {
            Entry::Occupied(e) => e.into_mut(),
            Entry::Vacant(e) => e.insert(create_module_sized(gpu, self.name, traversal, sizes)?),
        })
    }
}

/// [`create_module_variant`] with private arrays of `sizes`
/// ([`with_sizes`]; a scene's are `SceneAccel::sizes`).
pub fn create_module_sized(
    gpu: &crate::gpu::Gpu,
    name: &str,
    traversal: Traversal,
    sizes: PrivateSizes,
) -> Result<wgpu::ShaderModule, GpuError> {
    let overrides = gpu.shader_overrides();
    let composed = match &overrides {
        Some(o) => compose_with(name, o, traversal)?,
        None => compose_variant(name, traversal)?,
    };
    let source = with_sizes(&composed, sizes)?;
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
