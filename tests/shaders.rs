//! CPU-only shader checks: every composed pass validates with naga; every
//! Rust twin matches its WGSL struct in size, field offsets and constants;
//! every pass's bindings (group, number, type) match the Rust bind-group
//! layouts; and the limits WGSL shares with Rust come only from the header
//! generated from Rust (`gpu::shader::limits_header`), never a literal copy.

use std::mem::{offset_of, size_of};

use celray::gpu::shader::{compose, pass_files};
use celray::gpu::twins::*;

fn parse(name: &str) -> naga::Module {
    let src = compose(name).unwrap_or_else(|e| panic!("{name}: {e}"));
    naga::front::wgsl::parse_str(&src)
        .unwrap_or_else(|e| panic!("{name}:\n{}", e.emit_to_string(&src)))
}

#[test]
fn every_pass_validates() {
    let mut count = 0;
    for name in pass_files() {
        let module = parse(name);
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::all(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name} fails validation: {e:?}"));
        count += 1;
    }
    assert!(
        count >= 3,
        "expected at least the raster, accumulate and resolve passes"
    );
}

/// (size, [(field, offset)]) of WGSL struct `name` in `module`.
fn wgsl_layout(module: &naga::Module, name: &str) -> (u32, Vec<(String, u32)>) {
    for (_, ty) in module.types.iter() {
        if ty.name.as_deref() == Some(name) {
            if let naga::TypeInner::Struct { members, span } = &ty.inner {
                return (
                    *span,
                    members
                        .iter()
                        .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                        .collect(),
                );
            }
        }
    }
    panic!("struct {name} not found in WGSL");
}

macro_rules! check_twin {
    ($module:expr, $ty:ident { $($field:ident),* $(,)? }) => {{
        let (size, members) = wgsl_layout(&$module, stringify!($ty));
        assert_eq!(size as usize, size_of::<$ty>(), "size of {}", stringify!($ty));
        let rust: Vec<(String, u32)> = vec![$((stringify!($field).to_string(), offset_of!($ty, $field) as u32)),*];
        assert_eq!(members, rust, "fields and offsets of {}", stringify!($ty));
    }};
}

#[test]
fn twins_match_wgsl_layouts() {
    let module = parse("raster.wgsl");
    check_twin!(
        module,
        FrameUniforms {
            clip_from_world,
            eye_in_world,
            view_forward,
            ambient,
            background,
            size_px,
            light_count,
            sample_index,
            jitter_px,
            max_outline_px,
            seed,
            world_from_clip,
            mode,
            max_bounces,
            ray_epsilon,
            trace_accumulates,
            gbuffer_only,
            _pad1,
            _pad2,
            _pad3
        }
    );
    check_twin!(
        module,
        GpuLight {
            position_or_direction,
            radiance
        }
    );
    check_twin!(
        module,
        GpuMaterial {
            base_color,
            shininess,
            specular_color,
            highlight_cos,
            outline_color,
            outline_width_px,
            rim_color,
            rim_threshold,
            model,
            band_count,
            reflectivity,
            roughness,
            thresholds,
            checker_a,
            checker_size,
            checker_b,
            texture_layer,
            uv_scale,
            texture_nearest,
            _pad
        }
    );
    check_twin!(
        module,
        GpuInstance {
            world_from_object,
            object_from_world,
            normal_from_object,
            material,
            shape,
            mirrored,
            _pad
        }
    );
    let trace = parse("trace.wgsl");
    check_twin!(
        trace,
        BvhNode {
            bounds_min,
            left_or_first,
            bounds_max,
            count
        }
    );
    check_twin!(
        trace,
        GpuTriangle {
            p0,
            p1,
            p2,
            n0,
            n1,
            n2
        }
    );
    check_twin!(
        trace,
        GpuShape {
            params,
            kind,
            blas_root,
            csg_fast,
            _pad1
        }
    );
    check_twin!(trace, GpuCsgOp { op, arg });
    check_twin!(
        trace,
        GpuCsgLeaf {
            leaf_from_csg,
            csg_normal_from_leaf,
            params,
            kind,
            blas_root,
            material,
            table
        }
    );
    check_twin!(
        trace,
        GpuShadowCull {
            u,
            v,
            planes,
            cells_per_unit,
            dims,
            first_cell,
            plane_count,
            enabled,
            first_list,
            first_sphere,
            _pad
        }
    );
    check_twin!(trace, GpuRay { origin, dir });
    check_twin!(
        trace,
        GpuHit {
            normal,
            t,
            instance,
            steps,
            overflow,
            _pad
        }
    );
    check_twin!(
        module,
        ResolveUniforms {
            width,
            exposure,
            _pad
        }
    );
}

