// Two-level BVH traversal (included by bvh.cuh; instantiated by trace.cu).
//
// One stack serves both levels: on reaching a TLAS leaf, LINK_INSTANCE_END
// is pushed, the ray is moved into object space with the instance's
// world_to_object (direction not renormalised, so t means the same in both
// spaces) and traversal continues at the BLAS root; popping the marker
// restores the world ray and the TLAS node array.
//
// Two loop structures from Aila & Laine 2009:
// - while-while: descend inner nodes until a leaf, then test leaves until
//   an inner node is popped (threads of a warp test triangles together);
// - speculative while-while: a thread that reaches a leaf postpones it and
//   keeps descending until every thread of the warp has a leaf (__any_sync),
//   so the warp stays busy in the inner loop. Its warp votes need every
//   lane of `mask` to run the outer and inner loops in step: those loops
//   are written with warp-uniform trip counts.
#pragma once

// Alpha masks tested during traversal: only in the trace module compiled
// for scenes with alpha (`-DATOLL_TRACE_ALPHA=1`, src/trace.rs
// `TraceFeatures`): the call inside the triangle loop costs the kernels
// registers and stack even where it is never taken.
#ifndef ATOLL_TRACE_ALPHA
#define ATOLL_TRACE_ALPHA 0
#endif

// Shadow rays crossing surfaces that only bound media (`-DATOLL_TRACE_MEDIA=1`,
// scenes with media, which also have ATOLL_TRACE_ALPHA): such a candidate
// is no hit, and the change of σt across it adds to the ray's depth
// (media.cuh `medium_crossing`).
#ifndef ATOLL_TRACE_MEDIA
#define ATOLL_TRACE_MEDIA 0
#endif

// Curve pieces among the triangle records (`-DATOLL_TRACE_CURVES=1`,
// scenes with curves): a record marked CURVE_RECORD_MARKER is tested as
// the curve piece it names (curve.cuh).
#ifndef ATOLL_TRACE_CURVES
#define ATOLL_TRACE_CURVES 0
#endif

// Moving instances (`-DATOLL_TRACE_MOTION=1`, scenes with motion blur): a
// record marked TRANSFORM_MOVING takes its transform from its motion at
// the ray's time (motion.cuh).
#ifndef ATOLL_TRACE_MOTION
#define ATOLL_TRACE_MOTION 0
#endif

// BLAS leaf links counting from their instance record's tri_base (a BVH
// built in pieces, src/bvh/pieces.rs; `-DATOLL_TRI_BASES=1`): elsewhere
// every base is 0, and adding it measured a few percent slower.
#ifndef ATOLL_TRI_BASES
#define ATOLL_TRI_BASES 0
#endif

/// The ray of instance record `s` in object space (`world` unchanged for an
/// identity instance, kept in `ray`) and its BLAS's first record in
/// `tri_base`; returns the record's BLAS root. `time`: the ray's time
/// sample (moving instances).
__device__ __forceinline__ int instance_ray(const SceneBvhView& v, unsigned int s, const TraversalRay& world,
                                            TraversalRay& ray, unsigned int& tri_base, float time) {
    const float4* p = reinterpret_cast<const float4*>(v.instances + s);
    count_access(p);
    const int4 meta = __ldg(reinterpret_cast<const int4*>(p + 3));
    tri_base = (unsigned int)meta.w;
    if (meta.z != TRANSFORM_IDENTITY) {
        float4 m0, m1, m2;
#if ATOLL_TRACE_MOTION
        if (meta.z == TRANSFORM_MOVING) {
            const unsigned int motion = __float_as_uint(__ldg(&p->x));
            count_access(v.motions + motion);
            float to_world[12], m[12];
            motion_object_to_world(v.motions[motion], time, to_world);
            affine_inverse(to_world, m, nullptr);
            m0 = make_float4(m[0], m[1], m[2], m[3]);
            m1 = make_float4(m[4], m[5], m[6], m[7]);
            m2 = make_float4(m[8], m[9], m[10], m[11]);
        } else
#endif
        {
            (void)time;
            m0 = __ldg(p);
            m1 = __ldg(p + 1);
            m2 = __ldg(p + 2);
        }
        const float3 o = world.o, d = world.d;
        // glam's Affine3A::transform_point3a / transform_vector3a, rounding included.
        ray = make_traversal_ray(
            make_float3(affine_row_rn(m0, o, true), affine_row_rn(m1, o, true), affine_row_rn(m2, o, true)),
            make_float3(affine_row_rn(m0, d, false), affine_row_rn(m1, d, false), affine_row_rn(m2, d, false)));
    }
    return meta.x;
}

