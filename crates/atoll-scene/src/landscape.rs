//! The benchmark landscape: a noise terrain with rocks, trees, glass and metal
//! objects instanced over it, grown by a `growth` factor so a benchmark can
//! go from a million to billions of instanced triangles without files (the
//! "up-sampled landscape" of Wald et al. 2023, *ray queue cycling*).
//!
//! Growth `g` multiplies the terrain's area and triangles and the number of
//! instances by `g`, so the density of things and the look near the camera
//! stay the same while the world reaches further. Object tessellation grows
//! mildly (`1 + 0.1 log10 g`) and the instance count is trimmed by the same
//! factor, so instanced triangles stay `g ×` those of growth 1. Unique
//! triangles are the terrain (`≈ 32,768 g`) plus a few thousand per object.
//!
//! At detail 1 ([`Landscape::estimate`]; seed-independent; instances count
//! the terrain's own; memory is mesh data plus instance records, no BVH):
//!
//! | growth | instances | unique triangles | instanced triangles | memory |
//! |---|---|---|---|---|
//! | 1 | 1,056 | 40,352 | 999,732 | 1.0 MiB |
//! | 10 | 10,427 | 335,796 | 10,000,280 | 8.5 MiB |
//! | 100 | 83,929 | 3,286,354 | 99,981,704 | 81.7 MiB |
//! | 1000 | 834,136 | 32,782,248 | 999,785,158 | 814.2 MiB |
//!
//! Building takes time in proportion to the growth (seconds at the largest
//! growths, release, one core); the estimate takes milliseconds at any
//! growth.
//!
//! Everything is a function of `(growth, seed, detail)`: no global state,
//! no time, no thread count, so the same fields give the same scene.

mod shapes;
mod tiles;

use glam::{Affine3A, Quat, UVec2, Vec3};

use crate::{
    Camera, Instance, IntegratorSettings, Light, Material, MaterialId, Object, Rgb, Scene, TriangleMesh,
};

use shapes::{hash, unit};
pub use tiles::{Placement, Tiling, MATERIAL_NAMES, MAX_TILES};

/// Half the side of the square terrain at growth 1, in scene units (metres).
const HALF_SIZE: f32 = 50.0;
/// Terrain quads along one side at growth 1 (2 × 128² = 32,768 triangles).
const TERRAIN_QUADS: f32 = 128.0;
/// Instances (besides the terrain) at growth 1: with the objects' mean of
/// about 920 triangles, that makes growth 1 one million instanced triangles.
const INSTANCES_PER_GROWTH: f64 = 1055.0;

/// Most terrain quads along a side: the terrain's `(quads + 1)²` vertices
/// are addressed with 32 bits.
const MAX_TERRAIN_QUADS: u32 = 65_534;
/// Most object tessellation factor (objects of some 100,000 triangles).
const MAX_TESSELLATION: f32 = 100.0;

/// What one object kind is made of and how it is placed.
struct Kind {
    name: &'static str,
    /// Instances of this kind per [`PATTERN_LEN`] instances.
    weight: u32,
    /// Range of the uniform scale of an instance.
    scale: (f32, f32),
}

/// The object kinds, in object order (object 0 is the terrain).
const KINDS: [Kind; 8] = [
    Kind { name: "rock_round", weight: 3, scale: (0.4, 1.9) },
    Kind { name: "rock_flat", weight: 3, scale: (0.5, 2.2) },
    Kind { name: "rock_tall", weight: 2, scale: (0.4, 1.6) },
    Kind { name: "conifer", weight: 5, scale: (0.7, 1.4) },
    Kind { name: "broadleaf", weight: 4, scale: (0.7, 1.3) },
    Kind { name: "crystals", weight: 1, scale: (0.7, 1.5) },
    Kind { name: "glass_orb", weight: 1, scale: (0.8, 1.5) },
    Kind { name: "gold_torus", weight: 1, scale: (0.8, 1.3) },
];
/// Vertical field of view of the camera.
const FOV_DEGREES: f32 = 40.0;
/// Sum of the kinds' weights: every run of this many instances (in
/// generation order, before shuffling) holds each kind `weight` times.
const PATTERN_LEN: u32 = 20;

