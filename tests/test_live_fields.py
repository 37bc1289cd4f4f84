"""Live fields that contradict each other are refused by ``validate`` in one line naming the field and the
conflict (issue 25, item 8): explore bounds with min > max, a start outside the bounds, a view straight up or
at the camera's own position (start, path keyframe, or between two path samples), keyframe times that do not
increase or keys that would be ignored, explore settings on a path, a stimulus shorter than two frames, a
frame-rate floor above the display's refresh rate, a gaze delay as long as the stimulus."""

from __future__ import annotations

import numpy as np
import pytest
from test_run_refusals import LIVE, replaced

from studyapp.cli import main
from studyapp.runner.camera import path_problem, view_problem

# the small live study of test_run_refusals, its stimulus block replaced by each case's (%s)
BASE = replaced(LIVE, ("duration_s: 1.0", "duration_s: 2.0"), (
    "  motion: path\n  gaze: fixation\n  camera_path: [{t: 0, yaw_deg: -3}, {t: 1, yaw_deg: 3}]\n",
    "  min_fps: 30\n  gaze: fixation\n%s\n"),
    ("design:", 'keys: {switch: {q: 0, e: 1}, answer: {"1": A, "2": B}}\ndesign:'))
EXPLORE = "  motion: explore\n  explore: {bounds: {cornell: %s}, start: {cornell: {position: %s, look_at: %s}}}"
PATH = "  motion: path\n  camera_path:\n%s"
BOX = "[[0, 0, -900], [560, 560, 560]]"
OK_EXPLORE = EXPLORE % (BOX, "[278, 273, -800]", "[278, 273, 0]")
# cornell's camera: position (278, 273, -800), look_at (278, 273, 0), up +y


def _validate(tmp_path, capsys, stimulus: str, replace=()) -> tuple[int, str]:
    text = replaced(BASE % stimulus, *replace)
    (tmp_path / "p.yaml").write_text(text)
    status = main(["validate", str(tmp_path / "p.yaml")])
    out, err = capsys.readouterr()
    assert status in (0, 2) and "Traceback" not in err
    return status, err


@pytest.mark.parametrize("stimulus,replace,expected", [
    (EXPLORE % ("[[0, 0, 0], [560, -1, 560]]", "[278, 273, -800]", "[278, 273, 0]"), (),
     "p.yaml:19: stimulus.explore.bounds.cornell: y min 0 is above y max -1"),
    (EXPLORE % (BOX, "[278, 273, 600]", "[278, 273, 0]"), (),
     "p.yaml:19: stimulus.explore.start.cornell.position: outside stimulus.explore.bounds.cornell (z = 600 not in "
     "[-900, 560]): the camera would jump at the first frame"),
    ("  motion: explore\n  explore: {bounds: {cornell: [[0, 0, 0], [560, 560, 560]]}}", (),
     "p.yaml:19: stimulus.explore.bounds.cornell: the scene's camera at [278.0, 273.0, -800.0] (the start: no "
     "explore.start for cornell) is outside these bounds"),
    (EXPLORE % (BOX, "[278, 273, -800]", "[278, 500, -800]"), (),
     "p.yaml:19: stimulus.explore.start.cornell: the view direction is parallel to the scene's up vector (0, 1, 0)"),
    (EXPLORE % (BOX, "[278, 273, -800]", "[278, 273, -800]"), (),
     "p.yaml:19: stimulus.explore.start.cornell: look_at is the camera's own position"),
    (PATH % "    - {t: 0, position: [0, 1, 0], look_at: [0, 1, 5]}\n    - {t: 1, position: [0, 1, 0], look_at: "
     "[0, 9, 0]}", (), "p.yaml:21: stimulus.camera_path[1]: in scene cornell at t = 1: the view direction is "
     "parallel to the scene's up vector"),
    (PATH % "    - {t: 0, position: [0, 1, 0], look_at: [0, 1, 0]}", (),
     "p.yaml:20: stimulus.camera_path[0]: in scene cornell at t = 0: look_at is the camera's own position"),
    # every keyframe and every one of the 64 path samples looks fine; the way between two samples does not
    (PATH % "    - {t: 0, position: [0, 1, 0], look_at: [1, 2, 0]}\n    - {t: 1, position: [0, 1, 0], look_at: "
     "[-1, 2, 0]}", (), "stimulus.camera_path[0]: in scene cornell at t = 0.5: the view direction sweeps (almost) "
     "through the scene's up vector"),
    (PATH % "    - {t: 0, position: [0, 1, 0], look_at: [0, 1, 5]}\n    - {t: 1, position: [0, 1, 10], look_at: "
     "[0, 1, 5]}", (), "at t = 0.5: the camera passes (almost) through its look_at"),
    (PATH % "    - {t: 0, pitch_deg: 80}\n    - {t: 1, pitch_deg: 89}", (("scenes: [cornell]", "scenes: [yard]"),),
     "stimulus.camera_path[1]: in scene yard at t = 0.964: the view direction sweeps (almost) through"),
    (PATH % "    - {t: 0.5, yaw_deg: -3}\n    - {t: 0.2, yaw_deg: 3}", (),
     "p.yaml:21: stimulus.camera_path[1].t: 0.2 is not after the previous keyframe's t = 0.5"),
    (PATH % "    - {t: 0, yaw_deg: -3}\n    - {t: 1, yaw_deg: 3, pitch_deg: 5}", (),
     "p.yaml:21: stimulus.camera_path[1].pitch_deg: not in the first keyframe, so never used"),
    (PATH % "    - {t: 0, yaw_deg: -3, look_at: [0, 0, 0]}\n    - {t: 1, yaw_deg: 3}", (),
     "p.yaml:20: stimulus.camera_path[0].look_at: yaw_deg/pitch_deg turn the scene camera's view and replace "
     "look_at"),
    (PATH % "    - {t: 0, yaw_deg: -3}\n  explore: {move_speed_m_s: 2}", (),
     "p.yaml:21: stimulus.explore: explore settings belong to motion: explore"),
    (OK_EXPLORE, (("duration_s: 2.0", "duration_s: 0.02"),),
     "p.yaml:15: stimulus.duration_s: 0.02 s is shorter than two refreshes of the display (60 Hz)"),
    (OK_EXPLORE, (("min_fps: 30", "min_fps: 75"),),
     "p.yaml:16: stimulus.min_fps: 75 fps is above the display's refresh rate (60 Hz)"),
    (OK_EXPLORE, (("quality: 1.0}", "quality: 1.0, max_fps: 0.5}"),),
     "p.yaml:10: conditions.GT.max_fps: at 0.5 fps a 2 s stimulus shows fewer than two frames"),
    (OK_EXPLORE, (("quality: 0.5}", "quality: 0.5, latency_ms: 500}"),
                  ("duration_s: 2.0", "duration_s: 0.5")),
     "p.yaml:11: conditions.LaFR.latency_ms: a gaze delay of 500 ms is not shorter than the stimulus (duration_s "
     "0.5 s): the gaze would never drive the foveation"),
])
def test_contradictory_live_fields_are_refused_naming_field_and_conflict(stimulus, replace, expected, tmp_path,
                                                                         capsys):
    status, err = _validate(tmp_path, capsys, stimulus, replace)
    assert status == 2 and len(err.splitlines()) == 1 and err.startswith("studyapp: error: "), err
    assert expected in err, err


