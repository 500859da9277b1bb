//! Integration tests of the scene module: the shipped scene files, mesh
//! loading, tessellation, `--set` overrides and every load error.

use std::path::{Path, PathBuf};

use celray::scene::{
    parse_shading_model, sphere_inset, tessellate, tessellate_sphere, Light, Mesh, PlaneKind,
    Scene, SceneError, ShadingModel, Shape, Toon, MAX_TOON_BANDS, ROUND_SEGMENTS, SPHERE_LEVELS,
    SPHERE_RINGS, SPHERE_SEGMENTS,
};
use glam::{Vec2, Vec3, Vec4};

fn assets() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets")
}

/// A fresh, empty scratch directory for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create scratch dir");
    dir
}

const CAMERA: &str = "(eye: (0.0, 1.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), \
                      fov_y_deg: 40.0, width: 320, height: 240)";

/// A small valid scene with a material "red", shapes "ball" and "crate"
/// and one instance; `edit` replaces parts of it.
fn scene_text(edit: &[(&str, &str)]) -> String {
    let mut text = format!(
        r#"(
    version: 1,
    camera: {CAMERA},
    lights: [Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 1.0)],
    materials: {{ "red": (base_color: (0.8, 0.1, 0.1), model: Toon(bands: 4)) }},
    shapes: {{ "ball": Sphere(radius: 1.0), "crate": Box(half_extents: (0.5, 0.5, 0.5)) }},
    instances: [(shape: "ball", material: "red")],
)"#
    );
    for (from, to) in edit {
        assert!(text.contains(from), "test bug: {from} not in scene text");
        text = text.replacen(from, to, 1);
    }
    text
}

fn parse(src: &str) -> Result<Scene, SceneError> {
    Scene::from_ron_str(src, "test.ron", &assets().join("scenes"))
}

/// Parses `src`, expecting an error; returns its message.
fn error_of(src: &str) -> String {
    match parse(src) {
        Ok(_) => panic!("expected an error for:\n{src}"),
        Err(e) => e.to_string(),
    }
}

fn assert_contains(message: &str, parts: &[&str]) {
    for part in parts {
        assert!(
            message.contains(part),
            "message {message:?} should contain {part:?}"
        );
    }
}

// ---------------------------------------------------------------- files

#[test]
fn every_scene_file_loads_and_validates() {
    let dir = assets().join("scenes");
    let mut names = Vec::new();
    for entry in std::fs::read_dir(&dir).expect("read assets/scenes") {
        let path = entry.expect("dir entry").path();
        if path.extension().is_some_and(|e| e == "ron") {
            let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
            scene.validate().unwrap_or_else(|e| panic!("{e}"));
            assert!(!scene.instances.is_empty(), "{} is empty", path.display());
            names.push(path.file_name().unwrap().to_string_lossy().into_owned());
        }
    }
    for expected in ["default.ron", "toon_vs_blinn.ron"] {
        assert!(names.iter().any(|n| n == expected), "{expected} missing");
    }
}

#[test]
fn builtin_default_matches_default_ron() {
    let builtin = Scene::builtin_default();
    let from_file = Scene::load(&assets().join("scenes/default.ron")).unwrap();
    assert_eq!(builtin.instances, from_file.instances);
    assert_eq!(builtin.materials, from_file.materials);
    assert_eq!(builtin.material_names, from_file.material_names);
    assert_eq!(builtin.shape_names, from_file.shape_names);
    assert_eq!(builtin.camera, from_file.camera);
    assert!(Scene::BUILTIN_DEFAULT_RON.contains("../models/spot/spot_triangulated.obj"));
}

fn toon_bands(model: &ShadingModel) -> Option<u32> {
    match model {
        ShadingModel::Toon(t) => Some(t.bands()),
        ShadingModel::BlinnPhong => None,
    }
}

