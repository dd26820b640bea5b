//! The CPU device: queues in host memory, stages mapped over them with rayon.

mod sharing;

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Instant;

use atoll_bvh::{part_bytes, part_geometry_bytes, ByteModel, Hit, Ray, SceneBvh, ScenePart};
use atoll_scene::camera::tile_order_pixel;
use atoll_scene::Scene;
use glam::{Affine3A, Mat3A, Vec3};
use rayon::prelude::*;

use crate::camera::CameraRays;
use crate::chunks::SceneSharing;
use crate::device::{Device, DeviceError, DeviceStats, PrepareStats, Queue};
use crate::film::Film;
use crate::frame::{FrameContext, RenderOptions, Wave};
use crate::material_coeffs::{hair_offset_at, store_hair_offset, store_tangent, wants_tangent};
use crate::record::{flags, to_f16x3, RayRecord, NO_LIGHT};
use crate::shadow_media::ShadowFilter;
use crate::spawn;
use crate::stages::{generate::camera_record, shade::shade, shade::ShadeOutcome};
use crate::texture::{SceneTextures, TexPoint};

/// Records per rayon task: big enough to amortise scheduling.
const CHUNK: usize = 256;

pub use sharing::CpuSharing;
use sharing::{ChunkCounter, MeshTable, Share};

/// Scene data resident on a CPU device.
struct Resident {
    scene: Arc<Scene>,
    /// Shared by the devices of a shared scene.
    bvh: Arc<SceneBvh>,
    /// Per instance: the matrix taking object-space normals to world space.
    normal_to_world: Vec<Mat3A>,
    /// Under the shared strategy: this device's chunk table and counters.
    share: Option<Share>,
}

impl Resident {
    fn new(scene: &Arc<Scene>, bvh: Arc<SceneBvh>, share: Option<Share>) -> Self {
        let normal_to_world = scene.instances.iter().map(|i| i.normal_to_world()).collect();
        Resident { scene: scene.clone(), bvh, normal_to_world, share }
    }

    /// The access counter, while counting.
    fn counter(&self) -> Option<ChunkCounter<'_>> {
        self.share.as_ref().and_then(Share::counter)
    }

    /// Instance `instance`'s object-to-world transform and normal matrix
    /// at `time`.
    fn placement(&self, instance: u32, time: f32) -> (Affine3A, Mat3A) {
        let inst = &self.scene.instances[instance as usize];
        match inst.motion {
            Some(m) => {
                let to_world = self.scene.motions[m as usize].at(time);
                (to_world, to_world.matrix3.inverse().transpose())
            }
            None => (inst.object_to_world, self.normal_to_world[instance as usize]),
        }
    }

    /// The frame's texture programs over this scene (alpha masks filter hits).
    fn textures<'a>(&'a self, frame: &'a FrameContext) -> SceneTextures<'a> {
        SceneTextures { scene: &self.scene, tables: &frame.textures }
    }
}

/// A device that runs every stage on the host's cores.
pub struct CpuDevice {
    name: String,
    pool: Option<Arc<rayon::ThreadPool>>,
    memory_budget: Option<u64>,
    resident: Option<Resident>,
    frame: Option<Arc<FrameContext>>,
    paths: Vec<RayRecord>,
    shadows: Vec<RayRecord>,
    /// Waves queued and not yet fully started; the front one's first
    /// pixels are trimmed off as they start.
    pending: VecDeque<Wave>,
    /// Buffers reused across bounces: fresh multi-megabyte allocations per
    /// stage cost more in page faults than the stage itself.
    outcomes: Vec<ShadeOutcome>,
    spare_paths: Vec<RayRecord>,
    film: Film,
    stats: DeviceStats,
}

impl CpuDevice {
    /// A CPU device using rayon's global pool (all cores, or `--threads`).
    pub fn new() -> Self {
        CpuDevice {
            name: "cpu".into(),
            pool: None,
            memory_budget: None,
            resident: None,
            frame: None,
            paths: Vec::new(),
            shadows: Vec::new(),
            pending: VecDeque::new(),
            outcomes: Vec::new(),
            spare_paths: Vec::new(),
            film: Film::new(glam::UVec2::ZERO),
            stats: DeviceStats::default(),
        }
    }