#[test]
fn reproject_twin_matches_wgsl() {
    let module = parse("reproject.wgsl");
    check_twin!(
        module,
        ReprojectUniforms {
            cur_clip_from_world,
            prev_clip_from_world,
            prev_eye,
            prev_forward,
            max_history,
            clip_gamma,
            depth_tolerance,
            rejection
        }
    );
    for (name, value) in [
        ("TEMPORAL_REJECT_NONE", TEMPORAL_REJECT_NONE),
        ("TEMPORAL_REJECT_CLIP", TEMPORAL_REJECT_CLIP),
    ] {
        assert_eq!(wgsl_u32_constant(&module, name), value, "{name}");
    }
    let main = module
        .entry_points
        .iter()
        .find(|e| e.name == "main")
        .expect("reproject main");
    assert_eq!(
        main.workgroup_size,
        [REPROJECT_WORKGROUP, REPROJECT_WORKGROUP, 1]
    );
}

fn wgsl_u32_constant(module: &naga::Module, name: &str) -> u32 {
    for (_, c) in module.constants.iter() {
        if c.name.as_deref() == Some(name) {
            match module.global_expressions[c.init] {
                naga::Expression::Literal(naga::Literal::U32(v)) => return v,
                ref other => panic!("{name} is not a u32 literal: {other:?}"),
            }
        }
    }
    panic!("constant {name} not found");
}

#[test]
fn constants_and_workgroup_sizes_match() {
    let module = parse("raster.wgsl");
    for (name, value) in [
        ("SHADING_BLINN_PHONG", SHADING_BLINN_PHONG),
        ("SHADING_TOON", SHADING_TOON),
        ("MAX_TOON_BANDS", MAX_TOON_BANDS),
        ("TONE_MAP_CLAMP", TONE_MAP_CLAMP),
        ("TONE_MAP_REINHARD", TONE_MAP_REINHARD),
        ("RENDER_MODE_RASTER", RENDER_MODE_RASTER),
        ("RENDER_MODE_HYBRID", RENDER_MODE_HYBRID),
        ("RENDER_MODE_RAYTRACE", RENDER_MODE_RAYTRACE),
        ("NO_TEXTURE", NO_TEXTURE),
    ] {
        assert_eq!(wgsl_u32_constant(&module, name), value, "{name}");
    }
    let trace = parse("trace.wgsl");
    for (name, value) in [
        ("SHAPE_SPHERE", SHAPE_SPHERE),
        ("SHAPE_BOX", SHAPE_BOX),
        ("SHAPE_CYLINDER", SHAPE_CYLINDER),
        ("SHAPE_CONE", SHAPE_CONE),
        ("SHAPE_QUAD", SHAPE_QUAD),
        ("SHAPE_DISK", SHAPE_DISK),
        ("SHAPE_MESH", SHAPE_MESH),
        ("SHAPE_CSG", SHAPE_CSG),
        ("CSG_OP_END", CSG_OP_END),
        ("CSG_OP_LEAF", CSG_OP_LEAF),
        ("CSG_OP_UNION", CSG_OP_UNION),
        ("CSG_OP_INTERSECTION", CSG_OP_INTERSECTION),
        ("CSG_OP_DIFFERENCE", CSG_OP_DIFFERENCE),
        ("CSG_NO_MATERIAL", CSG_NO_MATERIAL),
        ("CULL_CELL_MANY", CULL_CELL_MANY),
        ("CSG_MAX_INTERVALS", CSG_MAX_INTERVALS),
        ("CSG_STACK", CSG_STACK),
        ("CSG_MESH_MAX_CROSSINGS", CSG_MESH_MAX_CROSSINGS),
        ("CSG_ENDPOINTS", 2 * CSG_MAX_INTERVALS),
        ("CSG_SLOTS", CSG_STACK + 1),
        ("TRAVERSAL_STACK", TRAVERSAL_STACK),
        ("MAX_TRAVERSAL_STEPS", MAX_TRAVERSAL_STEPS),
    ] {
        assert_eq!(wgsl_u32_constant(&trace, name), value, "{name}");
    }
    let main = trace
        .entry_points
        .iter()
        .find(|e| e.name == "main")
        .expect("trace main");
    assert_eq!(main.workgroup_size, [TRACE_WORKGROUP, TRACE_WORKGROUP, 1]);
    let batch = parse("ray_batch.wgsl");
    let main = batch
        .entry_points
        .iter()
        .find(|e| e.name == "main")
        .expect("ray batch main");
    assert_eq!(main.workgroup_size, [RAY_BATCH_WORKGROUP, 1, 1]);
    assert_eq!(MAX_TOON_BANDS, celray::scene::MAX_TOON_BANDS);
    assert_eq!(CSG_MAX_INTERVALS, celray::scene::CSG_MAX_INTERVALS);
    assert_eq!(CSG_STACK, celray::scene::CSG_STACK);
    assert_eq!(
        CSG_MESH_MAX_CROSSINGS,
        celray::scene::CSG_MESH_MAX_CROSSINGS
    );
    let accumulate = parse("accumulate.wgsl");
    let entry = accumulate
        .entry_points
        .iter()
        .find(|e| e.name == "main")
        .expect("accumulate main");
    // Its edge is the override constant each pipeline sets.
    assert!(
        entry.workgroup_size_overrides.is_some(),
        "accumulate main's workgroup size comes from ACCUMULATE_TILE"
    );
}

