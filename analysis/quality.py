"""Image quality of a stimulus against ground truth (GT) inside the fovea and in the periphery.

MSE, PSNR and SSIM (scikit-image) are computed per *region* of the display, the regions being
set by the eccentricity of every pixel centre seen from the gaze point (seed 001 Eq 3):

.. math::

    c_r = \\frac{2 \\tan(\\mathrm{fov}_y / 2)}{H}, \\qquad
    r = \\sqrt{(x - x_0)^2 + (y - y_0)^2}, \\qquad
    e = \\tan^{-1}(c_r \\, r),

with pixel ``(i, j)`` centred at ``(i + 0.5, j + 0.5)``, ``y`` growing downwards and the gaze
``(x0, y0)`` in the same continuous pixel coordinates (default: the display centre). This is
the convention of :class:`data_schema.geometry.ViewingGeometry`, which computes it (the one home of the
viewing geometry; it needs only NumPy, so ``import analysis`` loads neither numba nor the renderers).

Light on purpose: scikit-image and matplotlib are imported inside the functions that need them.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from data_schema.errors import UserError
from data_schema.geometry import FOVEA_DEG, PIXELS, RegionMasks  # RegionMasks: re-exported, its home is there
from data_schema.ranges import Range

__all__ = [
    "QUALITY_COLUMNS",
    "RegionMasks",
    "eccentricity_map",
    "error_heatmap",
    "fovea_radius_px",
    "image_quality",
    "region_masks",
    "squared_error_map",
]

#: Columns of :func:`image_quality`, in order.
QUALITY_COLUMNS: tuple[str, ...] = ("region", "mse", "psnr", "ssim", "n_pixels", "n_ssim_pixels", "note")

#: scikit-image's default SSIM window (7 x 7, uniform weights); its radius is cropped at the border.
SSIM_WIN_SIZE = 7
_SSIM_PAD = (SSIM_WIN_SIZE - 1) // 2

#: Default ``data_range`` per dtype: the largest value of the integer type, 1.0 for floats.
_DTYPE_RANGE = {"uint8": 255.0, "uint16": 65535.0}
#: Allowed ``data_range`` (``--data-range``): SSIM's constants ``(0.01 L)^2`` and ``(0.03 L)^2`` must stay
#: normal floats and mean something against the pixel values; 1e-6 to 1e12 spans any linear radiance.
DATA_RANGE = Range(1e-6, 1e12)

_NOTE_EMPTY = "no pixels in this region: metrics left empty"
_NOTE_SSIM_BORDER = (f"region lies within {_SSIM_PAD} px of the image border: SSIM left empty "
                     "(the SSIM window radius is excluded there)")
_NOTE_IDENTICAL = "identical in this region: MSE 0, PSNR +inf"


# --- validation ---------------------------------------------------------------------------------------------
def _whole(name: str, value: Any) -> int:
    return PIXELS.check(name, value)


def _open_interval(name: str, value: Any, low: float, high: float) -> float:
    return Range(low, high, low_open=True, high_open=True).check(name, value)


def _gaze_xy(gaze: Any, width: int, height: int) -> tuple[float, float]:
    if gaze is None:
        return width / 2.0, height / 2.0
    try:
        gx, gy = (float(g) for g in gaze)
    except (TypeError, ValueError):
        raise UserError(f"gaze={gaze!r} is invalid: must be a pair (x, y) of pixel coordinates") from None
    if not (math.isfinite(gx) and math.isfinite(gy)):
        raise UserError(f"gaze=({gx:g}, {gy:g}) is invalid: both coordinates must be finite")
    return gx, gy


def _as_image(a: Any, name: str) -> np.ndarray:
    """Check one image: 2-D ``(H, W)`` or channels-last ``(H, W, C)``, C in 1..4; supported dtype; finite."""
    a = np.asarray(a)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[:, :, 0]
    if a.ndim not in (2, 3) or (a.ndim == 3 and not 1 <= a.shape[2] <= 4):
        raise UserError(f"{name} has shape {a.shape}: expected (H, W) or channels-last (H, W, C), "
                         "C in 1..4")
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise UserError(f"{name} has shape {a.shape}: it has no pixels")
    if a.dtype.name not in _DTYPE_RANGE and a.dtype.kind != "f":
        raise UserError(f"{name} has dtype {a.dtype}: supported are uint8, uint16 and float")
    if a.dtype.kind == "f":
        bad = int(np.count_nonzero(~np.isfinite(a)))
        if bad:
            raise UserError(f"{name} contains {bad} NaN or infinite value(s)")
    return a


def _check_pair(image: Any, reference: Any, data_range: Any) -> tuple[np.ndarray, np.ndarray, float]:
    """Validate an image/reference pair; return both as float64 and the data range."""
    img = _as_image(image, "image")
    ref = _as_image(reference, "reference")
    if img.shape != ref.shape:
        raise UserError(f"image shape {img.shape} differs from reference shape {ref.shape}")
    kinds = {a.dtype.name if a.dtype.kind != "f" else "float" for a in (img, ref)}
    if len(kinds) > 1:
        raise UserError(f"image dtype {img.dtype} and reference dtype {ref.dtype} differ in scale: "
                         "convert both to uint8, uint16 or float first")
    if data_range is None:
        rng = _DTYPE_RANGE.get(img.dtype.name, 1.0)
        if img.dtype.kind == "f":
            lo = min(float(img.min()), float(ref.min()))
            hi = max(float(img.max()), float(ref.max()))
            if lo < 0.0 or hi > 1.0:
                raise UserError(f"float images have values in [{lo:g}, {hi:g}], outside [0, 1]: "
                                 "pass data_range (e.g. the GT's peak value)")
    else:
        rng = DATA_RANGE.check("data_range", data_range)
    return img.astype(np.float64), ref.astype(np.float64), rng


# --- geometry -----------------------------------------------------------------------------------------------
def _geometry(width: int, height: int, fov_y_deg: float, gaze: Any = None):
    from data_schema.geometry import ViewingGeometry

    w, h = _whole("width", width), _whole("height", height)
    fov = _open_interval("fov_y_deg", fov_y_deg, 0.0, 180.0)
    return ViewingGeometry.create(w, h, fov, _gaze_xy(gaze, w, h))


def eccentricity_map(width: int, height: int, fov_y_deg: float, gaze: Any = None) -> np.ndarray:
    """Eccentricity in degrees of every pixel centre seen from the gaze point (seed 001 Eq 3).

    Parameters
    ----------
    width, height : int
        Display size in pixels (>= 1).
    fov_y_deg : float
        Vertical field of view of the display in degrees, in (0, 180).
    gaze : (float, float) or None
        Gaze point ``(x0, y0)`` in continuous pixel coordinates (pixel ``(i, j)`` spans
        ``[i, i+1) x [j, j+1)``, ``y`` downwards); may lie outside the display. None: the
        display centre ``(width / 2, height / 2)``.

    Returns
    -------
    ndarray of float64, shape (height, width)
        :math:`e_{ji} = \\tan^{-1}(c_r r_{ji})` in degrees, with
        :math:`c_r = 2\\tan(\\mathrm{fov}_y/2)/H` and :math:`r_{ji}` the distance of the
        centre ``(i + 0.5, j + 0.5)`` from the gaze. Values lie in [0, 90).

    Raises
    ------
    ValueError
        A size that is not a whole number >= 1, ``fov_y_deg`` outside (0, 180), or a gaze
        that is not a pair of finite numbers.

    Notes
    -----
    :meth:`data_schema.geometry.ViewingGeometry.eccentricity_map`: the gaze is taken to lie on the optical
    axis, as in the seed, so ``e`` depends on the distance from the gaze only.
    """
    return _geometry(width, height, fov_y_deg, gaze).eccentricity_map()


def fovea_radius_px(height: int, fov_y_deg: float, fovea_deg: float = 5.0) -> float:
    """Radius in pixels of the fovea circle: :math:`r = \\tan(e_f) / c_r` (seed 001 Eq 3).

    Parameters
    ----------
    height : int
        Display height in pixels (>= 1).
    fov_y_deg : float
        Vertical field of view in degrees, in (0, 180).
    fovea_deg : float
        Fovea radius ``e_f`` in degrees of eccentricity, in (0, 90).

    Returns
    -------
    float
        Distance from the gaze at which the eccentricity equals ``fovea_deg``.
    """
    ef = FOVEA_DEG.check("fovea_deg", fovea_deg)
    return float(_geometry(1, height, fov_y_deg).radius(ef))


def region_masks(width: int, height: int, fov_y_deg: float, gaze: Any = None, fovea_deg: float = 5.0
                 ) -> RegionMasks:
    """Fovea and periphery masks of a display from its geometry and the gaze point.

    Parameters
    ----------
    width, height, fov_y_deg, gaze
        As :func:`eccentricity_map`.
    fovea_deg : float
        Fovea radius in degrees of eccentricity, in (0, 90). Default 5.

    Returns
    -------
    RegionMasks
        :meth:`data_schema.geometry.ViewingGeometry.region_masks` of the checked geometry.
        ``fovea``: pixel centres with :math:`e \\le e_f`; ``periphery``: :math:`e > e_f`.
        Both boolean, shape ``(height, width)``; they partition the display (every pixel is in
        exactly one). Either may be empty, e.g. the fovea when the gaze lies far outside the
        display, or the periphery when ``fovea_deg`` exceeds the largest eccentricity.
    """
    return _geometry(width, height, fov_y_deg, gaze).region_masks(fovea_deg)


# --- metrics ------------------------------------------------------------------------------------------------
def squared_error_map(image: Any, reference: Any) -> np.ndarray:
    """Per-pixel squared error, averaged over the colour channels.

    Parameters
    ----------
    image, reference : array_like
        Same shape ``(H, W)`` or ``(H, W, C)``; same scale (both uint8, both uint16 or both
        float); finite.

    Returns
    -------
    ndarray of float64, shape (H, W)
        :math:`E_{ji} = \\frac{1}{C}\\sum_c (I_{jic} - R_{jic})^2` in the input's units squared.
    """
    img, ref, _ = _check_pair(image, reference, 1.0)
    d = img - ref
    se = d * d
    return se if se.ndim == 2 else se.mean(axis=2)


def _ssim_map(img: np.ndarray, ref: np.ndarray, data_range: float) -> np.ndarray:
    """Full SSIM map ``(H, W)`` (channel mean) of scikit-image's default SSIM."""
    from skimage.metrics import structural_similarity

    h, w = img.shape[:2]
    if min(h, w) < SSIM_WIN_SIZE:
        raise UserError(f"image is {w}x{h} pixels: SSIM needs at least {SSIM_WIN_SIZE}x{SSIM_WIN_SIZE} "
                         f"(its {SSIM_WIN_SIZE}x{SSIM_WIN_SIZE} window)")
    channel_axis = 2 if img.ndim == 3 else None
    _, s = structural_similarity(img, ref, win_size=SSIM_WIN_SIZE, data_range=data_range,
                                 channel_axis=channel_axis, full=True)
    return s if s.ndim == 2 else s.mean(axis=2)


