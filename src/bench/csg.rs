//! `celray bench csg`: frame times of CSG shapes as leaf count and tree
//! depth grow, for the textbook solid and the 100-instance grid. Hybrid mode
//! (the default): CSG is always traced, so the trace pass is the cost.

use std::path::Path;

use celray::render::RenderMode;
use celray::scene::{Scene, Shape};

use super::report::{md, Report};
use super::{pass_ms, time_frames, BenchArgs};
use celray::gpu::Gpu;

/// A scene with one CSG shape `shape` (RON text) filling the middle of the
/// frame, lit by one light, toon-shaded, on no floor.
fn single(shape: &str, args: &BenchArgs) -> anyhow::Result<Scene> {
    let ron = format!(
        r#"(version: 1,
            camera: (eye: (2.2, 1.6, 3.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: {w}, height: {h}),
            lights: [Directional(direction: (-0.4, -1.0, -0.3))],
            materials: {{ "toon": (base_color: (0.85, 0.25, 0.15), model: Toon(bands: 4)) }},
            shapes: {{ "csg": {shape} }},
            instances: [(shape: "csg", material: "toon")],
        )"#,
        w = args.width,
        h = args.height
    );
    Ok(Scene::from_ron_str(&ron, "bench-csg", Path::new("."))?)
}

/// The intersection of `n` unit-ish boxes turned about different axes: a
/// convex polyhedron, so one interval per ray whatever `n` (leaf count
/// without interval growth).
fn box_intersection(n: u32) -> String {
    let boxes: Vec<String> = (0..n)
        .map(|i| {
            let a = i as f32 * 137.5;
            format!(
                "Box(half_extents: (0.9, 0.9, 0.9), transform: (rotate_deg: ({:.1}, {:.1}, {:.1})))",
                a % 90.0,
                (a * 0.61) % 90.0,
                (a * 0.37) % 90.0
            )
        })
        .collect();
    format!("Intersection([{}])", boxes.join(", "))
}

/// A tree `depth` levels deep: a sphere, then alternately cut by a turned
/// box (Intersection) and carved by a small sphere (Difference).
fn chain(depth: u32) -> String {
    let mut node = "Sphere(radius: 1.0)".to_string();
    for k in 1..depth {
        let a = k as f32 * 0.9;
        node = if k % 2 == 1 {
            format!(
                "Intersection([{node}, Box(half_extents: (0.85, 0.85, 0.85), transform: (rotate_deg: ({:.1}, {:.1}, 0.0)))])",
                k as f32 * 23.0,
                k as f32 * 41.0
            )
        } else {
            format!(
                "Difference({node}, Sphere(radius: 0.3, transform: (translate: ({:.3}, {:.3}, {:.3}))))",
                0.8 * a.cos(),
                0.8 * (a * 1.3).sin(),
                0.8 * a.sin()
            )
        };
    }
    node
}

fn leaves(scene: &Scene) -> (usize, u32) {
    scene
        .shapes
        .iter()
        .filter_map(|s| match s {
            Shape::Csg(c) => Some((c.root.leaves().len(), c.root.depth())),
            _ => None,
        })
        .fold((0, 0), |(l, d), (l2, d2)| (l.max(l2), d.max(d2)))
}

pub fn csg_suite(gpu: &Gpu, args: &BenchArgs, r: &Report) -> anyhow::Result<()> {
    md!(
        r,
        "\n## CSG frames ({}x{}, hybrid mode, ms per frame)\n",
        args.width,
        args.height
    );
    md!(
        r,
        "| case | CSG instances | leaves | depth | frame ms (mean) | median | GPU trace |"
    );
    md!(r, "|---|---|---|---|---|---|---|");
    let row = |name: &str, case: Option<&str>, mut scene: Scene| -> anyhow::Result<()> {
        scene.camera.width = args.width;
        scene.camera.height = args.height;
        let csg_instances = scene
            .instances
            .iter()
            .filter(|i| matches!(scene.shapes[i.shape], Shape::Csg(_)))
            .count();
        let (l, d) = leaves(&scene);
        let s = time_frames(gpu, scene, RenderMode::Hybrid, args)?;
        if let Some(case) = case {
            r.case(case, s.mean, None, &s.kernels());
        }
        md!(
            r,
            "| {name} | {csg_instances} | {l} | {d} | {:.1} | {:.1} | {:.1} |",
            s.mean,
            s.median,
            pass_ms(&s, "trace")
        );
        Ok(())
    };
    row(
        "reference: a plain box (not CSG)",
        None,
        single("Box(half_extents: (0.8, 0.8, 0.8))", args)?,
    )?;
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    row(
        "textbook solid (csg_textbook.ron: floor, mirror, shadows)",
        Some("csg_textbook"),
        Scene::load(&scenes.join("csg_textbook.ron"))?,
    )?;
    row(
        "textbook solid alone",
        None,
        single(
            "Difference(Intersection([Box(half_extents: (0.8, 0.8, 0.8)), Sphere(radius: 1.05)]), \
             Union([Cylinder(radius: 0.45, height: 2.0), \
             Cylinder(radius: 0.45, height: 2.0, transform: (rotate_deg: (90.0, 0.0, 0.0))), \
             Cylinder(radius: 0.45, height: 2.0, transform: (rotate_deg: (0.0, 0.0, 90.0)))]))",
            args,
        )?,
    )?;
    row(
        "100-instance grid (csg_grid.ron)",
        Some("csg_grid"),
        Scene::load(&scenes.join("csg_grid.ron"))?,
    )?;
    row(
        "six-level tree (csg_deep.ron)",
        None,
        Scene::load(&scenes.join("csg_deep.ron"))?,
    )?;
    for n in [1, 2, 4, 8, 16, 32] {
        row(
            &format!("intersection of {n} boxes"),
            None,
            single(&box_intersection(n), args)?,
        )?;
    }
    for depth in [2, 4, 8, 12] {
        row(
            &format!("chain {depth} levels deep"),
            None,
            single(&chain(depth), args)?,
        )?;
    }
    Ok(())
}
