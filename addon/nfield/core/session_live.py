"""Live guide edits of DesignSession: local exact solves while an edit changes the guide weights.

A guide edit that changes only guide *targets* (directions: a rotation, the base field) changes only the
right-hand side of V w = b: the global exact solve reuses its factorization (one back-substitution). An edit
that changes the guide *weights* (moving a curve, a comb stroke, painting the alignment weight) changes
V = E_m + |lambda| M_W itself, and the global exact answer needs a new factorization (about a second on 70k
faces for the biharmonic energy). During such an interaction, solve(live=True) therefore solves the edit
locally and exactly: the faces whose weight or target changed since the last global solve, grown by a margin
of edge rings, are the region; every other face keeps its value from that global solve (the paper's local
editing, section 9); the region's own small system is factored and solved. The result is the exact spline of
the region with the rest held fixed (C^1 across the region's border for m >= 2), not the global spline.
pending_work() then says "factorization": the global solve is due, and the Blender layer runs it in the
background once the interaction pauses (or a plain solve() does it at once).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

#: live local solves grow the changed faces by 2 m + LIVE_MARGIN_EXTRA_RINGS edge rings (the stencil of E_m
#: reaches m rings; the rest gives the edit room to blend into the fixed field)
LIVE_MARGIN_EXTRA_RINGS = 1
#: a live edit that touches more than this fraction of the faces solves globally instead
LIVE_MAX_REGION_FRACTION = 0.25
#: live regions grow by fewer margin rings (down to none) when the full margin would exceed this many faces:
#: the cost of a live solve grows with its region (its factorization), the changed faces must be in it, the
#: margin only lets the edit blend further into the held field
LIVE_REGION_BUDGET = 5000


@dataclass
class BaseRecord:
    """What the last global exact solve used and found: the base for live local solves."""

    key: tuple               # everything but the guide field: a live solve needs the same operators and settings
    value: np.ndarray        # guide target value per triangle (zeros without guides)
    weight: np.ndarray       # guide weight per triangle (ones without guides)
    raw: np.ndarray          # raw solution per triangle
    summary: Any = None      # ResultSummary of the solve's FieldResult (live results update it on their region)


class SessionLive:
    """Mixin of DesignSession (state lives on the session)."""

    def _init_live(self) -> None:
        self._base_record: BaseRecord | None = None
        self._live_solver = None
        self._live_key = None         # ((base version, mirror), region, weights there) of the live solver
        self._base_version = 0        # bumped by every global solve (the values a live solver holds fixed)
        self._live_in_solver: dict[str, dict] = {"dir": {}, "vec": {}, "sing": {}}
        self._global_due = False

    def _record_key(self, inputs) -> tuple:
        s = self._settings
        return (self._ops_token, s["order"], s["strength"], inputs.kind, inputs.frozen_key)

    def _remember_base(self, inputs, raw: np.ndarray, live: bool = False) -> None:
        """Record a solve as the base of the next live edit: a global one, or a live one (then the global
        solve stays due)."""
        T = self.mesh.num_triangles
        value = np.zeros(T, dtype=np.complex128) if inputs.alignment is None else np.asarray(inputs.alignment)
        weight = np.ones(T) if inputs.matrix_weight is None else np.asarray(inputs.matrix_weight)
        # (value and weight are the session's guide arrays, never changed in place: no copies; raw is also the
        # result's, which its user may change)
        self._base_record = BaseRecord(self._record_key(inputs), value, weight, raw.copy())
        self._global_due = live
        if not live:
            self._base_version += 1

    def _live_base_ready(self, inputs) -> bool:
        """A live solve can start from the last solve: one was recorded for the same operators and settings,
        and no region edit is in progress."""
        rec = self._base_record
        return rec is not None and self._region is None and rec.key == self._record_key(inputs)

    def _live_region(self, inputs) -> np.ndarray | None:
        """Triangles to re-solve for a live edit, or None when the edit should be solved globally (no global
        solve to start from, other settings, a region edit in progress, only targets changed, or too many
        faces changed)."""
        rec = self._base_record
        if not self._live_base_ready(inputs):
            return None
        T = self.mesh.num_triangles
        value = np.zeros(T, dtype=np.complex128) if inputs.alignment is None else np.asarray(inputs.alignment)
        weight = np.ones(T) if inputs.matrix_weight is None else np.asarray(inputs.matrix_weight)
        weight_changed = weight != rec.weight
        if not weight_changed.any() and not self._global_due:
            return None  # the global factorization still holds: a right-hand-side update is cheaper
        changed = np.flatnonzero(weight_changed | (value != rec.value))
        if not changed.size:
            return None
        nm = self._solve_native_mesh()
        rings = 2 * self._settings["order"] + LIVE_MARGIN_EXTRA_RINGS
        region, steps = _grow(nm, changed, rings, limit=LIVE_REGION_BUDGET)
        if len(region) > LIVE_REGION_BUDGET:  # the widest margin within the budget (the changed faces are margin 0)
            within = np.cumsum(np.bincount(steps, minlength=rings + 1)) <= LIVE_REGION_BUDGET
            region = region[steps <= (int(np.flatnonzero(within)[-1]) if within.any() else 0)]
        # Whole rings of pinned singularities that the region touches (their rows cannot straddle its border).
        inside = np.zeros(T, dtype=bool)
        inside[region] = True
        for v in inputs.sings:
            ring = list(nm.vertex_ring_faces(v))
            if inside[ring].any():
                inside[ring] = True
        if self._mirror is not None:  # the symmetric solve needs a face and its mirror both free
            partner = np.asarray(self._mirror.partner)
            inside[partner[inside & (partner >= 0)]] = True
        inside[inputs.frozen_tris] = False  # committed layers keep their values (their faces are held)
        region = np.flatnonzero(inside & np.asarray(nm.face_active, dtype=bool))
        if not region.size or len(region) > LIVE_MAX_REGION_FRACTION * T:
            return None
        return region

    def _solve_local(self, ops, inputs, region: np.ndarray):
        """Exact solve of the region with every other face held at the last solve's values. The region's
        factorization is kept: the next live edit of the same region with the same weights there (only targets
        changed, and no global solve in between: the held values are the same) reuses it and only updates the
        right-hand side."""
        from ._loader import native

        s = self._settings
        rec = self._base_record
        weight = np.ones(len(region)) if inputs.matrix_weight is None else np.asarray(inputs.matrix_weight)[region]
        key = self._live_key
        solver = self._live_solver
        if (solver is not None and key is not None and key[0] == (self._base_version, id(self._mirror))
                and np.array_equal(key[1], region) and np.array_equal(key[2], weight)):
            solver.set_alignment(inputs.alignment)  # the same V_UU: right-hand side only
            in_solver = self._live_in_solver
        else:
            # Every face outside the region is held at the last solve's value; only those within the energy's
            # stencil of the region enter the region's system (frozen_faces.hpp), so the set-up costs the region.
            solver = native().ExactSolver(ops, s["order"], s["strength"], inputs.alignment, inputs.kind,
                                          progress=self.progress, free_faces=region, held_field=rec.raw,
                                          **self._weight_arguments(inputs))
            if self._mirror is not None:
                solver.set_symmetry(self._mirror)
            in_solver = {"dir": {}, "vec": {}, "sing": {}}
            self._live_solver = solver
            self._live_key = ((self._base_version, id(self._mirror)), region.copy(), weight.copy())
        inside = set(region.tolist())
        local = _restrict(inputs, inside, self)
        try:
            self._live_in_solver = self._sync(solver, in_solver, ops, local)
        except Exception:
            self._live_solver = self._live_key = None  # its constraint state is unknown now: rebuild next time
            raise
        w = np.asarray(solver.solve(), dtype=np.complex128)
        self._global_due = True
        return w, float(solver.lambda_), list(solver.sign_fixed_faces)


def _grow(native_mesh, faces: np.ndarray, rings: int, limit: int = -1) -> tuple[np.ndarray, np.ndarray]:
    """(faces and every face within `rings` dual steps of them, sorted; the steps to each) (a walk over the dual
    graph, native). With a limit the walk ends with the first complete step past `limit` faces (the steps within
    the limit are all there, and the region's size is known to exceed it)."""
    from ._loader import native

    grown, steps = native().grow_faces(native_mesh, np.asarray(faces, dtype=np.int64), int(rings), int(limit))
    return np.asarray(grown), np.asarray(steps)


def _restrict(inputs, inside: set, session) -> Any:
    """The solve inputs with only the constraints inside the region (the others hold through the fixed values)."""
    import dataclasses

    tri = session.mesh.face_triangle
    nm = session._solve_native_mesh()
    return dataclasses.replace(
        inputs,
        dirs={f: d for f, d in inputs.dirs.items() if tri(f) in inside},
        vecs={f: v for f, v in inputs.vecs.items() if tri(f) in inside},
        sings={v: i for v, i in inputs.sings.items() if all(t in inside for t in nm.vertex_ring_faces(v))},
        guide_dirs={t: z for t, z in inputs.guide_dirs.items() if t in inside})