#[test]
fn default_scene_has_the_required_content() {
    let scene = Scene::builtin_default();
    assert_eq!((scene.camera.width, scene.camera.height), (1280, 720));
    assert!(scene
        .materials
        .iter()
        .all(|m| toon_bands(&m.model).is_some()));

    let directional = scene
        .lights
        .iter()
        .filter(|l| matches!(l, Light::Directional { .. }))
        .count();
    let point = scene
        .lights
        .iter()
        .filter(|l| matches!(l, Light::Point { .. }))
        .count();
    assert_eq!((directional, point), (1, 1));

    let shape_of = |i: &celray::scene::Instance| &scene.shapes[i.shape];
    let sphere_colours: Vec<Vec3> = scene
        .instances
        .iter()
        .filter(|i| matches!(shape_of(i), Shape::Sphere { .. }))
        .map(|i| scene.materials[i.material].base_color)
        .collect();
    assert!(sphere_colours.len() >= 2);
    for (a, i) in sphere_colours.iter().enumerate() {
        for b in &sphere_colours[a + 1..] {
            assert_ne!(i, b, "spheres should differ in colour");
        }
    }
    assert!(scene
        .instances
        .iter()
        .any(|i| matches!(shape_of(i), Shape::Box { .. })));
    let floor = scene
        .instances
        .iter()
        .find(|i| matches!(shape_of(i), Shape::Plane(PlaneKind::Quad { .. })))
        .expect("floor");
    let (lo, hi) = shape_of(floor).bounds();
    assert!(hi.x - lo.x >= 10.0 && hi.z - lo.z >= 10.0, "floor is large");

    // The cow stands on the floor (y = 0).
    let cow = scene
        .instances
        .iter()
        .find(|i| matches!(shape_of(i), Shape::Mesh(_)))
        .expect("cow instance");
    let Shape::Mesh(mesh) = shape_of(cow) else {
        unreachable!()
    };
    assert_eq!(mesh.triangle_count(), 5856);
    let min_y = mesh
        .positions
        .iter()
        .map(|&p| cow.world_from_object.transform_point3(p).y)
        .fold(f32::INFINITY, f32::min);
    assert!(min_y.abs() < 0.01, "cow feet at y = {min_y}");

    // Every object except the floor is inside the frame.
    let cam = &scene.camera;
    let forward = (cam.target - cam.eye).normalize();
    let right = forward.cross(cam.up).normalize();
    let up = right.cross(forward);
    let tan_half = (cam.fov_y_deg.to_radians() / 2.0).tan();
    for (k, instance) in scene.instances.iter().enumerate() {
        let points: Vec<Vec3> = match shape_of(instance) {
            Shape::Plane(_) => continue,
            Shape::Mesh(m) => m.positions.clone(),
            other => tessellate(other).positions,
        };
        for p in points {
            let d = instance.world_from_object.transform_point3(p) - cam.eye;
            let depth = d.dot(forward);
            let ndc_x = d.dot(right) / (depth * tan_half * cam.aspect());
            let ndc_y = d.dot(up) / (depth * tan_half);
            assert!(
                depth > 0.0 && ndc_x.abs() < 0.95 && ndc_y.abs() < 0.95,
                "instance {k} leaves the frame: ({ndc_x}, {ndc_y})"
            );
        }
    }
}

#[test]
fn toon_vs_blinn_shows_the_four_models_side_by_side() {
    let scene = Scene::load(&assets().join("scenes/toon_vs_blinn.ron")).unwrap();
    assert_eq!(scene.lights.len(), 1);
    assert!(matches!(scene.lights[0], Light::Directional { .. }));
    let mut row: Vec<(f32, Option<u32>, Vec3)> = scene
        .instances
        .iter()
        .map(|i| {
            assert!(matches!(scene.shapes[i.shape], Shape::Sphere { .. }));
            let m = &scene.materials[i.material];
            (
                i.world_from_object.w_axis.x,
                toon_bands(&m.model),
                m.base_color,
            )
        })
        .collect();
    row.sort_by(|a, b| a.0.total_cmp(&b.0));
    let bands: Vec<Option<u32>> = row.iter().map(|r| r.1).collect();
    assert_eq!(bands, [None, Some(2), Some(4), Some(7)]);
    assert!(row.iter().all(|r| r.2 == row[0].2), "same base colour");
}

#[test]
fn format_example_in_the_module_docs_parses() {
    let source =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("src/scene/mod.rs"))
            .unwrap();
    let doc: Vec<&str> = source
        .lines()
        .filter_map(|l| l.strip_prefix("//!"))
        .map(|l| l.strip_prefix(' ').unwrap_or(l))
        .collect();
    let start = doc
        .iter()
        .position(|l| *l == "```ron")
        .expect("ron example")
        + 1;
    let end = start + doc[start..].iter().position(|l| *l == "```").unwrap();
    let example = doc[start..end].join("\n");
    let scene = parse(&example).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.shapes.len(), 8);
    assert!(matches!(scene.shapes[7], celray::scene::Shape::Csg(_)));
    assert_eq!(scene.instances.len(), 3);
    assert_eq!(scene.instances[1].world_from_object.w_axis.x, 2.0);
}

// --------------------------------------------------------------- meshes

fn assert_unit_normals(mesh: &Mesh) {
    assert_eq!(mesh.normals.len(), mesh.positions.len());
    for n in &mesh.normals {
        assert!((n.length() - 1.0).abs() < 1e-4, "normal {n} is not unit");
    }
}

#[test]
fn spot_obj_loads_with_outward_unit_normals() {
    let mesh = Mesh::load(&assets().join("models/spot/spot_triangulated.obj")).unwrap();
    assert_eq!(mesh.triangle_count(), 5856);
    assert_unit_normals(&mesh);

    let centroid = mesh.positions.iter().copied().sum::<Vec3>() / mesh.positions.len() as f32;
    let outward = mesh
        .positions
        .iter()
        .zip(&mesh.normals)
        .filter(|(&p, &n)| n.dot(p - centroid) > 0.0)
        .count();
    let fraction = outward as f32 / mesh.positions.len() as f32;
    assert!(
        fraction > 0.85,
        "only {fraction} of the normals point outward"
    );

    // Counter-clockwise outward winding encloses a positive volume.
    let volume: f32 = mesh
        .indices
        .chunks_exact(3)
        .map(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize] - centroid);
            a.dot(b.cross(c)) / 6.0
        })
        .sum();
    assert!(volume > 0.0, "enclosed volume {volume}");

    // The computed normals agree with the triangles' winding.
    assert_winding_matches_normals(&mesh, 0.99);
}

