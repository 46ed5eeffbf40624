"""nfield: n-symmetry direction field design on triangle meshes (n-field splines).

A plain Python library (``nfield.core``), a command line (``python -m nfield``) and, inside Blender, an
add-on (``register``/``unregister``; the Blender layer lives in ``nfield.blender``). Importing this package
imports neither ``bpy`` nor the compiled module ``nfield._native``.
"""

bl_info = {
    "name": "nfield",
    "author": "nfield developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Sidebar > nfield",
    "description": "Design smooth n-symmetry direction fields (n-field splines) on triangle meshes",
    "category": "Mesh",
}

__version__ = "0.1.0"

__all__ = ["bl_info", "register", "unregister", "__version__"]


def _blender_layer():
    import importlib

    name = __name__ + ".blender"
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name == name:
            raise ImportError(
                "nfield's Blender layer (nfield.blender) is not part of this installation; "
                "register()/unregister() need it (the library and the command line work without it)"
            ) from exc
        if exc.name == "bpy":
            raise ImportError("nfield.register() must run inside Blender (module 'bpy' not found)") from exc
        raise


def register():
    """Blender add-on entry point: registers the Blender layer (nfield.blender)."""
    _blender_layer().register()


def unregister():
    """Blender add-on exit point (nothing to do if the Blender layer was never loaded)."""
    import sys

    mod = sys.modules.get(__name__ + ".blender")
    if mod is not None:
        mod.unregister()
