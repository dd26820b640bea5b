//! A scene BVH built in pieces, for scenes whose whole build fits no GPU:
//! the BLAS segments are built a group at a time (on a GPU, or on the host
//! by the reference build), put together here, and the TLAS is built on
//! the host over them.
//!
//! Objects larger than a piece are cut into several segments
//! ([`ScenePlan::split`]), each its own BLAS, entered by one TLAS record
//! per instance and segment. Each piece's leaf links count from the
//! piece's first triangle record (`GpuTlasInstance::tri_base`), so the
//! scene may hold more records than one build's links can address.
//! Where no object is cut, each BLAS is the one a whole build makes (a
//! segment's build depends only on its own triangles); only node and
//! record indices differ.

use std::ops::Range;

use super::host::ScenePlan;
use super::layout::{LEAF_FIRST_BITS, LINK_DONE};
use super::reference::HostBlases;
use crate::error::CudaError;
use crate::scene::SceneTables;

/// Most triangles of one piece: its leaf links address `1 << LEAF_FIRST_BITS` records.
pub(crate) const MAX_PIECE_TRIANGLES: u32 = (1 << LEAF_FIRST_BITS) - 1;

/// `plan`'s segments, in order, grouped into pieces of at most `capacity`
/// triangles (a segment larger than that is a piece of its own).
pub(crate) fn pieces(plan: &ScenePlan, capacity: u32) -> Vec<Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for s in 0..plan.segments() as usize {
        let end_triangles = plan.seg_start[s + 1] - plan.seg_start[start];
        if s > start && end_triangles > capacity {
            out.push(start..s);
            start = s;
        }
    }
    if start < plan.segments() as usize {
        out.push(start..plan.segments() as usize);
    }
    out
}

/// The plan of the segments `segments` of `plan`, primitives counted from
/// 0 (triangles still indexed as in `plan`); no instances.
pub(crate) fn piece_plan(plan: &ScenePlan, segments: Range<usize>) -> ScenePlan {
    let first = plan.seg_start[segments.start];
    ScenePlan {
        seg_start: plan.seg_start[segments.start..=segments.end].iter().map(|&p| p - first).collect(),
        seg_first_tri: plan.seg_first_tri[segments.clone()].to_vec(),
        seg_object: plan.seg_object[segments].to_vec(),
        object_segment: Vec::new(),
        valid_instances: Vec::new(),
    }
}

/// Appends `piece` (built alone: node links and records from 0) to `all`,
/// moving its node links past `all`'s nodes and its records past `all`'s
/// records (as its BLASes' record base).
fn append(all: &mut HostBlases, piece: HostBlases) -> Result<(), String> {
    let node_offset = all.nodes.len() as u64;
    if node_offset + piece.nodes.len() as u64 >= LINK_DONE as u64 {
        return Err(format!("a BVH of more than {LINK_DONE} nodes"));
    }
    let tri_base = u32::try_from(all.tris.len())
        .map_err(|_| format!("a BVH of more than {} triangle records", u32::MAX))?;
    let node_offset = node_offset as i32;
    let moved = |link: i32| if (0..LINK_DONE).contains(&link) { link + node_offset } else { link };
    all.nodes.extend(piece.nodes.into_iter().map(|mut n| {
        n.links[0] = moved(n.links[0]);
        n.links[1] = moved(n.links[1]);
        n
    }));
    all.tris.extend(piece.tris);
    all.tri_ids.extend(piece.tri_ids);
    all.roots.extend(piece.roots.into_iter().map(moved));
    all.bounds.extend(piece.bounds);
    all.tri_bases.extend(piece.tri_bases.into_iter().map(|b| b + tri_base));
    Ok(())
}

