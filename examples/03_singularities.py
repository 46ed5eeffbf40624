"""03: pinning a singularity, and the indices a vertex can carry.

    PYTHONPATH=addon .venv/bin/python examples/03_singularities.py     (from the repository root;
    or with nfield pip-installed: python examples/03_singularities.py)

A DesignSession keeps the solver warm between edits. A vertex with k faces and angle defect K can carry
an index only where |index - K / 2pi| < k / (2n) (docs/math.md: the holonomy-corrected singularity
constraint); index_range says which. The pinned index is met exactly, and on a closed surface the indices
of all singularities still sum to the Euler characteristic.
"""
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

from nfield.core import DesignSession, Mesh  # noqa: E402

n = 4
mesh = Mesh.from_file(ROOT / "tests" / "data" / "sphere.obj")
session = DesignSession(mesh, n=n, order=2)
session.set_direction(0, (1.0, 0.0, 0.0))  # a hard direction constraint on face 0

vertex = 100
lo, hi = session.index_range(vertex)
ring = len(mesh.native.vertex_ring_faces(vertex))
print(f"vertex {vertex} ({ring} faces around it) can carry indices {lo:g} .. {hi:g} (multiples of 1/{n})")

for index in (0.5, -0.25):
    session.set_singularity(vertex, index)  # re-pins the same vertex
    result = session.solve()
    found = dict(result.singularities)
    total = sum(found.values())
    print(f"pinned {index:+g}: measured {found.get(vertex, 0):+g} at vertex {vertex}, "
          f"{len(found)} singularities summing to {total:g}")
    assert found.get(vertex) == index and abs(total - 2.0) < 1e-9

try:
    session.set_singularity(vertex, hi + 1.0 / n)  # one step too far: refused with the valid range
except ValueError as exc:
    print(f"refused: {exc}")
