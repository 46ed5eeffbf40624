"""Benchmark of live guide edits in the exact session (docs/guides.md, section 7).

For each mesh: a 4-direction field, curvature-max alignment, strength 1, the biharmonic (order 2) and the
harmonic (order 1) energy, 30 random hard direction constraints, one soft curve guide (a closed loop through
the surface, width 2 % of the diagonal) and a comb stroke's worth of comb field, solved globally once. Then,
each repeated --repeats times (medians):

  curve move     translate the curve by 0.5 % of the diagonal (set_curve) + solve(live=True): the curve's band
                 moves, so the guide weights change; solved exactly in a region, the rest held fixed. The
                 moves follow each other like the steps of one drag going back and forth (each starts from the
                 last live solve; the loop stays on the surface)
  comb stroke    one brush stroke as the comb tool makes it: 24 samples along 5 % of the diagonal, radius 3 %,
                 fed 2 samples per viewport tick (begin / extend_comb_stroke) with a live solve per tick. The
                 edit timed is one tick (what the brush costs while it moves); the whole stroke is reported too
  weight change  set the alignment weight to 0 in a disk of radius 4 % of the diagonal (set_alignment_weight)
                 + solve(live=True)
  target change  turn the base guide by 30 degrees in the same disk (set_alignment_rotation) + solve(): only
                 the right-hand side changes, the global factorization is reused (one back-substitution)
  global re-solve after an edit: solve() with the new weights (a new factorization): what the background
                 solve of pending_work() does when the interaction pauses, and what every weight edit would
                 cost without the live region

Each edit is split into the guide computation (projection, layers, combination; Python + native) and the
solve; the CPU time of the whole edit (all threads) is given too: on the shared machine the wall time is that
times the wait for a core. Prints JSON and a Markdown table and writes bench/results/guides.{json,md} (--quick: the rocker arm,
guides_quick.*). Every mesh runs in its own subprocess.

Usage: python bench/guides.py [--quick] [--meshes a.obj,b.obj] [--repeats 7]
"""
from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import common  # noqa: E402

MESHES = ["stanford-bunny.obj", "armadillo.obj"]
QUICK_MESHES = ["rocker-arm.obj"]
NUM_CONSTRAINTS = 30
TARGET_MS = 100.0  # the goal for a live guide edit in the exact session: under 100 ms


def loop_through(mesh):
    """A closed polyline near the surface: the mesh's vertices nearest to a circle around its centre in the
    plane of its two largest extents, smoothed (a curve a user could have drawn on the model)."""
    import numpy as np

    V = mesh.vertices
    c = V.mean(axis=0)
    ext = V.max(axis=0) - V.min(axis=0)
    a, b = np.argsort(ext)[::-1][:2]
    t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    ring = np.tile(c, (len(t), 1))
    ring[:, a] += 0.3 * ext[a] * np.cos(t)
    ring[:, b] += 0.3 * ext[b] * np.sin(t)
    # pull each point to the nearest vertex, then smooth: the loop lies on (or very near) the surface
    near = np.array([V[np.argmin(((V - p) ** 2).sum(axis=1))] for p in ring])
    for _ in range(3):
        near = 0.5 * near + 0.25 * (np.roll(near, 1, axis=0) + np.roll(near, -1, axis=0))
    return np.vstack([near, near[:1]])


