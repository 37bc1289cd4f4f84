"""Exploration at a human pace in every scene, and instructions that name the keys it answers to (issue 26,
item 8): speeds are declared in metres per second and degrees per second, each built-in scene declares its unit
once (``renderers.catalog.METRES_PER_UNIT``, scene files ``metres_per_unit``), ``studyapp scenes`` prints it;
the participant's instructions are generated from the motion model's keys and the gaze source."""

from __future__ import annotations

import dataclasses
import json
import math
import re
import string
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from renderers.catalog import BUILTIN_SCENES, METRES_PER_UNIT, builtin, resolve
from studyapp.cli import main
from studyapp.runner.live import WALK_M_S, controls_text, instructions_text, live_stimulus
from studyapp.runner.protocol import CONTROLS, EXPLORE_KEYS, load_protocol

PROTOCOLS = Path(__file__).resolve().parents[1] / "studyapp" / "protocols"
SHIPPED_LIVE = sorted(p.stem for p in PROTOCOLS.glob("*_live.yaml"))
FAR = 1e7  # explore bounds far enough that no walk of these tests reaches them

PACE = """
schema_version: 1
name: pace
version: "1"
family: yes_no
question: "Acceptable? Y / N"
instructions: "INSTRUCTIONS"
display: {width_px: 320, height_px: 180, width_cm: 40.0, distance_cm: 40.0, refresh_hz: 60}
scenes: SCENES
conditions:
  LaFR: {renderer: lafr, params: {delta: 4.0}, backend: cpu}
stimulus:
  kind: live
  duration_s: 2.0
  motion: explore
  gaze: GAZE
  explore: {bounds: BOUNDS}
EYETRACKER
design: {repetitions: 1}
analysis: {dv: response, unit: trial, test: summary_table}
"""


def _pace_text(scenes=tuple(BUILTIN_SCENES), gaze="fixation", eyetracker="",
               instructions="Explore. {controls} Press Y or N.") -> str:
    bounds = {s: [[-FAR] * 3, [FAR] * 3] for s in scenes}
    return (PACE.replace("SCENES", json.dumps(list(scenes))).replace("BOUNDS", json.dumps(bounds))
            .replace("GAZE", gaze).replace("EYETRACKER", eyetracker).replace("INSTRUCTIONS", instructions))


def _pace_protocol(folder: Path, *args, **kw):
    (folder / "pace.yaml").write_text(_pace_text(*args, **kw))
    return load_protocol(folder / "pace.yaml")


@pytest.fixture(scope="module")
def pace(tmp_path_factory):
    """An exploring protocol over every built-in scene (bounds far away: the walk is never stopped)."""
    return _pace_protocol(tmp_path_factory.mktemp("pace"))


def _hold(motion, key: str, dts) -> None:
    """Hold ``key`` over frames ``dts`` apart (the first call only starts the clock, as in a trial)."""
    t = 0.0
    motion.pose(t)
    for dt in dts:
        t += dt
        motion.pose(t, keys={key})


def _heading(motion) -> float:
    return math.degrees(motion.yaw)


def _frames(draw_dts, total: float = 1.0) -> list[float]:
    """Frame intervals that add up to ``total`` seconds exactly."""
    out, t = [], 0.0
    for dt in draw_dts:
        if t + dt >= total:
            break
        out.append(dt)
        t += dt
    return out + [total - t]


def test_every_builtin_scene_declares_its_unit_consistent_with_its_eye_separation():
    assert set(METRES_PER_UNIT) == set(BUILTIN_SCENES)
    for name in BUILTIN_SCENES:
        scene = builtin(name)
        assert scene.metres_per_unit == METRES_PER_UNIT[name]
        # the scene's own interocular distance (in its units) is a human's 64 mm in the declared unit
        assert scene.display.ipd * scene.metres_per_unit == pytest.approx(0.064)
    assert METRES_PER_UNIT["cornell"] == 0.001 and METRES_PER_UNIT["temple"] == 1.0
    # the unit does not change what is rendered: cached stimuli and recorded sessions keep their hash
    moved = dataclasses.replace(builtin("cornell"), metres_per_unit=1.0, _hash=None)
    assert moved.content_hash() == builtin("cornell").content_hash()


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scene=st.sampled_from(list(BUILTIN_SCENES)), m_s=st.floats(0.3, 3.0), deg_s=st.floats(10.0, 170.0),
       dts=st.lists(st.floats(1 / 240, 0.3), min_size=1, max_size=300))
