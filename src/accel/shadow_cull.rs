//! Shadow rays that cannot meet anything, found before they are cast.
//!
//! A shadow ray towards a directional light runs from a surface point o
//! along the light's direction l. It can only meet an instance whose world
//! box it crosses, and a ray along l crosses a box only where o, projected
//! along l onto a plane across it, falls inside the box's projection. So
//! per directional light each occluder's footprint is projected onto two
//! axes (u, v) across l: its box's rectangle, the circle around its
//! bounding sphere (spheres and CSG solids, where smaller), or each of its
//! triangles (static meshes). A grid of up to [`SHADOW_CULL_CELLS`]^2 cells
//! over them records which land on each cell: none, only one sphere or box
//! (its instance), or more ([`CULL_CELL_MANY`]). A ray whose origin
//! projects onto an empty cell, or off the grid, meets none of them.
//! Nor does a ray leaving the outside of a sphere or a box on its lit side
//! (the kernel only casts towards lights a surface faces) when that solid
//! is all its cell holds: a convex solid lies wholly behind its tangent
//! plane, and the ray starts in front of it, offset along the normal.
//! Where one sun casts shadows (the lists below), a cell whose occluders
//! are all static analytic shapes or CSG solids evaluated by their truth
//! table, at most [`SHADOW_LIST_MAX`], points at their list instead
//! ([`CULL_CELL_LIST`]): a ray starting there tests just them, however
//! its receiver is made (the floor, a mesh, a CSG solid).
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
//! of a lit floor's pixels now cast none (docs/performance-history.md).

use glam::{DVec2, DVec3, Vec2, Vec3, Vec4Swizzles};

use crate::accel::bvh::Aabb;
use crate::accel::layout::{
    GpuShadowCull, CELL_LIST_TRIANGLE_SHIFT, CULL_CELL_LIST, CULL_CELL_MANY, MAX_CULL_PLANES,
    SHADOW_CULL_CELLS, SHADOW_LIST_CONVEX, SHADOW_LIST_MAX, SHADOW_LIST_WALK, SHADOW_LIST_WORDS,
    SHAPE_BOX, SHAPE_CSG, SHAPE_DISK, SHAPE_MESH, SHAPE_QUAD, SHAPE_SPHERE,
};
use crate::accel::screen_tiles::{convex_hull, hull_vertices};
use crate::accel::{world_sphere, SceneAccel};
use crate::scene::Light;

/// Relative margin of the plane test: a sum of four f32 products is within
/// about 4 ulp (2.4e-7) of its sum of magnitudes; 1e-5 is 40 times that.
pub const PLANE_MARGIN: f32 = 1e-5;

/// Cells of one light's grid in [`ShadowCull::cells`].
pub const CELLS_PER_LIGHT: usize = (SHADOW_CULL_CELLS * SHADOW_CULL_CELLS) as usize;
/// Words after the bounding spheres for the cells' lists of the one light
/// that has lists: a full list (header and [`SHADOW_LIST_MAX`] instances)
/// in every cell at most.
pub const CELL_LIST_ROOM: usize = CELLS_PER_LIGHT * SHADOW_LIST_WORDS as usize;
/// The most triangles (of one static mesh) a cell's list holds.
pub const CELL_LIST_TRIANGLES: u32 = 64;

/// What the trace pass reads: one [`GpuShadowCull`] per light (at least
/// one); [`CELLS_PER_LIGHT`] cells for each of the first
/// [`MAX_CULL_LIGHTS`]; then, for each of those, every instance's occluder
/// list ([`SHADOW_LIST_WORDS`] words each; see [`occluder_lists`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ShadowCull {
    pub lights: Vec<GpuShadowCull>,
    pub cells: Vec<u32>,
    /// For the CPU's proofs (not uploaded): the lone sun's culled regions
    /// ([`the_sun`]), where its rays are culled.
    pub sun: Option<CulledRegions>,
}

/// Lights that get a grid: the first ones (each grid is 64 KiB; a light
/// past them casts all its shadow rays). The buffers' sizes depend only on
/// the light and instance counts, so edits of lights rewrite them in place.
pub const MAX_CULL_LIGHTS: usize = 8;

/// The most words all lights' occluder lists may take (64 MiB); a scene
/// whose lists would take more has none.
pub const MAX_LIST_WORDS: usize = 1 << 24;

/// Whether the trace kernel reads occluder lists for `lights` over
/// `accel` (`SHADOW_LISTS`; `render::trace::Variant`): exactly one light
/// casts shadows, a directional one among the first [`MAX_CULL_LIGHTS`],
/// and some instance is an analytic shape (a list's receiver and entries
/// are). With more shadow-casting lights the kernel casts their rays in a
/// loop, where the list code cost more than it saved
/// (docs/performance-history.md, twentieth session).
pub fn lists_read(accel: &SceneAccel, lights: &[Light]) -> bool {
    the_sun(lights).is_some()
        && accel
            .instances
            .iter()
            .any(|&(_, _, shape)| accel.shapes[shape as usize].kind < SHAPE_MESH)
}

/// The lone sun: where exactly one of `lights` casts shadows, and it is
/// a directional light among the first [`MAX_CULL_LIGHTS`] (so it has a
/// grid), its index and the unit direction its shadow rays run along.
pub fn the_sun(lights: &[Light]) -> Option<(usize, Vec3)> {
    let mut casting = lights.iter().enumerate().filter(|(_, l)| l.casts_shadows());
    match (casting.next(), casting.next()) {
        (Some((i, Light::Directional { direction, .. })), None) if i < MAX_CULL_LIGHTS => {
            Some((i, -direction.normalize()))
        }
        _ => None,
    }
}

/// The cull data of `lights` over the instances of `accel`. Where `lists`
/// and they fit in [`MAX_LIST_WORDS`], it has room for occluder lists
/// (its size depends only on the light and instance counts, so that light
/// edits rewrite it in place), filled where the kernel reads them
/// ([`lists_read`]); unfilled, every record is [`SHADOW_LIST_WALK`].
pub fn build(accel: &SceneAccel, lights: &[Light], lists: bool) -> ShadowCull {
    let slots = lights.len().clamp(1, MAX_CULL_LIGHTS);
    let grids = slots * CELLS_PER_LIGHT;
    let per_light = accel.instances.len() * SHADOW_LIST_WORDS as usize;
    let per_light = if lists && slots * per_light <= MAX_LIST_WORDS {
        per_light
    } else {
        0
    };
    let mut cells = vec![0; grids];
    cells.resize(grids + slots * per_light, SHADOW_LIST_WALK);
    // With room for lists, room for the instances' bounding spheres too,
    // which the kernel reads as vec4s (the grids and lists are whole
    // multiples of 4 words).
    let first_sphere = cells.len();
    debug_assert_eq!(first_sphere % 4, 0);
    if per_light > 0 {
        cells.extend(
            (0..accel.instances.len())
                .flat_map(|k| bounding_sphere(accel, k).to_array().map(f32::to_bits)),
        );
    }
    // Then room for one light's cell lists (only one light has lists: a
    // lone shadow-casting sun), whatever the light's direction, so that
    // light edits rewrite the buffer in place: at most a header and
    // SHADOW_LIST_MAX instances per cell.
    let first_cell_list = cells.len();
    if per_light > 0 {
        cells.resize(first_cell_list + CELL_LIST_ROOM, 0);
    }
    let mut out = ShadowCull {
        lights: vec![bytemuck::Zeroable::zeroed(); lights.len().max(1)],
        cells,
        sun: None,
    };
    let fill = per_light > 0 && lists_read(accel, lights);
    let (planes, boxes) = split_occluders(accel);
    for (i, light) in lights.iter().enumerate().take(MAX_CULL_LIGHTS) {
        if let Light::Directional {
            direction,
            cast_shadows: true,
            ..
        } = light
        {
            let to_light = -direction.normalize();
            let cells = &mut out.cells[i * CELLS_PER_LIGHT..][..CELLS_PER_LIGHT];
            let Some((mut cull, pad, cell_lists)) = directional(to_light, &boxes, cells) else {
                continue;
            };
            // Each cell whose occluders are all listed points at their
            // list, after everything else (where the kernel reads lists).
            if fill {
                // Cells past the room keep their word (they walk).
                let end = first_cell_list + CELL_LIST_ROOM;
                let mut at = first_cell_list;
                for list in cell_lists {
                    if at + list.words.len() > end {
                        break;
                    }
                    out.cells[i * CELLS_PER_LIGHT + list.cell] = CULL_CELL_LIST | at as u32;
                    out.cells[at..][..list.words.len()].copy_from_slice(&list.words);
                    at += list.words.len();
                }
            }
            cull.first_cell = (i * CELLS_PER_LIGHT) as u32;
            cull.plane_count = planes.len() as u32;
            for (slot, row) in cull.planes.iter_mut().zip(&planes) {
                *slot = *row;
            }
            if fill {
                let first = grids + i * per_light;
                let records = &mut out.cells[first..][..per_light];
                occluder_lists(accel, to_light, pad, &boxes, records);
                cull.first_list = first as u32;
                cull.first_sphere = first_sphere as u32;
            }
            out.lights[i] = cull;
        }
    }
    out.sun = the_sun(lights).and_then(|(i, to_light)| {
        let record = &out.lights[i];
        let u = glam::Vec4::from_array(record.u).xyz();
        let v = glam::Vec4::from_array(record.v).xyz();
        let pad = f64::from(grid_pad(&boxes));
        let shades = shades(accel, &boxes, to_light, (u, v), pad);
        CulledRegions::new(record, &out.cells, to_light, shades, pad)
    });
    out
}

