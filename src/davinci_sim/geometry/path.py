"""Reference paths: polylines in 3-D, rounded corners, and closest-point queries.

A guidance fixture needs, at every haptic tick, the deviation φ of the seed (§II-C): the
vector from the tool tip to the closest point of the reference path. Paths are
:class:`Polyline` s (a smooth curve is a finely sampled polyline: :func:`rounded_polyline`
turns waypoints into straight runs joined by circular fillets). Queries are vectorised over
any batch of points, ``(..., 3)``.

Two query methods give the same answer (the tests check both against a plain loop):

* :func:`closest_point_brute`: every query against every segment, O(M·S), written as two
  matrix products; the fastest for the short paths of training tasks (tens of segments).
* :class:`ClosestPointTree`: a k-d tree of segment midpoints prunes the candidates, O(M log S),
  for long finely sampled curves.

The closest-point map is unique and continuous except on the path's *medial axis* (points
equidistant from two parts of the path, e.g. inside a corner beyond its fillet radius, or
far away); there the closest point, hence φ's direction, jumps. On the medial axis itself
either answer may come back (they are equally close).

All lengths are in metres; a path carries no frame itself, the owner says which (e.g.
``PathTask.frame``), and :meth:`Polyline.transformed` moves it to another frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

#: Up to this many segments ``method="auto"`` uses the brute force (400 queries on a 60-segment
#: path: 0.2 ms on a 2-core Xeon), beyond it the k-d tree.
BRUTE_FORCE_MAX_SEGMENTS = 256


class ClosestPoint(NamedTuple):
    """Result of a closest-point query, each with the batch shape of the queries."""

    point: np.ndarray
    """Closest point of the path, (..., 3), m."""
    deviation: np.ndarray
    """φ = point − query, from the query (tool tip) to the path, (..., 3), m."""
    distance: np.ndarray
    """‖φ‖, (...), m."""
    arc_length: np.ndarray
    """Arc length of the closest point from the path's start, (...), m."""
    segment: np.ndarray
    """Index of the segment the closest point is on, (...), int."""


def _as_points(points, name: str = "points") -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim < 1 or p.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (..., 3), got {p.shape}")
    return p


