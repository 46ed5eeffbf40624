"""The packaging metadata agrees with the package: pyproject.toml (what `pip install .` builds) and the Blender
extension's manifest and entry module (addon/extension/, which `build_addon.py package` zips with the wheels).

The builds themselves are legs of `build_addon.py test`: `pip install .` into fresh virtual environments, the
core suite from each repaired wheel with the system libraries hidden, the Blender suites from the zips.
"""
from __future__ import annotations

import ast
import importlib
import re
import tomllib

import nfield
import pytest
from conftest import ROOT

# Reads files of the repository and runs no native code; the sanitizer job's copy of tests/ has neither
# pyproject.toml nor addon/extension beside it, so the files are read by the tests, not at collection.
pytestmark = pytest.mark.no_sanitizer
EXTENSION = ROOT / "addon" / "extension"


def pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_pyproject_builds_this_package():
    config = pyproject()
    tool = config["tool"]["scikit-build"]
    assert tool["wheel"]["packages"] == ["addon/nfield"]
    # the version pip reports is __version__, read by the regex provider from the package's __init__.py
    version = tool["metadata"]["version"]
    assert version["provider"] == "scikit_build_core.metadata.regex"
    assert (ROOT / version["input"]).resolve() == (ROOT / "addon" / "nfield" / "__init__.py").resolve()
    assert re.search(r'^__version__ = "([^"]+)"', (ROOT / version["input"]).read_text(), re.M).group(1) == \
        nfield.__version__
    # one build directory per interpreter ABI, kept: rebuilds compile only what changed
    assert "{wheel_tag}" in tool["build-dir"] and tool["build-dir"].startswith("build/")
    # the pinned pybind11: every build of a Python compiles the same headers (objects reused via ccache)
    assert any(re.fullmatch(r"pybind11==[\d.]+", r) for r in config["build-system"]["requires"])


def test_console_script_is_the_cli(capsys):
    module, _, attr = pyproject()["project"]["scripts"]["nfield"].partition(":")
    main = getattr(importlib.import_module(module), attr)
    assert main is importlib.import_module("nfield.cli").main
    try:
        main(["--help"])
    except SystemExit as exc:  # argparse's --help
        assert exc.code == 0
    assert "usage: nfield" in capsys.readouterr().out


def test_extension_manifest_and_entry_module():
    manifest = tomllib.loads((EXTENSION / "blender_manifest.toml").read_text())
    assert manifest["id"] == "nfield" and manifest["type"] == "add-on"
    assert manifest["version"] == nfield.__version__
    assert manifest["platforms"] == ["linux-x64"]
    assert "wheels" not in manifest  # added by `build_addon.py package`, naming the wheels it built
    # the entry module registers the installed top-level package, whatever Blender names the module itself
    tree = ast.parse((EXTENSION / "__init__.py").read_text())
    functions = {node.name: ast.unparse(node) for node in tree.body if isinstance(node, ast.FunctionDef)}
    assert set(functions) == {"register", "unregister"}
    assert "import nfield" in functions["register"] and "nfield.register()" in functions["register"]
    assert "sys.modules.get('nfield')" in functions["unregister"]
