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
/// `sum over leaves of intersection_cost * blocks(count) * area(leaf)`,
/// divided by the root's area, where `blocks(n) = ceil(n / block)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildOptions {
    /// How split planes are chosen.
    pub split: SplitMethod,
    /// Bins per axis (2..=[`MAX_BINS`]).
    pub bins: usize,
    /// Leaves never hold more primitives than this.
    pub max_leaf: u32,
    /// Primitives tested together (a [`crate::Tri4`] block holds 4; a power
    /// of two): a leaf costs one intersection per started block.
    pub block: u32,
    /// SAH cost of visiting a node: its box tests and the stack work.
    pub traversal_cost: f32,
    /// SAH cost of one block test.
    pub intersection_cost: f32,
}

impl BuildOptions {
    /// Triangle BVHs with [`crate::Tri4`] leaves. A 4-wide triangle test costs
    /// about as much as a node visit (a 4-wide box test plus ordering and
    /// stack work), hence equal costs; leaves then hold 2–4 triangles, rarely
    /// more than one block.
    pub const TRIANGLES: BuildOptions = BuildOptions {
        split: SplitMethod::BinnedSah,
        bins: 16,
        max_leaf: 8,
        block: 4,
        traversal_cost: 1.0,
        intersection_cost: 1.0,
    };

    /// Instance BVHs: "intersecting" an instance means a whole bottom-level
    /// traversal, so every instance gets its own leaf.
    pub const INSTANCES: BuildOptions = BuildOptions { max_leaf: 1, block: 1, bins: 32, ..Self::TRIANGLES };

    /// The constants the reported SAH costs use ([`crate::BvhStats`]): the
    /// conventional per-primitive SAH (traversal and intersection cost 1,
    /// one intersection per primitive), comparable across builders, layouts
    /// and devices whatever block size a build optimised for.
    pub const METRIC: BuildOptions = BuildOptions { block: 1, ..Self::TRIANGLES };

    /// Same leaves, median splits: fast to build, worse to trace.
    pub const QUICK: BuildOptions = BuildOptions { split: SplitMethod::Median, ..Self::TRIANGLES };

    /// Block tests a leaf of `count` primitives costs (`block` is a power
    /// of two: a shift, not a division, in the builder's inner loop).
    #[inline(always)]
    pub fn blocks(&self, count: u32) -> f32 {
        ((count + self.block - 1) >> self.block.trailing_zeros()) as f32
    }
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
        assert!(options.block.is_power_of_two(), "blocks of {} primitives", options.block);
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

impl Bvh2 {
    /// Moves every leaf's range to start at a multiple of `block`, so leaves
    /// are runs of whole blocks (e.g. of [`crate::Tri4`]). Padding slots get
    /// `u32::MAX` in [`Bvh2::prim_order`]; leaves keep their depth-first order.
    pub fn align_leaves(&mut self, block: u32) {
        let mut order = Vec::with_capacity(self.prim_order.len() * 3 / 2);
        let mut todo = if self.nodes.is_empty() { vec![] } else { vec![0usize] };
        while let Some(i) = todo.pop() {
            let node = &mut self.nodes[i];
            if node.is_leaf() {
                let old = node.left_or_first as usize..(node.left_or_first + node.count) as usize;
                node.left_or_first = order.len() as u32;
                order.extend_from_slice(&self.prim_order[old]);
                order.resize(order.len().next_multiple_of(block as usize), u32::MAX);
            } else {
                let left = node.left_or_first as usize;
                todo.extend([left + 1, left]);
            }
        }
        self.prim_order = order;
    }
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
    let Some(best) = best_sah_split(o, &binning, refs, &bounds.centroids) else {
        // All centroids coincide: nothing to choose, halve if too many.
        return (!may_be_leaf).then(|| halve(refs, n / 2));
    };
    // Compare unnormalised costs (times the node's area): a flat node has
    // area 0, where both sides are 0 and a leaf wins.
    let area = bounds.prims.area();
    let leaf_cost = o.intersection_cost * o.blocks(n as u32) * area;
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
        // Bin i holds what rounds to i after scaling the centroid range to
        // [0, bins - 1] (the end bins are half as wide); axes without extent
        // map to bin 0.
        let scale =
            Vec3A::select(extent.cmpgt(Vec3A::ZERO), Vec3A::splat((bins - 1) as f32) / extent, Vec3A::ZERO);
        Binning { bins, origin: centroids.min, scale, last: Vec3A::splat((bins - 1) as f32) }
    }

