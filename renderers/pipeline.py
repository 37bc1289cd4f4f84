"""Rendering pipelines: GT, and the foveated ray-casting and deferred pipelines (seed 001 §3.4, §5.1, §6.1).

Ray casting (§6.1): one ray per shaded LP-buffer pixel, from the screen position of the pixel's centre given by
the inverse mapping; the hit point is shaded; the LP buffer is anti-aliased (VaFR: FXAA, LMFR/LaFR: 3x3
Gaussian); the screen image is the bilinear inverse mapping of the LP buffer (:mod:`._lp`), followed for
LMFR/LaFR by the foveal-aware Gaussian.

Deferred (§3.4): visibility (a G-buffer of triangle id and depth) at native resolution; shading only at the LP
samples, each reading the G-buffer pixel under its screen position; then the same anti-aliasing and inverse
mapping.

Only LP pixels whose screen position lies on the display, or that the bilinear fetch of a border pixel reads,
are shaded (``offscreen_lp_pixels`` counts the others). The screen is processed in row tiles of at most
``TILE_PIXELS`` pixels so that memory stays bounded at any resolution.

Binocular rendering (§5.1): ``dup`` renders each eye (cameras offset by -ipd/2 and +ipd/2 along the camera's
right vector); ``rep`` renders the left eye and builds the right eye's LP buffer by warping the left LP buffer's
hit points into the right view (forward point warping with a depth test, a simplification of Wissmann et al.'s
grid warping), re-shading the right LP pixels that received no sample (disoccluded).
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit, prange

from data_schema.errors import UserError

from . import _gt, _lp, _warp
from .antialias import FOVEAL_RADII, foveal_gaussian, lp_filter
from .projection import camera_rays, plane_to_screen, tan_half_fov
from .scene import Camera
from .tracer import Tracer

TILE_PIXELS = 1 << 18
MAPPING_KERNEL = {"vafr": 0, "lmfr": 1, "lafr": 2}


def _row_tiles(width: int, height: int, pixels: int = TILE_PIXELS):
    rows = max(1, pixels // max(1, width))
    for y0 in range(0, height, rows):
        yield y0, min(height, y0 + rows)


def render_gt(tracer: Tracer, camera: Camera, width: int, height: int, spp: int = 1,
              pixel_filter: str = "box") -> np.ndarray:
    """Every pixel shaded: one ray through its centre, or ``spp`` stratified samples (:func:`gt_sample_offsets`)
    resolved with a ``box`` filter (the pixel's own samples) or a ``tent`` of radius 1 px (:func:`resolve_samples`)."""
    img = np.empty((height, width, 3), dtype=np.float32)
    if spp == 1:
        xs = np.arange(width, dtype=np.float64) + 0.5
        for y0, y1 in _row_tiles(width, height):
            ys = np.arange(y0, y1, dtype=np.float64) + 0.5
            X, Y = np.meshgrid(xs, ys)
            img[y0:y1] = tracer.render_points(camera, width, height, X, Y).reshape(y1 - y0, width, 3)
        return img
    # The tent reads one sample row above and below the tile: those rows are carried over from the previous
    # tile, so every sample is traced once.
    halo = 1 if pixel_filter == "tent" else 0
    carry = (np.empty((0, width, spp, 3), np.float32), np.empty((0, width, spp)), np.empty((0, width, spp)))
    for y0, y1 in _row_tiles(width * spp, height):
        s0, n0, s1 = max(0, y0 - halo), min(height, y0 + halo), min(height, y1 + halo)
        n0 = s0 if y0 == 0 else n0
        py, px = np.mgrid[n0:s1, 0:width]
        ox, oy = gt_sample_offsets(px, py, spp)
        rad = tracer.render_points(camera, width, height, px[..., None] + ox, py[..., None] + oy)
        rad, ox, oy = (np.concatenate([c, a]) for c, a in zip(carry, (rad.reshape(s1 - n0, width, spp, 3), ox, oy)))
        img[y0:y1] = resolve_samples(rad, ox, oy, y0 - s0, y1 - s0, pixel_filter)
        carry = tuple(a[len(a) - 2 * halo:] for a in (rad, ox, oy))
    return img


def gt_sample_offsets(px, py, spp: int):
    """Sub-pixel positions ``(ox, oy)`` in [0, 1) of the ``spp`` samples of pixels ``(px, py)``, shape
    ``px.shape + (spp,)``: :func:`._gt.sample_offset` (a ``sqrt(spp)`` x ``sqrt(spp)`` grid of strata, each
    sample jittered inside its stratum by an integer hash of (pixel, sample index))."""
    px, py = np.broadcast_arrays(np.asarray(px, dtype=np.int64), np.asarray(py, dtype=np.int64))
    ox, oy = np.empty((px.size, spp)), np.empty((px.size, spp))
    _gt.sample_offsets(px.ravel(), py.ravel(), spp, math.isqrt(spp), ox, oy)
    return ox.reshape(px.shape + (spp,)), oy.reshape(px.shape + (spp,))


def resolve_samples(rad, ox, oy, r0: int, r1: int, pixel_filter: str) -> np.ndarray:
    """Pixels of rows ``[r0, r1)`` from samples ``rad`` (rows, W, spp, 3) at offsets ``ox, oy`` (rows, W, spp):
    ``box`` averages each pixel's samples; ``tent`` weights the samples of the 3 x 3 neighbouring pixels by
    ``(1 - |dx|)(1 - |dy|)`` (distance to the pixel centre, radius 1 px) and normalises (:func:`._gt.resolve_pixel`)."""
    out = np.empty((r1 - r0, rad.shape[1], 3), dtype=np.float32)
    _gt.resolve(np.ascontiguousarray(rad, dtype=np.float32), np.ascontiguousarray(ox), np.ascontiguousarray(oy),
                r0, r1, int(pixel_filter == "tent"), out)
    return out


class LPLayout:
    """Column periods ``L``, row counts ``n`` and the shaded mask of a mapping's LP buffer (see :mod:`._lp`)."""

    def __init__(self, mapping, table: bool = True):
        self.mapping = mapping
        w, h = mapping.lp_shape
        self.method = mapping.method
        if self.method == "vafr":
            uc = np.arange(w, dtype=np.float64) + 0.5
            n = mapping.column_heights()
            self.w_eff = int(np.count_nonzero(uc <= mapping.u_max)) or 1
            L = mapping.shading_height(mapping.acuity.e_of_u(uc)[0])
            n = np.where(np.arange(w) < self.w_eff, np.maximum(n, 1), 0)
        else:
            L = np.full(w, float(h))
            n = np.full(w, h, dtype=np.int64)
            self.w_eff = w
        self.w, self.h = w, h
        self.L = np.ascontiguousarray(L, dtype=np.float64)
        self.n = np.ascontiguousarray(n, dtype=np.int64)
        # The compiled inverse mapping reads columns [0, w_eff) and rows [0, n[c]) without bounds checks: a
        # 0 x 0 buffer or an empty column would read memory outside the LP buffer into the image.
        if not (1 <= self.w_eff <= w and h >= 1 and np.all((self.n[:self.w_eff] >= 1) & (self.n[:self.w_eff] <= h))
                and np.isfinite(self.L[:self.w_eff]).all()):
            raise UserError(f"{self.method} with {_params_text(mapping)}: the LP buffer is {w} x {h} pixels, "
                            "with nothing to shade")
        self.mask = np.arange(h)[:, None] < self.n[None, :]
        self.P = np.ascontiguousarray(mapping._params_vector(), dtype=np.float64)
        self.kernel = MAPPING_KERNEL[self.method]
        if table:
            self._build_table()

    def _build_table(self):
        mapping = self.mapping
        # u(r) table for the fast inverse mapping, out to the farthest corner (+2 px): the coarsest of 4, 16, 64
        # samples per pixel whose linear interpolation is within 0.01 LP pixel of the exact mapping at every
        # interval mid-point. Intervals that miss it at the finest step (LaFR's kink at its foveal boundary and
        # infinite slope at the farthest corner) are flagged in ``exact`` and use the exact kernel.
        disp = mapping.display
        self.Lr = self.L / (2 * math.pi)
        for step in (4.0, 16.0, 64.0):
            size = int((disp.corner_distance() + 2.0) * step) + 2
            r = np.arange(size) / step
            utab = mapping.forward(disp.gaze_x + r, np.full(r.shape, disp.gaze_y))[0]
            mid = r[:-1] + 0.5 / step
            exact = mapping.forward(disp.gaze_x + mid, np.full(mid.shape, disp.gaze_y))[0]
            bad = np.abs(0.5 * (utab[:-1] + utab[1:]) - exact) > 0.01
            if not bad.any() or size * 16 > (1 << 22):
                break
        self.inv_step, self.utab = step, np.ascontiguousarray(utab)
        self.exact = np.ascontiguousarray(np.append(bad, True), dtype=np.uint8)
        self.table_ok = not bad.any()

    def border_footprint(self, gaze=None) -> np.ndarray:
        """(h, w) bool: the LP pixels the bilinear fetches of the display's border pixels read (gaze: default
        the mapping's)."""
        disp = self.mapping.display
        gx, gy = disp.gaze if gaze is None else gaze
        need = np.zeros((self.h, self.w), dtype=np.bool_)
        W, H = disp.width, disp.height
        bx = np.concatenate([np.arange(W) + 0.5] * 2 + [np.full(H, 0.5), np.full(H, W - 0.5)])
        by = np.concatenate([np.full(W, 0.5), np.full(W, H - 0.5)] + [np.arange(H) + 0.5] * 2)
        _lp.mark_footprint(self.kernel, self.P, gx, gy, self.L, self.n, self.w_eff, bx, by, need)
        return need

    def shaded_pixels(self):
        """``(jj, ii, x, y, needed)``: LP pixel indices, their screen positions and which must be shaded."""
        m = self.mapping
        disp = m.display
        jj, ii = np.nonzero(self.mask)
        x, y = m.inverse(ii + 0.5, jj + 0.5)
        need = self.border_footprint()
        _lp.mark_needed(need, jj, ii, np.ascontiguousarray(x, dtype=np.float64),
                        np.ascontiguousarray(y, dtype=np.float64), float(disp.width), float(disp.height))
        sel = need[jj, ii]
        return jj, ii, x, y, sel

    def lp_coords(self, x, y):
        """LP pixel (row, column) containing screen positions ``(x, y)`` (nearest-sample splatting)."""
        disp = self.mapping.display
        u, _ = self.mapping.forward(x, y)
        c = np.clip(np.floor(u).astype(np.int64), 0, self.w_eff - 1)
        theta = np.mod(np.arctan2(y - disp.gaze_y, x - disp.gaze_x), 2 * math.pi)
        r = np.floor(theta * self.L[c] / (2 * math.pi)).astype(np.int64) % np.maximum(self.n[c], 1)
        return r, c


def _params_text(mapping) -> str:
    return ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v!r}" for k, v in mapping.params().items()
                     if k in ("e_max", "preset", "acuity_scale", "delta", "alpha", "beta", "a"))


