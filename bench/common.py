"""Shared helpers of the benchmarks: test meshes (including the generated 4x-subdivided armadillo), random
hard direction constraints, load average / CPU time / peak memory bookkeeping, per-mesh subprocesses.

Mesh names are files of tests/data, or "armadillo-x4": tests/data/armadillo.obj with one step of midpoint
subdivision (every triangle -> 4; 86,482 -> 345,928 faces), generated in memory by `subdivide`.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
RESULTS = ROOT / "bench" / "results"
SUBDIVIDED = {"armadillo-x4": "armadillo.obj"}

if str(ROOT / "addon") not in sys.path:
    sys.path.insert(0, str(ROOT / "addon"))


def subdivide(P, T):
    """Midpoint subdivision: a new vertex at the middle of every edge, each triangle (a, b, c) replaced by
    (a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca) (orientation kept). Returns (positions, triangles)."""
    import numpy as np

    P = np.asarray(P, dtype=np.float64)
    T = np.asarray(T, dtype=np.int64)
    a, b, c = T[:, 0], T[:, 1], T[:, 2]
    half = np.stack([np.stack([a, b], 1), np.stack([b, c], 1), np.stack([c, a], 1)], 1).reshape(-1, 2)
    edges, inverse = np.unique(np.sort(half, axis=1), axis=0, return_inverse=True)
    mid = len(P) + inverse.reshape(-1, 3)  # (F, 3): vertex ids of the midpoints of ab, bc, ca
    ab, bc, ca = mid[:, 0], mid[:, 1], mid[:, 2]
    P2 = np.concatenate([P, 0.5 * (P[edges[:, 0]] + P[edges[:, 1]])])
    T2 = np.stack([np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1), np.stack([ca, bc, c], 1),
                   np.stack([ab, bc, ca], 1)], 1).reshape(-1, 3)
    return P2, T2.astype(np.int32)


def read_positions_triangles(nat, name: str):
    """(positions, triangles) of a test mesh or of a generated one (see the module docstring)."""
    if name in SUBDIVIDED:
        P, T, _, _ = nat.read_mesh(str(DATA / SUBDIVIDED[name]))
        return subdivide(P, T)
    P, T, _, _ = nat.read_mesh(str(DATA / name))
    return P, T


def load_native_mesh(nat, name: str):
    P, T = read_positions_triangles(nat, name)
    return nat.Mesh(P, T)


def random_direction_constraints(ops, active, rng, count: int):
    """`count` distinct random faces among `active` with random unit tangent directions, as
    (faces, unit complex representations d)."""
    import numpy as np

    faces = rng.choice(active, size=count, replace=False)
    frames = ops.frames[faces]
    angles = rng.uniform(0, 2 * np.pi, size=count)
    vectors = np.cos(angles)[:, None] * frames[:, 0] + np.sin(angles)[:, None] * frames[:, 1]
    d = np.asarray(ops.tangent_to_representation(faces, vectors))
    return faces, d / np.abs(d)


def loadavg() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def cpu_seconds() -> float:
    """CPU time of this process, all threads, user + system."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


#: seconds to wait before a measured block (settle): longer than OpenBLAS's default spin of its worker threads
#: after a parallel call (2^28 cycles, ~0.1 s), which would otherwise be charged to the next block's CPU time
SETTLE_S = 0.3


def settle(seconds: float = SETTLE_S) -> None:
    """Lets the worker threads of the previous native call go idle before the next measured block."""
    time.sleep(seconds)


class Clock:
    """Wall and CPU time of a block: `with Clock() as c: ...; c.wall, c.cpu` (seconds)."""

    def __enter__(self):
        self._w, self._c = time.perf_counter(), cpu_seconds()
        return self

    def __exit__(self, *exc):
        self.wall = time.perf_counter() - self._w
        self.cpu = cpu_seconds() - self._c
        return False


def native_build() -> dict:
    """Which compiled module and sources were measured: the module's file, size and mtime, the git HEAD and
    whether native/ had uncommitted changes (other people may rebuild the module in this tree)."""
    info: dict = {}
    mods = sorted((ROOT / "addon" / "nfield").glob("_native*.so"))
    if mods:
        st = mods[0].stat()
        info.update(module=mods[0].name, module_bytes=st.st_size,
                    module_mtime=time.strftime("%Y-%m-%d %H:%M:%S %Z", time.localtime(st.st_mtime)))
    try:
        head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "native"], capture_output=True,
                               text=True, timeout=10).stdout.strip()
        info.update(git_head=head, native_sources_modified=bool(dirty))
    except (OSError, subprocess.SubprocessError):
        pass
    return info


