"""The Blender add-on, headless, in PyPI ``bpy`` 5.0.1 (and a smoke run in Debian's Blender 3.4.1).

The add-on is installed from the packaged zip (``build_addon.py package``, rebuilt only when a source is
newer than the zip) into a temporary user extensions directory and enabled as an extension; everything below
uses that installed copy (``bl_ext.user_default.nfield``), never ``addon/`` (two copies of the compiled module
in one process would clash).

bpy can only be imported once per process; tests reset the scene with ``read_factory_settings(use_empty=True)``
and re-enable nothing (add-on registration survives factory resets of the scene data only when it is kept
enabled, so each test re-checks ``bpy.types.Object.nfield``).
"""
from __future__ import annotations

import importlib
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest


ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data"

_USER_DIR = tempfile.mkdtemp(prefix="nfield-bpy-user-")
if "bpy" not in sys.modules:  # a fresh, empty Blender user profile for this process
    for _k in ("SCRIPTS", "EXTENSIONS", "CONFIG", "DATAFILES"):
        os.environ[f"BLENDER_USER_{_k}"] = os.path.join(_USER_DIR, _k.lower())

pytestmark = pytest.mark.blender
bpy = pytest.importorskip("bpy", reason="PyPI bpy is not installed in this Python (the headless Blender suite needs it)")
import bmesh  # noqa: E402  (after bpy)