#[test]
fn include_expander_includes_each_piece_once() {
    let src = compose("accumulate.wgsl").unwrap();
    assert_eq!(src.matches("struct FrameUniforms").count(), 1);
    assert!(!src.contains("#include"));
    assert!(compose("no-such-pass.wgsl").is_err());
}

/// The driver variants (lib/trace_rq.wgsl in place of lib/trace_bvh.wgsl)
/// of the passes that trace rays validate too, and only they carry ray
/// queries: the software kernels do not pay for them.
#[test]
fn driver_variants_validate_and_software_has_no_ray_queries() {
    use celray::gpu::shader::{compose_variant, Traversal};
    for name in ["trace.wgsl", "ray_batch.wgsl"] {
        let src = compose_variant(name, Traversal::Driver).unwrap_or_else(|e| panic!("{e}"));
        assert!(src.starts_with("enable wgpu_ray_query;"), "{name}");
        assert!(src.contains("rayQueryProceed"), "{name}");
        let module = naga::front::wgsl::parse_str(&src)
            .unwrap_or_else(|e| panic!("{name} (driver):\n{}", e.emit_to_string(&src)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::all(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name} (driver) fails validation: {e:?}"));
        let software = compose(name).unwrap();
        assert!(
            !software.contains("rayQuery") && !software.contains("acceleration_structure"),
            "{name}: the software variant carries ray-query code"
        );
        // Both define the one set of trace functions the pass calls.
        for f in ["fn trace_converged(", "fn trace_masked(", "fn any_lane("] {
            assert_eq!(src.matches(f).count(), 1, "{name} (driver): {f}");
            assert_eq!(software.matches(f).count(), 1, "{name}: {f}");
        }
    }
}

/// The packet variants (lib/trace_packet.wgsl in place of
/// lib/trace_bvh.wgsl) of the passes that trace rays validate, with the
/// subgroup operations only they use, and define the same functions for
/// the pass to call: `trace_converged`, `trace_masked` and `any_lane`.
#[test]
fn packet_variants_validate_and_only_they_use_subgroups() {
    use celray::gpu::shader::{compose_variant, Traversal};
    for name in ["trace.wgsl", "ray_batch.wgsl"] {
        let src = compose_variant(name, Traversal::Packet).unwrap_or_else(|e| panic!("{e}"));
        let module = naga::front::wgsl::parse_str(&src)
            .unwrap_or_else(|e| panic!("{name} (packet):\n{}", e.emit_to_string(&src)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::all(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name} (packet) fails validation: {e:?}"));
        let software = compose(name).unwrap();
        for op in [
            "subgroupBroadcast(",
            "subgroupAny(",
            "subgroupAdd(",
            "subgroupMin(",
        ] {
            assert!(src.contains(op), "{name} (packet): {op}");
            assert!(
                !software.contains(op),
                "{name}: the software variant uses {op}"
            );
        }
        for f in ["fn trace_converged(", "fn trace_masked(", "fn any_lane("] {
            assert_eq!(src.matches(f).count(), 1, "{name} (packet): {f}");
            assert_eq!(software.matches(f).count(), 1, "{name}: {f}");
        }
    }
}

/// The map word's layout (layer bits, glTF sampler bits) agrees between
/// src/gpu/twins.rs and shaders/lib/types.wgsl, in both passes' modules.
#[test]
fn map_word_constants_match() {
    for file in ["raster.wgsl", "trace.wgsl"] {
        let module = parse(file);
        for (name, value) in [
            ("MAP_LAYER_MASK", MAP_LAYER_MASK),
            ("MAP_WRAP_S_SHIFT", MAP_WRAP_S_SHIFT),
            ("MAP_WRAP_T_SHIFT", MAP_WRAP_T_SHIFT),
            ("MAP_WRAP_REPEAT", MAP_WRAP_REPEAT),
            ("MAP_WRAP_CLAMP", MAP_WRAP_CLAMP),
            ("MAP_WRAP_MIRROR", MAP_WRAP_MIRROR),
            ("MAP_MAG_NEAREST", MAP_MAG_NEAREST),
            ("MAP_MIN_NEAREST", MAP_MIN_NEAREST),
            ("MAP_MIP_NEAREST", MAP_MIP_NEAREST),
            ("MAP_NO_MIPS", MAP_NO_MIPS),
        ] {
            assert_eq!(wgsl_u32_constant(&module, name), value, "{file}: {name}");
        }
    }
}

fn wgsl_f32_constant(module: &naga::Module, name: &str) -> f32 {
    for (_, c) in module.constants.iter() {
        if c.name.as_deref() == Some(name) {
            match module.global_expressions[c.init] {
                naga::Expression::Literal(naga::Literal::F32(v)) => return v,
                ref other => panic!("{name} is not an f32 literal: {other:?}"),
            }
        }
    }
    panic!("constant {name} not found");
}

/// The f32 constants shared with Rust (CSG epsilons, far values) read back
/// bit for bit, as the u32 ones are.
#[test]
fn f32_constants_match() {
    use celray::accel::csg::{CSG_EPS_ABS, CSG_EPS_REL, CSG_FAR};
    for file in ["trace.wgsl", "ray_batch.wgsl"] {
        let module = parse(file);
        for (name, value) in [
            ("CSG_FAR", CSG_FAR),
            ("CSG_EPS_ABS", CSG_EPS_ABS),
            ("CSG_EPS_REL", CSG_EPS_REL),
            ("FAR_DEPTH", FAR_DEPTH),
            ("DEPTH_JUMP", celray::gpu::twins::DEPTH_JUMP),
        ] {
            let wgsl = wgsl_f32_constant(&module, name);
            assert_eq!(wgsl.to_bits(), value.to_bits(), "{file}: {name}");
        }
    }
}

/// Every limit of the generated header reads back from WGSL with its Rust
/// value, in every pass that includes it; the header's list names the twin
/// constants themselves.
#[test]
fn generated_limits_match_rust() {
    use celray::gpu::shader::{f32_limits, u32_limits};
    let listed = u32_limits();
    let expect = |name: &str| listed.iter().find(|(n, _)| *n == name).unwrap().1;
    for (name, value) in [
        ("TRAVERSAL_STACK", TRAVERSAL_STACK),
        ("MAX_TRAVERSAL_STEPS", MAX_TRAVERSAL_STEPS),
        ("MAX_INVOCATION_STEPS", MAX_INVOCATION_STEPS),
        ("CSG_MAX_INTERVALS", celray::scene::CSG_MAX_INTERVALS),
        ("CSG_STACK", celray::scene::CSG_STACK),
        (
            "CSG_MESH_MAX_CROSSINGS",
            celray::scene::CSG_MESH_MAX_CROSSINGS,
        ),
        ("MAX_TOON_BANDS", celray::scene::MAX_TOON_BANDS),
        ("MAX_OUTLINE_RADIUS", MAX_OUTLINE_RADIUS),
        ("TRACE_WORKGROUP", TRACE_WORKGROUP),
        ("MAX_CULL_PLANES", MAX_CULL_PLANES),
        ("RAY_BATCH_WORKGROUP", RAY_BATCH_WORKGROUP),
        ("MAX_ACCUMULATE_TILE", MAX_ACCUMULATE_TILE),
        ("REPROJECT_WORKGROUP", REPROJECT_WORKGROUP),
    ] {
        assert_eq!(expect(name), value, "{name}");
    }
    // The accumulate tile holds the workgroup and its outline halo.
    let tile = MAX_ACCUMULATE_TILE + 2 * MAX_OUTLINE_RADIUS;
    assert_eq!(expect("TILE_TEXELS"), tile * tile);
    for file in pass_files().filter(|f| *f != "bench_floor.wgsl") {
        let module = parse(file);
        for (name, value) in &listed {
            assert_eq!(wgsl_u32_constant(&module, name), *value, "{file}: {name}");
        }
        for (name, value) in f32_limits() {
            let wgsl = wgsl_f32_constant(&module, name);
            assert_eq!(wgsl.to_bits(), value.to_bits(), "{file}: {name}");
        }
    }
}

/// No shader file declares a limit of the generated header itself, nor
/// writes the big ones as literals: the header is their only WGSL source.
#[test]
fn wgsl_has_no_literal_copy_of_a_limit() {
    use celray::gpu::shader::{f32_limits, limits_header, u32_limits, SHADER_FILES};
    let names: Vec<&str> = u32_limits()
        .iter()
        .map(|(n, _)| *n)
        .chain(f32_limits().iter().map(|(n, _)| *n))
        .collect();
    for (file, text) in SHADER_FILES {
        for line in text.lines() {
            let code = line.split("//").next().unwrap_or("");
            for name in &names {
                for keyword in ["const", "override", "let", "var"] {
                    assert!(
                        !code.contains(&format!("{keyword} {name}:"))
                            && !code.contains(&format!("{keyword} {name} ")),
                        "{file} declares {name}, which comes from the generated header: {line}"
                    );
                }
            }
            for literal in ["65504", "48000", "12000", "1e30", "1.0e30"] {
                assert!(
                    !code.contains(literal),
                    "{file} writes the limit {literal} as a literal: {line}"
                );
            }
        }
    }
    for name in &names {
        assert_eq!(
            limits_header().matches(&format!("const {name}:")).count(),
            1,
            "{name} in the generated header"
        );
    }
}

/// The bind-group layouts Rust builds for pass `file`, by group.
fn rust_groups(file: &str) -> Vec<(u32, &'static [wgpu::BindGroupLayoutEntry])> {
    use celray::render::scene_buffers::{PASS_GROUP, SCENE_GROUP, SCENE_LAYOUT};
    use celray::render::{accumulate, raster, ray_batch, reproject, resolve, trace};
    let scene_and = |own: &'static [wgpu::BindGroupLayoutEntry]| {
        vec![(SCENE_GROUP, &SCENE_LAYOUT[..]), (PASS_GROUP, own)]
    };
    match file {
        "raster.wgsl" => scene_and(&raster::PASS_LAYOUT),
        "trace.wgsl" => scene_and(&trace::PASS_LAYOUT),
        "ray_batch.wgsl" => scene_and(&ray_batch::PASS_LAYOUT),
        "accumulate.wgsl" => scene_and(&accumulate::PASS_LAYOUT),
        "outline_tiles.wgsl" => scene_and(&accumulate::TILES_LAYOUT),
        "resolve.wgsl" => vec![(0, &resolve::PASS_LAYOUT[..])],
        "reproject.wgsl" => vec![(0, &reproject::PASS_LAYOUT[..])],
        "bench_floor.wgsl" => vec![(0, &celray::gpu::layout::BENCH_FLOOR_LAYOUT[..])],
        other => panic!("{other}: a pass with no Rust layout listed in tests/shaders.rs"),
    }
}

/// A binding's kind, said the same way for a WGSL global and a Rust layout
/// entry (WGSL cannot say whether a float texture is filterable or which
/// kind of non-comparison sampler it is, so neither side does).
fn wgsl_binding_kind(module: &naga::Module, var: &naga::GlobalVariable) -> String {
    use naga::{AddressSpace, ImageClass, StorageAccess, TypeInner};
    let access = |a: StorageAccess| match (
        a.contains(StorageAccess::LOAD),
        a.contains(StorageAccess::STORE),
    ) {
        (true, false) => "read",
        (false, true) => "write",
        _ => "read_write",
    };
    match var.space {
        AddressSpace::Uniform => "uniform buffer".into(),
        AddressSpace::Storage { access: a } => format!("storage buffer, {}", access(a)),
        AddressSpace::Handle => match &module.types[var.ty].inner {
            TypeInner::Image {
                dim,
                arrayed,
                class,
            } => {
                let dim = format!("{dim:?}{}", if *arrayed { " array" } else { "" });
                match class {
                    ImageClass::Sampled { kind, multi } => {
                        format!("texture {kind:?} {dim} multisampled={multi}")
                    }
                    ImageClass::Depth { multi } => {
                        format!("texture Depth {dim} multisampled={multi}")
                    }
                    ImageClass::Storage { format, access: a } => {
                        format!("storage texture {format:?} {dim} {}", access(*a))
                    }
                    ImageClass::External => "external texture".into(),
                }
            }
            TypeInner::Sampler { comparison } => format!("sampler comparison={comparison}"),
            TypeInner::AccelerationStructure { .. } => "acceleration structure".into(),
            other => panic!("binding of unexpected type {other:?}"),
        },
        other => panic!("binding in address space {other:?}"),
    }
}

fn rust_binding_kind(entry: &wgpu::BindGroupLayoutEntry) -> String {
    use wgpu::{BindingType, BufferBindingType, StorageTextureAccess, TextureSampleType};
    let dim = |d: wgpu::TextureViewDimension| match d {
        wgpu::TextureViewDimension::D1 => "D1",
        wgpu::TextureViewDimension::D2 => "D2",
        wgpu::TextureViewDimension::D2Array => "D2 array",
        wgpu::TextureViewDimension::Cube => "Cube",
        wgpu::TextureViewDimension::CubeArray => "Cube array",
        wgpu::TextureViewDimension::D3 => "D3",
    };
    match entry.ty {
        BindingType::Buffer {
            ty: BufferBindingType::Uniform,
            ..
        } => "uniform buffer".into(),
        BindingType::Buffer {
            ty: BufferBindingType::Storage { read_only },
            ..
        } => format!(
            "storage buffer, {}",
            if read_only { "read" } else { "read_write" }
        ),
        BindingType::Texture {
            sample_type,
            view_dimension,
            multisampled,
        } => {
            let kind = match sample_type {
                TextureSampleType::Float { .. } => "Float",
                TextureSampleType::Uint => "Uint",
                TextureSampleType::Sint => "Sint",
                TextureSampleType::Depth => "Depth",
            };
            format!(
                "texture {kind} {} multisampled={multisampled}",
                dim(view_dimension)
            )
        }
        BindingType::StorageTexture {
            access,
            format,
            view_dimension,
        } => {
            let access = match access {
                StorageTextureAccess::ReadOnly => "read",
                StorageTextureAccess::WriteOnly => "write",
                _ => "read_write",
            };
            format!(
                "storage texture {format:?} {} {access}",
                dim(view_dimension)
            )
        }
        BindingType::Sampler(s) => format!(
            "sampler comparison={}",
            s == wgpu::SamplerBindingType::Comparison
        ),
        BindingType::AccelerationStructure { .. } => "acceleration structure".into(),
        ref other => panic!("unexpected Rust binding type {other:?}"),
    }
}

/// Checks every binding of `module` (pass `label`) against `groups`, both
/// ways, and that each entry is visible to every entry point that uses it.
fn check_bindings(
    label: &str,
    module: &naga::Module,
    groups: &[(u32, &[wgpu::BindGroupLayoutEntry])],
) {
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(module)
    .unwrap_or_else(|e| panic!("{label} fails validation: {e:?}"));
    // The stages whose entry points use global `handle`.
    let stages = |handle: naga::Handle<naga::GlobalVariable>| {
        module
            .entry_points
            .iter()
            .enumerate()
            .filter(|(i, _)| !info.get_entry_point(*i)[handle].is_empty())
            .map(|(_, e)| match e.stage {
                naga::ShaderStage::Vertex => wgpu::ShaderStages::VERTEX,
                naga::ShaderStage::Fragment => wgpu::ShaderStages::FRAGMENT,
                naga::ShaderStage::Compute => wgpu::ShaderStages::COMPUTE,
                other => panic!("{label}: unexpected stage {other:?}"),
            })
            .fold(wgpu::ShaderStages::NONE, |a, b| a | b)
    };
    let mut seen = Vec::new();
    for (handle, var) in module.global_variables.iter() {
        let Some(rb) = &var.binding else { continue };
        let name = var.name.as_deref().unwrap_or("?");
        let at = format!(
            "{label}: {name} (@group({}) @binding({}))",
            rb.group, rb.binding
        );
        let entries = groups
            .iter()
            .find(|(g, _)| *g == rb.group)
            .unwrap_or_else(|| panic!("{at}: Rust has no group {}", rb.group))
            .1;
        let entry = entries
            .iter()
            .find(|e| e.binding == rb.binding)
            .unwrap_or_else(|| panic!("{at}: Rust's group has no binding {}", rb.binding));
        assert_eq!(
            wgsl_binding_kind(module, var),
            rust_binding_kind(entry),
            "{at}: WGSL (left) and Rust (right) disagree"
        );
        let used_in = stages(handle);
        assert!(
            entry.visibility.contains(used_in),
            "{at}: visible to {:?}, used in {used_in:?}",
            entry.visibility
        );
        assert!(entry.count.is_none(), "{at}: binding arrays are not used");
        seen.push((rb.group, rb.binding));
    }
    for (group, entries) in groups {
        for e in entries.iter() {
            assert!(
                seen.contains(&(*group, e.binding)),
                "{label}: Rust's group {group} binding {} has no WGSL declaration",
                e.binding
            );
        }
    }
}

/// Every pass's global variables against the Rust bind-group layouts:
/// group, binding number and type (uniform / read-only / read-write storage
/// buffer, texture kind and dimension, storage texture format and access,
/// sampler, acceleration structure), both ways; the driver variants with
/// the driver's group too.
#[test]
fn bindings_match_rust_layouts() {
    use celray::gpu::shader::{compose_variant, Traversal};
    use celray::render::driver_accel::{DRIVER_GROUP, DRIVER_LAYOUT};
    let mut count = 0;
    for file in pass_files() {
        check_bindings(file, &parse(file), &rust_groups(file));
        count += 1;
    }
    assert!(count >= 7, "every pass file is checked");
    for file in ["trace.wgsl", "ray_batch.wgsl"] {
        let src = compose_variant(file, Traversal::Packet).unwrap();
        let module = naga::front::wgsl::parse_str(&src)
            .unwrap_or_else(|e| panic!("{file} (packet):\n{}", e.emit_to_string(&src)));
        check_bindings(&format!("{file} (packet)"), &module, &rust_groups(file));
        let src = compose_variant(file, Traversal::Driver).unwrap();
        let module = naga::front::wgsl::parse_str(&src)
            .unwrap_or_else(|e| panic!("{file} (driver):\n{}", e.emit_to_string(&src)));
        let mut groups = rust_groups(file);
        groups.push((DRIVER_GROUP, &DRIVER_LAYOUT[..]));
        check_bindings(&format!("{file} (driver)"), &module, &groups);
    }
}

/// The scene's group is declared once, in lib/scene_bindings.wgsl: every
/// pass file that names one of its bindings includes it, and no pass that
/// includes it, nor any other shader-lib piece, declares a group-0 binding
/// of its own next to it. (Passes that read no scene, such as resolve, bind
/// their own resources as group 0.)
#[test]
fn scene_group_is_declared_once() {
    use celray::gpu::shader::SHADER_FILES;
    const SCENE: &str = "lib/scene_bindings.wgsl";
    let include = format!("#include \"{SCENE}\"");
    let scene_text = SHADER_FILES
        .iter()
        .find(|(file, _)| *file == SCENE)
        .map(|(_, text)| *text)
        .expect("lib/scene_bindings.wgsl is embedded");
    // `@group(0) @binding(N) var<...> NAME: TYPE;` -> NAME
    let scene_names: Vec<&str> = scene_text
        .lines()
        .filter(|l| l.starts_with("@group(0)"))
        .filter_map(|l| l.split(" var").nth(1))
        .map(|rest| match rest.strip_prefix('<') {
            Some(access) => access.split_once('>').map_or(access, |(_, after)| after),
            None => rest,
        })
        .filter_map(|rest| rest.split(':').next())
        .map(str::trim)
        .collect();
    assert_eq!(
        scene_names.len(),
        celray::render::scene_buffers::SCENE_LAYOUT.len(),
        "scene bindings parsed: {scene_names:?}"
    );
    let names_binding = |text: &str, name: &str| {
        text.lines()
            .map(|l| l.split("//").next().unwrap_or(""))
            .any(|code| {
                code.match_indices(name).any(|(at, _)| {
                    let before = code[..at].chars().next_back();
                    let after = code[at + name.len()..].chars().next();
                    !before.is_some_and(|c| c.is_alphanumeric() || c == '_')
                        && !after.is_some_and(|c| c.is_alphanumeric() || c == '_')
                })
            })
    };
    let mut users = 0;
    for (file, text) in SHADER_FILES {
        if *file == SCENE {
            continue;
        }
        let includes = text.contains(&include);
        if !file.starts_with("lib/") {
            if let Some(name) = scene_names.iter().find(|n| names_binding(text, n)) {
                assert!(
                    includes,
                    "{file} reads the scene's `{name}` and must include {SCENE}"
                );
            }
        }
        users += usize::from(includes);
        if includes || file.starts_with("lib/") {
            assert!(
                !text.contains("@group(0)"),
                "{file} declares a group-0 binding: the scene's group is {SCENE}'s"
            );
        }
    }
    assert!(users > 0, "no pass includes {SCENE}");
}

/// Each uniform copy of a scene table (gpu::uniform_tables) is declared in
/// WGSL as as many whole elements as fit in UNIFORM_TABLE_BYTES (what the
/// buffer holds), each element what the storage table's are (or four
/// two CSG instructions to a vec4: the same bytes), so
/// that a table of n elements, which the Rust side copies when n elements
/// of storage fit, is read at the same indices.
#[test]
fn uniform_table_copies_hold_the_storage_tables_bytes() {
    use celray::gpu::uniform_tables::{Table, UNIFORM_TABLE_BYTES};
    use naga::{AddressSpace, ArraySize, ResourceBinding, TypeInner};
    let module = parse("trace.wgsl");
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).unwrap();
    let array_at = |binding: u32| {
        let (_, var) = module
            .global_variables
            .iter()
            .find(|(_, v)| v.binding == Some(ResourceBinding { group: 0, binding }))
            .unwrap_or_else(|| panic!("no scene binding {binding}"));
        match module.types[var.ty].inner {
            TypeInner::Array { size, stride, .. } => {
                (var.space, size, stride, layouter[var.ty].size)
            }
            ref other => panic!("binding {binding} is {other:?}, not an array"),
        }
    };
    // The storage bindings of the same tables (lib/scene_bindings.wgsl).
    let storage_binding = |t: Table| match t {
        Table::Nodes => 4,
        Table::Instances => 0,
        Table::Shapes => 3,
        Table::Materials => 1,
        Table::CsgOps => 7,
        Table::CsgLeaves => 8,
    };
    for t in Table::ALL {
        let (space, size, stride, bytes) = array_at(t.binding());
        assert_eq!(space, AddressSpace::Uniform, "{t:?}");
        let ArraySize::Constant(n) = size else {
            panic!("{t:?}: the uniform copy has no fixed length");
        };
        assert_eq!(n.get(), t.uniform_length(), "{t:?}");
        assert!(bytes <= UNIFORM_TABLE_BYTES, "{t:?}: {bytes} bytes");
        assert!(
            bytes + stride > UNIFORM_TABLE_BYTES,
            "{t:?}: room for one more"
        );
        let (_, _, storage_stride, _) = array_at(storage_binding(t));
        let per_element = match t {
            Table::CsgOps => 2,
            _ => 1,
        };
        assert_eq!(stride, storage_stride * per_element, "{t:?}: element size");
        // A table fits exactly when its bytes are within the copy.
        let fitting = (bytes / storage_stride) as usize;
        assert!(t.fits(fitting * storage_stride as usize), "{t:?}");
        assert!(!t.fits((fitting + 1) * storage_stride as usize), "{t:?}");
    }
}

/// No pass binds more than 7 uniform buffers to one shader stage, its own
/// and the scene's together: Mesa 22.3's lavapipe corrupts its heap with 8
/// (it reports a limit of 15). Measured with the app's warm-up tests on
/// Mesa 22.3.6: with 7 scene copies and the frame uniforms they crashed in
/// about half the runs, with 6 and 4 in none of 8.
#[test]
fn no_stage_binds_more_than_seven_uniform_buffers() {
    use wgpu::{BindingType, BufferBindingType, ShaderStages};
    let mut checked = 0;
    for file in pass_files() {
        let groups = rust_groups(file);
        for stage in [
            ShaderStages::VERTEX,
            ShaderStages::FRAGMENT,
            ShaderStages::COMPUTE,
        ] {
            let uniforms = groups
                .iter()
                .flat_map(|(_, entries)| entries.iter())
                .filter(|e| e.visibility.contains(stage))
                .filter(|e| {
                    matches!(
                        e.ty,
                        BindingType::Buffer {
                            ty: BufferBindingType::Uniform,
                            ..
                        }
                    )
                })
                .count();
            assert!(
                uniforms <= 7,
                "{file}: {uniforms} uniform buffers in the {stage:?} stage"
            );
            checked += uniforms;
        }
    }
    assert!(checked > 0, "no uniform buffer was counted");
}

/// A pass built for a scene (`create_module_sized`) declares its private
/// arrays with the scene's lengths: the traversal stack `TRACE_STACK`
/// entries long in place of the full `TRAVERSAL_STACK`, the CSG store
/// (`CSG_EVAL_STACK` + 1 entries of 2 `CSG_EVAL_INTERVALS` endpoints) in
/// place of `CSG_STACK` and `CSG_MAX_INTERVALS`; nothing else changes:
/// the same lines, so that errors still map to their files, and the same
/// text outside those three. Lengths of 0 and past the full ones are
/// refused.
#[test]
fn a_sized_pass_declares_the_arrays_its_scene_needs() {
    use celray::accel::PrivateSizes;
    use celray::gpu::shader::with_sizes;
    let full = compose("trace.wgsl").unwrap();
    let sizes = PrivateSizes {
        trace_stack: 5,
        csg_stack: 2,
        csg_intervals: 3,
    };
    let sized = with_sizes(&full, sizes).unwrap();
    assert_eq!(sized.lines().count(), full.lines().count());
    let changed = full
        .lines()
        .zip(sized.lines())
        .filter(|(a, b)| a != b)
        .count();
    assert_eq!(changed, 3);
    let module = naga::front::wgsl::parse_str(&sized).unwrap();
    assert_eq!(wgsl_u32_constant(&module, "TRACE_STACK"), 5);
    assert_eq!(
        wgsl_u32_constant(&module, "TRAVERSAL_STACK"),
        TRAVERSAL_STACK
    );
    // The length of the array type of global `var`, or of its member.
    let length = |var: &str, member: Option<&str>| {
        let global = module
            .global_variables
            .iter()
            .find(|(_, g)| g.name.as_deref() == Some(var))
            .unwrap_or_else(|| panic!("no {var}"))
            .1;
        let mut ty = global.ty;
        if let Some(m) = member {
            match &module.types[ty].inner {
                naga::TypeInner::Struct { members, .. } => {
                    ty = members
                        .iter()
                        .find(|x| x.name.as_deref() == Some(m))
                        .unwrap()
                        .ty
                }
                other => panic!("{var} is {other:?}"),
            }
        }
        match module.types[ty].inner {
            naga::TypeInner::Array {
                size: naga::ArraySize::Constant(n),
                ..
            } => n.get(),
            ref other => panic!("{var} is {other:?}"),
        }
    };
    assert_eq!(length("trace_stack", None), 5);
    // 3 slots (2 entries and the scratch one) of 6 endpoints.
    assert_eq!(length("csg_store", Some("t")), 18);
    assert_eq!(length("csg_store", Some("len")), 3);
    assert_eq!(with_sizes(&full, PrivateSizes::FULL).unwrap(), full);
    let full_module = parse("trace.wgsl");
    assert_eq!(
        wgsl_u32_constant(&full_module, "CSG_STORE_ENDPOINTS"),
        (CSG_STACK + 1) * 2 * CSG_MAX_INTERVALS
    );
    for bad in [
        PrivateSizes {
            trace_stack: 0,
            ..sizes
        },
        PrivateSizes {
            trace_stack: TRAVERSAL_STACK + 1,
            ..sizes
        },
        PrivateSizes {
            csg_stack: CSG_STACK + 1,
            ..sizes
        },
        PrivateSizes {
            csg_intervals: 0,
            ..sizes
        },
    ] {
        assert!(with_sizes(&full, bad).is_err(), "{bad:?}");
    }
}
