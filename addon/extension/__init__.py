"""nfield as a Blender extension (Blender 4.2 and later): the module Blender enables.

The add-on itself is the package ``nfield`` (the library, the command line and the Blender layer), which
Blender installs from the wheels that blender_manifest.toml lists, one per Python ABI, into the extensions'
site-packages. This module is imported as ``bl_ext.<repository>.nfield``; ``import nfield`` below is the
installed top-level package, not this module.
"""


def register():
    import nfield

    nfield.register()


def unregister():
    import sys

    package = sys.modules.get("nfield")
    if package is not None:
        package.unregister()
