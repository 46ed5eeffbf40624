"""What every headless Blender test file shares: a fresh user profile, PyPI ``bpy``, the add-on installed from
the extension zip (fixtures ``nf`` and ``scene``) and small helpers.

The extension zip (``build_addon.py package``; the ``extension_zip`` fixture of conftest.py rebuilds it only
when a source is newer) is installed into a temporary user extensions directory and enabled: Blender installs
the wheel matching its Python into the extensions' site-packages and enables the entry module
``bl_ext.user_default.nfield``, which registers the package ``nfield`` from that wheel. The tests use that
installed package, never ``addon/`` (`build_addon.py test` runs this suite with NFIELD_TEST_INSTALLED=1).

bpy can only be imported once per process; tests reset the scene with ``read_factory_settings(use_empty=True)``
(``scene`` fixture) and re-enable the add-on if the reset disabled it. Import this module from a test file
(``from blender_support import nf, scene, ...``); it imports ``bpy``, so such files are listed in
conftest.BLENDER_ONLY_FILES.
"""
from __future__ import annotations

import importlib
import os
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data"

USER_DIR = tempfile.mkdtemp(prefix="nfield-bpy-user-")
if "bpy" not in sys.modules:  # a fresh, empty Blender user profile for this process
    for _k in ("SCRIPTS", "EXTENSIONS", "CONFIG", "DATAFILES"):
        os.environ[f"BLENDER_USER_{_k}"] = os.path.join(USER_DIR, _k.lower())

bpy = pytest.importorskip("bpy", reason="PyPI bpy is not installed in this Python (the headless Blender suite needs it)")


_installed: list = []  # the installed package, once per process (every test file imports the fixture)


EXTENSION = "bl_ext.user_default.nfield"  # the extension's entry module, as Blender names it


def extension_site_packages() -> Path:
    """Where Blender installs the wheels of the extensions in this profile."""
    return Path(USER_DIR, "extensions", ".local", "lib", "python%d.%d" % sys.version_info[:2], "site-packages")


def install_extension(extension_zip: Path):
    """Installs and enables the extension zip in this process's profile (once); returns the package nfield
    that Blender installed from the extension's wheel and registered."""
    if _installed:
        return _installed[0]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    result = bpy.ops.extensions.package_install_files(filepath=str(extension_zip), repo="user_default",
                                                      enable_on_install=True)
    assert result == {"FINISHED"}
    importlib.import_module(EXTENSION)
    pkg = importlib.import_module("nfield")
    assert Path(pkg.__file__).parent == extension_site_packages() / "nfield", pkg.__file__
    importlib.import_module("nfield.blender")
    importlib.import_module("nfield.core")
    assert hasattr(bpy.types.Object, "nfield"), "add-on enabled but Object.nfield is not registered"
    _installed.append(pkg)
    return pkg


@pytest.fixture(scope="session")
def nf(extension_zip):
    """The package nfield that Blender installed from the extension's wheel and registered."""
    return install_extension(extension_zip)


def script_env(nf, profile: Path) -> dict:
    """Environment of a child bpy process that uses the installed package `nf` (first on PYTHONPATH) with an
    empty Blender user profile of its own under `profile`: a child sharing this process's profile would see
    the installed extension, and Blender ending there may tidy the extension's wheel folder away under this
    process's feet."""
    env = dict(os.environ, PYTHONPATH=str(Path(nf.__file__).parent.parent))
    for key in ("SCRIPTS", "EXTENSIONS", "CONFIG", "DATAFILES"):
        env[f"BLENDER_USER_{key}"] = str(Path(profile) / key.lower())
    return env


def run_script(nf, script: Path, out_dir: Path, timeout: float = 300) -> tuple[dict, float]:
    """Runs `python script out_dir` in a fresh process of this Python with the installed package `nf` first on
    PYTHONPATH (a test file run as a script: its own bpy session and user profile). Returns (the JSON of the
    script's last output line, seconds); fails the test with the script's output when it fails."""
    import json
    import subprocess
    import time

    env = script_env(nf, Path(out_dir) / "profile")
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, str(script), str(out_dir)], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=timeout)
    seconds = time.perf_counter() - start
    assert proc.returncode == 0, f"{script.name} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return json.loads(proc.stdout.strip().splitlines()[-1]), seconds


@pytest.fixture
def scene(nf):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if not hasattr(bpy.types.Object, "nfield"):  # factory settings may disable add-ons: enable again
        bpy.ops.preferences.addon_enable(module=EXTENSION)
    assert hasattr(bpy.types.Object, "nfield")
    return nf


def blender_module(nf, name: str):
    """A module of the installed add-on's Blender layer, e.g. blender_module(nf, "session_cache")."""
    return importlib.import_module(f"{nf.__name__}.blender.{name}")


def object_from_arrays(name, V, F):
    """A mesh object from vertex and face arrays, linked and active (no validate(): dirty input stays dirty)."""
    me = bpy.data.meshes.new(name)
    me.from_pydata(np.asarray(V, float).tolist(), [], np.asarray(F, int).tolist())
    obj = bpy.data.objects.new(name, me)
    bpy.context.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    return obj


def import_obj(name: str):
    bpy.ops.wm.obj_import(filepath=str(DATA / name))
    obj = bpy.context.selected_objects[0]
    bpy.context.view_layer.objects.active = obj
    return obj


def attr_array(obj, name: str, domain: str, dtype: str) -> np.ndarray:
    me = obj.data
    a = me.attributes.get(name)
    assert a is not None, f"attribute {name} missing (have {list(me.attributes.keys())})"
    assert a.domain == domain and a.data_type == dtype, (a.domain, a.data_type)
    count = len(me.polygons) if domain == "FACE" else len(me.vertices)
    width = 3 if dtype == "FLOAT_VECTOR" else 1
    buf = np.empty(count * width, dtype=np.float32)
    a.data.foreach_get("vector" if width == 3 else "value", buf)
    return buf.reshape(count, 3) if width == 3 else buf


def poly_normals(obj) -> np.ndarray:
    me = obj.data
    buf = np.empty(len(me.polygons) * 3, dtype=np.float32)
    me.polygons.foreach_get("normal", buf)
    return buf.reshape(-1, 3).astype(np.float64)


def nsym_angle_error(a: np.ndarray, b: np.ndarray, normals: np.ndarray, n: int) -> np.ndarray:
    """Per row: |angle between a and b modulo 2 pi / n| in radians (a, b tangent unit vectors)."""
    ang = np.arctan2(np.einsum("ij,ij->i", np.cross(a, b), normals), np.einsum("ij,ij->i", a, b))
    period = 2 * np.pi / n
    r = np.mod(ang + period / 2, period) - period / 2
    return np.abs(r)


def core_reference(nf, obj, constraints=(), singularities=(), **kw):
    """nfield.core.solve on the same input (the mesh's loop triangulation, polygons as input faces)."""
    core = importlib.import_module(nf.__name__ + ".core")
    arrays = blender_module(nf, "mesh_read").mesh_arrays(obj)
    mesh = core.Mesh(arrays.vertices, arrays.triangles, face_to_polygon=arrays.triangle_polygon,
                     num_polygons=arrays.num_polygons)
    return core.solve(mesh, constraints=list(constraints), singularities=list(singularities), **kw)


def interior_vertex(obj) -> int:
    """A vertex far from everything special: the one closest to the mesh's first polygon's centre."""
    return int(obj.data.polygons[0].vertices[0])

