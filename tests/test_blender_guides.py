"""Guides in the installed add-on (headless PyPI ``bpy``), each kind read from Blender data and checked
against mathematics:

* hard feature alignment from edges marked sharp (fandisk): on every face next to a marked edge the field is
  within 1 degree of the edge's direction (the hard guide is a direction constraint, imposed to rounding;
  faces next to two feature edges get their mean direction when the two agree within 1 degree), except the
  faces the corner rule dropped, which the guide report lists; without features it is far off;
* face-set and material borders: the features the solve used are exactly the edges between differently
  labelled faces, counted independently;
* per-face weight and rotation attributes: a rotation of pi/2 everywhere turns a line field (n = 2) by
  exactly 90 degrees (the linear spline's guide is multiplied by e^{i n theta} = -1, so is its solution:
  float32 attribute, 1e-5 bound), and weights give the same field as nfield.core with the same weights;
* curve guides: a hard curve on a flat grid makes the faces it crosses point along it (1 degree); moving the
  curve object re-solves through the depsgraph handler and the field follows the new curve;
* mirror symmetry: u(mirror f) = reflect(u(f)) to 1e-8 with constraints on one side only (imposed exactly,
  rounding only); a non-symmetric mesh is refused with the faces listed, or applied to the matched part;
* cuts from seams: across a slit of seams the field jumps (> 45 degrees), without them it turns smoothly;
* guide settings persist in the .blend.
Fixtures and helpers: tests/blender_support.py.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from blender_support import (  # noqa: F401  (fixtures)
    DATA,
    blender_module,
    bpy,
    nf,
    object_from_arrays,
    scene,
)

import meshgen
from guide_support import (
    ellipsoid_object,
    faces_along,
    guide_api,
    guide_core,
    line_deviation,
    move_curve,
    poly_curve,
    still_object,
)

pytestmark = pytest.mark.blender


def _edge_directions(V, pairs):
    d = V[pairs[:, 1]] - V[pairs[:, 0]]
    return d / np.linalg.norm(d, axis=1)[:, None]


def _faces_of_edges(F, pairs):
    """{edge row: faces containing both vertices} by an independent search over the face list."""
    out = {}
    for i, (a, b) in enumerate(pairs.tolist()):
        out[i] = np.flatnonzero((F == a).any(axis=1) & (F == b).any(axis=1)).tolist()
    return out


def _dihedral_sharp_edges(V, F, degrees):
    """Interior edges whose two faces' normals differ by more than `degrees` (computed here with numpy)."""
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    edges = {}
    for f, tri in enumerate(F.tolist()):
        for k in range(3):
            e = tuple(sorted((tri[k], tri[(k + 1) % 3])))
            edges.setdefault(e, []).append(f)
    out = [e for e, fs in edges.items() if len(fs) == 2
           and math.degrees(math.acos(np.clip(n[fs[0]] @ n[fs[1]], -1, 1))) > degrees]
    return np.array(sorted(out), dtype=np.int64)


def _deviation(result, F, V, pairs, skip=()):
    """Per (face next to a marked edge): degrees between the edge line and the nearest field direction."""
    alld = np.asarray(result.all_directions())
    dirs = _edge_directions(V, pairs)
    faces = _faces_of_edges(F, pairs)
    out = []
    for i, fs in faces.items():
        for f in fs:
            if f not in skip:
                out.append(math.degrees(math.acos(min(1.0, float(np.abs(alld[f] @ dirs[i]).max())))))
    return np.array(out)


def _mark_sharp(obj, pairs):
    me = obj.data
    ev = np.empty(len(me.edges) * 2, dtype=np.int32)
    me.edges.foreach_get("vertices", ev)
    ev = np.sort(ev.reshape(-1, 2), axis=1)
    wanted = {tuple(p) for p in np.sort(pairs, axis=1).tolist()}
    flags = np.array([tuple(e) in wanted for e in ev.tolist()], dtype=bool)
    me.edges.foreach_set("use_edge_sharp", flags)
    me.update()
    return int(flags.sum())


