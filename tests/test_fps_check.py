"""The frame-rate check before the first trial of a live session, the refusal, --accept-slow and the console
flags (studyapp/runner/fpscheck.py, the session flow of studyapp/runner/session.py), with a fake renderer and
clock: each condition renders at a known rate."""

import math
import re

import pytest

from crafted_db import live_text
from data_schema.timing import format_fps
from studyapp.runner.fpscheck import (MAX_TOTAL_S, TooSlow, measure, sample_frames, seconds_per_cell,
                                      table_lines)

#: frames per second of each condition in the fake window
RATES = {"GT": 128.0, "LaFR": 16.0}  # frame times exact in binary


class FakeClock:
    def __init__(self):
        self.t = 5.0

    def __call__(self):
        return self.t


def fake_cell(clock, rates=RATES):
    """A window's ``fps_check_frames``: each frame of ``live`` takes 1/rate seconds; the gaze is 10 ms old."""
    def render_cell(live, seconds):
        def frame():
            clock.t += 1.0 / rates[live.condition]
            return clock.t, 0.5 / rates[live.condition], clock.t - 0.010
        return sample_frames(frame, clock, seconds)
    return render_cell


def protocol(tmp_path, extra=""):
    from studyapp.runner.protocol import load_protocol

    text = live_text(reference="GT", render_px=(32, 18))
    if extra:
        text = text.replace("  min_fps: 45\n", f"  min_fps: 45\n  {extra}\n")
    f = tmp_path / "live.yaml"
    f.write_text(text)
    return load_protocol(f)


def test_the_check_measures_each_condition_and_scene_at_its_rate(tmp_path):
    p = protocol(tmp_path)
    clock = FakeClock()
    rows = measure(p, 1.0, fake_cell(clock), 0.5)
    assert [(r["condition"], r["scene"]) for r in rows] == [("GT", "cornell"), ("LaFR", "cornell")]
    gt, lafr = rows
    assert gt["fps_p50"] == pytest.approx(128.0) and gt["fps_p5"] == pytest.approx(128.0)
    assert lafr["fps_p50"] == pytest.approx(16.0) and lafr["frames"] == 8  # 0.5 s at 16 fps
    assert gt["latency_p50_ms"] == pytest.approx(10.0)
    assert clock.t == pytest.approx(5.0 + 0.5 + 0.5)  # each cell rendered for its seconds, no more


def test_one_frame_slower_than_the_check_still_gives_its_rate():
    clock = FakeClock()
    flips, renders, gaze, dropped = sample_frames(lambda: (clock.__setattr__("t", clock.t + 8.0) or clock.t, 8.0,
                                                           None), clock, 2.0)
    from data_schema.timing import summary

    assert len(flips) == 2 and summary(flips, renders, gaze, dropped)["fps_median"] == pytest.approx(0.125)


def test_the_check_lasts_fps_check_s_per_cell_bounded_in_total(tmp_path):
    assert seconds_per_cell(protocol(tmp_path)) == 2.0  # the default
    assert seconds_per_cell(protocol(tmp_path, "fps_check_s: 0")) == 0.0
    assert seconds_per_cell(protocol(tmp_path, "fps_check_s: 45")) == MAX_TOTAL_S / 2  # 2 cells


def test_frame_rates_below_one_are_never_printed_as_zero():
    assert format_fps(0.13) == "0.13" and format_fps(0.04) == "0.04" and format_fps(7.66) == "7.7"
    assert format_fps(math.nan) == "-"


def test_the_table_stays_aligned_with_an_adaptive_level_longer_than_the_column():
    # latency_threshold_live's check renders LaFR_150ms(1.2): 15 characters, one more than the default column
    rows = [{"condition": c, "scene": "temple", "fps_p5": 5.0, "fps_p50": 7.8, "latency_p50_ms": 396.0,
             "frames": 15} for c in ("GT", "LaFR_150ms(1.2)")]
    head, *body = table_lines(rows, 30)[1:]
    assert [line.index("temple") for line in body] == [head.index("scene")] * 2
    assert {len(line) for line in body} == {len(head) + len("  BELOW min_fps")}


