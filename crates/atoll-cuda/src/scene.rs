//! The scene as flat device tables (the layout described in the crate docs).
//!
//! [`SceneTables::build`] is a pure host function (tested without a GPU);
//! [`GpuScene::upload`] checks the memory plan and copies the tables over.
//!
//! Meshes are laid out object by object, so each object's triangles are one
//! contiguous range of the global triangle table (what a per-object BLAS
//! build wants). A mesh that belongs to two objects is therefore stored
//! twice; pbrt scenes reuse geometry through instances of one object, not
//! through one mesh in several objects, so this costs nothing in practice.
//! Meshes no object uses are not uploaded (no ray can reach them).

pub(crate) mod rows;

use std::sync::Arc;

use atoll_bvh::{ByteModel, MeshRange, ScenePart};
use atoll_scene::{Scene, Texels, TextureImage};
use cudarc::driver::CudaSlice;
use glam::{Affine3A, Mat3, Vec2, Vec3};
use rayon::prelude::*;

use crate::error::{fmt_bytes, CudaError};
use crate::gpu::{Gpu, Uploader};
use crate::layout::{
    image_format, mesh_flags, GpuCurve, GpuImage, GpuInstance, GpuMesh, GpuMotion, GpuObject, NO_MOTION,
};
use rows::RowTable;

/// The scene tables in host memory, exactly as they go to the device.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneTables {
    /// x, y, z per vertex.
    pub vertices: Vec<f32>,
    /// x, y, z per vertex (same indexing as `vertices`), zero for meshes
    /// without normals; empty when no mesh has normals.
    pub normals: Vec<f32>,
    /// 3 absolute vertex indices per triangle.
    pub triangles: Vec<u32>,
    /// Index into `meshes` per triangle.
    pub triangle_mesh: Vec<u32>,
    pub meshes: Vec<GpuMesh>,
    /// One per scene object, same order as `Scene::objects`.
    pub objects: Vec<GpuObject>,
    /// One per scene instance, same order as `Scene::instances` (hit
    /// records, lights and the CPU device all use these indices).
    pub instances: Vec<GpuInstance>,
    /// The scene's motions ([`GpuInstance::motion`]), one per
    /// `Scene::motions`; empty when nothing moves.
    pub motions: Vec<GpuMotion>,
    /// u, v per vertex (same indexing as `vertices`), zero for meshes
    /// without uvs; empty when no mesh has uvs.
    pub uvs: Vec<f32>,
    /// Per triangle, the curve piece its proxy stands for ([`NO_CURVE`]
    /// for triangles); empty when the part has no curves.
    pub curve_of: Vec<u32>,
    /// The part's curve pieces, in triangle order.
    pub curves: Vec<GpuCurve>,
    /// The scene's texture images, by image id.
    pub images: Vec<GpuImage>,
    /// Their texels ([`GpuImage::texel_offset`]).
    pub texels: Vec<u32>,
}

/// Sizes of the tables, computable without building them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TableCounts {
    pub vertices: u64,
    pub triangles: u64,
    pub meshes: u64,
    pub objects: u64,
    pub instances: u64,
    pub has_normals: bool,
    pub has_uvs: bool,
    /// Curve pieces (proxy triangles among `triangles`).
    pub curves: u64,
    /// Motions of moving instances.
    pub motions: u64,
    pub images: u64,
    /// u32 words of all images' texels.
    pub texel_words: u64,
}

impl TableCounts {
    /// Counts for `scene` (as [`SceneTables::build`] would produce).
    #[cfg(test)]
    pub(crate) fn of(scene: &Scene) -> Self {
        Self::of_part(scene, &ScenePart::whole(scene))
    }

