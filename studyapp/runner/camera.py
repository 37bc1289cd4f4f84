"""Camera poses of a protocol's stimuli: the camera path's keyframes at a frame or a time, offsets turned into
the renderer's ``look_at``, the display's visual angle on every frame, the poses a live stimulus samples, and
whether a pose has a camera basis (the one place that knows them; the stimulus builder, the live loop, the
simulated observer and the protocol's validation all ask here). The protocol is passed in, never imported:
``protocol.py`` asks here when it validates live poses."""

from __future__ import annotations

import itertools
import math

import numpy as np


def camera_at(protocol, frame: int) -> dict | None:
    """Camera keyframe interpolated linearly at ``t = frame / (n_frames - 1)`` (None: the scene's camera)."""
    n = protocol.n_frames
    return path_camera(protocol, 0.0 if n <= 1 else frame / (n - 1))


def path_camera(protocol, t: float) -> dict | None:
    """The camera path's keyframes interpolated linearly at ``t`` in [0, 1] (None: the scene's camera)."""
    path = sorted(protocol.camera_path, key=lambda k: k["t"])
    if not path:
        return None
    keys = [k for k in path[0] if k != "t"]
    if t <= path[0]["t"]:
        return {k: path[0][k] for k in keys}
    for a, b in itertools.pairwise(path):
        if a["t"] <= t <= b["t"]:
            w = 0.0 if b["t"] == a["t"] else (t - a["t"]) / (b["t"] - a["t"])
            out = {}
            for k in keys:
                va, vb = a.get(k), b.get(k, a.get(k))
                if isinstance(va, list):
                    out[k] = [x + w * (y - x) for x, y in zip(va, vb)]
                elif va is not None:
                    out[k] = va + w * (vb - va)
            return out
    return {k: path[-1][k] for k in keys if k in path[-1]}


def frame_camera(protocol, scene: str, frame: int) -> dict:
    """The renderer's camera of ``frame``: the display's vertical visual angle (``fov_y``; the scene's own
    field of view never applies to a study's stimuli), the camera path's pose, and the previous frame's camera
    under ``previous`` (frames after the first of a moving sequence) for screen-space velocity."""
    fov = {"fov_y": protocol.display.fov_y_deg}
    cam = {**(absolute_camera(protocol.scene_ref(scene), camera_at(protocol, frame)) or {}), **fov}
    if frame == 0:
        return cam
    prev = {**(absolute_camera(protocol.scene_ref(scene), camera_at(protocol, frame - 1)) or {}), **fov}
    return cam if prev == cam else {**cam, "previous": prev}


def absolute_camera(scene: str, camera: dict | None) -> dict | None:
    """Turn ``yaw_deg``/``pitch_deg`` offsets into the renderer's ``look_at`` for the scene's own camera.

    Yaw turns the view direction about the camera's up vector, pitch about its right vector; the position
    stays. Keys ``position``/``look_at`` pass through unchanged.
    """
    if not camera or not ({"yaw_deg", "pitch_deg"} & set(camera)):
        return camera
    from renderers.catalog import resolve

    cam = resolve(scene).camera
    f, r, u = cam.basis()
    pos = np.asarray(camera.get("position", cam.position), dtype=np.float64)
    dist = float(np.linalg.norm(np.subtract(cam.look_at, cam.position)))
    yaw, pitch = math.radians(camera.get("yaw_deg", 0.0)), math.radians(camera.get("pitch_deg", 0.0))
    d = math.cos(pitch) * (math.cos(yaw) * f + math.sin(yaw) * r) + math.sin(pitch) * u
    out = {k: v for k, v in camera.items() if k not in ("yaw_deg", "pitch_deg")}
    out["position"] = [float(x) for x in pos]
    out["look_at"] = [float(x) for x in pos + dist * d]
    return out


#: Poses a live stimulus samples along its camera path (:class:`~studyapp.runner.live.PathMotion` interpolates
#: linearly between them).
PATH_SAMPLES = 64


def path_samples(protocol, scene: str) -> tuple[tuple[float, tuple, tuple], ...]:
    """The camera path of a live ``protocol`` in ``scene`` as the runner follows it: :data:`PATH_SAMPLES`
    ``(t, position, look_at)``, ``t`` in [0, 1] (the scene's camera where the path says nothing)."""
    from renderers.catalog import resolve

    ref = protocol.scene_ref(scene)
    cam = resolve(ref).camera
    out = []
    for k in range(PATH_SAMPLES):
        t = k / (PATH_SAMPLES - 1)
        c = absolute_camera(ref, path_camera(protocol, t)) or {}
        out.append((t, tuple(c.get("position", cam.position)), tuple(c.get("look_at", cam.look_at))))
    return tuple(out)


