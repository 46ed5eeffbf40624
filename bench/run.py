"""The whole benchmark (`python3 build_addon.py bench [args]`): the paper's Table 1 for our meshes, the exact
live session and the paper's Fig. 8, with the paper's numbers beside ours.

Parts (each also runs alone; every mesh in its own subprocess):
  exact     bench/exact_solver.py  factorization, unreduced solve (harmonic, biharmonic), peak memory; includes
                                   "armadillo-x4", the armadillo subdivided once (4x: 345,928 faces, generated)
  oneshot   bench/one_shot.py      the one-shot rows: nfield.core.solve end to end against the bare factorization
                                   (n = 1, 4; m = 1, 2; vector and direction splines; 30 constraints) and a live
                                   session's first solve with 30 new constraints
  spectral  bench/spectral.py      basis set-up (k = 500, wall and CPU), basis memory double / float32, reduced
                                   set-up & solve, reduced update, strength change, reconstruction, float32 vs
                                   double; --x4-basis adds the basis of the subdivided armadillo (long: see
                                   docs/benchmarks.md)
  live      bench/live_session.py  the exact live session: re-aim, new face, remove, region edits
  guides    bench/guides.py        live guide edits: moving a curve, a comb stroke, a weight change (live
                                   regions), a target change, and the global refactorization they defer
  fig8      bench/fig8.py          reduced vs exact on the bunny for k = 50 ... 2000 (one basis of k = 2000,
                                   cached in bench/results/cache/), table and PNG
  remesh    bench/remesh.py        quad remeshing beside QuadriFlow (bpy) and Instant Meshes (pyinstantmeshes,
                                   installed into bench/.peers by `build_addon.py bench`; failed when missing), ~5,000 quads on five meshes
Writes bench/results/table1.{json,md} (the combined table, with --quick: table1_quick.*) besides each part's
own files, prints the combined JSON and then the readable table.

--quick: small meshes, small k, few repeats (validates the scripts: under a minute on a quiet machine, a few
minutes on a busy one; the numbers mean little). Default: the full run, about 18 min on the shared 2-core
machine at load 6-8 once the Fig. 8 basis (bunny, k = 2000) is cached, plus ~12 min the first time for that
basis; --x4-basis adds ~15 min and needs ~9.5 GB of memory (docs/benchmarks.md).

Usage: python bench/run.py [--quick] [--parts exact,oneshot,spectral,live,guides,fig8,remesh] [--x4-basis]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import common  # noqa: E402
import exact_solver  # noqa: E402
import fig8  # noqa: E402
import guides  # noqa: E402
import one_shot  # noqa: E402
import remesh  # noqa: E402
import spectral  # noqa: E402
from paper import FIG8_THRESHOLD, TABLE1, paper_row  # noqa: E402

PARTS = ("exact", "oneshot", "spectral", "live", "guides", "fig8", "remesh")


def run_live(quick: bool) -> dict:
    args = ["--quick", "--fact-repeats", "1"] if quick else []
    env_path = str(common.ROOT / "addon")
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, str(HERE / "live_session.py"), *args], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": env_path})
    if proc.returncode != 0:
        raise RuntimeError(f"live session: failed (exit {proc.returncode})\n{proc.stderr[-4000:]}")
    print(f"live session: done in {time.perf_counter() - t0:.0f} s (load {common.loadavg()[0]:.1f})",
          file=sys.stderr, flush=True)
    stem = "live_session_quick" if quick else "live_session"
    return json.loads((common.RESULTS / f"{stem}.json").read_text())


def run_guides(quick: bool) -> dict:
    args = ["--quick"] if quick else []
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, str(HERE / "guides.py"), *args], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(common.ROOT / "addon")})
    if proc.returncode != 0:
        raise RuntimeError(f"guides: failed (exit {proc.returncode})\n{proc.stderr[-4000:]}")
    print(f"guides: done in {time.perf_counter() - t0:.0f} s (load {common.loadavg()[0]:.1f})", file=sys.stderr,
          flush=True)
    return json.loads((common.RESULTS / ("guides_quick.json" if quick else "guides.json")).read_text())


def pair(a: float | None, b: float | None) -> str:
    f = common.fmt_ms
    return f"{f(a)} \\ {f(b)}" if a is not None or b is not None else "-"


def combined_rows(exact: dict | None, spec: dict | None, oneshot: dict | None = None) -> list[dict]:
    """One row per mesh: our figures and the paper's row (same model or similar size)."""
    by_mesh: dict[str, dict] = {}
    for r in (oneshot or {}).get("results", []):
        by_mesh.setdefault(r["mesh"], {"mesh": r["mesh"], "faces": r["faces"]})["one_shot"] = r["rows"]
    for r in (exact or {}).get("results", []):
        by_mesh.setdefault(r["mesh"], {"mesh": r["mesh"], "faces": r["faces"]})["exact"] = r
    for r in (spec or {}).get("results", []):
        by_mesh.setdefault(r["mesh"], {"mesh": r["mesh"], "faces": r["faces"]})["spectral"] = r
    rows = []
    for row in sorted(by_mesh.values(), key=lambda r: r["faces"]):
        out = {"mesh": row["mesh"], "faces": row["faces"]}
        if row.get("one_shot"):
            out["one_shot"] = row["one_shot"]
        s, e = row.get("spectral"), row.get("exact")
        if s:
            out["k"] = s["k"]
            out["basis_wall_s"], out["basis_cpu_s"] = s["basis"]["wall_s"], s["basis"]["cpu_s"]
            out["basis_memory_double_mb"] = s["basis"]["memory_double_bytes"] / 2**20
            out["basis_memory_single_mb"] = s["basis"]["memory_single_bytes"] / 2**20
            out["basis_loadavg"] = [s["loadavg_before_basis"][0], s["loadavg_after_basis"][0]]
            for label in ("harmonic", "biharmonic"):
                d = s[label]["double"]
                out[f"reduced_setup_solve_{label}_s"] = d["setup_and_first_solve_s"]
                out[f"reduced_update_{label}_s"] = d["update_s"]
                out[f"strength_change_{label}_s"] = d["strength_change_s"]
                out[f"update_and_field_{label}_s"] = d["update_and_field_s"]
            out["reconstruction_double_s"] = s["biharmonic"]["double"]["reconstruction_s"]
            out["reconstruction_single_s"] = s["biharmonic"]["single"]["reconstruction_s"]
        if e:
            for label in ("harmonic", "biharmonic"):
                out[f"factorization_{label}_s"] = e[label]["factorization_s"]
                out[f"unreduced_solve_{label}_s"] = e[label]["reaim_solve_s"]
            out["exact_peak_rss_mb"] = e["peak_rss_mb"]
        p = paper_row(row["mesh"])
        if p:
            prow, how = p
            out["paper"] = {**prow, "match": how}
        rows.append(out)
    return rows


