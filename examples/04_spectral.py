"""04: spectral mode, where changing the alignment strength costs milliseconds (no new factorization).

    PYTHONPATH=addon .venv/bin/python examples/04_spectral.py     (from the repository root;
    or with nfield pip-installed: python examples/04_spectral.py)

The first k eigenfields are computed once (cached on disk by mesh content); every solve is then a reduced
solve of k unknowns, so the alignment strength can be dragged live. The result is the low-pass
approximation of the exact spline: compare the two (docs/math.md: spectral reduction).
"""
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

from nfield.core import DesignSession, Mesh  # noqa: E402

mesh = Mesh.from_file(ROOT / "tests" / "data" / "fandisk.obj")  # 6.5k vertices, 12.9k faces
settings = dict(n=4, order=2, align="curvature-max", strength=1.0)
with tempfile.TemporaryDirectory() as cache:  # a private cache: the example always computes its basis
    spectral = DesignSession(mesh, mode="spectral", k=60, cache_dir=cache, **settings)
    info = spectral.precompute()
    print(f"basis: k = {info.k} eigenfields ({info.source}) in {info.seconds:.1f} s, "
          f"{info.memory_bytes / 2**20:.1f} MB")
    spectral.set_direction(1000, (0.0, 0.0, 1.0))
    for strength in (0.1, 1.0, 10.0, 100.0):
        spectral.configure(strength=strength)
        t0 = time.perf_counter()
        r = spectral.solve(details=False)  # details=False: no energy / singularity post-processing
        print(f"strength {strength:6g}: reduced solve in {1e3 * (time.perf_counter() - t0):.1f} ms"
              + (" (the first one also sets up the reduced system)" if strength == 0.1 else ""))

exact = DesignSession(mesh, mode="exact", **settings)
exact.set_direction(1000, (0.0, 0.0, 1.0))
exact.configure(strength=100.0)
e = exact.solve()
# How close the low-pass field is: the angle between the n-fields, face by face (mod 2 pi / n).
a, b = r.representation, e.representation
angle = np.abs(np.angle(a * np.conj(b))) / 4
print(f"spectral vs exact: median {np.degrees(np.median(angle)):.2f} deg, "
      f"90th percentile {np.degrees(np.percentile(angle, 90)):.2f} deg")