/// Material ids, in the order [`materials`] lists them (which is also the
/// order meshes first use them, so a PBRT export reads back with equal ids).
const GROUND: MaterialId = 0;
const ROCK: MaterialId = 1;
const BARK: MaterialId = 2;
const NEEDLES: MaterialId = 3;
const LEAVES: MaterialId = 4;
const GLASS: MaterialId = 5;
const GOLD: MaterialId = 6;

/// The landscape's materials, indexed by the ids above.
fn materials() -> Vec<Material> {
    let diffuse = |r, g, b| Material::Diffuse { reflectance: Rgb::new(r, g, b) };
    vec![
        diffuse(0.20, 0.22, 0.10),
        diffuse(0.42, 0.40, 0.37),
        diffuse(0.22, 0.14, 0.08),
        diffuse(0.05, 0.16, 0.06),
        diffuse(0.16, 0.30, 0.06),
        Material::Dielectric { eta: 1.5, alpha_x: 0.0, alpha_y: 0.0 },
        // Gold's RGB complex index of refraction, slightly rough.
        Material::Conductor {
            eta: Rgb::new(0.143, 0.374, 1.442),
            k: Rgb::new(3.983, 2.385, 1.603),
            alpha_x: 0.12,
            alpha_y: 0.12,
        },
    ]
}

/// A procedural landscape; [`Landscape::build`] makes the [`Scene`].
/// The same fields always give the same scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Landscape {
    /// Scale factor: terrain area and triangles, instances and instanced
    /// triangles grow linearly with it (0 is treated as 1).
    pub growth: u32,
    /// Seed of the terrain, the rocks' shapes and the placement.
    pub seed: u32,
    /// Tessellation multiplier of the terrain and the objects: triangles
    /// scale about linearly with it, instance counts do not (tests use < 1).
    pub detail: f32,
}

impl Default for Landscape {
    fn default() -> Self {
        Landscape { growth: 1, seed: 0, detail: 1.0 }
    }
}

/// Sizes of a landscape, from [`Landscape::estimate`]; equal to the built
/// scene's [`crate::SceneStats`] (`bytes` adds the instance records).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LandscapeEstimate {
    pub meshes: u64,
    pub objects: u64,
    /// Instances, the terrain's identity instance included.
    pub instances: u64,
    pub unique_triangles: u64,
    pub instanced_triangles: u64,
    /// Vertices of all meshes.
    pub vertices: u64,
    /// Triangles of the object with the most (the terrain, but at tiny growths).
    pub largest_object_triangles: u64,
    /// Mesh data (as [`crate::SceneStats::geometry_bytes`]).
    pub geometry_bytes: u64,
    /// Mesh data plus `instances × size_of::<Instance>()`.
    pub bytes: u64,
}

impl LandscapeEstimate {
    /// The sizes a device's byte model charges.
    pub fn sizes(&self) -> crate::SceneSizes {
        crate::SceneSizes {
            geometry_bytes: self.geometry_bytes,
            vertices: self.vertices,
            triangles: self.unique_triangles,
            largest_object_triangles: self.largest_object_triangles,
            objects: self.objects,
            instances: self.instances,
        }
    }
}

impl Landscape {
    /// Growth `growth`, seed 0, detail 1.
    pub fn new(growth: u32) -> Self {
        Landscape { growth, ..Default::default() }
    }

    fn growth(&self) -> u32 {
        self.growth.max(1)
    }

    /// Refuses a landscape whose sizes would not fit the scene model:
    /// detail that is not positive, a terrain whose vertices 32-bit indices
    /// cannot address, objects tessellated past [`MAX_TESSELLATION`].
    /// [`Landscape::estimate`] and [`Landscape::build`] expect a landscape
    /// that passes.
    pub fn check(&self) -> Result<(), String> {
        let (growth, detail) = (self.growth(), self.detail);
        if !(detail > 0.0 && detail.is_finite()) {
            return Err(format!("detail {detail} must be a positive number"));
        }
        let quads = self.terrain_quads();
        if quads > MAX_TERRAIN_QUADS as f32 {
            return Err(format!(
                "growth {growth} at detail {detail} makes a terrain of {quads}² quads, more than the \
                 {MAX_TERRAIN_QUADS}² whose vertices 32-bit indices can address"
            ));
        }
        let t = self.tessellation(growth);
        if t > MAX_TESSELLATION {
            return Err(format!(
                "growth {growth} at detail {detail} tessellates objects {t} times finer than growth 1, \
                 more than the {MAX_TESSELLATION} allowed"
            ));
        }
        Ok(())
    }

