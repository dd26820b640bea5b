// GPU primitives for the LBVH build (src/bvh/sort.rs drives them):
// - an exclusive prefix sum over u32 (reduce, scan of the block sums,
//   downsweep: three launches, any length);
// - an LSD radix sort of (u32 key, u32 value) pairs, 8 bits per pass:
//   per-tile digit histograms, one exclusive scan over all of them
//   (digit-major, so the scan yields every tile's output offset per digit),
//   and a stable scatter that first sorts each tile by digit in shared
//   memory so that global writes come out as runs of consecutive addresses.
//
// The LBVH sorts 32-bit Morton codes with the primitive index as the value
// (DSGPURayTracing's trick: the index is appended to the key only on the
// fly, when the radix tree compares equal codes, so the sort moves 8 bytes
// per primitive, not 16). Several BLASes are sorted at once: after the
// Morton passes, passes over the segment id (found from the value by a
// binary search in the segment starts) make the order (segment, code).

#include "lbvh.cuh"

#define SCAN_THREADS 256
#define SCAN_ITEMS 8
#define SCAN_TILE (SCAN_THREADS * SCAN_ITEMS)

#define SORT_THREADS 256
#define SORT_WARPS (SORT_THREADS / 32)
#define SORT_ITEMS 16
#define SORT_TILE (SORT_THREADS * SORT_ITEMS)
#define SORT_WARP_TILE (32 * SORT_ITEMS)

/// Exclusive scan of one value per thread over the block (256 threads):
/// returns the sum of the values of lower threads; `*total` gets the block sum.
__device__ __forceinline__ unsigned int block_exclusive_scan(unsigned int x, unsigned int* total) {
    __shared__ unsigned int warp_sums[SCAN_THREADS / 32];
    const unsigned int lane = threadIdx.x & 31u, warp = threadIdx.x >> 5;
    unsigned int inclusive = x;
    for (unsigned int d = 1; d < 32; d <<= 1) {
        const unsigned int y = __shfl_up_sync(0xffffffffu, inclusive, d);
        if (lane >= d) inclusive += y;
    }
    if (lane == 31) warp_sums[warp] = inclusive;
    __syncthreads();
    if (warp == 0) {
        unsigned int w = lane < SCAN_THREADS / 32 ? warp_sums[lane] : 0u;
        for (unsigned int d = 1; d < 32; d <<= 1) {
            const unsigned int y = __shfl_up_sync(0xffffffffu, w, d);
            if (lane >= d) w += y;
        }
        if (lane < SCAN_THREADS / 32) warp_sums[lane] = w;  // inclusive over warps
    }
    __syncthreads();
    const unsigned int warp_base = warp == 0 ? 0u : warp_sums[warp - 1];
    *total = warp_sums[SCAN_THREADS / 32 - 1];
    __syncthreads();  // warp_sums is reused by the next call
    return warp_base + inclusive - x;
}

// Scan step 1: the sum of each tile of SCAN_TILE elements.
extern "C" __global__ void __launch_bounds__(SCAN_THREADS) scan_reduce(const unsigned int* in, unsigned int n,
                                                                      unsigned int* tile_sums) {
    const unsigned long long base = (unsigned long long)blockIdx.x * SCAN_TILE;
    unsigned int sum = 0;
    for (unsigned int k = 0; k < SCAN_ITEMS; ++k) {
        const unsigned long long i = base + k * SCAN_THREADS + threadIdx.x;
        if (i < n) sum += in[i];
    }
    unsigned int total;
    block_exclusive_scan(sum, &total);
    if (threadIdx.x == 0) tile_sums[blockIdx.x] = total;
}

// Scan step 2 (one block): exclusive scan of the tile sums in place, in
// chunks of 256 with a running carry (any number of tiles); `*grand_total`
// gets the sum of everything.
extern "C" __global__ void __launch_bounds__(SCAN_THREADS) scan_tile_sums(unsigned int* tile_sums, unsigned int tiles,
                                                                         unsigned int* grand_total) {
    unsigned int carry = 0;
    for (unsigned int base = 0; base < tiles; base += SCAN_THREADS) {
        const unsigned int i = base + threadIdx.x;
        const unsigned int x = i < tiles ? tile_sums[i] : 0u;
        unsigned int total;
        const unsigned int excl = block_exclusive_scan(x, &total);
        if (i < tiles) tile_sums[i] = carry + excl;
        carry += total;
    }
    if (threadIdx.x == 0) *grand_total = carry;
}

