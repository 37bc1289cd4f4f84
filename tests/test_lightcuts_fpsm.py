"""FPSM (seed 003 Eq 1-8): finite and in [0, 1] for any buffers, corrected Eq 7, edge cases, light budgets."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from data_schema.geometry import ViewingGeometry
from renderers.lightcuts import fpsm as F

H, W = 16, 24


def _buf(channels, kind, seed):
    rng = np.random.default_rng(seed)
    shape = (H, W, channels)
    if kind == "flat":
        return np.full(shape, rng.uniform(-1, 1))
    if kind == "black":
        return np.zeros(shape)
    if kind == "saturated":
        return np.full(shape, 1e6) * (rng.random(shape) > 0.5)
    return rng.normal(size=shape) * rng.uniform(0, 5)


kinds = st.sampled_from(["flat", "black", "saturated", "noise"])


@pytest.mark.parametrize("reading", F.FPSM_READINGS)
@settings(max_examples=60, deadline=None)
@given(kn=kinds, ka=kinds, kv=kinds, kl=kinds, seed=st.integers(0, 2**31), alpha=st.floats(1e-6, 1 - 1e-6),
       gx=st.floats(-10, 40), gy=st.floats(-10, 30), fov=st.floats(10, 120))
def test_fpsm_finite_and_in_unit_interval(reading, kn, ka, kv, kl, seed, alpha, gx, gy, fov):
    ecc = F.eccentricity_map(ViewingGeometry.create(W, H, fov, (gx, gy)))
    low = np.abs(_buf(3, kl, seed + 3))[: H // 8 + 1, : W // 8 + 1]
    m = F.build_fpsm(ecc, _buf(3, kn, seed), _buf(3, ka, seed + 1), _buf(2, kv, seed + 2), low, alpha,
                     reading=reading)
    assert m.reading == reading
    for name in ("fb_f", "fb_st", "fb_l", "map"):
        x = getattr(m, name)
        assert x.shape == (H, W) and np.all(np.isfinite(x)) and x.min() >= 0 and x.max() <= 1, name
    assert np.all((m.rho >= 0) & ~np.isnan(m.rho))
    assert np.all(m.fb_st >= m.fb_f) and np.all(m.fb_l >= m.fb_f)
    # the map is 0 exactly where the feature is below the threshold (rho unbounded)
    assert np.all(m.map[np.isinf(m.rho)] == 0)
    assert np.all(F.light_budget(m.map, 48) >= 1) and np.all(F.light_budget(m.map, 48) <= 48)


@settings(max_examples=60)
@given(st_=arrays(np.float64, (8, 9), elements=st.floats(0, 1)), lu=arrays(np.float64, (8, 9),
       elements=st.floats(0, 1)), alpha=st.floats(0.001, 0.999))
def test_corrected_eq7_solves_eq5_equals_eq6(st_, lu, alpha):
    rho = F.rho_map(st_, lu, alpha)
    d = (st_ - F.gaussian5(st_)) ** 2 + (lu - F.gaussian5(lu)) ** 2
    m = np.maximum(st_, lu)
    ok = np.isfinite(rho) & (rho > 0)
    # Eq 6 with the returned rho equals Eq 5 (M - alpha)
    np.testing.assert_allclose(np.exp(-d[ok] / (2 * rho[ok] ** 2)), m[ok] - alpha, rtol=1e-9, atol=1e-300)
    assert np.all(np.isinf(rho[m <= alpha]))
    assert np.all(rho[(m > alpha) & (d == 0)] == 0)
    mp = F.normalise_rho(rho)
    assert np.all(np.isfinite(mp)) and mp.min() >= 0 and mp.max() <= 1


features = arrays(np.float64, (8, 9), elements=st.floats(0, 1))


@settings(max_examples=60)
@given(st_=features, lu=features, alpha=st.floats(0.001, 0.999))
def test_blur_reading_is_eq4_maximum_and_reciprocal_of_derived(st_, lu, alpha):
    rho = F.rho_map(st_, lu, alpha, "blur")
    d = (st_ - F.gaussian5(st_)) ** 2 + (lu - F.gaussian5(lu)) ** 2
    d = np.where(d > F.D_TOL, d, 0.0)
    m = np.maximum(st_, lu)
    ok = np.isfinite(rho)
    # G(rho) = exp(-rho^2 D / 2) falls with rho: the largest rho with M - G <= alpha has G = M - alpha (Eq 5)
    np.testing.assert_allclose(np.exp(-rho[ok] ** 2 * d[ok] / 2), m[ok] - alpha, rtol=1e-9, atol=1e-300)
    g_wider = np.exp(-(1.01 * rho[ok]) ** 2 * d[ok] / 2)
    assert np.all(m[ok] - g_wider > alpha - 1e-12)  # a wider filter breaks Eq 4's constraint
    np.testing.assert_array_equal(ok, (m > alpha) & (d > 0))
    der = F.rho_map(st_, lu, alpha, "derived")
    both = ok & (der > 0)
    np.testing.assert_allclose(rho[both] * der[both], 1.0, rtol=1e-9)
    rho2, mp = F.fpsm_map(st_, lu, alpha, "blur")
    np.testing.assert_array_equal(rho2, rho)
    assert np.all(np.isfinite(mp)) and mp.min() >= 0 and mp.max() <= 1 and np.all(mp[~ok] == 0)


@settings(max_examples=60)
@given(st_=features, lu=features, alpha=st.floats(0.001, 0.998))
def test_retained_reading_is_eq5_feature_over_its_range(st_, lu, alpha):
    rho, mp = F.fpsm_map(st_, lu, alpha, "retained")
    m = np.maximum(st_, lu)
    np.testing.assert_allclose(mp, np.clip((m - alpha) / (1 - alpha), 0, 1), rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(rho, F.rho_map(st_, lu, alpha, "derived"))  # kept for comparison
    # more tolerance (larger alpha) never asks for more samples; a saturated feature always gets the maximum
    assert np.all(F.fpsm_map(st_, lu, min(alpha + 0.001, 0.999), "retained")[1] <= mp)
    assert np.all(mp[m == 1.0] == 1.0) and np.all(mp[m <= alpha] == 0.0)
    with pytest.raises(ValueError, match="no rho"):
        F.rho_map(st_, lu, alpha, "retained")


def _spot_in_the_periphery(fov):
    """Acuity-only features of a 96 x 64 view plus a 3 x 3 spot of full luminance contrast near a corner."""
    fb_f = F.acuity_map(F.eccentricity_map(ViewingGeometry.create(96, 64, fov)))
    lu = fb_f.copy()
    lu[2:5, 2:5] = 1.0
    return fb_f, lu


def test_high_contrast_periphery_keeps_samples_under_the_alternatives():
    fb_f, lu = _spot_in_the_periphery(40.0)
    assert fb_f[3, 3] == F.ACUITY_FLOOR and fb_f[32, 48] == 1.0  # the spot lies where acuity is at its floor
    b = {r: F.light_budget(F.fpsm_map(fb_f, lu, 0.1, r)[1], 48) for r in F.FPSM_READINGS}
    # derived: the spot's pixels with the largest local deviation D have the largest rho, which Eq 8 maps to
    # 0 -> one sample (the corners of the spot), its centre 27
    np.testing.assert_array_equal(b["derived"][2:5, 2:5], [[1, 12, 1], [12, 27, 12], [1, 12, 1]])
    # blur (rho falls with D and M) and retained (M = 1) give every pixel of the spot the maximum
    assert np.all(b["blur"][2:5, 2:5] == 48) and np.all(b["retained"][2:5, 2:5] == 48)
    # all three leave the flat periphery (M <= alpha) at one sample ...
    assert b["derived"][60, 90] == b["blur"][60, 90] == b["retained"][60, 90] == 1
    # ... and differ in the flat fovea (fb_f = 1, D = 0): rho_derived = 0 -> maximum; no blur reduces a flat
    # feature -> rho_blur unbounded -> one sample; retained: M - alpha = 1 - alpha -> maximum
    assert b["derived"][32, 48] == 48 and b["blur"][32, 48] == 1 and b["retained"][32, 48] == 48


def test_unknown_reading_is_a_one_line_error():
    with pytest.raises(ValueError, match="fpsm_reading='literal' is invalid: allowed derived, blur, retained"):
        F.fpsm_map(np.zeros((4, 4)), np.zeros((4, 4)), 0.1, "literal")


def test_normalise_rho_edge_cases():
    np.testing.assert_array_equal(F.normalise_rho(np.full((3, 3), 0.7)), np.ones((3, 3)))  # rho_max = rho_min
    np.testing.assert_array_equal(F.normalise_rho(np.full((2, 2), np.inf)), np.zeros((2, 2)))
    np.testing.assert_allclose(F.normalise_rho([0.0, 1.0, 0.25, np.inf]), [1.0, 0.0, 0.75, 0.0])
    with pytest.raises(ValueError, match="rho"):
        F.normalise_rho([np.nan, 1.0])


def test_acuity_eq2_values():
    e = np.radians([0.0, 4.0, 10.0, 30.0])
    expect = np.clip(1.1715 - 2.45 * e, 0.02, 1)
    np.testing.assert_allclose(F.acuity_map(e), expect)
    assert F.acuity_map(0.0) == 1.0 and F.acuity_map(math.radians(27.0)) == 0.02
    # full acuity ends where 1.1715 - 2.45 e = 1
    assert F.acuity_map((1.1715 - 1) / 2.45 - 1e-9) == 1.0 and F.acuity_map((1.1715 - 1) / 2.45 + 1e-3) < 1


def test_gradient_feature_is_sobel_over_eight():
    ramp = np.tile(np.arange(10.0) * 0.1, (6, 1))  # slope 0.1 per pixel along x
    g = F.gradient_feature(ramp)
    np.testing.assert_allclose(g[:, 1:-1], 0.1)
    step = np.zeros((6, 10))
    step[:, 5:] = 1.0
    np.testing.assert_allclose(F.gradient_feature(step)[:, 4:6], 0.5)  # 4/8 at a unit step
    assert F.gradient_feature(step * 100).max() == 1.0


def test_flat_image_has_no_luminance_contrast():
    c = F.luminance_contrast(np.full((4, 6, 3), 0.3), (32, 48))
    np.testing.assert_allclose(c, 0.0, atol=1e-12)
    c = F.luminance_contrast(np.zeros((4, 6, 3)), (32, 48))
    assert np.all(c == 0)
    rng = np.random.default_rng(2)
    c = F.luminance_contrast(rng.random((4, 6, 3)), (32, 48))
    assert c.max() > 0.05 and c.max() <= 1


def test_laplacian_pyramid_reconstructs():
    img = np.random.default_rng(0).random((32, 40))
    lp = F.laplacian_pyramid(img, 3)
    assert [x.shape for x in lp] == [(32, 40), (16, 20), (8, 10)]
    up = lp[2]
    for band in (lp[1], lp[0]):
        up = band + F._resize(up, band.shape, 1)
    np.testing.assert_allclose(up, img, atol=1e-12)


def test_screen_velocity_of_a_camera_translation():
    pts = np.array([[[0.0, 0.0, -5.0]]])
    ident = np.eye(4)
    shifted = np.eye(4)
    shifted[0, 3] = 0.1  # previous camera saw x shifted by +0.1 in clip space
    v = F.screen_velocity(pts, ident @ np.diag([1, 1, 1, 1.0]), shifted, 100, 50)
    # w = 1 for an identity "projection": ndc x moved from 0.1 to 0 -> -0.1 * 100 / 2 pixels
    np.testing.assert_allclose(v[0, 0], [-5.0, 0.0])


def test_fovea_gets_full_budget_and_flat_periphery_least():
    # 96 x 64 pixels, 40° vertical field: the fovea (4°) is ~6 px wide, the corners are at ~33° (floor 0.02)
    ecc = F.eccentricity_map(ViewingGeometry.create(96, 64, 40.0))
    n = np.zeros((64, 96, 3))
    n[..., 2] = 1
    m = F.build_fpsm(ecc, n, np.full(n.shape, 0.5), np.zeros((64, 96, 2)), np.full((8, 12, 3), 0.2), 0.1)
    assert m.map[32, 48] == 1.0 and m.map[0, 0] == 0.0 and np.isinf(m.rho[0, 0])
    b = F.light_budget(m.map, 48)
    assert b[32, 48] == 48 and b[0, 0] == 1


@pytest.mark.parametrize("alpha", [0, 1, -0.1, 1.5, float("nan"), "x"])
def test_alpha_outside_unit_interval(alpha):
    with pytest.raises(ValueError, match="alpha"):
        F.rho_map(np.zeros((4, 4)), np.zeros((4, 4)), alpha)


@pytest.mark.parametrize("mx", [0, -3, 2.5, True])
def test_max_lspp_must_be_positive(mx):
    with pytest.raises(ValueError, match="max_lspp"):
        F.light_budget(np.zeros((2, 2)), mx)


def test_nan_buffers_rejected():
    with pytest.raises(ValueError, match="buffer must be finite"):
        F.gradient_feature(np.full((4, 4), np.nan))