@pytest.mark.parametrize("stimulus", [
    OK_EXPLORE,
    EXPLORE % ("[[278, 273, -800], [278, 273, 560]]", "[278, 273, -800]", "[278, 273, 0]"),  # on the bounds
    "  motion: explore",  # the scene's camera, the scene's bounding box
    PATH % "    - {t: 0, yaw_deg: -3}\n    - {t: 1, yaw_deg: 3}",
    PATH % "    - {t: 0, pitch_deg: 80}\n    - {t: 1, pitch_deg: 89}",  # cornell looks level: 1° from up
    PATH % "    - {t: 0, position: [0, 1, 0], look_at: [1, 2, 0]}\n    - {t: 1, position: [0, 1, 0], look_at: "
    "[-1, 2, 1]}",  # turns past the zenith, 0.5 rad beside it
])
def test_consistent_live_fields_pass(stimulus, tmp_path, capsys):
    assert _validate(tmp_path, capsys, stimulus)[0] == 0


def test_a_path_is_checked_between_its_poses():
    up = (0.0, 1.0, 0.0)
    assert view_problem((0, 0, 0), (0, 0, 1), up) is None
    assert "parallel" in view_problem((0, 0, 0), (0, -3, 0), up)
    assert "own position" in view_problem((5, 5, 5), (5, 5, 5), up)
    a, b = ((0, 0, 0), (1, 1, 0)), ((0, 0, 0), (-1, 1, 0))
    x, problem = path_problem([a, b], up)  # both ends 45° from up, straight up halfway
    assert x == pytest.approx(0.5) and "sweeps" in problem
    x, problem = path_problem([a, a, b], up)
    assert x == pytest.approx(1.5) and "sweeps" in problem
    x, problem = path_problem([((0, 0, 0), (0, 0, 5)), ((0, 0, 10), (0, 0, 5))], up)
    assert x == pytest.approx(0.5) and "passes" in problem
    x, problem = path_problem([a, ((1, 1, 1), (1, 1, 1)), b], up)  # a pose itself: named as such
    assert x == 1.0 and "own position" in problem
    assert path_problem([a, ((0, 0, 0), (-1, 1, 1))], up) is None
    # what it accepts holds everywhere between the poses: the view is never within 1e-4 rad of up
    f = [np.array([1 - 2 * w, 1, w]) for w in np.linspace(0, 1, 1001)]
    assert min(np.linalg.norm(np.cross(v / np.linalg.norm(v), up)) for v in f) > 1e-4
