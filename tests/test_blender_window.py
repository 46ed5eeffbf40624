"""A real Blender window: Debian's GUI Blender 3.4.1 under Xvfb, driven with xdotool.

The legacy add-on zip (``python3 build_addon.py package`` -> dist/nfield-*-blender34-legacy.zip) is
installed into a temporary user profile; tests/blender_scripts/window_session.py builds the scene (icosphere
with rotation and non-uniform scale), maximizes the 3D view, activates the constraint tool and tells us where
to click. We press on a face, drag, release (xdotool), and Blender reports back what it stored.

Checks:
* exactly one constraint, on the clicked face, tangent to it;
* its direction, projected back to the screen by Blender's own projection (independently of the tool's
  unprojection code), points along the drag within ANGLE_TOL_DEG. Justification: the drag is ~98 px long,
  so one pixel of rounding of the press/target points is atan(1/98) = 0.6 deg; the stored direction is
  projected at the face centroid while the tool aims from the press point (the centroid's pixel, rounded),
  and the perspective change over that sub-pixel offset is far below 0.1 deg; the remaining error budget
  covers xdotool's final motion event landing one pixel off. 3 deg is > 4x the worst case, and a wrong
  transform (e.g. ignoring the non-uniform scale or the rotation) is off by tens of degrees;
* the face attribute changed, stays unit, and at the clicked face one of the n directions is the dragged
  one (the constraint is hard);
* a screenshot is saved to tests/artifacts/blender_window.png;
* the spectral Precompute button's operator (modal, worker thread): a large basis is cancelled with Esc
  while it computes (settings restored, the status says cancelled, the UI updated the progress meanwhile),
  a small one runs to the end (spectral mode, basis ready, the field solved in the basis);
* a settings change that needs a new factorization is solved by the background operator's worker thread;
* the toolbar: the three nfield tools (constraint, singularity, comb) in groups of their own after the
  transform tools and a separator, and every toolbar query Blender makes succeeds for every tool; no
  ``Traceback`` in the console from start to quit;
* pressing the constraint's arrowhead (over a neighbouring face) and dragging re-aims that constraint;
* at the sidebar's default width the split-layout labels, the full-width buttons and the wrapped message
  lines fit (measured with ``blf`` in the UI font, not read from pixels); the panel is drawn as a popover
  and kept as tests/artifacts/blender_panel.png;
* an undo to a state whose solve needs a spectral basis hands that solve to the worker: the UI timer keeps
  ticking, with no gap of 0.5 s or more (see _check_undo);
* zooming in spreads the field glyphs evenly on screen: more glyphs, closer together on the surface.
Skipped (with the reason printed) when Xvfb, xdotool or blender are missing, and, after every other check
passed, when a single redraw of the window already takes 0.5 s (the undo bound cannot be judged then).
test_comb_brush_in_real_window (tests/blender_scripts/window_comb.py) drags the comb brush across the Stanford
bunny: the comb attribute along the stroke, its direction against the drag measured with Blender's own ray
casts, the solved field turning to it, one undo removing exactly the stroke; tests/artifacts/comb_tool.png.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from conftest import system_blender_env

pytestmark = pytest.mark.gui

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "tests" / "blender_scripts" / "window_session.py"
ARTIFACTS = ROOT / "tests" / "artifacts"
BLENDER = os.environ.get("NFIELD_GUI_BLENDER", "/usr/bin/blender")
ANGLE_TOL_DEG = 3.0
#: the window (and X screen): small enough that one redraw under software GL stays well below the undo bound
#: on a loaded 2-core machine (1280 x 800: about 0.3 s at load 3, 0.6 s at load 7), large enough for the
#: sidebar at its default width beside the viewport
WINDOW = (960, 600)


def _missing() -> str:
    for tool in ("Xvfb", "xdotool"):
        if shutil.which(tool) is None:
            return f"{tool} is not installed (apt-get install xvfb xdotool)"
    if not os.path.exists(BLENDER):
        return f"GUI Blender not found at {BLENDER} (apt-get install blender)"
    return ""


def _free_display() -> int:
    for d in range(99, 140):
        if not os.path.exists(f"/tmp/.X{d}-lock") and not os.path.exists(f"/tmp/.X11-unix/X{d}"):
            return d
    raise RuntimeError("no free X display number")


def _wait_file(path: Path, proc: subprocess.Popen, timeout: float) -> dict:
    end = time.time() + timeout
    while time.time() < end:
        if path.exists():
            return json.loads(path.read_text())
        if proc.poll() is not None:
            raise AssertionError(f"blender exited ({proc.returncode}) before writing {path.name}")
        time.sleep(0.2)
    raise AssertionError(f"timed out waiting for {path.name}")


def _xdo(env, *args):
    subprocess.run(["xdotool", *map(str, args)], env=env, check=True, timeout=30)


def _start_xvfb(tmp_path, size=WINDOW):
    """(environment for GUI Blender on a fresh Xvfb display with a temporary user profile, the Xvfb process,
    the console log file). Skips the test (reason printed) without Xvfb, xdotool or Blender."""
    reason = _missing()
    if reason:
        print(f"SKIP: {reason}")
        pytest.skip(reason)
    display = _free_display()
    env = system_blender_env()
    env["DISPLAY"] = f":{display}"
    env["LIBGL_ALWAYS_SOFTWARE"] = "1"  # mesa llvmpipe
    for key in ("BLENDER_USER_CONFIG", "BLENDER_USER_SCRIPTS", "BLENDER_USER_DATAFILES"):
        env[key] = str(tmp_path / key.lower())
    env.pop("PYTHONPATH", None)
    env["NFIELD_CACHE_DIR"] = str(tmp_path / "bases")
    xvfb = subprocess.Popen(["Xvfb", f":{display}", "-screen", "0", f"{size[0]}x{size[1]}x24", "-nolisten", "tcp"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(1.0)
    assert xvfb.poll() is None, "Xvfb did not start"
    return env, xvfb, open(tmp_path / "blender.log", "w")


def _start_blender(env, script, args, log, size=WINDOW):
    """GUI Blender running `script` with `args` (the first: the work directory, created here)."""
    Path(args[0]).mkdir()
    return subprocess.Popen(
        [BLENDER, "--factory-startup", "-noaudio", "--window-geometry", "0", "0", str(size[0]), str(size[1]),
         "--python", str(script), "--", *map(str, args)],
        env=env, stdout=log, stderr=subprocess.STDOUT)


def _stop(blender, xvfb, log) -> str:
    """Stop Blender (if still running) and Xvfb; returns Blender's console output (its end printed)."""
    if blender is not None and blender.poll() is None:
        blender.kill()
    xvfb.terminate()
    xvfb.wait(timeout=10)
    log.close()
    console = Path(log.name).read_text()
    print(console[-3000:])
    return console


