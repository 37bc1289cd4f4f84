"""The viewing geometry: the one place that relates pixels to degrees of visual angle.

Two types, both plain data:

- :class:`Display` — the participant's physical display as a protocol declares it: pixels, physical width,
  viewing distance (hence the vertical visual angle ``fov_y_deg`` it subtends), refresh rate, window
  settings. It is the only source of the visual angle a study's stimuli subtend: renderers render with a
  camera of that vertical field of view, and the window shows each stimulus over the whole display.
- :class:`ViewingGeometry` — pixels, vertical visual angle and gaze point of one image (a render at any
  resolution of the same display, a stimulus on screen, an image to score). Renderers, the foveation mappings,
  the FPSM, the runner, the simulated observer, the presenter and the image-quality metrics all take this
  type; eccentricity and pixels per degree are computed here only.

Conventions. Screen coordinates are continuous pixels: pixel ``(i, j)`` covers ``[i, i+1) x [j, j+1)``, its
centre is ``(i + 0.5, j + 0.5)``, ``y`` grows downwards. The display is flat and seen from in front of its
centre; pixels are square. The eccentricity of a point ``r`` pixels from the gaze follows seed 001 Eq 3,
``e = atan(c_r r)`` with ``c_r = 2 tan(fov_y / 2) / H`` (the gaze taken to lie on the optical axis, as in the
seed; exact when the gaze is at the display centre), and pixels per degree at the gaze are
``ppd = tan(1°) / c_r``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from .errors import UserError
from .ranges import Range

RAD_PER_DEG = math.pi / 180.0
DEG_PER_RAD = 180.0 / math.pi
PIXELS = Range(1, 32768, integer=True)
DISPLAY_PIXELS = Range(16, 16384, integer=True)
FOV = Range(0.0, 180.0, low_open=True, high_open=True)
#: A fovea radius in degrees of eccentricity (image quality's regions, lightcuts' tables).
FOVEA_DEG = Range(0.0, 90.0, low_open=True, high_open=True)


def fov_from_size(height_cm: float, distance_cm: float) -> float:
    """Vertical visual angle (degrees) of a flat display ``height_cm`` high seen from ``distance_cm``."""
    return 2.0 * math.degrees(math.atan(0.5 * height_cm / distance_cm))


def check_gaze(gaze, width: int, height: int) -> tuple[float, float]:
    """Validate a gaze point in pixels: two finite numbers inside ``[0, width] x [0, height]``."""
    try:
        gx, gy = (float(g) for g in gaze)
    except (TypeError, ValueError):
        raise UserError(f"gaze={gaze!r} is invalid: must be a pair X,Y of pixel coordinates") from None
    if not (math.isfinite(gx) and math.isfinite(gy) and 0 <= gx <= width and 0 <= gy <= height):
        raise UserError(f"gaze=({gx:g}, {gy:g}) is outside the display: allowed x in [0, {width}], "
                        f"y in [0, {height}]")
    return gx, gy


class RegionMasks(NamedTuple):
    """Boolean masks ``(height, width)`` that partition an image (:meth:`ViewingGeometry.region_masks`)."""

    fovea: np.ndarray
    """Pixels whose centre has eccentricity ``e <= fovea_deg``."""
    periphery: np.ndarray
    """Every other pixel (``e > fovea_deg``)."""


#: Fewest pixels on a side of a render at ``--scale`` (:func:`scaled_size`).
MIN_SCALED_SIDE = 16


def scaled_size(width: int, height: int, scale: float) -> tuple[int, int]:
    """``scale`` times ``width`` x ``height`` (rounded), the smaller side at least :data:`MIN_SCALED_SIDE`, never
    more than the full size.

    Where the floor applies, both sides are scaled by the same factor, so that the image keeps its aspect ratio
    and is shown over the same window rectangle however it is placed (fitted into the window or covering it):
    the smallest whole multiple of the reduced aspect ratio (1920x1080 = 16:9 -> 32x18) whose smaller side is
    below twice the floor; else the floor's factor, rounded (the aspect ratio within a pixel)."""
    small = min(width, height)
    if min(round(width * scale), round(height * scale)) >= MIN_SCALED_SIDE:
        return round(width * scale), round(height * scale)
    if small <= MIN_SCALED_SIDE:
        return width, height
    g = math.gcd(width, height)
    n = math.ceil(MIN_SCALED_SIDE * g / small)  # n (width / g, height / g): exactly the full aspect ratio
    if n * small // g < 2 * MIN_SCALED_SIDE:
        return n * width // g, n * height // g
    f = MIN_SCALED_SIDE / small
    return min(width, round(width * f)), min(height, round(height * f))


