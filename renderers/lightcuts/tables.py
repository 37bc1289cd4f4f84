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

* Table 3 also holds the sample accounting of every method: ``light_samples`` (light samples drawn per frame,
  Ours' low-resolution pass included), ``traversals`` (of those, the ones that descended the light tree, i.e.
  not reused by multi-resolution selection) and ``glossy_rays``; ``lspp`` / ``rspp`` of the uniform baselines.
* Fig 9 — ``ms_<step>`` of Ours, Ours' and SL_f per step (``gbuffer``, ``low_res``, ``fpsm``, ``cuts``,
  ``select``, ``shade``, ``glossy``; the plug-ins' ``steps``).

Uniform baselines: SL_f / SL_p are the smallest uniform count (bisection in [1, max_lspp]) whose foveal /
peripheral MSE is at most Ours'. SL_e depends on the budget accounting (``budget``, ``BUDGETS``):

* ``equal-time`` (default, the seed's "same rendering time"): the uniform count whose time matches Ours, from a
  line ``t = a + b lspp`` through renders at 1 and 8 samples (``rspp = lspp``); speed-ups are ratios of frame
  times.
* ``equal-samples``: the uniform count nearest Ours' light samples per shaded pixel (its low-resolution pass
  included) and the glossy rays nearest Ours' per glossy pixel; speed-ups are ratios of rays per frame
  (``light_samples + glossy_rays``) and the multi-resolution gain is the ratio of light-tree traversals
  (the work reuse saves; both variants draw the same samples).

