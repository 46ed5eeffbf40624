"""The artist's path in the installed add-on (headless PyPI ``bpy``): settings that fail are reverted with the
reason, singularities keep their index across changes of n, undo never solves (it puts back a remembered
field or marks the field out of date), one undo step per action, the panel's texts, glyph arrowheads and the
screen-space size of constraint arrows. The real-window side (toolbar, sidebar width, arrowhead re-aim, undo
during a slow solve) is tests/test_blender_window.py. Fixtures and helpers: tests/blender_support.py.
"""
from __future__ import annotations

import importlib

import numpy as np
import pytest
from blender_support import blender_module, bpy, import_obj, interior_vertex, nf, scene  # noqa: F401

pytestmark = pytest.mark.blender


def _nb(scene):
    return importlib.import_module(scene.__name__ + ".blender")


def test_failed_setting_is_reverted_with_the_reason(scene):
    """Curvature alignment needs an even n: choosing n = 1 with it makes the solver refuse; the symmetry goes
    back to the last one that solved and the message names both the reason and what was reverted."""
    nb = _nb(scene)
    obj = import_obj("sphere.obj")
    nb.solve(obj, n=2, align="curvature-max")
    before = nb.field(obj)
    obj.nfield.symmetry = "1"  # the update callback solves live (Live Update is on by default)
    st = obj.nfield
    assert st.symmetry == "2", "the refused setting stayed selected"
    assert st.last_message.startswith("Solve failed:") and "even symmetry" in st.last_message, st.last_message
    assert "Symmetry back to" in st.last_message, st.last_message
    assert nb.field(obj) is before  # the field shown is still the one of the reverted settings


def test_setting_change_solves_live_before_the_first_solve(scene):
    """With Live Update on, a setting change solves even when nothing was solved yet."""
    nb = _nb(scene)
    obj = import_obj("sphere.obj")
    assert nb.field(obj) is None
    obj.nfield.alignment = "CURVATURE_MAX"
    r = nb.field(obj)
    assert r is not None and r.align == "curvature-max"


def test_singularity_keeps_its_index_across_n(scene):
    """+1/2 placed at n = 2 stays +1/2: at n = 4 it is numerator 2 (solved as index 0.5), at n = 1 it cannot
    exist (index x n = 1/2 is no integer): flagged with a message and left out of the solve; back at n = 2
    it is solved again."""
    nb = _nb(scene)
    panels = blender_module(scene, "panels")
    obj = import_obj("sphere.obj")
    v = interior_vertex(obj)
    nb.solve(obj, n=2)
    nb.add_singularity(obj, v, 0.5)
    r = nb.solve(obj, n=4)
    assert (v, pytest.approx(0.5)) in r.singularities
    item = obj.nfield.singularities[0]
    assert panels.singularity_row_text(item, 4) == f"Vertex {v} +1/2"
    r = nb.solve(obj, n=1)
    assert all(abs(i) < 1e-9 or vv != v for vv, i in r.singularities if vv == v)
    assert f"vertex {v}" in obj.nfield.last_message and "not a multiple of 1/1" in obj.nfield.last_message
    assert panels.singularity_row_text(item, 1) == f"Vertex {v} +1/2 (not at n = 1)"
    r = nb.solve(obj, n=2)
    assert (v, pytest.approx(0.5)) in r.singularities


def test_undo_puts_back_the_remembered_field_without_solving(scene):
    """Undo to a solved state restores that state's field object (no solve: the solve time stays that of the
    last solve); undo to a state that was never solved solves nothing either and marks the field out of date
    (in a window the background operator would then solve it)."""
    nb = _nb(scene)
    session_cache = blender_module(scene, "session_cache")
    obj = import_obj("sphere.obj")
    first = nb.solve(obj)
    bpy.ops.ed.undo_push(message="solved")
    nb.add_constraint(obj, 11, (1.0, 0.0, 0.0))
    second = nb.solve(obj)
    bpy.ops.ed.undo_push(message="constraint solved")
    nb.configure(obj, order=1)  # stored, never solved
    bpy.ops.ed.undo_push(message="harmonic, not solved")
    calls = []
    session = session_cache.get_entry_cached(obj).session
    original = type(session).solve
    type(session).solve = lambda self, *a, **k: calls.append(1) or original(self, *a, **k)
    try:
        assert bpy.ops.ed.undo() == {"FINISHED"}
        obj = bpy.data.objects["sphere"]
        assert nb.field(obj) is second and obj.nfield.energy == "BIHARMONIC"
        assert bpy.ops.ed.undo() == {"FINISHED"}
        obj = bpy.data.objects["sphere"]
        assert nb.field(obj) is first and len(obj.nfield.constraints) == 0
        assert bpy.ops.ed.redo() == {"FINISHED"} and bpy.ops.ed.redo() == {"FINISHED"}
        obj = bpy.data.objects["sphere"]
        assert obj.nfield.energy == "HARMONIC"
        assert nb.field(obj) is None  # never solved: nothing to put back, and nothing solved here
        entry = session_cache.get_entry_cached(obj)
        assert entry.extra.get("stale_reason") == "undo"
        assert "after undo" in blender_module(scene, "panels").field_stale_text(obj)
    finally:
        type(session).solve = original
    assert calls == [], "undo/redo solved in the UI thread"


