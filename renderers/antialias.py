"""Anti-aliasing of the foveated renderers (seed 001 §3.4, §7).

* :func:`fxaa` — FXAA 3.11 (NVIDIA, Lottes), PC quality preset 12 (search steps 1.0, 1.5, 2.0, 4.0, 12.0),
  subpix 0.75, edge threshold 0.166, edge threshold min 0.0833, bilinear fetches at half-pixel offsets;
  luma ``sqrt(clip(Y, 0, 1))`` of the (exposed) linear Rec. 709 luminance. VaFR runs it in the LP buffer.
* :func:`gaussian3` — LMFR's internal anti-aliasing: a 3x3 Gaussian (sigma 1) in the LP buffer.
* :func:`foveal_gaussian` — LMFR's post anti-aliasing: a screen-space Gaussian chosen by eccentricity — none
  below 5°, 3x3 (sigma 0.8) to 15°, 5x5 (sigma 1.2) to 30°, 11x11 (sigma 2.5) beyond (the bands of the LMFR
  demo, placed in degrees so they do not depend on the resolution). LaFR uses the same (seed 001 §5.2.1).

The LP-buffer filters see rows continued around the angular seam (:func:`renderers._lp.wrap_pad`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from . import _lp
from .constants import LUMA_B, LUMA_G, LUMA_R

FXAA_STEPS_12 = np.array([1.0, 1.5, 2.0, 4.0, 12.0])
FOVEAL_BANDS_DEG = np.array([5.0, 15.0, 30.0])
FOVEAL_SIGMAS = (0.0, 0.8, 1.2, 2.5)
FOVEAL_RADII = (0, 1, 2, 5)


#: FXAA's image: channels 0-2 the colour, channel ``LUMA_CHANNEL`` the luma (one array, so that one bilinear fetch
#: serves both and the GPU's generated kernel reads them through one accessor).
LUMA_CHANNEL = 3
#: The functions translated into GLSL (renderers/gpu/codegen.py fxaa_glsl) and their callees: in numba's types
#: (float32 sums of the image's values, float64 elsewhere), so that both backends take the same edge decisions.
GLSL_DOUBLE_ROOTS = ("fxaa_pixel",)


@njit(cache=True, inline="always")
def _bil(img, x, y, ch):
    """Bilinear fetch at continuous pixel position (x, y) (pixel centres at i + 0.5), clamped to the edge."""
    H, W = img.shape[0], img.shape[1]
    fx = min(max(x - 0.5, 0.0), W - 1.0)
    fy = min(max(y - 0.5, 0.0), H - 1.0)
    x0 = int(math.floor(fx))
    y0 = int(math.floor(fy))
    x1 = min(x0 + 1, W - 1)
    y1 = min(y0 + 1, H - 1)
    ax = fx - x0
    ay = fy - y0
    return ((img[y0, x0, ch] * (1 - ax) + img[y0, x1, ch] * ax) * (1 - ay)
            + (img[y1, x0, ch] * (1 - ax) + img[y1, x1, ch] * ax) * ay)


@njit(cache=True, inline="always")
def _lu(img, x, y):
    """The luma of pixel (x, y), clamped to the edge."""
    H, W = img.shape[0], img.shape[1]
    return img[min(max(y, 0), H - 1), min(max(x, 0), W - 1), LUMA_CHANNEL]


@njit(cache=True)
def fxaa_pixel(img, steps, subpix, edge_threshold, edge_threshold_min, x, y):
    """FXAA 3.11 of pixel (x, y) of ``img`` (colour and luma, see ``LUMA_CHANNEL``): its colour ``(r, g, b)``."""
    lumaM = img[y, x, LUMA_CHANNEL]
    lumaS = _lu(img, x, y + 1)
    lumaE = _lu(img, x + 1, y)
    lumaN = _lu(img, x, y - 1)
    lumaW = _lu(img, x - 1, y)
    rangeMax = max(max(lumaN, lumaW), max(lumaE, max(lumaS, lumaM)))
    rangeMin = min(min(lumaN, lumaW), min(lumaE, min(lumaS, lumaM)))
    rng = rangeMax - rangeMin
    if rng < max(edge_threshold_min, rangeMax * edge_threshold):
        return img[y, x, 0], img[y, x, 1], img[y, x, 2]
    lumaNW = _lu(img, x - 1, y - 1)
    lumaSE = _lu(img, x + 1, y + 1)
    lumaNE = _lu(img, x + 1, y - 1)
    lumaSW = _lu(img, x - 1, y + 1)
    lumaNS = lumaN + lumaS
    lumaWE = lumaW + lumaE
    subpixNSWE = lumaNS + lumaWE
    edgeHorz1 = -2.0 * lumaM + lumaNS
    edgeVert1 = -2.0 * lumaM + lumaWE
    lumaNESE = lumaNE + lumaSE
    lumaNWNE = lumaNW + lumaNE
    edgeHorz2 = -2.0 * lumaE + lumaNESE
    edgeVert2 = -2.0 * lumaN + lumaNWNE
    lumaNWSW = lumaNW + lumaSW
    lumaSWSE = lumaSW + lumaSE
    edgeHorz4 = abs(edgeHorz1) * 2.0 + abs(edgeHorz2)
    edgeVert4 = abs(edgeVert1) * 2.0 + abs(edgeVert2)
    edgeHorz3 = -2.0 * lumaW + lumaNWSW
    edgeVert3 = -2.0 * lumaS + lumaSWSE
    edgeHorz = abs(edgeHorz3) + edgeHorz4
    edgeVert = abs(edgeVert3) + edgeVert4
    subpixNWSWNESE = lumaNWSW + lumaNESE
    horzSpan = edgeHorz >= edgeVert
    subpixA = subpixNSWE * 2.0 + subpixNWSWNESE
    if not horzSpan:
        lumaN = lumaW
        lumaS = lumaE
    lengthSign = 1.0
    subpixB = subpixA / 12.0 - lumaM
    gradientN = lumaN - lumaM
    gradientS = lumaS - lumaM
    lumaNN = lumaN + lumaM
    lumaSS = lumaS + lumaM
    pairN = abs(gradientN) >= abs(gradientS)
    gradient = max(abs(gradientN), abs(gradientS))
    if pairN:
        lengthSign = -lengthSign
    subpixC = min(max(abs(subpixB) / rng, 0.0), 1.0)
    px, py = x + 0.5, y + 0.5
    bx, by = px, py
    ox = 1.0 if horzSpan else 0.0
    oy = 0.0 if horzSpan else 1.0
    if horzSpan:
        by += lengthSign * 0.5
    else:
        bx += lengthSign * 0.5
    nx, ny = bx - ox * steps[0], by - oy * steps[0]
    qx, qy = bx + ox * steps[0], by + oy * steps[0]
    subpixD = -2.0 * subpixC + 3.0
    if not pairN:
        lumaNN = lumaSS
    lumaHalf = lumaNN * 0.5
    lumaEndN = _bil(img, nx, ny, LUMA_CHANNEL) - lumaHalf
    lumaEndP = _bil(img, qx, qy, LUMA_CHANNEL) - lumaHalf
    subpixE = subpixC * subpixC
    gradientScaled = gradient * 0.25
    lumaMLTZero = lumaM - lumaHalf < 0.0
    subpixF = subpixD * subpixE
    doneN = abs(lumaEndN) >= gradientScaled
    doneP = abs(lumaEndP) >= gradientScaled
    for s in range(1, steps.size):
        if doneN and doneP:
            break
        if not doneN:
            nx -= ox * steps[s]
            ny -= oy * steps[s]
            lumaEndN = _bil(img, nx, ny, LUMA_CHANNEL) - lumaHalf
            doneN = abs(lumaEndN) >= gradientScaled
        if not doneP:
            qx += ox * steps[s]
            qy += oy * steps[s]
            lumaEndP = _bil(img, qx, qy, LUMA_CHANNEL) - lumaHalf
            doneP = abs(lumaEndP) >= gradientScaled
    if horzSpan:
        dstN = px - nx
        dstP = qx - px
    else:
        dstN = py - ny
        dstP = qy - py
    goodSpanN = (lumaEndN < 0.0) != lumaMLTZero
    goodSpanP = (lumaEndP < 0.0) != lumaMLTZero
    spanLength = dstP + dstN
    directionN = dstN < dstP
    dst = min(dstN, dstP)
    goodSpan = goodSpanN if directionN else goodSpanP
    subpixG = subpixF * subpixF
    pixelOffset = -dst / spanLength + 0.5
    subpixH = subpixG * subpix
    pixelOffsetGood = pixelOffset if goodSpan else 0.0
    off = max(pixelOffsetGood, subpixH)
    if horzSpan:
        py += off * lengthSign
    else:
        px += off * lengthSign
    return _bil(img, px, py, 0), _bil(img, px, py, 1), _bil(img, px, py, 2)


@njit(cache=True, parallel=True)
def _fxaa(img, steps, subpix, edge_threshold, edge_threshold_min, row0, row1, out):
    for y in prange(row0, row1):
        for x in range(img.shape[1]):
            out[y - row0, x, 0], out[y - row0, x, 1], out[y - row0, x, 2] = fxaa_pixel(
                img, steps, subpix, edge_threshold, edge_threshold_min, x, y)


def fxaa_luma(rgb: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """FXAA's luma channel: ``sqrt(clip(exposure * (0.2126 R + 0.7152 G + 0.0722 B), 0, 1))``, (h, w, 1)."""
    y = exposure * (LUMA_R * rgb[..., 0] + LUMA_G * rgb[..., 1] + LUMA_B * rgb[..., 2])
    return np.sqrt(np.clip(y, 0.0, 1.0)).astype(np.float32)[..., None]


