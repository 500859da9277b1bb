//! Shadow rays that cannot meet anything, found before they are cast.
//!
//! A shadow ray towards a directional light runs from a surface point o
//! along the light's direction l. It can only meet an instance whose world
//! box it crosses, and a ray along l crosses a box only where o, projected
//! along l onto a plane across it, falls inside the box's projection. So
//! per directional light the occluders' boxes are projected onto two axes
//! (u, v) across l, and a grid of up to [`SHADOW_CULL_CELLS`]^2 cells over
//! those projections marks, one bit per cell, where any box lands. A ray
//! whose origin projects onto an empty cell, or off the grid, meets none of
//! them.
//!
//! Flat floors and walls would cover the whole grid, so static quads and
//! disks (up to [`MAX_CULL_PLANES`], the largest first) are kept out of it
//! and tested exactly: the intersection test finds t = -o.y / d.y in the
//! plane's object space, so a ray whose object-space start height o.y and
//! direction d.y have the same sign (it starts on the plane's side that l
//! points away from, as on a lit floor) never reaches the plane.
//!
//! Every margin errs towards casting the ray: the skipped rays are exactly
//! rays that would have found nothing, so images do not change. Why it
//! matters: on the CPU driver, 8 neighbouring pixels run as one SIMD
//! program, and the traversal runs whenever one of them casts a ray; most
//! of a lit floor's pixels now cast none (docs/performance.md).

use glam::{Vec2, Vec3, Vec4Swizzles};

use crate::accel::bvh::Aabb;
use crate::accel::layout::{
    GpuShadowCull, MAX_CULL_PLANES, SHADOW_CULL_CELLS, SHADOW_CULL_WORDS, SHAPE_DISK, SHAPE_QUAD,
};
use crate::accel::SceneAccel;
use crate::scene::Light;

/// Relative margin of the plane test: a sum of four f32 products is within
/// about 4 ulp (2.4e-7) of its sum of magnitudes; 1e-5 is 40 times that.
pub const PLANE_MARGIN: f32 = 1e-5;

/// What the trace pass reads: one [`GpuShadowCull`] per light (at least
/// one) and [`SHADOW_CULL_WORDS`] words of cell bits per light.
#[derive(Debug, Clone, PartialEq)]
pub struct ShadowCull {
    pub lights: Vec<GpuShadowCull>,
    pub cells: Vec<u32>,
}

/// The cull data of `lights` over the instances of `accel`.
pub fn build(accel: &SceneAccel, lights: &[Light]) -> ShadowCull {
    let count = lights.len().max(1);
    let mut out = ShadowCull {
        lights: vec![bytemuck::Zeroable::zeroed(); count],
        cells: vec![0; count * SHADOW_CULL_WORDS as usize],
    };
    let (planes, boxes) = split_occluders(accel);
    for (i, light) in lights.iter().enumerate() {
        if let Light::Directional {
            direction,
            cast_shadows: true,
            ..
        } = light
        {
            let words =
                &mut out.cells[i * SHADOW_CULL_WORDS as usize..][..SHADOW_CULL_WORDS as usize];
            if let Some(mut cull) = directional(-direction.normalize(), &boxes, words) {
                cull.first_word = i as u32 * SHADOW_CULL_WORDS;
                cull.plane_count = planes.len() as u32;
                for (slot, row) in cull.planes.iter_mut().zip(&planes) {
                    *slot = *row;
                }
                out.lights[i] = cull;
            }
        }
    }
    out
}

/// The static quads and disks tested exactly (the largest
/// [`MAX_CULL_PLANES`]), as rows y of their `object_from_world`; and the
/// world boxes of every other instance, which go into the grid.
fn split_occluders(accel: &SceneAccel) -> (Vec<[f32; 4]>, Vec<Aabb>) {
    let mut flat: Vec<usize> = (0..accel.instances.len())
        .filter(|&k| {
            let kind = accel.shapes[accel.instances[k].2 as usize].kind;
            (kind == SHAPE_QUAD || kind == SHAPE_DISK) && !accel.moving[k]
        })
        .collect();
    let size = |k: usize| {
        let b = accel.world_bounds[k];
        (b.max - b.min).length()
    };
    flat.sort_by(|&a, &b| size(b).total_cmp(&size(a)));
    flat.truncate(MAX_CULL_PLANES as usize);
    let planes = flat
        .iter()
        .map(|&k| accel.instances[k].1.row(1).to_array())
        .collect();
    let boxes = (0..accel.instances.len())
        .filter(|k| !flat.contains(k))
        .map(|k| accel.world_bounds[k])
        .collect();
    (planes, boxes)
}

