//! The builders: binned SAH (the default) and object-median splits (the
//! quick, low-quality baseline), both producing the canonical [`Bvh2`].
//!
//! Subtrees are built in parallel with `rayon::join` once they are big
//! enough, and the bounds and bins of big nodes are computed in parallel
//! too. A node over `n` primitives owns a slot range of `2n - 1` nodes in a
//! scratch array (left subtree first), so parallel subtrees write disjoint
//! slices without locks; a final pass packs the used slots depth-first.

use std::time::Instant;

use glam::{Vec3, Vec3A, Vec4};
use rayon::prelude::*;

use crate::{Aabb, Bvh2, Bvh2Node};

/// Most bins per axis a binned build may use.
pub const MAX_BINS: usize = 32;

/// Below this depth the SAH decides splits; deeper, nodes are split at the
/// object median, which bounds the depth by this plus log2(n) and so keeps
/// the fixed traversal stacks ([`crate::MAX_DEPTH`]) sufficient.
pub const SAH_DEPTH_LIMIT: u32 = 32;

/// Nodes over at least this many primitives build their two subtrees in parallel.
const PARALLEL_SUBTREE: usize = 2048;
/// Nodes over at least this many primitives compute bounds and bins in parallel.
const PARALLEL_BINNING: usize = 1 << 16;
const CHUNK: usize = 1 << 14;

/// How split planes are chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitMethod {
    /// Surface area heuristic evaluated at bin boundaries of the centroid bounds.
    BinnedSah,
    /// Half the primitives on each side, along the longest centroid axis.
    Median,
}

/// Builder settings. The SAH cost of a tree is
/// `sum over interior nodes of traversal_cost * area(node)` plus
/// `sum over leaves of intersection_cost * count * area(leaf)`,
/// divided by the root's area.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildOptions {
    pub split: SplitMethod,
    /// Bins per axis (2..=[`MAX_BINS`]).
    pub bins: usize,
    /// Leaves never hold more primitives than this.
    pub max_leaf: u32,
    /// SAH cost of visiting a node: its box tests and the stack work.
    pub traversal_cost: f32,
    /// SAH cost of one primitive test.
    pub intersection_cost: f32,
}

impl BuildOptions {
    /// Triangle BVHs. A Möller–Trumbore test costs about as much as visiting a
    /// node (a box test plus ordering and stack work), hence equal costs;
    /// the SAH then stops splitting at about 2–4 triangles.
    pub const TRIANGLES: BuildOptions = BuildOptions {
        split: SplitMethod::BinnedSah,
        bins: 16,
        max_leaf: 8,
        traversal_cost: 1.0,
        intersection_cost: 1.0,
    };

    /// Instance BVHs: "intersecting" an instance means a whole bottom-level
    /// traversal, so every instance gets its own leaf.
    pub const INSTANCES: BuildOptions = BuildOptions { max_leaf: 1, bins: 32, ..Self::TRIANGLES };

    /// Same leaves, median splits: fast to build, worse to trace.
    pub const QUICK: BuildOptions = BuildOptions { split: SplitMethod::Median, ..Self::TRIANGLES };
}

/// One primitive's box with its index in the builder's input (32 bytes).
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct PrimRef {
    min: Vec3,
    id: u32,
    max: Vec3,
    _pad: u32,
}

impl PrimRef {
    /// Both corners as aligned 16-byte loads (the fourth lanes, holding the
    /// id and padding, are ignored by `Vec3A`): the builder reads every
    /// primitive a few times per tree level, and three-float loads cost shuffles.
    #[inline(always)]
    fn corners(&self) -> (Vec3A, Vec3A) {
        let [min, max]: &[Vec4; 2] = bytemuck::cast_ref(self);
        (Vec3A::from_vec4(*min), Vec3A::from_vec4(*max))
    }
    #[inline(always)]
    fn aabb(&self) -> Aabb {
        let (min, max) = self.corners();
        Aabb { min, max }
    }
    #[inline(always)]
    fn centroid2(&self) -> Vec3A {
        let (min, max) = self.corners();
        min + max
    }
}

