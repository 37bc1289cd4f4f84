"""The one viewing geometry (data_schema.geometry): pixels <-> degrees, the display's visual angle."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from data_schema.errors import UserError
from data_schema.geometry import Display, ViewingGeometry, fov_from_size, scaled_size


@given(st.integers(16, 4000), st.integers(16, 4000), st.floats(1.0, 200.0), st.floats(5.0, 300.0))
def test_display_visual_angle_and_ppd_follow_from_its_size(w, h, width_cm, distance_cm):
    d = Display(w, h, width_cm, distance_cm)
    height_cm = width_cm * h / w
    assert d.fov_y_deg == pytest.approx(2 * math.degrees(math.atan(height_cm / 2 / distance_cm)), rel=1e-12)
    assert d.ppd == pytest.approx(w / width_cm * distance_cm * math.tan(math.radians(1.0)), rel=1e-9)
    assert d.geometry().c_r == pytest.approx(width_cm / w / distance_cm, rel=1e-9)  # pixel size / distance


@given(st.integers(0, 63), st.integers(0, 47))
def test_eccentricity_from_the_centre_is_the_angle_between_the_rays(x, y):
    """Seed 001 Eq 3 with the gaze at the display centre is the exact angle seen by an eye in front of it."""
    d = Display(64, 48, 32.0, 40.0)
    e = d.geometry().eccentricity_map()
    s = 32.0 / 64
    p = np.array([(x + 0.5 - 32) * s, (y + 0.5 - 24) * s, 40.0])
    want = math.degrees(math.acos(40.0 / np.linalg.norm(p)))
    assert e[y, x] == pytest.approx(want, abs=1e-9)


@given(st.integers(16, 3000), st.integers(16, 3000), st.floats(1.0, 170.0), st.floats(0.05, 1.0))
def test_a_smaller_render_subtends_the_same_angle(w, h, fov, scale):
    g = ViewingGeometry.create(w, h, fov, (0.3 * w, 0.6 * h))
    s = g.scaled(scale)
    assert s.fov_y_deg == g.fov_y_deg
    assert s.gaze_x / s.width == pytest.approx(0.3) and s.gaze_y / s.height == pytest.approx(0.6)
    # the same eccentricity lies at the same fraction of the height
    assert s.radius(5.0) / s.height == pytest.approx(g.radius(5.0) / g.height, rel=1e-12)


def test_fov_from_size_of_the_seed_replications():
    # 53 cm x 29.8 cm at 45 cm: the shipped protocols' 36.6 degrees
    assert fov_from_size(53.0 * 1080 / 1920, 45.0) == pytest.approx(36.65, abs=0.01)


def test_region_masks_are_the_fovea_circle_counted_by_hand():
    # c_r = 2 tan 45 / 100 = 0.02; r = tan 5 deg / 0.02 = 4.3744 px from the corner (0, 0): 15 pixel centres
    # (columns 0-2 take rows 0-3, column 3 rows 0-2). The masks partition the image.
    m = ViewingGeometry.create(100, 100, 90.0, (0.0, 0.0)).region_masks(5.0)
    assert int(m.fovea.sum()) == 15 and m.fovea[:4, :4].sum() == 15 and not m.fovea[3, 3]
    np.testing.assert_array_equal(m.periphery, ~m.fovea)
    with pytest.raises(UserError, match=r"fovea_deg=90 is out of range: allowed \(0, 90\)"):
        ViewingGeometry.create(8, 8, 90.0).region_masks(90.0)


def test_a_render_clamped_at_a_small_scale_keeps_its_aspect_ratio():
    """seed003's 256x144 stimuli at --scale 0.05 / 0.1 rendered 16x16 / 26x16 (each side clamped to 16 px on its
    own), so a window fitting the image pillarboxed it while the live views covered the window. Now both sides
    are scaled together: 32x18, exactly 16:9, which fills a 1920x1080 window either way."""
    g = ViewingGeometry.create(256, 144, 36.7, (128.0, 72.0))
    for scale in (0.05, 0.1):
        s = g.scaled(scale)
        assert (s.width, s.height) == (32, 18)
        assert s.width * 1080 == s.height * 1920  # the fitted rectangle is the whole window
        assert (s.gaze_x, s.gaze_y) == (16.0, 9.0)
    assert (g.scaled(0.25).width, g.scaled(0.25).height) == (64, 36)  # above the floor: unchanged
    assert scaled_size(1366, 768, 0.01) == (28, 16)  # no small exact 683:384 size: the floor's factor, rounded
    assert scaled_size(16, 3000, 0.05) == (16, 3000)  # the floor would need more than the full size
    assert scaled_size(10, 8, 0.5) == (10, 8)


@given(st.integers(1, 4000), st.integers(1, 4000), st.floats(0.001, 1.0))
def test_a_scaled_size_keeps_the_floor_and_the_aspect_ratio(w, h, scale):
    sw, sh = scaled_size(w, h, scale)
    assert sw <= w and sh <= h
    assert min(sw, sh) >= min(16, w, h)
    if min(round(w * scale), round(h * scale)) < 16 and min(w, h) > 16:  # clamped: one factor for both sides
        assert abs(sw * h - sh * w) <= 0.5 * (w + h)  # each side within half a pixel of f * side