    /// Terrain quads along a side (before the minimum of 2).
    fn terrain_quads(&self) -> f32 {
        (TERRAIN_QUADS * (self.growth() as f32 * self.detail).sqrt()).round()
    }

    /// Object tessellation factor at this growth (triangles per object ∝ it).
    fn tessellation(&self, growth: u32) -> f32 {
        self.detail.max(1e-3) * (1.0 + 0.1 * (growth as f32).log10())
    }

    /// Half the side of the square terrain.
    pub fn half_size(&self) -> f32 {
        HALF_SIZE * (self.growth() as f32).sqrt()
    }

    /// The number of instances besides the terrain: `g ×` growth 1's, trimmed
    /// by how much the objects' mean triangle count grew, so instanced
    /// triangles stay proportional to growth.
    fn instance_count(&self, triangles: &[u64; KINDS.len()]) -> u64 {
        let base = object_meshes(self.tessellation(1), self.seed).map(|m| triangle_count(&m));
        let mean = |t: &[u64; KINDS.len()]| -> f64 {
            KINDS.iter().zip(t).map(|(k, &t)| k.weight as f64 * t as f64).sum::<f64>() / PATTERN_LEN as f64
        };
        (self.growth() as f64 * INSTANCES_PER_GROWTH * mean(&base) / mean(triangles)).round() as u64
    }

    /// Sizes of the scene [`Landscape::build`] would make, without making
    /// the terrain or the instances (the objects are made: a few thousand
    /// triangles). Instant at any growth.
    pub fn estimate(&self) -> LandscapeEstimate {
        let terrain = Terrain::new(self);
        let objects = object_meshes(self.tessellation(self.growth()), self.seed);
        let triangles = objects.each_ref().map(|m| triangle_count(m));
        let n = self.instance_count(&triangles);
        let (tn, tv) = (terrain.quads as u64, terrain.quads as u64 + 1);
        let terrain_triangles = 2 * tn * tn;
        let object_triangles: u64 = triangles.iter().sum();
        let instanced: u64 = kind_counts(n).iter().zip(&triangles).map(|(c, t)| c * t).sum();
        let geometry_bytes = tv * tv * 24
            + terrain_triangles * 12
            + objects.iter().flatten().map(TriangleMesh::memory_bytes).sum::<u64>();
        let object_vertices: u64 = objects.iter().flatten().map(|m| m.positions.len() as u64).sum();
        LandscapeEstimate {
            vertices: tv * tv + object_vertices,
            largest_object_triangles: triangles.iter().copied().fold(terrain_triangles, u64::max),
            meshes: 1 + objects.iter().map(|m| m.len() as u64).sum::<u64>(),
            objects: 1 + KINDS.len() as u64,
            instances: n + 1,
            unique_triangles: terrain_triangles + object_triangles,
            instanced_triangles: terrain_triangles + instanced,
            geometry_bytes,
            bytes: geometry_bytes + (n + 1) * std::mem::size_of::<Instance>() as u64,
        }
    }

    /// Height of the terrain mesh's surface at `(x, z)` (clamped to the
    /// terrain): what instances stand on.
    pub fn terrain_height(&self, x: f32, z: f32) -> f32 {
        Terrain::new(self).surface_height(x, z)
    }

