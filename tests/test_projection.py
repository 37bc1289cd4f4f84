"""The camera projection in one home (renderers/projection.py, issue 27 item 2): screen <-> image plane round
trips, the GPU's uniforms come from it, and no other renderer module writes tan(fov/2) again."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
from hypothesis import given, strategies as st

from renderers.projection import camera_rays, plane_to_screen, screen_to_plane, tan_half_fov, view_projection
from renderers.scene import Camera

ROOT = Path(__file__).resolve().parents[1]


@given(w=st.integers(1, 8000), h=st.integers(1, 8000), fov=st.floats(1.0, 170.0),
       fx=st.floats(0.0, 1.0), fy=st.floats(0.0, 1.0))
def test_a_screen_position_comes_back_from_the_image_plane(w, h, fov, fx, fy):
    t = tan_half_fov(Camera(fov_y=fov))
    assert t == math.tan(math.radians(fov) / 2.0)
    sx, sy = screen_to_plane(fx * w, fy * h, w, h, t)
    assert abs(sy) <= t * (1 + 1e-12) and abs(sx) <= t * w / h * (1 + 1e-12)  # inside the field of view
    x, y = plane_to_screen(sx, sy, w, h, t)
    assert abs(x - fx * w) <= 1e-9 * (w + h) and abs(y - fy * h) <= 1e-9 * (w + h)


def test_the_centre_ray_is_the_view_direction_and_the_matrix_maps_rays_back():
    cam = Camera(position=(1.0, 2.0, 3.0), look_at=(4.0, 2.5, -1.0), fov_y=50.0)
    f, _, _ = cam.basis()
    assert np.allclose(camera_rays(cam, 64, 48, 32.0, 24.0)[0], f / np.linalg.norm(f))
    x, y = np.array([0.5, 63.5, 10.0]), np.array([0.5, 47.5, 30.0])
    p = np.asarray(cam.position) + 7.0 * camera_rays(cam, 64, 48, x, y)
    c = np.c_[p, np.ones(3)] @ view_projection(cam, 64, 48).T
    assert np.allclose((c[:, 0] / c[:, 3] + 1) * 32, x) and np.allclose((1 - c[:, 1] / c[:, 3]) * 24, y)


def test_the_gpu_uniforms_take_the_projection_from_the_same_module():
    from renderers.gpu.upload import camera_uniforms

    cam = Camera(fov_y=73.0)
    assert camera_uniforms(cam, 320, 240)["u_tan"] == tan_half_fov(cam)


def test_no_other_renderer_module_writes_the_projection_again():
    pattern = re.compile(r"tan\(\s*(math|np)\.(radians|deg2rad)\([^)]*fov")
    found = [str(p.relative_to(ROOT)) for p in (ROOT / "renderers").rglob("*.py")
             if p.name != "projection.py" and pattern.search(p.read_text(encoding="utf-8"))]
    assert not found, f"tan(fov/2) written outside renderers/projection.py: {found}"