def test_one_undo_step_per_action(scene):
    """The background solve that a setting change starts makes no undo step of its own (the setting did);
    Clear Constraints asks for confirmation when invoked from the UI."""
    background = blender_module(scene, "background")
    operators = blender_module(scene, "operators")
    assert "UNDO" not in background.NFIELD_OT_solve_background.bl_options
    assert "UNDO" in operators.NFIELD_OT_solve.bl_options
    assert "invoke" in operators.NFIELD_OT_constraint_clear.__dict__


def test_panel_texts(scene):
    nb = _nb(scene)
    panels = blender_module(scene, "panels")
    obj = import_obj("sphere.obj")
    nb.add_constraint(obj, 25, (1.0, 0.0, 0.0))
    assert panels.constraint_row_text(obj.nfield.constraints[0]) == "Face 25 → direction"
    text = ("Solve failed: curvature alignment needs an even symmetry n (principal directions are lines, not "
            "vectors). Reverted: Symmetry back to 2 (Line)")
    lines = panels.wrap(text, 30)
    assert len(lines) > 3 and all(len(line) <= 30 for line in lines)
    assert " ".join(lines) == text  # nothing lost or cut
    assert panels.wrap("x" * 70, 30) == ["x" * 30, "x" * 30, "x" * 10]
    assert panels.NFIELD_PT_singularities in panels.SUBPANELS
    assert [p.bl_label for p in panels.SUBPANELS][:6] == ["Constraints", "Singularities", "Region", "Display",
                                                          "Output", "Shading"]
    assert all(p.bl_parent_id == "NFIELD_PT_main" for p in panels.SUBPANELS)


def test_odd_n_glyphs_have_arrowheads(scene):
    """n = 1: each glyph is a shaft plus two head strokes from its tip, back along the direction and to
    either side in the tangent plane; n = 2 glyphs have none (a line has no sign)."""
    glyphs = blender_module(scene, "glyphs")
    c = np.zeros((1, 3))
    nrm = np.array([[0.0, 0.0, 1.0]])
    d1 = np.array([[[1.0, 0.0, 0.0]]])
    seg = glyphs.glyph_segments(c, nrm, np.array([0.5]), d1, np.array([0.0])).reshape(-1, 2, 3)
    assert seg.shape == (3, 2, 3)
    tip = np.array([1.0, 0.0, 0.0])  # one-sided, length 2 x half_length
    assert np.allclose(seg[0], [[0, 0, 0], tip])
    for s in seg[1:]:
        assert np.allclose(s[0], tip)
        back = s[1] - tip
        assert back[0] < 0 and abs(back[2]) < 1e-7 and abs(back[1]) > 0  # backwards, sideways, in the plane
    assert np.allclose(seg[1][1][1], -seg[2][1][1])  # symmetric head
    d2 = np.array([[[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]])
    assert glyphs.glyph_segments(c, nrm, np.array([0.5]), d2, np.array([0.0])).shape == (2, 3)


def test_constraint_arrows_keep_a_screen_space_minimum(scene):
    """An orthographic view of scale s maps an object-space length L to L * s * width / 2 pixels; an arrow
    shorter than the minimum is stretched to exactly the minimum (orthographic: exact), longer ones are kept,
    and the stretch is capped (an arrow seen end-on stays short)."""
    glyphs = blender_module(scene, "glyphs")
    s, width, height = 0.1, 800, 600
    mvp = np.diag([s, s * width / height, s, 1.0])
    tails = np.zeros((3, 3))
    dirs = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    length = np.array([0.5, 5.0, 0.5])  # 20 px, 200 px, end-on
    out = glyphs.screen_min_length(tails, dirs, length, mvp, (width, height), 48.0, 8.0)
    assert out[0] * s * width / 2 == pytest.approx(48.0)
    assert out[1] == pytest.approx(5.0)
    assert out[2] == pytest.approx(0.5 * 8.0)


def _grid(n, z=0.0, extent=1.0):
    """Centroids of an n x n grid of unit-normal (0, 0, 1) faces covering [-extent, extent]^2 at height z."""
    t = (np.arange(n) + 0.5) / n * 2 * extent - extent
    x, y = np.meshgrid(t, t)
    c = np.c_[x.ravel(), y.ravel(), np.full(n * n, z)]
    return c, np.tile([0.0, 0.0, 1.0], (n * n, 1))


def _ortho(s, width, height):
    """Orthographic object -> clip matrix of scale s: x maps to s * width / 2 pixels per unit, as y does."""
    return np.diag([s, s * width / height, -s, 1.0])


def _perspective(eye_z, focal, width, height):
    """A camera on the z axis at eye_z looking down -z (OpenGL projection; focal = 1 / tan(half fov x))."""
    near, far = 0.01, 100.0
    proj = np.array([[focal, 0, 0, 0], [0, focal * width / height, 0, 0],
                     [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)], [0, 0, -1, 0]])
    view = np.eye(4)
    view[2, 3] = -eye_z
    return proj @ view


