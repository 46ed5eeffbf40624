"""Designing fields in the installed add-on (headless PyPI ``bpy``): operators and scripting API against
nfield.core, attributes, quads and transforms, save/reload, undo, mesh changes, regions, spectral mode and the
messages of bad states. Fixtures and helpers: tests/blender_support.py.
"""
from __future__ import annotations

import importlib
import os
from pathlib import Path

import numpy as np
import pytest
from blender_support import (  # noqa: F401  (fixtures)
    DATA,
    attr_array,
    blender_module,
    bpy,
    core_reference,
    import_obj,
    interior_vertex,
    nf,
    nsym_angle_error,
    object_from_arrays,
    poly_normals,
    scene,
)

import bmesh  # noqa: E402  (after bpy)

pytestmark = pytest.mark.blender


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
    obj = object_from_arrays(CHECK_MESH.stem, mesh.vertices, mesh.faces)
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
    sc = blender_module(nf, "session_cache")
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
    sc = blender_module(nf, "session_cache")
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

    arrays = blender_module(nf, "mesh_read").mesh_arrays(obj)
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
