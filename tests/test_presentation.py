"""Window-free tests of the PsychoPy presenter: placement geometry, frame timing, validation, lazy import."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from data_schema.geometry import Display, EyeView, Placement
from studyapp.presentation.base import Stimulus, TrialDisplay
from studyapp.presentation.trial_logic import (
    AnswerState,
    sequence_frame,
    stimulus_time,
    validate_trial,
)

ROOT = Path(__file__).resolve().parent.parent
sizes = st.integers(16, 5000)


@given(sizes, sizes, sizes, sizes)
def test_placement_fits_centres_and_maps_pixels(win_w, win_h, img_w, img_h):
    p = Placement.fit(win_w, win_h, img_w, img_h)
    w, h = p.size
    assert p.scale > 0
    assert p.left >= 0 and p.top >= 0 and p.left + w <= win_w + 1e-6 and p.top + h <= win_h + 1e-6
    # centred to within one pixel, and the image covers the window on at least one axis (scaled up or down:
    # a stimulus subtends the display's visual angle)
    assert abs((win_w - w) / 2 - p.left) < 1 and abs((win_h - h) / 2 - p.top) < 1
    assert math.isclose(w, win_w) or math.isclose(h, win_h)
    # image corners -> window corners of the drawn rectangle; pix units have the origin at the centre, y up
    assert p.image_to_window(0, 0) == (p.left, p.top)
    x1, y1 = p.image_to_window(img_w, img_h)
    assert math.isclose(x1, p.left + w) and math.isclose(y1, p.top + h)
    cx, cy = p.image_to_pix(img_w / 2, img_h / 2)
    assert math.isclose(cx, p.centre_pix[0], abs_tol=1e-9) and math.isclose(cy, p.centre_pix[1], abs_tol=1e-9)
    px, py = p.image_to_pix(0, 0)
    assert math.isclose(px, p.left - win_w / 2) and math.isclose(py, win_h / 2 - p.top)


def test_placement_native_size_is_pixel_exact_and_a_smaller_render_covers_the_window():
    p = Placement.fit(640, 480, 640, 480)
    assert (p.scale, p.left, p.top) == (1.0, 0, 0)
    assert p.image_to_window(10, 20) == (10, 20)
    q = Placement.fit(1920, 1080, 256, 144)  # seed 003's render on its 1920x1080 display
    assert q.scale == 7.5 and q.size == (1920, 1080) and (q.left, q.top) == (0, 0)


@given(st.floats(0, 100), st.sampled_from([10.0, 24.0, 30.0, 60.0]), st.integers(1, 500), st.booleans())
def test_sequence_frame_is_floor_of_elapsed_frames(t, fps, n, loop):
    k = sequence_frame(t, fps, n, loop)
    raw = math.floor(t * fps + 1e-6)
    assert 0 <= k < n
    assert k == (raw % n if loop else min(raw, n - 1)) or n == 1


def test_sequence_frame_values():
    # 30 fps sequence of 240 frames (8 s): frame boundaries every 1/30 s, held on the last frame after 8 s
    assert [sequence_frame(t, 30.0, 240, False) for t in (0.0, 0.0333, 1 / 30, 7.99, 8.0, 12.0)] == [
        0,
        0,
        1,
        239,
        239,
        239,
    ]
    assert [sequence_frame(t, 30.0, 240, True) for t in (8.0, 8.0 + 1 / 30, 16.0)] == [0, 1, 0]
    assert sequence_frame(3.0, 0.0, 1, True) == 0


def test_pixels_per_degree_matches_psychopy_flat_screen():
    d = Display(2560, 1440, 59.8, 57.0)
    expected = 2560 / 59.8 * 57.0 * math.tan(math.radians(1.0))
    assert math.isclose(d.ppd, expected)
    from psychopy import monitors
    from psychopy.tools import monitorunittools as mu

    mon = monitors.Monitor("t", width=59.8, distance=57.0)
    mon.setSizePix([2560, 1440])
    assert math.isclose(
        d.ppd, mu.deg2pix(np.array([[1.0, 0.0]]), mon, correctFlat=True)[0, 0], rel_tol=1e-9
    )


def _trial(**kw) -> TrialDisplay:
    img = (Path("a.png"),)
    base = dict(
        index=3,
        family="2afc",
        stimuli=(Stimulus("A", img), Stimulus("B", img)),
        question="?",
        answer_keys={"a": "A", "b": "B"},
        switch_keys={"left": 0, "right": 1},
    )
    return TrialDisplay(**{**base, **kw})


@pytest.mark.parametrize(
    "kw, message",
    [
        (
            dict(stimuli=(Stimulus("A", (Path("a.png"),)),)),
            "trial 3: family '2afc' needs 2..2 stimuli, got 1",
        ),
        (dict(family="yes_no"), "trial 3: family 'yes_no' needs 1..1 stimuli, got 2"),
        (dict(switch_keys={"x": 2}), "trial 3: switch key 'x' -> 2 is out of range 0..1"),
        (dict(family="preference", n_picks=3), "trial 3: n_picks=3 is out of range 1..2"),
        (
            dict(stimuli=(Stimulus("A", ()), Stimulus("B", (Path("b.png"),)))),
            "trial 3: stimulus 'A' has no frames",
        ),
        (
            dict(stimuli=(Stimulus("A", (Path("a"), Path("b"))), Stimulus("B", (Path("b"),)))),
            "trial 3: sequence 'A' needs fps > 0, got 0.0",
        ),
        (dict(duration_s=0.0), "trial 3: black_before_s must be >= 0 and duration_s > 0 or None"),
        (dict(answer_keys={}), "trial 3: a trial without answer keys needs a duration_s"),
    ],
)
def test_validate_trial_one_line_errors(kw, message):
    with pytest.raises(ValueError) as e:
        validate_trial(_trial(**kw))
    assert str(e.value) == message


def test_validate_trial_accepts_the_families():
    validate_trial(_trial())
    validate_trial(_trial(family="preference", n_picks=2, answer_keys={"1": "0", "2": "1", "space": ""}))
    validate_trial(
        _trial(
            family="yes_no",
            stimuli=(Stimulus("GT", (Path("a"), Path("b")), 30.0),),
            answer_keys={},
            switch_keys={},
            duration_s=8.0,
            label="this is the ground truth",
        )
    )


@pytest.mark.parametrize(
    "kw, message",
    [
        (dict(width_px=8), "display.width_px=8 is out of range: allowed [16, 16384]"),
        (dict(distance_cm=float("nan")), "display.distance_cm=nan is invalid: must be a finite number"),
        (dict(refresh_hz=0), "display.refresh_hz=0 is out of range: allowed [20, 1000]"),
        (dict(screen=-1), "display.screen=-1 is out of range: allowed [0, 16]"),
    ],
)
def test_display_one_line_errors(kw, message):
    """The display checks itself (data_schema.geometry, the ranges of data_schema.ranges)."""
    with pytest.raises(ValueError) as e:
        Display(**{**dict(width_px=640, height_px=480, width_cm=30.0, distance_cm=60.0), **kw})
    assert str(e.value) == message


def _run(code: str, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120, cwd=str(ROOT)
    )


def test_importing_the_window_module_does_not_import_psychopy():
    code = (
        "import sys; import studyapp.presentation.psychopy_window as m; "
        "print(sorted(k for k in sys.modules if k.split('.')[0] in ('psychopy', 'pyglet')))"
    )
    out = _run(code, dict(os.environ, PYTHONPATH=str(ROOT)))
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_open_without_a_display_is_a_one_line_error():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["PYTHONPATH"] = str(ROOT)
    code = (
        "from studyapp.presentation.psychopy_window import PsychoPyPresenter, PresentationError\n"
        "from data_schema.geometry import Display\n"
        "try:\n    PsychoPyPresenter().open(Display(640, 480, 30.0, 60.0))\n"
        "except PresentationError as e:\n    print('ERR', e)\n"
    )
    out = _run(code, env)
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("ERR")]
    assert len(line) == 1 and line[0].startswith("ERR cannot import PsychoPy's window modules: ")
    assert line[0].endswith("(no DISPLAY: run under a display or Xvfb, e.g. xvfb-run -a)")


def test_presenter_options_are_validated():
    from studyapp.presentation.psychopy_window import PsychoPyPresenter

    with pytest.raises(ValueError, match=r"^eyetracker='tobii' is not supported: use None, 'mousegaze', 'device' or 'pointer'$"):
        PsychoPyPresenter(eyetracker="tobii")
    with pytest.raises(ValueError, match=r"^fovea_deg=0\.0 is out of range: must be > 0$"):
        PsychoPyPresenter(fovea_deg=0.0)


@pytest.mark.parametrize(
    "kw, message",
    [
        (
            dict(answer_keys={"left": "A"}),
            "trial 3: key 'left' cannot both switch and answer (escape pauses)",
        ),
        (
            dict(answer_keys={"escape": "A"}),
            "trial 3: key 'escape' cannot both switch and answer (escape pauses)",
        ),
        (
            dict(family="preference", answer_keys={"f1": "2"}),
            "trial 3: answer key 'f1' -> '2' must be a stimulus index 0..1 or '' (stop picking)",
        ),
    ],
)
def test_validate_trial_key_errors(kw, message):
    with pytest.raises(ValueError) as e:
        validate_trial(_trial(**kw))
    assert str(e.value) == message


def test_answer_state_2afc_switches_then_answers():
    s = AnswerState(_trial())
    assert [
        s.press(k, t)
        for k, t in [
            ("right", 0.4),
            ("right", 0.5),
            ("q", 0.6),
            ("left", 0.9),
            ("b", 1.25),
            ("a", 1.5),
            ("escape", 2.0),
        ]
    ] == ["switch", None, None, "switch", "answer", None, "escape"]
    assert (s.current, s.switches, s.picks, s.rt_s) == (0, 2, ["B"], 1.25)


def test_answer_state_yes_no_no_switch_after_playback():
    s = AnswerState(
        _trial(
            family="yes_no", stimuli=(Stimulus("GT", (Path("a"),)),), answer_keys={"y": "yes"}, switch_keys={}
        )
    )
    assert s.press("y", 8.3, can_switch=False) == "answer" and (s.picks, s.rt_s) == (["yes"], 8.3)
    t = _trial()
    s = AnswerState(t)
    assert s.press("right", 1.0, can_switch=False) is None and s.current == 0


def test_answer_state_preference_picks_and_early_stop():
    stims = tuple(Stimulus(c, (Path(f"{c}.png"),)) for c in "pqrst")
    keys = {"f1": "0", "f2": "1", "f3": "2", "f4": "3", "f5": "4", "return": ""}
    t = _trial(
        family="preference", stimuli=stims, answer_keys=keys, switch_keys={"1": 0, "2": 1, "3": 2}, n_picks=2
    )
    s = AnswerState(t)
    assert [
        s.press(k, r)
        for k, r in [("return", 0.2), ("3", 0.5), ("f3", 1.0), ("f3", 1.1), ("f1", 2.0), ("f2", 2.5)]
    ] == [None, "switch", "pick", None, "answer", None]
    assert (s.picks, s.rt_s, s.switches) == (["2", "0"], 2.0, 1)
    s = AnswerState(t)
    assert [s.press(k, r) for k, r in [("f5", 0.7), ("return", 0.9)]] == ["pick", "answer"]
    assert (s.picks, s.rt_s) == (["4"], 0.9)


@given(
    st.lists(
        st.tuples(st.sampled_from(["1", "2", "3", "f1", "f2", "f3", "return", "x"]), st.floats(0.01, 10.0)),
        max_size=30,
    ),
    st.integers(1, 3),
)
def test_answer_state_preference_invariants(presses, n_picks):
    stims = tuple(Stimulus(c, (Path(f"{c}.png"),)) for c in "pqr")
    t = _trial(
        family="preference",
        stimuli=stims,
        answer_keys={"f1": "0", "f2": "1", "f3": "2", "return": ""},
        switch_keys={"1": 0, "2": 1, "3": 2},
        n_picks=n_picks,
    )
    s = AnswerState(t)
    shown, changes = 0, 0
    for k, r in presses:
        before = s.answered
        s.press(k, r)
        if not before and k in t.switch_keys and t.switch_keys[k] != shown:
            shown, changes = t.switch_keys[k], changes + 1
    assert len(set(s.picks)) == len(s.picks) <= n_picks
    assert s.switches == changes and s.current == shown
    if len(s.picks) == n_picks:
        assert s.answered
    if s.answered:
        assert s.picks and s.rt_s in [r for _, r in presses]


# ------------------------------------------------- one home for the geometry, a public drawing interface
@settings(max_examples=200, deadline=None)
@given(st.integers(64, 4096), st.integers(64, 4096), st.integers(16, 4096), st.integers(16, 4096),
       st.floats(0, 1), st.floats(0, 1))
def test_live_fixation_on_the_window_is_the_mapping_it_replaced(ww, wh, rw, rh, fu, fv):
    """LiveTrial's fixation fallback now maps through EyeView.to_window: bit for bit the old
    ``fix * window / render`` (the value used before geometry.py was its home), and to_render inverts it."""
    u, v = fu * rw, fv * rh
    got = EyeView("mono", 0, 0, ww, wh, rw, rh).to_window(u, v)
    assert got == (u * ww / rw, v * wh / rh)
    back = EyeView("mono", 0, 0, ww, wh, rw, rh).to_render(*got)
    assert back == pytest.approx((u, v), abs=1e-9 * max(rw, rh))


@settings(max_examples=300, deadline=None)
@given(st.floats(-3000, 3000), st.floats(-3000, 3000), st.floats(0.5, 5))
def test_fovea_check_is_the_geometry_s_eccentricity_and_agrees_with_the_old_linear_one(dx, dy, fovea_deg):
    """The gaze-outside-the-fovea check uses seed 001 Eq 3 from the fixation point (Display.outside_disc),
    the formula of the validation error; the old ``r > fovea_deg * ppd`` differed from it only in a band of
    (tan(f) - f tan(1 deg)) / c_r pixels at the rim (0.02 px at 2.5 deg on a 1920x1080 display 60 cm away)."""
    d = Display(1920, 1080, 53.0, 60.0)
    centre = (960.0, 540.0)
    point = (centre[0] + dx, centre[1] + dy)
    r = math.hypot(dx, dy)
    new = d.outside_disc(point, centre, fovea_deg)
    assert new == (d.geometry(centre).eccentricity(r) > fovea_deg)
    c_r = d.geometry().c_r
    rim_new, rim_old = math.tan(math.radians(fovea_deg)) / c_r, fovea_deg * d.ppd
    assert abs(rim_new - rim_old) < 3e-3 * rim_old
    if abs(r - rim_old) > abs(rim_new - rim_old) + 1e-9:
        assert new == (r > rim_old)


def test_live_trial_uses_only_the_presenter_s_public_drawing_interface():
    """live_window reaches into no private member of the presenter (before: _visual, _gaze_window_px,
    _exposure, _now, _frame_period, _draw_text, _progress_text, _draw_overlay, _save_shot, _emit, _info)."""
    import re

    src = (ROOT / "studyapp/presentation/live_window.py").read_text()
    assert re.findall(r"\b(?:p|presenter|self\.p)\._[a-z]\w*", src) == []


def test_a_switched_to_sequence_starts_at_its_first_frame():
    """The first flip after a switch showed the new sequence at the old one's elapsed time (a verification pass
    saw LaFR(1.8)'s screenshot at a later frame): the flip that becomes its onset shows frame 0."""
    fps, n = 30.0, 60
    # 1.5 s into stimulus A (onset 10.0), the participant switches: the next flip (11.5) is B's onset
    assert stimulus_time(11.5, 10.0, onset_pending=True) == 0.0
    assert sequence_frame(stimulus_time(11.5, 10.0, onset_pending=True), fps, n, loop=True) == 0
    # the flips after B's onset count from it; before any onset it is 0
    assert stimulus_time(11.6, 11.5, onset_pending=False) == pytest.approx(0.1)
    assert sequence_frame(stimulus_time(11.6, 11.5, False), fps, n, loop=True) == 3
    assert stimulus_time(5.0, None, onset_pending=False) == 0.0
