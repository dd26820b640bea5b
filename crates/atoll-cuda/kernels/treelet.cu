// The LBVH's quality pass (host side: src/bvh/lbvh.rs): treelet
// restructuring, Karras & Aila 2013, "Fast parallel construction of
// high-quality bounding volume hierarchies".
//
// One launch is one round: a bottom-up pass like lbvh_bounds (one thread
// per leaf, the second thread to reach a node goes on), and every node
// with at least `gamma` primitives becomes the root of a treelet of 7
// leaves (grown by repeatedly opening the leaf with the largest surface
// area), whose topology is replaced by the SAH-optimal one over those 7
// subtrees. The optimum comes from dynamic programming over the 127
// non-empty subsets of the leaves, by increasing size; the costs include
// the option of collapsing a subset into one leaf (<= max_leaf
// primitives), so the tree is optimised for the collapse that follows.
// A treelet is processed by a whole warp: lanes that have a treelet root
// queue it (__ballot_sync) and the warp takes them one at a time.

#include "lbvh.cuh"

#define TREELET_THREADS 128
#define TREELET_WARPS (TREELET_THREADS / 32)
#define TREELET_LEAVES 7
#define TREELET_SUBSETS (1 << TREELET_LEAVES)
#define TREELET_LOW_LEAVES 4
#define TREELET_LOW_SUBSETS (1 << TREELET_LOW_LEAVES)
#define TREELET_PARTS (TREELET_LOW_SUBSETS + (1 << (TREELET_LEAVES - TREELET_LOW_LEAVES)))
static_assert(TREELET_PARTS <= 32, "a lane per half-subset box");
// Levels of the root's subtree fetched before the treelet is formed (the
// root and three below it: the seven leaves mostly lie there).
#define TREELET_TOP_LEVELS 4
#define TREELET_TOP (1 << TREELET_TOP_LEVELS)
static_assert(TREELET_TOP_LEVELS >= 2, "the root's children are taken from the fetched top");

/// The non-empty subsets of 7 leaves ordered by size; those of size k are
/// at [SUBSET_START[k], SUBSET_START[k + 1]).
__constant__ unsigned char SUBSETS_BY_SIZE[TREELET_SUBSETS - 1] = {
    1,   2,   4,   8,   16,  32,  64,  3,   5,   6,   9,   10,  12,  17,  18,  20,  24,  33,  34,  36,  40,  48,
    65,  66,  68,  72,  80,  96,  7,   11,  13,  14,  19,  21,  22,  25,  26,  28,  35,  37,  38,  41,  42,  44,
    49,  50,  52,  56,  67,  69,  70,  73,  74,  76,  81,  82,  84,  88,  97,  98,  100, 104, 112, 15,  23,  27,
    29,  30,  39,  43,  45,  46,  51,  53,  54,  57,  58,  60,  71,  75,  77,  78,  83,  85,  86,  89,  90,  92,
    99,  101, 102, 105, 106, 108, 113, 114, 116, 120, 31,  47,  55,  59,  61,  62,  79,  87,  91,  93,  94,  103,
    107, 109, 110, 115, 117, 118, 121, 122, 124, 63,  95,  111, 119, 123, 125, 126, 127};
__constant__ unsigned char SUBSET_START[TREELET_LEAVES + 2] = {0, 0, 7, 28, 63, 98, 119, 126, 127};

