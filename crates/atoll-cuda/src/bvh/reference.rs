//! Host reference of the GPU LBVH build, step for step what the kernels
//! in `kernels/lbvh.cu`, `sort.cu` and `treelet.cu` compute, with the same
//! float operations in the same order (the kernels use `__fadd_rn` and
//! friends where contraction would differ); the independent per-primitive
//! steps and the treelet rounds run on all cores. The GPU tests compare the GPU's
//! output with this bit for bit; the host tests check its invariants and
//! its SAH against `atoll_bvh`'s binned-SAH builder without a GPU.
//!
//! The build tree over `P` primitives has `2P` slots: internal nodes
//! `0..P` (per segment of `n` primitives starting at sorted position `lo`,
//! slots `lo..lo+n-1` with the root at `lo`, slot `lo+n-1` spare) and leaves
//! `P..2P` (leaf `P + j` is sorted primitive `j`).

use rayon::prelude::*;

use super::host::{HostSceneBvh, ScenePlan};
use super::layout::{
    leaf_link, transform, GpuBvhNode, GpuTlasInstance, GpuTriRecord, TriangleTest, BUILD_COUNT_MASK,
    BUILD_LEAF_BIT, BUILD_NONE, LINK_DONE,
};
use super::BuildOptions;
use super::{box_area, Bounds};
use crate::layout::{GpuInstance, GpuMotion, NO_MOTION};
use crate::scene::SceneTables;

/// Float to unsigned with the same order (the kernels' atomicMin/Max key).
pub(crate) fn float_to_ordered(f: f32) -> u32 {
    let u = f.to_bits();
    if u & 0x8000_0000 != 0 {
        !u
    } else {
        u | 0x8000_0000
    }
}

pub(crate) fn ordered_to_float(u: u32) -> f32 {
    f32::from_bits(if u & 0x8000_0000 != 0 { u & 0x7fff_ffff } else { !u })
}

fn union(a: Bounds, b: Bounds) -> Bounds {
    let f =
        |x: [f32; 3], y: [f32; 3], op: fn(f32, f32) -> f32| [op(x[0], y[0]), op(x[1], y[1]), op(x[2], y[2])];
    (f(a.0, b.0, f32::min), f(a.1, b.1, f32::max))
}

/// `sah_node_cost` of lbvh.cuh: (cost, packed count).
pub(crate) fn sah_node_cost(
    area: f32,
    count: u32,
    children: f32,
    max_leaf: u32,
    ci: f32,
    ct: f32,
) -> (f32, u32) {
    let split = ct * area + children;
    let leaf = (ci * area) * count as f32;
    if count <= max_leaf && leaf <= split {
        (leaf, count | BUILD_LEAF_BIT)
    } else {
        (split, count)
    }
}

/// Spreads the low 10 bits of `v` to every third bit (Karras 2012).
pub(crate) fn expand_bits(mut v: u32) -> u32 {
    v = v.wrapping_mul(0x0001_0001) & 0xFF00_00FF;
    v = v.wrapping_mul(0x0000_0101) & 0x0F00_F00F;
    v = v.wrapping_mul(0x0000_0011) & 0xC30C_30C3;
    v = v.wrapping_mul(0x0000_0005) & 0x4924_9249;
    v
}

/// 30-bit Morton code of a point normalised to [0, 1]^3 (clamped), as `morton3` in lbvh.cuh.
pub(crate) fn morton3(x: f32, y: f32, z: f32) -> u32 {
    // NaN clamps to NaN and converts to 0, as fminf/fmaxf make it 0 on the GPU.
    let q = |v: f32| (v * 1024.0).clamp(0.0, 1023.0) as u32;
    expand_bits(q(x)) * 4 + expand_bits(q(y)) * 2 + expand_bits(q(z))
}