def _inverse_map(tracer, layout: LPLayout, lp, aa_post: bool, width: int, height: int) -> np.ndarray:
    """Screen image from the LP buffer (bilinear, tiled), with LMFR's foveal Gaussian when ``aa_post``."""
    c = tracer.counters
    disp = layout.mapping.display
    # zeros, not empty: the kernel writes every pixel, and a pixel it ever missed would be black, not garbage
    img = np.zeros((height, width, 3), dtype=np.float32)
    halo = max(FOVEAL_RADII) if aa_post else 0
    # a cancellable render (the live window) maps smaller tiles, so that Escape is asked every few milliseconds
    for y0, y1 in _row_tiles(width, height, TILE_PIXELS if tracer.cancel is None else TILE_PIXELS >> 2):
        tracer.check_cancel()  # the live window's Escape, between tiles
        t0 = time.perf_counter()
        a0, a1 = max(0, y0 - halo), min(height, y1 + halo)
        # Without post-filtering the kernel writes straight into the image rows (no copy).
        tile = np.zeros((a1 - a0, width, 3), dtype=np.float32) if aa_post else img[y0:y1]
        _lp.inverse_map_table(lp, layout.utab, layout.inv_step, layout.exact, layout.kernel, layout.P,
                              disp.gaze_x, disp.gaze_y, layout.Lr, layout.n, layout.w_eff, float(a0), tile)
        t0 = c.add_time("inverse_map", t0)
        if aa_post:
            img[y0:y1] = foveal_gaussian(tile, disp, a0, rows=(y0 - a0, y1 - a0))
            c.add_time("antialias", t0)
    return img


