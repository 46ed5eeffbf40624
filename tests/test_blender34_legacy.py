"""The legacy add-on zip (bl_info, Install... in Preferences) in Debian's Blender 3.4.1.

Blender 3.4 runs Debian's system Python 3.11; the legacy zip is the 3.11 wheel's nfield/ and nfield.libs/
(the libraries auditwheel bundled), so the test checks that Blender 3.4 loads the module built for its own
interpreter (asked from that Blender, not assumed) and CHOLMOD from nfield.libs/.
"""
from __future__ import annotations

import os
import subprocess

import pytest

from conftest import system_blender_env

pytestmark = pytest.mark.gui
BLENDER34 = os.environ.get("NFIELD_GUI_BLENDER", "/usr/bin/blender")

_LEGACY_SCRIPT = r"""
import sys, bpy, addon_utils
bpy.ops.preferences.addon_install(filepath=sys.argv[-1])
addon_utils.enable("nfield", default_set=True)
import nfield.blender as nb
obj = bpy.data.objects["Cube"]
bpy.context.view_layer.objects.active = obj
nb.add_constraint(obj, 0, (1, 0, 0))
r = nb.solve(obj, n=4)
assert bpy.ops.nfield.solve() == {"FINISHED"}
a = obj.data.attributes["nfield_direction"]
import nfield.core as core
loaded = core.native().__file__.rsplit("/", 1)[-1]
maps = open("/proc/self/maps").read().splitlines()
cholmod = sorted({l.split()[-1] for l in maps if "libcholmod" in l})
print("CHOLMOD", *cholmod)
print("RESULT", r.num_faces, len(r.singularities), a.domain, a.data_type, "%d%d" % sys.version_info[:2], loaded,
      bpy.app.version_string)
"""


def test_legacy_install_in_blender_34(legacy_zip, tmp_path):
    """The legacy zip installs as a legacy add-on (bl_info) in Debian's Blender 3.4.1 and solves, with the
    libraries bundled in it."""
    if not os.path.exists(BLENDER34):
        print(f"SKIP: Debian Blender not found at {BLENDER34}")
        pytest.skip(f"Debian Blender not found at {BLENDER34} (apt-get install blender)")
    script = tmp_path / "legacy.py"
    script.write_text(_LEGACY_SCRIPT)
    env = system_blender_env()
    env["BLENDER_USER_SCRIPTS"] = str(tmp_path / "scripts")
    env["BLENDER_USER_CONFIG"] = str(tmp_path / "config")
    env.pop("PYTHONPATH", None)
    proc = subprocess.run([BLENDER34, "-b", "--factory-startup", "--python-exit-code", "1", "--python", str(script),
                           "--", str(legacy_zip)], env=env, capture_output=True, text=True, timeout=180)
    line = next((l for l in proc.stdout.splitlines() if l.startswith("RESULT")), None)
    assert proc.returncode == 0 and line, proc.stdout[-3000:] + proc.stderr[-3000:]
    _, faces, sings, domain, dtype, python_tag, loaded, version = line.split(maxsplit=7)
    assert (faces, sings, domain, dtype) == ("6", "8", "FACE", "FLOAT_VECTOR")
    assert version.startswith("3.4")
    # it loaded the module built for its own Python, and CHOLMOD from the bundled libraries (nfield.libs/)
    assert f"cpython-{python_tag}" in loaded, loaded
    cholmod = next(l for l in proc.stdout.splitlines() if l.startswith("CHOLMOD")).split()[1:]
    assert cholmod and all("/addons/nfield.libs/libcholmod" in c for c in cholmod), cholmod