def _assert_no_traceback(console: str) -> None:
    """Nothing raised anywhere from start to quit (a toolbar query, a draw callback, a handler, a timer)."""
    assert "Traceback" not in console, console[console.index("Traceback") - 200:][:3000]


def _blender_window_id(env) -> str:
    wid = subprocess.run(["xdotool", "search", "--onlyvisible", "--name", "Blender"], env=env,
                         capture_output=True, text=True, timeout=30).stdout.split()
    assert wid, "no Blender window found"
    return wid[-1]


def _drag(env, win, points, pause=0.15):
    """Move the mouse through `points` (window pixels) with the left button held (already pressed)."""
    for x, y in points:
        _xdo(env, "mousemove", "--window", win, round(x), round(y))
        time.sleep(pause)


def _check_toolbar(toolbar):
    """The nfield tools sit in groups of their own at the top level, after the transform block, and no
    toolbar query raises."""
    layout = toolbar["layout"]
    print("toolbar:", json.dumps(layout))
    assert toolbar["query_errors"] == [], toolbar["query_errors"]
    ours = {"nfield.tool_constraint", "nfield.tool_singularity", "nfield.tool_comb"}
    groups = [item for item in layout if isinstance(item, list)]
    assert all(None not in g for g in groups), "a separator inside a toolbar group"
    holding = [g for g in groups if ours & set(g)]
    assert sorted(t for g in holding for t in g) == sorted(ours), holding  # no builtin tool shares their group
    flat = [item if not isinstance(item, list) else item[0] for item in layout]
    first = min(flat.index(g[0]) for g in holding)
    assert flat[first - 1] is None, "no separator before the nfield tools"
    assert "builtin.transform" in flat[:first], "the nfield tools come after the transform tools"


