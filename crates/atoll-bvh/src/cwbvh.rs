//! `Cwbvh`: the compressed 8-wide BVH of Ylitie, Karras and Laine (2017),
//! "Efficient Incoherent Ray Traversal on GPUs Through Compressed Wide
//! BVHs", converted from [`Bvh2`], with a scalar CPU traversal that serves as
//! the reference for the GPU kernel.
//!
//! - Nodes are the paper's 80-byte [`CwbvhNode`]: child boxes quantized to
//!   8 bits per plane on a per-node grid (origin plus a power-of-two cell size
//!   per axis), so the GPU uploads them byte for byte.
//! - Collapse: the paper's SAH dynamic programme (section 3.1). For every
//!   binary node `n` and slot budget `i` in 1..=8 it computes the cheapest way
//!   to represent `n`'s subtree with at most `i` slots of its parent: as leaf
//!   slots (all of the subtree's primitives, in chunks of at most 3, each
//!   chunk with the subtree's box: `intersection_cost * prims * area`), as one
//!   interior child (`traversal_cost * area` plus the best distribution of its
//!   two children over 8 slots), or by distributing the budget over its two
//!   children. Costs are those of [`BuildOptions::METRIC`]. A [`Bvh2`] leaf of
//!   more than 3 primitives cannot be split further, so it becomes
//!   `ceil(count / 3)` leaf slots of one node (or a node of its own).
//! - Slots are assigned by the paper's ray-octant heuristic (greedily; see
//!   `assign_slots`), so a GPU kernel visits children nearest-first by
//!   walking hit-mask bits in `slot ^ octant` order. Interior children are
//!   stored in slot order: slot `s` holds node `child_base + popcount(imask
//!   & ((1 << s) - 1))`, its meta `0b001_xxxxx` with `xxxxx = 24 + s`. The
//!   CPU traversal sorts by entry distance instead.
//! - Primitives are renumbered: all leaf primitives of a node are contiguous
//!   from its `prim_base` (at most 24 of them, the 5-bit offset), and
//!   [`Cwbvh::prim_order`] maps the new numbering to the [`Bvh2`]'s leaf order.

use glam::Vec3A;

use crate::layout::{BvhStats, TraversalRay, MAX_DEPTH};
use crate::{Aabb, BuildOptions, Bvh2};

/// Slots per node.
pub const WIDTH: usize = 8;
/// Most primitives of one leaf slot.
pub const MAX_LEAF_PRIMS: u32 = 3;
/// Most leaf primitives of one node (the 5-bit offset in `meta`).
pub const MAX_NODE_PRIMS: u32 = 24;

/// A node of [`Cwbvh`], exactly the paper's 80-byte layout.
///
/// Child `i`'s box is, per axis, `origin + 2^(exponent - 127) * [lo, hi]`
/// (the product is exact, so the GPU may use a fused multiply-add). Empty
/// slots have `meta == 0` and all-zero box bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct CwbvhNode {
    /// Quantization grid origin `p` (12 bytes): the node's box minimum.
    pub origin: [f32; 3],
    /// Per axis the grid cell size as a biased float exponent: the cell is
    /// `2^(e - 127)`, i.e. the float with bits `e << 23` (never 0, so never a
    /// zero or denormal cell).
    pub exponents: [u8; 3],
    /// Bit `i` set: slot `i` holds an interior child.
    pub imask: u8,
    /// Index of the first interior child node; interior children are
    /// consecutive, in slot order.
    pub child_base: u32,
    /// First primitive (in [`Cwbvh::prim_order`] numbering) of this node's
    /// leaf children; they are contiguous from here.
    pub prim_base: u32,
    /// Per slot `s`: 0 empty; interior child: `0b001_xxxxx` with
    /// `xxxxx = 24 + s` (node `child_base` plus the number of interior
    /// slots below `s`); leaf child: the primitive count in unary in the top
    /// 3 bits (`0b001`, `0b011`, `0b111` for 1..3) and the offset of its
    /// first primitive from `prim_base` in the low 5 bits (below 24).
    pub meta: [u8; 8],
    /// Per slot, the quantized box minimum along x.
    pub lo_x: [u8; 8],
    /// Per slot, the quantized box minimum along y.
    pub lo_y: [u8; 8],
    /// Per slot, the quantized box minimum along z.
    pub lo_z: [u8; 8],
    /// Per slot, the quantized box maximum along x.
    pub hi_x: [u8; 8],
    /// Per slot, the quantized box maximum along y.
    pub hi_y: [u8; 8],
    /// Per slot, the quantized box maximum along z.
    pub hi_z: [u8; 8],
}

const _: () = assert!(std::mem::size_of::<CwbvhNode>() == 80);

