//! `Bvh4Cpu`: a 4-wide BVH for CPU traversal, collapsed from [`Bvh2`]. Each
//! node holds its children's boxes as structure-of-arrays lanes, so one ray
//! is tested against four boxes with a handful of 4-wide SIMD operations
//! (glam's `Vec4` is an SSE register on x86-64 and a NEON one on aarch64).

use glam::{BVec4A, Vec3A, Vec4};

use crate::layout::{BvhLayout, BvhStats, Stack, TraversalRay, MAX_DEPTH};
use crate::{Aabb, BuildOptions, Bvh2};

/// A node of [`Bvh4Cpu`] (128 bytes: two 64-byte cache lines).
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Bvh4CpuNode {
    /// Child boxes, lane `i` for child `i`: min x, y, z, then max x, y, z
    /// (6 x 16 bytes). Unused lanes hold the empty box, which every ray misses.
    pub bounds: [Vec4; 6],
    /// Interior child: its node index; leaf child: its first primitive (16 bytes).
    pub child: [u32; 4],
    /// 0 for an interior child or an unused lane, else the leaf's primitive count (16 bytes).
    pub count: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Bvh4CpuNode>() == 128);

impl Bvh4CpuNode {
    const EMPTY: Bvh4CpuNode = Bvh4CpuNode {
        bounds: [
            Vec4::INFINITY,
            Vec4::INFINITY,
            Vec4::INFINITY,
            Vec4::NEG_INFINITY,
            Vec4::NEG_INFINITY,
            Vec4::NEG_INFINITY,
        ],
        child: [0; 4],
        count: [0; 4],
    };

    /// Box of lane `i`.
    pub fn lane(&self, i: usize) -> Aabb {
        let b = &self.bounds;
        Aabb { min: Vec3A::new(b[0][i], b[1][i], b[2][i]), max: Vec3A::new(b[3][i], b[4][i], b[5][i]) }
    }

    fn set_lane(&mut self, i: usize, b: &Aabb) {
        for axis in 0..3 {
            self.bounds[axis][i] = b.min[axis];
            self.bounds[axis + 3][i] = b.max[axis];
        }
    }
}

/// 4-wide BVH; node 0 is the root. Leaves are lanes of their parent, and
/// primitives keep the order of the [`Bvh2`] this was collapsed from.
#[derive(Clone, Debug, Default)]
pub struct Bvh4Cpu {
    /// The nodes; the root is node 0.
    pub nodes: Vec<Bvh4CpuNode>,
    /// The root's box (the root node stores only its children's).
    pub bounds: Aabb,
}

/// The hit lanes sorted by entry distance, nearest first, each as one
/// `u32`: the distance's bits with the lane in the two lowest. Entry
/// distances are never negative, so their bits order like the floats, and
/// dropping two mantissa bits only rounds them down (a popped entry is then
/// at worst visited when it could have been skipped). Missed lanes get an
/// infinite distance and sort last. A 5-comparator network: no branches.
#[inline(always)]
fn sort_keys(t_near: Vec4, hit: BVec4A) -> [u32; 4] {
    let dist = Vec4::select(hit, t_near, Vec4::INFINITY).to_array();
    let mut k: [u32; 4] = std::array::from_fn(|lane| (dist[lane].to_bits() & !3) | lane as u32);
    for (a, b) in [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)] {
        let (lo, hi) = (k[a].min(k[b]), k[a].max(k[b]));
        (k[a], k[b]) = (lo, hi);
    }
    k
}

/// Deferred work on the stack: `(child, count, entry distance)` as in a node lane.
type Entry = (u32, u32, f32);

/// A node pushes at most 3 entries and depth is at most [`MAX_DEPTH`].
const STACK: usize = 3 * MAX_DEPTH;

impl BvhLayout for Bvh4Cpu {
    const NAME: &'static str = "Bvh4Cpu";

