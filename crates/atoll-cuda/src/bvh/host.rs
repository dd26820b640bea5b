//! The GPU BVH's tables on the host: what [`super::GpuSceneBvh::download`]
//! returns and what `super::reference::build` produces, so both can be
//! compared, checked, costed (SAH) and, in tests, traversed here.
//!
//! Also the build plan both builders share: which objects get a BLAS (one
//! segment each) and which instances go into the TLAS.

use atoll_bvh::Aabb;
#[cfg(test)]
use atoll_bvh::{Ray, TraversalRay, TriAccel};
#[cfg(test)]
use glam::Vec3;
use glam::Vec3A;

use super::layout::{GpuBvhNode, GpuTlasInstance, GpuTriRecord, Link, TriangleTest, BUILD_NONE, LINK_DONE};
use crate::layout::{GpuInstance, GpuObject};

/// Which objects and instances a scene BVH covers (host-side plan).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ScenePlan {
    /// First primitive of each segment (= BLAS), plus the total: objects
    /// with triangles, in object order, each in one segment or, where a
    /// plan caps segments ([`ScenePlan::split`]), in consecutive ones.
    pub seg_start: Vec<u32>,
    /// First global triangle of each segment.
    pub seg_first_tri: Vec<u32>,
    /// Object of each segment.
    pub seg_object: Vec<u32>,
    /// First segment of each object, `BUILD_NONE` for objects without triangles.
    pub object_segment: Vec<u32>,
    /// Instances in the TLAS: those of this device's scene part whose object
    /// has triangles and whose `world_to_object` is finite (as
    /// `atoll_bvh::SceneBvh` leaves out the rest). Each has one TLAS
    /// record per segment of its object.
    pub valid_instances: Vec<u32>,
}

impl ScenePlan {
    /// One segment per object with triangles.
    pub fn new(objects: &[GpuObject], instances: &[GpuInstance]) -> Self {
        Self::split(objects, instances, u32::MAX)
    }

    /// Objects with more than `max_segment` triangles in consecutive
    /// segments of at most that many: a BVH built in pieces builds each
    /// segment whole in one piece.
    pub fn split(objects: &[GpuObject], instances: &[GpuInstance], max_segment: u32) -> Self {
        let max_segment = max_segment.max(1);
        let mut plan = ScenePlan { seg_start: vec![0], ..Default::default() };
        for (o, object) in objects.iter().enumerate() {
            if object.triangle_count == 0 {
                plan.object_segment.push(BUILD_NONE);
                continue;
            }
            plan.object_segment.push(plan.seg_object.len() as u32);
            let mut done = 0;
            while done < object.triangle_count {
                let n = (object.triangle_count - done).min(max_segment);
                plan.seg_object.push(o as u32);
                plan.seg_first_tri.push(object.first_triangle + done);
                plan.seg_start.push(plan.seg_start.last().unwrap() + n);
                done += n;
            }
        }
        plan.valid_instances = (0..instances.len() as u32)
            .filter(|&i| {
                let inst = &instances[i as usize];
                let has_blas =
                    plan.object_segment.get(inst.object as usize).is_some_and(|&s| s != BUILD_NONE);
                has_blas && inst.excluded == 0 && inst.world_to_object.iter().all(|x| x.is_finite())
            })
            .collect();
        plan
    }

    pub(crate) fn segments(&self) -> u32 {
        self.seg_object.len() as u32
    }

    /// BLAS primitives (triangles) over all segments.
    pub(crate) fn primitives(&self) -> u32 {
        *self.seg_start.last().unwrap_or(&0)
    }

    /// The segments of `object` (empty for one without triangles).
    pub(crate) fn segments_of(&self, object: u32) -> std::ops::Range<usize> {
        let first = self.object_segment[object as usize];
        if first == BUILD_NONE {
            return 0..0;
        }
        let first = first as usize;
        let count = self.seg_object[first..].iter().take_while(|&&o| o == object).count();
        first..first + count
    }

    /// The TLAS's entries: `(instance, segment)` for every segment of every
    /// valid instance's object, in instance order.
    pub(crate) fn tlas_entries(&self, instances: &[GpuInstance]) -> Vec<(u32, u32)> {
        self.valid_instances
            .iter()
            .flat_map(|&i| self.segments_of(instances[i as usize].object).map(move |s| (i, s as u32)))
            .collect()
    }
}