/// The grid of one directional light (`to_light`: unit, towards the
/// light) over `boxes`, its bits written to `words`; None where culling
/// is off (a box that is not finite).
fn directional(to_light: Vec3, boxes: &[Aabb], words: &mut [u32]) -> Option<GpuShadowCull> {
    let (u, v) = to_light.any_orthonormal_pair();
    let project = |b: &Aabb| {
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for i in 0..8 {
            let corner = Vec3::new(
                if i & 1 == 0 { b.min.x } else { b.max.x },
                if i & 2 == 0 { b.min.y } else { b.max.y },
                if i & 4 == 0 { b.min.z } else { b.max.z },
            );
            let p = Vec2::new(u.dot(corner), v.dot(corner));
            lo = lo.min(p);
            hi = hi.max(p);
        }
        (lo, hi)
    };
    // The margin covers a ray drifting off its projection over the scene
    // (l is only nearly perpendicular to u and v in f32) and the rounding
    // of the kernel's projection: both far below 1e-4 of the scene's size.
    let all = boxes.iter().fold(Aabb::EMPTY, |a, &b| a.grow(b));
    if boxes.is_empty() {
        return Some(cull_record(u, v, Vec2::ZERO, 0.0, [0, 0]));
    }
    if !(all.min.is_finite() && all.max.is_finite()) {
        return None;
    }
    let pad =
        1e-4 * (all.max - all.min).length() + 1e-5 * all.min.abs().max(all.max.abs()).max_element();
    let rects: Vec<(Vec2, Vec2)> = boxes
        .iter()
        .map(|b| {
            let (lo, hi) = project(b);
            (lo - pad, hi + pad)
        })
        .collect();
    let lo = rects
        .iter()
        .fold(Vec2::splat(f32::INFINITY), |a, r| a.min(r.0));
    let hi = rects
        .iter()
        .fold(Vec2::splat(f32::NEG_INFINITY), |a, r| a.max(r.1));
    let cell = (hi - lo).max_element() / SHADOW_CULL_CELLS as f32;
    let per_unit = 1.0 / cell;
    if !(per_unit.is_finite() && per_unit > 0.0) {
        return None;
    }
    let dims = ((hi - lo) * per_unit)
        .ceil()
        .clamp(Vec2::ONE, Vec2::splat(SHADOW_CULL_CELLS as f32));
    let dims = [dims.x as u32, dims.y as u32];
    let cell_of = |p: Vec2| {
        let c = ((p - lo) * per_unit).floor();
        [
            (c.x.max(0.0) as u32).min(dims[0] - 1),
            (c.y.max(0.0) as u32).min(dims[1] - 1),
        ]
    };
    for (a, b) in rects {
        let (from, to) = (cell_of(a), cell_of(b));
        for y in from[1]..=to[1] {
            for x in from[0]..=to[0] {
                let bit = y * dims[0] + x;
                words[(bit / 32) as usize] |= 1 << (bit % 32);
            }
        }
    }
    Some(cull_record(u, v, lo, per_unit, dims))
}

fn cull_record(u: Vec3, v: Vec3, lo: Vec2, per_unit: f32, dims: [u32; 2]) -> GpuShadowCull {
    GpuShadowCull {
        u: u.extend(lo.x).to_array(),
        v: v.extend(lo.y).to_array(),
        planes: [[0.0; 4]; MAX_CULL_PLANES as usize],
        cells_per_unit: [per_unit; 2],
        dims,
        first_word: 0,
        plane_count: 0,
        enabled: 1,
        _pad: 0,
    }
}

