"""Compiled kernels of the GT renderer (numba): where a pixel's samples lie and how a pixel filter resolves them.

The sample positions (:func:`sample_offset`) and the pixel filter (:func:`resolve_pixel`: ``box`` averages the
pixel's own samples, ``tent`` weights the samples of the 3 x 3 neighbouring pixels by ``(1 - |dx|)(1 - |dy|)``)
are scalar kernels: the CPU's ``prange`` loops call them, and renderers/gpu/codegen.py translates them into the
GPU's ``gt_gen.glsl``, so both backends place and filter the samples with one source.

The sums keep numpy's order (the CPU's images before these kernels: a float32 mean over the samples, einsum's
sequential float64 products, ``sum``'s pairwise float64 sum of the tent weights), so the CPU's images are the
same bytes as with the vectorised numpy they replace.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

#: Constants of Wellons' lowbias32 integer hash and of the per-pixel seeds (``HASH_X``, ``HASH_Y``).
HASH_M1 = 0x7FEB352D
HASH_M2 = 0x846CA68B
HASH_X = 0x9E3779B1
HASH_Y = 0x85EBCA77
#: numpy's pairwise summation: sequential below 8 values, 8 accumulators up to a block of 128 values.
PAIRWISE_BLOCK = 128

#: The kernels renderers/gpu/codegen.py translates (``gt_gen.glsl``), in double precision as the CPU's float64.
GLSL_DOUBLE_ROOTS = ("sample_offset", "resolve_pixel")


@njit(cache=True)
def lowbias32(x):
    """Wellons' lowbias32 hash of the uint32 ``x`` (each product wraps modulo 2^32)."""
    x = np.uint32(x ^ (x >> 16))
    x = np.uint32(x * HASH_M1)
    x = np.uint32(x ^ (x >> 15))
    x = np.uint32(x * HASH_M2)
    return np.uint32(x ^ (x >> 16))


@njit(cache=True)
def sample_offset(px, py, s, spp, side):
    """Sub-pixel position ``(ox, oy)`` in [0, 1) of sample ``s`` of pixel ``(px, py)``: a ``side`` x ``side``
    grid of strata (``spp = side^2``), the sample jittered inside its stratum by an integer hash of (pixel,
    sample), so both backends place the samples identically; the pixel centre when ``spp`` is 1."""
    if spp == 1:
        return 0.5, 0.5
    h = lowbias32(np.uint32(np.uint32(px) * HASH_X) ^ lowbias32(np.uint32(py) ^ lowbias32(np.uint32(s))))
    h2 = lowbias32(np.uint32(h ^ HASH_Y))
    return ((s % side) + (h >> 8) / 16777216.0) / side, ((s // side) + (h2 >> 8) / 16777216.0) / side


@njit(cache=True)
def tent_weight(ox, oy, x, y, s, dx, dy):
    """Tent weight (radius 1 px) of sample ``s`` of the pixel at ``(dx, dy)`` from pixel ``(x, y)``: ``ox, oy``
    are its sub-pixel positions (indexed ``[y, x, s]``)."""
    return max(0.0, 1.0 - abs(dx + ox[y, x, s] - 0.5)) * max(0.0, 1.0 - abs(dy + oy[y, x, s] - 0.5))


@njit(cache=True)
def weight_block(ox, oy, part, x, y, lo, n, dx, dy):
    """numpy's pairwise sum of the tent weights of samples ``[lo, lo + n)`` (``n <= PAIRWISE_BLOCK``) of one
    neighbour: sequential below 8, else 8 running sums ``part`` combined as a tree, then the rest."""
    res = 0.0
    if n < 8:
        for s in range(lo, lo + n):
            res += tent_weight(ox, oy, x, y, s, dx, dy)
        return res
    for j in range(8):
        part[j] = tent_weight(ox, oy, x, y, lo + j, dx, dy)
    for b in range(1, n // 8):
        for j in range(8):
            part[j] = part[j] + tent_weight(ox, oy, x, y, lo + 8 * b + j, dx, dy)
    res = ((part[0] + part[1]) + (part[2] + part[3])) + ((part[4] + part[5]) + (part[6] + part[7]))
    for s in range(lo + n - n % 8, lo + n):
        res += tent_weight(ox, oy, x, y, s, dx, dy)
    return res


@njit(cache=True)
def resolve_pixel(rad, ox, oy, part, x, y, width, rows, spp, tent):
    """Radiance of pixel ``(x, y)`` (``y`` a row of the ``rows`` sample rows ``rad[y, x, s, c]``, ``width``
    pixels each, ``spp`` samples): ``box`` (``tent`` 0) the float32 mean of its samples; ``tent`` 1 the
    normalised tent-weighted sum of the samples of the 3 x 3 neighbours inside the rows."""
    if tent == 0:
        r = np.float32(0.0)
        g = np.float32(0.0)
        b = np.float32(0.0)
        for s in range(spp):
            r = np.float32(r + rad[y, x, s, 0])
            g = np.float32(g + rad[y, x, s, 1])
            b = np.float32(b + rad[y, x, s, 2])
        return r / spp, g / spp, b / spp
    nr = 0.0
    ng = 0.0
    nb = 0.0
    den = 0.0
    split = spp // 2 - (spp // 2) % 8   # numpy's split of a sum longer than a block
    for dy in range(-1, 2):
        for dx in range(-1, 2):
            qx, qy = x + dx, y + dy
            if 0 <= qx < width and 0 <= qy < rows:
                pr = 0.0
                pg = 0.0
                pb = 0.0
                for s in range(spp):
                    w = tent_weight(ox, oy, qx, qy, s, dx, dy)
                    pr += w * rad[qy, qx, s, 0]
                    pg += w * rad[qy, qx, s, 1]
                    pb += w * rad[qy, qx, s, 2]
                nr += pr
                ng += pg
                nb += pb
                if spp <= PAIRWISE_BLOCK:
                    den += weight_block(ox, oy, part, qx, qy, 0, spp, dx, dy)
                else:
                    den += (weight_block(ox, oy, part, qx, qy, 0, split, dx, dy)
                            + weight_block(ox, oy, part, qx, qy, split, spp - split, dx, dy))
    return nr / den, ng / den, nb / den


@njit(cache=True, parallel=True)
def sample_offsets(px, py, spp, side, ox, oy):
    """:func:`sample_offset` of the ``spp`` samples of each pixel ``(px[i], py[i])`` into ``ox[i], oy[i]``."""
    for i in prange(px.shape[0]):
        for s in range(spp):
            ox[i, s], oy[i, s] = sample_offset(px[i], py[i], s, spp, side)


@njit(cache=True, parallel=True)
def resolve(rad, ox, oy, r0, r1, tent, out):
    """:func:`resolve_pixel` of the pixels of rows ``[r0, r1)`` of ``rad`` into ``out`` (r1 - r0, W, 3)."""
    rows, width, spp = rad.shape[0], rad.shape[1], rad.shape[2]
    for i in prange((r1 - r0) * width):
        part = np.empty(8)
        y, x = r0 + i // width, i % width
        out[y - r0, x, 0], out[y - r0, x, 1], out[y - r0, x, 2] = resolve_pixel(rad, ox, oy, part, x, y, width,
                                                                                 rows, spp, tent)
