"""One-bounce glossy pass (seed 003 Algorithm 1 lines 16–17: ``FoveatedPT`` with ``rspp = MAX_rspp · map``).

For a glossy or metallic pixel with specular colour ``k_s`` and Blinn-Phong exponent ``s`` (the scene model's
``f_s = k_s (s + 8) / (8π) (n·h)^s``), ``count`` half-vectors are drawn with density
``(s + 1)/(2π) (n·h)^s``; the reflected direction ``w_i = 2 (v·h) h − v`` has density
``(s + 1)/(2π) (n·h)^s / (4 v·h)``, so each ray carries the weight

    f_s cos θ_i / pdf(w_i) = k_s (s + 8) (n·w_i) (v·h) / (s + 1)          (0 below the surface)

times the radiance found at its first hit: emission + ambient + direct diffuse light from stochastic
lightcuts with ``lspp_bounce`` nodes (one bounce: the hit's own gloss is not followed). The pixel value is the
mean over its rays. Pixels with ``count = 0`` cast no ray; an all-diffuse scene casts none at all.

Random numbers: the lobe of ray ``r`` of pixel ``i`` uses slots ``2^24 + 2r`` and ``2^24 + 2r + 1`` of pixel ``i``;
its bounce's lightcuts use stream ``seed + 7919`` with the id ``(i << 20) + r``, so every ray's samples depend on
(seed, pixel, ray) alone, not on how the rays are batched (the GPU backend draws the same ones).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from data_schema.errors import UserError

from ._kernels import bitangent, tangent, uniform_f
from .sampling import stochastic_lightcuts

_STREAM = 1 << 24  # slot offset: glossy random numbers never reuse the light-sampling slots


#: The per-ray kernel that renderers/gpu/codegen.py translates into GLSL (``glossy_gen.glsl``, float32).
GLSL_FLOAT_ROOTS = ("lobe_sample",)


@njit(cache=True, inline="always")
def lobe_ray(nx, ny, nz, tx, ty, tz, bx, by, bz, vx, vy, vz, s, u1, u2, count):
    """One ray of the lobe (module docstring) from uniforms ``u1, u2``, for normal ``n`` with tangent frame
    ``t, b``, view direction ``v``, exponent ``s`` and ``count`` rays: the direction ``w_i = 2 (v.h) h - v`` of the
    half-vector ``h`` drawn with density ``(s + 1)/(2 pi) (n.h)^s`` and its weight per unit ``k_s``,
    ``(s + 8) (n.w_i) (v.h) / ((s + 1) count)``; ``(n, 0)`` when ``w_i`` is below the surface or ``v.h <= 0``."""
    cos_h = u1 ** (1.0 / (s + 1.0))
    sin_h = math.sqrt(max(0.0, 1.0 - cos_h * cos_h))
    phi = 2.0 * math.pi * u2
    ct, st = math.cos(phi) * sin_h, math.sin(phi) * sin_h
    hx = cos_h * nx + ct * tx + st * bx
    hy = cos_h * ny + ct * ty + st * by
    hz = cos_h * nz + ct * tz + st * bz
    voh = 0.0
    voh += vx * hx
    voh += vy * hy
    voh += vz * hz
    dx = 2.0 * voh * hx - vx
    dy = 2.0 * voh * hy - vy
    dz = 2.0 * voh * hz - vz
    cos_i = 0.0
    cos_i += nx * dx
    cos_i += ny * dy
    cos_i += nz * dz
    if voh <= 0.0 or cos_i <= 0.0:
        return nx, ny, nz, 0.0
    return dx, dy, dz, (s + 8.0) * cos_i * voh / ((s + 1.0) * count)


@njit(cache=True)
def lobe_sample(seed, pix, r, nx, ny, nz, vx, vy, vz, s, count):
    """Ray ``r`` of the ``count`` of a pixel with random id ``pix``, normal ``n``, view direction ``v`` and exponent
    ``s``: :func:`lobe_ray` in the normal's frame with the uniforms of slots ``2^24 + 2r``, ``2^24 + 2r + 1``."""
    t = tangent(nx, ny, nz)
    b = bitangent(nx, ny, nz)
    u1 = uniform_f(seed, pix, _STREAM + 2 * r)
    u2 = uniform_f(seed, pix, _STREAM + 2 * r + 1)
    return lobe_ray(nx, ny, nz, t[0], t[1], t[2], b[0], b[1], b[2], vx, vy, vz, s, u1, u2, count)


