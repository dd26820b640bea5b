//! Splitting a scene into K parts for the ring strategy (ray queue cycling,
//! Wald, Jaroš, Zellmann 2023, section 4.1), and choosing between
//! replicating and ringing for N devices.
//!
//! Every ray visits every device of its ring, so which triangles land
//! together barely matters for correctness or much for speed; what matters
//! is memory: the parts are balanced by a byte estimate ([`ByteModel`]) so
//! that the largest part, which decides whether K devices suffice, is as
//! small as it can be made cheaply.
//!
//! - Units are objects with all their instances: geometry shared by
//!   instances is held once per part.
//! - A unit above the split threshold is split: by instance groups when its
//!   instances outweigh its geometry, else by meshes and, where one mesh is
//!   still too big, by triangle ranges. One "ground object" then no longer
//!   dictates the smallest device that can hold a part.
//! - Pieces go heaviest first to the part they leave least loaded (the
//!   paper's least-loaded device, counting what the part already holds:
//!   another piece of a mesh there does not pay for its vertices again),
//!   skipping parts the piece would take over the budget. Ties go to the
//!   lowest part, so the heaviest piece (a landscape's ground) is on part
//!   0, where [`crate::RingOrder::Home`] traces every ray first.
//!
//! Triangle ranges follow the mesh's index order, which for grid-like
//! meshes (terrains) is already spatially coherent. No further spatial
//! ordering is attempted: nothing here has measured it to pay.

use std::fmt;
use std::str::FromStr;

use atoll_bvh::{part_bytes, ByteModel, MeshRange, ScenePart};
use atoll_scene::{MeshId, ObjectId, Scene};

/// How to partition.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PartitionOptions {
    /// Bytes one device may hold; `None` for no limit.
    pub budget: Option<u64>,
    /// Units heavier than this are split into pieces of about this weight.
    /// Default: the scene's weight / (2 K), and never above the budget.
    pub split_threshold: Option<u64>,
    /// Balance parts by ray work rather than bytes alone: a part's load is
    /// its bytes plus this many per instance it holds (0: bytes only, the
    /// memory-balanced partition). See [`GPU_INSTANCE_COST`].
    pub instance_cost: u64,
}

/// What a part's instances cost a GPU's rays, in bytes of part per
/// instance: a part's ray work measured as its bytes plus this per
/// instance, fitted to each part's busy time in memory-balanced rings on
/// the landscape at two sizes (`scripts/gpu-multi SERIAL=1`; the fit is in
/// BENCHMARKS.md). Instances cost beyond their bytes because
/// every ray walks the top-level BVH over them, dense and overlapping, and
/// descends into each one it enters.
///
/// Balancing by it spreads instanced objects over the parts, which costs
/// every ray more walks in total but stops one part holding all of them:
/// rings of 4 measured much faster for it, rings of 2 no better than bytes
/// alone (BENCHMARKS.md).
pub const GPU_INSTANCE_COST: u64 = 9 << 10;

/// A scene split into parts, one per device of a ring.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Partition {
    /// The parts; some may be empty when the scene has fewer pieces than parts.
    pub parts: Vec<ScenePart>,
    /// [`part_bytes`] of each part under the model it was made with.
    pub bytes: Vec<u64>,
    /// Per scene instance, the parts that include it (ascending).
    instance_parts: Vec<Vec<u32>>,
    /// Per scene instance, its object.
    instance_object: Vec<ObjectId>,
    /// Per object, its meshes with their triangle counts (for whole objects).
    object_meshes: Vec<Vec<(MeshId, u32)>>,
}

