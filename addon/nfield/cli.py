"""Command line: ``python -m nfield {eig,solve,info,remesh} ...``.

Exit codes: 0 success; 2 expected failure (bad arguments or files, invalid constraints, solver errors,
out of memory),
printed as one line ``nfield: error: <reason>`` on stderr; 1 unexpected internal error (one line; set
NFIELD_DEBUG=1 for the traceback); 130 interrupted.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import traceback
from collections import Counter
from typing import Sequence

PROG = "nfield"
ALIGN_CLI_CHOICES = ("none", "curvature-max", "curvature-min")
WEIGHT_CLI_CHOICES = ("geometric", "combinatorial")
OUT_EXTENSIONS = (".npy", ".csv")


class CLIError(Exception):
    """An expected failure: reported as one line, exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2 (argparse would print the usage first)
        hint = f" (see '{self.prog} --help')"
        self.exit(2, f"{PROG}: error: {_one_line(message)}{hint}\n")


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


# ---------------------------------------------------------------------- argument types
def _convert(s: str, convert, must_be: str):
    """convert(s); a value it rejects is an argparse error "<must_be>, got '<s>'"."""
    try:
        return convert(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{must_be}, got '{s}'") from None


def _int_at_least(lo: int, name: str):
    def parse(s: str) -> int:
        v = _convert(s, int, f"{name} must be an integer")
        if v < lo:
            raise argparse.ArgumentTypeError(f"{name} must be >= {lo} (got {v})")
        return v
    return parse


def _order(s: str) -> int:
    v = _convert(s, int, "order must be an integer 1..4")
    if not 1 <= v <= 4:
        raise argparse.ArgumentTypeError(f"order must be 1, 2, 3 or 4 (got {v})")
    return v


# Admissible ranges, as in nfield.core.solve (kept here so that --help works without the compiled module).
MAX_N = 64
MIN_STRENGTH, MAX_STRENGTH = 1e-6, 1e6


def _symmetry(s: str) -> int:
    v = _convert(s, int, f"n must be an integer 1..{MAX_N}")
    if not 1 <= v <= MAX_N:
        raise argparse.ArgumentTypeError(f"n must be 1..{MAX_N} (got {v})")
    return v


def _strength(s: str) -> float:
    must = f"strength must be a finite number in [{MIN_STRENGTH:g}, {MAX_STRENGTH:g}]"
    v = _convert(s, float, must)
    if not (math.isfinite(v) and MIN_STRENGTH <= v <= MAX_STRENGTH):
        raise argparse.ArgumentTypeError(f"{must} (got {s})")
    return v


def _nonnegative(name: str):
    def parse(s: str) -> float:
        v = _convert(s, float, f"{name} must be a number >= 0")
        if not (math.isfinite(v) and v >= 0):
            raise argparse.ArgumentTypeError(f"{name} must be a finite number >= 0 (got {s})")
        return v
    return parse


def _finite_float(name: str):
    def parse(s: str) -> float:
        v = _convert(s, float, f"{name} must be a number")
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{name} must be a finite number (got {s})")
        return v
    return parse


def _feature_spec(s: str) -> str:
    for part in s.split(","):
        name, _, arg = part.strip().partition(":")
        if name == "boundary" and not arg:
            continue
        if name == "sharp":
            if arg:
                v = _convert(arg, float, f"sharp angle in '{part}' must be a number of degrees")
                if not (math.isfinite(v) and 0 <= v <= 179):
                    raise argparse.ArgumentTypeError(f"sharp angle must lie in [0, 179] degrees (got {arg})")
            continue
        raise argparse.ArgumentTypeError(f"unknown feature '{part}' (expected 'boundary' or 'sharp[:DEGREES]', "
                                         f"e.g. boundary,sharp:30)")
    return s


def _symmetry_spec(s: str) -> tuple:
    axis, _, tol = s.partition(":")
    if axis not in ("x", "y", "z"):
        raise argparse.ArgumentTypeError(f"symmetry axis must be x, y or z (got '{axis}')")
    t = 1e-5
    if tol:
        t = _convert(tol, float, "symmetry tolerance must be a number")
        if not (math.isfinite(t) and 0 <= t <= 0.1):
            raise argparse.ArgumentTypeError(f"symmetry tolerance must lie in [0, 0.1] (fraction of the diagonal; "
                                             f"got {tol})")
    return axis, t


def _out_path(s: str) -> str:
    ext = os.path.splitext(s)[1].lower()
    if os.path.isdir(s) or s.endswith(("/", os.sep)):
        raise argparse.ArgumentTypeError(
            f"'{s}' is a directory: --out takes a file name ending in .npy (numpy) or .csv (text)")
    if ext not in OUT_EXTENSIONS:
        raise argparse.ArgumentTypeError(
            f"unsupported output extension '{ext or s}' (use .npy for numpy or .csv for text)")
    return s


# ---------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog=PROG, description="Design n-symmetry direction fields (n-field splines) on triangle "
                "meshes (OBJ, OFF, PLY).",
                epilog="Exit codes: 0 ok, 2 bad input or solver failure, 1 internal error "
                       "(NFIELD_DEBUG=1 prints the traceback).")
    sub = p.add_subparsers(dest="command", metavar="{eig,solve,info,remesh}")

    e = sub.add_parser("eig", help="lowest eigenvalues of the connection Laplacian (JSON)",
                       description="Print {\"eigenvalues\": [...]}: the K smallest eigenvalues of S z = lambda M z "
                                   "for n-vector fields (complex form: each eigenvalue once, ascending).")
    e.add_argument("mesh", metavar="MESH", help="mesh file (.obj, .off, .ply)")
    e.add_argument("--n", type=_symmetry, required=True, help=f"symmetry order (1..{MAX_N})")
    e.add_argument("--k", type=_int_at_least(1, "k"), default=10, help="number of eigenvalues (default 10)")
    e.add_argument("--weights", choices=WEIGHT_CLI_CHOICES, default="geometric",
                   help="edge weights (default geometric)")
    e.set_defaults(func=cmd_eig)

    s = sub.add_parser("solve", help="design an n-direction field",
                       description="Solve for an n-direction field spline with optional alignment, direction/"
                                   "vector constraints and singularities. Constraint faces are input faces "
                                   "(polygons for polygon OBJ files).",
                       epilog='Files: --constraints [{"face": 12, "direction": [x, y, z]}], '
                              '--vector-constraints [{"face": 3, "vector": [x, y, z]}], '
                              '--singularities [{"vertex": 7, "index": 0.25}]. '
                              "--out writes one unit 3D direction (the first of the n) per input face: "
                              ".npy (float64 F x 3) or .csv (x,y,z per line).")
    s.add_argument("mesh", metavar="MESH", help="mesh file (.obj, .off, .ply)")
    s.add_argument("--n", type=_symmetry, required=True, help=f"symmetry order (1..{MAX_N}), e.g. 4")
    s.add_argument("--order", type=_order, default=2, help="energy order 1..4 (default 2, biharmonic)")
    s.add_argument("--align", choices=ALIGN_CLI_CHOICES, default="none", help="alignment field (default none)")
    s.add_argument("--strength", type=_strength, default=1.0, help=f"alignment strength in [{MIN_STRENGTH:g}, {MAX_STRENGTH:g}] (default 1)")
    s.add_argument("--weights", choices=WEIGHT_CLI_CHOICES, default="geometric",
                   help="edge weights (default geometric)")
    s.add_argument("--constraints", metavar="C.json", help="direction constraints")
    s.add_argument("--vector-constraints", metavar="V.json", help="vector constraints")
    s.add_argument("--singularities", metavar="S.json", help="singularity constraints")
    s.add_argument("--out", metavar="FIELD.npy|FIELD.csv", type=_out_path, help="write the field")
    s.add_argument("--json", action="store_true", help="print a JSON summary instead of text")
    g = s.add_argument_group("guides (docs/guides.md)")
    g.add_argument("--align-features", metavar="SPEC", type=_feature_spec,
                   help="follow feature edges: 'boundary', 'sharp[:DEGREES]' (default 30) or both, e.g. "
                        "boundary,sharp:30")
    g.add_argument("--feature-mode", choices=("soft", "hard"), default="soft",
                   help="soft: weighted alignment near the features; hard: direction constraints on the faces "
                        "along them (default soft)")
    g.add_argument("--feature-weight", type=_nonnegative("feature weight"), default=1.0,
                   help="soft mode: weight relative to the base alignment (default 1)")
    g.add_argument("--feature-width", type=_int_at_least(1, "feature width"), default=2,
                   help="soft mode: width in edge rings (default 2)")
    g.add_argument("--feature-every", type=_int_at_least(1, "feature every"), default=1,
                   help="hard mode: constrain the faces of every k-th edge along each feature (default 1)")
    g.add_argument("--alignment-weight", metavar="W.npy|W.csv",
                   help="per-face weight (>= 0) of the --align field, one number per input face")
    g.add_argument("--alignment-rotation", metavar="R.npy|R.csv",
                   help="per-face angle (radians) turning the --align field, one number per input face")
    g.add_argument("--curves", metavar="CURVES.json",
                   help='curve guides: [{"points": [[x, y, z], ...], "mode": "soft"|"hard", "weight": 1, '
                        '"width": 0.02, "tolerance": 0.01, "every": 1, "name": "..."}] (lengths: fractions of '
                        'the bounding-box diagonal)')
    g.add_argument("--cuts", metavar="CUTS.json|CUTS.npy",
                   help="edges where the field may jump: vertex pairs [[a, b], ...]")
    g.add_argument("--symmetry", metavar="AXIS[:TOL]", type=_symmetry_spec,
                   help="mirror symmetry about the plane AXIS = 0 (x, y or z), vertices matched within TOL of "
                        "the bounding-box diagonal (default 1e-5)")
    g.add_argument("--symmetry-offset", type=_finite_float("symmetry offset"), default=0.0,
                   help="the mirror plane is AXIS = OFFSET (mesh units, default 0)")
    g.add_argument("--symmetry-partial", action="store_true",
                   help="apply the symmetry to the faces that have a mirror partner instead of refusing")
    s.set_defaults(func=cmd_solve)

    i = sub.add_parser("info", help="mesh report (JSON)",
                       description="Print what the mesh reader and validator found, as JSON.")
    i.add_argument("mesh", metavar="MESH", help="mesh file (.obj, .off, .ply)")
    i.set_defaults(func=cmd_info)

    r = sub.add_parser("remesh", help="quad remesh along a cross field",
                       description="Quad-dominant (or pure quad) remesh whose edges follow a cross field: the field "
                                   "designed here (curvature-aligned biharmonic 4-field, with --constraints and "
                                   "--singularities) or read from --field. Writes a polygon OBJ and prints the "
                                   "quality statistics.",
                       epilog="--field FIELD.npy|.csv: one 3D vector per input face (as written by 'solve --out'); "
                              "with --n 1 or 2 the field and its perpendicular are used. Exit code 2 when the mesh "
                              "cannot be remeshed (the message names the reason).")
    r.add_argument("mesh", metavar="MESH", help="mesh file (.obj, .off, .ply)")
    src = r.add_mutually_exclusive_group()
    src.add_argument("--field", metavar="FIELD.npy", help="per-face field directions (F x 3)")
    src.add_argument("--constraints", metavar="C.json", help="direction constraints of the designed field")
    r.add_argument("--singularities", metavar="S.json", help="singularity constraints of the designed field")
    r.add_argument("--n", type=_symmetry, default=4, help="symmetry of --field: 1, 2 or 4 (default 4)")
    r.add_argument("--align", choices=ALIGN_CLI_CHOICES, default="curvature-max",
                   help="alignment of the designed field (default curvature-max)")
    size = r.add_mutually_exclusive_group(required=True)
    size.add_argument("--faces", type=_int_at_least(1, "faces"), help="target number of output faces")
    size.add_argument("--edge-length", type=_strength_free_positive, help="target edge length (mesh units)")
    r.add_argument("--pure-quads", action="store_true",
                   help="quads only (the odd faces paired by half rows of quads at the target edge length)")
    r.add_argument("--pure-quad-method", choices=("pair", "subdivide"), default="pair",
                   help="with --pure-quads: pair (default) or subdivide (one subdivision step of a lattice twice "
                        "as coarse: fewer irregular vertices, further from the input)")
    r.add_argument("--pure-quad-cones", choices=("best", "pinned", "free"), default="best",
                   help="with --pure-quads pair: pin the field's singularities to lattice points, leave them free, "
                        "or try both and keep the better (default best: twice the work, on two threads)")
    r.add_argument("--sharp-angle", type=float, default=40.0,
                   help="keep edges with a dihedral angle above this many degrees (default 40; 0: none)")
    r.add_argument("--no-boundary", action="store_true", help="do not keep boundaries as feature curves")
    r.add_argument("--seed", type=_int_at_least(0, "seed"), default=0, help="random seed (default 0)")
    r.add_argument("--strict", action="store_true", help="refuse meshes with components too small for the target")
    r.add_argument("--out", metavar="OUT.obj", required=True, help="output polygon mesh (.obj)")
    r.add_argument("--json", action="store_true", help="print the statistics as JSON")
    r.set_defaults(func=cmd_remesh)
    return p


