//! Spatially coherent partitioning for the ring strategy: the scene cut
//! into K slabs along its longest axis, each slab balanced by bytes.
//!
//! In a ring every ray visits every part; with slabs, a ray that has found
//! its hit in one slab usually never enters another slab's bounds, so the
//! other devices reject it at their BVH roots (its `t_max` already ends
//! before their box). The memory-greedy [`crate::partition()`] spreads
//! every object over the whole scene instead, and each device then walks
//! each ray deep into its BVH. Measured in BENCHMARKS.md.
//!
//! Items placed by their centroid along the axis:
//! - every instance of a multiply instanced (or small) object: the
//!   object's geometry then goes to every slab holding one of its
//!   instances (instanced objects are small, that is why they are
//!   instanced);
//! - every triangle of a large object with a single instance (terrains,
//!   the "ground object"): its mesh is cut into triangle ranges, runs of
//!   consecutive triangles in the same slab (a row-major grid gives one or
//!   two runs per row).
//!
//! Cuts are weighted quantiles from a histogram of item centroids (linear
//! time: no sort of hundreds of millions of triangles). The result is
//! checked against the budget like any partition; callers fall back to the
//! memory-greedy one when it does not fit (duplicated instanced geometry
//! can make slabs heavier than greedy parts).

use atoll_bvh::{ByteModel, MeshRange, ScenePart};
use atoll_scene::{ObjectId, Scene};
use glam::Vec3;
use rayon::prelude::*;

use crate::partition::{Partition, PartitionError, PartitionOptions};

/// Histogram bins along the axis: cuts land within 1/BINS of the extent.
const BINS: usize = 1 << 14;

/// Bytes of one stored triangle index triple.
const INDEX_BYTES: u64 = 12;

/// How an object's geometry is placed.
enum Placement {
    /// Each instance goes to the slab of its centroid.
    ByInstance,
    /// Each triangle goes to the slab of its centroid (one instance).
    ByTriangle { instance: u32 },
}

