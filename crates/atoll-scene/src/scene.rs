//! The two-level scene: meshes grouped into objects, objects placed by instances.

use glam::{Affine3A, Vec3};
use rayon::prelude::*;

use crate::{Light, Material, MeshId, RenderSettings, TriangleMesh};

/// Index of an object in [`Scene::objects`].
pub type ObjectId = u32;

/// A named group of meshes sharing one object space (pbrt's `ObjectBegin`).
#[derive(Clone, Debug, Default)]
pub struct Object {
    pub name: String,
    pub meshes: Vec<MeshId>,
}

/// One placement of an object in the world.
#[derive(Clone, Copy, Debug)]
pub struct Instance {
    pub object: crate::ObjectId,
    /// Object to world; for a moving instance, at the start of its motion.
    pub object_to_world: Affine3A,
    /// Where it moves while the shutter is open: an index into
    /// [`Scene::motions`].
    pub motion: Option<u32>,
}

impl Instance {
    /// An instance that stays where `object_to_world` puts it.
    pub fn new(object: crate::ObjectId, object_to_world: Affine3A) -> Self {
        Instance { object, object_to_world, motion: None }
    }

    /// The matrix taking object-space normals to world space (inverse
    /// transpose of the linear part). Under a mirroring transform it keeps an
    /// object's orientation, as pbrt does for transformed interactions.
    pub fn normal_to_world(&self) -> glam::Mat3A {
        self.object_to_world.matrix3.inverse().transpose()
    }
}

/// A complete scene as loaded, before any device sees it.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    pub settings: RenderSettings,
    pub meshes: Vec<TriangleMesh>,
    pub objects: Vec<Object>,
    pub instances: Vec<Instance>,
    /// The motions of moving instances ([`Instance::motion`]).
    pub motions: Vec<crate::Motion>,
    pub materials: Vec<Material>,
    /// Lights not attached to geometry; area lights live on their meshes.
    pub lights: Vec<Light>,
    /// Images, texture nodes and their bindings to material parameters.
    pub textures: crate::Textures,
    /// Participating media; [`crate::MediumIndex`] `k` is `media[k - 1]`.
    pub media: Vec<crate::Medium>,
    /// Tabulated BRDFs that [`crate::Material::Measured`] surfaces read.
    pub measured: Vec<std::sync::Arc<crate::MeasuredBrdf>>,
}

/// Counts and sizes for `atoll info` and memory planning.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneStats {
    pub meshes: usize,
    pub objects: usize,
    pub instances: usize,
    /// Triangles stored once per mesh (curve pieces' proxies among them).
    pub unique_triangles: u64,
    /// Curve pieces stored once per mesh.
    pub curve_pieces: u64,
    /// Triangles as seen by rays: each instance counts its object's triangles.
    pub instanced_triangles: u64,
    pub emissive_triangles: u64,
    pub lights: usize,
    pub materials: usize,
    /// Bytes of mesh data (positions, normals, uvs, indices).
    pub geometry_bytes: u64,
    /// Texture nodes and the decoded images they read.
    pub textures: usize,
    /// Images, each MIP level of a filtered texture's pyramid counted.
    pub texture_images: usize,
    /// Bytes of image texels (every device holds all of them).
    pub texture_bytes: u64,
    /// Participating media, and the bytes of their grids (every device
    /// holds all of them too).
    pub media: usize,
    pub media_bytes: u64,
    /// Of [`SceneStats::media`], the interiors of subsurface materials.
    pub subsurface_interiors: usize,
    pub bounds_min: Vec3,
    pub bounds_max: Vec3,
}

impl Scene {
    /// Adds a material and returns its id.
    pub fn add_material(&mut self, material: Material) -> crate::MaterialId {
        self.materials.push(material);
        (self.materials.len() - 1) as crate::MaterialId
    }

    /// Bytes every device holds whole, whatever part of the geometry it
    /// holds: texture images, media grids and measured BRDFs.
    pub fn replicated_bytes(&self) -> u64 {
        self.textures.memory_bytes()
            + self.media.iter().map(|m| m.bytes()).sum::<u64>()
            + self.measured.iter().map(|m| m.bytes()).sum::<u64>()
    }

    /// Whether mesh `mesh` scatters no light (an `interface` material) in
    /// a scene with media: shadow rays cross it (pbrt-v4's
    /// `TraceTransmittance`), adding up the optical depth of the media on
    /// its two sides, if they differ. Without media (pbrt's `path`
    /// integrator) such surfaces still block shadow rays, as in pbrt.
    pub fn bounds_media_only(&self, mesh: MeshId) -> bool {
        let m = &self.meshes[mesh as usize];
        (m.media.is_some() || !self.media.is_empty())
            && matches!(self.materials.get(m.material as usize), Some(crate::Material::Interface))
    }

    /// Whether traversal must ask about each candidate hit on mesh `mesh`:
    /// [`TriangleMesh::filters_hits`], or a surface shadow rays cross.
    pub fn filters_hits(&self, mesh: MeshId) -> bool {
        self.meshes[mesh as usize].filters_hits() || self.bounds_media_only(mesh)
    }

