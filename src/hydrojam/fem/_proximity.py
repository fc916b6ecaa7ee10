"""Pairs of boundary primitives of different components closer than a distance, compiled: the
contact term's Hessian pattern within reach (:meth:`hydrojam.fem.contact.Contact.hessian_pattern`).

Each primitive's box, grown by half the distance, goes into the cells of a uniform grid; two
primitives whose grown boxes overlap are tested with their exact distance (point-segment in 2D,
point-triangle and segment-segment in 3D, all squared, as ipctk's). A pair is reported once, in
the cell that holds the lower corner of the boxes' overlap. The pairs kept are those closer than
the distance; those within ``ambiguity`` of it in relative terms are returned apart, for the
caller to decide with ipctk's own distance functions, so that the kept set is ipctk's to the
last bit.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _dot(a, b):  # pragma: no cover - compiled
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i] * b[i]
    return s


@numba.njit(cache=True)
def _point_segment_sq(p, a, b):  # pragma: no cover - compiled
    ab = b - a
    ap = p - a
    t = _dot(ap, ab)
    L = _dot(ab, ab)
    if L > 0.0:
        t = min(max(t / L, 0.0), 1.0)
    else:
        t = 0.0
    d = ap - t * ab
    return _dot(d, d)


@numba.njit(cache=True)
def _point_triangle_sq(p, a, b, c):  # pragma: no cover - compiled
    """Squared distance from p to the closed triangle abc (Ericson, Real-Time Collision Detection
    5.1.5), with the segments' distance where the triangle is degenerate."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    n = np.cross(ab, ac)
    if _dot(n, n) <= 1e-30 * (_dot(ab, ab) * _dot(ac, ac) + 1e-300):
        return min(_point_segment_sq(p, a, b), _point_segment_sq(p, b, c), _point_segment_sq(p, a, c))
    if d1 <= 0.0 and d2 <= 0.0:
        return _dot(ap, ap)
    bp = p - b
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    if d3 >= 0.0 and d4 <= d3:
        return _dot(bp, bp)
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        return _point_segment_sq(p, a, b)
    cp = p - c
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    if d6 >= 0.0 and d5 <= d6:
        return _dot(cp, cp)
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        return _point_segment_sq(p, a, c)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        return _point_segment_sq(p, b, c)
    h = _dot(ap, n)
    return h * h / _dot(n, n)


@numba.njit(cache=True)
def _segment_segment_sq(p1, q1, p2, q2):  # pragma: no cover - compiled
    """Squared distance between the closed segments p1q1 and p2q2: the least of the interior
    stationary point (where both parameters lie in (0, 1)) and the four endpoint-segment
    distances, which covers parallel segments."""
    best = min(_point_segment_sq(p1, p2, q2), _point_segment_sq(q1, p2, q2),
               _point_segment_sq(p2, p1, q1), _point_segment_sq(q2, p1, q1))
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, b = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2)
    c, f = _dot(d1, r), _dot(d2, r)
    denom = a * e - b * b
    if denom > 1e-14 * a * e and a > 0.0 and e > 0.0:
        s = (b * f - c * e) / denom
        t = (a * f - b * c) / denom
        if 0.0 < s < 1.0 and 0.0 < t < 1.0:
            d = r + s * d1 - t * d2
            best = min(best, _dot(d, d))
    return best


@numba.njit(cache=True)
def _boxes(V, prims, grow):  # pragma: no cover - compiled
    m, k = prims.shape
    d = V.shape[1]
    lo = np.empty((m, d))
    hi = np.empty((m, d))
    for i in range(m):
        for j in range(d):
            a = V[prims[i, 0], j]
            b = a
            for q in range(1, k):
                v = V[prims[i, q], j]
                a = min(a, v)
                b = max(b, v)
            lo[i, j] = a - grow
            hi[i, j] = b + grow
    return lo, hi


