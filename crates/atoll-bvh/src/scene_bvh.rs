//! The two-level BVH over a scene: one bottom-level BVH (BLAS) per object in
//! object space, one top-level BVH (TLAS) over the instances in world space.

use std::ops::Range;
use std::time::Instant;

use atoll_scene::{CurveKind, CurvePiece, MeshId, ObjectId, Scene};
use glam::{Affine3A, Vec3A};
use rayon::prelude::*;

use crate::curve::intersect_curve;
use crate::{
    Aabb, BuildOptions, Bvh2, Bvh4Cpu, BvhLayout, BvhStats, Hit, Ray, Ray4, TraversalRay, Tri4, TriAccel,
};

/// Some triangles of one mesh.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MeshRange {
    /// Index into `scene.meshes`.
    pub mesh: MeshId,
    /// Triangle indices within the mesh.
    pub triangles: Range<u32>,
}

/// The subset of a scene a BVH is built over: the unit a distribution
/// strategy hands to one device.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ScenePart {
    /// Indices into `scene.instances` to include.
    pub instances: Vec<u32>,
    /// Objects included only in part, with the triangle ranges to keep (of
    /// the object's own meshes; meshes not listed are left out), for every
    /// instance of the object in the part. Unlisted objects are included whole.
    pub object_subsets: Vec<(ObjectId, Vec<MeshRange>)>,
}

impl ScenePart {
    /// Every instance of the scene, every triangle.
    pub fn whole(scene: &Scene) -> Self {
        ScenePart { instances: (0..scene.instances.len() as u32).collect(), object_subsets: Vec::new() }
    }

    /// The triangles of `object` this part includes.
    pub fn object_ranges(&self, scene: &Scene, object: ObjectId) -> Vec<MeshRange> {
        if let Some((_, ranges)) = self.object_subsets.iter().find(|(o, _)| *o == object) {
            return ranges.clone();
        }
        let meshes = &scene.objects[object as usize].meshes;
        meshes
            .iter()
            .map(|&mesh| MeshRange { mesh, triangles: 0..scene.meshes[mesh as usize].indices.len() as u32 })
            .collect()
    }
}

/// Sizes and build times of both levels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SceneBvhStats {
    /// The instance level.
    pub tlas: BvhStats,
    /// All BLASes together: counts, bytes and build times summed (BLASes
    /// build concurrently, so the summed `build_ms` may exceed the wall
    /// time), depth the deepest, SAH cost the mean weighted by triangle count.
    pub blas: BvhStats,
    /// Objects with a BLAS (those with triangles in the part).
    pub blas_count: usize,
    /// Instances in the TLAS.
    pub instances: usize,
    /// Triangles stored in the BLASes (each once).
    pub triangles: u64,
    /// Triangles as rays see them (each instance counts its object's).
    pub instanced_triangles: u64,
    /// Both levels: nodes, triangle data, instance records.
    pub bytes: usize,
    /// Wall-clock time of the whole build.
    pub build_ms: f64,
}

/// Decides which candidate hits count: alpha masks that cut holes into
/// surfaces. Traversal asks only for meshes where [`HitFilter::filters`]
/// says so (the renderer's texture programs implement it).
pub trait HitFilter {
    /// Whether hits on scene mesh `mesh` need [`HitFilter::keeps`].
    fn filters(&self, mesh: MeshId) -> bool;
    /// Whether the hit of triangle `triangle` of `mesh` at barycentrics
    /// `(u, v)` and distance `t` counts; `origin` and `dir` are the ray in
    /// the triangle's (object) space.
    #[allow(clippy::too_many_arguments)]
    fn keeps(&self, mesh: MeshId, triangle: u32, u: f32, v: f32, t: f32, origin: Vec3A, dir: Vec3A) -> bool;
}

/// Every hit counts.
pub struct NoFilter;

