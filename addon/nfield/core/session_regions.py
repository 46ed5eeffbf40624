"""Local editing of DesignSession (a mixin; the state lives on the session object): the paper's section 9
and the way back.

``begin_region(faces)`` freezes every other face at its current value: the next solves factor only the
region, and every frozen face is copied bit-identically into the result. ``commit_region()`` turns the
region's field into a `Layer`, a set of frozen values kept in later global solves; ``release_layer(i)`` lets
those faces follow the global solve again. `_frozen()` is what a solve holds fixed: the region's outside, or
the committed layers (a later layer overrides an earlier one on shared faces).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .session_solvers import _token


@dataclass(frozen=True)
class Layer:
    """A committed local edit: faces (input numbering) whose field values are held fixed."""

    faces: np.ndarray       # input faces of the region
    triangles: np.ndarray   # their triangles
    values: np.ndarray      # raw field values (complex, per triangle) held fixed
    token: int = field(default_factory=_token, compare=False)


@dataclass
class _Region:
    """A region edit in progress: its faces and triangles, and what cancel_region puts back."""

    faces: np.ndarray          # input faces of the region (sorted, unique)
    triangles: np.ndarray      # their triangles
    saved: tuple               # (direction, vector, singularity constraints) before begin_region
    dirty: bool                # the session's dirty flag before begin_region
    field_before: Any          # the FieldResult before begin_region
    frozen_values: np.ndarray  # raw solution per triangle: the values of everything outside the region
    token: int = field(default_factory=_token)



class SessionRegions:
    """Mixin of DesignSession: region edits, committed layers and the faces a solve holds fixed."""

    def begin_region(self, faces) -> None:
        """Restrict edits to `faces` (input numbering); everything else keeps its current value exactly."""
        if self._region is not None:
            raise ValueError("a region edit is already in progress: commit or cancel it first")
        faces = np.unique(np.asarray(faces, dtype=np.int64).ravel())
        if faces.size == 0:
            raise ValueError("the region is empty: select at least one face")
        if faces[0] < 0 or faces[-1] >= self.mesh.num_faces:
            raise ValueError(f"region face {int(faces[0] if faces[0] < 0 else faces[-1])} is out of range "
                             f"(mesh has {self.mesh.num_faces} faces)")
        if self.field is None:
            self.solve()
        tris = np.flatnonzero(np.isin(self.mesh.triangle_face, faces))
        self._region = _Region(faces=faces, triangles=tris,
                               saved=(copy.deepcopy(self._dirs), copy.deepcopy(self._vecs), dict(self._sings)),
                               dirty=self._dirty, field_before=self.field,
                               frozen_values=np.asarray(self.field.raw_solution).copy())

    def commit_region(self) -> Layer:
        """End the region edit; its field becomes a layer held fixed by later global solves."""
        if self._region is None:
            raise ValueError("no region edit in progress")
        if self.field is None or self.field is self._region.field_before or self._dirty:
            self.solve()
        tris = self._region.triangles
        active = np.asarray(self.mesh.native.face_active, dtype=bool)
        tris = tris[active[tris]]
        layer = Layer(faces=self._region.faces, triangles=tris,
                      values=np.asarray(self.field.raw_solution)[tris].copy())
        self._layers.append(layer)
        self._region = None
        return layer

    def cancel_region(self) -> None:
        """End the region edit and restore the constraints and field from before begin_region."""
        if self._region is None:
            raise ValueError("no region edit in progress")
        self._dirs, self._vecs, self._sings = self._region.saved
        self.field = self._region.field_before
        self._dirty = self._region.dirty
        self._region = None

    @property
    def in_region(self) -> bool:
        return self._region is not None

    @property
    def layers(self) -> list[Layer]:
        return list(self._layers)

    def restore_layer(self, faces, vectors) -> Layer:
        """Re-create a committed layer from stored data (after a reload or undo): `faces` (input numbering)
        and one 3D vector per face whose direction is the field's first direction and whose length is the
        raw field magnitude. Polygons get the same vector on each of their triangles (projected)."""
        faces = np.asarray(faces, dtype=np.int64).ravel()
        vectors = np.asarray(vectors, dtype=np.float64).reshape(-1, 3)
        if faces.shape[0] != vectors.shape[0]:
            raise ValueError(f"restore_layer needs one vector per face ({faces.shape[0]} faces, "
                             f"{vectors.shape[0]} vectors)")
        if faces.size and (faces.min() < 0 or faces.max() >= self.mesh.num_faces):
            raise ValueError(f"layer face out of range (mesh has {self.mesh.num_faces} faces)")
        if not np.isfinite(vectors).all():
            raise ValueError("layer vectors must be finite")
        per_face = dict(zip(faces.tolist(), range(len(faces))))
        active = np.asarray(self.mesh.native.face_active, dtype=bool)
        tris = np.flatnonzero(np.isin(self.mesh.triangle_face, faces) & active)
        rows = np.array([per_face[int(f)] for f in self.mesh.triangle_face[tris]], dtype=np.int64)
        values = np.asarray(self._operators().tangent_to_representation(tris, np.ascontiguousarray(vectors[rows])))
        layer = Layer(faces=np.unique(faces), triangles=tris, values=values.astype(np.complex128))
        self._layers.append(layer)
        return layer

    def release_layer(self, i: int) -> None:
        if self._region is not None:
            raise ValueError("finish the region edit before releasing a layer")
        if not 0 <= i < len(self._layers):
            raise ValueError(f"layer {i} does not exist (there are {len(self._layers)})")
        del self._layers[i]

    def _ring_in_region(self, v: int) -> bool:
        region = set(self._region.triangles.tolist())
        return all(t in region for t in self._solve_native_mesh().vertex_ring_faces(v))

    def _face_frozen(self, face: int, frozen_set: set) -> bool:
        return int(self.mesh.face_triangle(face)) in frozen_set

    def _frozen(self):
        """(triangles, values, key) of the faces held fixed in the next solve. With mirror symmetry a face is
        held only if its mirror face is held too (the symmetric solve needs both or neither)."""
        tris, values, key = self._frozen_unclosed()
        if self._mirror is not None and tris.size:
            partner = np.asarray(self._mirror.partner)
            held = np.zeros(self.mesh.num_triangles, dtype=bool)
            held[tris] = True
            keep = (partner[tris] < 0) | held[np.maximum(partner[tris], 0)]
            tris, values = tris[keep], values[keep]
        return tris, values, key

    def _frozen_unclosed(self):
        if self._region is not None:
            active = np.asarray(self.mesh.native.face_active, dtype=bool)
            free = np.zeros(self.mesh.num_triangles, dtype=bool)
            free[self._region.triangles] = True
            tris = np.flatnonzero(active & ~free)
            return tris, self._region.frozen_values[tris], ("region", self._region.token)
        if not self._layers:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.complex128), ()
        tris = np.concatenate([layer.triangles for layer in self._layers])
        values = np.concatenate([layer.values for layer in self._layers])
        # A later layer overrides an earlier one on shared faces.
        _, last = np.unique(tris[::-1], return_index=True)
        keep = len(tris) - 1 - last
        return tris[keep], values[keep], tuple(layer.token for layer in self._layers)