/// An occluder of the grid: its world box, for spheres and CSG solids
/// also a bounding sphere in object space (centre, radius) with the
/// instance's matrix, and what a cell it alone lands on holds (k + 1 for a
/// sphere or a box, instance k; else [`CULL_CELL_MANY`]).
struct Occluder {
    /// Its GPU instance index and shape kind.
    instance: u32,
    kind: u32,
    bounds: Aabb,
    sphere: Option<(Vec3, f32, glam::Mat4)>,
    /// A static mesh's triangles in world space, each projected on its
    /// own, with their indices in the triangle buffer (empty: the box or
    /// sphere stands for the occluder).
    triangles: Vec<(u32, [Vec3; 3])>,
    tag: u32,
    /// Whether a cell's list may hold it: the list test intersects it as
    /// the walk does (a static analytic shape, or a CSG solid evaluated by
    /// its truth table, `GpuShape::csg_fast`).
    listable: bool,
}

/// Mesh triangles projected one by one, in all instances together: past
/// this budget a mesh instance's box stands for it.
pub const MAX_FOOTPRINT_TRIANGLES: usize = 1 << 18;

/// The triangles (object space) of the bottom-level BVH rooted at `root`,
/// with their indices in `accel.triangles`.
fn mesh_triangles(accel: &SceneAccel, root: u32) -> Vec<(u32, [Vec3; 3])> {
    let mut out = Vec::new();
    let mut stack = vec![root];
    while let Some(i) = stack.pop() {
        let node = accel.nodes[i as usize];
        if node.count == 0 {
            stack.extend([node.left_or_first, node.left_or_first + 1]);
            continue;
        }
        for k in node.left_or_first..node.left_or_first + node.count {
            let t = &accel.triangles[k as usize];
            out.push((k, [t.p0, t.p1, t.p2].map(|p| Vec3::from_slice(&p[..3]))));
        }
    }
    out
}

/// The static quads and disks tested exactly (the largest
/// [`MAX_CULL_PLANES`]), as rows y of their `object_from_world`; and every
/// other instance, which goes into the grid.
fn split_occluders(accel: &SceneAccel) -> (Vec<[f32; 4]>, Vec<Occluder>) {
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
    let mut budget = MAX_FOOTPRINT_TRIANGLES;
    let boxes = (0..accel.instances.len())
        .filter(|k| !flat.contains(k))
        .map(|k| {
            let (world_from_object, _, shape) = accel.instances[k];
            let shape = accel.shapes[shape as usize];
            let mut triangles = Vec::new();
            if shape.kind == SHAPE_MESH && !accel.moving[k] {
                let mesh = mesh_triangles(accel, shape.blas_root);
                if mesh.len() <= budget {
                    budget -= mesh.len();
                    triangles = mesh
                        .into_iter()
                        .map(|(k, t)| (k, t.map(|p| world_from_object.transform_point3(p))))
                        .collect();
                }
            }
            let convex = shape.kind == SHAPE_SPHERE || shape.kind == SHAPE_BOX;
            // A moving instance keeps its box, which covers the motion.
            let sphere = match shape.kind {
                _ if accel.moving[k] => None,
                SHAPE_SPHERE => Some((Vec3::ZERO, shape.params[0])),
                SHAPE_CSG => Some((Vec3::from_slice(&shape.params[..3]), shape.params[3])),
                _ => None,
            };
            Occluder {
                instance: k as u32,
                kind: shape.kind,
                bounds: accel.world_bounds[k],
                sphere: sphere.map(|(c, r)| (c, r, world_from_object)),
                listable: triangles.is_empty()
                    && !accel.moving[k]
                    && shape.kind != SHAPE_MESH
                    && (shape.kind != SHAPE_CSG || shape.csg_fast != 0),
                triangles,
                tag: if convex { k as u32 + 1 } else { CULL_CELL_MANY },
            }
        })
        .collect();
    (planes, boxes)
}

/// A sphere (centre xyz, radius w) around all of instance k in world
/// space, which the kernel's list test uses to skip occluders a ray
/// misses (trace.wgsl, `may_meet_sphere`, which adds the rounding
/// margin); w = -1 where it must not: only boxes (their world box's
/// circumsphere, over the whole shutter) and static spheres get one. A
/// sphere's radius is scaled by the matrix's largest stretch, bounded
/// above by Gershgorin's circle theorem (exact for rotations with uniform
/// scale); spheres stretched more than 4x in one direction against
/// another get none, since the sphere test's rounding near a tangent
/// grows with that ratio squared and the kernel's margin allows for 4.
/// Other shapes get none: their tests' rounding is not bounded by these
/// radii.
fn bounding_sphere(accel: &SceneAccel, k: usize) -> glam::Vec4 {
    let none = glam::Vec4::new(0.0, 0.0, 0.0, -1.0);
    let b = accel.world_bounds[k];
    let (world_from_object, _, shape) = accel.instances[k];
    let shape = accel.shapes[shape as usize];
    match shape.kind {
        SHAPE_BOX => ((b.min + b.max) * 0.5).extend((b.max - b.min).length() * 0.5),
        SHAPE_SPHERE if !accel.moving[k] => {
            let m = glam::Mat3::from_mat4(world_from_object);
            let largest = crate::accel::squared_stretch_bound(m);
            // The eigenvalues' product is the determinant and the middle
            // one is at most the largest, so largest^3 / det bounds the
            // ratio of the largest to the smallest: the stretch ratio^2.
            let det = (m.transpose() * m).determinant();
            if !(det > 0.0 && largest.powi(3) <= 16.0 * det) {
                return none;
            }
            // The sphere the screen tiles use (`accel::world_sphere`).
            accel.footprints[k].sphere.unwrap_or(none)
        }
        _ => none,
    }
}

/// A region across the light that holds an occluder's projection: the
/// rectangle (lo, hi), and the circle (centre, radius) inside it where
/// that is tighter.
#[derive(Debug, Clone, Copy)]
struct Footprint {
    lo: Vec2,
    hi: Vec2,
    circle: Option<(Vec2, f32)>,
}

impl Footprint {
    fn grown(self, by: f32) -> Footprint {
        Footprint {
            lo: self.lo - by,
            hi: self.hi + by,
            circle: self.circle.map(|(c, r)| (c, r + by)),
        }
    }

    /// Whether the two regions may share a point (false only where they
    /// provably do not).
    fn overlaps(&self, other: &Footprint) -> bool {
        if self.lo.cmpgt(other.hi).any() || other.lo.cmpgt(self.hi).any() {
            return false;
        }
        match (self.circle, other.circle) {
            (Some((a, ra)), Some((b, rb))) => a.distance(b) <= ra + rb,
            (Some((c, r)), None) => c.distance(c.clamp(other.lo, other.hi)) <= r,
            (None, Some((c, r))) => c.distance(c.clamp(self.lo, self.hi)) <= r,
            (None, None) => true,
        }
    }
}

/// The axes (u, v) across the light (`to_light`: unit, towards it).
fn axes(to_light: Vec3) -> (Vec3, Vec3) {
    to_light.any_orthonormal_pair()
}

fn across(u: Vec3, v: Vec3, p: Vec3) -> Vec2 {
    Vec2::new(u.dot(p), v.dot(p))
}

fn project(u: Vec3, v: Vec3, points: &[Vec3]) -> (Vec2, Vec2) {
    points.iter().map(|&p| across(u, v, p)).fold(
        (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(p), hi.max(p)),
    )
}

/// Occluder `b`'s footprint across the light, grown by `pad`: its box's
/// rectangle, or the circle around the projection of its bounding sphere,
/// whichever is smaller.
fn footprint(b: &Occluder, u: Vec3, v: Vec3, pad: f32) -> Footprint {
    let (lo, hi) = project(u, v, &b.bounds.corners());
    let rect = Footprint {
        lo: lo - pad,
        hi: hi + pad,
        circle: None,
    };
    let Some((centre, radius, m)) = b.sphere else {
        return rect;
    };
    let c = across(u, v, m.transform_point3(centre));
    let r = radius * projected_stretch(m, u, v) + pad;
    if (2.0 * r) * (2.0 * r) < (hi - lo + 2.0 * pad).element_product() {
        Footprint {
            lo: c - r,
            hi: c + r,
            circle: Some((c, r)),
        }
    } else {
        rect
    }
}

/// The grid's margin across the light for `boxes` (their extent's size
/// and coordinates); not finite where they are not.
fn grid_pad(boxes: &[Occluder]) -> f32 {
    let all = boxes.iter().fold(Aabb::EMPTY, |a, b| a.grow(b.bounds));
    if !(all.min.is_finite() && all.max.is_finite()) {
        return f32::INFINITY;
    }
    1e-4 * (all.max - all.min).length() + 1e-5 * all.min.abs().max(all.max.abs()).max_element()
}