impl HitFilter for NoFilter {
    fn filters(&self, _: MeshId) -> bool {
        false
    }
    fn keeps(&self, _: MeshId, _: u32, _: f32, _: f32, _: f32, _: Vec3A, _: Vec3A) -> bool {
        true
    }
}

/// What a traversal reads, told as it reads it: a shared scene's access
/// counters map each read to the chunk holding it. Indices are those of
/// [`SceneBvh::memory_tables`]' arrays.
pub trait Visits: Sync {
    /// Node `node` of the instance level.
    fn tlas_node(&self, node: u32);
    /// The instance record of TLAS leaf `leaf`.
    fn instance(&self, leaf: u32);
    /// Node `node` of BLAS `blas`.
    fn blas_node(&self, blas: u32, node: u32);
    /// Triangle block `block` of BLAS `blas` (one [`Tri4`] test).
    fn triangles(&self, blas: u32, block: u32);
    /// The triangle id in slot `prim` of BLAS `blas` (read for a hit).
    fn prim(&self, blas: u32, prim: u32);
    /// The curve piece in slot `prim` of BLAS `blas` (read to test it).
    fn curve(&self, blas: u32, prim: u32);
}

/// Reads go untold: plain traversal.
pub struct NoVisits;

impl Visits for NoVisits {
    #[inline(always)]
    fn tlas_node(&self, _: u32) {}
    #[inline(always)]
    fn instance(&self, _: u32) {}
    #[inline(always)]
    fn blas_node(&self, _: u32, _: u32) {}
    #[inline(always)]
    fn triangles(&self, _: u32, _: u32) {}
    #[inline(always)]
    fn prim(&self, _: u32, _: u32) {}
    #[inline(always)]
    fn curve(&self, _: u32, _: u32) {}
}

/// One array traversal reads ([`SceneBvh::memory_tables`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryTable {
    /// What it holds (`tlas nodes`, `blas 3 triangles`, …).
    pub name: String,
    /// Bytes of the whole array.
    pub bytes: u64,
    /// Bytes per element: element `i` starts at `i * element_bytes`.
    pub element_bytes: u64,
}

/// Which triangle a leaf position holds (8 bytes); padding slots hold `u32::MAX`s.
#[derive(Clone, Copy, Debug)]
struct PrimId {
    mesh: MeshId,
    triangle: u32,
}

/// One object's triangles with their BVH; leaves are runs of whole
/// [`Tri4`] blocks, and `prims` names the triangle in each block lane.
struct Blas<L> {
    bvh: L,
    tris: Vec<Tri4>,
    prims: Vec<PrimId>,
    /// Some of its meshes have alpha masks: candidate hits go through the
    /// [`HitFilter`] (the others take the unfiltered fast path).
    filtered: bool,
    /// Per primitive slot, the curve piece it holds (its [`Tri4`] lane is
    /// then degenerate and never hits); empty where the BLAS has no curves.
    curves: Vec<Option<(CurveKind, CurvePiece)>>,
    stats: BvhStats,
}