def _strength_free_positive(s: str) -> float:
    v = _convert(s, float, "edge length must be a positive number")
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"edge length must be a positive finite number (got {s})")
    return v


# ---------------------------------------------------------------------- commands
def _load_mesh(path: str):
    from .core import Mesh

    return Mesh.from_file(path)


def _dump(obj) -> str:
    return json.dumps(obj, allow_nan=False)


def cmd_eig(args) -> int:
    from .core import eigenvalues

    mesh = _load_mesh(args.mesh)
    vals = eigenvalues(mesh, args.n, args.k, weights=args.weights)
    print(_dump({"eigenvalues": [float(v) for v in vals]}))
    return 0


def cmd_info(args) -> int:
    mesh = _load_mesh(args.mesh)
    nm = mesh.native
    info = {
        "file": args.mesh,
        "vertices": mesh.num_vertices,
        "faces": mesh.num_faces,
        "triangles": mesh.num_triangles,
        "active_faces": int(nm.num_active_faces),
        "total_area": float(nm.total_area),
        "bounding_box_diagonal": float(nm.bounding_box_diagonal),
    }
    info.update(mesh.report)
    print(_dump(info))
    return 0


def _write_field(path: str, directions) -> None:
    import numpy as np

    arr = np.ascontiguousarray(directions, dtype=np.float64)
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext == ".npy":
            np.save(path, arr)
        else:
            np.savetxt(path, arr, fmt="%.9g", delimiter=",")
    except OSError as exc:
        raise CLIError(f"cannot write {path}: {exc.strerror or exc}") from None


