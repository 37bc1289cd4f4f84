"""Stochastic lightcuts on plain arrays: cut to a node budget, one light per cut node, unbiased weights.

For a shading point ``p`` (normal ``N``, diffuse albedo ``a``) the exact direct lighting is

    L(p) = sum_l a / pi * I_l * max(0, cos theta_l) / max(d_l^2, c^2) * V(p, x_l) [* max(0, cos theta'_l)],

with ``c = 0.001 * scene light radius`` (the clamp of Lin & Yuksel's error bound, applied to the
contribution too so that ``L`` is finite); the bracketed emitter cosine ``theta'`` applies to one-sided
(mesh) lights. The cut ``C`` partitions the lights, so
``L(p) = sum_{k in C} sum_{l under k} f(l)``; each node ``k`` draws one light ``l_k`` with probability
``pdf_k(l_k)`` (``_kernels.descend``) and ``sum_k f(l_k) / pdf_k(l_k)`` is an unbiased estimate of ``L(p)``.
Visibility ``V`` comes from an ``occluded(origins, targets) -> bool`` callback (e.g.
``visibility.EmbreeOccluder``); without one every light is visible.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from data_schema.errors import UserError

from ..constants import LC_CLAMP_FRACTION, LC_OFFSET_FRACTION
from . import _kernels as K
from .tree import LightTree

Occluder = Callable[[np.ndarray, np.ndarray], np.ndarray]

MAX_LSPP = 48  # seed 003 §4.1


@dataclass(frozen=True)
class GBuffer:
    """Shading points as flat arrays (``P`` points): world position, unit normal, diffuse albedo, validity."""

    position: np.ndarray
    normal: np.ndarray
    albedo: np.ndarray
    valid: np.ndarray
    shape: tuple[int, ...]

    @classmethod
    def create(cls, position, normal, albedo, valid=None) -> GBuffer:
        """Validate and flatten ``(..., 3)`` arrays; normals are renormalised, invalid pixels are skipped."""
        pos = np.asarray(position, dtype=np.float64)
        if pos.ndim < 2 or pos.shape[-1] != 3:
            raise UserError(f"position has shape {pos.shape}: must be (..., 3)")
        shape = pos.shape[:-1]
        arrays = {}
        for name, arr in (("normal", normal), ("albedo", albedo)):
            a = np.asarray(arr, dtype=np.float64)
            if a.shape != pos.shape:
                raise UserError(f"{name} has shape {a.shape}: must match position {pos.shape}")
            arrays[name] = a.reshape(-1, 3)
        ok = np.ones(int(np.prod(shape)), bool) if valid is None else np.asarray(valid, bool).reshape(-1)
        if ok.size != int(np.prod(shape)):
            raise UserError(f"valid has {ok.size} entries: must have one per pixel ({int(np.prod(shape))})")
        pos = pos.reshape(-1, 3)
        nrm = arrays["normal"]
        for name, a in (("position", pos), ("normal", nrm), ("albedo", arrays["albedo"])):
            if not np.all(np.isfinite(a[ok])):
                raise UserError(f"{name} must be finite on valid pixels (found NaN or inf)")
        length = np.linalg.norm(nrm, axis=1)
        ok = ok & (length > 0)
        nrm = np.where(ok[:, None], nrm / np.where(length > 0, length, 1.0)[:, None], 0.0)
        pos = np.where(ok[:, None], pos, 0.0)
        return cls(np.ascontiguousarray(pos), np.ascontiguousarray(nrm),
                   np.ascontiguousarray(arrays["albedo"]), ok, tuple(shape))

    @property
    def n(self) -> int:
        return self.position.shape[0]


@dataclass(frozen=True)
class ShadingResult:
    """Radiance ``(..., 3)``, light samples per pixel ``(...)`` and shadow rays cast."""

    radiance: np.ndarray
    samples: np.ndarray
    shadow_rays: int


def clamp2(tree: LightTree) -> float:
    """Squared distance clamp ``(0.001 * scene light radius)^2``."""
    return (LC_CLAMP_FRACTION * tree.scene_radius) ** 2


def ray_offset_for(tree: LightTree, gbuf: GBuffer) -> float:
    """Default shadow-ray origin offset along the normal: 1e-4 of the scene's half-diagonal."""
    pts = gbuf.position[gbuf.valid]
    lo = np.minimum(tree.bmin[1], pts.min(axis=0)) if pts.size else tree.bmin[1]
    hi = np.maximum(tree.bmax[1], pts.max(axis=0)) if pts.size else tree.bmax[1]
    return LC_OFFSET_FRACTION * max(0.5 * float(np.linalg.norm(hi - lo)), 1e-9)


