"""Runs inside GUI Blender (3.4+) for tests/test_blender_window.py.

    blender --factory-startup -noaudio --python window_session.py -- WORKDIR ADDON_ZIP

1. installs the packaged add-on from ADDON_ZIP and enables it;
2. builds the scene: an icosphere with a rotation and a non-uniform scale, solved once (field + attributes);
3. maximizes a 3D view, frames the object, activates the constraint tool (toolbar tool
   ``nfield.tool_constraint``), and picks a front-facing face near the middle of the view;
4. writes WORKDIR/ready.json: the window-relative X11 pixel where the test must press (the face centroid),
   the pixel to drag to, and the face; the test drives xdotool;
5. when WORKDIR/dragged exists, writes WORKDIR/result.json (the stored constraint, the constraint direction
   projected back to the screen, the output attribute before/after) and a screenshot WORKDIR/window.png;
6. spectral Precompute in the background (the modal operator, as the panel button runs it): starts a large
   basis, writes WORKDIR/spectral_started.json, and the test presses Esc; then a small basis runs to the
   end. WORKDIR/spectral.json says what happened (states, settings, how often a UI timer ran meanwhile),
   then Blender quits. Any exception is written to the JSON file of its phase as {"error": ...}.
"""
import json
import math
import os
import sys
import time
import traceback

import faulthandler
faulthandler.enable()

import bpy
import numpy as np
from bpy_extras import view3d_utils
from mathutils import Euler, Vector

argv = sys.argv[sys.argv.index("--") + 1:]
WORKDIR, ADDON_ZIP = argv[0], argv[1]
DRAG = (90.0, 40.0)  # pixels (region coordinates, y up) from the press point
STATE = {"t0": time.time()}


def out(name, data):
    path = os.path.join(WORKDIR, name)
    with open(path + ".tmp", "w") as fh:
        json.dump(data, fh, indent=1)
    os.replace(path + ".tmp", path)


def fail(exc_text):
    out("result.json", {"error": exc_text})
    bpy.ops.wm.quit_blender()


def view3d():
    win = bpy.context.window_manager.windows[0]
    for area in win.screen.areas:
        if area.type == "VIEW_3D":
            region = next(r for r in area.regions if r.type == "WINDOW")
            return win, area, region
    raise RuntimeError("no 3D view")


def install_addon():
    bpy.ops.preferences.addon_install(filepath=ADDON_ZIP, overwrite=True)
    bpy.ops.preferences.addon_enable(module="nfield")
    import nfield  # noqa: F401
    return sys.modules["nfield"]


def build_scene():
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=4, radius=1.0)
    obj = bpy.context.active_object
    obj.name = "FieldSphere"
    obj.rotation_euler = Euler((math.radians(25), math.radians(-15), math.radians(40)))
    obj.scale = (1.4, 0.9, 1.1)  # non-uniform
    bpy.context.view_layer.update()
    import nfield.blender as nb

    obj.nfield.glyph_density = 1.0
    nb.solve(obj, n=4, order=2, align="none", write=True)
    return obj


def attr_values(obj):
    a = obj.data.attributes[obj.nfield.direction_attribute]
    buf = np.empty(len(obj.data.polygons) * 3, dtype=np.float32)
    a.data.foreach_get("vector", buf)
    return buf.reshape(-1, 3)


def setup():
    try:
        install_addon()
        print("nfield-window: add-on enabled", flush=True)
        obj = build_scene()
        print("nfield-window: scene built", flush=True)
        win, area, region = view3d()
        win, area, region = view3d()
        space = area.spaces.active
        space.overlay.show_floor = False
        space.overlay.show_axis_x = space.overlay.show_axis_y = False
        space.shading.type = "SOLID"
        with bpy.context.temp_override(window=win, area=area, region=region, screen=win.screen):
            bpy.ops.object.select_all(action="DESELECT")
            obj.select_set(True)
            bpy.context.view_layer.objects.active = obj
            bpy.ops.view3d.view_selected()
            print("nfield-window: framed", flush=True)
            bpy.ops.wm.tool_set_by_id(name="nfield.tool_constraint")
            print("nfield-window: tool active", flush=True)
        space.region_3d.view_distance *= 0.55  # the sphere fills most of the view
        STATE.update(obj=obj.name, attr_before=attr_values(obj))
        bpy.app.timers.register(pick_face, first_interval=1.0)
    except Exception:  # noqa: BLE001
        fail(traceback.format_exc())
    return None


