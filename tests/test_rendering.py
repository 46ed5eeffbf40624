"""Anisotropic shading renders the field (Cycles, CPU, 64 x 64, 16 samples, fixed seeds).

The scene: a flat 2 x 2 grid (20 x 20 quads) with a line field (n = 2, no alignment, one hard direction
constraint, so the whole field equals the constraint), a metallic Principled material built by
``nfield.blender.build_anisotropic_material`` (roughness 0.4), a camera looking down at 45 degrees and a
small area light placed so its mirror highlight lands in the middle of the image. With anisotropy the
highlight is an ellipse stretched along the field; rotating the constraint by 90 degrees (re-solve, rewrite
the attributes) turns the ellipse.

Measurements (mean absolute difference of linear RGB over all pixels):

* noise floor: the same state rendered with two seeds (Cycles sampling noise at 16 spp), and the same state
  rendered twice with the same seed (must be identical: Cycles' CPU sampling is deterministic per seed);
* anisotropic, constraint rotated by 90 degrees: must exceed 5 x the noise floor. 5x is far above what
  sampling noise can produce (the seed-to-seed difference *is* the noise, and re-rendering the same state
  with the other seed would give about 1x), yet far below the measured ratio (about 65x with bpy 5.0.1), so the
  test is robust against small renderer changes;
* isotropic (anisotropy 0), constraint rotated: the tangent is not used, so the image must not change beyond
  noise: below 0.5 x the noise floor (measured: bit-identical, since the seed is the same);
* "perpendicular" with the original constraint equals "field" with the rotated one (on a plane
  cross(normal, d) is d rotated by 90 degrees): below the noise floor;
* the object rotated by 90 degrees about Z with the original constraint renders like the unrotated object
  with the rotated constraint (the tangent is transformed from object to world space): below the noise floor
  (both measured bit-identical: Cycles' anisotropic GGX does not depend on the tangent's sign).

The renders run in a subprocess (this file run as a script) with the nfield that Blender installed from the
extension zip (the ``nf`` fixture of tests/blender_support.py) first on PYTHONPATH.
"""
from __future__ import annotations

import time
from pathlib import Path

import pytest
from blender_support import nf, run_script  # noqa: F401  (fixture)

pytestmark = pytest.mark.blender

SIZE = 64
SAMPLES = 16


# ------------------------------------------------------------------------------------------ the renderer
def _render_all(out_dir: Path) -> dict:
    import bpy
    import numpy as np

    import nfield.blender as nb
    from nfield.blender import material as nb_material

    bpy.ops.wm.read_factory_settings(use_empty=True)
    nb.register()
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"
    cy.samples = SAMPLES
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.max_bounces = 2
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.color_mode = "RGB"
    world = bpy.data.worlds.new("W")
    world.color = (0.02, 0.02, 0.02)
    scene.world = world

    bpy.ops.mesh.primitive_grid_add(x_subdivisions=20, y_subdivisions=20, size=2.0)
    obj = bpy.context.active_object
    from mathutils import Vector

    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.lens = 35
    scene.collection.objects.link(cam)
    cam.location = (0.0, -2.2, 2.2)
    cam.rotation_euler = (-Vector(cam.location)).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    light = bpy.data.objects.new("Light", bpy.data.lights.new("Light", "AREA"))
    light.data.energy = 60.0
    light.data.size = 0.2
    light.location = (0.0, 2.2, 2.2)
    light.rotation_euler = (-Vector(light.location)).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(light)

    face = 210  # a face in the middle of the grid
    d0, d1 = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)
    nb.configure(obj, n=2, order=2, align="none", live_update=False)

    def set_constraint(d):
        nb.add_constraint(obj, face, d)
        nb.solve(obj, write=True)

    set_constraint(d0)
    mat = nb.build_anisotropic_material(obj, anisotropy=0.9, roughness=0.4, metallic=1.0,
                                        base_color=(0.9, 0.9, 0.9, 1.0))
    timings = {}

    def render(name, seed=0):
        t = time.perf_counter()
        cy.seed = seed
        path = out_dir / f"{name}.exr"
        scene.render.filepath = str(path)
        bpy.ops.render.render(write_still=True)
        img = bpy.data.images.load(str(path))
        px = np.empty(SIZE * SIZE * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
        bpy.data.images.remove(img)
        np.save(out_dir / f"{name}.npy", px.reshape(SIZE, SIZE, 4)[:, :, :3])
        timings[name] = round(time.perf_counter() - t, 3)

    render("aniso_d0")
    render("aniso_d0_seed1", seed=1)
    render("aniso_d0_again")
    set_constraint(d1)
    render("aniso_d1")
    nb.build_anisotropic_material(obj, direction="perpendicular")
    set_constraint(d0)
    render("perp_d0")
    nb.build_anisotropic_material(obj, direction="field")
    obj.rotation_euler = (0.0, 0.0, np.pi / 2)
    render("aniso_d0_objrot90")
    obj.rotation_euler = (0.0, 0.0, 0.0)
    nb_material.build(obj, anisotropy=0.0)
    render("iso_d0")
    render("iso_d0_seed1", seed=1)
    set_constraint(d1)
    render("iso_d1")

    # structure of the material, for the asserts
    nt = mat.node_tree
    bsdf = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tangent = next(s for s in bsdf.inputs if s.identifier == "Tangent")
    chain = []
    sock = tangent
    while sock.is_linked:
        node = sock.links[0].from_node
        chain.append([node.bl_idname, getattr(node, "operation", None) or getattr(node, "convert_to", None)
                      or getattr(node, "attribute_name", None)])
        sock = node.inputs[0] if len(node.inputs) else None
        if sock is None:
            break
    # error on a material without an anisotropic BSDF
    emit = bpy.data.materials.new("EmitOnly")
    nb_material.ensure_nodes(emit)
    for n in list(emit.node_tree.nodes):
        if n.bl_idname != "ShaderNodeOutputMaterial":
            emit.node_tree.nodes.remove(n)
    emit.node_tree.nodes.new("ShaderNodeEmission")
    try:
        nb.build_anisotropic_material(obj, material="EmitOnly")
        missing_error = ""
    except ValueError as exc:
        missing_error = str(exc)
    # a material with Glossy and Metallic BSDFs: every Tangent is driven
    multi = bpy.data.materials.new("Multi")
    nb_material.ensure_nodes(multi)
    kinds = ["ShaderNodeBsdfGlossy"] + (["ShaderNodeBsdfMetallic"] if hasattr(bpy.types, "ShaderNodeBsdfMetallic")
                                        else [])
    for k in kinds:
        multi.node_tree.nodes.new(k)
    nb.build_anisotropic_material(obj, material="Multi", anisotropy=0.7)
    driven = {n.bl_idname: [next(s for s in n.inputs if s.identifier == "Tangent").is_linked,
                            next(s for s in n.inputs if s.identifier in nb_material.ANISOTROPIC_BSDFS[n.bl_idname])
                            .default_value]
              for n in multi.node_tree.nodes if n.bl_idname in nb_material.ANISOTROPIC_BSDFS}
    # the smoothed point attribute as the source; None arguments keep the material's settings
    obj.active_material = mat
    nb.build_anisotropic_material(obj, source="point", direction="perpendicular", anisotropy=0.3)
    nb.build_anisotropic_material(obj)
    point_source = [nt.nodes[nb_material.NODE_ATTR].attribute_name, mat["nfield_direction"],
                    mat["nfield_anisotropy"], obj.nfield.smooth_attribute]
    return {"timings": timings, "chain": chain, "missing_error": missing_error, "driven": driven,
            "point_source": point_source, "blender": bpy.app.version_string}


# ------------------------------------------------------------------------------------------ the test
def _mad(a, b) -> float:
    import numpy as np

    return float(np.abs(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)).mean())


