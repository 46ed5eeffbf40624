"""The README's viewport screenshot: the demo's design in Blender's window, the nfield tab in the sidebar.

    .venv/bin/python examples/demo/viewport_screenshot.py [--out docs/images/viewport_tool.png]
        [--blender /usr/bin/blender] [--size 1280x720]

Run with any Python (the repository's ``.venv`` also stores the PNG with a 256-colour palette): it starts a
virtual X server (Xvfb) and Debian's GUI Blender 3.4 with this file as its script, which

1. loads the add-on from ``addon/`` (this checkout, with its compiled module) and the rocker arm, applies the
   demo's design (``demo.design_rocker_arm``) and solves it;
2. turns the 3D view to the demo's camera direction, frames the object, makes *Field Constraint* the active
   tool and opens the sidebar; Blender 3.4 cannot choose the sidebar's tab from Python, so it simulates
   Ctrl+Tab over the sidebar (Blender's shortcut that cycles its tabs) until the nfield panel draws;
3. waits until the overlay's glyphs are built for this view, saves the window as a PNG and quits.

Blender runs with ``--enable-event-simulate`` (simulated events only: the screenshot cannot be disturbed).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
BLENDER_SIDE = "bpy" in sys.modules  # this file runs as Blender's --python script


# ==================================================================================== outside Blender
def _outside(argv) -> int:
    import argparse
    import shutil
    import subprocess
    import time

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=str(ROOT / "docs" / "images" / "viewport_tool.png"))
    p.add_argument("--blender", default="/usr/bin/blender")
    p.add_argument("--size", default="1280x720")
    args = p.parse_args(argv)
    width, height = (int(x) for x in args.size.lower().split("x"))
    for tool in ("Xvfb",):
        if shutil.which(tool) is None:
            print(f"{tool} is not installed (apt-get install xvfb)")
            return 2
    display = next(d for d in range(120, 160) if not os.path.exists(f"/tmp/.X{d}-lock"))
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONHOME", "PYTHONPATH", "VIRTUAL_ENV")}
    # Debian's Blender embeds the system Python, which finds its home through PATH: no venv first
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "/usr/bin:/bin").split(os.pathsep)
                                  if ".venv" not in p and ".pyenv" not in p) or "/usr/bin:/bin"
    env.update(DISPLAY=f":{display}", LIBGL_ALWAYS_SOFTWARE="1")
    xvfb = subprocess.Popen(["Xvfb", f":{display}", "-screen", "0", f"{width}x{height}x24", "-nolisten", "tcp"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    out = Path(args.out).resolve()
    try:
        time.sleep(1.0)
        proc = subprocess.run([args.blender, "--factory-startup", "-noaudio", "--enable-event-simulate",
                               "--window-geometry", "0", "0", str(width), str(height),
                               "--python", str(Path(__file__).resolve()), "--", str(out)],
                              env=env, capture_output=True, text=True, timeout=600)
    finally:
        xvfb.terminate()
        xvfb.wait(timeout=10)
    log = [line for line in proc.stdout.splitlines() if line.startswith("nfield-screenshot")]
    print("\n".join(log))
    if proc.returncode != 0 or not out.exists() or any("error" in line for line in log):
        print(proc.stdout[-3000:], proc.stderr[-3000:])
        return 1
    sys.path.insert(0, str(HERE))
    from demo import palette_png

    palette_png(out)
    print(f"wrote {out} ({out.stat().st_size // 1024} KB)")
    return 0


# ==================================================================================== inside Blender
def _inside(out: str) -> None:
    import time
    import traceback

    import bpy
    from mathutils import Vector

    sys.path.insert(0, str(ROOT / "addon"))
    sys.path.insert(0, str(HERE))
    import demo
    import nfield.blender as nb
    from nfield.blender import overlay, panels

    state = {"t0": time.time(), "panel_drawn": False, "changes": 0, "ui_draws": 0, "sent_at": None}

    def say(text):
        print(f"nfield-screenshot: {text}", flush=True)

    def fail():
        say("error " + traceback.format_exc().replace("\n", " | "))
        bpy.ops.wm.quit_blender()

    def view3d():
        win = bpy.context.window_manager.windows[0]
        area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
        return win, area, next(r for r in area.regions if r.type == "WINDOW")

    draw = panels.NFIELD_PT_main.draw

    def draw_and_note(self, context):  # tells the script that the nfield tab is the one shown
        state["panel_drawn"] = True
        return draw(self, context)

    panels.NFIELD_PT_main.draw = draw_and_note

    def count_ui_draw():
        state["ui_draws"] += 1

    bpy.types.SpaceView3D.draw_handler_add(count_ui_draw, (), "UI", "POST_PIXEL")

    def setup():
        try:
            nb.register()
            for o in list(bpy.data.objects):
                bpy.data.objects.remove(o)
            obj = demo.import_obj(bpy, demo.MESH, "rocker-arm")
            demo.design_rocker_arm(nb, obj)
            nb.solve(obj, write=True)
            state["obj"] = obj.name
            win, area, region = view3d()
            space = area.spaces.active
            rv3d = space.region_3d
            rv3d.view_perspective = "PERSP"
            rv3d.view_rotation = Vector(demo.ROCKER_VIEW).normalized().to_track_quat("Z", "Y")
            with bpy.context.temp_override(window=win, area=area, region=region, screen=win.screen):
                bpy.ops.object.select_all(action="DESELECT")
                obj.select_set(True)
                bpy.context.view_layer.objects.active = obj
                bpy.ops.view3d.view_selected()
                bpy.ops.wm.tool_set_by_id(name="nfield.tool_constraint")
            rv3d.view_distance *= 0.8
            space.show_region_ui = True
            bpy.app.timers.register(switch_tab, first_interval=2.0)  # the first draws settle
        except Exception:  # noqa: BLE001
            fail()
        return None

    def switch_tab():
        """Ctrl+Tab over the sidebar (the next tab) until the nfield panel draws. The simulated keys are handled
        in the next turn of Blender's event loop, which then redraws the sidebar: the panel is looked for a
        second after each change, once the sidebar has drawn since."""
        try:
            if state["sent_at"] is not None:
                waited = time.time() - state["sent_time"]
                if waited < 1.0 or (state["ui_draws"] == state["sent_at"] and waited < 10.0):
                    return 0.2
            if state["panel_drawn"]:
                say(f"nfield tab shown after {state['changes']} tab change(s)")
                bpy.app.timers.register(shoot, first_interval=1.0)
                return None
            if state["changes"] >= 8:
                raise RuntimeError("the nfield tab did not show after 8 tab changes")
            win, area, _region = view3d()
            ui = next(r for r in area.regions if r.type == "UI")
            x, y = ui.x + ui.width - 8, ui.y + ui.height // 2  # over the tab strip at the sidebar's right edge
            state["panel_drawn"] = False
            state.update(sent_at=state["ui_draws"], sent_time=time.time(), changes=state["changes"] + 1)
            win.event_simulate(type="MOUSEMOVE", value="NOTHING", x=x, y=y)
            win.event_simulate(type="LEFT_CTRL", value="PRESS", x=x, y=y)
            win.event_simulate(type="TAB", value="PRESS", x=x, y=y, ctrl=True)
            win.event_simulate(type="TAB", value="RELEASE", x=x, y=y, ctrl=True)
            win.event_simulate(type="LEFT_CTRL", value="RELEASE", x=x, y=y)
            return 0.2
        except Exception:  # noqa: BLE001
            fail()
            return None

    def shoot():
        """Once the glyphs are built for this view (a timer after the view is drawn), save the window."""
        try:
            win, area, region = view3d()
            obj = bpy.data.objects[state["obj"]]
            st = overlay._states.get(obj.name)
            view = None if st is None else st.views.get(region.as_pointer())
            ready = view is not None and view.key == overlay._view_key(region, area.spaces.active.region_3d, obj) \
                and view.built == (view.key, st.built)
            if not ready and time.time() - state["t0"] < 120:
                area.tag_redraw()
                return 0.5
            with bpy.context.temp_override(window=win, area=area, region=region, screen=win.screen):
                bpy.ops.screen.screenshot(filepath=out)
            say(f"saved {out}: {view.stats if view else 'no glyph view'}")
        except Exception:  # noqa: BLE001
            fail()
            return None
        bpy.ops.wm.quit_blender()
        return None

    bpy.context.preferences.view.show_splash = False
    win, area, region = view3d()
    with bpy.context.temp_override(window=win, area=area, region=region, screen=win.screen):
        bpy.ops.screen.screen_full_area()  # the 3D view alone, with its toolbar and sidebar (from the script
        # body: screen operators are not safe from timers)
    bpy.app.timers.register(setup, first_interval=0.5)


if __name__ == "__main__":
    if BLENDER_SIDE:
        _inside(sys.argv[sys.argv.index("--") + 1])
    else:
        sys.exit(_outside(sys.argv[1:]))
