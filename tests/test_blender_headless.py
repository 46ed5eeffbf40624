"""The headless Blender suite (PyPI ``bpy``, every release of the test matrix): installing the add-on.

The suite is split by topic; every file uses the installed extension through tests/blender_support.py:

* this file: the extension zip (the manifest listing a repaired wheel per Python, the entry module), what
  Blender installs from it, and Blender's refusal, with a message, of a zip without a wheel for its Python;
* tests/test_blender_design.py: designing fields through the operators and the scripting API, attributes
  against nfield.core, save/reload, undo, mesh changes, regions, spectral mode;
* tests/test_blender_failures.py: bad input and failures of the core reaching the user as messages, with the
  design left as it was;
* tests/test_blender_mesh_read.py: the mesh reader, the stored design and the layering at run time.
"""
from __future__ import annotations

import io
import json
import os
import re
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest
from blender_support import EXTENSION, bpy, extension_site_packages, nf  # noqa: F401  (fixtures)

pytestmark = pytest.mark.blender

HERE = "cp3%d" % sys.version_info.minor  # this Python's wheel tag


def test_extension_installs_the_wheel_for_this_python(nf, extension_zip):
    """Blender installed nfield from the wheel matching its Python into the extensions' site-packages: the
    compiled module for this Python, and CHOLMOD from the libraries auditwheel bundled (nfield.libs/)."""
    site = extension_site_packages()
    assert Path(nf.__file__).parent == site / "nfield"
    installed = [p.name for p in site.glob("nfield-*.dist-info")]
    assert len(installed) == 1, installed  # one wheel of the zip's two: the other is for another Python
    core = sys.modules[nf.__name__ + ".core"]
    assert Path(core.native().__file__).parent == site / "nfield"
    assert core.native().__file__.endswith(f".cpython-3{sys.version_info.minor}-x86_64-linux-gnu.so")
    # Checked in a fresh process (this one may have loaded a system CHOLMOD earlier, and the loader reuses a
    # library by soname): importing the installed package maps the bundled CHOLMOD only.
    probe = ("import sys, nfield.core\nnfield.core.native()\n"
             "maps = open('/proc/self/maps').read().splitlines()\n"
             "print('\\n'.join(sorted({l.split()[-1] for l in maps if 'libcholmod' in l})))\n")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(site)
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True, env=env).stdout
    cholmod = out.split()
    assert cholmod and all(c.startswith(str(site / "nfield.libs") + "/libcholmod") for c in cholmod), cholmod
    for op in ("solve", "write_attributes", "constraint_add", "constraint_remove", "constraint_clear",
               "singularity_add", "singularity_remove", "region_begin", "region_commit", "region_cancel",
               "layer_release", "precompute_spectral"):
        assert hasattr(bpy.ops.nfield, op), op
    assert EXTENSION in bpy.context.preferences.addons


def test_zip_lists_a_wheel_per_python(extension_zip):
    """One zip for Blender 4.2 and later: blender_manifest.toml lists a manylinux wheel per Python ABI (3.11 for
    Blender 4.2-5.0, 3.13 for 5.1+ when that interpreter is set up), each carrying its compiled module and the
    libraries it needs; the entry module and no bytecode."""
    with zipfile.ZipFile(extension_zip) as zf:
        names = zf.namelist()
        manifest = tomllib.loads(zf.read("blender_manifest.toml").decode())
        wheels = {n: zf.read(n) for n in names if n.endswith(".whl")}
    assert "__init__.py" in names and not any("__pycache__" in n for n in names)
    assert manifest["blender_version_min"] == "4.2.0" and manifest["platforms"] == ["linux-x64"]
    assert sorted(manifest["wheels"]) == sorted("./" + n for n in wheels), (manifest["wheels"], list(wheels))
    tags = {}
    for name, data in wheels.items():
        m = re.fullmatch(r"wheels/nfield-[\d.]+-(cp3\d+)-\1-manylinux_\d+_\d+_x86_64\.whl", name)
        assert m, name
        tags[m.group(1)] = name
        with zipfile.ZipFile(io.BytesIO(data)) as whl:
            inside = whl.namelist()
        assert f"nfield/_native.cpython-{m.group(1)[2:]}-x86_64-linux-gnu.so" in inside, name
        assert any(n.startswith("nfield.libs/libcholmod") for n in inside), name
        assert "nfield/blender/__init__.py" in inside and "nfield/core/__init__.py" in inside, name
    assert "cp311" in tags and HERE in tags, tags


_INSTALL_SCRIPT = r"""
import os, sys, json
import bpy
out = {}
try:
    out["result"] = sorted(bpy.ops.extensions.package_install_files(filepath=sys.argv[-1], repo="user_default",
                                                                    enable_on_install=True))
except RuntimeError as exc:
    out["error"] = str(exc)
out["registered"] = hasattr(bpy.types.Object, "nfield")
print("RESULT" + json.dumps(out))
sys.stdout.flush()
if bpy.app.version < (4, 3):  # bpy 4.2 crashes in its exit destructors (tests/conftest.py: bpy_exit_crashes)
    os._exit(0)
"""


def test_zip_without_a_wheel_for_this_python_is_refused(extension_zip, tmp_path):
    """A zip whose wheels are all for other Pythons: Blender refuses it with a message naming the Python
    versions, registers nothing, and nothing crashes."""
    other = "cp3%d" % (sys.version_info.minor - 2)
    bad = tmp_path / "nfield-other-python.zip"
    with zipfile.ZipFile(extension_zip) as src, zipfile.ZipFile(bad, "w") as dst:
        for item in src.infolist():
            if item.filename.endswith(".whl"):
                continue
            data = src.read(item.filename)
            if item.filename == "blender_manifest.toml":
                data = re.sub(rb"wheels = \[.*\]", b'wheels = ["./wheels/nfield-0.1.0-%s-%s-manylinux_2_34_x86_64.whl"]'
                              % (other.encode(), other.encode()), data)
            dst.writestr(item.filename, data)
        wheel = next(n for n in src.namelist() if n.endswith(".whl"))
        dst.writestr(f"wheels/nfield-0.1.0-{other}-{other}-manylinux_2_34_x86_64.whl", src.read(wheel))
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # this leg's Python (PyPI bpy)
    for k in ("SCRIPTS", "EXTENSIONS", "CONFIG", "DATAFILES"):
        env[f"BLENDER_USER_{k}"] = str(tmp_path / k.lower())
    script = tmp_path / "install.py"
    script.write_text(_INSTALL_SCRIPT)
    proc = subprocess.run([sys.executable, str(script), str(bad)], env=env, capture_output=True, text=True,
                          timeout=120)
    line = next((l for l in proc.stdout.splitlines() if l.startswith("RESULT")), None)
    assert line and proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    out = json.loads(line[len("RESULT"):])
    print(out)
    assert not out["registered"] and out.get("result") != ["FINISHED"], out
    here = "%d.%d" % sys.version_info[:2]
    assert "Python" in out.get("error", "") and here in out["error"], out
    assert "Traceback" not in proc.stderr