def _tick(timings: dict | None, step: str, t0: float) -> float:
    """Add the seconds since ``t0`` to ``timings[step]`` (if ``timings`` is given); returns now."""
    t = time.perf_counter()
    if timings is not None:
        timings[step] = timings.get(step, 0.0) + t - t0
    return t


def cut_and_sample(tree: LightTree, pos, nrm, budget, pix_id, seed: int, max_budget: int,
                   timings: dict | None = None):
    """Cuts (``build_cuts``) and one hierarchical sample per cut node (``sample_cuts``) for one tile.

    ``timings``, if given, accumulates the seconds of the two steps under ``cuts`` and ``select``.
    """
    t0 = time.perf_counter()
    n = pos.shape[0]
    cut = np.zeros((n, max_budget), dtype=np.int64)
    err = np.zeros((n, max_budget))
    size = K.build_cuts(pos, nrm, budget, tree.bmin, tree.bmax, tree.intensity, tree.n_leaves, clamp2(tree),
                        cut, err)
    t0 = _tick(timings, "cuts", t0)
    leaf = np.empty((n, max_budget), dtype=np.int64)
    pdf = np.empty((n, max_budget))
    K.sample_cuts(pos, nrm, pix_id, cut, size, tree.bmin, tree.bmax, tree.intensity, tree.n_leaves,
                  clamp2(tree), np.uint64(seed), leaf, pdf)
    _tick(timings, "select", t0)
    return cut, size, leaf, pdf


def shade_tile(tree: LightTree, pos, nrm, alb, leaf, pdf, occluded: Occluder | None, ray_offset: float):
    """Shade the chosen samples of a tile and apply visibility; returns ``(radiance (n, 3), rays)``: the shadow
    rays of the samples that contribute, cast in one batch, then ``_kernels.shade_pixel`` per pixel."""
    one_sided = tree.light_nrm is not None
    light = (tree.light_pos, tree.light_rgb, tree.light_nrm if one_sided else np.zeros((1, 3)), one_sided,
             tree.n_leaves, clamp2(tree))
    need = K.shade_samples(pos, nrm, alb, leaf, pdf, *light)
    rays = int(need.sum())
    blocked = np.zeros(need.shape, dtype=bool)
    if occluded is not None and rays:
        pi, si = np.nonzero(need)
        origins = pos[pi] + ray_offset * nrm[pi]
        targets = tree.light_pos[leaf[pi, si] - tree.n_leaves]
        blocked[pi, si] = np.asarray(occluded(origins, targets), dtype=bool)
    return K.shade_pixels(pos, nrm, alb, leaf, pdf, *light, blocked), rays