/// What one slot holds, decoded from `meta`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CwbvhChild {
    /// Nothing.
    Empty,
    /// An interior node (its index in [`Cwbvh::nodes`]).
    Node(u32),
    /// A leaf: `count` primitives (1..=3) from `first` (absolute, in
    /// [`Cwbvh::prim_order`] numbering).
    Leaf {
        /// First primitive.
        first: u32,
        /// Primitive count.
        count: u32,
    },
}

/// The grid cell size encoded by a biased exponent byte.
#[inline]
fn cell(e: u8) -> f32 {
    f32::from_bits((e as u32) << 23)
}

/// The dequantized coordinate: `origin + cell * q` (one rounding: the product is exact).
#[inline]
fn dequantize(origin: f32, cell: f32, q: u8) -> f32 {
    origin + cell * q as f32
}

impl CwbvhNode {
    /// The grid cell size per axis.
    pub fn scale(&self) -> Vec3A {
        Vec3A::new(cell(self.exponents[0]), cell(self.exponents[1]), cell(self.exponents[2]))
    }

    /// Slot `i`'s dequantized box (meaningless for an empty slot).
    pub fn child_aabb(&self, i: usize) -> Aabb {
        let o = Vec3A::from_array(self.origin);
        let s = self.scale();
        let lo = Vec3A::new(self.lo_x[i] as f32, self.lo_y[i] as f32, self.lo_z[i] as f32);
        let hi = Vec3A::new(self.hi_x[i] as f32, self.hi_y[i] as f32, self.hi_z[i] as f32);
        // Per component exactly `dequantize`: the product is exact, one rounding in the sum.
        Aabb { min: o + s * lo, max: o + s * hi }
    }

    /// What slot `i` holds.
    pub fn child(&self, i: usize) -> CwbvhChild {
        let meta = self.meta[i];
        if meta == 0 {
            CwbvhChild::Empty
        } else if self.imask >> i & 1 == 1 {
            CwbvhChild::Node(self.child_base + (self.imask as u32 & ((1u32 << i) - 1)).count_ones())
        } else {
            CwbvhChild::Leaf { first: self.prim_base + (meta & 31) as u32, count: (meta >> 5).count_ones() }
        }
    }

    /// Sets the grid from the node's box: origin its minimum, per axis the
    /// smallest power-of-two cell with 255 cells covering the box.
    fn set_grid(&mut self, b: &Aabb) {
        self.origin = b.min.into();
        for axis in 0..3 {
            let (lo, hi) = (b.min[axis], b.max[axis]);
            let extent = hi - lo;
            let mut e = if extent > 0.0 {
                ((extent as f64 / 255.0).log2().ceil() as i32 + 127).clamp(1, 254) as u8
            } else {
                1
            };
            // The float extent may have been rounded down: make sure 255 cells reach the maximum.
            while e < 254 && dequantize(lo, cell(e), 255) < hi {
                e += 1;
            }
            self.exponents[axis] = e;
        }
    }

    /// Stores `b` (inside the node's box) in slot `i`, rounded outwards.
    fn set_child_box(&mut self, i: usize, b: &Aabb) {
        let mut lo = [0u8; 3];
        let mut hi = [0u8; 3];
        for axis in 0..3 {
            let (o, c) = (self.origin[axis], cell(self.exponents[axis]));
            let to_grid = |x: f32| (x as f64 - o as f64) / c as f64;
            let mut q = to_grid(b.min[axis]).floor().clamp(0.0, 255.0) as u8;
            while q > 0 && dequantize(o, c, q) > b.min[axis] {
                q -= 1;
            }
            lo[axis] = q;
            let mut q = to_grid(b.max[axis]).ceil().clamp(0.0, 255.0) as u8;
            while q < 255 && dequantize(o, c, q) < b.max[axis] {
                q += 1;
            }
            hi[axis] = q;
        }
        (self.lo_x[i], self.lo_y[i], self.lo_z[i]) = (lo[0], lo[1], lo[2]);
        (self.hi_x[i], self.hi_y[i], self.hi_z[i]) = (hi[0], hi[1], hi[2]);
    }
}

/// Compressed 8-wide BVH; node 0 is the root (always an interior node, also
/// over a single leaf). Empty when converted from an empty [`Bvh2`].
#[derive(Clone, Debug, Default)]
pub struct Cwbvh {
    /// The nodes; the root is node 0.
    pub nodes: Vec<CwbvhNode>,
    /// For each primitive slot, its index in the [`Bvh2`]'s leaf order:
    /// callers permute their per-primitive data as
    /// `new[i] = old_leaf_order[prim_order[i]]`.
    pub prim_order: Vec<u32>,
    /// The root's exact box (`Aabb::EMPTY` when empty).
    pub bounds: Aabb,
}

/// How the dynamic programme represents a binary subtree within a slot budget.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Choice {
    /// Leaf slots holding all of the subtree's primitives.
    Leaf,
    /// One interior child node.
    Node,
    /// The two children, with these budgets.
    Split(u8, u8),
    /// No way (only a leaf of more than 24 primitives has none).
    None,
}

