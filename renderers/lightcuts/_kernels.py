"""numba kernels of stochastic lightcuts (Lin & Yuksel 2020): bounds, cuts, hierarchical importance sampling.

All kernels take the tree as plain arrays (``bmin``, ``bmax``, ``intensity``, ``light_pos``, ``light_rgb``,
``n_leaves``) and shading points as ``(P, 3)`` arrays, so they do not depend on any scene class.

Conservative bounds. The geometry bound of a node box seen from ``p`` with normal ``N`` is

    geom = nrm_max / sqrt(nrm_max^2 + tng_min^2),   0 if nrm_max <= 0,

with ``nrm_max = max_box N.(x - p)`` and ``tng_min^2 = min_box (T.(x - p))^2 + min_box (B.(x - p))^2`` for an
orthonormal frame ``(T, B, N)``; it is an upper bound of ``cos(theta)`` over the box. ``N.(x - p)`` is always
summed as ``sum_a N_a (x_a - p_a)`` in axis order, so a parent's ``nrm_max`` is >= every leaf's (IEEE
rounding is monotone) and a node with ``geom = 0`` holds only lights whose contribution is exactly 0:
skipping such nodes, or giving them probability 0, keeps the estimator unbiased.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

_M1 = np.uint64(0x9E3779B97F4A7C15)
_M2 = np.uint64(0xBF58476D1CE4E5B9)
_M3 = np.uint64(0x94D049BB133111EB)
_INV53 = 1.0 / 9007199254740992.0
ONE_MINUS = 1.0 - 2.0 ** -53

#: The kernels renderers/gpu/codegen.py translates into GLSL (``lightcuts_gen.glsl``), in double precision ...
GLSL_DOUBLE_ROOTS = ("uniform",)
#: ... and in float32 (the tree's arrays become the shader's tree image, codegen.lightcuts_glsl).
GLSL_FLOAT_ROOTS = ("refine_cut", "prob_left", "descend", "sample_weight", "node_live", "cut_pixel",
                    "sample_pixel", "shade_pixel")


@njit(cache=True)
def uniform(seed, pixel, slot):
    """Counter-based uniform number in [0, 1) from (seed, pixel, slot): splitmix64 of a mixed key."""
    x = np.uint64(seed) * _M1 + np.uint64(pixel) * _M2 + np.uint64(slot) * _M3 + _M1
    x ^= x >> np.uint64(30)
    x *= _M2
    x ^= x >> np.uint64(27)
    x *= _M3
    x ^= x >> np.uint64(31)
    return float(x >> np.uint64(11)) * _INV53


@njit(cache=True)
def uniform_f(seed, pixel, slot):
    """:func:`uniform` capped at ``ONE_MINUS``: no float64 uniform changes; the GPU's float32 one stays below 1."""
    return min(uniform(seed, pixel, slot), ONE_MINUS)


@njit(cache=True)
def tangent(n0, n1, n2):
    """Tangent T of a unit normal's orthonormal frame (T, B, N) (Duff et al. 2017)."""
    sgn = 1.0 if n2 >= 0.0 else -1.0
    a = -1.0 / (sgn + n2)
    return 1.0 + sgn * n0 * n0 * a, sgn * (n0 * n1 * a), -sgn * n0


@njit(cache=True)
def bitangent(n0, n1, n2):
    """Bitangent B of the frame of ``tangent``."""
    sgn = 1.0 if n2 >= 0.0 else -1.0
    a = -1.0 / (sgn + n2)
    return n0 * n1 * a, sgn + n1 * n1 * a, -n1


@njit(cache=True)
def dot_interval(v0, v1, v2, p, bmin, bmax, k):
    """Range ``[lo, hi]`` of ``v.(x - p)`` over the box of node ``k``."""
    lo = 0.0
    hi = 0.0
    for a in range(3):
        va = v0 if a == 0 else (v1 if a == 1 else v2)
        x0 = va * (bmin[k, a] - p[a])
        x1 = va * (bmax[k, a] - p[a])
        if x0 < x1:
            lo += x0
            hi += x1
        else:
            lo += x1
            hi += x0
    return lo, hi


