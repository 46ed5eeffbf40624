"""02: hard direction constraints on the rocker arm (the command line's example files).

    PYTHONPATH=addon .venv/bin/python examples/02_constraints.py     (from the repository root;
    or with nfield pip-installed: python examples/02_constraints.py)

A biharmonic (order 2) cross field through four hard direction constraints. A direction constraint says
"one of the n directions points along d", and nfield guarantees +d, not -d (docs/math.md: the +d
safeguard): the check below measures the angle between d and the nearest of the n directions.
"""
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

from nfield.core import Mesh, load_constraints, solve  # noqa: E402

mesh = Mesh.from_file(ROOT / "tests" / "data" / "rocker-arm.obj")  # 10k vertices, 20k faces
constraints = load_constraints(ROOT / "examples" / "rocker_constraints.json")
result = solve(mesh, n=4, order=2, constraints=constraints)
print(f"solved {result.num_faces} faces in {result.seconds:.2f} s, energy {result.energy:.4g}, "
      f"{len(result.singularities)} singularities")

all_dirs = result.all_directions()  # (faces, n, 3) unit directions
for c in constraints:
    d = np.asarray(c.direction, dtype=float)
    normal = mesh.native.face_normals[mesh.face_triangle(c.face)]
    d = d - normal * (d @ normal)  # the constraint acts on the tangent part of d
    d /= np.linalg.norm(d)
    cosines = all_dirs[c.face] @ d
    angle = np.degrees(np.arccos(np.clip(cosines.max(), -1.0, 1.0)))
    print(f"face {c.face:5d}: nearest direction is {angle:.2e} degrees from +d")
    assert angle < 1e-4  # exact up to rounding
