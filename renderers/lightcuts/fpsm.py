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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from data_schema.errors import UserError
from data_schema.ranges import Range

from .options import FPSM_READINGS

from ..constants import ACUITY_FLOOR, ACUITY_INTERCEPT, ACUITY_SLOPE, LUMA_B, LUMA_G, LUMA_R

EPSILON = 0.01
LUMA = np.array([LUMA_R, LUMA_G, LUMA_B])
_BINOMIAL = np.array([1.0, 4.0, 6.0, 4.0, 1.0]) / 16.0


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


#: The kernels renderers/gpu/codegen.py translates into GLSL (``fpsm_gen.glsl``, float32).
GLSL_FLOAT_ROOTS = ("acuity",)


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


def gradient_feature(buffer) -> np.ndarray:
    """``|∇fb|``: largest 3×3 Sobel gradient magnitude over channels, divided by 8, clipped to [0, 1]."""
    b = _finite("buffer", buffer)
    if b.ndim == 2:
        b = b[..., None]
    if b.ndim != 3:
        raise UserError(f"buffer has shape {b.shape}: must be (h, w) or (h, w, channels)")
    out = np.zeros(b.shape[:2])
    for c in range(b.shape[2]):
        gx = ndimage.sobel(b[..., c], axis=1, mode="nearest")
        gy = ndimage.sobel(b[..., c], axis=0, mode="nearest")
        np.maximum(out, np.hypot(gx, gy) / 8.0, out=out)
    return np.clip(out, 0.0, 1.0)


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
    """Eq 1: ``fb_st = max(fb_f, |∇fb_n|, |∇fb_a|, |∇fb_v|)`` (Stengel et al.'s adaptive sampling map)."""
    f = _finite("fb_f", fb_f)
    out = f.copy()
    for name, buf in (("normal", normal), ("albedo", albedo), ("velocity", velocity)):
        g = gradient_feature(buf)
        if g.shape != f.shape:
            raise UserError(f"{name} has shape {np.shape(buf)}: must match fb_f {f.shape}")
        np.maximum(out, g, out=out)
    return np.clip(out, 0.0, 1.0)


def gaussian5(image) -> np.ndarray:
    """5×5 Gaussian (binomial 1-4-6-4-1) average, edges replicated."""
    x = ndimage.correlate1d(np.asarray(image, dtype=np.float64), _BINOMIAL, axis=0, mode="nearest")
    return ndimage.correlate1d(x, _BINOMIAL, axis=1, mode="nearest")


def _resize(img: np.ndarray, shape, order: int) -> np.ndarray:
    from skimage.transform import resize

    return resize(img, shape, order=order, mode="edge", anti_aliasing=False, preserve_range=True)


def laplacian_pyramid(image, levels: int = 3) -> list[np.ndarray]:
    """Burt–Adelson Laplacian pyramid: ``levels - 1`` band-pass images and the low-pass residual last."""
    g = [np.asarray(image, dtype=np.float64)]
    for _ in range(levels - 1):
        g.append(gaussian5(g[-1])[::2, ::2])
    bands = [g[i] - _resize(g[i + 1], g[i].shape, 1) for i in range(levels - 1)]
    return bands + [g[-1]]


def luminance_contrast(low_res_rgb, shape, eps: float = EPSILON) -> np.ndarray:
    """``|LP_1| / (LP_3 + ε)`` of the bicubically upsampled low-resolution render, clipped to [0, 1].

    ``low_res_rgb`` is ``(h', w', 3)`` linear RGB (or ``(h', w')`` luminance); ``shape`` is ``(h, w)``.
    """
    lo = _finite("low_res_rgb", low_res_rgb)
    if lo.ndim == 3:
        if lo.shape[2] != 3:
            raise UserError(f"low_res_rgb has shape {lo.shape}: must be (h', w', 3) or (h', w')")
        lo = lo @ LUMA
    elif lo.ndim != 2:
        raise UserError(f"low_res_rgb has shape {lo.shape}: must be (h', w', 3) or (h', w')")
    lum = np.maximum(_resize(lo, tuple(shape), 3), 0.0)
    lp = laplacian_pyramid(lum, 3)
    residual = np.maximum(_resize(lp[2], lum.shape, 1), 0.0)
    with np.errstate(over="ignore"):
        c = np.abs(lp[0]) / (residual + eps)
    return np.clip(np.nan_to_num(c, nan=1.0, posinf=1.0), 0.0, 1.0)