/// One warp's scratch for the treelet it is restructuring.
struct TreeletScratch {
    float area[TREELET_SUBSETS];
    float cost[TREELET_SUBSETS];
    unsigned int count[TREELET_SUBSETS];
    unsigned char partition[TREELET_SUBSETS];  // the best left side of each subset
    unsigned char as_leaf[TREELET_SUBSETS];
    unsigned int leaf_node[TREELET_LEAVES];
    unsigned int inner_node[TREELET_LEAVES - 1];
    float4 lo[TREELET_LEAVES], hi[TREELET_LEAVES];  // w: subtree cost / packed count
    // Boxes of the subsets of the low leaves (0..TREELET_LOW_LEAVES) at
    // [0, TREELET_LOW_SUBSETS) and of the high ones after them (w of
    // part_hi: the primitive count): every subset's box is the union of one
    // of each, so it takes one union, not one per leaf.
    float4 part_lo[TREELET_PARTS], part_hi[TREELET_PARTS];
    int leaves;
    // The top of the root's subtree, fetched by the lanes level by level
    // (heap order: slot 1 the root, slot s's children 2s and 2s + 1), so
    // that forming the treelet seldom loads one node after another. (It
    // measured neither faster nor slower than lane 0 loading them: the
    // pass is bound by the instructions it issues, BENCHMARKS.md.)
    unsigned int top_node[TREELET_TOP];
    uint2 top_child[TREELET_TOP];
    float4 top_lo[TREELET_TOP], top_hi[TREELET_TOP];
    float top_area[TREELET_TOP];
    float leaf_area[TREELET_LEAVES];
    unsigned char leaf_slot[TREELET_LEAVES];  // 0: not in the top
    // The rebuilt inner nodes and their subsets (root first), whose boxes
    // the lanes write at once.
    unsigned int rebuilt_node[TREELET_LEAVES - 1];
    unsigned char rebuilt_set[TREELET_LEAVES - 1];
};

/// Box of subset `s` of the treelet's leaves from the half-subset boxes;
/// returns its primitive count.
__device__ __forceinline__ unsigned int subset_box(const TreeletScratch& sh, unsigned int s, float3& lo, float3& hi) {
    const unsigned int low = s & (TREELET_LOW_SUBSETS - 1u), high = TREELET_LOW_SUBSETS + (s >> TREELET_LOW_LEAVES);
    const float4 llo = sh.part_lo[low], lhi = sh.part_hi[low], hlo = sh.part_lo[high], hhi = sh.part_hi[high];
    lo = min3f(xyz(llo), xyz(hlo));
    hi = max3f(xyz(lhi), xyz(hhi));
    return __float_as_uint(lhi.w) + __float_as_uint(hhi.w);
}

/// Records the best split `best_left` (cost `children`) of subset `s`.
__device__ __forceinline__ void finish_subset(TreeletScratch& sh, unsigned int s, float children,
                                              unsigned int best_left, unsigned int max_leaf, float ci, float ct) {
    unsigned int packed;
    sh.cost[s] = sah_node_cost(sh.area[s], sh.count[s], children, max_leaf, ci, ct, packed);
    sh.partition[s] = (unsigned char)best_left;
    sh.as_leaf[s] = (packed & BUILD_LEAF_BIT) ? 1 : 0;
}

/// The cheapest split of subset `s` (at least 2 leaves): every partition
/// once, by fixing its highest leaf on the left, its other leaves `q`
/// taken in decreasing order; ties go to the first (the order the host
/// reference and the size-6 lane groups below keep).
__device__ __forceinline__ void evaluate_subset(TreeletScratch& sh, unsigned int s, unsigned int max_leaf, float ci,
                                                float ct) {
    const unsigned int high = 1u << (31 - __clz(s));
    const unsigned int rest = s ^ high;
    const int partitions = (1 << __popc(rest)) - 1;
    float best = __int_as_float(0x7f800000);
    unsigned int best_left = high;
    unsigned int q = (rest - 1u) & rest;
#pragma unroll 4
    for (int at = 0; at < partitions; ++at) {
        const unsigned int left = high | q;
        const float c = __fadd_rn(sh.cost[left], sh.cost[s ^ left]);
        if (c < best) {
            best = c;
            best_left = left;
        }
        q = (q - 1u) & rest;
    }
    finish_subset(sh, s, best, best_left, max_leaf, ci, ct);
}

/// Fetches the top of the subtree under `root` into `sh.top_*`, one level
/// per step, a lane per node (through L2: other warps wrote the nodes in
/// this launch). Called by all 32 lanes.
__device__ __forceinline__ void fetch_top(TreeletScratch& sh, unsigned int root, unsigned int P, const uint2* child,
                                          const float4* node_lo, const float4* node_hi) {
    const unsigned int lane = threadIdx.x & 31u;
    for (int level = 0; level < TREELET_TOP_LEVELS; ++level) {
        const unsigned int first = 1u << level;
        if (lane < first) {
            const unsigned int slot = first + lane;
            unsigned int n = root;
            if (level > 0) {
                const unsigned int up = slot >> 1;
                const unsigned int parent = sh.top_node[up];
                n = parent < P ? ((slot & 1u) ? sh.top_child[up].y : sh.top_child[up].x) : BUILD_NONE;
            }
            sh.top_node[slot] = n;
            if (n != BUILD_NONE && level > 0) {
                const float4 lo = __ldcg(node_lo + n), hi = __ldcg(node_hi + n);
                sh.top_lo[slot] = lo;
                sh.top_hi[slot] = hi;
                sh.top_area[slot] = box_area(xyz(lo), xyz(hi));
            }
            if (n < P) sh.top_child[slot] = __ldcg(child + n);
        }
        __syncwarp();
    }
}