def test_hard_features_from_marked_sharp_edges(scene):
    nf = scene
    api = guide_api(nf)
    mesh = guide_core(nf).Mesh.from_file(DATA / "fandisk.obj")
    V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    obj = still_object("fandisk", V, F)
    pairs = _dihedral_sharp_edges(V, F, 30.0)
    assert _mark_sharp(obj, pairs) == len(pairs) > 100
    plain = api.solve(obj, n=4, order=2, align="curvature-max", strength=1.0, write=False)
    api.set_feature_alignment(obj, boundary=False, dihedral=False, marked=["sharp"], mode="hard")
    result = api.solve(obj, write=False)
    report = api.guide_report(obj)
    assert report["feature_edges"] == len(pairs)
    assert report["hard_constraints"] > 0
    dropped = {d["face"] for d in report["dropped"]}
    for d in report["dropped"]:  # every dropped face names the two feature chains and their angle
        assert "feature chain" in d["reason"] and "degrees apart" in d["reason"]
    dev = _deviation(result, F, V, pairs, skip=dropped)
    assert len(dev) > 0.8 * 2 * len(pairs)
    assert dev.max() < 1.0, dev.max()
    # without the features, curvature alignment alone leaves many of these faces degrees away from the rim
    assert _deviation(plain, F, V, pairs).max() > 5.0


def _border_pairs(F, labels):
    edges = {}
    for f, tri in enumerate(F.tolist()):
        for k in range(3):
            edges.setdefault(tuple(sorted((tri[k], tri[(k + 1) % 3]))), set()).add(int(labels[f]))
    return sorted(e for e, ls in edges.items() if len(ls) > 1)


@pytest.mark.parametrize("source", ["materials", "face_sets"])
def test_region_borders_are_the_features(scene, source):
    nf = scene
    api = guide_api(nf)
    V, F = meshgen.icosphere(3)
    obj = still_object("sphere", V, F)
    cent = V[F].mean(axis=1)
    labels = (cent[:, 2] > 0.3).astype(np.int64) + (cent[:, 0] > 0.5).astype(np.int64) * 2
    me = obj.data
    if source == "materials":
        for name in ("a", "b", "c", "d"):
            me.materials.append(bpy.data.materials.new(name))
        me.polygons.foreach_set("material_index", labels.astype(np.int32))
    else:
        attr = me.attributes.new(".sculpt_face_set", "INT", "FACE")
        attr.data.foreach_set("value", (labels + 1).astype(np.int32))
    me.update()
    expected = _border_pairs(F, labels)
    assert len(expected) > 20
    reader = blender_module(nf, "guides")
    assert [tuple(p) for p in reader.marked_edges(obj, [source.upper()]).tolist()] == expected
    api.set_feature_alignment(obj, boundary=False, dihedral=False, marked=[source], mode="soft", weight=2.0)
    api.solve(obj, n=4, order=2, align="curvature-max", write=False)
    assert api.guide_report(obj)["feature_edges"] == len(expected)


def _face_attribute(obj, name, values):
    attr = obj.data.attributes.get(name) or obj.data.attributes.new(name, "FLOAT", "FACE")
    attr.data.foreach_set("value", np.asarray(values, dtype=np.float32))
    obj.data.update()


def test_rotation_attribute_turns_a_line_field_by_its_angle(scene):
    nf = scene
    api = guide_api(nf)
    obj, V, F = ellipsoid_object()
    plain = np.asarray(api.solve(obj, n=2, order=2, align="curvature-max", write=False).directions)
    _face_attribute(obj, "turn", np.full(len(F), math.pi / 2))
    api.set_guide_attributes(obj, rotation="turn")
    turned = np.asarray(api.solve(obj, write=False).directions)
    # perpendicular everywhere: |cos| below the float32 rounding of pi/2 (~4e-8) times the solve's conditioning
    assert np.abs(np.einsum("ij,ij->i", plain, turned)).max() < 1e-5


