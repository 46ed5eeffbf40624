"""Render set-ups of the demo and the README gallery (headless PyPI bpy, Cycles on the CPU).

Two looks, both framed by :func:`frame`:

* :func:`metal_studio`: brushed metal in a photo studio. A soft grey gradient world (the metal reflects it
  everywhere, so no part of the object is black) and three rectangular softboxes: a long strip light above
  and in front of the object, a square key light to the right and a rim strip behind it. An anisotropic
  material stretches the reflection of each softbox into a streak along the field, which the strip lights
  make easy to follow across the surface;
* :func:`paper_studio`: pen on paper for the hatching. A white world (the paper), a matte off-white object,
  one soft sun for a little form shading, the Standard view transform so that white stays white.

:func:`cycles` sets the render: fixed seed, a few samples, and OpenImageDenoise (part of PyPI bpy) on the
colour with albedo and normal passes, which cleans a 32-sample render without smearing the strokes.
"""
from __future__ import annotations

import math

import bpy
import numpy as np
from mathutils import Vector

__all__ = ["cycles", "bounds", "frame", "metal_studio", "paper_studio", "clear_lights", "render"]


def cycles(scene, width: int, height: int, samples: int, *, denoise: bool = True, threads: int = 0) -> None:
    """Cycles on the CPU at `width` x `height`, `samples` per pixel (fixed seed), denoised with
    OpenImageDenoise when `denoise`; `threads` 0 = all cores."""
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"
    cy.samples = samples
    cy.use_adaptive_sampling = False
    cy.seed = 0
    cy.use_denoising = denoise
    if denoise:
        cy.denoiser = "OPENIMAGEDENOISE"
        cy.denoising_input_passes = "RGB_ALBEDO_NORMAL"
    cy.max_bounces = 6
    cy.diffuse_bounces = 2
    cy.glossy_bounces = 4
    cy.transmission_bounces = 0
    cy.volume_bounces = 0
    cy.transparent_max_bounces = 4
    if threads:
        scene.render.threads_mode = "FIXED"
        scene.render.threads = threads
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    r.film_transparent = False
    settings = r.image_settings
    settings.file_format = "PNG"
    settings.color_mode = "RGB"
    settings.color_depth = "8"
    settings.compression = 100


def _view_transform(scene, name: str) -> None:
    try:  # a dynamic enum: its items cannot be listed without a context, so try the name
        scene.view_settings.view_transform = name
    except TypeError:  # AgX is new in Blender 4.0; Filmic is the older equivalent
        scene.view_settings.view_transform = "Filmic" if name == "AgX" else scene.view_settings.view_transform
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0


def bounds(obj) -> tuple[Vector, float]:
    """World-space centre of the bounding box of mesh object `obj` and half its diagonal."""
    me = obj.data
    v = np.empty(len(me.vertices) * 3, dtype=np.float32)
    me.vertices.foreach_get("co", v)
    mw = np.array(obj.matrix_world, dtype=np.float64)
    vw = v.reshape(-1, 3).astype(np.float64) @ mw[:3, :3].T + mw[:3, 3]
    lo, hi = vw.min(0), vw.max(0)
    return Vector(((lo + hi) / 2).tolist()), float(np.linalg.norm(hi - lo)) / 2


def frame(scene, obj, view_dir, *, lens: float = 50.0, margin: float = 0.1, roll: float = 0.0):
    """A camera looking at `obj` from direction `view_dir` (world, from the object towards the camera), turned
    by `roll` degrees about its axis, at the distance and with the lens shift that make the object's
    projection fill the frame up to `margin` (a fraction of the frame) on its tighter side, centred.
    Returns the camera object."""
    from mathutils import Quaternion

    center, radius = bounds(obj)
    data = bpy.data.cameras.new("Camera")
    data.lens = lens
    data.sensor_fit = "HORIZONTAL"
    cam = bpy.data.objects.new("Camera", data)
    scene.collection.objects.link(cam)
    d = Vector(view_dir).normalized()
    rot = (-d).to_track_quat("-Z", "Y") @ Quaternion((0.0, 0.0, 1.0), math.radians(roll))
    cam.rotation_euler = rot.to_euler()
    r = scene.render
    aspect = r.resolution_y / r.resolution_x
    tan_x = data.sensor_width / 2 / lens
    tan_y = tan_x * aspect
    me = obj.data
    v = np.empty(len(me.vertices) * 3, dtype=np.float32)
    me.vertices.foreach_get("co", v)
    mw = np.array(obj.matrix_world, dtype=np.float64)
    world = v.reshape(-1, 3).astype(np.float64) @ mw[:3, :3].T + mw[:3, 3]
    axes = np.array(rot.to_matrix(), dtype=np.float64)  # columns: camera x, y, z (looking along -z)
    local = (world - np.array(center)) @ axes  # camera frame, origin at the bounding-box centre
    dist = 3.0 * radius
    for _ in range(6):  # perspective: the fit depends on the distance; a few fixed-point steps converge
        depth = dist - local[:, 2]
        x, y = local[:, 0] / depth / tan_x, local[:, 1] / depth / tan_y  # normalised to [-1, 1]
        half = max((x.max() - x.min()) / 2, (y.max() - y.min()) / 2)
        dist *= half / (1.0 - margin)
    depth = dist - local[:, 2]
    x, y = local[:, 0] / depth / tan_x, local[:, 1] / depth / tan_y
    # lens shift in units of the larger frame side (the width here): centre the projection
    data.shift_x = (x.max() + x.min()) / 2 / 2
    data.shift_y = (y.max() + y.min()) / 2 / 2 * aspect
    cam.location = center + d * dist
    data.clip_start, data.clip_end = dist / 100, dist + 10 * radius
    scene.camera = cam
    return cam