def test_rotating_a_constraint_moves_the_anisotropic_highlight(tmp_path, nf):
    import numpy as np

    info, seconds = run_script(nf, Path(__file__).resolve(), tmp_path)
    img = {p.stem: np.load(p) for p in tmp_path.glob("*.npy")}

    assert img["aniso_d0"].mean() > 0.01, "the render is black: no light reaches the camera"
    noise = _mad(img["aniso_d0"], img["aniso_d0_seed1"])
    iso_noise = _mad(img["iso_d0"], img["iso_d0_seed1"])
    same_seed = _mad(img["aniso_d0"], img["aniso_d0_again"])
    moved = _mad(img["aniso_d0"], img["aniso_d1"])
    iso_moved = _mad(img["iso_d0"], img["iso_d1"])
    perp = _mad(img["perp_d0"], img["aniso_d1"])
    objrot = _mad(img["aniso_d0_objrot90"], img["aniso_d1"])
    report = (f"noise floor {noise:.5f} (isotropic {iso_noise:.5f}, same seed {same_seed:.2e}); rotated constraint: "
              f"anisotropic {moved:.5f} ({moved / noise:.1f} x noise), isotropic {iso_moved:.2e}; perpendicular vs "
              f"rotated {perp:.5f}; object rotated vs rotated constraint {objrot:.5f}; {seconds:.1f} s; {info}")
    print(report)
    assert noise > 0, report
    assert same_seed < 0.05 * noise, "the same seed must give the same image: " + report
    assert moved > 5 * noise, "rotating the constraint must move the anisotropic highlight: " + report
    assert iso_moved < 0.5 * iso_noise, "an isotropic material must not depend on the field: " + report
    assert perp < noise, "perpendicular of d must render like the field rotated by 90 degrees: " + report
    assert objrot < noise, "the tangent must be transformed from object to world space: " + report

    # node chain: Tangent <- Normalize <- Vector Transform (to world) <- Attribute (the face attribute)
    assert [c[0] for c in info["chain"]] == ["ShaderNodeVectorMath", "ShaderNodeVectorTransform",
                                             "ShaderNodeAttribute"], info["chain"]
    assert info["chain"][0][1] == "NORMALIZE" and info["chain"][1][1] == "WORLD"
    assert info["chain"][2][1] == "nfield_direction"
    assert "EmitOnly" in info["missing_error"] and "Tangent" in info["missing_error"], info["missing_error"]
    assert info["driven"] and all(linked and abs(a - 0.7) < 1e-6 for linked, a in info["driven"].values()), \
        info["driven"]
    attr, direction, amount, smooth = info["point_source"]
    assert attr == smooth and direction == "PERPENDICULAR" and abs(amount - 0.3) < 1e-6, info["point_source"]


if __name__ == "__main__":
    from conftest import bpy_script_main

    bpy_script_main(_render_all)
