//! Which instances each screen tile's primary rays can meet
//! (`accel::screen_tiles`), against the CPU tracer: no GPU needed.
use celray::accel::bvh::Aabb;
use celray::accel::screen_tiles::{
    plane_region_tiles, primary_tiles, reached_tiles, smooth_plane_tiles, smooth_sphere_tiles,
    tile_list, ScreenBound, SmoothSteps, TILE_PAD_PX,
};
use celray::accel::SceneAccel;
use celray::gpu::twins::{PRIMARY_TILE_MAX, PRIMARY_TILE_WORDS};
use celray::render::camera::{depth_range, sample_camera, SampleCamera};
use celray::scene::{Camera, Scene};
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
    built(ron, "test.ron")
}

/// Scene `ron` (named `name`) and its acceleration data, instances in
/// file order.
fn built(ron: &str, name: &str) -> (Scene, SceneAccel) {
    let scene = Scene::from_ron_str(ron, name, std::path::Path::new(".")).unwrap();
    let order: Vec<usize> = (0..scene.instances.len()).collect();
    let accel = SceneAccel::build(&scene, &order).unwrap();
    (scene, accel)
}

/// The camera the renderer makes the tiles of a sample with sub-pixel
/// `shift` and lens point `lens` for (`Renderer::tile_camera`): the
/// sample's own, but on a pinhole lens without its shift, which every
/// proof's pad (`TILE_PAD_PX`) covers. The tests below prove tiles with
/// it and follow the shifted sample's rays.
fn tile_camera(
    camera: &Camera,
    size: (u32, u32),
    shift: Vec2,
    lens: Vec2,
    depth: (f32, f32),
) -> SampleCamera {
    let shift = if camera.aperture_radius == 0.0 {
        Vec2::splat(0.5)
    } else {
        shift
    };
    sample_camera(camera, size, shift, lens, depth)
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
    let (_, accel) = scene();
    primary_rays_meet_only_their_tiles_instances(&accel.world_bounds);
}

/// The same with the footprints the renderer uses, where spheres and the
/// CSG solid also have a bounding sphere (a tile is kept only where its
/// cone of rays meets it): still every hit in its tile's list, and the
/// lists hold fewer entries than with the boxes alone.
#[test]
fn a_primary_ray_meets_only_its_tiles_instances_with_bounding_spheres() {
    let (_, accel) = scene();
    assert!(
        accel
            .footprints
            .iter()
            .filter(|f| f.sphere.is_some())
            .count()
            >= 3
    );
    let boxes = primary_rays_meet_only_their_tiles_instances(&accel.world_bounds);
    let spheres = primary_rays_meet_only_their_tiles_instances(&accel.footprints);
    assert!(
        spheres < boxes,
        "{spheres} entries, against {boxes} with boxes alone"
    );
}

