"""The demo (examples/demo/demo.py, what ``build_addon.py demo`` runs) works end to end, at a tiny size.

It runs as the README says (in its own process of this Python, with the package the Blender suite tests first on
PYTHONPATH: the installed extension's in the Blender legs), at 128 x 72 pixels with
one sample, and its JSON summary is checked: the design is the one the README describes (n = 2, least
curvature, four constraints, the +1/2 singularity), feature alignment found the rims (the 20-degree
threshold: about 3,700 edges of the rocker arm), the hatching has strokes, every picture is a PNG of the
asked size and the .blend was saved. Marked slow: about 20 s, and what it runs is covered piece by piece by
the headless Blender tests (material, hatching, features); this test keeps the demo itself from rotting.
"""
from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest
from blender_support import nf, script_env  # noqa: F401  (fixture)

pytestmark = [pytest.mark.blender, pytest.mark.slow]

ROOT = Path(__file__).resolve().parent.parent
DEMO = ROOT / "examples" / "demo" / "demo.py"
WIDTH, HEIGHT = 128, 72


def _png_size(path: Path) -> tuple[int, int]:
    with open(path, "rb") as fh:
        head = fh.read(24)
    assert head[:8] == b"\x89PNG\r\n\x1a\n", f"{path.name} is not a PNG"
    return struct.unpack(">II", head[16:24])


def test_demo_runs_and_renders(tmp_path, nf):
    import subprocess
    import sys

    env = script_env(nf, tmp_path / "profile")
    proc = subprocess.run([sys.executable, str(DEMO), "--out", str(tmp_path), "--size", f"{WIDTH}x{HEIGHT}",
                           "--samples", "1"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, f"demo failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    summary = json.loads(proc.stdout[proc.stdout.index("{\n"):])
    print(json.dumps({k: v for k, v in summary.items() if k != "files"}, indent=1))

    assert summary["faces"] == 20088 and summary["n"] == 2 and summary["align"] == "curvature-min"
    assert len(summary["constraints"]) == 4 and summary["singularities_pinned"][0][1] == 0.5
    features = summary["features"]
    assert features["mode"] == "soft" and features["angle"] == 20.0
    assert 3000 < features["edges"] < 4500, features  # 3,709 edges of rocker-arm.obj bend by more than 20 deg
    assert summary["hatching"]["strokes"] > 50
    pictures = ["demo_anisotropic", "demo_anisotropic_perpendicular", "demo_isotropic", "demo_anisotropic_strokes",
                "demo_hatching"]
    for name in pictures:
        assert _png_size(Path(summary["files"][name])) == (WIDTH, HEIGHT), name
    assert Path(summary["files"]["blend"]).stat().st_size > 100_000
