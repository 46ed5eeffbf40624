"""One-shot solves (what the command line and batch scripts do) and a live session's first constrained solve.

For every mesh, n in {1, 4}, energy order m in {1, 2} and both spline kinds, with 30 random hard constraints
(random faces, random tangent directions) and no alignment:
  factorization  - the bare factorization of the same system: `ExactSolver(ops, m, 1, None, kind)` with the
                   operators given, i.e. V = E_m - lambda M assembled from them, its CHOLMOD factorization and
                   the release of the solver (core.solve releases its own solver before it returns)
  operators      - `FieldOperators(mesh, n)` alone (frames, connection, S, M): part of the one-shot, not of the
                   factorization row
  one-shot       - `nfield.core.solve(mesh, ...)` end to end with the mesh already loaded: operators, the
                   constraints, the factorization, the solve and the result (unit field, 3D directions, energy,
                   singularities)
  ratio          - one-shot / factorization, measured back to back in each repeat; the median of the ratios,
                   of wall times and (less sensitive to a loaded machine) of CPU times of the process. Each
                   measured block starts after common.settle(), so that the BLAS worker threads of the block
                   before are idle and their CPU time is not charged to it.
  live first     - a DesignSession whose factorization is done (one constraint placed and solved) gets 30 new
                   constraints of the same kind and solves (details=False): the columns of the 30 new faces,
                   the Schur system and the per-face field
Vector rows place vector constraints (n-vector spline, eq. 8/11; length 1 in 3D), direction rows direction
constraints (n-direction spline, eq. 9/12). Medians of --repeats repeats (each with new random constraints).
Every mesh runs in its own subprocess. Writes bench/results/one_shot.{json,md} (with --quick: one_shot_quick.*).

Targets (bunny 69k and armadillo 86k faces): one-shot <= 1.2 x factorization for vector splines, <= 1.5 x
for direction splines; the live first solve >= 3 x faster than before (docs/benchmarks.md has both figures).

Usage: python bench/one_shot.py [--quick] [--meshes a.obj,b.obj] [--repeats 3]
"""
from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

MESHES = ["fandisk.obj", "rocker-arm.obj", "stanford-bunny.obj", "armadillo.obj"]
QUICK_MESHES = ["rocker-arm.obj"]
TARGET_MESHES = ("stanford-bunny.obj", "armadillo.obj")
NUM_CONSTRAINTS = 30
CONFIGS = [(n, m, kind) for n in (1, 4) for m in (1, 2) for kind in ("vector", "direction")]
TARGET_RATIO = {"vector": 1.2, "direction": 1.5}