@njit(cache=True)
def geom_bound(p, n, t, b, bmin, bmax, k):
    """Upper bound of ``cos(theta)`` over the box of node ``k`` (0 if the box is behind the surface)."""
    _, nrm_max = dot_interval(n[0], n[1], n[2], p, bmin, bmax, k)
    if nrm_max <= 0.0:
        return 0.0
    lo_t, hi_t = dot_interval(t[0], t[1], t[2], p, bmin, bmax, k)
    lo_b, hi_b = dot_interval(b[0], b[1], b[2], p, bmin, bmax, k)
    tt = 0.0 if lo_t <= 0.0 <= hi_t else min(abs(lo_t), abs(hi_t))
    bb = 0.0 if lo_b <= 0.0 <= hi_b else min(abs(lo_b), abs(hi_b))
    return nrm_max / math.sqrt(nrm_max * nrm_max + tt * tt + bb * bb)


@njit(cache=True)
def box_dist2(p, bmin, bmax, k):
    """Squared distances from ``p`` to the closest and the farthest point of node ``k``'s box."""
    dmin = 0.0
    dmax = 0.0
    for a in range(3):
        lo = bmin[k, a] - p[a]
        hi = bmax[k, a] - p[a]
        if lo > 0.0:
            dmin += lo * lo
        elif hi < 0.0:
            dmin += hi * hi
        m = max(abs(lo), abs(hi))
        dmax += m * m
    return dmin, dmax


@njit(cache=True)
def box_terms(p, n, t, b, bmin, bmax, k):
    """``(geom_bound, dmin^2, dmax^2)`` of node ``k`` in one pass over its box (see ``geom_bound``)."""
    nlo = 0.0
    nhi = 0.0
    tlo = 0.0
    thi = 0.0
    blo = 0.0
    bhi = 0.0
    dmin = 0.0
    dmax = 0.0
    for a in range(3):
        lo = bmin[k, a] - p[a]
        hi = bmax[k, a] - p[a]
        x0 = n[a] * lo
        x1 = n[a] * hi
        nlo += min(x0, x1)
        nhi += max(x0, x1)
        x0 = t[a] * lo
        x1 = t[a] * hi
        tlo += min(x0, x1)
        thi += max(x0, x1)
        x0 = b[a] * lo
        x1 = b[a] * hi
        blo += min(x0, x1)
        bhi += max(x0, x1)
        c = max(lo, 0.0) + min(hi, 0.0)  # lo if lo > 0, hi if hi < 0, else 0
        dmin += c * c
        m = max(-lo, hi)
        dmax += m * m
    if nhi <= 0.0:
        return 0.0, dmin, dmax
    tt = 0.0 if tlo <= 0.0 <= thi else min(abs(tlo), abs(thi))
    bb = 0.0 if blo <= 0.0 <= bhi else min(abs(blo), abs(bhi))
    return nhi / math.sqrt(nhi * nhi + tt * tt + bb * bb), dmin, dmax


@njit(cache=True)
def error_bound(p, n, t, b, bmin, bmax, inten, n_leaves, k, clamp2):
    """Cut-refinement error ``I geom / max(dmin^2, clamp^2)``; 0 for leaves and empty nodes."""
    if k >= n_leaves or inten[k] <= 0.0:
        return 0.0
    g, dmin, _ = box_terms(p, n, t, b, bmin, bmax, k)
    if g <= 0.0:
        return 0.0
    return inten[k] * g / max(dmin, clamp2)


