"""Seed 003's quality and performance tables on this app's scenes (issue 6 item 7), as tidy records.

``lightcut_tables(scene, width, height, ...)`` renders the scene with the plug-ins of ``plugin.py`` and returns
records ``{table, scene, method, metric, region, value}``:

* Table 1 — ``mse``, ``mse_d``, ``mse_g`` of Ours (``fsl``), SL_e and SL_as against GT (``sl_gt``) in the
  ``fovea``, ``periphery`` and ``all``. Images are clipped to [0, 1] first (display-referred). ``mse_d`` is the
  MSE over pixels of diffuse materials, ``mse_g`` over glossy/metallic ones (seed 003: the "diffuse parts"
  and "glossy parts"; an all-diffuse scene has no ``mse_g`` record).
* Table 2 — ``spp``, mean light samples per pixel per region, of Ours, SL_e, SL_as.
* Table 3 — ``ms`` per frame of Ours, Ours' (``fsl`` without multi-resolution selection), SL_as, SL_f, SL_p.
* Table 4 — ``ms`` of Ours for each α; Fig 8 — ``mse`` and ``mse_d`` of Ours per α and region.

Uniform baselines: SL_e uses the uniform count whose time matches Ours (a line ``t = a + b lspp`` through
renders at 1 and 8 samples), SL_f / SL_p the smallest uniform count (bisection in [1, max_lspp]) whose
foveal / peripheral MSE is at most Ours'. Regions: ``analysis.quality.region_masks`` (fovea radius
``fovea_deg`` of eccentricity around the gaze). Frame times are the registry's ``seconds.total``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np

METHOD_NAMES = {"fsl": "Ours", "fsl'": "Ours'", "sl_e": "SL_e", "sl_as": "SL_as", "sl_f": "SL_f",
                "sl_p": "SL_p"}


def _mse(img, ref, mask):
    if not mask.any():
        return None
    d = np.clip(img, 0, 1)[mask] - np.clip(ref, 0, 1)[mask]
    return float(np.mean(d * d))


def lightcut_tables(scene, width: int, height: int, *, alphas=(0.025, 0.05, 0.1, 0.2, 0.4), alpha: float = 0.1,
                    max_lspp: int = 48, max_rspp: int = 48, gt_lspp: int = 2048, gt_rspp: int = 2048,
                    fovea_deg: float = 5.0, seed: int = 0, camera: dict | None = None,
                    progress: Callable[[str], None] | None = None, images: dict | None = None,
                    cache_dir=None) -> list[dict]:
    """Render and measure (see the module docstring); ``scene`` is a Scene, a registered name or a YAML path.

    ``images``, if given, receives the linear images ``gt``, ``ours``, ``sl_e``, ``sl_as`` and the FPSM ``fpsm``
    of Ours (for the seed's Fig 5-7: FPSM and error maps). With ``cache_dir`` the GT comes from the stimulus
    cache (:func:`renderers.stimuli.render_stimulus`): rendered once, then a lookup.
    """
    from analysis.quality import region_masks
    from renderers import registry
    from renderers.catalog import resolve

    from .fpsm import check_alpha
    for a in (alpha, *alphas):
        check_alpha(a)
    sc = resolve(scene)
    cam = sc.camera.override(camera)
    say = progress or (lambda msg: None)
    regions = region_masks(width, height, cam.fov_y, None, fovea_deg)
    masks = {"fovea": regions.fovea, "periphery": regions.periphery, "all": np.ones((height, width), bool)}
    records: list[dict] = []

    def add(table, method, metric, region, value):
        if value is not None:
            records.append({"table": table, "scene": sc.name, "method": METHOD_NAMES.get(method, method),
                            "metric": metric, "region": region, "value": float(value)})

    def render(name, params):
        say(f"{sc.name}: {name} {params}")
        img, st = registry.render(sc, name.rstrip("'"), params, width, height, camera=camera)
        return img, st

    gt_params = {"lspp": gt_lspp, "rspp": gt_rspp, "seed": seed + 1}
    if cache_dir is not None:
        from renderers.stimuli import render_stimulus

        say(f"{sc.name}: sl_gt {gt_params} (stimulus cache)")
        png = render_stimulus(sc, "sl_gt", gt_params, width, height, None, camera=camera, cache_dir=cache_dir)
        gt = np.load(png.with_suffix(".npy"))
        glossy = None  # taken from Ours' G-buffer below (same primary hits)
    else:
        gt, gt_st = render("sl_gt", gt_params)
        glossy = gt_st["glossy_mask"]

    def quality(img):
        out = {}
        for rn, m in masks.items():
            out[("mse", rn)] = _mse(img, gt, m)
            out[("mse_d", rn)] = _mse(img, gt, m & ~glossy)
            out[("mse_g", rn)] = _mse(img, gt, m & glossy) if glossy.any() else None
        return out

    ms = lambda st: 1000.0 * st["seconds"]["total"]
    base = {"max_lspp": max_lspp, "max_rspp": max_rspp, "seed": seed}
    ours, ours_st = render("fsl", {"alpha": alpha, **base})
    if glossy is None:
        glossy = np.asarray(ours_st["glossy_mask"])
    _, ours2_st = render("fsl'", {"alpha": alpha, **base, "multires": False})
    sl_as, sl_as_st = render("sl_as", base)
    q_ours = quality(ours)

    def uniform(lspp):
        return render("sl_e", {"lspp": int(lspp), "rspp": int(lspp), "seed": seed})

    _, st1 = uniform(1)
    _, st8 = uniform(8)
    slope = max((ms(st8) - ms(st1)) / 7.0, 1e-9)
    lspp_e = int(np.clip(round(1 + (ms(ours_st) - ms(st1)) / slope), 1, max_lspp))
    sl_e, sl_e_st = uniform(lspp_e)

    def match(region):
        target = q_ours[("mse", region)]
        lo, hi = 1, max_lspp
        best = None
        while lo <= hi:
            mid = (lo + hi) // 2
            img, st = uniform(mid)
            if target is not None and _mse(img, gt, masks[region]) <= target:
                best, hi = (mid, st), mid - 1
            else:
                lo = mid + 1
        return best if best is not None else (max_lspp, uniform(max_lspp)[1])

    if images is not None:
        images.update(gt=gt, ours=ours, sl_e=sl_e, sl_as=sl_as, fpsm=np.asarray(ours_st["fpsm"]))
    lspp_f, sl_f_st = match("fovea")
    lspp_p, sl_p_st = match("periphery")

    for method, img, st in (("fsl", ours, ours_st), ("sl_e", sl_e, sl_e_st), ("sl_as", sl_as, sl_as_st)):
        q = q_ours if method == "fsl" else quality(img)
        for (metric, rn), v in q.items():
            add("1", method, metric, rn, v)
        spp = np.asarray(st["spp"], dtype=np.float64)
        for rn, m in masks.items():
            add("2", method, "spp", rn, spp[m].mean() if m.any() else None)
    for method, st in (("fsl", ours_st), ("fsl'", ours2_st), ("sl_as", sl_as_st), ("sl_f", sl_f_st),
                       ("sl_p", sl_p_st)):
        add("3", method, "ms", "all", ms(st))
    add("3", "sl_e", "lspp", "all", lspp_e)
    add("3", "sl_f", "lspp", "all", lspp_f)
    add("3", "sl_p", "lspp", "all", lspp_p)
    for a in alphas:
        img, st = (ours, ours_st) if math.isclose(a, alpha) else render("fsl", {"alpha": a, **base})
        add("4", f"fsl(alpha={a:g})", "ms", "all", ms(st))
        q = q_ours if math.isclose(a, alpha) else quality(img)
        for rn in ("fovea", "periphery"):
            add("fig8", f"fsl(alpha={a:g})", "mse", rn, q[("mse", rn)])
            add("fig8", f"fsl(alpha={a:g})", "mse_d", rn, q[("mse_d", rn)])
    return records


def summary_ratios(records: list[dict]) -> dict:
    """The issue's targets as same-run ratios (None where a record is missing)."""
    def get(table, method, metric, region):
        for r in records:
            if (r["table"], r["method"], r["metric"], r["region"]) == (table, method, metric, region):
                return r["value"]
        return None

    def ratio(a, b):
        return None if a is None or b is None or b == 0 else a / b

    times = [r["value"] for r in records if r["table"] == "4"]
    return {
        "speedup_vs_sl_f": ratio(get("3", "SL_f", "ms", "all"), get("3", "Ours", "ms", "all")),
        "foveal_mse_sl_e_over_ours": ratio(get("1", "SL_e", "mse", "fovea"), get("1", "Ours", "mse", "fovea")),
        "multires_speedup": ratio(get("3", "Ours'", "ms", "all"), get("3", "Ours", "ms", "all")),
        "time_falls_with_alpha": bool(times) and all(b <= a for a, b in itertools.pairwise(times)),
    }
