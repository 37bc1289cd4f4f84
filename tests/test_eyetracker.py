"""Window-free tests of the eye tracker's calibration and validation (studyapp/presentation/eyetracker.py):
the target's animation, the angular error, the texts, the experimenter's repeat/skip/end choice and the stored
result. The same procedure in a real window, the mouse moved by xdotool: tests/test_calibration_gui.py."""

from __future__ import annotations

import json
import math

import pytest

from data_schema.geometry import Display
from studyapp.presentation import eyetracker as E
from studyapp.presentation.base import PresentationError

DISPLAY = Display(480, 270, 30.0, 60.0)


def test_the_target_moves_on_iohubs_minimum_jerk_path():
    for t in (0.0, 0.1, 0.25, 0.5, 0.8, 1.0):  # iohub writes it 60 (t^5/10 - t^4/4 + t^3/6)
        assert E.min_jerk(t) == pytest.approx(60.0 * (t**5 / 10 - t**4 / 4 + t**3 / 6))
    assert E.min_jerk(-1.0) == 0.0 and E.min_jerk(2.0) == 1.0
    timing = E.Timing(delay_s=1.0, duration_s=2.0)
    pos, r, phase = E.target_frame(0.5, (0.0, 0.0), (100.0, 50.0), timing, 10.0, 3.0)
    assert phase == "move" and pos == pytest.approx((50.0, 25.0)) and r == 10.0
    pos, r, phase = E.target_frame(0.25, (0.0, 0.0), (100.0, 0.0), timing, 10.0, 3.0)
    assert pos[0] == pytest.approx(100 * (10 * 0.25**3 - 15 * 0.25**4 + 6 * 0.25**5))  # slow start
    # on the target: expand to 1.5x over half the duration, contract to the inner radius, then still
    assert E.target_frame(1.5, (0.0, 0.0), (100.0, 50.0), timing, 10.0, 3.0) == ((100.0, 50.0), 12.5,
                                                                                  "expand")
    _, r, phase = E.target_frame(2.99, (0.0, 0.0), (100.0, 50.0), timing, 10.0, 3.0)
    assert phase == "contract" and r == pytest.approx(3.0, abs=0.2)
    assert E.target_frame(3.2, (0.0, 0.0), (100.0, 50.0), timing, 10.0, 3.0) == ((100.0, 50.0), 3.0, "still")
    # the first target appears where it is (no move)
    assert E.target_frame(0.0, None, (7.0, 8.0), timing, 10.0, 3.0) == ((7.0, 8.0), 10.0, "expand")


def test_the_error_is_the_angle_between_gaze_and_target():
    g = DISPLAY.geometry()
    one_deg = float(g.radius(1.0))
    assert E.target_error_deg([(240 + one_deg, 135.0)] * 3, (240.0, 135.0), g) == pytest.approx(1.0)
    # mean of the per-sample errors (as iohub), not the error of the mean sample
    assert E.target_error_deg([(240 + one_deg, 135.0), (240 - one_deg, 135.0)], (240.0, 135.0), g) == \
        pytest.approx(1.0)
    assert E.target_error_deg([], (240.0, 135.0), g) == math.inf


def test_instructions_come_from_the_keys_and_the_gaze_source():
    mouse = E.instructions_text(5, mouse_is_gaze=True, calibrates=False)
    assert "mouse pointer" in mouse and "4 other places" in mouse and "Press SPACE to start" in mouse
    assert "Escape stops" in mouse and "calibrates" not in mouse
    eyes = E.instructions_text(9, mouse_is_gaze=False, calibrates=True)
    assert "with your eyes" in eyes and "8 other places" in eyes and "calibrates itself" in eyes
    assert "mouse" not in eyes


def _targets(*errors):
    return [{"x_px": 1.0, "y_px": 2.0, "error_deg": e, "n_samples": 10} for e in errors]


def test_a_failure_shows_the_errors_and_the_keys():
    res = E.attempt_result(_targets(0.5, 1.0, math.inf), 1.5)  # within the limit, but a target saw no gaze
    assert not res["passed"] and res["targets_without_gaze"] == 1
    assert (res["mean_error_deg"], res["max_error_deg"]) == (0.75, 1.0)  # of the targets with gaze
    text = E.result_text(E.attempt_result(_targets(0.5, 3.5), 1.5), 1.5, can_repeat=True)
    assert "Mean error 2.00° (limit 1.5°), worst target 3.50°" in text and "1: 0.50°   2: 3.50°" in text
    assert "R: repeat" in text and "S: skip" in text and "E: end the session" in text
    shown = E.result_text(res, 1.5, can_repeat=False)
    assert "R: repeat" not in shown and "worst target 1.00°; 1 target(s) without gaze." in shown
    assert "3: no gaze" in shown
    assert E.attempt_result(_targets(0.5, 3.5), None)["passed"]  # no limit: measured, never failed
    note = "Calibration: the tracker's calibration returned 'CALIBRATION_ABORTED'."
    noted = E.result_text(res, 1.5, True, note)
    assert "no gaze\nCalibration: the tracker's calibration returned 'CALIBRATION_ABORTED'.\n" in noted


