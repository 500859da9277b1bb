//! Plain Pod layouts of what `accel` builds for the GPU: BVH nodes, mesh
//! triangles, base shapes, CSG programs and leaves, their kind and opcode
//! constants, and the traversal limits both the CPU reference and the WGSL
//! traversal obey. No wgpu here: `gpu::twins` re-exports all of it, and
//! `tests/shaders.rs` checks every size, offset and constant against WGSL.

use bytemuck::{Pod, Zeroable};

/// Shape kinds of [`GpuShape::kind`].
pub const SHAPE_SPHERE: u32 = 0;
pub const SHAPE_BOX: u32 = 1;
pub const SHAPE_CYLINDER: u32 = 2;
pub const SHAPE_CONE: u32 = 3;
pub const SHAPE_QUAD: u32 = 4;
pub const SHAPE_DISK: u32 = 5;
pub const SHAPE_MESH: u32 = 6;

/// Entries of the traversal stack, shared by both levels (the bottom level
/// continues above the top level's entries); deeper trees are refused. The
/// trace kernel's stack is only as long as its scene needs
/// (`PrivateSizes::trace_stack`, the WGSL constant `TRACE_STACK`): lavapipe
/// zero-fills the whole private array for every invocation, and its
/// accesses cost more the longer it is (docs/performance-history.md,
/// twenty-third session).
pub const TRAVERSAL_STACK: u32 = 64;
/// Loop iterations one ray query may take before it gives up and reports
/// overflow: well under lavapipe's silent cut at ~65,535 per invocation.
pub const MAX_TRAVERSAL_STEPS: u32 = 12000;

/// Cells along each side of a light's shadow-cull grid, at most
/// ([`GpuShadowCull`]); `SHADOW_CULL_CELLS^2` words of `shadow_cells` per
/// light.
pub const SHADOW_CULL_CELLS: u32 = 128;
/// A shadow-cull cell that several occluders, or one that is not convex,
/// land on (0: none; k + 1: only instance k, a sphere or a box).
pub const CULL_CELL_MANY: u32 = u32::MAX;
/// A shadow-cull cell whose occluders are all listed: the word is this bit
/// plus the index in `shadow_cells` of their list (a header as an occluder
/// list's, then the instances; [`SHADOW_LIST_CONVEX`] where every one is a
/// sphere or a box), which a shadow ray starting in the cell tests instead
/// of walking the BVH.
pub const CULL_CELL_LIST: u32 = 1 << 31;
/// A cell list's header holds, from this bit, how many triangles of one
/// static mesh follow its whole occluders (after the mesh's instance).
pub const CELL_LIST_TRIANGLE_SHIFT: u32 = 8;
/// Planes per light whose shadow rays are tested against them exactly.
pub const MAX_CULL_PLANES: u32 = 4;
/// Words of one receiver's record in a light's occluder lists (in
/// `shadow_cells`, after the grids): a header, then up to
/// [`SHADOW_LIST_MAX`] instances whose shadows can fall on the receiver.
pub const SHADOW_LIST_WORDS: u32 = 8;
/// Instances one occluder list holds at most.
pub const SHADOW_LIST_MAX: u32 = SHADOW_LIST_WORDS - 1;
/// The header of a receiver whose shadow rays walk the BVH: its list
/// would be longer than [`SHADOW_LIST_MAX`], or would hold a mesh or a CSG
/// solid, which the kernel's list test does not intersect.
pub const SHADOW_LIST_WALK: u32 = u32::MAX;
/// Header bit (above the count): the receiver is a sphere or a box, so a
/// ray leaving its lit outside cannot meet it, and the list test skips it.
pub const SHADOW_LIST_CONVEX: u32 = 1 << 3;

/// Bits of a G-buffer id (instance + 1; 0 is the background) that the
/// outline search keeps next to a texel's reach in one word
/// (`shaders/accumulate.wgsl`), which bounds a scene's instances.
pub const INSTANCE_ID_BITS: u32 = 24;
/// The most instances a scene may have: every id fits in
/// [`INSTANCE_ID_BITS`] bits.
pub const MAX_INSTANCES: usize = (1 << INSTANCE_ID_BITS) - 1;

