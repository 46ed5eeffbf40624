"""Add-on wide runtime state (not saved): set by register(), read by the panels."""
from __future__ import annotations

from ..core import native

#: the loader's message when the compiled module nfield._native cannot be imported, else ""
native_problem: str = ""


def native_error() -> str | None:
    """The loader's message if the compiled module cannot be imported now, else None."""
    try:
        native()
    except ImportError as exc:
        return str(exc)
    return None
