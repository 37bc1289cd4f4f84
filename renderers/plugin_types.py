"""What a renderer plug-in is: its parameters, its entry points, and what it receives and returns.

This module is a leaf (it imports no other module of ``renderers``), so that plug-ins can declare themselves
without importing the registry, and the registry without importing any plug-in.

The renderer output contract
----------------------------
A plug-in's ``run(ctx)`` returns the image as **linear, unexposed radiance**: float32 ``(height, width, 3)``,
finite, non-negative, in the scene's radiance units. Exposure and tone mapping are applied once, when the PNG
is written (:func:`renderers.stimuli.write_png`); ``ctx.exposure`` is given to a plug-in only for perceptual
decisions made inside the render (FXAA's luma), never to scale its output. :func:`renderers.registry.render`
checks the type, shape and values of every output; ``tests/test_render.py`` checks for every registered
renderer that the output does not depend on the scene's exposure.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Callable, Literal

from data_schema.errors import UserError
from data_schema.geometry import ViewingGeometry
from data_schema.ranges import Range


@dataclass(frozen=True)
class Param:
    """One renderer parameter: ``type`` (bool, int, float, str), ``default``, range ``[low, high]`` (open ends
    with ``low_open``/``high_open``) or ``choices``."""

    type: type
    default: Any
    low: float | None = None
    high: float | None = None
    choices: tuple | None = None
    low_open: bool = False
    high_open: bool = False
    help: str = ""

    @property
    def range(self) -> Range:
        return Range(self.low, self.high, self.low_open, self.high_open, integer=self.type is int)

    def allowed(self) -> str:
        if self.choices:
            return ", ".join(map(str, self.choices))
        if self.type is bool:
            return "true, false"
        return self.range.describe()

    def coerce(self, where: str, value):
        """``value`` (possibly a string from the command line) as this parameter's type, checked."""
        bad = UserError(f"{where}={value!r} is invalid: allowed {self.allowed()}")
        if self.type is bool:
            if isinstance(value, str):
                v = value.strip().lower()
                if v not in ("1", "0", "true", "false", "yes", "no", "on", "off"):
                    raise bad
                return v in ("1", "true", "yes", "on")
            if type(value).__name__ not in ("bool", "bool_"):
                raise bad
            return bool(value)
        if self.type in (int, float):
            if isinstance(value, str):
                try:
                    value = float(value)
                except ValueError:
                    raise bad from None
            return self.range.check(where, value)
        value = str(value)
        if self.choices and value not in self.choices:
            raise bad
        return value


#: The directions a foveation strength can grow in (:class:`StrengthSpec`).
STRONGER = ("higher", "lower")
#: The device-independent counts a strength lowers: stats keys of :func:`renderers.registry.render`.
#: ``rays_primary`` of a log-polar renderer is its LP pixels traced (ray-casting pipeline: one primary ray per
#: shaded LP pixel on or bordering the display, hit or miss); ``shading_points`` counts only the hits, which a
#: coarser buffer can raise by a few when its samples land on geometry (LMFR at 48 x 27: 17 -> 20).
WORK_COUNTS = ("rays_primary", "light_samples")


@dataclass(frozen=True)
class StrengthSpec:
    """A renderer's continuous foveation strength: the parameter an adaptive design varies (issue 28).

    A plug-in declares ``StrengthSpec(param, stronger, count)``; :func:`renderers.registry.foveation_strength`
    returns it with ``range`` and ``default`` filled in from the parameter's :class:`Param` (the one home of the
    allowed range).

    Attributes
    ----------
    param : str
        The parameter (numeric) of the plug-in.
    stronger : {"higher", "lower"}
        Which way foveation grows: ``"higher"`` (LaFR/LMFR ``delta``, FSL ``alpha``) or ``"lower"`` (VaFR
        ``acuity_scale``, the lightcuts baselines' samples per pixel).
    count : {"rays_primary", "light_samples"}
        The render stat the strength lowers (:data:`WORK_COUNTS`): it never increases as foveation gets stronger
        (tests/test_strength.py).
    range : Range
        The parameter's allowed values (filled in by the registry).
    default : float
        The parameter's default (filled in by the registry).
    """

    param: str
    stronger: Literal["higher", "lower"]
    count: Literal["rays_primary", "light_samples"] = "rays_primary"
    range: Range | None = None
    default: float | None = None

    def __post_init__(self):
        if self.stronger not in STRONGER:
            raise ValueError(f"StrengthSpec.stronger={self.stronger!r}: allowed {', '.join(STRONGER)}")
        if self.count not in WORK_COUNTS:
            raise ValueError(f"StrengthSpec.count={self.count!r}: allowed {', '.join(WORK_COUNTS)}")

    def stronger_than(self, a: float, b: float) -> bool:
        """Whether value ``a`` foveates more strongly than ``b``."""
        return a > b if self.stronger == "higher" else a < b

    def weakest_first(self, values) -> list:
        """``values`` sorted from the weakest foveation to the strongest."""
        return sorted(values, reverse=self.stronger == "lower")

    def describe(self) -> str:
        """``delta (stronger = higher, allowed (1, 16], default 1.8)``."""
        rng = f", allowed {self.range.describe()}" if self.range is not None else ""
        dft = f", default {self.default:g}" if self.default is not None else ""
        return f"{self.param} (stronger = {self.stronger}{rng}{dft})"


