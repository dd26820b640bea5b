//! Host reference of one treelet-restructuring round (`kernels/treelet.cu`,
//! Karras & Aila 2013), operation for operation, so GPU and host trees can
//! be compared bit for bit.
//!
//! The GPU processes treelet roots in parallel, bottom-up; a root's result
//! depends only on its subtree after all treelets below it are done. So do
//! the threads here: roots are taken by their height at the start of the
//! round, lowest first. Roots of one height have disjoint subtrees (none is
//! below another), and a restructuring only rearranges nodes within its
//! root's subtree, so each height's treelets are planned in parallel from
//! the tree as it is and then written; the tree is the sequential
//! post-order pass's, bit for bit.

use rayon::prelude::*;

use super::layout::{BUILD_COUNT_MASK, BUILD_LEAF_BIT};
use super::reference::{sah_node_cost, BuildTree};
use super::{box_area, Bounds};

/// Leaves of a treelet.
pub(crate) const TREELET_LEAVES: usize = 7;
const SUBSETS: usize = 1 << TREELET_LEAVES;

/// Restructures every node with at least `gamma` primitives, bottom-up.
pub(crate) fn round(tree: &mut BuildTree, gamma: u32, max_leaf: u32, ci: f32, ct: f32) {
    for roots in roots_by_height(tree, gamma) {
        let plans: Vec<Rewrite> = roots.par_iter().filter_map(|&n| plan(tree, n, max_leaf, ci, ct)).collect();
        for rewrite in &plans {
            rewrite.apply(tree);
        }
    }
}

/// The nodes with at least `gamma` primitives, grouped by their height in
/// the tree (leaves 0), lowest first.
fn roots_by_height(tree: &BuildTree, gamma: u32) -> Vec<Vec<u32>> {
    let p = tree.prims();
    let mut height = vec![0u32; p as usize];
    let mut levels: Vec<Vec<u32>> = Vec::new();
    for n in tree.post_order() {
        let h = 1 + tree.child[n as usize]
            .iter()
            .map(|&c| if c < p { height[c as usize] } else { 0 })
            .max()
            .unwrap_or(0);
        height[n as usize] = h;
        if tree.count(n) >= gamma {
            let level = h as usize - 1;
            if levels.len() <= level {
                levels.resize_with(level + 1, Vec::new);
            }
            levels[level].push(n);
        }
    }
    levels
}

/// One treelet's new shape: for each of its inner nodes (the root first),
/// its children, box, cost and packed count.
struct Rewrite {
    nodes: Vec<(u32, [u32; 2], Bounds, f32, u32)>,
}

impl Rewrite {
    fn apply(&self, tree: &mut BuildTree) {
        for &(n, ids, bounds, cost, packed) in &self.nodes {
            for id in ids {
                tree.parent[id as usize] = n;
            }
            tree.child[n as usize] = ids;
            tree.bounds[n as usize] = bounds;
            tree.cost[n as usize] = cost;
            tree.packed[n as usize] = packed;
        }
    }
}

/// The sequential pass the parallel one must equal (tests).
#[cfg(test)]
pub(crate) fn round_sequential(tree: &mut BuildTree, gamma: u32, max_leaf: u32, ci: f32, ct: f32) {
    for n in tree.post_order() {
        if tree.count(n) >= gamma {
            if let Some(rewrite) = plan(tree, n, max_leaf, ci, ct) {
                rewrite.apply(tree);
            }
        }
    }
}

/// The DP tables of one treelet (`TreeletScratch`).
struct Scratch {
    area: [f32; SUBSETS],
    cost: [f32; SUBSETS],
    count: [u32; SUBSETS],
    partition: [usize; SUBSETS],
    as_leaf: [bool; SUBSETS],
}

fn finish(sh: &mut Scratch, s: usize, children: f32, best_left: usize, max_leaf: u32, ci: f32, ct: f32) {
    let (cost, packed) = sah_node_cost(sh.area[s], sh.count[s], children, max_leaf, ci, ct);
    sh.cost[s] = cost;
    sh.partition[s] = best_left;
    sh.as_leaf[s] = packed & BUILD_LEAF_BIT != 0;
}

fn subset_bounds(boxes: &[Bounds], s: usize) -> Bounds {
    let mut b = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for (k, leaf) in boxes.iter().enumerate() {
        if s >> k & 1 != 0 {
            for a in 0..3 {
                b.0[a] = b.0[a].min(leaf.0[a]);
                b.1[a] = b.1[a].max(leaf.1[a]);
            }
        }
    }
    b
}

