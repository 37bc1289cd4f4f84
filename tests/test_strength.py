"""A continuous foveation strength for every foveated renderer (issue 28 item 1).

Each foveated plug-in declares its strength parameter and direction once (``RendererPlugin.strength``), read by
:func:`renderers.registry.foveation_strength`; VaFR's is the new ``acuity_scale`` (seed 001 Eq 2's MAR slope
divided by it). Property tests (hypothesis, small CPU renders): the declared work count never increases as
foveation gets stronger, over the declared range.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from data_schema.errors import UserError
from renderers.foveation import DEFAULT_PIVOTS, PRESETS, make_mapping
from renderers.foveation.acuity import scale_falloff
from renderers.registry import available, check_geometry, foveation_strength, render
from studyapp.cli import main

DECLARED = {"vafr": ("acuity_scale", "lower", "rays_primary"), "lafr": ("delta", "higher", "rays_primary"),
            "lmfr": ("delta", "higher", "rays_primary"), "fsl": ("alpha", "higher", "light_samples"),
            "sl": ("lspp", "lower", "light_samples"), "sl_e": ("lspp", "lower", "light_samples"),
            "sl_f": ("lspp", "lower", "light_samples"), "sl_p": ("lspp", "lower", "light_samples"),
            "sl_as": ("max_lspp", "lower", "light_samples"), "gt": None, "sl_gt": None}
FOVEATED = sorted(k for k, v in DECLARED.items() if v is not None)
#: The renderers rendered by the property test: sl_e, sl_f and sl_p are sl under other names (same parameters,
#: same defaults, same code), their declarations are checked above.
RENDERED = [k for k in FOVEATED if k not in ("sl_e", "sl_f", "sl_p")]


def test_every_renderer_declares_its_strength():
    assert set(available()) == set(DECLARED)
    for name, want in DECLARED.items():
        spec = foveation_strength(name)
        if want is None:
            assert spec is None, name
            continue
        assert (spec.param, spec.stronger, spec.count) == want, name
        param = available()[name].params[spec.param]
        assert spec.range == param.range and spec.default == param.default
    assert foveation_strength("vafr").range.describe() == "[0.05, 2]"
    assert foveation_strength("vafr").weakest_first([0.1, 2.0, 1.0]) == [2.0, 1.0, 0.1]
    assert foveation_strength("lafr").weakest_first([4.0, 1.5]) == [1.5, 4.0]
    assert foveation_strength("fsl").stronger_than(0.5, 0.1) and not foveation_strength("sl").stronger_than(9, 8)
    with pytest.raises(UserError, match="renderer='nope' is unknown"):
        foveation_strength("nope")


def test_acuity_scale_one_is_the_seed_curve_and_below_one_lowers_the_periphery():
    assert scale_falloff(DEFAULT_PIVOTS, 1.0) == DEFAULT_PIVOTS
    seed = make_mapping("vafr", 1920, 1080, 90.0)
    one = make_mapping("vafr", 1920, 1080, 90.0, acuity_scale=1.0)
    assert np.array_equal(seed.acuity.params_vector(), one.acuity.params_vector())
    assert one.shading_points == 1_061_630
    # Eq 2 with m / s: omega_s(e) = omega_0 + (omega(e) - omega_0) / s; at 10 deg, s = 0.5: 0.025 + 0.075 * 2
    half = scale_falloff(DEFAULT_PIVOTS, 0.5)
    assert half[0] == (0.0, 40.0) and half[1][1] == pytest.approx(1 / 0.175, rel=1e-12)
    m = make_mapping("vafr", 1920, 1080, 90.0, acuity_scale=0.5)
    e = np.array([0.0, 5.0, 10.0, 30.0, 59.0])
    f0, f1 = seed.acuity.acuity(e), m.acuity.acuity(e)
    assert f1[0] == pytest.approx(40.0) and np.all(f1[1:] < f0[1:])
    # the shading-point count of every scale, the same on any display (the seed's constant LP buffer)
    for s, n in ((2.0, 2_970_617), (0.5, 346_289), (0.05, 6_114)):
        assert make_mapping("vafr", 1920, 1080, 90.0, acuity_scale=s).shading_points == n
        assert make_mapping("vafr", 480, 270, 60.0, acuity_scale=s).shading_points == n


def test_acuity_scale_out_of_range_is_one_line():
    with pytest.raises(UserError, match=r"vafr.acuity_scale=0.04 is out of range: allowed \[0.05, 2\]"):
        render("cornell", "vafr", {"acuity_scale": 0.04}, 16, 9)


def test_render_reports_the_shading_points_of_every_scale():
    _, st1 = render("cornell", "vafr", {"acuity_scale": 0.05}, 48, 27)
    _, st2 = render("cornell", "vafr", {"acuity_scale": 0.1}, 48, 27)
    assert st1["lp_pixels"] == 6_114 and st2["lp_pixels"] == 21_148
    assert st1["params"]["acuity_scale"] == 0.05
    assert 0 < st1["shading_points"] <= st1["rays_primary"] < st2["rays_primary"]


def _pair(spec):
    """Two values of ``spec``'s declared range: its ends, log-uniform over it, (integers) uniform."""
    rng = spec.range
    lo = math.nextafter(rng.low, math.inf) if rng.low_open else rng.low
    hi = math.nextafter(rng.high, -math.inf) if rng.high_open else rng.high
    if rng.integer:
        lo, hi = int(lo), int(hi)
        loguni = st.floats(math.log(lo), math.log(hi)).map(lambda x: min(max(round(math.exp(x)), lo), hi))
        one = st.one_of(st.sampled_from([lo, lo + 1, hi - 1, hi]), loguni, st.integers(lo, hi))
    else:
        one = st.one_of(st.sampled_from([lo, hi]),
                        st.floats(math.log(lo), math.log(hi)).map(lambda x: min(max(math.exp(x), lo), hi)))
    return st.tuples(one, one)