/// At least `fraction` of the non-degenerate triangles face the same way
/// as their vertex normals.
fn assert_winding_matches_normals(mesh: &Mesh, fraction: f32) {
    let (mut agree, mut total) = (0, 0);
    for tri in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| tri[k] as usize);
        let face =
            (mesh.positions[b] - mesh.positions[a]).cross(mesh.positions[c] - mesh.positions[a]);
        if face.length_squared() < 1e-20 {
            continue;
        }
        total += 1;
        let normal = mesh.normals[a] + mesh.normals[b] + mesh.normals[c];
        if face.dot(normal) > 0.0 {
            agree += 1;
        }
    }
    assert!(total > 0);
    let got = agree as f32 / total as f32;
    assert!(got >= fraction, "{} of triangles agree: {got}", mesh.source);
}

#[test]
fn box_gltf_applies_node_transforms() {
    let mesh = Mesh::load(&assets().join("models/Box/Box.gltf")).unwrap();
    assert_eq!(mesh.triangle_count(), 12);
    assert_unit_normals(&mesh);
    let (lo, hi) = mesh.bounds();
    assert!((lo + Vec3::splat(0.5)).abs().max_element() < 1e-5, "{lo}");
    assert!((hi - Vec3::splat(0.5)).abs().max_element() < 1e-5, "{hi}");
    // Face normals point away from the centre after the node rotation.
    for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
        assert!((p.dot(*n) - 0.5).abs() < 1e-5, "normal {n} at {p}");
    }
    assert_winding_matches_normals(&mesh, 1.0);
}

#[test]
fn flight_helmet_merges_all_primitives() {
    let mesh = Mesh::load(&assets().join("models/FlightHelmet/FlightHelmet.gltf")).unwrap();
    assert_eq!(mesh.triangle_count(), 94_722);
    assert_unit_normals(&mesh);
    assert!(mesh.validate().is_ok());
}

#[test]
fn obj_without_normals_gets_smooth_normals() {
    // A unit square pyramid in two OBJ objects; the files has no normals.
    let obj = b"v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nv 0.5 1 0.5\n\
                o base\nf 1 2 3 4\no sides\nf 1 5 2\nf 2 5 3\nf 3 5 4\nf 4 5 1\n";
    let mesh = Mesh::from_obj_bytes(obj, "pyramid.obj").unwrap();
    assert_eq!(mesh.triangle_count(), 6);
    assert_unit_normals(&mesh);
    // The apex normal points straight up (area-weighted, symmetric).
    for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
        if p.y == 1.0 {
            assert!(n.abs_diff_eq(Vec3::Y, 1e-5), "apex normal {n}");
        }
    }
}

// ---------------------------------------------------------- tessellation

/// Every triangle is non-degenerate and wound counter-clockwise seen from
/// the side its vertex normals point to.
fn assert_well_formed(mesh: &Mesh) {
    assert!(mesh.validate().is_ok(), "{}", mesh.source);
    assert_unit_normals(mesh);
    for tri in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| tri[k] as usize);
        let face =
            (mesh.positions[b] - mesh.positions[a]).cross(mesh.positions[c] - mesh.positions[a]);
        assert!(
            face.length() > 0.0,
            "degenerate triangle in {}",
            mesh.source
        );
        for v in [a, b, c] {
            assert!(
                face.dot(mesh.normals[v]) > 0.0,
                "{}: triangle {tri:?} is wound against its normals",
                mesh.source
            );
        }
    }
}

#[test]
fn tessellated_sphere_lies_on_the_sphere() {
    let radius = 2.5;
    let mesh = tessellate(&Shape::Sphere { radius });
    assert_well_formed(&mesh);
    let expected_tris = 2 * SPHERE_SEGMENTS * (SPHERE_RINGS - 1);
    assert_eq!(mesh.triangle_count(), expected_tris as usize);
    const { assert!(SPHERE_SEGMENTS >= 128 && SPHERE_RINGS >= 64) };
    for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
        assert!((p.length() - radius).abs() < 1e-5, "{p} off the sphere");
        assert!((*p / radius - *n).length() < 1e-5, "normal {n} at {p}");
    }
}

/// Every level of a sphere: n x n/2 with its vertices on the sphere, and
/// every point of every triangle (sampled on a barycentric grid of 8 steps
/// a side) between the sphere of radius r - inset and the true one, with
/// the inset reached (a sample within 1% of it: the deepest point of the
/// deepest triangle is its circumcentre, which the grid passes near). The
/// inset is about r (1 - cos(sqrt(2) pi / n)), the circumradius of an
/// equatorial triangle, half the diagonal of a square 2 pi / n a side
/// (within 5%: the square is not quite flat nor square).
#[test]
fn sphere_levels_lie_within_their_inset_of_the_sphere() {
    let radius = 2.5f32;
    assert_eq!(SPHERE_LEVELS[0], SPHERE_SEGMENTS);
    for n in SPHERE_LEVELS {
        let mesh = tessellate_sphere(radius, n);
        assert_well_formed(&mesh);
        assert_eq!(mesh.triangle_count(), (2 * n * (n / 2 - 1)) as usize, "{n}");
        for p in &mesh.positions {
            assert!(
                (p.length() - radius).abs() < 1e-5,
                "{n}: {p} off the sphere"
            );
        }
        let inset = sphere_inset(&mesh, radius);
        let expected =
            radius * (1.0 - (std::f32::consts::SQRT_2 * std::f32::consts::PI / n as f32).cos());
        assert!(
            (inset / expected - 1.0).abs() < 0.05,
            "{n} segments: inset {inset}, about {expected} expected"
        );
        let mut deepest = radius;
        for t in mesh.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
            for i in 0..=8 {
                for j in 0..=8 - i {
                    let (u, v) = (i as f32 / 8.0, j as f32 / 8.0);
                    let d = (a + (b - a) * u + (c - a) * v).length();
                    assert!(d >= radius - inset - 1e-5 && d <= radius + 1e-5, "{n}: {d}");
                    deepest = deepest.min(d);
                }
            }
        }
        assert!(
            radius - deepest > 0.99 * inset,
            "{n}: deepest {deepest}, inset {inset}"
        );
    }
}

