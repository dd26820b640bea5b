//! Structs shared between Rust and the CUDA kernels. Every one is
//! `#[repr(C)]`, its size and offsets asserted here and in
//! `kernels/layout.cuh` (generated text checked by a test).

use bytemuck::{Pod, Zeroable};

/// Per-mesh flags in [`GpuMesh::flags`].
pub mod mesh_flags {
    /// The mesh has per-vertex normals in the `normals` table.
    pub const HAS_NORMALS: u32 = 1 << 0;
    /// Negate the geometric normal (pbrt's orientation rule).
    pub const FLIP_NORMALS: u32 = 1 << 1;
    /// The mesh emits (its triangles are lights).
    pub const EMISSIVE: u32 = 1 << 2;
}

/// One mesh of the uploaded scene (32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuMesh {
    /// First entry of this mesh in the global `triangles` table.
    pub first_triangle: u32,
    pub triangle_count: u32,
    /// First vertex of this mesh in `vertices` (and `normals`).
    pub first_vertex: u32,
    pub vertex_count: u32,
    /// Index into the frame's packed material table.
    pub material: u32,
    /// [`mesh_flags`].
    pub flags: u32,
    /// Scene mesh id (index into `Scene::meshes`).
    pub scene_mesh: u32,
    pub pad: u32,
}

/// One object: a consecutive range of meshes and therefore of triangles (16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuObject {
    pub first_triangle: u32,
    pub triangle_count: u32,
    pub first_mesh: u32,
    pub mesh_count: u32,
}

/// One instance (144 bytes). Matrices are row-major 3×4 (`m[r*4 + c]`,
/// column 3 the translation); normals transform with `normal_to_world`
/// (row-major 3×3, the inverse transpose of the linear part).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuInstance {
    pub object_to_world: [f32; 12],
    pub world_to_object: [f32; 12],
    pub normal_to_world: [f32; 9],
    pub object: u32,
    /// Keeps the size a multiple of 16 bytes.
    pub pad: [u32; 2],
}

/// What traversal found for one ray, before hit attributes are computed
/// (16 bytes). `instance == u32::MAX` means "no hit found by this trace".
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct HitRef {
    /// Barycentrics of the 2nd and 3rd vertex (same convention as `atoll_bvh::Hit`).
    pub u: f32,
    pub v: f32,
    pub instance: u32,
    /// Global triangle index (into the `triangles` table).
    pub triangle: u32,
}

const _: () = {
    assert!(std::mem::size_of::<GpuMesh>() == 32);
    assert!(std::mem::size_of::<GpuObject>() == 16);
    assert!(std::mem::size_of::<GpuInstance>() == 144);
    assert!(std::mem::size_of::<HitRef>() == 16);
};