    /// Runs this device's stages on a dedicated pool of `threads` threads.
    pub fn with_threads(mut self, threads: usize) -> Result<Self, DeviceError> {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| {
            DeviceError::Other { device: self.name.clone(), message: format!("thread pool: {e}") }
        })?;
        self.pool = Some(Arc::new(pool));
        Ok(self)
    }

    /// Limits the scene bytes this device may hold.
    pub fn with_memory_budget(mut self, bytes: u64) -> Self {
        self.memory_budget = Some(bytes);
        self
    }

    pub fn with_name(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }

    /// Worker threads this device's stages use.
    pub fn threads(&self) -> usize {
        self.pool.as_ref().map_or_else(rayon::current_num_threads, |p| p.current_num_threads())
    }

    fn run<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.pool {
            Some(pool) => pool.install(f),
            None => f(),
        }
    }

    /// The error of a stage called before [`Device::prepare`].
    fn unprepared(&self) -> DeviceError {
        DeviceError::Other { device: self.name.clone(), message: "used before prepare()".into() }
    }

    fn frame(&self) -> Result<&Arc<FrameContext>, DeviceError> {
        self.frame.as_ref().ok_or_else(|| self.unprepared())
    }

    /// Most paths in flight: the frame's wave size.
    fn capacity(&self) -> Result<usize, DeviceError> {
        Ok(self.frame()?.options.queue_capacity() as usize)
    }

    /// Camera paths not yet started.
    fn pending_paths(&self) -> u64 {
        self.pending.iter().map(|w| w.pixel_count as u64).sum()
    }

    fn resident(&self) -> Result<&Resident, DeviceError> {
        self.resident.as_ref().ok_or_else(|| self.unprepared())
    }

    /// The device's part of a shared scene.
    fn share(&self) -> Result<&Share, DeviceError> {
        self.resident()?.share.as_ref().ok_or_else(|| self.not_shared())
    }

    fn share_mut(&mut self) -> Result<&mut Share, DeviceError> {
        let error = self.not_shared();
        self.resident.as_mut().and_then(|r| r.share.as_mut()).ok_or(error)
    }

    fn not_shared(&self) -> DeviceError {
        DeviceError::Other { device: self.name.clone(), message: "not prepared over a shared scene".into() }
    }

    /// Makes `resident` the device's scene and readies queues and film for `frame`.
    fn install(&mut self, resident: Resident, frame: &Arc<FrameContext>) {
        self.resident = Some(resident);
        self.film = Film::new(frame.options.resolution);
        self.frame = Some(frame.clone());
        self.paths.clear();
        self.shadows.clear();
        self.pending.clear();
        self.stats = DeviceStats::default();
    }
}

impl Default for CpuDevice {
    fn default() -> Self {
        Self::new()
    }
}

/// Where a hit lies and how the surface is oriented there, in world
/// space, before its material is looked at.
struct HitSurface {
    position: Vec3,
    /// The position's error bound along each axis.
    error: Vec3,
    ng: Vec3,
    ns: Vec3,
    uv: glam::Vec2,
    /// The shading normal was interpolated from the mesh's normals.
    interpolated: bool,
}

/// Where a hit's partial derivatives come from (made only where a bump
/// map or a BSDF frame asks for them).
enum Partials {
    /// A triangle's object-space corners and its instance's transform.
    Triangle([Vec3; 3], Affine3A),
    /// A curve's, in world space.
    Known(Vec3, Vec3),
}