@njit(cache=True, parallel=True)
def sample_lobe(P, N, V, ks, s_exp, counts, first, pix_id, seed, offset, orig, dirs, weight):
    """Fill the rays of every pixel ``i`` at ``first[i] .. first[i] + counts[i]`` (:func:`lobe_sample` each)."""
    for i in prange(P.shape[0]):
        c = counts[i]
        if c == 0:
            continue
        n = N[i]
        for r in range(c):
            j = first[i] + r
            dirs[j, 0], dirs[j, 1], dirs[j, 2], g = lobe_sample(seed, pix_id[i], r, n[0], n[1], n[2], V[i, 0], V[i, 1],
                                                                 V[i, 2], s_exp[i], c)
            for a in range(3):
                orig[j, a] = P[i, a] + offset * n[a]
                weight[j, a] = ks[i, a] * g if g > 0.0 else 0.0


#: Rays per pixel below this: a bounce's id ``(pixel << RAY_BITS) + r`` in the random stream is unique.
RAY_BITS = 20


def glossy_offset(tree) -> float:
    """Origin offset of the glossy rays along the normal: 1e-4 of the lights' half diagonal."""
    return 1e-4 * max(tree.scene_radius, 1e-9)


def glossy_pass(hits, counts, seed: int, trace, tree, occluded, lspp_bounce: int = 1,
                max_rays: int = 1 << 20, ray_offset: float | None = None):
    """Glossy radiance ``(n, 3)`` of the pixels of ``hits`` with ``counts`` rays each, and the rays cast.

    ``trace(origins, dirs)`` returns the hits of the bounce rays (an object with ``gbuf`` and ``base``).
    Pixels are processed in chunks of at most ``max_rays`` rays. ``ray_offset`` is the shadow-ray offset of the
    bounces' lightcuts (default: ``sampling.ray_offset_for`` of each chunk's hits).
    """
    counts = np.asarray(counts, dtype=np.int64).reshape(-1)
    if np.any(counts < 0):
        raise UserError("rspp must be >= 0")
    if np.any(counts >= 1 << RAY_BITS):
        raise UserError(f"rspp must be < {1 << RAY_BITS}")
    g = hits.gbuf
    n = g.n
    out = np.zeros((n, 3))
    total = 0
    offset = glossy_offset(tree)
    idx = np.nonzero(counts)[0]
    start = 0
    while start < len(idx):
        csum = np.cumsum(counts[idx[start:]])
        stop = start + max(1, int(np.searchsorted(csum, max_rays, side="right")))
        sel = idx[start:stop]
        c = counts[sel]
        m = int(c.sum())
        first = np.concatenate([[0], np.cumsum(c)[:-1]]).astype(np.int64)
        orig = np.empty((m, 3))
        dirs = np.empty((m, 3))
        weight = np.empty((m, 3))
        sample_lobe(g.position[sel], g.normal[sel], hits.view[sel], hits.ks[sel], hits.s_exp[sel], c, first,
                    sel.astype(np.int64), np.uint64(seed), offset, orig, dirs, weight)
        live = np.any(weight > 0, axis=1)
        if live.any():
            bounce = trace(orig[live], dirs[live])
            rad = bounce.base.copy()
            if lspp_bounce > 0:
                ray = np.arange(m, dtype=np.int64) - np.repeat(first, c)
                ids = ((np.repeat(sel.astype(np.int64), c) << RAY_BITS) + ray)[live]
                rad += stochastic_lightcuts(tree, bounce.gbuf, lspp_bounce, seed=seed + 7919, occluded=occluded,
                                            ray_offset=ray_offset, pixel_ids=ids).radiance.reshape(-1, 3)
            owner = np.repeat(np.arange(len(sel)), c)[live]
            contrib = weight[live] * rad
            for a in range(3):
                out[sel, a] += np.bincount(owner, weights=contrib[:, a], minlength=len(sel))
            total += int(live.sum())
        start = stop
    return out, total
