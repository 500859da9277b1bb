//! Which instances a primary ray can meet, per screen tile; and which
//! tiles an instance may reach ([`reached_tiles`]).
//!
//! A primary ray of pixel p leaves the near plane along the points that the
//! sample's projection maps onto p's centre, so every point it meets
//! projects onto that centre. A point inside an instance's world box
//! projects inside the rectangle around its 8 corners' projections, when
//! all of them lie in front of the eye (a perspective projection keeps
//! straight lines straight on that side). So only the instances whose
//! rectangles cover p can give p's closest hit, and per tile of the trace
//! pass's workgroup (every 8 invocations of which run as one SIMD program
//! on the CPU driver) the kernel tests just those instead of walking the
//! BVH: the same intersection tests on the same instances, so the same
//! hits. A tile where more than [`PRIMARY_TILE_MAX`] may be seen walks.
//! The tiles depend on the camera, so they are made for every sample, on
//! the CPU; scenes with more than [`MAX_TILED_INSTANCES`] instances walk.
//!
//! A sphere's box projects onto a rectangle well beyond the sphere's own
//! disk (a third more across, and the rectangle's corners). Where an
//! instance also has a bounding sphere ([`Footprint`]: static spheres and
//! CSG solids), a tile inside its rectangle is kept only where the cone
//! of rays from the eye through the tile (grown as the rectangle is) meets
//! that sphere: every point the tile's rays can meet on the instance lies
//! in both.

use std::ops::RangeInclusive;

use glam::{DMat4, DVec2, DVec3, DVec4, Mat4, Vec2, Vec3, Vec4};

use crate::accel::bvh::Aabb;
use crate::accel::layout::{
    DEPTH_JUMP, PRIMARY_TILE_MAX, PRIMARY_TILE_WALK, PRIMARY_TILE_WORDS, TILE_RECORD_READ,
};

/// Scenes with more instances walk the BVH for every primary ray: most of
/// their tiles would see more than [`PRIMARY_TILE_MAX`] and walk anyway.
/// On lavapipe, sphere grids' trace pass took 0.64 of the walk's time
/// with tiles at 1,000 spheres, 0.94 at 4,000, 0.99 at 10,000 and 1.05 at
/// 100,000 (docs/performance-history.md, twenty-first session).
pub const MAX_TILED_INSTANCES: usize = 4096;

/// How far (pixels) each rectangle is grown: the kernel's rays are made in
/// f32 through the inverse projection, so a hit may project a little off
/// its pixel's centre; a millionth of a pixel would do for the shipped
/// scenes, and 2 px cost a few more entries at the edges.
pub const TILE_PAD_PX: f32 = 2.0;

/// How far each box is grown first, relative to the largest coordinate of
/// it and of the eye: f32 ray origins and hit points are off by about
/// 1e-7 of those, which far from the origin and close to the eye can
/// reach more than [`TILE_PAD_PX`] on the image.
pub const BOX_PAD_REL: f32 = 1e-5;

/// What the tiles know of an instance's extent in the world: a box, and
/// optionally a sphere holding it too.
pub trait ScreenBound {
    /// Its world box (over the whole shutter).
    fn world_box(&self) -> &Aabb;
    /// A world sphere (centre xyz, radius w) holding all of it, if any.
    fn world_sphere(&self) -> Option<Vec4> {
        None
    }
    /// Points of a flat convex polygon holding all of it, in order
    /// around it, if any.
    fn world_outline(&self) -> Option<[Vec3; 8]> {
        None
    }
}

impl ScreenBound for Aabb {
    fn world_box(&self) -> &Aabb {
        self
    }
}

/// An instance's extent as the renderer gives it to the tiles
/// (`SceneAccel::footprints`): its world box over the whole shutter; for
/// static spheres and CSG solids, a world sphere holding it; for static
/// quads and disks, a flat polygon holding it (`accel::world_outline`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    pub bounds: Aabb,
    pub sphere: Option<Vec4>,
    pub outline: Option<[Vec3; 8]>,
}

impl ScreenBound for Footprint {
    fn world_box(&self) -> &Aabb {
        &self.bounds
    }
    fn world_sphere(&self) -> Option<Vec4> {
        self.sphere
    }
    fn world_outline(&self) -> Option<[Vec3; 8]> {
        self.outline
    }
}

/// The tiles' records, row by row over `size` in `tile_px` squares,
/// [`PRIMARY_TILE_WORDS`] words each: the count, then the GPU instance
/// indices (ascending) whose extents in `bounds` (per GPU instance, over
/// the whole shutter) `clip_from_world` may show in the tile; or
/// [`PRIMARY_TILE_WALK`]. `seen(k)`: instance k can be a primary hit at
/// all (hybrid mode rasterizes meshes).
pub fn primary_tiles(
    bounds: &[impl ScreenBound],
    seen: impl Fn(usize) -> bool,
    clip_from_world: Mat4,
    size: (u32, u32),
    tile_px: u32,
) -> Vec<u32> {
    let tiles = tile_grid(size, tile_px);
    let words = PRIMARY_TILE_WORDS as usize;
    let mut out = vec![0u32; tiles.0 * tiles.1 * words];
    let cones = TileCones::new(clip_from_world, size, tile_px, 0);
    for (k, xs, ys, sphere, polygon) in
        touched_tiles(bounds, seen, clip_from_world, size, tile_px, 0)
    {
        let sphere = cones.sphere(sphere);
        for ty in ys {
            for tx in xs.clone() {
                if !cones.meets(&sphere, tx, ty) || !polygon.meets(&cones, tx, ty) {
                    continue;
                }
                let record = &mut out[(ty * tiles.0 + tx) * words..][..words];
                if record[0] == PRIMARY_TILE_WALK {
                    continue;
                }
                if record[0] == PRIMARY_TILE_MAX {
                    record[0] = PRIMARY_TILE_WALK;
                    continue;
                }
                record[0] += 1;
                record[record[0] as usize] = k as u32;
            }
        }
    }
    out
}