/// The surface of a triangle hit.
fn triangle_surface(
    hit: &Hit,
    res: &Resident,
    textures: &SceneTextures,
    (to_world, normal_to_world): (Affine3A, Mat3A),
) -> (HitSurface, Partials) {
    let scene = &res.scene;
    let mesh = &scene.meshes[hit.mesh as usize];
    let [i0, i1, i2] = mesh.indices[hit.triangle as usize].map(|i| i as usize);
    let (b1, b2) = (hit.u, hit.v);
    let b0 = 1.0 - b1 - b2;
    // Interpolating the vertices is more precise than origin + t * direction.
    let corners = [mesh.positions[i0], mesh.positions[i1], mesh.positions[i2]];
    let p_obj = corners[0] * b0 + corners[1] * b1 + corners[2] * b2;
    let position = to_world.transform_point3(p_obj);
    let error = spawn::transformed_error(
        &to_world,
        p_obj,
        spawn::gamma(7) * spawn::barycentric_magnitude(corners, [b0, b1, b2]),
    );
    let mut ng = (normal_to_world * mesh.geometric_normal(hit.triangle as usize)).normalize_or_zero();
    let ns = if mesh.normals.is_empty() {
        ng
    } else {
        let n = mesh.normals[i0] * b0 + mesh.normals[i1] * b1 + mesh.normals[i2] * b2;
        let ns = (normal_to_world * n).normalize_or_zero();
        // pbrt: interpolated normals are authoritative for orientation.
        if ns != Vec3::ZERO && ng.dot(ns) < 0.0 {
            ng = -ng;
        }
        if ns == Vec3::ZERO {
            ng
        } else {
            ns
        }
    };
    let surface = HitSurface {
        position,
        error,
        ng,
        ns,
        uv: textures.uv(hit.mesh, hit.triangle, hit.u, hit.v),
        interpolated: !mesh.normals.is_empty(),
    };
    (surface, Partials::Triangle(corners, to_world))
}

/// The surface of a curve hit, as pbrt-v4's `Curve` makes it: the point
/// along the ray, an error bound of the curve's width there, and the
/// partial derivatives [`atoll_scene::CurvePiece::surface`] gives.
fn curve_surface(
    r: &RayRecord,
    hit: &Hit,
    res: &Resident,
    curves: &atoll_scene::Curves,
    (to_world, normal_to_world): (Affine3A, Mat3A),
) -> (HitSurface, Partials) {
    let scene = &res.scene;
    let mesh = &scene.meshes[hit.mesh as usize];
    let to_object = to_world.inverse();
    let piece = &curves.pieces[hit.triangle as usize];
    let dir_obj = to_object.transform_vector3a(r.direction().into());
    let s = piece.surface(curves.kind, hit.u, hit.v, dir_obj);
    let origin_obj = to_object.transform_point3a(r.origin().into());
    let p_obj = Vec3::from(origin_obj + dir_obj * hit.t);
    let normal = if mesh.flip_normals { -s.normal } else { s.normal };
    let ng = (normal_to_world * normal).normalize_or_zero();
    let surface = HitSurface {
        position: to_world.transform_point3(p_obj),
        error: spawn::transformed_error(&to_world, p_obj, Vec3::splat(s.width)),
        ng,
        ns: ng,
        uv: glam::Vec2::new(hit.u, hit.v),
        interpolated: false,
    };
    (surface, Partials::Known(to_world.transform_vector3(s.dpdu), to_world.transform_vector3(s.dpdv)))
}