/// The CPU twin of the trace kernel's `shadow_may_be_blocked`: whether the
/// shadow ray from `origin` along `to_light` may meet an occluder. False
/// only where it provably meets none.
pub fn may_be_blocked(cull: &GpuShadowCull, cells: &[u32], origin: Vec3, to_light: Vec3) -> bool {
    if cull.enabled == 0 {
        return true;
    }
    for row in &cull.planes[..cull.plane_count as usize] {
        let r = glam::Vec4::from_array(*row);
        let side = r.xyz().dot(origin) + r.w;
        let along = r.xyz().dot(to_light);
        let side_err = PLANE_MARGIN * (r.xyz().abs().dot(origin.abs()) + r.w.abs());
        let along_err = PLANE_MARGIN * r.xyz().abs().dot(to_light.abs());
        let behind =
            (side > side_err && along > along_err) || (side < -side_err && along < -along_err);
        if !behind {
            return true;
        }
    }
    let u = glam::Vec4::from_array(cull.u);
    let v = glam::Vec4::from_array(cull.v);
    let g = Vec2::new(u.xyz().dot(origin) - u.w, v.xyz().dot(origin) - v.w)
        * Vec2::from_array(cull.cells_per_unit);
    let dims = Vec2::new(cull.dims[0] as f32, cull.dims[1] as f32);
    if g.x < 0.0 || g.y < 0.0 || g.x >= dims.x || g.y >= dims.y {
        return false;
    }
    if g.is_nan() {
        return true;
    }
    let bit = g.y as u32 * cull.dims[0] + g.x as u32;
    cells[(cull.first_word + bit / 32) as usize] & (1 << (bit % 32)) != 0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    /// A floor quad, a tilted quad, a disk below the floor, boxes, spheres,
    /// a cylinder and a moving sphere, under one directional light.
    fn scene(direction: &str) -> (Scene, SceneAccel) {
        let ron = format!(
            r#"(version: 1,
                camera: (eye: (0.0, 3.0, 8.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 64, height: 64),
                lights: [
                    Directional(direction: {direction}, color: (1.0, 1.0, 1.0), intensity: 1.0),
                    Point(position: (0.0, 5.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 1.0),
                    Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 1.0, cast_shadows: false),
                ],
                materials: {{ "m": (base_color: (0.8, 0.8, 0.8), model: BlinnPhong) }},
                shapes: {{
                    "floor": Plane(Quad(half_size: (20.0, 20.0))),
                    "wall": Plane(Quad(half_size: (1.0, 2.0))),
                    "disk": Plane(Disk(radius: 1.5)),
                    "ball": Sphere(radius: 0.5),
                    "crate": Box(half_extents: (0.4, 0.3, 0.5)),
                    "post": Cylinder(radius: 0.2, height: 2.0),
                }},
                instances: [
                    (shape: "floor", material: "m"),
                    (shape: "wall", material: "m", transform: (translate: (3.0, 1.0, -2.0), rotate_deg: (70.0, 20.0, 0.0))),
                    (shape: "disk", material: "m", transform: (translate: (-3.0, -1.0, 1.0))),
                    (shape: "ball", material: "m", transform: (translate: (-1.0, 0.5, 0.0))),
                    (shape: "ball", material: "m", transform: (translate: (1.0, 2.5, 1.0), scale: (2.0, 1.0, 1.0))),
                    (shape: "ball", material: "m", transform: (translate: (0.0, 1.0, 3.0)), transform_end: (translate: (1.0, 1.5, 3.0))),
                    (shape: "crate", material: "m", transform: (translate: (2.0, 0.3, 0.0), rotate_deg: (0.0, 30.0, 0.0))),
                    (shape: "post", material: "m", transform: (translate: (-2.0, 1.0, -1.0), rotate_deg: (0.0, 0.0, 25.0))),
                ],
            )"#
        );
        let scene = Scene::from_ron_str(&ron, "test", std::path::Path::new(".")).unwrap();
        let order: Vec<usize> = (0..scene.instances.len()).collect();
        let accel = SceneAccel::build(&scene, &order).unwrap();
        (scene, accel)
    }

    /// Deterministic points in [-r, r]^3 (a small LCG).
    fn points(n: usize, r: f32) -> Vec<Vec3> {
        let mut state = 0x2545_f491_u32;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1 << 24) as f32 * 2.0 - 1.0
        };
        (0..n)
            .map(|_| Vec3::new(next(), next(), next()) * r)
            .collect()
    }

    /// The property the trace kernel relies on: wherever the cull says a
    /// shadow ray cannot be blocked, the CPU reference tracer finds no hit
    /// along it. Rays start anywhere in and around the scene, on the floor
    /// (just above it, as the kernel offsets them) and just off every
    /// shape. It fails if a box is left out of the grid, the grid's axes or
    /// scale are off, or a plane's side test has the wrong sign.
    #[test]
    fn a_culled_shadow_ray_meets_nothing() {
        for direction in ["(-0.5, -1.0, -0.6)", "(0.3, -0.2, 0.9)", "(0.0, 1.0, 0.0)"] {
            let (scene, accel) = scene(direction);
            let cull = build(&accel, &scene.lights);
            let Light::Directional { direction, .. } = scene.lights[0] else {
                unreachable!()
            };
            let l = -direction.normalize();
            let mut origins = points(4000, 6.0);
            origins.extend(points(4000, 6.0).iter().map(|p| Vec3::new(p.x, 1e-3, p.z)));
            let (mut culled, mut cast) = (0, 0);
            for o in origins {
                if may_be_blocked(&cull.lights[0], &cull.cells, o, l) {
                    cast += 1;
                    continue;
                }
                culled += 1;
                let hit = accel.closest_hit(o, l, 0.0, f32::INFINITY);
                assert!(
                    hit.hit.is_none(),
                    "light {direction}: the ray from {o} was culled but meets instance {:?}",
                    hit.hit.map(|h| h.instance)
                );
            }
            // Both outcomes occur often, so the check above ran on many
            // culled rays (a light from below culls the fewest).
            assert!(culled > 500 && cast > 500, "culled {culled}, cast {cast}");
        }
    }

    /// Rays from just above the lit floor, away from every other shape,
    /// are culled (the floor is behind them); from just below it, under a
    /// light from above, they reach it and are cast. The grid leaves the
    /// floor out, so it does not cover the whole floor.
    #[test]
    fn the_floor_is_tested_as_a_plane() {
        let (scene, accel) = scene("(-0.5, -1.0, -0.6)");
        let cull = build(&accel, &scene.lights);
        let l = Vec3::new(0.5, 1.0, 0.6).normalize();
        let c = &cull.lights[0];
        assert_eq!(c.enabled, 1);
        assert_eq!(c.plane_count, 3, "floor, wall and disk are static planes");
        let above = Vec3::new(-10.0, 1e-3, 15.0);
        assert!(!may_be_blocked(c, &cull.cells, above, l));
        let below = Vec3::new(-10.0, -1e-3, 15.0);
        assert!(accel
            .closest_hit(below, l, 0.0, f32::INFINITY)
            .hit
            .is_some());
        assert!(may_be_blocked(c, &cull.cells, below, l));
        // A ray from the floor under the raised ball passes through it.
        let under_ball = Vec3::new(-1.0, 1e-3, 0.0) - l * (0.5 / l.y);
        assert!(accel
            .closest_hit(under_ball, l, 0.0, f32::INFINITY)
            .hit
            .is_some());
        assert!(may_be_blocked(c, &cull.cells, under_ball, l));
    }

    /// Point lights and lights that cast no shadows keep every ray.
    #[test]
    fn only_shadow_casting_directional_lights_cull() {
        let (scene, accel) = scene("(-0.5, -1.0, -0.6)");
        let cull = build(&accel, &scene.lights);
        assert_eq!(cull.lights.len(), 3);
        assert_eq!(cull.cells.len(), 3 * SHADOW_CULL_WORDS as usize);
        assert_eq!(cull.lights[1].enabled, 0);
        assert_eq!(cull.lights[2].enabled, 0);
        assert!(may_be_blocked(
            &cull.lights[1],
            &cull.cells,
            Vec3::new(-10.0, 1e-3, 15.0),
            Vec3::Y
        ));
    }
}