/// Words of one screen tile's record of primary-ray candidates
/// ([`crate::accel::screen_tiles`]): a header (the count), then up to
/// [`PRIMARY_TILE_MAX`] instances, ascending.
pub const PRIMARY_TILE_WORDS: u32 = 8;
/// Instances one tile's record holds at most.
pub const PRIMARY_TILE_MAX: u32 = PRIMARY_TILE_WORDS - 1;
/// The header of a tile whose primary rays walk the BVH: more instances
/// than [`PRIMARY_TILE_MAX`] may be seen there.
pub const PRIMARY_TILE_WALK: u32 = u32::MAX;
/// Bit of a tile's word after the records: in hybrid mode, a rasterized
/// mesh may show in the tile, so its primary rays read the raster G-buffer.
pub const TILE_MESH_MAY_SHOW: u32 = 1;
/// Bit of a tile's word after the records: no outline can reach the tile,
/// so the trace pass adds its pixels' colour to the accumulator itself.
pub const TILE_TRACE_ACCUMULATES: u32 = 2;
/// Bit of a tile's word after the records: no pass of this sample reads the
/// tile's traced normal, depth and id (it accumulates, and no tile whose
/// outline marks or search run lies within the outline radius of it), so
/// the trace pass does not store them. Never set on a moving frame, whose
/// reproject pass reads the whole G-buffer.
pub const TILE_GBUFFER_SKIPS: u32 = 4;
/// Bit of a tile's word after the records: every primary hit of the tile
/// is on one static quad or disk (the record lists it alone, and no
/// rasterized mesh may show), and the shadow ray of each such hit towards
/// the one light that casts shadows is culled by `shadow_query` or meets
/// nothing (the CPU proves it for the region the tile's rays meet,
/// [`crate::accel::shadow_cull::CulledRegions`]): the trace pass casts no
/// shadow ray from the tile's primary hits and asks nothing.
pub const TILE_UNSHADOWED: u32 = 8;
/// Where a tile's word after the records keeps, above its flag bits, the
/// summary of the tile's record
/// ([`crate::accel::screen_tiles::record_summary`]): 0 where the record
/// lists no instance, k + 1 where it lists instance k alone,
/// [`TILE_RECORD_READ`] otherwise. The trace kernel reads the flag word
/// anyway, so a tile of at most one instance costs it no read of the
/// record (one sphere, the trace pass about 0.9 of the time).
pub const TILE_RECORD_SHIFT: u32 = 8;
/// The summary of a record the trace kernel reads word by word: more than
/// one instance, a walk, or an instance index too large for the summary.
pub const TILE_RECORD_READ: u32 = (1 << (32 - TILE_RECORD_SHIFT)) - 1;

/// Which shadow rays of one light can meet something at all
/// ([`crate::accel::shadow_cull`]): the trace kernel casts a ray only where
/// this says it may be blocked, and the skipped rays are exactly those that
/// would have found nothing.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct GpuShadowCull {
    /// Unit axes across the light's direction (xyz); w: the grid's lower
    /// corner along the axis.
    pub u: [f32; 4],
    pub v: [f32; 4],
    /// Static quads and disks: row y of their `object_from_world`, so
    /// `dot(row.xyz, p) + row.w` is a point's object-space height (the
    /// plane's side), as the intersection test computes it.
    pub planes: [[f32; 4]; MAX_CULL_PLANES as usize],
    /// Grid cells per world unit along u and v.
    pub cells_per_unit: [f32; 2],
    /// Cells along u and v (0 x 0: no occluder in the grid).
    pub dims: [u32; 2],
    /// The grid's first cell in `shadow_cells` (cell y * dims.x + x).
    pub first_cell: u32,
    pub plane_count: u32,
    /// 0: every shadow ray of this light is cast (a point light, or a
    /// light that casts no shadows).
    pub enabled: u32,
    /// Where this light's occluder lists start in `shadow_cells`: instance
    /// k's record at `first_list + k * SHADOW_LIST_WORDS`; 0: no lists.
    pub first_list: u32,
    /// Where the instances' world bounding spheres start in
    /// `shadow_cells`, read with the lists: instance k's centre and radius
    /// as the f32 bits of words `first_sphere + 4 k ..`; 0: none.
    pub first_sphere: u32,
    pub _pad: [u32; 3],
}