@dataclass(frozen=True)
class ViewingGeometry:
    """An image of ``width`` x ``height`` pixels subtending ``fov_y_deg`` vertically, looked at ``gaze``.

    ``c_r`` is seed 001's constant of Eq 3 (film height over focal length, divided by the height in pixels):
    ``r = tan(e) / c_r`` is the distance in pixels from the gaze of a point at eccentricity ``e``.
    """

    width: int
    height: int
    fov_y_deg: float
    gaze_x: float
    gaze_y: float

    @classmethod
    def create(cls, width, height, fov_y_deg, gaze=None) -> ViewingGeometry:
        """Checked construction; ``gaze`` defaults to the centre and may lie anywhere (also off the image)."""
        w = PIXELS.check("width", width)
        h = PIXELS.check("height", height)
        fov = FOV.check("fov_y_deg", fov_y_deg)
        if gaze is None:
            gx, gy = w / 2.0, h / 2.0
        else:
            try:
                gx, gy = (float(g) for g in gaze)
            except (TypeError, ValueError):
                raise UserError(f"gaze={gaze!r} is invalid: must be a pair (x, y) of pixel coordinates") from None
            if not (math.isfinite(gx) and math.isfinite(gy)):
                raise UserError(f"gaze={gaze!r} is invalid: must be finite")
        return cls(w, h, fov, gx, gy)

    # -- derived views ----------------------------------------------------------------------------------------
    def with_gaze(self, gaze) -> ViewingGeometry:
        return ViewingGeometry.create(self.width, self.height, self.fov_y_deg, gaze)

    def resized(self, width: int, height: int) -> ViewingGeometry:
        """The same view at another resolution: same visual angle, the gaze at the same place of the image."""
        w, h = PIXELS.check("width", width), PIXELS.check("height", height)
        return replace(self, width=w, height=h, gaze_x=self.gaze_x * w / self.width,
                       gaze_y=self.gaze_y * h / self.height)

    def scaled(self, scale: float) -> ViewingGeometry:
        """``scale`` times the pixels, same visual angle (dry runs, ``--scale``); see :func:`scaled_size`."""
        return self.resized(*scaled_size(self.width, self.height, scale))

    # -- pixels <-> degrees (seed 001 Eq 3) ------------------------------------------------------------------
    @property
    def gaze(self) -> tuple[float, float]:
        return (self.gaze_x, self.gaze_y)

    @property
    def c_r(self) -> float:
        """Seed 001 Eq 3: ``c_r = (film height / focal length) / H = 2 tan(fov_y / 2) / H``."""
        return 2.0 * math.tan(0.5 * self.fov_y_deg * RAD_PER_DEG) / self.height

    @property
    def ppd(self) -> float:
        """Pixels per degree at the gaze (the centre of projection): ``tan(1°) / c_r``."""
        return math.tan(RAD_PER_DEG) / self.c_r

    @property
    def pixels(self) -> int:
        return self.width * self.height

    def radius(self, e_deg):
        """Pixel distance from the gaze of eccentricity ``e_deg`` (seed 001 Eq 3, ``r = tan e / c_r``)."""
        return np.tan(np.asarray(e_deg, dtype=np.float64) * RAD_PER_DEG) / self.c_r

    def eccentricity(self, r_px):
        """Eccentricity in degrees of a point ``r_px`` pixels from the gaze (``e = atan(c_r r)``)."""
        return np.arctan(self.c_r * np.asarray(r_px, dtype=np.float64)) * DEG_PER_RAD

    def eccentricity_map(self, rows: slice | None = None) -> np.ndarray:
        """Eccentricity (degrees, float64) of every pixel centre, ``(height, width)`` (or the given rows)."""
        rows = rows or slice(0, self.height)
        x = np.arange(self.width, dtype=np.float64) + 0.5 - self.gaze_x
        y = np.arange(self.height, dtype=np.float64)[rows] + 0.5 - self.gaze_y
        return self.eccentricity(np.hypot(x[None, :], y[:, None]))

    def region_masks(self, fovea_deg: float = 5.0) -> RegionMasks:
        """Fovea and periphery: pixel centres with ``e <= fovea_deg`` and the rest (seed 001 Eq 3).

        ``fovea_deg`` must lie in (0, 90). Either mask may be empty (the gaze far off the image, or a fovea
        larger than the largest eccentricity); together they cover every pixel exactly once.
        """
        ef = FOVEA_DEG.check("fovea_deg", fovea_deg)
        fovea = self.eccentricity_map() <= ef
        return RegionMasks(fovea=fovea, periphery=~fovea)

    def dr_de(self, e_deg):
        """Radial pixels per degree at eccentricity ``e``: the inverse of seed 001 Eq 7."""
        c = np.cos(np.asarray(e_deg, dtype=np.float64) * RAD_PER_DEG)
        return RAD_PER_DEG / (self.c_r * c * c)

    def corner_distance(self) -> float:
        """Largest distance in pixels from the gaze to a corner of the image."""
        xs = (0.0, float(self.width))
        ys = (0.0, float(self.height))
        return max(math.hypot(x - self.gaze_x, y - self.gaze_y) for x in xs for y in ys)

    def max_eccentricity(self) -> float:
        return float(self.eccentricity(self.corner_distance()))

    def contains(self, x, y):
        """Boolean mask of the points that fall on the image."""
        x = np.asarray(x)
        y = np.asarray(y)
        return (x >= 0) & (x < self.width) & (y >= 0) & (y < self.height)

    def pixel_centres(self):
        """Coordinates of every pixel centre, shape ``(height, width)`` each."""
        x = np.arange(self.width, dtype=np.float64) + 0.5
        y = np.arange(self.height, dtype=np.float64) + 0.5
        return np.meshgrid(x, y)