impl<L: BvhLayout> Blas<L> {
    /// `None` when the ranges hold no triangle.
    fn build(scene: &Scene, ranges: &[MeshRange]) -> Option<Self> {
        let start = Instant::now();
        let prims: Vec<PrimId> = ranges
            .iter()
            .flat_map(|r| r.triangles.clone().map(|triangle| PrimId { mesh: r.mesh, triangle }))
            .collect();
        if prims.is_empty() {
            return None;
        }
        let corners = |p: &PrimId| scene.meshes[p.mesh as usize].triangle(p.triangle as usize);
        let boxes: Vec<Aabb> = prims.par_iter().map(|p| Aabb::from_points(corners(p))).collect();
        let options = BuildOptions::TRIANGLES;
        let mut bvh2 = Bvh2::build(&boxes, &options);
        atoll_scene::progress::built(boxes.len() as u64);
        bvh2.align_leaves(Tri4::LANES as u32);
        let padding = PrimId { mesh: u32::MAX, triangle: u32::MAX };
        let prims: Vec<PrimId> = bvh2
            .prim_order
            .par_iter()
            .map(|&i| if i == u32::MAX { padding } else { prims[i as usize] })
            .collect();
        let curve_of = |p: &PrimId| {
            let curves = scene.meshes.get(p.mesh as usize)?.curves.as_ref()?;
            Some((curves.kind, curves.pieces[p.triangle as usize]))
        };
        let has_curves = ranges.iter().any(|r| scene.meshes[r.mesh as usize].curves.is_some());
        let curves: Vec<Option<(CurveKind, CurvePiece)>> =
            if has_curves { prims.par_iter().map(curve_of).collect() } else { Vec::new() };
        let tris: Vec<Tri4> = prims
            .par_chunks(Tri4::LANES)
            .map(|block| {
                // Padding only ever follows a leaf's triangles.
                let lanes = block.iter().take_while(|p| p.mesh != u32::MAX).count();
                let mut tris = [TriAccel::default(); Tri4::LANES];
                for (tri, p) in tris.iter_mut().zip(&block[..lanes]) {
                    // A curve's lane stays degenerate: its piece is tested instead.
                    if !has_curves || curve_of(p).is_none() {
                        *tri = TriAccel::new(corners(p));
                    }
                }
                Tri4::new(&tris[..lanes])
            })
            .collect();
        let bvh = L::from_bvh2(bvh2);
        let mut stats = bvh.stats(&BuildOptions::METRIC);
        stats.bytes += std::mem::size_of_val(&tris[..])
            + std::mem::size_of_val(&prims[..])
            + std::mem::size_of_val(&curves[..]);
        stats.build_ms = start.elapsed().as_secs_f64() * 1e3;
        let filtered = ranges.iter().any(|r| scene.filters_hits(r.mesh));
        Some(Blas { bvh, tris, prims, filtered, curves, stats })
    }

    /// Triangles stored (padding excluded).
    fn triangles(&self) -> u64 {
        self.prims.iter().filter(|p| p.mesh != u32::MAX).count() as u64
    }
}

/// A TLAS leaf: an instance with its world-to-object transform (80 bytes).
#[derive(Clone, Copy, Debug)]
struct TlasInstance {
    world_to_object: Affine3A,
    /// Skips transforming rays (the world object's instance is the identity).
    identity: bool,
    blas: u32,
    /// Index into `scene.instances`.
    instance: u32,
    /// A moving instance's index into [`SceneBvh::motions`]: its
    /// transform is made for each ray's time instead.
    motion: Option<u32>,
}

/// Two-level BVH over a scene or a part of one. `L` is the node layout of
/// both levels. The default, [`Bvh4Cpu`], measured faster than [`Bvh2`] for
/// primary, shadow and diffuse rays on the benchmark landscape (see
/// [`crate::bench`] and BENCHMARKS.md).
pub struct SceneBvh<L: BvhLayout = Bvh4Cpu> {
    tlas: L,
    /// In TLAS leaf order.
    instances: Vec<TlasInstance>,
    blases: Vec<Blas<L>>,
    /// The scene's motions, which moving instances index.
    motions: Vec<atoll_scene::Motion>,
    stats: SceneBvhStats,
}

/// The closest (or any) hit as traversal finds it: `(t, TLAS leaf, BLAS
/// primitive slot, u, v)`; `occluded` fills in only the leaf and slot.
type RawHit = (f32, u32, u32, f32, f32);

/// The constructors with the default layout (in their own `impl`, because a
/// default type parameter does not guide type inference: `SceneBvh::build`
/// would otherwise need the layout spelt out).
impl SceneBvh {
    /// Builds over the whole scene. Objects without triangles, and their
    /// instances, are left out.
    pub fn build(scene: &Scene) -> Self {
        Self::build_layout(scene, &ScenePart::whole(scene))
    }