// Scan step 3: each tile scanned locally plus its offset, from `in` to
// `out` (which may be the same: a block reads its tile before writing it).
extern "C" __global__ void __launch_bounds__(SCAN_THREADS) scan_downsweep(const unsigned int* in, unsigned int* out,
                                                                         unsigned int n,
                                                                         const unsigned int* tile_sums) {
    // Each thread owns SCAN_ITEMS consecutive elements (staged through
    // shared memory so that global accesses stay coalesced).
    __shared__ unsigned int tile[SCAN_TILE];
    const unsigned long long base = (unsigned long long)blockIdx.x * SCAN_TILE;
    for (unsigned int k = 0; k < SCAN_ITEMS; ++k) {
        const unsigned int j = k * SCAN_THREADS + threadIdx.x;
        tile[j] = base + j < n ? in[base + j] : 0u;
    }
    __syncthreads();
    unsigned int local[SCAN_ITEMS];
    unsigned int sum = 0;
    for (unsigned int k = 0; k < SCAN_ITEMS; ++k) {
        local[k] = sum;
        sum += tile[threadIdx.x * SCAN_ITEMS + k];
    }
    unsigned int total;
    const unsigned int offset = tile_sums[blockIdx.x] + block_exclusive_scan(sum, &total);
    for (unsigned int k = 0; k < SCAN_ITEMS; ++k) tile[threadIdx.x * SCAN_ITEMS + k] = offset + local[k];
    __syncthreads();
    for (unsigned int k = 0; k < SCAN_ITEMS; ++k) {
        const unsigned int j = k * SCAN_THREADS + threadIdx.x;
        if (base + j < n) out[base + j] = tile[j];
    }
}

/// The digit a sort pass orders by: 8 bits of the key (`from_segment == 0`)
/// or of the segment the value (a primitive index) belongs to.
__device__ __forceinline__ unsigned int radix_digit(unsigned int key, unsigned int value, unsigned int shift,
                                                    unsigned int from_segment, const unsigned int* seg_start,
                                                    unsigned int segments) {
    const unsigned int x = from_segment ? segment_of(value, seg_start, segments) : key;
    return (x >> shift) & 0xffu;
}

// Radix pass step 1: the digit histogram of each tile of SORT_TILE pairs,
// stored digit-major: hist[digit * tiles + tile].
extern "C" __global__ void __launch_bounds__(SORT_THREADS)
    radix_histogram(const unsigned int* keys, const unsigned int* values, unsigned int n, unsigned int shift,
                    unsigned int from_segment, const unsigned int* seg_start, unsigned int segments,
                    unsigned int* hist, unsigned int tiles) {
    __shared__ unsigned int counts[256];
    counts[threadIdx.x] = 0;
    __syncthreads();
    const unsigned long long base = (unsigned long long)blockIdx.x * SORT_TILE;
    for (unsigned int k = 0; k < SORT_ITEMS; ++k) {
        const unsigned long long i = base + k * SORT_THREADS + threadIdx.x;
        const bool valid = i < n;
        const unsigned int valid_mask = __ballot_sync(0xffffffffu, valid);
        if (valid) {
            // Key passes leave the values unread.
            const unsigned int d = from_segment ? radix_digit(0u, values[i], shift, 1u, seg_start, segments)
                                                : radix_digit(keys[i], 0u, shift, 0u, seg_start, segments);
            // Warp-aggregated: sorted inputs put whole warps on one digit,
            // and one shared atomic per distinct digit avoids serialising them.
            const unsigned int peers = __match_any_sync(valid_mask, d);
            if ((threadIdx.x & 31u) == (unsigned int)(__ffs(peers) - 1)) atomicAdd(&counts[d], __popc(peers));
        }
    }
    __syncthreads();
    hist[(unsigned long long)threadIdx.x * tiles + blockIdx.x] = counts[threadIdx.x];
}

