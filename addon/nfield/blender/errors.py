"""The one exception type of the Blender layer."""
from __future__ import annotations


class NFieldError(ValueError):
    """A user-facing problem (no mesh, empty mesh, bad index ...); the message is shown as is."""