/// Fills the hit fields of `r` from a BVH hit.
fn write_hit(
    r: &mut RayRecord,
    hit: &Hit,
    res: &Resident,
    frame: &FrameContext,
    counter: Option<&ChunkCounter>,
) {
    let scene = &res.scene;
    let mesh = &scene.meshes[hit.mesh as usize];
    if let Some(counter) = counter {
        count_hit_reads(counter, hit, mesh);
    }
    let textures = res.textures(frame);
    let placement = res.placement(hit.instance, frame.ray_time(r));
    let (surface, partials) = match &mesh.curves {
        Some(curves) => curve_surface(r, hit, res, curves, placement),
        None => triangle_surface(hit, res, &textures, placement),
    };
    let (p, ng, ns, uv) = (surface.position, surface.ng, surface.ns, surface.uv);
    r.t_max = hit.t;
    r.flags |= flags::HIT;
    r.position = p.to_array();
    r.position_error = spawn::pack_error(spawn::error_along(ng, surface.error));
    r.instance = hit.instance;
    r.geometric_normal = to_f16x3(ng);
    r.shading_normal = to_f16x3(ns);
    r.light = if mesh.emission.is_some() {
        frame.lights.triangle_light(hit.instance, hit.mesh, hit.triangle).unwrap_or(NO_LIGHT)
    } else {
        NO_LIGHT
    };
    r.emission_scale =
        if r.light != NO_LIGHT { frame.lights.emission_scale(r.light, hit.u, hit.v) } else { 0 };
    // The partial derivatives, for a texture's footprint, a bump or normal
    // map and the BSDF frame's tangent; made once, when first needed.
    let mut partials_once = None;
    let mut partials = || {
        *partials_once.get_or_insert_with(|| match partials {
            Partials::Known(dpdu, dpdv) => (dpdu, dpdv),
            Partials::Triangle(corners, to_world) => {
                let world = corners.map(|c| to_world.transform_point3(c));
                crate::bump::triangle_partials(world, textures.corner_uvs(hit.mesh, hit.triangle), ng)
            }
        })
    };
    // The hit's texture footprint; made once, when first needed.
    let mut footprint_once = None;
    let mut footprint = |(dpdu, dpdv): (Vec3, Vec3)| {
        *footprint_once.get_or_insert_with(|| {
            let (dpdx, dpdy) = frame.footprint.dp_dxy(p, ng);
            let (duvdx, duvdy) = crate::footprint::uv_footprint(dpdx, dpdy, dpdu, dpdv);
            crate::texture::Footprint { dpdx, dpdy, duvdx, duvdy }
        })
    };
    let at = || TexPoint { uv, position: p, normal: ng, ..Default::default() };
    let (material, packed) = frame.material_at(mesh.material, r, at);
    packed.store(r);
    r.set_hit_media(mesh.media);
    if !frame.textures.materials[material as usize].is_empty() {
        let footprint = footprint(partials());
        textures.apply(material, TexPoint { footprint, ..at() }, &mut r.coeffs);
    }
    store_hair_offset(packed.kind, &mut r.coeffs, hair_offset_at(uv.y));
    let bends = frame.textures.shading_normals[material as usize].kind != crate::bump::kind::NONE;
    if bends || wants_tangent(packed.kind, &r.coeffs) {
        let (dpdu, dpdv) = partials();
        let interpolated = surface.interpolated;
        let at = crate::bump::SurfaceAt { position: p, uv, ng, ns, dpdu, dpdv, interpolated };
        let bent = textures.shading_geometry(material, &at, || footprint((dpdu, dpdv)));
        r.shading_normal = to_f16x3(bent.normal);
        store_tangent(packed.kind, &mut r.coeffs, bent.dpdu);
    }
}

/// The mesh data a hit's shading reads: its indices, and per corner its
/// position, normal and uv where the mesh has them.
fn count_hit_reads(counter: &ChunkCounter, hit: &Hit, mesh: &atoll_scene::TriangleMesh) {
    counter.mesh(hit.mesh, MeshTable::Indices, hit.triangle);
    for corner in mesh.indices[hit.triangle as usize] {
        counter.mesh(hit.mesh, MeshTable::Positions, corner);
        if !mesh.normals.is_empty() {
            counter.mesh(hit.mesh, MeshTable::Normals, corner);
        }
        if !mesh.uvs.is_empty() {
            counter.mesh(hit.mesh, MeshTable::Uvs, corner);
        }
    }
}

/// The ray of record `r`, at its time in `frame`.
fn ray_of(r: &RayRecord, frame: &FrameContext) -> Ray {
    Ray { origin: r.origin(), direction: r.direction(), t_max: r.t_max, time: frame.ray_time(r) }
}

impl Device for CpuDevice {
    fn name(&self) -> String {
        self.name.clone()
    }

    fn prepare(
        &mut self,
        scene: &Arc<Scene>,
        part: &ScenePart,
        frame: &Arc<FrameContext>,
    ) -> Result<PrepareStats, DeviceError> {
        // Checked before building, from the same byte model the partitioner uses.
        let estimate = part_bytes(scene, part, &ByteModel::CPU);
        if let Some(budget) = self.memory_budget {
            if estimate > budget {
                return Err(DeviceError::OutOfMemory { device: self.name(), needed: estimate, budget });
            }
        }
        let start = Instant::now();
        let bvh = self.run(|| SceneBvh::build_part(scene, part));
        let build = start.elapsed().as_secs_f64();
        let bvh_stats = bvh.stats();
        self.install(Resident::new(scene, Arc::new(bvh), None), frame);
        Ok(PrepareStats {
            // Every device holds all texture images and media (see atoll_bvh::part_bytes).
            scene_bytes: part_geometry_bytes(scene, part) + bvh_stats.bytes as u64 + scene.replicated_bytes(),
            frame_bytes: self.frame_bytes(&frame.options),
            bvh_build_seconds: build,
            bvh_sah_cost: bvh_stats.blas.sah_cost,
            upload_seconds: 0.0,
            shared: None,
        })
    }

