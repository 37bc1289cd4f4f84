"""Every value a renderer's declared ranges accept renders something (issue 25, item 3).

For EVERY registered renderer (``renderers.registry.available()``, presets and plug-ins included), hypothesis
draws each numeric parameter from its declared range (``Param.range``): the values next to both ends
(``low + tiny``, ``high - tiny``), log-uniform over the range and uniform; choices and booleans from their
choices. Each draw either

* is refused at validation (``resolve_params`` and the plug-in's geometry check, what ``studyapp validate``
  runs) with ONE line that names the parameter (``vafr.e_max=...``), or
* renders a 48 x 27 ``cornell`` frame on the CPU that is finite, ``>= 0``, has at least one shading point,
  and leaves no visible region at the clear value. A region is a 16 x 16 block of the image (the last ones cut
  at its edge) in which the ground truth shows lit geometry (a pixel > 0) in more than half of the pixels; each
  must hold a pixel > 0, i.e. written by a shading point or a reconstruction from one (LP pixels that nothing
  shaded stay 0, the clear value, as does the background). Not 8 x 8: at 48 x 27 a sparse legitimate LP
  buffer (LaFR ``delta = 6``: 8 x 4, the 4 rows of the coarse catch condition's 64 x 36 thumbnails) interpolates
  an 8 x 8 block of the box between two samples off the display that see past the box.

Costs bound the draws, not validity: sample counts (``lspp``, ``rspp``, ``max_lspp``, ``max_rspp``, ``spp``)
are drawn up to 16 and held there when not drawn (4096 light samples per pixel is seconds per frame; the low end,
0 or 1 sample, is where a count can leave a pixel unlit), ``sl_gt`` up to 4 passes, and VaFR uses preset
``auto`` (the other acuity curves shade about a million LP pixels whatever the image size, ~4 s a frame;
``auto`` is also the preset whose smallest ``e_max`` depends on the display, the geometry check's case).
Bounded at a few examples per renderer: < 20 s.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from data_schema.errors import UserError
from data_schema.geometry import ViewingGeometry
from renderers.catalog import resolve
from renderers.registry import available, check_geometry, render, resolve_params

W, H, BLOCK, SCENE = 48, 27, 16, "cornell"
COUNTS = {"lspp", "rspp", "max_lspp", "max_rspp", "spp"}
COUNT_CAP = 16
#: Choice parameters held to their cheap value (see the module docstring).
FIXED = {"vafr": {"preset": "auto"}}
GAZES = ((W / 2, H / 2), (1.5, 1.5), (W - 0.5, H / 2), (W / 3, H - 1.0))


@functools.lru_cache(maxsize=None)
def lit_blocks() -> np.ndarray:
    """(rows, cols) bool: the regions (16 x 16 blocks) that the ground truth shows lit in more than half."""
    gt, _ = render(SCENE, "gt", {}, W, H)
    lit = _blocks(gt.sum(axis=2) > 0, lambda b: b.mean() > 0.5)
    assert lit.sum() == 2  # the box fills the middle third of the frame
    return lit


def _blocks(mask: np.ndarray, reduce=np.any) -> np.ndarray:
    """(rows, cols): ``reduce`` over each 16 x 16 block of ``mask`` (the last ones cut at the image's edge)."""
    rows, cols = -(-H // BLOCK), -(-W // BLOCK)
    return np.array([[bool(reduce(mask[r * BLOCK:(r + 1) * BLOCK, c * BLOCK:(c + 1) * BLOCK]))
                      for c in range(cols)] for r in range(rows)])


def _ends(spec) -> tuple[float, float]:
    """The smallest and largest accepted float of ``spec``'s range (an absent end: a large finite stand-in)."""
    lo = spec.low if spec.low is not None else -1e6
    hi = spec.high if spec.high is not None else max(1.0, lo) * 1e6
    if spec.low is not None and spec.low_open:
        lo = math.nextafter(lo, math.inf)
    if spec.high is not None and spec.high_open:
        hi = math.nextafter(hi, -math.inf)
    return lo, hi


def number(spec, name: str, key: str):
    """Values of one numeric parameter: both ends, next to them, log-uniform and uniform over the range."""
    lo, hi = _ends(spec)
    if spec.type is int:
        lo, hi = math.ceil(lo), math.floor(hi)
        if key in COUNTS:
            hi = min(hi, COUNT_CAP)
        ends = st.sampled_from(sorted({lo, min(lo + 1, hi), max(hi - 1, lo), hi}))
        return st.one_of(ends, st.integers(lo, hi))
    tiny = (hi - lo) * 1e-9
    ends = st.sampled_from([lo, lo + tiny, hi - tiny, hi])
    uniform = st.floats(lo, hi, allow_nan=False)
    if lo > 0:
        loguni = st.floats(math.log(lo), math.log(hi)).map(lambda x: min(max(math.exp(x), lo), hi))
        return st.one_of(ends, loguni, uniform)
    return st.one_of(ends, st.floats(-300, math.log10(hi)).map(lambda x: min(max(10.0 ** x, lo), hi)), uniform)


def params_of(name: str):
    """A strategy of full parameter dicts of renderer ``name``: choices drawn, and one or two of the numeric
    parameters drawn from their ranges, the others at their defaults (so that each parameter's ends are reached
    with the others valid: LaFR's ``alpha`` and ``a``, each in (0, 1), must together keep ``Fa`` in (0, 1))."""
    fields, numeric = {}, {}
    for key, spec in available()[name].params.items():
        if key in FIXED.get(name, {}):
            fields[key] = st.just(FIXED[name][key])
        elif spec.type is bool:
            fields[key] = st.booleans()
        elif spec.choices:
            fields[key] = st.sampled_from(spec.choices)
        else:
            numeric[key] = number(spec, name, key)
    if not numeric:
        return st.fixed_dictionaries(fields)

    capped = {k: min(p.default, COUNT_CAP) for k, p in available()[name].params.items() if k in COUNTS}

    @st.composite
    def full(draw):
        vary = draw(st.sets(st.sampled_from(sorted(numeric)), min_size=1, max_size=2))
        return {**draw(st.fixed_dictionaries(fields)), **capped, **{k: draw(numeric[k]) for k in sorted(vary)}}
    return full()


def _sl_gt_affordable(p: dict) -> dict:
    """``sl_gt``: at most 4 passes of ``max_lspp`` nodes (cost only; every count is valid)."""
    if "max_lspp" in p and "lspp" in p:
        p = {**p, "lspp": min(p["lspp"], 4 * p["max_lspp"])}
    return p


def check_renders_something(name: str, params: dict, gaze) -> str:
    """``"refused"`` (one line, naming the parameter) or ``"rendered"`` (the frame meets the module's criteria)."""
    full = resolve_params(name, params)  # every drawn value lies in the declared range: never refused here
    geometry = ViewingGeometry.create(W, H, resolve(SCENE).camera.fov_y, gaze)
    try:
        check_geometry(name, full, geometry)
    except UserError as exc:
        msg = str(exc)
        assert "\n" not in msg and msg.startswith(f"{name}."), msg
        return "refused"
    img, stats = render(SCENE, name, full, W, H, gaze=gaze)
    assert img.shape == (H, W, 3) and np.isfinite(img).all() and float(img.min()) >= 0.0
    assert stats["shading_points"] >= 1
    dark = lit_blocks() & ~_blocks(img.sum(axis=2) > 0)
    assert not dark.any(), f"{name} {params}: {int(dark.sum())} lit region(s) left at the clear value"
    return "rendered"


@pytest.mark.parametrize("name", sorted(available()))
@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_every_accepted_parameter_value_renders_something(name, data):
    params = _sl_gt_affordable(data.draw(params_of(name), label="params"))
    check_renders_something(name, params, data.draw(st.sampled_from(GAZES), label="gaze"))


@pytest.mark.parametrize("name, params, outcome", [
    # the issue's cases (0 shading points with uninitialised radiance; an all-black image) and the ends the
    # fuzzing found, at 48 x 27 with the gaze at the centre
    ("vafr", {"e_max": 0.00625, "preset": "default"}, "refused"),  # u(e) < 80 e: just below one LP column
    ("vafr", {"e_max": 0.3, "preset": "auto"}, "refused"),  # auto's column needs e_max >= 0.57 here
    ("vafr", {"e_max": 15.0, "preset": "auto"}, "refused"),  # the ring at 15 deg: more than half the radius beyond
    ("vafr", {"e_max": 30.0, "preset": "auto"}, "rendered"),
    ("lafr", {"alpha": 1e-300}, "refused"),  # Fa <= 0: (1 - a) Z_ef^a = 0.62 > alpha
    ("lafr", {"alpha": 0.7}, "rendered"),
    ("lafr", {"a": 1e-300}, "refused"),
    ("lafr", {"beta": 10.0}, "refused"),  # the periphery folded onto the farthest corner
    ("lafr", {"delta": 8.0}, "refused"),  # 3 LP rows: a quadrant around the gaze may hold none
    ("lafr", {"delta": 6.0}, "rendered"),  # 4 rows
    ("lmfr", {"alpha": 1e-300}, "refused"),  # every LP column on the gaze itself
    ("lmfr", {"alpha": 16.0}, "rendered"),
    ("fsl", {"alpha": 2.0 ** -23}, "rendered"),  # the declared bound: ln(1 - alpha) < 0 in float32
    ("sl_as", {"max_rspp": 0}, "rendered"),  # no glossy rays (was: "max_lspp=0 is out of range" at render)
    ("gt", {"spp": 2}, "refused"),  # a square number: refused at validation, not at render
])
def test_the_ends_found_by_the_fuzzing(name, params, outcome):
    assert check_renders_something(name, params, (W / 2, H / 2)) == outcome


@pytest.mark.parametrize("name, key, value, allowed", [
    ("vafr", "e_max", 1e-300, "[0.00625, 90)"),
    ("fsl", "alpha", 1e-300, "[1.19209e-07, 1)"),
])
def test_values_below_the_derived_bounds_are_refused_by_the_declared_range(name, key, value, allowed):
    with pytest.raises(UserError) as err:
        resolve_params(name, {key: value})
    assert str(err.value) == f"{name}.{key}={value:g} is out of range: allowed {allowed}"


def test_an_empty_lp_buffer_is_refused_before_the_compiled_inverse_mapping_reads_outside_it():
    """The last guard behind the mappings' checks: the compiled kernels index the LP buffer without bounds
    checks, so a 0 x 0 buffer (what vafr e_max=1e-300 made, with radiance up to 3.8e36 from outside it) is
    refused, naming the method and its parameters."""
    import types

    from renderers.pipeline import LPLayout

    stub = types.SimpleNamespace(lp_shape=(0, 0), method="lmfr", _params_vector=lambda: np.zeros(4),
                                 params=lambda: {"delta": 16.0, "alpha": 4.0})
    with pytest.raises(UserError) as err:
        LPLayout(stub, table=False)
    assert str(err.value) == "lmfr with delta=16, alpha=4: the LP buffer is 0 x 0 pixels, with nothing to shade"
