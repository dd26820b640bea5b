//! `Bvh2`: the canonical binary layout every builder produces and every
//! other layout is converted from.

use glam::Vec3A;

use crate::layout::{BvhLayout, BvhStats, Stack, TraversalRay, MAX_DEPTH};
use crate::{Aabb, BuildOptions};

/// A node of [`Bvh2`] (32 bytes, two to a 64-byte cache line).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Bvh2Node {
    /// Box minimum (12 bytes).
    pub min: [f32; 3],
    /// Interior node: index of the left child; the right child follows it.
    /// Leaf: first primitive in [`Bvh2::prim_order`] order (4 bytes).
    pub left_or_first: u32,
    /// Box maximum (12 bytes).
    pub max: [f32; 3],
    /// 0 for an interior node, else the leaf's primitive count (4 bytes).
    pub count: u32,
}

const _: () = assert!(std::mem::size_of::<Bvh2Node>() == 32);

impl Bvh2Node {
    pub(crate) fn new(b: &Aabb, left_or_first: u32, count: u32) -> Self {
        Bvh2Node { min: b.min.into(), left_or_first, max: b.max.into(), count }
    }

    /// The node's box.
    #[inline(always)]
    pub fn aabb(&self) -> Aabb {
        Aabb { min: Vec3A::from_array(self.min), max: Vec3A::from_array(self.max) }
    }

    /// Whether the node holds primitives rather than children.
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }
}

/// Binary BVH, nodes in depth-first order with sibling pairs adjacent; the
/// root is node 0. Empty when built over no primitives.
#[derive(Clone, Debug, Default)]
pub struct Bvh2 {
    /// The nodes; the root is node 0.
    pub nodes: Vec<Bvh2Node>,
    /// For each position in leaf order, the index of the builder's input
    /// primitive stored there: callers permute their primitive data by it.
    pub prim_order: Vec<u32>,
    /// Build time in milliseconds.
    pub build_ms: f64,
}

impl Bvh2 {
    /// SAH cost with the builder's constants (see [`BuildOptions`]); 0 when empty.
    pub fn sah_cost(&self, options: &BuildOptions) -> f32 {
        let Some(root) = self.nodes.first() else { return 0.0 };
        let root_area = root.aabb().area().max(f32::MIN_POSITIVE);
        let cost: f64 = self
            .nodes
            .iter()
            .map(|n| {
                let per_area = match n.count {
                    0 => options.traversal_cost,
                    c => options.intersection_cost * options.blocks(c),
                };
                (per_area * n.aabb().area()) as f64
            })
            .sum();
        (cost / root_area as f64) as f32
    }

    /// Depth of the deepest leaf (0 when empty).
    fn max_depth(&self) -> u32 {
        let mut deepest = 0;
        let mut todo = if self.nodes.is_empty() { vec![] } else { vec![(0usize, 1u32)] };
        while let Some((i, depth)) = todo.pop() {
            deepest = deepest.max(depth);
            let n = &self.nodes[i];
            if !n.is_leaf() {
                let l = n.left_or_first as usize;
                todo.extend([(l, depth + 1), (l + 1, depth + 1)]);
            }
        }
        deepest
    }
}

impl BvhLayout for Bvh2 {
    const NAME: &'static str = "Bvh2";

    fn from_bvh2(bvh: Bvh2) -> Self {
        bvh
    }