Regions: ``data_schema.geometry.ViewingGeometry.region_masks`` (fovea radius ``fovea_deg`` of eccentricity
around the gaze).
Frame times are the registry's ``seconds.total``, the minimum over ``repeats`` renders for Table 3, on the
``backend`` chosen (``"cpu"``, or ``"gpu"``: the GPU versions of the plug-ins, :mod:`renderers.gpu.lightcuts`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np

from data_schema.errors import UserError
from data_schema.geometry import ViewingGeometry
from data_schema.ranges import check as check_range_of

from .options import BUDGETS

STEPS = ("gbuffer", "low_res", "fpsm", "cuts", "select", "shade", "glossy")
METHOD_NAMES = {"fsl": "Ours", "fsl'": "Ours'", "sl_e": "SL_e", "sl_as": "SL_as", "sl_f": "SL_f",
                "sl_p": "SL_p"}


def _mse(img, ref, mask):
    if not mask.any():
        return None
    d = np.clip(img, 0, 1)[mask] - np.clip(ref, 0, 1)[mask]
    return float(np.mean(d * d))


def check_budget(budget) -> str:
    """The budget accounting of the comparison, one of ``BUDGETS``."""
    if budget not in BUDGETS:
        raise UserError(f"budget={budget!r} is invalid: allowed {', '.join(BUDGETS)}")
    return budget


def gt_frame(scene, width: int, height: int, *, gt_lspp: int = 2048, gt_rspp: int = 2048, seed: int = 0,
             camera: dict | None = None, backend: str = "cpu") -> dict:
    """The GT render of :func:`lightcut_tables` as :func:`renderers.stimuli.render_stimulus` arguments (so that
    a cluster can put it into the stimulus cache first: ``studyapp lightcuts tables``)."""
    return {"scene": scene, "renderer": "sl_gt", "params": {"lspp": gt_lspp, "rspp": gt_rspp, "seed": seed + 1},
            "width": width, "height": height, "gaze": None, "camera": camera, "backend": backend}


def lightcut_tables(scene, width: int, height: int, *, alphas=(0.025, 0.05, 0.1, 0.2, 0.4), alpha: float = 0.1,
                    max_lspp: int = 48, max_rspp: int = 48, gt_lspp: int = 2048, gt_rspp: int = 2048,
                    fovea_deg: float = 5.0, seed: int = 0, camera: dict | None = None,
                    progress: Callable[[str], None] | None = None, images: dict | None = None,
                    cache_dir=None, fpsm_reading: str = "derived", budget: str = "equal-time",
                    repeats: int = 1, backend: str = "cpu") -> list[dict]:
    """Render and measure (see the module docstring); ``scene`` is a Scene, a registered name or a YAML path.

    ``images``, if given, receives the linear images ``gt``, ``ours``, ``sl_e``, ``sl_as``, the FPSM ``fpsm``
    and light samples per pixel ``ours_spp`` of Ours, the ``glossy`` pixel mask (for the seed's Fig 5-7: FPSM
    and error maps). With
    ``cache_dir`` the GT comes from the stimulus cache (:func:`renderers.stimuli.render_stimulus`): rendered
    once, then a lookup. ``fpsm_reading`` is Ours' reading of Eq 4–8 (``fpsm.FPSM_READINGS``), ``budget`` the
    accounting of SL_e and of the speed-ups (``BUDGETS``), ``repeats`` the renders per Table 3 time (minimum),
    ``backend`` the renderers' backend (every render, the GT included).
    """
    from renderers import registry
    from renderers.catalog import resolve

    from .fpsm import check_alpha, check_reading
    for a in (alpha, *alphas):
        check_alpha(a)
    check_reading(fpsm_reading)
    check_budget(budget)
    repeats = check_range_of("repeats", repeats, 1, integer=True)
    sc = resolve(scene)
    cam = sc.camera.override(camera)
    say = progress or (lambda msg: None)
    regions = ViewingGeometry.create(width, height, cam.fov_y).region_masks(fovea_deg)
    masks = {"fovea": regions.fovea, "periphery": regions.periphery, "all": np.ones((height, width), bool)}
    records: list[dict] = []

    def add(table, method, metric, region, value):
        if value is not None:
            records.append({"table": table, "scene": sc.name, "method": METHOD_NAMES.get(method, method),
                            "metric": metric, "region": region, "value": float(value)})

    def render(name, params, times: int = 1):
        say(f"{sc.name}: {name} {params}")
        if backend == "gpu":  # compile the shaders of these parameters first: not part of a frame's time
            registry.render(sc, name.rstrip("'"), params, 16, 16, camera=camera, backend=backend)
        img, st = registry.render(sc, name.rstrip("'"), params, width, height, camera=camera, backend=backend)
        for _ in range(times - 1):  # the same image again (same seed): keep the fastest time
            again = registry.render(sc, name.rstrip("'"), params, width, height, camera=camera, backend=backend)[1]
            if again["seconds"]["total"] < st["seconds"]["total"]:
                st = {**st, "seconds": again["seconds"], "steps": again.get("steps", st.get("steps"))}
        return img, st

    gt_request = gt_frame(sc, width, height, gt_lspp=gt_lspp, gt_rspp=gt_rspp, seed=seed, camera=camera,
                          backend=backend)
    gt_params = gt_request["params"]
    if cache_dir is not None:
        from renderers.stimuli import entry_image, render_stimulus

        say(f"{sc.name}: sl_gt {gt_params} (stimulus cache)")
        png = render_stimulus(**gt_request, cache_dir=cache_dir)  # a damaged entry is rendered again
        gt = entry_image(png, (height, width, 3))
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
    ours_params = {"alpha": alpha, **base, "fpsm_reading": fpsm_reading}
    ours, ours_st = render("fsl", ours_params, repeats)
    if glossy is None:
        glossy = np.asarray(ours_st["glossy_mask"])
    _, ours2_st = render("fsl'", {**ours_params, "multires": False}, repeats)
    sl_as, sl_as_st = render("sl_as", base, repeats)
    q_ours = quality(ours)
    uniform_renders: dict = {}

    def uniform(lspp, rspp=None, timed=False):
        """SL with uniform counts, rendered once per count (the bisections and SL_e share renders); ``timed``
        renders it until it has been timed ``repeats`` times and keeps the fastest time."""
        key = (int(lspp), int(lspp if rspp is None else rspp))
        params = {"lspp": key[0], "rspp": key[1], "seed": seed}
        if key not in uniform_renders:
            uniform_renders[key] = (*render("sl_e", params), 1)
        img, st, n = uniform_renders[key]
        if timed and n < repeats:
            more = render("sl_e", params, repeats - n)[1]
            if ms(more) < ms(st):
                st = {**st, "seconds": more["seconds"], "steps": more.get("steps", st.get("steps"))}
            uniform_renders[key] = (img, st, repeats)
        return img, st

    if budget == "equal-time":
        st1, st8 = uniform(1, timed=True)[1], uniform(8, timed=True)[1]
        slope = max((ms(st8) - ms(st1)) / 7.0, 1e-9)
        lspp_e = int(np.clip(round(1 + (ms(ours_st) - ms(st1)) / slope), 1, max_lspp))
        rspp_e = lspp_e
    else:
        shaded = max(int(ours_st["shading_points"]), 1)
        lspp_e = int(np.clip(round(ours_st["light_samples"] / shaded), 1, max_lspp))
        n_glossy = int(np.sum(glossy))
        rspp_e = int(np.clip(round(ours_st["glossy_rays"] / n_glossy), 0, max_rspp)) if n_glossy else 0
    sl_e, sl_e_st = uniform(lspp_e, rspp_e)

    def match(region):
        target = q_ours[("mse", region)]
        lo, hi = 1, max_lspp
        best = max_lspp
        while lo <= hi:
            mid = (lo + hi) // 2
            if target is not None and _mse(uniform(mid)[0], gt, masks[region]) <= target:
                best, hi = mid, mid - 1
            else:
                lo = mid + 1
        return best, uniform(best, timed=True)[1]

    if images is not None:
        images.update(gt=gt, ours=ours, sl_e=sl_e, sl_as=sl_as, fpsm=np.asarray(ours_st["fpsm"]),
                      ours_spp=np.asarray(ours_st["spp"]), glossy=np.asarray(glossy))
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
                       ("sl_p", sl_p_st), ("sl_e", sl_e_st)):
        if method != "sl_e":
            add("3", method, "ms", "all", ms(st))
        for metric in ("light_samples", "traversals", "glossy_rays"):
            add("3", method, metric, "all", st.get(metric))
    for method, st in (("fsl", ours_st), ("fsl'", ours2_st), ("sl_f", sl_f_st)):
        for step in STEPS:
            if step in st.get("steps", {}):
                add("fig9", method, f"ms_{step}", "all", 1000.0 * st["steps"][step])
    add("3", "sl_e", "lspp", "all", lspp_e)
    add("3", "sl_e", "rspp", "all", rspp_e)
    add("3", "sl_f", "lspp", "all", lspp_f)
    add("3", "sl_p", "lspp", "all", lspp_p)
    for a in alphas:
        img, st = (ours, ours_st) if math.isclose(a, alpha) else render("fsl", {**ours_params, "alpha": a})
        add("4", f"fsl(alpha={a:g})", "ms", "all", ms(st))
        q = q_ours if math.isclose(a, alpha) else quality(img)
        for rn in ("fovea", "periphery"):
            add("fig8", f"fsl(alpha={a:g})", "mse", rn, q[("mse", rn)])
            add("fig8", f"fsl(alpha={a:g})", "mse_d", rn, q[("mse_d", rn)])
    return records


