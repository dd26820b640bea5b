//! The BVH light sampler of pbrt-v4 (Conty Estevez and Kulla's "many
//! lights" sampling as pbrt-v4 §12.6.3 builds it): a binary tree over the
//! bounds of every light at a finite distance, each node summarising its
//! lights by a box, a direction cone, and their power. Sampling walks from
//! the root, choosing each child in proportion to an estimate of how much
//! its lights can contribute at the shading point, so a small light near
//! the point is found however much power the rest of the scene has.
//!
//! The nodes are stored as the GPU reads them ([`LightNode`], mirrored in
//! `kernels/light_bvh.cuh`); sampling and [`LightBvh::pmf`] use one
//! importance function on both.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

/// The largest float below 1: where a remapped random number is clamped.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// [`LightNode::parent`] of the root, and [`LightBvh::leaf_of`] of a light
/// outside the tree.
pub const NO_NODE: u32 = u32::MAX;

/// [`LightNode::flags`] bits.
pub mod node_flags {
    /// The node is one light (`child_or_light` is its emitter index).
    pub const LEAF: u32 = 1;
    /// Some light below emits on both sides (the cone is used both ways).
    pub const TWO_SIDED: u32 = 2;
}

/// What a light or a group of lights can emit and where (pbrt-v4's
/// `LightBounds`): a box holding the emitters, a cone of emission normals
/// (axis `w`, half-angle θo, as its cosine) and how far beyond a normal
/// light still leaves (θe, as its cosine), and the total power `phi`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightBounds {
    pub min: Vec3,
    pub max: Vec3,
    pub w: Vec3,
    pub phi: f32,
    pub cos_theta_o: f32,
    pub cos_theta_e: f32,
    pub two_sided: bool,
}

/// One node of the tree (80 bytes): the bounds of the lights below it,
/// and either its first child (the second follows it) or its light.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct LightNode {
    pub min: [f32; 3],
    pub phi: f32,
    pub max: [f32; 3],
    pub cos_theta_o: f32,
    pub w: [f32; 3],
    pub cos_theta_e: f32,
    /// sin θo and the radius of the box's bounding sphere, kept so that
    /// [`LightNode::importance`] needs two fewer square roots.
    pub sin_theta_o: f32,
    pub radius: f32,
    /// First child of an inner node; emitter index of a leaf.
    pub child_or_light: u32,
    pub parent: u32,
    /// [`node_flags`].
    pub flags: u32,
    pub pad: [u32; 3],
}

fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

/// cos(max(θa − θb, 0)) from the sines and cosines of θa and θb.
fn cos_sub_clamped(sin_a: f32, cos_a: f32, sin_b: f32, cos_b: f32) -> f32 {
    if cos_a > cos_b {
        1.0
    } else {
        cos_a * cos_b + sin_a * sin_b
    }
}

/// sin(max(θa − θb, 0)) from the sines and cosines of θa and θb.
fn sin_sub_clamped(sin_a: f32, cos_a: f32, sin_b: f32, cos_b: f32) -> f32 {
    if cos_a > cos_b {
        0.0
    } else {
        sin_a * cos_b - cos_a * sin_b
    }
}

impl LightNode {
    fn from_bounds(b: &LightBounds) -> Self {
        LightNode {
            min: b.min.to_array(),
            phi: b.phi,
            max: b.max.to_array(),
            cos_theta_o: b.cos_theta_o,
            w: b.w.to_array(),
            cos_theta_e: b.cos_theta_e,
            sin_theta_o: safe_sqrt(1.0 - b.cos_theta_o * b.cos_theta_o),
            radius: (b.max - 0.5 * (b.min + b.max)).length(),
            flags: if b.two_sided { node_flags::TWO_SIDED } else { 0 },
            parent: NO_NODE,
            ..Zeroable::zeroed()
        }
    }

    pub fn is_leaf(&self) -> bool {
        self.flags & node_flags::LEAF != 0
    }

