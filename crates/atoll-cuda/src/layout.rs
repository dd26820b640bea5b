//! Structs shared between Rust and the CUDA kernels. Every one is
//! `#[repr(C)]`, its size and offsets asserted here and in
//! `kernels/layout.cuh` (generated text checked by a test).

use bytemuck::{Pod, Zeroable};

/// `(name, offset, size)` of every field of a struct, in declaration order:
/// what `crate::header` turns into the kernels' `static_assert`s.
#[cfg(test)]
pub(crate) type FieldLayout = Vec<(&'static str, usize, usize)>;

/// The [`FieldLayout`] of `$t` (a `Zeroable` struct) from the listed fields.
#[cfg(test)]
macro_rules! field_layout {
    ($t:ty { $($field:ident),* $(,)? }) => {{
        let value = <$t as bytemuck::Zeroable>::zeroed();
        vec![$((
            stringify!($field),
            std::mem::offset_of!($t, $field),
            std::mem::size_of_val(&value.$field),
        )),*]
    }};
}
#[cfg(test)]
pub(crate) use field_layout;

/// `HitRef::instance` of a ray for which traversal found no hit.
pub const HIT_NONE: u32 = u32::MAX;

/// Per-mesh flags in [`GpuMesh::flags`].
pub(crate) mod mesh_flags {
    /// The mesh has per-vertex normals in the `normals` table.
    pub(crate) const HAS_NORMALS: u32 = 1 << 0;
    /// Negate the geometric normal (pbrt's orientation rule).
    pub(crate) const FLIP_NORMALS: u32 = 1 << 1;
    /// The mesh emits (its triangles are lights).
    pub(crate) const EMISSIVE: u32 = 1 << 2;
    /// The mesh has per-vertex texture coordinates in the `uvs` table.
    pub(crate) const HAS_UVS: u32 = 1 << 3;
    /// The mesh bounds media and scatters no light itself (an `interface`
    /// material): shadow rays cross it, gathering optical depth.
    pub(crate) const MEDIA_ONLY: u32 = 1 << 5;
    /// The mesh is made of curve pieces (`TriangleMesh::curves`): its
    /// triangles are their proxies, the `curves` table holds the pieces.
    pub(crate) const CURVES: u32 = 1 << 6;
    /// Where the mesh's media sit (inside << 4 | outside, 0 where it bounds
    /// none, as `RayRecord::material`'s high byte).
    pub(crate) const MEDIA_SHIFT: u32 = 8;
}

/// `GpuImage::format` values.
pub(crate) mod image_format {
    /// One u32 of RGBA bytes per texel, linear.
    pub(crate) const RGBA8: u32 = 0;
    /// One u32 of RGBA bytes per texel, colour channels sRGB-encoded.
    pub(crate) const RGBA8_SRGB: u32 = 1;
    /// Four f32 words (linear RGBA) per texel.
    pub(crate) const RGBA_F32: u32 = 2;
}

/// One texture image in the `texels` table (32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuImage {
    /// First u32 word of its texels, row 0 (the top) first.
    pub texel_offset: u64,
    pub width: u32,
    pub height: u32,
    /// [`image_format`].
    pub format: u32,
    pub pad: [u32; 3],
}

impl GpuImage {
    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuImage { texel_offset, width, height, format, pad })
    }
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
    /// The scene mesh's index of this mesh's first triangle: non-zero when a
    /// device holds only a range of the mesh (a scene part), so hits still
    /// name scene-wide triangles (emitter lookups need them).
    pub first_scene_triangle: u32,
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
    /// 1 when the instance is not part of this device's scene part (its
    /// row stays so instance indices are scene-wide; the TLAS leaves it out).
    pub excluded: u32,
    /// A moving instance's row of the `motions` table ([`NO_MOTION`] for
    /// one that stays still); its matrices above are then the start's.
    pub motion: u32,
}

/// [`GpuInstance::motion`] of an instance that does not move.
pub const NO_MOTION: u32 = u32::MAX;

/// A moving instance's motion on the device (`atoll_scene::Motion`, 176
/// bytes): its two keys' translation, rotation (quaternion x, y, z, w)
/// and row-major scale, the keys' times, the camera's shutter (a ray's
/// time is `shutter[0] + (shutter[1] - shutter[0]) u`) and the world box
/// it sweeps (for the TLAS build).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuMotion {
    pub translation: [f32; 6],
    pub rotation: [f32; 8],
    pub scale: [f32; 18],
    pub times: [f32; 2],
    pub shutter: [f32; 2],
    pub bounds: [f32; 6],
    /// Keeps the size a multiple of 16 bytes.
    pub pad: [u32; 2],
}

impl GpuMotion {
    /// `motion` under a camera shutter `shutter`, sweeping the world box `bounds` (min, max).
    pub fn new(motion: &atoll_scene::Motion, shutter: [f32; 2], bounds: (glam::Vec3, glam::Vec3)) -> Self {
        let (a, b) = (&motion.start, &motion.end);
        // Row-major: the transpose's columns.
        let scale = |m: &glam::Mat3| m.transpose().to_cols_array();
        let mut out = GpuMotion { times: motion.times, shutter, ..Default::default() };
        out.translation[..3].copy_from_slice(&a.translation.to_array());
        out.translation[3..].copy_from_slice(&b.translation.to_array());
        out.rotation[..4].copy_from_slice(&a.rotation.to_array());
        out.rotation[4..].copy_from_slice(&b.rotation.to_array());
        out.scale[..9].copy_from_slice(&scale(&a.scale));
        out.scale[9..].copy_from_slice(&scale(&b.scale));
        out.bounds[..3].copy_from_slice(&bounds.0.to_array());
        out.bounds[3..].copy_from_slice(&bounds.1.to_array());
        out
    }

    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuMotion { translation, rotation, scale, times, shutter, bounds, pad })
    }
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