    /// Makes the scene: the terrain as the world object (object 0, mesh 0),
    /// then one object per kind, instanced in a jittered grid over the terrain.
    pub fn build(&self) -> Scene {
        let mut scene = Scene { materials: materials(), ..Default::default() };
        let terrain = Terrain::new(self);
        let meshes = object_meshes(self.tessellation(self.growth()), self.seed);
        let triangles = meshes.each_ref().map(|m| triangle_count(m));
        let n = self.instance_count(&triangles);
        // The terrain and the placements are independent: make them together.
        let (ground, placements) = rayon::join(|| terrain.mesh(), || self.placements(&terrain, n));
        let ground = scene.add_mesh(ground);
        let world = scene.add_object(Object { name: "world".into(), meshes: vec![ground] });
        let mut ids = Vec::with_capacity(KINDS.len());
        for (kind, meshes) in KINDS.iter().zip(meshes) {
            let meshes = meshes.into_iter().map(|m| scene.add_mesh(m)).collect();
            ids.push(scene.add_object(Object { name: kind.name.into(), meshes }));
        }
        scene.instances = std::iter::once(Instance::new(world, Affine3A::IDENTITY))
            .chain(
                placements
                    .into_iter()
                    .map(|(kind, object_to_world)| Instance::new(ids[kind as usize], object_to_world)),
            )
            .collect();
        self.set_view(&mut scene, &terrain);
        scene
    }

    /// `n` placements `(kind, transform)` on a jittered grid: the grid has the
    /// fewest square cells ≥ `n`, and evenly spaced cells are skipped so that
    /// exactly `n` remain. Kinds come in the exact proportions of their
    /// weights, shuffled over the cells. Made in parallel; each placement
    /// depends only on its index, so the result does not.
    fn placements(&self, terrain: &Terrain, n: u64) -> Vec<(u8, Affine3A)> {
        use rayon::prelude::*;
        let mut kinds: Vec<u8> = (0..n).map(|i| PATTERN[(i % PATTERN_LEN as u64) as usize]).collect();
        let mut rng = Rng(hash(self.seed ^ 0x51ac_e5ed));
        for i in (1..kinds.len()).rev() {
            kinds.swap(i, rng.next_u32() as usize % (i + 1));
        }
        let side = ((n as f64).sqrt().ceil() as u64).max(1);
        let cells = side * side;
        let cell = 2.0 * terrain.half / side as f32;
        let seed = hash(self.seed ^ 0x9_1ace);
        kinds
            .into_par_iter()
            .enumerate()
            .map(|(m, kind)| {
                let c = kept_cell(m as u64, n, cells);
                let mut rng = Rng(hash(c as u32 ^ hash((c >> 32) as u32 ^ seed)));
                let (i, j) = ((c % side) as f32, (c / side) as f32);
                let x = -terrain.half + (i + 0.1 + 0.8 * rng.next()) * cell;
                let z = -terrain.half + (j + 0.1 + 0.8 * rng.next()) * cell;
                let k = &KINDS[kind as usize];
                // Squared: many small instances, few big ones, as in nature.
                let u = rng.next();
                let scale = k.scale.0 + (k.scale.1 - k.scale.0) * u * u;
                let rotation = Quat::from_rotation_y(rng.next() * std::f32::consts::TAU);
                // Objects are modelled with their ground contact at the origin.
                let position = Vec3::new(x, terrain.surface_height(x, z), z);
                (kind, Affine3A::from_scale_rotation_translation(Vec3::splat(scale), rotation, position))
            })
            .collect()
    }

