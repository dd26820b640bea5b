// Per-chunk read counters of a shared scene (the shared strategy's
// prepass, src/sharing.rs): compiled in only with
// `-DATOLL_COUNT_ACCESSES=1`, where every counted read of scene data adds
// one to the counter of the chunk holding it. The host sets the globals
// below in each module compiled so (one device per GPU: the module's
// globals are the GPU's). Without the define `count_access` is nothing.
#pragma once

#ifndef ATOLL_COUNT_ACCESSES
#define ATOLL_COUNT_ACCESSES 0
#endif

#if ATOLL_COUNT_ACCESSES
/// One counter per chunk of the device's window.
__device__ unsigned long long* atoll_access_counts;
/// The device's window: where it starts, its bytes, its chunk size.
__device__ unsigned long long atoll_window_base;
__device__ unsigned long long atoll_window_bytes;
__device__ unsigned long long atoll_chunk_bytes;

__device__ __forceinline__ void count_access(const void* p) {
    const unsigned long long offset = reinterpret_cast<unsigned long long>(p) - atoll_window_base;
    // Tables outside the window (light and material tables) are not counted.
    if (offset < atoll_window_bytes) atomicAdd(atoll_access_counts + offset / atoll_chunk_bytes, 1ull);
}
#else
__device__ __forceinline__ void count_access(const void*) {}
#endif