/// Makes node `n` treelet leaf `k`: from the fetched top where it is there
/// (`slot` not 0), else from memory.
__device__ __forceinline__ void take_treelet_leaf(TreeletScratch& sh, int k, unsigned int n, unsigned int slot,
                                                  const float4* node_lo, const float4* node_hi) {
    sh.leaf_node[k] = n;
    sh.leaf_slot[k] = (unsigned char)slot;
    if (slot != 0) {
        sh.lo[k] = sh.top_lo[slot];
        sh.hi[k] = sh.top_hi[slot];
        sh.leaf_area[k] = sh.top_area[slot];
    } else {
        const float4 lo = __ldcg(node_lo + n), hi = __ldcg(node_hi + n);
        sh.lo[k] = lo;
        sh.hi[k] = hi;
        sh.leaf_area[k] = box_area(xyz(lo), xyz(hi));
    }
}

/// Restructures the treelet rooted at `root`; called by all 32 lanes.
__device__ void restructure(TreeletScratch& sh, unsigned int root, unsigned int P, uint2* child,
                            unsigned int* parent, float4* node_lo, float4* node_hi, unsigned int max_leaf, float ci,
                            float ct) {
    const unsigned int lane = threadIdx.x & 31u;
    fetch_top(sh, root, P, child, node_lo, node_hi);
    // Form the treelet: open the largest-area leaf until there are 7 (the
    // lanes find it, ties to the first; lane 0 opens it).
    if (lane == 0) {
        const uint2 c = sh.top_child[1];
        sh.inner_node[0] = root;
        take_treelet_leaf(sh, 0, c.x, 2, node_lo, node_hi);
        take_treelet_leaf(sh, 1, c.y, 3, node_lo, node_hi);
    }
    __syncwarp();
    int leaves = 2;
    while (leaves < TREELET_LEAVES) {
        float a = lane < (unsigned int)leaves && sh.leaf_node[lane] < P ? sh.leaf_area[lane] : -1.0f;
        int best = (int)lane;
        for (int d = 4; d >= 1; d >>= 1) {
            const float other = __shfl_xor_sync(0xffffffffu, a, d);
            const int other_best = __shfl_xor_sync(0xffffffffu, best, d);
            if (other > a || (other == a && other_best < best)) {
                a = other;
                best = other_best;
            }
        }
        best = __shfl_sync(0xffffffffu, best, 0);
        if (__shfl_sync(0xffffffffu, a, 0) < 0.0f) break;  // every leaf a primitive
        if (lane == 0) {
            const unsigned int opened = sh.leaf_node[best], slot = sh.leaf_slot[best];
            const uint2 oc = slot != 0 ? sh.top_child[slot] : __ldcg(child + opened);
            const unsigned int below = 2u * slot < TREELET_TOP ? 2u * slot : 0u;
            sh.inner_node[leaves - 1] = opened;
            take_treelet_leaf(sh, best, oc.x, below, node_lo, node_hi);
            take_treelet_leaf(sh, leaves, oc.y, below ? below + 1u : 0u, node_lo, node_hi);
        }
        __syncwarp();
        ++leaves;
    }
    if (lane == 0) sh.leaves = leaves;
    __syncwarp();
    if (sh.leaves < TREELET_LEAVES) return;  // fewer than 7 primitives (gamma < 7)

    // Boxes, areas and primitive counts of all subsets (each the union of
    // a low and a high part); costs of single leaves.
    if (lane < TREELET_PARTS) {
        const unsigned int part =
            lane < TREELET_LOW_SUBSETS ? lane : (lane - TREELET_LOW_SUBSETS) << TREELET_LOW_LEAVES;
        const float inf = __int_as_float(0x7f800000);
        float3 lo = make_float3(inf, inf, inf), hi = make_float3(-inf, -inf, -inf);
        unsigned int count = 0;
        for (int k = 0; k < TREELET_LEAVES; ++k) {
            if (!((part >> k) & 1u)) continue;
            lo = min3f(lo, xyz(sh.lo[k]));
            hi = max3f(hi, xyz(sh.hi[k]));
            count += __float_as_uint(sh.hi[k].w) & BUILD_COUNT_MASK;
        }
        sh.part_lo[lane] = make_float4(lo.x, lo.y, lo.z, 0.0f);
        sh.part_hi[lane] = make_float4(hi.x, hi.y, hi.z, __uint_as_float(count));
    }
    __syncwarp();
    for (unsigned int s = lane + 1; s < TREELET_SUBSETS; s += 32) {
        float3 lo, hi;
        const unsigned int count = subset_box(sh, s, lo, hi);
        sh.area[s] = box_area(lo, hi);
        sh.count[s] = count;
        if (__popc(s) == 1) sh.cost[s] = sh.lo[__ffs(s) - 1].w;
    }
    __syncwarp();

    // Optimal splits by increasing subset size: sizes 2..5 one subset per lane...
    for (int size = 2; size < TREELET_LEAVES - 1; ++size) {
        for (unsigned int i = SUBSET_START[size] + lane; i < SUBSET_START[size + 1]; i += 32)
            evaluate_subset(sh, SUBSETS_BY_SIZE[i], max_leaf, ci, ct);
        __syncwarp();
    }
    // ...size 6 (7 subsets of 31 partitions) four lanes per subset, each
    // taking every fourth partition of evaluate_subset's order; ties go
    // to the earliest in that order, as there...
    {
        const unsigned int group = lane >> 2, step = lane & 3u;
        const bool in_use = group < 7;
        const unsigned int s = in_use ? SUBSETS_BY_SIZE[SUBSET_START[TREELET_LEAVES - 1] + group] : 0u;
        const unsigned int high = in_use ? 1u << (31 - __clz(s)) : 0u, rest = s ^ high;
        float best = __int_as_float(0x7f800000);
        unsigned int best_left = high;
        int order = 0x7fffffff;  // the best partition's place in evaluate_subset's order
        if (in_use) {
            unsigned int q = (rest - 1u) & rest;
            for (unsigned int k = 0; k < step; ++k) q = (q - 1u) & rest;
#pragma unroll
            for (int at = (int)step; at < 31; at += 4) {
                const unsigned int left = high | q;
                const float c = __fadd_rn(sh.cost[left], sh.cost[s ^ left]);
                if (c < best) {
                    best = c;
                    best_left = left;
                    order = at;
                }
                for (int k = 0; k < 4; ++k) q = (q - 1u) & rest;
            }
        }
        for (int d = 1; d <= 2; d <<= 1) {
            const float other = __shfl_xor_sync(0xffffffffu, best, d);
            const unsigned int other_left = __shfl_xor_sync(0xffffffffu, best_left, d);
            const int other_order = __shfl_xor_sync(0xffffffffu, order, d);
            if (other < best || (other == best && other_order < order)) {
                best = other;
                best_left = other_left;
                order = other_order;
            }
        }
        if (in_use && step == 0) finish_subset(sh, s, best, best_left, max_leaf, ci, ct);
        __syncwarp();
    }
    // ...and the whole treelet with its 63 partitions spread over the lanes.
    {
        const unsigned int all = TREELET_SUBSETS - 1, high = 1u << (TREELET_LEAVES - 1);
        float best = __int_as_float(0x7f800000);
        unsigned int best_left = high;
        for (unsigned int q = lane; q < high - 1; q += 32) {
            const unsigned int left = high | q;
            const float c = __fadd_rn(sh.cost[left], sh.cost[all ^ left]);
            if (c < best) {
                best = c;
                best_left = left;
            }
        }
        for (int d = 16; d >= 1; d >>= 1) {
            const float other = __shfl_xor_sync(0xffffffffu, best, d);
            const unsigned int other_left = __shfl_xor_sync(0xffffffffu, best_left, d);
            if (other < best || (other == best && other_left < best_left)) {
                best = other;
                best_left = other_left;
            }
        }
        if (lane == 0) finish_subset(sh, all, best, best_left, max_leaf, ci, ct);
    }
    __syncwarp();

    // Rebuild the treelet's inner nodes (same node slots, root first)
    // top-down: lane 0 links them, then a lane per node writes its box.
    if (lane == 0) {
        unsigned int stack_set[TREELET_LEAVES - 1], stack_node[TREELET_LEAVES - 1];
        int sp = 0, next_inner = 1, rebuilt = 0;
        stack_set[sp] = TREELET_SUBSETS - 1;
        stack_node[sp++] = root;
        while (sp > 0) {
            --sp;
            const unsigned int s = stack_set[sp], n = stack_node[sp];
            sh.rebuilt_set[rebuilt] = (unsigned char)s;
            sh.rebuilt_node[rebuilt++] = n;
            const unsigned int sides[2] = {sh.partition[s], s ^ sh.partition[s]};
            unsigned int ids[2];
            for (int k = 0; k < 2; ++k) {
                if (__popc(sides[k]) == 1) {
                    ids[k] = sh.leaf_node[__ffs(sides[k]) - 1];
                } else {
                    ids[k] = sh.inner_node[next_inner++];
                    stack_set[sp] = sides[k];
                    stack_node[sp++] = ids[k];
                }
                parent[ids[k]] = n;
            }
            child[n] = make_uint2(ids[0], ids[1]);
        }
    }
    __syncwarp();
    if (lane < TREELET_LEAVES - 1) {
        const unsigned int s = sh.rebuilt_set[lane], n = sh.rebuilt_node[lane];
        float3 lo, hi;
        subset_box(sh, s, lo, hi);
        node_lo[n] = make_float4(lo.x, lo.y, lo.z, sh.cost[s]);
        node_hi[n] = make_float4(hi.x, hi.y, hi.z, __uint_as_float(sh.count[s] | (sh.as_leaf[s] ? BUILD_LEAF_BIT : 0u)));
    }
    if (lane < TREELET_LEAVES - 1) __threadfence();
    __syncwarp();
}

