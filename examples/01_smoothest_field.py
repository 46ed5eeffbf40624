"""01: the smoothest cross field of a sphere, its spectrum and its singularities.

    PYTHONPATH=addon .venv/bin/python examples/01_smoothest_field.py     (from the repository root;
    or with nfield pip-installed: python examples/01_smoothest_field.py)

The smoothest n-field is the first eigenvector of the connection Laplacian (docs/math.md). On the unit
sphere the eigenvalues tend to 2 (l (l + 1) - n^2) for l = n, n + 1, ..., the first one (2n) with 2n + 1
fields; a field without zeros has singularities whose indices sum to the Euler characteristic (2).
"""
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

from nfield.core import Mesh, eigenvalues, smoothest_field  # noqa: E402

n = 4
mesh = Mesh.from_file(ROOT / "tests" / "data" / "sphere.obj")  # 642 vertices, 1280 triangles, radius 1
print(f"mesh: {mesh.num_vertices} vertices, {mesh.num_faces} faces")

# The 12 lowest eigenvalues (complex form: each eigenvalue once, 1/length^2).
values = eigenvalues(mesh, n=n, k=12)
print("lowest eigenvalues:", " ".join(f"{v:.3f}" for v in values))
print(f"  continuum: 2n = {2 * n} with multiplicity 2n + 1 = {2 * n + 1}, "
      f"then 2((n+1)(n+2) - n^2) = {2 * ((n + 1) * (n + 2) - n * n)}")
assert abs(values[0] / (2 * n) - 1) < 0.05  # this coarse sphere is within a few percent of the continuum

# The smoothest field: one unit direction per face (the first of the n), and where it turns around.
field = smoothest_field(mesh, n=n)
print(f"first face's direction: {field.directions[0].round(3)}")
total = sum(index for _, index in field.singularities)
print(f"{len(field.singularities)} singularities, e.g. {field.singularities[:4]}, indices sum to {total:g}")
assert abs(total - 2.0) < 1e-9  # Poincare-Hopf on a sphere