class GBuffer:
    """Visibility at native resolution (deferred pipeline): triangle id and hit distance of each pixel."""

    def __init__(self, tracer: Tracer, camera: Camera, width: int, height: int):
        self.prim = np.empty((height, width), dtype=np.int32)
        self.tfar = np.empty((height, width), dtype=np.float32)
        xs = np.arange(width, dtype=np.float64) + 0.5
        for y0, y1 in _row_tiles(width, height):
            X, Y = np.meshgrid(xs, np.arange(y0, y1, dtype=np.float64) + 0.5)
            p, t = tracer.trace(camera, width, height, X, Y)
            self.prim[y0:y1] = p.reshape(y1 - y0, width)
            self.tfar[y0:y1] = t.reshape(y1 - y0, width)
        self.camera, self.width, self.height = camera, width, height

    def shade(self, tracer: Tracer, x, y):
        """Shade the G-buffer pixels under screen positions ``(x, y)`` (clamped to the display)."""
        px = np.clip(np.floor(x), 0, self.width - 1).astype(np.int64)
        py = np.clip(np.floor(y), 0, self.height - 1).astype(np.int64)
        d = camera_rays(self.camera, self.width, self.height, px + 0.5, py + 0.5)
        return tracer.shade_hits(np.asarray(self.camera.position), d, self.prim[py, px], self.tfar[py, px])