def _check_zoom(zoom):
    """Zooming in (the sphere 4.5x closer: from a small disc to most of the view) rebuilt the glyphs for the
    new view: more glyphs, closer together on the surface (the cell size in object units falls with the
    zoom), at the same spacing on screen."""
    print("glyphs zoomed out / in:", json.dumps(zoom))
    out, zin = zoom["out"], zoom["in"]
    assert zin["glyphs"] > out["glyphs"], zoom
    assert zin["median_cell"] < 0.5 * out["median_cell"], zoom
    assert zin["spacing_px"] == out["spacing_px"], zoom


def _check_reaim(reaim, ready2):
    """Pressing the arrowhead re-aimed the constraint (still one, on the same face) instead of adding one on
    the face under the arrowhead; the new direction points at the drag target (same tolerance argument as
    the first drag: a 90 px drag, one pixel of rounding is 0.6 deg)."""
    assert "error" not in reaim, reaim.get("error")
    print("re-aim:", json.dumps(reaim), "arrow length on screen:", ready2["arrow_px"])
    assert ready2["arrow_px"] >= 40.0, ready2  # the screen-space minimum (48 px, less rounding/perspective)
    live = [c for c in reaim["constraints"] if not c["stale"]]
    assert [c["face"] for c in live] == [reaim["face"]], reaim["constraints"]
    assert reaim["press_face"] == reaim["face"], reaim
    # the press was over another face (the head reaches past the constrained face: arrows are >= 48 px, the
    # faces of this sphere ~25 px): before, that press made a new constraint there
    assert reaim["press_hit_face"] != reaim["face"], reaim
    want = (reaim["target"][0] - reaim["centroid_px"][0], reaim["target"][1] - reaim["centroid_px"][1])
    sx, sy = reaim["screen_direction"]
    angle = math.degrees(math.atan2(want[0] * sy - want[1] * sx, want[0] * sx + want[1] * sy))
    assert abs(angle) < ANGLE_TOL_DEG, f"re-aimed direction is {angle:.2f} deg off the drag target"


def _check_panel(panel):
    """At the sidebar's default width every split-layout label of the main panel fits its column (so Blender
    draws it whole, without '…'), and so do the full-width buttons (Precompute, the two tools) and each line
    of a long message as the panel wraps it."""
    assert "error" not in panel, panel.get("error")
    print("sidebar:", json.dumps(panel, indent=1))
    for key, row in panel["rows"].items():
        assert row["px"] <= row["room"], f"{key}: '{row['text']}' needs {row['px']:.0f} px, has {row['room']:.0f}"
    lines = [k for k in panel["rows"] if k.startswith("message line")]
    assert len(lines) >= 3, "the long message was not wrapped over several lines"


#: the done-when bound on the longest gap between 50 ms UI timer ticks after an undo during a pending solve
UNDO_MAX_GAP_S = 0.5