    /// Camera, film, sampler, integrator and lights: a view from the
    /// south-west corner along the diagonal (so the land's side edges stay
    /// out of the picture), under sun and sky.
    fn set_view(&self, scene: &mut Scene, terrain: &Terrain) {
        let (x, z) = (-terrain.half + 4.0, -terrain.half + 4.0);
        let ground = [(-4.0, -4.0), (4.0, -4.0), (0.0, 0.0), (-4.0, 4.0), (4.0, 4.0), (8.0, 8.0)]
            .iter()
            .map(|&(dx, dz)| terrain.surface_height(x + dx, z + dz))
            .fold(f32::NEG_INFINITY, f32::max);
        let eye = Vec3::new(x, ground + 16.0, z);
        // Tilted down so the far edge of the land sits just below the top of
        // the image: little sky at growth 1, the horizon's edge at large growth.
        let far = std::f32::consts::SQRT_2 * (2.0 * terrain.half - 4.0);
        let pitch = (16.0 / far).atan() + (FOV_DEGREES / 2.0 - 3.0).to_radians();
        let target = eye + Vec3::new(1.0, -std::f32::consts::SQRT_2 * pitch.tan(), 1.0);
        scene.settings.camera = Camera {
            camera_to_world: glam::camera::lh::view::look_at_mat4(eye, target, Vec3::Y).inverse(),
            fov_degrees: FOV_DEGREES,
            ..Default::default()
        };
        scene.settings.film.resolution = UVec2::new(1280, 720);
        scene.settings.spp = 16;
        scene.settings.integrator = IntegratorSettings::Path { max_depth: 5 };
        // Sun from the left of the view, 38 degrees up: long shadows across it.
        let to_sun = Vec3::new(-0.75, 0.6, 0.2).normalize();
        scene.lights = vec![
            Light::Distant { direction: -to_sun, radiance: Rgb::new(3.0, 2.8, 2.45) },
            Light::Infinite { radiance: Rgb::new(0.28, 0.38, 0.55), portal: None },
        ];
    }
}

/// One kind index per slot of a [`PATTERN_LEN`]-long run.
const PATTERN: [u8; PATTERN_LEN as usize] = {
    let mut pattern = [0u8; PATTERN_LEN as usize];
    let (mut kind, mut slot) = (0, 0);
    while kind < KINDS.len() {
        let mut w = 0;
        while w < KINDS[kind].weight {
            pattern[slot] = kind as u8;
            slot += 1;
            w += 1;
        }
        kind += 1;
    }
    assert!(slot == PATTERN_LEN as usize, "weights must sum to PATTERN_LEN");
    pattern
};

/// Instances of each kind among `n`.
fn kind_counts(n: u64) -> [u64; KINDS.len()] {
    let mut counts = [0; KINDS.len()];
    let (full, rest) = (n / PATTERN_LEN as u64, (n % PATTERN_LEN as u64) as usize);
    for (slot, &kind) in PATTERN.iter().enumerate() {
        counts[kind as usize] += full + (slot < rest) as u64;
    }
    counts
}

/// The cell of the `m`-th of `n` placements over `cells ≥ n` grid cells:
/// cell `c` is kept when `⌊(c+1)n/cells⌋ > ⌊cn/cells⌋`, which spaces the
/// skipped cells evenly; the `m`-th kept cell is the first `c` with
/// `(c+1)n ≥ (m+1)·cells`. In closed form so placements need no scan.
fn kept_cell(m: u64, n: u64, cells: u64) -> u64 {
    ((m + 1) as u128 * cells as u128).div_ceil(n as u128) as u64 - 1
}

fn triangle_count(meshes: &[TriangleMesh]) -> u64 {
    meshes.iter().map(|m| m.triangle_count() as u64).sum()
}