/// Splits `scene` into `parts` slabs along its longest axis, each holding
/// about the same bytes under `model`; errors when a slab exceeds
/// `options.budget` (or the scene has no geometry to place).
pub fn partition_spatial(
    scene: &Scene,
    parts: usize,
    model: &ByteModel,
    options: &PartitionOptions,
) -> Result<Partition, PartitionError> {
    if parts == 0 {
        return Err(PartitionError::NoParts(parts));
    }
    let (lo, hi) = scene.world_bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
    let extent = (hi - lo).max(Vec3::splat(f32::MIN_POSITIVE));
    let axis = extent.max_position();
    let (origin, width) = (lo[axis], extent[axis]);
    let bin_of =
        |x: f32| (((x - origin) / width * BINS as f32) as isize).clamp(0, BINS as isize - 1) as usize;

    let mut instances_of: Vec<Vec<u32>> = vec![Vec::new(); scene.objects.len()];
    for (i, inst) in scene.instances.iter().enumerate() {
        instances_of[inst.object as usize].push(i as u32);
    }
    let object_triangles: Vec<u64> =
        (0..scene.objects.len()).map(|o| scene.object_triangles(o as u32)).collect();
    let total_triangles: u64 =
        instances_of.iter().zip(&object_triangles).filter(|(i, _)| !i.is_empty()).map(|(_, t)| *t).sum();
    // Objects with one instance and more than 1/(4K) of the triangles are cut by triangles.
    let placements: Vec<Placement> = (0..scene.objects.len())
        .map(|o| match instances_of[o].as_slice() {
            [only] if object_triangles[o] * 4 * parts as u64 > total_triangles && parts > 1 => {
                Placement::ByTriangle { instance: *only }
            }
            _ => Placement::ByInstance,
        })
        .collect();
    let triangle_weight = INDEX_BYTES + model.per_triangle;
    let object_weight = |o: usize| object_triangles[o] * triangle_weight + model.per_object;

    // Weighted histogram of item centroids.
    let mut histogram = vec![0u64; BINS];
    let instance_centre = |i: u32| -> f32 {
        let inst = &scene.instances[i as usize];
        let centre = object_centre(scene, inst.object);
        inst.object_to_world.transform_point3(centre)[axis]
    };
    for (o, placement) in placements.iter().enumerate() {
        match placement {
            Placement::ByInstance => {
                let insts = &instances_of[o];
                if insts.is_empty() {
                    continue;
                }
                let share = model.per_instance + object_weight(o) / insts.len() as u64;
                for &i in insts {
                    histogram[bin_of(instance_centre(i))] += share;
                }
            }
            Placement::ByTriangle { instance } => {
                let bins = triangle_bins(scene, o as ObjectId, *instance, axis, &bin_of);
                for (b, n) in bins.into_iter().enumerate() {
                    histogram[b] += n * triangle_weight;
                }
            }
        }
    }
    // Cuts: slab s takes the bins whose cumulative weight is in [s, s + 1) / K of the total.
    let total: u64 = histogram.iter().sum();
    let mut slab_of_bin = vec![0usize; BINS];
    let mut running = 0u64;
    for (b, w) in histogram.iter().enumerate() {
        // The bin goes to the slab its middle falls in.
        let middle = running + w / 2;
        slab_of_bin[b] =
            ((middle as u128 * parts as u128) / total.max(1) as u128).min(parts as u128 - 1) as usize;
        running += w;
    }
    let slab = |x: f32| slab_of_bin[bin_of(x)];

    let mut slabs: Vec<ScenePart> = (0..parts).map(|_| ScenePart::default()).collect();
    for (o, placement) in placements.iter().enumerate() {
        match placement {
            Placement::ByInstance => {
                for &i in &instances_of[o] {
                    slabs[slab(instance_centre(i))].instances.push(i);
                }
            }
            Placement::ByTriangle { instance } => {
                let runs = triangle_runs(scene, o as ObjectId, *instance, axis, &slab);
                for (s, ranges) in runs.into_iter().enumerate() {
                    if !ranges.is_empty() {
                        slabs[s].instances.push(*instance);
                        slabs[s].object_subsets.push((o as ObjectId, ranges));
                    }
                }
            }
        }
    }
    for part in &mut slabs {
        part.instances.sort_unstable();
        part.object_subsets.sort_by_key(|s| s.0);
    }
    let partition = Partition::from_parts(scene, slabs, model);
    if let Some(budget) = options.budget {
        if let Some((&heaviest, _)) = partition.bytes.iter().zip(0..).max() {
            if heaviest > budget {
                return Err(PartitionError::DoesNotFit {
                    parts,
                    budget,
                    total: partition.bytes.iter().sum(),
                    piece: heaviest,
                    least_loaded: partition.bytes.iter().copied().min().unwrap_or(0),
                });
            }
        }
    }
    Ok(partition)
}