// Radix pass step 3 (after the scan of `hist`): stable scatter of each tile.
// Warp w ranks its contiguous SORT_WARP_TILE pairs round by round with
// __match_any_sync (rank = same-digit lanes below + that digit's count in
// the warp's earlier rounds), then the tile's digit offsets combine warps
// in order, so ranks follow input order: the pass is stable.
extern "C" __global__ void __launch_bounds__(SORT_THREADS)
    radix_scatter(const unsigned int* keys_in, const unsigned int* values_in, unsigned int* keys_out,
                  unsigned int* values_out, unsigned int n, unsigned int shift, unsigned int from_segment,
                  const unsigned int* seg_start, unsigned int segments, const unsigned int* hist_scanned,
                  unsigned int tiles) {
    __shared__ unsigned int warp_counts[SORT_WARPS][256];
    __shared__ unsigned int tile_prefix[256];
    __shared__ unsigned int global_base[256];
    __shared__ unsigned int s_keys[SORT_TILE];
    __shared__ unsigned int s_values[SORT_TILE];
    __shared__ unsigned char s_digits[SORT_TILE];

    const unsigned int lane = threadIdx.x & 31u, warp = threadIdx.x >> 5;
    for (unsigned int w = 0; w < SORT_WARPS; ++w) warp_counts[w][threadIdx.x] = 0;
    __syncthreads();

    const unsigned long long tile_base = (unsigned long long)blockIdx.x * SORT_TILE;
    const unsigned long long warp_base = tile_base + warp * SORT_WARP_TILE;
    const unsigned int lanes_below = (1u << lane) - 1u;
    unsigned int key[SORT_ITEMS], value[SORT_ITEMS], digit[SORT_ITEMS], rank[SORT_ITEMS];
#pragma unroll
    for (unsigned int k = 0; k < SORT_ITEMS; ++k) {
        const unsigned long long i = warp_base + k * 32 + lane;
        const bool valid = i < n;
        key[k] = valid ? keys_in[i] : 0u;
        value[k] = valid ? values_in[i] : 0u;
        digit[k] = valid ? radix_digit(key[k], value[k], shift, from_segment, seg_start, segments) : 256u;
        const unsigned int valid_mask = __ballot_sync(0xffffffffu, valid);
        unsigned int peers = 0, before = 0;
        if (valid) {
            peers = __match_any_sync(valid_mask, digit[k]);
            before = warp_counts[warp][digit[k]];
        }
        __syncwarp();
        if (valid && lane == (unsigned int)(__ffs(peers) - 1)) warp_counts[warp][digit[k]] = before + __popc(peers);
        __syncwarp();
        rank[k] = before + __popc(peers & lanes_below);
    }
    __syncthreads();

    // Per digit (thread = digit): exclusive prefix over warps, tile total.
    unsigned int running = 0;
    for (unsigned int w = 0; w < SORT_WARPS; ++w) {
        const unsigned int c = warp_counts[w][threadIdx.x];
        warp_counts[w][threadIdx.x] = running;
        running += c;
    }
    unsigned int total;
    tile_prefix[threadIdx.x] = block_exclusive_scan(running, &total);
    global_base[threadIdx.x] = hist_scanned[(unsigned long long)threadIdx.x * tiles + blockIdx.x];
    __syncthreads();

    // The tile sorted by digit, in shared memory.
#pragma unroll
    for (unsigned int k = 0; k < SORT_ITEMS; ++k) {
        if (digit[k] < 256u) {
            const unsigned int local = tile_prefix[digit[k]] + warp_counts[warp][digit[k]] + rank[k];
            s_keys[local] = key[k];
            s_values[local] = value[k];
            s_digits[local] = (unsigned char)digit[k];
        }
    }
    __syncthreads();

    // Consecutive threads write consecutive positions within a digit's run.
    const unsigned long long left = n - tile_base;
    const unsigned int tile_n = left < SORT_TILE ? (unsigned int)left : SORT_TILE;
    for (unsigned int j = threadIdx.x; j < tile_n; j += SORT_THREADS) {
        const unsigned int d = s_digits[j];
        const unsigned long long out = (unsigned long long)global_base[d] + (j - tile_prefix[d]);
        keys_out[out] = s_keys[j];
        values_out[out] = s_values[j];
    }
}