/// The summary of one tile's record (of [`primary_tiles`]) that the flag
/// word after the records keeps above
/// [`TILE_RECORD_SHIFT`](crate::accel::layout::TILE_RECORD_SHIFT): 0 where the
/// record lists no instance, k + 1 where it lists instance k alone, else
/// [`TILE_RECORD_READ`] (more instances, a walk, or an index too large).
pub fn record_summary(record: &[u32]) -> u32 {
    match record[0] {
        0 => 0,
        1 if record[1] < TILE_RECORD_READ - 1 => record[1] + 1,
        _ => TILE_RECORD_READ,
    }
}

/// The tiles of `tile_px` over `size`: across and down.
fn tile_grid(size: (u32, u32), tile_px: u32) -> (usize, usize) {
    (
        size.0.div_ceil(tile_px) as usize,
        size.1.div_ceil(tile_px) as usize,
    )
}

/// For each box k of `bounds` with `pick(k)` that may show on the image
/// (grown by [`BOX_PAD_REL`], projected by `clip_from_world`: [`pixel_rect`]),
/// k, the tiles, across and down, that its rectangle grown by `reach_px`
/// touches, its sphere, if any (grown as the box is), which
/// [`TileCones::meets`] tests those tiles against, and its flat polygon's
/// image ([`ScreenPolygon`]), which [`ScreenPolygon::meets`] tests them against.
fn touched_tiles<'a, B: ScreenBound>(
    bounds: &'a [B],
    pick: impl Fn(usize) -> bool + 'a,
    clip_from_world: Mat4,
    size: (u32, u32),
    tile_px: u32,
    reach_px: u32,
) -> impl Iterator<
    Item = (
        usize,
        RangeInclusive<usize>,
        RangeInclusive<usize>,
        Option<Vec4>,
        ScreenPolygon,
    ),
> + 'a {
    let tiles = tile_grid(size, tile_px);
    let eye = clip_from_world.inverse().project_point3(glam::Vec3::ZERO);
    let reach = reach_px as f32;
    let tile = move |v: f32, n: usize| ((v / tile_px as f32).floor().max(0.0) as usize).min(n - 1);
    bounds
        .iter()
        .enumerate()
        .filter(move |&(k, _)| pick(k))
        .filter_map(move |(k, b)| {
            let (lo, hi) = pixel_rect(&grown_box(b.world_box(), eye), clip_from_world, size)?;
            let xs = tile(lo.x - reach, tiles.0)..=tile(hi.x + reach, tiles.0);
            let ys = tile(lo.y - reach, tiles.1)..=tile(hi.y + reach, tiles.1);
            let sphere = b.world_sphere().map(|s| grown_sphere(s, eye));
            let polygon = ScreenPolygon::new(b, eye, clip_from_world, size);
            Some((k, xs, ys, sphere, polygon))
        })
}

/// The image of an instance's flat polygon
/// ([`ScreenBound::world_outline`]) in pixel points (as [`pixel_rect`]),
/// as the half-planes n . p <= c holding it, grown by [`TILE_PAD_PX`];
/// none (every tile may meet it) without a polygon, or where a point of
/// it lies before the near plane. So that a kernel's hit, off the surface
/// by its f32 rounding, still projects inside, the polygon is first made
/// a flat prism: its points moved by [`BOX_PAD_REL`] of the largest
/// coordinate of it and of the eye, outward from its centre and both
/// ways along its normal. A perspective projection maps the prism's
/// points in front of the eye into the convex hull of its corners'
/// images.
struct ScreenPolygon {
    edges: Vec<(DVec2, f64)>,
}

impl ScreenPolygon {
    fn new(
        b: &impl ScreenBound,
        eye: Vec3,
        clip_from_world: Mat4,
        size: (u32, u32),
    ) -> ScreenPolygon {
        let none = ScreenPolygon { edges: Vec::new() };
        let Some(outline) = b.world_outline() else {
            return none;
        };
        let outline = outline.map(|c| c.as_dvec3());
        let scale = (outline.iter())
            .fold(eye.abs().as_dvec3(), |m, c| m.max(c.abs()))
            .max_element();
        let pad = f64::from(BOX_PAD_REL) * scale;
        let centre = outline.iter().sum::<DVec3>() / outline.len() as f64;
        let normal = (outline[2] - outline[0])
            .cross(outline[4] - outline[0])
            .normalize()
            * pad;
        let clip = clip_from_world.as_dmat4();
        let (w, h) = (f64::from(size.0), f64::from(size.1));
        let mut points = Vec::with_capacity(2 * outline.len());
        for c in outline {
            let out = c + (c - centre).normalize_or_zero() * pad * 2.0;
            for p in [out + normal, out - normal] {
                let q = clip * p.extend(1.0);
                // Before the near plane (NDC z < 0), or not a number.
                if !(q.z >= 0.0 && q.w > 0.0) {
                    return none;
                }
                let ndc = q.truncate().truncate() / q.w;
                points.push(DVec2::new(
                    (ndc.x + 1.0) * 0.5 * w - 0.5,
                    (1.0 - ndc.y) * 0.5 * h - 0.5,
                ));
            }
        }
        ScreenPolygon {
            edges: convex_hull(&mut points)
                .into_iter()
                .map(|(n, c)| (n, c + f64::from(TILE_PAD_PX)))
                .collect(),
        }
    }

    /// Whether tile (tx, ty) of `cones`, grown by their reach, may meet
    /// the image: no edge has the whole grown tile outside it.
    fn meets(&self, cones: &TileCones, tx: usize, ty: usize) -> bool {
        let (lo, hi) = cones.tile_rect(tx, ty, 0.0);
        self.edges.iter().all(|&(n, c)| {
            let x = if n.x > 0.0 { lo.x } else { hi.x };
            let y = if n.y > 0.0 { lo.y } else { hi.y };
            n.x * x + n.y * y <= c
        })
    }
}

