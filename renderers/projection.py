"""The pinhole camera's projection, in one place: screen positions <-> rays and the world -> clip matrix.

A camera (:class:`~renderers.scene.Camera`) with vertical field of view ``fov_y`` and basis ``(f, r, u)``
(forward, right, up) shoots the ray

    ``d = f + sx r + sy u``, ``sx = (2x/H - W/H) t``, ``sy = (1 - 2y/H) t``, ``t = tan(fov_y / 2)``

through the screen position ``(x, y)`` (pixels, y down) of a ``W x H`` image; the c_r of seed 001 Eq 3 is
``2 t / H``. The CPU tracer, the pipelines (reprojection), the lightcuts renderers (velocity buffer, FPSM) and the
GPU backend all take it from here. :func:`plane_offsets` and :func:`ray_direction` (the ray of a screen position)
and :func:`plane_to_screen` are written for scalars as well as arrays, so that ``renderers/gpu/codegen.py``
translates them for the GPU (``projection_gen.glsl``: the camera rays of ``camera.glsl`` in float64, the
reprojection's screen positions in float32). The expressions keep their order of operations: the backends' rays
must agree bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["camera_rays", "plane_offsets", "plane_to_screen", "ray_direction", "screen_to_plane", "tan_half_fov",
           "view_projection"]
#: The functions translated into GLSL (renderers/gpu/codegen.py projection_glsl), by precision.
GLSL_DOUBLE_ROOTS = ("plane_offsets", "ray_direction")
GLSL_FLOAT_ROOTS = ("plane_to_screen",)


def tan_half_fov(camera) -> float:
    """``t = tan(fov_y / 2)`` of ``camera`` (``fov_y`` in degrees): the half-height of the image plane at
    distance 1."""
    return math.tan(math.radians(camera.fov_y) / 2.0)


def screen_to_plane(x, y, width: int, height: int, t: float) -> tuple[np.ndarray, np.ndarray]:
    """The image-plane offsets ``(sx, sy)`` (along ``r`` and ``u``, at distance 1) of screen positions ``(x, y)``:
    ``sx = (2x/H - W/H) t``, ``sy = (1 - 2y/H) t``, in float64."""
    return plane_offsets(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64), width, height, t)


def plane_offsets(x, y, width, height, t):
    """:func:`screen_to_plane` of float64 scalars or arrays ``x``, ``y``."""
    return (2.0 * x / height - width / height) * t, (1.0 - 2.0 * y / height) * t


def ray_direction(fx, fy, fz, rx, ry, rz, ux, uy, uz, sx, sy):
    """The unit direction of ``d = f + sx r + sy u`` (camera basis ``f, r, u``), scalars or arrays ``sx, sy``:
    ``d / sqrt((dx^2 + dy^2) + dz^2)``, the rounding of ``np.linalg.norm``."""
    dx = fx + sx * rx + sy * ux
    dy = fy + sx * ry + sy * uy
    dz = fz + sx * rz + sy * uz
    norm = np.sqrt(dx * dx + dy * dy + dz * dz)
    return dx / norm, dy / norm, dz / norm


def plane_to_screen(sx, sy, width: int, height: int, t: float) -> tuple[np.ndarray, np.ndarray]:
    """The screen positions ``(x, y)`` of image-plane offsets ``(sx, sy)``: the inverse of
    :func:`screen_to_plane`, ``x = (sx/t + W/H) H/2``, ``y = (1 - sy/t) H/2``."""
    return (sx / t + width / height) * height / 2.0, (1.0 - sy / t) * height / 2.0


def camera_rays(camera, width: int, height: int, x, y) -> np.ndarray:
    """Unit float64 directions of the pinhole rays through screen positions ``(x, y)`` (pixels, y down).

    ``d = f + (2x/W - 1) tan(fov/2) (W/H) r + (1 - 2y/H) tan(fov/2) u``: the ray of screen position ``(x, y)`` of a
    display whose vertical field of view is ``fov_y`` (the c_r of seed 001 Eq 3 is ``2 tan(fov/2) / H``).
    """
    f, r, u = camera.basis()
    sx, sy = screen_to_plane(x, y, width, height, tan_half_fov(camera))
    return np.stack(ray_direction(*f, *r, *u, sx.reshape(-1), sy.reshape(-1)), axis=1)


def view_projection(camera, width: int, height: int) -> np.ndarray:
    """World -> clip matrix (4x4, column vectors) of the pinhole camera (:func:`camera_rays`).

    With ``v = p - eye`` and the camera basis ``(f, r, u)``: ``clip = (r.v / (t a), u.v / t, 0, f.v)``,
    ``t = tan(fov_y / 2)``, ``a = width / height``, so ``x = (ndc_x + 1) w / 2`` and ``y = (1 - ndc_y) h / 2`` are
    the screen position whose ray :func:`camera_rays` shoots through ``p``.
    """
    f, r, u = camera.basis()
    e = np.asarray(camera.position, dtype=np.float64)
    t = tan_half_fov(camera)
    a = width / height
    m = np.zeros((4, 4))
    m[0, :3], m[0, 3] = r / (t * a), -(r @ e) / (t * a)
    m[1, :3], m[1, 3] = u / t, -(u @ e) / t
    m[3, :3], m[3, 3] = f, -(f @ e)
    return m