/// The meshes of every kind at tessellation factor `t` (about linear in
/// triangles), with their materials. Rock shapes depend on `seed`.
fn object_meshes(t: f32, seed: u32) -> [Vec<TriangleMesh>; KINDS.len()] {
    use shapes::{crystal, fbm3, geodesic, lathe, torus, with_normals};
    let root = t.sqrt();
    let freq = |base: f32| ((base * root).round() as u32).max(1);
    let segments = |base: f32| ((base * root).round() as u32).max(3);
    let with = |material, mesh: TriangleMesh| TriangleMesh { material, ..mesh };
    // A lumpy boulder: noise on the radius, squashed by `stretch`, lifted by
    // `lift` so about a third of it is buried.
    let rock = |name: &str, f: u32, variant: u32, stretch: Vec3, lift: f32| {
        let s = hash(seed ^ hash(variant));
        let mesh = geodesic(name, f, |d| {
            let bumps = fbm3(d * 1.7 + Vec3::splat(variant as f32 * 3.1), 5, s) - 0.5;
            d * (1.0 + 1.1 * bumps) * stretch + Vec3::Y * lift
        });
        vec![with(ROCK, with_normals(mesh))]
    };
    let trunk = |top: f32, radius: f32| {
        let profile = [(radius, -0.4), (0.6 * radius, top)];
        with(BARK, lathe("trunk", &profile, segments(10.0)))
    };
    // Four stacked cones, each overhanging the one above.
    let tiers = [
        (0.0, 0.9),
        (1.5, 0.9),
        (0.55, 2.1),
        (1.15, 1.9),
        (0.4, 3.1),
        (0.85, 2.9),
        (0.25, 4.0),
        (0.55, 3.85),
        (0.0, 5.0),
    ];
    let canopy = geodesic("canopy", freq(7.0), |d| {
        let lumps = fbm3(d * 2.2, 3, hash(seed ^ 0xb10b)) - 0.5;
        d * (1.0 + 0.6 * lumps) * Vec3::new(1.6, 1.25, 1.6) + Vec3::Y * 3.1
    });
    let mut cluster = TriangleMesh { name: "crystals".into(), material: GLASS, ..Default::default() };
    for (offset, axis, radius, length) in [
        (Vec3::new(0.0, -0.2, 0.0), Vec3::new(0.05, 1.0, 0.02), 0.26, 1.7),
        (Vec3::new(0.25, -0.2, 0.1), Vec3::new(0.7, 1.0, 0.25), 0.2, 1.2),
        (Vec3::new(-0.2, -0.2, -0.15), Vec3::new(-0.6, 1.0, -0.5), 0.17, 1.0),
    ] {
        crystal(&mut cluster, offset, axis, radius, length);
    }
    let orb = geodesic("glass_orb", freq(8.0), |d| d * 0.6 + Vec3::Y * 0.5);
    let orb =
        TriangleMesh { normals: orb.positions.iter().map(|p| (*p - Vec3::Y * 0.5) / 0.6).collect(), ..orb };
    let ring = torus("gold_torus", 0.75, 0.2, segments(40.0), segments(16.0));
    let ring =
        TriangleMesh { positions: ring.positions.iter().map(|p| *p + Vec3::Y * 0.7).collect(), ..ring };
    [
        rock("rock_round", freq(8.0), 1, Vec3::new(1.0, 0.8, 0.9), 0.3),
        rock("rock_flat", freq(8.0), 2, Vec3::new(1.3, 0.6, 1.0), 0.3),
        rock("rock_tall", freq(7.0), 3, Vec3::new(0.6, 1.4, 0.7), 0.6),
        vec![trunk(1.3, 0.16), with(NEEDLES, lathe("canopy", &tiers, segments(28.0)))],
        vec![trunk(2.6, 0.2), with(LEAVES, with_normals(canopy))],
        vec![cluster],
        vec![with(GLASS, orb)],
        vec![with(GOLD, ring)],
    ]
}

/// The heightfield: `quads × quads` cells over `[-half, half]²`, heights
/// from fractal value noise.
struct Terrain {
    half: f32,
    quads: u32,
    step: f32,
    seed: u32,
}

impl Terrain {
    fn new(l: &Landscape) -> Self {
        let quads = (l.terrain_quads() as u32).max(2);
        let half = l.half_size();
        Terrain { half, quads, step: 2.0 * half / quads as f32, seed: hash(l.seed ^ 0x7e44a1) }
    }

    /// Coordinate of grid line `i` (x and z alike); the one formula the mesh
    /// and [`Terrain::surface_height`] share, so they agree bit for bit.
    fn coord(&self, i: u32) -> f32 {
        -self.half + i as f32 * self.step
    }

    /// The smooth height function: rolling hills with finer bumps, about ±8.
    fn height(&self, x: f32, z: f32) -> f32 {
        let (mut sum, mut amplitude, mut frequency) = (0.0, 1.0, 1.0 / 55.0);
        for octave in 0..6 {
            sum += amplitude * (shapes::value_noise2(x * frequency, z * frequency, self.seed ^ octave) - 0.5);
            amplitude *= 0.48;
            frequency *= 2.07;
        }
        // Squaring the positive part sharpens hilltops and widens valleys.
        let h = sum * 16.0;
        if h > 0.0 {
            h + 0.12 * h * h
        } else {
            h
        }
    }

