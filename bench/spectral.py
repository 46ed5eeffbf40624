"""Benchmark of the spectral reduction (paper Table 1, "Bases setup" and "Reduced setup & solve").

For each mesh: a 4-direction field, curvature-max alignment, strength 1, 30 random hard direction constraints
(the exact-solver benchmark's setting), a basis of k = 500 eigenfields.
  basis set-up      - SpectralBasis.compute(ops, k), computed fresh (never from the cache): wall time and CPU
                      time of the process (all threads; the computation uses two cores), one run
  basis memory      - SpectralBasis.memory_bytes stored in double (complex128) and in float32 (complex64)
  peak RSS          - of the process after the basis (mesh, operators, basis and its workspace)
then for the harmonic and biharmonic energies, with the basis stored in double and in float32:
  reduced set-up    - ReducedSolver construction (Lambda, projection of the alignment U^H M u')
  reduced first     - placing the 30 constraints + solve_coefficients(): with the set-up, the paper's
                      "Reduced setup & solve"
  reduced update    - re-aim one of the 30 constraints + solve_coefficients() (k coefficients: the reduced
                      solve alone), median of --repeats
  strength change   - set_strength(s) + solve_coefficients() (no refactorization), median of --repeats
  update + field    - re-aim + solve(): the same plus the reconstruction U x of the per-face field (and the
                      snapping of the constrained faces), median of --solve-repeats
  reconstruction    - reconstruct(x) alone (U x), median of --solve-repeats
  float32 vs double - relative differences of the reduced solutions computed from the two storages (same
                      constraints): coefficients x (Euclidean), raw field w and unit field w/|w| (area-weighted L2)
  reduced vs exact  - area-weighted relative L2 distance of the reduced (k) solution to the exact spline
                      (ExactSolver, same constraints), raw w and unit field: the scale against which the
                      float32 rounding is judged
Every mesh runs in its own subprocess (peak RSS is its own); the load average is recorded before the
basis, after it, and at the end. Writes bench/results/spectral.{json,md}.

Usage: python bench/spectral.py [--quick] [--meshes a.obj,...] [--k 500] [--repeats 200] [--solve-repeats 30]
       (mesh "armadillo-x4" is the 4x-subdivided armadillo: ~10 min or more and ~6 GB for its basis)
"""
from __future__ import annotations

import json
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402
from paper import paper_row  # noqa: E402

MESHES = ["fandisk.obj", "rocker-arm.obj", "stanford-bunny.obj", "armadillo.obj"]
QUICK_MESHES = ["fandisk.obj", "rocker-arm.obj"]
OPTIONAL_MESHES = ["armadillo-x4"]  # a failure (e.g. out of memory) leaves the mesh out instead of stopping the run
NUM_CONSTRAINTS = 30
# Targets of the spectral mode.
TARGETS = {"basis_s": {"stanford-bunny.obj": 60.0, "armadillo.obj": 75.0}, "update_ms": 2.0, "reconstruction_ms": 10.0}


