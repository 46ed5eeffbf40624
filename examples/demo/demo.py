"""nfield demo (the README's main job): design a field on the rocker arm in headless PyPI bpy, shade it
anisotropically, hatch it, render with Cycles on the CPU and save an editable .blend.

    PYTHONPATH=addon .venv/bin/python examples/demo/demo.py [--out out] [--size 640x360] [--samples 16]
        [--threads N] [--no-features] [--no-denoise] [--gallery]

(``python3 build_addon.py demo`` runs it with ``--out out``.) Steps, all through the scripting API
``nfield.blender``:

1. load tests/data/rocker-arm.obj (10k vertices, 20k faces), smooth shading;
2. design a line field (n = 2, biharmonic, aligned with the direction of least curvature) with the hard
   direction constraints of examples/rocker_constraints.json, the pinned singularity of index +1/2 of
   examples/rocker_singularities.json (the files the command line examples use) and feature alignment on the
   rims (see FEATURES), solve, write the attributes;
3. build the anisotropic material (Principled BSDF, tangent = the field; then its perpendicular; then
   isotropic for reference) and hatching strokes as a Curves object parented to the mesh;
4. render PNGs with Cycles (CPU, fixed seed, OpenImageDenoise) into --out, in the looks of studio.py, and
   save out/demo.blend: open it in Blender with the nfield add-on enabled and the design (constraints,
   singularity, settings, feature alignment) is there to edit; the material and strokes are ordinary data.

``--gallery`` renders the README's gallery instead: the same images at 1280 x 720 with more samples, plus
the double torus (tests/data/eight.off) in brushed steel with its field, its perpendicular and without
anisotropy, and stores the PNGs with a 256-colour palette (32 greys for the hatching) so that they stay a
few hundred KB (``--out docs/images`` replaces the committed pictures).

Prints a JSON summary (timings, counts, files) at the end.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(HERE))  # studio.py

MESH = ROOT / "tests" / "data" / "rocker-arm.obj"
SECOND_MESH = ROOT / "tests" / "data" / "eight.off"

# The design: face/vertex indices of rocker-arm.obj, which Blender's OBJ importer keeps in the file's order
# (object space). The singularity's index 1/2 is a multiple of 1/n for this n = 2 (and for n = 4).
CONSTRAINTS_FILE = ROOT / "examples" / "rocker_constraints.json"
SINGULARITIES_FILE = ROOT / "examples" / "rocker_singularities.json"
N = 2
#: the base guide: the direction of least curvature. On a machined part it runs along the rims and the
#: fillets (the direction of most curvature crosses them, against the feature guide) and around the bore
ALIGN = "curvature-min"
#: Feature alignment of the demo. The rocker arm's rims are fillets a few triangles wide, not sharp edges:
#: their bend is spread over several edges of 20-45 degrees each (10% of all edges bend by more than 22
#: degrees, 1% by more than 43). A 20-degree threshold finds every rim, as many short, parallel pieces
#: (3,700 edges in 2,300 chains) whose directions scatter by tens of degrees from edge to edge. Soft mode
#: over 12 edge rings averages them into one smooth band along each rim: 42 singularities in the field,
#: against 178 with 4 rings and 72 with 8, and long strokes that follow the rims. The hard mode cannot
#: average (one constraint per piece, ~2,000 of them: a two-minute solve here). Weight 3: the rims win over
#: the curvature guide near them.
FEATURES = {"angle": 20.0, "mode": "soft", "weight": 3.0, "width": 12}
#: camera directions (world, towards the camera): the bore's end face and its inside, the pin at the right
ROCKER_VIEW = (0.8, -0.35, 0.45)
SECOND_VIEW = (0.2, -0.6, 0.75)
#: hatching: stroke separation and shortest stroke (fractions of the bounding-box diagonal); strokes drawn
#: thinner than the default (0.06 instead of 0.1 of the separation) read as pen lines at 1280 x 720
HATCH_SPACING = 0.013
HATCH_MIN_LENGTH = 0.03
HATCH_WIDTH = 0.06
#: the rocker arm's field turns quickly on its small fillets: a milder anisotropy and the smoothed point
#: attribute keep the reflections there from breaking up into facets (the double torus takes the full 1.0)
ROCKER_ANISOTROPY = 0.7
BRASS = (0.85, 0.62, 0.38, 1.0)
STEEL = (0.8, 0.8, 0.82, 1.0)
PAPER = (0.95, 0.95, 0.93, 1.0)


def _args(argv):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=str(ROOT / "out"))
    p.add_argument("--size", default=None, help="WIDTHxHEIGHT (default 640x360; 1280x720 with --gallery)")
    p.add_argument("--samples", type=int, default=None, help="Cycles samples (default 16; 32 with --gallery)")
    p.add_argument("--threads", type=int, default=0, help="Cycles CPU threads (0: all)")
    p.add_argument("--no-features", action="store_true", help="leave feature alignment off (for comparison)")
    p.add_argument("--no-denoise", action="store_true", help="render without OpenImageDenoise")
    p.add_argument("--gallery", action="store_true", help="the README gallery (see the module docstring)")
    args = p.parse_args(argv)
    args.size = args.size or ("1280x720" if args.gallery else "640x360")
    args.samples = args.samples or (32 if args.gallery else 16)
    return args


def main(argv=None) -> int:
    args = _args(sys.argv[1:] if argv is None else argv)
    t_start = time.perf_counter()
    import bpy

    import nfield.blender as nb
    import studio

    timings: dict[str, float] = {}
    files: dict[str, str] = {}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    width, height = (int(x) for x in args.size.lower().split("x"))

    def lap(key, t0):
        timings[key] = round(time.perf_counter() - t0, 3)

    def render(scene, name, colors=256):
        t = time.perf_counter()
        path = out / f"{name}.png"
        studio.render(scene, path)
        if args.gallery:
            palette_png(path, colors, dither=colors > 32)
        timings[f"render_{name}"] = round(time.perf_counter() - t, 3)
        files[name] = str(path)

    t0 = time.perf_counter()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    nb.register()
    obj = import_obj(bpy, MESH, "RockerArm")
    lap("load", t0)

    # --- the design, through the scripting API
    t0 = time.perf_counter()
    design_rocker_arm(nb, obj, features=not args.no_features)
    result = nb.solve(obj, write=True)
    guide_report = nb.guide_report(obj)
    lap("solve_and_write", t0)

    scene = bpy.context.scene
    studio.cycles(scene, width, height, args.samples, denoise=not args.no_denoise, threads=args.threads)
    studio.frame(scene, obj, ROCKER_VIEW)

    # --- brushed brass: the field, its perpendicular, no anisotropy
    studio.metal_studio(scene, obj)
    t0 = time.perf_counter()
    mat = nb.build_anisotropic_material(obj, anisotropy=ROCKER_ANISOTROPY, direction="field", source="point",
                                        roughness=0.35, base_color=BRASS)
    lap("material", t0)
    render(scene, "demo_anisotropic")
    nb.build_anisotropic_material(obj, direction="perpendicular")
    render(scene, "demo_anisotropic_perpendicular")
    nb.build_anisotropic_material(obj, anisotropy=0.0)  # the same material, isotropic: the reference
    render(scene, "demo_isotropic")
    nb.build_anisotropic_material(obj, anisotropy=ROCKER_ANISOTROPY, direction="field")

    # --- hatching: the strokes over the metal, then pen on paper
    t0 = time.perf_counter()
    diagonal = 2 * studio.bounds(obj)[1]
    curves_obj = nb.build_hatching(obj, spacing=HATCH_SPACING, cross_hatch=False, seed=1,
                                   min_length=HATCH_MIN_LENGTH, radius=HATCH_WIDTH * HATCH_SPACING * diagonal)
    lap("hatching", t0)
    strokes_info = {"object": curves_obj.name, "strokes": curves_obj.get("nfield_strokes"),
                    "points": curves_obj.get("nfield_points"), "radius": curves_obj.get("nfield_radius")}
    render(scene, "demo_anisotropic_strokes")
    obj.active_material = nb.hatching.ink_material("Paper", PAPER)
    studio.clear_lights(scene)
    studio.paper_studio(scene, obj)
    render(scene, "demo_hatching", colors=32)
    obj.active_material = mat

    # --- save the editable design
    t0 = time.perf_counter()
    blend = out / "demo.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), compress=True)
    lap("save", t0)
    files["blend"] = str(blend)

    st = obj.nfield
    me = obj.data
    summary = {
        "mesh": MESH.name, "vertices": len(me.vertices), "faces": len(me.polygons),
        "n": st.n, "order": st.order, "align": st.align,
        "constraints": [c.face for c in st.constraints],
        "singularities_pinned": [(s.vertex, s.numerator / st.n) for s in st.singularities],
        "singularities": len(result.singularities), "energy": float(result.energy),
        "features": None if args.no_features else dict(FEATURES, edges=guide_report["feature_edges"],
                                                       chains=guide_report["feature_chains"]),
        "attributes": [st.direction_attribute, st.smooth_attribute, st.singularity_attribute],
        "material": mat.name, "hatching": strokes_info,
        "render": {"engine": scene.render.engine, "size": [width, height], "samples": scene.cycles.samples,
                   "denoised": scene.cycles.use_denoising, "device": scene.cycles.device},
    }
    if args.gallery:
        summary["second_mesh"] = _second_mesh(bpy, nb, studio, args, render, timings)
    summary.update(files=files, seconds=timings, total_seconds=round(time.perf_counter() - t_start, 2),
                   blender=bpy.app.version_string)
    print(json.dumps(summary, indent=2))
    _end_bpy(bpy, nb)
    return 0


def _end_bpy(bpy, nb) -> None:
    """Leave PyPI bpy cleanly: unregister the add-on (bpy 4.5 hangs at exit while an add-on property with an
    update callback is registered) and, in bpy older than 4.3 (whose exit crashes once any add-on registered
    one, a Blender bug), end the process here, after flushing the output."""
    nb.unregister()
    if bpy.app.version < (4, 3):
        import os

        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)


def design_rocker_arm(nb, obj, features: bool = True) -> None:
    """The demo's design on the rocker arm `obj`, through the scripting API (nothing solved yet)."""
    nb.configure(obj, n=N, order=2, align=ALIGN, strength=1.0, live_update=False)
    for c in json.loads(CONSTRAINTS_FILE.read_text()):
        nb.add_constraint(obj, c["face"], c["direction"])
    for s in json.loads(SINGULARITIES_FILE.read_text()):
        nb.add_singularity(obj, s["vertex"], s["index"])
    nb.set_feature_alignment(obj, features, boundary=True, dihedral=True, angle=FEATURES["angle"],
                             mode=FEATURES["mode"], weight=FEATURES["weight"], width=FEATURES["width"])