def test_weight_attribute_matches_core(scene):
    nf = scene
    core = guide_core(nf)
    api = guide_api(nf)
    obj, V, F = ellipsoid_object()
    cent = V[F].mean(axis=1)
    w = np.where(cent[:, 0] > 0, 0.0, 3.0).astype(np.float32)  # no alignment at all on the x > 0 half
    _face_attribute(obj, "w", w)
    api.set_guide_attributes(obj, weight="w")
    got = api.solve(obj, n=4, order=2, align="curvature-max", write=False)
    arrays = blender_module(nf, "mesh_read").mesh_arrays(obj)
    mesh = core.Mesh(arrays.vertices, arrays.triangles, face_to_polygon=arrays.triangle_polygon,
                     num_polygons=arrays.num_polygons)
    s = core.DesignSession(mesh, n=4, order=2, align="curvature-max")
    s.set_alignment_weight(w.astype(np.float64))
    ref = s.solve()
    unweighted = core.DesignSession(mesh, n=4, order=2, align="curvature-max").solve()
    # the same system solved twice: equal to rounding; a field without the weights differs visibly
    assert np.abs(np.asarray(got.representation) - np.asarray(ref.representation)).max() < 1e-9
    assert np.abs(np.asarray(got.representation) - np.asarray(unweighted.representation)).max() > 1e-3
    with pytest.raises(ValueError, match="does not exist"):
        api.set_guide_attributes(obj, weight="no such attribute")
    assert obj.nfield_guides.weight_attribute == "w"  # the failed edit left the settings as they were


def test_curve_guide_follows_the_curve_and_its_edits(scene):
    nf = scene
    api = guide_api(nf)
    V, F = meshgen.grid(25, 25)
    obj = object_from_arrays("grid", V, F)
    st = obj.nfield
    st.live_update = True
    h = 1.0 / 24
    start, d1 = np.array([0.1, 0.2, 0.0]), np.array([1.0, 0.45, 0.0])
    curve = poly_curve("guide", [start + t * d1 for t in np.linspace(0, 0.8, 9)])
    bpy.context.view_layer.objects.active = obj
    api.add_curve_guide(obj, curve, mode="hard", tolerance=0.02)
    result = api.solve(obj, n=4, order=2, align="none", write=False)
    faces = faces_along(V, F, start, d1, 0.25 * h)
    faces = faces[(V[F].mean(axis=1)[faces, 0] > 0.15) & (V[F].mean(axis=1)[faces, 0] < 0.8)]
    assert len(faces) >= 8
    dev = line_deviation(result, faces, d1)
    assert max(dev) < 1.0, max(dev)
    # move the curve: a new direction; the depsgraph handler re-solves (Live Update) with the new curve
    d2 = np.array([0.4, 1.0, 0.0])
    move_curve(curve, [start + t * d2 for t in np.linspace(0, 0.75, 9)])
    moved = api.field(obj)
    assert moved is not result, "editing the curve did not re-solve"
    faces = faces_along(V, F, start, d2, 0.25 * h)
    faces = faces[(V[F].mean(axis=1)[faces, 1] > 0.25) & (V[F].mean(axis=1)[faces, 1] < 0.9)]
    dev = line_deviation(moved, faces, d2)
    assert len(faces) >= 8 and max(dev) < 1.0, (len(faces), max(dev) if dev else None)
    api.remove_curve_guide(obj, curve)
    assert len(obj.nfield_guides.curves) == 0


def test_mirror_symmetry_exact_and_refusal(scene):
    nf = scene
    core = guide_core(nf)
    api = guide_api(nf)
    obj, V, F = ellipsoid_object()
    info = api.set_mirror_symmetry(obj, "x")
    assert info["matched"] == len(F) and info["unmatched"] == []
    cent = V[F].mean(axis=1)
    normals = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    rng = np.random.default_rng(3)
    for f in rng.choice(np.flatnonzero(cent[:, 0] > 0.3), 3, replace=False):
        d = rng.normal(size=3)
        api.add_constraint(obj, int(f), tuple(d - normals[f] * (d @ normals[f])))
    result = api.solve(obj, n=4, order=2, align="curvature-max", write=False)
    # measured on the mesh Blender holds (float32 coordinates: its frames differ from the float64 icosphere's
    # by ~1e-7, which a map built from V would report as asymmetry)
    arrays = blender_module(nf, "mesh_read").mesh_arrays(obj)
    mm = core.native().MirrorMap(core.Mesh(arrays.vertices, arrays.triangles).native, "x", 0.0, 1e-9)
    assert mm.asymmetry(result.representation, 4) < 1e-8
    # the design tool mirrors the constraints: 3 new ones, at the mirror faces
    assert api.mirror_design(obj) == 3 and len(obj.nfield.constraints) == 6
    # a vertex moved off the mirror image: refused with the faces listed, or applied to the matched part
    api.set_mirror_symmetry(obj, None)
    obj.data.vertices[int(np.argmax(V[:, 0]))].co.y += 0.05
    obj.data.update()
    with pytest.raises(ValueError, match="no mirror partner"):
        api.set_mirror_symmetry(obj, "x")
    assert obj.nfield_guides.mirror_axis == "NONE"
    info = api.set_mirror_symmetry(obj, "x", partial=True)
    assert 0 < len(info["unmatched"]) < 20


