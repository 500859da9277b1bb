//! The scene tables that passes may read from a uniform-buffer copy.
//!
//! lavapipe reads a storage-buffer word whose index differs between the 8
//! lanes of its SIMD program in a loop over the lanes, two branches a word
//! (the lane's mask, the buffer's bounds); a uniform-buffer read at the same
//! indices is one branchless gather (docs/performance-history.md, fourteenth
//! session). So each table of the scene's group that fits in
//! [`UNIFORM_TABLE_BYTES`] is also uploaded as a uniform buffer, and the
//! pipelines read it there: bit [`Table::bit`] of the override constant
//! `UNIFORM_TABLES` (lib/scene_bindings.wgsl) says so, and the shaders'
//! accessors (`load_node`, `load_instance`, ...) pick the binding. A table
//! too big (a large mesh's BVH, 100,000 instances) is read from storage.
//!
//! Six tables at most: Mesa 22.3's lavapipe corrupts its heap with 8
//! uniform buffers in one stage, and every pass binds its frame uniforms
//! too (tests/shaders.rs checks the count). The top-level items
//! (`tlas_items`) have no copy: reading one word of a `vec4` at a per-lane
//! component cost more than the copy saved (the trace pass measured 0.97x
//! without that copy).
//!
//! The storage buffers stay the tables' home (edits write both copies:
//! `SceneBuffers::write_materials` and `write_instances_at` in
//! render/scene_buffers.rs); the uniform copies are always
//! [`UNIFORM_TABLE_BYTES`] long, as WGSL declares them (fixed-size
//! arrays).

use crate::gpu::twins::{BvhNode, GpuCsgLeaf, GpuCsgOp, GpuInstance, GpuMaterial, GpuShape};

/// Bytes of each uniform copy: WebGPU's default (and lavapipe's) limit on a
/// uniform binding. [`crate::gpu::Gpu`] refuses an adapter with less.
pub const UNIFORM_TABLE_BYTES: u32 = 65536;

/// The first binding of the uniform copies in the scene's group; table `t`
/// is at `FIRST_UNIFORM_TABLE_BINDING + t as u32`.
pub const FIRST_UNIFORM_TABLE_BINDING: u32 = 13;

/// A table of the scene's group with a uniform copy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Table {
    Nodes,
    Instances,
    Shapes,
    Materials,
    CsgOps,
    CsgLeaves,
}

impl Table {
    pub const ALL: [Table; 6] = [
        Table::Nodes,
        Table::Instances,
        Table::Shapes,
        Table::Materials,
        Table::CsgOps,
        Table::CsgLeaves,
    ];

    /// Its bit in `UNIFORM_TABLES`.
    pub const fn bit(self) -> u32 {
        1 << self as u32
    }

    pub const fn binding(self) -> u32 {
        FIRST_UNIFORM_TABLE_BINDING + self as u32
    }

    /// The WGSL name of its bit (generated into lib/limits.wgsl).
    pub const fn bit_name(self) -> &'static str {
        match self {
            Table::Nodes => "TABLE_NODES",
            Table::Instances => "TABLE_INSTANCES",
            Table::Shapes => "TABLE_SHAPES",
            Table::Materials => "TABLE_MATERIALS",
            Table::CsgOps => "TABLE_CSG_OPS",
            Table::CsgLeaves => "TABLE_CSG_LEAVES",
        }
    }

    /// The WGSL name of its uniform array's length (lib/limits.wgsl).
    pub const fn length_name(self) -> &'static str {
        match self {
            Table::Nodes => "UNIFORM_NODES",
            Table::Instances => "UNIFORM_INSTANCES",
            Table::Shapes => "UNIFORM_SHAPES",
            Table::Materials => "UNIFORM_MATERIALS",
            Table::CsgOps => "UNIFORM_CSG_OP_VECS",
            Table::CsgLeaves => "UNIFORM_CSG_LEAVES",
        }
    }

    /// Bytes of one element of its uniform array. A uniform array's stride
    /// is a multiple of 16, so the 8-byte CSG instructions are packed two
    /// to a `vec4<u32>`, which is the storage buffer's own byte layout.
    const fn uniform_stride(self) -> u32 {
        (match self {
            Table::Nodes => std::mem::size_of::<BvhNode>(),
            Table::Instances => std::mem::size_of::<GpuInstance>(),
            Table::Shapes => std::mem::size_of::<GpuShape>(),
            Table::CsgOps => 16,
            Table::Materials => std::mem::size_of::<GpuMaterial>(),
            Table::CsgLeaves => std::mem::size_of::<GpuCsgLeaf>(),
        }) as u32
    }

    /// Elements of its uniform array: as many whole ones as fit.
    pub const fn uniform_length(self) -> u32 {
        UNIFORM_TABLE_BYTES / self.uniform_stride()
    }

    /// Whether a table of `bytes` (its storage buffer's contents) fits its
    /// uniform copy.
    pub const fn fits(self, bytes: usize) -> bool {
        bytes as u64 <= (self.uniform_length() * self.uniform_stride()) as u64
    }
}

// Two CSG instructions to a `vec4<u32>` (load_csg_op) needs 8 bytes each.
const _: () = assert!(std::mem::size_of::<GpuCsgOp>() == 8);