/// The BLASes of `t` built in pieces of at most `capacity` triangles:
/// `build_piece` builds the BLASes of one piece's plan (as
/// [`reference::build_blases`] does: links and records from 0), and they
/// are put together here (the TLAS over them: [`reference::with_tlas`]).
/// Returns the plan (objects cut at `capacity`) with the BLASes; errors
/// are `build_piece`'s, or the put-together BVH's index limits.
pub(crate) fn build_blases_in_pieces(
    t: &SceneTables,
    capacity: u32,
    mut build_piece: impl FnMut(&ScenePlan) -> Result<HostBlases, CudaError>,
) -> Result<(ScenePlan, HostBlases), CudaError> {
    let capacity = capacity.clamp(1, MAX_PIECE_TRIANGLES);
    let plan = ScenePlan::split(&t.objects, &t.instances, capacity);
    // Room for every piece up front: growing the arrays piece by piece
    // would copy them, and hold both copies at once. Nodes are at most one
    // per triangle; pages never written are never resident.
    let p = plan.primitives() as usize;
    let mut all = HostBlases {
        nodes: Vec::with_capacity(p),
        tris: Vec::with_capacity(p),
        tri_ids: Vec::with_capacity(p),
        ..Default::default()
    };
    for segments in pieces(&plan, capacity) {
        let piece = build_piece(&piece_plan(&plan, segments))?;
        append(&mut all, piece).map_err(|e| CudaError::Usage(format!("building the BVH in pieces: {e}")))?;
    }
    Ok((plan, all))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::testing::{brute_force, random_rays, random_scene};
    use crate::bvh::{reference, BuildOptions, HostSceneBvh};
    use atoll_scene::Scene;

    fn scene() -> (Scene, SceneTables) {
        let scene = random_scene(21, 7, 400, 30);
        let t = SceneTables::build(&scene);
        (scene, t)
    }

    /// [`build_blases_in_pieces`] with the reference build of each piece; also
    /// how many pieces were built.
    fn reference_pieces(
        t: &SceneTables,
        options: &BuildOptions,
        capacity: u32,
    ) -> (ScenePlan, HostSceneBvh, usize) {
        let (plan, bvh) = reference::build_in_pieces(t, capacity, options).unwrap();
        let built = pieces(&plan, capacity.clamp(1, MAX_PIECE_TRIANGLES)).len();
        (plan, bvh, built)
    }

    #[test]
    fn pieces_group_segments_in_order_under_the_capacity() {
        let plan = ScenePlan {
            seg_start: vec![0, 4, 6, 16, 17, 18],
            seg_first_tri: vec![0, 4, 6, 16, 17],
            seg_object: vec![0, 1, 2, 3, 4],
            ..Default::default()
        };
        assert_eq!(pieces(&plan, 6), [0..2, 2..3, 3..5]);
        assert_eq!(pieces(&plan, 100), vec![0..5_usize]);
        assert_eq!(pieces(&plan, 1), [0..1, 1..2, 2..3, 3..4, 4..5]);
        let p = piece_plan(&plan, 2..5);
        assert_eq!(p.seg_start, [0, 10, 11, 12]);
        assert_eq!(p.seg_first_tri, [6, 16, 17]);
        assert_eq!(p.seg_object, [2, 3, 4]);
    }

    #[test]
    fn split_plans_cut_large_objects_into_consecutive_segments() {
        let (_, t) = scene();
        let whole = ScenePlan::new(&t.objects, &t.instances);
        let largest = t.objects.iter().map(|o| o.triangle_count).max().unwrap();
        let cap = largest / 3;
        let split = ScenePlan::split(&t.objects, &t.instances, cap);
        assert!(split.segments() > whole.segments());
        assert_eq!(split.primitives(), whole.primitives());
        assert_eq!(split.valid_instances, whole.valid_instances);
        for o in 0..t.objects.len() as u32 {
            let segments = split.segments_of(o);
            let triangles: u32 = segments.clone().map(|s| split.seg_start[s + 1] - split.seg_start[s]).sum();
            assert_eq!(triangles, t.objects[o as usize].triangle_count);
            let mut next = t.objects[o as usize].first_triangle;
            for s in segments {
                assert!(split.seg_start[s + 1] - split.seg_start[s] <= cap);
                assert_eq!((split.seg_object[s], split.seg_first_tri[s]), (o, next));
                next += split.seg_start[s + 1] - split.seg_start[s];
            }
        }
        let entries = split.tlas_entries(&t.instances);
        let expected: usize = split
            .valid_instances
            .iter()
            .map(|&i| split.segments_of(t.instances[i as usize].object).len())
            .sum();
        assert_eq!(entries.len(), expected);
        assert!(entries.len() > split.valid_instances.len());
    }

    #[test]
    fn one_piece_is_the_whole_build() {
        let (_, t) = scene();
        let options = BuildOptions::default();
        let (_, bvh, built) = reference_pieces(&t, &options, u32::MAX);
        assert_eq!(built, 1);
        assert_eq!(bvh, reference::build_scene(&t, &options));
    }

    #[test]
    fn pieces_give_a_valid_bvh_with_the_brute_force_hits() {
        let (_, t) = scene();
        let options = BuildOptions::default();
        let whole = reference::build_scene(&t, &options);
        let largest = t.objects.iter().map(|o| o.triangle_count).max().unwrap();
        // Pieces that keep objects whole, and pieces that cut them.
        for capacity in [largest, largest / 4] {
            let (plan, bvh, built) = reference_pieces(&t, &options, capacity);
            assert!(built > 1, "capacity {capacity}: one piece");
            bvh.check(&plan).unwrap_or_else(|e| panic!("capacity {capacity}: {e}"));
            assert!(bvh.blas_tri_bases.iter().any(|&b| b > 0));
            let rays = random_rays(5, 3000);
            let mut hits = 0;
            for ray in &rays {
                let (got, want) = (bvh.intersect(ray), brute_force(&t, &plan, ray));
                assert_eq!(got.map(|h| h.t), want.map(|h| h.t), "capacity {capacity}: {ray:?}");
                assert_eq!(bvh.occluded(ray), want.is_some());
                if capacity == largest {
                    // Objects whole: the whole build's BLASes, so the same hits.
                    assert_eq!(got, whole.intersect(ray));
                }
                hits += want.is_some() as usize;
            }
            assert!(hits > rays.len() / 5, "{hits} hits");
        }
    }
}
