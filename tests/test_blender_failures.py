"""Bad input and failures of the core in the installed add-on (headless PyPI ``bpy``): every failure reaches
the user as a message (an ERROR report; from a script a RuntimeError or ValueError carrying it) and leaves the
settings, the stored design and the last field as they were. Fixtures and helpers: tests/blender_support.py.
"""
from __future__ import annotations

import importlib
import re

import numpy as np
import pytest
from blender_support import attr_array, blender_module, bpy, nf, object_from_arrays, scene  # noqa: F401

pytestmark = pytest.mark.blender


# ------------------------------------------------------------------------------------------ bad input (add-on layer)
# The table of tests/bad_input_cases.py (no bpy, no nfield there), run through the installed add-on: settings through
# the scripting API (nfield.blender.configure), constraints through the operators (the scripting API for an
# index that is not a multiple of 1/n, which the operator's integer numerator cannot express), then
# bpy.ops.nfield.solve(). The first step that fails must fail with an ERROR report matching the case and leave
# the settings and the design exactly as they were before that step.
from bad_input_cases import CASES as BAD_INPUT_CASES  # noqa: E402
from bad_input_cases import _sphere, _sphere_ring_vectors, check_field  # noqa: E402

#: attributes are float32: unit length, tangency and constraint angles hold to float32 rounding (~1e-7) of
#: coordinates and results; 1e-5 is far from any real violation (a wrong field is off by >= 1e-3)
F32_TOL = 1e-5


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
    sc = blender_module(nf, "session_cache")
    V, F = case.mesh()
    obj = object_from_arrays(case.name, V, F)
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
    obj = object_from_arrays("ring", *_sphere())
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
    # (n stays 4: the pinned index 1/4 is no multiple of 1/2, so at n = 2 it would be left out of the solve and
    # nothing would contradict)
    with pytest.raises(ValueError, match="contradictory constraints"):
        nb.solve(obj, order=1, strength=3.0)
    assert _user_state(obj) == before and (obj.nfield.n, obj.nfield.order) == (4, 2)
    assert "contradictory" in obj.nfield.last_message


def test_cancelled_solve_changes_nothing(scene):
    nb = importlib.import_module(scene.__name__ + ".blender")
    core = importlib.import_module(scene.__name__ + ".core")
    obj = object_from_arrays("cancel", *_sphere())
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
    obj = object_from_arrays("oom", *_sphere())
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
    obj = object_from_arrays("collapse", *_sphere())
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