def pick_face():
    """After the view settled: the front-facing face nearest to the region's centre-left."""
    try:
        win, area, region = view3d()
        rv3d = area.spaces.active.region_3d
        obj = bpy.data.objects[STATE["obj"]]
        mw = obj.matrix_world
        nmat = mw.inverted_safe().transposed().to_3x3()
        want = Vector((region.width * 0.45, region.height * 0.45))
        view_dir = rv3d.view_rotation @ Vector((0.0, 0.0, -1.0))
        best = None
        for p in obj.data.polygons:
            wc = mw @ p.center
            wn = (nmat @ p.normal).normalized()
            if wn.dot(view_dir) > -0.9:  # strongly front-facing only (drag plane well conditioned)
                continue
            q = view3d_utils.location_3d_to_region_2d(region, rv3d, wc)
            if q is None:
                continue
            d = (q - want).length
            if best is None or d < best[0]:
                best = (d, p.index, q)
        _, face, q = best
        press = (round(q.x), round(q.y))
        target = (press[0] + round(DRAG[0]), press[1] + round(DRAG[1]))
        tool = bpy.context.workspace.tools.from_space_view3d_mode("OBJECT", create=False)
        STATE.update(face=face, press=press, target=target)
        out("ready.json", {
            "face": face,
            # X11 coordinates relative to the Blender window (y down)
            # (GHOST/X11: window y = height - 1 - Blender's y)
            "press_window": [region.x + press[0], win.height - 1 - (region.y + press[1])],
            "target_window": [region.x + target[0], win.height - 1 - (region.y + target[1])],
            "window_size": [win.width, win.height],
            "active_tool": tool.idname if tool else None,
        })
        bpy.app.timers.register(wait_for_drag, first_interval=0.2)
    except Exception:  # noqa: BLE001
        fail(traceback.format_exc())
    return None


def wait_for_drag():
    from nfield.blender import tool_common

    if tool_common.last_press and not STATE.get("press_seen"):
        # the tool has the press: the test starts dragging only now (on a loaded machine Blender can take
        # a second to handle the press, and it reads the cursor position when it does)
        STATE["press_seen"] = True
        out("pressed.json", {"mouse": list(tool_common.last_press.get("mouse", []))})
    if not os.path.exists(os.path.join(WORKDIR, "dragged")):
        if time.time() - STATE["t0"] > 240:
            fail("timed out waiting for the test's drag")
            return None
        return 0.2
    bpy.app.timers.register(report, first_interval=1.0)  # let the last redraw happen
    return None


def report():
    try:
        win, area, region = view3d()
        rv3d = area.spaces.active.region_3d
        obj = bpy.data.objects[STATE["obj"]]
        st = obj.nfield
        cons = [{"face": c.face, "direction": list(c.direction), "kind": c.kind, "stale": c.stale}
                for c in st.constraints]
        mw = obj.matrix_world
        # The clicked face: where Blender actually received the press (X events can land a few pixels
        # from where xdotool aimed), found with Blender's own ray cast, independently of the tool's code.
        from nfield.blender import tool_common

        face = STATE["face"]
        press_offset = None
        mouse = tool_common.last_press.get("mouse")
        if mouse:
            press_offset = math.hypot(mouse[0] - STATE["press"][0], mouse[1] - STATE["press"][1])
            origin = view3d_utils.region_2d_to_origin_3d(region, rv3d, Vector(mouse))
            ray = view3d_utils.region_2d_to_vector_3d(region, rv3d, Vector(mouse))
            inv = mw.inverted()
            hit, _loc, _nrm, index = obj.ray_cast(inv @ origin, (inv.to_3x3() @ ray).normalized())
            if hit:
                face = index
        item = next((c for c in st.constraints if c.face == face), None)
        res = {"face": face, "aimed_face": STATE["face"], "press_offset_px": press_offset, "constraints": cons,
               "press": STATE["press"], "target": STATE["target"], "n": st.n, "undo_steps": None}
        if item is not None:
            # the stored (object-space) direction seen on screen, independently of the tool's math:
            c = obj.data.polygons[face].center
            eps = 0.02 * obj.dimensions.length
            d = Vector(item.direction).normalized()
            a = view3d_utils.location_3d_to_region_2d(region, rv3d, mw @ c)
            b = view3d_utils.location_3d_to_region_2d(region, rv3d, mw @ (c + d * eps))
            res["screen_direction"] = [b.x - a.x, b.y - a.y]
            nrm = obj.data.polygons[face].normal
            res["tangent_residual"] = abs(d.dot(nrm))
        before, after = STATE["attr_before"], attr_values(obj)
        res["attr_max_change"] = float(np.max(np.linalg.norm(after - before, axis=1)))
        res["attr_face_before"] = before[face].tolist()
        res["attr_face_after"] = after[face].tolist()
        res["attr_unit_err"] = float(np.max(np.abs(np.linalg.norm(after, axis=1) - 1.0)))
        from nfield.blender import overlay

        res["overlay_stats"] = overlay.last_build_stats()
        res["tool_press"] = dict(tool_common.last_press)
        shot = os.path.join(WORKDIR, "window.png")
        with bpy.context.temp_override(window=win, area=area, region=region, screen=win.screen):
            bpy.ops.screen.screenshot(filepath=shot)
        res["screenshot"] = shot
        out("result.json", res)
    except Exception:  # noqa: BLE001
        out("result.json", {"error": traceback.format_exc()})
        bpy.ops.wm.quit_blender()
        return None
    bpy.app.timers.register(spectral_start, first_interval=0.5)
    return None