@njit(cache=True)
def prob_left(p, n, t, b, bmin, bmax, inten, k, clamp2):
    """Probability of descending from node ``k`` to its left child ``2k``.

    Weight ``w = I geom``; the probability averages the normalised weights divided by the closest-point and by
    the farthest-point squared distances (both clamped below by ``clamp2``). It is > 0 whenever the left
    subtree can contribute and 0 when it cannot.
    """
    c0 = 2 * k
    c1 = c0 + 1
    i0 = inten[c0]
    i1 = inten[c1]
    if i0 <= 0.0:
        return 0.0
    if i1 <= 0.0:
        return 1.0
    g0, dmin0, dmax0 = box_terms(p, n, t, b, bmin, bmax, c0)
    g1, dmin1, dmax1 = box_terms(p, n, t, b, bmin, bmax, c1)
    w0 = i0 * g0
    w1 = i1 * g1
    if w0 + w1 <= 0.0:
        return i0 / (i0 + i1)
    if w0 <= 0.0:
        return 0.0
    if w1 <= 0.0:
        return 1.0
    a0 = w0 / max(dmin0, clamp2)
    a1 = w1 / max(dmin1, clamp2)
    f0 = w0 / max(dmax0, clamp2)
    f1 = w1 / max(dmax1, clamp2)
    return 0.5 * (a0 / (a0 + a1) + f0 / (f0 + f1))


@njit(cache=True)
def descend(p, n, t, b, bmin, bmax, inten, n_leaves, node, u, clamp2):
    """Hierarchical importance sampling from ``node`` to a leaf with one uniform ``u`` rescaled per level.

    Returns ``(leaf_node, pdf)`` where ``pdf`` is the product of the branch probabilities.
    """
    pdf = 1.0
    while node < n_leaves:
        pl = prob_left(p, n, t, b, bmin, bmax, inten, node, clamp2)
        if u < pl:
            node = 2 * node
            u = u / pl
            pdf *= pl
        else:
            node = 2 * node + 1
            u = (u - pl) / (1.0 - pl)
            pdf *= 1.0 - pl
        u = min(u, ONE_MINUS)
    return node, pdf


@njit(cache=True)
def leaf_pdf(p, n, t, b, bmin, bmax, inten, n_leaves, node, leaf, clamp2):
    """Probability that ``descend`` from ``node`` ends at ``leaf`` (0 if ``leaf`` is not below ``node``)."""
    depth_node = 0
    x = node
    while x > 1:
        x >>= 1
        depth_node += 1
    depth_leaf = 0
    x = leaf
    while x > 1:
        x >>= 1
        depth_leaf += 1
    shift = depth_leaf - depth_node
    if shift < 0 or (leaf >> shift) != node:
        return 0.0
    pdf = 1.0
    k = node
    for s in range(shift - 1, -1, -1):
        pl = prob_left(p, n, t, b, bmin, bmax, inten, k, clamp2)
        if (leaf >> s) & 1:
            pdf *= 1.0 - pl
            k = 2 * k + 1
        else:
            pdf *= pl
            k = 2 * k
    return pdf


@njit(cache=True)
def refine_cut(p, n, t, b, bmin, bmax, inten, n_leaves, clamp2, budget, cut, err):
    """Refine one point's cut from the root to ``budget`` nodes, always splitting the first node of largest
    error; stops early when no node has error left. ``cut`` receives the node ids sorted by heap offset, ``err``
    is scratch (both of length >= budget). Returns the cut size."""
    if budget <= 0:
        return 0
    cut[0] = 1
    err[0] = error_bound(p, n, t, b, bmin, bmax, inten, n_leaves, 1, clamp2)
    m = 1
    while m < budget:
        j = 0
        for q in range(1, m):
            if err[q] > err[j]:
                j = q
        if err[j] <= 0.0:
            break
        k = cut[j]
        cut[j] = 2 * k
        err[j] = error_bound(p, n, t, b, bmin, bmax, inten, n_leaves, 2 * k, clamp2)
        cut[m] = 2 * k + 1
        err[m] = error_bound(p, n, t, b, bmin, bmax, inten, n_leaves, 2 * k + 1, clamp2)
        m += 1
    for q in range(1, m):  # insertion sort by heap offset
        v = cut[q]
        r = q - 1
        while r >= 0 and cut[r] > v:
            cut[r + 1] = cut[r]
            r -= 1
        cut[r + 1] = v
    return m