#[test]
fn tessellated_shapes_are_well_formed() {
    let shapes = [
        Shape::Box {
            half_extents: Vec3::new(1.0, 2.0, 3.0),
        },
        Shape::Cylinder {
            radius: 0.5,
            height: 2.0,
        },
        Shape::Cone {
            radius: 0.5,
            height: 1.0,
        },
        Shape::Plane(PlaneKind::Quad {
            half_size: Vec2::new(3.0, 2.0),
        }),
        Shape::Plane(PlaneKind::Disk { radius: 2.0 }),
    ];
    for shape in &shapes {
        let mesh = tessellate(shape);
        assert_well_formed(&mesh);
        let (lo, hi) = mesh.bounds();
        let (want_lo, want_hi) = shape.bounds();
        assert!(lo.abs_diff_eq(want_lo, 1e-5) && hi.abs_diff_eq(want_hi, 1e-5));
    }
    let cube = tessellate(&shapes[0]);
    assert_eq!((cube.positions.len(), cube.triangle_count()), (24, 12));
    let quad = tessellate(&shapes[3]);
    assert_eq!((quad.positions.len(), quad.triangle_count()), (4, 2));
    assert!(quad.normals.iter().all(|&n| n == Vec3::Y));
    assert_eq!(
        tessellate(&shapes[4]).triangle_count(),
        ROUND_SEGMENTS as usize
    );

    // Cylinder: side + two capped fans of ROUND_SEGMENTS segments each; cap vertices
    // have flat normals.
    let can = tessellate(&shapes[1]);
    assert_eq!(can.triangle_count(), 4 * ROUND_SEGMENTS as usize);
    for (p, n) in can.positions.iter().zip(&can.normals) {
        if n.y == 0.0 {
            assert!((Vec2::new(p.x, p.z).length() - 0.5).abs() < 1e-5);
        } else {
            assert!(p.y.abs() == 1.0 && n.y == p.y.signum());
        }
    }
    // Cone: base at y = 0, apex at y = height, base normal -y.
    let cone = tessellate(&shapes[2]);
    assert_eq!(cone.triangle_count(), 2 * ROUND_SEGMENTS as usize);
    assert!(cone
        .positions
        .iter()
        .zip(&cone.normals)
        .all(|(p, n)| *n != Vec3::NEG_Y || p.y == 0.0));
}

#[test]
fn tessellating_a_mesh_returns_it() {
    let mesh = Mesh::load(&assets().join("models/Box/Box.gltf")).unwrap();
    assert_eq!(tessellate(&Shape::Mesh(mesh.clone())), mesh);
}

// ------------------------------------------------------------- transforms

#[test]
fn trs_is_translate_rotate_z_y_x_scale() {
    let scene = parse(&scene_text(&[(
        r#"material: "red")"#,
        r#"material: "red", transform: (translate: (0.0, 0.0, 5.0), rotate_deg: (0.0, 90.0, 0.0), scale: (2.0, 1.0, 1.0)))"#,
    )]))
    .unwrap();
    let m = scene.instances[0].world_from_object;
    // Scale x by 2, rotate +x onto -z, then translate.
    assert!(m
        .transform_point3(Vec3::X)
        .abs_diff_eq(Vec3::new(0.0, 0.0, 3.0), 1e-5));

    let rotations = scene_text(&[(
        r#"material: "red")"#,
        r#"material: "red", transform: (rotate_deg: (90.0, 90.0, 0.0)))"#,
    )]);
    let m = parse(&rotations).unwrap().instances[0].world_from_object;
    // Rx first: +y -> +z; then Ry: +z -> +x.
    assert!(m.transform_vector3(Vec3::Y).abs_diff_eq(Vec3::X, 1e-5));
}

#[test]
fn matrix_transform_is_row_major() {
    let text = scene_text(&[(
        r#"material: "red")"#,
        r#"material: "red", transform: Matrix(((1, 0, 0, 4), (0, 2, 0, 5), (0, 0, 1, 6), (0, 0, 0, 1))))"#,
    )]);
    let m = parse(&text).unwrap().instances[0].world_from_object;
    assert_eq!(m.w_axis, Vec4::new(4.0, 5.0, 6.0, 1.0));
    assert_eq!(m.y_axis, Vec4::new(0.0, 2.0, 0.0, 0.0));
}

