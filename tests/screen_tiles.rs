//! Which instances each screen tile's primary rays can meet
//! (`accel::screen_tiles`), against the CPU tracer: no GPU needed.
use celray::accel::bvh::Aabb;
use celray::accel::screen_tiles::{primary_tiles, reached_tiles, tile_list};
use celray::accel::SceneAccel;
use celray::gpu::twins::{PRIMARY_TILE_MAX, PRIMARY_TILE_WORDS};
use celray::render::camera::{depth_range, sample_camera};
use celray::scene::Scene;
use glam::{Mat4, Vec2, Vec3, Vec4Swizzles};

/// Scattered solids of every analytic kind, a CSG solid, the spot mesh
/// and a floor whose far corners lie behind the eye; a wide lens.
fn scene() -> (Scene, SceneAccel) {
    let ron = r#"(version: 1,
        camera: (eye: (0.5, 2.0, 6.0), target: (0.0, 0.5, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 50.0, width: 203, height: 117),
        lights: [Directional(direction: (-0.5, -1.0, -0.6), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: { "m": (base_color: (0.8, 0.8, 0.8), model: BlinnPhong) },
        shapes: {
            "floor": Plane(Quad(half_size: (20.0, 20.0))),
            "ball": Sphere(radius: 0.5),
            "crate": Box(half_extents: (0.4, 0.3, 0.5)),
            "post": Cylinder(radius: 0.2, height: 2.0),
            "cone": Cone(radius: 0.4, height: 1.0),
            "holed": Difference(Box(half_extents: (0.6, 0.6, 0.6)), Sphere(radius: 0.75)),
            "cow": Mesh(path: "assets/models/spot/spot_triangulated.obj"),
        },
        instances: [
            (shape: "floor", material: "m"),
            (shape: "ball", material: "m", transform: (translate: (-1.5, 0.5, 0.0))),
            (shape: "ball", material: "m", transform: (translate: (1.0, 1.5, -1.0), scale: (2.0, 1.0, 1.0))),
            (shape: "crate", material: "m", transform: (translate: (0.3, 0.3, 1.5), rotate_deg: (0.0, 30.0, 0.0))),
            (shape: "post", material: "m", transform: (translate: (2.0, 0.0, 0.5))),
            (shape: "cone", material: "m", transform: (translate: (-2.5, 0.0, -2.0))),
            (shape: "holed", material: "m", transform: (translate: (-0.5, 0.6, -2.5))),
            (shape: "cow", material: "m", transform: (translate: (2.5, 0.74, -3.0))),
        ],
    )"#;
    let scene = Scene::from_ron_str(ron, "test.ron", std::path::Path::new(".")).unwrap();
    let order: Vec<usize> = (0..scene.instances.len()).collect();
    let accel = SceneAccel::build(&scene, &order).unwrap();
    (scene, accel)
}

/// The ray of pixel (x, y) as the trace kernel makes it: the pixel
/// centre's points on the near and far planes, through the inverse.
fn kernel_ray(clip_from_world: Mat4, size: (u32, u32), x: u32, y: u32) -> (Vec3, Vec3) {
    let (w, h) = (size.0 as f32, size.1 as f32);
    let ndc = Vec2::new(
        (x as f32 + 0.5) / w * 2.0 - 1.0,
        1.0 - (y as f32 + 0.5) / h * 2.0,
    );
    let world_from_clip = clip_from_world.as_dmat4().inverse().as_mat4();
    let near = world_from_clip * ndc.extend(0.0).extend(1.0);
    let far = world_from_clip * ndc.extend(1.0).extend(1.0);
    let o = near.xyz() / near.w;
    (o, (far.xyz() / far.w - o).normalize())
}

/// Every pixel's closest hit, found by the CPU tracer along the ray
/// the kernel makes, is an instance of its tile's list (or the tile
/// walks), for sub-pixel offsets at the pixel's corners and points on
/// the lens, with tiles of 8 pixels and of 1. And the lists are
/// short: nine tenths of the 8 x 8 tiles hold a list, of fewer than 4
/// of the 8 instances on average. With tiles of one pixel it fails
/// where the rectangles are half a pixel smaller than the corners'
/// projections (pixel (106, 42) loses the CSG solid's hit).
#[test]
fn a_primary_ray_meets_only_its_tiles_instances() {
    let (mut scene, accel) = scene();
    scene.camera.aperture_radius = 0.15;
    scene.camera.focus_distance = Some(5.0);
    let size = (scene.camera.width, scene.camera.height);
    let (mut hits, mut listed_tiles, mut entries) = (0, 0, 0);
    let shifts = [(0.0, 0.0), (0.999, 0.999), (0.0, 0.999), (0.5, 0.5)];
    // Tiles of one pixel hold the rectangles to the pixel.
    for (i, &(sx, sy), tile) in shifts
        .iter()
        .enumerate()
        .flat_map(|(i, s)| [(i, s, 1), (i, s, 8)])
    {
        let tiles_x = size.0.div_ceil(tile) as usize;
        let lens = Vec2::from_angle(i as f32 * 1.7) * (i % 2) as f32;
        let depth = depth_range(&scene.camera, scene.bounds());
        let cam = sample_camera(&scene.camera, size, Vec2::new(sx, sy), lens, depth);
        let tiles = primary_tiles(
            &accel.world_bounds,
            |_| true,
            cam.clip_from_world,
            size,
            tile,
        );
        for t in 0..tiles.len() / PRIMARY_TILE_WORDS as usize {
            if tile == 1 {
                break;
            }
            if let Some(list) = tile_list(&tiles, t) {
                listed_tiles += 1;
                entries += list.len();
            }
        }
        for y in 0..size.1 {
            for x in 0..size.0 {
                let t = (y / tile) as usize * tiles_x + (x / tile) as usize;
                let Some(list) = tile_list(&tiles, t) else {
                    continue;
                };
                let (o, d) = kernel_ray(cam.clip_from_world, size, x, y);
                let Some(h) = accel.closest_hit(o, d, 0.0, f32::INFINITY).hit else {
                    continue;
                };
                hits += 1;
                assert!(
                    list.contains(&h.instance),
                    "pixel ({x}, {y}), shift {i}: instance {} not in {list:?}",
                    h.instance
                );
            }
        }
    }
    let tiles = shifts.len() * (size.0.div_ceil(8) * size.1.div_ceil(8)) as usize;
    assert!(hits > 2 * shifts.len() * 203 * 117 / 2, "{hits} hits");
    assert!(
        listed_tiles * 10 > tiles * 9,
        "{listed_tiles} of {tiles} tiles listed"
    );
    let mean = entries as f64 / listed_tiles as f64;
    assert!(mean < 4.0, "{mean:.2} instances a listed tile");
}

/// A tile that may see more than PRIMARY_TILE_MAX instances walks,
/// and a box off the image lands on no tile.
#[test]
fn crowded_tiles_walk_and_boxes_off_the_image_are_left_out() {
    let (scene, accel) = scene();
    let size = (64, 64);
    let cam = sample_camera(
        &scene.camera,
        size,
        Vec2::splat(0.5),
        Vec2::ZERO,
        depth_range(&scene.camera, scene.bounds()),
    );
    let mut bounds = vec![accel.world_bounds[1]; PRIMARY_TILE_MAX as usize];
    let behind = Aabb {
        min: scene.camera.eye + Vec3::new(-0.1, -0.1, 1.0),
        max: scene.camera.eye + Vec3::new(0.1, 0.1, 1.2),
    };
    bounds.push(behind);
    let tiles = primary_tiles(&bounds, |_| true, cam.clip_from_world, size, 8);
    let full = (0..64)
        .filter(|&t| tile_list(&tiles, t).is_some_and(|l| l.len() == 7))
        .count();
    assert!(full > 0, "the ball's tiles list it 7 times");
    assert!((0..64).all(|t| tile_list(&tiles, t).is_none_or(|l| !l.contains(&7))));
    bounds.push(accel.world_bounds[1]);
    let tiles = primary_tiles(&bounds, |_| true, cam.clip_from_world, size, 8);
    assert_eq!(
        (0..64).filter(|&t| tile_list(&tiles, t).is_none()).count(),
        full,
        "the tiles of 8 balls walk"
    );
}

/// The outline marks skip a tile unread where `reached_tiles` says no
/// source (an instance whose outline reaches other pixels) can show
/// within the outline's reach of it. So every pixel whose closest hit
/// (CPU tracer, the kernel's ray) is a source must flag every tile that
/// holds a pixel within `reach` of it in x and in y: the tiles whose
/// halo holds it. Sources here: the two balls, the crate and the cow;
/// for sub-pixel shifts and lens points, 8 px tiles with reach 1 and 3,
/// 16 px tiles with reach 7; and 8 px tiles with reach 0, as the trace
/// pass asks which tiles a (rasterized) mesh may show in. And the flags are not everywhere: the
/// floor, the other solids and the sky are no source, so at least a
/// third of the tiles stay 0.
#[test]
fn a_source_pixel_flags_every_tile_within_its_reach() {
    let (mut scene, accel) = scene();
    scene.camera.aperture_radius = 0.15;
    scene.camera.focus_distance = Some(5.0);
    let size = (scene.camera.width, scene.camera.height);
    let sources = [1u32, 2, 3, 7];
    let cases = [
        (Vec2::new(0.0, 0.0), Vec2::ZERO, 8u32, 1u32),
        // Reach 0: the trace pass's test for a rasterized mesh in its tile.
        (Vec2::new(0.25, 0.75), Vec2::new(0.0, 1.0), 8, 0),
        (Vec2::new(0.999, 0.5), Vec2::new(0.6, -0.8), 8, 3),
        (Vec2::new(0.5, 0.999), Vec2::new(-1.0, 0.0), 16, 7),
    ];
    for (shift, lens, tile, reach) in cases {
        let depth = depth_range(&scene.camera, scene.bounds());
        let cam = sample_camera(&scene.camera, size, shift, lens, depth);
        let flags = reached_tiles(
            &accel.world_bounds,
            |k| sources.contains(&(k as u32)),
            cam.clip_from_world,
            size,
            tile,
            reach,
        );
        let tiles_x = size.0.div_ceil(tile);
        assert_eq!(flags.len() as u32, tiles_x * size.1.div_ceil(tile));
        let mut source_pixels = 0;
        for y in 0..size.1 {
            for x in 0..size.0 {
                let (o, d) = kernel_ray(cam.clip_from_world, size, x, y);
                let Some(h) = accel.closest_hit(o, d, 0.0, f32::INFINITY).hit else {
                    continue;
                };
                if !sources.contains(&h.instance) {
                    continue;
                }
                source_pixels += 1;
                let span =
                    |v: u32, n: u32| v.saturating_sub(reach) / tile..=(v + reach).min(n - 1) / tile;
                for ty in span(y, size.1) {
                    for tx in span(x, size.0) {
                        assert_eq!(
                            flags[(ty * tiles_x + tx) as usize],
                            1,
                            "pixel ({x}, {y}) of instance {} reaches tile ({tx}, {ty}) \
                             ({tile} px, reach {reach})",
                            h.instance
                        );
                    }
                }
            }
        }
        assert!(source_pixels > 1000, "{source_pixels} source pixels");
        let unflagged = flags.iter().filter(|&&f| f == 0).count();
        assert!(
            unflagged * 3 >= flags.len(),
            "{unflagged} of {} tiles unflagged ({tile} px, reach {reach})",
            flags.len()
        );
    }
}