def import_obj(bpy, path: Path, name: str):
    """Blender's OBJ importer (Y up -> Z up), smooth shading, the object active."""
    import numpy as np

    bpy.ops.wm.obj_import(filepath=str(path))
    obj = bpy.context.selected_objects[0]
    bpy.context.view_layer.objects.active = obj
    obj.name = name
    me = obj.data
    me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), dtype=bool))
    me.update()
    return obj


def _second_mesh(bpy, nb, studio, args, render, timings) -> dict:
    """The double torus in brushed steel (gallery only): its smoothest line field along the direction of
    least curvature runs around the two holes and along the waist, and the highlights follow it."""
    import numpy as np

    from nfield.core import Mesh

    t0 = time.perf_counter()
    scene = bpy.context.scene
    for old in list(scene.objects):  # a fresh stage in the same scene (the rocker arm is saved already)
        bpy.data.objects.remove(old)
    mesh = Mesh.from_file(str(SECOND_MESH))  # OFF: Blender has no importer for it
    me = bpy.data.meshes.new("Eight")
    me.from_pydata(np.asarray(mesh.vertices, float).tolist(), [], np.asarray(mesh.faces, int).tolist())
    me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), dtype=bool))
    me.update()
    obj = bpy.data.objects.new("Eight", me)
    scene.collection.objects.link(obj)
    obj.rotation_euler = (math.pi / 2, 0.0, math.pi / 2)  # lying on its side, the long axis along x
    bpy.context.view_layer.objects.active = obj
    bpy.context.view_layer.update()
    nb.configure(obj, n=N, order=2, align=ALIGN, strength=1.0, live_update=False)
    result = nb.solve(obj, write=True)
    timings["second_mesh_solve"] = round(time.perf_counter() - t0, 3)
    width, height = (int(x) for x in args.size.lower().split("x"))
    studio.cycles(scene, width, height, args.samples, denoise=not args.no_denoise, threads=args.threads)
    studio.frame(scene, obj, SECOND_VIEW)
    studio.metal_studio(scene, obj)
    nb.build_anisotropic_material(obj, anisotropy=1.0, direction="field", roughness=0.3, base_color=STEEL)
    render(scene, "eight_anisotropic")
    nb.build_anisotropic_material(obj, direction="perpendicular")
    render(scene, "eight_anisotropic_perpendicular")
    nb.build_anisotropic_material(obj, anisotropy=0.0)
    render(scene, "eight_isotropic")
    return {"mesh": SECOND_MESH.name, "faces": len(me.polygons), "singularities": len(result.singularities)}


def palette_png(path: Path, colors: int = 256, dither: bool = True) -> None:
    """Store a render with an adaptive palette of `colors` (256 with dithering: a third of the size of the RGB
    PNG and no visible banding on these smooth renders; the hatching needs only a few greys, 32 without
    dithering); left as it is where Pillow is missing."""
    try:
        from PIL import Image
    except ImportError:
        return
    with Image.open(path) as im:
        small = im.convert("RGB").quantize(colors=colors, method=Image.Quantize.MEDIANCUT,
                                           dither=Image.Dither.FLOYDSTEINBERG if dither else Image.Dither.NONE)
    small.save(path, optimize=True)


if __name__ == "__main__":
    sys.exit(main())