@dataclass(frozen=True)
class Display:
    """The participant's physical display: ``width_px`` x ``height_px`` pixels, ``width_cm`` wide, seen from
    ``distance_cm``; the window covers it (``fullscreen``, or a window of its size on ``screen``). ``stereo``:
    the display shows a binocular condition's two eyes side by side (a stereoscope, a side-by-side 3D mode); a
    monoscopic display (the default) shows one eye of it over the whole window, as it shows any condition.

    The vertical visual angle it subtends, ``fov_y_deg = 2 atan(height_cm / 2 / distance_cm)`` with
    ``height_cm = width_cm * height_px / width_px`` (square pixels), is the angle every stimulus of the study
    subtends.
    """

    width_px: int
    height_px: int
    width_cm: float
    distance_cm: float
    refresh_hz: float = 60.0
    fullscreen: bool = False
    screen: int = 0
    stereo: bool = False

    def __post_init__(self):
        # The ranges of the protocol schema's display block, for displays made in code too.
        for name, rng in (("width_px", DISPLAY_PIXELS), ("height_px", DISPLAY_PIXELS),
                          ("width_cm", Range(0.0, 1000.0, low_open=True)),
                          ("distance_cm", Range(0.0, 10000.0, low_open=True)), ("refresh_hz", Range(20.0, 1000.0)),
                          ("screen", Range(0, 16, integer=True))):
            object.__setattr__(self, name, rng.check(f"display.{name}", getattr(self, name)))
        for name in ("fullscreen", "stereo"):
            if not isinstance(getattr(self, name), bool):
                raise UserError(f"display.{name}={getattr(self, name)!r} is invalid: must be true or false")

    @property
    def height_cm(self) -> float:
        return self.width_cm * self.height_px / self.width_px

    @property
    def fov_y_deg(self) -> float:
        return fov_from_size(self.height_cm, self.distance_cm)

    def geometry(self, gaze=None) -> ViewingGeometry:
        """The display's own pixels and visual angle, looked at ``gaze`` (default: the centre)."""
        return ViewingGeometry.create(self.width_px, self.height_px, self.fov_y_deg, gaze)

    @property
    def ppd(self) -> float:
        """Pixels per degree at the screen centre, ``width_px / width_cm * distance_cm * tan(1°)``."""
        return self.geometry().ppd

    def outside_disc(self, point, centre, radius_deg: float) -> bool:
        """Whether display pixel ``point`` lies more than ``radius_deg`` of visual angle from ``centre``
        (e.g. a gaze sample outside the foveal disc around the fixation point): its eccentricity seen from
        ``centre`` as the centre of projection, seed 001 Eq 3 ``e = atan(c_r r)``, against ``radius_deg``."""
        r = math.hypot(point[0] - centre[0], point[1] - centre[1])
        return bool(self.geometry(centre).eccentricity(r) > radius_deg)