/// The convex hull of `points` (Andrew's monotone chain) as its edges'
/// outward unit normals n and offsets c (n . p <= c inside); none where
/// the hull has no area (then no edge rules a tile out).
pub(crate) fn convex_hull(points: &mut [DVec2]) -> Vec<(DVec2, f64)> {
    let hull = hull_vertices(points);
    let area: f64 = (0..hull.len())
        .map(|i| hull[i].perp_dot(hull[(i + 1) % hull.len()]))
        .sum();
    if hull.len() < 3 || area.abs() < 1e-9 {
        return Vec::new();
    }
    // Counter-clockwise (positive area): the inside lies to the left of
    // each edge, so the outward normal is the edge turned clockwise.
    (0..hull.len())
        .filter_map(|i| {
            let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
            let n = DVec2::new(b.y - a.y, a.x - b.x).normalize_or_zero() * area.signum();
            (n != DVec2::ZERO).then(|| (n, n.dot(a)))
        })
        .collect()
}

/// The corners of the convex hull of `points` (Andrew's monotone chain),
/// in order around it.
pub(crate) fn hull_vertices(points: &mut [DVec2]) -> Vec<DVec2> {
    points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<DVec2> = Vec::with_capacity(2 * points.len());
    for &p in points.iter() {
        while hull.len() >= 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
            hull.pop();
        }
        hull.push(p);
    }
    let lower = hull.len() + 1;
    for &p in points.iter().rev().skip(1) {
        while hull.len() >= lower && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
            hull.pop();
        }
        hull.push(p);
    }
    // The last point is the first again.
    hull.pop();
    hull
}

/// The cones of rays through the tiles of one sample's image, for testing
/// bounding spheres against them: each tile's pixel rectangle is grown by
/// the reach asked for and [`TILE_PAD_PX`], as [`touched_tiles`] grows the
/// boxes' rectangles.
///
/// Every primary ray passes through the centre of projection (the eye; a
/// point on the lens in a depth-of-field sample) and its pixel's point on
/// the far plane, whose homogeneous coordinates h are linear in the pixel
/// point. So its direction, (h.xyz - eye h.w) / h.w, is a positive
/// multiple of a linear function of the pixel point wherever h.w > 0 (a
/// perspective projection): the rays pass through the points of one plane
/// that are an affine function of the pixel point. (The far plane itself
/// is that only up to the f32 matrix's rounding, which near planes 1e-4 of
/// the far plane's distance magnify to a relative 2e-4.) A tile's rays lie
/// in the cone from the eye around the ray through the tile's centre whose
/// half-angle reaches the grown rectangle's corners, and that half-angle
/// is at most the rectangle's half-diagonal on that plane over the plane's
/// distance from the eye (radial projection onto the sphere of that
/// radius shortens no path): one bound for every tile, taken 1% wider for
/// the rounding. So a tile is tested with one direction.
struct TileCones {
    /// The eye, then the direction of the ray through pixel point (x, y)
    /// (pixel centres at integers, as [`pixel_rect`]) as a + x b + y c;
    /// `None` where the projection is not a perspective one (then every
    /// tile may meet every sphere).
    rays: Option<(DVec3, [DVec3; 3])>,
    /// A tile's centre pixel point is (t + 0.5) tile_px - 0.5 in x and y.
    tile_px: f64,
    /// The reach the tiles are grown by (pixels).
    reach: f64,
    /// The bound on every tile's half-angle (radians).
    half_angle: f64,
    /// A bound on the angle between the rays of two neighbouring pixels
    /// (radians): a pixel's step on the plane over the plane's distance,
    /// 1% wider as `half_angle`.
    pixel_angle: f64,
}

/// A corner ray of a tile where it meets a plane
/// ([`TileCones::corner_plane_hits`]): the ray's world direction `v` from
/// the eye, its parameter `t` there, and the hit `eye + v t` in the world
/// and in the plane's object space.
#[derive(Clone, Copy, Default)]
struct CornerHit {
    v: DVec3,
    t: f64,
    world: DVec3,
    object: DVec3,
}

impl CornerHit {
    /// Whether the ray meets the plane in front of the eye.
    fn ahead(&self) -> bool {
        self.t > 0.0 && self.t.is_finite()
    }
}

/// A bounding sphere as [`TileCones::meets`] tests it: the unit direction
/// from the eye to its centre, and the cosine of the largest angle a
/// tile's axis may make with it and still have its cone meet the sphere.
struct SphereCone {
    to_centre: DVec3,
    cos_reach: f64,
}

impl TileCones {
    fn new(clip_from_world: Mat4, size: (u32, u32), tile_px: u32, reach_px: u32) -> TileCones {
        let world_from_clip = clip_from_world.as_dmat4().inverse();
        let (w, h) = (f64::from(size.0), f64::from(size.1));
        // The far-plane point of pixel point (x, y): NDC ((x + 0.5) / w * 2
        // - 1, 1 - (y + 0.5) / h * 2, 1), linear in x and y.
        let h0 = world_from_clip * DVec4::new(1.0 / w - 1.0, 1.0 - 1.0 / h, 1.0, 1.0);
        let hx = world_from_clip * DVec4::new(2.0 / w, 0.0, 0.0, 0.0);
        let hy = world_from_clip * DVec4::new(0.0, -2.0 / h, 0.0, 0.0);
        // The centre of projection maps to clip x = y = w = 0.
        let centre = world_from_clip * DVec4::Z;
        let eye = centre.truncate() / centre.w;
        // h.w at the image's corners: positive there, positive over it.
        let ahead = [h0, h0 + w * hx, h0 + h * hy, h0 + w * hx + h * hy]
            .iter()
            .all(|c| c.w > 0.0);
        let direction = |h: DVec4| h.truncate() - eye * h.w;
        let (a, b, c) = (direction(h0), direction(hx), direction(hy));
        let span = f64::from(tile_px) - 1.0 + 2.0 * (f64::from(reach_px) + f64::from(TILE_PAD_PX));
        let distance = a.dot(b.cross(c).normalize()).abs();
        let half_diagonal = 0.5 * span * (b + c).length().max((b - c).length());
        let half_angle = 1.01 * half_diagonal / distance;
        let perspective = ahead && eye.is_finite() && half_angle.is_finite();
        TileCones {
            rays: perspective.then_some((eye, [a, b, c])),
            tile_px: f64::from(tile_px),
            reach: f64::from(reach_px),
            half_angle,
            pixel_angle: 1.01 * b.length().max(c.length()) / distance,
        }
    }

