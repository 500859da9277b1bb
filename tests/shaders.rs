//! CPU-only shader checks: every composed pass validates with naga, and every
//! Rust twin matches its WGSL struct in size, field offsets and constants.

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
            _pad
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
            specular_threshold,
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
            _pad0,
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
            tone_map,
            encode_srgb,
            exposure
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
    assert_eq!(
        entry.workgroup_size,
        [ACCUMULATE_WORKGROUP, ACCUMULATE_WORKGROUP, 1]
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
        // Both define the one `trace` the pass calls.
        assert_eq!(src.matches("fn trace(").count(), 1, "{name} (driver)");
        assert_eq!(software.matches("fn trace(").count(), 1, "{name}");
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
