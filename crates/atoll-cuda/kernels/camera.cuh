// Camera rays: the mirror of `atoll_render::camera::CameraRays::ray`
// (pbrt-v4's perspective camera with a thin lens) over `FrameParams`.
#pragma once

#include "common.cuh"
#include "params.cuh"
#include "sampling.cuh"

/// Mirrors `CameraRays::ray`: world-space ray through raster position
/// `raster` (pixels, y down) with lens sample `u_lens`; writes the origin
/// and the unit direction.
__device__ __forceinline__ void camera_ray(const FrameParams& p, float2 raster, float2 u_lens, float3* origin_out,
                                           float3* direction_out) {
    const float2 t = raster / make_float2(p.raster_size[0], p.raster_size[1]);
    // Raster y grows downwards, camera y upwards.
    const float x = p.window_min[0] + t.x * (p.window_max[0] - p.window_min[0]);
    const float y = p.window_max[1] - t.y * (p.window_max[1] - p.window_min[1]);
    float3 dir = make_float3(x, y, 1.0f);
    float3 origin = zero3();
    if (p.lens_radius > 0.0f) {
        const float2 lens = p.lens_radius * sample_uniform_disk_concentric(u_lens);
        const float3 focus = dir * p.focal_distance;
        origin = make_float3(lens.x, lens.y, 0.0f);
        dir = focus - origin;
    }
    *origin_out = affine_point(p.camera_to_world, origin);
    *direction_out = normalize3(affine_vector(p.camera_to_world, dir));
}