/// The segment holding primitive `p` (`segment_of` in lbvh.cuh).
pub fn segment_of(p: u32, seg_start: &[u32]) -> usize {
    let segments = seg_start.len() - 1;
    let (mut lo, mut hi) = (0, segments);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if seg_start[mid] <= p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The build tree (the device arrays of `lbvh.rs`, on the host).
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct BuildTree {
    /// Segment starts in primitive (and sorted) order, `segments + 1` entries.
    pub seg_start: Vec<u32>,
    /// Morton codes in sorted order.
    pub keys: Vec<u32>,
    /// Primitive index of each sorted position.
    pub values: Vec<u32>,
    /// Children of internal slots (`[BUILD_NONE; 2]` for spare slots).
    pub child: Vec<[u32; 2]>,
    pub parent: Vec<u32>,
    pub bounds: Vec<Bounds>,
    /// SAH cost of each subtree (area-weighted, not normalised).
    pub cost: Vec<f32>,
    /// Primitive count, with `BUILD_LEAF_BIT` where the SAH prefers a leaf.
    pub packed: Vec<u32>,
}

impl BuildTree {
    pub(crate) fn prims(&self) -> u32 {
        self.values.len() as u32
    }

    /// The root slot of segment `s`.
    pub(crate) fn root(&self, s: usize) -> u32 {
        let lo = self.seg_start[s];
        if self.seg_start[s + 1] - lo >= 2 {
            lo
        } else {
            self.prims() + lo
        }
    }

    pub(crate) fn count(&self, n: u32) -> u32 {
        self.packed[n as usize] & BUILD_COUNT_MASK
    }

    pub(crate) fn is_leaf_choice(&self, n: u32) -> bool {
        self.packed[n as usize] & BUILD_LEAF_BIT != 0
    }

    /// Internal slots in an order with every node after its children.
    pub(crate) fn post_order(&self) -> Vec<u32> {
        let p = self.prims();
        let mut order = Vec::with_capacity(p as usize);
        let mut todo: Vec<(u32, bool)> =
            (0..self.seg_start.len() - 1).map(|s| (self.root(s), false)).filter(|&(n, _)| n < p).collect();
        while let Some((n, expanded)) = todo.pop() {
            if expanded {
                order.push(n);
                continue;
            }
            todo.push((n, true));
            for c in self.child[n as usize] {
                if c < p {
                    todo.push((c, false));
                }
            }
        }
        order
    }
}

/// Steps 1–2: per-segment bounds of the doubled centroids, Morton codes,
/// and the sort by (segment, code), stable (values are primitive indices).
pub(crate) fn sorted_codes(boxes: &[Bounds], seg_start: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let segments = seg_start.len() - 1;
    let mut bounds = vec![[u32::MAX, u32::MAX, u32::MAX, 0, 0, 0]; segments];
    let centroid = |b: &Bounds| [b.0[0] + b.1[0], b.0[1] + b.1[1], b.0[2] + b.1[2]];
    for (p, b) in boxes.iter().enumerate() {
        let s = segment_of(p as u32, seg_start);
        let c = centroid(b);
        for k in 0..3 {
            bounds[s][k] = bounds[s][k].min(float_to_ordered(c[k]));
            bounds[s][3 + k] = bounds[s][3 + k].max(float_to_ordered(c[k]));
        }
    }
    let keys: Vec<u32> = boxes
        .par_iter()
        .enumerate()
        .map(|(p, b)| {
            let s = segment_of(p as u32, seg_start);
            let c = centroid(b);
            let b0: [f32; 3] = std::array::from_fn(|k| ordered_to_float(bounds[s][k]));
            let extent = (0..3).fold(0.0f32, |e, k| e.max(ordered_to_float(bounds[s][3 + k]) - b0[k]));
            let scale = if extent > 0.0 { 1.0 / extent } else { 0.0 };
            let n: [f32; 3] = std::array::from_fn(|k| (c[k] - b0[k]) * scale);
            morton3(n[0], n[1], n[2])
        })
        .collect();
    let mut values: Vec<u32> = (0..boxes.len() as u32).collect();
    // Stable, as the GPU's radix sort.
    values.par_sort_by_key(|&p| (segment_of(p, seg_start), keys[p as usize]));
    (values.par_iter().map(|&p| keys[p as usize]).collect(), values)
}

/// Karras' delta on local positions `a`, `b` of a segment (`karras_delta`).
fn delta(keys: &[u32], a: i64, b: i64) -> i32 {
    if b < 0 || b >= keys.len() as i64 {
        return -1;
    }
    let (ka, kb) = (keys[a as usize], keys[b as usize]);
    if ka != kb {
        (ka ^ kb).leading_zeros() as i32
    } else {
        32 + ((a as u32) ^ (b as u32)).leading_zeros() as i32
    }
}

/// Step 4: the binary radix tree of every segment (`lbvh_karras`).
pub(crate) fn karras(keys: &[u32], seg_start: &[u32]) -> (Vec<[u32; 2]>, Vec<u32>) {
    let p = keys.len() as u32;
    let mut child = vec![[BUILD_NONE; 2]; p as usize];
    let mut parent = vec![BUILD_NONE; 2 * p as usize];
    for s in 0..seg_start.len() - 1 {
        let lo = seg_start[s];
        let seg = &keys[lo as usize..seg_start[s + 1] as usize];
        let n = seg.len() as i64;
        for i in 0..n - 1 {
            let d: i64 = if delta(seg, i, i + 1) - delta(seg, i, i - 1) >= 0 { 1 } else { -1 };
            let delta_min = delta(seg, i, i - d);
            let mut lmax = 2;
            while delta(seg, i, i + lmax * d) > delta_min {
                lmax <<= 1;
            }
            let mut l = 0;
            let mut t = lmax >> 1;
            while t >= 1 {
                if delta(seg, i, i + (l + t) * d) > delta_min {
                    l += t;
                }
                t >>= 1;
            }
            let j = i + l * d;
            let delta_node = delta(seg, i, j);
            let (mut split, mut t) = (0, l);
            loop {
                t = (t + 1) >> 1;
                if delta(seg, i, i + (split + t) * d) > delta_node {
                    split += t;
                }
                if t <= 1 {
                    break;
                }
            }
            let gamma = i + split * d + if d < 0 { -1 } else { 0 };
            let node = |k: i64, leaf: bool| lo + k as u32 + if leaf { p } else { 0 };
            let left = node(gamma, i.min(j) == gamma);
            let right = node(gamma + 1, i.max(j) == gamma + 1);
            let gi = (lo as i64 + i) as usize;
            child[gi] = [left, right];
            parent[left as usize] = gi as u32;
            parent[right as usize] = gi as u32;
        }
    }
    (child, parent)
}

/// Steps 1–5 over primitive boxes: the sorted codes, the radix tree and
/// bottom-up bounds, costs and leaf preferences (`lbvh_bounds`).
pub(crate) fn build_tree(boxes: &[Bounds], seg_start: &[u32], max_leaf: u32, ci: f32, ct: f32) -> BuildTree {
    let (keys, values) = sorted_codes(boxes, seg_start);
    let (child, parent) = karras(&keys, seg_start);
    let p = keys.len();
    let mut tree = BuildTree {
        seg_start: seg_start.to_vec(),
        keys,
        values,
        child,
        parent,
        bounds: vec![([0.0; 3], [0.0; 3]); 2 * p],
        cost: vec![0.0; 2 * p],
        packed: vec![0; 2 * p],
    };
    for j in 0..p {
        let b = boxes[tree.values[j] as usize];
        tree.bounds[p + j] = b;
        tree.cost[p + j] = ci * box_area(b.0, b.1);
        tree.packed[p + j] = 1 | BUILD_LEAF_BIT;
    }
    for n in tree.post_order() {
        let [l, r] = tree.child[n as usize].map(|c| c as usize);
        let b = union(tree.bounds[l], tree.bounds[r]);
        let count = (tree.packed[l] & BUILD_COUNT_MASK) + (tree.packed[r] & BUILD_COUNT_MASK);
        let children = tree.cost[l] + tree.cost[r];
        let (cost, packed) = sah_node_cost(box_area(b.0, b.1), count, children, max_leaf, ci, ct);
        tree.bounds[n as usize] = b;
        tree.cost[n as usize] = cost;
        tree.packed[n as usize] = packed;
    }
    tree
}

/// The collapsed tree in the traversal layout (steps 7–8).
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Collapsed {
    pub nodes: Vec<GpuBvhNode>,
    /// Sorted primitive position `j` of each output record, in leaf order.
    pub order: Vec<u32>,
    /// Root link and box of each segment.
    pub roots: Vec<i32>,
    pub root_bounds: Vec<Bounds>,
}

/// Steps 7–8 (`lbvh_mark`, the two scans, `lbvh_emit_*`): the topmost
/// nodes preferring to be leaves become leaves, kept inner nodes and leaf
/// records are numbered in slot order.
pub(crate) fn collapse(tree: &BuildTree, max_leaf: u32) -> Collapsed {
    let p = tree.prims();
    let slot = |n: u32| if n < p { 2 * n as usize } else { 2 * (n - p) as usize + 1 };
    let mut kept = vec![false; p as usize];
    let mut leaf_size = vec![0u32; 2 * p as usize];
    for n in 0..2 * p {
        if n < p && tree.child[n as usize][0] == BUILD_NONE {
            continue;
        }
        let mut absorbed = false;
        let mut a = tree.parent[n as usize];
        while a != BUILD_NONE && tree.count(a) <= max_leaf {
            if tree.is_leaf_choice(a) {
                absorbed = true;
                break;
            }
            a = tree.parent[a as usize];
        }
        let leaf = tree.is_leaf_choice(n);
        if n < p {
            kept[n as usize] = !leaf && !absorbed;
        }
        if leaf && !absorbed {
            leaf_size[slot(n)] = tree.count(n);
        }
    }
    let exclusive = |v: &mut dyn Iterator<Item = u32>| -> Vec<u32> {
        let mut sum = 0;
        v.map(|x| {
            let before = sum;
            sum += x;
            before
        })
        .collect()
    };
    let node_id = exclusive(&mut kept.iter().map(|&k| k as u32));
    let offset = exclusive(&mut leaf_size.iter().copied());
    let link = |c: u32| -> i32 {
        if c < p && kept[c as usize] {
            node_id[c as usize] as i32
        } else {
            leaf_link(offset[slot(c)], tree.count(c))
        }
    };
    let mut nodes = vec![GpuBvhNode::default(); kept.iter().filter(|&&k| k).count()];
    for n in (0..p).filter(|&n| kept[n as usize]) {
        let [l, r] = tree.child[n as usize];
        nodes[node_id[n as usize] as usize] =
            GpuBvhNode::new([tree.bounds[l as usize], tree.bounds[r as usize]], [link(l), link(r)]);
    }
    let mut order = vec![0u32; p as usize];
    for (k, &size) in leaf_size.iter().enumerate() {
        if size == 0 {
            continue;
        }
        let mut position = offset[k];
        let mut stack = vec![if k % 2 == 0 { (k / 2) as u32 } else { p + (k / 2) as u32 }];
        while let Some(m) = stack.pop() {
            if m >= p {
                order[position as usize] = m - p;
                position += 1;
            } else {
                let [l, r] = tree.child[m as usize];
                stack.extend([r, l]);
            }
        }
    }
    let segments = tree.seg_start.len() - 1;
    let roots = (0..segments).map(|s| link(tree.root(s))).collect();
    let root_bounds = (0..segments).map(|s| tree.bounds[tree.root(s) as usize]).collect();
    Collapsed { nodes, order, roots, root_bounds }
}

/// A whole build over primitive boxes with `options`' treelet rounds.
pub(crate) fn build(
    boxes: &[Bounds],
    seg_start: &[u32],
    max_leaf: u32,
    options: &BuildOptions,
) -> (BuildTree, Collapsed) {
    let (ci, ct) = (options.intersection_cost, options.traversal_cost);
    if boxes.is_empty() {
        let roots = vec![LINK_DONE; seg_start.len().saturating_sub(1)];
        let root_bounds = vec![([0.0; 3], [0.0; 3]); roots.len()];
        return (BuildTree::default(), Collapsed { roots, root_bounds, ..Default::default() });
    }
    let mut tree = build_tree(boxes, seg_start, max_leaf, ci, ct);
    for round in 0..options.treelet_rounds {
        super::treelet_reference::round(&mut tree, options.gamma(round), max_leaf, ci, ct);
    }
    let collapsed = collapse(&tree, max_leaf);
    (tree, collapsed)
}

/// The record of triangle (p0, p1, p2) (`make_tri_record` in lbvh.cu; the
/// Woop rows are computed in f64 there too, but may differ in the last bit).
pub(crate) fn tri_record([p0, p1, p2]: [[f32; 3]; 3], test: TriangleTest) -> GpuTriRecord {
    let w = |v: [f32; 3], w: f32| [v[0], v[1], v[2], w];
    match test {
        TriangleTest::Exact => {
            let e = |q: [f32; 3]| [q[0] - p0[0], q[1] - p0[1], q[2] - p0[2]];
            GpuTriRecord { a: w(p0, 0.0), b: w(e(p1), 0.0), c: w(e(p2), 0.0) }
        }
        TriangleTest::Woop => {
            let a = p0.map(f64::from);
            let e1: [f64; 3] = std::array::from_fn(|k| p1[k] as f64 - a[k]);
            let e2: [f64; 3] = std::array::from_fn(|k| p2[k] as f64 - a[k]);
            let cross = |x: [f64; 3], y: [f64; 3]| {
                [x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]]
            };
            let n = cross(e1, e2);
            let nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
            if !(nn > 0.0 && nn < 1e300) {
                let nan = [f32::NAN; 4];
                return GpuTriRecord { a: nan, b: nan, c: nan };
            }
            let row = |r: [f64; 3]| {
                let r = r.map(|x| x / nn);
                [r[0] as f32, r[1] as f32, r[2] as f32, -(r[0] * a[0] + r[1] * a[1] + r[2] * a[2]) as f32]
            };
            GpuTriRecord { a: row(n), b: row(cross(e2, n)), c: row(cross(n, e1)) }
        }
    }
}