impl Bvh2 {
    /// Builds over primitive boxes; leaf ranges index [`Bvh2::prim_order`],
    /// which lists input indices in leaf order.
    pub fn build(prims: &[Aabb], options: &BuildOptions) -> Bvh2 {
        let start = Instant::now();
        assert!((2..=MAX_BINS).contains(&options.bins) && options.max_leaf >= 1);
        assert!(prims.len() < (u32::MAX / 2) as usize, "too many primitives for u32 node indices");
        if prims.is_empty() {
            return Bvh2 { nodes: Vec::new(), prim_order: Vec::new(), build_ms: 0.0 };
        }
        let mut refs: Vec<PrimRef> = prims
            .par_iter()
            .enumerate()
            .map(|(i, b)| PrimRef { min: b.min.into(), id: i as u32, max: b.max.into(), _pad: 0 })
            .collect();
        let mut scratch: Vec<Bvh2Node> = bytemuck::zeroed_vec(2 * prims.len() - 1);
        let bounds = bounds_of(&refs);
        build_node(options, &mut refs, bounds, 0, &mut scratch, 0, 0);
        let nodes = pack(&scratch);
        let prim_order = refs.par_iter().map(|r| r.id).collect();
        Bvh2 { nodes, prim_order, build_ms: start.elapsed().as_secs_f64() * 1e3 }
    }
}

/// A node's primitives: the box around them and the box around their
/// doubled centroids (which binning divides).
#[derive(Clone, Copy, Debug)]
struct Bounds {
    prims: Aabb,
    centroids: Aabb,
}

/// Builds the subtree over `refs` (primitives `first..` of the final order)
/// into `slots`, whose first element is this node and which lies at index
/// `base` of the scratch array. In the scratch array an interior node's
/// left child is the next slot and `left_or_first` holds the right child's index.
fn build_node(
    o: &BuildOptions,
    refs: &mut [PrimRef],
    bounds: Bounds,
    first: u32,
    slots: &mut [Bvh2Node],
    base: u32,
    depth: u32,
) {
    let n = refs.len();
    let (head, rest) = slots.split_at_mut(1);
    let Some((mid, left_bounds, right_bounds)) = split(o, refs, &bounds, depth) else {
        head[0] = Bvh2Node::new(&bounds.prims, first, n as u32);
        return;
    };
    let right_base = base + 2 * mid as u32;
    head[0] = Bvh2Node::new(&bounds.prims, right_base, 0);
    let (left_refs, right_refs) = refs.split_at_mut(mid);
    let (left_slots, right_slots) = rest.split_at_mut(2 * mid - 1);
    let right_first = first + mid as u32;
    let mut left = || build_node(o, left_refs, left_bounds, first, left_slots, base + 1, depth + 1);
    let mut right =
        || build_node(o, right_refs, right_bounds, right_first, right_slots, right_base, depth + 1);
    if n >= PARALLEL_SUBTREE {
        rayon::join(left, right);
    } else {
        left();
        right();
    }
}

fn bounds_of(refs: &[PrimRef]) -> Bounds {
    let fold = |b: Bounds, r: &PrimRef| Bounds {
        prims: b.prims.union(r.aabb()),
        centroids: b.centroids.grow_point(r.centroid2()),
    };
    let merge = |a: Bounds, b: Bounds| Bounds {
        prims: a.prims.union(b.prims),
        centroids: a.centroids.union(b.centroids),
    };
    let empty = Bounds { prims: Aabb::EMPTY, centroids: Aabb::EMPTY };
    if refs.len() >= PARALLEL_BINNING {
        refs.par_chunks(CHUNK).map(|c| c.iter().fold(empty, fold)).reduce(|| empty, merge)
    } else {
        refs.iter().fold(empty, fold)
    }
}

