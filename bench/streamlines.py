"""Benchmark of the hatching-stroke tracer (target: "strokes covering the 69k-face bunny at a spacing of 1%
of its bounding-box diagonal in under 2 s").

Field: nfield.core.solve(bunny, n=2, order=2, align="curvature-max") (not timed). Timed: the whole
nfield.core.trace_streamlines call (building the field operators, finding singularities, tracing, the
coverage statistic), median over --repeats runs. Also a cross-hatched 4-field and a 0.5% spacing.
  strokes   - kept strokes;  points - polyline points;  length / ideal - total stroke length divided by
              area / d_sep (the length of perfectly parallel strokes d_sep apart)
  coverage  - area fraction of traceable triangles whose centroid has a stroke sample within d_sep
Prints JSON and a table; writes bench/results/streamlines.json and .md.

Usage: python bench/streamlines.py [--repeats 3]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "addon"))
RESULTS = ROOT / "bench" / "results"
TARGET_SECONDS = 2.0

CASES = [
    # (label, mesh, n, spacing, cross_hatch)
    ("bunny n=2 1% (target)", "stanford-bunny.obj", 2, 0.01, False),
    ("bunny n=4 1% cross-hatch", "stanford-bunny.obj", 4, 0.01, True),
    ("bunny n=2 0.5%", "stanford-bunny.obj", 2, 0.005, False),
]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    from nfield.core import Mesh, solve, trace_streamlines

    fields: dict = {}
    rows = []
    for label, mesh_name, n, spacing, cross in CASES:
        if mesh_name not in fields:
            fields[mesh_name] = {"mesh": Mesh.from_file(ROOT / "tests" / "data" / mesh_name)}
        entry = fields[mesh_name]
        mesh = entry["mesh"]
        if n not in entry:
            entry[n] = solve(mesh, n=n, order=2, align="curvature-max")
        field = entry[n]
        times, s = [], None
        for r in range(args.repeats):
            t0 = time.perf_counter()
            s = trace_streamlines(mesh, field, spacing=spacing, cross_hatch=cross, seed=r)
            times.append(time.perf_counter() - t0)
        ideal = mesh.native.total_area / s.separation * (2 if cross else 1)
        rows.append({
            "case": label, "mesh": mesh_name, "faces": int(mesh.num_triangles), "n": n, "spacing": spacing,
            "cross_hatch": cross, "seconds": statistics.median(times), "seconds_all": times,
            "strokes": s.num_strokes, "points": s.num_points, "length_over_ideal": s.total_length / ideal,
            "coverage": s.stats["coverage"], "discarded": s.stats["num_discarded"],
            "singularities": s.stats["num_singularities"], "truncated": s.stats["truncated"],
        })
    target = rows[0]
    out = {
        "benchmark": "streamlines",
        "machine": {"platform": platform.platform(), "python": platform.python_version(),
                    "cpus": os.cpu_count()},
        "target": {"case": target["case"], "seconds": target["seconds"], "limit_seconds": TARGET_SECONDS,
                   "met": target["seconds"] < TARGET_SECONDS and min(target["coverage"]) > 0.95},
        "rows": rows,
    }
    print(json.dumps(out, indent=1))
    header = "| case | faces | time (s) | strokes | points | length / ideal | coverage |"
    lines = [header, "|" + "---|" * 7]
    for r in rows:
        cov = "/".join(f"{c:.3f}" for c in r["coverage"])
        lines.append(f"| {r['case']} | {r['faces']} | {r['seconds']:.3f} | {r['strokes']} | {r['points']} | "
                     f"{r['length_over_ideal']:.2f} | {cov} |")
    table = "\n".join(lines)
    print()
    print(table)
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "streamlines.json").write_text(json.dumps(out, indent=1) + "\n")
    md = ("# Hatching strokes benchmark\n\n"
          f"Target: {target['case']} under {TARGET_SECONDS} s: "
          f"{'met' if out['target']['met'] else 'NOT met'} ({target['seconds']:.3f} s, median of "
          f"{args.repeats}). Machine: {out['machine']['platform']}, {out['machine']['cpus']} CPUs.\n\n"
          "Time is the whole `trace_streamlines` call (operators, singularities, tracing, coverage); the field "
          "solve is not included. length / ideal: total stroke length over area / d_sep. coverage: area "
          "fraction of triangles whose centroid has a stroke sample within d_sep (per family).\n\n"
          + table + "\n")
    (RESULTS / "streamlines.md").write_text(md)
    return 0 if out["target"]["met"] else 1


if __name__ == "__main__":
    sys.exit(main())
