//! CSG on the CPU: the interval algebra against point membership (property
//! tests), mesh leaves against their analytic twins, and the errors bad CSG
//! input gives.

use celray::accel::csg::{bound_may_hit, CompiledCsg, Endpoint};
use celray::scene::{tessellate, Csg, CsgLeaf, CsgNode, Scene, Shape};
use glam::{EulerRot, Mat4, Quat, Vec3};
use proptest::prelude::*;

fn leaf(shape: Shape, csg_from_leaf: Mat4) -> CsgNode {
    CsgNode::Leaf(CsgLeaf {
        shape,
        csg_from_leaf,
        material: None,
    })
}

fn leaf_strategy() -> impl Strategy<Value = CsgNode> {
    let shape = prop_oneof![
        (0.3f32..1.0).prop_map(|radius| Shape::Sphere { radius }),
        (0.2f32..1.0, 0.2f32..1.0, 0.2f32..1.0).prop_map(|(x, y, z)| Shape::Box {
            half_extents: Vec3::new(x, y, z)
        }),
        (0.2f32..1.0, 0.4f32..2.0).prop_map(|(radius, height)| Shape::Cylinder { radius, height }),
        (0.2f32..1.0, 0.4f32..2.0).prop_map(|(radius, height)| Shape::Cone { radius, height }),
    ];
    let transform = (
        prop::array::uniform3(-0.8f32..0.8),
        prop::array::uniform3(0.0f32..6.3),
        prop::array::uniform3(0.5f32..1.5),
    )
        .prop_map(|(t, r, s)| {
            Mat4::from_scale_rotation_translation(
                Vec3::from(s),
                Quat::from_euler(EulerRot::XYZ, r[0], r[1], r[2]),
                Vec3::from(t),
            )
        });
    (shape, transform).prop_map(|(s, m)| leaf(s, m))
}

fn tree_strategy() -> impl Strategy<Value = CsgNode> {
    leaf_strategy().prop_recursive(5, 16, 3, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 1..4).prop_map(CsgNode::Union),
            prop::collection::vec(inner.clone(), 1..4).prop_map(CsgNode::Intersection),
            (inner.clone(), inner).prop_map(|(a, b)| CsgNode::Difference(Box::new(a), Box::new(b))),
        ]
    })
}

/// Four rays, each from a point in [-4, 4]^3 towards one in [-1, 1]^3.
fn rays_strategy() -> impl Strategy<Value = Vec<([f32; 3], [f32; 3])>> {
    prop::collection::vec(
        (
            prop::array::uniform3(-4.0f32..4.0),
            prop::array::uniform3(-1.0f32..1.0),
        ),
        4,
    )
}

/// The rays' origins and unit directions (a ray whose two points coincide
/// is left out).
fn lines(rays: Vec<([f32; 3], [f32; 3])>) -> Vec<(Vec3, Vec3)> {
    rays.into_iter()
        .filter_map(|(origin, aim)| {
            let o = Vec3::from(origin);
            (Vec3::from(aim) - o).try_normalize().map(|d| (o, d))
        })
        .collect()
}

/// The tree and its program, where the tree loads (a tree over the
/// interval or stack bound is refused at load, never evaluated).
fn loadable(root: CsgNode) -> Option<(Csg, CompiledCsg)> {
    let csg = Csg {
        root: Box::new(root),
    };
    csg.check().ok()?;
    let program = CompiledCsg::new(&csg).unwrap();
    Some((csg, program))
}

