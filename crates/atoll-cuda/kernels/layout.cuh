// The GPU scene tables (mirror of `atoll_cuda::layout`): meshes, objects,
// instances and the per-ray hit reference traversal writes. The generated
// block asserts every offset and size against the Rust structs and defines
// the mesh flag constants from the Rust ones.
#pragma once

/// Mirror of `layout::GpuMesh` (32 bytes).
struct GpuMesh {
    unsigned int first_triangle;
    unsigned int triangle_count;
    unsigned int first_vertex;
    unsigned int vertex_count;
    unsigned int material;
    unsigned int flags;
    unsigned int scene_mesh;
    unsigned int first_scene_triangle;
};

/// Mirror of `layout::GpuCurve` (96 bytes): a curve piece's control
/// points with the segment's widths and the piece's parameter range in
/// their w, then the ribbon normals, the first with the kind.
struct __align__(16) GpuCurve {
    float p0_w0[4];
    float p1_u0[4];
    float p2_u1[4];
    float p3_w1[4];
    float n0_kind[4];
    float n1[4];
};

/// Mirror of `layout::GpuObject` (16 bytes).
struct GpuObject {
    unsigned int first_triangle;
    unsigned int triangle_count;
    unsigned int first_mesh;
    unsigned int mesh_count;
};

/// Mirror of `layout::GpuInstance` (144 bytes): row-major 3x4 matrices
/// (`m[r*4 + c]`, column 3 the translation) and the row-major 3x3
/// `normal_to_world` (inverse transpose of the linear part).
struct GpuInstance {
    float object_to_world[12];
    float world_to_object[12];
    float normal_to_world[9];
    unsigned int object;
    unsigned int excluded;
    /// Row of the `motions` table of a moving instance (NO_MOTION for one
    /// that stays still: the matrices above are then the start's).
    unsigned int motion;
};

/// Mirror of `layout::GpuMotion` (176 bytes): a moving instance's two keys
/// (translation, rotation quaternion x y z w, row-major symmetric scale),
/// their times, the camera's shutter and the world box swept.
struct GpuMotion {
    float translation[6];
    float rotation[8];
    float scale[18];
    float times[2];
    float shutter[2];
    float bounds[6];
    unsigned int pad[2];
};

/// Mirror of `layout::HitRef` (16 bytes); `instance == HIT_NONE` means
/// "this trace found no hit".
struct __align__(16) HitRef {
    float u;
    float v;
    unsigned int instance;
    unsigned int triangle;
};

/// Mirror of `layout::GpuImage` (32 bytes): texels from `texel_offset`
/// (u32 words) in `texels`, row 0 at the top; `format` an IMAGE_* constant.
struct GpuImage {
    unsigned long long texel_offset;
    unsigned int width;
    unsigned int height;
    unsigned int format;
    unsigned int pad[3];
};

/// Mirrors of `work::GpuWave`, `work::WorkStatus` and `work::WorkFifo`
/// (wave-front merging; see src/work.rs). The array lengths are
/// WORK_SLOTS and WORK_CLAIMS, pinned by the size asserts below.
struct GpuWave {
    unsigned int sample;
    unsigned int first_pixel;
    unsigned int pixel_count;
    unsigned int queue_offset;
};

struct WorkStatus {
    unsigned long long paths_started;
    unsigned int queue_len;
    unsigned int waves_started;
};

struct WorkFifo {
    GpuWave waves[64];
    GpuWave claims[8];
    unsigned int pushed;
    unsigned int taken;
    unsigned int claim_count;
    unsigned int pad;
};

