//! What every BVH layout shares: the traversal contract, the prepared ray,
//! the fixed-size traversal stack and the statistics.

use std::mem::MaybeUninit;

use glam::Vec3A;

use crate::{Aabb, BuildOptions, Bvh2};

/// Deepest tree the builders make (they switch to median splits below
/// [`crate::build::SAH_DEPTH_LIMIT`], which bounds the depth by 32 + log2(n)).
/// It sizes the fixed traversal stacks.
pub const MAX_DEPTH: usize = 64;

/// A BVH layout: a tree over primitives kept in the order of the [`Bvh2`] it
/// was converted from, so every layout shares that layout's leaf ranges and
/// per-primitive arrays.
pub trait BvhLayout: Send + Sync + Sized + 'static {
    /// The layout's name as reports print it (`Bvh2`, `Bvh4Cpu`).
    const NAME: &'static str;

    /// Converts from the canonical layout.
    fn from_bvh2(bvh: Bvh2) -> Self;

    /// Visits the leaves whose boxes `ray` enters before `*t_max`, nearer
    /// boxes first. `leaf(first, count, t_max)` tests primitives
    /// `first..first + count`, lowers `*t_max` on a closer hit and returns
    /// whether it hit. With `ANY` traversal ends at the first leaf that hits.
    /// Returns whether any leaf hit.
    fn traverse<const ANY: bool>(
        &self,
        ray: &TraversalRay,
        t_max: &mut f32,
        leaf: impl FnMut(u32, u32, &mut f32) -> bool,
    ) -> bool {
        self.traverse_visiting::<ANY>(ray, t_max, |_| {}, leaf)
    }

    /// [`BvhLayout::traverse`], telling `node` the index of every node it
    /// reads (a shared scene's access counters; a no-op closure costs nothing).
    fn traverse_visiting<const ANY: bool>(
        &self,
        ray: &TraversalRay,
        t_max: &mut f32,
        node: impl FnMut(u32),
        leaf: impl FnMut(u32, u32, &mut f32) -> bool,
    ) -> bool;

    /// Bytes of one node as the layout stores them (node `i` starts at
    /// `i * NODE_BYTES` of its node array).
    const NODE_BYTES: usize;

    /// The box of everything in the tree (`Aabb::EMPTY` when empty).
    fn bounds(&self) -> Aabb;

    /// Node counts, depth, SAH cost (with the constants of `options`) and
    /// node bytes (`build_ms` left 0).
    fn stats(&self, options: &BuildOptions) -> BvhStats;
}

/// Size and quality of one BVH.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhStats {
    /// Nodes as the layout stores them (a `Bvh4Cpu` node holds up to 4 boxes).
    pub nodes: usize,
    /// Leaves (primitive ranges).
    pub leaves: usize,
    /// Longest root-to-leaf path in nodes (a lone leaf root has depth 1).
    pub max_depth: u32,
    /// SAH cost, relative to the root's area ([`BuildOptions::METRIC`] in
    /// [`crate::SceneBvhStats`]).
    pub sah_cost: f32,
    /// Build time including conversion to this layout.
    pub build_ms: f64,
    /// Bytes of nodes plus the primitive data traversal reads.
    pub bytes: usize,
}

/// A ray prepared for box tests: origin, direction, the inverse direction
/// with zero components replaced by a tiny value (so that `0 * inf` never
/// makes a NaN), and per axis whether the ray goes towards negative values.
#[derive(Clone, Copy, Debug)]
pub struct TraversalRay {
    /// Where the ray starts.
    pub origin: Vec3A,
    /// Its direction (not normalised).
    pub dir: Vec3A,
    /// `1 / dir` per component, with tiny components replaced (see [`TraversalRay::new`]).
    pub inv_dir: Vec3A,
    /// `origin * inv_dir`, so a slab distance is one multiply and one subtract.
    pub origin_inv: Vec3A,
    /// Per axis, 1 when the direction's sign bit is set (the near plane is then the box's max).
    pub negative: [usize; 3],
}

impl TraversalRay {
    /// Prepares a ray for box tests.
    #[inline]
    pub fn new(origin: Vec3A, dir: Vec3A) -> Self {
        // Components below 1e-20 become +-1e-20: inv_dir stays finite (so no
        // `0 * inf` NaNs when the origin lies on a slab plane), and slab
        // distances `box * inv_dir` stay finite for coordinates up to 1e18.
        // The sign is kept (also of -0.0) so near and far planes stay right.
        let tiny = Vec3A::splat(1e-20);
        let safe = Vec3A::select(dir.abs().cmplt(tiny), tiny.copysign(dir), dir);
        let inv_dir = safe.recip();
        let neg = |x: f32| x.is_sign_negative() as usize;
        let negative = [neg(dir.x), neg(dir.y), neg(dir.z)];
        TraversalRay { origin, dir, inv_dir, origin_inv: origin * inv_dir, negative }
    }