    /// An upper estimate of what the node's lights contribute at `p`
    /// (pbrt-v4's `LightBounds::Importance` without the receiver's normal:
    /// a BSDF-sampled hit on an emitter must recompute the same value, and
    /// the ray record does not keep the previous vertex's normal). Power
    /// over squared distance, times the cosine of the smallest angle
    /// between the emission cone and the direction to `p` that the box
    /// allows (θb, the half-angle the box's bounding sphere subtends, is
    /// taken off); 0 when even that is beyond the cone's reach. From inside
    /// the sphere every direction is possible, and the squared distance is
    /// clamped to the radius squared, so points inside a node do not make
    /// it infinitely important. Three square roots and two divisions: this
    /// runs twice per tree level for every light sample.
    /// `kernels/light_bvh.cuh` mirrors it.
    pub fn importance(&self, p: Vec3) -> f32 {
        let center = 0.5 * (Vec3::from(self.min) + Vec3::from(self.max));
        let to_p = p - center;
        let distance2 = to_p.length_squared();
        let radius2 = self.radius * self.radius;
        let inv_distance = 1.0 / distance2.sqrt();
        let inv_distance = if inv_distance.is_finite() { inv_distance } else { 0.0 };
        let mut cos_w = Vec3::from(self.w).dot(to_p) * inv_distance;
        if self.flags & node_flags::TWO_SIDED != 0 {
            cos_w = cos_w.abs();
        }
        let sin_w = safe_sqrt(1.0 - cos_w * cos_w);
        let (cos_b, sin_b) = if distance2 <= radius2 {
            (-1.0, 0.0)
        } else {
            ((distance2 - radius2).sqrt() * inv_distance, self.radius * inv_distance)
        };
        // θx: the angle from the cone's edge to p; θ': less what the box spans.
        let cos_x = cos_sub_clamped(sin_w, cos_w, self.sin_theta_o, self.cos_theta_o);
        let sin_x = sin_sub_clamped(sin_w, cos_w, self.sin_theta_o, self.cos_theta_o);
        let cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
        if cos_p <= self.cos_theta_e {
            return 0.0;
        }
        (self.phi * cos_p / distance2.max(radius2).max(f32::MIN_POSITIVE)).max(0.0)
    }
}

impl LightBounds {
    /// The bounds of both.
    pub fn union(&self, o: &LightBounds) -> LightBounds {
        if self.phi == 0.0 {
            return *o;
        }
        if o.phi == 0.0 {
            return *self;
        }
        let (w, cos_theta_o) = cone_union(self.w, self.cos_theta_o, o.w, o.cos_theta_o);
        LightBounds {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
            w,
            phi: self.phi + o.phi,
            cos_theta_o,
            cos_theta_e: self.cos_theta_e.min(o.cos_theta_e),
            two_sided: self.two_sided || o.two_sided,
        }
    }