/// Decides whether to split; if so, partitions `refs` and returns the size
/// of the left part (`0 < mid < n`) and the bounds of both parts, else `None`
/// for a leaf. The binned path gets the children's bounds for free (boxes
/// from the bins, centroid boxes from the partition pass), which saves a
/// pass over the primitives per node.
fn split(
    o: &BuildOptions,
    refs: &mut [PrimRef],
    bounds: &Bounds,
    depth: u32,
) -> Option<(usize, Bounds, Bounds)> {
    let n = refs.len();
    if n == 1 {
        return None;
    }
    let may_be_leaf = n <= o.max_leaf as usize;
    let halve = |refs: &mut [PrimRef], mid: usize| {
        let (left, right) = refs.split_at(mid);
        (mid, bounds_of(left), bounds_of(right))
    };
    if o.split == SplitMethod::Median || depth >= SAH_DEPTH_LIMIT {
        if may_be_leaf {
            return None;
        }
        let mid = median_split(refs, &bounds.centroids);
        return Some(halve(refs, mid));
    }
    // More bins than about twice the primitives buys nothing.
    let binning = Binning::new(o.bins.min(2 * n), &bounds.centroids);
    let Some(best) = best_sah_split(&binning, refs, &bounds.centroids) else {
        // All centroids coincide: nothing to choose, halve if too many.
        return (!may_be_leaf).then(|| halve(refs, n / 2));
    };
    // Compare unnormalised costs (times the node's area): a flat node has
    // area 0, where both sides are 0 and a leaf wins.
    let area = bounds.prims.area();
    let leaf_cost = o.intersection_cost * n as f32 * area;
    let split_cost = o.traversal_cost * area + o.intersection_cost * best.cost;
    if may_be_leaf && leaf_cost <= split_cost {
        return None;
    }
    let (mid, left_centroids, right_centroids) =
        partition(refs, |r| binning.bin(r.centroid2())[best.axis] <= best.bin);
    // Binning guarantees both sides are non-empty; rounding must not break that.
    if mid == 0 || mid == n {
        return Some(halve(refs, n / 2));
    }
    let left = Bounds { prims: best.left, centroids: left_centroids };
    Some((mid, left, Bounds { prims: best.right, centroids: right_centroids }))
}

/// Object median along the longest centroid axis.
fn median_split(refs: &mut [PrimRef], centroids: &Aabb) -> usize {
    let axis = (centroids.max - centroids.min).max_position();
    let mid = refs.len() / 2;
    refs.select_nth_unstable_by(mid, |a, b| a.centroid2()[axis].total_cmp(&b.centroid2()[axis]));
    mid
}

/// Maps doubled centroids to bin indices per axis.
struct Binning {
    bins: usize,
    origin: Vec3A,
    scale: Vec3A,
    last: Vec3A,
}

impl Binning {
    fn new(bins: usize, centroids: &Aabb) -> Self {
        let extent = centroids.max - centroids.min;
        // Slightly less than bins/extent so the largest centroid lands in the
        // last bin, not one past it; axes without extent map to bin 0.
        let scale = Vec3A::select(
            extent.cmpgt(Vec3A::ZERO),
            Vec3A::splat(bins as f32 * (1.0 - 1e-5)) / extent,
            Vec3A::ZERO,
        );
        Binning { bins, origin: centroids.min, scale, last: Vec3A::splat((bins - 1) as f32) }
    }

    #[inline(always)]
    fn bin(&self, centroid2: Vec3A) -> [usize; 3] {
        let b = ((centroid2 - self.origin) * self.scale).min(self.last).max(Vec3A::ZERO).as_uvec3();
        [b.x as usize, b.y as usize, b.z as usize]
    }

    /// Per axis and bin, the count and box of `refs`: bin `i` of axis `a` is
    /// at `a * bins + i`.
    fn fill(&self, refs: &[PrimRef]) -> Vec<Bin> {
        let mut bins = vec![Bin::EMPTY; 3 * self.bins];
        for r in refs {
            let b = self.bin(r.centroid2());
            let aabb = r.aabb();
            for (axis, &i) in b.iter().enumerate() {
                let bin = &mut bins[axis * self.bins + i];
                bin.count += 1;
                bin.bounds = bin.bounds.union(aabb);
            }
        }
        bins
    }
}

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