def _region_row(name: str, mask: np.ndarray, se: np.ndarray, ssim: np.ndarray, interior: np.ndarray,
                data_range: float) -> dict[str, Any]:
    n = int(np.count_nonzero(mask))
    ssim_mask = mask & interior
    n_ssim = int(np.count_nonzero(ssim_mask))
    row: dict[str, Any] = {"region": name, "mse": pd.NA, "psnr": pd.NA, "ssim": pd.NA,
                           "n_pixels": n, "n_ssim_pixels": n_ssim, "note": ""}
    if n == 0:
        row["note"] = _NOTE_EMPTY
        return row
    mse = float(se[mask].mean())
    row["mse"] = mse
    # as a difference of logs: L^2 / MSE would overflow or underflow for extreme L or MSE
    row["psnr"] = math.inf if mse == 0.0 else 20.0 * math.log10(data_range) - 10.0 * math.log10(mse)
    notes = [_NOTE_IDENTICAL] if mse == 0.0 else []
    if n_ssim:
        row["ssim"] = float(ssim[ssim_mask].mean())
    else:
        notes.append(_NOTE_SSIM_BORDER)
    row["note"] = "; ".join(notes)
    return row


def image_quality(image: Any, reference: Any, *, fov_y_deg: float, gaze: Any = None, fovea_deg: float = 5.0,
                  data_range: float | None = None) -> pd.DataFrame:
    """MSE, PSNR and SSIM of ``image`` against ``reference`` in the fovea, the periphery and overall.

    Parameters
    ----------
    image, reference : array_like
        The stimulus and the ground truth: same shape, ``(H, W)`` grey or channels-last
        ``(H, W, C)`` with C in 1..4 (all channels compared). Both uint8, both uint16 or both
        float (any float width), finite. The values are compared *as given*: pass linear
        radiance for linear errors, sRGB-encoded values (e.g. PNG pixels) for display errors;
        nothing is converted.
    fov_y_deg : float
        Vertical field of view of the display in degrees, in (0, 180).
    gaze : (float, float) or None
        Gaze point in pixel coordinates (see :func:`eccentricity_map`); None: the image centre.
    fovea_deg : float
        Fovea radius in degrees of eccentricity, in (0, 90). Default 5.
    data_range : float or None
        Peak-to-peak range :math:`L` of the values, used by PSNR and by SSIM's constants.
        None: 255 for uint8, 65535 for uint16, 1.0 for float, in which case float values must
        lie in [0, 1] (an HDR/linear image needs an explicit ``data_range``).

    Returns
    -------
    DataFrame
        Three rows, ``region`` = ``"fovea"``, ``"periphery"``, ``"all"``, with columns
        ``region, mse, psnr, ssim, n_pixels, n_ssim_pixels, note`` (:data:`QUALITY_COLUMNS`):

        * ``mse`` :math:`= \\frac{1}{|M|}\\sum_{p \\in M} E_p`, :math:`E_p` the channel-mean
          squared error (:func:`squared_error_map`), in the input's units squared (divide by
          255² to compare uint8 results with errors on [0, 1]).
        * ``psnr`` :math:`= 10 \\log_{10}(L^2 / \\mathrm{MSE})` dB; exactly ``+inf`` when MSE
          is 0 (identical in the region; ``note`` says so). Never NaN.
        * ``ssim``: the full SSIM map of :func:`skimage.metrics.structural_similarity` (its
          defaults: 7 x 7 uniform window, K1 = 0.01, K2 = 0.03, sample covariance; per channel,
          then averaged over the channels) averaged over the region's pixels that lie at least
          3 px (the window radius) from the image border, the pixels scikit-image itself
          averages. For the whole image it equals scikit-image's global mean SSIM.
        * ``n_pixels`` = :math:`|M|`; ``n_ssim_pixels`` the pixels the SSIM mean is over.

        The metric columns have the nullable dtype ``Float64``. Empty-region policy: a region
        without pixels (``n_pixels`` = 0, e.g. the fovea when the gaze lies far off the
        display) has ``<NA>`` (not NaN) in mse, psnr and ssim and a ``note``; likewise
        ``ssim`` is ``<NA>`` with a note when ``n_ssim_pixels`` = 0. ``<NA>`` is written as an
        empty CSV cell and as JSON ``null``.

    Raises
    ------
    ValueError
        Shapes differ; an unsupported dtype (not uint8, uint16 or float) or mixed scales;
        NaN or infinite values; float values outside [0, 1] without ``data_range``; an image
        smaller than the 7 x 7 SSIM window; bad geometry (see :func:`eccentricity_map`).

    References
    ----------
    Wang, Z., Bovik, A. C., Sheikh, H. R. & Simoncelli, E. P. (2004). Image quality
    assessment: from error visibility to structural similarity. *IEEE TIP* 13(4), 600-612.
    Seed 003 Table 1 reports MSE in the foveal and peripheral regions in the same way.
    """
    img, ref, rng = _check_pair(image, reference, data_range)
    h, w = img.shape[:2]
    masks = region_masks(w, h, fov_y_deg, gaze, fovea_deg)
    d = img - ref
    se = d * d if d.ndim == 2 else (d * d).mean(axis=2)
    ssim = _ssim_map(img, ref, rng)
    interior = np.zeros((h, w), dtype=bool)
    interior[_SSIM_PAD:h - _SSIM_PAD, _SSIM_PAD:w - _SSIM_PAD] = True
    everything = np.ones((h, w), dtype=bool)
    rows = [_region_row(name, m, se, ssim, interior, rng)
            for name, m in (("fovea", masks.fovea), ("periphery", masks.periphery), ("all", everything))]
    out = pd.DataFrame(rows, columns=list(QUALITY_COLUMNS))
    return out.astype({"mse": "Float64", "psnr": "Float64", "ssim": "Float64",
                       "n_pixels": "int64", "n_ssim_pixels": "int64"})


