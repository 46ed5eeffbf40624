"""Runs inside GUI Blender (3.4+) for tests/test_blender_window.py::test_comb_brush_in_real_window.

    blender --factory-startup -noaudio --python window_comb.py -- WORKDIR ADDON_ZIP MESH_OBJ

1. installs the packaged add-on from ADDON_ZIP and enables it;
2. builds the scene: the mesh of MESH_OBJ (the Stanford bunny) standing up, a 4-direction biharmonic field
   aligned to the curvature, solved once; a marker undo step (a custom property set, then pushed);
3. maximizes a 3D view, frames the object, activates the comb tool (toolbar tool ``nfield.tool_comb``) with
   a brush radius of BRUSH_PIXELS, and picks a straight drag path across the front of the body at 45
   degrees to the field there, in integer pixel steps (every pixel of it on the mesh);
4. writes WORKDIR/ready.json (window-relative X11 pixels of the path); the test presses, drags, releases;
5. when WORKDIR/dragged exists: waits for the background global solve the stroke hands over, then writes
   WORKDIR/result.json (the stroke, the comb attribute, the field and the reference directions at the
   faces under the stroke, measured with Blender's own projection) and a screenshot WORKDIR/comb.png
   with the mouse resting on the body (the brush circle around it);
6. one undo (ed.undo), then WORKDIR/undo.json: the comb attribute, the marker and the field after the
   undo;
7. Quad Remesh from Field invoked as the panel button does, on a design changed since its last solve (Solve
   First solves it in the worker), then WORKDIR/remesh.json: what invoke returned, whether the worker owned
   the object right after, the field state before and after, the operator's status and messages, how often
   a UI timer ticked meanwhile, the new object's faces; then Blender quits. Any exception is written to the
   JSON file of its phase as {"error": ...}.
"""
import json
import math
import os
import sys
import time
import traceback
from pathlib import Path

import faulthandler

faulthandler.enable()

import bpy
import numpy as np
from bpy_extras import view3d_utils
from mathutils import Euler, Vector

argv = sys.argv[sys.argv.index("--") + 1:]
WORKDIR, ADDON_ZIP, MESH = argv[0], argv[1], argv[2]
BRUSH_PIXELS = 40
PATH_PIXELS = 240  # length of the drag on screen
STATE = {"t0": time.time()}