def luminance_feature(fb_f, contrast) -> np.ndarray:
    """Eq 3: ``fb_l = max(fb_f, LP_1 / (LP_3 + ε))``."""
    return np.clip(np.maximum(_finite("fb_f", fb_f), _finite("contrast", contrast)), 0.0, 1.0)


#: Squared local deviations ``D`` at or below this (a feature deviation of 1e-6; features lie in [0, 1]) are
#: rounding of ``gaussian5`` on a flat map, taken as 0 so that readings with ``ρ ∝ 1/sqrt(D)`` do not turn
#: rounding noise into a pole.
D_TOL = 1e-12


def check_reading(reading) -> str:
    """The name of a reading of Eq 4–8, one of ``FPSM_READINGS``."""
    if reading not in FPSM_READINGS:
        raise UserError(f"fpsm_reading={reading!r} is invalid: allowed {', '.join(FPSM_READINGS)}")
    return reading


def _features(fb_st, fb_l, alpha):
    """``(α, M, D)`` of Eq 5–6: ``M = max(fb_st, fb_l)``, ``D`` the squared deviations from the 5×5 means."""
    a = check_alpha(alpha)
    st = np.clip(_finite("fb_st", fb_st), 0.0, 1.0)
    lu = np.clip(_finite("fb_l", fb_l), 0.0, 1.0)
    if st.shape != lu.shape:
        raise UserError(f"fb_l has shape {lu.shape}: must match fb_st {st.shape}")
    d = (st - gaussian5(st)) ** 2 + (lu - gaussian5(lu)) ** 2
    return a, np.maximum(st, lu), np.where(d > D_TOL, d, 0.0)


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
    a, m, d = _features(fb_st, fb_l, alpha)
    defined = m > a
    neg2ln = -2.0 * np.log(np.where(defined, m - a, 0.5))
    if reading == "derived":
        return np.where(defined, np.sqrt(d / neg2ln), np.inf)
    ok = defined & (d > 0)
    return np.where(ok, np.sqrt(neg2ln / np.where(ok, d, 1.0)), np.inf)


def normalise_rho(rho) -> np.ndarray:
    """Eq 8: ``map = 1 - (ρ - ρ_min) / (ρ_max - ρ_min)`` over the finite ρ; ``+inf`` maps to 0.

    When ``ρ_max = ρ_min`` (every finite pixel equally tolerant) Eq 8 is 0/0; the map is then 1 on those
    pixels (no pixel can be reduced more than another). With no finite ρ the map is 0 everywhere.
    """
    r = np.asarray(rho, dtype=np.float64)
    if np.any(np.isnan(r)) or np.any(r < 0):
        raise UserError("rho must be >= 0 or +inf (found NaN or a negative value)")
    fin = np.isfinite(r)
    out = np.zeros(r.shape)
    if not fin.any():
        return out
    lo, hi = r[fin].min(), r[fin].max()
    if hi > lo:
        out[fin] = 1.0 - (r[fin] - lo) / (hi - lo)
    else:
        out[fin] = 1.0
    return np.clip(out, 0.0, 1.0)


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
        a, m, _ = _features(fb_st, fb_l, alpha)
        # (M - alpha) / (1 - alpha) written as 1 - (1 - M) / (1 - alpha): equal in exact arithmetic, and with
        # rounded operations it stays monotone in alpha (a larger tolerance never rounds to more samples)
        return rho_map(fb_st, fb_l, a, "derived"), np.clip(1.0 - (1.0 - m) / (1.0 - a), 0.0, 1.0)
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


def light_budget(fpsm_map, max_lspp: int = 48) -> np.ndarray:
    """``#L = map[p] · MAX_lspp`` (seed 003 §3.1) rounded up, at least 1 so no pixel goes unlit."""
    if isinstance(max_lspp, bool) or not float(max_lspp).is_integer() or max_lspp <= 0:
        raise UserError(f"max_lspp={max_lspp!r} is out of range: must be a whole number >= 1")
    m = np.asarray(fpsm_map, dtype=np.float64)
    if np.any(~np.isfinite(m)) or np.any(m < 0) or np.any(m > 1):
        raise UserError("map must hold values in [0, 1]")
    return np.maximum(1, np.ceil(m * int(max_lspp) - 1e-9)).astype(np.int64)
