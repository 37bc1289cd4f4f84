"""How closely two renders of the same stimulus agree: the GPU backend against the CPU one (issue 13 item 5),
and two stochastic renderers over seeds (issue 16 item 1)."""

from __future__ import annotations

import numpy as np


def agreement(reference: np.ndarray, image: np.ndarray, exposure: float = 1.0) -> tuple[float, float]:
    """``(psnr_db, within_one)`` of two linear images.

    ``psnr_db``: PSNR of the exposed linear images clipped to the display range [0, 1] (peak 1; what the PNG
    encodes), ``inf`` if equal. ``within_one``: share of pixels whose 8-bit sRGB PNG values differ by at most
    one level in every channel.
    """
    from ..stimuli import to_srgb8

    x = np.clip(np.asarray(reference, dtype=np.float64) * exposure, 0.0, 1.0)
    y = np.clip(np.asarray(image, dtype=np.float64) * exposure, 0.0, 1.0)
    mse = float(np.mean((x - y) ** 2))
    psnr = float("inf") if mse == 0.0 else 10.0 * float(np.log10(1.0 / mse))
    d = np.abs(to_srgb8(reference, exposure).astype(np.int16) - to_srgb8(image, exposure).astype(np.int16))
    return psnr, float(np.mean(d.max(axis=2) <= 1))


def seed_agreement(cpu, gpu, ratio_range: tuple[float, float] = (0.8, 1.25), n_se: float = 4.0) -> dict:
    """How two stochastic renderers agree over seeds (issue 16 item 1): ``cpu`` and ``gpu`` are ``(seeds, H, W, 3)``
    stacks of linear images.

    Per pixel and channel, over the seeds: the means agree when they differ by at most ``n_se`` standard errors
    ``sqrt((s_cpu^2 + s_gpu^2) / seeds)`` (sample variances; where both are 0 the pixel is deterministic and its
    means must agree to float32 rounding); the variance ratio ``s_gpu^2 / s_cpu^2`` should lie in
    ``ratio_range``. A pixel passes when all its channels do. Returns the shares of pixels passing
    (``means_within``, and ``ratio_within`` over the pixels with a non-deterministic channel; per channel
    ``ratio_within_channels``), the counts
    (``pixels``, ``deterministic``), the median variance ratio and the worst standardised mean difference.
    """
    a = np.asarray(cpu, dtype=np.float64)
    b = np.asarray(gpu, dtype=np.float64)
    n = a.shape[0]
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    va, vb = a.var(axis=0, ddof=1), b.var(axis=0, ddof=1)
    se = np.sqrt((va + vb) / n)
    det = (va == 0) & (vb == 0)
    tol = 1e-5 * np.maximum(np.abs(ma), 1e-2)
    diff = np.abs(ma - mb)
    means_ok = np.where(det, diff <= tol, diff <= n_se * se + tol)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = vb / va
    in_range = (ratio >= ratio_range[0]) & (ratio <= ratio_range[1])
    ratio_ok = det | in_range
    pixel_det = det.all(axis=-1)
    live = ~pixel_det
    z = np.where(det, 0.0, diff / np.where(se > 0, se, np.inf))
    finite = ratio[~det & np.isfinite(ratio)]
    return {"seeds": int(n), "pixels": int(live.size), "deterministic": int(pixel_det.sum()),
            "means_within": float(means_ok.all(axis=-1).mean()),
            "ratio_within": float(ratio_ok.all(axis=-1)[live].mean()) if live.any() else 1.0,
            "ratio_within_channels": float(in_range[~det].mean()) if (~det).any() else 1.0,
            "median_ratio": float(np.median(finite)) if finite.size else 1.0,
            "max_z": float(z.max()) if z.size else 0.0}
