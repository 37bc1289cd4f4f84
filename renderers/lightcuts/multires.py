"""Multi-resolution light-sample selection (seed 003 §3.2, Algorithm 2, Eq 9–10).

Tree offsets are the heap ids of ``tree`` (root 1, leaves ``N .. 2N - 1``, ``n = levels`` levels).

Eq 9 (leaf range of a node) is correct for this layout: with ``ceil(log2(node + 1)) = depth(node) + 1``,

    lid_min = node * 2^(n - ceil(log2(node + 1))),  lid_max = lid_min + 2^(n - ceil(log2(node + 1))) - 1.

Eq 10 as printed,

    dist = floor(log2(node' + 1)) + floor(log2(node + 1)) - 2 floor(log2(gcd(2 floor(node'/2), 2 floor(node/2))) + 1),

is not a tree distance: it is negative for the root's children (2, 3 -> -1), for a node and itself (4, 4 -> -2)
and undefined when a ``floor(node/2)`` is 0 (``gcd(0, 0)``). The distance it names is the path length
``depth(a) + depth(b) - 2 depth(lca(a, b))``, computed exactly from the binary prefixes of the heap ids
(``tree_distance``). Inside ``nLight`` both nodes lie above the same leaf, so one is an ancestor of the other
and the distance is their depth difference.

``lrLS`` as described in the text ("true if lid_min is less than the smallest sample offset or lid_max is
greater than the largest") does not test what the sentence before it asks (whether a low-resolution sample is
a leaf of ``node``): it is true for a node whose range misses every sample and false for a range strictly
inside the samples' span that holds none. ``lrls`` implements the stated purpose: a sample offset in
``[lid_min, lid_max]``, found by binary search in the sorted ``LS'[p']``.

Which sample is reused, with which weight: ``reuse_sample``. The seed's ``nLight`` (the sample whose cut node
is nearest, ``n_light`` here, kept for reference and tests) reuses one fixed sample for every pixel of a
low-resolution pixel; with its weight it biased image means by +7 % (first of tied samples) and still −5 %
(ties broken at random) on small test scenes. ``reuse_sample`` instead uses that ``LC'[p']`` is a cut: the
samples under ``node`` either come from one ancestor cut node (one candidate, weight approximated) or from
cut nodes that partition ``node``'s subtree (one drawn in proportion to its intensity, exact weight).
Hierarchical sampling (the ``else`` branch of Algorithm 2) stays unbiased.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from . import _kernels as K
from ._kernels import ONE_MINUS, bitangent, descend, node_live, tangent, uniform

#: The per-pixel kernels renderers/gpu/codegen.py translates with those of ``_kernels``, in float32 ...
GLSL_FLOAT_ROOTS = ("select_pixel", "sort_pixel")
#: ... and in double precision (as the CPU's float64: a pixel's low-resolution pixel must be the same)
GLSL_DOUBLE_ROOTS = ("low_res_pixel",)


@njit(cache=True)
def depth(node):
    """Depth of a heap id (root 1 has depth 0): ``floor(log2(node))``."""
    d = 0
    while node > 1:
        node >>= 1
        d += 1
    return d


@njit(cache=True)
def leaf_range(node, levels):
    """Eq 9: first and last leaf offset under ``node`` in a tree of ``levels`` levels."""
    span = 1 << (levels - (depth(node) + 1))
    lo = node * span
    return lo, lo + span - 1


@njit(cache=True)
def tree_distance(a, b):
    """Number of edges on the tree path between heap ids ``a`` and ``b`` (what Eq 10 intends)."""
    da = depth(a)
    db = depth(b)
    if da > db:
        a >>= da - db
    else:
        b >>= db - da
    k = 0
    while a != b:
        a >>= 1
        b >>= 1
        k += 1
    return abs(da - db) + 2 * k


def eq10_as_printed(a: int, b: int) -> float:
    """Seed 003 Eq 10 exactly as printed (for the comparison in the docs and tests); NaN where undefined."""
    g = math.gcd(2 * (a // 2), 2 * (b // 2))
    if g == 0:
        return float("nan")
    return math.floor(math.log2(a + 1)) + math.floor(math.log2(b + 1)) - 2 * math.floor(math.log2(g) + 1)


@njit(cache=True)
def lrls(lr_leaves, q, count, lid_min, lid_max):
    """Index of the first entry of the sorted ``lr_leaves[q, :count]`` in ``[lid_min, lid_max]``, or -1."""
    lo = 0
    hi = count
    while lo < hi:
        mid = (lo + hi) >> 1
        if lr_leaves[q, mid] < lid_min:
            lo = mid + 1
        else:
            hi = mid
    if lo < count and lr_leaves[q, lo] <= lid_max:
        return lo
    return -1


@njit(cache=True)
def n_light(node, leaves, nodes, count, first, lid_max, pdfs=None, inten=None, u=0.0, depths=None):
    """nLight: among the samples from ``first`` with offset <= ``lid_max``, one whose cut node is nearest.

    Ties (common: e.g. every low-res cut node a leaf at the same depth) are broken at random with probability
    proportional to the reuse weight ``pdf' I(node') / I(node)`` when ``pdfs`` and ``inten`` are given (one
    uniform ``u``, rescaled per candidate), else the first tied sample is taken. With ``depths`` (the depth of
    each ``nodes`` entry) the distance is the depth difference: ``node`` and every candidate's cut node lie
    above the same leaf, so one is an ancestor of the other.
    """
    dn = depth(node)
    best = first
    best_d = tree_distance(node, nodes[first]) if depths is None else abs(dn - depths[first])
    j = first + 1
    while j < count and leaves[j] <= lid_max:
        d = tree_distance(node, nodes[j]) if depths is None else abs(dn - depths[j])
        if d < best_d:
            best_d = d
            best = j
        j += 1
    if pdfs is None:
        return best
    total = 0.0
    pick = best
    for q in range(best, j):
        dq = tree_distance(node, nodes[q]) if depths is None else abs(dn - depths[q])
        if dq != best_d:
            continue
        wq = pdfs[q] * inten[nodes[q]]
        if wq <= 0.0:
            continue
        total += wq
        r = wq / total
        if u < r:
            pick = q
            u = u / r
        else:
            u = (u - r) / (1.0 - r)
        u = min(u, K.ONE_MINUS)
    return pick


@njit(cache=True)
def reuse_sample(node, lr_leaves, lr_nodes, lr_pdfs, lr_depths, q, count, first, lid_max, inten, u):
    """The reused sample ``LS'[q][index]`` for cut node ``node`` and its probability ``(index, pdf)`` (used by
    Algorithm 2).

    The low-resolution cut ``LC'[p']`` partitions the lights, so the samples under ``node`` come either
    (a) from one cut node ``node'`` above ``node`` — a single candidate, probability approximated by
    ``pdf'(l | node') · I(node') / I(node)`` (branch probabilities between the two replaced by intensity shares;
    exact when ``node' = node``) — or (b) from cut nodes ``node'_j`` at or below ``node``, which partition its
    subtree: one is drawn with probability ``q_j = I(node'_j) / Σ I`` and ``pdf = pdf'_j · q_j``, so
    ``f(l_j) / pdf`` estimates the whole subtree without bias apart from nodes that had no live sample at
    ``p'``. This replaces the seed's "nearest node" choice (``n_light``), which drew a fixed sample per region
    and biased the image (−5 % to +7 % on small lamps; docs/lightcuts.md).
    """
    dn = depth(node)
    if lr_depths[q, first] < dn:
        return first, lr_pdfs[q, first] * inten[lr_nodes[q, first]] / inten[node]
    total = 0.0
    pick = first
    pick_w = 0.0
    j = first
    while j < count and lr_leaves[q, j] <= lid_max:
        wj = inten[lr_nodes[q, j]]
        if wj > 0.0:
            total += wj
            r = wj / total
            if u < r:
                pick = j
                pick_w = wj
                u = u / r
            else:
                u = (u - r) / (1.0 - r)
            u = min(u, ONE_MINUS)
        j += 1
    if total <= 0.0:
        return first, lr_pdfs[q, first]
    return pick, lr_pdfs[q, pick] * pick_w / total


@njit(cache=True)
def sort_pixel(q, cuts, sizes, leaves, pdfs, ls_leaves, ls_nodes, ls_pdfs, ls_depths):
    """``LS'[q]``: the samples of low-resolution pixel ``q`` that have a light (``leaves[q, s] >= 0``, ``s <
    sizes[q]``) sorted by leaf offset by insertion (stable: ties keep the slot order), with their cut node, pdf
    and node depth. Returns their count."""
    count = 0
    for s in range(sizes[q]):
        lf = leaves[q, s]
        if lf >= 0:
            r = count - 1
            while r >= 0 and ls_leaves[q, r] > lf:
                ls_leaves[q, r + 1] = ls_leaves[q, r]
                ls_nodes[q, r + 1] = ls_nodes[q, r]
                ls_pdfs[q, r + 1] = ls_pdfs[q, r]
                ls_depths[q, r + 1] = ls_depths[q, r]
                r -= 1
            ls_leaves[q, r + 1] = lf
            ls_nodes[q, r + 1] = cuts[q, s]
            ls_pdfs[q, r + 1] = pdfs[q, s]
            ls_depths[q, r + 1] = depth(cuts[q, s])
            count += 1
    return count


@njit(cache=True, parallel=True)
def _sort_rows(cut, size, leaf, pdf, leaves, nodes, pdfs, depths, counts):
    for q in prange(cut.shape[0]):
        counts[q] = sort_pixel(q, cut, size, leaf, pdf, leaves, nodes, pdfs, depths)
        r = counts[q]
        for s in range(cut.shape[1]):   # then the empty entries in slot order (those past the cut too)
            if leaf[q, s] < 0 or s >= size[q]:
                leaves[q, r] = leaf[q, s]
                nodes[q, r] = cut[q, s]
                pdfs[q, r] = pdf[q, s]
                depths[q, r] = depth(max(cut[q, s], 1))
                r += 1


def sort_low_res_samples(cut, size, leaf, pdf):
    """``LS'`` per low-resolution pixel sorted by leaf offset: ``(leaves, nodes, pdfs, counts, depths)``.

    ``cut``/``leaf``/``pdf`` are the ``(P', B')`` outputs of ``sampling.cut_and_sample``; empty entries
    (``leaf = -1``) follow the ``counts`` sorted ones.
    """
    leaves, nodes, pdfs, depths = (np.empty_like(leaf), np.empty_like(cut), np.empty_like(pdf), np.empty_like(cut))
    counts = np.zeros(cut.shape[0], dtype=np.int64)
    _sort_rows(cut, np.asarray(size, dtype=np.int64), leaf, pdf, leaves, nodes, pdfs, depths, counts)
    return leaves, nodes, pdfs, counts, depths


@njit(cache=True)
def low_res_pixel(x, y, scale_x, scale_y, lr_width, lr_height):
    """Algorithm 2's low-resolution pixel ``p'`` under pixel ``(x, y)`` (``scale``: w' / w, h' / h), row-major."""
    return min(int(y * scale_y), lr_height - 1) * lr_width + min(int(x * scale_x), lr_width - 1)


@njit(cache=True)
def select_pixel(i, q, seed, pos, nrm, pix_id, fmap, cuts, sizes, bmin, bmax, inten, n_leaves, levels, clamp2,
                 lr_leaves, lr_nodes, lr_pdfs, lr_counts, lr_depths, leaves, pdfs):
    """Algorithm 2 for pixel ``i`` over low-resolution pixel ``q``: for each cut node, with probability
    ``1 - map[p]`` (uniform ``rad``, slot ``2 s + 1``) the reused sample ``LS'[q]`` under the node (Eq 9's leaf
    range; ``lrls``, ``reuse_sample``), else (or if none) hierarchical importance sampling (slot ``2 s``). Writes
    ``leaves[i, s]``, ``pdfs[i, s]``; returns the number of reused samples. The minima with ``ONE_MINUS`` keep
    the GPU's float32 uniforms below 1 (for ``rad / (1 - map)`` also the CPU's, where it would round to 1)."""
    p = pos[i]
    nn = nrm[i]
    t = tangent(nn[0], nn[1], nn[2])
    b = bitangent(nn[0], nn[1], nn[2])
    reused = 0
    for s in range(sizes[i]):
        k = cuts[i, s]
        leaves[i, s] = -1
        pdfs[i, s] = 0.0
        if node_live(p, nn, t, b, bmin, bmax, inten, k):
            rad = min(uniform(seed, pix_id[i], 2 * s + 1), ONE_MINUS)
            first = -1
            if rad <= 1.0 - fmap[i] and lr_counts[q] > 0:
                lo, hi = leaf_range(k, levels)
                first = lrls(lr_leaves, q, lr_counts[q], lo, hi)
                if first >= 0:
                    j, pj = reuse_sample(k, lr_leaves, lr_nodes, lr_pdfs, lr_depths, q, lr_counts[q], first, hi,
                                         inten, min(rad / (1.0 - fmap[i]), ONE_MINUS) if fmap[i] < 1.0 else 0.0)
                    leaves[i, s] = lr_leaves[q, j]
                    pdfs[i, s] = pj
                    reused += 1
            if first < 0:
                u = min(uniform(seed, pix_id[i], 2 * s), ONE_MINUS)
                lf, pr = descend(p, nn, t, b, bmin, bmax, inten, n_leaves, k, u, clamp2)
                leaves[i, s] = lf
                pdfs[i, s] = pr
    return reused


@njit(cache=True, parallel=True)
def select_lights(pos, nrm, pix_id, pix_x, pix_y, fmap, cut, size, bmin, bmax, inten, n_leaves, levels, clamp2,
                  seed, lr_leaves, lr_nodes, lr_pdfs, lr_counts, lr_depths, scale_x, scale_y, lr_width, lr_height,
                  leaf, pdf):
    """Algorithm 2 for every pixel: reuse a low-resolution sample with probability ``1 - map[p]`` when one
    lies under the cut node, else hierarchical importance sampling. Returns the number of reused samples."""
    n_pix = pos.shape[0]
    reused = np.zeros(n_pix, dtype=np.int64)
    for i in prange(n_pix):
        q = low_res_pixel(pix_x[i], pix_y[i], scale_x, scale_y, lr_width, lr_height)
        reused[i] = select_pixel(i, q, seed, pos, nrm, pix_id, fmap, cut, size, bmin, bmax, inten,
                                 n_leaves, levels, clamp2, lr_leaves, lr_nodes, lr_pdfs, lr_counts, lr_depths, leaf,
                                 pdf)
        for s in range(size[i], leaf.shape[1]):
            leaf[i, s] = -1
            pdf[i, s] = 0.0
    return reused
