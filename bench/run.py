"""Benchmarks of the exact n-field spline solver (paper Table 1, "Factorization" and "Unreduced Solve").

For every test mesh and for the harmonic (order 1) and biharmonic (order 2) energies, 4-direction fields
with 30 random hard direction constraints and curvature alignment:
  factorization  - building V = E_m - lambda M and its CHOLMOD factorization (ExactSolver construction)
  first solve    - placing all 30 constraints (30 back-substitutions) and solving
  re-aim solve   - changing the direction of one existing constraint and solving again (eq. 13-14)
  from scratch   - reading nothing: mesh ingestion + operators + alignment + factorization + first solve
  peak memory    - peak resident set size of a fresh process doing all of the above for that mesh
Each timing is the median over --repeats runs. Every mesh runs in its own subprocess so its peak memory is
its own. Prints a table and writes bench/results/exact_solver.json and .md.

Usage: python bench/run.py [--meshes a.obj,b.off] [--repeats 3]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
RESULTS = ROOT / "bench" / "results"
MESHES = ["sphere.obj", "fertility.off", "eight.off", "fandisk.obj", "rocker-arm.obj", "camelhead.off",
          "stanford-bunny.obj", "armadillo.obj"]
# Paper Table 1 (their machine): faces, factorization harmonic/biharmonic (ms), unreduced solve (ms).
PAPER = {
    "rocker-arm.obj": {"paper_mesh": "Rocker Arm", "faces": 20088, "fact": (267, 654), "solve": (28, 37)},
    "stanford-bunny.obj": {"paper_mesh": "Bunny", "faces": 69666, "fact": (1318, 4413), "solve": (138, 194)},
    "armadillo.obj": {"paper_mesh": "Armadillo", "faces": 331904, "fact": (8155, 28000), "solve": (598, 801)},
}


def measure_one(mesh_name: str, repeats: int) -> dict:
    """Runs inside the subprocess: all timings for one mesh."""
    sys.path.insert(0, str(ROOT / "addon"))
    import numpy as np
    from nfield.core import native

    N = native()
    rng = np.random.default_rng(7)
    t0 = time.perf_counter()
    P, T, _, _ = N.read_mesh(str(DATA / mesh_name))
    mesh = N.Mesh(P, T)
    t_ingest = time.perf_counter() - t0
    t0 = time.perf_counter()
    ops = N.FieldOperators(mesh, 4)
    align = N.alignment_field(ops, "curvature-max")
    t_ops = time.perf_counter() - t0
    active = np.flatnonzero(mesh.face_active)
    out = {"mesh": mesh_name, "faces": int(mesh.num_faces), "ingest_s": t_ingest, "operators_s": t_ops}
    for order, label in ((1, "harmonic"), (2, "biharmonic")):
        fact, first, reaim, scratch = [], [], [], []
        for r in range(repeats):
            faces = rng.choice(active, size=30, replace=False)
            frames = ops.frames[faces]
            angles = rng.uniform(0, 2 * np.pi, size=30)
            vectors = np.cos(angles)[:, None] * frames[:, 0] + np.sin(angles)[:, None] * frames[:, 1]
            d = ops.tangent_to_representation(faces, vectors)
            d = d / np.abs(d)
            t0 = time.perf_counter()
            solver = N.ExactSolver(ops, order, 1.0, align, "direction")
            t1 = time.perf_counter()
            for f, dd in zip(faces, d):
                solver.set_direction_constraint(int(f), complex(dd))
            solver.solve()
            t2 = time.perf_counter()
            times = []
            for k in range(5):
                solver.set_direction_constraint(int(faces[0]), complex(d[0] * np.exp(1j * 0.1 * (k + 1))))
                t3 = time.perf_counter()
                solver.solve()
                times.append(time.perf_counter() - t3)
            fact.append(t1 - t0)
            first.append(t2 - t1)
            reaim.append(statistics.median(times))
            scratch.append(t_ingest + t_ops + (t1 - t0) + (t2 - t1))
        out[label] = {"factorization_s": statistics.median(fact), "first_solve_s": statistics.median(first),
                      "reaim_solve_s": statistics.median(reaim), "from_scratch_s": statistics.median(scratch)}
    out["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return out


def ms(x: float) -> str:
    return f"{1000 * x:.0f} ms" if x < 10 else f"{x:.1f} s"


def table(rows: list[dict]) -> str:
    head = ("| mesh | faces | factorization harm. \\ biharm. | paper | first solve (30 new) harm. \\ biharm. "
            "| re-aim solve harm. \\ biharm. | paper unreduced solve | from scratch (biharm.) | peak RSS |")
    lines = [head, "|" + "---|" * 9]
    for r in rows:
        p = PAPER.get(r["mesh"])
        h, b = r["harmonic"], r["biharmonic"]
        paper_fact = f"{p['fact'][0]} ms \\ {p['fact'][1]} ms ({p['paper_mesh']}, {p['faces']} faces)" if p else "-"
        paper_solve = f"{p['solve'][0]} ms \\ {p['solve'][1]} ms" if p else "-"
        lines.append(
            f"| {r['mesh']} | {r['faces']} | {ms(h['factorization_s'])} \\ {ms(b['factorization_s'])} | {paper_fact} | "
            f"{ms(h['first_solve_s'])} \\ {ms(b['first_solve_s'])} | {ms(h['reaim_solve_s'])} \\ {ms(b['reaim_solve_s'])} | "
            f"{paper_solve} | {ms(b['from_scratch_s'])} | {r['peak_rss_mb']:.0f} MB |")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--meshes", default=",".join(MESHES))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure_one(args.one, args.repeats)))
        return 0
    rows = []
    for name in args.meshes.split(","):
        proc = subprocess.run([sys.executable, __file__, "--one", name, "--repeats", str(args.repeats)],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            print(f"{name}: failed\n{proc.stderr}", file=sys.stderr)
            return 1
        rows.append(json.loads(proc.stdout.strip().splitlines()[-1]))
        print(f"{name}: done", file=sys.stderr)
    RESULTS.mkdir(parents=True, exist_ok=True)
    meta = {"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
            "python": platform.python_version(), "repeats": args.repeats,
            "setting": "4-direction field, curvature-max alignment, strength 1, 30 random hard direction constraints"}
    (RESULTS / "exact_solver.json").write_text(json.dumps({"meta": meta, "results": rows}, indent=2))
    md = "# Exact solver benchmark\n\n" + meta["setting"] + f"; medians of {args.repeats} runs.\n\n" + table(rows) + "\n"
    (RESULTS / "exact_solver.md").write_text(md)
    print(json.dumps({"meta": meta, "results": rows}, indent=2))
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