// BEGIN GENERATED layout (src/header.rs; regenerate: ATOLL_BLESS=1 cargo test -p atoll-cuda header)
inline constexpr unsigned int HIT_NONE = 4294967295u;
inline constexpr unsigned int FILTER_BINS = 32u;
inline constexpr unsigned int MEDIA_SLOTS = 16u;
inline constexpr unsigned int NO_GRID = 4294967295u;
inline constexpr unsigned int GRID_FIELD_CONSTANT = 4294967295u;
inline constexpr unsigned int GRID_FIELD_RGB = 65536u;
inline constexpr unsigned int MESH_HAS_NORMALS = 1u;
inline constexpr unsigned int MESH_FLIP_NORMALS = 2u;
inline constexpr unsigned int MESH_EMISSIVE = 4u;
inline constexpr unsigned int MESH_HAS_UVS = 8u;
inline constexpr unsigned int MESH_MEDIA_ONLY = 32u;
inline constexpr unsigned int MESH_CURVES = 64u;
inline constexpr unsigned int CURVE_FLAT = 0u;
inline constexpr unsigned int CURVE_CYLINDER = 1u;
inline constexpr unsigned int CURVE_RIBBON = 2u;
inline constexpr unsigned int CURVE_RECORD_MARKER = 2139144429u;
inline constexpr unsigned int NO_CURVE = 4294967295u;
inline constexpr unsigned int NO_MOTION = 4294967295u;
inline constexpr unsigned int MESH_MEDIA_SHIFT = 8u;
inline constexpr unsigned int IMAGE_RGBA8 = 0u;
inline constexpr unsigned int IMAGE_RGBA8_SRGB = 1u;
inline constexpr unsigned int IMAGE_RGBA_F32 = 2u;
static_assert(sizeof(GpuMesh) == 32, "GpuMesh: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(GpuMesh, first_triangle) == 0 && sizeof(GpuMesh::first_triangle) == 4, "GpuMesh.first_triangle: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMesh, triangle_count) == 4 && sizeof(GpuMesh::triangle_count) == 4, "GpuMesh.triangle_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMesh, first_vertex) == 8 && sizeof(GpuMesh::first_vertex) == 4, "GpuMesh.first_vertex: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMesh, vertex_count) == 12 && sizeof(GpuMesh::vertex_count) == 4, "GpuMesh.vertex_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMesh, material) == 16 && sizeof(GpuMesh::material) == 4, "GpuMesh.material: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMesh, flags) == 20 && sizeof(GpuMesh::flags) == 4, "GpuMesh.flags: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMesh, scene_mesh) == 24 && sizeof(GpuMesh::scene_mesh) == 4, "GpuMesh.scene_mesh: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMesh, first_scene_triangle) == 28 && sizeof(GpuMesh::first_scene_triangle) == 4, "GpuMesh.first_scene_triangle: offset or size differs from Rust");
#endif
static_assert(sizeof(GpuObject) == 16, "GpuObject: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(GpuObject, first_triangle) == 0 && sizeof(GpuObject::first_triangle) == 4, "GpuObject.first_triangle: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuObject, triangle_count) == 4 && sizeof(GpuObject::triangle_count) == 4, "GpuObject.triangle_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuObject, first_mesh) == 8 && sizeof(GpuObject::first_mesh) == 4, "GpuObject.first_mesh: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuObject, mesh_count) == 12 && sizeof(GpuObject::mesh_count) == 4, "GpuObject.mesh_count: offset or size differs from Rust");
#endif
static_assert(sizeof(GpuCurve) == 96, "GpuCurve: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(GpuCurve, p0_w0) == 0 && sizeof(GpuCurve::p0_w0) == 16, "GpuCurve.p0_w0: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuCurve, p1_u0) == 16 && sizeof(GpuCurve::p1_u0) == 16, "GpuCurve.p1_u0: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuCurve, p2_u1) == 32 && sizeof(GpuCurve::p2_u1) == 16, "GpuCurve.p2_u1: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuCurve, p3_w1) == 48 && sizeof(GpuCurve::p3_w1) == 16, "GpuCurve.p3_w1: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuCurve, n0_kind) == 64 && sizeof(GpuCurve::n0_kind) == 16, "GpuCurve.n0_kind: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuCurve, n1) == 80 && sizeof(GpuCurve::n1) == 16, "GpuCurve.n1: offset or size differs from Rust");
#endif
static_assert(sizeof(GpuInstance) == 144, "GpuInstance: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(GpuInstance, object_to_world) == 0 && sizeof(GpuInstance::object_to_world) == 48, "GpuInstance.object_to_world: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuInstance, world_to_object) == 48 && sizeof(GpuInstance::world_to_object) == 48, "GpuInstance.world_to_object: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuInstance, normal_to_world) == 96 && sizeof(GpuInstance::normal_to_world) == 36, "GpuInstance.normal_to_world: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuInstance, object) == 132 && sizeof(GpuInstance::object) == 4, "GpuInstance.object: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuInstance, excluded) == 136 && sizeof(GpuInstance::excluded) == 4, "GpuInstance.excluded: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuInstance, motion) == 140 && sizeof(GpuInstance::motion) == 4, "GpuInstance.motion: offset or size differs from Rust");
#endif
static_assert(sizeof(GpuMotion) == 176, "GpuMotion: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(GpuMotion, translation) == 0 && sizeof(GpuMotion::translation) == 24, "GpuMotion.translation: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMotion, rotation) == 24 && sizeof(GpuMotion::rotation) == 32, "GpuMotion.rotation: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMotion, scale) == 56 && sizeof(GpuMotion::scale) == 72, "GpuMotion.scale: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMotion, times) == 128 && sizeof(GpuMotion::times) == 8, "GpuMotion.times: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMotion, shutter) == 136 && sizeof(GpuMotion::shutter) == 8, "GpuMotion.shutter: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMotion, bounds) == 144 && sizeof(GpuMotion::bounds) == 24, "GpuMotion.bounds: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMotion, pad) == 168 && sizeof(GpuMotion::pad) == 8, "GpuMotion.pad: offset or size differs from Rust");
#endif
static_assert(sizeof(HitRef) == 16, "HitRef: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(HitRef, u) == 0 && sizeof(HitRef::u) == 4, "HitRef.u: offset or size differs from Rust");
static_assert(__builtin_offsetof(HitRef, v) == 4 && sizeof(HitRef::v) == 4, "HitRef.v: offset or size differs from Rust");
static_assert(__builtin_offsetof(HitRef, instance) == 8 && sizeof(HitRef::instance) == 4, "HitRef.instance: offset or size differs from Rust");
static_assert(__builtin_offsetof(HitRef, triangle) == 12 && sizeof(HitRef::triangle) == 4, "HitRef.triangle: offset or size differs from Rust");
#endif
static_assert(sizeof(GpuImage) == 32, "GpuImage: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(GpuImage, texel_offset) == 0 && sizeof(GpuImage::texel_offset) == 8, "GpuImage.texel_offset: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuImage, width) == 8 && sizeof(GpuImage::width) == 4, "GpuImage.width: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuImage, height) == 12 && sizeof(GpuImage::height) == 4, "GpuImage.height: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuImage, format) == 16 && sizeof(GpuImage::format) == 4, "GpuImage.format: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuImage, pad) == 20 && sizeof(GpuImage::pad) == 12, "GpuImage.pad: offset or size differs from Rust");
#endif
inline constexpr unsigned int WORK_SLOTS = 64u;
inline constexpr unsigned int WORK_CLAIMS = 8u;
static_assert(sizeof(GpuWave) == 16, "GpuWave: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(GpuWave, sample) == 0 && sizeof(GpuWave::sample) == 4, "GpuWave.sample: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuWave, first_pixel) == 4 && sizeof(GpuWave::first_pixel) == 4, "GpuWave.first_pixel: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuWave, pixel_count) == 8 && sizeof(GpuWave::pixel_count) == 4, "GpuWave.pixel_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuWave, queue_offset) == 12 && sizeof(GpuWave::queue_offset) == 4, "GpuWave.queue_offset: offset or size differs from Rust");
#endif
static_assert(sizeof(WorkStatus) == 16, "WorkStatus: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(WorkStatus, paths_started) == 0 && sizeof(WorkStatus::paths_started) == 8, "WorkStatus.paths_started: offset or size differs from Rust");
static_assert(__builtin_offsetof(WorkStatus, queue_len) == 8 && sizeof(WorkStatus::queue_len) == 4, "WorkStatus.queue_len: offset or size differs from Rust");
static_assert(__builtin_offsetof(WorkStatus, waves_started) == 12 && sizeof(WorkStatus::waves_started) == 4, "WorkStatus.waves_started: offset or size differs from Rust");
#endif
static_assert(sizeof(WorkFifo) == 1168, "WorkFifo: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(WorkFifo, waves) == 0 && sizeof(WorkFifo::waves) == 1024, "WorkFifo.waves: offset or size differs from Rust");
static_assert(__builtin_offsetof(WorkFifo, claims) == 1024 && sizeof(WorkFifo::claims) == 128, "WorkFifo.claims: offset or size differs from Rust");
static_assert(__builtin_offsetof(WorkFifo, pushed) == 1152 && sizeof(WorkFifo::pushed) == 4, "WorkFifo.pushed: offset or size differs from Rust");
static_assert(__builtin_offsetof(WorkFifo, taken) == 1156 && sizeof(WorkFifo::taken) == 4, "WorkFifo.taken: offset or size differs from Rust");
static_assert(__builtin_offsetof(WorkFifo, claim_count) == 1160 && sizeof(WorkFifo::claim_count) == 4, "WorkFifo.claim_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(WorkFifo, pad) == 1164 && sizeof(WorkFifo::pad) == 4, "WorkFifo.pad: offset or size differs from Rust");
#endif
// END GENERATED layout