# --- heat map -----------------------------------------------------------------------------------------------
def error_heatmap(image: Any, reference: Any, out_png: str | Path, *, fov_y_deg: float, gaze: Any = None,
                  fovea_deg: float = 5.0, title: str | None = None) -> Path:
    """Write a PNG heat map of the per-pixel squared error with the fovea circle.

    Parameters
    ----------
    image, reference : array_like
        As :func:`image_quality`.
    out_png : str or Path
        Output file; written atomically (temporary file, then rename); parent folders are
        created.
    fov_y_deg, gaze, fovea_deg
        Display geometry and fovea, as :func:`image_quality`.
    title : str or None
        Axes title (default: ``"squared error"``).

    Returns
    -------
    Path
        ``out_png``.

    Notes
    -----
    Colour: :func:`squared_error_map` on a logarithmic scale (colormap ``viridis``) from
    :math:`\\max(E_{min>0}, 10^{-10} E_{max})` to :math:`E_{max}`; pixels with zero error are
    drawn black (the colour bar's ``min`` extension). If the images are identical the whole
    map is black and the title says so. The fovea circle (radius :func:`fovea_radius_px`,
    red) and the gaze (``+``) are drawn in pixel coordinates and clipped to the image. The
    PNG carries no software/version metadata: the same input gives the same bytes.
    """
    import matplotlib
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    from data_schema.atomic import atomic_path

    se = squared_error_map(image, reference)
    h, w = se.shape
    gx, gy = _gaze_xy(gaze, w, h)
    radius = fovea_radius_px(h, fov_y_deg, fovea_deg)
    positive = se[se > 0]
    identical = positive.size == 0
    vmax = float(positive.max()) if not identical else 1.0
    vmin = max(float(positive.min()), vmax * 1e-10) if not identical else 0.1
    if vmin >= vmax:
        vmin = vmax / 10.0
    shown = np.where(se > 0, np.maximum(se, vmin), vmin / 2.0)

    fig_w = 6.4
    fig_h = min(max(fig_w * h / w * 0.85 + 0.6, 2.5), 10.0)
    fig = Figure(figsize=(fig_w, fig_h), dpi=100, layout="constrained")
    ax = fig.add_subplot()
    cmap = matplotlib.colormaps["viridis"].with_extremes(under="black")
    im = ax.imshow(shown, cmap=cmap, norm=LogNorm(vmin=vmin, vmax=vmax), extent=(0, w, h, 0),
                   interpolation="nearest")
    ax.add_patch(Circle((gx, gy), radius, fill=False, edgecolor="red", linewidth=1.8,
                        label=f"fovea ({fovea_deg:g}°)"))
    ax.plot([gx], [gy], marker="+", color="red", markersize=10, linestyle="none")
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px)")
    text = title if title is not None else "squared error"
    ax.set_title(text + (" — identical (zero error)" if identical else ""), fontsize=10)
    ax.legend(loc="upper right", fontsize=8, framealpha=0.6)
    cbar = fig.colorbar(im, ax=ax, extend="min", shrink=0.9)
    cbar.set_label("squared error per pixel (log scale; black = 0)")
    out_png = Path(out_png)
    with atomic_path(out_png) as tmp:
        fig.savefig(tmp, format="png", metadata={"Software": None})
    return out_png