@dataclass(frozen=True)
class EyeView:
    """Where one eye's image goes: its viewport in the window (pixels from the top-left) and the size it is
    rendered at. The one place that knows the per-eye projection of a condition (:func:`eye_views`: a stereo
    display shows a binocular condition's eyes side by side, a monoscopic one shows one eye over the window; an
    HMD presenter would map each eye to its own display)."""

    eye: str  # "mono", "left" or "right"
    x0: int
    y0: int
    width: int
    height: int
    render_width: int
    render_height: int

    def to_render(self, x: float, y: float) -> tuple[float, float]:
        """Window pixels -> this eye's render pixels (clamped to the image)."""
        u = (x - self.x0) * self.render_width / self.width
        v = (y - self.y0) * self.render_height / self.height
        return (min(max(u, 0.0), float(self.render_width)), min(max(v, 0.0), float(self.render_height)))

    def to_window(self, u: float, v: float) -> tuple[float, float]:
        """This eye's render pixels -> window pixels (the inverse of :meth:`to_render`, not clamped)."""
        return (self.x0 + u * self.width / self.render_width, self.y0 + v * self.height / self.render_height)

    def record(self) -> dict:
        """The view as plain data, as a session records it (:meth:`from_record` reads it back)."""
        return {"eye": self.eye, "x0": self.x0, "y0": self.y0, "width": self.width, "height": self.height,
                "render_width": self.render_width, "render_height": self.render_height}

    @classmethod
    def from_record(cls, rec) -> EyeView:
        """A view recorded by :meth:`record`, checked: a one-line :class:`UserError` for anything else."""
        names = ("eye", "x0", "y0", "width", "height", "render_width", "render_height")
        if not isinstance(rec, dict) or set(rec) != set(names) or rec["eye"] not in ("mono", *EYES):
            raise UserError(f"view {rec!r:.80} is invalid: must be an eye (mono, left, right) and its viewport")
        ints = {k: (Range(0, PIXELS.high, integer=True) if k in ("x0", "y0") else PIXELS).check(f"view.{k}", rec[k])
                for k in names[1:]}
        return cls(rec["eye"], **ints)


EYES = ("left", "right")


