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
from .constants import LP_GAUSS_RADIUS, LP_GAUSS_SIGMA, LP_PAD_FXAA, LP_PAD_GAUSS, LUMA_B, LUMA_G, LUMA_R

#: The kernels the GPU backend translates (renderers/gpu/codegen.py ``antialias_glsl``): the Gaussian of a pixel
#: (LMFR's LP filter), and the foveal Gaussian's band and pixel, which call it.
GLSL_FLOAT_ROOTS = ("gauss_pixel",)
GLSL_FOVEAL_ROOTS = ("foveal_band", "foveal_pixel")
GLSL_LUMA_ROOTS = ("luma",)

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


@njit(cache=True, inline="always")
def luma(r, g, b, exposure):
    """FXAA's luma of a linear RGB pixel: ``sqrt(clip(exposure Y, 0, 1))``, ``Y`` the Rec. 709 luminance, in
    float32 throughout (as numpy computes it for a float32 image and a Python float)."""
    y = np.float32(exposure) * (np.float32(LUMA_R) * r + np.float32(LUMA_G) * g + np.float32(LUMA_B) * b)
    return math.sqrt(min(max(y, np.float32(0.0)), np.float32(1.0)))


@njit(cache=True, parallel=True)
def _luma_image(rgb, exposure, out):
    for y in prange(rgb.shape[0]):
        for x in range(rgb.shape[1]):
            out[y, x, 0] = luma(rgb[y, x, 0], rgb[y, x, 1], rgb[y, x, 2], exposure)