def test_one_second_of_walking_is_the_declared_metres_and_turning_the_declared_degrees(pace, scene, m_s, deg_s,
                                                                                       dts):
    p = dataclasses.replace(pace, explore={**pace.explore, "move_speed_m_s": m_s, "turn_speed_deg": deg_s})
    stim = live_stimulus(p, "LaFR", scene)
    frames = _frames(dts)
    walk = stim.motion_model()
    start = np.asarray(walk.position)
    _hold(walk, "w", frames)
    metres = float(np.linalg.norm(walk.position - start)) * resolve(scene).metres_per_unit
    assert metres == pytest.approx(m_s, rel=0.05)
    turn = stim.motion_model()
    before = _heading(turn)
    _hold(turn, "right", frames)
    assert _heading(turn) - before == pytest.approx(deg_s, rel=0.05)


@pytest.mark.parametrize("name", [n for n in SHIPPED_LIVE if load_protocol(PROTOCOLS / f"{n}.yaml").motion
                                  == "explore"])
def test_shipped_explorations_walk_at_a_human_pace_in_every_scene(name):
    p = load_protocol(PROTOCOLS / f"{name}.yaml")
    assert p.explore["move_speed_m_s"] == WALK_M_S
    for scene in dict.fromkeys(p.scenes + (p.practice["scene"],)):
        stim = dataclasses.replace(live_stimulus(p, next(iter(p.conditions)), scene), bounds=None)
        motion = stim.motion_model()
        start = np.asarray(motion.position)
        _hold(motion, "w", [1 / 60] * 60)
        metres = float(np.linalg.norm(motion.position - start)) * resolve(p.scene_ref(scene)).metres_per_unit
        assert metres == pytest.approx(1.4, rel=0.05), scene
        turn = stim.motion_model()
        before = _heading(turn)
        _hold(turn, "left", [1 / 60] * 60)
        assert before - _heading(turn) == pytest.approx(p.explore["turn_speed_deg"], rel=0.05), scene


# -- instructions ----------------------------------------------------------------------------------------------
CANDIDATES = (tuple(string.ascii_lowercase) + tuple(string.digits) + EXPLORE_KEYS
              + ("space", "return", "escape", "tab", "lshift", "f1", "f2", "f5", "num_1"))


def _keys_that_move(stim) -> set[str]:
    """The keys the motion model responds to: held for 0.2 s, each changes the pose (away from any bounds: a
    start on the scene's edge cannot step back)."""
    stim, out = dataclasses.replace(stim, bounds=None), set()
    for key in CANDIDATES:
        motion = stim.motion_model()
        first = motion.pose(0.0)
        then = motion.pose(0.2, keys={key})
        if first != then:
            out.add(key)
    return out


def _mouse_turns(stim) -> bool:
    motion = stim.motion_model()
    first = motion.pose(0.0)
    return motion.pose(0.2, mouse=(200.0, 50.0)) != first


def _keys_named(text: str) -> set[str]:
    """The keys a text names: capital letters and digits standing alone, ``Left arrow`` and the like."""
    keys = {m.lower() for m in re.findall(r"(?<![\w-])([A-Z0-9])(?![\w-])", text)}
    return keys | {m.lower() for m in re.findall(r"\b(Left|Right|Up|Down) arrow\b", text)}


@pytest.mark.parametrize("name", SHIPPED_LIVE)
def test_shipped_instructions_name_exactly_the_keys_that_move_and_what_the_mouse_does(name):
    p = load_protocol(PROTOCOLS / f"{name}.yaml")
    text = instructions_text(p)
    assert CONTROLS not in text and "dragging" not in p.instructions  # nothing hand-written about the controls
    if p.motion != "explore":
        assert text == p.instructions and "arrow" not in text
        return
    controls = controls_text(p)
    assert text.count(controls) == 1
    for scene in dict.fromkeys(p.scenes + (p.practice["scene"],)):
        stim = live_stimulus(p, next(iter(p.conditions)), scene)
        assert _keys_named(controls) == _keys_that_move(stim) == set(EXPLORE_KEYS)
        assert p.mouse_is_gaze and not _mouse_turns(stim)  # MouseGaze by default: the mouse is the eye
    assert "does not turn" in controls and "drag" not in text.lower()