# ------------------------------------------------------------------ spectral precompute (modal, worker thread)
SPECTRAL = {"ticks": 0, "phase": "cancel"}


def spectral_fail(text):
    out("spectral.json", {"error": text})
    bpy.ops.wm.quit_blender()


def _invoke_precompute(k):
    win, area, region = view3d()
    with bpy.context.temp_override(window=win, area=area, region=region, screen=win.screen):
        return list(bpy.ops.nfield.precompute_spectral("INVOKE_DEFAULT", k=k))


def spectral_start():
    try:
        # A finer sphere (20,480 faces) makes the cancelled basis long enough (tens of seconds) for the
        # test's Esc to arrive mid-computation whatever the machine's load.
        bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=6, radius=1.0, location=(0.0, 0.0, 0.0))
        fine = bpy.context.active_object
        fine.name = "SpectralSphere"
        bpy.data.objects[STATE["obj"]].hide_set(True)
        STATE["obj"] = fine.name
        obj = fine
        SPECTRAL["before"] = [obj.nfield.solver_mode, obj.nfield.spectral_k]
        SPECTRAL["t0"] = time.time()
        SPECTRAL["invoke_cancel"] = _invoke_precompute(500)  # large: the test cancels it with Esc
        out("spectral_started.json", {"invoke": SPECTRAL["invoke_cancel"]})
        bpy.app.timers.register(spectral_wait, first_interval=0.05)
    except Exception:  # noqa: BLE001
        spectral_fail(traceback.format_exc())
    return None


def spectral_wait():
    """UI timer: counts its own ticks while the worker computes (a frozen UI would not tick)."""
    from nfield.blender import background

    try:
        status = background.precompute_status
        if status["state"] == "running":
            SPECTRAL["ticks"] += 1
            SPECTRAL.setdefault("tick_times", []).append(round(time.time() - SPECTRAL["t0"], 3))
            if time.time() - SPECTRAL["t0"] > 300:
                spectral_fail(f"precompute still running after 300 s: {status}")
                return None
            return 0.05
        obj = bpy.data.objects[STATE["obj"]]
        if SPECTRAL["phase"] == "cancel":
            SPECTRAL["cancel"] = dict(status, ticks=SPECTRAL["ticks"], seconds=time.time() - SPECTRAL["t0"],
                                      settings_after=[obj.nfield.solver_mode, obj.nfield.spectral_k])
            SPECTRAL["cancel"]["tick_times"] = SPECTRAL.pop("tick_times", [])
            SPECTRAL.update(phase="finish", ticks=0, t0=time.time())
            SPECTRAL["invoke_finish"] = _invoke_precompute(30)
            return 0.05
        import nfield.blender as nb

        res = nb.field(obj)
        SPECTRAL["finish"] = dict(status, ticks=SPECTRAL["ticks"], seconds=time.time() - SPECTRAL["t0"],
                                  settings_after=[obj.nfield.solver_mode, obj.nfield.spectral_k],
                                  spectral_ready=obj.nfield.spectral_ready,
                                  result_mode=getattr(res, "mode", None),
                                  basis_size=getattr(res, "basis_size", None))
        # A settings change with live update that needs a factorization: solved by the background operator.
        obj.nfield.solver_mode = "EXACT"
        SPECTRAL["before_background"] = nb.field(obj).lambda_
        SPECTRAL.update(phase="background", t0=time.time())
        obj.nfield.strength = 3.0  # property update -> live update -> background solve
        SPECTRAL["message_after_change"] = obj.nfield.last_message
        bpy.app.timers.register(background_wait, first_interval=0.1)
    except Exception:  # noqa: BLE001
        spectral_fail(traceback.format_exc())
    return None


def background_wait():
    from nfield.blender import background
    import nfield.blender as nb

    try:
        status = dict(background.status)
        if status["state"] != "finished" and status["state"] not in ("failed", "cancelled"):
            if time.time() - SPECTRAL["t0"] > 120:
                spectral_fail(f"background solve did not finish: {status}")
                return None
            return 0.1
        obj = bpy.data.objects[STATE["obj"]]
        res = nb.field(obj)
        SPECTRAL["background"] = dict(status, result_mode=res.mode, lambda_after=res.lambda_,
                                      strength=obj.nfield.strength)
        out("spectral.json", {k: v for k, v in SPECTRAL.items() if k not in ("t0",)})
    except Exception:  # noqa: BLE001
        spectral_fail(traceback.format_exc())
        return None
    bpy.ops.wm.quit_blender()
    return None


def maximize():
    """Maximize the 3D view (from the script body: screen operators are not safe from timers)."""
    win, area, region = view3d()
    with bpy.context.temp_override(window=win, area=area, region=region, screen=win.screen):
        bpy.ops.screen.screen_full_area()
    print("nfield-window: maximized", flush=True)


bpy.context.preferences.view.show_splash = False  # the splash would cover the viewport
bpy.context.preferences.view.smooth_view = 0  # no view animation: the picked pixel stays valid
maximize()
bpy.app.timers.register(setup, first_interval=0.5)
