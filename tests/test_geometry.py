"""The one viewing geometry (data_schema.geometry): pixels <-> degrees, the display's visual angle."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from data_schema.errors import UserError
from data_schema.geometry import Display, ViewingGeometry, fov_from_size


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
