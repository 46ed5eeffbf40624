#!/usr/bin/env python3
"""Writes the seed corpora of the fuzz targets (native/fuzz/corpus/<target>/); run from anywhere.

The seeds are committed; this script documents how they were made and regenerates them byte-identically.
Each seed is small (a few hundred bytes): libFuzzer mutates them, so they only need to reach every branch
of the syntax once (keywords, index forms, list/count types, binary bodies) and every decoder mode of
the ingestion target. Pieces of real meshes come from tests/data/ (sources and licences in
tests/data/README.md): the first vertices of a file and the faces that use only those.
"""
from __future__ import annotations

import struct
from pathlib import Path

HERE = Path(__file__).resolve().parent
DATA = HERE.parent.parent.parent / "tests" / "data"


def write(target: str, name: str, content: bytes | str) -> None:
    folder = HERE / target
    folder.mkdir(exist_ok=True)
    (folder / name).write_bytes(content.encode() if isinstance(content, str) else content)


def piece(path: Path, max_vertices: int, max_faces: int) -> tuple[list[str], list[list[int]]]:
    """Up to max_faces faces (0-based, renumbered) among the first max_vertices vertices, and their vertex lines."""
    text = path.read_text()
    if path.suffix == ".obj":
        verts = [ln.split()[1:4] for ln in text.splitlines() if ln.startswith("v ")]
        faces = [[int(t.split("/")[0]) - 1 for t in ln.split()[1:]] for ln in text.splitlines() if ln.startswith("f ")]
    else:
        tok = text.split()
        nv, nf = int(tok[1]), int(tok[2])
        nums = tok[4:]
        verts = [nums[3 * i:3 * i + 3] for i in range(nv)]
        rest = nums[3 * nv:]
        faces = []
        for _ in range(nf):
            k = int(rest[0])
            faces.append([int(x) for x in rest[1:1 + k]])
            rest = rest[1 + k:]
    # The faces whose largest vertex index is smallest (stable), i.e. the first faces of the file's front.
    faces = sorted((f for f in faces if max(f) < max_vertices), key=max)[:max_faces]
    used = sorted({v for f in faces for v in f})
    remap = {v: i for i, v in enumerate(used)}
    return [" ".join(verts[v]) for v in used], [[remap[v] for v in f] for f in faces]


TETRA_V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
TETRA_F = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def obj_seeds() -> None:
    write("parse_obj", "tetra.obj", "# tetrahedron\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in TETRA_V)
          + "".join("f " + " ".join(str(i + 1) for i in f) + "\n" for f in TETRA_F))
    write("parse_obj", "index_forms.obj",
          "o quad\r\nv 0 0 0\r\nv 1 0 0 1.0\r\nv 1 1 0\r\nv +0 1e0 -0.0\r\nvt 0 0\nvn 0 0 1\ng a b\ns off\n"
          "usemtl m\nf 1/1/1 2/2/1 3//1 4\nf -4 -2 -1\nl 1 2\nf 1 2 3 4 # fan\n")
    write("parse_obj", "forward_reference.obj", "f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n")
    verts, faces = piece(DATA / "sphere.obj", 10**9, 10)
    write("parse_obj", "sphere_piece.obj", "".join(f"v {v}\n" for v in verts)
          + "".join("f " + " ".join(str(i + 1) for i in f) + "\n" for f in faces))