impl Partition {
    /// The part holding triangle `triangle` of mesh `mesh` as seen through
    /// instance `instance` (scene-wide indices, as in a hit), or `None`
    /// when no part holds it (an index out of range, a mesh not in the
    /// instance's object). For false-colour views and tests.
    pub fn owner(&self, instance: u32, mesh: MeshId, triangle: u32) -> Option<usize> {
        let object = *self.instance_object.get(instance as usize)?;
        let holds = |r: &MeshRange| r.mesh == mesh && r.triangles.contains(&triangle);
        self.instance_parts[instance as usize].iter().map(|&p| p as usize).find(|&p| {
            let subsets = &self.parts[p].object_subsets;
            match subsets.binary_search_by_key(&object, |s| s.0) {
                Ok(i) => subsets[i].1.iter().any(holds),
                Err(_) => self.object_meshes[object as usize].iter().any(|&(m, n)| m == mesh && triangle < n),
            }
        })
    }
}

/// Why a scene could not be partitioned or planned.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PartitionError {
    /// Zero parts or zero devices.
    #[error("cannot partition over {0} parts or devices")]
    NoParts(usize),
    /// Measuring the frame's work (a low-resolution render) failed.
    #[error("measuring the frame's ray work: {0}")]
    Measure(String),
    /// A piece that cannot be split further needs more than a device holds.
    #[error("{what} needs {}, more than the budget of {} per device", Bytes(*.needed), Bytes(*.budget))]
    PieceTooBig {
        /// The piece, in words.
        what: String,
        /// Its bytes.
        needed: u64,
        /// The per-device budget.
        budget: u64,
    },
    /// The parts cannot hold the scene within the budget.
    #[error(
        "{parts} parts of at most {} cannot hold the scene ({} in all): a piece of {} fits in no part \
         (the least loaded holds {} already)",
        Bytes(*.budget), Bytes(*.total), Bytes(*.piece), Bytes(*.least_loaded)
    )]
    DoesNotFit {
        /// Parts asked for.
        parts: usize,
        /// The per-device budget.
        budget: u64,
        /// The scene's weight (its pieces summed).
        total: u64,
        /// The piece that found no room.
        piece: u64,
        /// Bytes of the least-loaded part when it did not fit.
        least_loaded: u64,
    },
    /// Even `devices` devices of `budget` bytes cannot hold the scene.
    #[error(
        "the scene ({}) does not fit {devices} devices of {} each, however partitioned; \
         more devices or a larger budget are needed",
        Bytes(*.total), Bytes(*.budget)
    )]
    TooFewDevices {
        /// Devices available.
        devices: usize,
        /// The per-device budget.
        budget: u64,
        /// The whole scene's bytes on one device.
        total: u64,
    },
    /// Replication forced, but the scene does not fit one device.
    #[error("cannot replicate: the scene needs {} per device, the budget is {}", Bytes(*.needed), Bytes(*.budget))]
    ReplicaTooBig {
        /// The whole scene's bytes.
        needed: u64,
        /// The per-device budget.
        budget: u64,
    },
}

/// Byte counts in messages: binary units for reading, the exact count for checking.
struct Bytes(u64);

impl fmt::Display for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const UNITS: [&str; 4] = ["KiB", "MiB", "GiB", "TiB"];
        let mut value = self.0 as f64;
        let mut unit = None;
        for u in UNITS {
            if value < 1024.0 {
                break;
            }
            value /= 1024.0;
            unit = Some(u);
        }
        match unit {
            Some(u) => write!(f, "{value:.1} {u} ({} bytes)", self.0),
            None => write!(f, "{} bytes", self.0),
        }
    }
}

/// One piece of a unit: what the greedy placement moves around.
#[derive(Clone, Debug)]
struct Piece {
    object: ObjectId,
    /// Scene instances that come with it.
    instances: Vec<u32>,
    /// `None`: the object's whole geometry; else the triangle ranges it keeps.
    ranges: Option<Vec<MeshRange>>,
    /// Bytes on a device of its own.
    weight: u64,
}

/// Costs of geometry pieces, mirroring [`part_bytes`] so that the greedy
/// loads match what the parts will measure.
struct Costs<'a> {
    scene: &'a Scene,
    model: &'a ByteModel,
}