/// The grid of one directional light (`to_light`: unit, towards the
/// light) over `boxes`, written to `cells`, with the margin its
/// footprints were grown by; None where culling is off (a box that is not
/// finite).
fn directional(
    to_light: Vec3,
    boxes: &[Occluder],
    cells: &mut [u32],
) -> Option<(GpuShadowCull, f32, Vec<CellList>)> {
    let (u, v) = axes(to_light);
    if boxes.is_empty() {
        return Some((cull_record(u, v, Vec2::ZERO, 0.0, [0, 0]), 0.0, Vec::new()));
    }
    // The margin covers a ray drifting off its projection over the scene
    // (l is only nearly perpendicular to u and v in f32) and the rounding
    // of the kernel's projection: both far below 1e-4 of the scene's size.
    let pad = grid_pad(boxes);
    if !pad.is_finite() {
        return None;
    }
    // Each occluder's footprint across the light. A static mesh within
    // the budget: one rectangle per triangle (a ray meets a triangle only
    // where it starts inside the triangle's projection).
    let triangle_rect = |b: &Occluder, (k, t): &(u32, [Vec3; 3])| {
        let (lo, hi) = project(u, v, t);
        let rect = Footprint {
            lo: lo - pad,
            hi: hi + pad,
            circle: None,
        };
        (
            rect,
            CULL_CELL_MANY,
            Some(Landing::Triangle(b.instance, *k)),
        )
    };
    // Each footprint with its cell word and what a cell's list would hold
    // for it (None: a cell it lands on walks).
    let mut footprints: Vec<(Footprint, u32, Option<Landing>)> = boxes
        .iter()
        .flat_map(|b| b.triangles.iter().map(move |t| triangle_rect(b, t)))
        .collect();
    footprints.extend(boxes.iter().filter(|b| b.triangles.is_empty()).map(|b| {
        let landing = b.listable.then_some(Landing::Whole(b));
        (footprint(b, u, v, pad), b.tag, landing)
    }));
    let lo = footprints
        .iter()
        .fold(Vec2::splat(f32::INFINITY), |a, r| a.min(r.0.lo));
    let hi = footprints
        .iter()
        .fold(Vec2::splat(f32::NEG_INFINITY), |a, r| a.max(r.0.hi));
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
    // Per cell, what lands on it while all of it can be listed (None from
    // the first that cannot).
    let mut occupants: Vec<Option<Occupants>> = vec![Some(Occupants::default()); cells.len()];
    for (f, tag, listed) in footprints {
        let (from, to) = (cell_of(f.lo), cell_of(f.hi));
        for y in from[1]..=to[1] {
            for x in from[0]..=to[0] {
                if let Some((c, r)) = f.circle {
                    // The cell's square, and its point nearest the centre.
                    let corner = lo + Vec2::new(x as f32, y as f32) * cell;
                    let nearest = c.clamp(corner, corner + cell);
                    if nearest.distance(c) > r {
                        continue;
                    }
                }
                let at = (y * dims[0] + x) as usize;
                let cell = &mut cells[at];
                *cell = if *cell == 0 { tag } else { CULL_CELL_MANY };
                let kept = match (&mut occupants[at], listed) {
                    (Some(o), Some(landing)) => o.add(landing),
                    _ => false,
                };
                if !kept {
                    occupants[at] = None;
                }
            }
        }
    }
    let lists = occupants
        .into_iter()
        .enumerate()
        .filter_map(|(cell, o)| {
            let o = o.filter(|o| !o.whole.is_empty() || o.mesh.is_some())?;
            Some(CellList {
                cell,
                words: o.words(),
            })
        })
        .collect();
    Some((cull_record(u, v, lo, per_unit, dims), pad, lists))
}

/// What lands on a grid cell: a whole occluder, or one triangle of a
/// static mesh (its instance and its index in the triangle buffer).
#[derive(Clone, Copy)]
enum Landing<'a> {
    Whole(&'a Occluder),
    Triangle(u32, u32),
}

/// What a cell's list holds: up to [`SHADOW_LIST_MAX`] whole occluders and
/// up to [`CELL_LIST_TRIANGLES`] triangles of one mesh instance.
#[derive(Clone, Default)]
struct Occupants<'a> {
    whole: Vec<&'a Occluder>,
    mesh: Option<u32>,
    triangles: Vec<u32>,
}

impl<'a> Occupants<'a> {
    /// Adds what landed; false where the list cannot hold it.
    fn add(&mut self, landing: Landing<'a>) -> bool {
        match landing {
            Landing::Whole(b) if self.whole.len() < SHADOW_LIST_MAX as usize => {
                self.whole.push(b);
                true
            }
            Landing::Triangle(instance, k)
                if self.mesh.is_none_or(|m| m == instance)
                    && self.triangles.len() < CELL_LIST_TRIANGLES as usize =>
            {
                self.mesh = Some(instance);
                self.triangles.push(k);
                true
            }
            _ => false,
        }
    }

    /// The list's words: a header (the whole occluders' count, as an
    /// occluder list's, [`SHADOW_LIST_CONVEX`] where all are spheres or
    /// boxes, and the triangles' count from [`CELL_LIST_TRIANGLE_SHIFT`]),
    /// the whole occluders, then the mesh instance and its triangles.
    fn words(&self) -> Vec<u32> {
        let convex = self
            .whole
            .iter()
            .all(|b| b.kind == SHAPE_SPHERE || b.kind == SHAPE_BOX);
        let header = self.whole.len() as u32
            | if convex { SHADOW_LIST_CONVEX } else { 0 }
            | (self.triangles.len() as u32) << CELL_LIST_TRIANGLE_SHIFT;
        let mut words = vec![header];
        words.extend(self.whole.iter().map(|b| b.instance));
        if let Some(mesh) = self.mesh {
            words.push(mesh);
            words.extend(&self.triangles);
        }
        words
    }
}

/// The list of the occluders of one cell of a light's grid: its index in
/// the grid and its words ([`Occupants::words`]).
struct CellList {
    cell: usize,
    words: Vec<u32>,
}

/// Every instance's occluder list for the directional light towards
/// `to_light` (unit), written to `records` ([`SHADOW_LIST_WORDS`] words per
/// instance, in instance order; `pad`: the grid's footprint margin).
///
/// A shadow ray from a surface point of instance r starts inside r's
/// footprint (grown by `reach`: the kernel's offset along the normal, 1e-4
/// of the scene's half diagonal at most, and rounding) and moves towards
/// the light. So it can only meet an occluder whose footprint overlaps
/// r's and that reaches further towards the light than r's lowest point:
/// r's list holds those (r among them; [`SHADOW_LIST_CONVEX`] marks a
/// sphere or a box, which a ray leaving its lit outside cannot meet). The
/// kernel then tests just them instead of walking the BVH, and finds a hit
/// exactly where the walk would. The list stays [`SHADOW_LIST_WALK`] where
/// it would hold more than [`SHADOW_LIST_MAX`] instances, or a mesh or CSG
/// solid (the list test intersects analytic shapes only). Planes tested
/// exactly are in no list (the kernel reads one only when they are all
/// behind the ray) and have none.
fn occluder_lists(
    accel: &SceneAccel,
    to_light: Vec3,
    pad: f32,
    boxes: &[Occluder],
    records: &mut [u32],
) {
    if boxes.is_empty() {
        return;
    }
    let (u, v) = axes(to_light);
    let scene = accel
        .world_bounds
        .iter()
        .fold(Aabb::EMPTY, |a, &b| a.grow(b));
    let reach = 1e-4 * (scene.max - scene.min).length() + pad;
    let prints: Vec<Footprint> = boxes.iter().map(|b| footprint(b, u, v, pad)).collect();
    // How far along the light each occluder reaches (its box's corners).
    let along: Vec<(f32, f32)> = boxes
        .iter()
        .map(|b| {
            let ts = b.bounds.corners().map(|p| p.dot(to_light));
            let lo = ts.iter().copied().fold(f32::INFINITY, f32::min);
            (lo, ts.iter().copied().fold(f32::NEG_INFINITY, f32::max))
        })
        .collect();
    let buckets = Buckets::new(&prints);
    // `seen[j] == r + 1`: occluder j was already considered for receiver r.
    let mut seen = vec![0usize; boxes.len()];
    let mut list = Vec::with_capacity(SHADOW_LIST_MAX as usize);
    for (r, receiver) in boxes.iter().enumerate() {
        let area = prints[r].grown(reach);
        list.clear();
        let mut walk = false;
        for j in buckets.near(&area) {
            if seen[j] == r + 1 {
                continue;
            }
            seen[j] = r + 1;
            if along[j].1 < along[r].0 - reach || !area.overlaps(&prints[j]) {
                continue;
            }
            let kind = boxes[j].kind;
            if kind == SHAPE_MESH || kind == SHAPE_CSG || list.len() == SHADOW_LIST_MAX as usize {
                walk = true;
                break;
            }
            list.push(boxes[j].instance);
        }
        if walk {
            continue;
        }
        let convex = receiver.kind == SHAPE_SPHERE || receiver.kind == SHAPE_BOX;
        let record = &mut records[receiver.instance as usize * SHADOW_LIST_WORDS as usize..]
            [..SHADOW_LIST_WORDS as usize];
        record[0] = list.len() as u32 | if convex { SHADOW_LIST_CONVEX } else { 0 };
        record[1..=list.len()].copy_from_slice(&list);
    }
}

/// Footprints sorted into a coarse grid of buckets (about one per
/// footprint), so that a receiver's list looks only at its neighbours;
/// footprints over more than [`Buckets::SPAN`] buckets are looked at for
/// every receiver.
struct Buckets {
    lo: Vec2,
    per_unit: f32,
    dims: [usize; 2],
    cells: Vec<Vec<usize>>,
    wide: Vec<usize>,
}

impl Buckets {
    const SPAN: usize = 16;

    fn new(prints: &[Footprint]) -> Buckets {
        let lo = prints
            .iter()
            .fold(Vec2::splat(f32::INFINITY), |a, f| a.min(f.lo));
        let hi = prints
            .iter()
            .fold(Vec2::splat(f32::NEG_INFINITY), |a, f| a.max(f.hi));
        let side = (prints.len() as f32).sqrt().ceil().clamp(1.0, 1024.0);
        let per_unit = side / (hi - lo).max_element();
        let per_unit = if per_unit.is_finite() { per_unit } else { 0.0 };
        let dims = ((hi - lo) * per_unit)
            .ceil()
            .clamp(Vec2::ONE, Vec2::splat(side));
        let mut b = Buckets {
            lo,
            per_unit,
            dims: [dims.x as usize, dims.y as usize],
            cells: vec![Vec::new(); dims.x as usize * dims.y as usize],
            wide: Vec::new(),
        };
        for (j, f) in prints.iter().enumerate() {
            let ([x0, y0], [x1, y1]) = b.range(f);
            if (x1 - x0 + 1) * (y1 - y0 + 1) > Buckets::SPAN {
                b.wide.push(j);
                continue;
            }
            for y in y0..=y1 {
                for x in x0..=x1 {
                    b.cells[y * b.dims[0] + x].push(j);
                }
            }
        }
        b
    }

    /// The buckets (first and last, along u and v) that `f` covers.
    fn range(&self, f: &Footprint) -> ([usize; 2], [usize; 2]) {
        let cell = |p: Vec2| {
            let c = ((p - self.lo) * self.per_unit).floor().max(Vec2::ZERO);
            [
                (c.x as usize).min(self.dims[0] - 1),
                (c.y as usize).min(self.dims[1] - 1),
            ]
        };
        (cell(f.lo), cell(f.hi))
    }

