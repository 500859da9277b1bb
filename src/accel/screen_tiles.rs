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

use std::ops::RangeInclusive;

use glam::{Mat4, Vec2};

use crate::accel::bvh::Aabb;
use crate::accel::layout::{PRIMARY_TILE_MAX, PRIMARY_TILE_WALK, PRIMARY_TILE_WORDS};

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

/// The tiles' records, row by row over `size` in `tile_px` squares,
/// [`PRIMARY_TILE_WORDS`] words each: the count, then the GPU instance
/// indices (ascending) whose boxes in `bounds` (per GPU instance, over
/// the whole shutter) `clip_from_world` may show in the tile; or
/// [`PRIMARY_TILE_WALK`]. `seen(k)`: instance k can be a primary hit at
/// all (hybrid mode rasterizes meshes).
pub fn primary_tiles(
    bounds: &[Aabb],
    seen: impl Fn(usize) -> bool,
    clip_from_world: Mat4,
    size: (u32, u32),
    tile_px: u32,
) -> Vec<u32> {
    let tiles = tile_grid(size, tile_px);
    let words = PRIMARY_TILE_WORDS as usize;
    let mut out = vec![0u32; tiles.0 * tiles.1 * words];
    for (k, xs, ys) in touched_tiles(bounds, seen, clip_from_world, size, tile_px, 0) {
        for ty in ys {
            for tx in xs.clone() {
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

/// The tiles of `tile_px` over `size`: across and down.
fn tile_grid(size: (u32, u32), tile_px: u32) -> (usize, usize) {
    (
        size.0.div_ceil(tile_px) as usize,
        size.1.div_ceil(tile_px) as usize,
    )
}

/// For each box k of `bounds` with `pick(k)` that may show on the image
/// (grown by [`BOX_PAD_REL`], projected by `clip_from_world`: [`pixel_rect`]),
/// k and the tiles, across and down, that its rectangle grown by
/// `reach_px` touches.
fn touched_tiles<'a>(
    bounds: &'a [Aabb],
    pick: impl Fn(usize) -> bool + 'a,
    clip_from_world: Mat4,
    size: (u32, u32),
    tile_px: u32,
    reach_px: u32,
) -> impl Iterator<Item = (usize, RangeInclusive<usize>, RangeInclusive<usize>)> + 'a {
    let tiles = tile_grid(size, tile_px);
    let eye = clip_from_world.inverse().project_point3(glam::Vec3::ZERO);
    let reach = reach_px as f32;
    let tile = move |v: f32, n: usize| ((v / tile_px as f32).floor().max(0.0) as usize).min(n - 1);
    bounds
        .iter()
        .enumerate()
        .filter(move |&(k, _)| pick(k))
        .filter_map(move |(k, b)| {
            let (lo, hi) = pixel_rect(&grown_box(b, eye), clip_from_world, size)?;
            let xs = tile(lo.x - reach, tiles.0)..=tile(hi.x + reach, tiles.0);
            let ys = tile(lo.y - reach, tiles.1)..=tile(hi.y + reach, tiles.1);
            Some((k, xs, ys))
        })
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
    bounds: &[Aabb],
    pick: impl Fn(usize) -> bool,
    clip_from_world: Mat4,
    size: (u32, u32),
    tile_px: u32,
    reach_px: u32,
) -> Vec<u32> {
    let tiles = tile_grid(size, tile_px);
    let mut out = vec![0u32; tiles.0 * tiles.1];
    for (_, xs, ys) in touched_tiles(bounds, pick, clip_from_world, size, tile_px, reach_px) {
        for ty in ys {
            out[ty * tiles.0 + xs.start()..=ty * tiles.0 + xs.end()].fill(1);
        }
    }
    out
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
