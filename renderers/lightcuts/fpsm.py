"""The foveated perceptual sensitivity map (FPSM) of seed 003 §3.1, Eq 1–8.

Pipeline (Fig 3 of the seed), all maps ``(h, w)`` with values in ``[0, 1]``:

1. ``fb_f`` — foveated visual acuity (Eq 2, Stengel et al.'s fall-off): ``clamp(1.1715 - 2.45 e, 0.02, 1)``
   with the eccentricity ``e`` in **radians** (full acuity within 4.0°, the floor 0.02 from 26.9° on; with ``e``
   in degrees the map would fall to its floor at 0.47° and could not describe a fovea).
2. ``fb_st`` — spatiotemporal feature (Eq 1): ``max(fb_f, |∇fb_n|, |∇fb_a|, |∇fb_v|)``, each gradient the 3×3
   Sobel magnitude divided by 8 (the response to a unit-slope ramp is 1), the largest over channels, clipped
   to ``[0, 1]``. ``fb_v`` is the screen-space motion (pixels) of each pixel's hit point between the previous
   and the current camera (``screen_velocity``).
3. ``fb_l`` — luminance feature (Eq 3): ``max(fb_f, |LP_1| / (LP_3 + ε))`` with ``ε = 0.01`` and ``LP`` the
   3-level Laplacian pyramid (Burt & Adelson, 5×5 binomial kernel) of the luminance of the ``w/8 × h/8``
   render upsampled bicubically to ``w × h``; ``LP_1`` is the finest band, ``LP_3`` the low-pass residual
   (Peli's band-limited contrast: band over local mean). Bicubic overshoot is clipped at 0 so ``LP_3 >= 0``;
   the contrast is clipped to ``[0, 1]``.
4. ``ρ`` (Eq 4–7) and ``map`` (Eq 8) under one of three readings of Eq 4–8 (``FPSM_READINGS``, the renderer
   parameter ``fpsm_reading``; ``fpsm_map``): ``derived`` (Eq 7 with its sign corrected, the default),
   ``blur`` (Eq 6 as a spatial Gaussian's attenuation, ρ = 1/ρ_derived) and ``retained`` (Eq 5's surviving
   feature ``M - α`` without Eq 6–7). docs/lightcuts.md compares them.

The per-pixel formulas are scalar numba kernels (``gradient_at``, ``feature``, ``blur5``, ``resample_at``,
``contrast_at``, ``rho_at``, ``map_at``, ``budget``; :data:`GLSL_FLOAT_ROOTS`) that these functions evaluate at
every pixel, summing in scipy's and scikit-image's order (the maps are theirs to the last bit but for ρ's ``log``),
and that renderers/gpu/codegen.py translates into the GPU's FPSM passes: one source for both backends.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange, vectorize
from scipy import ndimage

from data_schema.errors import UserError
from data_schema.ranges import Range

from .options import FPSM_READINGS

from ..constants import ACUITY_FLOOR, ACUITY_INTERCEPT, ACUITY_SLOPE, LUMA_B, LUMA_G, LUMA_R

EPSILON = 0.01
LUMA = np.array([LUMA_R, LUMA_G, LUMA_B])


#: The range of α. Eq 7, ``ρ = sqrt(D / -2 ln(M - α))``, needs ``ln(M - α) < 0`` where the features saturate
#: (``M = 1``: the fovea, ``fb_f = 1``), i.e. ``1 - α < 1`` after rounding in the float32 the GPU evaluates it
#: in: ``α >= 2^-23`` (float32's epsilon). Below, ``ln(1 - α)`` rounds to 0 and ρ to NaN (0 / 0) or +inf.
ALPHA = Range(2.0 ** -23, 1.0, high_open=True)


def check_alpha(alpha) -> float:
    """α, the maximum imperceptibility threshold, in :data:`ALPHA`."""
    return ALPHA.check("alpha", alpha)


def _finite(name: str, x) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if not np.all(np.isfinite(a)):
        raise UserError(f"{name} must be finite (found NaN or inf)")
    return a


#: The kernels renderers/gpu/codegen.py translates into GLSL (``fpsm_gen.glsl``; ``budget`` in double precision,
#: the rest in float32). The CPU evaluates the same functions (numba) at every pixel.
GLSL_FLOAT_ROOTS = ("acuity", "blur5", "resample_at", "gradient_at", "feature", "contrast_at", "rho_at", "map_at")
GLSL_DOUBLE_ROOTS = ("budget",)
#: ``reading`` codes of :func:`rho_at` (the GPU's ``READING``).
DERIVED = 0
BLUR = 1
RETAINED = 2
#: Edge padding of ``fb'`` before the spline prefilter (scipy's ``zoom`` pads modes ``nearest`` by 12).
PAD = 12


def acuity(e):
    """Eq 2's fall-off at eccentricity ``e`` (radians, scalar or array): ``clamp(1.1715 - 2.45 e, 0.02, 1)``,
    the constants from renderers/constants.py; the GPU's FPSM pass runs the GLSL generated from this function."""
    return np.clip(ACUITY_INTERCEPT - ACUITY_SLOPE * e, ACUITY_FLOOR, 1.0)


