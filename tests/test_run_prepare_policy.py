"""No surprise work (issue 26, item 7; ``run --help``: item 9).

Before, ``run`` without ``--scale`` silently started a full-size ``prepare`` of a missing stimulus set, and a
database of another protocol was refused only after the rendering. Now ``run`` names the missing sets and the
``prepare`` command (same protocol argument, ``--scale``, ``--stimuli``, ``--full``) and exits 2 in one line,
rendering nothing, unless ``--prepare`` is given; every refusal the study database decides comes first; ``validate
--scale`` reports the set of that scale; a folder condition says where its images go, and ``prepare`` no longer
sends the user back to ``run``.
"""

from __future__ import annotations

import subprocess
import time

import numpy as np
import pytest
from test_run_refusals import SEQUENCE, replaced

from studyapp.cli import main

#: test_run_refusals' tiny pre-rendered study (cornell, GT against LaFR, 2 frames at 64x36) without declared
#: qualities: the simulated observer needs its images too.
NO_QUALITY = replaced(SEQUENCE, (", quality: 1.0}", "}"), (", quality: 0.5}", "}"))
#: ... as one still image per stimulus, with LaFR's images from a lab's folder.
FOLDER = replaced(NO_QUALITY, ("LaFR: {renderer: lafr, params: {delta: 4.0}}", "LaFR: {folder: lab}"),
                  ("  kind: sequence\n  fps: 2\n", "  kind: image\n"), ("  duration_s: 1.0\n", ""))


def _write(tmp_path, text: str, name: str = "p.yaml") -> str:
    (tmp_path / name).write_text(text)
    return name


def _no_rendering(monkeypatch) -> None:
    """Fail the test if anything is prepared or rendered."""
    from studyapp.runner import stimuli

    def refuse(*a, **k):
        raise AssertionError("rendering started")

    monkeypatch.setattr(stimuli, "prepare", refuse)
    monkeypatch.setattr(stimuli, "render_function", refuse)


def _refused(capsys, argv) -> str:
    assert main(argv) == 2, argv
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and err.startswith("studyapp: error: "), err
    return err[len("studyapp: error: "):-1]