fn inside(list: &[Endpoint], t: f32) -> bool {
    list.iter().filter(|e| e.t < t).count() % 2 == 1
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// For random trees and rays: every t the intervals call inside is
    /// inside by the tree's point test and vice versa, at samples farther
    /// than 2e-3 from any change of membership (the point test's own
    /// boundaries; the interval epsilon is 1e-5 relative, far smaller).
    /// And every boundary's normal points out of the result: against the
    /// ray at an entry, along it at an exit (where the ray is not grazing).
    #[test]
    fn intervals_agree_with_point_membership(
        root in tree_strategy(),
        rays in rays_strategy(),
    ) {
        let Some((csg, program)) = loadable(root) else { return Ok(()) };
        for (o, d) in lines(rays) {
            let list = program.intervals(o, d).unwrap();
            prop_assert!(list.len().is_multiple_of(2), "odd endpoint count {}", list.len());
            for w in list.windows(2) {
                prop_assert!(w[0].t <= w[1].t, "unsorted endpoints {list:?}");
            }
            for (k, e) in list.iter().enumerate() {
                let n = e.normal.normalize();
                let cos = n.dot(d);
                if cos.abs() > 1e-2 {
                    let entry = k % 2 == 0;
                    prop_assert!(entry == (cos < 0.0),
                        "endpoint {k} at t {} ({}) has normal {n} against d {d}", e.t,
                        if entry { "entry" } else { "exit" });
                }
            }
            let delta = 2e-3;
            let member = |t: f32| csg.root.contains(o + d * t);
            let mut checked = 0;
            for i in 0..1200 {
                let t = -8.0 + i as f32 * (16.0 / 1200.0);
                let m = member(t);
                if member(t - delta) != m || member(t + delta) != m {
                    continue;
                }
                if list.iter().any(|e| (e.t - t).abs() < delta) {
                    continue;
                }
                checked += 1;
                prop_assert_eq!(inside(&list, t), m, "t = {} (o {}, d {}), intervals {:?}", t, o, d,
                    list.iter().map(|e| e.t).collect::<Vec<_>>());
            }
            prop_assert!(checked > 1000);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// The renderer skips a CSG tree for rays that miss its bounding
    /// sphere, so the solid must lie inside it: for random trees (leaves
    /// rotated, scaled 0.5-1.5x per axis and moved), every interval
    /// endpoint of random rays is inside the sphere, and rays aimed to
    /// pass just outside it (by 1e-3 of the radius; the sphere's own
    /// margin is 1e-3 wider than the bound) are refused by the test and
    /// have no interval at all.
    #[test]
    fn bounding_sphere_holds_the_solid(
        root in tree_strategy(),
        rays in rays_strategy(),
        aside in prop::collection::vec(prop::array::uniform3(-1.0f32..1.0), 4),
    ) {
        let csg = Csg { root: Box::new(root) };
        if csg.check().is_err() {
            return Ok(());
        }
        let program = CompiledCsg::new(&csg).unwrap();
        let bound = csg.bounding_sphere();
        let (c, r) = (Vec3::new(bound[0], bound[1], bound[2]), bound[3]);
        for (origin, aim) in rays {
            let o = Vec3::from(origin);
            let Some(d) = (Vec3::from(aim) - o).try_normalize() else { continue };
            for e in program.intervals(o, d).unwrap() {
                let p = o + d * e.t;
                prop_assert!((p - c).length() <= r, "endpoint {p} outside the sphere {c}, {r}");
            }
        }
        // Rays tangent to a sphere 1e-3 wider than the bound, from 4 radii away.
        for dir in aside {
            let Some(d) = Vec3::from(dir).try_normalize() else { continue };
            let side = d.any_orthonormal_vector();
            let o = c + side * (r * 1.001) - d * (4.0 * r);
            prop_assert!(!bound_may_hit(bound, o, d, f32::NEG_INFINITY, f32::INFINITY));
            prop_assert!(program.intervals(o, d).unwrap().is_empty());
        }
    }
}

/// The bounding sphere from the math: the textbook solid (box of half
/// size 0.8 intersected with a sphere of radius 1.05, minus cylinders)
/// lies in the smaller of the two leaves' spheres, the ball of 1.05 (the
/// box's own reaches 0.8 * sqrt(3) = 1.386); a union of two unit balls
/// at x = +-2 lies in the ball of radius 3 about the origin; a unit ball
/// scaled by 2 along x and rotated lies in a ball of radius 2. Each 0.1%
/// wider, plus 1e-6 of (centre distance + radius).
#[test]
fn bounding_sphere_radius_follows_the_tree() {
    let ball = |r: f32| Shape::Sphere { radius: r };
    let textbook = Csg {
        root: Box::new(CsgNode::Difference(
            Box::new(CsgNode::Intersection(vec![
                leaf(
                    Shape::Box {
                        half_extents: Vec3::splat(0.8),
                    },
                    Mat4::IDENTITY,
                ),
                leaf(ball(1.05), Mat4::IDENTITY),
            ])),
            Box::new(leaf(
                Shape::Cylinder {
                    radius: 0.45,
                    height: 2.0,
                },
                Mat4::IDENTITY,
            )),
        )),
    };
    let pair = Csg {
        root: Box::new(CsgNode::Union(vec![
            leaf(ball(1.0), Mat4::from_translation(Vec3::X * 2.0)),
            leaf(ball(1.0), Mat4::from_translation(Vec3::X * -2.0)),
        ])),
    };
    let stretched = Csg {
        root: Box::new(leaf(
            ball(1.0),
            Mat4::from_rotation_y(0.7) * Mat4::from_scale(Vec3::new(2.0, 1.0, 1.0)),
        )),
    };
    for (csg, centre, radius) in [
        (textbook, Vec3::ZERO, 1.05f32),
        (pair, Vec3::ZERO, 3.0),
        (stretched, Vec3::ZERO, 2.0),
    ] {
        let b = csg.bounding_sphere();
        let want = radius * 1.001 + 1e-6 * radius;
        assert!(Vec3::new(b[0], b[1], b[2]).distance(centre) < 1e-5, "{b:?}");
        assert!((b[3] - want).abs() < 1e-5, "radius {} against {want}", b[3]);
    }
}

/// The interval bounds are worst cases: a tree exactly at the bound
/// realizes it on some ray (8 spheres in a row, one ray through all).
#[test]
fn union_of_eight_spheres_on_a_line_gives_eight_intervals() {
    let spheres = (0..8)
        .map(|i| {
            leaf(
                Shape::Sphere { radius: 0.4 },
                Mat4::from_translation(Vec3::new(i as f32 - 3.5, 0.0, 0.0)),
            )
        })
        .collect();
    let csg = Csg {
        root: Box::new(CsgNode::Union(spheres)),
    };
    assert_eq!(csg.root.interval_bound(), 8);
    csg.check().unwrap();
    let list = CompiledCsg::new(&csg)
        .unwrap()
        .intervals(Vec3::new(-10.0, 0.0, 0.0), Vec3::X)
        .unwrap();
    assert_eq!(list.len(), 16);
    // Sphere i spans x in [i - 3.5 - 0.4, i - 3.5 + 0.4]; t = x + 10.
    for (i, pair) in list.chunks(2).enumerate() {
        let c = i as f32 - 3.5 + 10.0;
        assert!((pair[0].t - (c - 0.4)).abs() < 1e-5 && (pair[1].t - (c + 0.4)).abs() < 1e-5);
    }
}

/// Coincident faces: a box minus a box sharing its +x face exactly gives
/// one interval and no sliver, and two boxes touching face to face give one
/// merged interval, on every ray through the shared face (the epsilon rule).
#[test]
fn coincident_faces_leave_no_slivers_or_gaps() {
    let a = |m: Mat4| {
        leaf(
            Shape::Box {
                half_extents: Vec3::splat(0.5),
            },
            m,
        )
    };
    // Box [-0.5, 0.5]^3 minus box [0.1, 0.5] x [-1, 1] x [-1, 1]: flush at x = 0.5.
    let cut = Csg {
        root: Box::new(CsgNode::Difference(
            Box::new(a(Mat4::IDENTITY)),
            Box::new(leaf(
                Shape::Box {
                    half_extents: Vec3::new(0.2, 1.0, 1.0),
                },
                Mat4::from_translation(Vec3::new(0.3, 0.0, 0.0)),
            )),
        )),
    };
    // Two unit boxes touching at x = 0.5, the second rotated (rounding differs).
    let touch = Csg {
        root: Box::new(CsgNode::Union(vec![
            a(Mat4::IDENTITY),
            a(Mat4::from_translation(Vec3::new(1.0, 0.0, 0.0))
                * Mat4::from_rotation_x(std::f32::consts::FRAC_PI_2)),
        ])),
    };
    let (cut, touch) = (
        CompiledCsg::new(&cut).unwrap(),
        CompiledCsg::new(&touch).unwrap(),
    );
    for i in 0..500 {
        let y = -0.45 + 0.9 * (i as f32 / 499.0);
        let z = 0.37 * (i as f32 * 0.7).sin();
        let d = Vec3::new(1.0, 0.013 * (i as f32).cos(), 0.0).normalize();
        let o = Vec3::new(-3.0, y, z);
        let l = cut.intervals(o, d).unwrap();
        assert_eq!(l.len(), 2, "ray {i}: cut gave {l:?}");
        let l = touch.intervals(o, d).unwrap();
        assert_eq!(l.len(), 2, "ray {i}: touching boxes gave {l:?}");
    }
}

/// A ray tangent to a sphere leaf gives no interval (not a random sliver).
#[test]
fn grazing_ray_gives_no_interval() {
    let csg = Csg {
        root: Box::new(leaf(Shape::Sphere { radius: 1.0 }, Mat4::IDENTITY)),
    };
    let p = CompiledCsg::new(&csg).unwrap();
    assert!(p
        .intervals(Vec3::new(-5.0, 1.0, 0.0), Vec3::X)
        .unwrap()
        .is_empty());
}

/// A closed triangle mesh as a leaf gives the intervals of the analytic
/// solid it tessellates (a box: exact), on random rays: t within 1e-4, and
/// the same through a difference.
#[test]
fn closed_mesh_leaf_matches_its_analytic_twin() {
    let h = Vec3::new(0.6, 0.4, 0.5);
    let mesh = tessellate(&Shape::Box { half_extents: h });
    let m = Mat4::from_rotation_y(0.4) * Mat4::from_translation(Vec3::new(0.1, 0.0, 0.0));
    let hole = leaf(Shape::Sphere { radius: 0.45 }, Mat4::IDENTITY);
    let make = |s: Shape| Csg {
        root: Box::new(CsgNode::Difference(
            Box::new(leaf(s, m)),
            Box::new(hole.clone()),
        )),
    };
    let with_mesh = CompiledCsg::new(&make(Shape::Mesh(mesh))).unwrap();
    let analytic = CompiledCsg::new(&make(Shape::Box { half_extents: h })).unwrap();
    let mut hits = 0;
    for i in 0..2000u32 {
        let u = |k: u32| celray::sampling::uniform(i, 5, k);
        let o = Vec3::new(u(0), u(1), u(2)) * 6.0 - Vec3::splat(3.0);
        let aim = Vec3::new(u(3), u(4), u(5)) - Vec3::splat(0.5);
        let d = (aim - o).normalize();
        let a = analytic.intervals(o, d).unwrap();
        let b = with_mesh.intervals(o, d).unwrap();
        assert_eq!(a.len(), b.len(), "ray {i}: analytic {a:?} mesh {b:?}");
        for (x, y) in a.iter().zip(&b) {
            assert!((x.t - y.t).abs() < 1e-4 * x.t.abs().max(1.0), "ray {i}");
        }
        hits += usize::from(!a.is_empty());
    }
    assert!(hits > 500, "only {hits} rays hit");
}

fn load(shape: &str) -> Result<Scene, String> {
    let ron = format!(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 32, height: 32),
            materials: {{ "m": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong) }},
            shapes: {{ "s": {shape} }},
            instances: [(shape: "s", material: "m")],
        )"#
    );
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    Scene::from_ron_str(&ron, "csg.ron", dir).map_err(|e| e.to_string())
}