def measure_one(mesh_name: str, repeats: int) -> dict:
    """Runs inside the subprocess: every configuration for one mesh."""
    import numpy as np
    from nfield import core

    nat = core.native()
    rng = np.random.default_rng(11)
    load_before = common.loadavg()
    mesh = core.Mesh.from_file(common.DATA / mesh_name)
    active = np.flatnonzero(np.asarray(mesh.native.face_active))
    normals = np.asarray(mesh.native.face_normals)

    def random_constraints(count: int):
        faces = rng.choice(active, size=count, replace=False)
        d = rng.normal(size=(count, 3))
        d -= (d * normals[faces]).sum(1, keepdims=True) * normals[faces]
        return [int(f) for f in faces], d / np.linalg.norm(d, axis=1, keepdims=True)

    rows = []
    for n, m, kind in CONFIGS:
        fact, fact_cpu, operators, one_shot, ratio, ratio_cpu, live = [], [], [], [], [], [], []
        for _ in range(repeats):
            faces, d = random_constraints(NUM_CONSTRAINTS + 1)
            common.settle()
            with common.Clock() as ops_clock:
                ops = nat.FieldOperators(mesh.native, n, "geometric")
            common.settle()
            with common.Clock() as bare:
                solver = nat.ExactSolver(ops, m, 1.0, None, kind)
                del solver
            del ops
            make = core.VectorConstraint if kind == "vector" else core.DirectionConstraint
            cons = [make(f, tuple(v)) for f, v in zip(faces[1:], d[1:])]
            kw = {"vector_constraints": cons} if kind == "vector" else {"constraints": cons}
            common.settle()
            with common.Clock() as whole:
                core.solve(mesh, n=n, order=m, **kw)
            fact.append(bare.wall)
            fact_cpu.append(bare.cpu)
            operators.append(ops_clock.wall)
            one_shot.append(whole.wall)
            ratio.append(whole.wall / bare.wall)
            ratio_cpu.append(whole.cpu / max(bare.cpu, 1e-9))
            # live: factor with one constraint, then 30 new ones
            session = core.DesignSession(mesh, n=n, order=m)
            place = session.set_vector if kind == "vector" else session.set_direction
            place(faces[0], d[0])
            session.solve(details=False)
            for f, v in zip(faces[1:], d[1:]):
                place(f, v)
            common.settle()
            t0 = time.perf_counter()
            session.solve(details=False)
            live.append(time.perf_counter() - t0)
            del session
        rows.append({"n": n, "order": m, "kind": kind, "factorization_s": statistics.median(fact),
                     "factorization_cpu_s": statistics.median(fact_cpu), "operators_s": statistics.median(operators),
                     "one_shot_s": statistics.median(one_shot), "ratio": statistics.median(ratio),
                     "ratio_cpu": statistics.median(ratio_cpu),
                     "live_first_solve_s": statistics.median(live),
                     "spread": {"ratio": [min(ratio), max(ratio)], "ratio_cpu": [min(ratio_cpu), max(ratio_cpu)],
                                "live_first_solve_s": [min(live), max(live)]},
                     "samples": {"ratio": ratio, "ratio_cpu": ratio_cpu, "factorization_s": fact,
                                 "one_shot_s": one_shot, "live_first_solve_s": live}})
        print(f"{mesh_name} n={n} m={m} {kind}: factorization {common.fmt_ms(rows[-1]['factorization_s'])}, one-shot "
              f"{common.fmt_ms(rows[-1]['one_shot_s'])}, ratio {rows[-1]['ratio']:.2f} (CPU "
              f"{rows[-1]['ratio_cpu']:.2f}), live first solve "
              f"{common.fmt_ms(rows[-1]['live_first_solve_s'])}", file=sys.stderr, flush=True)
    return {"mesh": mesh_name, "faces": int(mesh.num_faces), "repeats": repeats, "rows": rows,
            "loadavg_before": load_before, "loadavg_after": common.loadavg()}


def table(results: list[dict]) -> str:
    f = common.fmt_ms
    columns = ["mesh", "faces", "n", "m", "kind", "factorization", "operators", "one-shot `core.solve`",
               "ratio wall (CPU)", "target", "live first solve (30 new)"]
    rows = [[r["mesh"], str(r["faces"]), str(x["n"]), str(x["order"]), x["kind"], f(x["factorization_s"]),
             f(x.get("operators_s")), f(x["one_shot_s"]), f"{x['ratio']:.2f} ({x.get('ratio_cpu', float('nan')):.2f})",
             f"<= {TARGET_RATIO[x['kind']]}" if r["mesh"] in TARGET_MESHES else "-", f(x["live_first_solve_s"])]
            for r in results for x in r["rows"]]
    return common.markdown_table(columns, rows)


def targets(results: list[dict]) -> list[dict]:
    checks = []
    for r in (r for r in results if r["mesh"] in TARGET_MESHES):
        for x in r["rows"]:
            limit = TARGET_RATIO[x["kind"]]
            checks.append({"what": f"one-shot / factorization, {r['mesh']} n={x['n']} m={x['order']} {x['kind']}",
                           "ratio": x["ratio"], "ratio_cpu": x.get("ratio_cpu"), "target_ratio": limit,
                           "met": x["ratio"] <= limit, "met_cpu": x.get("ratio_cpu", float("inf")) <= limit})
    return checks


def run(meshes: list[str], repeats: int, stem: str = "one_shot") -> dict:
    results = common.run_children(Path(__file__), meshes, ["--repeats", str(repeats)], "one-shot")
    m = common.meta(repeats=repeats, setting=f"{NUM_CONSTRAINTS} random hard constraints, no alignment, strength 1")
    doc = {"meta": m, "results": results, "targets": targets(results)}
    md = (f"# One-shot solve and live first solve\n\n{m['setting']}; medians of {repeats} repeats; {m['date']}, load "
          f"{m['loadavg']}.\n\n{table(results)}\n")
    common.write_results(stem, doc, md)
    return doc


if __name__ == "__main__":
    sys.exit(common.repeats_main(__doc__, "the rocker arm only, one repeat", measure_one=measure_one, run=run,
                                 table=table, meshes=MESHES, quick_meshes=QUICK_MESHES, stem="one_shot"))