// One round of treelet restructuring over every segment of the build;
// with `fit_bounds` (the first round) it also does lbvh_bounds' work in
// the same bottom-up pass: a node's box and cost are fitted from its
// children's (already restructured: the result equals bounds, then the
// round) before its treelet is. `counter` must be zero at launch.
extern "C" __global__ void __launch_bounds__(TREELET_THREADS)
    lbvh_treelet(const unsigned int* values, const float4* prim_box, unsigned int P, uint2* child,
                 unsigned int* parent, float4* node_lo, float4* node_hi, unsigned int* counter, unsigned int gamma,
                 unsigned int max_leaf, float ci, float ct, unsigned int fit_bounds) {
    __shared__ TreeletScratch scratch[TREELET_WARPS];
    TreeletScratch& sh = scratch[threadIdx.x >> 5];
    const unsigned long long j = (unsigned long long)blockIdx.x * blockDim.x + threadIdx.x;
    if (fit_bounds && j < P) {
        fit_leaf(j, values, prim_box, P, node_lo, node_hi, ci);
        __threadfence();
    }
    unsigned int node = j < P ? __ldcg(parent + P + j) : BUILD_NONE;
    bool active = node != BUILD_NONE;
    while (__any_sync(0xffffffffu, active)) {
        bool process = false;
        if (active) {
            if (atomicAdd(counter + node, 1u) == 0) {
                active = false;  // the other child's thread goes on
            } else {
                __threadfence();
                const unsigned int packed = fit_bounds ? fit_inner(node, child, node_lo, node_hi, max_leaf, ci, ct)
                                                       : __float_as_uint(__ldcg(node_hi + node).w);
                process = (packed & BUILD_COUNT_MASK) >= gamma;
            }
        }
        for (unsigned int pending = __ballot_sync(0xffffffffu, process); pending; pending &= pending - 1) {
            const unsigned int root = __shfl_sync(0xffffffffu, node, __ffs(pending) - 1);
            restructure(sh, root, P, child, parent, node_lo, node_hi, max_leaf, ci, ct);
        }
        if (active) {
            __threadfence();
            node = __ldcg(parent + node);
            active = node != BUILD_NONE;
        }
    }
}
