"""GPU versions of the pipelines of :mod:`renderers.pipeline`: GT, the LP buffer (ray casting and deferred),
the LP filters, the inverse mapping, the foveal Gaussian and the reprojection of ``rep``.

Each function issues compute dispatches on a :class:`~renderers.gpu.frame.Frame`; images stay on the GPU
until :func:`read_image`.
"""

from __future__ import annotations

import math

import numpy as np

from .. import pipeline as cpu
from .upload import camera_uniforms
from .frame import BATCH, B_OUT, B_SAMPLES, C, Frame


def read_image(buf, width: int, height: int) -> np.ndarray:
    """An (H, W, 3) float32 image from a buffer of 3 floats per pixel (row-major)."""
    img = np.empty((height, width, 3), dtype=np.float32)
    buf.read_into(img, size=img.nbytes)
    return img


def render_gt(fr: Frame, camera, width: int, height: int, spp: int = 1, pixel_filter: str = "box"):
    """GT into the pooled buffer ``image`` (3 floats per pixel); see :func:`renderers.pipeline.render_gt`.

    Rows are rendered in batches of at most :data:`~renderers.gpu.frame.BATCH` samples; with the tent filter
    the sample rows around a batch boundary are carried over, so that every sample is traced once.
    """
    img = fr.pool.get("image", 12 * width * height)
    side = math.isqrt(spp)
    defines = {"SPP": spp, "SPP_SIDE": side, **{k: f"{v}u" for k, v in cpu.GT_HASH.items()}}
    cam = camera_uniforms(camera, width, height)
    origin = camera.position
    rows = max(1, BATCH // (width * spp))
    if spp == 1:
        for y0 in range(0, height, rows):
            n = (min(height, y0 + rows) - y0) * width
            with fr.timer("visibility"):
                fr.run("gen_gt.comp", n, fr.sample_buffers(n), {**cam, "u_y0": y0, "u_width": width,
                                                                 "u_slot_base": y0 * width}, defines)
            fr.shade_batch(origin, n, img, n=n)
            fr.drain_counters()
        return img
    halo = 1 if pixel_filter == "tent" else 0
    row_bytes = 12 * width * spp
    tiles = [fr.pool.get(f"gt_tile{k}", row_bytes * (rows + 2 * halo)) for k in (0, 1)]
    for t, y0 in enumerate(range(0, height, rows)):
        y1 = min(height, y0 + rows)
        s0, n0, s1 = max(0, y0 - halo), min(height, y0 + halo), min(height, y1 + halo)
        n0 = s0 if y0 == 0 else n0
        buf, prev = tiles[t % 2], tiles[(t + 1) % 2]
        if n0 > s0:  # carry the sample rows [s0, n0) from the end of the previous tile
            fr.dev.ctx.copy_buffer(buf, prev, (n0 - s0) * row_bytes, read_offset=prev_rows * row_bytes)
        n = (s1 - n0) * width * spp
        with fr.timer("visibility"):
            fr.run("gen_gt.comp", n, fr.sample_buffers(n), {**cam, "u_y0": n0, "u_width": width,
                                                             "u_slot_base": (n0 - s0) * width * spp}, defines)
        fr.shade_batch(origin, n, buf, n=n)
        with fr.timer("antialias"):
            fr.run("resolve_gt.comp", (y1 - y0) * width, {B_OUT: buf, 15: img},
                   {"u_width": width, "u_y0": y0, "u_s0": s0, "u_s1": s1, "u_tent": int(halo)}, defines)
        prev_rows = s1 - s0 - 2 * halo
        fr.drain_counters()
    return img