/// A node of a bounding volume hierarchy. A leaf has `count > 0` items
/// starting at `left_or_first`; an inner node's children are nodes
/// `left_or_first` and `left_or_first + 1`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct BvhNode {
    pub bounds_min: [f32; 3],
    pub left_or_first: u32,
    pub bounds_max: [f32; 3],
    pub count: u32,
}

/// A triangle of a mesh in object space, with its vertex normals; the w
/// components carry the texture coordinates: `(p_k.w, n_k.w)` is corner
/// k's (u, v).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuTriangle {
    pub p0: [f32; 4],
    pub p1: [f32; 4],
    pub p2: [f32; 4],
    pub n0: [f32; 4],
    pub n1: [f32; 4],
    pub n2: [f32; 4],
}

/// A base shape for the ray tracer: its kind, parameters (radius, half
/// extents, height, ...; for CSG its bounding sphere, centre and radius,
/// from [`crate::scene::Csg::bounding_sphere`]) and, for meshes, the root
/// of its bottom-level BVH.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuShape {
    pub params: [f32; 4],
    pub kind: u32,
    pub blas_root: u32,
    /// For a CSG shape evaluated by its truth table (lib/csg.wgsl,
    /// `intersect_csg_fast`): its leaf count times [`CSG_FAST_COUNT_SHIFT`]
    /// plus the index of its first leaf; 0 for every other shape and for
    /// CSG programs the interpreter runs. See [`crate::accel::csg::fast_table`].
    pub csg_fast: u32,
    pub _pad1: u32,
}

/// Shape kind of a CSG tree: `blas_root` is the first instruction of its
/// postfix program in the CSG op buffer.
pub const SHAPE_CSG: u32 = 7;
/// [`GpuShape::csg_fast`]: the leaf count sits above this bit.
pub const CSG_FAST_COUNT_SHIFT: u32 = 24;
/// The most leaves a CSG program evaluated by its truth table may have
/// (2^8 table bits, spread over the `table` words of its first leaves).
pub const CSG_FAST_MAX_LEAVES: u32 = 8;
/// CSG program instructions ([`GpuCsgOp::op`]).
pub const CSG_OP_END: u32 = 0;
pub const CSG_OP_LEAF: u32 = 1;
pub const CSG_OP_UNION: u32 = 2;
pub const CSG_OP_INTERSECTION: u32 = 3;
pub const CSG_OP_DIFFERENCE: u32 = 4;
/// [`GpuCsgLeaf::material`] of a leaf that uses the instance's material.
pub const CSG_NO_MATERIAL: u32 = u32::MAX;

/// One instruction of a CSG postfix program. `op` is a `CSG_OP_*`; for
/// `CSG_OP_LEAF`, `arg` indexes the leaf buffer; for the set operations,
/// `arg` is 1 when the operands were evaluated in swapped order (the first
/// operand is on top of the stack).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct GpuCsgOp {
    pub op: u32,
    pub arg: u32,
}

/// A CSG leaf: an analytic shape or a mesh (`blas_root`) placed in the CSG
/// shape's object space, with an optional material.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuCsgLeaf {
    /// Inverse of the leaf's transform: CSG space to leaf space.
    pub leaf_from_csg: [[f32; 4]; 4],
    /// Inverse transpose of the leaf's transform: leaf normals to CSG space.
    pub csg_normal_from_leaf: [[f32; 4]; 4],
    pub params: [f32; 4],
    /// `SHAPE_*` (sphere, box, cylinder, cone or mesh).
    pub kind: u32,
    pub blas_root: u32,
    /// Material id, or [`CSG_NO_MATERIAL`].
    pub material: u32,
    /// Word i of the truth table of the program this leaf is leaf i of,
    /// where that program is evaluated by its table
    /// ([`GpuShape::csg_fast`]); else 0.
    pub table: u32,
}

/// A surface is in front of another when its view depth is smaller by this
/// fraction: an outline's depth edge (accumulate) and a disocclusion
/// (reproject).
pub const DEPTH_JUMP: f32 = 0.05;
