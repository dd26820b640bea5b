// Ray queues sent GPU to GPU for the ring strategy (host side: src/peer.rs).
// The sender's kernel reads its queue length on the device and writes the
// records and the length straight into the receiver's memory (peer access
// over NVLink), so the host never waits to learn a length: the whole ring
// step is queued asynchronously and ordered with events.

#include "record.cuh"

/// Copies `min(*src_count, capacity)` records from `src` to `dst` (another
/// GPU's memory) and writes that count to `dst_count`. Grid-stride over
/// 16-byte words: every launch shape works.
extern "C" __global__ void send_records(const uint4* __restrict__ src, const unsigned int* __restrict__ src_count,
                                        uint4* __restrict__ dst, unsigned int* __restrict__ dst_count,
                                        unsigned int capacity) {
    const unsigned int n = min(*src_count, capacity);
    const unsigned long long words = (unsigned long long)n * (sizeof(RayRecord) / sizeof(uint4));
    const unsigned long long stride = (unsigned long long)gridDim.x * blockDim.x;
    for (unsigned long long i = (unsigned long long)blockIdx.x * blockDim.x + threadIdx.x; i < words; i += stride) {
        dst[i] = src[i];
    }
    if (blockIdx.x == 0 && threadIdx.x == 0) *dst_count = n;
}