@njit(cache=True)
def cut_pixel(i, pos, nrm, budgets, bmin, bmax, inten, n_leaves, clamp2, cut, err):
    """Pixel ``i`` of ``build_cuts``: its cut refined to ``budgets[i]`` nodes into ``cut`` (scratch ``err``, both
    of length >= the budget); returns its size (0 for a budget <= 0)."""
    nb = budgets[i]
    if nb <= 0:
        return 0
    p = pos[i]
    nn = nrm[i]
    t = tangent(nn[0], nn[1], nn[2])
    b = bitangent(nn[0], nn[1], nn[2])
    return refine_cut(p, nn, t, b, bmin, bmax, inten, n_leaves, clamp2, nb, cut, err)


@njit(cache=True, parallel=True)
def build_cuts(pos, nrm, budget, bmin, bmax, inten, n_leaves, clamp2, cut, err):
    """Refine each pixel's cut from the root to ``budget[i]`` nodes by the largest error bound.

    ``cut`` (P, B) receives the node ids sorted ascending (heap offsets), ``err`` (P, B) is scratch.
    Refinement stops early when every cut node has error 0 (leaves, empty or back-facing nodes).
    Returns the cut sizes (P,).
    """
    n_pix = pos.shape[0]
    size = np.zeros(n_pix, dtype=np.int32)
    for i in prange(n_pix):
        size[i] = cut_pixel(i, pos, nrm, budget, bmin, bmax, inten, n_leaves, clamp2, cut[i], err[i])
    return size


@njit(cache=True)
def node_live(p, n, t, b, bmin, bmax, inten, k):
    """True if node ``k`` can contribute at ``p`` (non-zero intensity and geometry bound)."""
    return inten[k] > 0.0 and geom_bound(p, n, t, b, bmin, bmax, k) > 0.0


@njit(cache=True)
def sample_pixel(i, seed, pos, nrm, pix_id, cuts, sizes, bmin, bmax, inten, n_leaves, clamp2, leaves, pdfs):
    """Pixel ``i`` of ``sample_cuts``: a light ``leaves[i, s]`` drawn with probability ``pdfs[i, s]`` for each of
    its cut nodes ``cuts[i, s]`` (random slot ``2 s``, :func:`uniform_f`), -1 and 0 where the node cannot
    contribute."""
    p = pos[i]
    nn = nrm[i]
    t = tangent(nn[0], nn[1], nn[2])
    b = bitangent(nn[0], nn[1], nn[2])
    for s in range(sizes[i]):
        k = cuts[i, s]
        leaves[i, s] = -1
        pdfs[i, s] = 0.0
        if node_live(p, nn, t, b, bmin, bmax, inten, k):
            u = uniform_f(seed, pix_id[i], 2 * s)
            lf, pr = descend(p, nn, t, b, bmin, bmax, inten, n_leaves, k, u, clamp2)
            leaves[i, s] = lf
            pdfs[i, s] = pr


@njit(cache=True, parallel=True)
def sample_cuts(pos, nrm, pix_id, cut, size, bmin, bmax, inten, n_leaves, clamp2, seed, leaf, pdf):
    """One light per cut node by hierarchical importance sampling; ``leaf = -1`` where a node cannot contribute."""
    for i in prange(pos.shape[0]):
        sample_pixel(i, seed, pos, nrm, pix_id, cut, size, bmin, bmax, inten, n_leaves, clamp2, leaf, pdf)
        for s in range(size[i], leaf.shape[1]):
            leaf[i, s] = -1
            pdf[i, s] = 0.0


