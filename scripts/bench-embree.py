#!/usr/bin/env python3
"""Embree on the same triangles and rays as atoll's traversal benchmark.

Reads what `cargo run --release -p atoll-bvh --example bench -- --export DIR`
wrote into DIR (little-endian f32: triangles.f32 as N x 9, primary.f32,
shadow.f32 and diffuse.f32 as M x 7 = origin, direction, t_max; atoll.json
with atoll's results), builds an Embree scene with the `embreex` binding
(Embree 4; `pip install embreex numpy`) and times it like atoll's bench:
one untimed warm-up, then the median of several runs.

What is timed:
- build: committing the scene, which builds the BVH (Embree builds with all
  cores through TBB, like atoll's rayon builder). embreex's own copy of the
  triangles into an Embree buffer (TriangleMesh) is timed apart: it is
  binding overhead, not BVH building;
- traversal: one `EmbreeScene.run` call per batch. embreex loops over the
  rays in Cython calling rtcIntersect1 / rtcOccluded1 on ONE thread (it
  holds the GIL), and that loop copies each ray in and the result out. So
  Embree is compared with atoll's single-thread column; the binding's own
  cost per ray is estimated with rays that miss the scene's bounding box and
  printed, not subtracted.
- primary and diffuse: query INTERSECT (closest hit; a hit is primID >= 0).
  shadow: query OCCLUDED with per-ray tfar = t_max (`dists`), occluded when
  the returned geomID is not -1. Every query has tnear = 0 like atoll.
"""

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from embreex import mesh_construction, rtcore_scene


def load(path: Path, width: int) -> np.ndarray:
    return np.fromfile(path, dtype="<f4").reshape(-1, width)


def timed(fn, runs: int):
    """Untimed warm-up, then the median wall time of `runs` calls, and the last result."""
    result = fn()
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def build(triangles: np.ndarray):
    """A committed Embree scene, with the seconds spent copying the mesh in and committing."""
    start = time.perf_counter()
    scene = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(scene, triangles)
    copied = time.perf_counter()
    # embreex commits lazily on the first query: force it with one ray.
    scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
    return scene, copied - start, time.perf_counter() - copied


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dir", type=Path)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--builds", type=int, default=3)
    args = parser.parse_args()

    triangles = np.ascontiguousarray(load(args.dir / "triangles.f32", 9).reshape(-1, 3, 3))
    atoll = json.loads((args.dir / "atoll.json").read_text())
    print(f"{len(triangles)} triangles")

    copies, commits = [], []
    for _ in range(max(args.builds, 1)):
        scene, copy_s, commit_s = build(triangles)
        copies.append(copy_s)
        commits.append(commit_s)
    build_s = statistics.median(commits)
    print(f"{'build':<9} {'ms':>9} {'Mtris/s':>8}")
    print(f"{'embree':<9} {build_s * 1e3:>9.1f} {len(triangles) / build_s / 1e6:>8.2f}"
          f"   (commit; embreex's mesh copy before it: {statistics.median(copies) * 1e3:.0f} ms)")
    for b in atoll["builds"]:
        print(f"{b['layout']:<9} {b['build_ms']:>9.1f} {b['mtris_per_s']:>8.2f}")

    # The binding's floor: rays that start outside the scene box and point away.
    lo, hi = triangles.reshape(-1, 3).min(0), triangles.reshape(-1, 3).max(0)
    n = 1 << 20
    away_o = np.tile(hi + (hi - lo), (n, 1)).astype(np.float32)
    away_d = np.tile(np.float32(hi - lo), (n, 1)).astype(np.float32)
    floor_s, _ = timed(lambda: scene.run(away_o, away_d), args.runs)
    print(f"binding floor (rays missing the scene box): {n / floor_s / 1e6:.2f} Mrays/s")

    layouts = sorted({m["layout"] for b in atoll["batches"] for m in b["measurements"] if m["threads"] == 1})
    header = f"{'batch':<8} {'rays':>8} {'hits':>8} {'embree 1t':>10}"
    for layout in layouts:
        header += f" {layout + ' 1t':>11} {'ratio':>6}"
    print(header + "   (Mrays/s; ratio = atoll / embree)")
    ok = True
    for batch in atoll["batches"]:
        rays = load(args.dir / f"{batch['name']}.f32", 7)
        origins = np.ascontiguousarray(rays[:, 0:3])
        directions = np.ascontiguousarray(rays[:, 3:6])
        t_max = np.ascontiguousarray(rays[:, 6])
        if batch["query"] == "occluded":
            seconds, result = timed(lambda: scene.run(origins, directions, dists=t_max, query="OCCLUDED"), args.runs)
            hits = int((result != -1).sum())
        else:
            seconds, result = timed(lambda: scene.run(origins, directions, dists=t_max, query="INTERSECT"), args.runs)
            hits = int((result >= 0).sum())
        embree = len(rays) / seconds / 1e6
        line = f"{batch['name']:<8} {len(rays):>8} {hits:>8} {embree:>10.2f}"
        for layout in layouts:
            m = next(m for m in batch["measurements"] if m["layout"] == layout and m["threads"] == 1)
            line += f" {m['mrays_per_s']:>11.2f} {m['mrays_per_s'] / embree:>6.2f}"
            # Hits may differ by a few rays: two ray/triangle tests disagree on edges.
            if abs(m["hits"] - hits) > max(10, len(rays) // 10_000):
                line += f"  HITS DIFFER: atoll {m['hits']}"
                ok = False
        print(line)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
