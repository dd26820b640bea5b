// Ray queues sent GPU to GPU for the ring strategy (host side: src/peer.rs).
// The sender's kernel reads its queue length on the device and writes the
// records and the length straight into the receiver's memory (peer access
// over NVLink), so the host never waits to learn a length: the whole ring
// step is queued asynchronously and ordered with events.

#include "record.cuh"

/// Copies the first `1 << word_shift` 16-byte words of each of
/// `min(*src_count, capacity)` records from `src` to `dst` (another GPU's
/// memory), writes that count to `dst_count` and adds the bytes sent to
/// `*sent_bytes` (this GPU's statistics). Shadow rays need only their first
/// four words (ray, pixel, throughput, flags): what any-hit tracing and
/// resolving read, unless media give them an optical depth (the fifth
/// word; the host sends them whole then). Grid-stride: every launch shape works.
extern "C" __global__ void send_records(const uint4* __restrict__ src, const unsigned int* __restrict__ src_count,
                                        uint4* __restrict__ dst, unsigned int* __restrict__ dst_count,
                                        unsigned int capacity, unsigned int word_shift,
                                        unsigned long long* sent_bytes) {
    constexpr unsigned int RECORD_WORDS = sizeof(RayRecord) / sizeof(uint4);
    const unsigned int n = min(*src_count, capacity);
    const unsigned long long words = (unsigned long long)n << word_shift;
    const unsigned long long mask = (1ull << word_shift) - 1;
    const unsigned long long stride = (unsigned long long)gridDim.x * blockDim.x;
    for (unsigned long long i = (unsigned long long)blockIdx.x * blockDim.x + threadIdx.x; i < words; i += stride) {
        const unsigned long long at = (i >> word_shift) * RECORD_WORDS + (i & mask);
        dst[at] = src[at];
    }
    if (blockIdx.x == 0 && threadIdx.x == 0) {
        *dst_count = n;
        *sent_bytes += words * sizeof(uint4);
    }
}