@settings(max_examples=25, deadline=None)
@given(data=st.data(), preset=st.sampled_from(sorted(PRESETS)),
       display=st.sampled_from([(1920, 1080, 90.0), (64, 36, 90.0), (480, 270, 40.0)]))
def test_vafr_shading_points_never_increase_with_strength(data, preset, display):
    """The seed's count, the LP pixels of the semi-ellipse (Fig 4), over the whole declared range, every preset."""
    spec = foveation_strength("vafr")
    a, b = sorted(data.draw(_pair(spec)))  # a is the stronger (lower) scale
    n = [make_mapping("vafr", *display, preset=preset, acuity_scale=s).shading_points for s in (a, b)]
    assert n[0] <= n[1], (a, b, n)


#: Image sizes: log-polar renderers at 96 x 54 (LaFR/LMFR ``delta`` up to 13.5 keeps their 4 LP rows); the
#: lightcuts ones at 16 x 9 (4096 samples per pixel in about half a second). VaFR renders with preset ``auto``
#: (the others trace about a million LP pixels whatever the size; their count is the mapping's, tested above).
SIZE = {"lafr": (96, 54), "lmfr": (96, 54), "vafr": (96, 54)}
FIXED = {"vafr": {"preset": "auto"}}


@pytest.mark.parametrize("name", RENDERED)
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(data=st.data())
def test_work_never_increases_as_foveation_gets_stronger(name, data):
    spec = foveation_strength(name)
    w, h = SIZE.get(name, (16, 9))
    weak, strong = spec.weakest_first(data.draw(_pair(spec)))
    gaze = (data.draw(st.floats(0.5, w - 0.5)), data.draw(st.floats(0.5, h - 0.5)))
    counts = []
    for value in (weak, strong):
        params = {**FIXED.get(name, {}), spec.param: value}
        try:
            _, stats = render("cornell", name, params, w, h, gaze=gaze)
        except UserError as exc:  # a buffer too coarse for this display: refused at validation, one line
            assert f"{name}.{spec.param}=" in str(exc) and "\n" not in str(exc)
            assume(False)
        counts.append(stats[spec.count])
    assert counts[1] <= counts[0], (name, spec.param, weak, strong, counts)
    assert counts[1] > 0


def test_gpu_honours_acuity_scale():
    """The GPU backend reads the same mapping (its LP tables are keyed by the mapping parameters): same counts,
    the same image to >= 35 dB, and a different one from the seed's curve."""
    from renderers.gpu import render as gpu_render
    from renderers.gpu.agreement import agreement

    a, sa = render("cornell", "vafr", {"acuity_scale": 0.1}, 64, 48)
    b, sb = gpu_render("cornell", "vafr", {"acuity_scale": 0.1}, 64, 48)
    psnr, within = agreement(a, b)
    assert psnr >= 35.0 and within >= 0.99, (psnr, within)
    for k in ("lp_pixels", "rays_primary", "shading_points"):
        assert sb[k] == sa[k], k
    assert sa["lp_pixels"] == 21_148
    seed, _ = gpu_render("cornell", "vafr", {}, 64, 48)
    assert agreement(seed, b)[0] < 30.0


def test_renderers_command_shows_the_strength(capsys):
    assert main(["renderers"]) == 0
    out = capsys.readouterr().out
    assert ("vafr: visual-acuity-consistent" in out and "    foveation strength: acuity_scale (stronger = lower, "
            "allowed [0.05, 2], default 1); lowers rays_primary" in out)
    assert "    foveation strength: delta (stronger = higher, allowed (1, 16], default 1.8); lowers rays_primary" in out
    assert "    acuity_scale (float, default 1.0; allowed [0.05, 2])" in out
    assert out.count("    foveation strength: none") == 2