@pytest.mark.parametrize("gaze,eyetracker,mouse_is_gaze", [
    ("mouse", "", True),
    ("tracker", "eyetracker: {device: eyetracker.hw.mouse.EyeTracker}", True),
    ("tracker", "eyetracker: {device: eyetracker.hw.sr_research.eyelink.EyeTracker}", False),
    ("fixation", "", False)])
def test_the_mouse_turns_and_is_said_to_turn_only_where_it_is_not_the_gaze(tmp_path, gaze, eyetracker,
                                                                           mouse_is_gaze):
    p = _pace_protocol(tmp_path, ("cornell",), gaze, eyetracker)
    stim = live_stimulus(p, "LaFR", "cornell")
    controls = controls_text(p)
    assert p.mouse_is_gaze == mouse_is_gaze and _mouse_turns(stim) == (not mouse_is_gaze)
    assert ("dragging the mouse" in controls) == (not mouse_is_gaze)
    assert ("does not turn" in controls) == mouse_is_gaze
    assert instructions_text(p) == f"Explore. {controls} Press Y or N."
    assert _keys_named(controls) == _keys_that_move(stim)


def test_controls_follow_instructions_without_the_placeholder_and_the_placeholder_needs_exploring(tmp_path,
                                                                                                   capsys):
    p = _pace_protocol(tmp_path, ("cornell",), instructions="Explore, then press Y or N.")
    assert instructions_text(p) == f"Explore, then press Y or N.\n\n{controls_text(p)}"
    path = tmp_path / "path.yaml"
    text = _pace_text(("cornell",))
    path.write_text(re.sub(r"  explore: .*\n", "  camera_path: [{t: 0, yaw_deg: 0}]\n",
                           text.replace("motion: explore", "motion: path")))
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "path.yaml:7: instructions: {controls} names the keys that move the camera: only a live stimulus with " \
        "motion: explore has them" in err


# -- scene files and `studyapp scenes` -------------------------------------------------------------------------
SCENE_FILE = """name: box
meshes:
  - {file: floor.ply}
lights:
  - {type: point, position: [0, 3, 0], intensity: [5, 5, 5]}
camera: {position: [0, 1.5, -3], look_at: [0, 0.5, 1], up: [0, 1, 0], fov_y: 50}
UNIT"""


def test_a_scene_file_declares_its_unit_metres_by_default(mesh_file, tmp_path):
    from renderers.scene import SceneError, load_yaml

    import shutil

    folder = tmp_path
    shutil.copy(mesh_file / "floor.ply", folder / "floor.ply")
    (folder / "m.yaml").write_text(SCENE_FILE.replace("UNIT", ""))
    (folder / "cm.yaml").write_text(SCENE_FILE.replace("UNIT", "metres_per_unit: 0.01"))
    (folder / "bad.yaml").write_text(SCENE_FILE.replace("UNIT", "metres_per_unit: 0"))
    metres, centimetres = load_yaml(folder / "m.yaml"), load_yaml(folder / "cm.yaml")
    assert metres.metres_per_unit == 1.0 and centimetres.metres_per_unit == 0.01
    assert metres.content_hash() == centimetres.content_hash()
    with pytest.raises(SceneError, match=r"bad.yaml:7: metres_per_unit: .*minimum"):
        load_yaml(folder / "bad.yaml")
    # an exploring protocol walks a centimetre scene at 140 units per second
    p = _pace_protocol(folder, ("cm",))
    assert live_stimulus(p, "LaFR", "cm").move_speed == pytest.approx(140.0)


def test_scenes_prints_each_scene_unit_and_walking_speed(capsys):
    assert main(["scenes"]) == 0
    rows = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()[1:]}
    assert set(rows) == set(BUILTIN_SCENES)
    assert rows["cornell"].endswith("1 mm  1,400 units/s") and rows["temple"].endswith("1 m  1.4 units/s")
    assert main(["scenes", "--json"]) == 0
    data = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    assert data["cornell_many"]["metres_per_unit"] == 0.001
    assert data["yard"]["walk_units_per_s"] == pytest.approx(1.4)