def measure_one(mesh_name: str, k: int, repeats: int, solve_repeats: int, seed: int) -> dict:
    import numpy as np
    from nfield.core import native

    nat = native()
    rng = np.random.default_rng(seed)
    out = {"mesh": mesh_name, "k": k, "repeats": repeats, "solve_repeats": solve_repeats,
           "loadavg_start": common.loadavg()}
    mesh = common.load_native_mesh(nat, mesh_name)
    ops = nat.FieldOperators(mesh, 4)
    align = nat.alignment_field(ops, "curvature-max")
    areas = np.asarray(mesh.face_areas)
    active = np.flatnonzero(mesh.face_active)
    out.update(faces=int(mesh.num_faces), active_faces=int(active.size))
    out["rss_before_basis_mb"] = common.peak_rss_mb()

    # ---- basis set-up
    out["loadavg_before_basis"] = common.loadavg()
    with common.Clock() as c:
        basis = nat.SpectralBasis.compute(ops, k, "double")
    out["loadavg_after_basis"] = common.loadavg()
    single = basis.with_precision("single")
    out["basis"] = {"wall_s": c.wall, "cpu_s": c.cpu, "cores_used": c.cpu / c.wall if c.wall > 0 else None,
                    "memory_double_bytes": int(basis.memory_bytes), "memory_single_bytes": int(single.memory_bytes),
                    "single_over_double": single.memory_bytes / basis.memory_bytes,
                    "peak_rss_mb": common.peak_rss_mb(), "lambda_k": float(np.asarray(basis.values)[-1])}

    # Streaming-read bandwidth of this machine (numpy sum over 256 MB), the bound of the reconstruction U x.
    buf = np.ones(1 << 25)
    bw = []
    for _ in range(5):
        t0 = time.perf_counter()
        buf.sum()
        bw.append(buf.nbytes / (time.perf_counter() - t0))
    del buf
    out["read_bandwidth_gb_s"] = statistics.median(bw) / 1e9

    faces, d = common.random_direction_constraints(ops, active, rng, NUM_CONSTRAINTS)
    f0 = int(faces[0])
    rot = np.exp(1j * rng.uniform(-0.5, 0.5, size=max(repeats, solve_repeats)))

    def med(xs):
        return statistics.median(xs)

    for order, label in ((1, "harmonic"), (2, "biharmonic")):
        res: dict = {}
        ex = nat.ExactSolver(ops, order, 1.0, align, "direction")
        for f, dd in zip(faces, d):
            ex.set_direction_constraint(int(f), complex(dd))
        w_exact = np.asarray(ex.solve())
        del ex
        finals = {}
        for prec, B in (("double", basis), ("single", single)):
            r: dict = {}
            t0 = time.perf_counter()
            red = nat.ReducedSolver(ops, B, order, 1.0, align, "direction")
            t1 = time.perf_counter()
            for f, dd in zip(faces, d):
                red.set_direction_constraint(int(f), complex(dd))
            red.solve_coefficients()
            t2 = time.perf_counter()
            r["setup_s"], r["first_solve_s"] = t1 - t0, t2 - t1
            r["setup_and_first_solve_s"] = t2 - t0
            upd, upd_cpu = [], []
            for i in range(repeats):
                c0, t0 = common.cpu_seconds(), time.perf_counter()
                red.set_direction_constraint(f0, complex(d[0] * rot[i]))
                red.solve_coefficients()
                upd.append(time.perf_counter() - t0)
                upd_cpu.append(common.cpu_seconds() - c0)
            r["update_s"] = med(upd)
            r["update_p90_s"] = float(np.percentile(upd, 90))
            r["update_cpu_s"] = med(upd_cpu)  # rusage resolution is coarse (~1 ms ticks on some kernels)
            strength = []
            for i in range(repeats):
                t0 = time.perf_counter()
                red.set_strength(1.0 + (i % 2))
                red.solve_coefficients()
                strength.append(time.perf_counter() - t0)
            red.set_strength(1.0)
            r["strength_change_s"] = med(strength)
            full, recon = [], []
            for i in range(solve_repeats):
                t0 = time.perf_counter()
                red.set_direction_constraint(f0, complex(d[0] * rot[i]))
                red.solve()
                full.append(time.perf_counter() - t0)
            red.set_direction_constraint(f0, complex(d[0]))
            x = np.asarray(red.solve_coefficients())
            for _ in range(solve_repeats):
                t0 = time.perf_counter()
                red.reconstruct(x)
                recon.append(time.perf_counter() - t0)
            r["update_and_field_s"] = med(full)
            r["reconstruction_s"] = med(recon)
            r["reconstruction_gb_s"] = B.memory_bytes / r["reconstruction_s"] / 1e9
            w = np.asarray(red.solve())
            r["constraint_residual"] = float(red.constraint_residual)
            r["vs_exact_raw"] = float(np.sqrt((areas * np.abs(w - w_exact) ** 2).sum() / (areas * np.abs(w_exact) ** 2).sum()))
            u, ue = unit(w), unit(w_exact)
            r["vs_exact_unit"] = float(np.sqrt((areas * np.abs(u - ue) ** 2).sum() / areas[np.abs(ue) > 0].sum()))
            finals[prec] = (x, w)
            res[prec] = r
            del red
        (xd, wd), (xs, ws) = finals["double"], finals["single"]
        ud, us = unit(wd), unit(ws)
        res["single_vs_double"] = {
            "coefficients": float(np.linalg.norm(xs - xd) / np.linalg.norm(xd)),
            "raw": float(np.sqrt((areas * np.abs(ws - wd) ** 2).sum() / (areas * np.abs(wd) ** 2).sum())),
            "unit": float(np.sqrt((areas * np.abs(us - ud) ** 2).sum() / areas[np.abs(ud) > 0].sum())),
            "unit_max_angle_deg": float(np.degrees(np.abs(np.angle(us[np.abs(ud) > 0] * np.conj(ud[np.abs(ud) > 0])))).max() / 4),
        }
        out[label] = res
    out["peak_rss_mb"] = common.peak_rss_mb()
    out["loadavg_end"] = common.loadavg()
    return out