def acuity_map(eccentricity_rad) -> np.ndarray:
    """Eq 2: ``fb_f = clamp(1.1715 - 2.45 e, 0.02, 1)``, ``e`` in radians (>= 0) (:func:`acuity`)."""
    e = _finite("eccentricity", eccentricity_rad)
    if np.any(e < 0):
        raise UserError("eccentricity must be >= 0")
    return acuity(e)


def eccentricity_map(geometry) -> np.ndarray:
    """Eccentricity in radians (Eq 2's unit) of every pixel centre of a
    :class:`~data_schema.geometry.ViewingGeometry`."""
    return np.radians(geometry.eccentricity_map())


@njit(cache=True)
def gradient_at(gbuf, x, y, w, h, channels):
    """``|∇fb|`` of Eq 1 at pixel ``(x, y)`` of a ``w × h`` image: the largest 3×3 Sobel gradient magnitude over
    the ``channels`` channels of ``gbuf`` (``(w·h, channels)``, row-major) divided by 8 (a unit-slope ramp gives
    1), edges replicated. Each derivative is summed as scipy's ``ndimage.sobel`` sums it: the difference across,
    then the rows (columns) weighted 1-2-1, the centre first."""
    xl = max(x - 1, 0)
    xr = min(x + 1, w - 1)
    up = max(y - 1, 0) * w
    mid = y * w
    dn = min(y + 1, h - 1) * w
    g = 0.0
    for c in range(channels):
        gx = (gbuf[mid + xr, c] - gbuf[mid + xl, c]) * 2.0 + ((gbuf[up + xr, c] - gbuf[up + xl, c])
                                                             + (gbuf[dn + xr, c] - gbuf[dn + xl, c]))
        gy = (gbuf[dn + x, c] - gbuf[up + x, c]) * 2.0 + ((gbuf[dn + xl, c] - gbuf[up + xl, c])
                                                         + (gbuf[dn + xr, c] - gbuf[up + xr, c]))
        g = max(g, math.hypot(gx, gy) / 8.0)
    return g


@njit(cache=True)
def feature(fb_f, g):
    """The form of Eq 1 and Eq 3: the acuity ``fb_f`` raised to a feature ``g``, clipped to [0, 1]."""
    return min(max(max(fb_f, g), 0.0), 1.0)


