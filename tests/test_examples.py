"""Every numbered example in examples/ runs from the repository root and succeeds.

The examples check their own claims (constraints met along +d, pinned indices, Poincare-Hopf sums, unit
directions) with assertions, so an example that stops being true fails here. One that imports ``bpy``
runs in the headless Blender legs (marker ``blender``), the others in the core legs; each runs in its own
process with this interpreter. They are marked ``slow`` (about 25 s together, and they exercise code the
unit tests cover): ``build_addon.py test --quick`` and the sanitizer job leave them out.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT, TEST_INSTALLED, package_env

EXAMPLES = sorted(p for p in (ROOT / "examples").iterdir() if p.name[:2].isdigit() and p.suffix in (".py", ".sh"))


def _param(path: Path):
    marks = [pytest.mark.slow] + ([pytest.mark.blender] if "import bpy" in path.read_text() else [])
    return pytest.param(path, id=path.name, marks=marks)


def test_examples_are_numbered_in_order():
    numbers = [int(p.name[:2]) for p in EXAMPLES]
    assert len(EXAMPLES) >= 5 and numbers == list(range(1, len(EXAMPLES) + 1)), [p.name for p in EXAMPLES]


@pytest.mark.parametrize("path", [_param(p) for p in EXAMPLES])
def test_example_runs(path, tmp_path, request):
    if not TEST_INSTALLED:  # an installed nfield always has its compiled module
        pytest.importorskip("nfield._native", reason="compiled module nfield._native is not built")
    env = dict(package_env(), PYTHON=sys.executable)
    if "import bpy" in path.read_text():  # an empty Blender user profile: no installed copy of the add-on
        for key in ("SCRIPTS", "EXTENSIONS", "CONFIG", "DATAFILES"):
            env[f"BLENDER_USER_{key}"] = str(tmp_path / key.lower())
        if TEST_INSTALLED:  # the package Blender installed from the extension zip (tests/blender_support.py)
            from blender_support import install_extension

            installed = install_extension(request.getfixturevalue("extension_zip"))
            env["PYTHONPATH"] = str(Path(installed.__file__).parents[1])
    cmd = ["sh", str(path)] if path.suffix == ".sh" else [sys.executable, str(path)]
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    print(proc.stdout[-3000:])
    assert proc.returncode == 0, f"{path.name} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    assert "Traceback" not in proc.stderr
