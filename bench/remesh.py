"""Quad remeshing side by side with the peers, in one run: ours (quad-dominant and pure quads), Blender's
QuadriFlow (`bpy.ops.object.quadriflow_remesh`, headless PyPI bpy) and Instant Meshes (`pyinstantmeshes`
from PyPI, BSD; benchmark-only, see docs/benchmarks.md), at the same target (about 5,000 quads).

Ours runs in three modes: quad-dominant, pure quads (the odd faces paired by half rows, at the target edge
length) and pure quads by subdividing a lattice twice as coarse. Every method gets the same mesh; ours also gets the designed field (curvature-aligned biharmonic cross field
with three hard direction constraints along the principal direction at seeded random faces). All outputs
are measured by the same functions (nfield.core.quad_mesh_stats) against the same field and input: time,
quad fraction, irregular vertices (against the field's singularity count), edge alignment to the designed
field, Hausdorff distance, min scaled Jacobian, manifold / oriented, failures.

Usage: python bench/remesh.py [--quick] [--meshes a,b] [--faces 5000] [--render]
Writes bench/results/remesh{_quick}.{json,md}; --render also writes docs/images/remesh_{rocker_arm,bunny}.png
(our result | QuadriFlow | Instant Meshes, wireframe over shaded). Each mesh runs in its own subprocess.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import common  # noqa: E402

MESHES = ("fertility.off", "fandisk.obj", "rocker-arm.obj", "stanford-bunny.obj", "armadillo.obj")
QUICK_MESHES = ("fandisk.obj", "rocker-arm.obj")
METHODS = ("ours", "ours_pure", "ours_pure_subdivided", "quadriflow", "instant_meshes")
RENDERS = {"rocker-arm.obj": ("remesh_rocker_arm.png", (1.0, 0.35, 0.25), False),
           "stanford-bunny.obj": ("remesh_bunny.png", (0.25, -1.0, 0.3), True)}

# The quality and speed targets (docs/quad_remeshing.md).
TARGETS = {"quad_fraction_dominant": 0.97, "alignment_mean_deg": 4.0, "alignment_p95_deg": 12.0,
           "irregular_per_singularity": 1.5, "hausdorff_relative": 0.0075, "bunny_seconds": 10.0}


def read_obj_polygons(path: str):
    import numpy as np

    V, F = [], []
    with open(path) as fh:
        for line in fh:
            if line.startswith("v "):
                V.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("f "):
                F.append([int(tok.split("/")[0]) - 1 for tok in line.split()[1:]])
    return np.asarray(V, dtype=np.float64), F


def designed_field(mesh, seed: int = 0):
    """Curvature-aligned biharmonic cross field with three direction constraints (principal directions at
    seeded random faces)."""
    import numpy as np
    from nfield.core import DirectionConstraint, native, solve

    pc = native().principal_curvature(mesh.native)
    rng = np.random.default_rng(seed)
    active = np.flatnonzero(np.asarray(mesh.native.face_active))
    faces = rng.choice(active, size=3, replace=False)
    cons = [DirectionConstraint(int(mesh.triangle_face[f]), tuple(np.asarray(pc["dir_max"])[f].tolist())) for f in faces]
    return solve(mesh, n=4, order=2, align="curvature-max", constraints=cons)


def run_ours(mesh, field, faces: int, pure: bool, method: str = "pair"):
    from nfield.core import quad_remesh

    t0 = time.perf_counter()
    V, F, stats = quad_remesh(mesh, field, target_faces=faces, pure_quads=pure, pure_quad_method=method, stats=False)
    return V, F, time.perf_counter() - t0, stats


def run_quadriflow(mesh, faces: int):
    import bpy
    import numpy as np

    bpy.ops.wm.read_factory_settings(use_empty=True)
    me = bpy.data.meshes.new("input")
    me.from_pydata(mesh.vertices.tolist(), [], mesh.faces.tolist())
    me.update()
    ob = bpy.data.objects.new("input", me)
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.view_layer.objects.active = ob
    ob.select_set(True)
    t0 = time.perf_counter()
    with bpy.context.temp_override(active_object=ob, object=ob, selected_objects=[ob], selected_editable_objects=[ob]):
        res = bpy.ops.object.quadriflow_remesh(target_faces=faces, mode="FACES", use_mesh_symmetry=False,
                                               use_preserve_sharp=True, use_preserve_boundary=True, seed=0)
    dt = time.perf_counter() - t0
    if "FINISHED" not in res:
        raise RuntimeError(f"quadriflow_remesh returned {res}")
    out = ob.data
    V = np.array([v.co[:] for v in out.vertices], dtype=np.float64)
    F = [list(p.vertices) for p in out.polygons]
    if len(F) == 0 or out is me and len(F) == len(mesh.faces):
        raise RuntimeError("QuadriFlow left the mesh unchanged (it refuses non-manifold input)")
    return V, F, dt, {}


# Instant Meshes is a benchmark-only peer: `python3 build_addon.py bench` installs it into bench/.peers.
PEERS_DIR = HERE / ".peers"


def run_instant_meshes(mesh, faces: int, pure: bool = False):
    if PEERS_DIR.is_dir() and str(PEERS_DIR) not in sys.path:
        sys.path.append(str(PEERS_DIR))
    try:
        import pyinstantmeshes
    except ImportError:
        raise RuntimeError("pyinstantmeshes is not installed: `python3 build_addon.py bench` installs it into "
                           "bench/.peers") from None

    tmp = tempfile.mkdtemp(prefix="nfield_im_")
    src, dst = os.path.join(tmp, "in.obj"), os.path.join(tmp, "out.obj")
    with open(src, "w") as fh:
        fh.writelines(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in mesh.vertices)
        fh.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in mesh.faces)
    t0 = time.perf_counter()
    pyinstantmeshes.remesh_file(src, dst, target_face_count=faces, pure_quad=pure, deterministic=True,
                                crease_angle=40.0, align_to_boundaries=True)
    dt = time.perf_counter() - t0
    V, F = read_obj_polygons(dst)
    return V, F, dt, {}


def measure_mesh(name: str, faces: int, render: bool) -> dict:
    """All methods on one mesh (run in a child process)."""
    import numpy as np
    from nfield.core import Mesh, field_directions, quad_mesh_stats

    mesh = Mesh.from_file(common.DATA / name)
    t0 = time.perf_counter()
    field = designed_field(mesh)
    field_seconds = time.perf_counter() - t0
    directions, _ = field_directions(mesh, field)
    sings = field.singularities
    closed = mesh.report["num_boundary_edges"] == 0
    row = {"mesh": name, "faces_in": int(mesh.num_triangles), "closed": bool(closed), "field_seconds": field_seconds,
           "field_singularities": len(sings), "methods": {}}
    outputs = {}
    runners = {
        "ours": lambda: run_ours(mesh, field, faces, False),
        "ours_pure": lambda: run_ours(mesh, field, faces, True),
        "ours_pure_subdivided": lambda: run_ours(mesh, field, faces, True, "subdivide"),
        "quadriflow": lambda: run_quadriflow(mesh, faces),
        "instant_meshes": lambda: run_instant_meshes(mesh, faces),
    }
    for method in METHODS:
        entry: dict = {}
        try:
            V, F, seconds, own = runners[method]()
            stats = quad_mesh_stats(V, F, mesh, directions, sings)
            entry = {k: v for k, v in stats.items() if k not in ("irregular_vertex_list",)}
            entry["seconds"] = seconds
            if own.get("messages"):
                entry["messages"] = own["messages"]
            outputs[method] = (V, F)
        except Exception as exc:  # noqa: BLE001 - a peer's failure is a result
            entry = {"failed": f"{type(exc).__name__}: {' '.join(str(exc).split())}"}
            traceback.print_exc(file=sys.stderr)
        row["methods"][method] = entry
        print(f"  {name} {method}: {entry.get('seconds', float('nan')):.2f} s {entry.get('failed', '')}",
              file=sys.stderr, flush=True)
    if render and name in RENDERS and all(m in outputs for m in ("ours", "quadriflow", "instant_meshes")):
        from remesh_render import render_panels

        file, view, y_up = RENDERS[name]
        out = common.ROOT / "docs" / "images" / file
        render_panels([outputs[m] for m in ("ours", "quadriflow", "instant_meshes")], out, view=view, size=(1000, 1000),
                      y_up=y_up)
        row["render"] = str(out.relative_to(common.ROOT))
    return row


def fmt(x, spec=".2f", scale=1.0):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return format(x * scale, spec)


def markdown(rows: list[dict], faces: int) -> str:
    names = {"ours": "ours (quad-dominant)", "ours_pure": "ours (pure quads)",
             "ours_pure_subdivided": "ours (pure, subdivided)", "quadriflow": "QuadriFlow",
             "instant_meshes": "Instant Meshes"}
    lines = [f"Target: about {faces} faces. Irregular: interior valence != 4 plus boundary vertices off their "
             "expected valence; alignment: angle of each edge to the nearest direction of the designed field "
             "at its midpoint; Hausdorff: symmetric, % of the bounding-box diagonal; Jmin: min scaled Jacobian "
             "(<= 0: folded or flipped faces); M/O: manifold / consistently oriented.", "",
             "| mesh (faces, singularities) | method | time s | faces | quads % | irregular | align mean / p95 deg "
             "| Hausdorff % | Jmin (folded) | M/O |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        label = f"{r['mesh']} ({r['faces_in']}, {r['field_singularities']})"
        for m in METHODS:
            e = r["methods"].get(m, {})
            if "failed" in e:
                lines.append(f"| {label} | {names[m]} | failed: {e['failed'][:80]} |||||||")
                continue
            lines.append(
                f"| {label} | {names[m]} | {fmt(e['seconds'])} | {e['num_faces']} | {fmt(e['quad_fraction'], '.1f', 100)} "
                f"| {e['irregular_vertices']} | {fmt(e.get('alignment_mean_deg'))} / {fmt(e.get('alignment_p95_deg'))} "
                f"| {fmt(e['hausdorff_relative'], '.3f', 100)} | {fmt(e['min_scaled_jacobian'])} ({e['inverted_faces']}) "
                f"| {'y' if e['manifold'] else 'n'}/{'y' if e['oriented'] else 'n'} |")
            label = ""
    return "\n".join(lines) + "\n"


def run(meshes, faces: int, render: bool, stem: str) -> dict:
    rows = []
    for name in meshes:
        args = ["--child", name, "--faces", str(faces)] + (["--render"] if render else [])
        try:
            rows.append(common.run_child(Path(__file__), args, f"remesh {name}", timeout=1800))
        except Exception as exc:  # noqa: BLE001
            rows.append({"mesh": name, "faces_in": 0, "field_singularities": 0,
                         "methods": {m: {"failed": str(exc)} for m in METHODS}})
    doc = {"meta": common.meta(faces=faces, meshes=list(meshes)), "targets": TARGETS, "rows": rows}
    md = markdown(rows, faces)
    common.write_results(stem, doc, md)
    return {"doc": doc, "markdown": md}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help=f"only {', '.join(QUICK_MESHES)}")
    p.add_argument("--meshes", help="comma-separated mesh files of tests/data")
    p.add_argument("--faces", type=int, default=5000)
    p.add_argument("--render", action="store_true", help="write the comparison renders into docs/images/")
    p.add_argument("--child", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        print(json.dumps(measure_mesh(args.child, args.faces, args.render)))
        return 0
    meshes = args.meshes.split(",") if args.meshes else (QUICK_MESHES if args.quick else MESHES)
    out = run(meshes, args.faces, args.render, "remesh_quick" if args.quick else "remesh")
    print(json.dumps(out["doc"]["rows"], indent=1))
    print(out["markdown"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