def _check_undo(undo) -> str:
    """An undo to a state whose solve is slow (spectral basis not computed) hands the solve to the worker
    thread: the UI keeps running its 50 ms timer, with no gap of UNDO_MAX_GAP_S or more.

    The same run measures two controls just before: the timer with nothing running (it ticks on time: Blender
    only blocks its timers while it redraws, and with the viewport's progressive anti-aliasing off nothing
    redraws when idle), and the timer redrawing the 3D view at every tick: the longest gap there is what one
    redraw of this window costs now. An undo redraws the view at least once, so when a single redraw already
    takes UNDO_MAX_GAP_S (a machine overloaded at test time), the bound cannot be judged: the caller skips
    with this reason (returned), after every other check has passed. Otherwise the bound is asserted; it
    discriminates: the worker is still computing the basis at the end of the 10 s window (asserted below), so
    a solve in the UI thread would leave one gap of at least 10 s. Returns "" when the bound was asserted."""
    assert "error" not in undo, undo.get("error")
    print("undo:", json.dumps({k: v for k, v in undo.items() if k != "ticks"}, indent=1))
    assert undo["undo"] == ["FINISHED"], undo
    assert undo["after_undo"] == {"mode": "SPECTRAL", "k": 400, "constraints": 0}, undo["after_undo"]
    assert undo["undo_seconds"] < UNDO_MAX_GAP_S, undo["undo_seconds"]
    # the solve was handed to the worker (or is about to be), and the panel says the field is out of date
    assert undo["busy"] or undo["status"]["state"] == "running", undo["status"]
    assert "after undo" in undo["stale_text"], undo["stale_text"]
    assert undo["max_gap"] is not None and undo["max_gap"] < 10.0, undo["max_gap"]  # never frozen
    if undo["redraw_max_gap"] >= UNDO_MAX_GAP_S:
        return (f"machine overloaded: one redraw of the test window blocks the UI for {undo['redraw_max_gap']:.2f} s "
                f"(idle gap {undo['idle_max_gap']:.2f} s, load {' '.join(undo['load'])}), so the "
                f"{UNDO_MAX_GAP_S} s bound cannot be judged; the longest gap after the undo was {undo['max_gap']:.2f} s")
    assert undo["max_gap"] < UNDO_MAX_GAP_S, \
        (f"the UI timer stopped for {undo['max_gap']:.2f} s after the undo (idle gap {undo['idle_max_gap']:.2f} s, "
         f"one redraw {undo['redraw_max_gap']:.2f} s)")
    return ""