#[test]
fn bounds_cover_all_instances() {
    let text = scene_text(&[(
        r#"instances: [(shape: "ball", material: "red")]"#,
        r#"instances: [
            (shape: "ball", material: "red", transform: (translate: (-3.0, 0.0, 0.0))),
            (shape: "crate", material: "red", transform: (translate: (2.0, 1.0, 0.0), scale: (2.0, 2.0, 2.0))),
        ]"#,
    )]);
    let (lo, hi) = parse(&text).unwrap().bounds();
    assert!(lo.abs_diff_eq(Vec3::new(-4.0, -1.0, -1.0), 1e-5), "{lo}");
    assert!(hi.abs_diff_eq(Vec3::new(3.0, 2.0, 1.0), 1e-5), "{hi}");
}

#[test]
fn materials_keep_file_order_and_defaults() {
    let text = scene_text(&[(
        r#"materials: { "red": (base_color: (0.8, 0.1, 0.1), model: Toon(bands: 4)) }"#,
        r#"materials: {
            "zeta": (base_color: (0.1, 0.1, 0.1), model: BlinnPhong),
            "red": (base_color: (0.8, 0.1, 0.1), model: Toon(bands: 4)),
            "alpha": (base_color: (0.2, 0.2, 0.2), model: Toon(thresholds: [0.2, 0.5, 0.8],
                      rim: Some((color: (1.0, 1.0, 1.0), threshold: 0.6)))),
        }"#,
    )]);
    let scene = parse(&text).unwrap();
    assert_eq!(scene.material_names, ["zeta", "red", "alpha"]);
    assert_eq!(scene.instances[0].material, 1);
    let [zeta, red, alpha] = &scene.materials[..] else {
        panic!()
    };
    assert_eq!(zeta.outline_width_px, 0.0);
    assert_eq!(red.outline_width_px, 1.5);
    assert_eq!((red.shininess, red.specular_color), (32.0, Vec3::ONE));
    assert_eq!(red.model, ShadingModel::Toon(Toon::even(4)));
    let ShadingModel::Toon(toon) = &alpha.model else {
        panic!()
    };
    assert_eq!(toon.bands(), 4);
    assert_eq!(toon.rim.as_ref().map(|r| r.threshold), Some(0.6));
    assert_eq!(scene.camera.aperture_radius, 0.0);
    assert_eq!(scene.camera.focus_distance, None);
}

// ------------------------------------------------------------------ errors

#[test]
fn syntax_error_reports_file_line_and_column() {
    let dir = scratch("syntax_error");
    let path = dir.join("typo.ron");
    // The misspelt field `fov_y_degs` starts at line 7, column 9.
    let text = "(\n    version: 1,\n    camera: (\n        eye: (0.0, 1.0, 5.0),\n        \
                target: (0.0, 0.0, 0.0),\n        up: (0.0, 1.0, 0.0),\n        \
                fov_y_degs: 40.0,\n        width: 320,\n        height: 240,\n    ),\n)\n";
    assert_eq!(text.lines().nth(6).unwrap().find("fov_y_degs"), Some(8));
    std::fs::write(&path, text).unwrap();

    let message = Scene::load(&path).unwrap_err().to_string();
    let expected = format!("{}:7:9", path.display());
    assert_contains(&message, &[&expected, "fov_y_degs"]);
}

#[test]
fn wrong_type_reports_line_and_column() {
    let text = "(\n    version: 1,\n    camera: (eye: (0.0, 1.0, 5.0), target: (0.0, 0.0, 0.0),\n        up: (0.0, 1.0, 0.0), fov_y_deg: \"wide\", width: 320, height: 240),\n)\n";
    let message = error_of(text);
    assert_contains(&message, &["test.ron:4:41"]);

    let message = error_of("(version: 1, camera: (eye: (0.0, 1.0), target: (0.0, 0.0, 0.0)))");
    assert_contains(&message, &["test.ron:1:", "3"]);
}

#[test]
fn missing_scene_file_is_reported() {
    let missing = assets().join("scenes/does_not_exist.ron");
    let message = Scene::load(&missing).unwrap_err().to_string();
    assert_contains(&message, &["does_not_exist.ron", "cannot read scene file"]);
}

#[test]
fn unsupported_version_is_reported() {
    let message = error_of(&scene_text(&[("version: 1", "version: 2")]));
    assert_contains(&message, &["test.ron", "version 2", "version 1"]);
    // A newer file with new fields still reports the version.
    let message = error_of(&scene_text(&[("version: 1", "version: 3, sky: Fancy")]));
    assert_contains(&message, &["version 3"]);
}

