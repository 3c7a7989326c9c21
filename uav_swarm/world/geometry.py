"""Vectorised 2D geometry of points, line segments and rectangles (metres, local East-North frame).

Segments are rows ``(x1, y1, x2, y2)`` of float arrays; every function broadcasts over
many points or segments at once, with no Python loop over elements.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "point_segment_distances",
    "segment_segment_distances",
    "segments_cross",
    "rectangle_segment_distances",
]

_EPS = 1e-12


def point_segment_distances(points_m: np.ndarray, segments_m: np.ndarray) -> np.ndarray:
    """Distance from every point to every segment.

    Args:
        points_m: ``(N, 2)`` points.
        segments_m: ``(M, 4)`` segments ``x1, y1, x2, y2`` (zero-length segments are points).

    Returns:
        ``(N, M)`` float64 distances.

    Examples:
        >>> point_segment_distances(np.array([[1.0, 2.0]]), np.array([[0.0, 0.0, 4.0, 0.0]]))
        array([[2.]])
    """
    p = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
    s = np.asarray(segments_m, dtype=np.float64).reshape(-1, 4)
    ax, ay = s[:, 0], s[:, 1]
    wx, wy = s[:, 2] - ax, s[:, 3] - ay
    inv_len2 = 1.0 / np.maximum(wx * wx + wy * wy, _EPS)
    rx = p[:, 0, None] - ax
    ry = p[:, 1, None] - ay
    t = np.clip((rx * wx + ry * wy) * inv_len2, 0.0, 1.0)
    return np.hypot(rx - t * wx, ry - t * wy)


def _orientation(ax, ay, bx, by, cx, cy):
    """Twice the signed area of triangle abc (positive when counter-clockwise)."""
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


def segments_cross(first_m: np.ndarray, second_m: np.ndarray) -> np.ndarray:
    """Whether segments intersect (touching counts), broadcasting ``first`` against ``second``.

    Args:
        first_m: ``(..., 4)`` segments.
        second_m: ``(..., 4)`` segments, broadcastable against ``first_m``.

    Returns:
        Boolean array of the broadcast shape (without the last axis).

    Examples:
        >>> segments_cross(np.array([0.0, 0.0, 2.0, 2.0]), np.array([0.0, 2.0, 2.0, 0.0]))
        array(True)
    """
    a = np.asarray(first_m, dtype=np.float64)
    b = np.asarray(second_m, dtype=np.float64)
    p1x, p1y, p2x, p2y = (a[..., k] for k in range(4))
    q1x, q1y, q2x, q2y = (b[..., k] for k in range(4))
    o1 = _orientation(p1x, p1y, p2x, p2y, q1x, q1y)
    o2 = _orientation(p1x, p1y, p2x, p2y, q2x, q2y)
    o3 = _orientation(q1x, q1y, q2x, q2y, p1x, p1y)
    o4 = _orientation(q1x, q1y, q2x, q2y, p2x, p2y)
    proper = (o1 * o2 <= 0) & (o3 * o4 <= 0)
    # Collinear segments: orientation tests all vanish; require overlapping bounding boxes.
    collinear = (o1 == 0) & (o2 == 0)
    overlap = (
        (np.minimum(p1x, p2x) <= np.maximum(q1x, q2x))
        & (np.minimum(q1x, q2x) <= np.maximum(p1x, p2x))
        & (np.minimum(p1y, p2y) <= np.maximum(q1y, q2y))
        & (np.minimum(q1y, q2y) <= np.maximum(p1y, p2y))
    )
    return np.asarray(proper & (~collinear | overlap))


def segment_segment_distances(first_m: np.ndarray, second_m: np.ndarray) -> np.ndarray:
    """Distance between every segment of ``first_m`` and every segment of ``second_m``.

    Args:
        first_m: ``(K, 4)`` segments.
        second_m: ``(L, 4)`` segments.

    Returns:
        ``(K, L)`` float64 distances (0 where they intersect).
    """
    a = np.asarray(first_m, dtype=np.float64).reshape(-1, 4)
    b = np.asarray(second_m, dtype=np.float64).reshape(-1, 4)
    candidates = np.stack(
        [
            point_segment_distances(a[:, 0:2], b),
            point_segment_distances(a[:, 2:4], b),
            point_segment_distances(b[:, 0:2], a).T,
            point_segment_distances(b[:, 2:4], a).T,
        ]
    )
    distances = candidates.min(axis=0)
    distances[segments_cross(a[:, None, :], b[None, :, :])] = 0.0
    return distances


def rectangle_segment_distances(rectangles_m: np.ndarray, segments_m: np.ndarray) -> np.ndarray:
    """Distance between axis-aligned rectangles and segments (0 where a segment touches or enters one).

    Args:
        rectangles_m: ``(K, 4)`` rectangles ``x_min, y_min, x_max, y_max`` (degenerate ones allowed).
        segments_m: ``(L, 4)`` segments.

    Returns:
        ``(K, L)`` float64 distances.
    """
    r = np.asarray(rectangles_m, dtype=np.float64).reshape(-1, 4)
    s = np.asarray(segments_m, dtype=np.float64).reshape(-1, 4)
    x0, y0, x1, y1 = r.T
    edges = np.stack(
        [
            np.stack([x0, y0, x1, y0], axis=1),
            np.stack([x1, y0, x1, y1], axis=1),
            np.stack([x1, y1, x0, y1], axis=1),
            np.stack([x0, y1, x0, y0], axis=1),
        ],
        axis=1,
    ).reshape(-1, 4)
    distances = segment_segment_distances(edges, s).reshape(len(r), 4, len(s)).min(axis=1)
    # A segment lying wholly inside a rectangle touches none of its edges.
    sx, sy = s[:, 0], s[:, 1]
    inside = (sx >= x0[:, None]) & (sx <= x1[:, None]) & (sy >= y0[:, None]) & (sy <= y1[:, None])
    distances[inside] = 0.0
    return distances
