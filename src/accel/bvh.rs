//! Binned-SAH bounding volume hierarchies, built on the CPU and stored flat:
//! children of a node are adjacent, so a node needs one index.

use glam::Vec3;

use super::layout::BvhNode;

/// An axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn grow(self, other: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    pub fn grow_point(self, p: Vec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    pub fn centre(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Half the surface area (enough for SAH cost ratios).
    pub fn half_area(&self) -> f32 {
        let e = (self.max - self.min).max(Vec3::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }

    /// The 8 corners (bit 0 of the index picks max.x, bit 1 max.y, bit 2
    /// max.z).
    pub fn corners(&self) -> [Vec3; 8] {
        std::array::from_fn(|i| {
            Vec3::new(
                if i & 1 == 0 { self.min.x } else { self.max.x },
                if i & 2 == 0 { self.min.y } else { self.max.y },
                if i & 4 == 0 { self.min.z } else { self.max.z },
            )
        })
    }

    /// The box of the 8 corners of `self` under `m`.
    pub fn transformed(&self, m: glam::Mat4) -> Aabb {
        self.corners()
            .into_iter()
            .fold(Aabb::EMPTY, |out, c| out.grow_point(m.transform_point3(c)))
    }
}

/// A built hierarchy: nodes (root at 0) and the item order its leaves index.
#[derive(Debug, Clone)]
pub struct Bvh {
    pub nodes: Vec<BvhNode>,
    /// Leaf item slots: `items[k]` is the caller's item index.
    pub items: Vec<u32>,
    /// Depth of the deepest leaf (root = 1).
    pub depth: u32,
}

const BINS: usize = 16;

/// Builds a BVH over items with these bounds, at most `max_leaf` per leaf
/// (more only when items cannot be separated). Split by binned SAH with 16
/// bins per axis over the centroid bounds (traversal cost 1, item cost 1).
pub fn build(bounds: &[Aabb], max_leaf: usize) -> Bvh {
    let mut bvh = Bvh {
        nodes: vec![BvhNode::zeroed_node()],
        items: (0..bounds.len() as u32).collect(),
        depth: 1,
    };
    if bounds.is_empty() {
        // A root whose box no ray reaches: a point at f32's far corner,
        // beyond any ray's t_max (3e38 at most) along unit directions (a
        // zero or negative component misses it too). An inverted box would
        // not do: the slab test takes the planes in either order, and the
        // root (count 0, an inner node) would lead the walk to nodes that
        // are not its children.
        bvh.nodes[0] = BvhNode {
            bounds_min: [f32::MAX; 3],
            left_or_first: 0,
            bounds_max: [f32::MAX; 3],
            count: 0,
        };
        return bvh;
    }
    let centres: Vec<Vec3> = bounds.iter().map(Aabb::centre).collect();
    // (node index, first item, item count, depth)
    let mut work = vec![(0usize, 0usize, bounds.len(), 1u32)];
    while let Some((node, first, count, depth)) = work.pop() {
        bvh.depth = bvh.depth.max(depth);
        let slice = &mut bvh.items[first..first + count];
        let node_box = slice
            .iter()
            .fold(Aabb::EMPTY, |b, &i| b.grow(bounds[i as usize]));
        if count <= max_leaf {
            bvh.nodes[node] = BvhNode {
                bounds_min: node_box.min.to_array(),
                left_or_first: first as u32,
                bounds_max: node_box.max.to_array(),
                count: count as u32,
            };
            continue;
        }
        // Partition items: centroid below the SAH plane first.
        let mut left = 0;
        if let Some((axis, position)) = find_split(slice, bounds, &centres, node_box) {
            for k in 0..count {
                if centres[slice[k] as usize][axis] < position {
                    slice.swap(k, left);
                    left += 1;
                }
            }
        }
        // No plane separates the centroids: split the list in half.
        if left == 0 || left == count {
            left = count / 2;
        }
        push_children(
            &mut bvh,
            node,
            node_box,
            &mut work,
            (first, left),
            (first + left, count - left),
            depth,
        );
    }
    bvh
}

fn push_children(
    bvh: &mut Bvh,
    node: usize,
    node_box: Aabb,
    work: &mut Vec<(usize, usize, usize, u32)>,
    left: (usize, usize),
    right: (usize, usize),
    depth: u32,
) {
    let l = bvh.nodes.len();
    bvh.nodes.push(BvhNode::zeroed_node());
    bvh.nodes.push(BvhNode::zeroed_node());
    bvh.nodes[node] = BvhNode {
        bounds_min: node_box.min.to_array(),
        left_or_first: l as u32,
        bounds_max: node_box.max.to_array(),
        count: 0,
    };
    work.push((l, left.0, left.1, depth + 1));
    work.push((l + 1, right.0, right.1, depth + 1));
}