    /// Entry distance of the ray into the box if it enters before `t_max`
    /// (and leaves after 0), else `f32::INFINITY`. Branch-free slab test; the
    /// box must not be empty (min/max per axis make it sign-agnostic, so an
    /// inverted box would look infinite).
    #[inline(always)]
    pub fn box_entry(&self, min: Vec3A, max: Vec3A, t_max: f32) -> f32 {
        let t0 = min * self.inv_dir - self.origin_inv;
        let t1 = max * self.inv_dir - self.origin_inv;
        // Plain comparisons rather than f32::max/min, whose NaN rules cost instructions.
        let near = t0.min(t1).max_element();
        let near = if near > 0.0 { near } else { 0.0 };
        let far = t0.max(t1).min_element();
        let far = if far < t_max { far } else { t_max };
        if near <= far {
            near
        } else {
            f32::INFINITY
        }
    }
}

/// A traversal stack of fixed capacity that costs nothing to create (no
/// zeroing: traversal starts once per ray and per instance, and zeroing a
/// few hundred bytes each time would show in the Mrays/s).
pub(crate) struct Stack<T: Copy, const N: usize> {
    items: [MaybeUninit<T>; N],
    len: usize,
}

impl<T: Copy, const N: usize> Stack<T, N> {
    #[inline(always)]
    pub fn new() -> Self {
        Stack { items: [const { MaybeUninit::uninit() }; N], len: 0 }
    }

    /// Panics (index out of bounds) past `N`; the depth limit of the builders
    /// makes that unreachable.
    #[inline(always)]
    pub fn push(&mut self, item: T) {
        self.items[self.len] = MaybeUninit::new(item);
        self.len += 1;
    }

    #[inline(always)]
    pub fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: `push` wrote every slot below the length before raising it,
        // and `pop` lowers it before reading, so this slot is initialised.
        Some(unsafe { self.items[self.len].assume_init() })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slab_test_handles_axis_parallel_rays() {
        let (min, max) = (Vec3A::ZERO, Vec3A::ONE);
        // Along +x from inside the slab of y and z, and exactly on its boundary plane.
        let r = TraversalRay::new(Vec3A::new(-1.0, 0.5, 0.5), Vec3A::X);
        assert_eq!(r.box_entry(min, max, 10.0), 1.0);
        let r = TraversalRay::new(Vec3A::new(-1.0, 0.0, 0.5), Vec3A::X);
        assert_eq!(r.box_entry(min, max, 10.0), 1.0);
        // On the max plane a +0 component counts as leaving the slab at t = 0:
        // such a ray could only have hit triangle edges lying in that plane.
        let r = TraversalRay::new(Vec3A::new(-1.0, 0.5, 1.0), Vec3A::X);
        assert_eq!(r.box_entry(min, max, 10.0), f32::INFINITY);
        // Parallel but outside, behind, and beyond t_max.
        let r = TraversalRay::new(Vec3A::new(-1.0, 1.5, 0.5), Vec3A::X);
        assert_eq!(r.box_entry(min, max, 10.0), f32::INFINITY);
        let r = TraversalRay::new(Vec3A::new(2.0, 0.5, 0.5), Vec3A::X);
        assert_eq!(r.box_entry(min, max, 10.0), f32::INFINITY);
        let r = TraversalRay::new(Vec3A::new(-1.0, 0.5, 0.5), -Vec3A::X);
        assert_eq!(r.box_entry(min, max, 10.0), f32::INFINITY);
        let r = TraversalRay::new(Vec3A::new(-1.0, 0.5, 0.5), Vec3A::X);
        assert_eq!(r.box_entry(min, max, 0.5), f32::INFINITY);
        // From inside: entry clamps to 0.
        let r = TraversalRay::new(Vec3A::splat(0.5), Vec3A::new(-0.0, 1.0, 0.0));
        assert_eq!(r.box_entry(min, max, 10.0), 0.0);
    }

    #[test]
    fn stack_is_lifo() {
        let mut s = Stack::<u32, 4>::new();
        s.push(1);
        s.push(2);
        assert_eq!(s.pop(), Some(2));
        s.push(3);
        assert_eq!((s.pop(), s.pop(), s.pop()), (Some(3), Some(1), None));
    }
}
