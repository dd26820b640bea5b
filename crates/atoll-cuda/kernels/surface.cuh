// Hit attributes from a traversal result: the GPU port of the CPU
// device's `write_hit` (atoll-render `cpu.rs`). Used by the `surface`
// kernel (wavefront.cu) and, folded into traversal, by the closest-hit
// kernels of trace.cu, which then skip the separate pass.

#include "common.cuh"
#include "record.cuh"
#include "layout.cuh"
#include "materials.cuh"
#include "params.cuh"
#include "lights.cuh"
#include "rng.cuh"
#include "texture.cuh"
#include "bump.cuh"
#include "spawn.cuh"
#include "curve.cuh"
#include "motion.cuh"

// Textured material parameters and emission textures at hits: compiled in
// unless the trace module is specialised for a frame without textures
// (`-DATOLL_WITH_TEXTURES=0`, src/trace.rs `TraceFeatures`): the texture
// calls cost the closest-hit kernels many registers.
#ifndef ATOLL_WITH_TEXTURES
#define ATOLL_WITH_TEXTURES 1
#endif

// Hits on curve pieces: compiled out of trace modules for frames without
// curves (`-DATOLL_TRACE_CURVES=0`), in everywhere else.
#ifdef ATOLL_TRACE_CURVES
#define ATOLL_WITH_CURVES ATOLL_TRACE_CURVES
#else
#define ATOLL_WITH_CURVES 1
#endif

// Hits on moving instances: compiled out of trace modules for frames where
// nothing moves (`-DATOLL_TRACE_MOTION=0`), in everywhere else.
#ifdef ATOLL_TRACE_MOTION
#define ATOLL_WITH_MOTION ATOLL_TRACE_MOTION
#else
#define ATOLL_WITH_MOTION 1
#endif

/// Where an instance is when a ray hits it: its stored transforms, or for
/// a moving one those of its motion at the ray's time (the CPU's
/// `Resident::placement`).
struct Placement {
    float object_to_world[12];
    float world_to_object[12];
    float normal_to_world[9];
};

__device__ __forceinline__ void place_instance(const FrameParams& p, const SceneView& s, const RayRecord* record,
                                               const GpuInstance& instance, Placement& out) {
    if (ATOLL_WITH_MOTION && instance.motion != NO_MOTION) {
        count_access(s.motions + instance.motion);
        const float time = ray_time_sample(p.seed, record->pixel, record->sample);
        motion_object_to_world(s.motions[instance.motion], time, out.object_to_world);
        affine_inverse(out.object_to_world, out.world_to_object, out.normal_to_world);
        return;
    }
    for (int k = 0; k < 12; ++k) {
        out.object_to_world[k] = instance.object_to_world[k];
        out.world_to_object[k] = instance.world_to_object[k];
    }
    for (int k = 0; k < 9; ++k) out.normal_to_world[k] = instance.normal_to_world[k];
}

/// Coefficient `slot` of a material's two 16-byte words, as a float.
__device__ __forceinline__ float coeff_of(uint4 c0, uint4 c1, unsigned int slot) {
    const uint4 w = slot < 8u ? c0 : c1;
    const unsigned int i = (slot % 8u) / 2u;
    const unsigned int word = i == 0u ? w.x : i == 1u ? w.y : i == 2u ? w.z : w.w;
    return f16_to_f32((unsigned short)(word >> (16u * (slot & 1u))));
}

/// Sets coefficient `slot` of a material's two 16-byte words to the f16
/// `bits`, in registers: a local array indexed by `slot` would cost every
/// hit a stack frame.
__device__ __forceinline__ void put_coeff(uint4& c0, uint4& c1, unsigned int slot, unsigned short bits) {
    const unsigned int word = slot / 2u, shift = 16u * (slot & 1u);
    const unsigned int mask = ~(0xffffu << shift), value = (unsigned int)bits << shift;
    const auto put = [&](unsigned int w, unsigned int i) { return i == word ? (w & mask) | value : w; };
    c0 = make_uint4(put(c0.x, 0u), put(c0.y, 1u), put(c0.z, 2u), put(c0.w, 3u));
    c1 = make_uint4(put(c1.x, 4u), put(c1.y, 5u), put(c1.z, 6u), put(c1.w, 7u));
}