def fxaa(rgb: np.ndarray, exposure: float = 1.0, *, subpix: float = 0.75, edge_threshold: float = 0.166,
         edge_threshold_min: float = 0.0833, rows: tuple[int, int] | None = None) -> np.ndarray:
    """FXAA 3.11 quality preset 12 of an (h, w, 3) float32 image; ``rows`` limits the output rows."""
    rgb = np.ascontiguousarray(rgb, dtype=np.float32)
    r0, r1 = rows if rows is not None else (0, rgb.shape[0])
    img = np.empty((*rgb.shape[:2], 4), dtype=np.float32)
    img[..., :3] = rgb
    img[..., LUMA_CHANNEL:] = fxaa_luma(rgb, exposure)
    out = np.empty((r1 - r0, rgb.shape[1], 3), dtype=np.float32)
    _fxaa(img, FXAA_STEPS_12, subpix, edge_threshold, edge_threshold_min, r0, r1, out)
    return out


def _gauss1d(sigma: float, radius: int) -> np.ndarray:
    k = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma) ** 2)
    return (k / k.sum()).astype(np.float32)


def blur(img: np.ndarray, sigma: float, radius: int, axes=(0, 1)) -> np.ndarray:
    """Separable Gaussian blur (edge-clamped) of an (h, w, 3) image."""
    from scipy.ndimage import correlate1d

    k = _gauss1d(sigma, radius)
    out = img
    for ax in axes:
        out = correlate1d(out, k, axis=ax, mode="nearest")
    return out