/// The centre of an object's bounds in its own space.
fn object_centre(scene: &Scene, object: ObjectId) -> Vec3 {
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for &m in &scene.objects[object as usize].meshes {
        for &p in &scene.meshes[m as usize].positions {
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    if lo.x <= hi.x {
        (lo + hi) * 0.5
    } else {
        Vec3::ZERO
    }
}

/// World-space centroid coordinate along `axis` of every triangle of
/// `object` as placed by `instance`, mesh by mesh, handed to `f`.
fn for_each_mesh_centroids<R: Send>(
    scene: &Scene,
    object: ObjectId,
    instance: u32,
    axis: usize,
    f: impl Fn(u32, &mut dyn Iterator<Item = f32>) -> R + Sync,
) -> Vec<R> {
    let to_world = scene.instances[instance as usize].object_to_world;
    scene.objects[object as usize]
        .meshes
        .par_iter()
        .map(|&m| {
            let mesh = &scene.meshes[m as usize];
            let mut centroids = mesh.indices.iter().map(|t| {
                let c = (mesh.positions[t[0] as usize]
                    + mesh.positions[t[1] as usize]
                    + mesh.positions[t[2] as usize])
                    / 3.0;
                to_world.transform_point3(c)[axis]
            });
            f(m, &mut centroids)
        })
        .collect()
}

/// Triangle counts of `object` per histogram bin.
fn triangle_bins(
    scene: &Scene,
    object: ObjectId,
    instance: u32,
    axis: usize,
    bin_of: &(dyn Fn(f32) -> usize + Sync),
) -> Vec<u64> {
    let per_mesh = for_each_mesh_centroids(scene, object, instance, axis, |_, centroids| {
        let mut bins = vec![0u64; BINS];
        for x in centroids {
            bins[bin_of(x)] += 1;
        }
        bins
    });
    per_mesh.into_iter().fold(vec![0u64; BINS], |mut acc, bins| {
        acc.iter_mut().zip(bins).for_each(|(a, b)| *a += b);
        acc
    })
}

/// Per slab, the runs of consecutive triangles of `object` whose centroid
/// falls in it.
fn triangle_runs(
    scene: &Scene,
    object: ObjectId,
    instance: u32,
    axis: usize,
    slab: &(dyn Fn(f32) -> usize + Sync),
) -> Vec<Vec<MeshRange>> {
    let per_mesh = for_each_mesh_centroids(scene, object, instance, axis, |mesh, centroids| {
        let mut runs: Vec<(usize, MeshRange)> = Vec::new();
        for (t, x) in centroids.enumerate() {
            let s = slab(x);
            match runs.last_mut() {
                Some((last, r)) if *last == s => r.triangles.end = t as u32 + 1,
                _ => runs.push((s, MeshRange { mesh, triangles: t as u32..t as u32 + 1 })),
            }
        }
        runs
    });
    let slabs = per_mesh.iter().flatten().map(|(s, _)| s + 1).max().unwrap_or(0);
    let mut out = vec![Vec::new(); slabs];
    for (s, r) in per_mesh.into_iter().flatten() {
        out[s].push(r);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every (instance, mesh, triangle) of `scene` in exactly one part.
    fn assert_exactly_once(scene: &Scene, p: &Partition) {
        for (i, inst) in scene.instances.iter().enumerate() {
            for &m in &scene.objects[inst.object as usize].meshes {
                for t in 0..scene.meshes[m as usize].indices.len() as u32 {
                    let holders: Vec<usize> = (0..p.parts.len())
                        .filter(|&k| {
                            let part = &p.parts[k];
                            part.instances.contains(&(i as u32))
                                && part
                                    .object_ranges(scene, inst.object)
                                    .iter()
                                    .any(|r| r.mesh == m && r.triangles.contains(&t))
                        })
                        .collect();
                    assert_eq!(holders.len(), 1, "instance {i} mesh {m} triangle {t}: {holders:?}");
                    assert_eq!(p.owner(i as u32, m, t), Some(holders[0]));
                }
            }
        }
    }

    #[test]
    fn slabs_cover_everything_once_and_split_the_ground_along_the_long_axis() {
        let scene = atoll_scene::procedural::bench_scene(20_000);
        let model = ByteModel::CPU;
        for k in [1, 2, 3] {
            let p = partition_spatial(&scene, k, &model, &PartitionOptions::default()).unwrap();
            assert_eq!(p.parts.len(), k);
            assert_exactly_once(&scene, &p);
            if k > 1 {
                // The terrain (object 0, one instance) is cut by triangles into every slab.
                assert!(p.parts.iter().all(|part| part.object_subsets.iter().any(|s| s.0 == 0)));
                // Balanced within a factor 2 (instanced geometry is duplicated).
                let (min, max) = (p.bytes.iter().min().unwrap(), p.bytes.iter().max().unwrap());
                assert!(*max < 2 * *min, "{:?}", p.bytes);
            }
        }
    }

    #[test]
    fn a_budget_the_slabs_exceed_is_an_error_and_results_are_deterministic() {
        let scene = atoll_scene::procedural::bench_scene(20_000);
        let model = ByteModel::CPU;
        let a = partition_spatial(&scene, 2, &model, &PartitionOptions::default()).unwrap();
        let b = partition_spatial(&scene, 2, &model, &PartitionOptions::default()).unwrap();
        assert_eq!(a, b);
        let tight =
            PartitionOptions { budget: Some(a.bytes.iter().max().unwrap() - 1), split_threshold: None };
        assert!(matches!(
            partition_spatial(&scene, 2, &model, &tight),
            Err(PartitionError::DoesNotFit { .. })
        ));
        let cornell = atoll_scene::cornell::builtin_cornell_box();
        assert_exactly_once(
            &cornell,
            &partition_spatial(&cornell, 3, &model, &PartitionOptions::default()).unwrap(),
        );
    }
}
