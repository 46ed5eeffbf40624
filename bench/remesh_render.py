"""Renders of quad meshes for docs/quad_remeshing.md: wireframe over shaded, headless bpy (Workbench).

Each panel: the polygon mesh shaded in light grey (studio light) with its edges drawn as thin dark tubes (a
copy of the mesh with a Wireframe modifier), seen from a fixed direction fitted to the bounding box.
Panels are put side by side into one PNG with a title line drawn nowhere (captions live in the docs).

    render_panels([(V, faces), ...], "docs/images/remesh_bunny.png", view=(1, -1, 0.6))
"""
from __future__ import annotations

import math
import os
import tempfile

import numpy as np


def _clear(bpy):
    bpy.ops.wm.read_factory_settings(use_empty=True)


def _mesh_object(bpy, name, V, faces):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(map(float, v)) for v in V], [], [list(map(int, f)) for f in faces])
    me.update()
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def render_panel(V, faces, path, view=(1.0, -1.0, 0.6), size=(1000, 1000), wire_ratio=0.0012, y_up=False):
    """Render one panel to `path` (PNG). y_up: the mesh's up axis is +y (turned to +z first)."""
    import bpy
    from mathutils import Vector

    _clear(bpy)
    scene = bpy.context.scene
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.film_transparent = False
    shading = scene.display.shading
    shading.light = "STUDIO"
    shading.color_type = "OBJECT"
    shading.show_cavity = False
    scene.display.render_aa = "8"
    V = np.asarray(V, dtype=np.float64)
    if y_up:
        V = np.stack([V[:, 0], -V[:, 2], V[:, 1]], axis=1)
    lo, hi = V.min(0), V.max(0)
    centre = 0.5 * (lo + hi)
    diag = float(np.linalg.norm(hi - lo))
    surf = _mesh_object(bpy, "surface", V - centre, faces)
    surf.color = (0.78, 0.78, 0.76, 1.0)
    for p in surf.data.polygons:
        p.use_smooth = False
    wire = _mesh_object(bpy, "wire", V - centre, faces)
    wire.color = (0.05, 0.07, 0.12, 1.0)
    mod = wire.modifiers.new("wire", "WIREFRAME")
    mod.thickness = wire_ratio * diag
    mod.use_even_offset = False
    mod.use_replace = True
    mod.offset = 1.0  # outwards, so the wires sit on top of the surface
    cam_data = bpy.data.cameras.new("cam")
    cam_data.lens = 50
    cam = bpy.data.objects.new("cam", cam_data)
    scene.collection.objects.link(cam)
    d = Vector(view).normalized()
    # The bounding sphere (radius diag / 2) fits the 50 mm lens' narrower field of view (39.6 degrees) with a
    # small margin at 1.45 diag.
    cam.location = d * diag * 1.45
    cam.rotation_euler = (-d).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    scene.view_settings.view_transform = "Standard"
    scene.world = bpy.data.worlds.new("world")
    scene.world.color = (1.0, 1.0, 1.0)
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)


def compose(paths, out_path):
    """Side-by-side composite of PNGs of equal height (via bpy's image API)."""
    import bpy

    imgs = [bpy.data.images.load(str(p)) for p in paths]
    w = [im.size[0] for im in imgs]
    h = imgs[0].size[1]
    arrays = []
    for im in imgs:
        a = np.empty(im.size[0] * im.size[1] * 4, dtype=np.float32)
        im.pixels.foreach_get(a)
        arrays.append(a.reshape(im.size[1], im.size[0], 4))
    sep = np.ones((h, 8, 4), dtype=np.float32)
    sep[..., :3] = 0.6
    parts = []
    for i, a in enumerate(arrays):
        if i:
            parts.append(sep)
        parts.append(a)
    out = np.concatenate(parts, axis=1)
    img = bpy.data.images.new("composite", out.shape[1], out.shape[0], alpha=True)
    img.pixels.foreach_set(out.ravel())
    img.filepath_raw = str(out_path)
    img.file_format = "PNG"
    img.save()


def render_panels(meshes, out_path, view=(1.0, -1.0, 0.6), size=(1000, 1000), y_up=False):
    """meshes: list of (V, faces). Renders each panel and composes them left to right into out_path."""
    tmp = tempfile.mkdtemp(prefix="nfield_render_")
    paths = []
    for i, (V, faces) in enumerate(meshes):
        p = os.path.join(tmp, f"panel{i}.png")
        render_panel(V, faces, p, view=view, size=size, y_up=y_up)
        paths.append(p)
    compose(paths, out_path)
    return paths