def test_the_stored_summary_is_json_without_infinities():
    a0 = E.attempt_result(_targets(math.inf, 9.0), 2.0)
    a1 = E.attempt_result(_targets(0.2, 0.4), 2.0)
    s = E.summary([a0, a1], "passed", 2.0, {"done": True})
    again = json.loads(json.dumps(s, allow_nan=False))
    assert again["status"] == "passed" and again["n_attempts"] == 2
    assert again["error_deg"] == pytest.approx(0.3) and again["max_error_deg"] == pytest.approx(0.4)
    first = again["attempts"][0]
    assert first["targets"][0]["error_deg"] is None and first["mean_error_deg"] == 9.0
    assert again["attempts"][0]["targets_without_gaze"] == 1 and not again["attempts"][0]["passed"]
    nothing = E.summary([E.attempt_result(_targets(math.inf), 2.0)], "skipped", 2.0, {"done": True})
    assert nothing["error_deg"] is None and json.dumps(nothing, allow_nan=False)


class FakeScreen:
    """The window side of the procedure: keys from a script, texts and events recorded."""

    def __init__(self, keys):
        self.keys, self.texts, self.events, self.t = list(keys), [], [], 0.0
        self.win = type("Win", (), {"flip": lambda _self: None, "size": (480, 270)})()

    def screen(self) -> E.Screen:
        def wait_key(allowed):
            while self.keys:
                k = self.keys.pop(0)
                if k in allowed:
                    return k
            raise AssertionError(f"no key left among {allowed}")

        def now():
            self.t += 0.1
            return self.t

        return E.Screen(win=self.win, visual=None, show_text=lambda text, dim: self.texts.append(text),
                        wait_key=wait_key, poll_keys=lambda keys: [], now=now,
                        emit=lambda name, **info: self.events.append((name, info)))


def _tracker(monkeypatch, errors, **spec):
    """A MouseGaze tracker whose validations measure ``errors`` (one list per attempt) in turn."""
    tr = E.EyeTracker("device", {"device": E.MOUSE_GAZE_DEVICE, "calibrate": True, **spec})
    runs = iter(errors)
    monkeypatch.setattr(tr, "validate", lambda screen, display, attempt: E.attempt_result(
        _targets(*next(runs)), spec.get("max_validation_error_deg")))
    return tr


def test_repeat_skip_and_end_after_a_failed_validation(monkeypatch):
    fs = FakeScreen(["space", "r", "space", "s"])  # fail, repeat, fail, skip
    tr = _tracker(monkeypatch, [[9.0, 9.0], [4.0, 6.0]], max_validation_error_deg=1.0, max_attempts=3)
    res = tr.calibrate_and_validate(fs.screen(), DISPLAY)
    assert res["status"] == "skipped" and res["n_attempts"] == 2 and res["error_deg"] == pytest.approx(5.0)
    assert res["calibration"]["reason"].startswith("not needed")  # MouseGaze: the mouse is the gaze
    assert [n for n, _ in fs.events].count("validation_instructions") == 2
    fs = FakeScreen(["space", "r", "space", "e"])  # the second failure ends the session: one line
    tr = _tracker(monkeypatch, [[9.0], [3.0]], max_validation_error_deg=1.0, max_attempts=2)
    with pytest.raises(PresentationError) as exc:
        tr.calibrate_and_validate(fs.screen(), DISPLAY)
    assert str(exc.value) == ("eye-tracker validation failed (mean error 3.00°, limit 1°, 2 attempt(s)): the "
                              "experimenter ended the session")
    assert "R: repeat" not in fs.texts[-1]  # no attempt left to repeat
    fs = FakeScreen(["escape", "r", "space"])  # Escape at the instructions: a stopped attempt, then a pass
    tr = _tracker(monkeypatch, [[0.3]], max_validation_error_deg=1.0)
    res = tr.calibrate_and_validate(fs.screen(), DISPLAY)
    assert res["status"] == "passed" and res["n_attempts"] == 2 and res["attempts"][0]["aborted"]
    assert "The check was stopped." in fs.texts[1]