    /// The footprints that may overlap `area` (some more than once).
    fn near<'a>(&'a self, area: &Footprint) -> impl Iterator<Item = usize> + 'a {
        let ([x0, y0], [x1, y1]) = self.range(area);
        let in_grid = (y0..=y1).flat_map(move |y| (x0..=x1).map(move |x| y * self.dims[0] + x));
        self.wide
            .iter()
            .copied()
            .chain(in_grid.flat_map(|c| self.cells[c].iter().copied()))
    }
}

/// The largest factor by which `m` stretches object-space lengths as seen
/// across the light: the spectral norm of the 2 x 3 map x -> (u . Mx,
/// v . Mx), so a ball of radius r projects inside a circle of radius r
/// times this (exactly, for a uniformly scaled sphere).
fn projected_stretch(m: glam::Mat4, u: Vec3, v: Vec3) -> f32 {
    let m = glam::Mat3::from_mat4(m).transpose();
    let (pu, pv) = (m * u, m * v);
    let (a, c, b) = (pu.length_squared(), pv.length_squared(), pu.dot(pv));
    let half_sum = 0.5 * (a + c);
    let half_diff = 0.5 * (a - c);
    (half_sum + (half_diff * half_diff + b * b).sqrt()).sqrt()
}

fn cull_record(u: Vec3, v: Vec3, lo: Vec2, per_unit: f32, dims: [u32; 2]) -> GpuShadowCull {
    GpuShadowCull {
        u: u.extend(lo.x).to_array(),
        v: v.extend(lo.y).to_array(),
        planes: [[0.0; 4]; MAX_CULL_PLANES as usize],
        cells_per_unit: [per_unit; 2],
        dims,
        first_cell: 0,
        plane_count: 0,
        enabled: 1,
        first_list: 0,
        first_sphere: 0,
        _pad: [0; 3],
    }
}

/// The most occluders whose shadows [`CulledRegions`] tests one by one
/// (more, and it tests the grid's cells alone).
const MAX_SHADES: usize = 32;

/// One occluder's shadow across a directional light, for
/// [`CulledRegions::all_culled`]: the convex hull of its projection
/// across the light (the points, and the edges as outward unit normals n
/// and offsets c, n . q <= c inside, grown by the grid's margin), and how
/// far it reaches towards the light (the largest p . to_light of its
/// points).
#[derive(Debug, Clone, PartialEq)]
struct Shade {
    points: Vec<DVec2>,
    edges: Vec<(DVec2, f64)>,
    top: f64,
    /// The grown hull's bounding rectangle, for a quick first test.
    lo: DVec2,
    hi: DVec2,
    /// How far past the occluder the kernel's test may report a hit.
    slack: Slack,
}

/// How far past an occluder's surface the kernel's f32 test of it may
/// report a hit, beyond the margins every shade has (the grid's, and 1e-4
/// of the receiver's coordinates, which cover a box's slab test and a
/// triangle's edge tests).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Slack {
    /// A box's or a mesh's: those margins.
    None,
    /// A sphere's or a CSG solid's (whose hits its bounding sphere's test
    /// gates): the kernel's own `may_meet_sphere` margin for this world
    /// sphere (centre, radius), 1e-5 of the sizes involved and 6.4e-5
    /// D^2 / R, D the receiver's distance from the centre: b^2 - ac near
    /// a tangent may report a hit about 2e-7 D^2 / R beyond the sphere,
    /// 16 times that stretched 4x (the most a sphere given a disc may be).
    Sphere(DVec3, f64),
    /// Anything else (cylinders, cones and stretched spheres, whose
    /// quadratics round by their own radii; moving instances): 1e-3 of
    /// the receiver's distance from this point (its world box's centre),
    /// a hit up to D / r = 8,000 times f32's epsilon beyond a surface of
    /// radius r.
    Far(DVec3),
}

impl Slack {
    /// The slack for receivers at `points` (world).
    fn at(self, points: &[Vec3]) -> f64 {
        let farthest =
            |c: DVec3| (points.iter()).fold(0.0f64, |m, p| m.max(p.as_dvec3().distance(c)));
        match self {
            Slack::None => 0.0,
            Slack::Sphere(c, r) => {
                let sizes =
                    (points.iter()).fold(0.0f64, |m, p| m.max(p.as_dvec3().abs().element_sum()));
                let d = farthest(c);
                1e-5 * (r + c.abs().element_sum() + sizes) + 6.4e-5 * d * d / r
            }
            Slack::Far(c) => 1e-3 * farthest(c),
        }
    }
}

/// The shadows of `occluders` (instances of `accel`) across `to_light`
/// (axes `u`, `v`): points holding each one, projected (a static sphere
/// or CSG solid: the octagon around its bounding sphere's disc; a static
/// box: its corners; a static mesh within the footprint budget: its
/// triangles' corners; anything else: its world box's corners, over the
/// shutter); each hull grown by `pad`. `None` past [`MAX_SHADES`].
fn shades(
    accel: &SceneAccel,
    occluders: &[Occluder],
    to_light: Vec3,
    (u, v): (Vec3, Vec3),
    pad: f64,
) -> Option<Vec<Shade>> {
    if occluders.len() > MAX_SHADES {
        return None;
    }
    let (u, v, l) = (u.as_dvec3(), v.as_dvec3(), to_light.as_dvec3());
    let shade = |b: &Occluder| {
        let k = b.instance as usize;
        let (world_from_object, _, shape) = accel.instances[k];
        let shape = accel.shapes[shape as usize];
        let mut world: Vec<DVec3> = Vec::new();
        let mut disc = None;
        let mut slack = Slack::None;
        if accel.moving[k] {
            world.extend(b.bounds.corners().map(|c| c.as_dvec3()));
            slack = Slack::Far(b.bounds.centre().as_dvec3());
        } else if let Some(sphere) = (world_sphere(&shape, world_from_object))
            // A sphere stretched too far for the kernel's margin has none
            // (bounding_sphere), as in the occluder lists.
            .filter(|_| shape.kind != SHAPE_SPHERE || bounding_sphere(accel, k).w > 0.0)
        {
            let (c, r) = (sphere.xyz().as_dvec3(), f64::from(sphere.w));
            disc = Some((c, r));
            slack = Slack::Sphere(c, r);
        } else if shape.kind == SHAPE_BOX {
            let h = Vec3::from_slice(&shape.params[..3]);
            let corners = Aabb { min: -h, max: h }.corners();
            world.extend(corners.map(|c| world_from_object.transform_point3(c).as_dvec3()));
        } else if !b.triangles.is_empty() {
            world.extend((b.triangles.iter()).flat_map(|(_, t)| t.map(|p| p.as_dvec3())));
        } else {
            world.extend(b.bounds.corners().map(|c| c.as_dvec3()));
            if shape.kind != SHAPE_MESH {
                slack = Slack::Far(b.bounds.centre().as_dvec3());
            }
        }
        let mut points: Vec<DVec2> = world
            .iter()
            .map(|p| DVec2::new(u.dot(*p), v.dot(*p)))
            .collect();
        let mut top = world
            .iter()
            .map(|p| p.dot(l))
            .fold(f64::NEG_INFINITY, f64::max);
        if let Some((c, r)) = disc {
            // The octagon around the disc: corners at r / cos 22.5 degrees.
            let centre = DVec2::new(u.dot(c), v.dot(c));
            let reach = r / std::f64::consts::FRAC_PI_8.cos();
            points.extend((0..8).map(|i| {
                let a = f64::from(i) * std::f64::consts::FRAC_PI_4;
                centre + reach * DVec2::new(a.cos(), a.sin())
            }));
            top = c.dot(l) + r;
        }
        // Its hull's corners stand for it: a mesh has thousands of points.
        let points = hull_vertices(&mut points);
        let edges = convex_hull(&mut points.clone())
            .into_iter()
            .map(|(n, c)| (n, c + pad))
            .collect();
        let lo = points.iter().fold(DVec2::INFINITY, |a, p| a.min(*p)) - pad;
        let hi = points.iter().fold(DVec2::NEG_INFINITY, |a, p| a.max(*p)) + pad;
        Shade {
            points,
            edges,
            top,
            lo,
            hi,
            slack,
        }
    };
    Some(occluders.iter().map(shade).collect())
}

/// Where a light's shadow rays meet nothing over whole regions of
/// receivers: the question the CPU asks for the trace pass's tiles
/// (`TILE_UNSHADOWED`), answered from the kernel's `shadow_query` data
/// (its static planes and grid) and from the occluders' shadows, with
/// margins for the kernel's rounding.
#[derive(Debug, Clone, PartialEq)]
pub struct CulledRegions {
    cull: GpuShadowCull,
    to_light: Vec3,
    /// Per grid cell (x, y), the number of non-empty cells at x' < x and
    /// y' < y: a summed-area table of (dims.x + 1) x (dims.y + 1).
    occupied: Vec<u32>,
    /// Every occluder of the grid's shadow, where there are few enough.
    shades: Option<Vec<Shade>>,
    /// The grid's margin across the light (world units).
    pad: f64,
}

impl CulledRegions {
    /// For the light whose cull record is `cull` (its cells in `cells`),
    /// whose shadow rays all run along `to_light` (a directional light's),
    /// with its occluders' `shades` and margin `pad`; `None` where the
    /// light's rays are not culled (`enabled` 0).
    fn new(
        cull: &GpuShadowCull,
        cells: &[u32],
        to_light: Vec3,
        shades: Option<Vec<Shade>>,
        pad: f64,
    ) -> Option<Self> {
        if cull.enabled == 0 {
            return None;
        }
        let (w, h) = (cull.dims[0] as usize, cull.dims[1] as usize);
        let mut occupied = vec![0u32; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = 0;
            for x in 0..w {
                row += u32::from(cells[cull.first_cell as usize + y * w + x] != 0);
                occupied[(y + 1) * (w + 1) + x + 1] = occupied[y * (w + 1) + x + 1] + row;
            }
        }
        Some(CulledRegions {
            cull: *cull,
            to_light,
            occupied,
            shades,
            pad,
        })
    }