def meta(**extra) -> dict:
    out = {"date": time.strftime("%Y-%m-%d %H:%M %Z"), "machine": platform.processor() or platform.machine(),
           "cpus": os.cpu_count(), "python": platform.python_version(), "loadavg": loadavg(),
           "build": native_build()}
    out.update(extra)
    return out


def run_child(script: Path, args: list[str], label: str, timeout: float | None = None) -> dict:
    """Runs `python script args...` in a fresh process (its own peak memory) and returns the JSON object
    printed on its last stdout line. RuntimeError with the child's stderr when it fails."""
    env = dict(os.environ, PYTHONPATH=str(ROOT / "addon") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, str(script), *args], stdout=subprocess.PIPE, text=True, env=env,
                          timeout=timeout)  # stderr (progress, errors) goes straight to ours
    if proc.returncode != 0:
        raise RuntimeError(f"{label}: failed (exit {proc.returncode}; its error is printed above)")
    print(f"{label}: done in {time.perf_counter() - t0:.0f} s (load {loadavg()[0]:.1f})", file=sys.stderr, flush=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def write_results(stem: str, doc: dict, markdown: str) -> None:
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{stem}.json").write_text(json.dumps(doc, indent=2))
    (RESULTS / f"{stem}.md").write_text(markdown)


def fmt_ms(seconds: float | None) -> str:
    """Seconds as a readable duration: '0.42 ms', '12.3 ms', '540 ms', '4.2 s', '2m05s'."""
    if seconds is None:
        return "-"
    ms = 1000.0 * seconds
    if ms < 1:
        return f"{ms:.2f} ms"
    if ms < 100:
        return f"{ms:.1f} ms"
    if seconds < 1:
        return f"{ms:.0f} ms"
    if seconds < 10:
        return f"{seconds:.2f} s"
    if seconds < 120:
        return f"{seconds:.1f} s"
    return f"{int(seconds // 60)}m{int(seconds % 60):02d}s"


def markdown_table(columns: list[str], rows: list[list[str]]) -> str:
    """A markdown table: the column titles, then one line per row of cells."""
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    return "\n".join(lines + ["| " + " | ".join(cells) + " |" for cells in rows])


def mesh_parser(doc: str, quick_help: str, meshes_help: str = "comma-separated meshes of tests/data"):
    """The options of a benchmark that measures each mesh in a child process: --quick, --meshes and the hidden
    --one (the mesh a child measures)."""
    parser = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help=quick_help)
    parser.add_argument("--meshes", help=meshes_help)
    parser.add_argument("--one", help=argparse.SUPPRESS)
    return parser


def chosen_meshes(args, meshes, quick_meshes) -> list[str]:
    """--meshes if given, else the quick or the full list."""
    return args.meshes.split(",") if args.meshes else list(quick_meshes if args.quick else meshes)


def run_children(script: Path, meshes: list[str], child_args: list[str], label: str) -> list[dict]:
    """run_child for every mesh (`--one mesh` + child_args), in order."""
    return [run_child(Path(script), ["--one", name, *child_args], f"{label} {name}") for name in meshes]


def repeats_main(doc: str, quick_help: str, *, measure_one, run, table, meshes, quick_meshes, stem: str) -> int:
    """main() of a benchmark whose only other option is --repeats (1 with --quick, else 3): a child measures one
    mesh and prints its JSON; the parent runs `run(meshes, repeats, stem)` and prints the document and `table`."""
    parser = mesh_parser(doc, quick_help)
    parser.add_argument("--repeats", type=int)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure_one(args.one, args.repeats or 3)))
        return 0
    repeats = args.repeats or (1 if args.quick else 3)
    result = run(chosen_meshes(args, meshes, quick_meshes), repeats, f"{stem}_quick" if args.quick else stem)
    print(json.dumps(result, indent=2))
    print(table(result["results"]))
    return 0