    /// Counts for `part` of `scene` (as [`SceneTables::build_part`] would produce).
    pub(crate) fn of_part(scene: &Scene, part: &ScenePart) -> Self {
        let mut c = TableCounts {
            objects: scene.objects.len() as u64,
            instances: scene.instances.len() as u64,
            motions: scene.motions.len() as u64,
            ..Default::default()
        };
        // Vertex arrays once per mesh, however many ranges of it the part holds.
        let mut stored = std::collections::HashSet::new();
        for ranges in part_ranges(scene, part).iter().flatten() {
            for range in ranges {
                let mesh = &scene.meshes[range.mesh as usize];
                if stored.insert(range.mesh) {
                    c.vertices += mesh.positions.len() as u64;
                }
                c.triangles += range.triangles.len() as u64;
                c.meshes += 1;
                c.has_normals |= !mesh.normals.is_empty();
                c.has_uvs |= !mesh.uvs.is_empty();
                if mesh.curves.is_some() {
                    c.curves += range.triangles.len() as u64;
                }
            }
        }
        // Every device holds every image: a texture may be read by any
        // part's materials and alpha masks (images split with their
        // meshes are future work).
        c.images = scene.textures.images.len() as u64;
        c.texel_words = scene.textures.images.iter().map(|i| texel_words(i)).sum();
        c
    }

    /// Device bytes of the tables (empty tables still take one element).
    pub fn bytes(&self) -> u64 {
        let vertex = self.vertices.max(1) * 12;
        // Absent tables are one placeholder f32 on the device.
        let normals = if self.has_normals { vertex } else { 4 };
        let uvs = if self.has_uvs { self.vertices.max(1) * 8 } else { 4 };
        let curves = if self.curves > 0 { self.triangles * 4 } else { 4 }
            + self.curves.max(1) * std::mem::size_of::<GpuCurve>() as u64;
        vertex
            + normals
            + uvs
            + curves
            + self.images.max(1) * std::mem::size_of::<GpuImage>() as u64
            + self.texel_words.max(1) * 4
            + self.triangles.max(1) * (12 + 4)
            + self.meshes.max(1) * std::mem::size_of::<GpuMesh>() as u64
            + self.objects.max(1) * std::mem::size_of::<GpuObject>() as u64
            + self.instances.max(1) * std::mem::size_of::<GpuInstance>() as u64
            + self.motions.max(1) * std::mem::size_of::<GpuMotion>() as u64
    }
}

/// u32 words of one image's texels on the device: one per 8-bit RGBA
/// texel, four per float texel ([`SceneTables::push_image`]).
fn texel_words(image: &TextureImage) -> u64 {
    match &image.texels {
        Texels::Rgba8 { data, .. } => data.len() as u64,
        Texels::RgbaF32(data) => data.len() as u64 * 4,
    }
}

/// Row-major 3×4 of an affine map (column 3 the translation).
fn rows_3x4(a: &Affine3A) -> [f32; 12] {
    let m = Mat3::from(a.matrix3);
    let t = a.translation;
    let mut out = [0.0; 12];
    for r in 0..3 {
        let row = m.row(r);
        out[r * 4..r * 4 + 4].copy_from_slice(&[row.x, row.y, row.z, t[r]]);
    }
    out
}

/// The device form of one instance.
pub(crate) fn gpu_instance(instance: &atoll_scene::Instance) -> GpuInstance {
    let to_world = instance.object_to_world;
    // Same normal matrix as the CPU device: inverse transpose of the linear part.
    let normal = Mat3::from(to_world.matrix3).inverse().transpose();
    let mut normal_to_world = [0.0; 9];
    for r in 0..3 {
        normal_to_world[r * 3..r * 3 + 3].copy_from_slice(&normal.row(r).to_array());
    }
    GpuInstance {
        object_to_world: rows_3x4(&to_world),
        world_to_object: rows_3x4(&to_world.inverse()),
        normal_to_world,
        object: instance.object,
        excluded: 0,
        motion: instance.motion.unwrap_or(NO_MOTION),
    }
}

/// Per scene object, the mesh triangle ranges `part` holds of it (`None`
/// for objects no instance of the part uses).
fn part_ranges(scene: &Scene, part: &ScenePart) -> Vec<Option<Vec<MeshRange>>> {
    let mut used = vec![false; scene.objects.len()];
    for &i in &part.instances {
        used[scene.instances[i as usize].object as usize] = true;
    }
    (0..scene.objects.len()).map(|o| used[o].then(|| part.object_ranges(scene, o as u32))).collect()
}

impl SceneTables {
    /// Flattens all of `scene` into the device tables.
    pub fn build(scene: &Scene) -> Self {
        Self::build_part(scene, &ScenePart::whole(scene))
    }

