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
* the toolbar: the two nfield tools in groups of their own after the transform tools and a separator, and
  every toolbar query Blender makes succeeds for every tool; no ``Traceback`` in the console from start to
  quit;
* pressing the constraint's arrowhead (over a neighbouring face) and dragging re-aims that constraint;
* at the sidebar's default width the split-layout labels, the full-width buttons and the wrapped message
  lines fit (measured with ``blf`` in the UI font, not read from pixels); the panel is drawn as a popover
  and kept as tests/artifacts/blender_panel.png;
* an undo to a state whose solve needs a spectral basis hands that solve to the worker: the UI timer keeps
  ticking (see _check_undo for the bound).
Skipped (with the reason printed) only when Xvfb, xdotool or blender are missing.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
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


def _check_toolbar(toolbar):
    """The nfield tools sit in groups of their own at the top level, after the transform block, and no
    toolbar query raises."""
    layout = toolbar["layout"]
    print("toolbar:", json.dumps(layout))
    assert toolbar["query_errors"] == [], toolbar["query_errors"]
    ours = {"nfield.tool_constraint", "nfield.tool_singularity"}
    groups = [item for item in layout if isinstance(item, list)]
    assert all(None not in g for g in groups), "a separator inside a toolbar group"
    holding = [g for g in groups if ours & set(g)]
    assert sorted(t for g in holding for t in g) == sorted(ours), holding  # no builtin tool shares their group
    flat = [item if not isinstance(item, list) else item[0] for item in layout]
    first = min(flat.index(g[0]) for g in holding)
    assert flat[first - 1] is None, "no separator before the nfield tools"
    assert "builtin.transform" in flat[:first], "the nfield tools come after the transform tools"


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


def _check_undo(undo):
    """An undo to a state whose solve is slow (spectral basis not computed) hands the solve to the worker
    thread: the UI keeps running its 50 ms timer.

    Bound: the issue's 0.5 s, unless this Blender's own idle gap, measured in the same run just before
    (the same timer with nothing running), is already larger: on a loaded 2-core machine with software GL
    an idle Blender ticks only every one to three seconds. Then the gap may be up to twice the idle one.
    Either way the check discriminates: the worker is still computing the basis at the end of the 10 s
    window (asserted below), so a solve in the UI thread would leave one gap of at least 10 s."""
    assert "error" not in undo, undo.get("error")
    print("undo:", json.dumps({k: v for k, v in undo.items() if k != "ticks"}, indent=1))
    assert undo["undo"] == ["FINISHED"], undo
    assert undo["after_undo"] == {"mode": "SPECTRAL", "k": 400, "constraints": 0}, undo["after_undo"]
    assert undo["undo_seconds"] < 0.5, undo["undo_seconds"]
    bound = max(0.5, 2.0 * undo["idle_max_gap"])
    assert bound < 10.0, f"this Blender is too slow to tell (idle gap {undo['idle_max_gap']:.2f} s)"
    assert undo["max_gap"] is not None and undo["max_gap"] < bound, (undo["max_gap"], undo["idle_max_gap"])
    # the solve was handed to the worker (or is about to be), and the panel says the field is out of date
    assert undo["busy"] or undo["status"]["state"] == "running", undo["status"]
    assert "after undo" in undo["stale_text"], undo["stale_text"]


def test_constraint_drag_in_real_window(tmp_path, legacy_zip):
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
    xvfb = subprocess.Popen(["Xvfb", f":{display}", "-screen", "0", "1280x800x24", "-nolisten", "tcp"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    blender = None
    log = open(tmp_path / "blender.log", "w")
    try:
        time.sleep(1.0)
        assert xvfb.poll() is None, "Xvfb did not start"
        work = tmp_path / "work"
        work.mkdir()
        blender = subprocess.Popen(
            [BLENDER, "--factory-startup", "-noaudio", "--window-geometry", "0", "0", "1280", "800",
             "--python", str(SCRIPT), "--", str(work), str(legacy_zip)],
            env=env, stdout=log, stderr=subprocess.STDOUT)
        ready = _wait_file(work / "ready.json", blender, 180)
        if "error" in ready:
            raise AssertionError(ready["error"])
        assert ready["active_tool"] == "nfield.tool_constraint", ready
        wid = subprocess.run(["xdotool", "search", "--onlyvisible", "--name", "Blender"], env=env,
                             capture_output=True, text=True, timeout=30).stdout.split()
        assert wid, "no Blender window found"
        win = wid[-1]
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
        if blender is not None and blender.poll() is None:
            blender.kill()
        xvfb.terminate()
        xvfb.wait(timeout=10)
        log.close()
    console = (tmp_path / "blender.log").read_text()
    print(console[-3000:])
    assert "error" not in result, result.get("error")
    # Nothing raised anywhere from start to quit (a toolbar query, a draw callback, a handler, a timer).
    assert "Traceback" not in console, console[console.index("Traceback") - 200:][:3000]
    _check_toolbar(ready["toolbar"])
    _check_reaim(json.loads((work / "reaim.json").read_text()), json.loads((work / "ready2.json").read_text()))
    _check_panel(json.loads((work / "panel.json").read_text()))
    assert shown.get("popover") in (["FINISHED"], ["RUNNING_MODAL"], ["INTERFACE"]), shown
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(shown["screenshot"], ARTIFACTS / "blender_panel.png")
    _check_undo(undo)
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