    fn vertex_height(&self, i: u32, j: u32) -> f32 {
        self.height(self.coord(i), self.coord(j))
    }

    /// Height of the triangulated surface at `(x, z)`: the cell's two
    /// triangles (split along the diagonal from `(i+1, j)` to `(i, j+1)`)
    /// interpolate their corners linearly.
    fn surface_height(&self, x: f32, z: f32) -> f32 {
        let cell = |v: f32| {
            let u = ((v + self.half) / self.step).clamp(0.0, self.quads as f32);
            let i = (u.floor() as u32).min(self.quads - 1);
            (i, u - i as f32)
        };
        let ((i, fu), (j, fv)) = (cell(x), cell(z));
        let h = |di, dj| self.vertex_height(i + di, j + dj);
        if fu + fv <= 1.0 {
            let h00 = h(0, 0);
            h00 + fu * (h(1, 0) - h00) + fv * (h(0, 1) - h00)
        } else {
            let h11 = h(1, 1);
            h11 + (1.0 - fu) * (h(0, 1) - h11) + (1.0 - fv) * (h(1, 0) - h11)
        }
    }

    /// The terrain mesh, normals from central differences of the heights.
    /// Made in parallel; every element depends only on its index.
    fn mesh(&self) -> TriangleMesh {
        use rayon::prelude::*;
        let (n, row) = (self.quads, self.quads as usize + 1);
        let heights: Vec<f32> = (0..row * row)
            .into_par_iter()
            .map(|k| self.vertex_height((k % row) as u32, (k / row) as u32))
            .collect();
        let positions = (0..row * row)
            .into_par_iter()
            .map(|k| {
                let (i, j) = (k % row, k / row);
                Vec3::new(self.coord(i as u32), heights[k], self.coord(j as u32))
            })
            .collect();
        let normals = (0..row * row)
            .into_par_iter()
            .map(|k| {
                let (i, j) = (k % row, k / row);
                // One-sided differences at the border.
                let (i0, i1, j0, j1) =
                    (i.saturating_sub(1), (i + 1).min(row - 1), j.saturating_sub(1), (j + 1).min(row - 1));
                let dx = (heights[j * row + i1] - heights[j * row + i0]) / ((i1 - i0) as f32 * self.step);
                let dz = (heights[j1 * row + i] - heights[j0 * row + i]) / ((j1 - j0) as f32 * self.step);
                Vec3::new(-dx, 1.0, -dz).normalize()
            })
            .collect();
        let indices = (0..2 * (n as usize) * (n as usize))
            .into_par_iter()
            .map(|t| {
                let quad = (t / 2) as u32;
                let (i, j) = (quad % n, quad / n);
                let a = j * (n + 1) + i;
                let (b, c, d) = (a + 1, a + n + 1, a + n + 2);
                // Wound so the geometric normal points up (+y).
                if t % 2 == 0 {
                    [a, c, b]
                } else {
                    [b, c, d]
                }
            })
            .collect();
        TriangleMesh {
            name: "terrain".into(),
            positions,
            normals,
            indices,
            material: GROUND,
            ..Default::default()
        }
    }
}

/// A tiny deterministic generator: a counter through [`hash`].
struct Rng(u32);

impl Rng {
    fn next_u32(&mut self) -> u32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9);
        hash(self.0)
    }

    /// Uniform in [0, 1).
    fn next(&mut self) -> f32 {
        unit(self.next_u32())
    }
}

#[cfg(test)]
mod tests {
    use super::kept_cell;

    #[test]
    fn kept_cells_in_closed_form_are_the_scanned_ones() {
        for n in [1u64, 2, 3, 7, 10, 99, 100, 101, 1055, 4097] {
            let side = ((n as f64).sqrt().ceil() as u64).max(1);
            let cells = side * side;
            let scanned: Vec<u64> = (0..cells).filter(|&c| (c + 1) * n / cells > c * n / cells).collect();
            let closed: Vec<u64> = (0..n).map(|m| kept_cell(m, n, cells)).collect();
            assert_eq!(scanned, closed, "n = {n}");
        }
    }
}
