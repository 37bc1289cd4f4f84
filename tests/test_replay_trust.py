"""Replay trusts nothing it can check, and crafted frame rows are refused (issue 25, items 4, 5 and 10).

The databases are written through the store (tests/crafted_db.py): a live session of a tiny protocol, then rows
changed with valid checksums, so only the checks of the values themselves can refuse them.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from crafted_db import BOX, craft, live_db, live_protocol, live_text
from studyapp.cli import main


def _run(capsys, *argv) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _refused(code: int, err: str, *words: str) -> None:
    lines = [line for line in err.splitlines() if not line.startswith("frames:")]  # the progress bar
    assert code == 2 and len(lines) == 1 and lines[0].startswith("studyapp: error: "), err
    for w in words:
        assert w in lines[0], (w, lines[0])


def _replay(capsys, db: Path, out: Path, *extra, trial=0):
    return _run(capsys, "replay", "--db", db, "--participant", "P1", "--trial", trial, "--out", out, "--serial",
                "--cache", out.parent / "cache", *extra)


@pytest.fixture
def study(tmp_path):
    return live_db(live_protocol(tmp_path / "proto"), tmp_path / "s.db")


# -- the ground truth apart from every condition ------------------------------------------------------------
def test_a_condition_named_gt_is_not_overwritten_by_the_ground_truth(tmp_path, capsys):
    db = live_db(live_protocol(tmp_path / "proto", condition="gt"), tmp_path / "s.db")
    out = tmp_path / "rep"
    code, _, err = _replay(capsys, db, out, "--quality")
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["conditions", "flips.csv", "frames.csv", "gaze.csv",
                                                      "ground_truth", "quality.csv", "quality.md", "shown"]
    assert sorted(p.name for p in (out / "conditions").iterdir()) == ["Ref", "gt"]
    import pandas as pd

    q = pd.read_csv(out / "quality.csv")
    assert (q[q.image.str.startswith("conditions/Ref/")]["mse"] == 0).all()
    lafr = q[q.image.str.startswith("conditions/gt/")]
    assert len(lafr) == 3 * 3 and (lafr["mse"] > 0).all()  # 3 frames x (fovea, periphery, all)
    frames = pd.read_csv(out / "frames.csv")
    assert set(frames["file"].str.split("/").str[0]) == {"conditions"} and set(frames["eye"]) == {"mono"}
    gaze = pd.read_csv(out / "gaze.csv")
    assert gaze["file"].tolist() == frames["file"].tolist()
    assert gaze["gaze_x"].tolist() == [16.0] * 6 and gaze["gaze_y"].tolist() == [9.0] * 6  # centre of 32 x 18


# -- the scene: from the recorded folder, with the recorded content ----------------------------------------
@pytest.fixture
def box_study(tmp_path, mesh_file):
    a, b = tmp_path / "a", tmp_path / "b"
    for folder, x in ((a, 0.5), (b, -1.5)):
        folder.mkdir()
        for mesh in ("floor.ply", "cube.stl"):
            shutil.copy(mesh_file / mesh, folder / mesh)
        (folder / "box.yaml").write_text(BOX.format(x=x))
    return live_db(live_protocol(a, scene="box"), tmp_path / "s.db")


def test_scene_files_are_read_from_the_recorded_protocol_folder(box_study, tmp_path, capsys, monkeypatch):
    from data_schema.store import open_store

    with open_store(box_study) as st:
        record = st.session_scenes("P1-s1")
    assert record["folder"] == str((tmp_path / "a").resolve()) and len(record["scenes"]["box"]) == 64
    monkeypatch.chdir(tmp_path / "a")
    assert _replay(capsys, box_study, tmp_path / "from_a")[0] == 0
    monkeypatch.chdir(tmp_path / "b")  # another box.yaml here: not the one the session rendered
    assert _replay(capsys, box_study, tmp_path / "from_b")[0] == 0
    for png in sorted((tmp_path / "from_a").rglob("*.png")):
        assert png.read_bytes() == (tmp_path / "from_b" / png.relative_to(tmp_path / "from_a")).read_bytes()


def test_a_changed_scene_file_is_refused_before_anything_is_written(box_study, tmp_path, capsys):
    (tmp_path / "a" / "box.yaml").write_text(BOX.format(x=-1.5))
    code, _, err = _replay(capsys, box_study, tmp_path / "rep")
    _refused(code, err, str(box_study), "scene 'box'", "is not the one session P1-s1 rendered", "recorded")
    assert not (tmp_path / "rep").exists() and not (tmp_path / "cache").exists()


def test_a_session_that_recorded_no_scene_hashes(tmp_path, capsys, mesh_file):
    """Older databases: a built-in scene replays with a warning; a scene file (folder unknown) is refused."""
    db = live_db(live_protocol(tmp_path / "p1"), tmp_path / "old.db", scenes=False)
    code, out, err = _replay(capsys, db, tmp_path / "rep")
    warn = [line for line in err.splitlines() if line.startswith("studyapp: warning:")]
    assert code == 0 and len(warn) == 1 and "recorded no scene hashes" in warn[0] and "replayed unchecked" in warn[0]
    folder = tmp_path / "p2"
    folder.mkdir()
    for mesh in ("floor.ply", "cube.stl"):
        shutil.copy(mesh_file / mesh, folder / mesh)
    (folder / "box.yaml").write_text(BOX.format(x=0.5))
    db = live_db(live_protocol(folder, scene="box"), tmp_path / "old_box.db", scenes=False)
    code, _, err = _replay(capsys, db, tmp_path / "rep2")
    _refused(code, err, "recorded no scene hashes", "scene file 'box' cannot be checked")


# -- binocular: the eye the gaze falls on ---------------------------------------------------------------------
def test_eye_at_picks_the_viewport_that_holds_the_point():
    from data_schema.geometry import eye_at, eye_views

    views = eye_views((320, 180), (32, 18), 2, stereo=True)  # a stereo display: the eyes side by side
    assert eye_at(views, 40, 90).eye == "left" and eye_at(views, 240, 90).eye == "right"
    assert eye_at(views, 240, 90).to_render(240, 90) == (8.0, 9.0)  # the centre of the right half's left half
    assert views[0].to_render(240, 90) == (16.0, 9.0)  # through the left eye: clamped to its edge (the bug)
    assert eye_at(views, 999, -5).eye == "right" and eye_at(views, -3, 50).eye == "left"
    assert eye_at(eye_views((320, 180), (32, 18), 1), 240, 90).eye == "mono"


def test_the_live_window_foveates_both_eyes_at_the_gaze_in_the_eye_it_falls_on(monkeypatch):
    """LiveTrial._render without a window: a gaze in the right half is not clamped to the centre line."""
    from types import SimpleNamespace

    import numpy as np

    from data_schema.geometry import eye_views
    from studyapp.presentation import live_window as lw
    from studyapp.runner.live import Pose

    seen = {}

    def fake_render(scene, renderer, params, w, h, gaze=None, camera=None, backend=None, cancel=None):
        seen.update(size=(w, h), gaze=gaze)
        img = np.zeros((h, w, 3), np.float32)
        return img, {"seconds": {"total": 0.0}, "eye_images": [img, img]}

    monkeypatch.setattr("renderers.registry.render", fake_render)
    monkeypatch.setattr(lw.LiveTrial, "_surfaces", lambda self, i: [])
    trial = object.__new__(lw.LiveTrial)
    trial.live = [SimpleNamespace(scene="cornell", renderer="lafr", params={"stereo": "dup"}, backend="cpu",
                                  fov_y_deg=30.0, condition="LaFR")]
    trial.views = [eye_views((320, 180), (32, 18), 2, stereo=True)]
    trial.motions = [SimpleNamespace(pose=lambda *a: Pose((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)))]
    trial.p = SimpleNamespace(exposure=lambda scene: 1.0)
    for window_gaze, gaze in (((240.0, 45.0), (8.0, 4.5)), ((40.0, 90.0), (4.0, 9.0))):
        trial._render(0, 0.0, window_gaze, set(), (0.0, 0.0))
        assert seen == {"size": (16, 18), "gaze": gaze}


@pytest.mark.parametrize("stereo,params,eye,gaze,size", [
    (True, "{delta: 4.0, stereo: dup}", "right", (8.0, 4.5), (16, 18)),  # side by side: the eye gazed at
    (False, "{delta: 4.0, stereo: dup}", "left", (24.0, 4.5), (32, 18)),  # mono display: the named eye, full size
    (False, "{delta: 4.0, stereo: dup, eye: right}", "right", (24.0, 4.5), (32, 18))])
def test_a_binocular_trial_replays_the_eye_shown(tmp_path, capsys, stereo, params, eye, gaze, size):
    folder = tmp_path / "proto"
    folder.mkdir()
    proto = folder / "live.yaml"
    text = live_text(params=params)
    proto.write_text(text.replace("refresh_hz: 60}", "refresh_hz: 60, stereo: true}") if stereo else text)
    db = live_db(proto, tmp_path / "s.db", frames_per_stimulus=1, gaze=(240.0, 45.0))
    out = tmp_path / "rep"
    code, _, err = _replay(capsys, db, out)
    assert code == 0, err
    import pandas as pd

    f = pd.read_csv(out / "frames.csv").set_index("condition")
    assert f.loc["LaFR", "eye"] == eye and f.loc["Ref", "eye"] == "mono"
    assert (f.loc["LaFR", "gaze_x"], f.loc["LaFR", "gaze_y"]) == gaze
    assert (f.loc["Ref", "gaze_x"], f.loc["Ref", "gaze_y"]) == (24.0, 4.5)  # mono: 32 x 18 pixels
    from PIL import Image

    assert Image.open(out / f.loc["LaFR", "file"]).size == size
    assert Image.open(out / "ground_truth" / Path(f.loc["LaFR", "file"]).name).size == size


# -- crafted frame rows: one line naming the database, the row and the field ------------------------------
CRAFTED = [
    ({"stimulus": -1}, "stimulus=-1", "must be a stimulus index 0..1"),
    ({"stimulus": 2}, "stimulus=2", "must be a stimulus index 0..1"),
    ({"stimulus": "abc"}, "stimulus='abc'", "must be a stimulus index"),
    ({"stimulus": 1.5}, "stimulus=1.5", "must be a stimulus index"),
    ({"pos_x": None}, "pos_x=None", "must be a number"),
    ({"look_z": float("inf")}, "look_z=inf", "must be a number"),
    ({"gaze_t": "soon"}, "gaze_t='soon'", "must be empty or a number"),
    ({"gaze_x": None}, "gaze_x=None", "both be given or both be empty"),
    ({"flip_s": 1e300}, "flip_s=1e+300", "must be a number in"),
    ({"render_s": -1.0}, "render_s=-1.0", "must be empty or a number in [0,"),
    ({"dropped": "yes"}, "dropped='yes'", "must be 0 or 1"),
    ({"dropped": 2}, "dropped=2", "must be 0 or 1"),
    ({"frame": "x"}, "frame='x'", "must be a whole number"),
    ({"look_x": 0.0, "look_y": 0.0, "look_z": 0.0, "pos_x": 0.0, "pos_y": 0.0, "pos_z": 0.0}, "look_x=0.0",
     "equals the camera position"),
]


@pytest.mark.parametrize("changes,field,why", CRAFTED, ids=[c[1] for c in CRAFTED])
@pytest.mark.parametrize("command", ["export", "sessions", "replay"])
def test_crafted_frame_rows_are_refused_in_one_line(study, tmp_path, capsys, changes, field, why, command):
    assert craft(study, "frames", {"idx": 0, "frame": 1}, changes) == 1
    if command == "export":
        code, _, err = _run(capsys, "export", "--db", study, "--format", "frames", "--out", tmp_path / "f.csv")
    elif command == "sessions":
        code, _, err = _run(capsys, "sessions", "--db", study)
    else:
        code, _, err = _replay(capsys, study, tmp_path / "rep")
    frame = "'x'" if field.startswith("frame=") else "1"
    _refused(code, err, f"{study}: participant 'P1', trial 0, frame {frame}: {field}", why)
    assert not (tmp_path / "f.csv").exists() and not (tmp_path / "rep").exists()


def test_crafted_planned_conditions_and_protocol_json_are_refused(study, tmp_path, capsys):
    spare = tmp_path / "spare.db"
    shutil.copy(study, spare)
    craft(study, "planned_trials", {"idx": 1}, {"conditions": "[1, 2"})
    for argv in (("sessions", "--db", study), ("export", "--db", study, "--out", tmp_path / "t.csv")):
        code, _, err = _run(capsys, *argv)
        _refused(code, err, "participant 'P1', trial 1: conditions='[1, 2' is invalid")
    craft(spare, "study", {"key": "protocol_json"}, {"value": "{bad"})
    code, _, err = _run(capsys, "sessions", "--db", spare)
    _refused(code, err, f"{spare}: the recorded protocol is not a JSON object")
    code, _, err = _replay(capsys, spare, tmp_path / "rep")
    _refused(code, err, f"{spare}: the recorded protocol is not a JSON object")


def test_replay_of_a_trial_beyond_any_database_is_one_line(study, tmp_path, capsys):
    code, _, err = _replay(capsys, study, tmp_path / "rep", trial=2 ** 70)
    _refused(code, err, "--trial=1180591620717411303424 is out of range")
    code, _, err = _replay(capsys, study, tmp_path / "rep", trial=2 ** 63 - 1)
    _refused(code, err, "participant 'P1' has no trial 9223372036854775807")


# -- sessions: every trial counts --------------------------------------------------------------------------
def test_sessions_flags_a_trial_with_one_rendered_frame_and_pools_every_trial(tmp_path, capsys):
    db = live_db(live_protocol(tmp_path / "proto", repetitions=3), tmp_path / "s.db")
    # trial 0: one rendered frame, every flip dropped, the gaze 500 ms old
    craft(db, "frames", {"idx": 0}, {"render_s": None, "dropped": 1})
    craft(db, "frames", {"idx": 0, "frame": 0}, {"render_s": 0.01})
    from data_schema.store import open_store

    with open_store(db) as st:
        flips = [f["flip_s"] for f in st.frames("P1", 0)]
    for k, flip in enumerate(flips):
        craft(db, "frames", {"idx": 0, "frame": k}, {"gaze_t": flip - 0.5})
    code, out, _ = _run(capsys, "sessions", "--db", db)
    assert code == 0
    row = [line for line in out.splitlines() if line.startswith("P1-s1 ") and "ms" in line][0]
    assert "FLAGGED trials 0 (< 2 rendered frames); trials 1, 2 (below min_fps)" in row
    # pooled over the 18 flips of the 3 trials: 6 dropped; latencies 6 x 500 ms and 12 x 52 ms
    assert " 33.3% " in row and " 52ms " in row and " 500ms" in row


def test_sessions_lists_a_reference_trial_with_one_rendered_frame(tmp_path, capsys):
    """A reference (not in the tidy log) that rendered one frame is listed and flagged, never hidden."""
    db = live_db(live_protocol(tmp_path / "proto", repetitions=1), tmp_path / "s.db")
    assert craft(db, "planned_trials", {"idx": 0}, {"kind": "reference"}) == 1
    craft(db, "frames", {"idx": 0}, {"render_s": None})
    craft(db, "frames", {"idx": 0, "frame": 0}, {"render_s": 0.01})
    code, out, _ = _run(capsys, "sessions", "--db", db)
    lines = out.splitlines()
    row = [line for line in lines if line.startswith("P1-s1 ") and "ms" in line][0]
    assert code == 0 and row.split()[1] == "1" and "FLAGGED trials 0 (< 2 rendered frames)" in row
    assert " 52ms " in row
    assert [line for line in lines if line.startswith("  trial 0 ")][0].endswith("fewer than two rendered frames")


def test_frame_rates_are_taken_within_a_stimulus_never_across_the_pause_between_a_and_b(tmp_path, capsys):
    """live_db logs each stimulus of a 2AFC trial as 3 flips 1/30 s apart, B 2 s after A: every frame interval
    is 1/30 s (the pause between A and B is none; it read as 0.5 fps in fps_p5), and a trial that rendered
    one frame of each stimulus has no frame rate, so it is flagged although it rendered two frames."""
    from data_schema.store import open_store
    from data_schema.timing import rates, summary

    db = live_db(live_protocol(tmp_path / "proto", repetitions=2), tmp_path / "s.db")
    craft(db, "frames", {"idx": 0}, {"render_s": None})
    craft(db, "frames", {"idx": 0, "frame": 0}, {"render_s": 0.01})  # A's first flip
    craft(db, "frames", {"idx": 0, "frame": 3}, {"render_s": 0.01})  # B's first flip
    with open_store(db) as st:
        flips = st.trial_flips()
        rows = {r["trial"]: r for r in st.tidy_rows()}
    assert flips[("P1", 1)][4] == [0, 0, 0, 1, 1, 1]
    t1 = summary(*flips[("P1", 1)])
    assert t1["fps_median"] == pytest.approx(30.0) and t1["fps_p5"] == pytest.approx(30.0)
    assert rows[1]["fps_p5"] == pytest.approx(30.0)
    assert rates(*flips[("P1", 1)][:2]).min() < 1.0  # without the stimulus column the pause counts
    assert rates(flips[("P1", 0)][0], flips[("P1", 0)][1], flips[("P1", 0)][4]).size == 0
    code, out, _ = _run(capsys, "sessions", "--db", db)
    row = [line for line in out.splitlines() if line.startswith("P1-s1 ") and "ms" in line][0]
    assert code == 0 and "FLAGGED trials 0 (< 2 rendered frames); trials 1 (below min_fps)" in row
    assert "    30.0    30.0 " in row