fn load_err(shape: &str) -> String {
    match load(shape) {
        Ok(_) => panic!("{shape} should be refused"),
        Err(e) => e,
    }
}

#[test]
fn good_csg_loads_with_leaf_materials_and_transforms() {
    let scene = load(
        r#"Difference(Sphere(radius: 1.0), Box(half_extents: (0.5, 0.5, 2.0), transform: (translate: (0.2, 0.0, 0.0)), material: "m"))"#,
    )
    .unwrap();
    let Shape::Csg(csg) = &scene.shapes[0] else {
        panic!("not CSG")
    };
    let leaves = csg.root.leaves();
    assert_eq!(leaves.len(), 2);
    assert_eq!(leaves[0].material, None);
    assert_eq!(leaves[1].material, Some(0));
    assert_eq!(
        leaves[1].csg_from_leaf,
        Mat4::from_translation(Vec3::new(0.2, 0.0, 0.0))
    );
}

#[test]
fn bad_csg_input_gives_the_stated_errors() {
    let e = load_err("Union([])");
    assert!(e.contains("Union([]) is empty"), "{e}");
    let e = load_err("Intersection([])");
    assert!(e.contains("Intersection([]) is empty"), "{e}");
    // Difference with one child: a syntax error at its position.
    let e = load_err("Difference(Sphere(radius: 1.0))");
    assert!(e.starts_with("csg.ron:4:"), "{e}");
    assert!(e.contains("Difference with 2 elements"), "{e}");
    // Unknown leaf kind: the accepted kinds are listed.
    let e = load_err("Union([Torus(radius: 1.0)])");
    assert!(e.starts_with("csg.ron:4:") && e.contains("Torus"), "{e}");
    assert!(e.contains("Sphere") && e.contains("Cylinder"), "{e}");
    let e = load_err("Union([Plane(Quad(half_size: (1.0, 1.0))), Sphere(radius: 1.0)])");
    assert!(e.contains("plane has no inside"), "{e}");
    let e = load_err(r#"Union([Sphere(radius: 1.0, material: "nope")])"#);
    assert!(e.contains("\"nope\" is not defined"), "{e}");
    let e = load_err("Union([Sphere(radius: -1.0)])");
    assert!(e.contains("sphere radius must be positive"), "{e}");
    let e = load_err("Union([Sphere(radius: 1.0, transform: (scale: (0.0, 1.0, 1.0)))])");
    assert!(e.contains("singular"), "{e}");
    // Nine spheres in a union: 9 intervals may be needed, over the bound of 8.
    let nine = (0..9)
        .map(|i| format!("Sphere(radius: 0.4, transform: (translate: ({i}.0, 0.0, 0.0)))"))
        .collect::<Vec<_>>()
        .join(", ");
    let e = load_err(&format!("Union([{nine}])"));
    assert!(
        e.contains("up to 9 separate intervals") && e.contains("limit of 8"),
        "{e}"
    );
    // A balanced tree of 16 box leaves (2 by 2 intersections): one interval
    // per ray, but its evaluation needs 5 stack entries, over the 4 allowed.
    let mut level: Vec<String> = (0..16)
        .map(|i| {
            format!(
                "Box(half_extents: (1.0, 1.0, 1.0), transform: (rotate_deg: (0.0, {i}.0, 0.0)))"
            )
        })
        .collect();
    while level.len() > 1 {
        level = level
            .chunks(2)
            .map(|p| format!("Intersection([{}, {}])", p[0], p[1]))
            .collect();
    }
    let e = load_err(&level[0]);
    assert!(
        e.contains("CSG tree too deep")
            && e.contains("needs 5 stack entries")
            && e.contains("limit of 4"),
        "{e}"
    );
    // Eight is fine.
    let eight = (0..8)
        .map(|i| format!("Sphere(radius: 0.4, transform: (translate: ({i}.0, 0.0, 0.0)))"))
        .collect::<Vec<_>>()
        .join(", ");
    load(&format!("Union([{eight}])")).unwrap();
}

#[test]
fn mesh_leaves_must_be_closed() {
    let dir = std::env::temp_dir().join(format!("celray-csg-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // A tetrahedron missing its base: three triangles, an open mesh.
    let open = dir.join("open.obj");
    std::fs::write(
        &open,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\n",
    )
    .unwrap();
    let closed = dir.join("closed.obj");
    std::fs::write(
        &closed,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    let e = load_err(&format!(
        "Union([Mesh(path: {:?})])",
        open.display().to_string()
    ));
    assert!(e.contains("is not closed") && e.contains("open.obj"), "{e}");
    load(&format!(
        "Difference(Mesh(path: {:?}), Sphere(radius: 0.1))",
        closed.display().to_string()
    ))
    .unwrap();
    // The shipped cow is closed, and a valid leaf.
    load(r#"Difference(Mesh(path: "assets/models/spot/spot_triangulated.obj"), Sphere(radius: 0.3))"#)
        .unwrap();
    std::fs::remove_dir_all(&dir).ok();
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// The trace kernel's CSG store is sized to a scene's programs
    /// (`PrivateSizes::new`, which runs each program on interval
    /// bounds). For random trees that load: the stack is at most the
    /// loader's bound (`stack_need` takes the children in their written
    /// order; the compiled program takes the neediest first, so it may
    /// need fewer) and 2 wherever there is an operation (a binary step
    /// holds both operands), else 1; the intervals are the tree's
    /// worst-case count (its root's, since no operation's bound is below
    /// its operands'); and the intervals of random rays fit them.
    #[test]
    fn sized_csg_store_holds_every_tree_that_loads(
        root in tree_strategy(),
        rays in rays_strategy(),
    ) {
        let Some((csg, program)) = loadable(root) else { return Ok(()) };
        let sizes = celray::accel::PrivateSizes::new(1, &program.ops, &program.leaves);
        prop_assert!(sizes.csg_stack <= csg.root.stack_need());
        let operations = program.ops.iter().filter(|o| o.op > 1).count();
        let least = if operations > 0 { 2 } else { 1 };
        prop_assert!(sizes.csg_stack >= least, "{} < {}", sizes.csg_stack, least);
        prop_assert_eq!(sizes.csg_intervals, csg.root.interval_bound());
        for (o, d) in lines(rays) {
            let list = program.intervals(o, d).unwrap();
            prop_assert!(list.len() as u32 <= 2 * sizes.csg_intervals);
        }
    }
}
