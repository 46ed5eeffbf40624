""""Quad Remesh from Field" in the installed add-on (headless PyPI ``bpy``): the operator creates a new
object beside the source and leaves the source untouched; the new mesh is manifold, consistently oriented,
made of quads (pure-quad mode) or reports its quad share truthfully (quad-dominant mode), and its edges follow
the object's designed field; undo removes it; missing or unusable fields are refused with a message.
Fixtures and helpers: tests/blender_support.py.
"""
from __future__ import annotations

import importlib
import math

import numpy as np
import pytest
from blender_support import blender_module, bpy, import_obj, nf, scene  # noqa: F401

pytestmark = pytest.mark.blender


def _polygons(obj) -> tuple[np.ndarray, list[list[int]]]:
    """Vertices (object space) and polygons of `obj`'s mesh, read back from Blender's data."""
    me = obj.data
    V = np.empty(len(me.vertices) * 3)
    me.vertices.foreach_get("co", V)
    return V.reshape(-1, 3), [list(p.vertices) for p in me.polygons]


def _edge_use(faces) -> tuple[int, int]:
    """(edges used by more than two faces, directed edges used twice): both 0 for a manifold, consistently
    oriented polygon mesh (each interior edge is walked once in each direction)."""
    undirected: dict = {}
    directed: dict = {}
    for f in faces:
        for a, b in zip(f, f[1:] + f[:1]):
            undirected[(min(a, b), max(a, b))] = undirected.get((min(a, b), max(a, b)), 0) + 1
            directed[(a, b)] = directed.get((a, b), 0) + 1
    return (sum(1 for c in undirected.values() if c > 2), sum(1 for c in directed.values() if c > 1))


def _rotated(directions: np.ndarray, normals: np.ndarray, degrees: float) -> np.ndarray:
    """Each tangent direction turned by `degrees` about its face normal."""
    t = math.radians(degrees)
    return math.cos(t) * directions + math.sin(t) * np.cross(normals, directions)


@pytest.fixture
def fandisk_with_field(scene):
    nb = importlib.import_module(scene.__name__ + ".blender")
    obj = import_obj("fandisk.obj")
    nb.solve(obj, n=4, order=2, align="curvature-max", strength=1.0)
    return scene, nb, obj


