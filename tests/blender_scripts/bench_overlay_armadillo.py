"""Overlay cost on the 86k-face armadillo in GUI Blender (run under Xvfb; prints one JSON line and quits).

    DISPLAY=:99 blender --factory-startup -noaudio --python bench_overlay_armadillo.py -- ADDON_ZIP MESH [OUT.json]

ADDON_ZIP is the legacy add-on zip (dist/nfield-<version>-blender34-legacy.zip; Debian's Blender is 3.4).

Measures: the first batch build per density (geometry read + the view's subsample + glyph batch), the rebuild
after a new solve at the same density and view (the live path: sample cached), and the viewport redraw time
with the overlay (``wm.redraw_timer``, DRAW, 20 iterations) against the same view without the overlay. The
glyphs are spread on screen (``glyphs.sample_on_screen``), so their count depends on the view: the object is
framed in the default 3D view.
"""
import json
import os
import sys
import time
import traceback

import bpy

argv = sys.argv[sys.argv.index("--") + 1:]
ADDON_ZIP, MESH = argv[0], argv[1]
OUT = argv[2] if len(argv) > 2 else None
bpy.context.preferences.view.show_splash = False


def view3d():
    win = bpy.context.window_manager.windows[0]
    for area in win.screen.areas:
        if area.type == "VIEW_3D":
            return win, area, next(r for r in area.regions if r.type == "WINDOW")


def redraw_ms(win, area, region, iterations=20):
    with bpy.context.temp_override(window=win, area=area, region=region, screen=win.screen):
        t = time.perf_counter()
        bpy.ops.wm.redraw_timer(type="DRAW", iterations=iterations)
        return (time.perf_counter() - t) / iterations * 1e3


def run():
    res = {}
    try:
        bpy.ops.preferences.addon_install(filepath=ADDON_ZIP, overwrite=True)
        bpy.ops.preferences.addon_enable(module="nfield")
        import nfield.blender as nb
        from nfield.blender import mesh_read, overlay

        for o in list(bpy.data.objects):
            bpy.data.objects.remove(o)
        if hasattr(bpy.ops.wm, "obj_import"):
            bpy.ops.wm.obj_import(filepath=MESH)
        else:
            bpy.ops.import_scene.obj(filepath=MESH)
        obj = bpy.context.selected_objects[0]
        bpy.context.view_layer.objects.active = obj
        res["faces"] = len(obj.data.polygons)
        win, area, region = view3d()
        with bpy.context.temp_override(window=win, area=area, region=region, screen=win.screen):
            bpy.ops.view3d.view_selected()
        obj.nfield.show_field = False
        res["redraw_ms_without_overlay"] = redraw_ms(win, area, region)
        obj.nfield.show_field = True
        t = time.perf_counter()
        nb.solve(obj, n=4, order=2, write=False)
        res["first_solve_s"] = time.perf_counter() - t
        for density in (0.25, 0.5, 1.0):
            obj.nfield.glyph_density = density
            overlay.forget(obj)  # a cold build: batches, glyph sample and the mesh read
            mesh_read.forget(obj.name)
            overlay.refresh(obj)
            redraw_ms(win, area, region, iterations=1)  # the region's view is recorded
            for view in overlay._states[obj.name].views.values():
                view.sample = None  # a cold sample for this density
            overlay.refresh(obj)
            first, view = overlay.last_build_stats(), overlay.view_stats(obj)[0]
            overlay.refresh(obj)  # same mesh + density + view: the live path (sample cached)
            again = overlay.last_build_stats()
            res[f"density_{density}"] = {
                "glyphs": view["glyphs"], "first_build_ms": first["total_s"] * 1e3,
                "sample_ms": view["sample_s"] * 1e3, "rebuild_ms": again["total_s"] * 1e3,
                "redraw_ms": redraw_ms(win, area, region),
            }
    except Exception:  # noqa: BLE001
        res["error"] = traceback.format_exc()
    print("NFIELD_BENCH " + json.dumps(res), flush=True)
    if OUT:
        with open(OUT, "w") as fh:
            json.dump(res, fh, indent=1)
    bpy.ops.wm.quit_blender()


bpy.app.timers.register(run, first_interval=0.5)