    fn set_camera(&mut self, camera: &CameraRays) -> Result<(), DeviceError> {
        let frame = self.frame()?;
        let moved = FrameContext { camera: camera.clone(), ..(**frame).clone() };
        self.frame = Some(Arc::new(moved));
        Ok(())
    }

    fn queue_work(&mut self, wave: &Wave) -> Result<(), DeviceError> {
        if wave.pixel_count > 0 {
            self.pending.push_back(*wave);
        }
        Ok(())
    }

    fn wants_work(&self) -> Result<bool, DeviceError> {
        Ok(self.pending_paths() <= self.capacity()? as u64)
    }

    fn refill(&mut self) -> Result<(), DeviceError> {
        let start = Instant::now();
        let frame = self.frame()?.clone();
        let mut free = self.capacity()?.saturating_sub(self.paths.len());
        let mut paths = std::mem::take(&mut self.paths);
        while free > 0 {
            let Some(&wave) = self.pending.front() else { break };
            let n = (wave.pixel_count as usize).min(free) as u32;
            self.run(|| {
                paths.par_extend(
                    (wave.first_pixel..wave.first_pixel + n).into_par_iter().with_min_len(CHUNK).map(
                        |ordinal| {
                            let pixel = tile_order_pixel(ordinal, frame.options.resolution);
                            camera_record(&frame, pixel, wave.sample)
                        },
                    ),
                )
            });
            if n == wave.pixel_count {
                self.pending.pop_front();
            } else if let Some(front) = self.pending.front_mut() {
                front.first_pixel += n;
                front.pixel_count -= n;
            }
            free -= n as usize;
        }
        self.paths = paths;
        self.stats.busy_seconds += start.elapsed().as_secs_f64();
        Ok(())
    }

    fn trace_paths(&mut self) -> Result<(), DeviceError> {
        let start = Instant::now();
        self.resident()?;
        let mut paths = std::mem::take(&mut self.paths);
        let (res, frame) = (self.resident()?, self.frame()?);
        let counter = res.counter();
        self.run(|| {
            paths.par_iter_mut().with_min_len(CHUNK).for_each(|r| {
                let textures = res.textures(frame);
                let hit = match &counter {
                    Some(counter) => res.bvh.intersect_visiting(&ray_of(r, frame), &textures, counter),
                    None => res.bvh.intersect_filtered(&ray_of(r, frame), &textures),
                };
                if let Some(hit) = hit {
                    write_hit(r, &hit, res, frame, counter.as_ref());
                }
            })
        });
        self.stats.rays_traced += paths.len() as u64;
        self.paths = paths;
        self.stats.busy_seconds += start.elapsed().as_secs_f64();
        Ok(())
    }

    fn shade(&mut self) -> Result<(), DeviceError> {
        let start = Instant::now();
        let frame = self.frame()?.clone();
        let mut outcomes = std::mem::take(&mut self.outcomes);
        self.run(|| {
            self.paths
                .par_iter()
                .with_min_len(CHUNK)
                .map(|r| shade(&frame, r))
                .collect_into_vec(&mut outcomes)
        });
        // Film updates and queue compaction keep queue order: each pixel
        // appears once per wave, so the image is the same for any thread count.
        for (r, o) in self.paths.iter().zip(&outcomes) {
            if o.emitted != Vec3::ZERO {
                self.film.add(r.pixel, o.emitted);
            }
        }
        let mut next = std::mem::take(&mut self.spare_paths);
        let mut shadows = std::mem::take(&mut self.shadows);
        next.clear();
        shadows.clear();
        self.run(|| {
            next.par_extend(outcomes.par_iter().with_min_len(CHUNK).filter_map(|o| o.next));
            shadows.par_extend(outcomes.par_iter().with_min_len(CHUNK).filter_map(|o| o.shadow));
        });
        self.shadows = shadows;
        self.outcomes = outcomes;
        self.spare_paths = std::mem::replace(&mut self.paths, next);
        self.stats.busy_seconds += start.elapsed().as_secs_f64();
        Ok(())
    }