# ------------------------------------------------------------------------------------------ fixtures
@pytest.fixture(scope="session")
def nf(addon_zip):
    """The installed, enabled add-on package (module bl_ext.user_default.nfield)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    result = bpy.ops.extensions.package_install_files(filepath=str(addon_zip), repo="user_default",
                                                      enable_on_install=True)
    assert result == {"FINISHED"}
    pkg = importlib.import_module("bl_ext.user_default.nfield")
    importlib.import_module("bl_ext.user_default.nfield.blender")
    importlib.import_module("bl_ext.user_default.nfield.core")
    assert hasattr(bpy.types.Object, "nfield"), "add-on enabled but Object.nfield is not registered"
    return pkg


@pytest.fixture
def scene(nf):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if not hasattr(bpy.types.Object, "nfield"):  # factory settings may disable add-ons: enable again
        bpy.ops.preferences.addon_enable(module="bl_ext.user_default.nfield")
    assert hasattr(bpy.types.Object, "nfield")
    return nf


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
    sc = importlib.import_module(nf.__name__ + ".blender.session_cache")
    arrays = sc.mesh_arrays(obj)
    mesh = core.Mesh(arrays.vertices, arrays.triangles, face_to_polygon=arrays.triangle_polygon,
                     num_polygons=arrays.num_polygons)
    return core.solve(mesh, constraints=list(constraints), singularities=list(singularities), **kw)


def interior_vertex(obj) -> int:
    """A vertex far from everything special: the one closest to the mesh's first polygon's centre."""
    return int(obj.data.polygons[0].vertices[0])


# ------------------------------------------------------------------------------------------ tests
def test_enabled_from_zip_with_bundled_libraries(nf, addon_zip):
    path = Path(nf.__file__).parent
    assert str(path).startswith(_USER_DIR) or "extensions" in str(path)
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


#: the mesh of the design-a-field check: any triangle mesh file nfield reads (NFIELD_CHECK_MESH), by default one
#: no other Blender test uses (the double torus: genus 2, 11k faces)
CHECK_MESH = Path(os.environ.get("NFIELD_CHECK_MESH", str(DATA / "eight.off")))


def test_design_on_a_new_mesh_matches_core(scene):
    """Installed from the zip, the add-on designs a field (direction constraints, a singularity, curvature
    alignment) on a mesh no other Blender test uses, and the face attribute equals nfield.core.solve's result
    to 1e-4 degrees. The attribute is float32: its directions are within ~1e-7 rad (6e-6 deg) of the double
    precision result, far below the bound; a different solve (settings, constraint lost) is off by degrees."""
    nf = scene
    core = importlib.import_module(nf.__name__ + ".core")
    mesh = core.Mesh.from_file(CHECK_MESH)
    obj = _object_from_arrays(CHECK_MESH.stem, mesh.vertices, mesh.faces)
    st = obj.nfield
    st.live_update = False
    st.symmetry, st.energy, st.alignment, st.strength = "4", "BIHARMONIC", "CURVATURE_MAX", 0.3
    faces = len(obj.data.polygons)
    picks = [faces // 7, (3 * faces) // 5]
    directions = []
    normals = poly_normals(obj)
    for face, raw in zip(picks, ((1.0, 0.2, 0.1), (0.1, 0.3, 1.0))):
        t = np.asarray(raw) - normals[face] * (normals[face] @ np.asarray(raw))  # a tangent direction
        directions.append(tuple(t / np.linalg.norm(t)))
        assert bpy.ops.nfield.constraint_add(face=face, direction=directions[-1]) == {"FINISHED"}
    session = core.DesignSession(mesh, n=4, order=2, align="curvature-max", strength=0.3)
    vertex = int(mesh.faces[faces // 3][0])
    low, high = session.index_range(vertex)
    index = 0.25 if low < 0.25 < high else -0.25
    assert bpy.ops.nfield.singularity_add(vertex=vertex, numerator=int(index * 4)) == {"FINISHED"}
    assert bpy.ops.nfield.solve() == {"FINISHED"}

    d = attr_array(obj, st.direction_attribute, "FACE", "FLOAT_VECTOR").astype(np.float64)
    ref = core.solve(mesh, n=4, order=2, align="curvature-max", strength=0.3,
                     constraints=[core.DirectionConstraint(f, t) for f, t in zip(picks, directions)],
                     singularities=[core.SingularityConstraint(vertex, index)])
    err = np.degrees(nsym_angle_error(d, ref.directions, normals, 4))
    print(f"{CHECK_MESH.name}: {faces} faces, max difference to nfield.core.solve {err.max():.2e} deg")
    assert err.max() < 1e-4, f"{err.max()} deg"
    for face, t in zip(picks, directions):
        assert np.degrees(nsym_angle_error(d[face:face + 1], np.asarray([t]), normals[face:face + 1], 4))[0] < 1e-4
    sing = attr_array(obj, st.singularity_attribute, "POINT", "FLOAT")
    assert sing[vertex] == pytest.approx(index)


def test_operators_attributes_match_core(scene):
    nf = scene
    obj = import_obj("fandisk.obj")
    st = obj.nfield
    st.live_update = False
    st.symmetry = "4"
    st.energy = "BIHARMONIC"
    st.alignment = "CURVATURE_MAX"
    st.strength = 0.5
    v = interior_vertex(obj)
    assert bpy.ops.nfield.constraint_add(face=100, direction=(1.0, 0.0, 0.0)) == {"FINISHED"}
    assert bpy.ops.nfield.constraint_add(face=5000, direction=(0.0, 1.0, 0.0)) == {"FINISHED"}
    assert bpy.ops.nfield.constraint_add(face=6000, direction=(0.6, 0.3, 0.74), kind="DIRECTION") == {"FINISHED"}
    assert [c.face for c in st.constraints] == [100, 5000, 6000]
    assert bpy.ops.nfield.constraint_remove(face=6000) == {"FINISHED"}
    assert bpy.ops.nfield.singularity_add(vertex=v, numerator=1) == {"FINISHED"}
    assert bpy.ops.nfield.solve() == {"FINISHED"}

    n = 4
    normals = poly_normals(obj)
    d = attr_array(obj, st.direction_attribute, "FACE", "FLOAT_VECTOR").astype(np.float64)
    assert d.shape == (len(obj.data.polygons), 3)
    assert np.abs(np.linalg.norm(d, axis=1) - 1).max() < 1e-5
    assert np.abs(np.einsum("ij,ij->i", d, normals)).max() < 1e-5

    core = importlib.import_module(nf.__name__ + ".core")
    ref = core_reference(nf, obj, [core.DirectionConstraint(100, (1.0, 0.0, 0.0)),
                                   core.DirectionConstraint(5000, (0.0, 1.0, 0.0))],
                         [core.SingularityConstraint(v, 0.25)], n=4, order=2, align="curvature-max",
                         strength=0.5)
    err = nsym_angle_error(d, ref.directions, normals, n)
    assert err.max() < 1e-6, f"max angle difference to nfield.core.solve: {err.max()}"
    # the hard constraints hold
    for face, direction in ((100, (1.0, 0.0, 0.0)), (5000, (0.0, 1.0, 0.0))):
        t = np.asarray(direction) - normals[face] * (normals[face] @ np.asarray(direction))
        t /= np.linalg.norm(t)
        assert nsym_angle_error(d[face:face + 1], t[None], normals[face:face + 1], n)[0] < 1e-5

    smooth = attr_array(obj, st.smooth_attribute, "POINT", "FLOAT_VECTOR")
    lengths = np.linalg.norm(smooth, axis=1)
    assert np.all((np.abs(lengths - 1) < 1e-5) | (lengths == 0))
    assert (lengths > 0).mean() > 0.99
    sing = attr_array(obj, st.singularity_attribute, "POINT", "FLOAT")
    assert sing[v] == pytest.approx(0.25)
    nonzero = {int(i): float(sing[i]) for i in np.flatnonzero(sing)}
    assert nonzero == {vv: pytest.approx(ii) for vv, ii in ref.singularities}

    # write_attributes with other names; removal operators
    st.direction_attribute = "my_dir"
    assert bpy.ops.nfield.write_attributes() == {"FINISHED"}
    assert np.allclose(attr_array(obj, "my_dir", "FACE", "FLOAT_VECTOR"), d, atol=1e-7)
    assert bpy.ops.nfield.singularity_remove(vertex=v) == {"FINISHED"}
    assert len(st.singularities) == 0
    assert bpy.ops.nfield.constraint_clear() == {"FINISHED"}
    assert len(st.constraints) == 0


def test_scripting_api_and_live_update(scene):
    nf = scene
    nb = importlib.import_module(nf.__name__ + ".blender")
    obj = import_obj("sphere.obj")
    nb.add_constraint(obj, 3, (1, 0, 0))
    nb.add_constraint(obj, 3, (0, 1, 0))  # re-aims, no duplicate
    assert len(obj.nfield.constraints) == 1 and tuple(obj.nfield.constraints[0].direction) == (0, 1, 0)
    nb.configure(obj, n=2)
    nb.add_singularity(obj, 10, 0.5)  # stored as numerator 1: index = numerator / n (the current n)
    r = nb.solve(obj, n=2, order=3, align="none")
    assert obj.nfield.symmetry == "2" and obj.nfield.energy == "TRIHARMONIC"
    assert r.directions.shape == (1280, 3) and r.n == 2
    assert (10, pytest.approx(0.5)) in [(v, i) for v, i in r.singularities]
    assert nb.field(obj) is r
    # live update: an edit operator re-solves and rewrites the attribute
    obj.nfield.live_update = True
    before = attr_array(obj, "nfield_direction", "FACE", "FLOAT_VECTOR").copy()
    assert bpy.ops.nfield.constraint_add(face=3, direction=(0.3, 0.0, 1.0)) == {"FINISHED"}
    after = attr_array(obj, "nfield_direction", "FACE", "FLOAT_VECTOR")
    assert not np.allclose(before, after)
    # API errors name the problem
    with pytest.raises(ValueError, match="out of range"):
        nb.add_constraint(obj, 99999, (1, 0, 0))
    with pytest.raises(ValueError, match="not a multiple of 1/2"):
        nb.add_singularity(obj, 5, 0.25)
    with pytest.raises(ValueError, match="parallel to the face normal"):
        nb.add_constraint(obj, 0, tuple(obj.data.polygons[0].normal))
    with pytest.raises(ValueError, match="n must be one of"):
        nb.solve(obj, n=5)


def test_quads_ngons_and_transforms(scene):
    nf = scene
    nb = importlib.import_module(nf.__name__ + ".blender")
    bpy.ops.mesh.primitive_cylinder_add(vertices=16, depth=2.0, end_fill_type="NGON")
    cyl = bpy.context.active_object
    bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12, location=(4, 0, 0))
    uvs = bpy.context.active_object
    for obj in (cyl, uvs):
        me = obj.data
        sizes = {len(p.vertices) for p in me.polygons}
        assert max(sizes) >= 4
        nb.add_constraint(obj, 0, (0.0, 0.0, 1.0) if obj is cyl else (1.0, 0.0, 0.0))
        r = nb.solve(obj, n=4, order=2)
        d = attr_array(obj, "nfield_direction", "FACE", "FLOAT_VECTOR").astype(np.float64)
        normals = poly_normals(obj)
        assert d.shape[0] == len(me.polygons) == r.directions.shape[0]
        assert np.abs(np.linalg.norm(d, axis=1) - 1).max() < 1e-5
        assert np.abs(np.einsum("ij,ij->i", d, normals)).max() < 1e-5
        core = importlib.import_module(nf.__name__ + ".core")
        ref = core_reference(nf, obj, [core.DirectionConstraint(0, tuple(obj.nfield.constraints[0].direction))],
                             n=4, order=2)
        assert nsym_angle_error(d, ref.directions, normals, 4).max() < 1e-5
    # transforms: a rotated, non-uniformly scaled copy gets the same object-space attributes
    base = attr_array(uvs, "nfield_direction", "FACE", "FLOAT_VECTOR").copy()
    copy = uvs.copy()
    copy.data = uvs.data.copy()
    bpy.context.collection.objects.link(copy)
    copy.rotation_euler = (0.3, 1.1, -0.4)
    copy.scale = (1.0, 3.0, 0.5)
    bpy.context.view_layer.update()
    nb.solve(copy)
    assert np.allclose(attr_array(copy, "nfield_direction", "FACE", "FLOAT_VECTOR"), base, atol=1e-6)
    # modifiers are ignored (base mesh)
    copy.modifiers.new("sub", "SUBSURF")
    nb.solve(copy)
    assert attr_array(copy, "nfield_direction", "FACE", "FLOAT_VECTOR").shape == base.shape


def test_save_reload_keeps_design(scene, tmp_path):
    nf = scene
    nb = importlib.import_module(nf.__name__ + ".blender")
    obj = import_obj("sphere.obj")
    nb.configure(obj, n=6, order=1, align="curvature-min", strength=2.0)
    nb.add_constraint(obj, 7, (1, 0, 0))
    nb.add_constraint(obj, 70, (0, 0, 1), kind="vector")
    nb.add_singularity(obj, 12, -1 / 6)
    obj.nfield.direction_attribute = "dir6"
    nb.solve(obj)
    before = attr_array(obj, "dir6", "FACE", "FLOAT_VECTOR").copy()
    path = tmp_path / "design.blend"
    assert bpy.ops.wm.save_as_mainfile(filepath=str(path)) == {"FINISHED"}
    bpy.ops.wm.read_homefile(use_empty=True)  # another file in between (keeps the enabled add-on)
    assert "sphere" not in bpy.data.objects
    assert bpy.ops.wm.open_mainfile(filepath=str(path)) == {"FINISHED"}
    obj = bpy.data.objects["sphere"]
    st = obj.nfield
    assert (st.symmetry, st.energy, st.alignment, st.strength) == ("6", "HARMONIC", "CURVATURE_MIN", 2.0)
    assert [(c.face, tuple(c.direction), c.kind, c.stale) for c in st.constraints] == [
        (7, (1.0, 0.0, 0.0), "DIRECTION", False), (70, (0.0, 0.0, 1.0), "VECTOR", False)]
    assert [(s.vertex, s.numerator) for s in st.singularities] == [(12, -1)]
    assert nb.field(obj) is None  # sessions are not saved; rebuilt on demand
    r = nb.solve(obj)
    assert np.allclose(attr_array(obj, "dir6", "FACE", "FLOAT_VECTOR"), before, atol=1e-6)
    assert (12, pytest.approx(-1 / 6)) in r.singularities


def test_undo_redo(scene):
    nb = importlib.import_module(scene.__name__ + ".blender")
    obj = import_obj("sphere.obj")
    obj.nfield.live_update = True
    nb.solve(obj)
    bpy.ops.ed.undo_push(message="start")
    assert bpy.ops.nfield.constraint_add(face=11, direction=(1, 0, 0)) == {"FINISHED"}
    bpy.ops.ed.undo_push(message="add constraint")
    attr_after = attr_array(obj, "nfield_direction", "FACE", "FLOAT_VECTOR").copy()
    assert bpy.ops.ed.undo() == {"FINISHED"}
    obj = bpy.data.objects["sphere"]
    assert len(obj.nfield.constraints) == 0
    assert not np.allclose(attr_array(obj, "nfield_direction", "FACE", "FLOAT_VECTOR"), attr_after)
    # the in-memory session follows the restored design (undo handler re-solved without the constraint)
    r = nb.field(obj)
    assert r is not None
    assert bpy.ops.ed.redo() == {"FINISHED"}
    obj = bpy.data.objects["sphere"]
    assert [c.face for c in obj.nfield.constraints] == [11]
    assert np.allclose(attr_array(obj, "nfield_direction", "FACE", "FLOAT_VECTOR"), attr_after, atol=1e-6)
    for cls_name in ("NFIELD_OT_constraint_add", "NFIELD_OT_solve", "NFIELD_OT_singularity_add",
                     "NFIELD_OT_region_begin"):
        assert "UNDO" in getattr(bpy.types, cls_name).bl_options


def test_topology_change_remaps_or_flags_constraints(scene):
    nb = importlib.import_module(scene.__name__ + ".blender")
    obj = import_obj("sphere.obj")
    nb.add_constraint(obj, 5, (1, 0, 0))
    nb.add_constraint(obj, 600, (0, 1, 0))
    nb.add_constraint(obj, 1200, (0, 0, 1))
    nb.add_singularity(obj, 600, 0.25)
    nb.solve(obj)
    c5 = tuple(obj.data.polygons[5].center)
    c1200 = tuple(obj.data.polygons[1200].center)
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bm.faces.ensure_lookup_table()
    bmesh.ops.delete(bm, geom=[bm.faces[i] for i in (2, 3, 600)], context="FACES")
    bm.to_mesh(obj.data)
    bm.free()
    obj.data.update()
    r = nb.solve(obj)  # must not fail: the stale constraint is ignored
    st = obj.nfield
    assert len(st.constraints) == 3, "no constraint may be dropped"
    by_dir = {tuple(c.direction): c for c in st.constraints}
    kept = by_dir[(1.0, 0.0, 0.0)]  # faces 2 and 3 before it were deleted: 5 -> 3, found by its centroid
    assert not kept.stale and kept.face == 3
    assert np.allclose(tuple(obj.data.polygons[kept.face].center), c5, atol=1e-6)
    moved = by_dir[(0.0, 0.0, 1.0)]
    assert not moved.stale and moved.face == 1197
    assert np.allclose(tuple(obj.data.polygons[moved.face].center), c1200, atol=1e-6)
    assert by_dir[(0.0, 1.0, 0.0)].stale  # its face was deleted
    assert "constraint on face 600" in nb.stale_items(obj)
    assert r.directions.shape[0] == len(obj.data.polygons) == 1277
    assert st.num_stale >= 1 and "stale" in st.last_message
    # the singularity's vertex still exists (only faces were deleted) -> kept
    assert [s.vertex for s in st.singularities] == [600] and not st.singularities[0].stale
    assert bpy.ops.nfield.constraint_clear(stale_only=True) == {"FINISHED"}
    assert len(st.constraints) == 2


def test_regions(scene):
    nf = scene
    nb = importlib.import_module(nf.__name__ + ".blender")
    sc = importlib.import_module(nf.__name__ + ".blender.session_cache")
    obj = import_obj("sphere.obj")
    nb.solve(obj)
    before = nb.field(obj).directions.copy()
    assert bpy.ops.nfield.region_begin(faces="0-39") == {"FINISHED"}
    assert obj.nfield.region_active
    nb.add_constraint(obj, 10, (0, 0, 1))
    r = nb.solve(obj)
    outside = np.arange(40, 1280)
    assert np.array_equal(r.directions[outside], before[outside])
    assert bpy.ops.nfield.region_commit() == {"FINISHED"}
    assert len(obj.nfield.layers) == 1 and len(obj.nfield.layers[0].faces) == 40
    assert bpy.ops.nfield.layer_release(index=0) == {"FINISHED"}
    assert bpy.ops.nfield.region_begin(faces="0-9") == {"FINISHED"}
    with pytest.raises(ValueError, match="outside the region"):
        nb.add_constraint(obj, 500, (1, 0, 0)) and nb.solve(obj)
    obj.nfield.constraints.remove(len(obj.nfield.constraints) - 1)
    nb.add_constraint(obj, 5, (0, 1, 0))
    field_before = nb.field(obj).directions.copy()
    nb.solve(obj)
    assert bpy.ops.nfield.region_cancel() == {"FINISHED"}
    assert not obj.nfield.region_active
    assert [c.face for c in obj.nfield.constraints] == [10]  # the region's constraint went with it
    assert np.array_equal(nb.field(obj).directions, field_before)


def test_spectral_mode(scene, tmp_path, monkeypatch):
    """Spectral mode through the add-on: Precompute (blocking execute path; the modal worker-thread path
    runs in the real-window test), the result equals nfield.core's spectral session on the same input, a
    live strength change keeps the basis and the reduced solver, a cancelled precompute leaves settings and
    field as they were, the disk cache serves a second object, exact <-> spectral switches keep the session,
    and a UI-triggered solve never computes a basis in the UI thread."""
    nf = scene
    monkeypatch.setenv("NFIELD_CACHE_DIR", str(tmp_path / "bases"))
    nb = importlib.import_module(nf.__name__ + ".blender")
    sc = importlib.import_module(nf.__name__ + ".blender.session_cache")
    core = importlib.import_module(nf.__name__ + ".core")
    obj = import_obj("sphere.obj")  # 1,280 faces: the iterative eigen solver
    nb.add_constraint(obj, 3, (1, 0, 0))
    nb.add_constraint(obj, 700, (0, 0, 1))
    assert bpy.ops.nfield.precompute_spectral(k=30) == {"FINISHED"}
    st = obj.nfield
    assert st.solver_mode == "SPECTRAL" and st.spectral_k == 30 and st.spectral_ready
    res = nb.field(obj)
    assert res.mode == "spectral" and res.basis_size == 30
    session = sc.get_entry(obj).session
    assert session.basis_info.source == "computed" and session.basis_info.path.parent == tmp_path / "bases"

    arrays = sc.mesh_arrays(obj)
    mesh = core.Mesh(arrays.vertices, arrays.triangles, face_to_polygon=arrays.triangle_polygon,
                     num_polygons=arrays.num_polygons)
    ref = core.DesignSession(mesh, n=4, order=2, mode="spectral", k=30, cache_dir=tmp_path / "bases")
    for c in session.constraints:
        ref.set_direction(c.face, c.direction)
    expected = ref.solve()
    assert ref.basis_info.source == "cache"
    got = attr_array(obj, st.direction_attribute, "FACE", "FLOAT_VECTOR").astype(np.float64)
    err = nsym_angle_error(got / np.linalg.norm(got, axis=1)[:, None], expected.directions,
                           poly_normals(obj), 4)
    assert err.max() < 1e-3, err.max()  # float32 attribute vs float64 core result

    reduced = session._reduced
    nb.configure(obj, strength=4.0, align="curvature-max")
    r1 = nb.solve(obj)
    nb.configure(obj, strength=0.5)
    r2 = nb.solve(obj)
    assert sc.get_entry(obj).session is session and session._reduced is not None
    reduced = session._reduced
    nb.configure(obj, strength=2.0)
    nb.solve(obj)
    assert session._reduced is reduced  # strength is live: no new solver, no new basis
    assert not np.allclose(r1.raw_solution, r2.raw_solution)

    before = nb.field(obj)
    with pytest.raises(Exception, match="[Cc]ancel"):
        nb.precompute_spectral(obj, k=60, progress=lambda fraction: False)
    assert st.solver_mode == "SPECTRAL" and st.spectral_k == 30 and nb.field(obj) is before

    other = import_obj("sphere.obj")
    other.location.x += 3
    assert bpy.ops.nfield.precompute_spectral(k=30) == {"FINISHED"}
    assert sc.get_entry(other).session.basis_info.source == "cache"

    bpy.context.view_layer.objects.active = obj
    nb.configure(obj, mode="exact")
    assert nb.solve(obj).mode == "exact" and sc.get_entry(obj).session is session
    nb.configure(obj, mode="spectral")
    assert nb.solve(obj).mode == "spectral" and session._reduced is reduced

    # a UI edit asking for a basis that is neither in memory nor cached does not solve (no freeze)
    solved = nb.field(obj)
    st.spectral_k = 45  # property update callback with live update on
    assert nb.field(obj) is solved and "Precompute" in st.last_message
    assert not sc.get_entry(obj).session.basis_available()


def test_bad_states_give_messages(scene):
    bpy.context.view_layer.objects.active = None
    with pytest.raises(RuntimeError, match="No active object"):
        bpy.ops.nfield.solve()
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    bpy.context.collection.objects.link(cam)
    bpy.context.view_layer.objects.active = cam
    with pytest.raises(RuntimeError, match="not a mesh"):
        bpy.ops.nfield.constraint_add(face=0, direction=(1, 0, 0))
    empty = bpy.data.objects.new("Empty", bpy.data.meshes.new("EmptyMesh"))
    bpy.context.collection.objects.link(empty)
    bpy.context.view_layer.objects.active = empty
    with pytest.raises(RuntimeError, match="empty"):
        bpy.ops.nfield.solve()
    with pytest.raises(RuntimeError, match="empty"):
        bpy.ops.nfield.write_attributes()
    obj = import_obj("sphere.obj")
    with pytest.raises(RuntimeError, match="out of range"):
        bpy.ops.nfield.constraint_add(face=5000, direction=(1, 0, 0))
    with pytest.raises(RuntimeError, match="no constraint"):
        bpy.ops.nfield.constraint_remove(face=3)
    with pytest.raises(RuntimeError, match="no region edit"):
        bpy.ops.nfield.region_commit()
    obj.nfield.alignment = "ATTRIBUTE"
    obj.nfield.alignment_attribute = "missing"
    with pytest.raises(RuntimeError, match="'missing' does not exist"):
        bpy.ops.nfield.solve()


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


# ------------------------------------------------------------------------------------------ bad input (add-on layer)
# The table of tests/test_bad_input_matrix.py (no bpy there), run through the installed add-on: settings through
# the scripting API (nfield.blender.configure), constraints through the operators (the scripting API for an
# index that is not a multiple of 1/n, which the operator's integer numerator cannot express), then
# bpy.ops.nfield.solve(). The first step that fails must fail with an ERROR report matching the case and leave
# the settings and the design exactly as they were before that step.
from test_bad_input_matrix import CASES as BAD_INPUT_CASES  # noqa: E402
from test_bad_input_matrix import check_field  # noqa: E402

#: attributes are float32: unit length, tangency and constraint angles hold to float32 rounding (~1e-7) of
#: coordinates and results; 1e-5 is far from any real violation (a wrong field is off by >= 1e-3)
F32_TOL = 1e-5


def _object_from_arrays(name, V, F):
    me = bpy.data.meshes.new(name)
    me.from_pydata(np.asarray(V, float).tolist(), [], np.asarray(F, int).tolist())  # no validate(): keep it dirty
    obj = bpy.data.objects.new(name, me)
    bpy.context.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    return obj


def _addon_steps(nb, obj, case):
    """(description, callable) in the order a user would do them."""
    st = obj.nfield
    steps = []
    params = {k: v for k, v in case.params.items() if k in ("n", "order", "align", "strength")}
    if params:
        steps.append((f"configure({params})", lambda: nb.configure(obj, **params)))
    for c in case.constraints:
        if "face" in c:
            kind = "VECTOR" if "vector" in c else "DIRECTION"
            d = tuple(c.get("direction", c.get("vector")))
            steps.append((f"constraint_add({c})", lambda f=c["face"], d=d, kind=kind:
                          bpy.ops.nfield.constraint_add(face=f, direction=d, kind=kind)))
        else:
            def add_singularity(c=c):
                num = c["index"] * st.n
                if abs(num - round(num)) < 1e-9:
                    return bpy.ops.nfield.singularity_add(vertex=c["vertex"], numerator=int(round(num)))
                return nb.add_singularity(obj, c["vertex"], c["index"])
            steps.append((f"singularity_add({c})", add_singularity))
    steps.append(("solve", lambda: bpy.ops.nfield.solve()))
    return steps


def _user_state(obj) -> tuple:
    """What the user set on `obj` (independent of the add-on's own snapshot code): settings and design."""
    st = obj.nfield
    settings = tuple(getattr(st, k) for k in ("symmetry", "energy", "alignment", "alignment_attribute", "strength",
                                              "solver_mode", "spectral_k", "live_update"))
    cons = tuple((c.face, tuple(c.direction), c.kind, c.stale) for c in st.constraints)
    sings = tuple((x.vertex, x.numerator, x.stale) for x in st.singularities)
    return settings, cons, sings


@pytest.mark.parametrize("case", BAD_INPUT_CASES, ids=[c.name for c in BAD_INPUT_CASES])
def test_bad_input_matrix_addon(scene, case):
    if case.blender_na:
        pytest.skip(f"add-on layer of {case.name}: {case.blender_na}")
    nf = scene
    nb = importlib.import_module(nf.__name__ + ".blender")
    sc = importlib.import_module(nf.__name__ + ".blender.session_cache")
    V, F = case.mesh()
    obj = _object_from_arrays(case.name, V, F)
    obj.nfield.live_update = False
    expected = case.blender_error or case.error
    objects_before = len(bpy.data.objects)
    for what, step in _addon_steps(nb, obj, case):
        before = _user_state(obj)
        try:
            result = step()
        except (RuntimeError, ValueError) as exc:  # operators: RuntimeError carrying the report; api: ValueError
            assert expected is not None, f"{what} failed: {exc}"
            assert re.search(expected, str(exc)), f"{what}: {str(exc)!r} !~ {expected!r}"
            assert "Traceback" not in str(exc), str(exc)
            assert _user_state(obj) == before, f"{what} changed the settings or the design although it failed"
            assert obj.data.attributes.get("nfield_direction") is None
            assert len(bpy.data.objects) == objects_before
            return
        if isinstance(result, set):
            assert result == {"FINISHED"}, (what, result)
    assert expected is None, f"no step failed; expected {expected!r}"
    entry = sc.get_entry(obj)
    mesh = entry.mesh
    d = attr_array(obj, "nfield_direction", "FACE", "FLOAT_VECTOR").astype(np.float64)
    active = np.asarray(mesh.native.face_active)[mesh.polygon_first_triangle]
    normals = np.asarray(mesh.native.face_normals)[mesh.polygon_first_triangle]
    check_field(d, normals, active, obj.nfield.n, case.constraints, report=mesh.report, case=case,
                singularities=nb.field(obj).singularities, tol_unit=F32_TOL, tol_constraint=F32_TOL)


# ------------------------------------------------------------------------------------------ failures across the boundary
# Real failures of the core / compiled solver reach the user as an ERROR report and {'CANCELLED'} (from a
# script: a RuntimeError carrying the report), and leave the settings, the stored design and the last field as
# they were.
def _ring_design(nf):
    """An 80-face icosphere object; vertex 0 pinned with index 1/4 and a vector constraint on one face of its
    ring (consistent). A vector constraint on a second ring face then contradicts the singularity's rows."""
    from test_bad_input_matrix import _sphere, _sphere_ring_vectors

    obj = _object_from_arrays("ring", *_sphere())
    obj.nfield.live_update = False
    ring = _sphere_ring_vectors(0)
    assert bpy.ops.nfield.singularity_add(vertex=0, numerator=1) == {"FINISHED"}
    assert bpy.ops.nfield.constraint_add(face=ring[0]["face"], direction=ring[0]["vector"], kind="VECTOR") == {"FINISHED"}
    assert bpy.ops.nfield.solve() == {"FINISHED"}
    return obj, ring


def test_failed_live_edit_keeps_design_and_field(scene):
    nb = importlib.import_module(scene.__name__ + ".blender")
    obj, ring = _ring_design(scene)
    obj.nfield.live_update = True
    before, field_before = _user_state(obj), nb.field(obj)
    attr_before = attr_array(obj, "nfield_direction", "FACE", "FLOAT_VECTOR").copy()
    with pytest.raises(RuntimeError, match=r"contradictory constraints.*singularity at vertex 0") as info:
        bpy.ops.nfield.constraint_add(face=ring[1]["face"], direction=ring[1]["vector"], kind="VECTOR")
    assert "Traceback" not in str(info.value)
    assert _user_state(obj) == before, "the failed constraint was kept in the design"
    assert nb.field(obj) is field_before
    assert np.array_equal(attr_array(obj, "nfield_direction", "FACE", "FLOAT_VECTOR"), attr_before)
    # the session follows the restored design: solving again works
    assert bpy.ops.nfield.solve() == {"FINISHED"}
    # a live singularity edit that fails the same way (a second ring face already fixed) also leaves nothing
    obj.nfield.live_update = False
    assert bpy.ops.nfield.singularity_remove(vertex=0) == {"FINISHED"}
    assert bpy.ops.nfield.constraint_add(face=ring[1]["face"], direction=ring[1]["vector"], kind="VECTOR") == {"FINISHED"}
    obj.nfield.live_update = True
    before = _user_state(obj)
    with pytest.raises(RuntimeError, match="contradictory constraints"):
        bpy.ops.nfield.singularity_add(vertex=0, numerator=1)
    assert _user_state(obj) == before


def test_failed_solve_with_new_settings_restores_them(scene):
    nb = importlib.import_module(scene.__name__ + ".blender")
    obj, ring = _ring_design(scene)
    nb.add_constraint(obj, ring[1]["face"], ring[1]["vector"], kind="vector")  # now contradictory
    before = _user_state(obj)
    with pytest.raises(ValueError, match="contradictory constraints"):
        nb.solve(obj, n=2, order=1, strength=3.0)
    assert _user_state(obj) == before and (obj.nfield.n, obj.nfield.order) == (4, 2)
    assert "contradictory" in obj.nfield.last_message


def test_cancelled_solve_changes_nothing(scene):
    nb = importlib.import_module(scene.__name__ + ".blender")
    core = importlib.import_module(scene.__name__ + ".core")
    from test_bad_input_matrix import _sphere

    obj = _object_from_arrays("cancel", *_sphere())
    nb.add_constraint(obj, 3, (1.0, 0.0, 0.0))
    before = _user_state(obj)
    calls = []

    def cancel(fraction):
        calls.append(fraction)
        return False

    with pytest.raises(core.Cancelled):
        nb.solve(obj, n=2, order=3, progress=cancel)  # a new session: its factorization asks `cancel`
    assert calls, "the progress callback was never called"
    assert _user_state(obj) == before, "a cancelled solve changed the settings"
    assert nb.field(obj) is None and obj.data.attributes.get("nfield_direction") is None
    # the cached session does not keep the cancelling callback: the next solves work
    r = nb.solve(obj)
    assert np.isfinite(r.directions).all() and len(calls) == 1
    assert nb.solve(obj, order=1).order == 1


def test_out_of_memory_is_reported(scene, monkeypatch):
    """std::bad_alloc arrives as MemoryError (pybind11's default translation). It cannot be provoked safely
    inside this Blender process (limiting the address space breaks Blender's own allocations first), so the
    session's solve raises it here; tests/test_bad_input_matrix.py provokes a real one in a subprocess."""
    session = importlib.import_module(scene.__name__ + ".core.session")
    from test_bad_input_matrix import _sphere

    obj = _object_from_arrays("oom", *_sphere())
    obj.nfield.live_update = True
    before = _user_state(obj)

    def no_memory(self, *a, **k):
        raise MemoryError("std::bad_alloc")

    monkeypatch.setattr(session.DesignSession, "solve", no_memory)
    with pytest.raises(RuntimeError, match=r"out of memory in the solver \(std::bad_alloc\)") as info:
        bpy.ops.nfield.constraint_add(face=3, direction=(1.0, 0.0, 0.0))
    assert "Traceback" not in str(info.value)
    assert _user_state(obj) == before
    with pytest.raises(RuntimeError, match="out of memory"):
        bpy.ops.nfield.solve()


def test_tool_delete_failure_keeps_constraint(scene):
    """The viewport tool's delete (nfield.constraint_delete, executed with an explicit face) re-solves with
    Live Update; when the mesh has meanwhile become unusable (every face collapsed) the solve fails: the
    report names the problem and the constraint stays."""
    from test_bad_input_matrix import _sphere

    obj = _object_from_arrays("collapse", *_sphere())
    obj.nfield.live_update = False
    assert bpy.ops.nfield.constraint_add(face=3, direction=(1.0, 0.0, 0.0)) == {"FINISHED"}
    assert bpy.ops.nfield.solve() == {"FINISHED"}
    me = obj.data
    me.vertices.foreach_set("co", np.zeros(3 * len(me.vertices), dtype=np.float32))
    me.update()
    obj.nfield.live_update = True
    with pytest.raises(RuntimeError, match="no usable face"):
        bpy.ops.nfield.constraint_delete(face=3)
    assert [c.face for c in obj.nfield.constraints] == [3]
    before = _user_state(obj)
    with pytest.raises(RuntimeError, match="no usable face"):
        bpy.ops.nfield.solve()
    assert _user_state(obj) == before