/// Mirrors `material_coeffs::wants_tangent` with `material_layout::tangent_slot`:
/// where a hit on kind `kind` with coefficients `c0`, `c1` (textures applied)
/// carries the surface's `dpdu`, or -1 where it needs none.
__device__ __forceinline__ int wanted_tangent_slot(unsigned int kind, uint4 c0, uint4 c1) {
    if (kind == MATERIAL_HAIR) return COEFF_HAIR_TANGENT;
    if (kind == MATERIAL_MEASURED) return COEFF_MEASURED_TANGENT;
    if (kind == MATERIAL_CONDUCTOR && coeff_of(c0, c1, COEFF_CONDUCTOR_ALPHA_X) != coeff_of(c0, c1, COEFF_CONDUCTOR_ALPHA_Y))
        return COEFF_CONDUCTOR_TANGENT;
    if (kind == MATERIAL_DIELECTRIC &&
        coeff_of(c0, c1, COEFF_DIELECTRIC_ALPHA_X) != coeff_of(c0, c1, COEFF_DIELECTRIC_ALPHA_Y))
        return COEFF_DIELECTRIC_TANGENT;
    if (kind == MATERIAL_SUBSURFACE &&
        coeff_of(c0, c1, COEFF_SUBSURFACE_ALPHA_X) != coeff_of(c0, c1, COEFF_SUBSURFACE_ALPHA_Y))
        return COEFF_SUBSURFACE_TANGENT;
    if (kind == MATERIAL_COATED_DIFFUSE &&
        coeff_of(c0, c1, COEFF_COATED_DIFFUSE_ALPHA_X) != coeff_of(c0, c1, COEFF_COATED_DIFFUSE_ALPHA_Y))
        return COEFF_COATED_DIFFUSE_TANGENT;
    return -1;
}