def stochastic_lightcuts(tree: LightTree, gbuf: GBuffer, budget, *, seed: int = 0,
                         occluded: Occluder | None = None, ray_offset: float | None = None,
                         tile: int = 1 << 16, timings: dict | None = None,
                         pixel_ids: np.ndarray | None = None) -> ShadingResult:
    """Render direct diffuse lighting with stochastic lightcuts.

    Parameters
    ----------
    tree : LightTree
    gbuf : GBuffer
    budget : int or array of int, shape ``gbuf.shape``
        Cut size per pixel (light samples per pixel), each in ``[0, MAX]``; 0 leaves a pixel black.
    seed : int
        Random stream; the same inputs and seed give byte-identical output (independent of ``tile``).
    occluded : callable, optional
        ``occluded(origins (m, 3), targets (m, 3)) -> (m,) bool``.
    ray_offset : float, optional
        Shadow-ray origin offset along the normal (default ``ray_offset_for``).
    tile : int
        Pixels per batch (bounds memory: about ``tile * max_budget * 56`` bytes).
    timings : dict, optional
        Accumulates seconds per step: ``cuts`` (cut refinement), ``select`` (hierarchical sampling), ``shade``
        (shading and shadow rays) — the steps of seed 003 Fig 9.
    pixel_ids : (P,) int, optional
        The points' ids in the random stream (default ``0 .. P - 1``): a point's samples depend only on
        ``(seed, id, slot)``.
    """
    b = np.broadcast_to(np.asarray(budget), gbuf.shape).reshape(-1)
    if not np.issubdtype(b.dtype, np.integer) and (not np.all(np.isfinite(b)) or np.any(b != np.round(b))):
        raise UserError("budget must hold whole numbers of light samples")
    b = b.astype(np.int64)
    if np.any(b < 0):
        raise UserError(f"budget must be >= 0 (found {int(b.min())})")
    b = np.where(gbuf.valid, b, 0)
    if seed < 0:
        raise UserError(f"seed={seed} is out of range: must be >= 0")
    offset = ray_offset_for(tree, gbuf) if ray_offset is None else float(ray_offset)
    max_b = max(int(b.max()) if b.size else 0, 1)
    out = np.zeros((gbuf.n, 3))
    spp = np.zeros(gbuf.n, dtype=np.int64)
    rays = 0
    for start in range(0, gbuf.n, tile):
        sl = slice(start, min(start + tile, gbuf.n))
        pos, nrm = gbuf.position[sl], gbuf.normal[sl]
        ids = np.arange(sl.start, sl.stop, dtype=np.int64) if pixel_ids is None else pixel_ids[sl]
        _, _, leaf, pdf = cut_and_sample(tree, pos, nrm, b[sl], ids, seed, max_b, timings)
        t0 = time.perf_counter()
        out[sl], r = shade_tile(tree, pos, nrm, gbuf.albedo[sl], leaf, pdf, occluded, offset)
        _tick(timings, "shade", t0)
        spp[sl] = (leaf >= 0).sum(axis=1)
        rays += r
    return ShadingResult(out.reshape(gbuf.shape + (3,)), spp.reshape(gbuf.shape), rays)


def exact_direct(tree: LightTree, gbuf: GBuffer, *, occluded: Occluder | None = None,
                 ray_offset: float | None = None) -> np.ndarray:
    """Brute-force reference: the sum over every light of the same contribution (``(..., 3)``)."""
    offset = ray_offset_for(tree, gbuf) if ray_offset is None else float(ray_offset)
    lp = tree.light_pos[:tree.n_lights]
    rgb = tree.light_rgb[:tree.n_lights]
    out = np.zeros((gbuf.n, 3))
    for i in np.nonzero(gbuf.valid)[0]:
        p, n = gbuf.position[i], gbuf.normal[i]
        d = lp - p
        cosnum = d @ n
        d2 = (d * d).sum(axis=1)
        g = np.where(cosnum > 0, cosnum / np.sqrt(np.maximum(d2, 1e-300)) / np.maximum(d2, clamp2(tree)), 0.0)
        if tree.light_nrm is not None:
            ln = tree.light_nrm[:tree.n_lights]
            em = -(ln * d).sum(axis=1) / np.sqrt(np.maximum(d2, 1e-300))
            g = g * np.where(np.any(ln != 0, axis=1), np.maximum(em, 0.0), 1.0)
        if occluded is not None:
            vis = ~np.asarray(occluded(np.repeat((p + offset * n)[None], len(lp), 0), lp), dtype=bool)
            g = g * vis
        out[i] = gbuf.albedo[i] / np.pi * (rgb * g[:, None]).sum(axis=0)
    return out.reshape(gbuf.shape + (3,))