impl Costs<'_> {
    /// Vertex arrays of a mesh, held once per part whatever share of its triangles.
    fn vertices(&self, mesh: MeshId) -> u64 {
        let m = &self.scene.meshes[mesh as usize];
        (m.positions.len() * 12 + m.normals.len() * 12 + m.uvs.len() * 8) as u64
            + m.positions.len() as u64 * self.model.per_vertex
    }

    /// Index entry, BVH share and build scratch of one triangle.
    fn per_triangle(&self) -> u64 {
        12 + self.model.per_triangle + self.model.scratch_per_triangle
    }

    /// The whole object's triangles as ranges (each mesh once).
    fn whole(&self, object: ObjectId) -> Vec<MeshRange> {
        let mut seen = Vec::new();
        let mut ranges = Vec::new();
        for &mesh in &self.scene.objects[object as usize].meshes {
            if !seen.contains(&mesh) {
                seen.push(mesh);
                let n = self.scene.meshes[mesh as usize].indices.len() as u32;
                ranges.push(MeshRange { mesh, triangles: 0..n });
            }
        }
        ranges
    }

    /// Bytes of `ranges` of one object with `instances` instances, alone on a device.
    fn piece(&self, ranges: &[MeshRange], instances: usize) -> u64 {
        let tris: u64 = ranges.iter().map(|r| r.triangles.len() as u64).sum();
        if tris == 0 {
            return 0;
        }
        let mut meshes: Vec<MeshId> =
            ranges.iter().filter(|r| !r.triangles.is_empty()).map(|r| r.mesh).collect();
        meshes.sort_unstable();
        meshes.dedup();
        meshes.iter().map(|&m| self.vertices(m)).sum::<u64>()
            + tris * self.per_triangle()
            + self.model.per_object
            + instances as u64 * self.model.per_instance
    }
}

/// What one part holds so far, to price a further piece by what it adds.
/// Indexed by mesh and object, so a scene of many small objects costs
/// O(pieces × K), not a search through what each part holds.
struct Load {
    bytes: u64,
    /// Scene instances the part holds (each object's once).
    instances: u64,
    /// Per mesh, whether the part holds its vertices.
    meshes: Vec<bool>,
    /// Per object, its triangles in the part (`None`: not in the part).
    objects: Vec<Option<u64>>,
    /// The most triangles of one object (its build scratch is the peak).
    largest: u64,
}

impl Load {
    fn new(scene: &Scene) -> Self {
        Load {
            // Every part holds all texture images and media (see `part_bytes`).
            bytes: scene.replicated_bytes(),
            instances: 0,
            meshes: vec![false; scene.meshes.len()],
            objects: vec![None; scene.objects.len()],
            largest: 0,
        }
    }

    /// Bytes `piece` would add.
    fn added(&self, costs: &Costs, piece: &Piece, ranges: &[MeshRange]) -> u64 {
        let tris: u64 = ranges.iter().map(|r| r.triangles.len() as u64).sum();
        if tris == 0 {
            return 0;
        }
        let m = costs.model;
        let mut meshes: Vec<MeshId> =
            ranges.iter().filter(|r| !r.triangles.is_empty()).map(|r| r.mesh).collect();
        meshes.sort_unstable();
        meshes.dedup();
        let vertices: u64 =
            meshes.iter().filter(|&&x| !self.meshes[x as usize]).map(|&x| costs.vertices(x)).sum();
        let before = self.objects[piece.object as usize];
        let group = piece.instances.len() as u64 * m.per_instance;
        let (instances, object, after) = match (&piece.ranges, before) {
            // Another instance group of an object already here: its BLAS
            // and geometry are shared, only the instances are new.
            (None, Some(_)) => return group,
            (None, None) => (group, m.per_object, tris),
            // A further geometry piece: its instances (all of the object's)
            // and its BLAS are here already; the BLAS grows.
            (Some(_), Some(held)) => (0, 0, held + tris),
            (Some(_), None) => (group, m.per_object, tris),
        };
        let scratch = after.saturating_sub(self.largest) * m.scratch_per_triangle;
        vertices + tris * (12 + m.per_triangle) + object + instances + scratch
    }

