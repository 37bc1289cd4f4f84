"""Bounding-volume hierarchy for the GPU ray caster, built on the CPU (numba, binned SAH).

Top-down build: at each node the triangles are binned by centroid into ``BINS`` slabs along each axis and the
split of least surface-area-heuristic cost ``C_t + (A_l N_l + A_r N_r) / A`` is taken (Wald 2007, "On fast
construction of SAH-based bounding volume hierarchies"); a node becomes a leaf when it holds at most
``MAX_LEAF`` triangles or no split beats intersecting all of them (up to ``MAX_LEAF_FORCED``). Children are
stored next to each other, so an inner node needs one index.

GPU layout (64 bytes per inner node, 48 per triangle), read by ``trace`` in ``shaders/scene.glsl``: only inner
nodes are stored, each holding both children's boxes, so one visit reads one node and tests leaves directly:

* inner node ``k``: for its left and right child ``vec4(bmin, ref), vec4(bmax, count)`` with the integer bits of
  ``ref, count`` in the float slots; a leaf child has ``count`` > 0 triangles from ``ref``, an inner child
  ``count`` = 0 and ``ref`` its node index. A tree that is a single leaf gets a root with an empty right child.
* triangle ``i`` (in leaf order): ``vec4(v0, prim id), vec4(e1 = v1 - v0, material), vec4(e2 = v2 - v0, 0)``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

BINS = 16
MAX_LEAF = 4
MAX_LEAF_FORCED = 16
TRAVERSAL_COST = 1.0
#: Deepest tree the shader's traversal stack holds (``BVH_STACK`` in ``shaders/bvh.glsl``).
MAX_DEPTH = 64


@njit(cache=True, inline="always")
def _area(lo, hi):
    dx = max(hi[0] - lo[0], 0.0)
    dy = max(hi[1] - lo[1], 0.0)
    dz = max(hi[2] - lo[2], 0.0)
    return dx * dy + dy * dz + dz * dx


@njit(cache=True)
def _build(tmin, tmax, cent, order, nmin, nmax, na, nb):
    """Fill node arrays; returns ``(node count, depth)`` (``-1`` if the depth would exceed ``MAX_DEPTH``).
    ``order`` is permuted into leaf order."""
    n = cent.shape[0]
    stack = np.empty((MAX_DEPTH + 2, 4), dtype=np.int64)  # node, start, end, depth
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3] = 0, 0, n, 1
    sp = 1
    n_nodes = 1
    max_depth = 1
    bin_lo = np.empty((BINS, 3))
    bin_hi = np.empty((BINS, 3))
    bin_n = np.empty(BINS, dtype=np.int64)
    right_area = np.empty(BINS)
    right_n = np.empty(BINS, dtype=np.int64)
    lo = np.empty(3)
    hi = np.empty(3)
    clo = np.empty(3)
    chi = np.empty(3)
    acc_lo = np.empty(3)
    acc_hi = np.empty(3)
    while sp > 0:
        sp -= 1
        node, start, end, depth = stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3]
        max_depth = max(max_depth, depth)
        for a in range(3):
            lo[a] = np.inf
            hi[a] = -np.inf
            clo[a] = np.inf
            chi[a] = -np.inf
        for q in range(start, end):
            i = order[q]
            for a in range(3):
                lo[a] = min(lo[a], tmin[i, a])
                hi[a] = max(hi[a], tmax[i, a])
                clo[a] = min(clo[a], cent[i, a])
                chi[a] = max(chi[a], cent[i, a])
        for a in range(3):
            nmin[node, a] = lo[a]
            nmax[node, a] = hi[a]
        count = end - start
        if count <= MAX_LEAF:
            na[node], nb[node] = start, count
            continue
        best_cost = np.inf
        best_axis = -1
        best_bin = -1
        for a in range(3):
            ext = chi[a] - clo[a]
            if ext <= 0.0:
                continue
            scale = BINS / ext
            for b in range(BINS):
                bin_n[b] = 0
                for c in range(3):
                    bin_lo[b, c] = np.inf
                    bin_hi[b, c] = -np.inf
            for q in range(start, end):
                i = order[q]
                b = min(BINS - 1, int((cent[i, a] - clo[a]) * scale))
                bin_n[b] += 1
                for c in range(3):
                    bin_lo[b, c] = min(bin_lo[b, c], tmin[i, c])
                    bin_hi[b, c] = max(bin_hi[b, c], tmax[i, c])
            # sweep from the right: area and count of bins b..BINS-1
            for c in range(3):
                acc_lo[c] = np.inf
                acc_hi[c] = -np.inf
            cnt = 0
            for b in range(BINS - 1, 0, -1):
                cnt += bin_n[b]
                for c in range(3):
                    acc_lo[c] = min(acc_lo[c], bin_lo[b, c])
                    acc_hi[c] = max(acc_hi[c], bin_hi[b, c])
                right_area[b] = _area(acc_lo, acc_hi) if cnt > 0 else 0.0
                right_n[b] = cnt
            for c in range(3):
                acc_lo[c] = np.inf
                acc_hi[c] = -np.inf
            cnt = 0
            for b in range(BINS - 1):
                cnt += bin_n[b]
                for c in range(3):
                    acc_lo[c] = min(acc_lo[c], bin_lo[b, c])
                    acc_hi[c] = max(acc_hi[c], bin_hi[b, c])
                if cnt == 0 or right_n[b + 1] == 0:
                    continue
                cost = _area(acc_lo, acc_hi) * cnt + right_area[b + 1] * right_n[b + 1]
                if cost < best_cost:
                    best_cost, best_axis, best_bin = cost, a, b
        parent_area = _area(lo, hi)
        split_cost = TRAVERSAL_COST + best_cost / parent_area if parent_area > 0.0 else np.inf
        if count <= MAX_LEAF_FORCED and (best_axis < 0 or split_cost >= count):
            na[node], nb[node] = start, count
            continue
        if best_axis >= 0:
            a = best_axis
            scale = BINS / (chi[a] - clo[a])
            i0, i1 = start, end - 1
            while i0 <= i1:
                b = min(BINS - 1, int((cent[order[i0], a] - clo[a]) * scale))
                if b <= best_bin:
                    i0 += 1
                else:
                    order[i0], order[i1] = order[i1], order[i0]
                    i1 -= 1
            mid = i0
        else:  # all centroids coincide: split by index
            mid = (start + end) // 2
        if depth + 1 > MAX_DEPTH:
            return -1, depth + 1
        left = n_nodes
        n_nodes += 2
        na[node], nb[node] = left, 0
        stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3] = left + 1, mid, end, depth + 1
        sp += 1
        stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3] = left, start, mid, depth + 1
        sp += 1
    return n_nodes, max_depth


def _wide(nmin, nmax, na, nb) -> np.ndarray:
    """Inner nodes with their children's boxes (the layout above) from the binary tree's node arrays."""
    if nb[0] > 0:  # a single leaf: a root whose right child is empty (an inverted box that nothing hits)
        nmin = np.vstack([nmin[:1], nmin[:1], np.full((1, 3), np.inf)])
        nmax = np.vstack([nmax[:1], nmax[:1], np.full((1, 3), -np.inf)])
        na = np.array([1, na[0], 0])
        nb = np.array([0, nb[0], 1])
    inner = np.nonzero(nb == 0)[0]
    index = np.full(len(nb), -1, dtype=np.int64)
    index[inner] = np.arange(len(inner))
    out = np.zeros((len(inner), 16), dtype=np.float32)
    ints = out.view(np.int32)
    for side in (0, 1):
        child = na[inner] + side
        leaf = nb[child] > 0
        out[:, 8 * side:8 * side + 3] = nmin[child]
        out[:, 8 * side + 4:8 * side + 7] = nmax[child]
        ints[:, 8 * side + 3] = np.where(leaf, na[child], index[child])
        ints[:, 8 * side + 7] = np.where(leaf, nb[child], 0)
    return out


class BVH:
    """A built hierarchy: ``nodes`` (n, 8) float32 and ``tris`` (m, 12) float32 in the GPU layout above."""

    def __init__(self, nodes: np.ndarray, tris: np.ndarray, depth: int):
        self.nodes = nodes
        self.tris = tris
        self.depth = depth

    @property
    def nbytes(self) -> int:
        return self.nodes.nbytes + self.tris.nbytes


def build(vertices: np.ndarray, faces: np.ndarray) -> BVH:
    """Binned-SAH BVH of a triangle mesh (float32 vertices, int32 faces)."""
    v = np.asarray(vertices, dtype=np.float32)
    f = np.asarray(faces, dtype=np.int64)
    tri = v[f]                                              # (m, 3, 3) float32
    tmin = tri.min(axis=1).astype(np.float64)
    tmax = tri.max(axis=1).astype(np.float64)
    cent = 0.5 * (tmin + tmax)
    m = len(f)
    order = np.arange(m, dtype=np.int64)
    cap = 2 * m + 1
    nmin = np.empty((cap, 3))
    nmax = np.empty((cap, 3))
    na = np.zeros(cap, dtype=np.int64)
    nb = np.zeros(cap, dtype=np.int64)
    n_nodes, depth = _build(tmin, tmax, cent, order, nmin, nmax, na, nb)
    if n_nodes < 0:
        raise ValueError(f"the scene's BVH would be deeper than {MAX_DEPTH} levels (degenerate geometry)")
    nodes = _wide(nmin[:n_nodes], nmax[:n_nodes], na[:n_nodes], nb[:n_nodes])
    t = tri[order]
    tris = np.zeros((m, 12), dtype=np.float32)
    tris[:, 0:3] = t[:, 0]
    tris.view(np.int32)[:, 3] = order
    tris[:, 4:7] = t[:, 1] - t[:, 0]
    tris[:, 8:11] = t[:, 2] - t[:, 0]
    return BVH(nodes, tris, int(depth))
