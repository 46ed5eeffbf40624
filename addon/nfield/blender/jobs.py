"""Which objects a worker thread owns right now (the background solve of ``background``).

While a worker solves an object's session, nothing else may touch that session: :func:`busy` says so, the
api refuses to solve the object (NFieldError), and live updates are deferred (:func:`defer`) until the
worker is done. :func:`start_later` launches the background solve operator from a timer, which is safe
from property update callbacks and modal tools; :func:`start_when_idle` does so once the viewport tools
have paused on the object (the comb brush: strokes in quick succession are solved live, the global solve
waits for the pause).
"""
from __future__ import annotations

import time

import bpy

#: object name -> the running background operator's shared state
_running: dict[str, dict] = {}
#: object name -> when a viewport tool last worked on it (time.monotonic(); 0.0 while a stroke is in progress)
_interaction: dict[str, float] = {}
#: objects with a start_when_idle timer waiting
_scheduled: set[str] = set()


def busy(obj) -> bool:
    """True while a worker thread solves `obj`'s session."""
    return getattr(obj, "name", None) in _running


def claim(obj_name: str, shared: dict) -> None:
    """A worker starts on the object's session (`shared`: the operator's state, see background)."""
    _running[obj_name] = shared


def release(obj_name: str, default: dict) -> dict:
    """The worker is done with the object's session: returns its shared state (`default` if none)."""
    return _running.pop(obj_name, default)


def defer(obj) -> None:
    """A live update arrived while `obj` is being solved: solve again when the worker is done."""
    shared = _running.get(obj.name)
    if shared is not None:
        shared["again"] = True


def interactive() -> bool:
    """True in a Blender with windows (background work makes sense only there)."""
    return not bpy.app.background and bool(getattr(bpy.context.window_manager, "windows", None))


def start_later(obj_name: str) -> None:
    """Invoke the background solve (``nfield.solve_background``) for an object from a timer."""
    bpy.app.timers.register(lambda: _launch(obj_name), first_interval=0.0)


def interacting(obj_name: str, active: bool) -> None:
    """A viewport tool starts (active) or ends a stroke on the object (see start_when_idle)."""
    _interaction[obj_name] = 0.0 if active else time.monotonic()


def start_when_idle(obj_name: str, idle_seconds: float) -> None:
    """Invoke the background solve once no tool stroke has worked on the object for `idle_seconds`, so that
    quick successive strokes (each solved live) are not held up by a global solve between them."""
    if obj_name in _scheduled:
        return
    _scheduled.add(obj_name)

    def launch():
        last = _interaction.get(obj_name)
        if bpy.data.objects.get(obj_name) is not None and last is not None and (
                last == 0.0 or time.monotonic() - last < idle_seconds):
            return 0.1  # still working: look again
        _scheduled.discard(obj_name)
        return _launch(obj_name)

    bpy.app.timers.register(launch, first_interval=idle_seconds)


def _launch(obj_name: str):
    obj = bpy.data.objects.get(obj_name)
    wm = bpy.context.window_manager
    if obj is None or busy(obj) or not wm.windows:
        return None
    win = wm.windows[0]
    area = next((a for a in win.screen.areas if a.type == "VIEW_3D"), win.screen.areas[0])
    with bpy.context.temp_override(window=win, area=area, screen=win.screen, object=obj, active_object=obj):
        bpy.ops.nfield.solve_background("INVOKE_DEFAULT", object_name=obj_name)
    return None
