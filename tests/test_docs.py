"""Every code block of README.md and docs/*.md, run as written, so the docs cannot drift from the product.

* ``python`` blocks run in a fresh namespace after ``from nfield.core import *`` with the names the docs say
  they assume (docs/python_api.md: ``mesh``, ``face``, ``faces``, ``(x, y, z)``, ``vertex``, ``index``, ``cb``,
  ``field``), built here on the small sphere of tests/data (1,280 faces), from the repository root.
* ``sh`` blocks: each command line (continuations joined) runs when it is cheap and safe (the command line
  on a test mesh, an example script); otherwise the test prints why it is skipped (a placeholder such as
  MESH, or a command that installs packages, builds for minutes or fuzzes for an hour). A block whose every
  line is skipped is reported as skipped with those reasons.
* blocks without a language or marked ``text`` are listings (a directory tree, a data-flow sketch,
  signatures): skipped with that reason printed.
"""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT, package_env

# The sanitizer job runs a copy of tests/ without the docs beside it (the docs run the same native code the
# core tests run under ASan): the test is left out there, and collecting it must not fail.
pytestmark = pytest.mark.no_sanitizer
DOCS = [p for p in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))] if p.is_file()]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)

#: shell commands never run by this test, with the reason printed
SKIP_RULES = [
    (re.compile(r"build_addon\.py (demo|test|setup|bench|fuzz|sanitize)\b"),
     "installs packages and/or runs for minutes (covered by CI's own run of build_addon.py test)"),
    (re.compile(r"build_addon\.py (build|wheel|package)\b"),
     "rebuilds the native module (minutes); the suite runs on the built one"),
    (re.compile(r"\bpip install\b"), "installs packages (build_addon.py test runs `pip install .` in fresh "
                                      "virtual environments)"),
    (re.compile(r"^build/fuzz"), "runs a libFuzzer binary for up to an hour (docs/hardening.md)"),
    (re.compile(r"\b(MESH|OUT\.obj|C\.json|FIELD\.npy|N|K|M|T)\b(?![./\w])|\[--"),
     "a usage line with placeholders (MESH, N, [--option]), not a command"),
    (re.compile(r"<[a-z0-9]+>"), "a placeholder in angle brackets"),
]


#: python blocks not run yet, recognised by a line they contain, with the reason printed
PYTHON_SKIPS = {
    "from nfield.core.guides import FeatureGuide": "the guides listing uses inputs it does not define (w, theta, "
                                                   "pairs, points, directions); run by tests/test_guides*.py "
                                                   "instead, to be made runnable here",
}


#: blocks that run for seconds, recognised by a text they contain: marked `slow` (left out of `test --quick`;
#: the remesher's own tests cover the same code quickly)
SLOW_BLOCK_MARKERS = ("quad_remesh(", "nfield remesh ")


def _blocks():
    for path in DOCS:
        text = path.read_text(encoding="utf-8")
        for m in FENCE.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            slow = any(marker in m.group(2) for marker in SLOW_BLOCK_MARKERS)
            yield pytest.param(path, line, m.group(1), m.group(2), id=f"{path.relative_to(ROOT)}:{line}",
                               marks=[pytest.mark.slow] if slow else [])


def _has_native() -> bool:
    import importlib.util

    return importlib.util.find_spec("nfield._native") is not None


def _env(tmp_path) -> dict:
    env = package_env()
    env["NFIELD_CACHE_DIR"] = str(tmp_path / "bases")
    env["PYTHON"] = sys.executable  # the interpreter examples/05_cli.sh runs
    return env


def _commands(block: str) -> list[str]:
    lines, cur = [], ""
    for raw in block.splitlines():
        cur += raw.rstrip("\\").rstrip() + " " if raw.rstrip().endswith("\\") else raw
        if not raw.rstrip().endswith("\\"):
            if cur.strip():
                lines.append(cur.strip())
            cur = ""
    return lines


def _why_skip(cmd: str) -> str | None:
    code = cmd.split("#", 1)[0]
    for rule, why in SKIP_RULES:
        if rule.search(code):
            return why
    return None


def _python_namespace(tmp_path) -> dict:
    """The names docs/python_api.md says its blocks assume, on the 1,280-face sphere."""
    import nfield.core as core

    ns: dict = {}
    exec("from nfield.core import *", ns)  # noqa: S102 - what the docs say the blocks start from
    mesh = core.Mesh.from_file(str(ROOT / "tests" / "data" / "sphere.obj"))
    V = np.asarray(mesh.vertices, dtype=float)
    F = np.asarray(mesh.faces, dtype=int)
    face = 0
    e = V[F[face, 1]] - V[F[face, 0]]
    vertex = int(F[face, 0])
    ns.update(mesh=mesh, face=face, faces=list(range(40)), x=float(e[0]), y=float(e[1]), z=float(e[2]),
              vertex=vertex, index=0.25, cb=lambda fraction: True,
              field=core.solve(mesh, n=4, order=2))
    os.environ["NFIELD_CACHE_DIR"] = str(tmp_path / "bases")
    return ns


@pytest.mark.parametrize("path,line,lang,block", list(_blocks()))
def test_doc_code_block(path, line, lang, block, tmp_path, monkeypatch):
    where = f"{path.relative_to(ROOT)}:{line}"
    if lang in ("", "text"):
        reason = f"{where}: a listing (directory tree, data flow or signatures), not a program"
        print(f"SKIP: {reason}")
        pytest.skip(reason)
    if not _has_native():
        reason = "compiled module nfield._native is not built"
        print(f"SKIP: {where}: {reason}")
        pytest.skip(reason)
    monkeypatch.chdir(ROOT)
    if lang == "python":
        why = next((r for marker, r in PYTHON_SKIPS.items() if marker in block), None)
        if why:
            print(f"SKIP: {where}: {why}")
            pytest.skip(f"{where}: {why}")
        monkeypatch.setenv("NFIELD_CACHE_DIR", str(tmp_path / "bases"))
        ns = _python_namespace(tmp_path)
        exec(compile(block, where, "exec"), ns)  # noqa: S102 - the documented code, as written
        return
    assert lang == "sh", f"{where}: code block language {lang!r}: teach tests/test_docs.py how to run it"
    ran, skipped = [], []
    env = _env(tmp_path)
    for cmd in _commands(block):
        why = _why_skip(cmd)
        if why:
            skipped.append(f"{cmd.split('#')[0].strip()}: {why}")
            continue
        argv = shlex.split(cmd.split(" #", 1)[0])
        if argv[:1] == ["export"]:
            continue  # the environment is set up by this test (conftest.package_env)
        while argv and re.match(r"^[A-Z_]+=", argv[0]):  # VAR=value prefixes: the same environment
            argv.pop(0)
        argv = [sys.executable if a in ("python", ".venv/bin/python") else a for a in argv]
        if argv[:1] == ["nfield"]:  # the installed command line: the same as `python -m nfield` here
            argv[:1] = [sys.executable, "-m", "nfield"]
        if "--out" in argv:  # outputs go to the test's directory, not the repository
            i = argv.index("--out") + 1
            argv[i] = str(tmp_path / Path(argv[i]).name)
        proc = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, f"{where}: `{cmd}` failed ({proc.returncode}):\n{proc.stderr[-2000:]}"
        ran.append(cmd)
    for s in skipped:
        print(f"SKIP line of {where}: {s}")
    if not ran:
        pytest.skip(f"{where}: every command skipped: " + "; ".join(skipped))