def _format_index(x: float, n: int) -> str:
    num = round(x * n)
    if num == 0:
        return "0"
    from fractions import Fraction

    f = Fraction(num, n)
    return f"{'+' if f > 0 else '-'}{abs(f)}"


def _load_on_mesh(load_constraints, path, kind: str, mesh) -> list:
    """The constraints of a JSON file, each face / vertex checked against the mesh: an index out of range
    names the file and the entry (the solver alone could only name the index)."""
    if not path:
        return []
    entries = load_constraints(path, kind=kind)
    for i, c in enumerate(entries):
        if kind == "singularity":
            if not 0 <= c.vertex < mesh.num_vertices:
                raise CLIError(f"{path}: entry {i}: vertex {c.vertex} is out of range: the mesh has "
                               f"{mesh.num_vertices} vertices (valid indices 0..{mesh.num_vertices - 1})")
        elif not 0 <= c.face < mesh.num_faces:
            raise CLIError(f"{path}: entry {i}: face {c.face} is out of range: the mesh has {mesh.num_faces} "
                           f"faces (valid indices 0..{mesh.num_faces - 1})")
    return entries


def cmd_solve(args) -> int:
    from .core import load_constraints, solve

    if args.out:
        parent = os.path.dirname(os.path.abspath(args.out))
        if not os.path.isdir(parent):
            raise CLIError(f"cannot write {args.out}: directory {parent} does not exist")
    mesh = _load_mesh(args.mesh)
    dirs = _load_on_mesh(load_constraints, args.constraints, "direction", mesh)
    vecs = _load_on_mesh(load_constraints, args.vector_constraints, "vector", mesh)
    sings = _load_on_mesh(load_constraints, args.singularities, "singularity", mesh)
    guides = _guide_arguments(args, mesh)
    result = solve(mesh, n=args.n, order=args.order, align=args.align, strength=args.strength,
                   constraints=dirs, vector_constraints=vecs, singularities=sings, weights=args.weights, **guides)
    if args.out:
        _write_field(args.out, result.directions)
    if args.json:
        print(_dump(result.to_dict()))
        return 0
    counts = Counter(_format_index(i, result.n) for _, i in result.singularities)
    by_index = ", ".join(f"{k}: {counts[k]}" for k in sorted(counts, key=lambda s: _frac_value(s)))
    lines = [
        f"nfield: {result.n}-direction field, order {result.order}, align {result.align} "
        f"on {os.path.basename(args.mesh)}",
        f"faces: {result.num_faces}",
        f"energy: {result.energy:.6g}",
        f"singularities: {len(result.singularities)}" + (f" (index {by_index})" if by_index else ""),
    ]
    if result.sign_fixed_faces:
        lines.append(f"sign-fixed constraint faces: {len(result.sign_fixed_faces)}")
    for line in result.mesh_report.get("summary", []) or []:
        lines.append(f"mesh: {line}")
    if result.guides is not None:
        lines.extend(f"guides: {line}" for line in result.guides.summary())
    lines.append(f"time: {result.seconds:.3f} s")
    if args.out:
        lines.append(f"wrote {args.out}")
    print("\n".join(lines))
    return 0