    /// Instances `piece` would add: none for a further geometry piece of
    /// an object already here (it carries the same instances).
    fn added_instances(&self, piece: &Piece) -> u64 {
        match (&piece.ranges, self.objects[piece.object as usize]) {
            (Some(_), Some(_)) => 0,
            _ => piece.instances.len() as u64,
        }
    }

    fn add(&mut self, costs: &Costs, piece: &Piece, ranges: &[MeshRange]) {
        self.bytes += self.added(costs, piece, ranges);
        self.instances += self.added_instances(piece);
        for r in ranges.iter().filter(|r| !r.triangles.is_empty()) {
            self.meshes[r.mesh as usize] = true;
        }
        let tris: u64 = ranges.iter().map(|r| r.triangles.len() as u64).sum();
        let held = &mut self.objects[piece.object as usize];
        // Only geometry pieces of one object meet in a part, or instance
        // groups of the whole object (which share one BLAS).
        *held = Some(match (*held, &piece.ranges) {
            (Some(h), Some(_)) => h + tris,
            (Some(h), None) => h,
            (None, _) => tris,
        });
        self.largest = self.largest.max(held.unwrap_or(0));
    }
}

/// Splits one object's unit into pieces of about `threshold` bytes.
fn split(
    costs: &Costs,
    object: ObjectId,
    instances: Vec<u32>,
    threshold: u64,
    budget: Option<u64>,
) -> Result<Vec<Piece>, PartitionError> {
    let scene = costs.scene;
    let model = costs.model;
    let whole = costs.whole(object);
    let weight = costs.piece(&whole, instances.len());
    if weight <= threshold || weight == 0 {
        return Ok(vec![Piece { object, instances, ranges: None, weight }]);
    }
    let name = |o: ObjectId| format!("object {o} ('{}')", scene.objects[o as usize].name);
    let too_big =
        |what: String, needed: u64| PartitionError::PieceTooBig { what, needed, budget: budget.unwrap_or(0) };
    // Many instances of little geometry: groups of instances, each with the
    // whole geometry (splitting the geometry would leave every piece with
    // all the instances).
    let one = costs.piece(&whole, 1);
    if instances.len() > 1 && one <= threshold / 2 {
        let per_group = ((threshold - one) / model.per_instance.max(1)).max(1) as usize;
        let groups = instances.len().div_ceil(per_group);
        let size = instances.len().div_ceil(groups);
        return Ok(instances
            .chunks(size)
            .map(|c| Piece {
                object,
                instances: c.to_vec(),
                ranges: None,
                weight: costs.piece(&whole, c.len()),
            })
            .collect());
    }
    // Geometry pieces: each carries every instance.
    let fixed = model.per_object + instances.len() as u64 * model.per_instance;
    if let Some(budget) = budget {
        if fixed > budget {
            return Err(too_big(format!("{} with its {} instances", name(object), instances.len()), fixed));
        }
    }
    let mut pieces: Vec<Vec<MeshRange>> = Vec::new();
    let mut current: Vec<MeshRange> = Vec::new();
    let flush = |current: &mut Vec<MeshRange>, pieces: &mut Vec<Vec<MeshRange>>| {
        if !current.is_empty() {
            pieces.push(std::mem::take(current));
        }
    };
    for range in whole {
        let alone = costs.piece(std::slice::from_ref(&range), instances.len());
        if alone > threshold {
            // Too big a mesh: triangle ranges of about the threshold, each
            // with the mesh's vertices; above the budget if the vertices
            // leave no room under the threshold.
            flush(&mut current, &mut pieces);
            let base = fixed + costs.vertices(range.mesh);
            let per = costs.per_triangle();
            let mut room = threshold.saturating_sub(base);
            if room < per {
                room = budget.unwrap_or(u64::MAX).saturating_sub(base);
            }
            if room < per {
                let mesh = &scene.meshes[range.mesh as usize];
                let what = format!(
                    "a one-triangle piece of mesh {} ('{}', {} vertices) of {}",
                    range.mesh,
                    mesh.name,
                    mesh.positions.len(),
                    name(object)
                );
                return Err(too_big(what, base + per));
            }
            let tris = range.triangles.len() as u64;
            let chunks = tris.div_ceil(room / per);
            let size = tris.div_ceil(chunks) as u32;
            let n = range.triangles.end;
            pieces.extend(
                (0..n)
                    .step_by(size as usize)
                    .map(|s| vec![MeshRange { mesh: range.mesh, triangles: s..(s + size).min(n) }]),
            );
        } else {
            current.push(range);
            if costs.piece(&current, instances.len()) > threshold {
                let range = current.pop().expect("just pushed");
                flush(&mut current, &mut pieces);
                current.push(range);
            }
        }
    }
    flush(&mut current, &mut pieces);
    Ok(pieces
        .into_iter()
        .map(|ranges| Piece {
            object,
            instances: instances.clone(),
            weight: costs.piece(&ranges, instances.len()),
            ranges: Some(ranges),
        })
        .collect())
}