/// A child of a node under construction: a binary node that becomes an
/// interior child, or one whose primitives become leaf slots.
#[derive(Clone, Copy)]
enum Item {
    Node(usize),
    Leaf(usize),
}

/// What one slot of a node under construction holds: a binary node that
/// becomes an interior child, or a run of (at most 3) leaf primitives.
enum SlotContent {
    Node(usize),
    Prims(std::ops::Range<usize>),
}

/// The SAH tables over a [`Bvh2`].
struct Collapse<'a> {
    bvh: &'a Bvh2,
    /// Per binary node, the best cost and choice for each budget `1..=8` (index 0 unused).
    cost: Vec<[f32; WIDTH + 1]>,
    choice: Vec<[Choice; WIDTH + 1]>,
    /// Per interior binary node, the best split of its children over 8 slots.
    split8: Vec<(u8, u8)>,
    /// Primitives per subtree.
    prims: Vec<u32>,
}

impl<'a> Collapse<'a> {
    fn new(bvh: &'a Bvh2) -> Self {
        let src = &bvh.nodes;
        let n = src.len();
        let o = BuildOptions::METRIC;
        let mut t = Collapse {
            bvh,
            cost: vec![[f32::INFINITY; WIDTH + 1]; n],
            choice: vec![[Choice::None; WIDTH + 1]; n],
            split8: vec![(0, 0); n],
            prims: vec![0; n],
        };
        // Children before parents: a post-order over an explicit stack.
        let mut order = Vec::with_capacity(n);
        let mut todo = vec![0usize];
        while let Some(i) = todo.pop() {
            order.push(i);
            if !src[i].is_leaf() {
                let l = src[i].left_or_first as usize;
                todo.extend([l, l + 1]);
            }
        }
        for &i in order.iter().rev() {
            let node = &src[i];
            let area = node.aabb().area();
            let leaf_slots;
            let mut inner = o.traversal_cost * area;
            if node.is_leaf() {
                assert!(
                    node.count <= MAX_NODE_PRIMS,
                    "a Bvh2 leaf of {} primitives does not fit one Cwbvh node",
                    node.count
                );
                t.prims[i] = node.count;
                leaf_slots = node.count.div_ceil(MAX_LEAF_PRIMS) as usize;
            } else {
                let l = node.left_or_first as usize;
                t.prims[i] = t.prims[l] + t.prims[l + 1];
                leaf_slots = t.prims[i].div_ceil(MAX_LEAF_PRIMS) as usize;
            }
            let leaf_cost = o.intersection_cost * t.prims[i] as f32 * area;
            if node.is_leaf() {
                inner += leaf_cost;
            } else {
                let (best, a, b) = t.distribute(i, WIDTH);
                t.split8[i] = (a, b);
                inner += best;
            }
            for budget in 1..=WIDTH {
                let mut best = (inner, Choice::Node);
                if leaf_slots <= budget && leaf_cost <= best.0 {
                    best = (leaf_cost, Choice::Leaf);
                }
                if !node.is_leaf() && budget >= 2 {
                    let (c, a, b) = t.distribute(i, budget);
                    if c < best.0 {
                        best = (c, Choice::Split(a, b));
                    }
                }
                if best.0 == f32::INFINITY {
                    best.1 = Choice::None;
                }
                t.cost[i][budget] = best.0;
                t.choice[i][budget] = best.1;
            }
        }
        t
    }

    /// The cheapest split of interior node `i`'s children over `budget` slots:
    /// `(cost, left budget, right budget)`.
    fn distribute(&self, i: usize, budget: usize) -> (f32, u8, u8) {
        let l = self.bvh.nodes[i].left_or_first as usize;
        let mut best = (f32::INFINITY, 1, budget as u8 - 1);
        for k in 1..budget {
            let c = self.cost[l][k] + self.cost[l + 1][budget - k];
            if c < best.0 {
                best = (c, k as u8, (budget - k) as u8);
            }
        }
        best
    }

    /// Appends the items representing subtree `i` within `budget` slots.
    fn collect(&self, i: usize, budget: usize, items: &mut Vec<Item>) {
        match self.choice[i][budget] {
            Choice::Leaf => items.push(Item::Leaf(i)),
            Choice::Node => items.push(Item::Node(i)),
            Choice::Split(a, b) => {
                let l = self.bvh.nodes[i].left_or_first as usize;
                self.collect(l, a as usize, items);
                self.collect(l + 1, b as usize, items);
            }
            Choice::None => unreachable!("no way to represent subtree {i} in {budget} slots"),
        }
    }

    /// The children of the Cwbvh node made from binary node `i`.
    fn children(&self, i: usize) -> Vec<Item> {
        let node = &self.bvh.nodes[i];
        let mut items = Vec::with_capacity(WIDTH);
        if node.is_leaf() {
            items.push(Item::Leaf(i));
        } else {
            let l = node.left_or_first as usize;
            let (a, b) = self.split8[i];
            self.collect(l, a as usize, &mut items);
            self.collect(l + 1, b as usize, &mut items);
        }
        items
    }