class WindowLike:
    """The simulated observer with a window's frame-rate check (a fake renderer and clock)."""

    def __new__(cls, protocol, stimuli, clock, rates=RATES, end_after=None):
        from studyapp.presentation.base import TrialResult
        from studyapp.runner.observer import SimulatedObserver
        from studyapp.runner.session import ground_truth_stimuli

        obs = SimulatedObserver(protocol, "P1", 0, ground_truth_stimuli(protocol, stimuli))
        obs.fps_check_frames = fake_cell(clock, rates)
        if end_after is not None:  # Escape at that trial, then "end": the session stops with trials left
            present = obs.present
            obs.present = lambda d: (TrialResult(answers=[], rt_s=math.nan, onset_s=math.nan, escaped=True)
                                     if d.index >= end_after else present(d))
            obs.pause = lambda: "end"
        return obs


def run(tmp_path, p, rates=RATES, end_after=None, **kw):
    from studyapp.runner.session import run_session

    lines = []
    clock = FakeClock()
    summary = run_session(p, "P1", tmp_path / "s.db", lambda st, d: WindowLike(p, st, clock, rates, end_after),
                          console=lines.append, **kw)
    return summary, lines


def test_a_condition_below_min_fps_stops_the_session_before_its_first_trial(tmp_path):
    p = protocol(tmp_path, "fps_check_s: 0.2")
    with pytest.raises(TooSlow) as exc:
        run(tmp_path, p)
    assert str(exc.value) == ("frame-rate check: LaFR 16.0 fps (cornell): below the protocol's min_fps 45 at this "
                              "size and backend; use a smaller --scale or a faster machine, or add --accept-slow "
                              "to run anyway (its trials are flagged)")
    assert not (tmp_path / "s.db").exists()  # a refused first run leaves no database behind (no answer stored)


def test_a_refused_resumed_session_is_recorded_as_refused(tmp_path):
    from data_schema.store import open_store

    p = protocol(tmp_path, "fps_check_s: 0.2")
    first, _ = run(tmp_path, p, rates={"GT": 128.0, "LaFR": 64.0}, end_after=1)  # fast enough; ended at trial 1
    assert first.status == "ended" and first.answered == 1
    with pytest.raises(TooSlow):  # now LaFR renders at 16 fps
        run(tmp_path, p, resume=True)
    with open_store(tmp_path / "s.db") as st:
        last = st.sessions()[-1]
        assert last["status"] == "refused" and last["responses"] == 0
        assert [r["condition"] for r in st.fps_check(last["id"])["rows"]] == ["GT", "LaFR"]


def test_accept_slow_runs_records_the_check_and_flags_slow_trials(tmp_path, capsys):
    from data_schema.store import open_store
    from studyapp.cli import main

    p = protocol(tmp_path, "fps_check_s: 0.2")
    summary, lines = run(tmp_path, p, accept_slow=True)
    assert summary.status == "completed"
    with open_store(tmp_path / "s.db") as st:
        rec = st.fps_check(summary.session)
    assert rec["accepted_slow"] == ["LaFR"] and rec["min_fps"] == 45 and rec["seconds"] == 0.2
    assert [(r["condition"], round(r["fps_p50"])) for r in rec["rows"]] == [("GT", 128), ("LaFR", 16)]
    assert lines[0] == "frame-rate check (min_fps 45):"
    assert any(re.fullmatch(r"  LaFR +cornell +16\.0 +16\.0 +10ms +4  BELOW min_fps", s) for s in lines), lines
    assert "--accept-slow: the trials of LaFR are flagged" in lines
    # the simulated frames (3 over a 2-s stimulus) are below 45 fps: each stimulus of each trial is flagged
    flags = [s for s in lines if s.startswith("trial ")]
    assert len(flags) == 4 and all(re.fullmatch(r"trial [01] \((GT|LaFR), cornell\): [0-9.]+ fps, below min_fps 45",
                                                s) for s in flags), flags
    capsys.readouterr()
    assert main(["sessions", "--db", str(tmp_path / "s.db")]) == 0
    out = capsys.readouterr().out
    assert f"session {summary.session}: frame-rate check (min_fps 45):" in out
    assert "run with --accept-slow: trials of LaFR flagged" in out
    per_trial = [s for s in out.splitlines() if s.startswith("  trial ")]
    assert len(per_trial) == 2 and all("frame time p50" in s for s in per_trial)
    assert " 0.0 " not in out