def test_constraint_drag_in_real_window(tmp_path, legacy_zip):
    env, xvfb, log = _start_xvfb(tmp_path)
    blender = None
    try:
        work = tmp_path / "work"
        blender = _start_blender(env, SCRIPT, [work, legacy_zip], log)
        ready = _wait_file(work / "ready.json", blender, 180)
        if "error" in ready:
            raise AssertionError(ready["error"])
        assert ready["active_tool"] == "nfield.tool_constraint", ready
        win = _blender_window_id(env)
        (px, py), (tx, ty) = ready["press_window"], ready["target_window"]
        _xdo(env, "mousemove", "--window", win, px, py)
        time.sleep(0.5)
        _xdo(env, "mousedown", 1)
        _wait_file(work / "pressed.json", blender, 60)  # Blender handled the press: now drag
        steps = 12
        for i in range(1, steps + 1):
            _xdo(env, "mousemove", "--window", win, round(px + (tx - px) * i / steps),
                 round(py + (ty - py) * i / steps))
            time.sleep(0.15)
        time.sleep(0.8)  # live solves catch up (one per timer tick)
        _xdo(env, "mouseup", 1)
        time.sleep(1.0)
        (work / "dragged").write_text("1")
        result = _wait_file(work / "result.json", blender, 120)
        if "error" not in result:
            # second drag: press on the arrowhead of the constraint just made, drag at a right angle
            ready2 = _wait_file(work / "ready2.json", blender, 60)
            (px, py), (tx, ty) = ready2["press_window"], ready2["target_window"]
            _xdo(env, "mousemove", "--window", win, px, py)
            time.sleep(0.5)
            _xdo(env, "mousedown", 1)
            _wait_file(work / "pressed2.json", blender, 60)
            for i in range(1, steps + 1):
                _xdo(env, "mousemove", "--window", win, round(px + (tx - px) * i / steps),
                     round(py + (ty - py) * i / steps))
                time.sleep(0.15)
            time.sleep(0.8)
            _xdo(env, "mouseup", 1)
            time.sleep(1.0)
            (work / "dragged2").write_text("1")
            # the main panel is shown as a popover (its draw code runs in the window): close it with Esc
            shown = _wait_file(work / "panel_shown.json", blender, 120)
            time.sleep(0.5)
            _xdo(env, "key", "Escape")
            time.sleep(0.5)
            (work / "panel_closed").write_text("1")
            started = _wait_file(work / "spectral_started.json", blender, 60)
            assert started.get("invoke") == ["RUNNING_MODAL"], started
            time.sleep(1.5)
            _xdo(env, "mousemove", "--window", win, 400, 400)
            _xdo(env, "key", "Escape")
            spectral = _wait_file(work / "spectral.json", blender, 400)
            undo = _wait_file(work / "undo.json", blender, 300)
        blender.wait(timeout=60)
    finally:
        console = _stop(blender, xvfb, log)
    assert "error" not in result, result.get("error")
    _assert_no_traceback(console)
    _check_toolbar(ready["toolbar"])
    _check_zoom(ready["zoom"])
    _check_reaim(json.loads((work / "reaim.json").read_text()), json.loads((work / "ready2.json").read_text()))
    _check_panel(json.loads((work / "panel.json").read_text()))
    assert shown.get("popover") in (["FINISHED"], ["RUNNING_MODAL"], ["INTERFACE"]), shown
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(shown["screenshot"], ARTIFACTS / "blender_panel.png")
    undo_skip = _check_undo(undo)
    print("spectral precompute:", json.dumps(spectral, indent=1))
    assert "error" not in spectral, spectral["error"]
    cancel, finish = spectral["cancel"], spectral["finish"]
    assert cancel["state"] == "cancelled" and cancel["settings_after"] == spectral["before"], cancel
    assert finish["state"] == "finished" and finish["settings_after"] == ["SPECTRAL", 30], finish
    assert finish["spectral_ready"] and finish["result_mode"] == "spectral" and finish["basis_size"] == 30
    # The UI was not frozen by the computation: Esc reached the modal operator while the worker was still
    # computing (it stopped short of the end), and the status bar progress was updated meanwhile. (Tick
    # rates are no measure here: under Xvfb's software GL on a loaded 2-core machine even an idle Blender
    # runs its 50 ms timers only about once a second.)
    assert cancel["fraction"] < 1.0 and cancel["ui_updates"] >= 1 and cancel["ticks"] >= 1, cancel
    # A strength change with live update needs a new factorization: it ran in the background operator's
    # worker thread and its result was stored (exact mode, a different lambda).
    bg = spectral["background"]
    assert "background" in spectral["message_after_change"], spectral["message_after_change"]
    assert bg["state"] == "finished" and bg["thread"] == "nfield-solve" and bg["work"] == "factorization", bg
    assert bg["result_mode"] == "exact" and bg["lambda_after"] != spectral["before_background"], bg

    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    shot = ARTIFACTS / "blender_window.png"
    shutil.copyfile(result["screenshot"], shot)
    (ARTIFACTS / "blender_window.json").write_text(json.dumps(result, indent=1))
    print(f"screenshot: {shot}")

    # The press must land where aimed (within a few pixels: X event delivery jitter) and the constraint
    # must sit on the face under the press as Blender's own ray cast sees it.
    assert result["press_offset_px"] is not None and result["press_offset_px"] < 25, result.get("tool_press")
    face = result["face"]
    live = [c for c in result["constraints"] if not c["stale"]]
    assert [c["face"] for c in live] == [face], result["constraints"]
    assert live[0]["kind"] == "DIRECTION"
    assert result["tangent_residual"] < 1e-4, "stored direction is not tangent to the face"

    drag = (result["target"][0] - result["press"][0], result["target"][1] - result["press"][1])
    sx, sy = result["screen_direction"]
    angle = math.degrees(math.atan2(drag[0] * sy - drag[1] * sx, drag[0] * sx + drag[1] * sy))
    assert abs(angle) < ANGLE_TOL_DEG, f"constraint direction is {angle:.2f} deg off the drag on screen"

    assert result["attr_max_change"] > 1e-3, "the output attribute did not change"
    assert result["attr_unit_err"] < 1e-4
    n = result["n"]
    d = live[0]["direction"]
    a = result["attr_face_after"]
    nd = math.sqrt(sum(x * x for x in d))
    cosang = sum(x * y for x, y in zip(d, a)) / nd
    # one of the n directions (spaced 2 pi / n) is the constraint: angle mod 2 pi / n ~ 0
    ang = math.acos(max(-1.0, min(1.0, cosang)))
    period = 2 * math.pi / n
    off = min(ang % period, period - ang % period)
    assert math.degrees(off) < 1.0, f"attribute at face {face} is {math.degrees(off):.2f} deg off symmetry"
    if undo_skip:  # every other check passed; only the responsiveness bound could not be judged
        print(f"SKIP: {undo_skip}")
        pytest.skip(undo_skip)