def test_seams_cut_the_field(scene):
    nf = scene
    api = guide_api(nf)
    V, F = meshgen.grid(21, 21)
    obj = still_object("slit", V, F)
    idx = np.arange(21 * 21).reshape(21, 21)
    slit = np.array([(idx[10, j], idx[10, j + 1]) for j in range(0, 16)])
    me = obj.data
    ev = np.empty(len(me.edges) * 2, dtype=np.int32)
    me.edges.foreach_get("vertices", ev)
    ev = np.sort(ev.reshape(-1, 2), axis=1)
    wanted = {tuple(p) for p in np.sort(slit, axis=1).tolist()}
    me.edges.foreach_set("use_seam", np.array([tuple(e) in wanted for e in ev.tolist()], dtype=bool))
    me.update()
    cent = V[F].mean(axis=1)
    left = int(np.argmin(np.linalg.norm(cent - [0.25, 0.4, 0], axis=1)))
    right = int(np.argmin(np.linalg.norm(cent - [0.75, 0.4, 0], axis=1)))
    api.add_constraint(obj, left, (1.0, 0.0, 0.0), kind="vector")
    api.add_constraint(obj, right, (0.0, 1.0, 0.0), kind="vector")
    across = [np.flatnonzero((F == idx[10, j]).any(axis=1) & (F == idx[10, j + 1]).any(axis=1)) for j in range(5, 11)]

    def jump(result):
        d = np.asarray(result.directions)
        return max(math.degrees(math.acos(np.clip(d[a] @ d[b], -1, 1))) for a, b in across)

    without = jump(api.solve(obj, n=1, order=1, align="none", write=False))
    api.set_cuts(obj, "seams")
    with_cut = api.solve(obj, write=False)
    assert api.guide_report(obj)["cuts"]["opened"] == len(slit)
    assert without < 15 and jump(with_cut) > 45, (without, jump(with_cut))


def test_guides_persist_in_the_blend(scene, tmp_path):
    nf = scene
    api = guide_api(nf)
    V, F = meshgen.icosphere(2)
    obj = still_object("keep", V, F)
    curve = poly_curve("keep_curve", [(0, 0, 1.2), (0.5, 0.5, 1.0)])
    api.set_feature_alignment(obj, boundary=False, dihedral=True, angle=5.0, mode="hard", every=2)
    api.add_curve_guide(obj, curve, mode="soft", weight=2.5, tolerance=0.5)
    api.set_mirror_symmetry(obj, "z")
    path = tmp_path / "guides.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    g = bpy.data.objects["keep"].nfield_guides
    assert (g.use_features, g.feature_use_angle, g.feature_angle, g.feature_mode, g.feature_every) == (
        True, True, 5.0, "HARD", 2)
    assert len(g.curves) == 1 and g.curves[0].curve.name == "keep_curve" and g.curves[0].weight == 2.5
    assert g.mirror_axis == "Z"
    api.solve(bpy.data.objects["keep"], write=False)
    report = api.guide_report(bpy.data.objects["keep"])
    assert report["symmetry"]["axis"] == "z" and report["feature_edges"] > 0


