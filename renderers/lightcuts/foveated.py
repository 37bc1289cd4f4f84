"""Foveated stochastic lightcuts for direct diffuse lighting (seed 003 Algorithm 1, lines 5–15).

Inputs are plain arrays: a ``LightTree``, the full-resolution G-buffer ``(h, w)`` and a low-resolution one
``(h', w')`` (the seed uses ``w' = w/8``, ``h' = h/8``), the per-pixel eccentricity and screen velocity. The
glossy one-bounce pass (lines 16–18) belongs to the renderer plug-in, which knows the materials.

Steps and their timings (``FoveatedResult.timings``, seconds):

* ``low_res``: stochastic lightcuts at ``(w', h')`` with ``MAX_lspp`` samples — ``fb'``, ``LC'``, ``LS'``;
* ``fpsm``: the map (``fpsm.build_fpsm``) and ``#L = max(1, ceil(map · MAX_lspp))``;
* ``cuts``: per-pixel cuts refined to ``#L`` nodes by the largest error bound;
* ``select``: Algorithm 2 (``multires=True``) or hierarchical sampling of every node (``multires=False``,
  the seed's *Ours'*);
* ``shade``: Lambertian shading and shadow rays.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from data_schema.errors import UserError

from . import _kernels as K
from . import multires as MR
from .fpsm import FPSM, build_fpsm, check_alpha, check_reading, light_budget
from .sampling import GBuffer, Occluder, clamp2, cut_and_sample, ray_offset_for, shade_tile
from .tree import LightTree


@dataclass(frozen=True)
class FoveatedResult:
    radiance: np.ndarray        # (h, w, 3)
    low_res: np.ndarray         # (h', w', 3)
    fpsm: FPSM
    budget: np.ndarray          # (h, w) cut size #L
    samples: np.ndarray         # (h, w) light samples drawn (cut nodes that can contribute)
    reused: np.ndarray          # (h, w) of which taken from LS' (Algorithm 2 line 6)
    shadow_rays: int
    timings: dict = field(default_factory=dict)
    low_res_samples: int = 0    # light samples of the low-resolution pass (LS')


def _check_image_gbuffer(name: str, g: GBuffer) -> tuple[int, int]:
    if len(g.shape) != 2:
        raise UserError(f"{name} G-buffer has shape {g.shape}: must be an image (h, w)")
    return g.shape


def foveated_lightcuts(tree: LightTree, full: GBuffer, low: GBuffer, eccentricity_rad, velocity, alpha,
                       max_lspp: int = 48, *, seed: int = 0, occluded: Occluder | None = None,
                       multires: bool = True, tile: int = 1 << 15,
                       fpsm_reading: str = "derived") -> FoveatedResult:
    """Render one frame of foveated stochastic lightcuts (diffuse part). See the module docstring.

    ``fpsm_reading`` selects the reading of Eq 4–8 (``fpsm.FPSM_READINGS``, see ``fpsm.fpsm_map``).
    """
    alpha = check_alpha(alpha)
    check_reading(fpsm_reading)
    light_budget(np.zeros(1), max_lspp)  # validates max_lspp
    max_lspp = int(max_lspp)
    if seed < 0:
        raise UserError(f"seed={seed} is out of range: must be >= 0")
    h, w = _check_image_gbuffer("full", full)
    hl, wl = _check_image_gbuffer("low", low)
    offset = ray_offset_for(tree, full)
    c2 = clamp2(tree)
    timings = {}

    t0 = time.perf_counter()
    lr_ids = np.arange(full.n, full.n + low.n, dtype=np.int64)
    lr_budget = np.where(low.valid, max_lspp, 0).astype(np.int64)
    lr_cut, lr_size, lr_leaf, lr_pdf = cut_and_sample(tree, low.position, low.normal, lr_budget, lr_ids, seed,
                                                      max_lspp)
    lr_rad, rays = shade_tile(tree, low.position, low.normal, low.albedo, lr_leaf, lr_pdf, occluded, offset)
    ls = MR.sort_low_res_samples(lr_cut, lr_size, lr_leaf, lr_pdf)
    timings["low_res"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    fp = build_fpsm(eccentricity_rad, full.normal.reshape(h, w, 3), full.albedo.reshape(h, w, 3), velocity,
                    lr_rad.reshape(hl, wl, 3), alpha, reading=fpsm_reading)
    budget = np.where(full.valid, light_budget(fp.map, max_lspp).reshape(-1), 0)
    fmap = np.ascontiguousarray(fp.map.reshape(-1))
    timings["fpsm"] = time.perf_counter() - t0

    out = np.zeros((full.n, 3))
    spp = np.zeros(full.n, dtype=np.int64)
    reused = np.zeros(full.n, dtype=np.int64)
    timings.update(cuts=0.0, select=0.0, shade=0.0)
    for start in range(0, full.n, tile):
        sl = slice(start, min(start + tile, full.n))
        pos, nrm = full.position[sl], full.normal[sl]
        ids = np.arange(sl.start, sl.stop, dtype=np.int64)
        n = len(ids)
        t0 = time.perf_counter()
        cut = np.zeros((n, max_lspp), dtype=np.int64)
        size = K.build_cuts(pos, nrm, budget[sl], tree.bmin, tree.bmax, tree.intensity, tree.n_leaves, c2, cut,
                            np.zeros((n, max_lspp)))
        t1 = time.perf_counter()
        leaf = np.empty((n, max_lspp), dtype=np.int64)
        pdf = np.empty((n, max_lspp))
        if multires:
            reused[sl] = MR.select_lights(pos, nrm, ids, ids % w, ids // w, fmap[sl], cut, size, tree.bmin,
                                          tree.bmax, tree.intensity, tree.n_leaves, tree.levels, c2,
                                          np.uint64(seed), *ls, wl / w, hl / h, wl, hl, leaf, pdf)
        else:
            K.sample_cuts(pos, nrm, ids, cut, size, tree.bmin, tree.bmax, tree.intensity, tree.n_leaves, c2,
                          np.uint64(seed), leaf, pdf)
        t2 = time.perf_counter()
        out[sl], r = shade_tile(tree, pos, nrm, full.albedo[sl], leaf, pdf, occluded, offset)
        t3 = time.perf_counter()
        spp[sl] = (leaf >= 0).sum(axis=1)
        rays += r
        timings["cuts"] += t1 - t0
        timings["select"] += t2 - t1
        timings["shade"] += t3 - t2
    return FoveatedResult(out.reshape(h, w, 3), lr_rad.reshape(hl, wl, 3), fp, budget.reshape(h, w),
                          spp.reshape(h, w), reused.reshape(h, w), rays, timings, int(ls[3].sum()))