class FakeDevice:
    def __init__(self, reply):
        self.reply = reply

    def runSetupProcedure(self, args):  # noqa: N802 - iohub's name
        assert "target_attributes" in args and "animate" in args["target_attributes"]
        if isinstance(self.reply, Exception):
            raise self.reply
        return self.reply


@pytest.mark.parametrize("reply, done, reason", [
    ({"RESULT": "CALIBRATION_OK"}, True, None),
    ({"RESULT": "CALIBRATION_ABORTED"}, False, "the tracker's calibration returned 'CALIBRATION_ABORTED'"),
    (KeyError("target_attributes"), False, "the tracker's calibration failed: 'target_attributes'"),
])
def test_a_real_trackers_calibration_never_raises(monkeypatch, reply, done, reason):
    complete = {"target_attributes": {"animate": {"enable": True}}}
    monkeypatch.setattr(E, "calibration_args", lambda *a: complete)
    tr = E.EyeTracker("device", {"device": "eyetracker.hw.sr_research.eyelink.EyeTracker", "calibrate": True})
    tr._device, tr._win = FakeDevice(reply), type("Win", (), {"flip": lambda _self: None})()
    got = tr.calibrate(DISPLAY)
    assert got["done"] is done and got.get("reason") == reason


def test_a_failed_calibration_is_shown_with_the_validation_result(monkeypatch):
    fs = FakeScreen(["space", "s"])
    tr = _tracker(monkeypatch, [[5.0]], max_validation_error_deg=1.0)
    tr.spec["device"] = "eyetracker.hw.sr_research.eyelink.EyeTracker"  # a real tracker: it calibrates
    aborted = {"done": False, "reason": "the tracker's calibration returned 'CALIBRATION_ABORTED'"}
    monkeypatch.setattr(tr, "calibrate", lambda display: aborted)
    res = tr.calibrate_and_validate(fs.screen(), DISPLAY)
    assert "calibrates itself" in fs.texts[0] and "with your eyes" in fs.texts[0]
    assert "Calibration: the tracker's calibration returned 'CALIBRATION_ABORTED'." in fs.texts[1]
    assert res["status"] == "skipped" and res["calibration"]["done"] is False
    assert ("calibration", {"attempt": 0, "done": False, "reason": "the tracker's calibration returned "
                                                                   "'CALIBRATION_ABORTED'"}) in fs.events


def stored_validation(tmp_path, record: dict) -> tuple[float | None, dict]:
    """Run a simulated session (seed001_pilot) whose window reported ``record`` as ``facts["validation"]``;
    return what the study database holds: ``sessions.validation_deg`` and the ``validation`` event's JSON."""
    import sqlite3
    from pathlib import Path

    from studyapp.runner.observer import SimulatedObserver
    from studyapp.runner.protocol import load_protocol
    from studyapp.runner.session import ground_truth_stimuli, run_session

    p = load_protocol(Path(__file__).resolve().parents[1] / "protocols" / "seed001_pilot.yaml",
                      stimuli_dir=tmp_path / "none", check_renderers=False)

    def window_like(stimuli, display):
        obs = SimulatedObserver(p, "P1", 0, ground_truth_stimuli(p, stimuli))
        opened = obs.open
        obs.open = lambda disp: {**opened(disp), "validation": record}
        return obs

    run_session(p, "P1", tmp_path / "s.db", window_like, allow_declared=True)
    con = sqlite3.connect(tmp_path / "s.db")
    try:
        (deg,), = con.execute("SELECT validation_deg FROM sessions").fetchall()
        (detail,), = con.execute("SELECT detail FROM events WHERE kind = 'validation'").fetchall()
    finally:
        con.close()
    return deg, json.loads(detail)


@pytest.mark.parametrize("errors, status", [([0.2, 0.4], "passed"), ([math.inf], "skipped")])
def test_the_result_is_stored_with_the_session(tmp_path, errors, status):
    """``facts["validation"]`` of the window reaches the study database: ``sessions.validation_deg`` (the
    last attempt's mean error; left empty when no gaze came) and a ``validation`` event with the whole record."""
    record = E.summary([E.attempt_result(_targets(*errors), 1.0)], status, 1.0, {"done": True})
    deg, detail = stored_validation(tmp_path, record)
    assert deg == (pytest.approx(0.3) if status == "passed" else None)
    assert detail == record and detail["status"] == status
