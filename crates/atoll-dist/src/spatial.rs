//! Spatially coherent partitioning for the ring strategy: the scene's
//! items ordered along a Morton curve through its bounds, cut into chunks of
//! equal bytes, and the chunks dealt out to the K parts in turn.
//!
//! In a ring every ray visits every part, and a part costs a ray little
//! where the ray's `t_max`, shortened by a hit found on an earlier part,
//! ends before that part's geometry. Two layouts:
//! - **slabs** (one chunk per part): a ray that found its hit in one part
//!   rarely enters another's bounds, but the work follows the camera: the
//!   part holding what the camera sees traces nearly every ray deep while
//!   the others idle.
//! - **interleaved chunks** (many chunks per part, dealt out in turn): every
//!   view sees all parts about equally, so the work is balanced, while each
//!   chunk is compact enough that a ray's hit in one chunk still ends its
//!   walk through the others. Measured in BENCHMARKS.md.
//!
//! The memory-greedy [`crate::partition()`] spreads every object over the
//! whole scene instead and balances bytes, not work: on the landscape it puts
//! the terrain and the trees on different devices, whose traversal costs
//! differ several times over.
//!
//! Items placed by their centroid:
//! - every instance of a multiply instanced (or small) object: the
//!   object's geometry then goes to every part holding one of its
//!   instances (instanced objects are small, that is why they are
//!   instanced);
//! - every triangle of a large object with a single instance (terrains,
//!   the "ground object"): its mesh is cut into triangle ranges, runs of
//!   consecutive triangles in the same part.
//!
//! Chunks are cut from a weighted histogram over grid cells in Morton
//! order (linear time: no sort of hundreds of millions of triangles). The
//! result is checked against the budget like any partition; callers fall
//! back to the memory-greedy one when it does not fit (duplicated instanced
//! geometry can make spatial parts heavier than greedy ones).

use atoll_bvh::{ByteModel, MeshRange, ScenePart};
use atoll_scene::{ObjectId, Scene};
use glam::Vec3;
use rayon::prelude::*;

use crate::partition::{Partition, PartitionError, PartitionOptions};

/// Bits of the cell grid's Morton code: 2^18 cells, split between the axes
/// so that cells are about cubes.
const CELL_BITS: u32 = 18;

/// Bytes of one stored triangle index triple.
const INDEX_BYTES: u64 = 12;

/// How an object's geometry is placed.
enum Placement {
    /// Each instance goes to the part of its centroid.
    ByInstance,
    /// Each triangle goes to the part of its centroid (one instance).
    ByTriangle { instance: u32 },
}

/// The scene's bounds cut into 2^[`CELL_BITS`] cells, numbered along a
/// Morton curve: each level halves the axis along which cells are then
/// longest, so that a flat world is not cut along its thin axis.
struct CellGrid {
    lo: Vec3,
    extent: Vec3,
    /// Bits per axis.
    bits: [u32; 3],
    /// The axis each level of the code halves, most significant first.
    order: Vec<usize>,
}

impl CellGrid {
    fn new(lo: Vec3, hi: Vec3) -> Self {
        let extent = (hi - lo).max(Vec3::splat(f32::MIN_POSITIVE));
        let mut cell = extent;
        let mut bits = [0u32; 3];
        let mut order = Vec::with_capacity(CELL_BITS as usize);
        for _ in 0..CELL_BITS {
            let axis = cell.max_position();
            cell[axis] *= 0.5;
            bits[axis] += 1;
            order.push(axis);
        }
        CellGrid { lo, extent, bits, order }
    }

    fn cells(&self) -> usize {
        1 << CELL_BITS
    }

    /// The Morton number of the cell holding `p` (clamped into the bounds).
    fn cell_of(&self, p: Vec3) -> usize {
        let q = (p - self.lo) / self.extent;
        let coord: [u32; 3] = std::array::from_fn(|a| {
            let n = 1u32 << self.bits[a];
            ((q[a] * n as f32) as i64).clamp(0, n as i64 - 1) as u32
        });
        let mut left = self.bits;
        let mut code = 0usize;
        for &axis in &self.order {
            left[axis] -= 1;
            code = (code << 1) | ((coord[axis] >> left[axis]) & 1) as usize;
        }
        code
    }
}