/// The best (axis, plane) by binned SAH, or None if a leaf is cheaper.
fn find_split(
    items: &[u32],
    bounds: &[Aabb],
    centres: &[Vec3],
    node_box: Aabb,
) -> Option<(usize, f32)> {
    let cbox = items
        .iter()
        .fold(Aabb::EMPTY, |b, &i| b.grow_point(centres[i as usize]));
    let mut best: Option<(f32, usize, f32)> = None;
    #[allow(clippy::needless_range_loop)] // axis indexes Vec3 components too
    for axis in 0..3 {
        let (lo, hi) = (cbox.min[axis], cbox.max[axis]);
        if hi - lo <= 1e-12 * hi.abs().max(1.0) {
            continue;
        }
        let scale = BINS as f32 / (hi - lo);
        let mut bin_box = [Aabb::EMPTY; BINS];
        let mut bin_count = [0usize; BINS];
        for &i in items {
            let b = (((centres[i as usize][axis] - lo) * scale) as usize).min(BINS - 1);
            bin_box[b] = bin_box[b].grow(bounds[i as usize]);
            bin_count[b] += 1;
        }
        // Sweep from the right to get the cost of every right side.
        let mut right_area = [0.0f32; BINS];
        let mut right_count = [0usize; BINS];
        let (mut acc_box, mut acc_n) = (Aabb::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc_box = acc_box.grow(bin_box[b]);
            acc_n += bin_count[b];
            right_area[b] = acc_box.half_area();
            right_count[b] = acc_n;
        }
        let (mut acc_box, mut acc_n) = (Aabb::EMPTY, 0);
        for b in 0..BINS - 1 {
            acc_box = acc_box.grow(bin_box[b]);
            acc_n += bin_count[b];
            if acc_n == 0 || right_count[b + 1] == 0 {
                continue;
            }
            let cost = 1.0
                + (acc_box.half_area() * acc_n as f32
                    + right_area[b + 1] * right_count[b + 1] as f32)
                    / node_box.half_area().max(1e-30);
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, lo + (b + 1) as f32 / scale));
            }
        }
    }
    // The caller only asks when the node is over the leaf size, so the best
    // plane is taken even when SAH would prefer a leaf.
    best.map(|(_, axis, position)| (axis, position))
}

impl BvhNode {
    fn zeroed_node() -> BvhNode {
        bytemuck::Zeroable::zeroed()
    }

    pub fn aabb(&self) -> Aabb {
        Aabb {
            min: Vec3::from(self.bounds_min),
            max: Vec3::from(self.bounds_max),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxes(n: usize) -> Vec<Aabb> {
        (0..n)
            .map(|i| {
                let p = Vec3::new(
                    (i * 7 % 13) as f32,
                    (i * 5 % 11) as f32,
                    (i * 3 % 17) as f32,
                );
                Aabb {
                    min: p,
                    max: p + Vec3::splat(0.5),
                }
            })
            .collect()
    }

    #[test]
    fn every_item_in_exactly_one_leaf_inside_its_ancestors() {
        for n in [1usize, 2, 5, 100, 1000] {
            let b = boxes(n);
            let bvh = build(&b, 4);
            let mut seen = vec![0; n];
            let mut stack = vec![(
                0usize,
                Aabb {
                    min: Vec3::splat(-1e30),
                    max: Vec3::splat(1e30),
                },
            )];
            while let Some((i, parent)) = stack.pop() {
                let node = bvh.nodes[i];
                let nb = node.aabb();
                assert!(nb.min.cmpge(parent.min).all() && nb.max.cmple(parent.max).all());
                if node.count > 0 {
                    for k in node.left_or_first..node.left_or_first + node.count {
                        let item = bvh.items[k as usize] as usize;
                        seen[item] += 1;
                        assert!(b[item].min.cmpge(nb.min).all() && b[item].max.cmple(nb.max).all());
                    }
                } else {
                    stack.push((node.left_or_first as usize, nb));
                    stack.push((node.left_or_first as usize + 1, nb));
                }
            }
            assert!(seen.iter().all(|&s| s == 1), "n = {n}");
            // A balanced-enough tree: depth within a few times log2(n).
            assert!(
                bvh.depth <= 4 * (n as f32).log2().ceil() as u32 + 2,
                "n = {n}, depth {}",
                bvh.depth
            );
        }
    }

    /// The empty BVH's root is entered by no ray: unit directions from
    /// the 26 axis and diagonal directions and 1,000 pseudo-random ones,
    /// from points up to 1e4 from the origin, with t_max up to 3e38 (the
    /// largest any query uses). An inverted box [1, -1]^3, as the root
    /// once was, is the box [-1, 1]^3 to the slab test: the rays from the
    /// origin would all enter it (checked here too).
    #[test]
    fn the_empty_root_is_entered_by_no_ray() {
        let root = build(&[], 4).nodes[0].aabb();
        let inverted = Aabb {
            min: Vec3::ONE,
            max: -Vec3::ONE,
        };
        let mut dirs: Vec<Vec3> = (0..27)
            .map(|i| {
                Vec3::new(
                    (i % 3) as f32 - 1.0,
                    (i / 3 % 3) as f32 - 1.0,
                    (i / 9) as f32 - 1.0,
                )
            })
            .filter(|d| *d != Vec3::ZERO)
            .map(Vec3::normalize)
            .collect();
        dirs.extend((0..1000).map(|i| {
            let u = crate::sampling::uniform(i, 1, 0) * std::f32::consts::TAU;
            let z = crate::sampling::uniform(i, 2, 0) * 2.0 - 1.0;
            let r = (1.0 - z * z).sqrt();
            Vec3::new(r * u.cos(), r * u.sin(), z)
        }));
        for (i, d) in dirs.iter().enumerate() {
            for o in [Vec3::ZERO, Vec3::splat(1e4), Vec3::new(-1e4, 3.0, 1e4)] {
                let hit =
                    crate::accel::intersect::ray_box(o, d.recip(), root.min, root.max, 0.0, 3.0e38);
                assert_eq!(hit, None, "ray {i} from {o} along {d}");
            }
            let old = crate::accel::intersect::ray_box(
                Vec3::ZERO,
                d.recip(),
                inverted.min,
                inverted.max,
                0.0,
                3.0e38,
            );
            assert!(
                old.is_some(),
                "ray {i}: the inverted box should be entered from its inside"
            );
        }
    }

    #[test]
    fn identical_boxes_still_split_into_small_leaves() {
        let b = vec![
            Aabb {
                min: Vec3::ZERO,
                max: Vec3::ONE
            };
            64
        ];
        let bvh = build(&b, 4);
        assert!(bvh.nodes.iter().all(|n| n.count <= 4));
    }
}