    /// The leaf-order indices of subtree `i`'s primitives, appended to `out`.
    fn leaf_prims(&self, i: usize, out: &mut Vec<u32>) {
        let mut todo = vec![i];
        while let Some(j) = todo.pop() {
            let n = &self.bvh.nodes[j];
            if n.is_leaf() {
                out.extend(n.left_or_first..n.left_or_first + n.count);
            } else {
                // Right pushed first so the left subtree's primitives come first.
                todo.extend([n.left_or_first as usize + 1, n.left_or_first as usize]);
            }
        }
    }
}

/// The slot of each child (at most [`WIDTH`] boxes inside `parent`), after
/// Ylitie et al.: slot `s` stands for the diagonal direction whose x, y, z
/// components are positive where bits 0, 1, 2 of `s` are set, and gets the
/// child lying farthest against it, i.e. the one a ray travelling that way
/// meets first. A ray of direction octant `o` then visits slots in the order
/// of `slot ^ o`, nearest first, without sorting. Pairs are taken greedily,
/// cheapest first (the paper uses an auction; greedy is within a few
/// percent for eight slots).
fn assign_slots(parent: &Aabb, boxes: &[Aabb]) -> Vec<usize> {
    let center = (parent.min + parent.max) * 0.5;
    let mut cost = Vec::with_capacity(boxes.len() * WIDTH);
    for (c, b) in boxes.iter().enumerate() {
        let offset = (b.min + b.max) * 0.5 - center;
        for s in 0..WIDTH {
            let d = Vec3A::new(
                if s & 1 != 0 { 1.0 } else { -1.0 },
                if s & 2 != 0 { 1.0 } else { -1.0 },
                if s & 4 != 0 { 1.0 } else { -1.0 },
            );
            cost.push((offset.dot(d), c, s));
        }
    }
    cost.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut slot_of = vec![usize::MAX; boxes.len()];
    let mut taken = [false; WIDTH];
    for (_, c, s) in cost {
        if slot_of[c] == usize::MAX && !taken[s] {
            slot_of[c] = s;
            taken[s] = true;
        }
    }
    slot_of
}

impl Cwbvh {
    /// Collapses a binary BVH with the SAH dynamic programme (see the module
    /// docs). Panics on a [`Bvh2`] leaf of more than 24 primitives.
    pub fn from_bvh2(bvh: &Bvh2) -> Cwbvh {
        let Some(root) = bvh.nodes.first() else { return Cwbvh::default() };
        let tables = Collapse::new(bvh);
        let src = &bvh.nodes;
        let mut nodes = vec![CwbvhNode::default()];
        let mut prim_order = Vec::with_capacity(bvh.prim_order.len());
        let mut todo = vec![(0usize, 0usize)]; // (Bvh2 node, Cwbvh node)
        let mut prims = Vec::with_capacity(MAX_NODE_PRIMS as usize);
        while let Some((from, to)) = todo.pop() {
            let items = tables.children(from);
            let mut node = CwbvhNode::default();
            node.set_grid(&src[from].aabb());
            node.child_base = nodes.len() as u32;
            node.prim_base = prim_order.len() as u32;
            // Leaf children are split into chunks of at most 3 primitives,
            // one slot each; then every child gets the slot of the octant it
            // lies towards (see `assign_slots`).
            let mut children: Vec<(SlotContent, Aabb)> = Vec::with_capacity(WIDTH);
            for item in &items {
                match *item {
                    Item::Node(i) => children.push((SlotContent::Node(i), src[i].aabb())),
                    Item::Leaf(i) => {
                        let start = prims.len();
                        tables.leaf_prims(i, &mut prims);
                        for chunk_start in (start..prims.len()).step_by(MAX_LEAF_PRIMS as usize) {
                            let end = (chunk_start + MAX_LEAF_PRIMS as usize).min(prims.len());
                            children.push((SlotContent::Prims(chunk_start..end), src[i].aabb()));
                        }
                    }
                }
            }
            assert!(children.len() <= WIDTH, "{} slots", children.len());
            let boxes: Vec<Aabb> = children.iter().map(|c| c.1).collect();
            let slots = assign_slots(&src[from].aabb(), &boxes);
            // Interior children are stored in slot order (child `child_base +
            // interior slots below`), leaf primitives likewise.
            let mut by_slot: [Option<usize>; WIDTH] = [None; WIDTH];
            for (c, &slot) in slots.iter().enumerate() {
                by_slot[slot] = Some(c);
            }
            for (slot, c) in by_slot.iter().enumerate() {
                let Some(c) = *c else { continue };
                let (content, b) = &children[c];
                node.set_child_box(slot, b);
                match content {
                    SlotContent::Node(i) => {
                        node.imask |= 1 << slot;
                        node.meta[slot] = (1 << 5) | (24 + slot as u8);
                        todo.push((*i, nodes.len()));
                        nodes.push(CwbvhNode::default());
                    }
                    SlotContent::Prims(range) => {
                        let offset = prim_order.len() as u32 - node.prim_base;
                        debug_assert!(offset + range.len() as u32 <= MAX_NODE_PRIMS);
                        let unary = (1u8 << range.len()) - 1;
                        node.meta[slot] = (unary << 5) | offset as u8;
                        prim_order.extend_from_slice(&prims[range.clone()]);
                    }
                }
            }
            prims.clear();
            nodes[to] = node;
        }
        Cwbvh { nodes, prim_order, bounds: root.aabb() }
    }

