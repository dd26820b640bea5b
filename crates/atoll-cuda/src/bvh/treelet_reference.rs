//! Host reference of one treelet-restructuring round (`kernels/treelet.cu`,
//! Karras & Aila 2013), operation for operation, so GPU and host trees can
//! be compared bit for bit.
//!
//! The GPU processes treelet roots in parallel, bottom-up; a root's result
//! depends only on its subtree after all treelets below it are done, so a
//! sequential post-order pass over the same roots gives the same tree.

use super::layout::{BUILD_COUNT_MASK, BUILD_LEAF_BIT};
use super::reference::{sah_node_cost, BuildTree};
use super::{box_area, Bounds};

/// Leaves of a treelet.
pub(crate) const TREELET_LEAVES: usize = 7;
const SUBSETS: usize = 1 << TREELET_LEAVES;

/// Restructures every node with at least `gamma` primitives, bottom-up.
pub(crate) fn round(tree: &mut BuildTree, gamma: u32, max_leaf: u32, ci: f32, ct: f32) {
    for n in tree.post_order() {
        if tree.count(n) >= gamma {
            restructure(tree, n, max_leaf, ci, ct);
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

fn restructure(tree: &mut BuildTree, root: u32, max_leaf: u32, ci: f32, ct: f32) {
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
        return;
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
            tree.parent[ids[k] as usize] = n;
        }
        tree.child[n as usize] = ids;
        tree.bounds[n as usize] = subset_bounds(&boxes, s);
        tree.cost[n as usize] = sh.cost[s];
        tree.packed[n as usize] =
            (sh.count[s] & BUILD_COUNT_MASK) | if sh.as_leaf[s] { BUILD_LEAF_BIT } else { 0 };
    }
}