@njit(parallel=True, cache=True)
def _feature_map(fb_f, gbuf, w, h):
    out = np.empty(w * h)
    for k in prange(w * h):
        out[k] = feature(fb_f[k], gradient_at(gbuf, k % w, k // w, w, h, gbuf.shape[1]))
    return out.reshape(h, w)


def _channels(name: str, buffer, shape=None) -> np.ndarray:
    b = _finite(name, buffer)
    if b.ndim == 2:
        b = b[..., None]
    if b.ndim != 3:
        raise UserError(f"{name} has shape {b.shape}: must be (h, w) or (h, w, channels)")
    if shape is not None and b.shape[:2] != shape:
        raise UserError(f"{name} has shape {np.shape(buffer)}: must match fb_f {shape}")
    return b


def gradient_feature(buffer) -> np.ndarray:
    """``|∇fb|``: largest 3×3 Sobel gradient magnitude over channels, divided by 8, clipped to [0, 1]
    (:func:`gradient_at`)."""
    b = _channels("buffer", buffer)
    h, w, c = b.shape
    return _feature_map(np.zeros(h * w), np.ascontiguousarray(b.reshape(-1, c)), w, h)


def screen_velocity(world_pos, view_proj, prev_view_proj, width: int, height: int) -> np.ndarray:
    """Screen-space motion (pixels, ``(h, w, 2)``) of each hit point between the previous and current camera.

    ``view_proj`` are 4×4 world→clip matrices (column vectors); pixel ``x = (ndc_x + 1) w / 2``,
    ``y = (1 - ndc_y) h / 2``. Points behind either camera get velocity 0.
    """
    p = _finite("world_pos", world_pos)
    hom = np.concatenate([p, np.ones(p.shape[:-1] + (1,))], axis=-1)

    def to_px(m):
        c = hom @ np.asarray(m, dtype=np.float64).T
        w = c[..., 3]
        ok = w > 1e-12
        w = np.where(ok, w, 1.0)
        return np.stack([(c[..., 0] / w + 1.0) * width / 2.0, (1.0 - c[..., 1] / w) * height / 2.0], -1), ok

    now, ok0 = to_px(view_proj)
    before, ok1 = to_px(prev_view_proj)
    return np.where((ok0 & ok1)[..., None], now - before, 0.0)


def spatiotemporal_feature(fb_f, normal, albedo, velocity) -> np.ndarray:
    """Eq 1: ``fb_st = max(fb_f, |∇fb_n|, |∇fb_a|, |∇fb_v|)`` (Stengel et al.'s adaptive sampling map), the
    gradients of all channels at once (:func:`gradient_at`, :func:`feature`)."""
    f = _finite("fb_f", fb_f)
    bufs = [_channels(n, b, f.shape) for n, b in (("normal", normal), ("albedo", albedo), ("velocity", velocity))]
    h, w = f.shape
    gbuf = np.concatenate(bufs, axis=2).reshape(h * w, -1)
    return _feature_map(np.ascontiguousarray(f.reshape(-1)), np.ascontiguousarray(gbuf), w, h)


@njit(cache=True)
def binomial5(a, b, c, d, e):
    """The 1-4-6-4-1 / 16 tap (Burt & Adelson's kernel: the 5×5 Gaussian of Eq 6 and of the pyramid) over five
    consecutive values, summed as scipy's ``correlate1d`` sums a symmetric kernel: centre, outer pair, inner pair."""
    return c * 0.375 + (a + e) * 0.0625 + (b + d) * 0.25


@njit(cache=True)
def _column5(img, c, x, y, w, h):
    return binomial5(img[c, max(y - 2, 0) * w + x], img[c, max(y - 1, 0) * w + x], img[c, y * w + x],
                     img[c, min(y + 1, h - 1) * w + x], img[c, min(y + 2, h - 1) * w + x])


@njit(cache=True)
def blur5(img, c, x, y, w, h):
    """The 5×5 binomial mean of channel ``c`` of ``img`` (``(channels, w·h)``, row-major ``w × h``) at ``(x, y)``,
    edges replicated: along y, then along x, as :func:`gaussian5` (scipy) blurs."""
    return binomial5(_column5(img, c, max(x - 2, 0), y, w, h), _column5(img, c, max(x - 1, 0), y, w, h),
                     _column5(img, c, x, y, w, h), _column5(img, c, min(x + 1, w - 1), y, w, h),
                     _column5(img, c, min(x + 2, w - 1), y, w, h))


@njit(parallel=True, cache=True)
def _blur_map(img, w, h, step):
    ow, oh = (w + step - 1) // step, (h + step - 1) // step
    out = np.empty((oh, ow))
    for k in prange(ow * oh):
        out[k // ow, k % ow] = blur5(img, 0, (k % ow) * step, (k // ow) * step, w, h)
    return out


def gaussian5(image, step: int = 1) -> np.ndarray:
    """5×5 Gaussian (binomial 1-4-6-4-1) average of an ``(h, w)`` image, edges replicated (:func:`blur5`), at
    every ``step``-th pixel of each row and column."""
    img = np.ascontiguousarray(image, dtype=np.float64)
    return _blur_map(img.reshape(1, -1), img.shape[1], img.shape[0], step)


@njit(cache=True)
def spline_weights(t, order):
    """Weights of the ``order + 1`` knots around a point a fraction ``t`` (``0 <= t < 1``) past a knot, for the
    B-spline of ``order`` 1 (that knot and the next) or 3 (from the knot before to the second after; the cubic
    weights of Eq 3's bicubic upsampling), as scipy's ``get_spline_interpolation_weights`` computes them: the last
    weight is 1 minus the others."""
    if order == 1:
        w0 = 1.0 - t
        return (w0, 1.0 - w0, 0.0, 0.0)
    z = 1.0 - t
    w0 = z * z * z / 6.0
    w1 = (t * t * (t - 2.0) * 3.0 + 4.0) / 6.0
    w2 = (z * z * (z - 2.0) * 3.0 + 4.0) / 6.0
    return (w0, w1, w2, 1.0 - w0 - w1 - w2)


@njit(cache=True)
def resample_at(coef, at, cw, ch, x, y, sx, sy, pad, order, lo, hi):
    """Pixel ``(x, y)`` of an image resampled from ``cw × ch`` values (``coef[at:]``, row-major) by the B-spline of
    ``order`` (1, or 3 with ``coef`` the spline coefficients padded by ``pad``) at the scale ``(sx, sy)`` = input /
    output size, clipped to ``[lo, hi]``: scikit-image's ``resize`` (scipy's ``zoom`` in grid mode, edges
    replicated, the products summed in scipy's order)."""
    cx = (x + 0.5) * sx - 0.5 + pad
    cy = (y + 0.5) * sy - 0.5 + pad
    fx = math.floor(cx)
    fy = math.floor(cy)
    wx = spline_weights(cx - fx, order)
    wy = spline_weights(cy - fy, order)
    x0 = int(fx) - (1 if order == 3 else 0)
    y0 = int(fy) - (1 if order == 3 else 0)
    v = 0.0
    for j in range(order + 1):
        row = at + min(max(y0 + j, 0), ch - 1) * cw
        for i in range(order + 1):
            v += coef[row + min(max(x0 + i, 0), cw - 1)] * wy[j] * wx[i]
    return min(max(v, lo), hi)


@njit(parallel=True, cache=True)
def _resample_map(coef, cw, ch, w, h, sx, sy, pad, order, lo, hi):
    out = np.empty((h, w))
    for k in prange(w * h):
        out[k // w, k % w] = resample_at(coef, 0, cw, ch, k % w, k // w, sx, sy, pad, order, lo, hi)
    return out


def bicubic_coefficients(image: np.ndarray) -> np.ndarray:
    """Cubic B-spline coefficients of ``image`` (h', w') padded by :data:`PAD` replicated pixels: what
    ``scipy.ndimage.zoom(order=3, mode="nearest", grid_mode=True)`` (skimage's ``resize`` with ``mode="edge"``)
    interpolates."""
    return ndimage.spline_filter(np.pad(np.asarray(image, dtype=np.float64), PAD, mode="edge"), order=3,
                                 output=np.float64, mode="nearest")


def upsampling(img: np.ndarray, order: int, floor: float = -math.inf) -> tuple[np.ndarray, float, float]:
    """What :func:`resample_at` reads to resample ``img`` by the B-spline of ``order`` (1 or 3): the
    coefficients (``img`` itself for order 1) and the range ``[lo, hi]`` of the result: ``img``'s (skimage clips
    to it), clipped at ``floor`` (the same as clipping the result at ``floor``)."""
    img = np.asarray(img, dtype=np.float64)
    coef = bicubic_coefficients(img) if order == 3 else img
    return coef, max(float(img.min()), floor), max(float(img.max()), floor)


def _resize(img: np.ndarray, shape, order: int, floor: float = -math.inf) -> np.ndarray:
    """``img`` resampled to ``shape`` by the B-spline of ``order`` (1 or 3; :func:`resample_at`), clipped to its
    range and at ``floor``."""
    img = np.asarray(img, dtype=np.float64)
    coef, lo, hi = upsampling(img, order, floor)
    return _resample_map(np.ascontiguousarray(coef).reshape(-1), coef.shape[1], coef.shape[0], shape[1], shape[0],
                         img.shape[1] / shape[1], img.shape[0] / shape[0], float(PAD if order == 3 else 0), order,
                         lo, hi)


def laplacian_pyramid(image, levels: int = 3) -> list[np.ndarray]:
    """Burt–Adelson Laplacian pyramid: ``levels - 1`` band-pass images and the low-pass residual last."""
    g = [np.asarray(image, dtype=np.float64)]
    for _ in range(levels - 1):
        g.append(gaussian5(g[-1], 2))
    bands = [g[i] - _resize(g[i + 1], g[i].shape, 1) for i in range(levels - 1)]
    return bands + [g[-1]]


@njit(cache=True)
def contrast_at(band, residual, eps):
    """Eq 3's contrast ``|LP_1| / (LP_3 + ε)`` at one pixel, ``LP_3`` clipped at 0 and the contrast to [0, 1] (1
    where it is not finite)."""
    c = abs(band) / (max(residual, 0.0) + eps)
    if not c <= 1.0:   # also NaN and +inf
        c = 1.0
    return c


@vectorize(["float64(float64, float64, float64)"], cache=True)
def _contrast(band, residual, eps):
    return contrast_at(band, residual, eps)


@vectorize(["float64(float64, float64)"], cache=True)
def _feature(fb_f, g):
    return feature(fb_f, g)


def luminance_contrast(low_res_rgb, shape, eps: float = EPSILON) -> np.ndarray:
    """``|LP_1| / (LP_3 + ε)`` of the bicubically upsampled low-resolution render, clipped to [0, 1]
    (:func:`contrast_at`).

    ``low_res_rgb`` is ``(h', w', 3)`` linear RGB (or ``(h', w')`` luminance); ``shape`` is ``(h, w)``.
    """
    lo = _finite("low_res_rgb", low_res_rgb)
    if lo.ndim == 3:
        if lo.shape[2] != 3:
            raise UserError(f"low_res_rgb has shape {lo.shape}: must be (h', w', 3) or (h', w')")
        lo = lo @ LUMA
    elif lo.ndim != 2:
        raise UserError(f"low_res_rgb has shape {lo.shape}: must be (h', w', 3) or (h', w')")
    lum = _resize(lo, tuple(shape), 3, floor=0.0)
    lp = laplacian_pyramid(lum, 3)
    return _contrast(lp[0], _resize(lp[2], lum.shape, 1), float(eps))


def luminance_feature(fb_f, contrast) -> np.ndarray:
    """Eq 3: ``fb_l = max(fb_f, LP_1 / (LP_3 + ε))`` (:func:`feature`)."""
    return _feature(_finite("fb_f", fb_f), _finite("contrast", contrast))


#: Squared local deviations ``D`` at or below this (a feature deviation of 1e-6; features lie in [0, 1]) are
#: rounding of ``gaussian5`` on a flat map, taken as 0 so that readings with ``ρ ∝ 1/sqrt(D)`` do not turn
#: rounding noise into a pole.
D_TOL = 1e-12


def check_reading(reading) -> str:
    """The name of a reading of Eq 4–8, one of ``FPSM_READINGS``."""
    if reading not in FPSM_READINGS:
        raise UserError(f"fpsm_reading={reading!r} is invalid: allowed {', '.join(FPSM_READINGS)}")
    return reading


@njit(cache=True)
def rho_at(st, lu, st_mean, lu_mean, alpha, reading):
    """ρ of Eq 4–7 at one pixel under ``reading`` (:data:`DERIVED`, :data:`BLUR`; see :func:`rho_map`) from the
    features ``fb_st``, ``fb_l`` and their 5×5 means, or under :data:`RETAINED` the map itself
    (:func:`fpsm_map`)."""
    dev_st = st - st_mean
    dev_lu = lu - lu_mean
    d = dev_st * dev_st + dev_lu * dev_lu
    if d <= D_TOL:
        d = 0.0
    m = max(st, lu)
    if reading == RETAINED:
        # (M - alpha) / (1 - alpha) written as 1 - (1 - M) / (1 - alpha): equal in exact arithmetic, and with
        # rounded operations it stays monotone in alpha (a larger tolerance never rounds to more samples)
        return min(max(1.0 - (1.0 - m) / (1.0 - alpha), 0.0), 1.0)
    if m <= alpha:
        return math.inf
    neg2ln = -2.0 * math.log(m - alpha)
    if reading == DERIVED:
        return math.sqrt(d / neg2ln)
    if d > 0.0:
        return math.sqrt(neg2ln / d)
    return math.inf


@vectorize(["float64(float64, float64, float64, float64, float64, int64)"], cache=True)
def _rho(st, lu, st_mean, lu_mean, alpha, reading):
    return rho_at(st, lu, st_mean, lu_mean, alpha, reading)


def _features(fb_st, fb_l, alpha, reading: int) -> np.ndarray:
    """:func:`rho_at` at every pixel of the features clipped to [0, 1], with their 5×5 means."""
    a = check_alpha(alpha)
    st = np.clip(_finite("fb_st", fb_st), 0.0, 1.0)
    lu = np.clip(_finite("fb_l", fb_l), 0.0, 1.0)
    if st.shape != lu.shape:
        raise UserError(f"fb_l has shape {lu.shape}: must match fb_st {st.shape}")
    return _rho(st, lu, gaussian5(st), gaussian5(lu), float(a), reading)


def rho_map(fb_st, fb_l, alpha, reading: str = "derived") -> np.ndarray:
    """Per-pixel standard deviation ρ of the 3-D Gaussian (Eq 4–7) under a reading of Eq 6.

    Parameters
    ----------
    fb_st, fb_l : array_like, shape (h, w)
        The spatiotemporal (Eq 1) and luminance (Eq 3) features, clipped to [0, 1].
    alpha : float
        The maximum imperceptibility threshold α, in (0, 1).
    reading : {"derived", "blur"}
        How Eq 6's Gaussian depends on ρ (``"retained"`` has no ρ; see ``fpsm_map``).

    Returns
    -------
    numpy.ndarray
        ρ >= 0, ``+inf`` where Eq 4's constraint holds for every ρ (no NaN).

    Notes
    -----
    With ``M = max(fb_st, fb_l)`` and ``D = (fb_st - mean5(fb_st))^2 + (fb_l - mean5(fb_l))^2`` (``mean5`` the
    5×5 Gaussian average; ``D <= D_TOL`` taken as 0):

    ``derived`` — Eq 6 as printed, ``G(ρ) = exp(-D / (2 ρ^2))``, a Gaussian over the feature space centred on
    the local means. Eq 5 (``G = M - α``) = Eq 6 gives ``ln(M - α) = -D / (2 ρ^2)``, hence

        ρ = sqrt( D / (-2 ln(M - α)) ).                                   (Eq 7, corrected)

    The printed Eq 7 has ``+2 ln(M - α)`` in the denominator, negative for every admissible ``M - α < 1``
    (a square root of a negative number) and undefined for ``M <= α``. Features lie in ``[0, 1]`` and
    ``α in (0, 1)``, so for ``M > α`` the denominator is positive and ρ finite (``D = 0`` gives ``ρ = 0``).
    This ``G`` grows with ρ, so Eq 4's constraint ``M - G <= α`` holds for every ``ρ >= ρ*``: Eq 4's maximum
    is unbounded and Eq 5's equality picks the boundary ``ρ*``, the *smallest* admissible ρ. When ``M <= α``
    Eq 5 asks for ``G <= 0``, which no Gaussian reaches, while Eq 4's constraint holds for every ρ: ρ is
    unbounded, returned as ``+inf`` (``normalise_rho`` maps it to 0, the least accurate cut).

    ``blur`` — Eq 6's Gaussian read as the attenuation of the local detail by a spatial Gaussian filter of
    standard deviation ρ (its frequency response), ``G(ρ) = exp(-ρ^2 D / 2)``. ``G`` falls as ρ grows, as
    §3.1's text says ("the larger the standard deviation, the more reduction"), so Eq 4 is a true maximum,
    attained where Eq 5 holds:

        ρ = sqrt( -2 ln(M - α) / D ) = 1 / ρ_derived.

    ``+inf`` where ``M <= α`` or ``D = 0`` (no filter reduces a flat feature: Eq 4 holds for every ρ).
    """
    if check_reading(reading) == "retained":
        raise UserError("fpsm_reading='retained' has no rho: use fpsm_map")
    return _features(fb_st, fb_l, alpha, DERIVED if reading == "derived" else BLUR)


@njit(cache=True)
def map_at(rho, lo, hi):
    """Eq 8 at one pixel: ``1 - (ρ - ρ_min) / (ρ_max - ρ_min)`` clipped to [0, 1] for finite ρ (1 where
    ``ρ_max = ρ_min``), 0 for ``+inf``."""
    if rho == math.inf:
        return 0.0
    if hi > lo:
        return min(max(1.0 - (rho - lo) / (hi - lo), 0.0), 1.0)
    return 1.0


@vectorize(["float64(float64, float64, float64)"], cache=True)
def _map(rho, lo, hi):
    return map_at(rho, lo, hi)


def normalise_rho(rho) -> np.ndarray:
    """Eq 8: ``map = 1 - (ρ - ρ_min) / (ρ_max - ρ_min)`` over the finite ρ; ``+inf`` maps to 0.

    When ``ρ_max = ρ_min`` (every finite pixel equally tolerant) Eq 8 is 0/0; the map is then 1 on those
    pixels (no pixel can be reduced more than another). With no finite ρ the map is 0 everywhere.
    """
    r = np.asarray(rho, dtype=np.float64)
    if np.any(np.isnan(r)) or np.any(r < 0):
        raise UserError("rho must be >= 0 or +inf (found NaN or a negative value)")
    fin = r[np.isfinite(r)]
    return _map(r, fin.min(), fin.max()) if fin.size else np.zeros(r.shape)


def fpsm_map(fb_st, fb_l, alpha, reading: str = "derived") -> tuple[np.ndarray, np.ndarray]:
    """ρ (Eq 4–7) and the FPSM ``map`` (Eq 8) under one reading of Eq 4–8.

    Parameters
    ----------
    fb_st, fb_l : array_like, shape (h, w)
        The spatiotemporal (Eq 1) and luminance (Eq 3) features.
    alpha : float
        The maximum imperceptibility threshold α, in (0, 1).
    reading : {"derived", "blur", "retained"}
        ``"derived"`` and ``"blur"``: ``rho_map`` then Eq 8 (``normalise_rho``). ``"retained"``: Eq 4–5
        without Eq 6–7 — the accuracy a pixel needs is the feature that must survive the largest imperceptible
        reduction, ``G = M - α`` (Eq 5), normalised by its largest admissible value ``1 - α`` (Eq 8's role):
        ``map = clip((M - α) / (1 - α), 0, 1)``. It rises with the feature and falls with α; it is 1 in the
        fovea (features saturated by ``fb_f = 1``) and at full-contrast edges anywhere, 0 where ``M <= α``.
        It has no ρ; the returned ρ is then the derived one, for comparison.

    Returns
    -------
    rho, map : numpy.ndarray
        ``rho >= 0`` or ``+inf``; ``map`` in ``[0, 1]``, finite for every finite input.
    """
    if check_reading(reading) == "retained":
        return rho_map(fb_st, fb_l, alpha, "derived"), _features(fb_st, fb_l, alpha, RETAINED)
    rho = rho_map(fb_st, fb_l, alpha, reading)
    return rho, normalise_rho(rho)


@dataclass(frozen=True)
class FPSM:
    """The maps of one FPSM construction (for the figures) and the final ``map``."""

    fb_f: np.ndarray
    fb_st: np.ndarray
    fb_l: np.ndarray
    rho: np.ndarray
    map: np.ndarray
    reading: str = "derived"


def build_fpsm(eccentricity_rad, normal, albedo, velocity, low_res_rgb, alpha, eps: float = EPSILON,
               reading: str = "derived") -> FPSM:
    """Construct the FPSM (Fig 3 of seed 003) from G-buffers ``(h, w, c)`` and the ``w/8 × h/8`` render.

    Parameters
    ----------
    eccentricity_rad : array_like, shape (h, w)
        Eccentricity of every pixel in radians (Eq 2).
    normal, albedo, velocity : array_like, shape (h, w, c)
        The G-buffer of Eq 1.
    low_res_rgb : array_like, shape (h', w', 3) or (h', w')
        The low-resolution render ``fb'`` of Eq 3.
    alpha : float
        The maximum imperceptibility threshold α, in (0, 1).
    eps : float
        ε of Eq 3.
    reading : {"derived", "blur", "retained"}
        The reading of Eq 4–8 (``fpsm_map``).
    """
    a = check_alpha(alpha)
    check_reading(reading)
    fb_f = acuity_map(eccentricity_rad)
    fb_st = spatiotemporal_feature(fb_f, normal, albedo, velocity)
    fb_l = luminance_feature(fb_f, luminance_contrast(low_res_rgb, fb_f.shape, eps))
    rho, fmap = fpsm_map(fb_st, fb_l, a, reading)
    return FPSM(fb_f, fb_st, fb_l, rho, fmap, reading)


@njit(cache=True)
def budget(fmap, most, least):
    """Seed 003 §3.1's count at one pixel, ``map · MAX`` rounded up (less 1e-9, so that an exact product does not
    round up by float noise), at least ``least``: the cut size ``#L`` (``MAX_lspp``, at least 1) or the glossy
    rays (``MAX_rspp``)."""
    return max(least, int(math.ceil(fmap * most - 1e-9)))


@vectorize(["int64(float64, int64, int64)"], cache=True)
def _budget(fmap, most, least):
    return budget(fmap, most, least)


def budget_map(fpsm_map, most: int, least: int) -> np.ndarray:
    """:func:`budget` at every pixel of a map (int64)."""
    return _budget(np.asarray(fpsm_map, dtype=np.float64), int(most), int(least))


def light_budget(fpsm_map, max_lspp: int = 48) -> np.ndarray:
    """``#L = map[p] · MAX_lspp`` (seed 003 §3.1) rounded up, at least 1 so no pixel goes unlit."""
    if isinstance(max_lspp, bool) or not float(max_lspp).is_integer() or max_lspp <= 0:
        raise UserError(f"max_lspp={max_lspp!r} is out of range: must be a whole number >= 1")
    m = np.asarray(fpsm_map, dtype=np.float64)
    if np.any(~np.isfinite(m)) or np.any(m < 0) or np.any(m > 1):
        raise UserError("map must hold values in [0, 1]")
    return budget_map(m, max_lspp, 1)