    /// Whether the shadow ray from every point of the convex hull of
    /// `points` meets nothing: every static plane lies behind all of them,
    /// by twice the kernel's margin (its side is linear over the hull, its
    /// margin convex, so the corners bound both), and either every grid
    /// cell that the hull's image on the grid may touch, grown by a cell
    /// for the kernel's rounding, is empty or off the grid (then
    /// `shadow_query` culls every such ray: answers `SHADOW_SKIP`), or
    /// every occluder's shadow misses the hull's ([`Self::shades_miss`]).
    /// False where unsure.
    pub fn all_culled(&self, points: &[Vec3]) -> bool {
        let cull = &self.cull;
        for row in &cull.planes[..(cull.plane_count as usize).min(cull.planes.len())] {
            let r = glam::Vec4::from_array(*row);
            let along = r.xyz().dot(self.to_light);
            let along_err = PLANE_MARGIN * r.xyz().abs().dot(self.to_light.abs());
            let (mut lo, mut hi, mut err) = (f32::INFINITY, f32::NEG_INFINITY, 0.0f32);
            for p in points {
                let side = r.xyz().dot(*p) + r.w;
                lo = lo.min(side);
                hi = hi.max(side);
                err = err.max(PLANE_MARGIN * (r.xyz().abs().dot(p.abs()) + r.w.abs()));
            }
            let behind = (lo > 2.0 * err && along > 2.0 * along_err)
                || (hi < -2.0 * err && along < -2.0 * along_err);
            if !behind {
                return false;
            }
        }
        let (w, h) = (cull.dims[0] as usize, cull.dims[1] as usize);
        let u = glam::Vec4::from_array(cull.u);
        let v = glam::Vec4::from_array(cull.v);
        let scale = Vec2::from_array(cull.cells_per_unit);
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for p in points {
            let g = Vec2::new(u.xyz().dot(*p) - u.w, v.xyz().dot(*p) - v.w) * scale;
            if !g.is_finite() {
                return false;
            }
            lo = lo.min(g);
            hi = hi.max(g);
        }
        let (lo, hi) = (lo - 1.0, hi + 1.0);
        let dims = Vec2::new(w as f32, h as f32);
        if w == 0 || h == 0 || hi.x < 0.0 || hi.y < 0.0 || lo.x >= dims.x || lo.y >= dims.y {
            return true;
        }
        let (x0, y0) = (lo.x.max(0.0) as usize, lo.y.max(0.0) as usize);
        let (x1, y1) = (
            (hi.x.min(dims.x - 1.0) as usize) + 1,
            (hi.y.min(dims.y - 1.0) as usize) + 1,
        );
        let at = |x: usize, y: usize| self.occupied[y * (w + 1) + x];
        at(x1, y1) + at(x0, y0) == at(x0, y1) + at(x1, y0) || self.shades_miss(points)
    }

    /// Whether no line from a point of the convex hull of `points` along
    /// the light meets an occluder's shadow towards the light: each
    /// occluder lies wholly behind every point (farther from the light,
    /// by the margin), or an edge of its shadow's hull or of the points'
    /// projected hull separates the two (the separating axis test, over
    /// the edges alone: a pair it cannot separate is not proven). The
    /// margin covers the kernel's rounding of its ray as the grid's does,
    /// and of its test of the occluder ([`Slack`]).
    fn shades_miss(&self, points: &[Vec3]) -> bool {
        let Some(shades) = &self.shades else {
            return false;
        };
        let u = glam::Vec4::from_array(self.cull.u).xyz().as_dvec3();
        let v = glam::Vec4::from_array(self.cull.v).xyz().as_dvec3();
        let l = self.to_light.as_dvec3();
        let mut across = [DVec2::ZERO; 8];
        let Some(across) = across.get_mut(..points.len()) else {
            return false;
        };
        for (q, p) in across.iter_mut().zip(points) {
            *q = DVec2::new(u.dot(p.as_dvec3()), v.dot(p.as_dvec3()));
        }
        let nearest = (points.iter()).fold(f64::INFINITY, |m, p| m.min(p.as_dvec3().dot(l)));
        // Beyond the grid's margin, one for the points' own coordinates: a
        // receiver far out on a wide floor casts its ray far across the
        // occluders, whose tests round relative to that distance.
        let far = (points.iter()).fold(0.0f64, |m, p| m.max(f64::from(p.abs().max_element())));
        let extra = 1e-4 * far;
        let lo = across.iter().fold(DVec2::INFINITY, |a, q| a.min(*q)) - extra;
        let hi = across.iter().fold(DVec2::NEG_INFINITY, |a, q| a.max(*q)) + extra;
        let beyond =
            |(n, c): &(DVec2, f64), qs: &[DVec2], pad: f64| qs.iter().all(|q| n.dot(*q) > c + pad);
        // The points' hull, made only for an occluder the cheap tests keep.
        let mut edges = None;
        shades.iter().all(|s| {
            if s.points.is_empty() {
                return false;
            }
            let slack = s.slack.at(points);
            if s.top + self.pad + extra + slack < nearest
                || (s.lo - slack).cmpgt(hi).any()
                || (s.hi + slack).cmplt(lo).any()
                || s.edges.iter().any(|e| beyond(e, across, extra + slack))
            {
                return true;
            }
            let edges = edges.get_or_insert_with(|| convex_hull(&mut across.to_vec()));
            let pad = self.pad + extra + slack;
            edges.iter().any(|e| beyond(e, &s.points, pad))
        })
    }
}

/// The CPU twin of the trace kernel's `shadow_may_be_blocked`: whether the
/// shadow ray from `origin` along `to_light` may meet an occluder. False
/// only where it provably meets none. `leaving`: the instance whose outside
/// the ray starts from, on the side facing the light (else `u32::MAX`).
pub fn may_be_blocked(
    cull: &GpuShadowCull,
    cells: &[u32],
    origin: Vec3,
    to_light: Vec3,
    leaving: u32,
) -> bool {
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
    let cell = match grid_cell(cull, cells, origin) {
        GridCell::Outside => return false,
        GridCell::NotANumber => return true,
        GridCell::Word(w) => w,
    };
    if let Some((list, convex, triangles)) = list_at_cell(cells, cell) {
        // The kernel's list test skips the lone convex solid left.
        return triangles.is_some() || list.iter().any(|&j| !(convex && j == leaving));
    }
    cell != 0 && cell != leaving.wrapping_add(1)
}

/// A cell's list: its whole occluders, whether all are spheres or boxes,
/// and the mesh instance whose triangles it lists with those triangles.
type CellOccluders<'a> = (&'a [u32], bool, Option<(u32, &'a [u32])>);

/// The list of a cell whose word is one ([`CULL_CELL_LIST`]).
fn list_at_cell(cells: &[u32], cell: u32) -> Option<CellOccluders<'_>> {
    if cell == CULL_CELL_MANY || cell & CULL_CELL_LIST == 0 {
        return None;
    }
    let at = (cell & !CULL_CELL_LIST) as usize;
    let header = cells[at];
    let count = (header & (SHADOW_LIST_CONVEX - 1)) as usize;
    let triangles = (header >> CELL_LIST_TRIANGLE_SHIFT) as usize;
    let mesh =
        (triangles > 0).then(|| (cells[at + 1 + count], &cells[at + 2 + count..][..triangles]));
    Some((
        &cells[at + 1..][..count],
        header & SHADOW_LIST_CONVEX != 0,
        mesh,
    ))
}

/// The CPU twin of the cell half of the trace kernel's `shadow_query`:
/// where the cell the shadow ray from `origin` starts in lists its
/// occluders, those instances, whether all are convex (then the one a ray
/// leaves from is skipped), and the mesh triangles it lists; None where
/// the ray is culled, answered by its receiver's list or walks.
pub fn cell_occluders<'a>(
    cull: &GpuShadowCull,
    cells: &'a [u32],
    origin: Vec3,
) -> Option<CellOccluders<'a>> {
    if cull.enabled == 0 {
        return None;
    }
    match grid_cell(cull, cells, origin) {
        GridCell::Word(w) => list_at_cell(cells, w),
        GridCell::Outside | GridCell::NotANumber => None,
    }
}

/// Where a shadow ray's origin falls on its light's grid.
enum GridCell {
    /// Off the grid: no occluder's footprint reaches it.
    Outside,
    /// A NaN origin, which every comparison fails (the kernel casts it).
    NotANumber,
    /// The word of the cell it starts in.
    Word(u32),
}

/// The cell of `cull`'s grid that `origin` falls in, as the trace
/// kernel's `shadow_query` finds it.
fn grid_cell(cull: &GpuShadowCull, cells: &[u32], origin: Vec3) -> GridCell {
    let u = glam::Vec4::from_array(cull.u);
    let v = glam::Vec4::from_array(cull.v);
    let g = Vec2::new(u.xyz().dot(origin) - u.w, v.xyz().dot(origin) - v.w)
        * Vec2::from_array(cull.cells_per_unit);
    let dims = Vec2::new(cull.dims[0] as f32, cull.dims[1] as f32);
    if g.x < 0.0 || g.y < 0.0 || g.x >= dims.x || g.y >= dims.y {
        return GridCell::Outside;
    }
    if g.is_nan() {
        return GridCell::NotANumber;
    }
    GridCell::Word(cells[(cull.first_cell + g.y as u32 * cull.dims[0] + g.x as u32) as usize])
}