/// Per-thread traversal state, in registers; the stack it points to is a
/// separate array in local memory (a struct holding the array would be put
/// in local memory whole).
struct Traversal {
    TraversalRay ray;    // in the current space
    TraversalRay world;  // the world ray, restored when leaving an instance
    const BvhNode* nodes;
    bool in_blas;
    unsigned int slot;   // TLAS instance record being traversed
    unsigned int tri_base;  // its BLAS's first triangle record
    float time;             // the ray's time sample (moving instances)
    int sp;
    int* stack;

    __device__ __forceinline__ void push(int link) {
        if (sp < TRAVERSAL_STACK - 1) stack[++sp] = link;
    }
    /// Pops the next link; the bottom entry LINK_DONE stays (popping it again returns it again).
    __device__ __forceinline__ int pop() {
        const int link = stack[sp];
        sp = sp > 0 ? sp - 1 : 0;
        return link;
    }

    /// Moves into instance record `s`; returns its BLAS root link.
    __device__ __forceinline__ int enter_instance(const SceneBvhView& v, unsigned int s) {
        const int root = instance_ray(v, s, world, ray, tri_base, time);
        nodes = v.blas_nodes;
        in_blas = true;
        slot = s;
        return root;
    }

    __device__ __forceinline__ void leave_instance(const SceneBvhView& v) {
        ray = world;
        nodes = v.tlas_nodes;
        in_blas = false;
    }

    /// One inner-node step: visit the nearer hit child, push the farther,
    /// or pop when neither is hit.
    __device__ __forceinline__ int step(int node, float t_max) {
        const BvhNode n = load_node(nodes, node);
        bool hit_left, hit_right;
        float near_left, near_right;
        intersect_children(n, ray, t_max, hit_left, hit_right, near_left, near_right);
        if (!hit_left && !hit_right) return pop();
        int next = hit_left ? n.links.x : n.links.y;
        if (hit_left && hit_right) {
            int other = n.links.y;
            if (near_right < near_left) {
                next = n.links.y;
                other = n.links.x;
            }
            push(other);
        }
        return next;
    }
};

__device__ __forceinline__ void init_traversal(Traversal& tr, int* stack, const SceneBvhView& v, float3 o,
                                               float3 d, float time) {
    tr.stack = stack;
    tr.time = time;
    tr.world = make_traversal_ray(o, d);
    tr.ray = tr.world;
    tr.nodes = v.tlas_nodes;
    tr.in_blas = false;
    tr.slot = 0;
    tr.tri_base = 0;
    tr.sp = 0;
    tr.stack[0] = LINK_DONE;
}

/// Tests triangle records `first .. first + count` of instance record `slot`
/// against `ray`; returns whether one was hit (with ANY, stops at the first).
/// APPROX: Woop tests divide with the hardware reciprocal (`intersect_woop`).
template <int TRI, bool ANY, bool APPROX = !ANY>
__device__ __forceinline__ bool test_triangles(const SceneBvhView& v, const TraversalRay& ray, unsigned int slot,
                                               unsigned int first, unsigned int count, TraversalHit& h) {
    bool any = false;
    for (unsigned int k = 0; k < count; ++k) {
        const TriRecord tri = load_tri(v.tris, first + k);
        float t, u, w;
        bool hit;
#if ATOLL_TRACE_CURVES
        if (__float_as_uint(tri.a.w) == CURVE_RECORD_MARKER) {
            count_access(v.curves + __float_as_uint(tri.a.x));
            hit = intersect_curve<ANY>(load_curve(v.curves, __float_as_uint(tri.a.x)), ray.o, ray.d, h.t, t, u, w);
        } else
#endif
            hit = TRI == TRI_EXACT ? intersect_exact(tri, ray.o, ray.d, h.t, t, u, w)
                                   : intersect_woop<APPROX>(tri, ray.o, ray.d, h.t, t, u, w);
#if ATOLL_TRACE_ALPHA
        // Alpha masks (texture.cuh): a cut-out candidate is no hit.
        if (hit && v.alpha_params) {
            count_access(v.tri_ids + first + k);
            hit = alpha_keeps(*v.alpha_params, *v.alpha_scene, __ldg(v.tri_ids + first + k), u, w, t, ray.o, ray.d);
#if ATOLL_TRACE_MEDIA
            if (ANY && hit) {
                unsigned int before = 0, after = 0;
                hit = medium_crossing(*v.alpha_scene, __ldg(v.tri_ids + first + k), u, w, ray.d, &before, &after);
                // Any-hit traversal never shrinks h.t: it is the ray's t_max.
                if (!hit) {
                    const FrameParams& p = *v.alpha_params;
                    h.depth = h.depth + medium_optical_depth(p, after, h.world_o, h.world_d, t, h.t) -
                              medium_optical_depth(p, before, h.world_o, h.world_d, t, h.t);
                }
            }
#endif
        }
#endif
        if (hit) {
            h.t = t;
            h.u = u;
            h.v = w;
            h.tri = first + k;
            h.slot = slot;
            h.hit = true;
            any = true;
            if (ANY) break;
        }
    }
    return any;
}

