"""Stimulus image files: reading them as the observer sees them, writing them, blurring them."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from data_schema.atomic import atomic_path


def load_gray(path: Path) -> np.ndarray:
    """Rec. 709 luma of an 8-bit image in [0, 1], float32 (H, W)."""
    return load_rgb(path) @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)


def save_png(path: Path, rgb: np.ndarray) -> Path:
    """Write a float RGB image in [0, 1] as an 8-bit PNG, atomically."""
    from PIL import Image

    a = np.clip(np.rint(np.asarray(rgb) * 255.0), 0, 255).astype(np.uint8)
    with atomic_path(path) as tmp:
        Image.fromarray(a).save(tmp, format="PNG")
    return Path(path)


def gaussian_blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """Separable Gaussian blur (reflect borders) of an (H, W[, C]) float image."""
    if sigma <= 0:
        return img
    from scipy.ndimage import gaussian_filter

    s = (sigma, sigma) + ((0,) if img.ndim == 3 else ())
    return gaussian_filter(img, s, mode="reflect")


def load_rgb(path: Path) -> np.ndarray:
    """An image file as float32 RGB in [0, 1]: its size checked from the header before it is decoded, a
    damaged file one line naming it (:func:`data_schema.images.open_image`)."""
    from data_schema.images import open_image

    with open_image(path, load=True) as im:
        return np.asarray(im.convert("RGB"), dtype=np.float32) / 255.0