    /// The pixel points of tile (tx, ty), grown by the reach and `pad`:
    /// the lowest and highest.
    fn tile_rect(&self, tx: usize, ty: usize, pad: f64) -> (DVec2, DVec2) {
        let grow = self.reach + pad;
        let lo = DVec2::new(tx as f64, ty as f64) * self.tile_px - grow;
        (lo, lo + (self.tile_px - 1.0 + 2.0 * grow))
    }

    /// The unit axis of tile (tx, ty)'s cone, from the eye.
    fn axis(&self, tx: usize, ty: usize) -> Option<DVec3> {
        let (x, y) = (
            (tx as f64 + 0.5) * self.tile_px - 0.5,
            (ty as f64 + 0.5) * self.tile_px - 0.5,
        );
        Some(self.ray(x, y)?.normalize())
    }

    /// The sine and cosine of the largest angle that a ray of the cone
    /// around `axis` (a tile's, [`TileCones::axis`]) may make with the
    /// unit direction `to`: the axis' angle grown by the half-angle.
    fn widest(&self, axis: DVec3, to: DVec3) -> (f64, f64) {
        let (sin_h, cos_h) = self.half_angle.sin_cos();
        let cos = axis.dot(to).clamp(-1.0, 1.0);
        let sin = (1.0 - cos * cos).sqrt();
        (sin * cos_h + cos * sin_h, cos * cos_h - sin * sin_h)
    }

    /// The direction (not unit) of the ray through pixel point (x, y).
    fn ray(&self, x: f64, y: f64) -> Option<DVec3> {
        let (_, [a, b, c]) = self.rays?;
        Some(a + x * b + y * c)
    }

    /// Where the four corner rays of pixel rectangle `(lo, hi)` (a tile's
    /// or a block's, [`TileCones::tile_rect`]) meet the plane y = 0 of the
    /// object space that `m` maps the world to (`o`: the eye there);
    /// `None` without rays. A hit is in front of the eye only where its
    /// `t` is positive and finite.
    fn corner_plane_hits(
        &self,
        (lo, hi): (DVec2, DVec2),
        m: &DMat4,
        o: DVec3,
    ) -> Option<[CornerHit; 4]> {
        let (eye, _) = self.rays?;
        let corners = [(lo.x, lo.y), (hi.x, lo.y), (lo.x, hi.y), (hi.x, hi.y)];
        let mut hits = [CornerHit::default(); 4];
        for (&(x, y), hit) in corners.iter().zip(&mut hits) {
            let v = self.ray(x, y)?;
            let dv = m.transform_vector3(v);
            let t = -o.y / dv.y;
            *hit = CornerHit {
                v,
                t,
                world: eye + v * t,
                object: o + dv * t,
            };
        }
        Some(hits)
    }

    /// `sphere` (centre xyz, radius w) as [`TileCones::meets`] tests it;
    /// `None` where every tile may meet it (no sphere, the eye inside it,
    /// or cones so wide that the test would keep little).
    fn sphere(&self, sphere: Option<Vec4>) -> Option<SphereCone> {
        let ((eye, _), sphere) = (self.rays?, sphere?);
        let to_centre = sphere.truncate().as_dvec3() - eye;
        let (distance, radius) = (to_centre.length(), f64::from(sphere.w));
        if distance <= radius {
            return None;
        }
        let reach = self.half_angle + (radius / distance).asin();
        (reach < std::f64::consts::FRAC_PI_2).then(|| SphereCone {
            to_centre: to_centre / distance,
            cos_reach: reach.cos(),
        })
    }

    /// Whether a ray through tile (tx, ty), grown, may meet `sphere`: the
    /// angle between the tile's axis and the sphere's centre is at most
    /// the half-angle plus the sphere's angular radius.
    fn meets(&self, sphere: &Option<SphereCone>, tx: usize, ty: usize) -> bool {
        let (Some(s), Some(axis)) = (sphere, self.axis(tx, ty)) else {
            return true;
        };
        axis.dot(s.to_centre) >= s.cos_reach
    }
}

/// Per tile of `tile_px` over `size`, row by row: 1 where an instance k
/// with `pick(k)` may show within `reach_px` pixels (in x and in y) of
/// the tile, else 0. The same rectangles as [`primary_tiles`]' (hybrid
/// mode's rasterized meshes and the raster pass's triangles lie inside
/// the same boxes), without the lists' length limit. Two uses:
/// - the outline marks (`shaders/outline_tiles.wgsl`) look for a *source*
///   texel (an instance whose outline reaches other pixels) in each tile
///   and its halo of the outline radius; where no source is in reach they
///   skip the tile without reading it;
/// - in hybrid mode the trace pass reads the raster G-buffer only in the
///   tiles where a (rasterized) mesh may show, `reach_px` 0.
pub fn reached_tiles(
    bounds: &[impl ScreenBound],
    pick: impl Fn(usize) -> bool,
    clip_from_world: Mat4,
    size: (u32, u32),
    tile_px: u32,
    reach_px: u32,
) -> Vec<u32> {
    let tiles = tile_grid(size, tile_px);
    let mut out = vec![0u32; tiles.0 * tiles.1];
    let cones = TileCones::new(clip_from_world, size, tile_px, reach_px);
    for (_, xs, ys, sphere, polygon) in
        touched_tiles(bounds, pick, clip_from_world, size, tile_px, reach_px)
    {
        let sphere = cones.sphere(sphere);
        for ty in ys {
            if sphere.is_none() && polygon.edges.is_empty() {
                out[ty * tiles.0 + xs.start()..=ty * tiles.0 + xs.end()].fill(1);
                continue;
            }
            for tx in xs.clone() {
                if cones.meets(&sphere, tx, ty) && polygon.meets(&cones, tx, ty) {
                    out[ty * tiles.0 + tx] = 1;
                }
            }
        }
    }
    out
}

