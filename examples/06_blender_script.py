"""06: the add-on's scripting API in Blender without a window (PyPI bpy).

    PYTHONPATH=addon .venv/bin/python examples/06_blender_script.py [out.blend]     (from the repository root;
    or with nfield pip-installed: python examples/06_blender_script.py)

Everything the panel and the tools do is available to scripts through ``nfield.blender`` (docs/
blender_addon.md). The design is stored on the object (``obj.nfield``), so a saved .blend opens with it,
editable in the add-on's panel.
"""
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

import bpy  # noqa: E402

import nfield.blender as nb  # noqa: E402

bpy.ops.wm.read_factory_settings(use_empty=True)
nb.register()  # inside Blender, enabling the add-on does this
bpy.ops.mesh.primitive_torus_add(major_segments=48, minor_segments=16)
obj = bpy.context.active_object

# Settings, a constraint and a singularity are stored on the object; nothing is solved yet.
nb.configure(obj, n=4, order=2, align="curvature-max", strength=1.0, live_update=False)
nb.add_constraint(obj, face=0, direction=(0.0, 0.0, 1.0))
result = nb.solve(obj)  # writes the nfield_direction / _smooth / _singularity attributes
print(f"solved {result.num_faces} faces, {len(result.singularities)} singularities, "
      f"attributes: {[a.name for a in obj.data.attributes if a.name.startswith('nfield')]}")

# The operators are the same calls with an undo step (what the panel's buttons run).
bpy.ops.nfield.constraint_add(face=100, direction=(1.0, 0.0, 0.0))
bpy.ops.nfield.solve()
print(obj.nfield.last_message, "| constraints on faces", [c.face for c in obj.nfield.constraints])

if len(sys.argv) > 1 and sys.argv[-1].endswith(".blend"):
    bpy.ops.wm.save_as_mainfile(filepath=sys.argv[-1])
    print("saved", sys.argv[-1])
nb.unregister()  # PyPI bpy 4.5 hangs at exit while an add-on property with an update callback is registered
if bpy.app.version < (4, 3):  # PyPI bpy 4.2 crashes at exit once any add-on registered one (a Blender bug)
    sys.stdout.flush()
    os._exit(0)