/// Splits `scene` into `parts` spatial slabs (compact regions along a
/// Morton curve), each holding about the same bytes under `model`; errors
/// when a part exceeds `options.budget` (or the scene has no geometry).
pub fn partition_spatial(
    scene: &Scene,
    parts: usize,
    model: &ByteModel,
    options: &PartitionOptions,
) -> Result<Partition, PartitionError> {
    partition_interleaved(scene, parts, 1, &[], model, options)
}

/// Splits `scene` into `parts` parts of `chunks_per_part` compact chunks
/// each: the chunks, of about equal bytes under `model`, follow a Morton
/// curve and are dealt out to the parts in turn (chunk `c` to part
/// `c mod parts`). With `work` (points where rays are expected to do their
/// work, e.g. hits of a prepass), chunks hold equal shares of bytes and
/// work together, so that where the work gathers chunks are small and
/// every part gets some. Errors when a part exceeds `options.budget`.
pub fn partition_interleaved(
    scene: &Scene,
    parts: usize,
    chunks_per_part: usize,
    work: &[Vec3],
    model: &ByteModel,
    options: &PartitionOptions,
) -> Result<Partition, PartitionError> {
    if parts == 0 {
        return Err(PartitionError::NoParts(parts));
    }
    let chunks = parts * chunks_per_part.max(1);
    let (lo, hi) = scene.world_bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
    let grid = CellGrid::new(lo, hi);

    let mut instances_of: Vec<Vec<u32>> = vec![Vec::new(); scene.objects.len()];
    for (i, inst) in scene.instances.iter().enumerate() {
        instances_of[inst.object as usize].push(i as u32);
    }
    let object_triangles: Vec<u64> =
        (0..scene.objects.len()).map(|o| scene.object_triangles(o as u32)).collect();
    let total_triangles: u64 =
        instances_of.iter().zip(&object_triangles).filter(|(i, _)| !i.is_empty()).map(|(_, t)| *t).sum();
    // Objects with one instance and more than 1/(4 × chunks) of the
    // triangles are cut by triangles.
    let placements: Vec<Placement> = (0..scene.objects.len())
        .map(|o| match instances_of[o].as_slice() {
            [only] if object_triangles[o] * 4 * chunks as u64 > total_triangles && chunks > 1 => {
                Placement::ByTriangle { instance: *only }
            }
            _ => Placement::ByInstance,
        })
        .collect();
    let triangle_weight = INDEX_BYTES + model.per_triangle;
    let object_weight = |o: usize| object_triangles[o] * triangle_weight + model.per_object;

    // Weighted histogram of item centroids over the cells.
    let mut histogram = vec![0u64; grid.cells()];
    // Once per object, not per instance (millions of them).
    let centres: Vec<Vec3> = (0..scene.objects.len() as ObjectId)
        .into_par_iter()
        .map(|o| scene.object_bounds(o).map_or(Vec3::ZERO, |(lo, hi)| (lo + hi) * 0.5))
        .collect();
    let instance_centre = |i: u32| -> Vec3 {
        let inst = &scene.instances[i as usize];
        inst.object_to_world.transform_point3(centres[inst.object as usize])
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
                    histogram[grid.cell_of(instance_centre(i))] += share;
                }
            }
            Placement::ByTriangle { instance } => {
                let cells = triangle_cells(scene, o as ObjectId, *instance, &grid);
                for (c, n) in cells.into_iter().enumerate() {
                    histogram[c] += n * triangle_weight;
                }
            }
        }
    }
    if !work.is_empty() {
        // Bytes and work in equal measure: each as a share of 2^40.
        let bytes: u64 = histogram.iter().sum::<u64>().max(1);
        let mut hits = vec![0u64; grid.cells()];
        for &p in work {
            hits[grid.cell_of(p)] += 1;
        }
        // Equal measure, not work alone: cut by work only, the chunks where
        // the camera looks are tiny and the rest huge, and the parts' bytes
        // (and, measured, their times: work is not only hits) drift apart.
        let share = |w: u64, total: u64| (((w as u128) << 40) / total as u128) as u64;
        for (h, n) in histogram.iter_mut().zip(hits) {
            *h = share(*h, bytes) + share(n, work.len() as u64);
        }
    }
    // Chunk c takes the cells whose cumulative weight is in [c, c + 1) /
    // chunks of the total; chunks are dealt out to the parts in turn.
    let total: u64 = histogram.iter().sum();
    let mut part_of_cell = vec![0u32; grid.cells()];
    let mut running = 0u64;
    for (c, w) in histogram.iter().enumerate() {
        // The cell goes to the chunk its middle falls in.
        let middle = running + w / 2;
        let chunk = ((middle as u128 * chunks as u128) / total.max(1) as u128).min(chunks as u128 - 1);
        part_of_cell[c] = (chunk % parts as u128) as u32;
        running += w;
    }
    let part_of = |p: Vec3| part_of_cell[grid.cell_of(p)] as usize;

    let mut assigned: Vec<ScenePart> = (0..parts).map(|_| ScenePart::default()).collect();
    for (o, placement) in placements.iter().enumerate() {
        match placement {
            Placement::ByInstance => {
                for &i in &instances_of[o] {
                    assigned[part_of(instance_centre(i))].instances.push(i);
                }
            }
            Placement::ByTriangle { instance } => {
                let runs = triangle_runs(scene, o as ObjectId, *instance, parts, &part_of);
                for (s, ranges) in runs.into_iter().enumerate() {
                    if !ranges.is_empty() {
                        assigned[s].instances.push(*instance);
                        assigned[s].object_subsets.push((o as ObjectId, ranges));
                    }
                }
            }
        }
    }
    for part in &mut assigned {
        part.instances.sort_unstable();
        part.object_subsets.sort_by_key(|s| s.0);
    }
    let partition = Partition::from_parts(scene, assigned, model);
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