def unit(w):
    import numpy as np

    mag = np.abs(w)
    return np.where(mag > 0, w / np.where(mag > 0, mag, 1), 0)


def mb(nbytes: int) -> str:
    return f"{nbytes / 2**20:.0f} MB"


def paper_cells(mesh: str) -> tuple[str, str]:
    p = paper_row(mesh)
    if p is None:
        return "-", "-"
    row, how = p
    name = row["paper_mesh"] + ("" if how == "same" else ", similar size")
    return (f"{common.fmt_ms(row['basis_s'])} ({name}, {row['faces']})",
            f"{row['reduced'][0]} \\ {row['reduced'][1]} ms")


def table(rows: list[dict]) -> str:
    f = common.fmt_ms
    columns = ["mesh", "faces", "basis k", "basis set-up wall (CPU)", "paper basis", "memory double \\ float32",
               "peak RSS", "reduced set-up & solve harm. \\ biharm.", "paper",
               "update (re-aim + solve_coefficients) harm. \\ biharm.", "strength change", "update + field U x",
               "reconstruction U x double \\ float32", "load before/after basis"]
    cells = []
    for r in rows:
        h, b = r["harmonic"]["double"], r["biharmonic"]["double"]
        pb, pr = paper_cells(r["mesh"])
        cells.append([
            r["mesh"], str(r["faces"]), str(r["k"]), f"{f(r['basis']['wall_s'])} ({f(r['basis']['cpu_s'])})", pb,
            f"{mb(r['basis']['memory_double_bytes'])} \\ {mb(r['basis']['memory_single_bytes'])}",
            f"{r['peak_rss_mb']:.0f} MB", f"{f(h['setup_and_first_solve_s'])} \\ {f(b['setup_and_first_solve_s'])}", pr,
            f"{f(h['update_s'])} \\ {f(b['update_s'])}", f"{f(h['strength_change_s'])} \\ {f(b['strength_change_s'])}",
            f"{f(h['update_and_field_s'])} \\ {f(b['update_and_field_s'])}",
            f"{f(b['reconstruction_s'])} \\ {f(r['biharmonic']['single']['reconstruction_s'])}",
            f"{r['loadavg_before_basis'][0]:.1f} / {r['loadavg_after_basis'][0]:.1f}"])
    return common.markdown_table(columns, cells)


def precision_table(rows: list[dict]) -> str:
    f = common.fmt_ms
    columns = ["mesh", "energy", "memory double \\ float32", "update double \\ float32",
               "reconstruction double \\ float32", "float32 vs double: x", "raw w", "unit field (max angle)",
               "reduced vs exact, unit field: double \\ float32", "constraint residual double \\ float32"]
    cells = []
    for r in rows:
        for label in ("harmonic", "biharmonic"):
            d, s, c = r[label]["double"], r[label]["single"], r[label]["single_vs_double"]
            cells.append([
                r["mesh"], label, f"{mb(r['basis']['memory_double_bytes'])} \\ {mb(r['basis']['memory_single_bytes'])}",
                f"{f(d['update_s'])} \\ {f(s['update_s'])}",
                f"{f(d['reconstruction_s'])} \\ {f(s['reconstruction_s'])}",
                f"{c['coefficients']:.1e}", f"{c['raw']:.1e}", f"{c['unit']:.1e} ({c['unit_max_angle_deg']:.2g} deg)",
                f"{100 * d['vs_exact_unit']:.2f} % \\ {100 * s['vs_exact_unit']:.2f} %",
                f"{d['constraint_residual']:.0e} \\ {s['constraint_residual']:.0e}"])
    return common.markdown_table(columns, cells)