def start_pose(protocol, scene: str) -> tuple[tuple, tuple]:
    """``(position, look_at)`` where exploring ``scene`` starts: its ``explore.start``, else the scene's camera."""
    start = (protocol.explore.get("start") or {}).get(scene)
    if start:
        return tuple(start["position"]), tuple(start["look_at"])
    from renderers.catalog import resolve

    cam = resolve(protocol.scene_ref(scene)).camera
    return tuple(cam.position), tuple(cam.look_at)


#: A view is refused when its direction is within about 0.006° of the up vector (the sine of the angle between
#: them below this), or look_at is within this fraction of the scene's scale of the position: the camera's
#: right and up vectors (``renderers.scene.Camera.basis``) would be undefined or swing wildly, also in float32.
DEGENERATE = 1e-4


def view_problem(position, look_at, up) -> str | None:
    """Why a camera at ``position`` looking at ``look_at`` with ``up`` has no basis, or None if it has one."""
    p, f, u = np.asarray(position, float), np.subtract(look_at, position, dtype=float), np.asarray(up, float)
    n = float(np.linalg.norm(f))
    if not n > DEGENERATE * (1.0 + float(np.linalg.norm(p))):
        return "look_at is the camera's own position (no view direction)"
    if float(np.linalg.norm(np.cross(f / n, u / np.linalg.norm(u)))) < DEGENERATE:
        return f"the view direction is parallel to the scene's up vector {_vec(u)} (looking straight up or down)"
    return None


def path_problem(poses, up) -> tuple[float, str] | None:
    """Where a camera moving through ``poses`` (``(position, look_at)`` pairs), linearly from one to the next as
    :class:`~studyapp.runner.live.PathMotion` does, has no basis: ``(x, problem)`` with ``x`` the place as a
    fractional index into ``poses`` (2.5: halfway from the third to the fourth), or None.

    Between two poses the view direction ``f(w)`` is linear in ``w``, so ``|f(w) x up|`` is smallest at a point
    found in closed form; it must stay above :data:`DEGENERATE` times the longer end direction (which bounds
    ``|f(w)|``), so no direction in between is within :data:`DEGENERATE` of the up vector or vanishes.
    """
    p = np.array([q[0] for q in poses], dtype=float)
    f = np.array([q[1] for q in poses], dtype=float) - p
    u = np.asarray(up, dtype=float) / np.linalg.norm(up)
    for k in sorted(_suspects(p, f, u)):
        problem = view_problem(*poses[k], u)
        if problem:
            return float(k), problem
    n = np.linalg.norm(f, axis=1)
    c = np.cross(f, u)
    ca, d = c[:-1], c[1:] - c[:-1]
    dd = np.einsum("ij,ij->i", d, d)
    w = np.clip(-np.einsum("ij,ij->i", ca, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    low = np.linalg.norm(ca + w[:, None] * d, axis=1) < DEGENERATE * np.maximum(n[:-1], n[1:])
    if not low.any():
        return None
    k = int(np.argmax(low))
    near = np.linalg.norm(f[k] + w[k] * (f[k + 1] - f[k])) < 0.01 * max(n[k], n[k + 1])
    return k + float(w[k]), ("the camera passes (almost) through its look_at (the view direction flips)" if near
                             else f"the view direction sweeps (almost) through the scene's up vector {_vec(u)}")


def _suspects(p: np.ndarray, f: np.ndarray, u: np.ndarray) -> set[int]:
    """Indexes of the poses :func:`view_problem` may refuse (all poses at once; it says why)."""
    n = np.linalg.norm(f, axis=1)
    bad = ~(n > DEGENERATE * (1.0 + np.linalg.norm(p, axis=1)))
    bad |= np.linalg.norm(np.cross(f, u), axis=1) < DEGENERATE * np.where(n > 0, n, 1.0)
    return set(np.flatnonzero(bad).tolist())


def _vec(v) -> str:
    return "(" + ", ".join(f"{float(x):g}" for x in v) + ")"