def measure_one(name: str, repeats: int, seed: int) -> dict:
    import numpy as np
    from nfield.core import DesignSession, Mesh

    rng = np.random.default_rng(seed)
    mesh = Mesh.from_file(common.DATA / name)
    diag = float(mesh.native.bounding_box_diagonal)
    F = mesh.num_faces
    cent = mesh.vertices[mesh.faces].mean(axis=1)
    normals = np.asarray(mesh.native.face_normals)
    active = np.flatnonzero(np.asarray(mesh.native.face_active))
    out = {"mesh": name, "faces": F, "loadavg_before": common.loadavg()}
    curve = loop_through(mesh)
    for order, label in ((2, "biharmonic"), (1, "harmonic")):
        s = DesignSession(mesh, n=4, order=order, align="curvature-max", strength=1.0)
        for f in rng.choice(active, NUM_CONSTRAINTS, replace=False):
            d = rng.normal(size=3)
            s.set_direction(int(f), d - normals[f] * (d @ normals[f]))
        s.set_curve("loop", curve, width=0.02, tolerance=0.02)
        start = int(rng.choice(active))
        path = cent[start] + np.outer(np.linspace(0, 0.06 * diag, 12), np.cross(normals[start], [0.3, 0.5, 0.8]))
        s.comb(path, np.gradient(path, axis=0), radius=0.03)
        with common.Clock() as c:
            s.solve(details=False)
        r = {"first_solve_s": c.wall}

        def timed(edit, live=True):
            with common.Clock() as g:
                edit()
                s._solve_inputs()  # the guide computation (cached afterwards)
            with common.Clock() as t:
                res = s.solve(details=False, live=live)
            return g.wall, t.wall, res.live_region, g.cpu + t.cpu

        def series(make_edit, live=True, settle=True):
            guide, solve, region, total, cpu = [], [], [], [], []
            for i in range(repeats):
                gw, sw, reg, c = timed(make_edit(i), live)
                guide.append(gw), solve.append(sw), total.append(gw + sw), cpu.append(c)
                region.append(reg or 0)
            res = {"guide_s": statistics.median(guide), "solve_s": statistics.median(solve),
                   "total_s": statistics.median(total), "total_cpu_s": statistics.median(cpu),
                   "region_faces": int(statistics.median(region))}
            if settle:
                with common.Clock() as gl:
                    s.solve(details=False)  # the global solve the background would run afterwards
                res["global_after_s"] = gl.wall
            return res

        step = 0.005 * diag * np.array([1.0, 0.7, 0.3]) / np.linalg.norm([1.0, 0.7, 0.3])
        # the steps of a drag that goes back and forth by one step (so the loop stays on the surface)
        r["curve_move"] = series(lambda i: (lambda: s.set_curve("loop", curve + (1 + i % 2) * step, width=0.02,
                                                                tolerance=0.02)))
        if order == 2:  # where the time of the biharmonic curve move goes
            r["curve_move"]["breakdown"] = breakdown(s, lambda i: s.set_curve(  # from where the series ended
                "loop", curve + (1 + (i + repeats) % 2) * step, width=0.02, tolerance=0.02), repeats)
            s.solve(details=False)

        r["comb_stroke"] = comb_brush(s, rng, active, cent, normals, diag, repeats, timed)
        with common.Clock() as gl:
            s.solve(details=False)
        r["comb_stroke"]["global_after_s"] = gl.wall

        def weight_edit(i):
            f0 = int(rng.choice(active))
            w = np.ones(F)
            w[np.linalg.norm(cent - cent[f0], axis=1) < 0.04 * diag] = 0.0
            return lambda: s.set_alignment_weight(w)
        r["weight_change"] = series(weight_edit)

        def rotation_edit(i):
            f0 = int(rng.choice(active))
            a = np.zeros(F)
            a[np.linalg.norm(cent - cent[f0], axis=1) < 0.04 * diag] = np.radians(30)
            return lambda: s.set_alignment_rotation(a)
        r["target_change"] = series(rotation_edit, live=False, settle=False)

        # Without the live region: every weight edit refactors the global system.
        r["weight_change_global"] = series(weight_edit, live=False, settle=False)
        out[label] = r
    out["loadavg_after"] = common.loadavg()
    return out


def breakdown(s, edit, repeats: int) -> dict:
    """Where the time of a live edit goes (medians, seconds): the guide computation, choosing the region, the
    rows of E_m for it (assembly), the region solver's construction (assembly + factorization + the set-up that
    does not grow with the region, measured alone with a one-face region), its solve, and the rest of
    DesignSession.solve (constraints, the live FieldResult). Reads the session's internals: a diagnostic of this
    benchmark, not an API."""
    from nfield.core import native

    parts: dict[str, list] = {k: [] for k in ("guide", "region", "rows", "solver", "solver_one_face", "solve",
                                               "total", "region_faces")}
    for i in range(repeats):
        edit(i)
        with common.Clock() as g:
            inputs = s._solve_inputs()
        with common.Clock() as rg:
            region = s._live_region(inputs)
        ops, order, rec = s._operators(), s._settings["order"], s._base_record

        def build(free_faces):  # as DesignSession builds a live region's solver (session_live.py)
            return native().ExactSolver(ops, order, s._settings["strength"], inputs.alignment, inputs.kind,
                                        free_faces=free_faces, held_field=rec.raw, **s._weight_arguments(inputs))

        with common.Clock() as rows:
            native().energy_rows(ops, order, region)
        with common.Clock() as ctor:
            solver = build(region)
        with common.Clock() as one:
            build(region[:1])
        with common.Clock() as sv:
            solver.solve()
        with common.Clock() as total:
            s.solve(details=False, live=True)
        for key, value in (("guide", g.wall), ("region", rg.wall), ("rows", rows.wall), ("solver", ctor.wall),
                           ("solver_one_face", one.wall), ("solve", sv.wall), ("total", total.wall),
                           ("region_faces", len(region))):
            parts[key].append(value)
    out = {k: statistics.median(v) for k, v in parts.items()}
    out["factorization_estimate"] = max(0.0, out["solver"] - out["rows"] - out["solver_one_face"])
    out["rest"] = max(0.0, out["total"] - out["region"] - out["solver"] - out["solve"])
    return out