/// How many (sphere or plane, other instance) pairs
/// [`smooth_sphere_tiles`] and [`smooth_plane_tiles`] each look at per
/// sample, at most: about a millisecond of the CPU's time.
pub const SMOOTH_PAIRS: usize = 1 << 16;

/// How many instances that may come first in its tiles
/// [`smooth_plane_tiles`] tests a plane's tile against one by one (the
/// tile's own hits beyond a face of each one's box); with more, the
/// tiles they reach are not claimed.
pub const SMOOTH_PLANE_BLOCKERS: usize = 16;

/// An instance that is exactly a sphere in the world: a static sphere
/// shape under a similarity (rotation, uniform scale, translation), so
/// the kernels' hits are those of this sphere. For [`smooth_sphere_tiles`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExactSphere {
    /// Its index among the footprints (the GPU instance index).
    pub instance: usize,
    pub centre: Vec3,
    pub radius: f32,
}

/// How far the normal and the view depth may move between the primary
/// hits of two neighbouring pixels for the outline marks' proof
/// (`shaders/lib/outline.wgsl`, `smooth_step_bounds`): the log of the
/// depth factor, and the angle (radians).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothSteps {
    pub ln_depth: f64,
    pub angle: f64,
}

impl SmoothSteps {
    /// The marks' bounds for an outline search of radius `r`: paths of L =
    /// 2 max(r, 1) steps, view depths within 1 - 0.8 [`DEPTH_JUMP`] end to
    /// end and normals within 54 degrees, shared out evenly over the steps.
    pub fn for_radius(r: u32) -> SmoothSteps {
        let steps = f64::from(2 * r.max(1));
        SmoothSteps {
            ln_depth: -(1.0 - 0.8 * f64::from(DEPTH_JUMP)).ln() / steps,
            angle: 54f64.to_radians() / steps,
        }
    }
}

/// Per tile of `tile_px` over `size`, row by row: true where the CPU
/// proves what the outline marks would prove texel by texel, that the
/// tile and its halo of `reach_px` pixels are the smooth inside of one
/// sphere of `spheres`, with half of `steps` to spare for the kernels'
/// rounding. Then no pixel of the tile can take an outline, and the marks
/// need not read it.
///
/// For the sample's projection `clip_from_world` (eye e, view direction
/// `forward`) and a sphere of centre c and radius R at distance D from
/// the eye, a ray at angle a from the direction u to the centre meets it
/// where sin a <= R / D, at incidence i with sin i = (D / R) sin a, at
/// distance t = D cos a - R cos i >= D - R. Let a tile's cone (its rays
/// and its halo's, as [`TileCones`] bounds them) reach out to a_max from
/// u, with i_max its incidence, and let the rays of two neighbouring
/// pixels be at most d apart (`TileCones::pixel_angle`). Then, within the
/// cone:
/// - every ray meets the sphere when sin a_max < R / D, and nothing else
///   comes first where no other instance's rectangle reaches the tile
///   and its halo, unless that instance lies wholly beyond the plane of
///   the sphere's silhouette seen from the eye (u . (x - e) >
///   (D^2 - R^2) / D, where no front hit lies) or beyond one face of its
///   own box from both the eye and the sphere's visible cap (a floor
///   under a ball resting on it);
/// - the normal turns by at most (1 + S) d between neighbours, S = D /
///   (R cos i_max): along u's great circles the normal's angle is a + i,
///   whose derivative is 1 + D cos a / (R cos i); around u it turns by
///   sin(a + i) / sin a <= cos i + D cos a / R per unit of angle;
/// - the view depth t (v . f), v the ray's unit direction, changes its
///   log by at most d (D sin a_max (S - 1) / (D - R) + tan f_max): dt /
///   da = D sin a (D cos a / (R cos i) - 1), which is not negative, and
///   f_max is the cone's largest angle with `forward`.
///
/// A sphere seen from inside or cut by the near plane (where the
/// kernel's rays start), a cone too wide, or a projection that is not a
/// perspective one proves nothing.
#[allow(clippy::too_many_arguments)]
pub fn smooth_sphere_tiles(
    bounds: &[impl ScreenBound],
    spheres: &[ExactSphere],
    forward: Vec3,
    clip_from_world: Mat4,
    size: (u32, u32),
    tile_px: u32,
    reach_px: u32,
    steps: SmoothSteps,
) -> Vec<bool> {
    let tiles = tile_grid(size, tile_px);
    let mut out = vec![false; tiles.0 * tiles.1];
    let cones = TileCones::new(clip_from_world, size, tile_px, reach_px);
    let Some((eye, _)) = cones.rays else {
        return out;
    };
    let forward = forward.as_dvec3().normalize();
    // A sphere the near plane cuts shows its inside through the hole.
    let near = near_depth(clip_from_world, eye, forward);
    let d = cones.pixel_angle;
    // Per tile, the last sphere (index into `spheres`) for which some
    // other instance may come first there.
    let mut blocked = vec![usize::MAX; out.len()];
    let mut budget = SMOOTH_PAIRS;
    for (n, s) in spheres.iter().enumerate() {
        let c = s.centre.as_dvec3();
        let radius = f64::from(s.radius);
        let to_centre = c - eye;
        let distance = to_centre.length();
        let nearest = to_centre.dot(forward) - radius;
        let cut = nearest.is_nan() || nearest <= near * 1.001;
        if distance.is_nan() || distance <= radius * 1.001 || cut {
            continue;
        }
        // A disc too small to hold a tile and its halo proves nothing, and
        // each sphere tried costs a look at every other instance.
        let across = (radius / distance).asin() / d;
        if across < f64::from(tile_px + 2 * reach_px) || budget < bounds.len() {
            continue;
        }
        budget -= bounds.len();
        let u = to_centre / distance;
        let silhouette = (distance * distance - radius * radius) / distance;
        // The visible cap's extent along each axis: its rim (the
        // silhouette circle, centre c - (R^2 / D) u, radius R sqrt(1 -
        // R^2 / D^2), across u) or, where the sphere's extreme point that
        // way faces the eye (u_a >= R / D), that point.
        let rim = radius * (1.0 - (radius / distance).powi(2)).sqrt();
        let rim_centre = c - u * (radius * radius / distance);
        let cap_extent = |a: usize| {
            let across = rim * (1.0 - u[a] * u[a]).max(0.0).sqrt();
            let low = if u[a] >= radius / distance {
                c[a] - radius
            } else {
                rim_centre[a] - across
            };
            let high = if -u[a] >= radius / distance {
                c[a] + radius
            } else {
                rim_centre[a] + across
            };
            (low, high)
        };
        let caps: [(f64, f64); 3] = std::array::from_fn(cap_extent);
        // The other instances that may come before the sphere somewhere.
        let in_way = |j: usize| {
            let b = grown_box(bounds[j].world_box(), eye.as_vec3());
            let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
            let beyond = b
                .corners()
                .iter()
                .all(|p| u.dot(p.as_dvec3() - eye) > silhouette);
            let apart = (0..3).any(|a| {
                (eye[a] > hi[a] && caps[a].0 > hi[a]) || (eye[a] < lo[a] && caps[a].1 < lo[a])
            });
            j != s.instance && !(beyond || apart)
        };
        for (_, xs, ys, _, _) in
            touched_tiles(bounds, in_way, clip_from_world, size, tile_px, reach_px)
        {
            for ty in ys {
                blocked[ty * tiles.0 + xs.start()..=ty * tiles.0 + xs.end()].fill(n);
            }
        }
        let Some((_, xs, ys, _, _)) = touched_tiles(
            bounds,
            |j| j == s.instance,
            clip_from_world,
            size,
            tile_px,
            reach_px,
        )
        .next() else {
            continue;
        };
        for ty in ys {
            for tx in xs.clone() {
                if blocked[ty * tiles.0 + tx] == n {
                    continue;
                }
                let Some(axis) = cones.axis(tx, ty) else {
                    continue;
                };
                let (sin_a, cos_a) = cones.widest(axis, u);
                let (sin_f, cos_f) = cones.widest(axis, forward);
                let sin_i = distance / radius * sin_a;
                if cos_a <= 0.0 || sin_i >= 1.0 || cos_f <= 0.05 {
                    continue;
                }
                let slant = distance / (radius * (1.0 - sin_i * sin_i).sqrt());
                let turn = (1.0 + slant) * d;
                let depth =
                    d * (distance * sin_a * (slant - 1.0) / (distance - radius) + sin_f / cos_f);
                if turn <= 0.5 * steps.angle && depth <= 0.5 * steps.ln_depth {
                    out[ty * tiles.0 + tx] = true;
                }
            }
        }
    }
    out
}