@dataclass(frozen=True)
class RendererPlugin:
    """A renderer: name, description, parameter table, and its implementations.

    ``run`` is the CPU implementation, ``gpu`` the GPU one (``None``: no GPU version), each a callable or a
    ``"module:function"`` reference loaded on first use (so listing renderers imports no rendering code).
    ``presets`` names parameter sets of this plug-in that are listed and used as renderers of their own
    (``{"sl_e": ("description", {"lspp": 8})}``). ``bytes_per_pixel`` is a rough memory estimate per screen
    pixel for the resolution check.
    """

    name: str
    description: str
    params: dict[str, Param]
    run: Callable[[RenderContext], Any] | str
    bytes_per_pixel: float = 16.0
    gpu: Callable[[RenderContext], Any] | str | None = None
    presets: dict[str, tuple[str, dict]] = field(default_factory=dict)
    preset_of: str | None = None  # set on the plug-ins made from a preset
    #: ``check(params, geometry)`` raises a one-line error when the renderer cannot render for a viewing
    #: geometry (e.g. a foveation mapping undefined on that display); called when a protocol is validated and
    #: by :func:`renderers.registry.render` before every frame (both backends), so it should be cheap (cache).
    check: Callable[[dict, ViewingGeometry], None] | str | None = None
    #: ``preview(params) -> params`` for a thumbnail render (the simulated observer's 64-pixel frames): the
    #: same method without work such a small image cannot show (``None``: the params unchanged).
    preview: Callable[[dict], dict] | None = None
    #: The continuous foveation strength (:class:`StrengthSpec`), or ``None`` (a ground truth, not foveated).
    strength: StrengthSpec | None = None

    def __post_init__(self):
        s = self.strength
        if s is not None and (s.param not in self.params or self.params[s.param].type not in (int, float)):
            raise ValueError(f"renderer {self.name!r}: strength parameter {s.param!r} is not a numeric parameter")

    def preset(self, name: str) -> RendererPlugin:
        """The plug-in of preset ``name``: this one, renamed, with the preset's defaults."""
        description, values = self.presets[name]
        params = {k: replace(p, default=values.get(k, p.default)) for k, p in self.params.items()}
        return replace(self, name=name, description=description, params=params, presets={}, preset_of=self.name)


@dataclass
class RenderContext:
    """What a plug-in's ``run`` receives; it adds counters to ``tracer`` and extras to ``extra``.

    ``geometry`` is the image's viewing geometry (pixels, the camera's vertical field of view, the gaze);
    ``tracer`` is the backend's scene (the CPU ray tracer, or the GPU's uploaded scene); ``exposure`` is for
    perceptual decisions only (see the output contract above).
    """

    scene: Any
    camera: Any
    geometry: ViewingGeometry
    params: dict
    tracer: Any
    exposure: float = 1.0
    extra: dict = field(default_factory=dict)
    previous_camera: Any = None  # the previous frame's camera (screen-space velocity), or None

    @property
    def width(self) -> int:
        return self.geometry.width

    @property
    def height(self) -> int:
        return self.geometry.height

    @property
    def gaze(self) -> tuple[float, float]:
        return self.geometry.gaze