/// Splits `scene` into `parts` parts balanced by `model`'s bytes; see the
/// module docs for how. Deterministic: the same input gives the same parts.
/// Objects no instance places are left out (no ray can reach them).
pub fn partition(
    scene: &Scene,
    parts: usize,
    model: &ByteModel,
    options: &PartitionOptions,
) -> Result<Partition, PartitionError> {
    if parts == 0 {
        return Err(PartitionError::NoParts(parts));
    }
    let costs = Costs { scene, model };
    let mut instances_of: Vec<Vec<u32>> = vec![Vec::new(); scene.objects.len()];
    for (i, inst) in scene.instances.iter().enumerate() {
        instances_of[inst.object as usize].push(i as u32);
    }
    let weights: Vec<u64> = instances_of
        .iter()
        .enumerate()
        .map(
            |(o, insts)| {
                if insts.is_empty() {
                    0
                } else {
                    costs.piece(&costs.whole(o as ObjectId), insts.len())
                }
            },
        )
        .collect();
    let total: u64 = weights.iter().sum();
    // One part: splitting cannot help. Else twice as many pieces as parts
    // for the heaviest units gives the greedy placement room to balance.
    let threshold = if parts == 1 {
        u64::MAX
    } else {
        let t = options.split_threshold.unwrap_or((total / (2 * parts as u64)).max(1));
        t.min(options.budget.unwrap_or(u64::MAX))
    };
    let mut pieces = Vec::new();
    for (o, insts) in instances_of.into_iter().enumerate() {
        if !insts.is_empty() {
            pieces.extend(split(&costs, o as ObjectId, insts, threshold, options.budget)?);
        }
    }
    if let Some(budget) = options.budget {
        if let Some(p) = pieces.iter().find(|p| p.weight > budget) {
            let what = format!("object {} ('{}')", p.object, scene.objects[p.object as usize].name);
            return Err(PartitionError::PieceTooBig { what, needed: p.weight, budget });
        }
    }
    // Heaviest first (bytes, plus instances at their cost); the sort is
    // stable, so ties keep scene order.
    let per_instance = options.instance_cost;
    pieces.sort_by_key(|p| std::cmp::Reverse(p.weight + per_instance * p.instances.len() as u64));

    let mut loads: Vec<Load> = (0..parts).map(|_| Load::new(scene)).collect();
    let mut assigned: Vec<Vec<usize>> = vec![Vec::new(); parts];
    let budget = options.budget.unwrap_or(u64::MAX);
    for (index, piece) in pieces.iter().enumerate() {
        let ranges = piece.ranges.clone().unwrap_or_else(|| costs.whole(piece.object));
        // To the part it leaves least loaded, within the budget.
        let best = (0..parts)
            .filter(|&p| loads[p].bytes + loads[p].added(&costs, piece, &ranges) <= budget)
            .map(|p| {
                let load = &loads[p];
                let bytes = load.bytes + load.added(&costs, piece, &ranges);
                (bytes + per_instance * (load.instances + load.added_instances(piece)), p)
            })
            .min();
        let Some((_, p)) = best else {
            let least_loaded = loads.iter().map(|l| l.bytes).min().unwrap_or(0);
            return Err(PartitionError::DoesNotFit {
                parts,
                budget,
                total,
                piece: piece.weight,
                least_loaded,
            });
        };
        loads[p].add(&costs, piece, &ranges);
        assigned[p].push(index);
    }

    let parts: Vec<ScenePart> =
        assigned.iter().map(|indices| assemble(indices.iter().map(|&i| &pieces[i]))).collect();
    Ok(Partition::from_parts(scene, parts, model))
}