/// World-space centroid of every triangle of `object` as placed by
/// `instance`, mesh by mesh, folded per thread with `fold` from `init`.
fn fold_mesh_centroids<A: Send>(
    scene: &Scene,
    object: ObjectId,
    instance: u32,
    init: impl Fn() -> A + Sync + Send,
    fold: impl Fn(A, u32, &mut dyn Iterator<Item = Vec3>) -> A + Sync + Send,
) -> Vec<A> {
    let to_world = scene.instances[instance as usize].object_to_world;
    scene.objects[object as usize]
        .meshes
        .par_iter()
        .fold(&init, |acc, &m| {
            let mesh = &scene.meshes[m as usize];
            let mut centroids = mesh.indices.iter().map(|t| {
                let c = (mesh.positions[t[0] as usize]
                    + mesh.positions[t[1] as usize]
                    + mesh.positions[t[2] as usize])
                    / 3.0;
                to_world.transform_point3(c)
            });
            fold(acc, m, &mut centroids)
        })
        .collect()
}

/// Triangle counts of `object` per grid cell (one histogram per thread,
/// not per mesh: objects may have many meshes).
fn triangle_cells(scene: &Scene, object: ObjectId, instance: u32, grid: &CellGrid) -> Vec<u64> {
    let per_thread = fold_mesh_centroids(
        scene,
        object,
        instance,
        || vec![0u64; grid.cells()],
        |mut cells, _, centroids| {
            for p in centroids {
                cells[grid.cell_of(p)] += 1;
            }
            cells
        },
    );
    per_thread
        .into_iter()
        .reduce(|mut acc, cells| {
            acc.iter_mut().zip(cells).for_each(|(a, b)| *a += b);
            acc
        })
        .unwrap_or_else(|| vec![0u64; grid.cells()])
}