/// The view depth of the near plane (NDC z 0, a plane of constant view
/// depth), where the kernel's primary rays start, for the eye `eye` and
/// unit view direction `forward` of `clip_from_world`.
fn near_depth(clip_from_world: Mat4, eye: DVec3, forward: DVec3) -> f64 {
    let p = clip_from_world.as_dmat4().inverse() * DVec4::W;
    (p.truncate() / p.w - eye).dot(forward)
}

/// A flat quad or disk of an instance in the world: a static plane shape
/// (`SHAPE_QUAD`, `SHAPE_DISK`) or a face of a static box, under the
/// instance's matrix, any invertible affine one. The kernels meet it
/// where a ray, taken by `object_from_world` into the frame where the
/// plane is y = 0, crosses y = 0 inside the outline, so all its hits lie
/// on one world plane with one normal. For [`smooth_plane_tiles`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExactPlane {
    /// Its index among the footprints (the GPU instance index).
    pub instance: usize,
    pub object_from_world: Mat4,
    /// A quad's half sizes in x and z, or a disk's radius in both.
    pub half: Vec2,
    pub disk: bool,
    /// A face of a box, its outside at y > 0: seen only from there, where
    /// a ray meeting it inside its outline enters the box through it, so
    /// that the box's other faces cannot come first.
    pub face: bool,
}