impl GpuMesh {
    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuMesh {
            first_triangle,
            triangle_count,
            first_vertex,
            vertex_count,
            material,
            flags,
            scene_mesh,
            first_scene_triangle
        })
    }
}

/// One curve piece on the device (`atoll_scene::CurvePiece`, 96 bytes),
/// as six 16-byte words: control point 0 with the segment's width at its
/// start, points 1 and 2 with the piece's parameter range, point 3 with
/// the segment's width at its end, and the ribbon normals at the
/// segment's ends, the first with the curve's kind (`CURVE_FLAT`, ...).
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuCurve {
    pub p0_w0: [f32; 4],
    pub p1_u0: [f32; 4],
    pub p2_u1: [f32; 4],
    pub p3_w1: [f32; 4],
    pub n0_kind: [f32; 4],
    pub n1: [f32; 4],
}

impl GpuCurve {
    pub fn new(kind: atoll_scene::CurveKind, c: &atoll_scene::CurvePiece) -> Self {
        let [p0, p1, p2, p3] = c.points;
        let [n0, n1] = c.normals;
        GpuCurve {
            p0_w0: p0.extend(c.widths[0]).to_array(),
            p1_u0: p1.extend(c.u[0]).to_array(),
            p2_u1: p2.extend(c.u[1]).to_array(),
            p3_w1: p3.extend(c.widths[1]).to_array(),
            n0_kind: n0.extend(f32::from_bits(kind.code())).to_array(),
            n1: n1.extend(0.0).to_array(),
        }
    }

    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuCurve { p0_w0, p1_u0, p2_u1, p3_w1, n0_kind, n1 })
    }
}

impl GpuObject {
    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuObject { first_triangle, triangle_count, first_mesh, mesh_count })
    }
}

impl GpuInstance {
    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuInstance {
            object_to_world,
            world_to_object,
            normal_to_world,
            object,
            excluded,
            motion
        })
    }
}

impl HitRef {
    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(HitRef { u, v, instance, triangle })
    }
}

const _: () = {
    assert!(std::mem::size_of::<GpuMesh>() == 32);
    assert!(std::mem::size_of::<GpuObject>() == 16);
    assert!(std::mem::size_of::<GpuInstance>() == 144);
    assert!(std::mem::size_of::<HitRef>() == 16);
    assert!(std::mem::size_of::<GpuCurve>() == atoll_scene::curve::CURVE_RECORD_BYTES);
};

/// [`atoll_render::RayRecord`] as a device element type. cudarc's typed
/// allocations and copies need `DeviceRepr`, which the orphan rule forbids
/// implementing here for the render crate's type; this transparent wrapper
/// has the same layout (`bytemuck::cast_slice` converts slices for free).
#[repr(transparent)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct GpuRecord(pub atoll_render::RayRecord);

impl GpuRecord {
    /// A record carrying just `ray` for pixel `pixel` (benchmarks and tests
    /// trace bare rays; every other field is zero).
    pub fn from_ray(ray: &atoll_bvh::Ray, pixel: u32) -> Self {
        let mut rec = <atoll_render::RayRecord as Zeroable>::zeroed();
        rec.origin = ray.origin.into();
        rec.direction = ray.direction.into();
        rec.t_max = ray.t_max;
        rec.pixel = pixel;
        GpuRecord(rec)
    }
}

// SAFETY (all six): plain-old-data `#[repr(C)]`/transparent structs (Pod),
// so any bit pattern, including all zeros, is a valid value and they can be
// copied to and from the device byte for byte.
unsafe impl cudarc::driver::DeviceRepr for GpuRecord {}
unsafe impl cudarc::driver::ValidAsZeroBits for GpuRecord {}
unsafe impl cudarc::driver::DeviceRepr for GpuMesh {}
unsafe impl cudarc::driver::ValidAsZeroBits for GpuMesh {}
unsafe impl cudarc::driver::DeviceRepr for GpuObject {}
unsafe impl cudarc::driver::ValidAsZeroBits for GpuObject {}
unsafe impl cudarc::driver::DeviceRepr for GpuInstance {}
unsafe impl cudarc::driver::ValidAsZeroBits for GpuInstance {}
unsafe impl cudarc::driver::DeviceRepr for GpuImage {}
unsafe impl cudarc::driver::ValidAsZeroBits for GpuImage {}
unsafe impl cudarc::driver::DeviceRepr for GpuCurve {}
unsafe impl cudarc::driver::ValidAsZeroBits for GpuCurve {}
unsafe impl cudarc::driver::DeviceRepr for GpuMotion {}
unsafe impl cudarc::driver::ValidAsZeroBits for GpuMotion {}
unsafe impl cudarc::driver::DeviceRepr for HitRef {}
unsafe impl cudarc::driver::ValidAsZeroBits for HitRef {}

const _: () = assert!(std::mem::size_of::<GpuRecord>() == 128);
