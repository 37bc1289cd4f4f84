"""GUI tests of the PsychoPy presenter: a real window under a private Xvfb, real key presses from xdotool.

Each test starts its own Xvfb (``tests/gui/xvfb.py``), runs ``tests/gui/drive_presenter.py`` in a subprocess
with DISPLAY set, waits for the presenter's events and injects keys. It checks the recorded answers against
the keys pressed, that reaction times are positive, and that the back-buffer screenshots show the stimulus
pixels and the fixation mark at the gaze point. No timing assertions: Xvfb has no vsync.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent / "gui"))
import psychopy  # noqa: E402,F401 - the GUI tests need it: a missing install is a failure, not a skip
from xvfb import Driver, Xvfb, missing_tools  # noqa: E402


@pytest.fixture(autouse=True)
def _gui_tools_installed():
    assert not missing_tools(), f"GUI tests need {missing_tools()} (Debian: xvfb, xdotool; ./run installs them)"

WIN_W, WIN_H = 640, 480
IMG_W, IMG_H = 320, 240
RED = (255, 0, 0)
DISPLAY = {"width_px": WIN_W, "height_px": WIN_H, "width_cm": 30.0, "distance_cm": 60.0}


def blocks_image(path: Path, seed: int, size=(IMG_W, IMG_H)) -> np.ndarray:
    """A stimulus of 16x16-pixel blocks of random colours (no pure red, so the fixation mark stands out)."""
    rng = np.random.default_rng(seed)
    w, h = size
    cells = rng.integers(0, 200, (h // 16, w // 16, 3), dtype=np.uint8)
    arr = np.repeat(np.repeat(cells, 16, axis=0), 16, axis=1)
    Image.fromarray(arr).save(path)
    return arr


def shot_of(shots: Path, trial: int, stim: int) -> np.ndarray:
    files = sorted(shots.glob(f"trial{trial:04d}_stim{stim}_*.png"))
    assert files, (
        f"no screenshot for trial {trial} stimulus {stim}: {sorted(p.name for p in shots.iterdir())}"
    )
    return np.asarray(Image.open(files[0]).convert("RGB"))


SCALE = WIN_W / IMG_W  # the stimulus covers the window (the display), here upscaled 2x from the render
TEXT_H = 14  # the presenter's text height in a 480-pixel-high window (max(14, 480 / 36))
BAND = round(1.6 * TEXT_H)  # the key reminder's band


def assert_shows(shot: np.ndarray, img: np.ndarray, fixation: tuple[int, int], rng_seed: int = 0) -> None:
    """The stimulus covers the window at the size the geometry predicts (SCALE): pixels of ``shot`` at 200
    random image positions inside the 16-px blocks (away from block edges, where the upscaling interpolates),
    the fixation cross and the corner label equal the stimulus; the pixels at the fixation point are the
    fixation colour; the stimulus reaches every edge of the window."""
    assert shot.shape == (WIN_H, WIN_W, 3)
    rng = np.random.default_rng(rng_seed)
    fx, fy = fixation
    checked = 0
    for x, y in zip(rng.integers(0, IMG_W, 2000), rng.integers(0, IMG_H, 2000)):
        if not (2 <= x % 16 <= 13 and 2 <= y % 16 <= 13) or max(abs(x - fx), abs(y - fy)) <= 10 or y < 24 \
                or SCALE * y > WIN_H - BAND - 2:  # the key reminder's band
            continue
        wx, wy = int(SCALE * x + 1), int(SCALE * y + 1)
        np.testing.assert_array_equal(shot[wy, wx], img[y, x], err_msg=f"image pixel ({x}, {y})")
        checked += 1
        if checked == 200:
            break
    assert checked == 200
    wfx, wfy = int(SCALE * fx), int(SCALE * fy)
    for dx, dy in ((-1, -1), (0, 0), (-6, 0), (5, -1), (0, 5), (-1, -7)):
        np.testing.assert_array_equal(shot[wfy + dy, wfx + dx], RED, err_msg=f"fixation pixel offset ({dx}, {dy})")
    for wx, wy, x, y in ((WIN_W - 3, WIN_H - 3, IMG_W - 2, IMG_H - 2), (2, WIN_H - 3, 1, IMG_H - 2)):
        # under the key reminder's dark band (70 % opaque) at the bottom edge
        np.testing.assert_allclose(shot[wy, wx], 0.3 * img[y, x], atol=2, err_msg="the stimulus does not "
                                   "cover the window under the key reminder")


def stim(cond: str, *frames: Path, fps: float = 0.0) -> dict:
    return {"condition": cond, "frames": [str(f) for f in frames], "fps": fps}


def yes_no_still(index: int, image: Path, fix: tuple[int, int], black_s: float) -> dict:
    return {
        "index": index,
        "family": "yes_no",
        "stimuli": [stim("GT", image)],
        "question": "GT?",
        "answer_keys": {"y": "yes", "n": "no"},
        "fixation_px": fix,
        "black_before_s": black_s,
    }


def test_gui_trials_keys_screenshots_and_pause(tmp_path):
    a = blocks_image(tmp_path / "a.png", 1)
    b = blocks_image(tmp_path / "b.png", 2)
    c = blocks_image(tmp_path / "c.png", 3)
    seq = [blocks_image(tmp_path / f"s{i}.png", 10 + i) for i in range(3)]
    fix = (100, 80)
    shots = tmp_path / "shots"
    t_2afc = {
        "index": 0,
        "family": "2afc",
        "stimuli": [stim("GT", tmp_path / "a.png"), stim("VaFR", tmp_path / "b.png")],
        "question": "Which looks better?",
        "answer_keys": {"a": "A", "b": "B"},
        "switch_keys": {"left": 0, "right": 1},
        "fixation_px": fix,
        "black_before_s": 0.2,
        "progress": [1, 4],
    }
    t_seq = {
        "index": 1,
        "family": "yes_no",
        "stimuli": [stim("EC", *(tmp_path / f"s{i}.png" for i in range(3)), fps=10.0)],
        "question": "Is this sequence the ground truth?",
        "answer_keys": {"y": "yes", "n": "no"},
        "fixation_px": fix,
        "duration_s": 0.3,
        "black_before_s": 0.2,
        "progress": [2, 4],
    }
    t_pref = {
        "index": 2,
        "family": "preference",
        "stimuli": [
            stim("m1", tmp_path / "a.png"),
            stim("m2", tmp_path / "b.png"),
            stim("m3", tmp_path / "c.png"),
        ],
        "question": "Pick your top two",
        "answer_keys": {"1": "0", "2": "1", "3": "2", "space": ""},
        "switch_keys": {"z": 0, "x": 1, "c": 2},
        "fixation_px": fix,
        "n_picks": 2,
        "black_before_s": 0.2,
    }
    t_esc = yes_no_still(3, tmp_path / "c.png", fix, 0.1)
    t_esc_black = yes_no_still(4, tmp_path / "c.png", fix, 1.0)
    spec = {
        "display": DISPLAY,
        "presenter": {"screenshot_dir": str(shots)},
        "steps": [
            {"instructions": "Welcome"},
            {"prefetch": t_seq},
            {"trial": t_2afc},
            {"preload": t_seq},
            {"prefetch": t_pref},
            {"trial": t_seq},
            {"trial": t_pref},
            {"trial": t_esc},
            {"trial": t_esc_black},
        ],
    }
    with Xvfb() as x:
        d = Driver(x, spec, tmp_path)
        try:
            for event, match, keys in [
                ("instructions", {}, ["space"]),
                ("onset", {"trial": 0, "stimulus": 0}, ["Right"]),
                ("onset", {"trial": 0, "stimulus": 1}, ["Left"]),
                ("onset", {"trial": 0, "stimulus": 0}, ["b"]),
                ("question", {"trial": 1}, ["n"]),
                ("onset", {"trial": 2, "stimulus": 0}, ["c"]),
                ("onset", {"trial": 2, "stimulus": 2}, ["3"]),
                ("pick", {"trial": 2}, ["x", "3", "1"]),  # "3" again is ignored; "1" is the second pick
                ("onset", {"trial": 3}, ["Escape"]),
                ("pause", {}, ["r"]),
                ("onset", {"trial": 3}, ["y"]),
                ("black", {"trial": 4}, ["Escape"]),  # during the black interval: paused before the onset
                ("pause", {}, ["r"]),
                ("onset", {"trial": 4}, ["n"]),
            ]:
                d.wait_for(event, **match)
                x.key(*keys)
            result = d.finish()
        finally:
            d.kill()
    assert result["facts"]["keyboard_backend"] == "ptb"
    assert result["facts"]["window_size_px"] == [WIN_W, WIN_H]
    trials = result["trials"]
    assert [t["index"] for t in trials] == [0, 1, 2, 3, 3, 4, 4]
    assert [t["answers"] for t in trials] == [["B"], ["no"], ["2", "0"], [], ["yes"], [], ["no"]]
    assert [t["escaped"] for t in trials] == [False, False, False, True, False, True, False]
    assert [t["switches"] for t in trials] == [2, 0, 2, 0, 0, 0, 0]
    assert result["pauses"] == ["resume", "resume"]
    assert [bool(i.get("escaped_in_black")) for i in result["trial_info"]] == [False] * 5 + [True, False]
    for t in trials:
        assert t["dropped_frames"] >= 0 and t["gaze_left_fovea"] is None
        assert t["onset_s"] is None if t is trials[5] else t["onset_s"] > 0
        if not t["escaped"]:
            assert t["rt_s"] > 0
    seq_info = result["trial_info"][1]  # the key was pressed only once the question had replaced the sequence
    assert trials[1]["rt_s"] > seq_info["question_shown"] - seq_info["onsets"][0][1] > 0
    assert_shows(shot_of(shots, 0, 0), a, fix)
    assert_shows(shot_of(shots, 0, 1), b, fix)
    assert_shows(shot_of(shots, 1, 0), seq[0], fix)
    assert_shows(shot_of(shots, 2, 2), c, fix)
    # trial 0 was shown A, B, A: three onsets, alternating stimuli
    assert [o[0] for o in result["trial_info"][0]["onsets"]] == [0, 1, 0]


def test_gui_mousegaze_flags_gaze_outside_fovea_and_pause_end(tmp_path):
    """iohub's MouseGaze follows the pointer moved by xdotool: a gaze kept on the fixation point leaves the
    trial unflagged, a gaze moved 9 degrees away flags it; Escape then "E" ends the session (saved as
    "end")."""
    blocks_image(tmp_path / "a.png", 1)
    fix = (100, 80)
    trials = [yes_no_still(i, tmp_path / "a.png", fix, 0.5) for i in range(3)]
    spec = {
        "display": DISPLAY,
        "presenter": {"eyetracker": "mousegaze", "fovea_deg": 2.5, "gaze_log": str(tmp_path / "gaze.csv")},
        "steps": [{"trial": t} for t in trials],
    }
    fwx, fwy = SCALE * fix[0], SCALE * fix[1]  # the fixation point in window pixels (stimulus upscaled)
    with Xvfb() as x:
        d = Driver(x, spec, tmp_path)
        try:
            facts = d.wait_for("opened")
            assert facts["eyetracker"] == {"kind": "mousegaze", "ok": True}
            wx, wy = facts["window_pos_px"]

            def gaze_at(px, py):  # window pixel -> screen pixel under the pointer
                x.xdotool("mousemove", str(int(wx + px)), str(int(wy + py)))

            for i, far in enumerate((False, True)):
                d.wait_for("black", trial=i)
                gaze_at(fwx, fwy)
                d.wait_for("onset", trial=i)
                if far:
                    gaze_at(fwx + 200, fwy)  # 200 window px = 9.0 deg at 22.3 px/deg
                time.sleep(0.4)
                x.key("ny"[i])
            d.wait_for("onset", trial=2)
            x.key("Escape")
            d.wait_for("pause")
            x.key("e")
            result = d.finish()
        finally:
            d.kill()
    got = result["trials"]
    assert [t["answers"] for t in got] == [["no"], ["yes"], []]
    assert [t["gaze_left_fovea"] for t in got[:2]] == [False, True]
    assert got[2]["escaped"] is True and result["pauses"] == ["end"]
    g0 = np.array(result["trial_info"][0]["gaze"])
    g1 = np.array(result["trial_info"][1]["gaze"])
    assert len(g0) > 3 and len(g1) > 3
    np.testing.assert_allclose(g0[:, 1:], [[fwx, fwy]] * len(g0), atol=1.0)
    np.testing.assert_allclose(g1[-1, 1:], [fwx + 200, fwy], atol=1.0)
    logged = np.loadtxt(tmp_path / "gaze.csv", delimiter=",", skiprows=1)  # the same samples, made durable
    assert (tmp_path / "gaze.csv").read_text().startswith("trial,t_s,x_px,y_px\n")
    np.testing.assert_allclose(logged[: len(g0), 1:], g0, atol=1e-2)
    np.testing.assert_array_equal(
        logged[:, 0], [0] * len(g0) + [1] * len(g1) + [2] * (len(logged) - len(g0) - len(g1))
    )


def _open_refusal(x: Xvfb, screen: int, pythonpath: str) -> list[str]:
    """Open a presenter on ``screen`` in a subprocess; return the PresentationError line(s) it printed."""
    code = (
        "from studyapp.presentation.psychopy_window import PsychoPyPresenter, PresentationError\n"
        "from data_schema.geometry import Display\n"
        f"try:\n    PsychoPyPresenter().open(Display(640, 480, 30.0, 60.0, screen={screen}))\n"
        "except PresentationError as e:\n    print('REFUSED', e)\n"
    )
    env = dict(x.env, PYTHONPATH=pythonpath)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60)
    return [ln for ln in out.stdout.splitlines() if ln.startswith("REFUSED")] or [out.stderr[-2000:]]


def test_gui_refuses_a_keyboard_without_psychtoolbox_and_a_missing_screen(tmp_path):
    """If psychtoolbox cannot be imported, PsychoPy silently falls back to its 'event' keyboard; asked for a
    screen that does not exist, it silently uses screen 0: open() refuses both."""
    fake = tmp_path / "fake" / "psychtoolbox"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text('raise ImportError("simulated: libjack missing")\n')
    with Xvfb() as x:
        no_ptb = _open_refusal(x, 0, f"{fake.parent}{os.pathsep}{x.env['PYTHONPATH']}")
        screen_1 = _open_refusal(x, 1, x.env["PYTHONPATH"])
    assert no_ptb == [
        "REFUSED keyboard backend is 'event', not 'ptb': psychtoolbox did not load (on Debian "
        "install libjack-jackd2-0); refusing to run with imprecise reaction times"
    ]
    assert screen_1 == ["REFUSED display.screen=1 does not exist: this machine has 1 screen(s), 0..0"]


LONG_QUESTION = ("Is the quality of what you just saw acceptable for exploring this scene on a headset for a "
                 "whole afternoon, considering flicker, blur in the periphery and any shimmering edges? "
                 "Press Y for yes or N for no, then wait for the next scene.")


def test_gui_question_text_is_laid_out_for_a_small_window_and_never_clipped(tmp_path):
    """A 320x180 display (seed 003's 256x144 render covers it): the question shown in the black interval is
    wrapped and sized for the window, and every one of its pixels lies inside it."""
    img = blocks_image(tmp_path / "a.png", 1, size=(256, 144))
    shots = tmp_path / "shots"
    trial = yes_no_still(0, tmp_path / "a.png", (128, 72), 0.3)
    trial["question"] = LONG_QUESTION
    trial["progress"] = [7, 50]
    spec = {"display": {"width_px": 320, "height_px": 180, "width_cm": 30.0, "distance_cm": 60.0},
            "presenter": {"screenshot_dir": str(shots)}, "steps": [{"trial": trial}]}
    with Xvfb() as x:
        d = Driver(x, spec, tmp_path)
        try:
            d.wait_for("onset", trial=0)
            x.key("y")
            result = d.finish()
        finally:
            d.kill()
    layout = result["text_layout"]["0"]
    assert layout["window_px"] == [320, 180]
    w, h = layout["text_box_px"]
    assert w <= 0.9 * 320 + 1 and h <= 0.8 * 180 + 1  # wrapped and shrunk to fit
    black = np.asarray(Image.open(sorted(shots.glob("trial0000_black_*.png"))[0]).convert("RGB")).astype(int)
    ink = black.max(axis=2) > 40
    ys, xs = np.nonzero(ink)
    assert len(xs) > 500  # the question is there
    assert xs.min() > 0 and xs.max() < 319 and ys.min() > 0 and ys.max() < 179  # and nowhere cut by the edges
    stim = np.asarray(Image.open(sorted(shots.glob("trial0000_stim0_*.png"))[0]).convert("RGB"))
    s = 320 / 256  # the stimulus covers the 320x180 window
    for x0, y0 in ((40, 40), (200, 100), (250, 120)):  # (above the key reminder's band)
        if 2 <= x0 % 16 <= 13 and 2 <= y0 % 16 <= 13:
            np.testing.assert_array_equal(stim[int(s * y0 + 1), int(s * x0 + 1)], img[y0, x0])
    assert result["trials"][0]["answers"] == ["yes"]


def _band_ink(shot: np.ndarray, y0: int, y1: int) -> int:
    """Bright text pixels in rows ``y0:y1`` (light grey: the stimulus stays below 200, the practice tag is
    yellow)."""
    return int((shot[y0:y1].min(axis=2) > 205).sum())


def test_gui_break_countdown_practice_label_and_key_reminders(tmp_path):
    """What a participant sees (issue 26, item 6): a break counts its seconds down, a key pressed meanwhile
    does not end it, then SPACE does; a practice trial says "practice"; a reference shows its label over the
    stimulus for its whole duration; the key reminder band sits at the bottom, at the top, or is off."""
    a = blocks_image(tmp_path / "a.png", 1)
    b = blocks_image(tmp_path / "b.png", 2)
    seq = [blocks_image(tmp_path / f"s{i}.png", 10 + i) for i in range(3)]
    fix = (100, 80)
    shots = tmp_path / "shots"
    practice = yes_no_still(0, tmp_path / "a.png", fix, 0.1) | {"kind": "practice"}
    reference = {"index": 1, "family": "yes_no", "kind": "reference", "label": "This is the ground truth",
                 "stimuli": [stim("GT", *(tmp_path / f"s{i}.png" for i in range(3)), fps=5.0)],
                 "question": "", "answer_keys": {}, "fixation_px": fix, "duration_s": 0.6,
                 "black_before_s": 0.1}
    top = {"index": 2, "family": "2afc",
           "stimuli": [stim("GT", tmp_path / "a.png"), stim("X", tmp_path / "b.png")], "question": "Which?",
           "answer_keys": {"1": "A", "2": "B"}, "switch_keys": {"left": 0, "right": 1},
           "fixation_px": fix, "black_before_s": 0.1, "progress": [1, 2], "key_reminder": "top"}
    off = yes_no_still(3, tmp_path / "b.png", fix, 0.1) | {"key_reminder": "off", "progress": [2, 2]}
    spec = {"display": DISPLAY, "presenter": {"screenshot_dir": str(shots)},
            "steps": [{"rest": "Take a short break.", "seconds": 2}, {"trial": practice},
                      {"trial": reference}, {"trial": top}, {"trial": off}]}
    with Xvfb() as x:
        d = Driver(x, spec, tmp_path)
        try:
            assert d.wait_for("rest")["left_s"] == 2
            x.key("space")  # during the countdown: ignored
            assert d.wait_for("rest")["left_s"] == 1
            assert d.wait_for("rest")["left_s"] == 0
            x.key("space")
            for event, match, key in [("onset", {"trial": 0}, "y"), ("onset", {"trial": 2}, "2"),
                                      ("onset", {"trial": 3}, "n")]:
                d.wait_for(event, **match)
                x.key(key)
            result = d.finish()
        finally:
            d.kill()
    assert [t["answers"] for t in result["trials"]] == [["yes"], [], ["B"], ["no"]]
    # the break: "2 s", "1 s", then "press SPACE to continue" (each screen differs from the one before)
    rest = [np.asarray(Image.open(f).convert("RGB")).astype(int) for f in
            sorted(shots.glob("break_*.png"), key=lambda f: int(f.stem.rsplit("_", 1)[1]))]
    assert [f.stem.split("_")[1] for f in sorted(shots.glob("break_*.png"),
                                                 key=lambda f: int(f.stem.rsplit("_", 1)[1]))] == \
        ["2s", "1s", "continue"]
    assert all(np.abs(rest[i] - rest[i + 1]).sum() > 1000 for i in range(2))
    # practice: the tag at the top right, the reminder band at the bottom (dimmed stimulus, bright text)
    shot = shot_of(shots, 0, 0).astype(int)
    tag = shot[:3 * TEXT_H, WIN_W // 2:]
    assert ((tag[..., 0] > 240) & (tag[..., 1] > 200) & (tag[..., 2] < 180)).sum() > 30  # yellow "practice"
    assert _band_ink(shot, WIN_H - BAND, WIN_H) > 50 and _band_ink(shot, 0, BAND) == 0
    np.testing.assert_allclose(shot[WIN_H - 3, 2], 0.3 * a[IMG_H - 2, 1], atol=2)
    # the reference: its label over the stimulus (white: the stimulus has no value over 200), no keys, no band
    shot = shot_of(shots, 1, 0).astype(int)
    assert (shot[:3 * TEXT_H, WIN_W // 4:3 * WIN_W // 4].min(axis=2) > 230).sum() > 50
    assert _band_ink(shot, WIN_H - BAND, WIN_H) == 0
    np.testing.assert_array_equal(shot[WIN_H - 3, 2], seq[0][IMG_H - 2, 1])
    # key_reminder top: the band at the top, the bottom edge is the stimulus itself
    shot = shot_of(shots, 2, 0).astype(int)
    assert _band_ink(shot, 0, BAND) > 50 and _band_ink(shot, WIN_H - BAND, WIN_H) == 0
    np.testing.assert_array_equal(shot[WIN_H - 3, WIN_W - 3], a[IMG_H - 2, IMG_W - 2])
    # key_reminder off: no band anywhere
    shot = shot_of(shots, 3, 0).astype(int)
    assert _band_ink(shot, WIN_H - BAND, WIN_H) == 0
    np.testing.assert_array_equal(shot[WIN_H - 3, 2], b[IMG_H - 2, 1])