/// Per tile of `tile_px` over `size`, row by row: true where the CPU
/// proves what the outline marks would prove texel by texel, that the
/// tile and its halo of `reach_px` pixels are the smooth inside of one
/// plane of `planes` (a quad, a disk or a box's face), with half of
/// `steps` to spare for the kernels' rounding, as [`smooth_sphere_tiles`]
/// does for spheres.
///
/// The rays of a tile and its halo pass through the eye and the far-plane
/// points of its pixel rectangle grown by the reach and [`TILE_PAD_PX`].
/// The far plane is an affine image of the pixel rectangle, so each ray
/// is a positive combination of the four corners' rays. Where those four
/// meet the plane in front of the eye, beyond the near plane (where the
/// kernel's rays start) and inside the quad or disk (both convex), every
/// ray of the tile does: seen from the eye, the far rectangle projects
/// onto the convex hull of the four hits. Nothing comes first where no
/// other instance's rectangle reaches the tile, unless that instance's
/// box lies wholly on the far side of the plane from the eye, or beyond
/// one face of its own box from both the eye and the four hits (every
/// segment from the eye to a hit of the tile then stays on the near side
/// of that face: a box resting on a floor, seen from above). Planes are
/// tried in order until [`SMOOTH_PAIRS`] is spent.
///
/// Then, with n the plane's unit normal facing away from the eye, h the
/// eye's distance to the plane and v a ray's unit direction, the hit's
/// view depth is z = h (v . f) / (v . n). The normal never turns, and ln
/// z changes between two neighbouring pixels (rays at most d apart,
/// `TileCones::pixel_angle`) by at most d (tan f_max + tan g_max): v .
/// w changes its log by at most tan(angle(v, w)) per radian that v turns,
/// and f_max and g_max are the cone's largest angles with `forward` and
/// with n. A grazing view (g_max near 90 degrees, the horizon) proves
/// nothing, as the marks would find the depth's steps too long there.
#[allow(clippy::too_many_arguments)]
pub fn smooth_plane_tiles(
    bounds: &[impl ScreenBound],
    planes: &[ExactPlane],
    forward: Vec3,
    clip_from_world: Mat4,
    size: (u32, u32),
    tile_px: u32,
    reach_px: u32,
    steps: SmoothSteps,
) -> Vec<bool> {
    let tiles = tile_grid(size, tile_px);
    let mut out = vec![false; tiles.0 * tiles.1];
    let cones = TileCones::new(clip_from_world, size, tile_px, reach_px);
    let Some((eye, _)) = cones.rays else {
        return out;
    };
    let forward = forward.as_dvec3().normalize();
    let near = near_depth(clip_from_world, eye, forward);
    // Per tile, the last plane (index into `planes`) for which some other
    // instance may come first there.
    let mut blocked = vec![usize::MAX; out.len()];
    let mut budget = SMOOTH_PAIRS;
    for (n, plane) in planes.iter().enumerate() {
        // Each plane tried costs a look at every other instance.
        if budget < bounds.len() {
            break;
        }
        budget -= bounds.len();
        let m = plane.object_from_world.as_dmat4();
        // The eye in object space, and the plane's normal in the world:
        // the gradient of the object-space y, facing away from the eye.
        let o = m.transform_point3(eye);
        let gradient = DVec3::new(m.x_axis.y, m.y_axis.y, m.z_axis.y);
        let normal = -o.y.signum() * gradient.normalize();
        let behind = plane.face && o.y < 0.0;
        if !normal.is_finite() || o.y.abs() <= 1e-6 * o.abs().max_element() || behind {
            continue;
        }
        // The outline, shrunk by a relative 1e-5 for the kernels' f32
        // rounding of the object-space hit.
        let half = plane.half.as_dvec2() * (1.0 - 1e-5);
        let inside = |q: DVec3| {
            if plane.disk {
                q.x * q.x + q.z * q.z <= half.x * half.x
            } else {
                q.x.abs() <= half.x && q.z.abs() <= half.y
            }
        };
        // Another instance cannot come first where its box lies wholly on
        // the plane's far side from the eye; nor in a tile where the eye
        // and the tile's hits lie beyond one face of its box (a floor
        // under a wall standing on it), tested tile by tile below.
        let beyond = |j: usize| {
            let b = grown_box(bounds[j].world_box(), eye.as_vec3());
            (b.corners().iter()).all(|c| m.transform_point3(c.as_dvec3()).y * o.y < 0.0)
        };
        let in_way = |j: usize| j != plane.instance && !beyond(j);
        let mut blockers = Vec::new();
        for (j, xs, ys, _, _) in
            touched_tiles(bounds, in_way, clip_from_world, size, tile_px, reach_px)
        {
            for ty in ys.clone() {
                blocked[ty * tiles.0 + xs.start()..=ty * tiles.0 + xs.end()].fill(n);
            }
            let b = grown_box(bounds[j].world_box(), eye.as_vec3());
            blockers.push((xs, ys, b.min.as_dvec3(), b.max.as_dvec3()));
        }
        // Whether no instance may come first on the way to `hits` (the
        // tile's corner hits, around every hit of its rays): each one
        // whose rectangle reaches tile (tx, ty) lies beyond a face of its
        // box from the eye and all of them, so every segment from the eye
        // to a hit of the tile stays on this side of that face.
        let clear = |tx: usize, ty: usize, hits: &[DVec3; 4]| {
            if blocked[ty * tiles.0 + tx] != n {
                return true;
            }
            blockers.len() <= SMOOTH_PLANE_BLOCKERS
                && blockers.iter().all(|(xs, ys, lo, hi)| {
                    !(xs.contains(&tx) && ys.contains(&ty))
                        || (0..3).any(|a| {
                            (eye[a] > hi[a] && hits.iter().all(|h| h[a] > hi[a]))
                                || (eye[a] < lo[a] && hits.iter().all(|h| h[a] < lo[a]))
                        })
                })
        };
        let Some((_, xs, ys, _, _)) = touched_tiles(
            bounds,
            |j| j == plane.instance,
            clip_from_world,
            size,
            tile_px,
            reach_px,
        )
        .next() else {
            continue;
        };
        for ty in ys {
            for tx in xs.clone() {
                // The tile's rays, as its cone's (its rectangle grown by
                // the reach and the padding), where they meet the plane
                // inside its outline beyond the near plane.
                let rect = cones.tile_rect(tx, ty, f64::from(TILE_PAD_PX));
                let Some(corner_hits) = cones.corner_plane_hits(rect, &m, o) else {
                    continue;
                };
                let meets_inside = corner_hits.iter().all(|h| {
                    h.ahead() && inside(h.object) && (h.v * h.t).dot(forward) > near * 1.001
                });
                let hits = corner_hits.map(|h| h.world);
                let claimable = meets_inside && clear(tx, ty, &hits);
                let Some(axis) = cones.axis(tx, ty).filter(|_| claimable) else {
                    continue;
                };
                let (sin_f, cos_f) = cones.widest(axis, forward);
                let (sin_g, cos_g) = cones.widest(axis, normal);
                if cos_f <= 0.05 || cos_g <= 0.05 {
                    continue;
                }
                let depth = cones.pixel_angle * (sin_f / cos_f + sin_g / cos_g);
                if depth <= 0.5 * steps.ln_depth {
                    out[ty * tiles.0 + tx] = true;
                }
            }
        }
    }
    out
}