impl Partition {
    /// The partition made of `parts` (each a valid [`ScenePart`] of
    /// `scene`), with its byte sizes under `model` and its owner index.
    pub fn from_parts(scene: &Scene, parts: Vec<ScenePart>, model: &ByteModel) -> Self {
        let bytes = parts.iter().map(|p| part_bytes(scene, p, model)).collect();
        let mut instance_parts = vec![Vec::new(); scene.instances.len()];
        for (p, part) in parts.iter().enumerate() {
            for &i in &part.instances {
                instance_parts[i as usize].push(p as u32);
            }
        }
        Partition {
            parts,
            bytes,
            instance_parts,
            instance_object: scene.instances.iter().map(|i| i.object).collect(),
            object_meshes: scene
                .objects
                .iter()
                .map(|o| {
                    o.meshes.iter().map(|&m| (m, scene.meshes[m as usize].indices.len() as u32)).collect()
                })
                .collect(),
        }
    }
}

/// The [`ScenePart`] holding `pieces`: instances sorted, geometry pieces of
/// one object merged into one subset (adjacent ranges joined).
fn assemble<'a>(pieces: impl Iterator<Item = &'a Piece>) -> ScenePart {
    let mut part = ScenePart::default();
    let mut subsets: Vec<(ObjectId, Vec<MeshRange>)> = Vec::new();
    for piece in pieces {
        match &piece.ranges {
            None => part.instances.extend(&piece.instances),
            Some(ranges) => match subsets.iter_mut().find(|s| s.0 == piece.object) {
                Some(s) => s.1.extend(ranges.iter().cloned()),
                None => {
                    part.instances.extend(&piece.instances);
                    subsets.push((piece.object, ranges.clone()));
                }
            },
        }
    }
    for (_, ranges) in &mut subsets {
        ranges.sort_by_key(|r| (r.mesh, r.triangles.start));
        let mut merged: Vec<MeshRange> = Vec::with_capacity(ranges.len());
        for r in ranges.drain(..) {
            match merged.last_mut() {
                Some(last) if last.mesh == r.mesh && last.triangles.end == r.triangles.start => {
                    last.triangles = last.triangles.start..r.triangles.end;
                }
                _ => merged.push(r),
            }
        }
        *ranges = merged;
    }
    subsets.sort_by_key(|s| s.0);
    part.instances.sort_unstable();
    part.object_subsets = subsets;
    part
}

/// The smallest K in `1..=max_parts` whose partition fits every part under
/// `budget`, or `None` when none does.
pub fn min_parts(scene: &Scene, model: &ByteModel, budget: u64, max_parts: usize) -> Option<usize> {
    smallest_fitting(scene, model, budget, 1..=max_parts).map(|(k, _)| k)
}

/// The first K of `ks` whose memory-balanced partition fits `budget`, with
/// that partition. Each try is cheap (work per object, mesh and instance,
/// not per triangle), so a linear search does.
fn smallest_fitting(
    scene: &Scene,
    model: &ByteModel,
    budget: u64,
    mut ks: impl Iterator<Item = usize>,
) -> Option<(usize, Partition)> {
    let options = PartitionOptions { budget: Some(budget), ..Default::default() };
    ks.find_map(|k| partition(scene, k, model, &options).ok().map(|p| (k, p)))
}

/// Which distribution strategy to use, as the command line names it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Strategy {
    /// Replicate when the scene fits every device, else share its memory
    /// where the devices can (GPUs with direct access to each other),
    /// else ring ([`crate::placement::place`]).
    #[default]
    Auto,
    /// The whole scene on every device.
    Replicate,
    /// The scene in K parts, rays cycling around rings of K devices.
    Ring,
    /// The scene in chunks spread over the devices' memories (hot ones
    /// replicated), read where they lie; rays stay where they started.
    Shared,
}

