"""Replay shows what was seen, without a window (issue 26, item 5): the session's --scale and recorded layout,
the attempts Escape interrupted (recorded apart from the answer's frames, replayed and marked), the window
image as the window magnifies it, and sessions of an older studyapp (replayed as before, with one note). The
real window is compared in tests/test_replay_gui.py."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from crafted_db import craft, live_db, live_protocol
from studyapp.cli import main


def _replay(capsys, db, out, *extra, trial=0):
    capsys.readouterr()
    code = main([str(a) for a in ("replay", "--db", db, "--participant", "P1", "--trial", trial, "--out", out,
                                  "--serial", "--cache", out.parent / "cache", *extra)])
    return code, *capsys.readouterr()


def _escaping_observer(protocol, stimuli):
    """The simulated observer, whose first attempt at trial 0 is ended by Escape after its first two flips."""
    from studyapp.presentation.base import TrialResult
    from studyapp.runner.observer import SimulatedObserver
    from studyapp.runner.session import ground_truth_stimuli

    obs = SimulatedObserver(protocol, "P1", 0, ground_truth_stimuli(protocol, stimuli))
    present, escaped = obs.present, []

    def first_escaped(d):
        res = present(d)
        if d.index == 0 and not escaped:
            escaped.append(res.frames[:2])
            return TrialResult(answers=[], rt_s=math.nan, onset_s=math.nan, escaped=True, frames=res.frames[:2])
        return res

    obs.present, obs.pause = first_escaped, lambda: "resume"
    return obs


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """A simulated session at --scale 0.5 (renders 32 x 18 of the protocol's 64 x 36) whose trial 0 was
    interrupted once."""
    from studyapp.runner.protocol import load_protocol
    from studyapp.runner.session import run_session

    tmp = tmp_path_factory.mktemp("attempts")
    p = load_protocol(live_protocol(tmp / "proto", render_px=(64, 36)))
    db = tmp / "s.db"
    summary = run_session(p, "P1", db, lambda st, d: _escaping_observer(p, st), scale=0.5)
    assert summary.status == "completed"
    return db


def test_an_interrupted_attempt_is_kept_apart_from_the_answer(session):
    from data_schema.store import open_store

    with open_store(session) as st:
        attempts = st.attempts("P1", 0)
        answered = st.frames("P1", 0)
        layout = st.session_layout("P1-s1")
        assert st.attempts("P1", 1) == []
    assert len(attempts) == 1 and attempts[0]["session"] == "P1-s1" and len(attempts[0]["frames"]) == 2
    assert [f["frame"] for f in attempts[0]["frames"]] == [0, 1] and len(answered) == 6  # 2 stimuli x 3 frames
    assert layout["window_px"] == (320, 180) and layout["scale"] == 0.5
    assert {c: (r["backend"], [(v.eye, v.render_width, v.render_height) for v in r["views"]])
            for c, r in layout["conditions"].items()} == {"Ref": ("cpu", [("mono", 32, 18)]),
                                                          "LaFR": ("cpu", [("mono", 32, 18)])}


def test_replay_renders_at_the_sessions_scale_with_the_interrupted_attempt_marked(session, tmp_path, capsys):
    from studyapp.runner.live import window_image

    out = tmp_path / "rep"
    code, stdout, err = _replay(capsys, session, out)
    assert code == 0, err
    assert "2 interrupted" not in stdout and "(2 attempt(s), 1 interrupted by Escape)" in stdout
    f = pd.read_csv(out / "frames.csv")
    assert f["attempt"].tolist() == [1, 1] + [2] * 6 and f["interrupted"].tolist() == [1, 1] + [0] * 6
    assert [name.split("/")[-1] for name in f["file"]][:3] == ["interrupted1_frame_00000.png",
                                                               "interrupted1_frame_00001.png", "frame_00000.png"]
    assert set(f["session"]) == {"P1-s1"} and set(f["backend"]) == {"cpu"}
    for r in f.itertuples():
        own = np.asarray(Image.open(out / r.file))
        assert own.shape == (18, 32, 3)  # the session's render size (--scale 0.5), not the protocol's 64 x 36
        assert Image.open(out / "ground_truth" / f"{r.file.split('/')[-1]}").size == (32, 18)
        shown = np.asarray(Image.open(out / r.shown))
        assert r.shown == f"shown/{r.file.split('/')[-1]}" and shown.shape == (180, 320, 3)
        assert np.array_equal(shown, window_image((320, 180), _views(session, r.condition), [own]))
    flips = pd.read_csv(out / "flips.csv")
    assert flips["attempt"].tolist() == [1, 1] + [2] * 6
    assert flips["image"].tolist() == f["shown"].tolist()  # every simulated flip rendered a frame


def _views(db, condition):
    from data_schema.store import open_store

    with open_store(db) as st:
        return st.session_layout("P1-s1")["conditions"][condition]["views"]


def test_an_older_session_replays_as_before_with_one_note(tmp_path, capsys):
    db = live_db(live_protocol(tmp_path / "proto"), tmp_path / "old.db", layout=False)
    out = tmp_path / "rep"
    code, _, err = _replay(capsys, db, out)
    notes = [line for line in err.splitlines() if line.startswith("studyapp: note:")]
    assert code == 0 and len(notes) == 1, err
    assert "session P1-s1 recorded no window layout (an older studyapp): replayed as before, at 32x18" in notes[0]
    assert not (out / "shown").exists()
    f = pd.read_csv(out / "frames.csv")
    assert f["shown"].isna().all() and set(f["backend"]) == {"cpu"}


@pytest.mark.parametrize("table,where,changes,words", [
    ("events", {"kind": "live_layout"}, {"detail": '{"window_px": [320, 180], "conditions": {"LaFR": '
                                                    '{"backend": "tpu", "views": []}}}'},
     "session P1-s1: the record of its window layout is invalid"),
    ("events", {"kind": "live_layout"}, {"detail": json.dumps({"window_px": [320, 180], "conditions": {
        c: {"backend": "cpu", "views": [{"eye": "mono", "x0": 0, "y0": 0, "width": 320, "height": 180,
                                         "render_width": 0, "render_height": 18}]} for c in ("LaFR", "Ref")}})},
     "session P1-s1: the record of its window layout is invalid"),
    ("events", {"kind": "interrupted_attempt"}, {"detail": '{"participant": "P1", "trial": 0, "frames": [[1]]}'},
     "session P1-s1: the record of an interrupted attempt is invalid"),
])
def test_a_crafted_record_is_refused_in_one_line(tmp_path, capsys, table, where, changes, words):
    from data_schema.store import open_store

    db = live_db(live_protocol(tmp_path / "proto"), tmp_path / "s.db")
    with open_store(db, "write") as st:
        st.record_attempt("P1-s1", "P1", 0, [])
    assert craft(db, table, where, changes) == 1
    out = tmp_path / "rep"
    code, _, err = _replay(capsys, db, out)
    lines = [line for line in err.splitlines() if not line.startswith("frames:")]
    assert code == 2 and len(lines) == 1 and words in lines[0], err
    assert not out.exists()


def test_the_window_magnifies_each_eye_bilinearly_over_its_viewport():
    from data_schema.geometry import EyeView, eye_views
    from studyapp.runner.live import window_image

    img = np.array([[[0, 0, 0], [200, 100, 40]]], dtype=np.uint8)  # 2 x 1 pixels
    (view,) = eye_views((8, 2), (2, 1), 1)
    shown = window_image((8, 2), [view], [img])
    # pixel centres at texel coordinates -0.25, 0.0, 0.25, ... 1.25: clamped at the edges, linear between
    assert shown[0, :, 0].tolist() == [0, 0, 25, 75, 125, 175, 200, 200] and (shown[1] == shown[0]).all()
    left, right = EyeView("left", 0, 0, 4, 2, 2, 1), EyeView("right", 4, 0, 4, 2, 2, 1)  # side by side
    pair = window_image((8, 2), [left, right], [img, img[:, ::-1]])
    assert pair[0, :, 0].tolist() == [0, 50, 150, 200, 200, 150, 50, 0]
    assert np.array_equal(window_image((2, 1), [eye_views((2, 1), (2, 1), 1)[0]], [img]), img)