def combined_table(rows: list[dict]) -> str:
    f = common.fmt_ms
    columns = ["mesh", "faces", "paper mesh (faces)", "basis set-up k=500: wall (CPU)", "paper",
               "basis memory double \\ float32", "reduced set-up & solve harm. \\ biharm.", "paper",
               "reduced update harm. \\ biharm.", "factorization harm. \\ biharm.", "paper",
               "unreduced solve harm. \\ biharm.", "paper"]
    table = []
    for r in rows:
        p = r.get("paper")
        pm = f"{p['paper_mesh']} ({p['faces']}){'' if p['match'] == 'same' else ', similar size only'}" if p else "-"
        has_s, has_e = "basis_wall_s" in r, "factorization_harmonic_s" in r
        cells = [r["mesh"], str(r["faces"]), pm]
        if has_s:
            basis = f"{f(r['basis_wall_s'])} ({f(r['basis_cpu_s'])})" + ("" if r["k"] == 500 else f" [k={r['k']}]")
            cells += [basis, f(p["basis_s"]) if p else "-",
                      f"{r['basis_memory_double_mb']:.0f} \\ {r['basis_memory_single_mb']:.0f} MB",
                      pair(r["reduced_setup_solve_harmonic_s"], r["reduced_setup_solve_biharmonic_s"]),
                      f"{p['reduced'][0]} \\ {p['reduced'][1]} ms" if p else "-",
                      pair(r["reduced_update_harmonic_s"], r["reduced_update_biharmonic_s"])]
        else:
            cells += ["(not run)", f(p["basis_s"]) if p else "-", "-", "-",
                      f"{p['reduced'][0]} \\ {p['reduced'][1]} ms" if p else "-", "-"]
        if has_e:
            cells += [pair(r["factorization_harmonic_s"], r["factorization_biharmonic_s"]),
                      f"{p['fact'][0]} \\ {p['fact'][1]} ms" if p else "-",
                      pair(r["unreduced_solve_harmonic_s"], r["unreduced_solve_biharmonic_s"]),
                      f"{p['solve'][0]} \\ {p['solve'][1]} ms" if p else "-"]
        else:
            cells += ["-", "-", "-", "-"]
        table.append(cells)
    return common.markdown_table(columns, table)


