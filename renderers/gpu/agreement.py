"""How closely two renders of the same stimulus agree (the GPU backend against the CPU one, issue 13 item 5)."""

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