def fxaa_luma(rgb: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """FXAA's luma channel of an (h, w, 3) image (:func:`luma` of every pixel), (h, w, 1) float32."""
    rgb = np.ascontiguousarray(rgb, dtype=np.float32)
    out = np.empty(rgb.shape[:2] + (1,), dtype=np.float32)
    _luma_image(rgb, float(exposure), out)
    return out


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


#: Weights of band ``b`` >= 1 start at ``FOVEAL_STRIDE * (b - 1)`` of :data:`FOVEAL_WEIGHTS`.
FOVEAL_STRIDE = 2 * max(FOVEAL_RADII) + 1
#: The foveal bands' normalised 1-D Gaussian weights, one after the other (both backends read this array).
FOVEAL_WEIGHTS = np.zeros(FOVEAL_STRIDE * (len(FOVEAL_RADII) - 1), dtype=np.float32)
for _b in range(1, len(FOVEAL_RADII)):
    FOVEAL_WEIGHTS[FOVEAL_STRIDE * (_b - 1):][:2 * FOVEAL_RADII[_b] + 1] = _gauss1d(FOVEAL_SIGMAS[_b],
                                                                                   FOVEAL_RADII[_b])
del _b
#: The number of foveal band edges (:data:`FOVEAL_BANDS_DEG`).
FOVEAL_EDGES = len(FOVEAL_BANDS_DEG)


@njit(cache=True, inline="always")
def _gauss_column(img, y, x, ch, k, o, r, h):
    """The vertical pass of :func:`blur` at ``(y, x)``, channel ``ch``, with the weights ``k[o:o + 2 r + 1]``, as
    scipy's ``correlate1d`` computes it (float64: the centre, then the symmetric pairs from the outermost in; rows
    clamped to ``[0, h)``), stored as float32."""
    acc = np.float64(img[y, x, ch]) * np.float64(k[o + r])
    for q in range(r):
        j = r - q
        acc += (np.float64(img[max(y - j, 0), x, ch]) + np.float64(img[min(y + j, h - 1), x, ch])) \
            * np.float64(k[o + q])
    return np.float32(acc)


@njit(cache=True, inline="always")
def gauss_pixel(img, y, x, ch, k, o, r, h, w):
    """:func:`blur` of an (h, w, 3) image at pixel ``(y, x)``, channel ``ch``: the horizontal pass of
    :func:`_gauss_column` (columns clamped to ``[0, w)``), bit for bit scipy's separable ``correlate1d``."""
    acc = np.float64(_gauss_column(img, y, x, ch, k, o, r, h)) * np.float64(k[o + r])
    for q in range(r):
        j = r - q
        acc += (np.float64(_gauss_column(img, y, max(x - j, 0), ch, k, o, r, h))
                + np.float64(_gauss_column(img, y, min(x + j, w - 1), ch, k, o, r, h))) * np.float64(k[o + q])
    return acc


@njit(cache=True, parallel=True)
def _gaussian(img, k, r, y0, out):
    """``out[y] = blur(img)[y0 + y]``: :func:`gauss_pixel` over the rows of ``out``."""
    h, w = img.shape[0], img.shape[1]
    for y in prange(out.shape[0]):
        for x in range(w):
            for ch in range(3):
                out[y, x, ch] = gauss_pixel(img, y0 + y, x, ch, k, 0, r, h, w)


@njit(cache=True, inline="always")
def foveal_band(e, edges):
    """The foveal band of eccentricity ``e`` (degrees): how many band edges lie at or below it."""
    b = 0
    for q in range(FOVEAL_EDGES):
        if e >= edges[q]:
            b += 1
    return b


@njit(cache=True, inline="always")
def foveal_pixel(img, y, x, ch, b, k, radii, h, w):
    """The foveal Gaussian of band ``b`` at pixel ``(y, x)``, channel ``ch``: the pixel itself in band 0, else
    :func:`gauss_pixel` with the band's radius and weights (:data:`FOVEAL_WEIGHTS`)."""
    if b == 0:
        return np.float64(img[y, x, ch])
    return gauss_pixel(img, y, x, ch, k, FOVEAL_STRIDE * (b - 1), radii[b], h, w)


@njit(cache=True, parallel=True)
def _foveal(img, ecc, edges, k, radii, r0, out):
    h, w = img.shape[0], img.shape[1]
    for y in prange(out.shape[0]):
        for x in range(w):
            b = foveal_band(ecc[y, x], edges)
            for ch in range(3):
                out[y, x, ch] = foveal_pixel(img, r0 + y, x, ch, b, k, radii, h, w)


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
    pad = LP_PAD_FXAA if kind == "fxaa" else LP_PAD_GAUSS
    padded = np.empty((lp.shape[0] + 2 * pad, lp.shape[1], 3), dtype=np.float32)
    _lp.wrap_pad(lp, n, pad, padded)
    if kind == "fxaa":
        return fxaa(padded, exposure, rows=(pad, pad + lp.shape[0]))
    out = np.empty(lp.shape, dtype=np.float32)
    _gaussian(padded, _gauss1d(LP_GAUSS_SIGMA, LP_GAUSS_RADIUS), LP_GAUSS_RADIUS, pad, out)
    return out


def foveal_gaussian(img: np.ndarray, geometry, y0: int = 0, rows: tuple[int, int] | None = None):
    """LMFR's post anti-aliasing: each pixel takes the Gaussian of its eccentricity band (seed 001 §7).

    ``img`` is a screen tile whose row 0 is screen row ``y0``, including up to ``max(FOVEAL_RADII)`` halo rows;
    ``rows`` (default: all) are the tile rows to return. Eccentricity is the viewing geometry's (seed 001
    Eq 3, :meth:`data_schema.geometry.ViewingGeometry.eccentricity_map`).
    """
    r0, r1 = rows if rows is not None else (0, img.shape[0])
    ecc = geometry.eccentricity_map(slice(y0 + r0, y0 + r1))
    out = np.empty((r1 - r0,) + img.shape[1:], dtype=np.float32)
    _foveal(np.ascontiguousarray(img, dtype=np.float32), ecc, FOVEAL_BANDS_DEG, FOVEAL_WEIGHTS,
            np.array(FOVEAL_RADII), r0, out)
    return out