    /// Builds over a part of the scene; hits still report scene-wide
    /// instance, mesh and triangle indices.
    pub fn build_part(scene: &Scene, part: &ScenePart) -> Self {
        Self::build_layout(scene, part)
    }
}

impl<L: BvhLayout> SceneBvh<L> {
    /// [`SceneBvh::build_part`] for any layout: `SceneBvh::<Bvh2>::build_layout(..)`.
    pub fn build_layout(scene: &Scene, part: &ScenePart) -> Self {
        let start = Instant::now();
        let mut objects: Vec<ObjectId> =
            part.instances.iter().map(|&i| scene.instances[i as usize].object).collect();
        objects.sort_unstable();
        objects.dedup();
        // All BLASes at once; each build is parallel inside as well.
        let built: Vec<Option<Blas<L>>> =
            objects.par_iter().map(|&o| Blas::build(scene, &part.object_ranges(scene, o))).collect();
        let mut blas_of = vec![u32::MAX; scene.objects.len()];
        let mut blases = Vec::new();
        for (&o, blas) in objects.iter().zip(built) {
            if let Some(blas) = blas {
                blas_of[o as usize] = blases.len() as u32;
                blases.push(blas);
            }
        }
        // Singular transforms flatten an object to nothing: leave those out too.
        let entries: Vec<(TlasInstance, Aabb)> = part
            .instances
            .iter()
            .filter_map(|&i| {
                let inst = &scene.instances[i as usize];
                let blas = blas_of[inst.object as usize];
                let world_to_object = inst.object_to_world.inverse();
                (blas != u32::MAX && world_to_object.is_finite()).then(|| {
                    let object = blases[blas as usize].bvh.bounds();
                    let bounds = match inst.motion {
                        Some(_) => {
                            let (lo, hi) = scene.instance_box(inst, object.min.into(), object.max.into());
                            Aabb { min: lo.into(), max: hi.into() }
                        }
                        None => object.transformed(&inst.object_to_world),
                    };
                    let identity = inst.object_to_world == Affine3A::IDENTITY && inst.motion.is_none();
                    let motion = inst.motion;
                    (TlasInstance { world_to_object, identity, blas, instance: i, motion }, bounds)
                })
            })
            .collect();
        let boxes: Vec<Aabb> = entries.iter().map(|e| e.1).collect();
        let tlas2 = Bvh2::build(&boxes, &BuildOptions::INSTANCES);
        let tlas_ms = tlas2.build_ms;
        let instances: Vec<TlasInstance> = tlas2.prim_order.iter().map(|&i| entries[i as usize].0).collect();
        let tlas = L::from_bvh2(tlas2);

        let mut stats = SceneBvhStats {
            tlas: BvhStats { build_ms: tlas_ms, ..tlas.stats(&BuildOptions::METRIC) },
            blas_count: blases.len(),
            instances: instances.len(),
            ..Default::default()
        };
        stats.tlas.bytes += std::mem::size_of_val(&instances[..]);
        let mut weighted_sah = 0.0;
        let triangles: Vec<u64> = blases.iter().map(Blas::triangles).collect();
        for (b, &tris) in blases.iter().zip(&triangles) {
            let s = &b.stats;
            stats.blas.nodes += s.nodes;
            stats.blas.leaves += s.leaves;
            stats.blas.max_depth = stats.blas.max_depth.max(s.max_depth);
            stats.blas.bytes += s.bytes;
            stats.blas.build_ms += s.build_ms;
            stats.triangles += tris;
            weighted_sah += s.sah_cost as f64 * tris as f64;
        }
        stats.blas.sah_cost = (weighted_sah / stats.triangles.max(1) as f64) as f32;
        stats.instanced_triangles = instances.iter().map(|i| triangles[i.blas as usize]).sum();
        stats.bytes = stats.tlas.bytes + stats.blas.bytes;
        stats.build_ms = start.elapsed().as_secs_f64() * 1e3;
        SceneBvh { tlas, instances, blases, motions: scene.motions.clone(), stats }
    }