    fn centroid(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// The split cost of these bounds in a node whose box is `node_min` to
    /// `node_max`, split along `axis` (pbrt-v4's `EvaluateCost`): power times
    /// the solid angle the cone can light times the box's surface area,
    /// scaled up for thin boxes split along their short side.
    fn cost(&self, node_min: Vec3, node_max: Vec3, axis: usize) -> f32 {
        use std::f32::consts::PI;
        let theta_o = self.cos_theta_o.clamp(-1.0, 1.0).acos();
        let theta_e = self.cos_theta_e.clamp(-1.0, 1.0).acos();
        let theta_w = (theta_o + theta_e).min(PI);
        let sin_o = theta_o.sin();
        let m_omega = 2.0 * PI * (1.0 - self.cos_theta_o)
            + PI / 2.0
                * (2.0 * theta_w * sin_o - (theta_o - 2.0 * theta_w).cos() - 2.0 * theta_o * sin_o
                    + self.cos_theta_o);
        let diagonal = node_max - node_min;
        let k_r = if diagonal[axis] > 0.0 { diagonal.max_element() / diagonal[axis] } else { 1.0 };
        let d = self.max - self.min;
        let area = 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
        self.phi * m_omega * k_r * area
    }
}

/// The smallest cone (axis, cosine of half-angle) holding two cones
/// (pbrt-v4's `DirectionCone::Union`).
fn cone_union(wa: Vec3, cos_a: f32, wb: Vec3, cos_b: f32) -> (Vec3, f32) {
    use std::f32::consts::PI;
    let theta_a = cos_a.clamp(-1.0, 1.0).acos();
    let theta_b = cos_b.clamp(-1.0, 1.0).acos();
    let theta_d = wa.dot(wb).clamp(-1.0, 1.0).acos();
    if (theta_d + theta_b).min(PI) <= theta_a {
        return (wa, cos_a);
    }
    if (theta_d + theta_a).min(PI) <= theta_b {
        return (wb, cos_b);
    }
    let theta_o = 0.5 * (theta_a + theta_d + theta_b);
    let axis = wa.cross(wb);
    if theta_o >= PI || axis.length_squared() == 0.0 {
        return (wa, -1.0);
    }
    // Rotate wa towards wb so the new cone's edge touches a's far edge.
    let rotation = glam::Quat::from_axis_angle(axis.normalize(), theta_o - theta_a);
    ((rotation * wa).normalize(), theta_o.cos())
}

/// The tree: nodes (root first) and, per emitter, the leaf holding it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LightBvh {
    pub nodes: Vec<LightNode>,
    /// Leaf node of each emitter; [`NO_NODE`] for those outside the tree
    /// (lights at infinity and lights without power).
    pub leaf_of: Vec<u32>,
}

/// Buckets per axis when choosing a split (pbrt-v4's count).
const SPLIT_BUCKETS: usize = 12;