/// The CPU twin of the list half of the trace kernel's `shadow_query`:
/// where `receiver` has an occluder list for this light, its instances and
/// whether the receiver is convex (then a ray leaving its lit outside
/// cannot meet it); None where its shadow rays walk the BVH.
pub fn occluder_list<'a>(
    cull: &GpuShadowCull,
    cells: &'a [u32],
    receiver: u32,
) -> Option<(&'a [u32], bool)> {
    if cull.enabled == 0 || cull.first_list == 0 {
        return None;
    }
    let words = SHADOW_LIST_WORDS as usize;
    let record = &cells[cull.first_list as usize + receiver as usize * words..][..words];
    if record[0] == SHADOW_LIST_WALK {
        return None;
    }
    let count = (record[0] & (SHADOW_LIST_CONVEX - 1)) as usize;
    Some((&record[1..=count], record[0] & SHADOW_LIST_CONVEX != 0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    /// A floor quad, a tilted quad, a disk below the floor, boxes, spheres
    /// (stretched, shrunk, moving), a cylinder, a stretched CSG solid and
    /// the spot mesh (its triangles projected one by one), under one
    /// directional light.
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
                    "holed": Difference(Box(half_extents: (0.6, 0.6, 0.6)), Sphere(radius: 0.75)),
                    "cow": Mesh(path: "assets/models/spot/spot_triangulated.obj"),
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
                    (shape: "holed", material: "m", transform: (translate: (-1.0, 1.2, -3.0), rotate_deg: (20.0, 40.0, 0.0), scale: (1.5, 0.7, 1.0))),
                    (shape: "ball", material: "m", transform: (translate: (3.0, 1.5, 2.5), scale: (0.5, 0.5, 0.5))),
                    (shape: "cow", material: "m", transform: (translate: (-3.5, 0.737, 3.0), rotate_deg: (0.0, 145.0, 0.0))),
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

    /// Whether the first light's shadow ray from `o` along `l` is culled;
    /// where it is, the CPU tracer must find no hit along it.
    fn culled_meets_nothing(
        cull: &ShadowCull,
        accel: &SceneAccel,
        o: Vec3,
        l: Vec3,
        leaving: u32,
    ) -> bool {
        if may_be_blocked(&cull.lights[0], &cull.cells, o, l, leaving) {
            return false;
        }
        let hit = accel.closest_hit(o, l, 0.0, f32::INFINITY).hit;
        assert!(
            hit.is_none(),
            "the ray from {o} along {l} (leaving {leaving}) was culled but meets {hit:?}"
        );
        true
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
            let cull = build(&accel, &scene.lights, true);
            let Light::Directional { direction, .. } = scene.lights[0] else {
                unreachable!()
            };
            let l = -direction.normalize();
            let mut origins = points(4000, 6.0);
            origins.extend(points(4000, 6.0).iter().map(|p| Vec3::new(p.x, 1e-3, p.z)));
            let (mut culled, mut cast) = (0, 0);
            for o in origins {
                match culled_meets_nothing(&cull, &accel, o, l, u32::MAX) {
                    true => culled += 1,
                    false => cast += 1,
                }
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
        let cull = build(&accel, &scene.lights, true);
        let l = Vec3::new(0.5, 1.0, 0.6).normalize();
        let c = &cull.lights[0];
        assert_eq!(c.enabled, 1);
        assert_eq!(c.plane_count, 3, "floor, wall and disk are static planes");
        let above = Vec3::new(-10.0, 1e-3, 15.0);
        assert!(!may_be_blocked(c, &cull.cells, above, l, u32::MAX));
        let below = Vec3::new(-10.0, -1e-3, 15.0);
        assert!(accel
            .closest_hit(below, l, 0.0, f32::INFINITY)
            .hit
            .is_some());
        assert!(may_be_blocked(c, &cull.cells, below, l, u32::MAX));
        // A ray from the floor under the raised ball passes through it.
        let under_ball = Vec3::new(-1.0, 1e-3, 0.0) - l * (0.5 / l.y);
        assert!(accel
            .closest_hit(under_ball, l, 0.0, f32::INFINITY)
            .hit
            .is_some());
        assert!(may_be_blocked(c, &cull.cells, under_ball, l, u32::MAX));
    }

    /// Rays leaving the lit outside of a sphere, a stretched sphere, a
    /// moving sphere or a turned box, offset along the normal as the kernel
    /// does, are culled where the solid is alone in its cell, and the CPU
    /// tracer finds no hit along any culled one. A cell names only a sphere
    /// or a box, never the cylinder or the planes. It fails if the tag is
    /// ignored, or given to other shapes.
    #[test]
    fn a_ray_leaving_a_lone_convex_solid_is_culled() {
        let (scene, accel) = scene("(-0.5, -1.0, -0.6)");
        let cull = build(&accel, &scene.lights, true);
        let l = Vec3::new(0.5, 1.0, 0.6).normalize();
        let eps = 1e-3;
        let dirs = points(3000, 1.0);
        // The grids of the scene's 3 lights (its lists are not filled:
        // two lights cast shadows).
        let grids = 3 * CELLS_PER_LIGHT;
        assert!(cull.cells[..grids]
            .iter()
            .any(|&c| c != 0 && c != CULL_CELL_MANY));
        for &cell in &cull.cells[..grids] {
            if cell != 0 && cell != CULL_CELL_MANY {
                let kind = accel.shapes[accel.instances[cell as usize - 1].2 as usize].kind;
                assert!(
                    kind == SHAPE_SPHERE || kind == SHAPE_BOX,
                    "cell {cell}: kind {kind}"
                );
            }
        }
        for (k, unit) in [(3usize, 0.5), (4, 0.5), (5, 0.5), (6, 0.0)] {
            let (world_from_object, object_from_world, _) = accel.instances[k];
            let normal_from_object = object_from_world.transpose();
            let (mut culled, mut cast) = (0, 0);
            for d in &dirs {
                // A point on the surface in object space, and its normal.
                let (p, n) = match k {
                    3..=5 => {
                        let n = d.normalize_or(Vec3::Y);
                        (n * unit, n)
                    }
                    _ => {
                        let h = Vec3::new(0.4, 0.3, 0.5);
                        let axis = (d.abs() / h).max_position();
                        let mut n = Vec3::ZERO;
                        n[axis] = d[axis].signum();
                        let mut p = *d * h;
                        p[axis] = n[axis] * h[axis];
                        (p, n)
                    }
                };
                let n = normal_from_object.transform_vector3(n).normalize();
                if n.dot(l) <= 0.0 {
                    continue;
                }
                let o = world_from_object.transform_point3(p) + n * eps;
                match culled_meets_nothing(&cull, &accel, o, l, k as u32) {
                    true => culled += 1,
                    false => cast += 1,
                }
            }
            assert!(culled > 300, "instance {k}: culled {culled}, cast {cast}");
        }
    }

    /// Rays that pass a sphere 0.999 of its radius from its centre meet it,
    /// so none may be culled, on any side: the cells that the sphere's
    /// circle only clips at a corner must be marked too. The rays start
    /// below the sphere (along -l), on the floor's lit side.
    #[test]
    fn rays_grazing_a_sphere_are_never_culled() {
        let (scene, accel) = scene("(-0.5, -1.0, -0.6)");
        let cull = build(&accel, &scene.lights, true);
        let l = Vec3::new(0.5, 1.0, 0.6).normalize();
        let (u, v) = l.any_orthonormal_pair();
        // The ball at (-1, 0.5, 0) of radius 0.5, and the shrunk ball at
        // (3, 1.5, 2.5) of radius 0.25.
        for (centre, radius) in [
            (Vec3::new(-1.0, 0.5, 0.0), 0.5),
            (Vec3::new(3.0, 1.5, 2.5), 0.25),
        ] {
            for k in 0..720 {
                let a = k as f32 / 720.0 * std::f32::consts::TAU;
                let o = centre + (u * a.cos() + v * a.sin()) * (0.999 * radius) - l * 0.4;
                let hit = accel.closest_hit(o, l, 0.0, f32::INFINITY);
                assert!(hit.hit.is_some(), "the ray from {o} should graze the ball");
                assert!(
                    may_be_blocked(&cull.lights[0], &cull.cells, o, l, u32::MAX),
                    "the ray from {o} grazing the ball at {centre} was culled"
                );
            }
        }
    }

    /// A mesh marks the cells of its triangles' projections, not its box's:
    /// floor points whose shadow ray crosses the cow's box but misses the
    /// cow are culled (many of them), and no culled ray meets anything.
    #[test]
    fn a_mesh_marks_only_its_triangles_footprint() {
        let (scene, accel) = scene("(-0.5, -1.0, -0.6)");
        let cull = build(&accel, &scene.lights, true);
        let l = Vec3::new(0.5, 1.0, 0.6).normalize();
        let cow = accel.instances.len() - 1;
        let b = accel.world_bounds[cow];
        let (mut culled_in_box, mut in_box) = (0, 0);
        for i in 0..120 {
            for j in 0..120 {
                // Floor points under the cow's box, seen along the light.
                let o = Vec3::new(-6.5 + 0.04 * i as f32, 1e-3, 0.0 + 0.04 * j as f32);
                let culled = culled_meets_nothing(&cull, &accel, o, l, u32::MAX);
                if crate::accel::intersect::ray_box(o, l.recip(), b.min, b.max, 0.0, f32::INFINITY)
                    .is_some()
                {
                    in_box += 1;
                    culled_in_box += usize::from(culled);
                }
            }
        }
        assert!(in_box > 2000, "{in_box} rays cross the cow's box");
        assert!(
            culled_in_box > in_box / 4,
            "{culled_in_box} of {in_box} culled"
        );
    }

    /// Every box and static sphere lies inside its world bounding sphere,
    /// which the kernel's list test uses to skip occluders a ray misses:
    /// points over each sphere, taken to world space, and the corners of
    /// each box's world box are within the radius, to 1e-6 of it (the f32
    /// rounding of the transform, a few ulp). The spheres are tight: a
    /// ball only moved or scaled uniformly gets its own radius (0.5,
    /// 0.25), a ball stretched 2x along x twice its radius. A moving ball,
    /// the cylinder, the CSG solid, the planes and the mesh get none (-1).
    #[test]
    fn bounding_spheres_hold_their_instances() {
        let (_, accel) = scene("(-0.5, -1.0, -0.6)");
        let on_sphere = points(200, 1.0);
        for k in 0..accel.instances.len() {
            let s = bounding_sphere(&accel, k);
            let inside = |p: Vec3| {
                let d = p.distance(s.xyz());
                assert!(
                    d <= s.w * (1.0 + 1e-6),
                    "instance {k}: {p} is {d} from the centre, radius {}",
                    s.w
                );
            };
            let (world_from_object, _, shape) = accel.instances[k];
            let shape = accel.shapes[shape as usize];
            match shape.kind {
                SHAPE_SPHERE if !accel.moving[k] => on_sphere
                    .iter()
                    .filter(|p| p.length() > 1e-3)
                    .for_each(|p| {
                        inside(world_from_object.transform_point3(p.normalize() * shape.params[0]))
                    }),
                SHAPE_BOX => accel.world_bounds[k].corners().into_iter().for_each(inside),
                _ => assert_eq!(
                    s.w, -1.0,
                    "instance {k} (kind {}) gets no sphere",
                    shape.kind
                ),
            }
        }
        for (k, radius) in [(3, 0.5), (9, 0.25), (4, 1.0), (5, -1.0), (7, -1.0)] {
            let r = bounding_sphere(&accel, k).w;
            assert!(
                (r - radius).abs() <= 1e-6,
                "instance {k}: radius {r}, not {radius}"
            );
        }
    }

    /// Point lights and lights that cast no shadows keep every ray. The
    /// lists' room is there for every light, but filled only where exactly
    /// one light, a directional one, casts shadows (`lists_read`): here the
    /// point light casts shadows too, until it is made not to.
    #[test]
    fn only_shadow_casting_directional_lights_cull() {
        let (scene, accel) = scene("(-0.5, -1.0, -0.6)");
        let cull = build(&accel, &scene.lights, true);
        assert_eq!(cull.lights.len(), 3);
        let lists = accel.instances.len() * SHADOW_LIST_WORDS as usize;
        // The bounding spheres, then the room for one light's cell lists.
        let spheres = 4 * accel.instances.len() + CELL_LIST_ROOM;
        assert_eq!(cull.cells.len(), 3 * (CELLS_PER_LIGHT + lists) + spheres);
        assert!(!lists_read(&accel, &scene.lights));
        assert_eq!(cull.lights[0].first_list, 0, "two lights cast shadows");
        assert_eq!(cull.lights[0].first_sphere, 0);
        assert!(cull.cells[3 * CELLS_PER_LIGHT..][..3 * lists]
            .iter()
            .all(|&w| w == SHADOW_LIST_WALK));
        let mut one_sun = scene.lights.clone();
        if let Light::Point { cast_shadows, .. } = &mut one_sun[1] {
            *cast_shadows = false;
        }
        assert!(lists_read(&accel, &one_sun));
        let cull = build(&accel, &one_sun, true);
        // After the grids, lists and spheres: room for the sun's cell lists.
        let cell_words: usize = cull.cells[..CELLS_PER_LIGHT]
            .iter()
            .filter_map(|&w| list_at_cell(&cull.cells, w))
            .map(|(list, _, mesh)| 1 + list.len() + mesh.map_or(0, |(_, t)| 1 + t.len()))
            .sum();
        assert!(cell_words > 0, "the sun's cells list their occluders");
        let room = 3 * (CELLS_PER_LIGHT + lists) + 4 * accel.instances.len();
        for &w in &cull.cells[..CELLS_PER_LIGHT] {
            if list_at_cell(&cull.cells, w).is_some() {
                assert!(
                    (w & !CULL_CELL_LIST) as usize >= room,
                    "a list outside its room"
                );
            }
        }
        assert_eq!(cull.cells.len(), 3 * (CELLS_PER_LIGHT + lists) + spheres);
        assert_eq!(cull.lights[0].first_list as usize, 3 * CELLS_PER_LIGHT);
        assert_eq!(
            cull.lights[0].first_sphere as usize,
            3 * (CELLS_PER_LIGHT + lists)
        );
        assert_eq!(cull.lights[1].first_list, 0, "a point light has no lists");
        // Past the first MAX_CULL_LIGHTS lights, none is culled.
        let many = vec![scene.lights[0].clone(); MAX_CULL_LIGHTS + 2];
        let cull_many = build(&accel, &many, true);
        assert_eq!(
            cull_many.cells.len(),
            MAX_CULL_LIGHTS * (CELLS_PER_LIGHT + lists) + spheres
        );
        assert_eq!(cull_many.lights[MAX_CULL_LIGHTS - 1].enabled, 1);
        assert_eq!(cull_many.lights[MAX_CULL_LIGHTS].enabled, 0);
        assert_eq!(cull.lights[1].enabled, 0);
        assert_eq!(cull.lights[2].enabled, 0);
        assert!(may_be_blocked(
            &cull.lights[1],
            &cull.cells,
            Vec3::new(-10.0, 1e-3, 15.0),
            Vec3::Y,
            u32::MAX
        ));
    }

    /// Close-packed analytic solids (spheres, stretched spheres, turned
    /// boxes, cylinders, cones) at uneven heights on a 7 x 7 grid, a low
    /// light, so that many cast shadows on their neighbours; a CSG solid
    /// and the spot mesh among them; a floor.
    fn packed_scene() -> (Scene, SceneAccel) {
        let kinds = ["ball", "egg", "crate", "post", "cone"];
        let mut instances = vec![
            r#"(shape: "floor", material: "m")"#.to_string(),
            r#"(shape: "holed", material: "m", transform: (translate: (7.5, 0.8, 3.0)))"#
                .to_string(),
            r#"(shape: "cow", material: "m", transform: (translate: (-1.5, 0.737, 3.0)))"#
                .to_string(),
        ];
        for i in 0..49 {
            let (x, z) = ((i % 7) as f32 * 1.1, (i / 7) as f32 * 1.1);
            let y = 0.5 + 0.3 * ((i * 7 % 5) as f32);
            let turn = (i * 37 % 90) as f32;
            instances.push(format!(
                r#"(shape: "{}", material: "m", transform: (translate: ({x}, {y}, {z}), rotate_deg: ({turn}, {turn}, 0.0)))"#,
                kinds[i % kinds.len()]
            ));
        }
        let ron = format!(
            r#"(version: 1,
                camera: (eye: (3.0, 6.0, 12.0), target: (3.0, 0.0, 3.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 64, height: 64),
                lights: [Directional(direction: (-0.6, -1.0, -0.4), color: (1.0, 1.0, 1.0), intensity: 1.0)],
                materials: {{ "m": (base_color: (0.8, 0.8, 0.8), model: BlinnPhong) }},
                shapes: {{
                    "floor": Plane(Quad(half_size: (20.0, 20.0))),
                    "ball": Sphere(radius: 0.5),
                    "egg": Sphere(radius: 0.4),
                    "crate": Box(half_extents: (0.4, 0.3, 0.35)),
                    "post": Cylinder(radius: 0.3, height: 1.2),
                    "cone": Cone(radius: 0.4, height: 1.0),
                    "holed": Difference(Box(half_extents: (0.6, 0.6, 0.6)), Sphere(radius: 0.75)),
                    "cow": Mesh(path: "assets/models/spot/spot_triangulated.obj"),
                }},
                instances: [{}],
            )"#,
            instances.join(",\n")
        );
        let scene = Scene::from_ron_str(&ron, "test", std::path::Path::new(".")).unwrap();
        let order: Vec<usize> = (0..scene.instances.len()).collect();
        let accel = SceneAccel::build(&scene, &order).unwrap();
        (scene, accel)
    }

    /// The packed scene with its lists, the direction towards its sun, and
    /// the offset along the normal that the kernel gives a shadow ray
    /// (1e-4 of the scene's half diagonal).
    fn packed_with_lists() -> (SceneAccel, ShadowCull, Vec3, f32) {
        let (scene, accel) = packed_scene();
        let cull = build(&accel, &scene.lights, true);
        let (lo, hi) = scene.bounds();
        let eps = (hi - lo).length() * 0.5 * 1e-4;
        (accel, cull, Vec3::new(0.6, 1.0, 0.4).normalize(), eps)
    }

    /// The shadow ray from `o` met `hit`: it must be in the `list` the ray
    /// was given, and not the convex instance it leaves where the list
    /// skips that (`convex`).
    fn assert_hit_listed(o: Vec3, hit: u32, list: &[u32], convex: bool, leaving: u32) {
        assert!(
            list.contains(&hit),
            "the shadow ray from {o} meets {hit} outside its list {list:?}"
        );
        assert!(
            !(convex && hit == leaving),
            "the ray from {o} leaving convex instance {leaving} meets it"
        );
    }

    /// The same property for the cells' lists: a shadow ray starting in a
    /// cell that lists its occluders (here from 18,000 floor points across
    /// the solids and the cow's shadow, and from the solids' own surfaces, offset as the
    /// kernel offsets it) can only meet instances of that list, and never
    /// the convex solid it leaves where the list is all convex. The CPU
    /// tracer's closest hit along each ray must be listed. It fails if a
    /// cell's list misses an occluder whose footprint lands on it (a wrong
    /// cell index, footprint or margin), or a list points at the wrong
    /// words. The CSG solid (evaluated by its truth table) is listed, and
    /// where the cow's triangles are few enough, those: a ray that meets
    /// the cow there must meet one of them, tested as the kernel tests
    /// them (the cow's object space, the shear of its root's bounds).
    #[test]
    fn a_shadow_ray_meets_only_its_cells_occluders() {
        let (accel, cull, l, eps) = packed_with_lists();
        let c = &cull.lights[0];
        // Shadow ray origins: (origin, the instance it leaves or MAX).
        let mut origins: Vec<(Vec3, u32)> = Vec::new();
        for i in 0..150 {
            for j in 0..120 {
                let (x, z) = (-4.5 + 0.092 * i as f32, -1.5 + 0.09 * j as f32);
                origins.push((Vec3::new(x, eps, z), u32::MAX));
            }
        }
        for k in 0..accel.instances.len() as u32 {
            let b = accel.world_bounds[k as usize];
            let centre = (b.min + b.max) * 0.5;
            for d in points(300, 1.0) {
                let d = d.normalize_or(Vec3::Y);
                let from = centre + d * 3.0;
                let Some(h) = accel.closest_hit(from, -d, 0.0, 10.0).hit else {
                    continue;
                };
                if h.instance == k && h.geometric.dot(l) > 0.0 {
                    origins.push((from - d * h.t + h.geometric * eps, k));
                }
            }
        }
        let (mut listed, mut blocked, mut by_csg, mut by_mesh) = (0, 0, 0, 0);
        for (o, leaving) in origins {
            let Some((list, convex, mesh)) = cell_occluders(c, &cull.cells, o) else {
                continue;
            };
            listed += 1;
            let Some(hit) = accel.closest_hit(o, l, 0.0, f32::INFINITY).hit else {
                continue;
            };
            blocked += 1;
            by_csg += usize::from(hit.instance == 1);
            if let Some((m, triangles)) = mesh.filter(|&(m, _)| m == hit.instance) {
                // The listed triangles alone block the ray, tested as the
                // kernel tests them.
                let (_, object_from_world, shape) = accel.instances[m as usize];
                let root = accel.nodes[accel.shapes[shape as usize].blas_root as usize];
                let ray = crate::accel::intersect::TriangleRay::new(
                    object_from_world.transform_point3(o),
                    object_from_world.transform_vector3(l),
                    Vec3::from(root.bounds_min),
                    Vec3::from(root.bounds_max),
                );
                // Every triangle of the mesh that the ray meets is listed
                // (all of them tested, not only the BVH's).
                let meets = |k: u32| {
                    let t = &accel.triangles[k as usize];
                    crate::accel::intersect::triangle(&ray, t, 0.0, f32::INFINITY).is_some()
                };
                let all = mesh_triangles(&accel, accel.shapes[shape as usize].blas_root);
                let met: Vec<u32> = all.iter().map(|&(k, _)| k).filter(|&k| meets(k)).collect();
                assert!(
                    !met.is_empty(),
                    "the CPU tracer's mesh hit from {o} is no triangle's"
                );
                for k in met {
                    assert!(
                        triangles.contains(&k),
                        "the shadow ray from {o} meets triangle {k}, not in its cell's list"
                    );
                }
                by_mesh += 1;
                continue;
            }
            assert_hit_listed(o, hit.instance, list, convex, leaving);
        }
        let lists = (0..CELLS_PER_LIGHT)
            .filter(|&i| list_at_cell(&cull.cells, cull.cells[i]).is_some())
            .count();
        assert!(lists >= 500, "{lists} cells have lists");
        assert!(
            listed >= 5000 && blocked >= 1000 && by_csg >= 20 && by_mesh >= 20,
            "{listed} rays start in listed cells, {blocked} of them blocked, \
             {by_csg} by the CSG solid, {by_mesh} by the mesh's listed triangles"
        );
    }

    /// The property the kernel's list test relies on: a shadow ray from the
    /// surface of an instance that has a list (offset along the normal as
    /// the kernel offsets it, on either side of the surface) can only meet
    /// the instances of that list, never the convex receiver itself when it
    /// leaves its outside. Surface points are found by the CPU tracer (rays
    /// aimed at each instance's centre from all sides); the CPU tracer's
    /// closest hit along each shadow ray must be in the list. It fails if
    /// the footprints, the overlap test, the light-side filter or the
    /// receiver's margin are too tight, or a record lands at the wrong
    /// instance.
    #[test]
    fn a_shadow_ray_meets_only_its_receivers_occluders() {
        let (accel, cull, l, eps) = packed_with_lists();
        let c = &cull.lights[0];
        let dirs = points(1000, 1.0);
        let (mut listed, mut long_lists, mut by_others, mut from_inside) = (0, 0, 0, 0);
        for k in 0..accel.instances.len() as u32 {
            let Some((list, convex)) = occluder_list(c, &cull.cells, k) else {
                continue;
            };
            listed += 1;
            long_lists += usize::from(list.len() >= 3);
            let b = accel.world_bounds[k as usize];
            let centre = (b.min + b.max) * 0.5;
            for d in &dirs {
                let d = d.normalize_or(Vec3::Y);
                let from = centre + d * 3.0;
                let Some(h) = accel.closest_hit(from, -d, 0.0, 10.0).hit else {
                    continue;
                };
                if h.instance != k {
                    continue;
                }
                let p = from - d * h.t;
                for side in [1.0, -1.0] {
                    let n = h.geometric * side;
                    if n.dot(l) <= 0.0 {
                        continue;
                    }
                    let o = p + n * eps;
                    let leaving = if side > 0.0 { k } else { u32::MAX };
                    let Some(hit) = accel.closest_hit(o, l, 0.0, f32::INFINITY).hit else {
                        continue;
                    };
                    by_others += usize::from(hit.instance != k);
                    from_inside += usize::from(side < 0.0);
                    assert_hit_listed(o, hit.instance, list, convex, leaving);
                }
            }
        }
        // Half the solids have lists, most with neighbours in them, and
        // many checked rays are blocked: by a neighbour, or (from inside)
        // by the receiver itself.
        assert!(listed >= 20, "{listed} instances have lists");
        assert!(long_lists >= 15, "{long_lists} lists hold 3 or more");
        assert!(
            by_others > 300 && from_inside > 1000,
            "{by_others} rays blocked by another instance, {from_inside} from inside"
        );
    }

    /// A list is never given where the kernel could not answer it: a
    /// receiver next to the CSG solid or the mesh, and the mesh and the
    /// CSG solid themselves, walk; the floor (a plane tested exactly) has
    /// none; lists hold analytic instances only, and cells' lists never the
    /// mesh. Without lists every record walks, and the grid differs only
    /// where a cell points at its list.
    #[test]
    fn meshes_and_csg_solids_keep_the_walk() {
        let (scene, accel) = packed_scene();
        let cull = build(&accel, &scene.lights, true);
        let c = &cull.lights[0];
        let kind = |k: u32| accel.shapes[accel.instances[k as usize].2 as usize].kind;
        let mut walks = 0;
        for k in 0..accel.instances.len() as u32 {
            match occluder_list(c, &cull.cells, k) {
                Some((list, _)) => {
                    assert!(kind(k) < SHAPE_QUAD, "instance {k} of kind {}", kind(k));
                    for &j in list {
                        assert!(kind(j) < SHAPE_QUAD, "list of {k} holds {j}");
                    }
                }
                None => walks += 1,
            }
        }
        for k in 0..3 {
            assert!(occluder_list(c, &cull.cells, k).is_none(), "instance {k}");
        }
        assert!(walks >= 4, "{walks} receivers walk");
        // The cells' lists never hold the cow (instance 2), whose
        // triangles' cells walk.
        for &w in &cull.cells[..CELLS_PER_LIGHT] {
            if let Some((list, _, _)) = list_at_cell(&cull.cells, w) {
                assert!(!list.contains(&2), "a cell lists the mesh whole");
            }
        }
        let off = build(&accel, &scene.lights, false);
        assert_eq!(off.lights[0].first_list, 0);
        assert_eq!(off.cells.len(), CELLS_PER_LIGHT);
        // With lists, a cell's word is the same, or points at its list
        // where something lands on it.
        for (i, (&without, &with)) in off.cells.iter().zip(&cull.cells).enumerate() {
            assert!(
                with == without || (without != 0 && list_at_cell(&cull.cells, with).is_some()),
                "cell {i}: {without:#x} without lists, {with:#x} with"
            );
        }
    }

    /// Under a light straight overhead, sphere A (radius 0.5 at the
    /// origin) has two neighbours whose footprints overlap its own by 0.03
    /// and 0.05 only: sphere B (radius 0.5, centre (0.97, 1.5, 0)) above
    /// it, and box C (x from -1.45 to -0.45, y from -1 to 0.3) beside it,
    /// whose top is lower than A's. Rays going up from A's rim, x >= 0.47
    /// (inside B's circle (x - 0.97)^2 + z^2 <= 0.25) or x <= -0.45 (from
    /// a point under C's top), are blocked, so A's list must hold
    /// both; and B's list must not hold A, which lies wholly below it. It
    /// fails if the overlap test is tighter than the footprints, or the
    /// light-side filter compares against A's top instead of its bottom.
    #[test]
    fn a_neighbour_that_shades_only_the_rim_is_listed() {
        let ron = r#"(version: 1,
            camera: (eye: (0.0, 3.0, 8.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 64, height: 64),
            lights: [Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 1.0)],
            materials: { "m": (base_color: (0.8, 0.8, 0.8), model: BlinnPhong) },
            shapes: { "ball": Sphere(radius: 0.5), "crate": Box(half_extents: (0.5, 0.65, 0.5)) },
            instances: [
                (shape: "ball", material: "m"),
                (shape: "ball", material: "m", transform: (translate: (0.97, 1.5, 0.0))),
                (shape: "crate", material: "m", transform: (translate: (-0.95, -0.35, 0.0))),
            ],
        )"#;
        let scene = Scene::from_ron_str(ron, "test", std::path::Path::new(".")).unwrap();
        let accel = SceneAccel::build(&scene, &[0, 1, 2]).unwrap();
        let cull = build(&accel, &scene.lights, true);
        let c = &cull.lights[0];
        let (a, _) = occluder_list(c, &cull.cells, 0).expect("A has a list");
        let (b, _) = occluder_list(c, &cull.cells, 1).expect("B has a list");
        assert!(a.contains(&1) && a.contains(&2), "A's list {a:?}");
        assert!(!b.contains(&0), "B's list {b:?}");
        // Rays from A's rim (z = 0) under B (x > 0) and over C (x < 0).
        let mut blocked = [0, 0];
        for (which, side) in [(0usize, 1.0f32), (1, -1.0)] {
            for i in 0..200 {
                let (x, z) = (side * (0.44 + 0.06 * i as f32 / 200.0), 0.0);
                let y2 = 0.25 - x * x - z * z;
                if y2 <= 0.0 {
                    continue;
                }
                let n = Vec3::new(x, y2.sqrt(), z) * 2.0;
                let o = n * 0.5 + n * 1e-4;
                if let Some(h) = accel.closest_hit(o, Vec3::Y, 0.0, f32::INFINITY).hit {
                    assert!(a.contains(&h.instance), "from {o}: {}", h.instance);
                    blocked[which] += usize::from(h.instance == which as u32 + 1);
                }
            }
        }
        assert!(blocked[0] > 10 && blocked[1] > 10, "blocked {blocked:?}");
    }
}