/// Fills the hit fields of `record` for `hit` (which found something).
/// `t_max` was already shrunk by traversal. Not inlined: traversal kernels
/// call it once per ray and should keep their own register budget.
__device__ __noinline__ void write_surface(const FrameParams& p, const SceneView& s, RayRecord* record,
                                           const HitRef hit) {
    Placement instance;
    place_instance(p, s, record, s.instances[hit.instance], instance);
    const GpuMesh& mesh = s.meshes[s.triangle_mesh[hit.triangle]];
    const unsigned int i0 = s.triangles[3ull * hit.triangle + 0];
    const unsigned int i1 = s.triangles[3ull * hit.triangle + 1];
    const unsigned int i2 = s.triangles[3ull * hit.triangle + 2];
    count_access(s.instances + hit.instance);
    count_access(s.triangle_mesh + hit.triangle);
    count_access(s.meshes + s.triangle_mesh[hit.triangle]);
    count_access(s.triangles + 3ull * hit.triangle);
    count_access(s.vertices + 3ull * i0);
    count_access(s.vertices + 3ull * i1);
    count_access(s.vertices + 3ull * i2);
    const float b1 = hit.u, b2 = hit.v;
    const float b0 = 1.0f - b1 - b2;
    // Interpolating the vertices is more precise than origin + t * direction.
    const float3 p0 = load3(s.vertices + 3ull * i0);
    const float3 p1 = load3(s.vertices + 3ull * i1);
    const float3 p2 = load3(s.vertices + 3ull * i2);
    float3 position, position_error, ng, ns;
    // A curve piece's surface (the CPU's `curve_surface`): the world
    // partial derivatives here, the hit's (u, v) its uv.
    const bool curve = ATOLL_WITH_CURVES && (mesh.flags & MESH_CURVES);
    float3 curve_dpdu = zero3(), curve_dpdv = zero3();
    if (curve) {
        const unsigned int c = s.curve_of[hit.triangle];
        count_access(s.curve_of + hit.triangle);
        count_access(s.curves + c);
        const float3 dir = make_float3(record->direction[0], record->direction[1], record->direction[2]);
        const float3 origin = make_float3(record->origin[0], record->origin[1], record->origin[2]);
        const float3 d_obj = affine_vector(instance.world_to_object, dir);
        const float3 o_obj = affine_point(instance.world_to_object, origin);
        float3 dpdu, dpdv, n_obj;
        const float width = curve_surface(load_curve(s.curves, c), b1, b2, d_obj, &dpdu, &dpdv, &n_obj);
        const float3 p_obj = o_obj + d_obj * record->t_max;
        position = affine_point(instance.object_to_world, p_obj);
        position_error = transformed_error(instance.object_to_world, p_obj, make_float3(width, width, width));
        if (mesh.flags & MESH_FLIP_NORMALS) n_obj = -n_obj;
        ng = normalize_or_zero3(mat3_mul(instance.normal_to_world, n_obj));
        ns = ng;
        curve_dpdu = affine_vector(instance.object_to_world, dpdu);
        curve_dpdv = affine_vector(instance.object_to_world, dpdv);
    } else {
        const float3 p_obj = p0 * b0 + p1 * b1 + p2 * b2;
        position = affine_point(instance.object_to_world, p_obj);
        position_error = transformed_error(instance.object_to_world, p_obj,
                                           barycentric_magnitude(p0, p1, p2, make_float3(b0, b1, b2)) * GAMMA_7);
        // TriangleMesh::geometric_normal: pbrt's orientation rule.
        float3 n_obj = cross3(p0 - p2, p1 - p2);
        if (mesh.flags & MESH_FLIP_NORMALS) n_obj = -n_obj;
        ng = normalize_or_zero3(mat3_mul(instance.normal_to_world, n_obj));
        ns = ng;
        if (mesh.flags & MESH_HAS_NORMALS) {
            count_access(s.normals + 3ull * i0);
            count_access(s.normals + 3ull * i1);
            count_access(s.normals + 3ull * i2);
            const float3 n = load3(s.normals + 3ull * i0) * b0 + load3(s.normals + 3ull * i1) * b1 +
                             load3(s.normals + 3ull * i2) * b2;
            const float3 shading = normalize_or_zero3(mat3_mul(instance.normal_to_world, n));
            // pbrt: interpolated normals are authoritative for orientation.
            if (!is_zero3(shading) && dot3(ng, shading) < 0.0f) ng = -ng;
            ns = is_zero3(shading) ? ng : shading;
        }
    }
    // The hit's uv: a curve's (u, v), a triangle's interpolated (or pbrt's default).
    const auto surface_uv = [&]() {
        return curve ? make_float2(b1, b2) : hit_uv(s, mesh, i0, i1, i2, b1, b2);
    };
    const unsigned int light = (mesh.flags & MESH_EMISSIVE)
                                   ? light_triangle_index(p, hit.instance, mesh.scene_mesh,
                                                          hit.triangle - mesh.first_triangle + mesh.first_scene_triangle)
                                   : NO_LIGHT;
    // FrameContext::material_at: a mix becomes one of its materials, chosen
    // with the vertex's material-choice number (rescaled for nested mixes).
    // The material's three 16-byte words (coefficients; kind and mix fields)
    // are loaded together before the mix test: loading the kind first and
    // the coefficients after the branch serialised two memory round trips
    // per hit (measurably slower on the Cornell-box benchmark).
    const uint4* mw = reinterpret_cast<const uint4*>(p.materials + mesh.material);
    uint4 c0 = mw[0], c1 = mw[1], meta = mw[2];  // coeffs[0..8], coeffs[8..16], (kind, pad[0..3])
    if (meta.x == MATERIAL_MIX) {
        float u = stream_bounce(sample_stream(p.seed, record->pixel, record->sample), record->depth,
                                BOUNCE_DIM_MATERIAL_CHOICE, 0);
        for (unsigned int level = 0; level < MAX_MIX_DEPTH && meta.x == MATERIAL_MIX; ++level) {
            float amount = __uint_as_float(meta.w);
#if ATOLL_WITH_TEXTURES
            // A textured amount: its program's range in the first two words.
            static_assert(COEFF_MIX_AMOUNT_PROGRAM == 0, "c0.x, c0.y are the mix amount's program range");
            if (c0.y != 0u) {
                ProgramRange range;
                range.start = c0.x;
                range.len = c0.y;
                amount = clampf(
                    run_program(p, range, surface_uv(), position, ng, nullptr).x, 0.0f, 1.0f);
            }
#endif
            unsigned int next;
            if (u < amount) {
                next = meta.z;
                u = __fdiv_rn(u, amount);
            } else {
                next = meta.y;
                u = __fdiv_rn(u - amount, 1.0f - amount);
            }
            mw = reinterpret_cast<const uint4*>(p.materials + next);
            c0 = mw[0];
            c1 = mw[1];
            meta = mw[2];
        }
    }
    // The surface's partial derivatives (world space), for a texture's
    // footprint, a bump or normal map and the BSDF frame's tangent.
    const auto partials = [&](float3* dpdu, float3* dpdv) {
        *dpdu = curve_dpdu;
        *dpdv = curve_dpdv;
        if (curve) return;
        float2 uv0 = make_float2(0.0f, 0.0f), uv1 = make_float2(1.0f, 0.0f), uv2 = make_float2(1.0f, 1.0f);
        if (mesh.flags & MESH_HAS_UVS) {
            uv0 = make_float2(s.uvs[2ull * i0], s.uvs[2ull * i0 + 1]);
            uv1 = make_float2(s.uvs[2ull * i1], s.uvs[2ull * i1 + 1]);
            uv2 = make_float2(s.uvs[2ull * i2], s.uvs[2ull * i2 + 1]);
        }
        triangle_partials(affine_point(instance.object_to_world, p0), affine_point(instance.object_to_world, p1),
                          affine_point(instance.object_to_world, p2), uv0, uv1, uv2, ng, dpdu, dpdv);
    };
    // Textured parameters (texture.cuh): a non-mix material's program
    // range is in meta.y (start) and meta.z (length).
    if (ATOLL_WITH_TEXTURES && meta.z != 0u) {
        // uint4 storage keeps the 16-byte alignment the word copies need.
        uint4 cw[2] = {c0, c1};
        unsigned short* coeffs = reinterpret_cast<unsigned short*>(cw);
        const float2 uv = surface_uv();
        ProgramRange range;
        range.start = meta.y;
        range.len = meta.z;
        float3 dpdu, dpdv;
        partials(&dpdu, &dpdv);
        const TexFootprint fp = hit_footprint(p.footprint, position, ng, dpdu, dpdv);
        run_program(p, range, uv, position, ng, coeffs, &fp);
        c0 = cw[0];
        c1 = cw[1];
    }
    // A hair hit's offset across the fibre (material_coeffs::hair_offset_at).
    if (meta.x == MATERIAL_HAIR) {
        put_coeff(c0, c1, COEFF_HAIR_OFFSET, f32_to_f16(clampf(-1.0f + 2.0f * surface_uv().y, -1.0f, 1.0f)));
    }
    // The chosen material's bump or normal map (GpuMaterial's bend word in
    // meta.w: kind << 30 | start << 8 | len), and the BSDF frame's tangent,
    // as the CPU's write_hit: both need the surface's partial derivatives.
    const bool bends = ATOLL_WITH_TEXTURES && meta.x != MATERIAL_MIX && meta.w != 0u;
    const int tangent_slot = wanted_tangent_slot(meta.x, c0, c1);
    if (bends || tangent_slot >= 0) {
        float3 dpdu, dpdv;
        partials(&dpdu, &dpdv);
        if (bends) {
            ProgramRange range;
            range.start = (meta.w >> 8) & 0x3fffffu;
            range.len = meta.w & 0xffu;
            float3 bent_dpdu;
            const TexFootprint fp = hit_footprint(p.footprint, position, ng, dpdu, dpdv);
            ns = bent_normal(p, meta.w >> 30, range, position, surface_uv(), ng, ns, dpdu, dpdv,
                             (mesh.flags & MESH_HAS_NORMALS) != 0u, fp, &bent_dpdu);
            dpdu = bent_dpdu;
        }
        // material_coeffs::store_tangent.
        if (tangent_slot >= 0) {
            const float3 t = normalize_or_zero3(dpdu);
            put_coeff(c0, c1, tangent_slot, f32_to_f16(t.x));
            put_coeff(c0, c1, tangent_slot + 1, f32_to_f16(t.y));
            put_coeff(c0, c1, tangent_slot + 2, f32_to_f16(t.z));
        }
    }
    // The record's bytes [32, 128) are written as whole 16-byte words, three
    // full 32-byte sectors: field-by-field stores of the hit leave partial
    // sectors that the memory system must merge (or, with ECC, read first).
    // Byte offsets are those of record.rs (checked by the asserts in record.cuh).
    uint4* words = reinterpret_cast<uint4*>(record);
    const uint4 w2 = words[2];  // throughput, sample: unchanged
    uint4 w3 = words[3];        // bsdf_pdf, depth | flags << 16, light, instance
    w3.y |= (unsigned int)FLAG_HIT << 16;
    w3.z = light;
    w3.w = hit.instance;
    // position, emission_scale (LightSet::emission_scale: textured emitters only)
    const unsigned int emission_scale =
        ATOLL_WITH_TEXTURES && light != NO_LIGHT && p.emitters[light].table != NO_EMISSION_TEXTURE
            ? pack_rgb9e5(emission_texture_value(p, p.emitters[light].table, make_float3(b0, b1, b2)))
            : 0u;
    const uint4 w4 = make_uint4(__float_as_uint(position.x), __float_as_uint(position.y),
                                __float_as_uint(position.z), emission_scale);
    const unsigned int ng0 = f32_to_f16(ng.x), ng1 = f32_to_f16(ng.y), ng2 = f32_to_f16(ng.z);
    const unsigned int ns0 = f32_to_f16(ns.x), ns1 = f32_to_f16(ns.y), ns2 = f32_to_f16(ns.z);
    // geometric_normal, material, shading_normal, position_error
    const unsigned int error_bits = pack_error(error_along(ng, position_error));
    // material: the kind, and above it the mesh's media (RayRecord::set_hit_media).
    const unsigned int material = (meta.x & 0xffu) | ((mesh.flags >> MESH_MEDIA_SHIFT) & 0xffu) << 8;
    const uint4 w5 = make_uint4(ng0 | ng1 << 16, ng2 | material << 16, ns0 | ns1 << 16, ns2 | error_bits << 16);
    words[2] = w2;
    words[3] = w3;
    words[4] = w4;
    words[5] = w5;
    words[6] = c0;
    words[7] = c1;
}
