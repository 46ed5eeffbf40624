"""Hatching strokes as Blender curves (nfield.blender.hatching), headless PyPI bpy.

* conversion (synthetic strokes, no tracer needed): a Curves object parented to the mesh, one curve per
  stroke, points = the stroke points lifted by lift x radius along the polygon normals (object space, so
  the world positions follow the mesh's transform), the radius attribute, the per-curve family attribute;
  degenerate strokes dropped; rebuilding re-uses the object (no orphan data, the stroke material kept);
  the legacy Curve fallback holds the same points;
* the operator / api with the tracer (nfield.core.trace_streamlines): strokes on the surface, the same seed
  gives the same strokes, a density vertex group thins strokes where it is low, unknown density names
  fail with a clear message, cross-hatching adds family 1;
* both operators (nfield.hatching, nfield.material_anisotropic) run from a script;
* a tiny Cycles render shows the strokes (they darken a self-lit white sheet).

Everything runs in a subprocess (this file as a script) with the nfield that Blender installed from the
extension zip (the ``nf`` fixture of tests/blender_support.py) first on PYTHONPATH; the test process itself
never imports bpy's scene state from it.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from blender_support import nf, run_script  # noqa: F401  (fixture)

pytestmark = pytest.mark.blender


def _run_checks(out_dir: Path) -> dict:
    import bpy
    import numpy as np
    from mathutils import Matrix

    import nfield.blender as nb
    from nfield.blender import hatching, material

    res: dict = {}
    bpy.ops.wm.read_factory_settings(use_empty=True)
    nb.register()
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=24, y_subdivisions=24, size=2.0)
    obj = bpy.context.active_object
    obj.name = "Sheet"
    # bend the sheet a little (a curved surface) and give it a non-trivial transform
    me = obj.data
    co = np.empty(len(me.vertices) * 3, dtype=np.float32)
    me.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    co[:, 2] = 0.15 * np.sin(1.5 * co[:, 0])
    me.vertices.foreach_set("co", co.ravel())
    me.update()
    obj.matrix_world = (Matrix.Translation((0.3, -0.2, 0.5)) @ Matrix.Rotation(0.7, 4, "Z")
                        @ Matrix.Rotation(0.4, 4, "X"))
    bpy.context.view_layer.update()
    normals = np.empty(len(me.polygons) * 3, dtype=np.float32)
    me.polygons.foreach_get("normal", normals)
    normals = normals.reshape(-1, 3).astype(np.float64)
    centers = np.empty(len(me.polygons) * 3, dtype=np.float32)
    me.polygons.foreach_get("center", centers)
    centers = centers.reshape(-1, 3).astype(np.float64)

    # --- synthetic strokes: polylines through polygon centres (rows of the grid)
    faces = [np.arange(r * 24, r * 24 + 24) for r in range(0, 24, 4)]
    pts = [centers[f] for f in faces]
    strokes = pts + [np.zeros((1, 3)), np.array([[0, 0, 0], [np.nan, 0, 0]])]  # two degenerate ones
    face_lists = faces + [np.zeros(1, int), np.zeros(2, int)]
    fam = [0, 1, 0, 1, 0, 1, 0, 0]
    radius = 0.004
    cobj = hatching.strokes_to_object(obj, strokes, faces=face_lists, family=fam, radius=radius, lift=1.0)
    cd = cobj.data
    expected = np.concatenate([p + normals[f] * radius for p, f in zip(pts, faces)])
    got = np.empty(len(cd.points) * 3, dtype=np.float32)
    cd.position_data.foreach_get("vector", got)
    got = got.reshape(-1, 3)
    rad = np.empty(len(cd.points), dtype=np.float32)
    cd.attributes["radius"].data.foreach_get("value", rad)
    famattr = np.empty(len(cd.curves), dtype=np.int32)
    cd.attributes["nfield_family"].data.foreach_get("value", famattr)
    mw = np.array(cobj.matrix_world)
    world = got @ mw[:3, :3].T + mw[:3, 3]
    mesh_mw = np.array(obj.matrix_world)
    world_expected = expected @ mesh_mw[:3, :3].T + mesh_mw[:3, 3]
    res["convert"] = {
        "type": cobj.type, "parent": cobj.parent.name if cobj.parent else None,
        "curves": len(cd.curves), "points": len(cd.points),
        "max_pos_err": float(np.abs(got - expected).max()),
        "max_world_err": float(np.abs(world - world_expected).max()),
        "radius": [float(rad.min()), float(rad.max())], "family": famattr.tolist(),
        "strokes_prop": int(cobj["nfield_strokes"]),
        "materials": [m.name for m in cd.materials if m is not None],
    }
    # moving the mesh moves the strokes
    obj.location.x += 1.0
    bpy.context.view_layer.update()
    res["convert"]["follows_x"] = float(np.array(cobj.matrix_world)[0, 3] - mw[0, 3])
    obj.location.x -= 1.0
    bpy.context.view_layer.update()

    # --- rebuilding re-uses the object; a user material is kept
    user_mat = bpy.data.materials.new("UserInk")
    cd.materials.clear()
    cd.materials.append(user_mat)
    n_curves_data = len(bpy.data.hair_curves) if hasattr(bpy.data, "hair_curves") else 0
    cobj2 = hatching.strokes_to_object(obj, pts[:2], radius=radius)
    res["rebuild"] = {
        "same_object": cobj2 == cobj, "curves": len(cobj2.data.curves),
        "materials": [m.name for m in cobj2.data.materials if m is not None],
        "hair_curves_datablocks": [n_curves_data, len(bpy.data.hair_curves) if hasattr(bpy.data, "hair_curves") else 0],
        "objects": sorted(o.name for o in bpy.data.objects),
    }

    # --- legacy curve fallback
    lobj = hatching.strokes_to_object(obj, pts, radius=radius, lift=0.0, legacy=True, name="Legacy")
    lpts = np.concatenate([np.array([p.co[:3] for p in sp.points]) for sp in lobj.data.splines])
    res["legacy"] = {"type": lobj.type, "splines": len(lobj.data.splines),
                     "max_pos_err": float(np.abs(lpts - np.concatenate(pts)).max()),
                     "bevel": float(lobj.data.bevel_depth), "parent": lobj.parent.name}
    bpy.data.objects.remove(lobj)

    # --- with the tracer (nfield.core.trace_streamlines)
    nb.configure(obj, n=2, order=2, align="none", live_update=False)
    nb.add_constraint(obj, 300, (1.0, 0.2, 0.0))
    nb.solve(obj, write=True)
    t = time.perf_counter()
    h1 = nb.build_hatching(obj, spacing=0.03, seed=3, name="H1")
    res["trace_seconds"] = time.perf_counter() - t
    h2 = nb.build_hatching(obj, spacing=0.03, seed=3, name="H2")

    def positions(o):
        a = np.empty(len(o.data.points) * 3, dtype=np.float32)
        o.data.position_data.foreach_get("vector", a)
        return a.reshape(-1, 3)

    p1, p2 = positions(h1), positions(h2)
    # distance to the surface (object space): BVH of the sheet
    from mathutils.bvhtree import BVHTree

    tree = BVHTree.FromPolygons([v.co[:] for v in me.vertices], [tuple(p.vertices) for p in me.polygons])
    r1 = float(h1["nfield_radius"])
    dist = np.array([tree.find_nearest(tuple(x))[3] for x in p1[:: max(1, len(p1) // 2000)]])
    res["trace"] = {"curves": len(h1.data.curves), "points": len(p1), "same_seed_equal":
                    bool(p1.shape == p2.shape and np.array_equal(p1, p2)), "radius": r1,
                    "max_dist_to_surface": float(dist.max()), "parent": h1.parent.name}
    # density: a vertex group with weight 1 on x < 0 and 0.1 on x >= 0 (object space)
    vg = obj.vertex_groups.new(name="tone")
    left = [v.index for v in me.vertices if v.co.x < 0]
    right = [v.index for v in me.vertices if v.co.x >= 0]
    vg.add(left, 1.0, "REPLACE")
    vg.add(right, 0.1, "REPLACE")
    hd = nb.build_hatching(obj, spacing=0.03, seed=3, density="tone", name="HD")
    pd = positions(hd)
    res["density"] = {"left_points": int((pd[:, 0] < 0).sum()), "right_points": int((pd[:, 0] >= 0).sum()),
                      "uniform_left": int((p1[:, 0] < 0).sum()), "uniform_right": int((p1[:, 0] >= 0).sum())}
    try:
        nb.build_hatching(obj, density="no_such_group")
        res["density_error"] = ""
    except ValueError as exc:
        res["density_error"] = str(exc)
    hx = nb.build_hatching(obj, spacing=0.05, seed=1, cross_hatch=True, name="HX")
    fx = np.empty(len(hx.data.curves), dtype=np.int32)
    hx.data.attributes["nfield_family"].data.foreach_get("value", fx)
    res["cross_families"] = sorted(set(fx.tolist()))
    # operators
    for o in list(bpy.context.selected_objects):
        o.select_set(False)
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    res["op_hatching"] = list(bpy.ops.nfield.hatching(spacing=0.04, seed=2))
    res["op_material"] = list(bpy.ops.nfield.material_anisotropic(anisotropy=0.5, direction="PERPENDICULAR"))
    res["op_hatching_object"] = f"{obj.name} Hatching" in bpy.data.objects
    for name in ("H1", "H2", "HD", "HX"):
        bpy.data.objects.remove(bpy.data.objects[name])

    # --- a tiny render: dark strokes on a white sheet
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 8
    scene.cycles.use_denoising = False
    scene.cycles.seed = 0
    scene.render.resolution_x = scene.render.resolution_y = 64
    scene.render.image_settings.file_format = "PNG"
    scene.view_settings.view_transform = "Standard"
    white = bpy.data.materials.new("White")  # a self-lit white sheet: every pixel is white without strokes
    material.ensure_nodes(white)  # Blender < 5.0 creates the node tree only with use_nodes
    nt = white.node_tree
    for node in list(nt.nodes):
        if node.bl_idname != "ShaderNodeOutputMaterial":
            nt.nodes.remove(node)
    emit = nt.nodes.new("ShaderNodeEmission")
    nt.links.new(emit.outputs[0], next(n for n in nt.nodes if n.bl_idname == "ShaderNodeOutputMaterial").inputs[0])
    obj.active_material = white
    world = bpy.data.worlds.new("W")
    world.color = (1.0, 1.0, 1.0)
    scene.world = world
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 2.0
    scene.collection.objects.link(cam)
    cam.matrix_world = obj.matrix_world @ Matrix.Translation((0, 0, 3))
    scene.camera = cam
    hatch = bpy.data.objects[f"{obj.name} Hatching"]
    # dark ink: the strokes still carry the grey user material of the rebuild check, which renders as a
    # default surface in Blender < 5.0 (no node tree) and as a Principled BSDF in 5.0
    hatch.data.materials.clear()
    hatch.data.materials.append(hatching.ink_material())
    means = []
    for visible in (False, True):
        hatch.hide_render = not visible
        path = out_dir / f"hatch_{int(visible)}.png"
        scene.render.filepath = str(path)
        bpy.ops.render.render(write_still=True)
        img = bpy.data.images.load(str(path))
        px = np.empty(64 * 64 * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
        means.append(float(px.reshape(-1, 4)[:, :3].mean()))
        dark = float((px.reshape(-1, 4)[:, :3].mean(axis=1) < 0.5).mean())
        res[f"dark_fraction_{int(visible)}"] = dark
    res["render_means"] = means
    return res


def test_hatching_curves(tmp_path, nf):
    r, seconds = run_script(nf, Path(__file__).resolve(), tmp_path)
    print(json.dumps(r, indent=1), f"{seconds:.1f} s")

    c = r["convert"]
    assert c["type"] == "CURVES" and c["parent"] == "Sheet"
    assert c["curves"] == 6 and c["points"] == 6 * 24 and c["strokes_prop"] == 6  # degenerate ones dropped
    assert c["max_pos_err"] < 1e-6, c          # object space, lifted by radius along the polygon normal
    assert c["max_world_err"] < 1e-5, c        # world = the mesh's transform
    assert abs(c["follows_x"] - 1.0) < 1e-6    # parented: moving the mesh moves the strokes
    assert abs(c["radius"][0] - 0.004) < 1e-8 and abs(c["radius"][1] - 0.004) < 1e-8, c["radius"]
    assert c["family"] == [0, 1, 0, 1, 0, 1]
    rb = r["rebuild"]
    assert rb["same_object"] and rb["curves"] == 2 and rb["materials"] == ["UserInk"]
    assert rb["hair_curves_datablocks"][1] == rb["hair_curves_datablocks"][0], "old curves data not freed"
    assert rb["objects"] == ["Sheet", "Sheet Hatching"]
    lg = r["legacy"]
    assert lg["type"] == "CURVE" and lg["splines"] == 6 and lg["max_pos_err"] < 1e-6 and lg["parent"] == "Sheet"
    assert abs(lg["bevel"] - 0.004) < 1e-9

    t = r["trace"]
    assert t["curves"] > 5 and t["same_seed_equal"] and t["parent"] == "Sheet"
    # on the surface: lifted by one radius (plus the chord error of the bent sheet, tiny here)
    assert t["max_dist_to_surface"] < t["radius"] * 1.05 + 1e-4, t
    d = r["density"]
    # weight 0.1 on the right half: separation x10 there (the tracer's d_sep / max(density, 0.1))
    assert d["right_points"] < 0.4 * d["uniform_right"], d
    assert d["left_points"] > 0.7 * d["uniform_left"], d
    assert "no_such_group" in r["density_error"] and "vertex group" in r["density_error"]
    assert r["cross_families"] == [0, 1]
    assert r["op_hatching"] == ["FINISHED"] and r["op_material"] == ["FINISHED"] and r["op_hatching_object"]
    # the strokes render: the self-lit white sheet alone is white (mean ~1); the strokes (about 0.7 px wide at
    # 64 x 64, every ~4 px) darken it by several percent (measured ~9 %; sampling noise at 8 spp is << 1 %)
    assert r["dark_fraction_0"] == 0.0 and r["render_means"][0] > 0.98, r
    assert r["render_means"][1] < r["render_means"][0] - 0.03, r


if __name__ == "__main__":
    from conftest import bpy_script_main

    bpy_script_main(_run_checks)