def target_check(rows: list[dict]) -> list[dict]:
    checks = []
    for r in rows:
        limit = TARGETS["basis_s"].get(r["mesh"])
        if limit:
            checks.append({"what": f"basis k={r['k']}, {r['mesh']} (wall)", "value_s": r["basis"]["wall_s"],
                           "cpu_s": r["basis"]["cpu_s"], "target_s": limit, "met": r["basis"]["wall_s"] < limit})
    worst = max(rows, key=lambda r: max(r[e]["double"]["update_s"] for e in ("harmonic", "biharmonic")))
    u = max(worst[e]["double"]["update_s"] for e in ("harmonic", "biharmonic"))
    checks.append({"what": f"reduced update, 30 constraints (worst mesh: {worst['mesh']})", "value_s": u,
                   "target_s": TARGETS["update_ms"] / 1000, "met": u < TARGETS["update_ms"] / 1000})
    for r in rows:
        if r["mesh"] == "armadillo.obj":
            for prec in ("double", "single"):
                t = r["biharmonic"][prec]["reconstruction_s"]
                checks.append({"what": f"reconstruction U x, {r['faces']} faces, {prec}", "value_s": t,
                               "target_s": TARGETS["reconstruction_ms"] / 1000, "met": t < TARGETS["reconstruction_ms"] / 1000})
    return checks


def markdown(rows: list[dict], checks: list[dict], m: dict) -> str:
    f = common.fmt_ms
    md = ["# Spectral reduction benchmark", "",
          f"4-direction field, curvature-max alignment, strength 1, {NUM_CONSTRAINTS} random hard direction "
          f"constraints, basis of k eigenfields computed fresh (one run; wall and process CPU time, two threads). "
          f"Update / strength change: medians of {m['repeats']} repeats; with the field: medians of "
          f"{m['solve_repeats']}. {m['date']}, {m['cpus']} CPUs shared with other jobs: load average "
          f"{m['loadavg'][0]:.1f} at the end.", "",
          table(rows), "",
          "## float32 vs double basis storage", "", precision_table(rows), "",
          "Streaming-read bandwidth measured in the same process (numpy sum of 256 MB): "
          + ", ".join(f"{r['mesh']} {r['read_bandwidth_gb_s']:.1f} GB/s" for r in rows)
          + "; the reconstruction reads all of U (k x faces complex values), so its time is bounded below by "
            "memory / bandwidth.", "",
          "## Spectral targets", "", "| what | measured | target | met |", "|---|---|---|---|"]
    for c in checks:
        extra = f" ({f(c['cpu_s'])} CPU)" if "cpu_s" in c else ""
        md.append(f"| {c['what']} | {f(c['value_s'])}{extra} | < {f(c['target_s'])} | {'yes' if c['met'] else 'NO'} |")
    md.append("")
    return "\n".join(md)


def run(meshes: list[str], k: int, repeats: int, solve_repeats: int, seed: int = 7, stem: str = "spectral") -> dict:
    rows, failed = [], []
    for name in meshes:
        try:
            rows.append(common.run_child(Path(__file__), ["--one", name, "--k", str(k), "--repeats", str(repeats),
                                                          "--solve-repeats", str(solve_repeats), "--seed", str(seed)],
                                         f"spectral {name} k={k}"))
        except RuntimeError as e:
            if name not in OPTIONAL_MESHES:
                raise
            print(f"{e}: left out of the table", file=sys.stderr, flush=True)
            failed.append(name)
    m = common.meta(repeats=repeats, solve_repeats=solve_repeats, seed=seed, k=k,
                    setting=f"4-direction field, curvature-max alignment, strength 1, {NUM_CONSTRAINTS} random hard "
                            f"direction constraints, k = {k}")
    checks = target_check(rows)
    doc = {"meta": m, "results": rows, "targets": checks, "failed": failed}
    common.write_results(stem, doc, markdown(rows, checks, m))
    return doc


def main() -> int:
    parser = common.mesh_parser(__doc__, "small meshes, k = 100, few repeats")
    parser.add_argument("--k", type=int)
    parser.add_argument("--repeats", type=int)
    parser.add_argument("--solve-repeats", type=int)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--out", help="stem of the result files in bench/results (default spectral, spectral_quick)")
    args = parser.parse_args()
    k = args.k or (100 if args.quick else 500)
    repeats = args.repeats or (30 if args.quick else 200)
    solve_repeats = args.solve_repeats or (5 if args.quick else 30)
    if args.one:
        print(json.dumps(measure_one(args.one, k, repeats, solve_repeats, args.seed)))
        return 0
    doc = run(common.chosen_meshes(args, MESHES, QUICK_MESHES), k, repeats, solve_repeats, args.seed,
              args.out or ("spectral_quick" if args.quick else "spectral"))
    print(json.dumps(doc, indent=2))
    print(markdown(doc["results"], doc["targets"], doc["meta"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