/// Per part, the runs of consecutive triangles of `object` whose centroid
/// falls in it.
fn triangle_runs(
    scene: &Scene,
    object: ObjectId,
    instance: u32,
    parts: usize,
    part_of: &(dyn Fn(Vec3) -> usize + Sync),
) -> Vec<Vec<MeshRange>> {
    let per_thread = fold_mesh_centroids(
        scene,
        object,
        instance,
        Vec::new,
        |mut runs: Vec<(usize, MeshRange)>, mesh, centroids| {
            for (t, p) in centroids.enumerate() {
                let s = part_of(p);
                match runs.last_mut() {
                    // A run continues only within its mesh.
                    Some((part, r)) if t > 0 && *part == s => r.triangles.end = t as u32 + 1,
                    _ => runs.push((s, MeshRange { mesh, triangles: t as u32..t as u32 + 1 })),
                }
            }
            runs
        },
    );
    let mut out = vec![Vec::new(); parts];
    for (s, r) in per_thread.into_iter().flatten() {
        out[s].push(r);
    }
    // Threads fold meshes in any order: sort, so that parts are the same
    // whatever the thread count.
    for ranges in &mut out {
        ranges.sort_by_key(|r| (r.mesh, r.triangles.start));
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

    /// Instances per part whose centre lies in `[lo, hi]`.
    fn instances_within(scene: &Scene, p: &Partition, lo: Vec3, hi: Vec3) -> Vec<usize> {
        p.parts
            .iter()
            .map(|part| {
                part.instances
                    .iter()
                    .filter(|&&i| {
                        let inst = &scene.instances[i as usize];
                        let (a, b) = scene.object_bounds(inst.object).unwrap();
                        let c = inst.object_to_world.transform_point3((a + b) * 0.5);
                        c.cmpge(lo).all() && c.cmple(hi).all()
                    })
                    .count()
            })
            .collect()
    }

    #[test]
    fn interleaved_chunks_cover_everything_once_and_share_out_the_work() {
        let scene = atoll_scene::procedural::bench_scene(20_000);
        let model = ByteModel::CPU;
        let none = PartitionOptions::default();
        for (k, chunks) in [(2, 2), (3, 4)] {
            let p = partition_interleaved(&scene, k, chunks, &[], &model, &none).unwrap();
            assert_eq!(p.parts.len(), k);
            assert_exactly_once(&scene, &p);
            let (min, max) = (p.bytes.iter().min().unwrap(), p.bytes.iter().max().unwrap());
            assert!(*max < 2 * *min, "{:?}", p.bytes);
        }
        // All the work in one corner (a fifth of the landscape's side each
        // way): bytes alone give the corner to one part; with the work, its
        // chunks are small and both parts get instances there.
        let scene = atoll_scene::landscape::Landscape::new(1).build();
        let (lo, hi) = scene.world_bounds().unwrap();
        let corner = Vec3::new(lo.x + (hi.x - lo.x) * 0.2, hi.y, lo.z + (hi.z - lo.z) * 0.2);
        let work: Vec<Vec3> = (0..1000)
            .map(|i| lo + (corner - lo) * Vec3::new((i % 32) as f32 / 32.0, 0.5, (i / 32) as f32 / 32.0))
            .collect();
        let slabs = partition_interleaved(&scene, 2, 1, &[], &model, &none).unwrap();
        let near = instances_within(&scene, &slabs, lo, corner);
        assert!(near.iter().sum::<usize>() > 20, "{near:?}");
        assert_eq!(near.iter().filter(|&&n| n > 0).count(), 1, "{near:?}");
        let balanced = partition_interleaved(&scene, 2, 2, &work, &model, &none).unwrap();
        let near = instances_within(&scene, &balanced, lo, corner);
        assert!(near.iter().all(|&n| n > 0), "{near:?}");
    }

    #[test]
    fn a_budget_the_slabs_exceed_is_an_error_and_results_are_deterministic() {
        let scene = atoll_scene::procedural::bench_scene(20_000);
        let model = ByteModel::CPU;
        let a = partition_spatial(&scene, 2, &model, &PartitionOptions::default()).unwrap();
        let b = partition_spatial(&scene, 2, &model, &PartitionOptions::default()).unwrap();
        assert_eq!(a, b);
        let tight =
            PartitionOptions { budget: Some(a.bytes.iter().max().unwrap() - 1), ..Default::default() };
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