def lp_filter(lp: np.ndarray, n: np.ndarray, kind: str, exposure: float = 1.0) -> np.ndarray:
    """Anti-alias an LP buffer (h, w, 3) whose column ``c`` holds ``n[c]`` rows: ``fxaa`` or ``gaussian3``."""
    pad = 16 if kind == "fxaa" else 1
    padded = np.empty((lp.shape[0] + 2 * pad, lp.shape[1], 3), dtype=np.float32)
    _lp.wrap_pad(lp, n, pad, padded)
    if kind == "fxaa":
        return fxaa(padded, exposure, rows=(pad, pad + lp.shape[0]))
    return np.ascontiguousarray(blur(padded, 1.0, 1)[pad:pad + lp.shape[0]])


def foveal_gaussian(img: np.ndarray, geometry, y0: int = 0, rows: tuple[int, int] | None = None):
    """LMFR's post anti-aliasing: each pixel takes the Gaussian of its eccentricity band (seed 001 §7).

    ``img`` is a screen tile whose row 0 is screen row ``y0``, including up to ``max(FOVEAL_RADII)`` halo rows;
    ``rows`` (default: all) are the tile rows to return. Eccentricity is the viewing geometry's (seed 001
    Eq 3, :meth:`data_schema.geometry.ViewingGeometry.eccentricity_map`).
    """
    r0, r1 = rows if rows is not None else (0, img.shape[0])
    ecc = geometry.eccentricity_map(slice(y0 + r0, y0 + r1))
    band = np.searchsorted(np.asarray(FOVEAL_BANDS_DEG), ecc, side="right")  # edges at or below e
    out = img[r0:r1].copy()
    for b in range(1, len(FOVEAL_SIGMAS)):
        sel = band == b
        if sel.any():
            out[sel] = blur(img, FOVEAL_SIGMAS[b], FOVEAL_RADII[b])[r0:r1][sel]
    return out