    /// The closest hit with `0 < t < ray.t_max`, ignoring alpha masks.
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.intersect_filtered(ray, &NoFilter)
    }

    /// Whether anything is hit with `0 < t < ray.t_max`, ignoring alpha masks.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.occluded_filtered(ray, &NoFilter)
    }

    /// The closest hit with `0 < t < ray.t_max` that `filter` keeps.
    pub fn intersect_filtered(&self, ray: &Ray, filter: &impl HitFilter) -> Option<Hit> {
        self.intersect_visiting(ray, filter, &NoVisits)
    }

    /// Whether anything `filter` keeps is hit with `0 < t < ray.t_max`.
    pub fn occluded_filtered(&self, ray: &Ray, filter: &impl HitFilter) -> bool {
        self.occluded_visiting(ray, filter, &NoVisits)
    }

    /// [`SceneBvh::intersect_filtered`], telling `visits` what it reads.
    pub fn intersect_visiting(
        &self,
        ray: &Ray,
        filter: &impl HitFilter,
        visits: &impl Visits,
    ) -> Option<Hit> {
        let (t, leaf, prim, u, v) = self.trace::<false>(ray, filter, visits)?;
        let inst = &self.instances[leaf as usize];
        visits.prim(inst.blas, prim);
        let id = self.blases[inst.blas as usize].prims[prim as usize];
        Some(Hit { t, u, v, instance: inst.instance, mesh: id.mesh, triangle: id.triangle })
    }

    /// [`SceneBvh::occluded_filtered`], telling `visits` what it reads.
    pub fn occluded_visiting(&self, ray: &Ray, filter: &impl HitFilter, visits: &impl Visits) -> bool {
        self.trace::<true>(ray, filter, visits).is_some()
    }

    /// The arrays traversal reads, in this order: `tlas nodes`, `tlas
    /// instances`, then per BLAS `b` (in [`Visits`]' numbering) `blas b
    /// nodes`, `blas b triangles`, `blas b prims`, `blas b curves` (empty
    /// without curves): table `2 + 4b + k`.
    pub fn memory_tables(&self) -> Vec<MemoryTable> {
        let table = |name: String, count: usize, element: usize| MemoryTable {
            name,
            bytes: (count * element) as u64,
            element_bytes: element as u64,
        };
        let mut tables = vec![
            table("tlas nodes".into(), self.tlas.stats(&BuildOptions::METRIC).nodes, L::NODE_BYTES),
            table("tlas instances".into(), self.instances.len(), std::mem::size_of::<TlasInstance>()),
        ];
        for (b, blas) in self.blases.iter().enumerate() {
            tables.push(table(
                format!("blas {b} nodes"),
                blas.bvh.stats(&BuildOptions::METRIC).nodes,
                L::NODE_BYTES,
            ));
            tables.push(table(format!("blas {b} triangles"), blas.tris.len(), std::mem::size_of::<Tri4>()));
            tables.push(table(format!("blas {b} prims"), blas.prims.len(), std::mem::size_of::<PrimId>()));
            let curve_bytes = std::mem::size_of_val(blas.curves.first().unwrap_or(&None));
            tables.push(table(format!("blas {b} curves"), blas.curves.len(), curve_bytes));
        }
        tables
    }

    /// Sizes, quality and build times.
    pub fn stats(&self) -> SceneBvhStats {
        self.stats
    }

    /// Both queries in one: with `ANY`, the first hit found ends the search.
    #[inline]
    fn trace<const ANY: bool>(
        &self,
        ray: &Ray,
        filter: &impl HitFilter,
        visits: &impl Visits,
    ) -> Option<RawHit> {
        let world = TraversalRay::new(ray.origin.into(), ray.direction.into());
        let mut t_max = ray.t_max;
        let mut best: Option<RawHit> = None;
        let mut visit = |leaf: u32, t_max: &mut f32| {
            let inst = &self.instances[leaf as usize];
            visits.instance(leaf);
            let b = inst.blas;
            let blas = &self.blases[b as usize];
            let node = |n: u32| visits.blas_node(b, n);
            // Not normalised: t stays the same in both spaces.
            let moved;
            let m = match inst.motion {
                Some(k) => {
                    moved = self.motions[k as usize].at(ray.time).inverse();
                    &moved
                }
                None => &inst.world_to_object,
            };
            let ray = if inst.identity {
                world
            } else {
                TraversalRay::new(m.transform_point3a(world.origin), m.transform_vector3a(world.dir))
            };
            let ray4 = Ray4::new(ray.origin, ray.dir);
            let lanes = Tri4::LANES as u32;
            if blas.filtered || !blas.curves.is_empty() {
                // Alpha-masked meshes and curves: every candidate lane goes
                // through the filter, curve lanes through the curve test,
                // and the nearest kept hit wins. A traversal of its own, so
                // the plain leaf loop below stays as lean as before.
                return blas.bvh.traverse_visiting::<ANY>(&ray, t_max, node, |first, count, t_max| {
                    let mut hit = false;
                    for block in first / lanes..(first + count).div_ceil(lanes) {
                        visits.triangles(b, block);
                        for prim in block * lanes..(block + 1) * lanes {
                            let Some(Some((kind, piece))) = blas.curves.get(prim as usize) else { continue };
                            visits.curve(b, prim);
                            let Some((t, u, v)) =
                                intersect_curve::<ANY>(*kind, piece, ray.origin, ray.dir, *t_max)
                            else {
                                continue;
                            };
                            best = Some((t, leaf, prim, u, v));
                            hit = true;
                            if ANY {
                                return true;
                            }
                            *t_max = t;
                        }
                        let (mut mask, t, u, v) = blas.tris[block as usize].test(&ray4, *t_max);
                        while mask != 0 {
                            let lane = mask.trailing_zeros() as usize;
                            mask &= mask - 1;
                            let prim = block * lanes + lane as u32;
                            visits.prim(b, prim);
                            let id = blas.prims[prim as usize];
                            let cut = filter.filters(id.mesh)
                                && !filter.keeps(
                                    id.mesh,
                                    id.triangle,
                                    u[lane],
                                    v[lane],
                                    t[lane],
                                    ray.origin,
                                    ray.dir,
                                );
                            if t[lane] >= *t_max || cut {
                                continue;
                            }
                            best = Some((t[lane], leaf, prim, u[lane], v[lane]));
                            hit = true;
                            if ANY {
                                return true;
                            }
                            *t_max = t[lane];
                        }
                    }
                    hit
                });
            }
            blas.bvh.traverse_visiting::<ANY>(&ray, t_max, node, |first, count, t_max| {
                let mut hit = false;
                for block in first / lanes..(first + count).div_ceil(lanes) {
                    visits.triangles(b, block);
                    let tris = &blas.tris[block as usize];
                    if ANY {
                        let mask = tris.test(&ray4, *t_max).0;
                        if mask != 0 {
                            best = Some((0.0, leaf, block * lanes + mask.trailing_zeros(), 0.0, 0.0));
                            return true;
                        }
                    } else if let Some((lane, t, u, v)) = tris.intersect(&ray4, *t_max) {
                        *t_max = t;
                        best = Some((t, leaf, block * lanes + lane as u32, u, v));
                        hit = true;
                    }
                }
                hit
            })
        };
        if self.instances.len() == 1 {
            // One instance (a scene without instancing): its BLAS root box
            // culls as well as the TLAS would.
            visit(0, &mut t_max);
        } else {
            let node = |n: u32| visits.tlas_node(n);
            self.tlas.traverse_visiting::<ANY>(&world, &mut t_max, node, |first, count, t_max| {
                let mut hit = false;
                for leaf in first..first + count {
                    hit |= visit(leaf, t_max);
                    if ANY && hit {
                        break;
                    }
                }
                hit
            });
        }
        best
    }
}