impl Bin {
    const EMPTY: Bin = Bin { bounds: Aabb::EMPTY, count: 0 };
}

/// The chosen split: between bins `bin` and `bin + 1` of `axis`.
struct Best {
    /// Sum over both sides of area times primitive count.
    cost: f32,
    axis: usize,
    bin: usize,
    left: Aabb,
    right: Aabb,
}

/// The cheapest split plane over all axes and bin boundaries.
fn best_sah_split(binning: &Binning, refs: &[PrimRef], centroids: &Aabb) -> Option<Best> {
    let bins = if refs.len() >= PARALLEL_BINNING {
        refs.par_chunks(CHUNK).map(|c| binning.fill(c)).reduce_with(|mut a, b| {
            for (x, y) in a.iter_mut().zip(b) {
                *x = Bin { bounds: x.bounds.union(y.bounds), count: x.count + y.count };
            }
            a
        })?
    } else {
        binning.fill(refs)
    };
    let nb = binning.bins;
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        if centroids.max[axis] <= centroids.min[axis] {
            continue;
        }
        let bins = &bins[axis * nb..(axis + 1) * nb];
        // Sweep from the right, recording the right side of each boundary...
        let mut right_cost = [0.0f32; MAX_BINS];
        let mut right_count = [0u32; MAX_BINS];
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        for i in (1..nb).rev() {
            acc = acc.union(bins[i].bounds);
            count += bins[i].count;
            right_cost[i - 1] = acc.area() * count as f32;
            right_count[i - 1] = count;
        }
        // ...then from the left, combining.
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        for i in 0..nb - 1 {
            acc = acc.union(bins[i].bounds);
            count += bins[i].count;
            if count == 0 || right_count[i] == 0 {
                continue;
            }
            let cost = acc.area() * count as f32 + right_cost[i];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, i));
            }
        }
    }
    let (cost, axis, bin) = best?;
    let side =
        |range: std::ops::Range<usize>| bins[range].iter().fold(Aabb::EMPTY, |b, bin| b.union(bin.bounds));
    Some(Best {
        cost,
        axis,
        bin,
        left: side(axis * nb..axis * nb + bin + 1),
        right: side(axis * nb + bin + 1..(axis + 1) * nb),
    })
}

/// Moves the elements satisfying `left` to the front; returns their count
/// and the centroid boxes of both sides.
fn partition(refs: &mut [PrimRef], left: impl Fn(&PrimRef) -> bool) -> (usize, Aabb, Aabb) {
    let (mut i, mut j) = (0, refs.len());
    let (mut left_centroids, mut right_centroids) = (Aabb::EMPTY, Aabb::EMPTY);
    while i < j {
        let c = refs[i].centroid2();
        if left(&refs[i]) {
            left_centroids = left_centroids.grow_point(c);
            i += 1;
        } else {
            right_centroids = right_centroids.grow_point(c);
            j -= 1;
            refs.swap(i, j);
        }
    }
    (i, left_centroids, right_centroids)
}

/// Packs the scratch tree depth-first into the final layout, where the two
/// children of a node are adjacent (`left_or_first` is the left child).
fn pack(scratch: &[Bvh2Node]) -> Vec<Bvh2Node> {
    let mut nodes = Vec::with_capacity(scratch.len() / 2 + 1);
    nodes.push(scratch[0]);
    // (index in `nodes`, index in `scratch`) of nodes whose children are not yet placed.
    let mut todo = vec![(0usize, 0usize)];
    while let Some((out, src)) = todo.pop() {
        if scratch[src].count > 0 {
            continue;
        }
        let (left, right) = (src + 1, scratch[src].left_or_first as usize);
        let first_child = nodes.len();
        nodes[out].left_or_first = first_child as u32;
        nodes.push(scratch[left]);
        nodes.push(scratch[right]);
        todo.push((first_child + 1, right));
        todo.push((first_child, left));
    }
    nodes
}