/// Tests the triangles of BLAS leaf `leaf`.
template <int TRI, bool ANY>
__device__ __forceinline__ bool test_leaf(const SceneBvhView& v, const Traversal& tr, int leaf, TraversalHit& h) {
    const unsigned int base = ATOLL_TRI_BASES ? tr.tri_base : 0u;
    return test_triangles<TRI, ANY>(v, tr.ray, tr.slot, base + leaf_first(leaf), leaf_count(leaf), h);
}

/// While-while traversal of the ray (o, d) at time sample `time` with
/// hits in (0, t_max).
template <int TRI, bool ANY>
__device__ TraversalHit traverse_while_while(const SceneBvhView& v, float3 o, float3 d, float t_max, float time) {
    TraversalHit h = ray_hit(o, d, t_max);
    int stack[TRAVERSAL_STACK];
    Traversal tr;
    init_traversal(tr, stack, v, o, d, time);
    int node = v.tlas_root;
    while (node != LINK_DONE) {
        // Inner nodes (0 <= node < LINK_DONE) until a leaf or a marker.
        while ((unsigned int)node < (unsigned int)LINK_DONE) node = tr.step(node, h.t);
        // Leaves until an inner node or a marker comes off the stack.
        while (node < 0) {
            if (!tr.in_blas) {
                tr.push(LINK_INSTANCE_END);
                node = tr.enter_instance(v, leaf_first(node));
                continue;
            }
            if (test_leaf<TRI, ANY>(v, tr, node, h) && ANY) return h;
            node = tr.pop();
        }
        if (node == LINK_INSTANCE_END) {
            tr.leave_instance(v);
            node = tr.pop();
        }
    }
    return h;
}

/// Speculative while-while traversal (Aila & Laine 2009, section 4): like
/// `traverse_while_while`, but a lane that finds a leaf postpones it and
/// keeps traversing until all lanes of `mask` (the lanes calling this,
/// together) hold a leaf. Every lane of `mask` must call it.
template <int TRI, bool ANY>
__device__ TraversalHit traverse_speculative(const SceneBvhView& v, float3 o, float3 d, float t_max, float time,
                                             unsigned int mask) {
    TraversalHit h = ray_hit(o, d, t_max);
    int stack[TRAVERSAL_STACK];
    Traversal tr;
    init_traversal(tr, stack, v, o, d, time);
    int node = v.tlas_root;
    int leaf = 0;  // the postponed leaf link; >= 0 means none
    while (__any_sync(mask, node != LINK_DONE || leaf < 0)) {
        // A leaf popped from the stack (or a root that is a leaf) becomes the postponed leaf.
        if (node < 0 && leaf >= 0) {
            leaf = node;
            node = tr.pop();
        }
        bool searching = true;
        for (;;) {
            const bool inner = (unsigned int)node < (unsigned int)LINK_DONE;
            if (!__any_sync(mask, inner && searching)) break;
            if (inner) {
                node = tr.step(node, h.t);
                if (node < 0 && leaf >= 0) {
                    searching = false;
                    leaf = node;
                    node = tr.pop();
                }
            }
        }
        while (leaf < 0) {
            if (!tr.in_blas) {
                // Enter the instance; the TLAS continues later from `node`.
                tr.push(node);
                tr.push(LINK_INSTANCE_END);
                node = tr.enter_instance(v, leaf_first(leaf));
                leaf = 0;
                if (node < 0) {
                    leaf = node;
                    node = tr.pop();
                }
                continue;
            }
            if (test_leaf<TRI, ANY>(v, tr, leaf, h) && ANY) {
                // Done, but keep voting with the other lanes until they are.
                node = LINK_DONE;
                leaf = 0;
                break;
            }
            leaf = node;
            if (node < 0) node = tr.pop();
        }
        if (node == LINK_INSTANCE_END) {
            tr.leave_instance(v);
            node = tr.pop();
        }
    }
    return h;
}