/// Per tile of `tile_px` over `size`, row by row: true where `culled`
/// holds for a region around every point at which a primary ray of the
/// tile (its rectangle grown by [`TILE_PAD_PX`] for the jitter) meets
/// `plane`'s infinite plane, moved `offset` along its unit normal towards
/// the eye (where the kernel starts its shadow rays: the hit's normal
/// faces the ray). The tiles are taken in square groups of `group` x
/// `group`, one region a group: the convex hull of the points where the
/// group's four corner rays meet the plane, each moved from half to twice
/// `offset`, and farther either way by a bound on the kernel's f32
/// rounding of its hit (1e-6 of the eye's and the hit's coordinates,
/// about 16 units in the last place): a hit whose rounding may reach the
/// plane's other side is not proven. Where those four meet
/// it in front of the eye, every ray between them does (a positive
/// combination of them, in the same half of directions), inside that
/// hull; where one does not, the group's tiles are false.
pub fn plane_region_tiles(
    plane: &ExactPlane,
    clip_from_world: Mat4,
    size: (u32, u32),
    tile_px: u32,
    group: u32,
    offset: f64,
    culled: impl Fn(&[Vec3]) -> bool,
) -> Vec<bool> {
    let tiles = tile_grid(size, tile_px);
    let mut out = vec![false; tiles.0 * tiles.1];
    let cones = TileCones::new(clip_from_world, size, tile_px, 0);
    let Some((eye, _)) = cones.rays else {
        return out;
    };
    let m = plane.object_from_world.as_dmat4();
    let o = m.transform_point3(eye);
    // The world normal on the eye's side: the gradient of the
    // object-space height, signed as the eye's.
    let normal = o.y.signum() * DVec3::new(m.x_axis.y, m.y_axis.y, m.z_axis.y).normalize();
    if !normal.is_finite() || o.y == 0.0 {
        return out;
    }
    let group = group as usize;
    for gy in (0..tiles.1).step_by(group) {
        for gx in (0..tiles.0).step_by(group) {
            // The group's rectangle, from its first tile's to its last's.
            let pad = f64::from(TILE_PAD_PX);
            let last = (gx + group - 1, gy + group - 1);
            let rect = (
                cones.tile_rect(gx, gy, pad).0,
                cones.tile_rect(last.0, last.1, pad).1,
            );
            let Some(hits) = cones.corner_plane_hits(rect, &m, o) else {
                return out;
            };
            let mut points = [Vec3::ZERO; 8];
            for (k, h) in hits.iter().enumerate() {
                let rounding = 1e-6 * (eye.abs().element_sum() + h.world.abs().element_sum());
                points[2 * k] = (h.world + normal * (0.5 * offset - rounding)).as_vec3();
                points[2 * k + 1] = (h.world + normal * (2.0 * offset + rounding)).as_vec3();
            }
            if !hits.iter().all(CornerHit::ahead) || !culled(&points) {
                continue;
            }
            for ty in gy..(gy + group).min(tiles.1) {
                out[ty * tiles.0 + gx..ty * tiles.0 + (gx + group).min(tiles.0)].fill(true);
            }
        }
    }
    out
}

/// Sphere `s` (centre xyz, radius w) grown by [`BOX_PAD_REL`] of its
/// box's and the eye's largest coordinate, as [`grown_box`] grows boxes.
fn grown_sphere(s: Vec4, eye: Vec3) -> Vec4 {
    let far = s.truncate().abs() + Vec3::splat(s.w);
    let scale = far.max(eye.abs()).max_element();
    s + Vec4::W * BOX_PAD_REL * scale
}

/// Box `b` grown by [`BOX_PAD_REL`] of its and the eye's largest
/// coordinate.
fn grown_box(b: &Aabb, eye: glam::Vec3) -> Aabb {
    let scale = b.min.abs().max(b.max.abs()).max(eye.abs()).max_element();
    Aabb {
        min: b.min - BOX_PAD_REL * scale,
        max: b.max + BOX_PAD_REL * scale,
    }
}

/// The pixel rectangle (pixel centres at integer coordinates, as the
/// kernel numbers them: x right, y down) that box `b` may cover, grown by
/// [`TILE_PAD_PX`]; the whole image where a corner is not in front of the
/// eye, `None` where all are behind it (a primary ray meets only points in
/// front of the near plane) or it is off the image.
fn pixel_rect(b: &Aabb, clip_from_world: Mat4, size: (u32, u32)) -> Option<(Vec2, Vec2)> {
    let (w, h) = (size.0 as f32, size.1 as f32);
    let whole = (Vec2::splat(0.0), Vec2::new(w - 1.0, h - 1.0));
    let clips = b.corners().map(|c| clip_from_world * c.extend(1.0));
    // Wholly behind the eye: no ray that leaves the near plane meets it.
    if clips.iter().all(|c| c.w <= 0.0) {
        return None;
    }
    let mut lo = Vec2::splat(f32::INFINITY);
    let mut hi = Vec2::splat(f32::NEG_INFINITY);
    for clip in clips {
        if clip.w <= 0.0 || !clip.is_finite() {
            return Some(whole);
        }
        let ndc = Vec2::new(clip.x, clip.y) / clip.w;
        // The kernel's pixel centre x + 0.5 maps to ndc (x + 0.5) / w * 2 - 1.
        let p = Vec2::new((ndc.x + 1.0) * 0.5 * w - 0.5, (1.0 - ndc.y) * 0.5 * h - 0.5);
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let (lo, hi) = (lo - TILE_PAD_PX, hi + TILE_PAD_PX);
    if hi.x < 0.0 || hi.y < 0.0 || lo.x > w - 1.0 || lo.y > h - 1.0 {
        return None;
    }
    Some((lo, hi))
}

/// Tile `t`'s instances, or `None` where it walks: the CPU twin of the
/// kernel's reading of the records.
pub fn tile_list(tiles: &[u32], t: usize) -> Option<&[u32]> {
    let record = &tiles[t * PRIMARY_TILE_WORDS as usize..][..PRIMARY_TILE_WORDS as usize];
    (record[0] != PRIMARY_TILE_WALK).then(|| &record[1..=record[0] as usize])
}