    /// Closest hit: visits the leaves whose boxes the ray `origin + t * dir`
    /// enters before the current `t_max`, nearer boxes first.
    /// `leaf(first, count, t_max)` tests primitives `first..first + count`
    /// (in [`Cwbvh::prim_order`] numbering), lowers `*t_max` on a closer hit
    /// and returns whether it hit. Returns whether any leaf hit.
    pub fn intersect(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        t_max: f32,
        leaf: impl FnMut(u32, u32, &mut f32) -> bool,
    ) -> bool {
        let mut t_max = t_max;
        self.traverse::<false>(&TraversalRay::new(origin, dir), &mut t_max, leaf)
    }

    /// Any hit: as [`Cwbvh::intersect`], but stops at the first leaf that hits.
    pub fn occluded(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        t_max: f32,
        leaf: impl FnMut(u32, u32, &mut f32) -> bool,
    ) -> bool {
        let mut t_max = t_max;
        self.traverse::<true>(&TraversalRay::new(origin, dir), &mut t_max, leaf)
    }

    /// The traversal behind [`Cwbvh::intersect`] (`ANY = false`) and
    /// [`Cwbvh::occluded`] (`ANY = true`), with the contract of
    /// [`crate::BvhLayout::traverse`]. Each node's hit children are sorted by
    /// entry distance; the nearest is visited next, the others are pushed
    /// farthest first and skipped when popped beyond the closest hit so far.
    pub fn traverse<const ANY: bool>(
        &self,
        ray: &TraversalRay,
        t_max: &mut f32,
        mut leaf: impl FnMut(u32, u32, &mut f32) -> bool,
    ) -> bool {
        if self.nodes.is_empty() || ray.box_entry(self.bounds.min, self.bounds.max, *t_max) == f32::INFINITY {
            return false;
        }
        let mut stack: Vec<(CwbvhChild, f32)> = Vec::with_capacity((WIDTH - 1) * MAX_DEPTH);
        let mut hit = false;
        let mut cur = CwbvhChild::Node(0);
        loop {
            match cur {
                CwbvhChild::Leaf { first, count } => {
                    if leaf(first, count, t_max) {
                        hit = true;
                        if ANY {
                            return true;
                        }
                    }
                }
                CwbvhChild::Node(index) => {
                    let node = &self.nodes[index as usize];
                    let mut hits: Vec<(CwbvhChild, f32)> = (0..WIDTH)
                        .filter(|&slot| node.meta[slot] != 0)
                        .filter_map(|slot| {
                            let b = node.child_aabb(slot);
                            let entry = ray.box_entry(b.min, b.max, *t_max);
                            (entry != f32::INFINITY).then_some((node.child(slot), entry))
                        })
                        .collect();
                    if !hits.is_empty() {
                        // Farthest first, so that the nearest is at the end.
                        hits.sort_by(|a, b| b.1.total_cmp(&a.1));
                        let (nearest, _) = hits.pop().unwrap();
                        stack.extend(hits);
                        cur = nearest;
                        continue;
                    }
                }
                CwbvhChild::Empty => unreachable!(),
            }
            // Pop, skipping entries beyond the closest hit found since their push.
            loop {
                let Some((child, entry)) = stack.pop() else { return hit };
                if entry < *t_max {
                    cur = child;
                    break;
                }
            }
        }
    }

