"""Exact, vectorised visibility between points in a simple polygon or in its exterior.

A guard ``g`` sees a witness ``w`` when the closed segment ``[g, w]`` lies in a closed
region ``R``: the polygon itself (``"interior"``, the Art Gallery rule: touching the boundary
is allowed) or the closure of its complement (``"exterior"``, the Fortress rule: the segment
must not cross the polygon's interior). Both ends must lie in ``R``.

The rule, decided for every (guard, witness) pair at once:

1. **Proper crossing.** If the segment crosses an edge at a point interior to both (the four
   orientation signs alternate), it enters the other side: not visible.
2. **Passing through a vertex.** For each vertex ``v`` strictly inside the segment, the
   segment leaves ``v`` in directions ``+d`` and ``-d`` (``d = w - g``). It stays in ``R``
   near ``v`` only if both directions lie in ``R``'s closed wedge at ``v``. When that wedge is
   narrower than 180 degrees (a convex vertex for the interior, a reflex one for the exterior)
   this is impossible; otherwise it holds unless ``+d`` or ``-d`` points strictly into the
   other region's wedge, i.e. unless both edge-direction cross products have the same
   strict sign.
3. **Otherwise** the open segment minus its vertex hits splits into pieces that meet the
   boundary nowhere, or lie along an edge (collinear overlaps end at vertices, which are
   hits, or at ``g``/``w``). Every piece next to a vertex hit was judged in step 2. With no hit
   the whole open segment is one piece: it is in ``R`` when ``g`` or ``w`` is strictly inside
   ``R``, and otherwise (both ends on the boundary) when its midpoint is in ``R``.

**Exactness.** Vertices and guards are integer pixel centres, witnesses are rationals
``p / m`` with ``m <= 1000`` (boundary samples ``a + (b - a) i / m``), and midpoints add a
factor 2. Every orientation determinant is therefore a multiple of ``1 / (2 m)``, while
float64 rounding on these magnitudes (< 1e5) stays below 1e-10; comparing with the
tolerance ``1e-7`` yields the exact sign. The rule is exact for such inputs, including
collinear and vertex-grazing segments (other float inputs get the same rule with that
tolerance). When every point is an integer the determinants are integers below ``2**24``
and the dense work runs in float32, still exactly.

**Cost.** ``O(G * W * n)`` for ``n`` vertices, vectorised one vertex at a time over all
pairs; only the pairs whose segment's line meets a vertex, or whose ends both lie on the
boundary, are revisited. When guards and witnesses are the same points (Art Gallery) only
the upper triangle is computed. A 64 px building takes about 40 ms (see
``benchmarks/README.md``).

Examples:
    >>> from uav_swarm.missions.monitoring.polygons import Polygon
    >>> square = Polygon(np.array([[0, 0], [4, 0], [4, 4], [0, 4]]), size_px=8)
    >>> visibility_matrix(square, np.array([[0.0, 0.0]]), np.array([[4.0, 4.0], [2.0, 4.0]]), "interior")
    array([[ True,  True]])
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from uav_swarm.missions.monitoring.polygons import Polygon, locate_points

__all__ = ["Region", "visibility_matrix", "EPS"]

Region = Literal["interior", "exterior"]

EPS = 1e-7
"""Zero test of orientation determinants (see the module docstring on exactness)."""

_FLOAT32_MAX_COORDINATE = 1024
"""Integer coordinates up to this magnitude give determinants below 2**24: exact in float32."""

_CHUNK_ELEMENTS = 1 << 21
"""Guard rows are processed in chunks of at most this many (guard, witness) pairs."""


def _sign(values: np.ndarray) -> np.ndarray:
    """int8 sign with the exactness tolerance."""
    return (values > EPS).view(np.int8) - (values < -EPS).view(np.int8)


def _block_proper_crossings(
    sign_a: np.ndarray, sign_b: np.ndarray, side_g: np.ndarray, side_w: np.ndarray, blocked: np.ndarray
) -> None:
    """Mark pairs whose segment properly crosses edge a-b (given orientation signs of both ends)."""
    crossing = (sign_a * sign_b) + (side_g[:, None] * side_w[None, :])
    blocked |= crossing == -2


def _cross_with(points: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """``(P, V)`` cross products ``C(p, q) = p_x q_y - p_y q_x``."""
    return points[:, 0, None] * vectors[None, :, 1] - points[:, 1, None] * vectors[None, :, 0]


def _strictly_in(codes: np.ndarray, region: Region) -> np.ndarray:
    return codes == (1 if region == "interior" else -1)


def _check_points(name: str, points: np.ndarray, vertices: np.ndarray, region: Region) -> np.ndarray:
    codes = locate_points(points, vertices)
    outside = codes == (-1 if region == "interior" else 1)
    if np.any(outside):
        bad = points[np.argmax(outside)]
        raise ValueError(
            f"{name} must lie in the closed {region} region of the polygon; ({bad[0]}, {bad[1]}) does not")
    return codes


def visibility_matrix(
    polygon: Polygon,
    guards_px: np.ndarray,
    witnesses_px: np.ndarray,
    region: Region,
    *,
    guard_codes: np.ndarray | None = None,
    witness_codes: np.ndarray | None = None,
) -> np.ndarray:
    """Which guard sees which witness (see the module docstring for the exact rule).

    Args:
        polygon: The building.
        guards_px: ``(G, 2)`` guard points ``(x, y)`` in the closed ``region``.
        witnesses_px: ``(W, 2)`` witness points in the closed ``region``.
        region: ``"interior"`` (Art Gallery) or ``"exterior"`` (Fortress).
        guard_codes: The guards' :func:`~uav_swarm.missions.monitoring.polygons.locate_points` codes when the
            caller already has them (e.g. from ``Polygon.pixel_locations``); they are trusted, not checked.
        witness_codes: The same for the witnesses.

    Returns:
        ``(G, W)`` bool: ``True`` where the segment guard-witness lies in the closed region.

    Raises:
        ValueError: Unknown region, or a point outside the closed region.
    """
    if region not in ("interior", "exterior"):
        raise ValueError(f"region = {region!r}: allowed 'interior' or 'exterior'")
    guards = np.asarray(guards_px, dtype=np.float64).reshape(-1, 2)
    witnesses = np.asarray(witnesses_px, dtype=np.float64).reshape(-1, 2)
    vertices = polygon.vertices_px
    if guard_codes is None:
        guard_codes = _check_points("guards_px", guards, vertices, region)
    if witness_codes is None:
        witness_codes = _check_points("witnesses_px", witnesses, vertices, region)
    g_strict = _strictly_in(np.asarray(guard_codes), region)
    w_strict = _strictly_in(np.asarray(witness_codes), region)
    visible = np.ones((len(guards), len(witnesses)), dtype=bool)
    if len(guards) == 0 or len(witnesses) == 0:
        return visible
    symmetric = guards.shape == witnesses.shape and np.array_equal(guards, witnesses)
    points = np.concatenate([guards, witnesses, vertices])
    small_integers = np.all(points == np.round(points)) and np.abs(points).max() <= _FLOAT32_MAX_COORDINATE
    dtype = np.float32 if small_integers else np.float64
    chunk = max(1, _CHUNK_ELEMENTS // len(witnesses))
    if symmetric:
        chunk = min(chunk, max(64, -(-len(guards) // 8)))
    for start in range(0, len(guards), chunk):
        stop = min(start + chunk, len(guards))
        first = start if symmetric else 0  # the rule is symmetric: compute the upper triangle only
        block = _visible_block(
            polygon, guards[start:stop].astype(dtype), witnesses[first:].astype(dtype),
            g_strict[start:stop], w_strict[first:], region)
        visible[start:stop, first:] = block
        if symmetric:
            visible[first:, start:stop] = block.T
    return visible


def _visible_block(
    polygon: Polygon,
    guards: np.ndarray,
    witnesses: np.ndarray,
    g_strict: np.ndarray,
    w_strict: np.ndarray,
    region: Region,
) -> np.ndarray:
    """The visibility rule for one block of guards against all witnesses (in the guards' dtype)."""
    vertices = polygon.vertices_px.astype(guards.dtype)
    n = len(vertices)
    nxt = np.roll(vertices, -1, axis=0)
    # Side of edge k (v_k -> v_k+1) per point: sign of C(e_k, p - v_k) = C(v_k, e_k) - C(p, e_k).
    # Per-vertex arrays are laid out (vertex, point) so that each loop step reads contiguous rows.
    edge_dir = nxt - vertices
    edge_offset = _cross_with(vertices, edge_dir)[np.arange(n), np.arange(n)]  # C(v_k, e_k)
    side_g = np.ascontiguousarray(_sign(edge_offset[None, :] - _cross_with(guards, edge_dir)).T)
    side_w = np.ascontiguousarray(_sign(edge_offset[None, :] - _cross_with(witnesses, edge_dir)).T)
    # O(g, w, v) = C(w - g, v - g) = C(g, w) + C(w, v) - C(g, v), built one vertex at a time.
    c_gv = np.ascontiguousarray(_cross_with(guards, vertices).T)
    c_wv = np.ascontiguousarray(_cross_with(witnesses, vertices).T)
    c_gw = _cross_with(guards, witnesses)
    shape = c_gw.shape
    orientation = np.empty_like(c_gw)
    blocked = np.zeros(shape, dtype=bool)
    hits: list[tuple[np.ndarray, np.ndarray, int]] = []
    first = previous = np.zeros(0, dtype=np.int8)
    for k in range(n):
        np.subtract(c_gw, c_gv[k][:, None], out=orientation)
        orientation += c_wv[k][None, :]
        current = _sign(orientation)
        flat = np.flatnonzero(current == 0)
        if len(flat):
            gi, wi = np.divmod(flat, shape[1])
            hits.append((gi, wi, k))
        if k == 0:
            first = current
        else:
            _block_proper_crossings(previous, current, side_g[k - 1], side_w[k - 1], blocked)
        previous = current
    _block_proper_crossings(previous, first, side_g[n - 1], side_w[n - 1], blocked)
    for gi, wi, k in hits:
        _block_vertex_passages(polygon, guards, witnesses, gi, wi, k, region, blocked)
    ends_on_boundary = ~g_strict[:, None] & ~w_strict[None, :] & ~blocked
    gi, wi = np.nonzero(ends_on_boundary)
    if len(gi):
        midpoints = 0.5 * (guards[gi] + witnesses[wi])
        codes = locate_points(midpoints, vertices)
        outside = codes == (-1 if region == "interior" else 1)
        blocked[gi[outside], wi[outside]] = True
    return ~blocked


def _block_vertex_passages(
    polygon: Polygon,
    guards: np.ndarray,
    witnesses: np.ndarray,
    gi: np.ndarray,
    wi: np.ndarray,
    k: int,
    region: Region,
    blocked: np.ndarray,
) -> None:
    """Step 2 of the rule for the pairs whose segment line passes through vertex ``k``."""
    v = polygon.vertices_px[k]
    g, w = guards[gi], witnesses[wi]
    between = np.einsum("ij,ij->i", v - g, w - v) > EPS
    gi, wi, g, w = gi[between], wi[between], g[between], w[between]
    if len(gi) == 0:
        return
    narrow_wedge = bool(polygon.reflex[k]) == (region == "exterior")
    if narrow_wedge:
        blocked[gi, wi] = True
        return
    vertices = polygon.vertices_px
    out_dir = vertices[(k + 1) % len(vertices)] - v
    in_dir = vertices[k - 1] - v
    d = w - g
    s1 = _sign(out_dir[0] * d[:, 1] - out_dir[1] * d[:, 0])
    s2 = _sign(d[:, 0] * in_dir[1] - d[:, 1] * in_dir[0])
    strict = s1 * s2 > 0
    blocked[gi[strict], wi[strict]] = True