    /// Flattens `part` of `scene` ([`make_tables`]) into host tables.
    pub(crate) fn build_part(scene: &Scene, part: &ScenePart) -> Self {
        let mut t = SceneTables::default();
        let Ok(()) = make_tables::<std::convert::Infallible>(scene, part, &mut |table| {
            match table {
                Table::Vertices(v) => t.vertices = v.to_vec(),
                Table::Normals(v) => t.normals = v.to_vec(),
                Table::Uvs(v) => t.uvs = v.to_vec(),
                Table::Triangles(v) => t.triangles = v.to_vec(),
                Table::TriangleMesh(v) => t.triangle_mesh = v.to_vec(),
                Table::Meshes(v) => t.meshes = v,
                Table::Objects(v) => t.objects = v,
                Table::Instances(v, m) => (t.instances, t.motions) = (v, m),
                Table::Images(images, texels) => (t.images, t.texels) = (images, texels),
                Table::Curves(curve_of, curves) => (t.curve_of, t.curves) = (curve_of, curves),
            }
            Ok(())
        });
        t
    }

    pub fn counts(&self) -> TableCounts {
        TableCounts {
            vertices: (self.vertices.len() / 3) as u64,
            triangles: self.triangle_mesh.len() as u64,
            meshes: self.meshes.len() as u64,
            objects: self.objects.len() as u64,
            instances: self.instances.len() as u64,
            has_normals: !self.normals.is_empty(),
            has_uvs: !self.uvs.is_empty(),
            curves: self.curves.len() as u64,
            motions: self.motions.len() as u64,
            images: self.images.len() as u64,
            texel_words: self.texels.len() as u64,
        }
    }
}

/// Where a part's tables put everything, found in one cheap pass over its
/// mesh ranges (the order [`make_tables`] documents); the big
/// arrays are then filled in parallel, each range and vertex block into
/// its own slice.
struct TablePlan {
    meshes: Vec<GpuMesh>,
    objects: Vec<GpuObject>,
    /// Scene meshes whose vertices the tables hold, in table order (each
    /// starts where the previous ends).
    vertex_blocks: Vec<atoll_scene::MeshId>,
}

impl TablePlan {
    fn of(scene: &Scene, part: &ScenePart) -> Self {
        let mut plan = TablePlan { meshes: Vec::new(), objects: Vec::new(), vertex_blocks: Vec::new() };
        let mut first_vertices: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
        let (mut vertices, mut triangles) = (0u32, 0u32);
        for ranges in part_ranges(scene, part) {
            let (first_triangle, first_mesh) = (triangles, plan.meshes.len() as u32);
            for range in ranges.iter().flatten() {
                let mesh = &scene.meshes[range.mesh as usize];
                let first_vertex = *first_vertices.entry(range.mesh).or_insert_with(|| {
                    plan.vertex_blocks.push(range.mesh);
                    vertices += mesh.positions.len() as u32;
                    vertices - mesh.positions.len() as u32
                });
                let mut flags = 0;
                if !mesh.normals.is_empty() {
                    flags |= mesh_flags::HAS_NORMALS;
                }
                if mesh.flip_normals {
                    flags |= mesh_flags::FLIP_NORMALS;
                }
                if mesh.emission.is_some() {
                    flags |= mesh_flags::EMISSIVE;
                }
                if !mesh.uvs.is_empty() {
                    flags |= mesh_flags::HAS_UVS;
                }
                if let Some(media) = mesh.media {
                    flags |= ((media.inside << 4 | media.outside) as u32) << mesh_flags::MEDIA_SHIFT;
                }
                if scene.bounds_media_only(range.mesh) {
                    flags |= mesh_flags::MEDIA_ONLY;
                }
                if mesh.curves.is_some() {
                    flags |= mesh_flags::CURVES;
                }
                let count = range.triangles.end - range.triangles.start;
                plan.meshes.push(GpuMesh {
                    first_triangle: triangles,
                    triangle_count: count,
                    first_vertex,
                    vertex_count: mesh.positions.len() as u32,
                    material: mesh.material,
                    flags,
                    scene_mesh: range.mesh,
                    first_scene_triangle: range.triangles.start,
                });
                triangles += count;
            }
            plan.objects.push(GpuObject {
                first_triangle,
                triangle_count: triangles - first_triangle,
                first_mesh,
                mesh_count: plan.meshes.len() as u32 - first_mesh,
            });
        }
        plan
    }
}

