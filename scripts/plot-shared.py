#!/usr/bin/env python3
"""Plots the shared strategy's sweep of the replicated share (Jaroš et al.
2021, Figure 5) from the summary of `scripts/gpu-multi` run with modes
`replicate ring-peer shared-r0 shared-r1 shared-r5 shared-r10 ...`:
samples/s against replicate's for each replicated share, with the ring's
speed as a line. Writes an SVG (no plotting library needed on the GPU
machine or here).

    scripts/plot-shared.py gpu-multi-out/summary.txt -o shared.svg
"""

import argparse
import re
import sys

ROW = re.compile(r"^(\S+)\s+(\S+)\s+rc=0\s+([0-9.]+) M samples/s")


def read(path):
    """{scene: {mode: M samples/s}} from a gpu-multi summary."""
    speeds = {}
    with open(path) as f:
        for line in f:
            m = ROW.match(line)
            if m:
                speeds.setdefault(m.group(1), {})[m.group(2)] = float(m.group(3))
    return speeds


def svg(scene, modes, width=480, height=320, pad=48):
    """One scene's plot: relative speed against the replicated share."""
    replicate = modes.get("replicate")
    if not replicate:
        sys.exit(f"{scene}: no replicate run to compare with")
    points = sorted(
        (float(mode[len("shared-r"):]), speed / replicate)
        for mode, speed in modes.items()
        if mode.startswith("shared-r")
    )
    if not points:
        sys.exit(f"{scene}: no shared-rN runs")
    ring = modes.get("ring-peer")
    x_max = max(max(p for p, _ in points), 10.0)
    x = lambda share: pad + (width - 2 * pad) * share / x_max
    y = lambda rel: height - pad - (height - 2 * pad) * rel / 1.1
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-size="11">']
    out.append(f'<text x="{width / 2}" y="16" text-anchor="middle">{scene}: shared scene memory, 2 GPUs</text>')
    out.append(f'<line x1="{pad}" y1="{y(0)}" x2="{width - pad}" y2="{y(0)}" stroke="black"/>')
    out.append(f'<line x1="{pad}" y1="{y(0)}" x2="{pad}" y2="{y(1.1)}" stroke="black"/>')
    for rel in (0.0, 0.25, 0.5, 0.75, 1.0):
        out.append(f'<text x="{pad - 4}" y="{y(rel) + 4}" text-anchor="end">{rel:.2f}</text>')
    for share in sorted({0.0, x_max / 2, x_max} | {p for p, _ in points}):
        out.append(f'<text x="{x(share)}" y="{y(0) + 14}" text-anchor="middle">{share:g}%</text>')
    out.append(f'<text x="{width / 2}" y="{height - 8}" text-anchor="middle">chunks replicated on every GPU</text>')
    out.append(f'<text x="12" y="{height / 2}" transform="rotate(-90 12 {height / 2})" text-anchor="middle">× replicate\'s samples/s</text>')
    out.append(f'<line x1="{pad}" y1="{y(1)}" x2="{width - pad}" y2="{y(1)}" stroke="gray" stroke-dasharray="4"/>')
    if ring:
        out.append(f'<line x1="{pad}" y1="{y(ring / replicate)}" x2="{width - pad}" y2="{y(ring / replicate)}" stroke="firebrick" stroke-dasharray="2"/>')
        out.append(f'<text x="{width - pad}" y="{y(ring / replicate) - 4}" text-anchor="end" fill="firebrick">ring of 2 ({ring / replicate:.3f})</text>')
    path = " ".join(f"{x(p):.1f},{y(r):.1f}" for p, r in points)
    out.append(f'<polyline points="{path}" fill="none" stroke="steelblue" stroke-width="2"/>')
    for p, r in points:
        out.append(f'<circle cx="{x(p):.1f}" cy="{y(r):.1f}" r="3" fill="steelblue"/>')
        out.append(f'<text x="{x(p) + 5:.1f}" y="{y(r) + 14:.1f}">{r:.3f}</text>')
    out.append("</svg>")
    return "\n".join(out)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("summary", help="summary.txt of scripts/gpu-multi")
    parser.add_argument("-o", "--output", default="shared.svg")
    parser.add_argument("--scene", help="which scene of the summary (default: the first with shared runs)")
    args = parser.parse_args()
    speeds = read(args.summary)
    scenes = [s for s, m in speeds.items() if any(k.startswith("shared-r") for k in m)]
    scene = args.scene or (scenes[0] if scenes else None)
    if scene not in speeds:
        sys.exit(f"{args.summary}: no shared-rN runs")
    with open(args.output, "w") as f:
        f.write(svg(scene, speeds[scene]))
    print(args.output)


if __name__ == "__main__":
    main()