    /// Adds a mesh and returns its id.
    pub fn add_mesh(&mut self, mesh: TriangleMesh) -> MeshId {
        self.meshes.push(mesh);
        (self.meshes.len() - 1) as MeshId
    }

    /// Adds an object and returns its id.
    pub fn add_object(&mut self, object: Object) -> crate::ObjectId {
        self.objects.push(object);
        (self.objects.len() - 1) as crate::ObjectId
    }

    /// Triangles of one object (summed over its meshes).
    pub fn object_triangles(&self, object: crate::ObjectId) -> u64 {
        self.objects[object as usize]
            .meshes
            .iter()
            .map(|&m| self.meshes[m as usize].indices.len() as u64)
            .sum()
    }

    /// Object-space bounds of one object; `None` when it has no vertices.
    pub fn object_bounds(&self, object: crate::ObjectId) -> Option<(Vec3, Vec3)> {
        let meshes = &self.objects[object as usize].meshes;
        let points = meshes.par_iter().flat_map(|&m| self.meshes[m as usize].positions.par_iter().copied());
        let (lo, hi) = bounds_of(points);
        (lo.x <= hi.x).then_some((lo, hi))
    }

    /// World-space bounds of all instances; `None` for an empty scene.
    pub fn world_bounds(&self) -> Option<(Vec3, Vec3)> {
        let object_bounds: Vec<_> = (0..self.objects.len() as u32).map(|o| self.object_bounds(o)).collect();
        let corners = self.instances.par_iter().flat_map_iter(|inst| {
            object_bounds[inst.object as usize].into_iter().flat_map(move |(lo, hi)| {
                let (a, b) = self.instance_box(inst, lo, hi);
                [a, b]
            })
        });
        let (lo, hi) = bounds_of(corners);
        (lo.x <= hi.x).then_some((lo, hi))
    }

    /// The world box of `instance`'s object box `lo`..`hi`: over the whole
    /// of its motion where it moves.
    pub fn instance_box(&self, instance: &Instance, lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
        if let Some(m) = instance.motion {
            return self.motions[m as usize].bounds(lo, hi);
        }
        let corners = (0..8).map(|i| {
            let corner = Vec3::select(glam::BVec3::new(i & 1 != 0, i & 2 != 0, i & 4 != 0), hi, lo);
            instance.object_to_world.transform_point3(corner)
        });
        corners.fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), p| (a.min(p), b.max(p)))
    }

    pub fn stats(&self) -> SceneStats {
        let (bounds_min, bounds_max) = self.world_bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let per_object: Vec<u64> = (0..self.objects.len() as u32).map(|o| self.object_triangles(o)).collect();
        SceneStats {
            meshes: self.meshes.len(),
            objects: self.objects.len(),
            instances: self.instances.len(),
            unique_triangles: self.meshes.iter().map(|m| m.indices.len() as u64).sum(),
            curve_pieces: self
                .meshes
                .iter()
                .filter_map(|m| m.curves.as_ref())
                .map(|c| c.pieces.len() as u64)
                .sum(),
            instanced_triangles: self.instances.iter().map(|i| per_object[i.object as usize]).sum(),
            emissive_triangles: self.emissive_triangle_count(),
            lights: self.lights.len(),
            materials: self.materials.len(),
            geometry_bytes: self.meshes.iter().map(|m| m.memory_bytes()).sum(),
            textures: self.textures.textures.len(),
            texture_images: self.textures.images.len(),
            texture_bytes: self.textures.memory_bytes(),
            media: self.media.len(),
            subsurface_interiors: self
                .media
                .iter()
                .filter(|m| matches!(m, crate::Medium::Subsurface(_)))
                .count(),
            media_bytes: self.media.iter().map(|m| m.bytes()).sum(),
            bounds_min,
            bounds_max,
        }
    }

    /// Emissive triangles as instanced into the world (each is a light).
    pub fn emissive_triangle_count(&self) -> u64 {
        self.instances
            .iter()
            .flat_map(|inst| self.objects[inst.object as usize].meshes.iter())
            .map(|&m| &self.meshes[m as usize])
            .filter(|m| m.emission.is_some())
            .map(|m| m.indices.len() as u64)
            .sum()
    }
}

/// The smallest box around `points` (inverted when there are none); in
/// parallel, and exact whatever the order: min and max round nothing.
fn bounds_of(points: impl ParallelIterator<Item = Vec3>) -> (Vec3, Vec3) {
    let empty = || (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    points
        .fold(empty, |(lo, hi), p| (lo.min(p), hi.max(p)))
        .reduce(empty, |(a, b), (c, d)| (a.min(c), b.max(d)))
}

/// The sizes a device's memory use follows from ([`atoll_bvh`'s byte
/// model]): counted from a built scene or part, or known before a scene is
/// built (a generated scene's estimate; a file scene's mesh headers, where
/// faces count as one triangle each, so triangles are then a lower bound),
/// so that one that cannot fit is refused before it is made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SceneSizes {
    /// Bytes of the meshes' arrays.
    pub geometry_bytes: u64,
    pub vertices: u64,
    pub triangles: u64,
    /// Triangles of the object with the most.
    pub largest_object_triangles: u64,
    pub objects: u64,
    pub instances: u64,
}