/// A closest hit found by [`HostSceneBvh::intersect`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HostHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
    pub instance: u32,
    /// Global triangle index.
    pub triangle: u32,
}

/// The GPU BVH's tables, on the host.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HostSceneBvh {
    pub blas_nodes: Vec<GpuBvhNode>,
    pub tlas_nodes: Vec<GpuBvhNode>,
    pub tris: Vec<GpuTriRecord>,
    pub tri_ids: Vec<u32>,
    pub instances: Vec<GpuTlasInstance>,
    pub tlas_root: i32,
    /// Root link, box and first triangle record of each BLAS (segment):
    /// its leaf links count from that record (`GpuTlasInstance::tri_base`).
    pub blas_roots: Vec<i32>,
    pub blas_bounds: Vec<([f32; 3], [f32; 3])>,
    pub blas_tri_bases: Vec<u32>,
    /// The TLAS root box.
    pub tlas_bounds: ([f32; 3], [f32; 3]),
    pub triangle_test: TriangleTest,
}

/// Woop's test on the host, as `intersect_woop` in bvh.cuh (with FMA
/// contraction and, for closest hits, the approximate division on the GPU,
/// the floats may differ in the last bits).
#[cfg(test)]
fn intersect_woop(r: &GpuTriRecord, o: Vec3A, d: Vec3A, t_max: f32) -> Option<(f32, f32, f32)> {
    let row =
        |m: &[f32; 4]| (m[3] + o.x * m[0] + o.y * m[1] + o.z * m[2], d.x * m[0] + d.y * m[1] + d.z * m[2]);
    let (ow, dw) = row(&r.a);
    let t = -ow / dw;
    if !(t > 0.0 && t < t_max) {
        return None;
    }
    let (ou, du) = row(&r.b);
    let u = ou + t * du;
    let (ov, dv) = row(&r.c);
    let v = ov + t * dv;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then_some((t, u, v))
}

impl HostSceneBvh {
    /// The closest hit with `0 < t < ray.t_max`, traversing like the kernels.
    #[cfg(test)]
    pub(crate) fn intersect(&self, ray: &Ray) -> Option<HostHit> {
        self.trace(ray, false)
    }

    /// Whether anything is hit with `0 < t < ray.t_max`.
    #[cfg(test)]
    pub(crate) fn occluded(&self, ray: &Ray) -> bool {
        self.trace(ray, true).is_some()
    }

    #[cfg(test)]
    fn trace(&self, ray: &Ray, any: bool) -> Option<HostHit> {
        let world = TraversalRay::new(ray.origin.into(), ray.direction.into());
        let mut t_max = ray.t_max;
        let mut best = None;
        let mut todo = vec![(self.tlas_root, None::<u32>)];
        while let Some((link, instance)) = todo.pop() {
            let (nodes, tr) = match instance {
                None => (&self.tlas_nodes, world),
                Some(slot) => (&self.blas_nodes, self.object_ray(slot, ray)),
            };
            match Link::decode(link) {
                Link::Marker(_) => {}
                Link::Node(n) => {
                    let node = &nodes[n as usize];
                    for c in 0..2 {
                        let (lo, hi) = node.child_box(c);
                        if tr.box_entry(Vec3A::from_array(lo), Vec3A::from_array(hi), t_max) < f32::INFINITY {
                            todo.push((node.links[c], instance));
                        }
                    }
                }
                Link::Leaf { first, count } => match instance {
                    None => {
                        for slot in first..first + count {
                            todo.push((self.instances[slot as usize].blas_root, Some(slot)));
                        }
                    }
                    Some(slot) => {
                        let base = self.instances[slot as usize].tri_base;
                        for k in base + first..base + first + count {
                            let r = &self.tris[k as usize];
                            let hit = match self.triangle_test {
                                TriangleTest::Exact => TriAccel {
                                    v0: Vec3::new(r.a[0], r.a[1], r.a[2]),
                                    e1: Vec3::new(r.b[0], r.b[1], r.b[2]),
                                    e2: Vec3::new(r.c[0], r.c[1], r.c[2]),
                                }
                                .intersect(tr.origin, tr.dir, t_max),
                                TriangleTest::Woop => intersect_woop(r, tr.origin, tr.dir, t_max),
                            };
                            if let Some((t, u, v)) = hit {
                                t_max = t;
                                let instance = self.instances[slot as usize].instance;
                                best =
                                    Some(HostHit { t, u, v, instance, triangle: self.tri_ids[k as usize] });
                                if any {
                                    return best;
                                }
                            }
                        }
                    }
                },
            }
        }
        best
    }