def live_summary(live: dict) -> str:
    f = common.fmt_ms
    lines = ["| mesh | faces | energy | factorization | re-aim, native (full field) | re-aim, session | new face, native "
             "| remove, native | region (2000 faces): begin + solve | region: re-aim |", "|" + "---|" * 10]
    for r in live["results"]:
        for label in ("biharmonic", "harmonic"):
            x = r[label]
            lines.append(f"| {r['mesh']} | {r['faces']} | {label} | " + " | ".join(
                f(x[key] / 1000) for key in ("factorization_ms", "native_reaim_ms", "session_reaim_ms",
                                             "native_new_face_ms", "native_remove_ms",
                                             "region_begin_first_solve_ms", "region_reaim_ms")) + " |")
    return "\n".join(lines)


def markdown(doc: dict) -> str:
    m = doc["meta"]
    md = ["# nfield benchmark: paper Table 1, live session, Fig. 8", "",
          f"{m['date']}; {m['cpus']} CPUs shared with other jobs; load average (1 min) {m['loadavg_start'][0]:.1f} at "
          f"the start, {m['loadavg_end'][0]:.1f} at the end; whole run {common.fmt_ms(m['duration_s'])}"
          f"{' (--quick: small meshes, small k, few repeats)' if m['quick'] else ''}. The paper's numbers are from "
          "the authors' machine. Setting of Table 1: 4-direction field, curvature-max alignment, strength 1, "
          "30 random hard direction constraints, harmonic \\ biharmonic energy.", ""]
    if doc.get("table1"):
        md += ["## Table 1", "", combined_table(doc["table1"]), "",
               "Basis set-up: one fresh computation, wall time and (in parentheses) CPU time of the process (two "
               "threads); on a loaded machine the wall time is mostly waiting for a core. Reduced set-up & solve: "
               "ReducedSolver construction + 30 constraints + reduced solve. Reduced update: re-aim one constraint "
               "+ reduced solve (the k coefficients; median). Factorization: ExactSolver construction. Unreduced "
               "solve: re-aim one constraint + exact solve with the factorization done (median). Details: "
               "exact_solver.md, spectral.md.", ""]
        extra = [r for r in doc["table1"] if "basis_wall_s" in r]
        if extra:
            md += ["| mesh | strength change harm. \\ biharm. | update + field (U x) harm. \\ biharm. "
                   "| reconstruction U x double \\ float32 |", "|---|---|---|---|"]
            md += [f"| {r['mesh']} | {pair(r['strength_change_harmonic_s'], r['strength_change_biharmonic_s'])} | "
                   f"{pair(r['update_and_field_harmonic_s'], r['update_and_field_biharmonic_s'])} | "
                   f"{pair(r['reconstruction_double_s'], r['reconstruction_single_s'])} |" for r in extra]
            md.append("")
    if doc.get("oneshot"):
        md += ["## One-shot rows", "", one_shot.table(doc["oneshot"]["results"]), "",
               "One-shot: `nfield.core.solve` end to end (mesh loaded; operators, constraints, solve, unit field, 3D "
               "directions, energy, singularities) with 30 random hard constraints and no alignment. Factorization: "
               "the bare `ExactSolver` construction of the same system. Ratio: one-shot / factorization per repeat, "
               "median. Live first solve: a DesignSession with its factorization done gets 30 new constraints and "
               "solves (details=False). Details: one_shot.md.", ""]
    if doc.get("spectral"):
        md += ["## float32 vs double basis", "", spectral.precision_table(doc["spectral"]["results"]), ""]
    if doc.get("targets"):
        md += ["## Targets", "", "| what | measured | target | met |", "|---|---|---|---|"]
        for c in doc["targets"]:
            if "ratio" in c:
                md.append(f"| {c['what']} | {c['ratio']:.2f} | <= {c['target_ratio']} | {'yes' if c['met'] else 'NO'} |")
                continue
            extra = f" ({common.fmt_ms(c['cpu_s'])} CPU)" if "cpu_s" in c else ""
            md.append(f"| {c['what']} | {common.fmt_ms(c['value_s'])}{extra} | < {common.fmt_ms(c['target_s'])} | "
                      f"{'yes' if c['met'] else 'NO'} |")
        md.append("")
    if doc.get("live"):
        md += ["## Exact live session", "", live_summary(doc["live"]), "", "Details: live_session.md.", ""]
    if doc.get("guides"):
        md += ["## Live guide edits (exact session)", "", guides.table(doc["guides"]["results"]), "",
               "total = guide computation + solve (medians); live edits are solved exactly in a region around the "
               "changed faces, the global refactorization follows when the interaction pauses (docs/guides.md). "
               "Details: guides.md.", ""]
    if doc.get("fig8"):
        r = doc["fig8"]["result"]
        md += ["## Accuracy of the reduction (Fig. 8)", "",
               f"{r['mesh']} ({r['faces']} faces), 4-direction, biharmonic, no alignment; {r['trials']} trials of "
               f"{r['constraints']} random constraints; relative L2 distance (area-weighted) to the exact spline of "
               "the unit field w/|w| (plotted) and of the raw solution w. The paper: >= 1000 eigenfields keep it "
               f"below {100 * FIG8_THRESHOLD:.0f} %.", "", fig8.table(r), "",
               f"![Fig. 8]({Path(r['png']).name})" if r.get("png") else f"(no plot: {r.get('png_note')})", "",
               "Details: fig8.md.", ""]
    if doc.get("remesh"):
        md += ["## Quad remeshing (ours vs QuadriFlow vs Instant Meshes)", "", doc["remesh"]["markdown"],
               "Details: remesh.md, docs/quad_remeshing.md.", ""]
    md += ["## The paper's Table 1 (their machine)", "",
           "| mesh | faces | bases setup | reduced setup & solve | factorization | unreduced solve |",
           "|---|---|---|---|---|---|"]
    md += [f"| {p['paper_mesh']} | {p['faces']} | {common.fmt_ms(p['basis_s'])} | {p['reduced'][0]} \\ {p['reduced'][1]} ms | "
           f"{p['fact'][0]} \\ {p['fact'][1]} ms | {p['solve'][0]} \\ {p['solve'][1]} ms |" for p in TABLE1]
    md.append("")
    return "\n".join(md)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="small meshes, small k, few repeats (a few minutes)")
    parser.add_argument("--parts", default=",".join(PARTS), help="comma-separated subset of " + ",".join(PARTS))
    parser.add_argument("--x4-basis", action="store_true",
                        help="also compute the k=500 basis of the 4x-subdivided armadillo (long, ~6 GB)")
    args = parser.parse_args()
    parts = [p for p in args.parts.split(",") if p]
    unknown = set(parts) - set(PARTS)
    if unknown:
        parser.error(f"unknown parts {sorted(unknown)} (choose from {', '.join(PARTS)})")
    t_start = time.perf_counter()
    load_start = common.loadavg()
    print(f"bench: {'quick' if args.quick else 'full'} run of {', '.join(parts)}; load {load_start}", file=sys.stderr,
          flush=True)
    doc: dict = {}
    if "exact" in parts:
        meshes = exact_solver.QUICK_MESHES if args.quick else exact_solver.MESHES
        doc["exact"] = exact_solver.run(meshes, 1 if args.quick else 3,
                                        "exact_solver_quick" if args.quick else "exact_solver")
    if "oneshot" in parts:
        doc["oneshot"] = one_shot.run(one_shot.QUICK_MESHES if args.quick else one_shot.MESHES, 1 if args.quick else 3,
                                      "one_shot_quick" if args.quick else "one_shot")
    if "spectral" in parts:
        meshes = list(spectral.QUICK_MESHES if args.quick else spectral.MESHES)
        if args.x4_basis:
            meshes.append("armadillo-x4")
        doc["spectral"] = spectral.run(meshes, 100 if args.quick else 500, 30 if args.quick else 200,
                                       5 if args.quick else 30, stem="spectral_quick" if args.quick else "spectral")
    if "live" in parts:
        doc["live"] = run_live(args.quick)
    if "guides" in parts:
        doc["guides"] = run_guides(args.quick)
    if "fig8" in parts:
        doc["fig8"] = (fig8.run(fig8.QUICK_KS, 4, 10, fig8.QUICK_MESH, stem="fig8_quick") if args.quick
                       else fig8.run(fig8.KS, 20, 10, fig8.MESH))
    if "remesh" in parts:
        meshes = remesh.QUICK_MESHES if args.quick else remesh.MESHES
        doc["remesh"] = remesh.run(meshes, 5000, False, "remesh_quick" if args.quick else "remesh")
    doc["table1"] = combined_rows(doc.get("exact"), doc.get("spectral"), doc.get("oneshot"))
    doc["targets"] = ((doc.get("spectral") or {}).get("targets", []) + (doc.get("oneshot") or {}).get("targets", [])
                      + (doc.get("live") or {}).get("targets", []) + (doc.get("guides") or {}).get("targets", []))
    for c in doc["targets"]:  # live_session reports ms; make every target seconds
        if "median_ms" in c:
            c["value_s"], c["target_s"] = c.pop("median_ms") / 1000, c.pop("target_ms") / 1000
    doc["meta"] = common.meta(quick=args.quick, parts=parts, x4_basis=args.x4_basis, loadavg_start=load_start,
                              loadavg_end=common.loadavg(), duration_s=time.perf_counter() - t_start)
    stem = "table1_quick" if args.quick else "table1"
    md = markdown(doc)
    summary = {k: doc[k] for k in ("meta", "table1", "targets")}
    if doc.get("fig8"):
        summary["fig8"] = [{k: v for k, v in r.items() if not k.endswith("_all")} for r in doc["fig8"]["result"]["rows"]]
    parts_doc = {k: doc[k] for k in PARTS if k in doc}
    if "remesh" in parts_doc:
        parts_doc["remesh"] = parts_doc["remesh"]["doc"]
    common.write_results(stem, {**summary, "parts": parts_doc}, md)
    print(json.dumps(summary, indent=2))
    print(md)
    print(f"written: {common.RESULTS / (stem + '.md')} and .json", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
