"""Fuzzing the live block of the shipped live protocols (issue 25, item 8): explore bounds and start, camera path
poses, durations, frame-rate floor and caps, gaze delays.

Hypothesis rewrites the ``stimulus`` block of ``seed001_2afc_live`` (explore) or ``seed003_task1_live`` (camera
path) with values drawn near the contradictions (coincident points, views along the up vector, min above max,
a start on or past the bounds, equal keyframe times). ``validate`` must exit 0, or 2 with exactly one line; and
whenever it accepts, the runner's own camera code (``live_stimulus`` -> its motion model) gives a camera basis
(``renderers.scene.Camera``) at every path sample, between samples and at the start, and the start lies inside
the bounds. Bounded to about 15 s.
"""

from __future__ import annotations

import contextlib
import io
import tempfile
from pathlib import Path

import numpy as np
import yaml
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from studyapp.cli import main

PROTOCOLS = Path(__file__).resolve().parents[1] / "studyapp" / "protocols"
EXPLORE, PATH = "seed001_2afc_live", "seed003_task1_live"
DOCS = {name: yaml.safe_load((PROTOCOLS / f"{name}.yaml").read_text()) for name in (EXPLORE, PATH)}

# Coordinates near the shipped scenes' cameras (about (0, 1.7, -3) and (278, 273, -800)), on a coarse grid so
# that points coincide and directions line up with +y often.
COORD = st.sampled_from([-800.0, -9.0, -3.0, -2.5, -1.0, 0.0, 0.5, 1.0, 1.7, 2.0, 3.0, 20.0, 273.0, 278.0])
POINT = st.lists(COORD, min_size=3, max_size=3)
NUMBER = st.one_of(st.sampled_from([0.001, 0.01, 0.0334, 0.5, 1.0, 2.0, 30.0, 60.0, 120.0, 600.0]),
                   st.floats(0.001, 600.0))


@st.composite
def pose(draw) -> dict:
    position = draw(POINT)
    kind = draw(st.sampled_from(["free", "same", "above", "below"]))
    up = draw(st.sampled_from([1e-9, 1.0, 50.0]))
    look = {"free": draw(POINT), "same": list(position), "above": [position[0], position[1] + up, position[2]],
            "below": [position[0], position[1] - 3.0, position[2]]}[kind]
    return {"position": position, "look_at": look}


@st.composite
def keyframe(draw, keys) -> dict:
    out = {"t": draw(st.sampled_from([0.0, 0.25, 0.5, 1.0]))}
    if "pose" in keys:
        out.update(draw(pose()))
    if "yaw" in keys:
        out["yaw_deg"] = draw(st.sampled_from([-180.0, -6.0, 0.0, 6.0, 90.0, 180.0]))
    if "pitch" in keys:
        out["pitch_deg"] = draw(st.sampled_from([-89.0, -45.0, 0.0, 45.0, 80.0, 89.0]))
    return out


@st.composite
def live_block(draw) -> tuple[str, dict]:
    name = draw(st.sampled_from([EXPLORE, PATH]))
    doc = yaml.safe_load(yaml.safe_dump(DOCS[name]))
    stim, scenes = doc["stimulus"], doc["scenes"] + [doc["practice"]["scene"]]
    sometimes = st.integers(0, 3).map(lambda k: k == 0)  # a quarter of the examples change each number
    if draw(sometimes):
        stim["duration_s"] = draw(NUMBER)
    if draw(sometimes):
        stim["min_fps"] = draw(NUMBER)
    if draw(sometimes):
        doc["display"]["refresh_hz"] = draw(st.sampled_from([20.0, 60.0, 144.0]))
    cond = doc["conditions"][draw(st.sampled_from(sorted(doc["conditions"])))]
    for key in ("max_fps", "latency_ms"):
        if draw(sometimes):
            cond[key] = draw(st.sampled_from([0.5, 1.0, 30.0, 60.0, 500.0, 1000.0]))
    if name == EXPLORE:
        ex = stim["explore"]
        for scene in draw(st.lists(st.sampled_from(scenes), max_size=2, unique=True)):
            lo, hi = draw(POINT), draw(POINT)
            if not draw(sometimes):  # mostly min <= max, so that the start is checked against them
                lo, hi = [min(a, b) for a, b in zip(lo, hi)], [max(a, b) for a, b in zip(lo, hi)]
            ex.setdefault("bounds", {})[scene] = [lo, hi]
        for scene in draw(st.lists(st.sampled_from(scenes), max_size=2, unique=True)):
            ex.setdefault("start", {})[scene] = draw(pose())
    else:
        keys = draw(st.sampled_from([("pose",), ("yaw",), ("pitch",), ("yaw", "pitch")]))
        path = draw(st.lists(keyframe(keys), min_size=1, max_size=4))
        if not draw(sometimes):  # mostly increasing times, so that the pose checks are reached
            path = [{**k, "t": i / max(1, len(path) - 1)} for i, k in enumerate(path)]
        stim["camera_path"] = path
    return name, doc


def _basis_ok(position, look_at, up) -> bool:
    from renderers.scene import Camera

    f, r, u = Camera(position=tuple(position), look_at=tuple(look_at), up=tuple(up)).basis()
    m = np.stack([f, r, u])
    return bool(np.isfinite(m).all() and np.allclose(m @ m.T, np.eye(3), atol=1e-6))


def _check_accepted(path: Path) -> None:
    """The runner's camera code on an accepted protocol: a basis everywhere, the start inside the bounds."""
    from renderers.catalog import resolve
    from studyapp.runner.live import live_stimulus
    from studyapp.runner.protocol import load_protocol

    p = load_protocol(path)
    condition = next(iter(p.conditions))
    for scene in dict.fromkeys(p.scenes + (p.practice["scene"],)):
        up = resolve(p.scene_ref(scene)).camera.up
        stim = live_stimulus(p, condition, scene)
        motion = stim.motion_model()
        if p.motion == "explore":
            lo, hi = (np.asarray(b, float) for b in stim.bounds)
            start = np.asarray(stim.start.position, float)
            assert (lo <= start).all() and (start <= hi).all(), (scene, stim.start, stim.bounds)
            assert _basis_ok(stim.start.position, stim.start.look_at, up)
            first = motion.pose(0.0)
            assert np.allclose(first.position, stim.start.position)  # no jump at the first frame
            assert _basis_ok(first.position, first.look_at, up)
            continue
        for t in np.linspace(0.0, stim.duration_s, 2 * len(stim.path) - 1):  # the samples and halfway between
            q = motion.pose(float(t))
            assert _basis_ok(q.position, q.look_at, up), (scene, t, q)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(live_block())
def test_validate_refuses_in_one_line_or_accepts_only_usable_camera_poses(block):
    name, doc = block
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"{name}.yaml"
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            status = main(["validate", str(path)])
        assert status in (0, 2), err.getvalue()
        if status == 2:
            lines = err.getvalue().splitlines()
            event("refused: " + lines[0].split(": ")[3].split("[")[0] if lines else "")
            assert len(lines) == 1 and lines[0].startswith(f"studyapp: error: {path}:"), err.getvalue()
            return
        assert err.getvalue() == ""
        event(f"accepted {name}")
        _check_accepted(path)