@dataclass(frozen=True, eq=False)
class Polyline:
    """A 3-D polyline through ``vertices`` (N ≥ 2, consecutive vertices distinct).

    Arc length runs from vertex 0 (s = 0) to the last vertex (s = :attr:`length`).
    """

    vertices: np.ndarray
    """(N, 3), m."""
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        v = np.array(self.vertices, dtype=float)
        if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 2:
            raise ValueError(f"a polyline needs vertices of shape (N >= 2, 3), got {v.shape}")
        if not np.all(np.isfinite(v)):
            raise ValueError("polyline vertices must be finite")
        if np.any(np.linalg.norm(np.diff(v, axis=0), axis=1) <= 1e-12):
            raise ValueError("consecutive polyline vertices must be distinct")
        v.setflags(write=False)
        object.__setattr__(self, "vertices", v)

    # A pickled copy (a loop process's, a Ray worker's) has its vertices only, read-only as
    # here: unpickled arrays are writable, and numba compiles the closest-point kernel again
    # for a writable argument where it had a read-only one.
    def __getstate__(self) -> dict:
        return {"vertices": self.vertices}

    def __setstate__(self, state: dict) -> None:
        v = np.array(state["vertices"], dtype=float)
        v.setflags(write=False)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "_cache", {})

    # ------------------------------------------------------------ geometry
    @cached_property
    def starts(self) -> np.ndarray:
        """Segment start points (S, 3)."""
        return self.vertices[:-1]

    @cached_property
    def edges(self) -> np.ndarray:
        """Segment vectors end − start (S, 3)."""
        return np.diff(self.vertices, axis=0)

    @cached_property
    def segment_lengths(self) -> np.ndarray:
        return np.linalg.norm(self.edges, axis=1)

    @cached_property
    def cumulative_length(self) -> np.ndarray:
        """Arc length at each vertex (N,), from 0 to :attr:`length`."""
        return np.concatenate([[0.0], np.cumsum(self.segment_lengths)])

    @cached_property
    def centre(self) -> np.ndarray:
        """Mean of the vertices (3,): the origin of the brute-force query's arithmetic."""
        return self.vertices.mean(axis=0)

    @cached_property
    def _brute_constants(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        A, E = self.starts - self.centre, self.edges
        return (
            np.concatenate([E, A]).T.copy(),
            np.einsum("sj,sj->s", A, E),
            np.einsum("sj,sj->s", A, A),
            self.segment_lengths**2,
        )

    @property
    def length(self) -> float:
        return float(self.cumulative_length[-1])

    def point_at(self, arc_length) -> np.ndarray:
        """Point at arc length ``s`` (clipped to [0, length]), shape ``s.shape + (3,)``."""
        s = np.clip(np.asarray(arc_length, dtype=float), 0.0, self.length)
        i = self._segment_of(s)
        u = (s - self.cumulative_length[i]) / self.segment_lengths[i]
        return self.starts[i] + u[..., None] * self.edges[i]

    def tangent_at(self, arc_length) -> np.ndarray:
        """Unit tangent (direction of increasing s) at arc length ``s``, ``s.shape + (3,)``."""
        s = np.clip(np.asarray(arc_length, dtype=float), 0.0, self.length)
        i = self._segment_of(s)
        return self.edges[i] / self.segment_lengths[i][..., None]

    def _segment_of(self, s: np.ndarray) -> np.ndarray:
        i = np.searchsorted(self.cumulative_length, s, side="right") - 1
        return np.clip(i, 0, len(self.segment_lengths) - 1)

    def transformed(self, T_a_b) -> Polyline:
        """This path (given in frame b) expressed in frame a, for a 4x4 rigid ``T_a_b``."""
        T = np.asarray(T_a_b, dtype=float)
        if T.shape != (4, 4):
            raise ValueError(f"T_a_b must be 4x4, got {T.shape}")
        return Polyline(self.vertices @ T[:3, :3].T + T[:3, 3])

    def resampled(self, step: float) -> Polyline:
        """The same curve with vertices every ``step`` m of arc length (plus the end)."""
        if not step > 0:
            raise ValueError(f"step must be > 0, got {step!r}")
        n = max(1, math.ceil(self.length / step - 1e-9))
        s = np.linspace(0.0, self.length, n + 1)
        # Keep the original corners so that resampling does not cut them.
        s = np.unique(np.concatenate([self.cumulative_length, s]))
        s = s[np.concatenate([[True], np.diff(s) > 1e-9])]
        s[-1] = self.length
        return Polyline(self.point_at(s))

    # ------------------------------------------------------------ queries
    def closest_point(self, points, *, method: str = "auto") -> ClosestPoint:
        """Closest point of the path to each of ``points`` (..., 3).

        Args:
            points: query points (tool tips), m, in the path's frame.
            method: ``"brute"``, ``"tree"`` (:class:`ClosestPointTree`) or ``"auto"``: the
                brute force up to :data:`BRUTE_FORCE_MAX_SEGMENTS` segments, the tree beyond.
        """
        if method == "auto":
            method = "brute" if len(self.segment_lengths) <= BRUTE_FORCE_MAX_SEGMENTS else "tree"
        if method == "brute":
            return closest_point_brute(self, points)
        if method == "tree":
            tree = self._cache.get("tree")
            if tree is None:
                tree = self._cache["tree"] = ClosestPointTree(self)
            return tree.query(points)
        raise ValueError(f"unknown closest-point method {method!r}; methods: auto, brute, tree")


def _project(
    points: np.ndarray, starts: np.ndarray, edges: np.ndarray, inv_len2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Projection parameter u in [0, 1] and squared distance of ``points`` (M, 1, 3) to
    segments broadcast as (M, C, 3)."""
    u = np.clip(np.einsum("mcj,mcj->mc", points - starts, edges) * inv_len2, 0.0, 1.0)
    d = starts + u[..., None] * edges - points
    return u, np.einsum("mcj,mcj->mc", d, d)


def brute_force_constants(path: Polyline) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What :func:`closest_point_brute` compares a query against, for a compiled row form of
    it (``haptics.path_query``): the basis (3, 2S) (edges E then centred starts A, as
    columns), A·E (S,), A·A (S,) and ‖E‖² (S,); coordinates centred on :attr:`Polyline.centre`."""
    return path._brute_constants


def _result(path: Polyline, q: np.ndarray, seg: np.ndarray, u: np.ndarray) -> ClosestPoint:
    point = path.starts[seg] + u[..., None] * path.edges[seg]
    phi = point - q
    return ClosestPoint(
        point=point,
        deviation=phi,
        distance=np.linalg.norm(phi, axis=-1),
        arc_length=path.cumulative_length[seg] + u * path.segment_lengths[seg],
        segment=seg,
    )


def closest_point_brute(path: Polyline, points, *, chunk: int = 2048) -> ClosestPoint:
    """Closest point by testing every segment (the reference; exact, O(M·S)).

    The projections of all queries on all segments come from two products
    (q·Aᵀ, q·Eᵀ for segment starts A and edges E, coordinates centred on the path so that
    the expansion of ‖q − A − uE‖² loses no precision at the mm scale), so a few hundred
    queries against a few hundred segments cost well under a millisecond.
    """
    p = _as_points(points)
    shape = p.shape[:-1]
    q = p.reshape(-1, 3) - path.centre
    basis, AE, AA, EE = path._brute_constants
    seg = np.empty(len(q), dtype=int)
    u = np.empty(len(q))
    for a in range(0, len(q), chunk):
        # (m, 2S): q·E then q·A, as three elementwise products rather than one matrix
        # product, so that a query's result does not depend on how many others come with
        # it (BLAS rounds a product's rows differently with the matrix size).
        qa = q[a : a + chunk]
        qb = qa[:, 0:1] * basis[0] + qa[:, 1:2] * basis[1] + qa[:, 2:3] * basis[2]
        qE = qb[:, : len(EE)]
        qE -= AE  # (q − A)·E
        uu = np.clip(qE / EE, 0.0, 1.0)
        # ‖q − A − uE‖² = ‖q‖² − 2q·A + ‖A‖² − 2u (q − A)·E + u²‖E‖²; ‖q‖² is the same for
        # every segment of a query, so it is left out of the comparison.
        d2 = uu * EE
        d2 -= 2.0 * qE
        d2 *= uu
        d2 -= 2.0 * qb[:, len(EE) :]
        d2 += AA
        k = np.argmin(d2, axis=1)  # first minimum: ties go to the lower arc length
        seg[a : a + chunk] = k
        u[a : a + chunk] = uu[np.arange(len(k)), k]
    return _result(path, p, seg.reshape(shape), u.reshape(shape))


class ClosestPointTree:
    """Exact closest-point queries on long polylines through a k-d tree of segment midpoints.

    For a query q whose nearest midpoint is r₀ away, the closest segment is at most r₀ away
    (its midpoint is on it), so its midpoint is within r₀ + L_max/2 of q, L_max the longest
    segment: the tree's ball query with that radius returns every candidate, and the exact
    projection on the candidates picks the closest. On a finely sampled curve the ball holds
    a few segments whatever the path's length, hence O(M log S) rather than O(M·S).
    """

    def __init__(self, path: Polyline) -> None:
        self.path = path
        self.tree = cKDTree(path.starts + 0.5 * path.edges)
        self.reach = 0.5 * float(path.segment_lengths.max())

    def query(self, points) -> ClosestPoint:
        p = _as_points(points)
        shape = p.shape[:-1]
        q = p.reshape(-1, 3)
        path = self.path
        r0, _ = self.tree.query(q)
        balls = self.tree.query_ball_point(q, r0 * (1 + 1e-9) + self.reach + 1e-12)
        counts = np.fromiter((len(b) for b in balls), dtype=np.int64, count=len(q))
        cand = np.concatenate([np.asarray(b, dtype=np.int64) for b in balls])
        owner = np.repeat(np.arange(len(q)), counts)
        uu, d2 = _project(
            q[owner][:, None],
            path.starts[cand][:, None],
            path.edges[cand][:, None],
            1.0 / path.segment_lengths[cand][:, None] ** 2,
        )
        uu, d2 = uu[:, 0], d2[:, 0]
        # Per query, the smallest distance; ties to the lower segment index.
        order = np.lexsort((cand, d2, owner))
        first = order[np.concatenate([[0], np.cumsum(counts)[:-1]])]
        return _result(path, p, cand[first].reshape(shape), uu[first].reshape(shape))


# ---------------------------------------------------------------- construction
def rounded_polyline(
    waypoints,
    corner_radius: float,
    *,
    arc_step_deg: float = 5.0,
) -> tuple[Polyline, np.ndarray]:
    """Straight runs through ``waypoints`` joined at each interior waypoint by a circular
    fillet of radius ``corner_radius`` (0: sharp corners), sampled every ``arc_step_deg``.

    Returns:
        ``(path, waypoint_arc_length)``: the polyline, and for each waypoint the arc length
        of its closest point on the path (the fillet's midpoint for interior waypoints, 0 and
        the length for the ends). A fillet cuts a 90° corner by r·(√2 − 1) ≈ 0.41 r.

    Raises:
        ValueError: fewer than 2 waypoints, repeated or collinear-reversing waypoints, or a
            radius whose fillets do not fit on the runs.
    """
    w = np.asarray(waypoints, dtype=float)
    if w.ndim != 2 or w.shape[1] != 3 or len(w) < 2:
        raise ValueError(f"waypoints must have shape (N >= 2, 3), got {w.shape}")
    if not (corner_radius >= 0 and math.isfinite(corner_radius)):
        raise ValueError(f"corner_radius must be a finite number >= 0, got {corner_radius!r}")
    runs = np.diff(w, axis=0)
    lengths = np.linalg.norm(runs, axis=1)
    if np.any(lengths <= 1e-9):
        raise ValueError("consecutive waypoints must be distinct")
    dirs = runs / lengths[:, None]
    # Tangent length of each interior corner: r·tan(δ/2) for a turn of δ.
    tangent = np.zeros(len(w))
    turn = np.zeros(len(w))
    for i in range(1, len(w) - 1):
        cos_d = float(np.clip(dirs[i - 1] @ dirs[i], -1.0, 1.0))
        turn[i] = math.acos(cos_d)
        if turn[i] > math.pi - 1e-6:
            raise ValueError(f"the path reverses at waypoint {i + 1}: no fillet exists")
        tangent[i] = corner_radius * math.tan(turn[i] / 2)
    for k in range(len(runs)):
        if tangent[k] + tangent[k + 1] > lengths[k] + 1e-12:
            raise ValueError(
                f"corner_radius {corner_radius} m is too large for the run from waypoint "
                f"{k + 1} to {k + 2} ({lengths[k]:.4f} m long)"
            )
    vertices = [w[0]]
    mids: list[np.ndarray | None] = [None] * len(w)
    for i in range(1, len(w) - 1):
        if tangent[i] <= 1e-12:
            vertices.append(w[i])
            continue
        a, b = dirs[i - 1], dirs[i]
        t1 = w[i] - tangent[i] * a
        # The centre lies at distance r from t1, perpendicular to a, in the plane of (a, b).
        normal = b - (b @ a) * a
        normal /= np.linalg.norm(normal)
        centre = t1 + corner_radius * normal
        e1 = (t1 - centre) / corner_radius
        e2 = a  # the arc starts moving along a
        n_arc = max(2, math.ceil(math.degrees(turn[i]) / arc_step_deg))
        angles = np.linspace(0.0, turn[i], n_arc + 1)
        arc = centre + corner_radius * (np.cos(angles)[:, None] * e1 + np.sin(angles)[:, None] * e2)
        vertices.extend(arc)
        mids[i] = centre + corner_radius * (math.cos(turn[i] / 2) * e1 + math.sin(turn[i] / 2) * e2)
    vertices.append(w[-1])
    v = np.asarray(vertices)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(v, axis=0), axis=1) > 1e-12])
    path = Polyline(v[keep])
    targets = np.array([w[i] if mids[i] is None else mids[i] for i in range(len(w))])
    s = closest_point_brute(path, targets).arc_length
    s[0], s[-1] = 0.0, path.length
    return path, s