/// The restructuring of the treelet at `root`, from `tree` as it is; `None`
/// where the subtree has too few nodes for a treelet.
fn plan(tree: &BuildTree, root: u32, max_leaf: u32, ci: f32, ct: f32) -> Option<Rewrite> {
    let p = tree.prims();
    // Treelet formation: open the largest-area leaf (first on ties) until 7.
    let mut leaves: Vec<u32> = tree.child[root as usize].to_vec();
    let mut inner = vec![root];
    while leaves.len() < TREELET_LEAVES {
        let mut best = None;
        let mut best_area = -1.0f32;
        for (k, &n) in leaves.iter().enumerate() {
            if n >= p {
                continue;
            }
            let (lo, hi) = tree.bounds[n as usize];
            let a = box_area(lo, hi);
            if a > best_area {
                best_area = a;
                best = Some(k);
            }
        }
        let Some(best) = best else { break };
        let opened = leaves[best];
        let [a, b] = tree.child[opened as usize];
        inner.push(opened);
        leaves[best] = a;
        leaves.push(b);
    }
    if leaves.len() < TREELET_LEAVES {
        return None;
    }
    let boxes: Vec<Bounds> = leaves.iter().map(|&n| tree.bounds[n as usize]).collect();
    let mut sh = Scratch {
        area: [0.0; SUBSETS],
        cost: [0.0; SUBSETS],
        count: [0; SUBSETS],
        partition: [0; SUBSETS],
        as_leaf: [false; SUBSETS],
    };
    for s in 1..SUBSETS {
        let (lo, hi) = subset_bounds(&boxes, s);
        sh.area[s] = box_area(lo, hi);
        sh.count[s] = (0..TREELET_LEAVES).filter(|k| s >> k & 1 != 0).map(|k| tree.count(leaves[k])).sum();
        if s.count_ones() == 1 {
            sh.cost[s] = tree.cost[leaves[s.trailing_zeros() as usize] as usize];
        }
    }
    // Sizes 2..6: every partition once, highest leaf on the left, q downwards.
    for size in 2..TREELET_LEAVES as u32 {
        for s in (1..SUBSETS).filter(|s| s.count_ones() == size) {
            let high = 1usize << (usize::BITS - 1 - s.leading_zeros());
            let rest = s ^ high;
            let (mut best, mut best_left) = (f32::INFINITY, high);
            let mut q = rest.wrapping_sub(1) & rest;
            loop {
                let left = high | q;
                let c = sh.cost[left] + sh.cost[s ^ left];
                if c < best {
                    best = c;
                    best_left = left;
                }
                if q == 0 {
                    break;
                }
                q = (q - 1) & rest;
            }
            finish(&mut sh, s, best, best_left, max_leaf, ci, ct);
        }
    }
    // The whole treelet: the cheapest partition, the smallest left side on ties.
    let all = SUBSETS - 1;
    let high = 1 << (TREELET_LEAVES - 1);
    let (mut best, mut best_left) = (f32::INFINITY, high);
    for q in 0..high - 1 {
        let left = high | q;
        let c = sh.cost[left] + sh.cost[all ^ left];
        if c < best {
            best = c;
            best_left = left;
        }
    }
    finish(&mut sh, all, best, best_left, max_leaf, ci, ct);

    // Rebuild top-down with the treelet's own inner slots (a stack, as the kernel).
    let mut rewrite = Rewrite { nodes: Vec::with_capacity(TREELET_LEAVES - 1) };
    let mut stack = vec![(all, root)];
    let mut next_inner = 1;
    while let Some((s, n)) = stack.pop() {
        let sides = [sh.partition[s], s ^ sh.partition[s]];
        let mut ids = [0u32; 2];
        for k in 0..2 {
            ids[k] = if sides[k].count_ones() == 1 {
                leaves[sides[k].trailing_zeros() as usize]
            } else {
                let id = inner[next_inner];
                next_inner += 1;
                stack.push((sides[k], id));
                id
            };
        }
        let packed = (sh.count[s] & BUILD_COUNT_MASK) | if sh.as_leaf[s] { BUILD_LEAF_BIT } else { 0 };
        rewrite.nodes.push((n, ids, subset_bounds(&boxes, s), sh.cost[s], packed));
    }
    Some(rewrite)
}