def _per_face_file(path: str, what: str, num_faces: int):
    """One number per input face from .npy or a text file (.csv / .txt: numbers separated by commas or
    whitespace)."""
    import numpy as np

    try:
        arr = np.load(path) if path.lower().endswith(".npy") else np.loadtxt(path, delimiter=None if not path.lower().endswith(".csv") else ",", ndmin=1)
    except OSError as exc:
        raise CLIError(f"cannot read {what} file {path}: {exc.strerror or exc}") from None
    except ValueError as exc:
        raise CLIError(f"{what} file {path}: {_one_line(exc)}") from None
    arr = np.asarray(arr, dtype=np.float64).ravel()
    if arr.shape != (num_faces,):
        raise CLIError(f"{what} file {path} has {arr.size} numbers; the mesh has {num_faces} faces (one each)")
    return arr


def _json_file(path: str, what: str):
    try:
        with open(path, encoding="utf-8") as fh:
            return json.load(fh)
    except OSError as exc:
        raise CLIError(f"cannot read {what} file {path}: {exc.strerror or exc}") from None
    except json.JSONDecodeError as exc:
        raise CLIError(f"{what} file {path} is not valid JSON: {exc.msg} (line {exc.lineno})") from None


def _guide_arguments(args, mesh) -> dict:
    """The guide keywords of nfield.core.solve from the command line (only those given)."""
    import numpy as np

    from .core.guides import CurveGuide, Symmetry, parse_features

    out: dict = {}
    if args.align_features:
        out["features"] = parse_features(args.align_features, mode=args.feature_mode, weight=args.feature_weight,
                                         width=args.feature_width, every=args.feature_every)
    if args.alignment_weight:
        out["alignment_weight"] = _per_face_file(args.alignment_weight, "alignment weight", mesh.num_faces)
    if args.alignment_rotation:
        out["alignment_rotation"] = _per_face_file(args.alignment_rotation, "alignment rotation", mesh.num_faces)
    if args.cuts:
        if args.cuts.lower().endswith(".npy"):
            try:
                out["cuts"] = np.load(args.cuts)
            except (OSError, ValueError) as exc:
                raise CLIError(f"cannot read cuts file {args.cuts}: {_one_line(exc)}") from None
        else:
            out["cuts"] = _json_file(args.cuts, "cuts")
    if args.curves:
        items = _json_file(args.curves, "curves")
        if not isinstance(items, list):
            raise CLIError(f"curves file {args.curves} must hold a JSON list of curves")
        curves = {}
        for i, item in enumerate(items):
            if not isinstance(item, dict) or "points" not in item:
                raise CLIError(f"curves file {args.curves}: curve {i} must be an object with \"points\"")
            opts = {k: item[k] for k in ("mode", "weight", "width", "tolerance", "every") if k in item}
            unknown = set(item) - set(opts) - {"points", "name"}
            if unknown:
                raise CLIError(f"curves file {args.curves}: curve {i} has unknown key(s) {sorted(unknown)}")
            try:
                curves[str(item.get("name", i))] = CurveGuide(item["points"], **opts)
            except (TypeError, ValueError) as exc:
                raise CLIError(f"curves file {args.curves}: curve {i}: {_one_line(exc)}") from None
        out["curves"] = curves
    if args.symmetry:
        axis, tol = args.symmetry
        out["symmetry"] = Symmetry(axis, args.symmetry_offset, tol, args.symmetry_partial)
    return out