impl Strategy {
    /// The names [`FromStr`] accepts.
    pub const NAMES: [&'static str; 4] = ["auto", "replicate", "ring", "shared"];
}

impl fmt::Display for Strategy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Strategy::Auto => "auto",
            Strategy::Replicate => "replicate",
            Strategy::Ring => "ring",
            Strategy::Shared => "shared",
        })
    }
}

/// An unknown strategy name.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown distribution strategy '{0}': expected auto, replicate, ring or shared")]
pub struct ParseStrategyError(pub String);

impl FromStr for Strategy {
    type Err = ParseStrategyError;

    /// `auto`, `replicate`, `ring` or `shared`, in any case.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "auto" => Ok(Strategy::Auto),
            "replicate" => Ok(Strategy::Replicate),
            "ring" => Ok(Strategy::Ring),
            "shared" => Ok(Strategy::Shared),
            _ => Err(ParseStrategyError(s.to_string())),
        }
    }
}

/// How N devices share a scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plan {
    /// Every device holds the whole scene.
    Replicate,
    /// The scene in `k` parts; the devices form `islands` rings of `k`
    /// (device `i` holds part `i % k`); devices beyond `k × islands` idle.
    Ring {
        /// Parts, and devices per ring.
        k: usize,
        /// Rings, each with the whole scene.
        islands: usize,
    },
    /// The scene in chunks over every device's memory (placed after the
    /// prepass; whether they fit is the chunk placement's to say).
    Shared,
}

/// Chooses how `devices` devices of `budget` bytes each (`None`: no limit)
/// share `scene`, as `forced` asks or, for `None` or [`Strategy::Auto`]:
/// replicate when the whole scene fits a device, else a ring of the
/// smallest K that fits, with as many islands as the devices allow.
///
/// A forced ring without a budget uses every device in one ring; with a
/// budget it takes the smallest K that fits, but at least 2 where there are
/// 2 devices (a ring of one is replication).
pub fn plan(
    scene: &Scene,
    model: &ByteModel,
    devices: usize,
    budget: Option<u64>,
    forced: Option<Strategy>,
) -> Result<Plan, PartitionError> {
    plan_partitioned(scene, model, devices, budget, forced).map(|(plan, _)| plan)
}

/// [`plan`], with the memory-balanced partition (under `budget`) that
/// found a ring's K, where it made one: on scenes of millions of instances
/// a partition takes a second, and rings cut that way need not make it
/// again.
pub fn plan_partitioned(
    scene: &Scene,
    model: &ByteModel,
    devices: usize,
    budget: Option<u64>,
    forced: Option<Strategy>,
) -> Result<(Plan, Option<Partition>), PartitionError> {
    if devices == 0 {
        return Err(PartitionError::NoParts(devices));
    }
    let whole = || part_bytes(scene, &ScenePart::whole(scene), model);
    let ring = |smallest: usize| {
        let Some(budget) = budget else { return Ok((Plan::Ring { k: devices, islands: 1 }, None)) };
        let (k, partition) = smallest_fitting(scene, model, budget, smallest..=devices)
            .ok_or(PartitionError::TooFewDevices { devices, budget, total: whole() })?;
        Ok((Plan::Ring { k, islands: devices / k }, Some(partition)))
    };
    match forced.unwrap_or_default() {
        Strategy::Replicate => match budget {
            Some(budget) if whole() > budget => {
                Err(PartitionError::ReplicaTooBig { needed: whole(), budget })
            }
            _ => Ok((Plan::Replicate, None)),
        },
        Strategy::Ring => ring(devices.min(2)),
        Strategy::Shared => Ok((Plan::Shared, None)),
        Strategy::Auto => match budget {
            Some(budget) if whole() > budget => ring(2.min(devices)),
            _ => Ok((Plan::Replicate, None)),
        },
    }
}
