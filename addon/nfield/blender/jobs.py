"""Which objects a worker thread owns right now (the background solve of ``background``), and the worker
thread of the modal operators that compute in the background (:class:`Worker`).

While a worker solves an object's session, nothing else may touch that session: :func:`busy` says so, the
api refuses to solve the object (NFieldError), and live updates are deferred (:func:`defer`) until the
worker is done. :func:`start_later` launches the background solve operator from a timer, which is safe
from property update callbacks and modal tools; :func:`start_when_idle` does so once the viewport tools
have paused on the object (the comb brush: strokes in quick succession are solved live, the global solve
waits for the pause).
"""
from __future__ import annotations

import os
import threading
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


def lower_worker_priority() -> None:
    """Called first in a worker thread: the solver's threads (it and the threads it starts, which inherit
    a thread's nice value on Linux) yield the CPU to Blender's UI thread, so the viewport keeps drawing
    while a factorization, a basis or a remesh is computed on a machine with few cores."""
    try:
        tid = threading.get_native_id()
        os.setpriority(os.PRIO_PROCESS, tid, min(19, os.getpriority(os.PRIO_PROCESS, tid) + 10))
    except (AttributeError, OSError):  # not Linux / not permitted: the worker just runs at normal priority
        pass


class Worker:
    """A computation in a worker thread, driven by a modal operator: ``work(progress)`` runs off the UI
    thread (``progress(fraction)`` returns False once Esc was pressed, which the native calls take as
    cancel); the window's progress bar and a status-bar line follow it, and ``status`` (a dict scripts
    read) gets ``fraction`` and ``ui_updates`` (timer ticks the UI handled while the worker ran).

    The operator calls :meth:`start` from invoke, :meth:`step` from modal (True: the worker is done; other
    events pass on to Blender so the viewport stays usable), then :meth:`stop` and reads :attr:`outcome`:
    ("ok", value) or ("error", exception)."""

    def __init__(self, work, status: dict, name: str):
        self.fraction = 0.0
        self.cancel = False
        self.outcome = None
        self._work = work
        self._status = status
        self._timer = None
        self.thread = threading.Thread(target=self._run, name=name, daemon=True)

    def progress(self, fraction) -> bool:
        self.fraction = float(fraction)
        self._status["fraction"] = self.fraction
        return not self.cancel

    def _run(self) -> None:
        lower_worker_priority()
        try:
            self.outcome = ("ok", self._work(self.progress))
        except BaseException as exc:  # noqa: BLE001 - reported in the main thread
            self.outcome = ("error", exc)

    def start(self, operator, context) -> None:
        self.thread.start()
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(operator)

    def step(self, context, event, label: str) -> bool:
        """Handle one modal event; True once the worker is done."""
        if event.type == "ESC" and event.value == "PRESS":
            self.cancel = True
        if event.type != "TIMER":
            return not self.thread.is_alive()
        context.window_manager.progress_update(int(100 * self.fraction))
        if not self.thread.is_alive():
            return True
        self._status["ui_updates"] = self._status.get("ui_updates", 0) + 1
        if context.workspace is not None:
            state = "cancelling" if self.cancel else f"{100 * self.fraction:.0f}%"
            context.workspace.status_text_set(f"nfield: {label} ({state}), Esc to cancel")
        return False

    @staticmethod
    def passed_on(event) -> set:
        """What modal returns while the worker runs: the timer and Esc are ours, the rest goes to Blender."""
        return {"RUNNING_MODAL"} if event.type in ("TIMER", "ESC") else {"PASS_THROUGH"}

    def stop(self, context) -> None:
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