def test_guide_edits_undo_and_redo(scene):
    """Guide edits are undo steps like the rest of the design: feature settings (obj.nfield_guides) and a comb
    stroke (the comb face attributes, one step per stroke) come and go with undo / redo, and the next solve
    uses what the restored state holds."""
    nf = scene
    api = guide_api(nf)
    reader = blender_module(nf, "guides")
    obj, V, F = ellipsoid_object("undo_guides")
    api.solve(obj, n=4, order=2, align="curvature-max", write=False)
    bpy.ops.ed.undo_push(message="start")
    api.set_feature_alignment(obj, boundary=False, dihedral=True, angle=5.0, mode="soft")
    bpy.ops.ed.undo_push(message="features")
    samples = [{"name": "", "location": tuple(V[F[0]].mean(axis=0)), "direction": (0.0, 0.0, 1.0)}]
    assert bpy.ops.nfield.comb_stroke(samples=samples, radius=0.1) == {"FINISHED"}
    bpy.ops.ed.undo_push(message="comb")
    combed = reader.comb_field(bpy.data.objects["undo_guides"])
    assert combed is not None and combed[1].max() > 0
    assert bpy.ops.ed.undo() == {"FINISHED"}
    obj = bpy.data.objects["undo_guides"]
    assert reader.comb_field(obj) is None and obj.nfield_guides.use_features  # the stroke only
    assert bpy.ops.ed.undo() == {"FINISHED"}
    obj = bpy.data.objects["undo_guides"]
    assert not obj.nfield_guides.use_features
    api.solve(obj, write=False)
    assert api.guide_report(obj)["feature_edges"] == 0
    assert bpy.ops.ed.redo() == {"FINISHED"} and bpy.ops.ed.redo() == {"FINISHED"}
    obj = bpy.data.objects["undo_guides"]
    assert obj.nfield_guides.use_features and np.array_equal(reader.comb_field(obj)[1], combed[1])
    api.solve(obj, write=False)
    assert api.guide_report(obj)["feature_edges"] > 0


def test_curve_sources_are_read_in_the_mesh_space(scene):
    """A Bezier curve with handles on its chord is a straight segment: every evaluated point lies on it; a
    Curves object gives its control points per curve; both are mapped into the mesh object's space (the mesh
    object is moved and scaled: the points follow the inverse of its transform)."""
    nf = scene
    reader = blender_module(nf, "guides")
    V, F = meshgen.grid(5, 5)
    mesh_obj = object_from_arrays("plate", V, F)
    mesh_obj.location = (1.0, 0.0, 0.0)
    mesh_obj.scale = (2.0, 2.0, 2.0)
    bpy.context.view_layer.update()
    a, b = np.array([0.2, 0.4, 0.0]), np.array([2.2, 1.4, 0.0])
    cd = bpy.data.curves.new("bez", "CURVE")
    cd.dimensions = "3D"
    cd.resolution_u = 8
    sp = cd.splines.new("BEZIER")
    sp.bezier_points.add(1)
    for p, xyz, h in zip(sp.bezier_points, (a, b), ((b - a) / 3, (a - b) / 3)):
        p.co = xyz
        p.handle_left_type = p.handle_right_type = "FREE"
        p.handle_right, p.handle_left = xyz + h, xyz - h
    bez = bpy.data.objects.new("bez", cd)
    bpy.context.collection.objects.link(bez)
    bpy.context.view_layer.update()
    (line,) = reader.curve_polylines(bez, mesh_obj)
    world = line * 2.0 + [1.0, 0.0, 0.0]  # back to world space
    u = (b - a) / np.linalg.norm(b - a)
    off = (world - a) - np.outer((world - a) @ u, u)
    assert len(line) == 9 and np.abs(off).max() < 1e-5  # float32 coordinates
    assert np.allclose(world[0], a, atol=1e-5) and np.allclose(world[-1], b, atol=1e-5)
    hc = bpy.data.hair_curves.new("hair")
    hc.add_curves([3, 1, 2])  # the single-point curve cannot guide: skipped
    pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [5, 5, 5], [0, 2, 0], [2, 2, 0]], dtype=float)
    for p, xyz in zip(hc.points, pts):
        p.position = xyz
    hair = bpy.data.objects.new("hair", hc)
    bpy.context.collection.objects.link(hair)
    bpy.context.view_layer.update()
    lines = reader.curve_polylines(hair, mesh_obj)
    assert [len(x) for x in lines] == [3, 2]
    assert np.allclose(lines[0] * 2.0 + [1, 0, 0], pts[:3]) and np.allclose(lines[1] * 2.0 + [1, 0, 0], pts[4:])