/// World box of an instance whose object has box `b` (`lbvh_tlas_boxes`:
/// Arvo's method, padded by a relative 1e-6).
pub(crate) fn instance_bounds(object_to_world: &[f32; 12], b: Bounds) -> Bounds {
    let m = object_to_world;
    let (mut lo, mut hi) = ([0.0f32; 3], [0.0f32; 3]);
    for r in 0..3 {
        lo[r] = m[r * 4 + 3];
        hi[r] = m[r * 4 + 3];
        for c in 0..3 {
            let (x, y) = (m[r * 4 + c] * b.0[c], m[r * 4 + c] * b.1[c]);
            lo[r] += x.min(y);
            hi[r] += x.max(y);
        }
        let pad = 1e-6 * lo[r].abs().max(hi[r].abs());
        lo[r] -= pad;
        hi[r] += pad;
    }
    (lo, hi)
}

/// A TLAS built on the host: its nodes, instance records in leaf order,
/// root link, root box and root SAH cost (area-weighted).
pub(crate) struct HostTlas {
    pub nodes: Vec<GpuBvhNode>,
    pub instances: Vec<GpuTlasInstance>,
    pub root: i32,
    pub bounds: Bounds,
    pub cost: f32,
}

/// The TLAS over `plan`'s valid instances, one record per segment of each
/// one's object (`ScenePlan::tlas_entries`), where segment `s`'s BLAS has
/// root link `roots[s]`, box `bounds[s]` and first record `tri_bases[s]`; as the GPU builds it (`lbvh_tlas_boxes`, the build
/// with one record per leaf, `lbvh_emit_instances`) where every object is
/// one segment.
pub(crate) fn build_tlas(
    plan: &ScenePlan,
    instances: &[GpuInstance],
    motions: &[GpuMotion],
    roots: &[i32],
    bounds: &[Bounds],
    tri_bases: &[u32],
    options: &BuildOptions,
) -> HostTlas {
    let entries = plan.tlas_entries(instances);
    let boxes: Vec<Bounds> = entries
        .par_iter()
        .map(|&(i, s)| {
            let inst = &instances[i as usize];
            match motions.get(inst.motion as usize) {
                Some(m) => ([m.bounds[0], m.bounds[1], m.bounds[2]], [m.bounds[3], m.bounds[4], m.bounds[5]]),
                None => instance_bounds(&inst.object_to_world, bounds[s as usize]),
            }
        })
        .collect();
    let (tree, tlas) = build(&boxes, &[0, boxes.len() as u32], 1, options);
    let identity = |m: &[f32; 12]| (0..12).all(|k| m[k] == if k % 5 == 0 { 1.0 } else { 0.0 });
    let records = tlas
        .order
        .iter()
        .map(|&j| {
            let (id, s) = entries[tree.values[j as usize] as usize];
            let inst = &instances[id as usize];
            let mut record = GpuTlasInstance {
                world_to_object: inst.world_to_object,
                blas_root: roots[s as usize],
                instance: id,
                transform: if identity(&inst.object_to_world) {
                    transform::IDENTITY
                } else {
                    transform::AFFINE
                },
                tri_base: tri_bases[s as usize],
            };
            if inst.motion != NO_MOTION {
                record.transform = transform::MOVING;
                record.world_to_object[0] = f32::from_bits(inst.motion);
            }
            record
        })
        .collect();
    if boxes.is_empty() {
        return HostTlas {
            nodes: Vec::new(),
            instances: records,
            root: LINK_DONE,
            bounds: ([0.0; 3], [0.0; 3]),
            cost: 0.0,
        };
    }
    HostTlas {
        nodes: tlas.nodes,
        instances: records,
        root: tlas.roots[0],
        bounds: tlas.root_bounds[0],
        cost: tree.cost[tree.root(0) as usize],
    }
}

