// Scene tables made on the device from mesh arrays already uploaded
// (host side: src/scene/gather.rs): each table is a list of segments, one
// thread block per segment, so that no table is written on the host.

#include "layout.cuh"

/// Writes `table` from the `count` segments: segment `s`'s `words` words
/// from `src` (zeros where `src` is 0), each plus `add`, to `table + dst`.
extern "C" __global__ void copy_segments(const CopySegment* __restrict__ segments, unsigned int count,
                                         unsigned int* __restrict__ table) {
    for (unsigned int s = blockIdx.x; s < count; s += gridDim.x) {
        const CopySegment g = segments[s];
        const unsigned int* src = reinterpret_cast<const unsigned int*>(g.src);
        unsigned int* dst = table + g.dst;
        for (unsigned int i = threadIdx.x; i < g.words; i += blockDim.x) {
            dst[i] = (src ? src[i] : 0u) + g.add;
        }
    }
}