def _grease_pencil(name, strokes, layer_offset, frame=1):
    """A Grease Pencil object of this Blender (legacy GPENCIL up to 4.2, GREASEPENCIL from 4.3) whose layer
    "guides" is moved by `layer_offset` and holds `strokes` (lists of points) at `frame`; a hidden layer
    holds a stroke far away. Returns (object, kind) or (None, reason)."""
    # 4.3 to 4.5 have both collections and only the v3 one makes objects (an empty collection is falsy: test
    # for None, not truth)
    data = getattr(bpy.data, "grease_pencils_v3", None)
    if data is None:
        data = getattr(bpy.data, "grease_pencils", None)
    if data is None:
        return None, f"Blender {bpy.app.version_string} has no Grease Pencil data"
    gp = data.new(name)
    ob = bpy.data.objects.new(name, gp)
    bpy.context.collection.objects.link(ob)
    for layer_name, lines, hidden in (("guides", strokes, False), ("hidden", [[(9, 9, 9), (9, 8, 9)]], True)):
        layer = gp.layers.new(layer_name)
        fr = layer.frames.new(frame)
        if ob.type == "GREASEPENCIL":
            drawing = fr.drawing
            drawing.add_strokes([len(p) for p in lines])
            drawing.attributes["position"].data.foreach_set("vector", np.concatenate(lines).astype(np.float32).ravel())
            layer.translation = layer_offset
        else:
            for pts in lines:
                stroke = fr.strokes.new()
                stroke.points.add(len(pts))
                stroke.points.foreach_set("co", np.asarray(pts, dtype=np.float32).ravel())
            layer.location = layer_offset
        layer.hide = hidden
    return ob, ob.type


def test_grease_pencil_strokes_are_curve_guides(scene):
    """A Grease Pencil object (this Blender's kind) is a curve source: its visible strokes at the current
    frame, with the object's and the layer's transform, in the mesh's object space; as a hard guide on a flat
    grid the faces the stroke crosses point along it (1 degree, as for curve objects)."""
    nf = scene
    api = guide_api(nf)
    reader = blender_module(nf, "guides")
    V, F = meshgen.grid(25, 25)
    obj = still_object("gp_plate", V, F)
    obj.location = (1.0, 0.0, 0.0)
    obj.scale = (2.0, 2.0, 2.0)
    start, d = np.array([0.2, 0.3, 0.0]), np.array([1.0, 0.45, 0.0])
    # in the plate's space the stroke runs start + t d; in world space that is 2 (start + t d) + (1, 0, 0); the
    # GP object sits at (1, 0, 0) and its layer is moved by (0, 0.5, 0): the stored points are 2 (start + t d)
    # - (0, 0.5, 0)
    inside = [start + t * d for t in np.linspace(0, 0.8, 9)]
    stored = [2.0 * p - np.array([0.0, 0.5, 0.0]) for p in inside]
    gp, kind = _grease_pencil("gp_guide", [stored, stored[:1]], (0.0, 0.5, 0.0))  # a one-point stroke: skipped
    if gp is None:
        print(f"SKIP: {kind}")
        pytest.skip(kind)
    print(f"Blender {bpy.app.version_string}: Grease Pencil object type {kind}")
    gp.location = (1.0, 0.0, 0.0)
    bpy.context.scene.frame_set(1)
    bpy.context.view_layer.update()
    (line,) = reader.curve_polylines(gp, obj)  # the hidden layer's stroke is not read
    assert np.allclose(line, inside, atol=1e-5)  # float32 points
    api.add_curve_guide(obj, gp, mode="hard", tolerance=0.02)
    result = api.solve(obj, n=4, order=2, align="none", write=False)
    assert api.guide_report(obj)["hard_constraints"] > 0
    faces = faces_along(V, F, start, d, 0.25 / 24)
    faces = faces[(V[F].mean(axis=1)[faces, 0] > 0.25) & (V[F].mean(axis=1)[faces, 0] < 0.9)]
    dev = line_deviation(result, faces, d)
    assert len(faces) >= 8 and max(dev) < 1.0, (len(faces), max(dev) if dev else None)
