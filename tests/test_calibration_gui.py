"""The eye tracker's calibration and validation in a real window (issue 26 item 4): iohub's MouseGaze under a
private Xvfb, the mouse moved by xdotool. Following the dots passes with a small error and the result is
stored with the session; a mouse held still fails with its measured error shown, and the experimenter's
repeat (R) and skip (S) work. Window-free parts: tests/test_eyetracker.py."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent / "gui"))
from test_eyetracker import stored_validation  # noqa: E402
from xvfb import Driver, Xvfb, missing_tools  # noqa: E402

from data_schema.geometry import Display  # noqa: E402
from studyapp.presentation.eyetracker import TARGET_LAYOUTS, target_error_deg  # noqa: E402
from studyapp.runner.protocol import MOUSE_GAZE_DEVICE  # noqa: E402

DISPLAY = {"width_px": 480, "height_px": 270, "width_cm": 30.0, "distance_cm": 60.0}
TRACKER = {"device": MOUSE_GAZE_DEVICE, "calibrate": True, "max_validation_error_deg": 1.0,
           "target_delay_s": 0.3, "target_duration_s": 0.5}


@pytest.fixture(autouse=True)
def _gui_tools_installed():
    assert not missing_tools(), f"GUI tests need {missing_tools()} (Debian: xvfb, xdotool)"


def _spec(**tracker):
    return {"display": DISPLAY, "presenter": {"eyetracker": "device", "tracker": {**TRACKER, **tracker}},
            "steps": [], "watchdog_s": 90}


def _clean_stderr(d: Driver) -> None:
    err = d.stderr_path.read_text()
    assert "Traceback" not in err and "KeyError" not in err, err[-3000:]


def test_following_the_dots_passes_with_a_small_error_and_is_stored(tmp_path):
    with Xvfb() as x:
        d = Driver(x, _spec(), tmp_path, timeout_s=90)
        try:
            ev = d.wait_for("validation_instructions", attempt=0)
            # generated from the gaze source (MouseGaze: the mouse stands in for the eyes) and the keys
            assert "Follow it with the mouse pointer" in ev["text"] and "Press SPACE to start" in ev["text"]
            assert "4 other places" in ev["text"] and "calibrates itself" not in ev["text"]
            wx, wy = ev["window_pos_px"]
            x.key("space")
            prev = None
            for k in range(5):
                t = d.wait_for("validation_target", attempt=0, target=k)
                to = (t["x"], t["y"])
                for f in (0.5, 1.0) if prev else (1.0,):  # follow the moving dot, a little behind it
                    time.sleep(0.05)
                    p = to if f == 1.0 else ((prev[0] + to[0]) / 2, (prev[1] + to[1]) / 2)
                    x.xdotool("mousemove", str(round(wx + p[0])), str(round(wy + p[1])))
                prev = to
            measured = d.wait_for("validation", attempt=0)
            assert measured["passed"], measured["targets_deg"]  # (fails at once with the errors, no time-out)
            passed = d.wait_for("validation_passed")
            facts = d.wait_for("opened")
            d.finish()
        finally:
            d.kill()
    _clean_stderr(d)
    v = facts["validation"]
    assert v["status"] == "passed" and v["n_attempts"] == 1 and v["limit_deg"] == 1.0
    assert v["error_deg"] <= 0.05 and v["max_error_deg"] <= 0.05 and passed["error_deg"] == v["error_deg"]
    assert v["calibration"] == {"done": False, "reason": "not needed: the mouse is the gaze (MouseGaze)"}
    targets = v["attempts"][0]["targets"]
    assert [c for t in targets for c in (t["x_px"] / 480, t["y_px"] / 270)] == pytest.approx(
        [c for xy in TARGET_LAYOUTS[5] for c in xy])
    assert all(t["n_samples"] > 0 and t["error_deg"] <= 0.05 for t in targets)

    # the result is stored with the session: the sessions' validation_deg and a "validation" event with it all
    assert stored_validation(tmp_path, v) == (v["error_deg"], v)


def test_a_mouse_held_still_fails_shows_its_error_and_repeat_and_skip_work(tmp_path):
    still = (240, 135)  # the window's centre: right on the first target, far from the four others
    g = Display(**DISPLAY).geometry()
    corner = target_error_deg([still], (0.1 * 480, 0.1 * 270), g)
    expected = (0.0 + 4 * corner) / 5
    with Xvfb() as x:
        d = Driver(x, _spec(max_attempts=2), tmp_path, timeout_s=90)
        try:
            texts = []
            for attempt in (0, 1):
                ev = d.wait_for("validation_instructions", attempt=attempt)
                wx, wy = ev["window_pos_px"]
                x.xdotool("mousemove", str(wx + still[0]), str(wy + still[1]))
                x.key("space")
                failed = d.wait_for("validation_failed", attempt=attempt)
                texts.append(failed["text"])
                assert failed["can_repeat"] is (attempt == 0)
                x.key("r" if attempt == 0 else "s")  # repeat, then (no attempt left) skip
            facts = d.wait_for("opened")
            d.finish()
        finally:
            d.kill()
    _clean_stderr(d)
    assert f"Mean error {expected:.2f}° (limit 1°), worst target {corner:.2f}°" in texts[0]
    assert "1: 0.00°" in texts[0] and "R: repeat" in texts[0] and "S: skip" in texts[0]
    assert "R: repeat" not in texts[1] and "S: skip" in texts[1] and "E: end the session" in texts[1]
    v = facts["validation"]
    assert v["status"] == "skipped" and v["n_attempts"] == 2
    assert v["error_deg"] == pytest.approx(expected, abs=0.01)
    assert v["max_error_deg"] == pytest.approx(corner, abs=0.01)
    assert [a["passed"] for a in v["attempts"]] == [False, False]