/// BLASes built on the host, or built in pieces and put together
/// (`super::pieces`): nodes, triangle records and their global triangle
/// ids, and per segment its root link, box and first record.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct HostBlases {
    pub nodes: Vec<GpuBvhNode>,
    pub tris: Vec<GpuTriRecord>,
    pub tri_ids: Vec<u32>,
    pub roots: Vec<i32>,
    pub bounds: Vec<Bounds>,
    pub tri_bases: Vec<u32>,
}

/// The BLASes of `plan`'s segments, whose `seg_first_tri` index `t`'s
/// triangles, built on the host exactly as the GPU builds them (leaf links
/// count from record 0).
pub(crate) fn build_blases(t: &SceneTables, plan: &ScenePlan, options: &BuildOptions) -> HostBlases {
    let vertex = |i: u32| -> [f32; 3] { std::array::from_fn(|k| t.vertices[3 * i as usize + k]) };
    let triangle = |p: u32| {
        let s = segment_of(p, &plan.seg_start);
        plan.seg_first_tri[s] + (p - plan.seg_start[s])
    };
    let corners =
        |tri: u32| -> [[f32; 3]; 3] { std::array::from_fn(|k| vertex(t.triangles[3 * tri as usize + k])) };
    let boxes: Vec<Bounds> = (0..plan.primitives())
        .into_par_iter()
        .map(|p| {
            let [a, b, c] = corners(triangle(p));
            (
                std::array::from_fn(|k| a[k].min(b[k]).min(c[k])),
                std::array::from_fn(|k| a[k].max(b[k]).max(c[k])),
            )
        })
        .collect();
    let (tree, blas) = build(&boxes, &plan.seg_start, options.max_leaf, options);
    atoll_scene::progress::built(boxes.len() as u64);
    let tri_ids: Vec<u32> = blas.order.par_iter().map(|&j| triangle(tree.values[j as usize])).collect();
    let record = |id: u32| match t.curve_of.get(id as usize) {
        Some(&curve) if curve != crate::scene::NO_CURVE => super::layout::curve_record(curve),
        _ => tri_record(corners(id), options.triangle_test),
    };
    let tris = tri_ids.par_iter().map(|&id| record(id)).collect();
    HostBlases {
        nodes: blas.nodes,
        tris,
        tri_ids,
        tri_bases: vec![0; blas.roots.len()],
        roots: blas.roots,
        bounds: blas.root_bounds,
    }
}

