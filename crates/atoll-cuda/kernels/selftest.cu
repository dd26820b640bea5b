// Tiny kernels that check the CUDA plumbing itself (compile, load, launch,
// copies, events) without depending on the renderer's kernels. Used by
// tests/gpu_basic.rs.

// Writes out[i] = i * scale + offset for i < n.
extern "C" __global__ void selftest_affine(unsigned int* out, unsigned int n, unsigned int scale,
                                           unsigned int offset) {
    unsigned int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) out[i] = i * scale + offset;
}

// Launched for `capacity` threads, works on the first *count items only: the
// pattern every queue kernel follows (the host never reads counts back
// between stages). Appends the even inputs to `out` through an atomic counter.
extern "C" __global__ void selftest_compact_even(const unsigned int* in, const unsigned int* count,
                                                 unsigned int capacity, unsigned int* out,
                                                 unsigned int* out_count) {
    unsigned int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= capacity || i >= *count) return;
    unsigned int v = in[i];
    if ((v & 1u) == 0u) out[atomicAdd(out_count, 1u)] = v;
}
