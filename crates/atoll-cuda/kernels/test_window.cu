// Test kernels for tests/gpu_window.rs: reads and writes through a chunk
// window (src/window.rs), whose chunks may live on this GPU, on a peer GPU
// or in host memory. Kernels see one plain pointer either way. Not used for
// rendering.

// Adds words[0..n) into *sum (64-bit, wrapping); grid-stride.
extern "C" __global__ void window_sum(const unsigned int* words, unsigned long long n, unsigned long long* sum) {
    unsigned long long local = 0;
    const unsigned long long stride = (unsigned long long)gridDim.x * blockDim.x;
    for (unsigned long long i = (unsigned long long)blockIdx.x * blockDim.x + threadIdx.x; i < n; i += stride) {
        local += words[i];
    }
    atomicAdd(sum, local);
}

// out[i] = words[indices[i]] for i < n.
extern "C" __global__ void window_gather(const unsigned int* words, const unsigned long long* indices, unsigned int n,
                                         unsigned int* out) {
    const unsigned int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) out[i] = words[indices[i]];
}

// words[i] = i * 2654435761 + seed for i < n; grid-stride.
extern "C" __global__ void window_fill(unsigned int* words, unsigned long long n, unsigned int seed) {
    const unsigned long long stride = (unsigned long long)gridDim.x * blockDim.x;
    for (unsigned long long i = (unsigned long long)blockIdx.x * blockDim.x + threadIdx.x; i < n; i += stride) {
        words[i] = (unsigned int)i * 2654435761u + seed;
    }
}

__device__ __forceinline__ unsigned int window_hash(unsigned int x) {
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

// Dependent random reads of 32-byte blocks (one memory sector each): each
// thread reads `steps` blocks of blocks[0..mask], the next index hashed from
// what it read, so reads cannot be overlapped within a thread (as in BVH
// traversal). `mask + 1` is a power of two. out[thread] keeps the reads live.
extern "C" __global__ void window_random_reads(const uint4* blocks, unsigned int mask, unsigned int steps,
                                               unsigned int* out) {
    const unsigned int thread = blockIdx.x * blockDim.x + threadIdx.x;
    unsigned int index = window_hash(thread) & mask;
    unsigned int acc = 0;
    for (unsigned int s = 0; s < steps; ++s) {
        const uint4 a = blocks[2ull * index];
        const uint4 b = blocks[2ull * index + 1ull];
        acc += a.x ^ a.y ^ a.z ^ a.w ^ b.x ^ b.y ^ b.z ^ b.w;
        index = window_hash(acc + index + s) & mask;
    }
    out[thread] = acc;
}
