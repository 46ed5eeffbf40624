"""The headless Blender suite (PyPI ``bpy``, every release of the test matrix): installing the add-on.

The suite is split by topic; every file uses the installed, packaged add-on through tests/blender_support.py:

* this file: the zip (a compiled module per Python, bundled libraries, manifest, bl_info), the extension
  install, and the message (not a traceback) when no compiled module matches Blender's Python;
* tests/test_blender_design.py: designing fields through the operators and the scripting API, attributes
  against nfield.core, save/reload, undo, mesh changes, regions, spectral mode;
* tests/test_blender_failures.py: bad input and failures of the core reaching the user as messages, with the
  design left as it was;
* tests/test_blender_mesh_read.py: the mesh reader, the stored design and the layering at run time.
"""
from __future__ import annotations

import importlib
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from blender_support import USER_DIR, bpy, nf  # noqa: F401  (fixtures)

pytestmark = pytest.mark.blender


def test_enabled_from_zip_with_bundled_libraries(nf, addon_zip):
    path = Path(nf.__file__).parent
    assert str(path).startswith(USER_DIR) or "extensions" in str(path)
    assert (path / "blender_manifest.toml").is_file()
    natives = sorted(path.glob("_native*.so"))
    here = path / f"_native.cpython-3{sys.version_info.minor}-x86_64-linux-gnu.so"
    assert here in natives, (here, natives)  # one module per Python the zip was built for
    libs = sorted(p.name for p in (path / "libs").glob("*.so*"))
    assert any(n.startswith("libcholmod") for n in libs), libs
    core = importlib.import_module(nf.__name__ + ".core")
    mod = core.native()
    assert Path(mod.__file__) == here
    # The bundled CHOLMOD is the one the packaged module loads (DT_RPATH $ORIGIN/libs). Checked in a fresh
    # process: in this one, earlier tests may already have loaded the system CHOLMOD through the
    # development tree's module, and the dynamic loader then reuses it by soname.
    probe = (
        "import importlib.util, sys\n"
        f"spec = importlib.util.spec_from_file_location('_native', {str(here)!r})\n"
        "mod = importlib.util.module_from_spec(spec); spec.loader.exec_module(mod)\n"
        "maps = open('/proc/self/maps').read().splitlines()\n"
        "print('\\n'.join(sorted({l.split()[-1] for l in maps if 'libcholmod' in l})))\n"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    cholmod = set(out.split())
    assert cholmod and all(c.startswith(str(path / "libs")) for c in cholmod), cholmod
    for op in ("solve", "write_attributes", "constraint_add", "constraint_remove", "constraint_clear",
               "singularity_add", "singularity_remove", "region_begin", "region_commit", "region_cancel",
               "layer_release", "precompute_spectral"):
        assert hasattr(bpy.ops.nfield, op), op
    with zipfile.ZipFile(addon_zip) as zf:
        names = zf.namelist()
    assert "nfield/__init__.py" in names and "nfield/blender_manifest.toml" in names
    assert not any("__pycache__" in n for n in names)



_MISMATCH_SCRIPT = r"""
import os, sys, json
import bpy, importlib
bpy.ops.extensions.package_install_files(filepath=sys.argv[-1], repo="user_default", enable_on_install=True)
out = {"registered": hasattr(bpy.types.Object, "nfield")}
state = importlib.import_module("bl_ext.user_default.nfield.blender.state")
out["message"] = state.native_problem
bpy.ops.mesh.primitive_cube_add()
try:
    bpy.ops.nfield.solve()
    out["op"] = "no error"
except RuntimeError as exc:
    out["op"] = str(exc)
print("RESULT" + json.dumps(out))
if bpy.app.version < (4, 3):  # bpy 4.2 crashes in its exit destructors (tests/conftest.py: bpy_exit_crashes)
    sys.stdout.flush()
    os._exit(0)
"""


def _other_python_tags() -> list[str]:
    """Two CPython ABI tags that are not this interpreter's (so the mismatch is built from the running Python)."""
    here = sys.version_info.minor
    return [f"cpython-3{minor}-x86_64-linux-gnu" for minor in (here - 2, here + 2)]


def test_zip_carries_a_module_per_python(addon_zip):
    """One zip for every supported Blender: a module per Python ABI (3.11 for Blender 4.2-5.0, 3.13 for 5.1+
    when that interpreter is set up), the shared libraries once, the manifest for 4.2+, bl_info for 3.4."""
    with zipfile.ZipFile(addon_zip) as zf:
        names = zf.namelist()
        manifest = zf.read("nfield/blender_manifest.toml").decode()
        init = zf.read("nfield/__init__.py").decode()
    modules = sorted(n for n in names if re.fullmatch(r"nfield/_native\.cpython-3\d+-x86_64-linux-gnu\.so", n))
    here = f"nfield/_native.cpython-3{sys.version_info.minor}-x86_64-linux-gnu.so"
    assert here in modules, (here, modules)
    assert "nfield/_native.cpython-311-x86_64-linux-gnu.so" in modules, modules
    libs = [n for n in names if n.startswith("nfield/libs/")]
    assert len(libs) == len(set(libs)) and any("libcholmod" in n for n in libs), libs
    assert re.search(r'^blender_version_min = "4\.2\.0"$', manifest, re.M), manifest
    assert re.search(r'^platforms = \["linux-x64"\]$', manifest, re.M), manifest
    assert '"blender": (3, 4, 0)' in init


def test_mismatched_module_gives_message_not_traceback(addon_zip, tmp_path):
    """A package with compiled modules only for other Pythons: enabling works, the panel/operators say which
    Pythons it was built for and which one this is."""
    bad = tmp_path / "nfield-mismatch.zip"
    tags = _other_python_tags()
    with zipfile.ZipFile(addon_zip) as src, zipfile.ZipFile(bad, "w") as dst:
        native = next(i for i in src.infolist() if i.filename.startswith("nfield/_native"))
        for item in src.infolist():
            if not item.filename.startswith("nfield/_native"):
                dst.writestr(item.filename, src.read(item.filename))
        for tag in tags:
            dst.writestr(f"nfield/_native.{tag}.so", src.read(native.filename))
    env = dict(os.environ)  # runs this leg's Python (PyPI bpy), not Debian's Blender
    for k in ("SCRIPTS", "EXTENSIONS", "CONFIG", "DATAFILES"):
        env[f"BLENDER_USER_{k}"] = str(tmp_path / k.lower())
    env.pop("PYTHONPATH", None)
    script = tmp_path / "mismatch.py"
    script.write_text(_MISMATCH_SCRIPT)
    proc = subprocess.run([sys.executable, str(script), str(bad)], env=env, capture_output=True, text=True,
                          timeout=120)
    line = next((l for l in proc.stdout.splitlines() if l.startswith("RESULT")), None)
    assert line and proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    import json

    out = json.loads(line[len("RESULT"):])
    assert out["registered"]
    minor = sys.version_info.minor
    built_for = f"built for Python 3.{minor - 2}, 3.{minor + 2}"
    assert built_for in out["message"] and f"this is Python 3.{minor}" in out["message"], out["message"]
    assert built_for in out["op"], out["op"]
    assert "Traceback" not in proc.stderr