@njit(cache=True, inline="always")
def sample_weight(p, n, light_pos, light_nrm, one_sided, j, pdf, clamp2):
    """``cos / max(d^2, clamp2) / (pi pdf)`` of light ``j`` drawn with probability ``pdf`` at ``p`` (normal ``n``),
    times the emitter cosine ``n_l . (p - x_l) / d`` when ``one_sided``; 0 when the light is behind the point or
    the point behind the emitter. ``N.(x - p)`` is summed per axis as in ``box_terms``."""
    cosnum = 0.0
    d2 = 0.0
    for a in range(3):
        d = light_pos[j, a] - p[a]
        cosnum += n[a] * d
        d2 += d * d
    if cosnum <= 0.0:
        return 0.0
    g = cosnum / math.sqrt(d2) / max(d2, clamp2) / (math.pi * pdf)
    if one_sided and (light_nrm[j, 0] != 0.0 or light_nrm[j, 1] != 0.0 or light_nrm[j, 2] != 0.0):
        em = 0.0
        for a in range(3):
            em -= light_nrm[j, a] * (light_pos[j, a] - p[a])
        if em <= 0.0:
            return 0.0
        g *= em / math.sqrt(d2)
    return g


@njit(cache=True)
def sample_estimate(p, n, alb, lf, pr, light_pos, light_rgb, light_nrm, one_sided, n_leaves, clamp2):
    """Unshadowed Lambertian estimate (RGB) of light ``lf`` (a heap node, -1: none) drawn with probability ``pr``
    at ``p`` (normal ``n``, diffuse albedo ``alb``): ``albedo * I_rgb * sample_weight``."""
    if lf < 0 or pr <= 0.0:
        return 0.0, 0.0, 0.0
    j = lf - n_leaves
    g = sample_weight(p, n, light_pos, light_nrm, one_sided, j, pr, clamp2)
    return alb[0] * light_rgb[j, 0] * g, alb[1] * light_rgb[j, 1] * g, alb[2] * light_rgb[j, 2] * g


@njit(cache=True, parallel=True)
def shade_samples(pos, nrm, alb, leaf, pdf, light_pos, light_rgb, light_nrm, one_sided, n_leaves, clamp2):
    """The samples that need a shadow ray: a boolean (P, S) mask of those whose unshadowed estimate
    (``sample_estimate``) is > 0."""
    n_pix, n_s = leaf.shape
    need = np.zeros((n_pix, n_s), dtype=np.bool_)
    for i in prange(n_pix):
        for s in range(n_s):
            v = sample_estimate(pos[i], nrm[i], alb[i], leaf[i, s], pdf[i, s], light_pos, light_rgb, light_nrm,
                                one_sided, n_leaves, clamp2)
            need[i, s] = v[0] + v[1] + v[2] > 0.0
    return need


@njit(cache=True)
def shade_pixel(i, s0, s1, pos, nrm, albedo, leaves, pdfs, light_pos, light_rgb, light_nrm, one_sided, n_leaves,
                clamp2, blocked):
    """Direct diffuse radiance of pixel ``i`` from its samples ``[s0, s1)``: the sum, in slot order, of the
    estimates that are > 0 and whose shadow ray is not ``blocked[i, s]`` (asked only for those); returns ``(r, g,
    b, samples with a light)``."""
    c0 = 0.0
    c1 = 0.0
    c2 = 0.0
    drawn = 0
    for s in range(s0, s1):
        lf = leaves[i, s]
        if lf >= 0:
            drawn += 1
            v = sample_estimate(pos[i], nrm[i], albedo[i], lf, pdfs[i, s], light_pos, light_rgb, light_nrm, one_sided,
                                n_leaves, clamp2)
            if v[0] + v[1] + v[2] > 0.0 and not blocked[i, s]:
                c0 += v[0]
                c1 += v[1]
                c2 += v[2]
    return c0, c1, c2, drawn


@njit(cache=True, parallel=True)
def shade_pixels(pos, nrm, alb, leaf, pdf, light_pos, light_rgb, light_nrm, one_sided, n_leaves, clamp2, blocked):
    """``shade_pixel`` of every pixel over all its samples: the radiance (P, 3)."""
    out = np.zeros((leaf.shape[0], 3))
    for i in prange(leaf.shape[0]):
        c0, c1, c2, _ = shade_pixel(i, 0, leaf.shape[1], pos, nrm, alb, leaf, pdf, light_pos, light_rgb, light_nrm,
                                    one_sided, n_leaves, clamp2, blocked)
        out[i, 0] = c0
        out[i, 1] = c1
        out[i, 2] = c2
    return out