    /// The ray in instance record `slot`'s object space (the CPU's transform).
    #[cfg(test)]
    fn object_ray(&self, slot: u32, ray: &Ray) -> TraversalRay {
        let inst = &self.instances[slot as usize];
        let (o, d) = (Vec3A::from(ray.origin), Vec3A::from(ray.direction));
        if inst.transform == super::layout::transform::IDENTITY {
            return TraversalRay::new(o, d);
        }
        let m = &inst.world_to_object;
        let row = |r: usize, v: Vec3A, point: bool| {
            let linear = m[r * 4] * v.x + m[r * 4 + 1] * v.y + m[r * 4 + 2] * v.z;
            if point {
                linear + m[r * 4 + 3]
            } else {
                linear
            }
        };
        let o2 = Vec3A::new(row(0, o, true), row(1, o, true), row(2, o, true));
        let d2 = Vec3A::new(row(0, d, false), row(1, d, false), row(2, d, false));
        TraversalRay::new(o2, d2)
    }

    /// Calls `f(link, depth)` for every link of the tree under `root`.
    fn visit<F: FnMut(Link, u32)>(nodes: &[GpuBvhNode], root: i32, f: &mut F) {
        let mut todo = vec![(root, 1u32)];
        while let Some((link, depth)) = todo.pop() {
            let l = Link::decode(link);
            f(l, depth);
            if let Link::Node(n) = l {
                todo.extend(nodes[n as usize].links[..2].iter().map(|&c| (c, depth + 1)));
            }
        }
    }

    /// SAH cost of one tree (`atoll_bvh::Bvh2::sah_cost`'s formula) given
    /// its root box: traversal cost `ct` per inner node and `ci` per
    /// primitive, each weighted by its box's area, over the root's area.
    pub(crate) fn tree_sah(
        nodes: &[GpuBvhNode],
        root: i32,
        root_box: ([f32; 3], [f32; 3]),
        ci: f32,
        ct: f32,
    ) -> f32 {
        let area = |(lo, hi): ([f32; 3], [f32; 3])| {
            Aabb { min: Vec3A::from_array(lo), max: Vec3A::from_array(hi) }.area() as f64
        };
        let root_area = area(root_box).max(f32::MIN_POSITIVE as f64);
        let mut cost = match Link::decode(root) {
            Link::Leaf { count, .. } => ci as f64 * count as f64 * root_area,
            Link::Node(_) => ct as f64 * root_area,
            Link::Marker(_) => return 0.0,
        };
        Self::visit(nodes, root, &mut |link, _| {
            if let Link::Node(n) = link {
                let node = &nodes[n as usize];
                for c in 0..2 {
                    cost += match Link::decode(node.links[c]) {
                        Link::Leaf { count, .. } => ci as f64 * count as f64 * area(node.child_box(c)),
                        _ => ct as f64 * area(node.child_box(c)),
                    };
                }
            }
        });
        (cost / root_area) as f32
    }

    /// SAH of the BLASes (mean weighted by triangle count, as
    /// `atoll_bvh::SceneBvhStats::blas`) and of the TLAS.
    pub fn sah(&self, ci: f32, ct: f32) -> (f32, f32) {
        let (mut weighted, mut triangles) = (0.0f64, 0u64);
        for (s, &root) in self.blas_roots.iter().enumerate() {
            let mut count = 0u64;
            Self::visit(&self.blas_nodes, root, &mut |link, _| {
                if let Link::Leaf { count: c, .. } = link {
                    count += c as u64;
                }
            });
            weighted +=
                Self::tree_sah(&self.blas_nodes, root, self.blas_bounds[s], ci, ct) as f64 * count as f64;
            triangles += count;
        }
        let tlas = Self::tree_sah(&self.tlas_nodes, self.tlas_root, self.tlas_bounds, ci, ct);
        ((weighted / triangles.max(1) as f64) as f32, tlas)
    }