def off_seeds() -> None:
    cube_v = [(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)]
    cube_f = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    write("parse_off", "cube_quads.off", "OFF\n# a cube\n8 6 12\n" + "".join(f"{x} {y} {z}\n" for x, y, z in cube_v)
          + "".join("4 " + " ".join(map(str, f)) + "\n" for f in cube_f))
    write("parse_off", "coff_counts_on_header.off", "COFF 4 4 0\n" + "".join(f"{x} {y} {z} 255 0 0 255\n" for x, y, z in TETRA_V)
          + "".join("3 " + " ".join(map(str, f)) + " 1 2 3\n" for f in TETRA_F))
    write("parse_off", "stnoff_crlf.off", "STNOFF\r\n3 1 0\r\n0 0 0 0 0 1 0 0\r\n1 0 0 0 0 1 1 0\r\n"
          "0 1 0 0 0 1 0 1\r\n3 0 1 2\r\n")
    verts, faces = piece(DATA / "eight.off", 10**9, 10)
    write("parse_off", "eight_piece.off", f"OFF\n{len(verts)} {len(faces)} 0\n" + "".join(f"{v}\n" for v in verts)
          + "".join(f"{len(f)} " + " ".join(map(str, f)) + "\n" for f in faces))


def ply_header(fmt: str, nv: int, nf: int, vertex_props: str, face_prop: str, extra: str = "") -> str:
    return (f"ply\nformat {fmt} 1.0\ncomment seed\nobj_info x\nelement vertex {nv}\n{vertex_props}"
            f"element face {nf}\n{face_prop}{extra}end_header\n")


def ply_seeds() -> None:
    xyz = "property float x\nproperty float y\nproperty float z\n"
    write("parse_ply", "tetra_ascii.ply", ply_header("ascii", 4, 4, xyz, "property list uchar int vertex_indices\n")
          + "".join(f"{x} {y} {z}\n" for x, y, z in TETRA_V) + "".join("3 " + " ".join(map(str, f)) + "\n" for f in TETRA_F))
    body = b"".join(struct.pack("<3f", *v) for v in TETRA_V) + b"".join(struct.pack("<B3i", 3, *f) for f in TETRA_F)
    write("parse_ply", "tetra_binary.ply",
          ply_header("binary_little_endian", 4, 4, xyz, "property list uchar int vertex_indices\n").encode() + body)
    # Doubles, normals, an unsigned index list named vertex_index, a quad, and an element that is skipped.
    props = "property double x\nproperty double y\nproperty double z\nproperty float nx\nproperty uchar red\n"
    extra = "element edge 1\nproperty int vertex1\nproperty list ushort short junk\n"
    body = (b"".join(struct.pack("<3dfB", x, y, z, 0.5, 7) for x, y, z in TETRA_V)
            + struct.pack("<B4I", 4, 0, 1, 2, 3) + struct.pack("<B3I", 3, 0, 2, 3)
            + struct.pack("<iH2h", 1, 2, -1, 5))
    write("parse_ply", "mixed_binary.ply", ply_header("binary_little_endian", 4, 2, props,
                                                      "property list uchar uint vertex_index\n", extra).encode() + body)
    write("parse_ply", "mixed_ascii.ply",
          ply_header("ascii", 4, 2, props, "property list uchar uint vertex_index\n", extra)
          + "".join(f"{x} {y} {z} 0.5 7\n" for x, y, z in TETRA_V) + "4 0 1 2 3\n3 0 2 3\n1 2 -1 5\n")


def ingestion_seed(flags: int, setup: int, verts, faces) -> bytes:
    """Bytes in fuzz_mesh_ingestion.cpp's layout, coordinates as grid values (value * 8 + 112)."""
    out = bytearray([flags, setup, len(verts) - 1])
    for v in verts:
        out += bytes(int(round(c * 8)) + 112 for c in v)
    for f in faces:
        out += bytes(f)
    return bytes(out)


