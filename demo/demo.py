"""nfield demo (the README's main job): design a field on the rocker arm in headless PyPI bpy, shade it
anisotropically, hatch it, render with Cycles on the CPU and save an editable .blend.

    PYTHONPATH=addon .venv/bin/python demo/demo.py [--out out] [--size 320x240] [--samples 32] [--threads N]

(``python3 build_addon.py demo`` runs exactly this.) Steps, all through the scripting API ``nfield.blender``:

1. load tests/data/rocker-arm.obj (10k vertices, 20k faces), smooth shading;
2. design a curvature-aligned line field (n = 2, biharmonic, align curvature-max) with the hard direction
   constraints of examples/rocker_constraints.json and the pinned singularity of index +1/2 of
   examples/rocker_singularities.json (the files the command line examples use) and feature alignment on the
   boundary and the sharp rims (bend > 30 degrees, soft, strong), solve, write the attributes;
3. build the anisotropic material (Principled BSDF, tangent = the field; then its perpendicular) and hatching
   strokes as a Curves object parented to the mesh;
4. render small PNGs with Cycles (CPU, fixed seed, no denoising) into out/ and save out/demo.blend: open it
   in Blender with the nfield add-on enabled and the design (constraints, singularity, settings) is there to
   edit; the material and strokes are ordinary Blender data.

Prints a JSON summary (timings, counts, files) at the end.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MESH = ROOT / "tests" / "data" / "rocker-arm.obj"

# The design: face/vertex indices of rocker-arm.obj, which Blender's OBJ importer keeps in the file's order
# (object space). The singularity's index 1/2 is a multiple of 1/n for this n = 2 (and for n = 4).
CONSTRAINTS_FILE = ROOT / "examples" / "rocker_constraints.json"
SINGULARITIES_FILE = ROOT / "examples" / "rocker_singularities.json"
N = 2
#: feature alignment of the demo: edges bending by more than this many degrees (and the boundary) are features
FEATURE_ANGLE = 45.0
#: pull of the features relative to the curvature guide (soft mode, 2 edge rings)
FEATURE_WEIGHT = 3.0


def _args(argv):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=str(ROOT / "out"))
    p.add_argument("--size", default="320x240")
    p.add_argument("--samples", type=int, default=32)
    p.add_argument("--threads", type=int, default=0, help="Cycles CPU threads (0: all)")
    p.add_argument("--no-features", action="store_true", help="leave feature alignment off (for comparison)")
    return p.parse_args(argv)


def main(argv=None) -> int:
    args = _args(sys.argv[1:] if argv is None else argv)
    t_start = time.perf_counter()
    import bpy
    import numpy as np

    import nfield.blender as nb
    from nfield.blender import hatching as nb_hatching

    timings: dict[str, float] = {}

    def lap(key, t0):
        timings[key] = round(time.perf_counter() - t0, 3)

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    width, height = (int(x) for x in args.size.lower().split("x"))

    t0 = time.perf_counter()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    nb.register()
    bpy.ops.wm.obj_import(filepath=str(MESH))
    obj = bpy.context.selected_objects[0]
    bpy.context.view_layer.objects.active = obj
    obj.name = "RockerArm"
    me = obj.data
    me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), dtype=bool))
    me.update()
    lap("load", t0)

    # --- the design, through the scripting API
    t0 = time.perf_counter()
    nb.configure(obj, n=N, order=2, align="curvature-max", strength=1.0, live_update=False)
    for c in json.loads(CONSTRAINTS_FILE.read_text()):
        nb.add_constraint(obj, c["face"], c["direction"])
    for s in json.loads(SINGULARITIES_FILE.read_text()):
        nb.add_singularity(obj, s["vertex"], s["index"])
    # feature alignment: the field follows the boundary and the sharp rims of the bore and the pin (edges
    # bending by more than 30 degrees). Soft mode with a strong pull: the hard mode holds the rims exactly but
    # puts ~1800 direction constraints on this mesh (a ~30 s solve here, against ~1 s)
    nb.set_feature_alignment(obj, not args.no_features, boundary=True, dihedral=True, angle=FEATURE_ANGLE,
                             mode="soft", weight=FEATURE_WEIGHT, width=2)
    result = nb.solve(obj, write=True)
    guide_report = nb.guide_report(obj)
    lap("solve_and_write", t0)

    # --- scene: camera, lights, world, Cycles
    scene = bpy.context.scene
    _setup_scene(scene, obj, width, height, args.samples, args.threads)

    files = {}
    t0 = time.perf_counter()
    mat = nb.build_anisotropic_material(obj, anisotropy=1.0, direction="field", roughness=0.45,
                                        base_color=(0.85, 0.62, 0.38, 1.0))
    lap("material", t0)

    def render(name):
        t = time.perf_counter()
        path = out / f"demo_{name}.png"
        scene.render.filepath = str(path)
        bpy.ops.render.render(write_still=True)
        timings[f"render_{name}"] = round(time.perf_counter() - t, 3)
        files[name] = str(path)

    render("anisotropic")
    nb.build_anisotropic_material(obj, direction="perpendicular")
    render("anisotropic_perpendicular")
    nb.build_anisotropic_material(obj, anisotropy=0.0)  # the same material, isotropic: the reference
    render("isotropic")
    nb.build_anisotropic_material(obj, anisotropy=1.0, direction="field")

    # --- hatching
    t0 = time.perf_counter()
    curves_obj = nb.build_hatching(obj, spacing=0.02, cross_hatch=False, seed=1)
    lap("hatching", t0)
    strokes_info = {"object": curves_obj.name, "strokes": curves_obj.get("nfield_strokes"),
                    "points": curves_obj.get("nfield_points"), "radius": curves_obj.get("nfield_radius")}
    render("anisotropic_strokes")  # the strokes over the anisotropic metal: the highlight follows them
    # pen on paper: matte surface, bright background
    obj.active_material = nb_hatching.ink_material("Paper", (0.92, 0.9, 0.86, 1.0))
    bg = next(n for n in scene.world.node_tree.nodes if n.bl_idname == "ShaderNodeBackground")
    strength = bg.inputs["Strength"].default_value
    bg.inputs["Strength"].default_value = 1.5
    render("hatching")
    bg.inputs["Strength"].default_value = strength
    obj.active_material = mat

    # --- save the editable design
    t0 = time.perf_counter()
    blend = out / "demo.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), compress=True)
    lap("save", t0)
    files["blend"] = str(blend)

    st = obj.nfield
    summary = {
        "mesh": MESH.name, "vertices": len(me.vertices), "faces": len(me.polygons),
        "n": st.n, "order": st.order, "align": st.align,
        "constraints": [c.face for c in st.constraints],
        "singularities_pinned": [(s.vertex, s.numerator / st.n) for s in st.singularities],
        "singularities": len(result.singularities), "energy": float(result.energy),
        "features": None if args.no_features else {"angle": FEATURE_ANGLE, "weight": FEATURE_WEIGHT, "mode": "soft",
                     "edges": guide_report["feature_edges"], "chains": guide_report["feature_chains"]},
        "attributes": [st.direction_attribute, st.smooth_attribute, st.singularity_attribute],
        "material": mat.name, "hatching": strokes_info,
        "render": {"engine": scene.render.engine, "size": [width, height], "samples": scene.cycles.samples,
                   "device": scene.cycles.device},
        "files": files, "seconds": timings, "total_seconds": round(time.perf_counter() - t_start, 2),
        "blender": bpy.app.version_string,
    }
    print(json.dumps(summary, indent=2))
    return 0


def _setup_scene(scene, obj, width, height, samples, threads) -> None:
    import bpy
    import numpy as np
    from mathutils import Vector

    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"
    cy.samples = samples
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.seed = 0
    cy.max_bounces = 4
    cy.diffuse_bounces = 2
    cy.glossy_bounces = 2
    cy.transmission_bounces = 0
    cy.volume_bounces = 0
    cy.transparent_max_bounces = 4
    if threads:
        scene.render.threads_mode = "FIXED"
        scene.render.threads = threads
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.compression = 90
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard" if "Standard" in [
        i.identifier for i in scene.view_settings.bl_rna.properties["view_transform"].enum_items] else \
        scene.view_settings.view_transform

    # world: a soft studio gradient (the anisotropic highlight streaks across its bright top)
    world = bpy.data.worlds.new("Studio")
    scene.world = world
    world.use_nodes = True
    nt = world.node_tree
    bg = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeBackground")
    coord = nt.nodes.new("ShaderNodeTexCoord")
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    nt.links.new(coord.outputs["Generated"], sep.inputs[0])
    nt.links.new(sep.outputs["Z"], ramp.inputs["Fac"])
    ramp.color_ramp.interpolation = "LINEAR"
    ramp.color_ramp.elements[0].position = 0.3
    ramp.color_ramp.elements[0].color = (0.02, 0.02, 0.025, 1.0)
    ramp.color_ramp.elements[1].position = 0.9
    ramp.color_ramp.elements[1].color = (0.25, 0.26, 0.3, 1.0)
    nt.links.new(ramp.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = 1.0

    # bounding box in world space
    me = obj.data
    v = np.empty(len(me.vertices) * 3, dtype=np.float32)
    me.vertices.foreach_get("co", v)
    v = v.reshape(-1, 3).astype(np.float64)
    mw = np.array(obj.matrix_world)
    vw = v @ mw[:3, :3].T + mw[:3, 3]
    lo, hi = vw.min(0), vw.max(0)
    center = Vector(((lo + hi) / 2).tolist())
    radius = float(np.linalg.norm(hi - lo)) / 2

    # camera
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.lens = 50
    cam = bpy.data.objects.new("Camera", cam_data)
    scene.collection.objects.link(cam)
    view_dir = Vector((0.55, -0.45, 0.70)).normalized()
    fov = 2 * math.atan(cam_data.sensor_width / 2 / cam_data.lens) * min(1.0, height / width)
    dist = radius / math.sin(fov / 2) * 0.92
    cam.location = center + view_dir * dist
    cam.rotation_euler = (-view_dir).to_track_quat("-Z", "Y").to_euler()
    cam_data.clip_start = dist / 100
    cam_data.clip_end = dist * 10
    scene.camera = cam

    # lights: three soft sun lights (directional: cheap, and their small angular size gives crisp streaks)
    def sun(name, direction, energy, angle_deg, color=(1, 1, 1)):
        ld = bpy.data.lights.new(name, "SUN")
        ld.energy = energy
        ld.angle = math.radians(angle_deg)
        ld.color = color
        lo_ = bpy.data.objects.new(name, ld)
        d = Vector(direction).normalized()
        lo_.location = center + d * radius * 4
        lo_.rotation_euler = (-d).to_track_quat("-Z", "Y").to_euler()
        scene.collection.objects.link(lo_)

    sun("Key", (0.8, -0.9, 1.2), 4.0, 6.0)
    sun("Key2", (-0.3, -0.6, 1.4), 2.5, 6.0, (0.9, 0.95, 1.0))
    sun("Rim", (-1.0, 0.6, 0.7), 3.0, 6.0, (0.85, 0.9, 1.0))


if __name__ == "__main__":
    sys.exit(main())