def render_lp(tracer: Tracer, camera: Camera, layout: LPLayout, pipeline: str, width: int, height: int):
    """Shade the LP buffer of one eye: ``(lp, jj, ii, x, y, prim, tfar)`` of the shaded pixels (for reprojection)."""
    jj, ii, x, y, sel = layout.shaded_pixels()
    if not sel.any():  # every screen pixel would be reconstructed from unshaded (black) LP pixels
        raise UserError(f"{layout.method} with {_params_text(layout.mapping)}: no LP pixel maps onto the "
                        f"{width} x {height} display, nothing to shade")
    tracer.counters.offscreen_lp_pixels += int(sel.size - np.count_nonzero(sel))
    lp = np.zeros((layout.h, layout.w, 3), dtype=np.float32)
    xs, ys = x[sel], y[sel]
    if pipeline == "deferred":
        gb = GBuffer(tracer, camera, width, height)
        lp[jj[sel], ii[sel]] = gb.shade(tracer, xs, ys)
        # For reprojection: the LP sample's own ray meets the plane of the G-buffer pixel's triangle at t.
        px = np.clip(np.floor(xs), 0, width - 1).astype(np.int64)
        py = np.clip(np.floor(ys), 0, height - 1).astype(np.int64)
        prim = gb.prim[py, px]
        t = np.full(len(xs), np.inf, dtype=np.float32)
        hit = prim >= 0
        if hit.any():
            sc = tracer.scene
            tri = sc.vertices[sc.faces[prim[hit]]].astype(np.float64)
            n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            d = camera_rays(camera, width, height, xs[hit], ys[hit])
            den = np.einsum("ij,ij->i", d, n)
            num = np.einsum("ij,ij->i", tri[:, 0] - np.asarray(camera.position), n)
            ok = np.abs(den) > 1e-12
            t[hit] = np.where(ok, num / np.where(ok, den, 1.0), gb.tfar[py[hit], px[hit]])
        return lp, jj[sel], ii[sel], xs, ys, prim, t
    else:
        lp[jj[sel], ii[sel]], prim, tfar = tracer.render_points(camera, width, height, xs, ys, keep_hits=True)
    return lp, jj[sel], ii[sel], xs, ys, prim, tfar


def fill_unshaded(lp, layout: LPLayout, jj, ii):
    """Copy into each unshaded LP pixel the last shaded pixel of its row at a smaller column (``u``).

    Unshaded pixels lie off the display, beyond the shaded ones along their row (angle), so this continues the
    image past the display's edge (clamp to edge) and the LP-buffer filters do not blend black into the border.
    """
    shaded = np.zeros((layout.h, layout.w), dtype=np.bool_)
    shaded[jj, ii] = True
    out = np.array(lp, dtype=np.float32)   # a copy
    _lp.fill_rows(out, shaded)
    return out


def finish(tracer: Tracer, layout: LPLayout, lp, params: dict, width: int, height: int, exposure: float,
           shaded=None):
    """LP-buffer anti-aliasing, inverse mapping and post anti-aliasing; ``shaded = (jj, ii)`` of the shaded
    LP pixels (the others are filled from their row before the LP filters)."""
    tracer.check_cancel()
    t0 = time.perf_counter()
    lp_aa = (params.get("fxaa", False) if layout.method == "vafr" else params.get("aa", False))
    if lp_aa and shaded is not None:
        lp = fill_unshaded(lp, layout, *shaded)
    if layout.method == "vafr" and params.get("fxaa", False):
        lp = lp_filter(lp, layout.n, "fxaa", exposure)
    elif layout.method != "vafr" and params.get("aa", False):
        lp = lp_filter(lp, layout.n, "gaussian3")
    tracer.counters.add_time("antialias", t0)
    if not np.isfinite(lp).all():  # the screen image is a convex blend of LP pixels: checking them suffices
        raise UserError(f"{layout.method}: the LP buffer holds non-finite values")
    aa_post = layout.method != "vafr" and params.get("aa", False)
    return _inverse_map(tracer, layout, lp, aa_post, width, height)