def eye_views(window: tuple[int, int], render: tuple[int, int], eyes: int, stereo: bool = False,
              eye: str = "left") -> list[EyeView]:
    """The views of a stimulus covering a ``window``, rendered at ``render`` pixels.

    A one-view condition (``eyes=1``) covers the window. A binocular one (``eyes=2``: both eyes are rendered
    and timed) covers it the same way on a monoscopic display (``stereo=False``): the one eye ``eye`` at the
    full render size, so that every condition fills the same area at the same size and none is told apart by
    its layout; on a stereo display (``stereo=True``) the left and right eyes take the left and right halves,
    each rendered at half the width with the same vertical visual angle."""
    (ww, wh), (rw, rh) = window, render
    if eye not in EYES:
        raise UserError(f"eye={eye!r} is invalid: allowed {', '.join(EYES)}")
    if eyes == 1:
        return [EyeView("mono", 0, 0, ww, wh, rw, rh)]
    if not stereo:
        return [EyeView(eye, 0, 0, ww, wh, rw, rh)]
    half = ww // 2
    rw2 = max(16, rw // 2)
    return [EyeView("left", 0, 0, half, wh, rw2, rh), EyeView("right", half, 0, ww - half, wh, rw2, rh)]


def eye_at(views: list[EyeView], x: float, y: float) -> EyeView:
    """The view whose viewport holds the window point ``(x, y)`` (the eye the participant looks into); a point
    outside every viewport belongs to the nearest one. A binocular gaze is mapped through this eye's view, not
    always the left one (which clamps a gaze in the right half to the centre line)."""
    def distance(v: EyeView) -> float:
        dx = max(v.x0 - x, 0.0, x - (v.x0 + v.width))
        dy = max(v.y0 - y, 0.0, y - (v.y0 + v.height))
        return math.hypot(dx, dy)

    inside = [v for v in views if v.x0 <= x < v.x0 + v.width and v.y0 <= y < v.y0 + v.height]
    return inside[0] if inside else min(views, key=distance)


@dataclass(frozen=True)
class Placement:
    """Where a ``img_w`` x ``img_h`` stimulus lands in a ``win_w`` x ``win_h`` window.

    The window is the participant's display and a stimulus subtends the display's visual angle, so the image
    is scaled to cover the window (up from a smaller render, e.g. seed 003's 256x144 stimuli on a 1920x1080
    display), keeping its aspect ratio, and centred. ``left``/``top`` are whole window pixels from the window's
    top-left corner, so that at ``scale = 1`` every image pixel maps onto exactly one window pixel.
    """

    win_w: int
    win_h: int
    img_w: int
    img_h: int
    scale: float
    left: int
    top: int

    @classmethod
    def fit(cls, win_w: int, win_h: int, img_w: int, img_h: int) -> Placement:
        scale = min(win_w / img_w, win_h / img_h)
        if abs(scale - 1.0) < 1e-12:
            scale = 1.0
        w, h = img_w * scale, img_h * scale
        # 1e-9 absorbs the round-off of w = img_w * (win_w / img_w)
        return cls(
            win_w,
            win_h,
            img_w,
            img_h,
            scale,
            int(math.floor((win_w - w) / 2 + 1e-9)),
            int(math.floor((win_h - h) / 2 + 1e-9)),
        )

    @property
    def size(self) -> tuple[float, float]:
        """Drawn size in window pixels."""
        return (self.img_w * self.scale, self.img_h * self.scale)

    @property
    def centre_pix(self) -> tuple[float, float]:
        """Image centre in PsychoPy ``pix`` units (origin at the window centre, y up)."""
        w, h = self.size
        return (self.left + w / 2.0 - self.win_w / 2.0, self.win_h / 2.0 - (self.top + h / 2.0))

    def image_to_window(self, x: float, y: float) -> tuple[float, float]:
        """Image pixel coordinates (x right, y down, top-left origin) -> window pixels (same convention)."""
        return (self.left + x * self.scale, self.top + y * self.scale)

    def image_to_pix(self, x: float, y: float) -> tuple[float, float]:
        """Image pixel coordinates -> PsychoPy ``pix`` units (origin at the window centre, y up)."""
        wx, wy = self.image_to_window(x, y)
        return (wx - self.win_w / 2.0, self.win_h / 2.0 - wy)