def _world(scene, name: str, bottom, top, strength: float = 1.0):
    """A world whose colour goes from `bottom` (below the horizon) to `top` (zenith)."""
    world = bpy.data.worlds.get(name) or bpy.data.worlds.new(name)
    scene.world = world
    world.use_nodes = True
    nt = world.node_tree
    for node in [n for n in nt.nodes if n.bl_idname not in ("ShaderNodeBackground", "ShaderNodeOutputWorld")]:
        nt.nodes.remove(node)
    bg = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeBackground")
    coord = nt.nodes.new("ShaderNodeTexCoord")
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    nt.links.new(coord.outputs["Generated"], sep.inputs[0])
    nt.links.new(sep.outputs["Z"], ramp.inputs["Fac"])
    ramp.color_ramp.interpolation = "EASE"
    lo, hi = ramp.color_ramp.elements
    lo.position, lo.color = 0.35, (*bottom, 1.0)
    hi.position, hi.color = 1.0, (*top, 1.0)
    nt.links.new(ramp.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = strength
    return world


def _area(scene, name, center, radius, direction, energy, size, color=(1.0, 1.0, 1.0), distance=3.0):
    """A rectangular area light (`size` = (x, y) in units of `radius`) at `distance` x radius from `center`
    along `direction`, facing the centre. `energy` is scaled with the square of the distance, so a set-up
    looks the same on any mesh size."""
    data = bpy.data.lights.new(name, "AREA")
    data.shape = "RECTANGLE"
    data.size, data.size_y = size[0] * radius, size[1] * radius
    data.color = color
    d = Vector(direction).normalized()
    data.energy = energy * (distance * radius) ** 2
    light = bpy.data.objects.new(name, data)
    light.location = center + d * distance * radius
    light.rotation_euler = (-d).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(light)
    return light


def metal_studio(scene, obj, *, key=(0.9, -0.5, 0.9), strip=(0.1, -0.7, 1.0), rim=(-0.8, 0.7, 0.6)) -> None:
    """World and softboxes for brushed metal (see the module docstring); the light directions are world
    vectors from the object towards the light."""
    _view_transform(scene, "AgX")
    _world(scene, "Metal Studio", bottom=(0.07, 0.07, 0.08), top=(0.3, 0.31, 0.34))
    center, radius = bounds(obj)
    _area(scene, "Strip", center, radius, strip, 15.0, (3.0, 0.15))
    _area(scene, "Key", center, radius, key, 12.0, (0.6, 0.6), color=(1.0, 0.96, 0.9))
    _area(scene, "Rim", center, radius, rim, 12.0, (2.5, 0.12), color=(0.85, 0.9, 1.0))


def paper_studio(scene, obj, *, sun=(0.4, -0.6, 1.0), paper=(0.93, 0.92, 0.89)) -> None:
    """White world, one soft sun (see the module docstring)."""
    _view_transform(scene, "Standard")
    world = _world(scene, "Paper", bottom=paper, top=paper, strength=0.85)
    world.color = paper
    data = bpy.data.lights.new("Sun", "SUN")
    data.energy = 1.5
    data.angle = math.radians(20.0)
    sun_obj = bpy.data.objects.new("Sun", data)
    sun_obj.rotation_euler = (-Vector(sun).normalized()).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(sun_obj)


def clear_lights(scene) -> None:
    """Remove the lights (switching between the two looks)."""
    for obj in [o for o in scene.objects if o.type == "LIGHT"]:
        bpy.data.objects.remove(obj)


def render(scene, path) -> None:
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