COMB_SCRIPT = ROOT / "tests" / "blender_scripts" / "window_comb.py"


def _angle_mod(a, b, n) -> float:
    """Degrees between the lines of a and b up to the n-symmetry (a multiple of 360 / n)."""
    a, b = [float(x) for x in a], [float(x) for x in b]
    na, nb = math.sqrt(sum(x * x for x in a)), math.sqrt(sum(x * x for x in b))
    ang = math.degrees(math.acos(max(-1.0, min(1.0, sum(x * y for x, y in zip(a, b)) / (na * nb)))))
    period = 360.0 / n
    return min(ang % period, period - ang % period)


def test_comb_brush_in_real_window(tmp_path, legacy_zip):
    """The comb tool on the Stanford bunny (69,451 faces) in Debian's Blender 3.4 under Xvfb: a horizontal
    drag across the body (tests/blender_scripts/window_comb.py) paints the comb attribute along the stroke
    in the drag's direction, the solved field there turns to it, and one undo removes the stroke; then Quad
    Remesh from Field, invoked as the panel button does, solves the changed design and remeshes it in its
    worker thread."""
    env, xvfb, log = _start_xvfb(tmp_path)
    blender = None
    try:
        work = tmp_path / "work"
        blender = _start_blender(env, COMB_SCRIPT, [work, legacy_zip, ROOT / "tests" / "data" / "stanford-bunny.obj"],
                                 log)
        ready = _wait_file(work / "ready.json", blender, 300)
        if "error" in ready:
            raise AssertionError(ready["error"])
        assert ready["active_tool"] == "nfield.tool_comb", ready
        win = _blender_window_id(env)
        path = ready["path_window"]
        _xdo(env, "mousemove", "--window", win, *path[0])
        time.sleep(0.5)
        _xdo(env, "mousedown", 1)
        _wait_file(work / "pressed.json", blender, 60)  # Blender handled the press: now drag
        _drag(env, win, path[1:])
        time.sleep(1.0)  # the live solves catch up (one per timer tick)
        _xdo(env, "mouseup", 1)
        time.sleep(0.5)
        mid = path[len(path) // 2]
        _xdo(env, "mousemove", "--window", win, mid[0], mid[1])  # the brush circle in the screenshot
        time.sleep(0.5)
        (work / "dragged").write_text("1")
        result = _wait_file(work / "result.json", blender, 400)
        undo = _wait_file(work / "undo.json", blender, 400) if "error" not in result else {}
        remesh = _wait_file(work / "remesh.json", blender, 400) if undo and "error" not in undo else {}
        blender.wait(timeout=60)
    finally:
        console = _stop(blender, xvfb, log)
    assert "error" not in result, result.get("error")
    _assert_no_traceback(console)
    stroke = result["stroke"]
    print("stroke:", json.dumps(stroke), "background:", json.dumps(result["background"]))
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(result["screenshot"], ARTIFACTS / "comb_tool.png")
    (ARTIFACTS / "comb_tool.json").write_text(json.dumps(result, indent=1))
    # a drag of about 240 px with samples every quarter of the 40 px radius leaves about 24 samples
    assert stroke["samples"] >= 12 and stroke["changed"] > 0, stroke
    assert result["background"]["state"] == "finished", result["background"]
    n = result["n"]
    # the faces seen within 0.3 radius of the path, more than a radius from its ends (the path is 6 radii
    # long: 0.2 .. 0.8 of it), facing the view within 37 degrees (cos > 0.8)
    core = [f for f in result["faces"] if f["facing"] > 0.8 and 0.2 <= f["t"] <= 0.8]
    assert len(core) >= 20, len(core)
    # comb weight: the nearest sample is within sqrt(0.3^2 + 0.125^2) = 0.33 radius on screen (samples at most
    # 0.25 radius apart), so on a flat stretch facing the view the smooth falloff (1 - t^2)^2 at strength 1
    # is >= 0.80 and most faces are near 1; the scan's bumps tilt the surface between a face and its nearest
    # sample (space distances exceed screen distances): >= 0.5 everywhere still means within 0.54 radius of a
    # sample in space (measured: median 0.98, least 0.59)
    weights = sorted(f["weight"] for f in core)
    assert weights[0] >= 0.5 and weights[len(weights) // 2] >= 0.9, (weights[0], weights[len(weights) // 2])
    assert result["far_weights"] and max(result["far_weights"]) == 0.0, result["far_weights"][:20]
    # the combed direction is a weighted mean (in representation space) of the drag's chords near the face,
    # projected into it; each chord between two mouse positions is a sum of the fine chords the script measured
    # with Blender's own ray cast, so the combed direction lies in their cone. 0.05 degrees: float32 storage
    # of the direction (1e-7) and the ray casts of two BVHs of the same float32 mesh, with a wide margin
    outside = [(f["face"], f["cone"]) for f in core if not (f["cone"][0] - 0.05 <= 0.0 <= f["cone"][1] + 0.05)]
    widths = sorted(f["cone"][1] - f["cone"][0] for f in core)
    print("chord cones: median width %.2f deg, widest %.2f deg" % (widths[len(widths) // 2], widths[-1]))
    assert not outside, outside[:10]
    # the solved field turns to the combed direction: the comb is a soft pull (weight >= 0.5 in units of the
    # smoothness at the face, docs/guides.md) along a band whose faces are all combed alike, against the
    # curvature alignment (weight 1 in units of the global strength), so the field there follows the comb
    # closely (measured: median 0.1 degrees, at most 3.4 on a face where the scan bends sharply); the drag was
    # chosen 45 degrees off the mean field around it, so without the comb the median deviation is large
    # (30 to 40 degrees here: the curvature field turns along the path)
    field_dev = sorted(_angle_mod(f["field"], f["comb"], n) for f in core)
    before_dev = sorted(_angle_mod(f["field_before"], f["comb"], n) for f in core)
    print("field vs comb (deg): max %.2f median %.2f; before the stroke: median %.2f min %.2f" % (
        field_dev[-1], field_dev[len(field_dev) // 2], before_dev[len(before_dev) // 2], before_dev[0]))
    assert field_dev[-1] < 10.0 and field_dev[len(field_dev) // 2] < 1.0, field_dev[-5:]
    assert before_dev[len(before_dev) // 2] > 15.0
    # one undo removes the stroke and nothing before it: the comb attribute is gone, the marker set before
    # the stroke (its own undo step) is still there, and the field is the one before the stroke (the same
    # design: the remembered field or the same solve, to rounding)
    print("undo:", json.dumps(undo))
    assert "error" not in undo, undo.get("error")
    assert undo["undo"] == ["FINISHED"] and not undo["has_comb"] and undo["marker"] == 1, undo
    assert undo["from_before"] < 1e-6 < 0.1 < undo["from_stroke"], undo
    # Quad Remesh from the panel on a design changed since its last solve: invoke hands the solve and the
    # remesh to the worker thread (it owns the object's session when invoke returns, the field is still the
    # old one), the UI thread keeps ticking while the worker runs, and the design is current afterwards; the
    # new object is quad-dominant and the source keeps its faces
    print("remesh:", json.dumps(remesh))
    assert "error" not in remesh, remesh.get("error")
    assert remesh["invoke"] == ["RUNNING_MODAL"] and remesh["busy_after_invoke"], remesh
    assert remesh["state_before"] == "outdated" and remesh["state_after"] == "current", remesh
    assert remesh["status"]["state"] == "finished" and remesh["status"]["ui_updates"] >= 1, remesh["status"]
    assert remesh["ticks_while_running"] >= 1
    assert any("solved it again before remeshing" in m for m in remesh["messages"]), remesh["messages"]
    new = remesh["new_object"]
    assert new["source_faces_unchanged"] and new["quads"] >= 0.97 * new["faces"] > 0, new