def ingestion_seeds() -> None:
    write("mesh_ingestion", "tetra_n4", ingestion_seed(3, 0, TETRA_V, TETRA_F))
    octa_v = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    octa_f = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    write("mesh_ingestion", "octahedron_spline", ingestion_seed(1 | 16, 1 | 8 | 0x30, octa_v, octa_f))
    write("mesh_ingestion", "octahedron_vector_spline", ingestion_seed(4 | 16 | 8, 2 | 4, octa_v, octa_f))
    # 3 x 3 grid of quads (open, one boundary loop), half the faces flipped, spline with a singularity.
    grid_v = [(x, y, 0.25 * ((x + y) % 2)) for y in range(4) for x in range(4)]
    grid_f = []
    for y in range(3):
        for x in range(3):
            a, b, c, d = 4 * y + x, 4 * y + x + 1, 4 * y + x + 5, 4 * y + x + 4
            grid_f += [(a, b, c), (a, d, c) if (x + y) % 2 else (a, c, d)]
    write("mesh_ingestion", "grid_flipped_spline", ingestion_seed(2 | 16, 3 | 8, grid_v, grid_f))
    # Two triangles sharing a vertex (bowtie) plus a non-manifold fin, a duplicate and a degenerate face.
    bow_v = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (-1, 0, 0), (-1, -1, 0), (1, 0, 1)]
    bow_f = [(0, 1, 2), (0, 3, 4), (0, 1, 5), (0, 1, 2), (2, 1, 0), (0, 0, 1), (1, 2, 3)]
    write("mesh_ingestion", "bowtie_nonmanifold", ingestion_seed(0, 0, bow_v, bow_f))
    # Moebius strip: 6 quads around, the last one joined with a half twist (non-orientable).
    moebius_v = [(2 * (i % 3) - 2, (i // 3) % 2 * 2 - 1, (i % 6) // 3) for i in range(12)]
    moebius_v = [(c[0] + 2 * (i // 6), c[1], c[2]) for i, c in enumerate(moebius_v)]
    strip = [(0, 1, 4), (0, 4, 3), (1, 2, 5), (1, 5, 4), (2, 6, 9), (2, 9, 5), (6, 7, 10), (6, 10, 9),
             (7, 8, 11), (7, 11, 10), (8, 3, 0), (8, 0, 11)]
    write("mesh_ingestion", "moebius", ingestion_seed(2 | 8, 0, moebius_v, strip))
    # Special coordinate tags: a NaN (tag 224) and raw doubles (tag 240 + 8 bytes).
    nan = bytearray(ingestion_seed(1, 0, TETRA_V, TETRA_F))
    nan[3] = 224
    write("mesh_ingestion", "tetra_nan", bytes(nan))
    raw = bytearray([1 | 0x40, 0, 2])
    for v in [(0.0, 0.0, 1e-58), (1e-58, 0.0, 0.0), (0.0, 1e-58, 0.0)]:
        for c in v:
            raw += bytes([240]) + struct.pack("<d", c)
    raw += bytes([0, 1, 2])
    write("mesh_ingestion", "tiny_raw_doubles", bytes(raw))
    write("mesh_ingestion", "out_of_range_index", ingestion_seed(0, 0, TETRA_V, [(0, 1, 240), (0, 248, 2)]))
    # Three separate faces and a duplicate at the upper end of the supported extent (scale 1e11): the spline
    # fills the unconstrained components. The first fuzzer finding (NaN fill at extent 1e59) came from here.
    parts_v = [(1, -14, -12.25), (-14, -14, -14), (0, -1, -14), (-13.75, -13.5, -13.75), (-13.875, -13.5, -13.875),
               (-13.75, -7.375, -13.625)]
    parts_f = [(0, 3, 4), (0, 5, 1), (2, 5, 3), (1, 5, 0)]
    write("mesh_ingestion", "components_fill_large", ingestion_seed(0xB8, 3 | 8 | 0x30, parts_v, parts_f))
    write("mesh_ingestion", "components_fill_small", ingestion_seed(0x98, 3 | 4, parts_v, parts_f))


if __name__ == "__main__":
    obj_seeds()
    off_seeds()
    ply_seeds()
    ingestion_seeds()
    for target in sorted(p for p in HERE.iterdir() if p.is_dir()):
        files = sorted(target.iterdir())
        print(f"{target.name}: {len(files)} seeds, largest {max(f.stat().st_size for f in files)} bytes")