@numba.njit(cache=True)
def _close_pairs(V, first, second, components, limit, ambiguity, same):  # pragma: no cover - compiled
    """(pairs (n, 2), ambiguous (n,) bool) of primitives ``first`` [i] and ``second`` [j] (vertex
    index rows: 1 a point, 2 a segment, 3 a triangle) of different components whose squared
    distance is below ``limit`` (or within ``ambiguity`` of it, relative: flagged). ``same``:
    both sets are one, each pair once (i < j)."""
    d = V.shape[1]
    grow = 0.5 * np.sqrt(limit) * (1.0 + 2.0 * ambiguity)
    lo1, hi1 = _boxes(V, first, grow)
    lo2, hi2 = _boxes(V, second, grow)
    origin = np.empty(d)
    size = 0.0
    for j in range(d):
        origin[j] = min(lo1[:, j].min(), lo2[:, j].min())
        size = max(size, (hi1[:, j] - lo1[:, j]).max(), (hi2[:, j] - lo2[:, j]).max())
    size = max(size, 1e-12)
    dims = np.empty(d, dtype=np.int64)
    while True:  # cells at least as large as every box, and not many more cells than boxes
        ncell = 1
        for j in range(d):
            top = max(hi1[:, j].max(), hi2[:, j].max())
            dims[j] = int((top - origin[j]) / size) + 1
            ncell *= dims[j]
        if ncell <= 8 * (first.shape[0] + second.shape[0]) + 1024:
            break
        size *= 2.0
    m2 = second.shape[0]
    # the second set's boxes into cells (CSR: start[c] .. start[c + 1])
    count = np.zeros(ncell + 1, dtype=np.int64)
    cl = np.empty(d, dtype=np.int64)
    ch = np.empty(d, dtype=np.int64)
    for pas in range(2):
        if pas == 1:
            for c in range(ncell):
                count[c + 1] += count[c]
            fill = count[:-1].copy()
            members = np.empty(count[ncell], dtype=np.int64)
        for i in range(m2):
            for j in range(d):
                cl[j] = int((lo2[i, j] - origin[j]) / size)
                ch[j] = int((hi2[i, j] - origin[j]) / size)
            for cx in range(cl[0], ch[0] + 1):
                for cy in range(cl[1], ch[1] + 1):
                    for cz in range(cl[2] if d == 3 else 0, (ch[2] if d == 3 else 0) + 1):
                        c = (cx * dims[1] + cy) * (dims[2] if d == 3 else 1) + cz
                        if pas == 0:
                            count[c + 1] += 1
                        else:
                            members[fill[c]] = i
                            fill[c] += 1
    out = np.empty((64, 2), dtype=np.int64)
    flag = np.empty(64, dtype=np.bool_)
    n = 0
    k1, k2 = first.shape[1], second.shape[1]
    for i in range(first.shape[0]):
        ci = components[first[i, 0]]
        for j in range(d):
            cl[j] = int((lo1[i, j] - origin[j]) / size)
            ch[j] = int((hi1[i, j] - origin[j]) / size)
        for cx in range(cl[0], ch[0] + 1):
            for cy in range(cl[1], ch[1] + 1):
                for cz in range(cl[2] if d == 3 else 0, (ch[2] if d == 3 else 0) + 1):
                    c = (cx * dims[1] + cy) * (dims[2] if d == 3 else 1) + cz
                    for q in range(count[c], count[c + 1]):
                        o = members[q]
                        if same and o <= i:
                            continue
                        if components[second[o, 0]] == ci:
                            continue
                        overlap = True
                        home = True
                        for j in range(d):
                            a = max(lo1[i, j], lo2[o, j])
                            if a > min(hi1[i, j], hi2[o, j]):
                                overlap = False
                                break
                            cell = min(int((a - origin[j]) / size), dims[j] - 1)
                            if cell != (cx, cy, cz)[j]:
                                home = False
                        if not overlap or not home:
                            continue
                        if k1 == 1 and k2 == 2:
                            dist = _point_segment_sq(V[first[i, 0]], V[second[o, 0]], V[second[o, 1]])
                        elif k1 == 1 and k2 == 3:
                            dist = _point_triangle_sq(V[first[i, 0]], V[second[o, 0]], V[second[o, 1]],
                                                      V[second[o, 2]])
                        else:
                            dist = _segment_segment_sq(V[first[i, 0]], V[first[i, 1]], V[second[o, 0]],
                                                       V[second[o, 1]])
                        if dist < limit * (1.0 + ambiguity):
                            if n == out.shape[0]:
                                grown = np.empty((2 * n, 2), dtype=np.int64)
                                grown[:n] = out
                                out = grown
                                grownf = np.empty(2 * n, dtype=np.bool_)
                                grownf[:n] = flag
                                flag = grownf
                            out[n, 0] = i
                            out[n, 1] = o
                            flag[n] = dist >= limit * (1.0 - ambiguity)
                            n += 1
    return out[:n], flag[:n]


def close_pairs(V: np.ndarray, first: np.ndarray, second: np.ndarray, components: np.ndarray, limit: float,
                ambiguity: float = 1e-6, same: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i, j) of ``first`` [i] and ``second`` [j] primitives (rows of vertex indices into V
    (n, d) [mm]: 1 a point, 2 a segment, 3 a triangle; point-segment, point-triangle or
    segment-segment) of different ``components`` (per vertex) whose squared distance [mm^2] is
    below ``limit``, and a flag for those within ``ambiguity`` (relative) of it, which the caller
    decides with an exact reference. ``same``: one set, each pair once."""
    V = np.ascontiguousarray(V, dtype=float)
    first = np.ascontiguousarray(first, dtype=np.int64).reshape(len(first), -1)
    second = np.ascontiguousarray(second, dtype=np.int64).reshape(len(second), -1)
    if len(first) == 0 or len(second) == 0:
        return np.empty((0, 2), dtype=np.int64), np.empty(0, dtype=bool)
    return _close_pairs(V, first, second, np.ascontiguousarray(components, dtype=np.int64), float(limit),
                        float(ambiguity), bool(same))