#[test]
fn unknown_material_or_shape_names_the_instance_and_alternatives() {
    let text = scene_text(&[(
        r#"instances: [(shape: "ball", material: "red")]"#,
        r#"instances: [(shape: "ball", material: "red"), (shape: "ball", material: "blue")]"#,
    )]);
    let message = error_of(&text);
    assert_contains(&message, &["instance 1", "material", "\"blue\"", "\"red\""]);

    let text = scene_text(&[(r#"shape: "ball""#, r#"shape: "bal""#)]);
    let message = error_of(&text);
    assert_contains(
        &message,
        &["instance 0", "shape", "\"bal\"", "\"ball\", \"crate\""],
    );
}

#[test]
fn missing_mesh_names_path_and_scene() {
    let text = scene_text(&[(
        r#""crate": Box"#,
        r#""cow": Mesh(path: "../models/nope/missing.obj"), "crate": Box"#,
    )]);
    let message = error_of(&text);
    assert_contains(
        &message,
        &[
            "models/nope/missing.obj",
            "test.ron",
            "not found",
            "\"cow\"",
        ],
    );
}

#[test]
fn unparsable_mesh_names_path_and_reason() {
    let dir = scratch("bad_mesh");
    std::fs::write(dir.join("broken.obj"), "v 0 0 0\nv 1 0 0\nf 1 2 7\n").unwrap();
    std::fs::write(dir.join("empty.obj"), "# nothing here\n").unwrap();
    std::fs::write(dir.join("broken.gltf"), "{ not json").unwrap();
    std::fs::write(dir.join("model.stl"), "solid").unwrap();
    for (file, reason) in [
        ("broken.obj", "invalid OBJ"),
        ("empty.obj", "no triangles"),
        ("broken.gltf", "invalid glTF"),
        ("model.stl", "unsupported mesh format"),
    ] {
        let text = scene_text(&[(
            r#""crate": Box"#,
            &format!(r#""m": Mesh(path: "{file}"), "crate": Box"#),
        )]);
        let message = Scene::from_ron_str(&text, "test.ron", &dir)
            .unwrap_err()
            .to_string();
        assert_contains(&message, &[file, reason, "cannot load mesh"]);
    }
}

#[test]
fn gltf_with_missing_buffer_names_the_file() {
    let dir = scratch("gltf_missing_bin");
    std::fs::copy(
        assets().join("models/FlightHelmet/FlightHelmet.gltf"),
        dir.join("helmet.gltf"),
    )
    .unwrap();
    let message = Mesh::load(&dir.join("helmet.gltf"))
        .unwrap_err()
        .to_string();
    assert_contains(&message, &["helmet.gltf", "FlightHelmet.bin"]);
}

#[test]
fn bad_transforms_name_the_instance() {
    let two = |transform: &str| {
        scene_text(&[(
            r#"instances: [(shape: "ball", material: "red")]"#,
            &format!(
                r#"instances: [(shape: "ball", material: "red"), (shape: "crate", material: "red", transform: {transform})]"#
            ),
        )])
    };
    let message = error_of(&two("(scale: (1.0, 0.0, 1.0))"));
    assert_contains(&message, &["instance 1", "\"crate\"", "singular"]);
    let message = error_of(&two("(translate: (inf, 0.0, 0.0))"));
    assert_contains(&message, &["instance 1", "non-finite"]);
    let message = error_of(&two(
        "Matrix(((1, 0, 0, 0), (0, NaN, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)))",
    ));
    assert_contains(&message, &["instance 1", "non-finite"]);
    let message = error_of(&two(
        "Matrix(((1, 0, 0, 0), (0, 1, 0, 0), (1, 1, 0, 0), (0, 0, 0, 1)))",
    ));
    assert_contains(&message, &["instance 1", "singular"]);
    let message = error_of(&two(
        "Matrix(((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 1, 1)))",
    ));
    assert_contains(&message, &["instance 1", "affine"]);
    let message = error_of(&two("(translate: (1.0, 2.0, 3.0), scael: (1.0, 1.0, 1.0))"));
    assert_contains(&message, &["test.ron:", "scael"]);
}

#[test]
fn bad_toon_settings_are_rejected() {
    let with_model =
        |model: &str| scene_text(&[("model: Toon(bands: 4)", &format!("model: {model}"))]);
    for (model, expected) in [
        ("Toon(bands: 0)", "bands must be in 1..=16, got 0"),
        ("Toon(bands: 17)", "bands must be in 1..=16, got 17"),
        ("Toon(thresholds: [0.5, 0.3])", "strictly increasing"),
        ("Toon(thresholds: [0.5, 0.5])", "strictly increasing"),
        ("Toon(thresholds: [0.0, 0.5])", "strictly between 0 and 1"),
        ("Toon(thresholds: [0.5, 1.0])", "strictly between 0 and 1"),
        ("Toon(bands: 3, thresholds: [0.5])", "not both"),
        ("Toon()", "give `bands: N`"),
        (
            "Toon(bands: 2, specular_threshold: 1.5)",
            "specular_threshold",
        ),
        ("Phong", "Phong"),
    ] {
        let message = error_of(&with_model(model));
        assert_contains(&message, &["test.ron", expected]);
        if model != "Phong" {
            assert_contains(&message, &["material \"red\""]);
        }
    }
    let too_many = format!(
        "Toon(thresholds: [{}])",
        (1..=MAX_TOON_BANDS)
            .map(|i| format!("{}", i as f32 / 17.0))
            .collect::<Vec<_>>()
            .join(", ")
    );
    assert_contains(&error_of(&with_model(&too_many)), &["got 17"]);
}

#[test]
fn bad_image_size_is_rejected() {
    for (from, to, expected) in [
        (
            "width: 320",
            "width: 0",
            "image width must be in 1..=16384 pixels, got 0",
        ),
        (
            "height: 240",
            "height: 0",
            "image height must be in 1..=16384 pixels, got 0",
        ),
        ("width: 320", "width: 16385", "got 16385"),
        ("height: 240", "height: 20000", "got 20000"),
    ] {
        let message = error_of(&scene_text(&[(from, to)]));
        assert_contains(&message, &["test.ron", "camera", expected]);
    }
    assert!(parse(&scene_text(&[("width: 320", "width: 16384")])).is_ok());
}

#[test]
fn out_of_range_values_are_rejected() {
    for (from, to, expected) in [
        (
            "Sphere(radius: 1.0)",
            "Sphere(radius: 0.0)",
            "shape \"ball\": sphere radius must be positive, got 0",
        ),
        ("Sphere(radius: 1.0)", "Sphere(radius: -2.0)", "got -2"),
        (
            "half_extents: (0.5, 0.5, 0.5)",
            "half_extents: (0.5, -0.5, 0.5)",
            "half_extents.y",
        ),
        (
            "Sphere(radius: 1.0)",
            "Cylinder(radius: 1.0, height: 0.0)",
            "cylinder height",
        ),
        (
            "Sphere(radius: 1.0)",
            "Cone(radius: 0.0, height: 1.0)",
            "cone radius",
        ),
        (
            "Sphere(radius: 1.0)",
            "Plane(Quad(half_size: (1.0, 0.0)))",
            "half_size.y",
        ),
        (
            "Sphere(radius: 1.0)",
            "Plane(Disk(radius: -1.0))",
            "disk radius",
        ),
        (
            "fov_y_deg: 40.0",
            "fov_y_deg: 0.0",
            "fov_y_deg must be in (0, 180)",
        ),
        (
            "fov_y_deg: 40.0",
            "fov_y_deg: 180.0",
            "fov_y_deg must be in (0, 180)",
        ),
        (
            "target: (0.0, 0.0, 0.0)",
            "target: (0.0, 1.0, 5.0)",
            "eye and target must differ",
        ),
        ("up: (0.0, 1.0, 0.0)", "up: (0.0, 0.0, 0.0)", "up must be"),
        ("up: (0.0, 1.0, 0.0)", "up: (0.0, -1.0, -5.0)", "parallel"),
        (
            "height: 240",
            "height: 240, aperture_radius: -0.1",
            "aperture_radius",
        ),
        (
            "height: 240",
            "height: 240, focus_distance: 0.0",
            "focus_distance must be positive",
        ),
        (
            "height: 240",
            "height: 240, aperture: Polygon(blades: 2)",
            "at least 3 blades",
        ),
        (
            "height: 240",
            "height: 240, shutter_open_s: 0.5, shutter_close_s: 0.1",
            "shutter_close_s",
        ),
        (
            "intensity: 1.0",
            "intensity: -1.0",
            "light 0: intensity must be >= 0, got -1",
        ),
        (
            "color: (1.0, 1.0, 1.0)",
            "color: (1.0, -1.0, 1.0)",
            "light 0: color",
        ),
        (
            "direction: (0.0, -1.0, 0.0)",
            "direction: (0.0, 0.0, 0.0)",
            "light 0: direction",
        ),
        (
            "version: 1,",
            "version: 1, ambient: (-0.1, 0.0, 0.0),",
            "ambient",
        ),
        (
            "version: 1,",
            "version: 1, background: (NaN, 0.0, 0.0),",
            "background",
        ),
        (
            "model: Toon(bands: 4)",
            "model: Toon(bands: 4), shininess: 0.0",
            "shininess must be positive",
        ),
        (
            "model: Toon(bands: 4)",
            "model: Toon(bands: 4), reflectivity: 2.0",
            "reflectivity must be in [0, 1]",
        ),
        (
            "model: Toon(bands: 4)",
            "model: Toon(bands: 4), roughness: -1.0",
            "roughness",
        ),
        (
            "model: Toon(bands: 4)",
            "model: Toon(bands: 4), outline_width_px: -1.0",
            "outline_width_px",
        ),
        (
            "base_color: (0.8, 0.1, 0.1)",
            "base_color: (0.8, -0.1, 0.1)",
            "base_color",
        ),
    ] {
        let message = error_of(&scene_text(&[(from, to)]));
        assert_contains(&message, &["test.ron", expected]);
    }
}

#[test]
fn duplicate_and_unknown_fields_are_rejected() {
    let text = scene_text(&[(r#""crate": Box"#, r#""ball": Box"#)]);
    assert_contains(
        &error_of(&text),
        &["test.ron:", "\"ball\" is defined twice"],
    );
    let text = scene_text(&[(
        "model: Toon(bands: 4)",
        "model: Toon(bands: 4), colour: (1, 1, 1)",
    )]);
    assert_contains(&error_of(&text), &["test.ron:5:", "colour"]);
}

// --------------------------------------------------------------- overrides

#[test]
fn overrides_change_the_scene() {
    let mut scene = parse(&scene_text(&[])).unwrap();
    scene.apply_override("camera.eye", "(1, 2, 3)").unwrap();
    assert_eq!(scene.camera.eye, Vec3::new(1.0, 2.0, 3.0));
    scene.apply_override("camera.width", "1920").unwrap();
    scene.apply_override("camera.height", "1080").unwrap();
    assert_eq!((scene.camera.width, scene.camera.height), (1920, 1080));
    scene.apply_override("camera.fov_y_deg", "55").unwrap();
    assert_eq!(scene.camera.fov_y_deg, 55.0);
    scene
        .apply_override("camera.focus_distance", "2.5")
        .unwrap();
    assert_eq!(scene.camera.focus_distance, Some(2.5));
    scene
        .apply_override("camera.focus_distance", "None")
        .unwrap();
    assert_eq!(scene.camera.focus_distance, None);
    scene
        .apply_override("camera.aperture_radius", "0.05")
        .unwrap();
    scene
        .apply_override("camera.shutter_close_s", "0.02")
        .unwrap();
    scene.apply_override("ambient", "(0.2, 0.2, 0.2)").unwrap();
    assert_eq!(scene.ambient, Vec3::splat(0.2));
    scene.apply_override("background", "(0, 0, 0)").unwrap();
    scene
        .apply_override("materials.red.base_color", "(0.1, 0.2, 0.3)")
        .unwrap();
    assert_eq!(scene.materials[0].base_color, Vec3::new(0.1, 0.2, 0.3));
    scene
        .apply_override("materials.red.outline_width_px", "3")
        .unwrap();
    assert_eq!(scene.materials[0].outline_width_px, 3.0);
    scene
        .apply_override("materials.red.model", "toon:3")
        .unwrap();
    assert_eq!(scene.materials[0].model, ShadingModel::Toon(Toon::even(3)));
    scene.apply_override("lights.0.intensity", "2.5").unwrap();
    scene
        .apply_override("lights.0.color", "(1, 0.5, 0)")
        .unwrap();
    let Light::Directional {
        intensity, color, ..
    } = &scene.lights[0]
    else {
        panic!()
    };
    assert_eq!((*intensity, *color), (2.5, Vec3::new(1.0, 0.5, 0.0)));
}

#[test]
fn bad_overrides_are_explained_and_change_nothing() {
    let mut scene = parse(&scene_text(&[])).unwrap();
    let before = scene.clone();

    let message = scene
        .apply_override("camera.zoom", "2")
        .unwrap_err()
        .to_string();
    assert_contains(
        &message,
        &[
            "camera.zoom",
            "camera.fov_y_deg",
            "materials.NAME.",
            "red",
            "lights.I.",
        ],
    );
    for key in [
        "materials.blue.base_color",
        "materials.red.colour",
        "lights.1.intensity",
        "lights.x.color",
    ] {
        let message = scene.apply_override(key, "1").unwrap_err().to_string();
        assert_contains(&message, &["unknown scene setting", key]);
    }

    let message = scene
        .apply_override("camera.eye", "up")
        .unwrap_err()
        .to_string();
    assert_contains(&message, &["camera.eye", "tuple of 3 numbers"]);
    let message = scene
        .apply_override("camera.width", "-5")
        .unwrap_err()
        .to_string();
    assert_contains(&message, &["camera.width", "whole number of pixels"]);
    let message = scene
        .apply_override("materials.red.shininess", "shiny")
        .unwrap_err()
        .to_string();
    assert_contains(&message, &["materials.red.shininess", "a number"]);

    // Parses, but out of range: validation error, scene unchanged.
    let message = scene
        .apply_override("camera.fov_y_deg", "200")
        .unwrap_err()
        .to_string();
    assert_contains(
        &message,
        &["camera.fov_y_deg=200", "fov_y_deg must be in (0, 180)"],
    );
    let message = scene
        .apply_override("lights.0.intensity", "-1")
        .unwrap_err()
        .to_string();
    assert_contains(&message, &["light 0", "intensity"]);
    assert_eq!(scene, before);
}

#[test]
fn shading_models_parse() {
    assert_eq!(
        parse_shading_model("blinn-phong").unwrap(),
        ShadingModel::BlinnPhong
    );
    assert_eq!(
        parse_shading_model("toon").unwrap(),
        ShadingModel::Toon(Toon::even(4))
    );
    assert_eq!(
        parse_shading_model("toon:7").unwrap(),
        ShadingModel::Toon(Toon::even(7))
    );
    for bad in ["phong", "toon:0", "toon:17", "toon:x", "toon:", ""] {
        let message = parse_shading_model(bad).unwrap_err().to_string();
        assert_contains(&message, &["blinn-phong", "toon:N", "toon"]);
    }
}

#[test]
fn even_toon_bands() {
    let toon = Toon::even(4);
    assert_eq!(toon.thresholds, [0.25, 0.5, 0.75]);
    assert_eq!(
        (toon.bands(), toon.specular_threshold, &toon.rim),
        (4, 0.5, &None)
    );
    assert_eq!(Toon::even(1).bands(), 1);
    assert_eq!(Toon::even(MAX_TOON_BANDS).bands(), MAX_TOON_BANDS);
}

#[test]
fn override_shading_sets_every_material() {
    let mut scene = Scene::builtin_default();
    scene.override_shading(&ShadingModel::BlinnPhong);
    assert!(scene
        .materials
        .iter()
        .all(|m| m.model == ShadingModel::BlinnPhong));
    let toon = parse_shading_model("toon:2").unwrap();
    scene.override_shading(&toon);
    assert!(scene.materials.iter().all(|m| m.model == toon));
    scene.validate().unwrap();
}