    /// Structural checks: every node reached exactly once from the roots,
    /// every record in exactly one leaf, leaf links in range, child boxes
    /// containing their children's, triangle ids a permutation of the
    /// segments' triangles. Returns the first problem found.
    pub fn check(&self, plan: &ScenePlan) -> Result<(), String> {
        let check_tree =
            |nodes: &[GpuBvhNode], roots: &[(i32, u32)], records: usize, what: &str| -> Result<(), String> {
                let mut node_seen = vec![false; nodes.len()];
                let mut record_seen = vec![false; records];
                for &(root, base) in roots {
                    let mut todo = vec![root];
                    while let Some(link) = todo.pop() {
                        match Link::decode(link) {
                            Link::Marker(m) if m == LINK_DONE && records == 0 => {}
                            Link::Marker(m) => return Err(format!("{what}: marker {m:#x} as a link")),
                            Link::Node(n) => {
                                let seen = node_seen
                                    .get_mut(n as usize)
                                    .ok_or(format!("{what}: node {n} out of range"))?;
                                if std::mem::replace(seen, true) {
                                    return Err(format!("{what}: node {n} reached twice"));
                                }
                                let node = &nodes[n as usize];
                                for c in 0..2 {
                                    let (lo, hi) = node.child_box(c);
                                    if (0..3).any(|k| lo[k] > hi[k] || lo[k].is_nan() || hi[k].is_nan()) {
                                        return Err(format!(
                                            "{what}: node {n} child {c} has an inverted box"
                                        ));
                                    }
                                    if let Link::Node(m) = Link::decode(node.links[c]) {
                                        let inner = nodes
                                            .get(m as usize)
                                            .ok_or(format!("{what}: node {m} out of range"))?;
                                        let (a, b) = (inner.child_box(0), inner.child_box(1));
                                        if (0..3)
                                            .any(|k| a.0[k].min(b.0[k]) < lo[k] || a.1[k].max(b.1[k]) > hi[k])
                                        {
                                            return Err(format!(
                                                "{what}: node {m} pokes out of its box in node {n}"
                                            ));
                                        }
                                    }
                                    todo.push(node.links[c]);
                                }
                            }
                            Link::Leaf { first, count } => {
                                for r in base + first..base + first + count {
                                    let seen = record_seen
                                        .get_mut(r as usize)
                                        .ok_or(format!("{what}: record {r} out of range"))?;
                                    if std::mem::replace(seen, true) {
                                        return Err(format!("{what}: record {r} in two leaves"));
                                    }
                                }
                            }
                        }
                    }
                }
                if let Some(n) = node_seen.iter().position(|&s| !s) {
                    return Err(format!("{what}: node {n} unreachable"));
                }
                if let Some(r) = record_seen.iter().position(|&s| !s) {
                    return Err(format!("{what}: record {r} in no leaf"));
                }
                Ok(())
            };
        if self.blas_tri_bases.len() != self.blas_roots.len() {
            return Err("BLAS: not one record base per root".into());
        }
        let blas_roots: Vec<(i32, u32)> =
            self.blas_roots.iter().copied().zip(self.blas_tri_bases.iter().copied()).collect();
        check_tree(&self.blas_nodes, &blas_roots, self.tris.len(), "BLAS")?;
        check_tree(&self.tlas_nodes, &[(self.tlas_root, 0)], self.instances.len(), "TLAS")?;
        let mut ids = self.tri_ids.clone();
        ids.sort_unstable();
        let mut expected: Vec<u32> = (0..plan.segments() as usize)
            .flat_map(|s| {
                let n = plan.seg_start[s + 1] - plan.seg_start[s];
                plan.seg_first_tri[s]..plan.seg_first_tri[s] + n
            })
            .collect();
        expected.sort_unstable();
        if ids != expected {
            return Err("BLAS: triangle ids are not the segments' triangles".into());
        }
        // Each valid instance enters every segment of its object once.
        let segment_of_root: std::collections::HashMap<(i32, u32), usize> =
            blas_roots.iter().enumerate().map(|(s, &r)| (r, s)).collect();
        let mut entered: std::collections::BTreeMap<u32, Vec<usize>> = Default::default();
        for record in &self.instances {
            let s = segment_of_root
                .get(&(record.blas_root, record.tri_base))
                .ok_or(format!("TLAS: instance {} enters no BLAS's root", record.instance))?;
            entered.entry(record.instance).or_default().push(*s);
        }
        if !entered.keys().copied().eq(plan.valid_instances.iter().copied()) {
            return Err("TLAS: instance records are not the valid instances".into());
        }
        for (instance, segments) in &mut entered {
            segments.sort_unstable();
            let object = plan.seg_object[segments[0]];
            if !segments.iter().copied().eq(plan.segments_of(object)) {
                return Err(format!(
                    "TLAS: instance {instance} does not enter each segment of its object once"
                ));
            }
        }
        Ok(())
    }
}
