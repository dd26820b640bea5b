// Camera rays: the mirror of `atoll_render::camera::CameraRays::ray`
// (pbrt-v4's perspective and orthographic cameras with a thin lens, and its
// spherical camera) over `FrameParams`.
#pragma once

#include "common.cuh"
#include "params.cuh"
#include "sampling.cuh"
#include "environment.cuh"
#include "lens.cuh"
#include "motion.cuh"

/// Mirrors `wrap_equal_area_square`.
__device__ __forceinline__ float2 wrap_equal_area_square(float2 uv) {
    if (uv.x < 0.0f) {
        uv = make_float2(-uv.x, 1.0f - uv.y);
    } else if (uv.x > 1.0f) {
        uv = make_float2(2.0f - uv.x, 1.0f - uv.y);
    }
    if (uv.y < 0.0f) {
        uv = make_float2(1.0f - uv.x, -uv.y);
    } else if (uv.y > 1.0f) {
        uv = make_float2(1.0f - uv.x, 2.0f - uv.y);
    }
    return uv;
}

/// Mirrors `CameraRays::weighted_ray_at`: world-space ray through raster
/// position `raster` (pixels, y down) with lens sample `u_lens` at time
/// sample `time` (where a moving camera is then); writes the origin and the
/// unit direction, and returns the ray's weight (1 but for a realistic
/// camera; 0 where its lens blocks the ray).
__device__ __forceinline__ float camera_ray(const FrameParams& p, float2 raster, float2 u_lens, float time,
                                            float3* origin_out, float3* direction_out) {
    float camera_to_world[12];
    if (p.camera_moves) {
        motion_object_to_world(p.camera_motion, time, camera_to_world);
    } else {
        for (int k = 0; k < 12; ++k) camera_to_world[k] = p.camera_to_world[k];
    }
    const float2 t = raster / make_float2(p.raster_size[0], p.raster_size[1]);
    // Raster y grows downwards, camera y upwards.
    const float x = p.window_min[0] + t.x * (p.window_max[0] - p.window_min[0]);
    const float y = p.window_max[1] - t.y * (p.window_max[1] - p.window_min[1]);
    float3 dir = make_float3(x, y, 1.0f);
    float3 origin = zero3();
    if (p.projection == PROJECTION_REALISTIC) {
        // The lens turns the image over: the film point is opposite.
        const float weight = lens_ray(p.lens, make_float2(-x, -y), u_lens, &origin, &dir);
        if (weight == 0.0f) {
            origin = zero3();
            dir = make_float3(0.0f, 0.0f, 1.0f);
        }
        *origin_out = affine_point(camera_to_world, origin);
        *direction_out = normalize3(affine_vector(camera_to_world, dir));
        return weight;
    }
    if (p.projection == PROJECTION_ORTHOGRAPHIC) {
        origin = make_float3(x, y, 0.0f);
        dir = make_float3(0.0f, 0.0f, 1.0f);
    } else if (p.projection == PROJECTION_SPHERE_EQUAL_AREA || p.projection == PROJECTION_SPHERE_LAT_LONG) {
        // `Projection::camera_ray`: the mapping's direction at (u, v) =
        // (x, -y), its pole (+z) turned to camera +y.
        const bool equal_area = p.projection == PROJECTION_SPHERE_EQUAL_AREA;
        float2 uv = make_float2(x, -y);
        if (equal_area) uv = wrap_equal_area_square(uv);
        const float3 d = env_direction(equal_area ? ENV_EQUAL_AREA : ENV_LAT_LONG, uv);
        *origin_out = affine_point(camera_to_world, zero3());
        *direction_out = normalize3(affine_vector(camera_to_world, make_float3(d.x, d.z, d.y)));
        return 1.0f;
    }
    if (p.lens_radius > 0.0f) {
        const float2 lens = p.lens_radius * sample_uniform_disk_concentric(u_lens);
        const float3 focus = origin + dir * p.focal_distance;
        origin = make_float3(lens.x, lens.y, 0.0f);
        dir = focus - origin;
    }
    *origin_out = affine_point(camera_to_world, origin);
    *direction_out = normalize3(affine_vector(camera_to_world, dir));
    return 1.0f;
}

/// Mirrors `FilterTable::sample_axis`: an offset along `axis` from the
/// pixel's centre and its weight.
__device__ __forceinline__ float filter_sample_axis(const FilterTable& f, unsigned int axis, float u, float* weight) {
    float side = 1.0f;
    if (u < 0.5f) {
        side = -1.0f;
        u = u * 2.0f;
    } else {
        u = u * 2.0f - 1.0f;
    }
    const float* ends = f.cdf + axis * FILTER_BINS;
    unsigned int lo = 0, hi = FILTER_BINS - 1;
    while (lo < hi) {
        const unsigned int mid = (lo + hi) / 2;
        if (ends[mid] <= u) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    const float start = lo == 0 ? 0.0f : ends[lo - 1];
    const float width = ends[lo] - start;
    const float within = width > 0.0f ? fminf(__fdiv_rn(u - start, width), 1.0f) : 0.5f;
    const float x = __fmul_rn((float)lo + within, __fdiv_rn(f.radius[axis], (float)FILTER_BINS));
    *weight = (f.negative[axis] >> lo) & 1u ? -f.weight[axis] : f.weight[axis];
    return side * x;
}

/// Mirrors `FilterTable::sample`: the raster position of a sample of the
/// pixel whose corner is `pixel`, from uniform numbers `u`, and its weight.
__device__ __forceinline__ float2 filter_sample(const FilterTable& f, float2 pixel, float2 u, float* weight) {
    if (f.kind == FILTER_PIXEL) {
        *weight = 1.0f;
        return pixel + u;
    }
    if (f.kind == FILTER_BOX) {
        *weight = 1.0f;
        // Rounded products: no FMA, as the CPU computes it.
        return make_float2(pixel.x + 0.5f + __fmul_rn(2.0f * u.x - 1.0f, f.radius[0]),
                           pixel.y + 0.5f + __fmul_rn(2.0f * u.y - 1.0f, f.radius[1]));
    }
    float wx, wy;
    const float x = filter_sample_axis(f, 0, u.x, &wx), y = filter_sample_axis(f, 1, u.y, &wy);
    *weight = wx * wy;
    return make_float2(pixel.x + 0.5f + x, pixel.y + 0.5f + y);
}
