"""Accuracy of the spectral reduction (paper Fig. 8): reduced vs exact 4-direction splines on the bunny.

Setting: tests/data/stanford-bunny.obj (69,451 faces), n = 4, biharmonic (order 2), NO alignment field
(the smoothest field through the constraints: the paper's Fig. 8 setting), strength 1 (lambda = -(4 pi/A)^2,
the same for both solvers), --trials (20) random sets of --constraints (10) random hard direction
constraints (random faces, random tangent directions). For every set, the exact spline (ExactSolver,
factored once; the sets only change constraints) is compared with the reduced spline (ReducedSolver) for
bases of k in --ks eigenfields. ONE basis of max(ks) eigenpairs is computed (or read from the disk cache
bench/results/cache/, via nfield.core.spectral.load_or_compute_basis) and truncated for the smaller k
(the first k' eigenpairs of a basis are the basis of size k').

Metrics, area-weighted relative L2 distances over the faces (A_f the face areas):
  unit field:   sqrt(sum A_f |u_f - e_f|^2 / sum A_f |e_f|^2), u = w / |w| and e = w_exact / |w_exact| the unit
                representation vectors (u^n encoding) of the reduced and exact solutions: the direction
                field as displayed (the denominator is the total area). This is what the plot shows.
  raw solution: sqrt(sum A_f |w_f - w_exact_f|^2 / sum A_f |w_exact_f|^2), the solutions w themselves
                (magnitudes included).
Min / mean / max over the trials per k. Writes bench/results/fig8.{json,md,png} (PNG if matplotlib imports).

Usage: python bench/fig8.py [--ks 50,100,200,500,1000,2000] [--trials 20] [--constraints 10] [--mesh NAME]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402
from paper import FIG8_THRESHOLD  # noqa: E402

KS = [50, 100, 200, 500, 1000, 2000]
QUICK_KS = [25, 50, 100, 200]
MESH = "stanford-bunny.obj"
QUICK_MESH = "fandisk.obj"
CACHE = common.RESULTS / "cache"


def rel_l2(a, b, areas) -> float:
    import numpy as np

    return float(np.sqrt((areas * np.abs(a - b) ** 2).sum() / (areas * np.abs(b) ** 2).sum()))


def unit(w):
    import numpy as np

    mag = np.abs(w)
    return np.where(mag > 0, w / np.where(mag > 0, mag, 1), 0)


def get_basis(nat, ops, mesh_name: str, k: int, progress_label: str = "basis"):
    """The basis of k eigenpairs from bench/results/cache (computed and cached if missing). Returns
    (basis, info dict). The time of the computation that made the cached file is kept next to it
    (<file>.timing.json) so a run that reads the cache can still report it."""
    from nfield.core import spectral

    last = [time.perf_counter()]

    def progress(fraction):
        if time.perf_counter() - last[0] > 30:
            last[0] = time.perf_counter()
            print(f"  {progress_label} k={k}: {100 * fraction:.0f}% (load {common.loadavg()[0]:.1f})",
                  file=sys.stderr, flush=True)
        return True

    load_before = common.loadavg()
    with common.Clock() as c:
        basis, info = spectral.load_or_compute_basis(ops, k, "double", cache_dir=CACHE, progress=progress)
    out = {"k": k, "source": info.source, "seconds": c.wall, "cpu_seconds": c.cpu,
           "memory_bytes": int(basis.memory_bytes), "loadavg_before": load_before, "loadavg_after": common.loadavg(),
           "path": str(info.path) if info.path else None}
    if info.path is not None:
        timing = Path(str(info.path) + ".timing.json")
        if info.source == "computed":
            timing.write_text(json.dumps({"mesh": mesh_name, "k": k, "wall_s": c.wall, "cpu_s": c.cpu,
                                          "loadavg_before": load_before, "loadavg_after": out["loadavg_after"],
                                          "peak_rss_mb": common.peak_rss_mb(),
                                          "date": time.strftime("%Y-%m-%d %H:%M %Z")}))
        elif timing.is_file():
            out["computed_earlier"] = json.loads(timing.read_text())
    return basis, out


def measure(mesh_name: str, ks: list[int], trials: int, constraints: int, seed: int) -> dict:
    import numpy as np
    from nfield.core import native

    nat = native()
    rng = np.random.default_rng(seed)
    mesh = common.load_native_mesh(nat, mesh_name)
    ops = nat.FieldOperators(mesh, 4)
    areas = np.asarray(mesh.face_areas)
    active = np.flatnonzero(mesh.face_active)
    kmax = max(ks)
    basis, basis_info = get_basis(nat, ops, mesh_name, kmax)
    order, strength = 2, 1.0
    t0 = time.perf_counter()
    exact = nat.ExactSolver(ops, order, strength, None, "direction")
    reduced = {k: nat.ReducedSolver(ops, basis if k == kmax else basis.truncated(k), order, strength, None,
                                    "direction") for k in ks}
    setup_s = time.perf_counter() - t0
    unit_err = {k: [] for k in ks}
    raw_err = {k: [] for k in ks}
    residual = {k: [] for k in ks}
    t0 = time.perf_counter()
    for _ in range(trials):
        faces, d = common.random_direction_constraints(ops, active, rng, constraints)
        exact.clear_constraints()
        for f, dd in zip(faces, d):
            exact.set_direction_constraint(int(f), complex(dd))
        w_exact = np.asarray(exact.solve())
        u_exact = unit(w_exact)
        for k, r in reduced.items():
            r.clear_constraints()
            for f, dd in zip(faces, d):
                r.set_direction_constraint(int(f), complex(dd))
            w = np.asarray(r.solve())
            unit_err[k].append(rel_l2(unit(w), u_exact, areas))
            raw_err[k].append(rel_l2(w, w_exact, areas))
            residual[k].append(float(r.constraint_residual))
    trials_s = time.perf_counter() - t0

    def stats(xs):
        return {"min": float(np.min(xs)), "mean": float(np.mean(xs)), "max": float(np.max(xs)),
                "median": float(np.median(xs))}

    rows = [{"k": k, "unit": stats(unit_err[k]), "raw": stats(raw_err[k]),
             "max_constraint_residual": float(np.max(residual[k])), "unit_all": unit_err[k], "raw_all": raw_err[k]}
            for k in ks]
    return {"mesh": mesh_name, "faces": int(mesh.num_faces), "n": 4, "order": order, "alignment": None,
            "strength": strength, "trials": trials, "constraints": constraints, "seed": seed, "basis": basis_info,
            "solver_setup_s": setup_s, "trials_s": trials_s, "rows": rows, "peak_rss_mb": common.peak_rss_mb()}


def table(res: dict) -> str:
    lines = ["| k | unit field: min | mean | max | raw solution w: min | mean | max | below 10 % (unit, all trials) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in res["rows"]:
        u, w = r["unit"], r["raw"]
        ok = "yes" if u["max"] < FIG8_THRESHOLD else ("mean only" if u["mean"] < FIG8_THRESHOLD else "no")
        lines.append(f"| {r['k']} | {100 * u['min']:.1f} % | {100 * u['mean']:.1f} % | {100 * u['max']:.1f} % | "
                     f"{100 * w['min']:.1f} % | {100 * w['mean']:.1f} % | {100 * w['max']:.1f} % | {ok} |")
    return "\n".join(lines)


def plot(res: dict, path: Path) -> str | None:
    """The PNG (log k axis, min-max band and mean of the unit-field error, mean of the raw-solution error,
    the paper's 10 % line). Returns None when matplotlib is not importable."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return "matplotlib is not installed: no PNG (pip install 'matplotlib<3.10')"
    ks = [r["k"] for r in res["rows"]]
    lo = [100 * r["unit"]["min"] for r in res["rows"]]
    mean = [100 * r["unit"]["mean"] for r in res["rows"]]
    hi = [100 * r["unit"]["max"] for r in res["rows"]]
    raw = [100 * r["raw"]["mean"] for r in res["rows"]]
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=120)
    ax.fill_between(ks, lo, hi, color="tab:blue", alpha=0.25, label="unit field: min-max")
    ax.plot(ks, mean, "o-", color="tab:blue", label="unit field: mean")
    ax.plot(ks, raw, "s:", color="0.45", markersize=4, label="raw solution w: mean")
    ax.axhline(100 * FIG8_THRESHOLD, color="tab:red", linestyle="--", linewidth=1, label="paper: 10 % at k >= 1000")
    ax.set_xscale("log")
    ax.set_xticks(ks)
    ax.set_xticklabels([str(k) for k in ks])
    ax.minorticks_off()
    ax.set_xlabel("number of eigenfields k")
    ax.set_ylabel("relative L2 error vs exact [%]")
    ax.set_ylim(bottom=0)
    ax.set_title(f"{res['mesh']} ({res['faces']} faces): {res['trials']} trials x {res['constraints']} "
                 f"constraints,\n4-direction biharmonic spline, no alignment", fontsize=9)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return None