/// The whole scene BVH from its BLASes: the TLAS built here over them.
pub(crate) fn with_tlas(
    t: &SceneTables,
    plan: &ScenePlan,
    blas: HostBlases,
    options: &BuildOptions,
) -> HostSceneBvh {
    let tlas =
        build_tlas(plan, &t.instances, &t.motions, &blas.roots, &blas.bounds, &blas.tri_bases, options);
    HostSceneBvh {
        blas_nodes: blas.nodes,
        tlas_nodes: tlas.nodes,
        tris: blas.tris,
        tri_ids: blas.tri_ids,
        instances: tlas.instances,
        tlas_root: tlas.root,
        blas_roots: blas.roots,
        blas_bounds: blas.bounds,
        blas_tri_bases: blas.tri_bases,
        tlas_bounds: tlas.bounds,
        triangle_test: options.triangle_test,
    }
}

/// The scene BVH built on the host in pieces of at most `capacity`
/// triangles, exactly as `super::build_in_pieces` builds it on a GPU.
pub fn build_in_pieces(
    t: &SceneTables,
    capacity: u32,
    options: &BuildOptions,
) -> Result<(ScenePlan, HostSceneBvh), crate::error::CudaError> {
    let (plan, blases) =
        super::pieces::build_blases_in_pieces(t, capacity, |piece| Ok(build_blases(t, piece, options)))?;
    let bvh = with_tlas(t, &plan, blases, options);
    Ok((plan, bvh))
}

/// The whole scene BVH built on the host exactly as the GPU builds it.
pub fn build_scene(t: &SceneTables, options: &BuildOptions) -> HostSceneBvh {
    let plan = ScenePlan::new(&t.objects, &t.instances);
    with_tlas(t, &plan, build_blases(t, &plan, options), options)
}

#[cfg(test)]
#[path = "reference_tests.rs"]
mod tests;