@pytest.mark.parametrize("pure_quads", [False, True])
def test_quad_remesh_operator_creates_a_field_aligned_object(fandisk_with_field, pure_quads):
    pkg, nb, obj = fandisk_with_field
    core = importlib.import_module(pkg.__name__ + ".core")
    source_V, source_F = _polygons(obj)
    objects_before = set(bpy.data.objects.keys())
    assert bpy.ops.nfield.quad_remesh(target_faces=1500, pure_quads=pure_quads, seed=3) == {"FINISHED"}
    created = set(bpy.data.objects.keys()) - objects_before
    assert created == {"fandisk_quads"}, created
    new = bpy.data.objects["fandisk_quads"]
    status = blender_module(pkg, "remesh_operator").remesh_status
    assert status["state"] == "finished" and status["result"] == new.name

    # the source is untouched: same vertices, same polygons, still the active design's object
    V0, F0 = _polygons(obj)
    assert np.array_equal(V0, source_V) and F0 == source_F
    # beside the source, not on top of it: shifted along world X by more than the source's width
    assert new.matrix_world.translation.x - obj.matrix_world.translation.x > obj.dimensions.x

    V, F = _polygons(new)
    sizes = np.array([len(f) for f in F])
    quad_share = float(np.mean(sizes == 4))
    info = new["nfield_remesh"]
    if pure_quads:
        assert np.all(sizes == 4)
    # the reported share is the mesh's own (exact: both count the same polygons)
    assert info["quad_fraction"] == pytest.approx(quad_share, abs=1e-12)
    assert info["num_faces"] == len(F)
    # quad-dominant on fandisk: rows end at the field's singularities and at dislocations, each costing a
    # triangle or a pentagon; the benchmark measures 97-98% at 5k faces, 1.5k faces has relatively more
    # row ends per face: 90% is a floor no correct run falls under (a broken extraction drops far below)
    assert quad_share >= 0.90, quad_share
    # 1500 requested: the lattice spacing is set from the area, the count lands within a quarter of it
    assert 0.75 * 1500 <= len(F) <= 1.25 * 1500, len(F)

    over_used, repeated = _edge_use(F)
    assert over_used == 0 and repeated == 0, (over_used, repeated)
    assert all(len(set(f)) == len(f) for f in F)

    # follows the field: alignment of the read-back mesh to the field the object was solved with, measured
    # by nfield.core.quad_mesh_stats (tested on hand-made quad meshes in tests/test_remesh_stats.py)
    mesh_read = blender_module(pkg, "mesh_read")
    arrays = mesh_read.mesh_arrays(obj)
    mesh = core.Mesh(arrays.vertices, arrays.triangles, face_to_polygon=arrays.triangle_polygon,
                     num_polygons=arrays.num_polygons)
    directions, n = core.field_directions(mesh, nb.field(obj))
    assert n == 4
    st = core.quad_mesh_stats(V, F, mesh, directions)
    # Bounds: edges placed with no regard to the field have angles spread over [0, 45] deg (mean 22.5);
    # the target of the 5k-quad benchmark is mean < 4 deg; at 1.5k faces the cleanup's shifted rungs
    # cost a little more, so 6 deg (quad-dominant) and 8 deg (pure quads: the half rows that pair the odd
    # faces turn around a centre vertex here and there, whose edges run off the field) bound a correct
    # result with margin while staying far below chance.
    bound = 8.0 if pure_quads else 6.0
    assert st["alignment_mean_deg"] < bound, st["alignment_mean_deg"]
    assert st["manifold"] and st["oriented"]
    # Distance to the input: the lattice spacing at 1.5k faces is about 2.5% of fandisk's diagonal, and the
    # vertices sit on the surface, so the chordal gap stays well below one spacing (measured ~1.3% in both
    # modes: pure quads keep the same lattice and split a few faces into half-width quads).
    assert st["hausdorff_relative"] < 0.02, st["hausdorff_relative"]
    # no flipped face (a corner with scaled Jacobian <= 0 against the surface there), in either mode, on
    # fandisk with its sharp edges kept (the remesher's last step moves or splits what would be flipped)
    assert st["inverted_faces"] == 0 and st["min_scaled_jacobian"] > 0, st["inverted_faces"]
    # and it is THIS field the edges follow: against the field turned by 45 deg the same edges are far off
    normals = np.asarray(mesh.native.face_normals, dtype=np.float64)
    turned = core.quad_mesh_stats(V, F, mesh, _rotated(directions, normals, 45.0))
    assert turned["alignment_mean_deg"] > 45.0 - 2 * bound, turned["alignment_mean_deg"]


def test_quad_remesh_is_one_undo_step(fandisk_with_field):
    _, nb, obj = fandisk_with_field
    assert "UNDO" in bpy.types.NFIELD_OT_quad_remesh.bl_options
    bpy.ops.ed.undo_push(message="before remesh")
    assert bpy.ops.nfield.quad_remesh(target_faces=800) == {"FINISHED"}
    bpy.ops.ed.undo_push(message="remeshed")
    assert "fandisk_quads" in bpy.data.objects
    assert bpy.ops.ed.undo() == {"FINISHED"}
    assert "fandisk_quads" not in bpy.data.objects
    assert "fandisk" in bpy.data.objects and len(bpy.data.objects["fandisk"].data.polygons) == 12946
    assert bpy.ops.ed.redo() == {"FINISHED"}
    assert "fandisk_quads" in bpy.data.objects


def test_settings_panel_and_scripting_api(fandisk_with_field):
    pkg, nb, obj = fandisk_with_field
    st = obj.nfield_remesh
    assert st.target_faces == 5000 and not st.pure_quads and st.keep_boundary and st.keep_sharp and st.pair_row_ends
    assert math.degrees(st.sharp_angle) == pytest.approx(40.0)
    assert bpy.types.NFIELD_PT_remesh.bl_parent_id == "NFIELD_PT_main"
    new, stats = nb.quad_remesh(obj, target_faces=600, seed=1)
    assert new.name in bpy.data.objects and stats["num_faces"] == len(new.data.polygons)
    # the same seed gives the same mesh
    again, _ = nb.quad_remesh(obj, target_faces=600, seed=1)
    Va, Fa = _polygons(new)
    Vb, Fb = _polygons(again)
    assert Fa == Fb and np.array_equal(Va, Vb)
    # "Pair Row Ends" on (default) lets the flow remove row ends; off skips it (the fast single pass)
    ps = stats["position_singularities"]
    assert ps["after"] < ps["before"], ps
    assert bpy.ops.nfield.quad_remesh(target_faces=600, seed=1, pair_row_ends=False) == {"FINISHED"}
    off = blender_module(pkg, "remesh_operator").remesh_status["stats"]["position_singularities"]
    assert off["changed_offsets"] == 0 and off["routed"] == 0, off