    fn trace_shadows(&mut self) -> Result<(), DeviceError> {
        let start = Instant::now();
        self.resident()?;
        let mut shadows = std::mem::take(&mut self.shadows);
        let (res, frame) = (self.resident()?, self.frame()?);
        let textures = res.textures(frame);
        let counter = res.counter();
        let media = frame.media.any();
        self.run(|| {
            shadows.par_iter_mut().with_min_len(CHUNK).for_each(|r| {
                if r.has(flags::OCCLUDED) {
                    return;
                }
                let occluded = if media {
                    // Boundaries of media are crossed, adding to the depth.
                    let filter = ShadowFilter::new(&textures, frame, r);
                    let occluded = match &counter {
                        Some(counter) => res.bvh.occluded_visiting(&ray_of(r, frame), &filter, counter),
                        None => res.bvh.occluded_filtered(&ray_of(r, frame), &filter),
                    };
                    r.position = filter.optical_depth().to_array();
                    occluded
                } else {
                    match &counter {
                        Some(counter) => res.bvh.occluded_visiting(&ray_of(r, frame), &textures, counter),
                        None => res.bvh.occluded_filtered(&ray_of(r, frame), &textures),
                    }
                };
                if occluded {
                    r.flags |= flags::OCCLUDED;
                }
            })
        });
        self.stats.shadow_rays_traced += shadows.len() as u64;
        self.shadows = shadows;
        self.stats.busy_seconds += start.elapsed().as_secs_f64();
        Ok(())
    }

    fn resolve_shadows(&mut self) -> Result<(), DeviceError> {
        let media = self.frame()?.media.any();
        for r in self.shadows.drain(..) {
            if !r.has(flags::OCCLUDED) {
                let attenuation = if media { (-r.optical_depth().max(Vec3::ZERO)).exp() } else { Vec3::ONE };
                self.film.add(r.pixel, r.throughput() * attenuation);
            }
        }
        Ok(())
    }

    fn has_paths(&self) -> Result<bool, DeviceError> {
        Ok(!self.paths.is_empty() || !self.pending.is_empty())
    }

    fn queue_len(&self, queue: Queue) -> Result<usize, DeviceError> {
        Ok(match queue {
            Queue::Paths => self.paths.len(),
            Queue::Shadows => self.shadows.len(),
        })
    }

    fn read_queue_into(&self, queue: Queue, into: &mut Vec<RayRecord>) -> Result<(), DeviceError> {
        into.clear();
        into.extend_from_slice(match queue {
            Queue::Paths => &self.paths,
            Queue::Shadows => &self.shadows,
        });
        Ok(())
    }

    fn write_queue(&mut self, queue: Queue, records: &[RayRecord]) -> Result<(), DeviceError> {
        let q = match queue {
            Queue::Paths => &mut self.paths,
            Queue::Shadows => &mut self.shadows,
        };
        q.clear();
        q.extend_from_slice(records);
        Ok(())
    }

    fn reset_frame(&mut self) -> Result<(), DeviceError> {
        self.film = Film::new(self.film.resolution);
        self.stats = DeviceStats::default();
        Ok(())
    }

    fn film(&self) -> Result<Film, DeviceError> {
        Ok(self.film.clone())
    }

    fn stats(&self) -> Result<DeviceStats, DeviceError> {
        Ok(self.stats.clone())
    }

    /// Two queues of the wave's records and the film.
    fn frame_bytes(&self, options: &RenderOptions) -> u64 {
        2 * options.queue_capacity() as u64 * std::mem::size_of::<RayRecord>() as u64
            + options.pixel_count() as u64 * 12
    }

    fn set_memory_budget(&mut self, bytes: Option<u64>) {
        self.memory_budget = bytes;
    }

    fn scene_sharing(&self) -> Option<Arc<dyn SceneSharing>> {
        Some(Arc::new(CpuSharing::default()))
    }

    fn count_accesses(&mut self, on: bool) -> Result<(), DeviceError> {
        self.share_mut()?.counting = on;
        Ok(())
    }

    fn access_counts(&self) -> Result<Vec<u64>, DeviceError> {
        Ok(self.share()?.counts.iter().map(|c| c.load(std::sync::atomic::Ordering::Relaxed)).collect())
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}