def write_json(name, data):
    """WORKDIR/name, written whole at once (the test polls for it)."""
    tmp = Path(WORKDIR, name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    tmp.replace(Path(WORKDIR, name))


def give_up(name, text):
    write_json(name, {"error": text})
    bpy.ops.wm.quit_blender()


def the_view():
    """(window, 3D view area, its WINDOW region)."""
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    return win, area, next(r for r in area.regions if r.type == "WINDOW")


def looking():
    """(window, 3D view region, its view matrices, the bunny object): what the picking code needs."""
    win, area, region = the_view()
    return win, region, area.spaces.active.region_3d, bpy.data.objects[STATE["obj"]]


def in_view(fn, *args, **kw):
    win, area, region = the_view()
    with bpy.context.temp_override(window=win, area=area, region=region, screen=win.screen):
        return fn(*args, **kw)


def build_scene():
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    from nfield.core import native  # the add-on's own OBJ reader

    verts, faces, _polygon, _count = native().read_mesh(MESH)
    me = bpy.data.meshes.new("bunny")
    me.from_pydata(np.asarray(verts).tolist(), [], np.asarray(faces).tolist())
    me.polygons.foreach_set("use_smooth", [True] * len(me.polygons))  # smooth shading: the glyphs read better
    me.update()
    obj = bpy.data.objects.new("Bunny", me)
    bpy.context.collection.objects.link(obj)
    obj.rotation_euler = Euler((math.radians(90), 0.0, 0.0))  # the scan is y-up
    obj.scale = (10.0, 10.0, 10.0)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    bpy.context.view_layer.update()
    import nfield.blender as nb

    obj.nfield.glyph_density, obj.nfield.glyph_scale = 0.15, 1.5  # fewer, larger crosses: a readable screenshot
    nb.solve(obj, n=4, order=2, align="curvature-max", write=True)
    return obj


def setup():
    try:
        bpy.ops.preferences.addon_install(filepath=ADDON_ZIP, overwrite=True)
        bpy.ops.preferences.addon_enable(module="nfield")
        obj = build_scene()
        print("nfield-comb: scene built", flush=True)
        win, area, region = the_view()
        space = area.spaces.active
        space.overlay.show_floor = False
        space.overlay.show_axis_x = space.overlay.show_axis_y = False
        space.shading.type = "SOLID"
        in_view(bpy.ops.view3d.view_axis, type="FRONT")
        in_view(bpy.ops.view3d.view_selected)
        space.region_3d.view_distance *= 0.6  # the body fills the view: larger glyphs in the screenshot
        in_view(bpy.ops.wm.tool_set_by_id, name="nfield.tool_comb")
        tool = bpy.context.workspace.tools.from_space_view3d_mode("OBJECT", create=False)
        tool.operator_properties("nfield.comb_tool").radius = BRUSH_PIXELS
        obj["comb_marker"] = 1
        in_view(bpy.ops.ed.undo_push, message="before the comb stroke")
        import nfield.blender as nb

        before = nb.field(obj)
        STATE.update(obj=obj.name, tool=tool.idname, field_before=np.array(before.directions), result_before=before,
                     rep_before=np.array(before.representation), source_faces=len(obj.data.polygons))
        bpy.app.timers.register(pick_path, first_interval=1.0)
    except Exception:  # noqa: BLE001
        give_up("ready.json", traceback.format_exc())
    return None


def cast(obj, region, rv3d, px):
    """(object-space point, polygon) under region pixel `px` (Blender's own ray cast), or None."""
    inv = obj.matrix_world.inverted()
    origin = view3d_utils.region_2d_to_origin_3d(region, rv3d, Vector(px))
    ray = view3d_utils.region_2d_to_vector_3d(region, rv3d, Vector(px))
    hit, loc, _nrm, index = obj.ray_cast(inv @ origin, (inv.to_3x3() @ ray).normalized())
    return (loc, index) if hit else None


def hit_face(obj, region, rv3d, px):
    got = cast(obj, region, rv3d, px)
    return None if got is None else got[1]


#: integer screen steps (pixels, y up) the drag may take: mouse events land exactly on the path
STEPS = [(10, 0), (10, 3), (10, 5), (10, 7), (10, 10), (7, 10), (5, 10), (3, 10), (0, 10),
         (-3, 10), (-5, 10), (-7, 10), (-10, 10), (-10, 7), (-10, 5), (-10, 3)]


def screen_angle(region, rv3d, obj, face, direction):
    """Angle (degrees) on screen of `direction` (object space) at the centroid of `face`."""
    mw = obj.matrix_world
    c = obj.data.polygons[face].center
    a = view3d_utils.location_3d_to_region_2d(region, rv3d, mw @ c)
    b = view3d_utils.location_3d_to_region_2d(region, rv3d, mw @ (c + 0.01 * Vector(direction)))
    return math.degrees(math.atan2(b.y - a.y, b.x - a.x))


def pick_path():
    """A straight drag of about PATH_PIXELS across the body, at 45 degrees on screen to the field there (the
    most a cross field can differ from a direction), in integer pixel steps, every pixel of it and a brush
    radius to either side on the mesh."""
    try:
        win, region, rv3d, obj = looking()
        mw = obj.matrix_world
        pts = [view3d_utils.location_3d_to_region_2d(region, rv3d, mw @ Vector(c)) for c in obj.bound_box]
        xs, ys = [p.x for p in pts if p], [p.y for p in pts if p]
        centre = Vector((0.5 * (min(xs) + max(xs)), 0.5 * (min(ys) + max(ys))))
        # the field's mean direction on screen near the centre (circular mean of 4 x angle: a cross field)
        z = 0j
        for face in range(0, len(obj.data.polygons), 7):
            q = view3d_utils.location_3d_to_region_2d(region, rv3d, mw @ obj.data.polygons[face].center)
            if q is not None and (q - centre).length < 150 and hit_face(obj, region, rv3d, q) == face:
                z += np.exp(4j * math.radians(screen_angle(region, rv3d, obj, face, STATE["field_before"][face])))
        want = math.degrees(np.angle(z)) / 4.0 + 45.0

        def off(step):
            d = (math.degrees(math.atan2(step[1], step[0])) - want) % 90.0
            return min(d, 90.0 - d)

        step = min(STEPS, key=off)
        u = Vector(step).normalized()
        v = Vector((-u.y, u.x))
        count = round(PATH_PIXELS / Vector(step).length)
        best = None
        for dy in range(-120, 121, 8):
            for dx in range(-80, 81, 8):
                a = Vector((round(centre.x + dx - u.x * PATH_PIXELS / 2), round(centre.y + dy - u.y * PATH_PIXELS / 2)))
                path = [a + Vector(step) * i for i in range(count + 1)]
                probes = [p + u * t + v * o for p in path[:-1] for t in (0.0, 0.5 * Vector(step).length)
                          for o in (-BRUSH_PIXELS, 0, BRUSH_PIXELS)]
                if all(hit_face(obj, region, rv3d, p) is not None for p in probes):
                    score = abs(dy) + abs(dx)
                    if best is None or score < best[0]:
                        best = (score, path)
        if best is None:
            raise RuntimeError("no straight path across the body that stays on the mesh")
        path = [(int(p.x), int(p.y)) for p in best[1]]
        STATE.update(path=path, step=step)

        def window_px(p):  # X11 coordinates relative to the Blender window (y down)
            return [region.x + p[0], win.height - 1 - (region.y + p[1])]

        write_json("ready.json", {"path_region": path, "path_window": [window_px(p) for p in path],
                                  "active_tool": STATE["tool"], "brush_px": BRUSH_PIXELS, "step": step,
                                  "field_angle": want - 45.0, "faces": len(obj.data.polygons)})
        bpy.app.timers.register(wait_for_drag, first_interval=0.2)
    except Exception:  # noqa: BLE001
        give_up("ready.json", traceback.format_exc())
    return None


def wait_for_drag():
    from nfield.blender import tool_common

    if tool_common.last_press.get("tool") == "comb" and not STATE.get("press_seen"):
        STATE["press_seen"] = True
        write_json("pressed.json", dict(tool_common.last_press))
    if not os.path.exists(os.path.join(WORKDIR, "dragged")):
        if time.time() - STATE["t0"] > 300:
            give_up("result.json", "timed out waiting for the test's drag")
            return None
        return 0.2
    STATE["t_release"] = time.time()
    bpy.app.timers.register(wait_for_global, first_interval=0.5)
    return None


def wait_for_global():
    """The stroke handed the global solve to the background once the brush rested: wait for it."""
    from nfield.blender import background, jobs

    obj = bpy.data.objects[STATE["obj"]]
    if jobs.busy(obj) or background.status["state"] == "running" or not STATE.get("seen_start"):
        STATE["seen_start"] = STATE.get("seen_start") or background.status["state"] in ("running", "finished")
        if time.time() - STATE["t_release"] > 240:
            give_up("result.json", f"the background solve did not finish: {background.status}")
            return None
        return 0.3
    bpy.app.timers.register(report, first_interval=1.0)  # let the last redraw happen
    return None


def comb_attribute(obj):
    from nfield.blender import guides

    got = guides.comb_field(obj)
    return (None, None) if got is None else got


def field_directions(obj):
    a = obj.data.attributes[obj.nfield.direction_attribute]
    buf = np.empty(len(obj.data.polygons) * 3, dtype=np.float32)
    a.data.foreach_get("vector", buf)
    return buf.reshape(-1, 3).astype(np.float64)


def stroke_faces(obj, region, rv3d, a, b, within):
    """Faces whose centroid is seen within `within` pixels of the screen segment a-b and faces the view."""
    mw = obj.matrix_world
    nmat = mw.inverted_safe().transposed().to_3x3()
    view_dir = rv3d.view_rotation @ Vector((0.0, 0.0, -1.0))
    a, b = Vector(a), Vector(b)
    out = []
    for p in obj.data.polygons:
        n = (nmat @ p.normal).normalized()
        if n.dot(view_dir) > -0.5:
            continue
        q = view3d_utils.location_3d_to_region_2d(region, rv3d, mw @ p.center)
        if q is None:
            continue
        t = max(0.0, min(1.0, (q - a).dot(b - a) / (b - a).length_squared))
        if (q - (a + (b - a) * t)).length <= within and hit_face(obj, region, rv3d, q) == p.index:
            out.append((p.index, t))
    return out


def chord_cone(obj, region, rv3d, face, comb, a, b, t, n):
    """The drag's own directions at `face`, independently of the tool: chords between surface points 1/5 of
    a mouse step apart along the path, within 1.5 brush radii plus a step of the face on screen, projected
    into the face's plane; their signed angles (degrees, within one 360/n period) to the combed direction
    `comb`. Every chord between two mouse positions is a sum of such chords, so the directions the tool
    combed with lie in their cone."""
    a, b = Vector(a), Vector(b)
    length = (b - a).length
    step = Vector(STATE["step"]).length
    nrm = Vector(obj.data.polygons[face].normal)
    c = Vector(comb)
    c2 = nrm.cross(c)
    span = 1.5 * BRUSH_PIXELS + step
    lo, hi = max(0.0, t * length - span), min(length, t * length + span)
    h = step / 5.0
    prev, angles = None, []
    s = lo
    while s <= hi + 1e-9:
        got = cast(obj, region, rv3d, a + (b - a) * (s / length))
        p = None if got is None else got[0]
        if p is not None and prev is not None:
            d = p - prev
            d -= nrm * d.dot(nrm)
            if d.length > 0:
                ang = math.degrees(math.atan2(d.dot(c2), d.dot(c)))
                period = 360.0 / n
                angles.append((ang + period / 2) % period - period / 2)
        prev = p
        s += h
    return angles


def report():
    from nfield.blender import background, tool_comb

    try:
        win, region, rv3d, obj = looking()
        a, b = STATE["path"][0], STATE["path"][-1]
        core = stroke_faces(obj, region, rv3d, a, b, 0.3 * BRUSH_PIXELS)
        v = Vector((-(b[1] - a[1]), b[0] - a[0])).normalized() * 4 * BRUSH_PIXELS  # four radii to the side
        far = stroke_faces(obj, region, rv3d, Vector(a) + v, Vector(b) + v, 1.0)
        dirs, weights = comb_attribute(obj)
        import nfield.blender as nb

        n = obj.nfield.n
        after = nb.field(obj)
        STATE["field_after"] = np.array(after.directions)
        STATE["rep_after"] = np.array(after.representation)
        view = -(obj.matrix_world.inverted_safe().to_3x3() @ (rv3d.view_rotation @ Vector((0.0, 0.0, -1.0))))
        faces = []
        for f, t in core:
            nrm = Vector(obj.data.polygons[f].normal)
            comb = None if dirs is None else Vector(dirs[f])
            cone = chord_cone(obj, region, rv3d, f, comb, a, b, t, n) if comb is not None else []
            faces.append({"face": f, "t": t, "facing": nrm.dot(view.normalized()),
                          "comb": None if comb is None else list(comb),
                          "weight": None if weights is None else float(weights[f]),
                          "cone": [min(cone), max(cone)] if cone else None,
                          "field": list(STATE["field_after"][f]), "field_before": list(STATE["field_before"][f])})
        res = {"faces": faces, "far_weights": [] if weights is None else [float(weights[f]) for f, _ in far],
               "stroke": dict(tool_comb.last_stroke), "background": dict(background.status),
               "marker": obj.get("comb_marker"), "n": n, "step": STATE["step"]}
        # the screenshot: the mouse rests on the body (the test moved it there), the brush circle around it
        shot = os.path.join(WORKDIR, "comb.png")
        in_view(bpy.ops.wm.redraw_timer, type="DRAW_WIN_SWAP", iterations=1)  # a whole, fresh frame
        in_view(bpy.ops.screen.screenshot, filepath=shot)
        res["screenshot"] = shot
        write_json("result.json", res)
    except Exception:  # noqa: BLE001
        give_up("result.json", traceback.format_exc())
        return None
    bpy.app.timers.register(undo_stroke, first_interval=0.5)
    return None


def undo_stroke():
    try:
        obj = bpy.data.objects[STATE["obj"]]
        STATE["undo"] = in_view(bpy.ops.ed.undo)
        STATE["t_undo"] = time.time()
        obj = bpy.data.objects[STATE["obj"]]  # undo replaces the data blocks
        dirs, weights = comb_attribute(obj)
        STATE["after_undo"] = {"comb_weight_max": None if weights is None else float(np.max(weights)),
                               "has_comb": weights is not None, "marker": obj.get("comb_marker")}
        bpy.app.timers.register(undo_settled, first_interval=0.5)
    except Exception:  # noqa: BLE001
        give_up("undo.json", traceback.format_exc())
    return None


def undo_settled():
    """After the undo the field of the restored state comes back (solved in the background)."""
    from nfield.blender import background, jobs

    obj = bpy.data.objects[STATE["obj"]]
    if jobs.busy(obj) or background.status["state"] == "running":
        if time.time() - STATE["t_undo"] < 240:
            return 0.3
    try:
        import nfield.blender as nb

        res = dict(STATE["after_undo"], undo=list(STATE["undo"]), background=dict(background.status))
        result = nb.field(obj)
        now = np.array(result.representation)  # representation vectors: one per cross, not per arm
        res["same_result_object"] = result is STATE["result_before"]
        res["faces_changed"] = int(np.count_nonzero(np.abs(now - STATE["rep_before"]) > 1e-6))
        res["before_changed"] = int(np.count_nonzero(np.abs(STATE["result_before"].representation - STATE["rep_before"]) > 1e-6))
        # the field of the restored state against the field before the stroke and the one after it
        res["from_before"] = float(np.max(np.abs(now - STATE["rep_before"])))
        res["from_stroke"] = float(np.max(np.abs(now - STATE["rep_after"])))
        write_json("undo.json", res)
    except Exception:  # noqa: BLE001
        write_json("undo.json", {"error": traceback.format_exc()})
        bpy.ops.wm.quit_blender()
        return None
    bpy.app.timers.register(start_remesh, first_interval=0.5)
    return None


def start_remesh():
    """Quad Remesh from Field as the panel button runs it (INVOKE_DEFAULT), on a design changed since its
    last solve (a constraint added with Live Update off), so Solve First has to solve before remeshing."""
    from nfield.blender import jobs

    try:
        import nfield.blender as nb

        obj = bpy.data.objects[STATE["obj"]]
        nb.configure(obj, live_update=False)
        face = int(np.argmax(np.asarray([p.area for p in obj.data.polygons])))
        normal = Vector(obj.data.polygons[face].normal)
        d = Vector(nb.field(obj).directions[face])
        nb.add_constraint(obj, face, tuple((d * math.cos(0.7) + normal.cross(d) * math.sin(0.7))))
        res = {"state_before": nb.field_state(obj)}
        STATE["ticks"] = []
        bpy.app.timers.register(ui_tick, first_interval=0.0)
        with bpy.context.temp_override(active_object=obj, object=obj):
            res["invoke"] = sorted(in_view(bpy.ops.nfield.quad_remesh, "INVOKE_DEFAULT", target_faces=1500))
        # the worker owns the session and has not solved yet when invoke returns (the UI thread did not solve)
        res["busy_after_invoke"] = jobs.busy(obj)
        STATE["remesh"], STATE["t_remesh"] = res, time.time()
        bpy.app.timers.register(remesh_done, first_interval=0.2)
    except Exception:  # noqa: BLE001
        give_up("remesh.json", traceback.format_exc())
    return None


def ui_tick():
    """A UI-thread timer: its ticks while the worker runs show that the UI stayed responsive."""
    STATE["ticks"].append(time.time())
    return None if "remesh_finished" in STATE else 0.05


def remesh_done():
    from nfield.blender import remesh_operator

    status = remesh_operator.remesh_status
    if status["state"] == "running" and time.time() - STATE["t_remesh"] < 240:
        return 0.2
    try:
        import nfield.blender as nb

        STATE["remesh_finished"] = time.time()
        obj = bpy.data.objects[STATE["obj"]]
        res = dict(STATE["remesh"], status={k: v for k, v in status.items() if k != "stats"},
                   messages=list(status["stats"].get("messages", [])), state_after=nb.field_state(obj),
                   ticks_while_running=sum(1 for t in STATE["ticks"] if t < STATE["remesh_finished"]))
        new = bpy.data.objects.get(status["result"])
        if new is not None:
            sizes = [len(p.vertices) for p in new.data.polygons]
            res["new_object"] = {"name": new.name, "faces": len(sizes), "quads": sizes.count(4),
                                 "source_faces_unchanged": len(obj.data.polygons) == STATE["source_faces"]}
        write_json("remesh.json", res)
    except Exception:  # noqa: BLE001
        write_json("remesh.json", {"error": traceback.format_exc()})
    bpy.ops.wm.quit_blender()
    return None


def maximize():
    """Maximize the 3D view (from the script body: screen operators are not safe from timers)."""
    in_view(bpy.ops.screen.screen_full_area)


bpy.context.preferences.view.show_splash = False
bpy.context.preferences.view.smooth_view = 0
maximize()
bpy.app.timers.register(setup, first_interval=0.5)