def test_refusals_name_the_problem(scene):
    nb = importlib.import_module(scene.__name__ + ".blender")
    obj = import_obj("sphere.obj")
    before = set(bpy.data.objects.keys())
    with pytest.raises(RuntimeError, match="no field to follow: solve its field first"):
        bpy.ops.nfield.quad_remesh(target_faces=500)
    nb.solve(obj, n=3)
    with pytest.raises(RuntimeError, match="3-direction field has no quad structure"):
        bpy.ops.nfield.quad_remesh(target_faces=500)
    nb.solve(obj, n=4)
    with pytest.raises(ValueError, match="edge length"):
        nb.quad_remesh(obj, edge_length=-1.0)
    assert set(bpy.data.objects.keys()) == before


def test_a_design_changed_since_the_last_solve_is_solved_first_or_named(fandisk_with_field):
    """A constraint added with Live Update off leaves the last field behind the design: Solve First (the
    default) solves the design again before remeshing, off remeshes the old field; both say so."""
    pkg, nb, obj = fandisk_with_field
    status = blender_module(pkg, "remesh_operator").remesh_status
    nb.configure(obj, live_update=False)
    assert nb.field_state(obj) == "current"
    before = np.array(nb.field(obj).directions, copy=True)
    # a constraint across the field at a face: its direction turned by 45 degrees about the face normal
    face = 2000
    normal = np.asarray(obj.data.polygons[face].normal)
    wanted = _rotated(before[face][None], normal[None], 45.0)[0]
    nb.add_constraint(obj, face, wanted)
    assert nb.field_state(obj) == "outdated"

    assert bpy.ops.nfield.quad_remesh(target_faces=600, solve_first=False) == {"FINISHED"}
    assert any("remeshed the last solved field" in m for m in status["stats"]["messages"]), status["stats"]["messages"]
    assert nb.field_state(obj) == "outdated"
    assert np.array_equal(np.asarray(nb.field(obj).directions), before)  # the field was left as it was

    assert bpy.ops.nfield.quad_remesh(target_faces=600) == {"FINISHED"}
    assert any("solved it again before remeshing" in m for m in status["stats"]["messages"]), status["stats"]["messages"]
    assert nb.field_state(obj) == "current"
    # the field remeshed is the new design's: the constrained face carries the constraint exactly (one of the
    # four cross directions along it, up to rounding), which the old field did not (45 degrees off)
    after = np.asarray(nb.field(obj).directions)[face]
    def off_cross(d):
        c = np.dot(d, wanted) / (np.linalg.norm(d) * np.linalg.norm(wanted))
        s = np.dot(np.cross(wanted, d), normal) / (np.linalg.norm(d) * np.linalg.norm(wanted))
        a = abs(math.degrees(math.atan2(s, c))) % 90.0
        return min(a, 90.0 - a)
    assert off_cross(after) < 1e-4 and off_cross(before[face]) > 40.0