def markdown(res: dict, m: dict) -> str:
    b = res["basis"]
    basis_line = f"basis k={b['k']}: {b['source']} in {common.fmt_ms(b['seconds'])}"
    if "computed_earlier" in b:
        e = b["computed_earlier"]
        basis_line += (f" (computed on {e['date']} in {common.fmt_ms(e['wall_s'])} wall, {common.fmt_ms(e['cpu_s'])} "
                       f"CPU, load {e['loadavg_before'][0]:.1f} / {e['loadavg_after'][0]:.1f})")
    elif b["source"] == "computed":
        basis_line += f" wall, {common.fmt_ms(b['cpu_seconds'])} CPU (load {b['loadavg_before'][0]:.1f} / {b['loadavg_after'][0]:.1f})"
    return "\n".join([
        "# Accuracy of the spectral reduction (paper Fig. 8)", "",
        f"{res['mesh']} ({res['faces']} faces), 4-direction spline, biharmonic, no alignment (the smoothest field "
        f"through the constraints, the paper's Fig. 8 setting), strength 1; {res['trials']} trials of "
        f"{res['constraints']} random hard direction constraints; reduced (k eigenfields, truncations of one "
        f"basis) vs exact. Relative L2 distance, area-weighted: **unit field** = of the unit representation "
        f"vectors w/|w| (the displayed direction field; the plot shows this), **raw** = of the solutions w. "
        f"{m['date']}, load {m['loadavg'][0]:.1f}.", "",
        table(res), "",
        f"The paper: >= 1000 eigenfields keep the error below {100 * FIG8_THRESHOLD:.0f} %; 500 are visually hard "
        "to tell apart from the full solution.", "",
        basis_line + f"; solver set-up {common.fmt_ms(res['solver_setup_s'])}, all trials "
        f"{common.fmt_ms(res['trials_s'])}; largest constraint residual of a reduced solve "
        f"{max(r['max_constraint_residual'] for r in res['rows']):.1e}.", "",
        "![Fig. 8](fig8.png)" if res.get("png") else f"(no plot: {res.get('png_note')})", ""])