impl LightBvh {
    /// Builds the tree over `lights` (emitter index and bounds; those of
    /// zero power are left out) for a light table of `emitter_count`
    /// entries. Iterative, so any number of lights builds without deep
    /// recursion.
    pub fn build(lights: &[(u32, LightBounds)], emitter_count: usize) -> Self {
        let mut items: Vec<(u32, LightBounds)> =
            lights.iter().copied().filter(|(_, b)| b.phi > 0.0 && b.phi.is_finite()).collect();
        let mut bvh = LightBvh { nodes: Vec::new(), leaf_of: vec![NO_NODE; emitter_count] };
        if items.is_empty() {
            return bvh;
        }
        bvh.nodes.push(LightNode::default());
        // (node index, range of items, parent)
        let mut stack = vec![(0usize, 0..items.len(), NO_NODE)];
        while let Some((node, range, parent)) = stack.pop() {
            let slice = &mut items[range.clone()];
            let bounds = slice.iter().skip(1).fold(slice[0].1, |acc, (_, b)| acc.union(b));
            let mut n = LightNode::from_bounds(&bounds);
            n.parent = parent;
            if slice.len() == 1 {
                n.flags |= node_flags::LEAF;
                n.child_or_light = slice[0].0;
                bvh.leaf_of[slice[0].0 as usize] = node as u32;
                bvh.nodes[node] = n;
                continue;
            }
            let mid = range.start + split(slice, &bounds);
            let first_child = bvh.nodes.len();
            bvh.nodes.push(LightNode::default());
            bvh.nodes.push(LightNode::default());
            n.child_or_light = first_child as u32;
            bvh.nodes[node] = n;
            stack.push((first_child + 1, mid..range.end, node as u32));
            stack.push((first_child, range.start..mid, node as u32));
        }
        bvh
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Chooses a light for shading point `p` with `u` in [0, 1): (emitter,
    /// probability). `None` when no light in the tree can reach `p`.
    pub fn sample(&self, p: Vec3, mut u: f32) -> Option<(u32, f32)> {
        let root = self.nodes.first()?;
        if root.is_leaf() {
            return (root.importance(p) > 0.0).then_some((root.child_or_light, 1.0));
        }
        let mut node = root;
        let mut pmf = 1.0f32;
        while !node.is_leaf() {
            let first = node.child_or_light as usize;
            let importance = [self.nodes[first].importance(p), self.nodes[first + 1].importance(p)];
            let total = importance[0] + importance[1];
            if total.is_nan() || total <= 0.0 {
                return None;
            }
            let p0 = importance[0] / total;
            let chosen = if u < p0 {
                u = (u / p0).min(ONE_MINUS_EPSILON);
                0
            } else {
                u = ((u - p0) / (1.0 - p0)).min(ONE_MINUS_EPSILON);
                1
            };
            pmf *= importance[chosen] / total;
            node = &self.nodes[first + chosen];
        }
        Some((node.child_or_light, pmf))
    }

    /// The probability that [`Self::sample`] at `p` chooses `emitter`,
    /// walking from its leaf up to the root.
    pub fn pmf(&self, p: Vec3, emitter: u32) -> f32 {
        let Some(&leaf) = self.leaf_of.get(emitter as usize) else { return 0.0 };
        if leaf == NO_NODE {
            return 0.0;
        }
        let mut node = leaf as usize;
        if self.nodes[node].parent == NO_NODE {
            return if self.nodes[node].importance(p) > 0.0 { 1.0 } else { 0.0 };
        }
        let mut pmf = 1.0f32;
        while self.nodes[node].parent != NO_NODE {
            let parent = self.nodes[node].parent as usize;
            let first = self.nodes[parent].child_or_light as usize;
            let sibling = if node == first { first + 1 } else { first };
            let own = self.nodes[node].importance(p);
            if own == 0.0 {
                return 0.0;
            }
            pmf *= own / (own + self.nodes[sibling].importance(p));
            node = parent;
        }
        pmf
    }
}

/// Reorders `items` (at least two) into two non-empty groups and returns
/// the size of the first: the bucketed split of least [`LightBounds::cost`]
/// over the three axes, or halves when every centroid coincides.
fn split(items: &mut [(u32, LightBounds)], bounds: &LightBounds) -> usize {
    let (cmin, cmax) = items.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), (_, b)| {
        (lo.min(b.centroid()), hi.max(b.centroid()))
    });
    let extent = cmax - cmin;
    let bucket_of = |b: &LightBounds, axis: usize| {
        let t = (b.centroid()[axis] - cmin[axis]) / extent[axis];
        ((t * SPLIT_BUCKETS as f32) as usize).min(SPLIT_BUCKETS - 1)
    };
    let mut best: Option<(f32, usize, usize)> = None; // (cost, axis, last bucket of the first group)
    for axis in 0..3 {
        if extent[axis].is_nan() || extent[axis] <= 0.0 {
            continue;
        }
        let mut buckets: [Option<LightBounds>; SPLIT_BUCKETS] = [None; SPLIT_BUCKETS];
        for (_, b) in items.iter() {
            let slot = &mut buckets[bucket_of(b, axis)];
            *slot = Some(slot.map_or(*b, |s| s.union(b)));
        }
        for last in 0..SPLIT_BUCKETS - 1 {
            let group = |range: std::ops::Range<usize>| {
                buckets[range].iter().flatten().copied().reduce(|a, b| a.union(&b))
            };
            let (Some(below), Some(above)) = (group(0..last + 1), group(last + 1..SPLIT_BUCKETS)) else {
                continue;
            };
            let cost = below.cost(bounds.min, bounds.max, axis) + above.cost(bounds.min, bounds.max, axis);
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, last));
            }
        }
    }
    let first_len = match best {
        Some((_, axis, last)) => partition(items, |b| bucket_of(b, axis) <= last),
        None => 0,
    };
    if first_len == 0 || first_len == items.len() {
        return items.len() / 2;
    }
    first_len
}

