#!/bin/sh
# 05: the command line (python -m nfield) on the rocker arm with the example constraint files.
#
#     PYTHONPATH=addon sh examples/05_cli.sh     (from the repository root; PYTHON=... picks another
#     interpreter; with nfield pip-installed there, no PYTHONPATH)
#
# Constraint files are JSON lists (see README.md: Command line). Bad arguments exit with code 2 and a
# one-line message; this script stops at the first failing command.
set -eu
PYTHON=${PYTHON:-.venv/bin/python}
# nfield as installed, or this checkout's with PYTHONPATH=addon (tests/test_examples.py sets it)
MESH=tests/data/rocker-arm.obj
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT

# the mesh report: counts, boundaries, components, anything dropped or repaired
"$PYTHON" -m nfield info "$MESH" | head -c 400; echo

# the 6 lowest eigenvalues of the connection Laplacian for a line field (n = 2)
"$PYTHON" -m nfield eig "$MESH" --n 2 --k 6

# a curvature-aligned line field through the example constraints and the pinned +1/2 singularity,
# one direction per face into a .npy file, and a summary
"$PYTHON" -m nfield solve "$MESH" --n 2 --order 2 --align curvature-max \
    --constraints examples/rocker_constraints.json --singularities examples/rocker_singularities.json \
    --out "$OUT/field.npy"
"$PYTHON" -c "
import numpy as np
f = np.load('$OUT/field.npy')  # one unit direction per face
print('field.npy:', f.shape)
assert np.allclose(np.linalg.norm(f, axis=1), 1.0)"