def run(ks: list[int], trials: int, constraints: int, mesh: str, seed: int = 8, stem: str = "fig8") -> dict:
    res = common.run_child(Path(__file__), ["--one", mesh, "--ks", ",".join(map(str, ks)), "--trials", str(trials),
                                            "--constraints", str(constraints), "--seed", str(seed)],
                           f"fig8 {mesh} k<={max(ks)}")
    common.RESULTS.mkdir(parents=True, exist_ok=True)
    png = common.RESULTS / f"{stem}.png"
    note = plot(res, png)
    res["png"] = None if note else str(png)
    res["png_note"] = note
    m = common.meta()
    doc = {"meta": m, "result": res}
    common.write_results(stem, doc, markdown(res, m))
    return doc


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_MESH}, k in {QUICK_KS}, 4 trials")
    parser.add_argument("--ks", help="comma-separated basis sizes (default 50,100,200,500,1000,2000)")
    parser.add_argument("--trials", type=int)
    parser.add_argument("--constraints", type=int, default=10)
    parser.add_argument("--mesh")
    parser.add_argument("--seed", type=int, default=8)
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args()
    ks = [int(k) for k in args.ks.split(",")] if args.ks else (QUICK_KS if args.quick else KS)
    trials = args.trials or (4 if args.quick else 20)
    if args.one:
        print(json.dumps(measure(args.one, ks, trials, args.constraints, args.seed)))
        return 0
    mesh = args.mesh or (QUICK_MESH if args.quick else MESH)
    doc = run(ks, trials, args.constraints, mesh, args.seed, "fig8_quick" if args.quick else "fig8")
    print(json.dumps({"meta": doc["meta"], "rows": [{k: v for k, v in r.items() if not k.endswith("_all")}
                                                    for r in doc["result"]["rows"]]}, indent=2))
    print(table(doc["result"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