/// One of a part's tables, as [`make_tables`] hands them out.
pub(crate) enum Table<'a> {
    Vertices(RowTable<'a, f32>),
    Normals(RowTable<'a, f32>),
    Uvs(RowTable<'a, f32>),
    Triangles(RowTable<'a, u32>),
    TriangleMesh(RowTable<'a, u32>),
    Meshes(Vec<GpuMesh>),
    Objects(Vec<GpuObject>),
    /// The instances and the motions of the moving ones.
    Instances(Vec<GpuInstance>, Vec<GpuMotion>),
    /// The images and their texels.
    Images(Vec<GpuImage>, Vec<u32>),
    /// Each triangle's curve piece (empty without curves) and the pieces.
    Curves(Vec<u32>, Vec<GpuCurve>),
}

/// Flattens `part` of `scene` into its tables, handing each to `sink`
/// before the next is made, so that an upload holds one large table at a
/// time beside the scene rather than all of them. Only the part's
/// triangles are stored; every object and instance keeps its row (hits and
/// lights use scene-wide indices), instances outside the part marked
/// `excluded`. A mesh held only in part keeps all its vertices (the
/// triangle ranges index them), once however many ranges of it the part
/// holds (a terrain cut into interleaved chunks has thousands), but only
/// its ranges of triangles.
pub(crate) fn make_tables<E>(
    scene: &Scene,
    part: &ScenePart,
    sink: &mut dyn FnMut(Table<'_>) -> Result<(), E>,
) -> Result<(), E> {
    let counts = TableCounts::of_part(scene, part);
    let mut in_part = vec![false; scene.instances.len()];
    for &i in &part.instances {
        in_part[i as usize] = true;
    }
    let instances = scene
        .instances
        .par_iter()
        .zip(in_part)
        .map(|(instance, in_part)| GpuInstance { excluded: u32::from(!in_part), ..gpu_instance(instance) })
        .collect();
    sink(Table::Instances(instances, motion_table(scene)))?;
    let plan = TablePlan::of(scene, part);
    let vertices = counts.vertices as usize;
    let blocks = &plan.vertex_blocks;
    sink(Table::Vertices(vertex_table::<Vec3, 3>(scene, blocks, vertices, |m| &m.positions)))?;
    let normals = if counts.has_normals { vertices } else { 0 };
    sink(Table::Normals(vertex_table::<Vec3, 3>(scene, blocks, normals, |m| &m.normals)))?;
    let uvs = if counts.has_uvs { vertices } else { 0 };
    sink(Table::Uvs(vertex_table::<Vec2, 2>(scene, blocks, uvs, |m| &m.uvs)))?;
    sink(Table::Triangles(triangle_table(scene, &plan.meshes)))?;
    sink(Table::TriangleMesh(triangle_mesh_table(&plan.meshes)))?;
    let (curve_of, curves) = curve_tables(scene, &plan.meshes, counts.curves);
    sink(Table::Curves(curve_of, curves))?;
    let mut images = Vec::with_capacity(counts.images as usize);
    let mut texels = Vec::with_capacity(counts.texel_words as usize);
    for image in &scene.textures.images {
        images.push(push_image(image, &mut texels));
    }
    sink(Table::Images(images, texels))?;
    sink(Table::Meshes(plan.meshes))?;
    sink(Table::Objects(plan.objects))
}

/// The scene's motions on the device, each with the world box it sweeps
/// the objects of its instances through.
fn motion_table(scene: &Scene) -> Vec<GpuMotion> {
    let mut bounds = vec![(Vec3::INFINITY, Vec3::NEG_INFINITY); scene.motions.len()];
    let mut object_bounds = std::collections::HashMap::new();
    for inst in &scene.instances {
        let Some(m) = inst.motion else { continue };
        let object = *object_bounds.entry(inst.object).or_insert_with(|| scene.object_bounds(inst.object));
        if let Some((lo, hi)) = object {
            let (a, b) = scene.instance_box(inst, lo, hi);
            let swept = &mut bounds[m as usize];
            *swept = (swept.0.min(a), swept.1.max(b));
        }
    }
    let shutter = scene.settings.camera.shutter;
    scene.motions.iter().zip(bounds).map(|(m, b)| GpuMotion::new(m, shutter, b)).collect()
}

/// The vertex table of one attribute (`attr`, `N` words a vertex) over
/// the vertices of `blocks`, in order; rows of meshes without the
/// attribute are zero, and a table of no `vertices` is empty.
fn vertex_table<'a, A: bytemuck::Pod + Sync, const N: usize>(
    scene: &'a Scene,
    blocks: &'a [atoll_scene::MeshId],
    vertices: usize,
    attr: impl Fn(&atoll_scene::TriangleMesh) -> &Vec<A> + Sync + 'a,
) -> RowTable<'a, f32> {
    debug_assert_eq!(std::mem::size_of::<A>(), 4 * N);
    if vertices == 0 {
        return RowTable::new(0, N, |_, _| {});
    }
    let counts = blocks.iter().map(|&m| scene.meshes[m as usize].positions.len());
    RowTable::segments(counts, N, move |k, first, out| {
        let values = attr(&scene.meshes[blocks[k] as usize]);
        let have = values.len().saturating_sub(first).min(out.len() / N);
        let (given, missing) = out.split_at_mut(have * N);
        if have > 0 {
            given.copy_from_slice(bytemuck::cast_slice(&values[first..first + have]));
        }
        missing.fill(0.0);
    })
}

/// Every table mesh's triangles (absolute vertex indices).
fn triangle_table<'a>(scene: &'a Scene, meshes: &'a [GpuMesh]) -> RowTable<'a, u32> {
    RowTable::segments(meshes.iter().map(|m| m.triangle_count as usize), 3, move |k, first, out| {
        let m = &meshes[k];
        let start = m.first_scene_triangle as usize + first;
        let source = &scene.meshes[m.scene_mesh as usize].indices[start..start + out.len() / 3];
        for (o, t) in out.chunks_exact_mut(3).zip(source) {
            o.copy_from_slice(&t.map(|i| m.first_vertex + i));
        }
    })
}

/// `curve_of` and `curves` ([`SceneTables`]) of the table meshes, which
/// hold `count` curve pieces.
fn curve_tables(scene: &Scene, meshes: &[GpuMesh], count: u64) -> (Vec<u32>, Vec<GpuCurve>) {
    if count == 0 {
        return (Vec::new(), Vec::new());
    }
    let mut curve_of = Vec::new();
    let mut pieces = Vec::with_capacity(count as usize);
    for m in meshes {
        let range = m.first_scene_triangle as usize..(m.first_scene_triangle + m.triangle_count) as usize;
        match &scene.meshes[m.scene_mesh as usize].curves {
            Some(curves) => {
                curve_of.extend(pieces.len() as u32..(pieces.len() + range.len()) as u32);
                pieces.extend(curves.pieces[range].iter().map(|c| GpuCurve::new(curves.kind, c)));
            }
            None => curve_of.extend(std::iter::repeat_n(NO_CURVE, range.len())),
        }
    }
    (curve_of, pieces)
}

/// `SceneTables::curve_of` of a triangle that is no curve's proxy.
pub(crate) const NO_CURVE: u32 = u32::MAX;

/// Each triangle's index into the table meshes.
fn triangle_mesh_table(meshes: &[GpuMesh]) -> RowTable<'_, u32> {
    RowTable::segments(meshes.iter().map(|m| m.triangle_count as usize), 1, |k, _, out| out.fill(k as u32))
}

/// Appends one image's texels in the device format to `texels`; its row.
fn push_image(image: &TextureImage, texels: &mut Vec<u32>) -> GpuImage {
    let texel_offset = texels.len() as u64;
    let format = match &image.texels {
        Texels::Rgba8 { srgb, data } => {
            texels.extend(data.iter().map(|p| u32::from_le_bytes(*p)));
            if *srgb {
                image_format::RGBA8_SRGB
            } else {
                image_format::RGBA8
            }
        }
        Texels::RgbaF32(data) => {
            texels.extend(data.iter().flat_map(|p| p.map(f32::to_bits)));
            image_format::RGBA_F32
        }
    };
    GpuImage { texel_offset, width: image.width, height: image.height, format, pad: [0; 3] }
}

/// Bytes of the rows every device's tables keep for the whole scene,
/// whatever part it holds (every instance and object, so that hits and
/// lights use scene-wide indices): what [`byte_model`], which charges
/// only the part's instances and objects, leaves out. Planners reserve it
/// beside the part.
pub fn scene_wide_rows(scene: &Scene) -> u64 {
    (scene.instances.len() * std::mem::size_of::<GpuInstance>()
        + scene.objects.len() * std::mem::size_of::<GpuObject>()) as u64
}

/// The scene side of a device's memory plan for `part`: its tables and
/// the BVH build's peak, with the BLASes and instances the build will
/// really have (objects of the part with triangles, the part's instances),
/// not the scene's (the tables keep every row; the BVH only the part's).
pub fn part_plan(scene: &Scene, part: &ScenePart) -> MemoryPlan {
    let counts = TableCounts::of_part(scene, part);
    let blases = part_ranges(scene, part)
        .iter()
        .flatten()
        .filter(|ranges| ranges.iter().any(|r| !r.triangles.is_empty()))
        .count() as u64;
    MemoryPlan {
        scene_tables: counts.bytes(),
        bvh: crate::bvh::build_bytes(counts.triangles, blases, part.instances.len() as u64),
        ..Default::default()
    }
}

/// The GPU's resident memory per scene element where the BVH is built in
/// pieces (shared scene memory, `crate::bvh::pieces`): the tables and the
/// BVH's triangle records, ids and nodes (at most one per triangle), no
/// build scratch; each instance its record and TLAS nodes, and as many
/// again for objects cut into segments.
pub fn shared_byte_model() -> ByteModel {
    let node = std::mem::size_of::<crate::bvh::GpuBvhNode>() as u64;
    let record = std::mem::size_of::<crate::bvh::GpuTriRecord>() as u64;
    let tlas = std::mem::size_of::<crate::bvh::GpuTlasInstance>() as u64 + node;
    ByteModel {
        // The mesh index and triangle id, the record and a node.
        per_triangle: 4 + 4 + record + node,
        per_vertex: 0,
        per_instance: std::mem::size_of::<GpuInstance>() as u64 + 2 * tlas,
        per_object: (std::mem::size_of::<GpuObject>() + std::mem::size_of::<GpuMesh>()) as u64 + 64,
        scratch_per_triangle: 0,
    }
}

/// The GPU's memory use per scene element, for partitioning scenes over
/// GPUs (`atoll_bvh::part_bytes`): derived from the same sizes the memory
/// plan checks ([`TableCounts::bytes`], [`crate::bvh::build_bytes`]). The
/// build sorts and builds every BLAS at once, so its scratch is charged per
/// triangle, not per largest object.
pub fn byte_model() -> ByteModel {
    const N: u64 = 1 << 20;
    let bvh = |triangles: u64, instances: u64| crate::bvh::build_bytes(triangles, 1, instances);
    ByteModel {
        // Index bytes are in the geometry; the device adds the triangle's mesh index.
        per_triangle: 4 + (bvh(N, 1) - bvh(0, 1)).div_ceil(N),
        // Positions, normals and uvs as stored.
        per_vertex: 0,
        per_instance: std::mem::size_of::<GpuInstance>() as u64 + (bvh(1, N) - bvh(1, 0)).div_ceil(N),
        per_object: (std::mem::size_of::<GpuObject>() + std::mem::size_of::<GpuMesh>()) as u64 + 64,
        scratch_per_triangle: 0,
    }
}

/// Everything a device will allocate for a frame, summed before allocating.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MemoryPlan {
    pub scene_tables: u64,
    pub bvh: u64,
    /// Ray queues, hit references, counters.
    pub queues: u64,
    pub film: u64,
    /// Frame parameters (camera, light and material tables).
    pub params: u64,
}

/// Kept free beyond the plan: kernel modules, the driver's own allocations
/// and allocator rounding are not in it.
pub const HEADROOM: u64 = 64 << 20;

impl MemoryPlan {
    pub fn total(&self) -> u64 {
        self.scene_tables + self.bvh + self.queues + self.film + self.params + HEADROOM
    }

    /// `Err(OutOfMemory)` when the plan exceeds `min(free, budget)`.
    pub(crate) fn check(&self, device: &str, budget: Option<u64>, free: u64) -> Result<(), CudaError> {
        let budget = budget.unwrap_or(u64::MAX);
        let needed = self.total();
        if needed <= budget.min(free) {
            return Ok(());
        }
        Err(CudaError::OutOfMemory {
            device: device.to_string(),
            what: format!(
                "scene tables {}, BVH {}, queues {}, film {}, frame parameters {}, headroom {}",
                fmt_bytes(self.scene_tables),
                fmt_bytes(self.bvh),
                fmt_bytes(self.queues),
                fmt_bytes(self.film),
                fmt_bytes(self.params),
                fmt_bytes(HEADROOM)
            ),
            needed,
            budget,
            free,
        })
    }
}

/// The scene resident on one GPU. Tables are never empty on the device (a
/// zero-length allocation is an error there): an empty table holds one
/// zeroed element and the counts below say how many are real.
pub struct GpuScene {
    pub gpu: Arc<Gpu>,
    pub vertices: CudaSlice<f32>,
    /// One zero placeholder when no mesh has normals.
    pub normals: CudaSlice<f32>,
    pub triangles: CudaSlice<u32>,
    pub triangle_mesh: CudaSlice<u32>,
    pub meshes: CudaSlice<GpuMesh>,
    pub objects: CudaSlice<GpuObject>,
    pub instances: CudaSlice<GpuInstance>,
    /// One placeholder when nothing moves.
    pub motions: CudaSlice<GpuMotion>,
    /// One zero placeholder when no mesh has uvs.
    pub uvs: CudaSlice<f32>,
    /// One placeholder each when the part has no curves.
    pub curve_of: CudaSlice<u32>,
    pub curves: CudaSlice<GpuCurve>,
    pub images: CudaSlice<GpuImage>,
    pub texels: CudaSlice<u32>,
    pub counts: TableCounts,
    /// Host copies of the small tables (BVH builds plan from them).
    pub host_meshes: Vec<GpuMesh>,
    pub host_objects: Vec<GpuObject>,
    pub host_instances: Vec<GpuInstance>,
    pub host_motions: Vec<GpuMotion>,
}

impl GpuScene {
    /// Checks the memory plan (these tables + the BVH estimate +
    /// `frame_bytes` for queues, film and parameters) against
    /// `min(free memory, budget)`, then builds and uploads the tables.
    pub fn upload(
        gpu: &Arc<Gpu>,
        scene: &Scene,
        budget: Option<u64>,
        frame_bytes: u64,
    ) -> Result<GpuScene, CudaError> {
        Self::upload_part(gpu, scene, &ScenePart::whole(scene), budget, frame_bytes)
    }

    /// [`GpuScene::upload`] of `part` of the scene.
    pub(crate) fn upload_part(
        gpu: &Arc<Gpu>,
        scene: &Scene,
        part: &ScenePart,
        budget: Option<u64>,
        frame_bytes: u64,
    ) -> Result<GpuScene, CudaError> {
        let plan = MemoryPlan { queues: frame_bytes, ..part_plan(scene, part) };
        plan.check(&gpu.label(), budget, gpu.free_memory()?)?;
        let start = std::time::Instant::now();
        let mut up = Uploader::new(gpu);
        // The small tables stay on the host too (BVH builds plan from them).
        let mut host = SceneTables::default();
        let (mut vertices, mut normals, mut uvs, mut triangles, mut triangle_mesh) =
            (None, None, None, None, None);
        let (mut images, mut texels) = (None, None);
        let (mut curve_of, mut curves, mut motions) = (None, None, None);
        make_tables(scene, part, &mut |table| {
            match table {
                Table::Vertices(v) => vertices = Some(up.upload_rows(&v, "vertices")?),
                Table::Normals(v) => normals = Some(up.upload_rows(&v, "normals")?),
                Table::Uvs(v) => uvs = Some(up.upload_rows(&v, "uvs")?),
                Table::Triangles(v) => triangles = Some(up.upload_rows(&v, "triangles")?),
                Table::TriangleMesh(v) => triangle_mesh = Some(up.upload_rows(&v, "triangle meshes")?),
                Table::Images(i, t) => {
                    images = Some(up.upload(&i, "images")?);
                    texels = Some(up.upload(&t, "texels")?);
                }
                Table::Curves(of, c) => {
                    curve_of = Some(up.upload(&of, "curve pieces of triangles")?);
                    curves = Some(up.upload(&c, "curve pieces")?);
                }
                Table::Meshes(v) => host.meshes = v,
                Table::Objects(v) => host.objects = v,
                Table::Instances(v, m) => {
                    motions = Some(up.upload(&m, "motions")?);
                    (host.instances, host.motions) = (v, m);
                }
            }
            Ok::<(), CudaError>(())
        })?;
        // What the tables hold (the host tests pin it to the built tables').
        let counts = TableCounts::of_part(scene, part);
        let made = "make_tables hands out every table";
        let gpu_scene = GpuScene {
            gpu: gpu.clone(),
            vertices: vertices.expect(made),
            normals: normals.expect(made),
            triangles: triangles.expect(made),
            triangle_mesh: triangle_mesh.expect(made),
            meshes: up.upload(&host.meshes, "meshes")?,
            objects: up.upload(&host.objects, "objects")?,
            instances: up.upload(&host.instances, "instances")?,
            motions: motions.expect(made),
            uvs: uvs.expect(made),
            curve_of: curve_of.expect(made),
            curves: curves.expect(made),
            images: images.expect(made),
            texels: texels.expect(made),
            counts,
            host_meshes: host.meshes,
            host_objects: host.objects,
            host_instances: host.instances,
            host_motions: host.motions,
        };
        gpu.synchronize()?;
        let seconds = start.elapsed().as_secs_f64();
        let gb = gpu_scene.bytes() as f64 / 1e9;
        tracing::info!(
            "{}: made and uploaded the scene's tables, {gb:.2} GB, one at a time in {seconds:.2} s ({:.1} GB/s)",
            gpu.label(),
            gb / seconds.max(1e-9)
        );
        Ok(gpu_scene)
    }

    /// Uploads prepared tables (no memory check).
    pub fn upload_tables(gpu: &Arc<Gpu>, t: SceneTables) -> Result<GpuScene, CudaError> {
        let counts = t.counts();
        let mut up = Uploader::new(gpu);
        let scene = GpuScene {
            gpu: gpu.clone(),
            vertices: up.upload(&t.vertices, "vertices")?,
            normals: up.upload(&t.normals, "normals")?,
            triangles: up.upload(&t.triangles, "triangles")?,
            triangle_mesh: up.upload(&t.triangle_mesh, "triangle meshes")?,
            meshes: up.upload(&t.meshes, "meshes")?,
            objects: up.upload(&t.objects, "objects")?,
            instances: up.upload(&t.instances, "instances")?,
            motions: up.upload(&t.motions, "motions")?,
            uvs: up.upload(&t.uvs, "uvs")?,
            curve_of: up.upload(&t.curve_of, "curve pieces of triangles")?,
            curves: up.upload(&t.curves, "curve pieces")?,
            images: up.upload(&t.images, "images")?,
            texels: up.upload(&t.texels, "texels")?,
            counts,
            host_meshes: t.meshes,
            host_objects: t.objects,
            host_instances: t.instances,
            host_motions: t.motions,
        };
        Ok(scene)
    }

    /// The motions table where something moves.
    pub(crate) fn moving(&self) -> Option<&CudaSlice<GpuMotion>> {
        (self.counts.motions > 0).then_some(&self.motions)
    }

    /// The `curve_of` table where the scene has curves.
    pub(crate) fn curve_pieces(&self) -> Option<&CudaSlice<u32>> {
        (self.counts.curves > 0).then_some(&self.curve_of)
    }

    /// Device bytes of the tables.
    pub fn bytes(&self) -> u64 {
        (self.vertices.num_bytes()
            + self.normals.num_bytes()
            + self.triangles.num_bytes()
            + self.triangle_mesh.num_bytes()
            + self.meshes.num_bytes()
            + self.objects.num_bytes()
            + self.instances.num_bytes()
            + self.motions.num_bytes()
            + self.uvs.num_bytes()
            + self.curve_of.num_bytes()
            + self.curves.num_bytes()
            + self.images.num_bytes()
            + self.texels.num_bytes()) as u64
    }
}

#[cfg(test)]
mod tests;