def test_run_with_missing_stimuli_names_them_and_the_prepare_command(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    proto = _write(tmp_path, NO_QUALITY)
    assert main(["validate", proto]) == 0  # imports the renderers: the runs below are timed without that
    capsys.readouterr()
    _no_rendering(monkeypatch)
    root = tmp_path / "stimuli" / "tiny_live"
    for extra, also in (([], ""), (["--simulate"], " (or declare a quality for each of their conditions)")):
        t0 = time.perf_counter()
        line = _refused(capsys, ["run", proto, "--participant", "P1", "--scale", "0.5", "--quiet", *extra])
        assert time.perf_counter() - t0 < 2.0
        assert line == (f"2 stimulus set(s) missing in {root / 'scale0.5'} (GT/cornell, LaFR/cornell): render them "
                        f"with `studyapp prepare p.yaml --scale 0.5`, or add --prepare to render them first{also}")
        assert sorted(p.name for p in tmp_path.iterdir()) == ["p.yaml"]  # no database, no stimulus or cache folder


def test_the_prepare_command_keeps_stimuli_and_full(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _no_rendering(monkeypatch)
    line = _refused(capsys, ["run", "seed003_task2", "--participant", "P1", "--quiet", "--scale", "0.25",
                             "--stimuli", "my stimuli", "--full"])
    assert line.startswith("34 stimulus set(s) missing in my stimuli/full/scale0.25 (EC/study, CC2/study, "
                           "CC3/study and 31 more): render them with `studyapp prepare seed003_task2 --scale "
                           "0.25 --stimuli 'my stimuli' --full`, or add --prepare"), line
    assert list(tmp_path.iterdir()) == []


def test_run_prepare_renders_then_runs(tmp_path, capsys, monkeypatch):
    from data_schema.store import read_trials
    from studyapp.runner.protocol import load_protocol
    from studyapp.runner.stimuli import frame_paths, missing_stimuli

    monkeypatch.chdir(tmp_path)
    proto = _write(tmp_path, NO_QUALITY)
    assert main(["run", proto, "--participant", "P1", "--simulate", "--prepare", "--scale", "0.5", "--serial",
                 "--db", "s.db"]) == 0
    out, err = capsys.readouterr()
    assert "2 stimulus set(s) missing: preparing them first (--prepare)" in err
    assert "frames: |" in err and "4/4" in err  # the progress bar (a line per 10 % when not a terminal)
    assert "tiny_live: 4 frame(s) built (4 rendered, 0 from the cache) on this process in " in err
    assert "session P1-s1: completed, 1/1 trials answered" in out
    p = load_protocol(tmp_path / proto)
    assert missing_stimuli(p, 0.5) == []
    from studyapp.runner.images import load_rgb

    assert load_rgb(frame_paths(p, "LaFR", "cornell", 0.5)[0]).shape == (18, 32, 3)  # 64x36 at --scale 0.5
    assert len(read_trials(tmp_path / "s.db")) == 1
    # Prepared: the next participant runs without --prepare and renders nothing.
    _no_rendering(monkeypatch)
    assert main(["run", proto, "--participant", "P2", "--simulate", "--scale", "0.5", "--db", "s.db",
                 "--quiet"]) == 0
    assert "session P2-s1: completed" in capsys.readouterr().out


def _study(db, protocol_path, participants: dict[str, str], runner: int | None = None) -> None:
    """A study database of ``protocol_path`` without rendering anything: each participant enrolled and
    ``completed`` (every trial answered), ``running`` (a session of process ``runner``, alive) or ``enrolled``."""
    from crafted_db import craft

    from data_schema.store import PlannedRow, open_store, process_identity
    from studyapp.runner.protocol import load_protocol
    from studyapp.runner.schedule import build_schedule, counterbalance_index, schedule_hash

    p = load_protocol(protocol_path)
    with open_store(db, "create") as st:
        st.bind_protocol(p.name, p.version, p.content_hash, p.data)
        for pid, state in participants.items():
            sched = build_schedule(p, pid, 0)
            st.enrol(pid, counterbalance_index(pid), 0, schedule_hash(sched),
                     [PlannedRow(t.index, t.kind, t.family, t.scene, t.block, t.conditions, t.expected,
                                 t.break_before) for t in sched])
            if state == "enrolled":
                continue
            sid = st.start_session(pid, p.content_hash, 0, {}, {}, {}, "test")
            if state == "completed":
                for t in sched:
                    st.commit_response(pid, t.index, sid, ["A"], chosen=t.conditions[0], rt_s=1.0, onset_s=1.0)
                st.end_session(sid, "completed")
    for pid, state in participants.items():
        if state == "running":  # its process still runs (the store ignores sessions of this very process)
            assert craft(db, "sessions", {"participant": pid}, {"process": process_identity(runner)}) == 1


@pytest.mark.parametrize("argv,words", [
    (["--db", "other.db", "--participant", "P5"], "other.db: written by protocol 'tiny_live' version '1' (sha256 "),
    (["--db", "s.db", "--participant", "P1"], "s.db: participant 'P1' already exists (1 of 1 planned trials "
                                              "answered): use --resume to continue, or another --participant"),
    (["--db", "s.db", "--participant", "P9", "--resume"], "s.db: participant 'P9' has no session to resume"),
    (["--db", "s.db", "--participant", "P1", "--resume"], "s.db: participant 'P1' has already answered every trial"),
    (["--db", "s.db", "--participant", "P2", "--resume"], "s.db: participant 'P2' has session P2-s1 still running "
                                                          "(here, process "),
    (["--db", "s.db", "--participant", "P3", "--resume", "--seed", "7"],
     "s.db: participant 'P3' was scheduled with --seed 0, not 7"),
    (["--db", "none.db", "--participant", "P1", "--resume"], "none.db: no such study database: nothing to resume"),
    (["--db", "s.db", "--participant", "a b"], "--participant='a b' is invalid"),
])
def test_the_database_refuses_before_any_rendering(argv, words, tmp_path, capsys, monkeypatch, request):
    monkeypatch.chdir(tmp_path)
    proto = _write(tmp_path, NO_QUALITY)
    runner = subprocess.Popen(["sleep", "60"])  # stands in for the process running P2's session
    request.addfinalizer(lambda: (runner.kill(), runner.wait()))
    _study(tmp_path / "s.db", tmp_path / proto, {"P1": "completed", "P2": "running", "P3": "enrolled"}, runner.pid)
    _study(tmp_path / "other.db", tmp_path / _write(tmp_path, SEQUENCE, "other.yaml"), {"P1": "completed"})

    def files():  # SQLite's own -wal/-shm files, which a reading connection may leave, aside
        return {p.name: p.read_bytes() for p in tmp_path.iterdir() if not p.name.endswith(("-wal", "-shm"))}

    before = files()
    _no_rendering(monkeypatch)
    for extra in (["--prepare"], [], ["--simulate", "--prepare"]):
        line = _refused(capsys, ["run", proto, "--quiet", "--scale", "0.5", *argv, *extra])
        assert words in line, line
        assert files() == before  # nothing rendered, no stimulus folder, the databases unchanged


def test_a_stop_during_run_prepare_speaks_of_prepare(tmp_path, capsys, monkeypatch):
    from studyapp.runner import stimuli

    def ctrl_c(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.chdir(tmp_path)
    proto = _write(tmp_path, NO_QUALITY)
    monkeypatch.setattr(stimuli, "prepare", ctrl_c)
    assert main(["run", proto, "--participant", "P1", "--prepare", "--quiet", "--serial"]) == 130
    assert capsys.readouterr().err.splitlines()[-1] == ("studyapp: interrupted (frames rendered so far are kept in "
                                                        "the cache: run the same prepare again to continue)")


def test_validate_reports_the_set_of_its_scale(tmp_path, capsys, monkeypatch):
    from studyapp.runner.protocol import load_protocol
    from studyapp.runner.stimuli import write_synthetic_stimuli

    monkeypatch.chdir(tmp_path)
    proto = _write(tmp_path, NO_QUALITY)
    write_synthetic_stimuli(load_protocol(tmp_path / proto), 0.5)
    root = tmp_path / "stimuli" / "tiny_live"
    assert main(["validate", proto, "--scale", "0.5"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == f"stimuli: complete in {root / 'scale0.5'}"
    assert main(["validate", proto]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == (
        f"stimuli: 2 stimulus set(s) missing in {root} (GT/cornell, LaFR/cornell): render them with "
        "`studyapp prepare p.yaml`")
    assert main(["validate", proto, "--scale", "0.25", "--stimuli", "elsewhere"]) == 0
    assert capsys.readouterr().out.splitlines()[-1].startswith(
        "stimuli: 2 stimulus set(s) missing in elsewhere/scale0.25 (GT/cornell, LaFR/cornell): "
        "render them with `studyapp prepare p.yaml --scale 0.25 --stimuli elsewhere`")
    live = _write(tmp_path, replaced(SEQUENCE, ("  kind: sequence\n  fps: 2\n", "  kind: live\n  motion: path\n"
                                                "  gaze: fixation\n")), "live.yaml")
    assert main(["validate", live, "--scale", "0.5"]) == 0  # live: the size rendered during the trials
    assert capsys.readouterr().out.splitlines()[-1] == ("stimuli: rendered during the trials at 32x18 (gpu backend), "
                                                        "nothing to prepare")


def test_a_folder_condition_says_where_its_images_go(tmp_path, capsys, monkeypatch):
    from PIL import Image

    from studyapp.runner.protocol import load_protocol
    from studyapp.runner.stimuli import write_synthetic_stimuli

    monkeypatch.chdir(tmp_path)
    proto = _write(tmp_path, FOLDER)
    lab = tmp_path / "lab"
    where = (f"1 stimulus set(s) of folder conditions missing (LaFR/cornell): condition LaFR reads a lab's own "
             f"images from {lab}: put cornell.png (one PNG per scene) there (prepare renders only renderer and "
             "derived conditions)")
    _no_rendering(monkeypatch)
    for extra in ([], ["--prepare"], ["--simulate"]):  # --prepare cannot make a lab's images
        line = _refused(capsys, ["run", proto, "--participant", "P1", "--quiet", *extra])
        assert line == (f"{where}; 1 stimulus set(s) missing in {tmp_path / 'stimuli' / 'tiny_live'} (GT/cornell): "
                        "render them with `studyapp prepare p.yaml`, then run again")
    monkeypatch.undo()
    monkeypatch.chdir(tmp_path)
    assert _refused(capsys, ["prepare", proto, "--serial"]) == where  # no "run prepare" loop: the folder again
    assert not (tmp_path / "stimuli").exists()
    # Following both: the GT rendered (here: a synthetic set), the lab's image put where it was asked for.
    write_synthetic_stimuli(load_protocol(tmp_path / proto))
    lab.mkdir()
    Image.fromarray(np.full((36, 64, 3), 128, np.uint8)).save(lab / "cornell.png")
    assert main(["run", proto, "--participant", "P1", "--simulate", "--quiet"]) == 0
    assert "session P1-s1: completed, 1/1 trials answered" in capsys.readouterr().out


def test_a_folder_sequence_names_its_frame_files(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    proto = _write(tmp_path, replaced(NO_QUALITY, ("LaFR: {renderer: lafr, params: {delta: 4.0}}",
                                                   "LaFR: {folder: lab, quality: 0.5}")))
    line = _refused(capsys, ["run", proto, "--participant", "P1", "--quiet", "--simulate", "--prepare"])
    assert (f"condition LaFR reads a lab's own images from {tmp_path / 'lab'}: put cornell/frame_00000.png ... "
            "cornell/frame_00001.png (2 PNG frames per scene, read in name order) there") in line


def test_run_help_documents_pause_keys_prepare_policy_and_live_scale(capsys):
    from studyapp.presentation.base import END_KEY, ESCAPE, RESUME_KEY

    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())  # argparse wraps lines
    assert (f"{ESCAPE.capitalize()} pauses the session at once (the trial is shown again): then {RESUME_KEY.upper()} "
            f"resumes, {END_KEY.upper()} ends it") in text
    assert "a missing set is refused in one line naming it and the `studyapp prepare` command, unless --prepare" in text
    assert "--prepare render the missing stimulus sets first" in text
    assert "a live protocol renders its trials at its render size times F" in text


def test_a_live_render_too_small_at_the_scale_is_refused_before_the_session(tmp_path, capsys, monkeypatch):
    """seed001_2afc_live at --scale 0.02 renders 38x22: its catch condition COARSE (LaFR delta 8) has a 3-row LP
    buffer. Refused by validate, run and run --preview alike in one line before any database or window (it
    stopped the session at the second practice trial)."""
    from pathlib import Path

    from studyapp.commands import study

    def no_window(*a, **k):
        raise AssertionError("a window was asked for")

    monkeypatch.setattr(study, "_presenter_factory", lambda *a: no_window)
    proto = str(Path(__file__).resolve().parents[1] / "protocols" / "seed001_2afc_live.yaml")
    want = ("cannot render COARSE live at --scale 0.02 (38x22 px): lafr.delta=8 is out of range on this display: "
            "the LP buffer has 3 rows")
    db = tmp_path / "s.db"
    for argv in (["validate", proto, "--scale", "0.02"],
                 ["run", proto, "--scale", "0.02", "--participant", "P1", "--db", str(db)],
                 ["run", proto, "--scale", "0.02", "--preview"]):
        assert _refused(capsys, argv).startswith(want), argv
    assert not db.exists()
    assert main(["validate", proto, "--scale", "0.25"]) == 0