    /// Node and leaf-slot counts, depth, SAH cost (with the constants of
    /// `options`, over the dequantized boxes: the root's exact box costs one
    /// traversal, each interior slot one traversal, each leaf slot
    /// `blocks(count)` intersections, relative to the root's area) and node
    /// bytes (`build_ms` left 0).
    pub fn stats(&self, options: &BuildOptions) -> BvhStats {
        let mut s = BvhStats { nodes: self.nodes.len(), ..Default::default() };
        if self.nodes.is_empty() {
            return s;
        }
        let mut cost = (options.traversal_cost * self.bounds.area()) as f64;
        let mut todo = vec![(0usize, 1u32)];
        while let Some((i, depth)) = todo.pop() {
            s.max_depth = s.max_depth.max(depth);
            let n = &self.nodes[i];
            for slot in 0..WIDTH {
                let area = n.child_aabb(slot).area();
                match n.child(slot) {
                    CwbvhChild::Empty => {}
                    CwbvhChild::Node(c) => {
                        cost += (options.traversal_cost * area) as f64;
                        todo.push((c as usize, depth + 1));
                    }
                    CwbvhChild::Leaf { count, .. } => {
                        s.leaves += 1;
                        cost += (options.intersection_cost * options.blocks(count) * area) as f64;
                    }
                }
            }
        }
        s.sah_cost = (cost / self.bounds.area().max(f32::MIN_POSITIVE) as f64) as f32;
        s.bytes = std::mem::size_of_val(&self.nodes[..]);
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::BvhLayout;
    use crate::TriAccel;
    use glam::Vec3;

    /// A small deterministic generator of floats in [0, 1).
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((self.0 >> 40) as f32) / (1u64 << 24) as f32
        }
        fn vec(&mut self) -> Vec3 {
            Vec3::new(self.next(), self.next(), self.next())
        }
    }

    /// Random triangles in a 100-unit cube, a few units across; every fifth
    /// lies in a plane of constant z (flat boxes), every eleventh is big.
    fn soup(n: usize, seed: u64) -> Vec<[Vec3; 3]> {
        let mut r = Rng(seed);
        (0..n)
            .map(|i| {
                let c = r.vec() * 100.0;
                let size = if i % 11 == 0 { 20.0 } else { 4.0 };
                let mut t = [c, c + (r.vec() - 0.5) * size, c + (r.vec() - 0.5) * size];
                if i % 5 == 0 {
                    for p in &mut t {
                        p.z = c.z;
                    }
                }
                t
            })
            .collect()
    }

    /// The Bvh2 and Cwbvh over a soup, and its triangles in Cwbvh primitive order.
    fn build(tris: &[[Vec3; 3]]) -> (Bvh2, Cwbvh, Vec<[Vec3; 3]>) {
        let boxes: Vec<Aabb> = tris.iter().map(|t| Aabb::from_points(*t)).collect();
        let bvh = Bvh2::build(&boxes, &BuildOptions::TRIANGLES);
        let cw = Cwbvh::from_bvh2(&bvh);
        let permuted = cw.prim_order.iter().map(|&i| tris[bvh.prim_order[i as usize] as usize]).collect();
        (bvh, cw, permuted)
    }

    fn accel(tris: &[[Vec3; 3]]) -> Vec<TriAccel> {
        tris.iter().map(|&t| TriAccel::new(t)).collect()
    }

    /// Checks the structure and returns the exact box of node `i`'s primitives.
    fn check_node(
        cw: &Cwbvh,
        tris: &[[Vec3; 3]],
        i: usize,
        seen_prims: &mut [bool],
        seen_nodes: &mut [bool],
    ) -> Aabb {
        assert!(!seen_nodes[i], "node {i} reached twice");
        seen_nodes[i] = true;
        let n = &cw.nodes[i];
        let mut total = Aabb::EMPTY;
        let mut interior = 0;
        let mut node_prims = 0;
        for slot in 0..WIDTH {
            let meta = n.meta[slot];
            let exact = match n.child(slot) {
                CwbvhChild::Empty => {
                    assert_eq!(n.imask >> slot & 1, 0);
                    continue;
                }
                CwbvhChild::Node(c) => {
                    assert_eq!(n.imask >> slot & 1, 1);
                    assert_eq!(meta >> 5, 1);
                    assert!(meta & 31 >= 24);
                    assert_eq!(c, n.child_base + interior);
                    interior += 1;
                    check_node(cw, tris, c as usize, seen_prims, seen_nodes)
                }
                CwbvhChild::Leaf { first, count } => {
                    assert_eq!(n.imask >> slot & 1, 0);
                    assert!((1..=3).contains(&count), "leaf of {count}");
                    assert!([0b001, 0b011, 0b111].contains(&(meta >> 5)));
                    let offset = (meta & 31) as u32;
                    assert!(offset < 24 && offset + count <= 24);
                    node_prims += count;
                    let mut b = Aabb::EMPTY;
                    for p in first..first + count {
                        assert!(!seen_prims[p as usize], "primitive {p} in two leaves");
                        seen_prims[p as usize] = true;
                        b = b.union(Aabb::from_points(tris[p as usize]));
                    }
                    b
                }
            };
            let q = n.child_aabb(slot);
            assert!(q.contains(&exact), "node {i} slot {slot}: {q:?} does not contain {exact:?}");
            total = total.union(exact);
        }
        assert!(node_prims <= 24);
        total
    }

    fn check(cw: &Cwbvh, tris: &[[Vec3; 3]], n: usize) {
        let mut sorted = cw.prim_order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..n as u32).collect::<Vec<_>>());
        if n == 0 {
            assert!(cw.nodes.is_empty());
            return;
        }
        let mut seen_prims = vec![false; n];
        let mut seen_nodes = vec![false; cw.nodes.len()];
        let all = check_node(cw, tris, 0, &mut seen_prims, &mut seen_nodes);
        assert!(seen_prims.iter().all(|&s| s) && seen_nodes.iter().all(|&s| s));
        assert!(cw.bounds.contains(&all));
    }

    /// Closest hit by brute force: `(t, triangle)`; the first of equal `t`.
    fn brute(tris: &[TriAccel], o: Vec3A, d: Vec3A, t_max: f32) -> Option<(f32, usize)> {
        let mut best = None;
        let mut t_max = t_max;
        for (i, tri) in tris.iter().enumerate() {
            if let Some((t, _, _)) = tri.intersect(o, d, t_max) {
                t_max = t;
                best = Some((t, i));
            }
        }
        best
    }

    fn closest(cw: &Cwbvh, tris: &[TriAccel], o: Vec3A, d: Vec3A, t_max: f32) -> Option<(f32, usize)> {
        let mut best = None;
        cw.intersect(o, d, t_max, |first, count, t_max| {
            let mut hit = false;
            for p in first..first + count {
                if let Some((t, _, _)) = tris[p as usize].intersect(o, d, *t_max) {
                    *t_max = t;
                    best = Some((t, p as usize));
                    hit = true;
                }
            }
            hit
        });
        best
    }

    fn any(cw: &Cwbvh, tris: &[TriAccel], o: Vec3A, d: Vec3A, t_max: f32) -> bool {
        cw.occluded(o, d, t_max, |first, count, t_max| {
            (first..first + count).any(|p| tris[p as usize].intersect(o, d, *t_max).is_some())
        })
    }

    /// Rays from inside and around the soup's cube: odd ones in random
    /// directions (every third of those with a finite `t_max`), even ones
    /// aimed at a random point of a random triangle, reached at `t = 1`
    /// (every fourth of those with `t_max` in 0.5..1.5).
    fn rays(n: usize, tris: &[TriAccel], seed: u64) -> Vec<(Vec3A, Vec3A, f32)> {
        let mut r = Rng(seed);
        (0..n)
            .map(|i| {
                let o = Vec3A::from(r.vec() * 140.0 - 20.0);
                if i % 2 == 1 {
                    let d = Vec3A::from(r.vec() * 2.0 - 1.0);
                    let t_max = if i % 3 == 0 { 20.0 + r.next() * 100.0 } else { f32::INFINITY };
                    return (o, d, t_max);
                }
                let tri = &tris[(r.next() * tris.len() as f32) as usize % tris.len()];
                let (u, v) = (r.next(), r.next());
                let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
                let target = Vec3A::from(tri.v0 + u * tri.e1 + v * tri.e2);
                let t_max = if i % 4 == 0 { 0.5 + r.next() } else { f32::INFINITY };
                (o, target - o, t_max)
            })
            .collect()
    }

    fn check_hits(cw: &Cwbvh, tris: &[TriAccel], seed: u64) -> usize {
        let mut hits = 0;
        for (o, d, t_max) in rays(2000, tris, seed) {
            let expected = brute(tris, o, d, t_max);
            let got = closest(cw, tris, o, d, t_max);
            match (expected, got) {
                (None, None) => {}
                (Some((te, ie)), Some((tg, ig))) => {
                    hits += 1;
                    assert_eq!(te, tg, "ray {o} {d}");
                    // Equal t on two triangles: either may win.
                    assert!(ie == ig || tris[ig].intersect(o, d, t_max).map(|h| h.0) == Some(te));
                }
                _ => panic!("ray {o} {d} {t_max}: brute force {expected:?}, Cwbvh {got:?}"),
            }
            assert_eq!(any(cw, tris, o, d, t_max), expected.is_some(), "any-hit of ray {o} {d}");
        }
        hits
    }

    #[test]
    fn node_is_the_papers_80_bytes() {
        assert_eq!(std::mem::size_of::<CwbvhNode>(), 80);
        assert_eq!(std::mem::align_of::<CwbvhNode>(), 4);
    }

    #[test]
    fn soups_make_valid_trees_with_conservative_boxes() {
        for (n, seed) in [(1, 1), (2, 2), (7, 3), (100, 4), (1000, 5), (20_000, 6)] {
            let tris = soup(n, seed);
            let (_, cw, permuted) = build(&tris);
            check(&cw, &permuted, n);
        }
    }

    #[test]
    fn quantization_is_conservative_on_awkward_boxes() {
        let mut r = Rng(9);
        for i in 0..2000 {
            let scale = [1e-6, 1e-3, 1.0, 1e3, 1e6][i % 5];
            let offset = [0.0, -7.3, 1e4, -1e5, 3.0][i / 5 % 5];
            let a = Vec3A::from(r.vec() * scale + offset);
            let b = Vec3A::from(r.vec() * scale + offset);
            let mut parent = Aabb::from_points([a.into(), b.into()]);
            if i % 7 == 0 {
                parent.max.y = parent.min.y; // flat
            }
            let mut node = CwbvhNode::default();
            node.set_grid(&parent);
            for slot in 0..WIDTH {
                let mut inside =
                    || (parent.min + (parent.max - parent.min) * Vec3A::from(r.vec())).min(parent.max);
                let child =
                    if slot == 0 { parent } else { Aabb::EMPTY.grow_point(inside()).grow_point(inside()) };
                node.set_child_box(slot, &child);
                assert!(node.child_aabb(slot).contains(&child), "{child:?} in {:?}", node.child_aabb(slot));
            }
        }
    }

    #[test]
    fn closest_and_any_hits_match_brute_force() {
        for (n, seed) in [(1, 11), (2, 12), (7, 13), (1000, 14), (20_000, 15)] {
            let tris = soup(n, seed);
            let (_, cw, permuted) = build(&tris);
            let hits = check_hits(&cw, &accel(&permuted), seed + 100);
            println!("{n} triangles: {hits} of 2000 rays hit");
            assert!(hits > 700, "{hits} hits of 2000 rays over {n} triangles");
        }
    }

    #[test]
    fn empty_and_single_triangle() {
        let (bvh, cw, permuted) = build(&[]);
        assert!(bvh.nodes.is_empty() && cw.nodes.is_empty() && cw.prim_order.is_empty());
        assert_eq!(cw.bounds, Aabb::EMPTY);
        assert!(!cw.intersect(Vec3A::ZERO, Vec3A::X, f32::INFINITY, |_, _, _| panic!("no leaves")));
        assert!(!cw.occluded(Vec3A::ZERO, Vec3A::X, f32::INFINITY, |_, _, _| panic!("no leaves")));
        assert_eq!(cw.stats(&BuildOptions::METRIC).nodes, 0);
        check(&cw, &permuted, 0);

        // One triangle, flat in z: a lone leaf root becomes a root node with one leaf slot.
        let tri = [Vec3::new(0.0, 0.0, 2.0), Vec3::new(4.0, 0.0, 2.0), Vec3::new(0.0, 4.0, 2.0)];
        let (bvh, cw, permuted) = build(&[tri]);
        let accel = accel(&permuted);
        assert_eq!(bvh.nodes.len(), 1);
        assert_eq!(cw.nodes.len(), 1);
        assert_eq!(cw.prim_order, vec![0]);
        assert_eq!(cw.nodes[0].imask, 0);
        assert_eq!(cw.nodes[0].meta, [0b001_00000, 0, 0, 0, 0, 0, 0, 0]);
        check(&cw, &permuted, 1);
        let (o, d) = (Vec3A::new(1.0, 1.0, 0.0), Vec3A::Z);
        assert_eq!(closest(&cw, &accel, o, d, f32::INFINITY), Some((2.0, 0)));
        assert_eq!(closest(&cw, &accel, o, d, 2.0), None);
        assert!(any(&cw, &accel, o, d, 3.0));
        assert!(!any(&cw, &accel, Vec3A::new(3.0, 3.0, 0.0), d, 3.0));
        let s = cw.stats(&BuildOptions::METRIC);
        assert_eq!((s.nodes, s.leaves, s.max_depth, s.bytes), (1, 1, 1, 80));
    }

    #[test]
    fn big_leaves_become_several_slots() {
        // 20 identical boxes: the builder cannot split them, leaves of up to 8.
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let tris = vec![tri; 20];
        let (bvh, cw, permuted) = build(&tris);
        assert!(bvh.nodes.iter().any(|n| n.count > 3));
        check(&cw, &permuted, 20);
        let accel = accel(&permuted);
        assert_eq!(closest(&cw, &accel, Vec3A::new(0.2, 0.2, -1.0), Vec3A::Z, 5.0).map(|h| h.0), Some(1.0));
    }

    #[test]
    fn report_20000_triangles() {
        let tris = soup(20_000, 6);
        let (bvh, cw, _) = build(&tris);
        let m = BuildOptions::METRIC;
        let b2 = bvh.stats(&m);
        let cs = cw.stats(&m);
        println!(
            "Bvh2:  {} nodes, {} leaves, depth {}, {} bytes, SAH {:.2}",
            b2.nodes, b2.leaves, b2.max_depth, b2.bytes, b2.sah_cost
        );
        println!(
            "Cwbvh: {} nodes, {} leaf slots, depth {}, {} bytes, SAH {:.2} (dequantized boxes)",
            cs.nodes, cs.leaves, cs.max_depth, cs.bytes, cs.sah_cost
        );
        assert_eq!(cs.bytes, cs.nodes * 80);
        assert!(cs.bytes < b2.bytes, "wide nodes take less memory");
        // Fewer, wider nodes: the per-node SAH with unit costs comes out lower.
        assert!(cs.sah_cost < b2.sah_cost, "{} vs {}", cs.sah_cost, b2.sah_cost);
    }
}