def test_solve_first_runs_in_the_worker_thread_and_its_field_survives_a_cancel(fandisk_with_field):
    """Invoked from the UI, Quad Remesh solves an outdated design in its worker thread, not in the UI thread:
    building the recipe solves nothing (the field stays outdated), the thread that runs the recipe solves the
    current design and then remeshes it. Cancelled after the solve (progress returns False once the remesh
    reports), nothing is created, and the field solved for it is kept: the design is current afterwards."""
    import threading

    pkg, nb, obj = fandisk_with_field
    api = blender_module(pkg, "api")
    nb.configure(obj, live_update=False)
    face = 2000
    normal = np.asarray(obj.data.polygons[face].normal)
    wanted = _rotated(np.asarray(nb.field(obj).directions)[face][None], normal[None], 45.0)[0]
    nb.add_constraint(obj, face, wanted)
    assert nb.field_state(obj) == "outdated"

    def run(recipe, progress):
        box = {}

        def work():
            box["thread"] = threading.current_thread().name
            try:
                box["value"] = api.remesh_from_recipe(recipe, progress)
            except BaseException as exc:  # noqa: BLE001 - inspected below
                box["error"] = exc
        thread = threading.Thread(target=work, name="nfield-remesh-test")
        thread.start()
        thread.join(300)
        return box

    # cancelled once the remesh has started: the solve before it finished, nothing was created
    recipe = api.remesh_recipe(obj, target_faces=600)
    assert recipe["solve"] is not None and nb.field_state(obj) == "outdated"  # nothing solved yet
    fractions = []
    box = run(recipe, lambda f: fractions.append(f) or f <= api._SOLVE_SHARE)
    assert type(box.get("error")).__name__ == "Cancelled", box
    assert recipe["solve"]["result"] is not None and nb.field_state(obj) == "outdated"
    objects_before = set(bpy.data.objects.keys())
    assert api.adopt_recipe_solve(obj, recipe) is True
    assert nb.field_state(obj) == "current" and set(bpy.data.objects.keys()) == objects_before
    assert nb.field(obj) is recipe["solve"]["result"]

    # with the design current the recipe has nothing to solve; a changed design again: solve, then remesh
    assert api.remesh_recipe(obj, target_faces=600)["solve"] is None
    nb.add_constraint(obj, face + 1, wanted)
    recipe = api.remesh_recipe(obj, target_faces=600)
    fractions.clear()
    box = run(recipe, lambda f: fractions.append(f) or True)
    assert box["thread"] == "nfield-remesh-test" and "value" in box, box
    assert fractions == sorted(fractions) and fractions[-1] == pytest.approx(1.0)  # one bar: solve, then remesh
    new = api.adopt_remesh(obj, recipe, box["value"])
    assert nb.field_state(obj) == "current" and new.name in bpy.data.objects
    assert any("solved it again before remeshing" in m for m in box["value"].stats["messages"])
    _, F = _polygons(new)
    assert _edge_use(F) == (0, 0) and sum(len(f) == 4 for f in F) > 0.97 * len(F)


def test_worker_runs_off_the_ui_thread_reports_progress_and_stops_on_esc(scene):
    """jobs.Worker, the worker thread of the modal operators (quad remesh, spectral precompute), driven by
    stand-ins for the window manager and events: timer events update the progress bar and the status
    line while the work runs in another thread, Esc makes progress() return False, the work's outcome comes
    back to the caller, and stop() takes the timer, progress bar and status line away."""
    import threading
    import time
    from types import SimpleNamespace

    jobs = blender_module(scene, "jobs")
    calls = []
    wm = SimpleNamespace(progress_begin=lambda a, b: calls.append(("begin", a, b)),
                         progress_update=lambda v: calls.append(("update", v)),
                         progress_end=lambda: calls.append(("end",)),
                         event_timer_add=lambda dt, window=None: "timer",
                         event_timer_remove=lambda t: calls.append(("timer removed", t)),
                         modal_handler_add=lambda op: calls.append(("modal", op)))
    texts = []
    context = SimpleNamespace(window_manager=wm, window=None,
                              workspace=SimpleNamespace(status_text_set=lambda t: texts.append(t)))
    seen_threads = []

    def work(progress):
        seen_threads.append(threading.current_thread().name)
        fraction = 0.0
        while progress(min(fraction, 0.99)):
            fraction += 0.01
            time.sleep(0.005)
        return "stopped at %.2f" % fraction

    status = {}
    worker = jobs.Worker(work, status, "nfield-test")
    worker.start("the operator", context)
    assert calls[:2] == [("begin", 0, 100), ("modal", "the operator")]
    timer = SimpleNamespace(type="TIMER", value="NOTHING")
    mouse = SimpleNamespace(type="MOUSEMOVE", value="NOTHING")
    for _ in range(3):
        time.sleep(0.05)
        assert worker.step(context, timer, "testing") is False
    assert worker.passed_on(mouse) == {"PASS_THROUGH"} and worker.passed_on(timer) == {"RUNNING_MODAL"}
    assert worker.step(context, mouse, "testing") is False
    assert status["ui_updates"] == 3 and 0 < status["fraction"] < 1
    assert texts[-1].startswith("nfield: testing (") and texts[-1].endswith("%), Esc to cancel")
    assert worker.step(context, SimpleNamespace(type="ESC", value="PRESS"), "testing") is False or worker.cancel
    worker.thread.join(10)
    assert worker.step(context, timer, "testing") is True
    worker.stop(context)
    assert seen_threads == ["nfield-test"] and worker.outcome[0] == "ok" and worker.outcome[1].startswith("stopped")
    assert ("timer removed", "timer") in calls and calls[-1] == ("end",) and texts[-1] is None