def test_pixels_per_unit(scene):
    """Orthographic: s * width / 2 pixels per unit everywhere. Perspective: the largest singular value of the
    projection's derivative, checked against finite differences along the three axes (a unit step along the
    view axis moves a point off the axis towards the centre, so the largest is the sideways one here)."""
    glyphs = blender_module(scene, "glyphs")
    width, height = 800, 600
    pts = np.random.default_rng(0).uniform(-1, 1, (50, 3))
    assert np.allclose(glyphs.pixels_per_unit(pts, _ortho(0.1, width, height), (width, height)), 0.1 * width / 2)
    mvp = _perspective(5.0, 1.5, width, height)
    got = glyphs.pixels_per_unit(pts, mvp, (width, height))
    eps = 1e-6
    base, _ = glyphs.project_to_region(pts, mvp, (width, height))
    fd = [np.linalg.norm(glyphs.project_to_region(pts + eps * e, mvp, (width, height))[0] - base, axis=1) / eps
          for e in np.eye(3)]
    assert np.all(got >= np.max(fd, axis=0) * (1 - 1e-4))  # the largest over all directions >= along any axis
    # on the view axis at distance d: focal * width / 2 / d pixels per unit, exactly
    on_axis = glyphs.pixels_per_unit(np.array([[0.0, 0.0, 1.0]]), mvp, (width, height))
    assert on_axis[0] == pytest.approx(1.5 * width / 2 / 4.0)
    behind = glyphs.pixels_per_unit(np.array([[0.0, 0.0, 6.0]]), mvp, (width, height))
    assert behind[0] == 0.0


def test_glyphs_are_spread_evenly_on_screen(scene):
    """Glyph faces are about spacing_px apart on screen, whatever the zoom: zooming in by 2 halves their
    spacing on the surface and, on an object that stays inside the view, shows four times as many; faces
    off screen or behind the viewer are never picked; the cap holds."""
    glyphs = blender_module(scene, "glyphs")
    width, height, spacing = 800, 600, 20.0
    c, nrm = _grid(200, extent=1.0)  # 40,000 faces, 0.01 apart
    counts, cells = [], []
    for s in (0.2, 0.4):  # the grid covers 160 x 160 px, then 320 x 320 px: inside the region both times
        faces, cell = glyphs.sample_on_screen(c, nrm, _ortho(s, width, height), (width, height), spacing, 20000)
        counts.append(len(faces))
        cells.append(float(np.median(cell)))
        assert np.allclose(cell, spacing / (s * width / 2))  # orthographic: one level, cell = spacing on screen
        px, _ = glyphs.project_to_region(c[faces], _ortho(s, width, height), (width, height))
        d = np.linalg.norm(px[:, None, :] - px[None, :, :], axis=2)
        np.fill_diagonal(d, np.inf)
        nearest = d.min(axis=1)
        # one face per cell, the one nearest its centre: neighbours sit one cell apart on screen, give or take
        # the grid's own step (0.01 units = 0.8 / 1.6 px here)
        assert np.median(nearest) == pytest.approx(spacing, abs=2.0), np.median(nearest)
    assert cells[1] == pytest.approx(cells[0] / 2)
    assert counts[1] == pytest.approx(4 * counts[0], rel=0.1), counts  # (160/20)^2 = 64 -> (320/20)^2 = 256
    # zoomed in so far that the grid overflows the region: only faces on screen (plus the margin) are picked
    s = 4.0
    faces, _ = glyphs.sample_on_screen(c, nrm, _ortho(s, width, height), (width, height), spacing, 20000)
    px, _ = glyphs.project_to_region(c[faces], _ortho(s, width, height), (width, height))
    assert px[:, 0].min() >= -0.1 * width - 1 and px[:, 0].max() <= 1.1 * width + 1
    assert px[:, 1].min() >= -0.1 * height - 1 and px[:, 1].max() <= 1.1 * height + 1
    # the cap: a 2 px spacing would keep 6,400 faces of the 160 px grid; with a cap of 1,000 the cells grow
    # by sqrt(count / cap) x 1.05 (a flat grid keeps 1 / cell^2 faces: about cap / 1.1 after one step)
    faces, _ = glyphs.sample_on_screen(c, nrm, _ortho(0.2, width, height), (width, height), 2.0, 1000)
    assert 800 <= len(faces) <= 1000 and len(np.unique(faces)) == len(faces), len(faces)
    # behind the viewer: nothing
    mvp = _perspective(-1.0, 1.5, width, height)  # the eye at z = -1 looks down -z, away from the grid
    assert len(glyphs.sample_on_screen(c, nrm, mvp, (width, height), spacing, 20000)[0]) == 0