#: The seed's figures for the ratios of ``summary_ratios`` (seed 003 §4.2–4.3: Tables 1 and 3).
SEED_RATIOS = {"speedup_vs_sl_f": (2.5, 3.9), "foveal_mse_sl_e_over_ours": (1.9, 4.2),
               "peripheral_mse_sl_e_over_ours": (1.2, 1.6), "multires_speedup": (1.3, 1.4)}


def summary_ratios(records: list[dict], budget: str = "equal-time") -> dict:
    """The issue's targets as same-run ratios (None where a record is missing).

    With ``budget="equal-time"`` the speed-ups are ratios of frame times (Table 3 ``ms``); with
    ``"equal-samples"`` ratios of rays per frame (``light_samples + glossy_rays``) for SL_f / Ours and of
    light-tree traversals for Ours' / Ours (multi-resolution selection saves traversals, not samples).
    ``peripheral_mse_sl_e_over_ours`` is the seed's second claim (1.2–1.6× for MSE in the periphery).
    """
    check_budget(budget)

    def get(table, method, metric, region="all"):
        for r in records:
            if (r["table"], r["method"], r["metric"], r["region"]) == (table, method, metric, region):
                return r["value"]
        return None

    def ratio(a, b):
        return None if a is None or b is None or b == 0 else a / b

    def rays(method):
        n, g = get("3", method, "light_samples"), get("3", method, "glossy_rays")
        return None if n is None or g is None else n + g

    times = [r["value"] for r in records if r["table"] == "4"]
    if budget == "equal-time":
        speedup = ratio(get("3", "SL_f", "ms"), get("3", "Ours", "ms"))
        multires = ratio(get("3", "Ours'", "ms"), get("3", "Ours", "ms"))
    else:
        speedup = ratio(rays("SL_f"), rays("Ours"))
        multires = ratio(get("3", "Ours'", "traversals"), get("3", "Ours", "traversals"))
    return {
        "speedup_vs_sl_f": speedup,
        "foveal_mse_sl_e_over_ours": ratio(get("1", "SL_e", "mse", "fovea"), get("1", "Ours", "mse", "fovea")),
        "peripheral_mse_sl_e_over_ours": ratio(get("1", "SL_e", "mse", "periphery"),
                                               get("1", "Ours", "mse", "periphery")),
        "multires_speedup": multires,
        "time_falls_with_alpha": bool(times) and all(b <= a for a, b in itertools.pairwise(times)),
    }