#: Forward grid warping in :func:`reproject` (False: nearest-sample splatting only).
GRID_WARP = True
#: A quad whose corner depths differ by more than this ratio spans a depth discontinuity and is not warped.
GRID_WARP_MAX_DEPTH_RATIO = 1.05
#: Warped triangles larger than this many LP pixels in either direction are stretched: not rasterised.
GRID_WARP_MAX_EXTENT = 6.0
#: A warped triangle replaces a splatted sample only where it is nearer by this relative margin: on a surface
#: facing the eye the two depths agree to rounding, and the sample (a real shading point) is kept.
GRID_WARP_SPLAT_MARGIN = 1e-4


def reproject(tracer: Tracer, layout: LPLayout, lp_left, jj, ii, xs, ys, prim, tfar, left: Camera,
              right: Camera, width: int, height: int):
    """Right-eye LP buffer from the left one (seed 001 §5.1): warp, depth-test, re-shade the holes.

    Each shaded left LP pixel's hit point (or, for a miss, its direction at infinity) is projected into the
    right view, forward-mapped into the LP buffer and splatted to the LP pixel containing it, nearest depth
    winning. Then forward grid warping (Wissmann et al. 2020, done in the LP buffer as seed 001 §5.1 says):
    each quad of neighbouring left LP samples without a depth discontinuity is split into two triangles,
    warped into the right view's LP coordinates (u, angle) and rasterised with the depth test, so continuous
    surfaces leave no gaps between samples. Needed right LP pixels that receive nothing are re-shaded by ray
    casting from the right eye.
    Returns the right LP buffer and the number of re-shaded pixels.
    """
    t0 = time.perf_counter()
    d = camera_rays(left, width, height, xs, ys)
    hit = prim >= 0
    f, r, u = right.basis()
    rel = np.where(hit[:, None], np.asarray(left.position) + d * tfar[:, None].astype(np.float64)
                   - np.asarray(right.position), d)
    zf = rel @ f
    front = zf > 0
    sx = np.where(front, rel @ r, 0.0) / np.where(front, zf, 1.0)
    sy = np.where(front, rel @ u, 0.0) / np.where(front, zf, 1.0)
    xr, yr = plane_to_screen(sx, sy, width, height, tan_half_fov(right))
    rows, cols = layout.lp_coords(xr[front], yr[front])
    depth = np.where(hit, zf, np.inf)[front]
    lin = rows * layout.w + cols
    order = np.argsort(-depth, kind="stable")      # farthest first: the nearest sample is written last
    right_lp = np.zeros_like(lp_left)
    flat = right_lp.reshape(-1, 3)
    covered = np.zeros(layout.h * layout.w, dtype=np.bool_)
    src = lp_left[jj, ii][front]
    flat[lin[order]] = src[order]
    covered[lin[order]] = True
    if GRID_WARP:
        # Forward grid warping: neighbouring left samples span triangles that fill the right LP pixels
        # between the splatted samples (continuous surfaces); depth discontinuities stay holes.
        zbuf = np.full(layout.h * layout.w, np.inf)
        np.minimum.at(zbuf, lin, depth)
        zbuf *= 1.0 - GRID_WARP_SPLAT_MARGIN  # the depth a triangle must beat
        disp = layout.mapping.display
        u_all = np.zeros(len(jj))
        phi_all = np.zeros(len(jj))
        z_all = np.full(len(jj), np.inf)
        u_all[front] = layout.mapping.forward(xr[front], yr[front])[0]
        phi_all[front] = np.mod(np.arctan2(yr[front] - disp.gaze_y, xr[front] - disp.gaze_x), 2 * math.pi)
        z_all[front] = depth
        grid = np.full((layout.h, layout.w), -1, dtype=np.int64)
        grid[jj, ii] = np.arange(len(jj))
        _warp.grid_warp(grid, u_all, phi_all, z_all, np.ascontiguousarray(lp_left[jj, ii], dtype=np.float64),
                      layout.L, layout.n, layout.w_eff, layout.w, zbuf, flat, covered, GRID_WARP_MAX_DEPTH_RATIO,
                      GRID_WARP_MAX_EXTENT)
    need = np.zeros(layout.h * layout.w, dtype=np.bool_)
    need[jj * layout.w + ii] = True
    holes = need & ~covered
    tracer.counters.add_time("shading", t0)
    hole_idx = np.nonzero(holes)[0]
    if hole_idx.size:
        hj, hi = np.divmod(hole_idx, layout.w)
        x, y = layout.mapping.inverse(hi + 0.5, hj + 0.5)
        flat[hole_idx] = tracer.render_points(right, width, height, x, y)
    return right_lp, int(hole_idx.size)