def test_glyph_spacing_in_perspective_and_on_thin_parts(scene):
    """In perspective each face's cell is spacing_px / pixels_per_unit rounded to a power-of-two level, so
    glyphs keep about the same spacing on screen near and far (within a factor sqrt(2) of the level
    rounding). A thin plate's back (normal away from the viewer) is sampled apart from its front, so the
    visible front keeps every glyph it would have alone."""
    glyphs = blender_module(scene, "glyphs")
    width, height, spacing = 800, 600, 16.0
    # a long strip receding from the eye: y along the view axis
    t = np.linspace(-1.0, 1.0, 400)
    x, y = np.meshgrid(np.linspace(-0.3, 0.3, 60), t)
    c = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    nrm = np.tile([0.0, 0.0, 1.0], (len(c), 1))
    tilt = np.array([[1, 0, 0, 0], [0, np.cos(1.2), -np.sin(1.2), 0], [0, np.sin(1.2), np.cos(1.2), 0], [0, 0, 0, 1]])
    mvp = _perspective(3.0, 1.5, width, height) @ tilt
    faces, cell = glyphs.sample_on_screen(c, nrm, mvp, (width, height), spacing, 20000)
    on_screen = cell * glyphs.pixels_per_unit(c[faces], mvp, (width, height))
    assert np.all(on_screen > spacing / np.sqrt(2) - 1e-9) and np.all(on_screen < spacing * np.sqrt(2) + 1e-9)
    assert cell.max() / cell.min() >= 2.0  # the far end does use coarser cells
    # a plate 0.004 thick (thinner than a cell): front alone vs front + back
    front, nf = _grid(100, z=0.002)
    back, nb_ = _grid(100, z=-0.002)
    mvp = _ortho(0.2, width, height)
    alone, _ = glyphs.sample_on_screen(front, nf, mvp, (width, height), spacing, 20000)
    both, _ = glyphs.sample_on_screen(np.r_[front, back], np.r_[nf, -nb_], mvp, (width, height), spacing, 20000)
    assert np.array_equal(both[both < len(front)], alone)


def _solved_sphere(scene):
    """The scripting API, the results module, the sphere solved once and its session cache entry."""
    nb = _nb(scene)
    obj = import_obj("sphere.obj")
    nb.solve(obj)
    entry = blender_module(scene, "session_cache").get_entry_cached(obj)
    return nb, blender_module(scene, "results"), obj, entry


def test_undo_history_is_bounded(scene, monkeypatch):
    """The fields remembered for undo are the newest HISTORY_SIZE states and no more bytes than
    HISTORY_BYTES (the newest result is always kept, whatever its size)."""
    from types import SimpleNamespace

    nb, results, obj, entry = _solved_sphere(scene)
    monkeypatch.setattr(results, "HISTORY_BYTES", 3 * 8000)
    fakes = []
    for s in range(6):  # six states (strengths), each result holding 8000 bytes of arrays
        nb.configure(obj, strength=1.0 + s)
        fakes.append(SimpleNamespace(directions=np.zeros(1000)))
        results._remember(obj, entry, fakes[-1])
    kept = [r for _k, r in entry.extra["history"]]
    assert kept == fakes[-3:]
    nb.configure(obj, strength=1.0 + 4)
    assert results.remembered_result(obj, entry) is fakes[4]
    nb.configure(obj, strength=1.0)
    assert results.remembered_result(obj, entry) is None  # evicted


def test_guides_read_from_mesh_data_are_never_restored_from_memory(scene):
    """Feature alignment reads marked edges, which the key of a remembered field cannot see: with it on, no
    field is remembered (undo re-solves in the background instead of showing a field of other edges)."""
    nb, results, obj, entry = _solved_sphere(scene)
    assert results.remembered_result(obj, entry) is entry.result
    obj.nfield.live_update = False
    obj.nfield_guides.use_features = True
    assert results.remembered_result(obj, entry) is None
    with pytest.raises(results.Unkeyable):
        results.design_key(obj, entry)
