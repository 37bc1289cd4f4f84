"""A lightcuts stimulus for the README demo: ``cornell_many`` rendered by ``fsl`` plus its FPSM (a few seconds).

``demo_step(out_dir, progress)`` follows the ``studyapp/commands`` demo convention, so a command module can
forward to it. Images are tone-mapped for display (clip to [0, 1], gamma 2.2), written atomically as PNG.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _png(path: Path, rgb: np.ndarray) -> Path:
    from PIL import Image

    from data_schema.atomic import atomic_path

    img = np.clip(np.asarray(rgb, dtype=np.float64), 0.0, 1.0)
    if img.ndim == 3:
        img = img ** (1.0 / 2.2)
    with atomic_path(path) as tmp:
        Image.fromarray(np.round(img * 255).astype(np.uint8)).save(tmp, format="PNG")
    return path


def demo_step(out_dir: Path, progress=None, width: int = 320, height: int = 180) -> list[Path]:
    """Render ``cornell_many`` (111,858 lights) with ``fsl`` (α = 0.1, seed 0); write the image and the FPSM."""
    from renderers import registry

    from .scenes import cornell_many

    out_dir = Path(out_dir)
    if progress:
        progress("lightcuts: cornell_many fsl")
    img, st = registry.render(cornell_many(), "fsl", {"alpha": 0.1, "seed": 0}, width, height)
    return [_png(out_dir / "cornell_many_fsl.png", img), _png(out_dir / "cornell_many_fpsm.png", st["fpsm"])]
