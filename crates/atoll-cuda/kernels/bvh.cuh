// The GPU BVH traversal layout and the device functions that walk it
// (trace.cu instantiates them; lbvh.cu writes the layout; the Rust mirror
// of every struct and constant is src/bvh/layout.rs, checked by a test).
//
// Layout (Aila & Laine 2009, "Understanding the efficiency of ray traversal
// on GPUs"): a binary node holds the boxes of its two *children* and their
// links, 64 bytes, so one node fetch decides which children to visit.
// Links: 0 <= link < LINK_DONE is a node index; link < 0 is a leaf,
// ~link = (first << 2) | (count - 1) with up to 4 primitives from `first`.
// BLAS leaves index triangle records (48 bytes each, in leaf order);
// TLAS leaves index instance records. One node array holds all BLASes,
// another the TLAS.
#pragma once

#include "texture.cuh"
#include "media.cuh"
#include "curve.cuh"
#include "motion.cuh"

/// Box far distances are scaled by 1 + 2 gamma(3) (pbrt's robust slab test,
/// Ize 2013) so that rounding never culls a box the ray touches.
#define BOX_ROBUST_SCALE 1.0000004f

/// Two children's boxes and links (64 bytes).
struct __align__(16) BvhNode {
    float4 left_xy;   // left.min.x, left.max.x, left.min.y, left.max.y
    float4 right_xy;  // right.min.x, right.max.x, right.min.y, right.max.y
    float4 z;         // left.min.z, left.max.z, right.min.z, right.max.z
    int4 links;       // left, right, 0, 0
};

/// A triangle prepared for the intersection test (48 bytes). Exact test:
/// a = (p0, 0), b = (p1 - p0, 0), c = (p2 - p0, 0). Woop test: the rows
/// of the world-to-unit-triangle affine map, a = row w (normal), b = row u,
/// c = row v, each (x, y, z, translation).
struct __align__(16) TriRecord {
    float4 a, b, c;
};

/// A TLAS leaf (64 bytes): the instance's world-to-object transform
/// (row-major 3x4, copied from GpuInstance), its BLAS root link and its
/// index. A moving instance's first word is its motion's index instead.
struct __align__(16) TlasInstance {
    float4 world_to_object[3];
    int blas_root;
    unsigned int instance;
    /// How a ray enters (TRANSFORM_*): through world_to_object, as it is
    /// (the identity, as the CPU does), or through its motion at the ray's time.
    unsigned int transform;
    /// Where the BLAS's triangle records start: its leaf links count from here.
    unsigned int tri_base;
};