/// Moves the items `first` holds for to the front; returns how many.
fn partition(items: &mut [(u32, LightBounds)], first: impl Fn(&LightBounds) -> bool) -> usize {
    let mut front = 0;
    for i in 0..items.len() {
        if first(&items[i].1) {
            items.swap(i, front);
            front += 1;
        }
    }
    front
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(center: Vec3, phi: f32) -> LightBounds {
        LightBounds {
            min: center - Vec3::new(0.5, 0.0, 0.5),
            max: center + Vec3::new(0.5, 0.0, 0.5),
            w: -Vec3::Y,
            phi,
            cos_theta_o: 1.0,
            cos_theta_e: 0.0,
            two_sided: false,
        }
    }

    #[test]
    fn pmf_matches_sampling_and_sums_to_one() {
        let lights: Vec<(u32, LightBounds)> = (0..37)
            .map(|i| {
                let x = (i % 7) as f32 * 3.0 - 9.0;
                let z = (i / 7) as f32 * 2.5 - 6.0;
                (i as u32 * 2, quad(Vec3::new(x, 4.0 + (i % 3) as f32, z), 1.0 + (i % 5) as f32))
            })
            .collect();
        let bvh = LightBvh::build(&lights, 80);
        assert_eq!(bvh.nodes.len(), 2 * lights.len() - 1);
        for p in [Vec3::ZERO, Vec3::new(5.0, 1.0, -3.0), Vec3::new(-20.0, 2.0, 7.0)] {
            let total: f32 = lights.iter().map(|(e, _)| bvh.pmf(p, *e)).sum();
            assert!((total - 1.0).abs() < 1e-5, "{p}: {total}");
            let n = 20_000;
            let mut counts = vec![0u32; 80];
            for i in 0..n {
                let u = (i as f32 + 0.5) / n as f32;
                let (e, pmf) = bvh.sample(p, u).unwrap();
                assert!((pmf - bvh.pmf(p, e)).abs() <= 1e-6 * pmf.max(1e-3), "{pmf} vs {}", bvh.pmf(p, e));
                counts[e as usize] += 1;
            }
            for (e, _) in &lights {
                let expected = bvh.pmf(p, *e) * n as f32;
                assert!((counts[*e as usize] as f32 - expected).abs() <= 2.0 + 0.02 * expected);
            }
        }
        assert_eq!(bvh.pmf(Vec3::ZERO, 1), 0.0, "not in the tree");
    }

    /// The point of the sampler: near a dim light far from a bright one,
    /// the dim one is chosen most of the time.
    #[test]
    fn nearby_light_dominates_far_brighter_one() {
        let near = (0, quad(Vec3::new(0.0, 1.5, 0.0), 1.0));
        let far = (1, quad(Vec3::new(200.0, 1.5, 0.0), 1000.0));
        let bvh = LightBvh::build(&[near, far], 2);
        assert!(bvh.pmf(Vec3::ZERO, 0) > 0.9);
        assert!(bvh.pmf(Vec3::new(200.0, 0.0, 0.0), 1) > 0.99);
        // Above a one-sided downward light nothing is chosen.
        let single = LightBvh::build(&[near], 1);
        assert_eq!(single.sample(Vec3::new(0.0, 3.0, 0.0), 0.5), None);
        assert_eq!(single.sample(Vec3::ZERO, 0.5), Some((0, 1.0)));
    }

    #[test]
    fn cone_union_holds_both_cones() {
        let (w, cos) = cone_union(Vec3::Y, 1.0, Vec3::X, 1.0);
        assert!((w.dot(Vec3::Y) - w.dot(Vec3::X)).abs() < 1e-5);
        assert!((cos - std::f32::consts::FRAC_PI_4.cos()).abs() < 1e-5);
        assert_eq!(cone_union(Vec3::Y, 1.0, -Vec3::Y, 1.0).1, -1.0);
        assert_eq!(cone_union(Vec3::Y, 0.5, Vec3::Y, 1.0), (Vec3::Y, 0.5));
    }

    #[test]
    fn many_coincident_lights_build_a_balanced_tree() {
        let lights: Vec<_> = (0..4096).map(|i| (i as u32, quad(Vec3::ZERO, 1.0))).collect();
        let bvh = LightBvh::build(&lights, lights.len());
        let total: f32 = (0..4096).map(|e| bvh.pmf(Vec3::new(0.0, -1.0, 0.0), e)).sum();
        assert!((total - 1.0).abs() < 1e-4);
        assert!((bvh.pmf(Vec3::new(0.0, -1.0, 0.0), 17) - 1.0 / 4096.0).abs() < 1e-7);
    }
}