    /// Per axis, the bin of a doubled centroid. Rounds by adding 2^23, which
    /// leaves the nearest integer in the low mantissa bits: no float-to-int
    /// conversions, which cost more than the rest of the binning.
    #[inline(always)]
    fn bin(&self, centroid2: Vec3A) -> [usize; 3] {
        let x = ((centroid2 - self.origin) * self.scale).min(self.last).max(Vec3A::ZERO);
        let bits: [u32; 4] = bytemuck::cast(x + Vec3A::splat(8_388_608.0));
        // The mask also proves to the compiler that indices are in range.
        [0, 1, 2].map(|axis| (bits[axis] & 0x7f_ffff) as usize & (MAX_BINS - 1))
    }

    /// Per axis and bin, the count and box of `refs`.
    fn fill(&self, refs: &[PrimRef]) -> Bins {
        let mut bins = Bins::EMPTY;
        for r in refs {
            let b = self.bin(r.centroid2());
            let aabb = r.aabb();
            for (axis, &i) in b.iter().enumerate() {
                bins.count[axis][i] += 1;
                bins.bounds[axis][i] = bins.bounds[axis][i].union(aabb);
            }
        }
        bins
    }
}

/// Per axis and bin: primitive count and box (3.4 KB, on the stack: cheaper
/// to clear than to allocate per node).
#[derive(Clone, Copy)]
struct Bins {
    count: [[u32; MAX_BINS]; 3],
    bounds: [[Aabb; MAX_BINS]; 3],
}

impl Bins {
    const EMPTY: Bins = Bins { count: [[0; MAX_BINS]; 3], bounds: [[Aabb::EMPTY; MAX_BINS]; 3] };

    fn merge(mut self, other: Bins) -> Bins {
        for axis in 0..3 {
            for i in 0..MAX_BINS {
                self.count[axis][i] += other.count[axis][i];
                self.bounds[axis][i] = self.bounds[axis][i].union(other.bounds[axis][i]);
            }
        }
        self
    }
}

/// The chosen split: between bins `bin` and `bin + 1` of `axis`.
struct Best {
    /// Sum over both sides of area times block count.
    cost: f32,
    axis: usize,
    bin: usize,
    left: Aabb,
    right: Aabb,
}

/// The cheapest split plane over all axes and bin boundaries.
fn best_sah_split(o: &BuildOptions, binning: &Binning, refs: &[PrimRef], centroids: &Aabb) -> Option<Best> {
    let bins = if refs.len() >= PARALLEL_BINNING {
        refs.par_chunks(CHUNK).map(|c| binning.fill(c)).reduce(|| Bins::EMPTY, Bins::merge)
    } else {
        binning.fill(refs)
    };
    let nb = binning.bins;
    let (mut best_cost, mut best_axis, mut best_bin) = (f32::INFINITY, 0, usize::MAX);
    for axis in 0..3 {
        if centroids.max[axis] <= centroids.min[axis] {
            continue;
        }
        let (counts, boxes) = (&bins.count[axis], &bins.bounds[axis]);
        // Sweep from the right, recording the right side of each boundary...
        let mut right_cost = [0.0f32; MAX_BINS];
        let mut right_count = [0u32; MAX_BINS];
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        for i in (1..nb).rev() {
            acc = acc.union(boxes[i]);
            count += counts[i];
            right_cost[i - 1] = acc.area() * o.blocks(count);
            right_count[i - 1] = count;
        }
        // ...then from the left, combining.
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        for i in 0..nb - 1 {
            acc = acc.union(boxes[i]);
            count += counts[i];
            let cost = acc.area() * o.blocks(count) + right_cost[i];
            if count > 0 && right_count[i] > 0 && cost < best_cost {
                (best_cost, best_axis, best_bin) = (cost, axis, i);
            }
        }
    }
    if best_bin == usize::MAX {
        return None;
    }
    let boxes = &bins.bounds[best_axis];
    let side = |range: std::ops::Range<usize>| boxes[range].iter().fold(Aabb::EMPTY, |b, &a| b.union(a));
    let (left, right) = (side(0..best_bin + 1), side(best_bin + 1..nb));
    Some(Best { cost: best_cost, axis: best_axis, bin: best_bin, left, right })
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