// LINK_DONE: the bottom of every traversal stack and the root link of an
// empty tree; LINK_INSTANCE_END: pushed when traversal descends into an
// instance (popping it returns to the TLAS, world space); TRAVERSAL_STACK:
// entries of the per-thread stack (local memory), TLAS + BLAS depth: pushes
// beyond it are dropped (a wrong result, never a fault); MAX_LEAF_PRIMS:
// primitives per leaf (2 bits of the link).
// BEGIN GENERATED bvh (src/header.rs; regenerate: ATOLL_BLESS=1 cargo test -p atoll-cuda header)
constexpr int LINK_DONE = 1985229328;
constexpr int LINK_INSTANCE_END = 1985229329;
constexpr unsigned int MAX_LEAF_PRIMS = 4u;
constexpr int TRAVERSAL_STACK = 96;
constexpr unsigned int TRANSFORM_AFFINE = 0u;
constexpr unsigned int TRANSFORM_IDENTITY = 1u;
constexpr unsigned int TRANSFORM_MOVING = 2u;
static_assert(sizeof(BvhNode) == 64, "BvhNode: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(BvhNode, left_xy) == 0 && sizeof(BvhNode::left_xy) == 16, "BvhNode.left_xy: offset or size differs from Rust");
static_assert(__builtin_offsetof(BvhNode, right_xy) == 16 && sizeof(BvhNode::right_xy) == 16, "BvhNode.right_xy: offset or size differs from Rust");
static_assert(__builtin_offsetof(BvhNode, z) == 32 && sizeof(BvhNode::z) == 16, "BvhNode.z: offset or size differs from Rust");
static_assert(__builtin_offsetof(BvhNode, links) == 48 && sizeof(BvhNode::links) == 16, "BvhNode.links: offset or size differs from Rust");
#endif
static_assert(sizeof(TriRecord) == 48, "TriRecord: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(TriRecord, a) == 0 && sizeof(TriRecord::a) == 16, "TriRecord.a: offset or size differs from Rust");
static_assert(__builtin_offsetof(TriRecord, b) == 16 && sizeof(TriRecord::b) == 16, "TriRecord.b: offset or size differs from Rust");
static_assert(__builtin_offsetof(TriRecord, c) == 32 && sizeof(TriRecord::c) == 16, "TriRecord.c: offset or size differs from Rust");
#endif
static_assert(sizeof(TlasInstance) == 64, "TlasInstance: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(TlasInstance, world_to_object) == 0 && sizeof(TlasInstance::world_to_object) == 48, "TlasInstance.world_to_object: offset or size differs from Rust");
static_assert(__builtin_offsetof(TlasInstance, blas_root) == 48 && sizeof(TlasInstance::blas_root) == 4, "TlasInstance.blas_root: offset or size differs from Rust");
static_assert(__builtin_offsetof(TlasInstance, instance) == 52 && sizeof(TlasInstance::instance) == 4, "TlasInstance.instance: offset or size differs from Rust");
static_assert(__builtin_offsetof(TlasInstance, transform) == 56 && sizeof(TlasInstance::transform) == 4, "TlasInstance.transform: offset or size differs from Rust");
static_assert(__builtin_offsetof(TlasInstance, tri_base) == 60 && sizeof(TlasInstance::tri_base) == 4, "TlasInstance.tri_base: offset or size differs from Rust");
#endif
// END GENERATED bvh

/// Triangle tests (template argument of the traversal).
#define TRI_EXACT 0
#define TRI_WOOP 1

__device__ __forceinline__ float3 f4_xyz(float4 v) { return make_float3(v.x, v.y, v.z); }

__device__ __forceinline__ int leaf_link(unsigned int first, unsigned int count) {
    return (int)~((first << 2) | (count - 1u));
}
__device__ __forceinline__ unsigned int leaf_first(int link) { return ((unsigned int)~link) >> 2; }
__device__ __forceinline__ unsigned int leaf_count(int link) { return (((unsigned int)~link) & 3u) + 1u; }

// --- exact arithmetic (no FMA contraction): glam's operation order ---

__device__ __forceinline__ float3 sub_rn(float3 a, float3 b) {
    return make_float3(__fsub_rn(a.x, b.x), __fsub_rn(a.y, b.y), __fsub_rn(a.z, b.z));
}
/// glam `Vec3A::dot`: `(x*x' + y*y') + z*z'`, each step rounded.
__device__ __forceinline__ float dot_rn(float3 a, float3 b) {
    return __fadd_rn(__fadd_rn(__fmul_rn(a.x, b.x), __fmul_rn(a.y, b.y)), __fmul_rn(a.z, b.z));
}
/// glam `Vec3A::cross` (SSE2 without FMA): each component `a*b - c*d`, rounded twice.
__device__ __forceinline__ float3 cross_rn(float3 a, float3 b) {
    return make_float3(__fsub_rn(__fmul_rn(a.y, b.z), __fmul_rn(a.z, b.y)),
                       __fsub_rn(__fmul_rn(a.z, b.x), __fmul_rn(a.x, b.z)),
                       __fsub_rn(__fmul_rn(a.x, b.y), __fmul_rn(a.y, b.x)));
}
/// Row `r` of glam `Mat3A * v` (+ translation `t` when `point`): `((m0 x + m1 y) + m2 z) + t`.
__device__ __forceinline__ float affine_row_rn(float4 row, float3 v, bool point) {
    const float linear = __fadd_rn(__fadd_rn(__fmul_rn(row.x, v.x), __fmul_rn(row.y, v.y)), __fmul_rn(row.z, v.z));
    return point ? __fadd_rn(linear, row.w) : linear;
}

/// Möller–Trumbore exactly as `atoll_bvh::TriAccel::intersect` (same
/// operations in the same order, IEEE division), so CPU and GPU agree bit
/// for bit: a hit with 0 < t < t_max sets (t, u, v), u and v the
/// barycentrics of p1 and p2.
__device__ __forceinline__ bool intersect_exact(const TriRecord& tri, float3 o, float3 d, float t_max, float& t,
                                                float& u, float& v) {
    const float3 e1 = f4_xyz(tri.b), e2 = f4_xyz(tri.c);
    const float3 p = cross_rn(d, e2);
    const float det = dot_rn(e1, p);
    if (det == 0.0f) return false;
    const float inv_det = __fdiv_rn(1.0f, det);
    const float3 s = sub_rn(o, f4_xyz(tri.a));
    const float uu = __fmul_rn(dot_rn(s, p), inv_det);
    const float3 q = cross_rn(s, e1);
    const float vv = __fmul_rn(dot_rn(d, q), inv_det);
    const float tt = __fmul_rn(dot_rn(e2, q), inv_det);
    if (uu >= 0.0f && vv >= 0.0f && __fadd_rn(uu, vv) <= 1.0f && tt > 0.0f && tt < t_max) {
        t = tt;
        u = uu;
        v = vv;
        return true;
    }
    return false;
}

/// Woop's unit-triangle test (Woop 2004; the form of Aila & Laine's
/// kernels): transform the ray into the triangle's frame, where the
/// triangle is (0,0,0), (1,0,0), (0,1,0). Fewer operations than
/// Möller–Trumbore; same conventions, but the floats differ slightly.
/// With APPROX_DIVIDE the hit distance comes from the hardware reciprocal
/// (`__fdividef`, within 2 ulp) instead of IEEE division, a sequence of
/// instructions with a slow path: closest-hit traversal is faster with it,
/// any-hit traversal faster without (BENCHMARKS.md).
template <bool APPROX_DIVIDE>
__device__ __forceinline__ bool intersect_woop(const TriRecord& tri, float3 o, float3 d, float t_max, float& t,
                                               float& u, float& v) {
    const float ow = tri.a.w + o.x * tri.a.x + o.y * tri.a.y + o.z * tri.a.z;
    const float dw = d.x * tri.a.x + d.y * tri.a.y + d.z * tri.a.z;
    const float tt = APPROX_DIVIDE ? __fdividef(-ow, dw) : -ow / dw;
    if (!(tt > 0.0f && tt < t_max)) return false;
    const float ou = tri.b.w + o.x * tri.b.x + o.y * tri.b.y + o.z * tri.b.z;
    const float du = d.x * tri.b.x + d.y * tri.b.y + d.z * tri.b.z;
    const float uu = ou + tt * du;
    if (!(uu >= 0.0f)) return false;
    const float ov = tri.c.w + o.x * tri.c.x + o.y * tri.c.y + o.z * tri.c.z;
    const float dv = d.x * tri.c.x + d.y * tri.c.y + d.z * tri.c.z;
    const float vv = ov + tt * dv;
    if (!(vv >= 0.0f && uu + vv <= 1.0f)) return false;
    t = tt;
    u = uu;
    v = vv;
    return true;
}

/// A ray prepared for box tests (as `atoll_bvh::TraversalRay`: direction
/// components below 1e-20 become ±1e-20, keeping the sign, so the inverse
/// stays finite).
struct TraversalRay {
    float3 o, d, inv_d, o_inv_d;
};

__device__ __forceinline__ float safe_inverse(float x) {
    const float tiny = 1e-20f;
    const float safe = fabsf(x) < tiny ? copysignf(tiny, x) : x;
    return __fdiv_rn(1.0f, safe);
}

__device__ __forceinline__ TraversalRay make_traversal_ray(float3 o, float3 d) {
    TraversalRay r;
    r.o = o;
    r.d = d;
    r.inv_d = make_float3(safe_inverse(d.x), safe_inverse(d.y), safe_inverse(d.z));
    r.o_inv_d = make_float3(o.x * r.inv_d.x, o.y * r.inv_d.y, o.z * r.inv_d.z);
    return r;
}

/// Slab test of both children of a node. `near*` is the entry distance
/// (clamped to 0); a child is hit when near <= far.
__device__ __forceinline__ void intersect_children(const BvhNode& n, const TraversalRay& r, float t_max,
                                                   bool& hit_left, bool& hit_right, float& near_left,
                                                   float& near_right) {
    const float l0x = fmaf(n.left_xy.x, r.inv_d.x, -r.o_inv_d.x), l1x = fmaf(n.left_xy.y, r.inv_d.x, -r.o_inv_d.x);
    const float l0y = fmaf(n.left_xy.z, r.inv_d.y, -r.o_inv_d.y), l1y = fmaf(n.left_xy.w, r.inv_d.y, -r.o_inv_d.y);
    const float l0z = fmaf(n.z.x, r.inv_d.z, -r.o_inv_d.z), l1z = fmaf(n.z.y, r.inv_d.z, -r.o_inv_d.z);
    const float r0x = fmaf(n.right_xy.x, r.inv_d.x, -r.o_inv_d.x), r1x = fmaf(n.right_xy.y, r.inv_d.x, -r.o_inv_d.x);
    const float r0y = fmaf(n.right_xy.z, r.inv_d.y, -r.o_inv_d.y), r1y = fmaf(n.right_xy.w, r.inv_d.y, -r.o_inv_d.y);
    const float r0z = fmaf(n.z.z, r.inv_d.z, -r.o_inv_d.z), r1z = fmaf(n.z.w, r.inv_d.z, -r.o_inv_d.z);
    near_left = fmaxf(fmaxf(fminf(l0x, l1x), fminf(l0y, l1y)), fmaxf(fminf(l0z, l1z), 0.0f));
    const float far_left = fminf(fminf(fmaxf(l0x, l1x), fmaxf(l0y, l1y)), fmaxf(l0z, l1z)) * BOX_ROBUST_SCALE;
    near_right = fmaxf(fmaxf(fminf(r0x, r1x), fminf(r0y, r1y)), fmaxf(fminf(r0z, r1z), 0.0f));
    const float far_right = fminf(fminf(fmaxf(r0x, r1x), fmaxf(r0y, r1y)), fmaxf(r0z, r1z)) * BOX_ROBUST_SCALE;
    hit_left = near_left <= fminf(far_left, t_max);
    hit_right = near_right <= fminf(far_right, t_max);
}

__device__ __forceinline__ BvhNode load_node(const BvhNode* nodes, int index) {
    const float4* p = reinterpret_cast<const float4*>(nodes + index);
    count_access(p);
    BvhNode n;
    n.left_xy = __ldg(p);
    n.right_xy = __ldg(p + 1);
    n.z = __ldg(p + 2);
    n.links = __ldg(reinterpret_cast<const int4*>(p + 3));
    return n;
}

__device__ __forceinline__ TriRecord load_tri(const TriRecord* tris, unsigned int index) {
    const float4* p = reinterpret_cast<const float4*>(tris + index);
    count_access(p);
    TriRecord t;
    t.a = __ldg(p);
    t.b = __ldg(p + 1);
    t.c = __ldg(p + 2);
    return t;
}

/// Everything one traversal reads (kernel arguments, gathered).
/// A compressed wide node (mirror of `atoll_bvh::CwbvhNode` through
/// `bvh::wide::GpuWideNode`, 80 bytes): origin xyz, then the exponent and
/// imask bytes; child_base, prim_base, meta[8]; lo_x[8] lo_y[8]; lo_z[8]
/// hi_x[8]; hi_y[8] hi_z[8]. Loaded as five 16-byte words.
struct __align__(16) WideNode {
    float4 w[5];
};
static_assert(sizeof(WideNode) == 80, "WideNode: size differs from Rust");

struct SceneBvhView {
    const BvhNode* tlas_nodes;
    const BvhNode* blas_nodes;
    /// The compressed wide tree (TLAS then BLASes), for the `cw` kernels only.
    const WideNode* wide_nodes;
    const TriRecord* tris;
    /// Global triangle index (into the scene's `triangles` table) per TriRecord.
    const unsigned int* tri_ids;
    const TlasInstance* instances;
    int tlas_root;
    /// Frame and scene tables for alpha masks; `alpha_params` is null
    /// unless some mesh has alpha (then candidate hits run `alpha_keeps`).
    const FrameParams* alpha_params;
    const SceneView* alpha_scene;
    /// The scene's curve pieces (records marked CURVE_RECORD_MARKER index
    /// them); null without curves.
    const GpuCurve* curves;
    /// The scene's motions (TRANSFORM_MOVING records index them); null
    /// where nothing moves.
    const GpuMotion* motions;
};

/// The result of one traversal: `tri` is the leaf-order triangle position
/// and `slot` the TLAS instance record of the closest (or any) hit.
struct TraversalHit {
    float t, u, v;
    unsigned int tri, slot;
    bool hit;
#if ATOLL_TRACE_MEDIA
    /// Any-hit queries through media: the optical depth gathered at the
    /// boundaries crossed, and the world ray (grids are in world space).
    float3 depth, world_o, world_d;
#endif
};

/// No hit yet, searching (0, t_max).
__device__ __forceinline__ TraversalHit no_hit(float t_max) {
    TraversalHit h;
    h.t = t_max;
    h.u = h.v = 0.0f;
    h.tri = h.slot = 0;
    h.hit = false;
#if ATOLL_TRACE_MEDIA
    h.depth = zero3();
#endif
    return h;
}

/// No hit yet of the ray (o, d), searching (0, t_max).
__device__ __forceinline__ TraversalHit ray_hit(float3 o, float3 d, float t_max) {
    TraversalHit h = no_hit(t_max);
#if ATOLL_TRACE_MEDIA
    h.world_o = o;
    h.world_d = d;
#else
    (void)o;
    (void)d;
#endif
    return h;
}

#include "traverse.cuh"
#include "wide.cuh"