def test_the_simulated_observer_has_no_check(tmp_path):
    from studyapp.runner.observer import SimulatedObserver

    assert not hasattr(SimulatedObserver, "fps_check_frames")  # --simulate: no window, no check (docs/live.md)


def test_run_refuses_a_slow_condition_in_one_line_and_accept_slow_runs(tmp_path, monkeypatch, capsys):
    from studyapp.cli import main
    from studyapp.commands import study

    p = protocol(tmp_path, "fps_check_s: 0.2")
    clock = FakeClock()
    monkeypatch.setattr(study, "_presenter_factory", lambda args, proto: lambda st, d: WindowLike(p, st, clock))
    args = ["run", str(p.path), "--participant", "P1", "--db", str(tmp_path / "s.db"), "--quiet"]
    assert main(args) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "frame-rate check (min_fps 45):" and "Traceback" not in "\n".join(err)
    assert err[-1].startswith("studyapp: error: frame-rate check: LaFR 16.0 fps (cornell): below the protocol's "
                              "min_fps 45")
    assert not (tmp_path / "s.db").exists()
    assert main(args + ["--accept-slow"]) == 0
    captured = capsys.readouterr()
    assert "--accept-slow: the trials of LaFR are flagged" in captured.err
    assert "completed, 2/2 trials answered" in captured.out


@pytest.mark.parametrize("detail", ["not json", "null", '{"rows": 3, "accepted_slow": []}',
                                    '{"rows": [{"condition": 1, "scene": "x"}], "accepted_slow": []}'])
def test_a_record_of_the_check_not_written_by_studyapp_is_refused(tmp_path, detail):
    from data_schema.store import StoreError, open_store

    p = protocol(tmp_path, "fps_check_s: 0.2")
    summary, _ = run(tmp_path, p, accept_slow=True)
    with open_store(tmp_path / "s.db", "write") as st:
        st.event(summary.session, "fps_check", detail)
        with pytest.raises(StoreError, match="the record of its frame-rate check is invalid"):
            st.fps_check(summary.session)


def test_accept_slow_flags_every_trial_of_a_slow_condition_in_the_record_export_and_sessions(tmp_path, capsys):
    """Each trial showing a condition the check found below min_fps (run with --accept-slow) carries
    ``fps_check_slow`` = 1 in the tidy log (CSV export, Parquet, analysis) and is marked in ``sessions``; a run
    where every condition was fast enough flags none."""
    import csv

    from data_schema.store import read_trials
    from studyapp.cli import main

    p = protocol(tmp_path, "fps_check_s: 0.2")
    summary, _ = run(tmp_path, p, accept_slow=True)
    assert main(["export", "--db", str(tmp_path / "s.db"), "--format", "csv", "--out", str(tmp_path / "t.csv")]) == 0
    rows = list(csv.DictReader((tmp_path / "t.csv").open()))
    assert [(r["trial"], r["fps_check_slow"]) for r in rows] == [("0", "1"), ("1", "1")]  # LaFR is in both
    assert read_trials(tmp_path / "s.db")["fps_check_slow"].tolist() == [1, 1]
    capsys.readouterr()
    assert main(["sessions", "--db", str(tmp_path / "s.db")]) == 0
    out = capsys.readouterr().out
    assert "run with --accept-slow: trials of LaFR flagged (trials 0, 1)" in out
    per_trial = [s for s in out.splitlines() if s.startswith("  trial ")]
    assert len(per_trial) == 2 and all(s.endswith("FLAGGED: below min_fps in the frame-rate check (--accept-slow)")
                                       for s in per_trial), per_trial

    fast = tmp_path / "fast"
    fast.mkdir()
    run(fast, p, rates={"GT": 128.0, "LaFR": 64.0})
    assert read_trials(fast / "s.db")["fps_check_slow"].tolist() == [0, 0]