    /// Collapses pairs of levels: each node takes its Bvh2 counterpart's
    /// children and, while it has fewer than 4, replaces the interior child
    /// with the largest surface area (the likeliest to be visited) by its two
    /// children.
    fn from_bvh2(bvh: Bvh2) -> Self {
        let Some(root) = bvh.nodes.first() else { return Bvh4Cpu::default() };
        let src = &bvh.nodes;
        let mut nodes = vec![Bvh4CpuNode::EMPTY];
        let mut todo = vec![(0usize, 0usize)]; // (Bvh2 node, Bvh4Cpu node)
        while let Some((from, to)) = todo.pop() {
            let mut kids = [0usize; 4];
            let mut len = 2;
            if src[from].is_leaf() {
                // Only a root can be a leaf here: it becomes the single lane.
                (kids[0], len) = (from, 1);
            } else {
                let l = src[from].left_or_first as usize;
                kids[..2].copy_from_slice(&[l, l + 1]);
            }
            while len < 4 {
                let widest = (0..len)
                    .filter(|&k| !src[kids[k]].is_leaf())
                    .max_by(|&a, &b| src[kids[a]].aabb().area().total_cmp(&src[kids[b]].aabb().area()));
                let Some(k) = widest else { break };
                let l = src[kids[k]].left_or_first as usize;
                kids[k] = l;
                kids[len] = l + 1;
                len += 1;
            }
            let mut node = Bvh4CpuNode::EMPTY;
            for (lane, &k) in kids[..len].iter().enumerate() {
                node.set_lane(lane, &src[k].aabb());
                if src[k].is_leaf() {
                    node.child[lane] = src[k].left_or_first;
                    node.count[lane] = src[k].count;
                } else {
                    node.child[lane] = nodes.len() as u32;
                    nodes.push(Bvh4CpuNode::EMPTY);
                    todo.push((k, nodes.len() - 1));
                }
            }
            nodes[to] = node;
        }
        Bvh4Cpu { nodes, bounds: root.aabb() }
    }

    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn stats(&self, o: &BuildOptions) -> BvhStats {
        let mut s = BvhStats { nodes: self.nodes.len(), ..Default::default() };
        if self.nodes.is_empty() {
            return s;
        }
        let mut cost = (o.traversal_cost * self.bounds.area()) as f64;
        let mut todo = vec![(0usize, 1u32)];
        while let Some((i, depth)) = todo.pop() {
            s.max_depth = s.max_depth.max(depth);
            let n = &self.nodes[i];
            for lane in 0..4 {
                let area = n.lane(lane).area();
                if n.count[lane] > 0 {
                    s.leaves += 1;
                    cost += (o.intersection_cost * o.blocks(n.count[lane]) * area) as f64;
                } else if !n.lane(lane).is_empty() {
                    cost += (o.traversal_cost * area) as f64;
                    todo.push((n.child[lane] as usize, depth + 1));
                }
            }
        }
        s.sah_cost = (cost / self.bounds.area().max(f32::MIN_POSITIVE) as f64) as f32;
        s.bytes = std::mem::size_of_val(&self.nodes[..]);
        s
    }

    const NODE_BYTES: usize = std::mem::size_of::<Bvh4CpuNode>();

    #[inline]
    fn traverse_visiting<const ANY: bool>(
        &self,
        ray: &TraversalRay,
        t_max: &mut f32,
        mut visit: impl FnMut(u32),
        mut leaf: impl FnMut(u32, u32, &mut f32) -> bool,
    ) -> bool {
        if self.nodes.is_empty() || ray.box_entry(self.bounds.min, self.bounds.max, *t_max) == f32::INFINITY {
            return false;
        }
        let inv = [Vec4::splat(ray.inv_dir.x), Vec4::splat(ray.inv_dir.y), Vec4::splat(ray.inv_dir.z)];
        let org =
            [Vec4::splat(ray.origin_inv.x), Vec4::splat(ray.origin_inv.y), Vec4::splat(ray.origin_inv.z)];
        // Per axis, which of the six bound rows is the near and the far plane.
        let [nx, ny, nz] = ray.negative;
        let near = [3 * nx, 1 + 3 * ny, 2 + 3 * nz];
        let far = [3 - 3 * nx, 4 - 3 * ny, 5 - 3 * nz];
        let mut stack = Stack::<Entry, STACK>::new();
        let mut hit = false;
        let mut cur: (u32, u32) = (0, 0);
        loop {
            if cur.1 > 0 {
                if leaf(cur.0, cur.1, t_max) {
                    hit = true;
                    if ANY {
                        return true;
                    }
                }
            } else {
                let node = &self.nodes[cur.0 as usize];
                visit(cur.0);
                let b = &node.bounds;
                let slab = |row: usize, axis: usize| b[row] * inv[axis] - org[axis];
                let t_near = slab(near[0], 0).max(slab(near[1], 1)).max(slab(near[2], 2).max(Vec4::ZERO));
                let t_far =
                    slab(far[0], 0).min(slab(far[1], 1)).min(slab(far[2], 2).min(Vec4::splat(*t_max)));
                let hit_lanes = t_near.cmple(t_far);
                let mask = hit_lanes.bitmask();
                if mask != 0 {
                    let first = mask.trailing_zeros() as usize;
                    if mask & (mask - 1) == 0 {
                        cur = (node.child[first], node.count[first]);
                        continue;
                    }
                    // Several children: sort them near to far, visit the
                    // nearest next and push the others farthest first.
                    let keys = sort_keys(t_near, hit_lanes);
                    for &key in keys[1..mask.count_ones() as usize].iter().rev() {
                        let lane = (key & 3) as usize;
                        stack.push((node.child[lane], node.count[lane], f32::from_bits(key & !3)));
                    }
                    let lane = (keys[0] & 3) as usize;
                    cur = (node.child[lane], node.count[lane]);
                    continue;
                }
            }
            // Pop, skipping entries beyond the closest hit found since their push.
            loop {
                let Some((child, count, entry)) = stack.pop() else { return hit };
                if entry < *t_max {
                    cur = (child, count);
                    break;
                }
            }
        }
    }
}