/// The bit of `UNIFORM_TABLES` that says the node table did not fit but
/// its first nodes, the top-level tree's, did: the copy holds those, and the
/// top-level walk reads it (the meshes' walks read storage).
pub const TOP_NODES_BIT: u32 = 1 << 7;
/// Its WGSL name (lib/limits.wgsl).
pub const TOP_NODES_NAME: &str = "TABLE_TOP_NODES";

/// Which tables a scene's pipelines read from their uniform copies: the
/// value of `UNIFORM_TABLES`, part of every pipeline key that reads the
/// scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct UniformTables(u32);

impl UniformTables {
    /// Every table from storage (what a pipeline that does not set the
    /// constant reads).
    pub const NONE: UniformTables = UniformTables(0);

    /// The tables whose contents (bytes, by table) fit; where the nodes do
    /// not, whether the top-level tree's (`top_node_bytes`, the first ones)
    /// do.
    pub fn fitting(bytes: impl Fn(Table) -> usize, top_node_bytes: usize) -> UniformTables {
        let whole = Table::ALL
            .into_iter()
            .filter(|&t| t.fits(bytes(t)))
            .fold(0, |bits, t| bits | t.bit());
        let top = whole & Table::Nodes.bit() == 0 && Table::Nodes.fits(top_node_bytes);
        UniformTables(whole | if top { TOP_NODES_BIT } else { 0 })
    }

    /// Whether `table` is read from its uniform copy, all of it.
    pub fn contains(self, table: Table) -> bool {
        self.0 & table.bit() != 0
    }

    /// Whether the node table's copy holds only the top-level tree.
    pub fn top_nodes_only(self) -> bool {
        self.0 & TOP_NODES_BIT != 0
    }

    /// The override constant that selects these tables.
    pub fn constant(self) -> (&'static str, f64) {
        ("UNIFORM_TABLES", f64::from(self.0))
    }
}

/// Tables of at most this many elements may be read by selection
/// ([`SelectedTables`]).
pub const MAX_SELECTED: u32 = 16;

/// The tables the passes read by selection, where the device wants it
/// ([`crate::gpu::Gpu::select_tables`]: lavapipe from Mesa 25), with their element
/// counts: the override constants `SELECT_MATERIALS` and
/// `SELECT_INSTANCES` (lib/scene_bindings.wgsl), 0 for a table read at
/// its index.
///
/// lavapipe loads a table word at an index it cannot prove the same for
/// its 8 lanes (only constants qualify) as a gather, even where the 8 ask
/// for the same element, as neighbouring pixels that hit one object do.
/// Read by selection, element i comes out of a binary tree of branches
/// over the constant indices 0 to n - 1 (lib/select_tables.wgsl,
/// generated by [`crate::gpu::shader`]), each leaf loading its element at
/// a constant index, once for the 8 lanes; a branch none of the 8 takes
/// is skipped, so 8 lanes that agree pay for about log2(n) tests and one
/// element. Trace pass of the default scene, paired: 0.85 of the gathers'
/// time; the cost grows with n (a tree over 16 elements on that scene's 6:
/// 0.90), hence [`MAX_SELECTED`] (docs/performance-history.md,
/// twenty-eighth session).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SelectedTables {
    materials: u32,
    instances: u32,
}

impl SelectedTables {
    /// No table read by selection (what a pipeline that does not set the
    /// constants reads).
    pub const NONE: SelectedTables = SelectedTables {
        materials: 0,
        instances: 0,
    };

    /// The tables of these element counts that are small enough.
    pub fn of(materials: usize, instances: usize) -> SelectedTables {
        let count = |n: usize| {
            u32::try_from(n)
                .ok()
                .filter(|&n| n <= MAX_SELECTED)
                .unwrap_or(0)
        };
        SelectedTables {
            materials: count(materials),
            instances: count(instances),
        }
    }

    /// The material table's count where it is read by selection, else 0.
    pub fn materials(self) -> u32 {
        self.materials
    }

    /// The instance table's count where it is read by selection, else 0.
    pub fn instances(self) -> u32 {
        self.instances
    }

    /// The override constants that select these reads.
    pub fn constants(self) -> [(&'static str, f64); 2] {
        [
            ("SELECT_MATERIALS", f64::from(self.materials)),
            ("SELECT_INSTANCES", f64::from(self.instances)),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A table is read by selection up to MAX_SELECTED elements, at its
    /// index from one more.
    #[test]
    fn tables_past_the_limit_are_read_at_their_index() {
        let max = MAX_SELECTED as usize;
        let at = |m, i| {
            let s = SelectedTables::of(m, i);
            (s.materials(), s.instances())
        };
        assert_eq!(at(1, max), (1, MAX_SELECTED));
        assert_eq!(at(max + 1, 6), (0, 6));
        assert_eq!(at(7, 100_000), (7, 0));
        let constants = SelectedTables::of(max + 1, 3).constants();
        assert_eq!(
            constants,
            [("SELECT_MATERIALS", 0.0), ("SELECT_INSTANCES", 3.0)]
        );
    }
}