def _read_field(path: str):
    import numpy as np

    if not os.path.exists(path):
        raise CLIError(f"field file not found: {path}")
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext == ".npy":
            arr = np.load(path, allow_pickle=False)
        elif ext == ".csv":
            arr = np.loadtxt(path, delimiter=",", ndmin=2)
        else:
            raise CLIError(f"unsupported field file '{ext or path}' (use .npy or .csv)")
    except (OSError, ValueError) as exc:
        raise CLIError(f"cannot read field {path}: {_one_line(str(exc))}") from None
    return arr


def cmd_remesh(args) -> int:
    from .core import load_constraints, quad_remesh, solve, write_polygon_obj

    if os.path.splitext(args.out)[1].lower() != ".obj":
        raise CLIError(f"unsupported output '{args.out}' (remesh writes .obj)")
    parent = os.path.dirname(os.path.abspath(args.out))
    if not os.path.isdir(parent):
        raise CLIError(f"cannot write {args.out}: directory {parent} does not exist")
    mesh = _load_mesh(args.mesh)
    if args.field:
        if args.singularities:
            raise CLIError("--singularities designs a field; it cannot be combined with --field")
        field = _read_field(args.field)
        n = args.n
    else:
        dirs = load_constraints(args.constraints, kind="direction") if args.constraints else []
        sings = load_constraints(args.singularities, kind="singularity") if args.singularities else []
        field = solve(mesh, n=4, order=2, align=args.align, constraints=dirs, singularities=sings)
        n = None
    V, faces, stats = quad_remesh(mesh, field, n=n, target_faces=args.faces, edge_length=args.edge_length,
                                  pure_quads=args.pure_quads, pure_quad_method=args.pure_quad_method,
                                  pure_quad_cones=args.pure_quad_cones,
                                  keep_boundary=not args.no_boundary,
                                  sharp_angle=args.sharp_angle, seed=args.seed, strict=args.strict)
    try:
        write_polygon_obj(args.out, V, faces)
    except OSError as exc:
        raise CLIError(f"cannot write {args.out}: {exc.strerror or exc}") from None
    summary = {k: v for k, v in stats.items() if k not in ("irregular_vertex_list", "vertex_feature_kind")}
    if args.json:
        print(_dump(summary))
        return 0
    lines = [
        f"nfield: remeshed {os.path.basename(args.mesh)} -> {args.out}",
        f"faces: {stats['num_faces']} ({100 * stats['quad_fraction']:.1f}% quads), vertices: {stats['num_vertices']}",
        f"irregular vertices: {stats['irregular_vertices']} (field singularities: {stats.get('field_singularities')})",
        f"alignment to the field: mean {stats['alignment_mean_deg']:.2f} deg, 95th percentile "
        f"{stats['alignment_p95_deg']:.2f} deg",
        f"Hausdorff distance: {100 * stats['hausdorff_relative']:.3f}% of the bounding-box diagonal",
        f"min scaled Jacobian: {stats['min_scaled_jacobian']:.3f}, manifold: {stats['manifold']}, "
        f"oriented: {stats['oriented']}",
    ]
    lines += [f"note: {m}" for m in stats["messages"]]
    lines.append(f"time: {stats['seconds']:.3f} s")
    print("\n".join(lines))
    return 0


