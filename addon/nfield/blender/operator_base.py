"""The mixin every nfield operator derives from (``NFieldObjectOperator``) and the report text of failures.

It polls for an active mesh object, refuses when the compiled solver cannot be loaded, and runs an api call
so that every failure of the core or the compiled solver becomes an ERROR report and ``{'CANCELLED'}`` with
the settings and design of the object as they were. The operators of ``operators``, ``background``,
``material`` and ``hatching`` derive from it; the viewport tools word their reports with
:func:`failure_message` too, so every nfield operator reports problems alike.
"""
from __future__ import annotations

from . import api, state


class NFieldObjectOperator:
    """Mixin: poll for an active mesh object; run an api call with error reporting."""

    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        if obj is None:
            cls.poll_message_set("No active object: select a mesh object")
            return False
        if obj.type != "MESH":
            cls.poll_message_set(f"Active object '{obj.name}' is not a mesh")
            return False
        return True

    def report_native_error(self) -> bool:
        """Report why the compiled solver cannot be loaded; True if it cannot (the operator must cancel)."""
        problem = state.native_error()
        if problem is not None:
            self.report({"ERROR"}, problem)
        return problem is not None

    #: snapshot the object's settings and design before running and put them back if the operator fails
    #: (a cancelled operator gets no undo step, so a half-done edit would otherwise stay)
    keeps_design_on_failure = False

    def run(self, context, fn, *, solve_after: bool = False):
        """fn(obj) -> message or None, then a re-solve if `solve_after` and Live Update is on.

        Every failure of the core or the compiled solver becomes an ERROR report and {'CANCELLED'}:
        ValueError (bad input, constraints, parameters: the message as is), RuntimeError (numerical failure,
        or Cancelled), MemoryError (std::bad_alloc in the solver)."""
        if self.report_native_error():
            return {"CANCELLED"}
        return guarded_edit(self, context.active_object, fn, keep_design=self.keeps_design_on_failure,
                            solve_after=solve_after)


def guarded_edit(op, obj, fn, *, keep_design: bool, solve_after: bool, redraw: bool = False) -> set:
    """Run the edit fn(obj) -> message or None for operator `op`, then a re-solve if `solve_after` and Live
    Update is on (else, with `redraw`, an overlay refresh). A failure becomes an ERROR report and
    {'CANCELLED'}; with `keep_design` the object's settings and design are put back as they were."""
    saved = None
    try:
        if keep_design:
            api.sync(obj)  # a mesh change remaps the design first: that remapping is kept
            saved = api.snapshot(obj)
        message = fn(obj)
        if solve_after and obj.nfield.live_update:
            api.solve(obj)
        elif redraw:
            api.notify_overlay(obj)
    except (ValueError, RuntimeError, MemoryError) as exc:
        if saved is not None:
            api.restore(obj, saved)
        op.report({"ERROR"}, failure_message(exc))
        return {"CANCELLED"}
    if message:
        op.report({"INFO"}, message)
    return {"FINISHED"}


def failure_message(exc: BaseException) -> str:
    """The report text for an exception from the core / the compiled solver."""
    if isinstance(exc, MemoryError):
        return (f"out of memory in the solver ({exc or 'MemoryError'}): the mesh or the number of constraints is "
                f"too large for this machine")
    if type(exc).__name__ == "Cancelled":
        return f"cancelled: {exc}"
    if isinstance(exc, ValueError):  # NFieldError and the core's ValueErrors: the message names the problem
        return str(exc)
    return f"numerical failure: {exc}"
