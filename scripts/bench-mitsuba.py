#!/usr/bin/env python3
"""Mitsuba 3 (OptiX on the GPU) on the same triangles and rays as `atoll bench SCENE`.

Reads what `atoll bench SCENE --export DIR` wrote into DIR (little-endian
f32: triangles.f32 as N x 9, world space, instances expanded; primary.f32,
shadow.f32 and diffuse.f32 as M x 7 = origin, direction, t_max), builds one
Mitsuba mesh of those triangles (`cuda_ad_rgb`: OptiX builds and traverses
its BVH) and times, per batch, one untimed warm-up (which also compiles
Dr.Jit's kernel) and then the median of --runs traces:

- primary and diffuse: `scene.ray_intersect_preliminary` (closest hit;
  `coherent=True` for primary rays), a hit where t is finite;
- shadow: `scene.ray_test` with each ray's t_max (occluded or not).

Two figures per batch: "kernels", the device time of the kernels the
trace launched (Dr.Jit's kernel history, which times them with CUDA events,
as `atoll bench` times its own), and "wall", around the whole call with the
device synchronised (Dr.Jit's tracing and launch overhead included). Hit
counts are printed to compare with atoll's report of the same rays.

    pip install mitsuba numpy      # on the GPU machine
    atoll bench landscape:100 --res 1920x1080 --export /tmp/rays --device cuda:0
    scripts/bench-mitsuba.py /tmp/rays
"""

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np


def load(path: Path, width: int) -> np.ndarray:
    return np.fromfile(path, dtype="<f4").reshape(-1, width)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dir", type=Path)
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--variant", default="cuda_ad_rgb")
    args = parser.parse_args()

    import drjit as dr
    import mitsuba as mi

    mi.set_variant(args.variant)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    triangles = load(args.dir / "triangles.f32", 9)
    n = len(triangles)
    start = time.perf_counter()
    mesh = mi.Mesh("bench", vertex_count=3 * n, face_count=n, has_vertex_normals=False, has_vertex_texcoords=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(triangles.ravel())
    params["faces"] = mi.UInt32(np.arange(3 * n, dtype=np.uint32))
    params.update()
    scene = mi.load_dict({"type": "scene", "mesh": mesh})
    dr.sync_thread()
    print(f"{n} triangles; mesh and scene (BVH) ready in {time.perf_counter() - start:.2f} s, {args.variant}")

    print(f"{'batch':<8} {'rays':>9} {'hits':>9} {'kernels':>9} {'wall':>9}   (Mrays/s)")
    for name in ["primary", "shadow", "diffuse"]:
        path = args.dir / f"{name}.f32"
        if not path.exists():
            continue
        rays = load(path, 7)
        if len(rays) == 0:
            continue
        column = lambda k: mi.Float(np.ascontiguousarray(rays[:, k]))
        ray = mi.Ray3f(
            mi.Point3f(column(0), column(1), column(2)),
            mi.Vector3f(column(3), column(4), column(5)),
        )
        ray.maxt = column(6)
        dr.eval(ray)
        dr.sync_thread()

        def trace():
            if name == "shadow":
                result = scene.ray_test(ray)
            else:
                result = scene.ray_intersect_preliminary(ray, coherent=(name == "primary")).t
            dr.eval(result)
            dr.sync_thread()
            return result

        result = trace()
        walls, kernels = [], []
        for _ in range(max(args.runs, 1)):
            dr.kernel_history()  # (reading it clears it)
            begin = time.perf_counter()
            result = trace()
            walls.append(time.perf_counter() - begin)
            kernels.append(sum(k.get("execution_time", 0.0) for k in dr.kernel_history()) * 1e-3)
        values = result.numpy()
        hits = int(values.sum()) if name == "shadow" else int(np.isfinite(values).sum())
        rate = lambda seconds: len(rays) / statistics.median(seconds) / 1e6
        print(f"{name:<8} {len(rays):>9} {hits:>9} {rate(kernels):>9.1f} {rate(walls):>9.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