/// The checks of [`a_primary_ray_meets_only_its_tiles_instances`] with
/// `bounds`; returns how many entries the 8 px tiles' lists hold.
fn primary_rays_meet_only_their_tiles_instances(bounds: &[impl ScreenBound]) -> usize {
    let (mut scene, accel) = scene();
    scene.camera.focus_distance = Some(5.0);
    let size = (scene.camera.width, scene.camera.height);
    let (mut hits, mut listed_tiles, mut entries) = (0, 0, 0);
    let shifts = [(0.0, 0.0), (0.999, 0.999), (0.0, 0.999), (0.5, 0.5)];
    let apertures = [0.15, 0.0];
    // Tiles of one pixel hold the rectangles to the pixel; on a pinhole
    // lens the tiles are the unshifted camera's.
    for (i, &(sx, sy), tile, aperture) in shifts
        .iter()
        .enumerate()
        .flat_map(|(i, s)| [(i, s, 1), (i, s, 8)])
        .flat_map(|(i, s, t)| apertures.map(|a| (i, s, t, a)))
    {
        scene.camera.aperture_radius = aperture;
        let tiles_x = size.0.div_ceil(tile) as usize;
        let lens = Vec2::from_angle(i as f32 * 1.7) * (i % 2) as f32;
        let depth = depth_range(&scene.camera, scene.bounds());
        let cam = sample_camera(&scene.camera, size, Vec2::new(sx, sy), lens, depth);
        let made = tile_camera(&scene.camera, size, Vec2::new(sx, sy), lens, depth);
        let tiles = primary_tiles(bounds, |_| true, made.clip_from_world, size, tile);
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
    let tiles = apertures.len() * shifts.len() * (size.0.div_ceil(8) * size.1.div_ceil(8)) as usize;
    assert!(
        hits > apertures.len() * 2 * shifts.len() * 203 * 117 / 2,
        "{hits} hits"
    );
    assert!(
        listed_tiles * 10 > tiles * 9,
        "{listed_tiles} of {tiles} tiles listed"
    );
    let mean = entries as f64 / listed_tiles as f64;
    assert!(mean < 4.0, "{mean:.2} instances a listed tile");
    entries
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
    let (_, accel) = scene();
    source_pixels_flag_every_tile_within_their_reach(&accel.world_bounds);
}

/// The same with the footprints the renderer uses (bounding spheres for
/// the balls and the CSG solid): still every tile within reach of a
/// source pixel, and fewer flags than with the boxes alone.
#[test]
fn a_source_pixel_flags_every_tile_within_its_reach_with_bounding_spheres() {
    let (_, accel) = scene();
    let boxes = source_pixels_flag_every_tile_within_their_reach(&accel.world_bounds);
    let spheres = source_pixels_flag_every_tile_within_their_reach(&accel.footprints);
    assert!(
        spheres < boxes,
        "{spheres} flags, against {boxes} with boxes alone"
    );
}

/// The checks of [`a_source_pixel_flags_every_tile_within_its_reach`]
/// with `bounds`; returns how many flags its cases set.
fn source_pixels_flag_every_tile_within_their_reach(bounds: &[impl ScreenBound]) -> usize {
    let (mut scene, accel) = scene();
    let mut flagged = 0;
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
    // On a pinhole lens the flags are the unshifted camera's.
    let apertures = [0.15, 0.0];
    for ((shift, lens, tile, reach), aperture) in
        cases.into_iter().flat_map(|c| apertures.map(|a| (c, a)))
    {
        scene.camera.aperture_radius = aperture;
        let depth = depth_range(&scene.camera, scene.bounds());
        let cam = sample_camera(&scene.camera, size, shift, lens, depth);
        let made = tile_camera(&scene.camera, size, shift, lens, depth);
        let flags = reached_tiles(
            bounds,
            |k| sources.contains(&(k as u32)),
            made.clip_from_world,
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
        flagged += flags.len() - unflagged;
    }
    flagged
}

/// A ball filling most of the view's height (the bench's single sphere,
/// at 640 x 360): its box's rectangle holds half the image again beside
/// the ball's disk. With its bounding sphere, the flags stay conservative
/// (every tile within reach of a pixel whose ray meets the ball) and
/// tight: a flagged tile's cone meets the ball within its half-angle, so
/// it lies within a tile, the reach and the padding of a pixel that
/// shows the ball. Here: within tile + reach + TILE_PAD_PX + 1 px (the
/// grown half-angle bound is 1% wider than the half-diagonal) in x and
/// in y. The box alone flags tiles three times that far out.
#[test]
fn a_balls_bounding_sphere_flags_only_the_tiles_near_its_disk() {
    let ron = r#"(version: 1,
        camera: (eye: (0.6283, 0.8377, 1.0472), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 640, height: 360),
        lights: [Directional(direction: (-0.4, -1.0, -0.5), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: { "m": (base_color: (0.8, 0.3, 0.2), model: Toon(bands: 4)) },
        shapes: { "ball": Sphere(radius: 0.45) },
        instances: [(shape: "ball", material: "m")],
    )"#;
    let scene = Scene::from_ron_str(ron, "test.ron", std::path::Path::new(".")).unwrap();
    let accel = SceneAccel::build(&scene, &[0]).unwrap();
    let size = (scene.camera.width, scene.camera.height);
    let depth = depth_range(&scene.camera, scene.bounds());
    let cam = sample_camera(&scene.camera, size, Vec2::new(0.3, 0.7), Vec2::ZERO, depth);
    let hit: Vec<bool> = (0..size.0 * size.1)
        .map(|i| {
            let (o, d) = kernel_ray(cam.clip_from_world, size, i % size.0, i / size.0);
            accel.closest_hit(o, d, 0.0, f32::INFINITY).hit.is_some()
        })
        .collect();
    let (tile, reach) = (8u32, 1u32);
    // The farthest (in x or y) a flagged tile may lie from a ball pixel.
    let near = tile + reach + TILE_PAD_PX.ceil() as u32 + 1;
    let far_out = flags_stay_near_hits(
        &accel,
        cam.clip_from_world,
        size,
        &hit,
        (tile, reach, near),
        "the ball",
    );
    assert!(
        far_out > 100,
        "the box flags {far_out} tiles far from the ball"
    );
}

/// Checks `reached_tiles` with `accel`'s footprints, for one sample's
/// projection `clip`, against `hit` (per pixel, whether its ray meets
/// `what`), with tiles of `tile` px and outline radius `reach`: it flags
/// every tile with a hit pixel within `reach` (conservative) and only
/// tiles with one within `near` px (tight), in x and y. Returns how many
/// tiles the boxes alone (`SceneAccel::world_bounds`) flag with no hit
/// pixel within 3 `near`.
fn flags_stay_near_hits(
    accel: &SceneAccel,
    clip: Mat4,
    size: (u32, u32),
    hit: &[bool],
    (tile, reach, near): (u32, u32, u32),
    what: &str,
) -> usize {
    let tiles_x = size.0.div_ceil(tile);
    // Whether some hit pixel lies within `d` px (x and y) of tile t.
    let within = |t: u32, d: u32| {
        let (tx, ty) = (t % tiles_x * tile, t / tiles_x * tile);
        let ys = ty.saturating_sub(d)..(ty + tile + d).min(size.1);
        let xs = tx.saturating_sub(d)..(tx + tile + d).min(size.0);
        ys.into_iter()
            .any(|y| xs.clone().any(|x| hit[(y * size.0 + x) as usize]))
    };
    let flags = reached_tiles(&accel.footprints, |_| true, clip, size, tile, reach);
    for t in 0..flags.len() as u32 {
        if within(t, reach) {
            assert_eq!(
                flags[t as usize], 1,
                "tile {t} ({tile} px, reach {reach}) has {what} within reach"
            );
        }
        if flags[t as usize] == 1 {
            assert!(
                within(t, near),
                "tile {t} ({tile} px, reach {reach}) is flagged, {what} not within {near} px"
            );
        }
    }
    let boxes = reached_tiles(&accel.world_bounds, |_| true, clip, size, tile, reach);
    (0..boxes.len() as u32)
        .filter(|&t| boxes[t as usize] == 1 && !within(t, 3 * near))
        .count()
}

/// A tilted, stretched quad and a disk (not under a similarity), whole in
/// front of the eye, seen at a slant through a lens: their boxes'
/// rectangles hold large parts of the image they do not cover. With their
/// polygons' images (`Footprint::outline`), the flags and lists stay
/// conservative (every tile within reach of a pixel whose ray meets one
/// flagged, and every pixel's hit in its tile's list) and tight: a flagged
/// tile lies within tile + reach + 2 TILE_PAD_PX + 1 + 9 px (in x and y)
/// of a pixel that shows one. The image is grown by TILE_PAD_PX at each
/// edge, which pushes a corner of angle a out by TILE_PAD_PX / sin(a / 2),
/// under 2 TILE_PAD_PX for the corners of at least 60 degrees seen here;
/// the octagon around the disk reaches 1 / cos 22.5 - 1 = 0.082 of its
/// radius (1.04 at most here) beyond it, under 9 px at its distance
/// (over 5) with a focal length of 494 px. The boxes alone flag tiles
/// of over 6,400 square pixels (a hundred 8 px tiles) farther than three
/// times that from any such pixel.
#[test]
fn a_quads_image_flags_only_the_tiles_near_it() {
    let ron = r#"(version: 1,
        camera: (eye: (1.0, 3.0, 6.0), target: (0.0, 0.5, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 640, height: 360,
                 aperture_radius: 0.05, focus_distance: 6.0),
        lights: [Directional(direction: (-0.4, -1.0, -0.5), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: { "m": (base_color: (0.8, 0.3, 0.2), model: Toon(bands: 4)) },
        shapes: { "quad": Plane(Quad(half_size: (2.0, 1.0))), "disk": Plane(Disk(radius: 0.8)) },
        instances: [
            (shape: "quad", material: "m", transform: (translate: (-0.5, 0.0, 0.0), rotate_deg: (0.0, 35.0, 20.0), scale: (1.0, 1.0, 1.5))),
            (shape: "disk", material: "m", transform: (translate: (2.0, 1.5, 0.5), rotate_deg: (60.0, -30.0, 0.0), scale: (1.3, 1.0, 0.8))),
        ],
    )"#;
    let scene = Scene::from_ron_str(ron, "test.ron", std::path::Path::new(".")).unwrap();
    let accel = SceneAccel::build(&scene, &[0, 1]).unwrap();
    assert!(accel.footprints.iter().all(|f| f.outline.is_some()));
    let size = (scene.camera.width, scene.camera.height);
    let depth = depth_range(&scene.camera, scene.bounds());
    let cases = [
        (Vec2::new(0.3, 0.7), Vec2::ZERO, 8u32, 1u32),
        (Vec2::new(0.9, 0.1), Vec2::new(0.6, -0.8), 8, 0),
        (Vec2::new(0.5, 0.5), Vec2::new(-1.0, 0.0), 16, 4),
    ];
    for (case, &(shift, lens, tile, reach)) in cases.iter().enumerate() {
        let cam = sample_camera(&scene.camera, size, shift, lens, depth);
        let hit: Vec<Option<u32>> = (0..size.0 * size.1)
            .map(|i| {
                let (o, d) = kernel_ray(cam.clip_from_world, size, i % size.0, i / size.0);
                accel
                    .closest_hit(o, d, 0.0, f32::INFINITY)
                    .hit
                    .map(|h| h.instance)
            })
            .collect();
        let tiles_x = size.0.div_ceil(tile);
        let near = tile + reach + 2 * TILE_PAD_PX.ceil() as u32 + 1 + 9;
        let lists = primary_tiles(&accel.footprints, |_| true, cam.clip_from_world, size, tile);
        for (i, h) in hit.iter().enumerate() {
            let Some(h) = h else { continue };
            let (x, y) = (i as u32 % size.0, i as u32 / size.0);
            let t = (y / tile * tiles_x + x / tile) as usize;
            let list = tile_list(&lists, t).unwrap();
            assert!(
                list.contains(h),
                "case {case}: pixel ({x}, {y}) meets {h}, not in {list:?}"
            );
        }
        let shown: Vec<bool> = hit.iter().map(Option::is_some).collect();
        let far_out = flags_stay_near_hits(
            &accel,
            cam.clip_from_world,
            size,
            &shown,
            (tile, reach, near),
            "a shape",
        );
        // 6,400 square pixels: a hundred 8 px tiles.
        assert!(
            far_out as u32 * tile * tile > 6400,
            "case {case}: the boxes flag {far_out} tiles far from the shapes"
        );
    }
}

/// A record's summary in the tile's flag word (`TILE_RECORD_SHIFT`): 0
/// for no instance, k + 1 for instance k alone, and "read the record"
/// for two instances, a walk, or an index whose k + 1 would be taken for
/// "read the record" (the summary has 32 - TILE_RECORD_SHIFT bits).
#[test]
fn a_record_of_at_most_one_instance_is_summarized_in_the_flag_word() {
    use celray::accel::screen_tiles::record_summary;
    use celray::gpu::twins::{
        PRIMARY_TILE_WALK, TILE_GBUFFER_SKIPS, TILE_MESH_MAY_SHOW, TILE_RECORD_READ,
        TILE_RECORD_SHIFT, TILE_TRACE_ACCUMULATES,
    };
    let record = |words: &[u32]| {
        let mut r = [0u32; PRIMARY_TILE_WORDS as usize];
        r[..words.len()].copy_from_slice(words);
        r
    };
    assert_eq!(record_summary(&record(&[0])), 0);
    assert_eq!(record_summary(&record(&[1, 0])), 1);
    assert_eq!(record_summary(&record(&[1, 41])), 42);
    assert_eq!(record_summary(&record(&[2, 3, 5])), TILE_RECORD_READ);
    assert_eq!(
        record_summary(&record(&[PRIMARY_TILE_WALK])),
        TILE_RECORD_READ
    );
    assert_eq!(
        record_summary(&record(&[1, TILE_RECORD_READ - 2])),
        TILE_RECORD_READ - 1
    );
    assert_eq!(
        record_summary(&record(&[1, TILE_RECORD_READ - 1])),
        TILE_RECORD_READ
    );
    // The summary fills the word above the flags, and no flag bit reaches
    // the summary.
    assert_eq!(u32::MAX >> TILE_RECORD_SHIFT, TILE_RECORD_READ);
    let flags = TILE_MESH_MAY_SHOW | TILE_TRACE_ACCUMULATES | TILE_GBUFFER_SKIPS;
    assert_eq!(flags >> TILE_RECORD_SHIFT, 0);
}

/// What [`check_smooth_claims`] found in one case: tiles claimed, tiles
/// whose every pixel sees the target first, and whether the tile of the
/// probe point (the centre of a ball's disc) was claimed.
struct Claims {
    claimed: usize,
    all_ball: usize,
    centre_claimed: bool,
}

/// A CPU proof of smooth tiles for one instance of a scene (the GPU
/// instance index), with the arguments `smooth_sphere_tiles` and
/// `smooth_plane_tiles` take after the shapes: the sample's view
/// direction and projection, the image size, the tile edge, the outline
/// radius and the per-step bounds.
type Proof = fn(&SceneAccel, usize, Vec3, Mat4, (u32, u32), u32, u32, SmoothSteps) -> Vec<bool>;

/// `smooth_sphere_tiles` for one exact sphere, as a [`Proof`].
#[allow(clippy::too_many_arguments)]
fn sphere_proof(
    accel: &SceneAccel,
    target: usize,
    forward: Vec3,
    clip: Mat4,
    size: (u32, u32),
    tile: u32,
    reach: u32,
    steps: SmoothSteps,
) -> Vec<bool> {
    let spheres: Vec<_> = (accel.exact_spheres.iter())
        .filter(|s| s.instance == target)
        .copied()
        .collect();
    smooth_sphere_tiles(
        &accel.footprints,
        &spheres,
        forward,
        clip,
        size,
        tile,
        reach,
        steps,
    )
}

/// `smooth_plane_tiles` for one exact plane, as a [`Proof`].
#[allow(clippy::too_many_arguments)]
fn plane_proof(
    accel: &SceneAccel,
    target: usize,
    forward: Vec3,
    clip: Mat4,
    size: (u32, u32),
    tile: u32,
    reach: u32,
    steps: SmoothSteps,
) -> Vec<bool> {
    let planes: Vec<_> = (accel.exact_planes.iter())
        .filter(|p| p.instance == target)
        .copied()
        .collect();
    smooth_plane_tiles(
        &accel.footprints,
        &planes,
        forward,
        clip,
        size,
        tile,
        reach,
        steps,
    )
}

/// Checks the claims of `prove` for the instance `target` of `scene` in
/// each case (sub-pixel shift, lens point, tile edge, outline radius):
/// along the kernel's ray of every pixel of a claimed tile and its halo
/// (the CPU tracer, the kernel's twin) the closest hit is on `target`,
/// and between every two neighbouring pixels there the view depth changes
/// its log by at most half of `SmoothSteps::ln_depth` and the normal
/// turns by at most half of `SmoothSteps::angle`. `depth` is the near and
/// far planes, `depth_range`'s where `None`. `probe` is a world point
/// whose tile [`Claims::centre_claimed`] reports.
fn check_smooth_claims(
    scene: &Scene,
    depth: Option<(f32, f32)>,
    (target, probe): (usize, Vec3),
    prove: Proof,
    cases: &[(Vec2, Vec2, u32, u32)],
) -> Vec<Claims> {
    let order: Vec<usize> = (0..scene.instances.len()).collect();
    let accel = SceneAccel::build(scene, &order).unwrap();
    let size = (scene.camera.width, scene.camera.height);
    let mut all = Vec::new();
    for &(shift, lens, tile, reach) in cases {
        let mut out = Claims {
            claimed: 0,
            all_ball: 0,
            centre_claimed: false,
        };
        let depth = depth.unwrap_or_else(|| depth_range(&scene.camera, scene.bounds()));
        let cam = sample_camera(&scene.camera, size, shift, lens, depth);
        let made = tile_camera(&scene.camera, size, shift, lens, depth);
        let steps = SmoothSteps::for_radius(reach);
        let claimed = prove(
            &accel,
            target,
            made.forward,
            made.clip_from_world,
            size,
            tile,
            reach,
            steps,
        );
        let tiles_x = size.0.div_ceil(tile);
        assert_eq!(claimed.len() as u32, tiles_x * size.1.div_ceil(tile));
        // Every pixel's hit on the ball (normal, view depth), if the ball
        // is its closest hit.
        let hits: Vec<Option<(Vec3, f32)>> = (0..size.0 * size.1)
            .map(|i| {
                let (x, y) = (i % size.0, i / size.0);
                let (o, d) = kernel_ray(cam.clip_from_world, size, x, y);
                let h = accel.closest_hit(o, d, 0.0, f32::INFINITY).hit?;
                (h.instance as usize == target)
                    .then(|| (h.geometric, (o + d * h.t - cam.eye).dot(cam.forward)))
            })
            .collect();
        let region = |tx: u32, ty: u32| {
            let lo = (
                (tx * tile).saturating_sub(reach),
                (ty * tile).saturating_sub(reach),
            );
            let hi = (
                ((tx + 1) * tile + reach).min(size.0) - 1,
                ((ty + 1) * tile + reach).min(size.1) - 1,
            );
            (lo, hi)
        };
        for t in 0..claimed.len() as u32 {
            let (tx, ty) = (t % tiles_x, t / tiles_x);
            let ((x0, y0), (x1, y1)) = region(tx, ty);
            let every =
                (y0..=y1).all(|y| (x0..=x1).all(|x| hits[(y * size.0 + x) as usize].is_some()));
            out.all_ball += usize::from(every);
            if !claimed[t as usize] {
                continue;
            }
            out.claimed += 1;
            assert!(
                every,
                "tile ({tx}, {ty}) ({tile} px, reach {reach}): a pixel does not see instance {target} first"
            );
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let (n, w) = hits[(y * size.0 + x) as usize].unwrap();
                    for (nx, ny) in [(x + 1, y), (x, y + 1)] {
                        if nx > x1 || ny > y1 {
                            continue;
                        }
                        let (m, v) = hits[(ny * size.0 + nx) as usize].unwrap();
                        let ratio = (f64::from(w) / f64::from(v)).ln().abs();
                        let turn = f64::from(n.dot(m) / (n.length() * m.length()))
                            .min(1.0)
                            .acos();
                        assert!(
                            ratio <= 0.5 * steps.ln_depth && turn <= 0.5 * steps.angle + 1e-6,
                            "tile ({tx}, {ty}) ({tile} px, reach {reach}), pixels ({x}, {y}) and \
                             ({nx}, {ny}): depth log {ratio:.5} against {:.5}, turn {turn:.5} \
                             against {:.5}",
                            0.5 * steps.ln_depth,
                            0.5 * steps.angle
                        );
                    }
                }
            }
        }
        // The tile holding the projection of the probe.
        let centre = cam.clip_from_world.project_point3(probe);
        let px = (
            ((centre.x + 1.0) * 0.5 * size.0 as f32) as u32,
            ((1.0 - centre.y) * 0.5 * size.1 as f32) as u32,
        );
        out.centre_claimed = claimed[((px.1 / tile) * tiles_x + px.0 / tile) as usize];
        all.push(out);
    }
    all
}

/// `smooth_sphere_tiles` claims a tile only where the outline marks would
/// prove it the smooth inside of one sphere, with half of each per-step
/// bound to spare ([`check_smooth_claims`]), and it claims enough to
/// matter. Three views:
/// - a ball near the eye (D / R about 4, 640 x 360), with what could
///   break the proof around it: a floor it rests on (no ray meets the
///   floor before the ball's visible cap), a crate between the eye and
///   part of the ball, and an ellipsoid (not an exact sphere, so never
///   claimed); outline radius 1 and 3, 8 and 16 px tiles, sub-pixel
///   shifts and a lens point (the eye moves with it). The depth bound is
///   the one that limits the claims here. The tile at the centre of the
///   disc (a ray meets the ball head-on there, incidence 0, so the normal
///   turns (1 + D / R) times the pixel angle a step, far under the bound)
///   is claimed in every case; with radius 1 at least half of the tiles
///   whose every pixel sees the ball are (the bounds hold out to
///   incidence 60 degrees there, three quarters of the disc, from the doc
///   comment's formulas at this camera);
/// - a small ball, rotated and scaled, far from the eye (D / R = 40)
///   through a narrow lens (6 degrees), with outline radius 1 and 8:
///   at radius 8 the normal's turn, (1 + D / (R cos i)) pixel angles a
///   step, is the bound that limits the claims (out to incidence 66
///   degrees, the depth's to 77), so a turn bound without the 1 / cos i
///   would claim tiles whose pixels turn too far;
/// - a ball the near plane cuts (the scene is the ball alone, 25 degrees
///   off the view axis, so the near plane, set from the distance to the
///   scene's centre, lies beyond the ball's nearest view depth): rays
///   start inside it there, and no tile of it is claimed.
#[test]
fn tiles_claimed_smooth_hold_only_the_smooth_inside_of_one_sphere() {
    let ron = r#"(version: 1,
        camera: (eye: (0.5, 2.0, 4.0), target: (0.0, 1.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 640, height: 360),
        lights: [Directional(direction: (-0.5, -1.0, -0.6), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: { "m": (base_color: (0.8, 0.8, 0.8), model: BlinnPhong) },
        shapes: {
            "floor": Plane(Quad(half_size: (20.0, 20.0))),
            "ball": Sphere(radius: 1.0),
            "crate": Box(half_extents: (0.06, 0.06, 0.06)),
        },
        instances: [
            (shape: "floor", material: "m"),
            (shape: "ball", material: "m", transform: (translate: (0.0, 1.0, 0.0))),
            (shape: "crate", material: "m", transform: (translate: (0.6, 1.55, 2.2))),
            (shape: "ball", material: "m", transform: (translate: (-2.5, 0.5, -1.0), scale: (1.5, 0.5, 0.5))),
            (shape: "ball", material: "m", transform: (translate: (30.0, 1.0, -30.0), rotate_deg: (20.0, 40.0, 0.0), scale: (0.5, 0.5, 0.5))),
        ],
    )"#;
    let mut scene = Scene::from_ron_str(ron, "test.ron", std::path::Path::new(".")).unwrap();
    scene.camera.focus_distance = Some(4.0);
    scene.camera.aperture_radius = 0.1;
    let order: Vec<usize> = (0..scene.instances.len()).collect();
    let spheres = SceneAccel::build(&scene, &order).unwrap().exact_spheres;
    assert_eq!(
        spheres.iter().map(|s| s.instance).collect::<Vec<_>>(),
        [1, 4],
        "the round balls are exact spheres, the ellipsoid is not"
    );
    assert!((spheres[1].radius - 0.5).abs() < 1e-6, "{:?}", spheres[1]);
    let near = check_smooth_claims(
        &scene,
        None,
        (spheres[0].instance, spheres[0].centre),
        sphere_proof,
        &[
            (Vec2::splat(0.5), Vec2::ZERO, 8, 1),
            (Vec2::new(0.1, 0.9), Vec2::new(0.6, -0.8), 8, 1),
            (Vec2::new(0.9, 0.3), Vec2::ZERO, 8, 3),
            (Vec2::new(0.4, 0.6), Vec2::new(-1.0, 0.0), 16, 3),
        ],
    );
    for (case, c) in near.iter().enumerate() {
        assert!(
            c.centre_claimed,
            "case {case}: the tile at the near ball's centre"
        );
    }
    for (case, c) in near[..2].iter().enumerate() {
        assert!(
            2 * c.claimed >= c.all_ball,
            "case {case}: {} tiles claimed of {} that see only the near ball",
            c.claimed,
            c.all_ball
        );
    }

    scene.camera.eye = Vec3::new(30.0, 1.2, -10.0);
    scene.camera.target = Vec3::new(30.0, 1.0, -30.0);
    scene.camera.fov_y_deg = 6.0;
    scene.camera.aperture_radius = 0.0;
    let far = check_smooth_claims(
        &scene,
        None,
        (spheres[1].instance, spheres[1].centre),
        sphere_proof,
        &[
            (Vec2::splat(0.5), Vec2::ZERO, 8, 1),
            (Vec2::new(0.2, 0.7), Vec2::ZERO, 16, 8),
        ],
    );
    for (case, c) in far.iter().enumerate() {
        assert!(
            c.centre_claimed,
            "case {case}: the tile at the far ball's centre"
        );
    }

    let cut = Scene::from_ron_str(
        r#"(version: 1,
        camera: (eye: (0.0, 0.0, 10.0), target: (-4.663, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 32.2, width: 720, height: 360),
        lights: [Directional(direction: (-0.5, -1.0, -0.6), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: { "m": (base_color: (0.8, 0.8, 0.8), model: BlinnPhong) },
        shapes: { "ball": Sphere(radius: 1.0) },
        instances: [(shape: "ball", material: "m")],
    )"#,
        "cut.ron",
        std::path::Path::new("."),
    )
    .unwrap();
    let ball = SceneAccel::build(&cut, &[0]).unwrap().exact_spheres[0];
    // `depth_range` keeps every object beyond the near plane, so this case
    // sets its own: 8.95, the distance to the ball's centre less 1.05
    // radii, through the ball, whose nearest view depth is
    // 10 cos 25 - 1 = 8.06. The premise: some pixel's ray starts inside
    // the ball and meets its far side, whose normal faces away from the
    // eye.
    let size = (cut.camera.width, cut.camera.height);
    let depth = (8.95, depth_range(&cut.camera, cut.bounds()).1);
    let accel = SceneAccel::build(&cut, &[0]).unwrap();
    let starts_inside = |depth: (f32, f32)| {
        let cam = sample_camera(&cut.camera, size, Vec2::splat(0.5), Vec2::ZERO, depth);
        (0..size.0 * size.1).any(|i| {
            let (o, d) = kernel_ray(cam.clip_from_world, size, i % size.0, i / size.0);
            (accel.closest_hit(o, d, 0.0, f32::INFINITY).hit)
                .is_some_and(|h| h.geometric.dot(d) > 0.0)
        })
    };
    assert!(starts_inside(depth), "the near plane cuts the ball");
    assert!(
        !starts_inside(depth_range(&cut.camera, cut.bounds())),
        "depth_range's near plane cuts the ball"
    );
    let claims = check_smooth_claims(
        &cut,
        Some(depth),
        (ball.instance, ball.centre),
        sphere_proof,
        &[(Vec2::splat(0.5), Vec2::ZERO, 8, 1)],
    );
    assert_eq!(claims[0].claimed, 0, "tiles of a ball the near plane cuts");
}

/// `smooth_plane_tiles` claims a tile only where the outline marks would
/// prove it the smooth inside of one quad or disk, with half of each
/// per-step bound to spare ([`check_smooth_claims`]), and it claims enough
/// to matter. A floor quad (6 x 6 half sizes, its far edge and the sky
/// beyond in view) with a crate standing on it (in the way: the crate's
/// tiles are not claimed) and a ball wholly under it (beyond the plane
/// from the eye, so it blocks nothing: the tile over it is claimed), and
/// a disk tilted and stretched by a matrix that is not a similarity.
/// - Looking down from 2.5 above the floor, 640 x 360, outline radius 1,
///   8 px tiles, a sub-pixel shift and a lens point: the tile over the
///   hidden ball, the tile of the disk's centre and the tile of the
///   centre of the crate's face towards the eye (a box's face, with the
///   floor it stands on below the tile's hits) are claimed, and at
///   least half of the tiles whose every pixel sees the floor are (the
///   depth bound, d (tan f + tan g), holds out to about 75 degrees from
///   the floor's normal here, where the far edge is at 79).
/// - From 6 above the floor, outline radius 3 (each step bounded to a
///   sixth of the end-to-end bounds), 8 and 16 px tiles: the tile over
///   the hidden ball is claimed. The eye is inside the scene's bounds, so
///   the near plane is 1e-4 of the far plane's distance, where the far
///   plane's points are affine in the pixel point only to a relative
///   2e-4 (`TileCones`).
/// - From 0.3 above the floor, looking along it: towards the far edge the
///   view grazes the floor (89 degrees from its normal), where the view
///   depth changes its log by d tan g = 0.07 a pixel, seven times the half
///   bound; tiles are claimed near the eye, but not all of the floor's.
///   Without the tan g term the claims would reach the far edge.
/// - A near plane set through the floor (view depth 4.0; the bottom row's
///   ray, 42 degrees below the horizontal, meets the floor at view depth
///   2.5 cos 22.5 / sin 42 = 3.45): the rays of the bottom rows start
///   beyond the floor and miss it, and their tiles are not claimed.
#[test]
fn tiles_claimed_smooth_hold_only_the_smooth_inside_of_one_plane() {
    let ron = r#"(version: 1,
        camera: (eye: (0.5, 2.5, 7.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 45.0, width: 640, height: 360),
        lights: [Directional(direction: (-0.5, -1.0, -0.6), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: { "m": (base_color: (0.8, 0.8, 0.8), model: BlinnPhong) },
        shapes: {
            "floor": Plane(Quad(half_size: (6.0, 6.0))),
            "crate": Box(half_extents: (0.5, 0.5, 0.5)),
            "ball": Sphere(radius: 0.5),
            "disk": Plane(Disk(radius: 1.0)),
        },
        instances: [
            (shape: "floor", material: "m"),
            (shape: "crate", material: "m", transform: (translate: (-0.5, 0.5, -1.0), rotate_deg: (0.0, 25.0, 0.0))),
            (shape: "ball", material: "m", transform: (translate: (1.5, -1.0, 1.5))),
            (shape: "disk", material: "m", transform: (translate: (-2.5, 1.3, 1.0), rotate_deg: (70.0, 30.0, 0.0), scale: (1.5, 1.0, 0.7))),
        ],
    )"#;
    let mut scene = Scene::from_ron_str(ron, "test.ron", std::path::Path::new(".")).unwrap();
    scene.camera.focus_distance = Some(7.0);
    scene.camera.aperture_radius = 0.05;
    let order: Vec<usize> = (0..scene.instances.len()).collect();
    let planes = SceneAccel::build(&scene, &order).unwrap().exact_planes;
    assert_eq!(
        planes
            .iter()
            .map(|p| (p.instance, p.disk, p.face))
            .collect::<Vec<_>>(),
        [
            [(0, false, false)].as_slice(),
            &[(1, false, true); 6],
            &[(3, true, false)]
        ]
        .concat(),
        "the floor, the crate's six faces and the disk are exact planes"
    );
    let cases = [
        (Vec2::splat(0.5), Vec2::ZERO, 8, 1),
        (Vec2::new(0.1, 0.9), Vec2::new(0.6, -0.8), 8, 1),
        (Vec2::new(0.9, 0.3), Vec2::ZERO, 8, 3),
        (Vec2::new(0.4, 0.6), Vec2::new(-1.0, 0.0), 16, 3),
    ];
    let over_ball = Vec3::new(1.5, 0.0, 1.5);
    let floor = check_smooth_claims(&scene, None, (0, over_ball), plane_proof, &cases[..2]);
    for (case, c) in floor.iter().enumerate() {
        assert!(
            c.centre_claimed,
            "case {case}: the tile over the hidden ball"
        );
        assert!(
            2 * c.claimed >= c.all_ball,
            "case {case}: {} tiles claimed of {} that see only the floor",
            c.claimed,
            c.all_ball
        );
    }
    let top = Camera {
        eye: Vec3::new(0.5, 6.0, 2.0),
        target: Vec3::ZERO,
        ..scene.camera.clone()
    };
    let from_above = Scene {
        camera: top,
        ..scene.clone()
    };
    // The eye is inside the scene's bounds here, so `depth_range` puts
    // the near plane at 1e-4 of the far plane's distance.
    let floor = check_smooth_claims(&from_above, None, (0, over_ball), plane_proof, &cases[2..]);
    for (case, c) in floor.iter().enumerate() {
        assert!(
            c.centre_claimed,
            "case {case}, radius 3: the tile over the hidden ball"
        );
    }
    let disk_centre = Vec3::new(-2.5, 1.3, 1.0);
    let disk = check_smooth_claims(&scene, None, (3, disk_centre), plane_proof, &cases[..2]);
    for (case, c) in disk.iter().enumerate() {
        assert!(
            c.centre_claimed,
            "case {case}: the tile of the disk's centre"
        );
    }
    // The crate's face towards the eye (+z turned 25 degrees about y),
    // 55 px across, 23 degrees from the view; the floor the crate stands
    // on lies below the tile's hits.
    let (sin, cos) = 25f32.to_radians().sin_cos();
    let face_centre = Vec3::new(-0.5 + 0.5 * sin, 0.5, -1.0 + 0.5 * cos);
    let face = check_smooth_claims(&scene, None, (1, face_centre), plane_proof, &cases[..2]);
    for (case, c) in face.iter().enumerate() {
        assert!(
            c.centre_claimed,
            "case {case}: the tile of the crate's face centre"
        );
    }

    scene.camera.eye = Vec3::new(0.0, 0.3, 5.5);
    scene.camera.target = Vec3::new(0.0, 0.25, -6.0);
    scene.camera.aperture_radius = 0.0;
    let low = check_smooth_claims(&scene, None, (0, over_ball), plane_proof, &cases[..1]);
    assert!(
        low[0].claimed > 0 && low[0].claimed < low[0].all_ball,
        "grazing view: {} tiles claimed of {} that see only the floor",
        low[0].claimed,
        low[0].all_ball
    );

    scene.camera.eye = Vec3::new(0.5, 2.5, 7.0);
    scene.camera.target = Vec3::ZERO;
    let size = (scene.camera.width, scene.camera.height);
    let depth = (4.0, depth_range(&scene.camera, scene.bounds()).1);
    let accel = SceneAccel::build(&scene, &order).unwrap();
    let cam = sample_camera(&scene.camera, size, Vec2::splat(0.5), Vec2::ZERO, depth);
    let (o, d) = kernel_ray(cam.clip_from_world, size, size.0 / 2, size.1 - 1);
    assert!(
        accel.closest_hit(o, d, 0.0, f32::INFINITY).hit.is_none(),
        "the near plane cuts the floor at the bottom row"
    );
    let cut = check_smooth_claims(
        &scene,
        Some(depth),
        (0, over_ball),
        plane_proof,
        &cases[..1],
    );
    assert!(cut[0].claimed > 0, "tiles beyond the cut are claimed");
}

/// The proof behind `TILE_UNSHADOWED`: where `plane_region_tiles` finds
/// the floor's region under a tile culled (`CulledRegions::all_culled`),
/// every pixel of the tile whose ray (the kernel's, at sub-pixel offsets
/// at the pixel's corners) hits the floor starts a shadow ray, from where
/// the kernel starts it (the ray epsilon off the floor, on the eye's
/// side), that the kernel's query culls (`may_be_blocked` false, with no
/// convex receiver to leave: the strictest answer) or that meets nothing
/// (the CPU twin of the kernel's closest hit, over every instance). The
/// proof is not empty, some of it rests on the occluders' shadows (rays
/// the query would cast; in the first scene, whose occluders are of every
/// kind, and on a wide floor under a low sun), and it is not the whole
/// floor: some floor pixels outside the proven tiles are in the solids'
/// shadows, so a proof that ignored the grid's cells and the occluders
/// would fail here. The test scene's level floor, a tilted quad under a
/// few solids, and long shadows of a stretched sphere, a cylinder and a
/// cone.
#[test]
fn unshadowed_tiles_cast_only_culled_shadow_rays() {
    let (scene, accel) = scene();
    let (proven, by_shades, shadowed) = check_unshadowed_tiles(&scene, &accel);
    assert!(proven > 4 * 2000, "{proven} floor pixels proven");
    assert!(by_shades > 0, "no pixel proven past the grid's cells");
    assert!(shadowed > 500, "{shadowed} floor pixels shadowed");
    let ron = r#"(version: 1,
        camera: (eye: (1.0, 3.0, 7.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 45.0, width: 160, height: 100),
        lights: [Directional(direction: (0.3, -1.0, -0.4), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: { "m": (base_color: (0.8, 0.8, 0.8), model: BlinnPhong) },
        shapes: {
            "floor": Plane(Quad(half_size: (6.0, 4.0))),
            "ball": Sphere(radius: 0.5),
            "crate": Box(half_extents: (0.4, 0.3, 0.5)),
        },
        instances: [
            (shape: "floor", material: "m", transform: (translate: (0.0, -0.5, 0.0), rotate_deg: (12.0, 20.0, -8.0), scale: (1.0, 1.0, 1.5))),
            (shape: "ball", material: "m", transform: (translate: (-1.0, 0.8, 0.5))),
            (shape: "crate", material: "m", transform: (translate: (1.2, 0.6, -0.8), rotate_deg: (0.0, 30.0, 0.0))),
        ],
    )"#;
    let (scene, accel) = built(ron, "tilted.ron");
    let (proven, _, shadowed) = check_unshadowed_tiles(&scene, &accel);
    assert!(proven > 4 * 1000, "tilted: {proven} floor pixels proven");
    assert!(shadowed > 200, "tilted: {shadowed} floor pixels shadowed");
    // A wide floor under a low sun, with long shadows of a stretched
    // sphere, a cylinder and a cone (whose shades carry the widest
    // slack), seen from far off.
    let ron = r#"(version: 1,
        camera: (eye: (0.0, 5.0, 14.0), target: (0.0, 0.0, -1.0), up: (0.0, 1.0, 0.0), fov_y_deg: 50.0, width: 320, height: 200),
        lights: [Directional(direction: (1.0, -0.3, 0.4), color: (1.0, 1.0, 1.0), intensity: 1.0)],
        materials: { "m": (base_color: (0.8, 0.8, 0.8), model: BlinnPhong) },
        shapes: {
            "floor": Plane(Quad(half_size: (60.0, 60.0))),
            "ball": Sphere(radius: 0.5),
            "post": Cylinder(radius: 0.1, height: 3.0),
            "cone": Cone(radius: 0.6, height: 1.5),
        },
        instances: [
            (shape: "floor", material: "m"),
            (shape: "ball", material: "m", transform: (translate: (-3.0, 0.6, 2.0), scale: (4.0, 1.0, 1.0))),
            (shape: "post", material: "m", transform: (translate: (2.0, 0.0, -1.0))),
            (shape: "cone", material: "m", transform: (translate: (-1.0, 0.0, -6.0))),
        ],
    )"#;
    let (scene, accel) = built(ron, "wide.ron");
    let (proven, by_shades, shadowed) = check_unshadowed_tiles(&scene, &accel);
    assert!(proven > 4 * 5000, "wide: {proven} floor pixels proven");
    assert!(by_shades > 0, "wide: no pixel proven past the grid's cells");
    assert!(shadowed > 500, "wide: {shadowed} floor pixels shadowed");
}

/// [`unshadowed_tiles_cast_only_culled_shadow_rays`] for instance 0 of
/// `scene`, a static quad, under its first light, a directional one:
/// asserts the proof over four sub-pixel offsets and returns how many
/// floor pixels of proven tiles it checked, how many of those the query
/// would not cull, and how many floor pixels elsewhere are shadowed.
fn check_unshadowed_tiles(scene: &Scene, accel: &SceneAccel) -> (usize, usize, usize) {
    use celray::accel::shadow_cull;
    let cull = shadow_cull::build(accel, &scene.lights, true);
    let celray::scene::Light::Directional { direction, .. } = scene.lights[0] else {
        panic!("the test scene's light is the sun");
    };
    let to_light = -direction.normalize();
    // The regions the renderer proves tiles with, built with the cull data.
    let regions = cull.sun.as_ref().expect("one sun: its rays are culled");
    let floor = (accel.exact_planes.iter())
        .find(|p| !p.face && p.instance == 0)
        .expect("the floor is an exact plane");
    let (lo, hi) = scene.bounds();
    let epsilon = ((hi - lo).length() * 0.5).max(1e-3) * 1e-4;
    let size = (scene.camera.width, scene.camera.height);
    let tiles_x = size.0.div_ceil(8) as usize;
    let (mut proven, mut by_shades, mut shadowed_elsewhere) = (0, 0, 0);
    let offsets = [(0.0, 0.0), (0.999, 0.999), (0.0, 0.999), (0.5, 0.5)];
    // The renderer's groups of 4 x 4 tiles, and single tiles: smaller
    // regions, which more often pass between the occluders' shadows.
    for ((sx, sy), group) in offsets.into_iter().zip([4, 4, 1, 1]) {
        let depth = depth_range(&scene.camera, scene.bounds());
        let cam = sample_camera(&scene.camera, size, Vec2::new(sx, sy), Vec2::ZERO, depth);
        let made = tile_camera(&scene.camera, size, Vec2::new(sx, sy), Vec2::ZERO, depth);
        let region = |points: &[Vec3]| regions.all_culled(points);
        let tiles = plane_region_tiles(
            floor,
            made.clip_from_world,
            size,
            8,
            group,
            epsilon.into(),
            region,
        );
        for y in 0..size.1 {
            for x in 0..size.0 {
                let (o, d) = kernel_ray(cam.clip_from_world, size, x, y);
                let Some(h) = accel.closest_hit(o, d, 0.0, f32::INFINITY).hit else {
                    continue;
                };
                if h.instance != 0 {
                    continue;
                }
                let facing = if h.geometric.dot(d) > 0.0 {
                    -h.normal
                } else {
                    h.normal
                };
                let origin = o + d * h.t + facing * epsilon;
                let may = shadow_cull::may_be_blocked(
                    &cull.lights[0],
                    &cull.cells,
                    origin,
                    to_light,
                    u32::MAX,
                );
                let meets = (accel.closest_hit(origin, to_light, 0.0, f32::INFINITY).hit).is_some();
                if tiles[(y / 8) as usize * tiles_x + (x / 8) as usize] {
                    assert!(
                        !may || !meets,
                        "pixel ({x}, {y}) of a proven tile is shadowed"
                    );
                    proven += 1;
                    by_shades += usize::from(may);
                } else if meets {
                    shadowed_elsewhere += 1;
                }
            }
        }
    }
    (proven, by_shades, shadowed_elsewhere)
}