def comb_brush(s, rng, active, cent, normals, diag, repeats: int, timed) -> dict:
    """`repeats` brush strokes of 24 samples, 2 per tick, each tick timed as one live edit (timed: see
    measure_one). Returns the medians over every tick and the median whole stroke."""
    import numpy as np

    guide, solve, total, cpu, region, strokes = [], [], [], [], [], []
    for _ in range(repeats):
        f0 = int(rng.choice(active))
        pts = cent[f0] + np.outer(np.linspace(0, 0.05 * diag, 24), np.cross(normals[f0], rng.normal(size=3)))
        dirs = np.gradient(pts, axis=0)
        s.begin_comb_stroke(0.03)
        whole = 0.0
        for k in range(0, len(pts), 2):
            gw, sw, reg, c = timed(lambda k=k: s.extend_comb_stroke(pts[k:k + 2], dirs[k:k + 2]))
            guide.append(gw), solve.append(sw), total.append(gw + sw), cpu.append(c), region.append(reg or 0)
            whole += gw + sw
        s.end_comb_stroke()
        strokes.append(whole)
    return {"guide_s": statistics.median(guide), "solve_s": statistics.median(solve),
            "total_s": statistics.median(total), "total_cpu_s": statistics.median(cpu),
            "region_faces": int(statistics.median(region)), "ticks_per_stroke": 12,
            "stroke_s": statistics.median(strokes)}


def table(results: list[dict]) -> str:
    f = common.fmt_ms
    def cell(x, key):
        e = x[key]
        reg = f", {e['region_faces']:,} faces" if e.get("region_faces") else ""
        return f"{f(e['total_s'])} ({f(e['guide_s'])} guide + {f(e['solve_s'])} solve{reg}; CPU {f(e['total_cpu_s'])})"
    columns = ["mesh", "faces", "energy", "curve move (live region)", "comb brush, one tick of 2 samples (live region)",
               "comb stroke of 24 samples", "weight change (live region)", "target change (global, no refactor)",
               "weight change, global refactor", "global solve after a live edit"]
    rows = [[r["mesh"], f"{r['faces']:,}", label, cell(r[label], "curve_move"), cell(r[label], "comb_stroke"),
             f(r[label]["comb_stroke"]["stroke_s"]), cell(r[label], "weight_change"), cell(r[label], "target_change"),
             f(r[label]["weight_change_global"]["total_s"]), f(r[label]["curve_move"]["global_after_s"])]
            for r in results for label in ("biharmonic", "harmonic")]
    return common.markdown_table(columns, rows)


#: the columns of the breakdown table: (header, key of breakdown())
BREAKDOWN_COLUMNS = (("guide", "guide"), ("region choice", "region"), ("rows of E_m", "rows"),
                     ("solver set-up (rows + factorization + the rest)", "solver"),
                     ("set-up of a one-face region", "solver_one_face"),
                     ("factorization (estimate)", "factorization_estimate"),
                     ("solve", "solve"), ("rest of solve()", "rest"))


def breakdown_table(results: list[dict]) -> str:
    columns = ["mesh", "live region"] + [h for h, _ in BREAKDOWN_COLUMNS] + ["total"]
    rows = []
    for r in results:
        b = r["biharmonic"]["curve_move"].get("breakdown")
        if b:
            rows.append([r["mesh"], f"{int(b['region_faces']):,}"] + [common.fmt_ms(b[k]) for _, k in BREAKDOWN_COLUMNS]
                        + [common.fmt_ms(b["guide"] + b["total"])])
    return common.markdown_table(columns, rows)


def targets(results: list[dict]) -> list[dict]:
    out = []
    for r in results:
        x = r["biharmonic"]
        for key, what in (("curve_move", "moving a curve"), ("comb_stroke", "the comb brush (one tick)"),
                          ("weight_change", "a weight change")):
            ms = 1000 * x[key]["total_s"]
            out.append({"what": f"{what}, {r['mesh']} ({r['faces']:,} faces), biharmonic, live", "median_ms": ms,
                        "median_cpu_ms": 1000 * x[key]["total_cpu_s"], "target_ms": TARGET_MS, "met": ms < TARGET_MS})
    return out


def main() -> int:
    parser = common.mesh_parser(__doc__, "rocker arm only, 3 repeats",
                                "comma-separated meshes of tests/data (default: bunny, armadillo)")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--seed", type=int, default=11)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure_one(args.one, args.repeats, args.seed)))
        return 0
    repeats = 3 if args.quick else args.repeats
    results = common.run_children(Path(__file__), common.chosen_meshes(args, MESHES, QUICK_MESHES),
                                  ["--repeats", str(repeats), "--seed", str(args.seed)], "guides")
    doc = {"meta": common.meta(quick=args.quick, repeats=repeats), "results": results, "targets": targets(results)}
    md = "\n".join(["# Live guide edits (exact session)", "", table(results), "",
                    "Medians of " + str(repeats) + " edits. total = guide computation + solve; live edits solve a "
                    "region around the changed faces exactly with the rest held fixed (docs/guides.md, section 7).",
                    "", "Where the time of a biharmonic curve move goes (medians):", "", breakdown_table(results), ""])
    common.write_results("guides_quick" if args.quick else "guides", doc, md)
    print(json.dumps(doc, indent=2))
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