    fn bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::EMPTY, Bvh2Node::aabb)
    }

    fn stats(&self, options: &BuildOptions) -> BvhStats {
        BvhStats {
            nodes: self.nodes.len(),
            leaves: self.nodes.iter().filter(|n| n.is_leaf()).count(),
            max_depth: self.max_depth(),
            sah_cost: self.sah_cost(options),
            build_ms: 0.0,
            bytes: std::mem::size_of_val(&self.nodes[..]),
        }
    }

    const NODE_BYTES: usize = std::mem::size_of::<Bvh2Node>();

    #[inline]
    fn traverse_visiting<const ANY: bool>(
        &self,
        ray: &TraversalRay,
        t_max: &mut f32,
        mut visit: impl FnMut(u32),
        mut leaf: impl FnMut(u32, u32, &mut f32) -> bool,
    ) -> bool {
        let Some(root) = self.nodes.first() else { return false };
        visit(0);
        if ray.box_entry(root.aabb().min, root.aabb().max, *t_max) == f32::INFINITY {
            return false;
        }
        let mut stack = Stack::<(u32, f32), MAX_DEPTH>::new();
        let mut hit = false;
        let mut node = root;
        loop {
            if node.is_leaf() {
                if leaf(node.left_or_first, node.count, t_max) {
                    hit = true;
                    if ANY {
                        return true;
                    }
                }
            } else {
                // Ordered: continue with the nearer child, push the farther.
                let left = node.left_or_first as usize;
                let (a, b) = (&self.nodes[left], &self.nodes[left + 1]);
                visit(left as u32);
                visit(left as u32 + 1);
                let mut near = (left as u32, ray.box_entry(a.aabb().min, a.aabb().max, *t_max));
                let mut far = (left as u32 + 1, ray.box_entry(b.aabb().min, b.aabb().max, *t_max));
                if far.1 < near.1 {
                    std::mem::swap(&mut near, &mut far);
                }
                if near.1 != f32::INFINITY {
                    if far.1 != f32::INFINITY {
                        stack.push(far);
                    }
                    node = &self.nodes[near.0 as usize];
                    continue;
                }
            }
            // Pop, skipping nodes entered beyond the closest hit found since the push.
            loop {
                let Some((next, entry)) = stack.pop() else { return hit };
                if entry < *t_max {
                    node = &self.nodes[next as usize];
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use glam::Vec3;

    /// Checks that every primitive is in exactly one leaf, that every node's
    /// box contains its children's and its primitives', and leaf sizes.
    pub(crate) fn validate(bvh: &Bvh2, prims: &[Aabb], max_leaf: u32) {
        let mut seen = vec![false; prims.len()];
        let mut sorted = bvh.prim_order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..prims.len() as u32).collect::<Vec<_>>());
        for n in &bvh.nodes {
            let b = n.aabb();
            if n.is_leaf() {
                assert!(n.count <= max_leaf);
                for i in n.left_or_first..n.left_or_first + n.count {
                    let p = bvh.prim_order[i as usize] as usize;
                    assert!(!seen[p]);
                    seen[p] = true;
                    assert!(b.contains(&prims[p]));
                }
            } else {
                let l = n.left_or_first as usize;
                assert!(b.contains(&bvh.nodes[l].aabb()) && b.contains(&bvh.nodes[l + 1].aabb()));
            }
        }
        assert!(seen.iter().all(|&s| s));
        assert!(bvh.max_depth() as usize <= MAX_DEPTH);
    }

    /// Boxes of random little triangles plus clusters of identical boxes.
    pub(crate) fn random_boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut s = seed;
        let mut next = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32) / (1u64 << 24) as f32
        };
        (0..n)
            .map(|i| {
                if i % 7 == 0 {
                    return Aabb::from_points([Vec3::splat(3.0), Vec3::splat(3.5)]);
                }
                let c = Vec3::new(next(), next(), next()) * 100.0;
                Aabb::from_points([c, c + Vec3::new(next(), next(), next())])
            })
            .collect()
    }

    #[test]
    fn builds_valid_trees() {
        for (n, seed) in [(1, 1), (2, 2), (9, 3), (1000, 4), (100_000, 5)] {
            let prims = random_boxes(n, seed);
            for o in [BuildOptions::TRIANGLES, BuildOptions::INSTANCES, BuildOptions::QUICK] {
                let bvh = Bvh2::build(&prims, &o);
                validate(&bvh, &prims, o.max_leaf);
            }
        }
        assert!(Bvh2::build(&[], &BuildOptions::TRIANGLES).nodes.is_empty());
    }

    #[test]
    fn identical_boxes_split_to_leaf_size() {
        let prims = vec![Aabb::from_points([Vec3::ZERO, Vec3::ONE]); 100];
        let bvh = Bvh2::build(&prims, &BuildOptions::TRIANGLES);
        validate(&bvh, &prims, 8);
        assert!(bvh.max_depth() <= 6);
    }
}