def _frac_value(s: str) -> float:
    from fractions import Fraction

    return float(Fraction(s))


# ---------------------------------------------------------------------- entry point
def _silence_stdout() -> None:
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # stdout without a file descriptor (embedded): nothing left to flush there
        pass


def main(argv: Sequence[str] | None = None) -> int:
    debug = os.environ.get("NFIELD_DEBUG", "") not in ("", "0")
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or a parse error (2, already printed)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    if getattr(args, "func", None) is None:
        sys.stderr.write(f"{PROG}: error: missing command: choose one of eig, solve, info, remesh "
                         f"(see '{PROG} --help')\n")
        return 2
    from .core import NativeModuleError

    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        sys.stderr.write(f"{PROG}: interrupted\n")
        return 130
    except BrokenPipeError:
        # The reader went away (`nfield ... | head`): stop quietly, as a C tool killed by SIGPIPE would. Point
        # stdout at /dev/null so that the interpreter's final flush does not raise again.
        _silence_stdout()
        return 128 + 13
    except MemoryError as exc:  # std::bad_alloc in the solver: an expected failure on too large input
        if debug:
            traceback.print_exc()
        sys.stderr.write(f"{PROG}: error: out of memory ({_one_line(str(exc)) or 'MemoryError'}): the mesh or the "
                         f"number of constraints is too large for this machine\n")
        return 2
    except (CLIError, ValueError, RuntimeError, OSError, NativeModuleError) as exc:
        if debug:
            traceback.print_exc()
        msg = _one_line(str(exc)) or type(exc).__name__
        if isinstance(exc, OSError) and exc.filename and exc.strerror and str(exc.filename) not in msg:
            msg = f"{exc.strerror}: {exc.filename}"
        sys.stderr.write(f"{PROG}: error: {msg}\n")
        return 2
    except Exception as exc:  # noqa: BLE001 - last resort: one line, no traceback unless debugging
        if debug:
            traceback.print_exc()
        sys.stderr.write(f"{PROG}: internal error: {type(exc).__name__}: {_one_line(str(exc))} "
                         f"(set NFIELD_DEBUG=1 for the traceback)\n")
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
