"""Live trials apart from any window: motion, gaze delay, frame pacing, timing summary (studyapp/runner/live.py)."""

import math

import numpy as np
import pytest

from crafted_db import live_text
from studyapp.runner.live import ExploreMotion, FramePacer, FrameRecord, GazeDelay, Pose, timing_summary


def test_gaze_delay_uses_the_newest_sample_old_enough():
    g = GazeDelay(latency_s=0.05)
    for i in range(20):  # 100 Hz samples moving right
        g.push(i * 0.01, float(i), 0.0)
    t, x, _ = g.at(0.19)
    assert t == pytest.approx(0.14) and x == 14.0  # 50 ms behind
    assert GazeDelay(0.5).at(0.1) is None
    g0 = GazeDelay(0.0)
    g0.push(1.0, 3.0, 4.0)
    g0.push(1.0, 9.0, 9.0)  # the same sample polled twice is kept once
    assert g0.at(1.0) == (1.0, 3.0, 4.0)


@pytest.mark.parametrize("refresh,cap,expected", [(60, 30, 30), (60, None, 60), (60, 20, 20), (90, 45, 45)])
def test_frame_pacer_renders_at_the_cap(refresh, cap, expected):
    p = FramePacer(cap)
    flips = [i / refresh for i in range(refresh * 2)]
    n = sum(p.due(t) for t in flips)
    assert n == pytest.approx(2 * expected, abs=1)


def test_explore_moves_turns_and_stays_in_bounds():
    m = ExploreMotion(Pose((0, 1, 0), (0, 1, 1)), move_speed=2.0, turn_speed_deg=90.0,
                      bounds=((-1, 0, -1), (1, 2, 3)))
    m.pose(0.0)
    p = m.pose(0.5, keys={"w"})  # forward (+z) for 0.5 s at 2 units/s
    assert p.position == pytest.approx((0, 1, 1))
    p = m.pose(1.5, keys={"w"})  # stopped by the bounds at z = 3
    assert p.position[2] == pytest.approx(3.0)
    p = m.pose(2.5, keys={"right"})  # 90 degrees to the right: now looking along +x
    d = np.subtract(p.look_at, p.position)
    assert d / np.linalg.norm(d) == pytest.approx((1, 0, 0), abs=1e-9)
    p = m.pose(3.0, keys={"up"}, mouse=(0, -10000))  # pitch stays within 85 degrees
    d = np.subtract(p.look_at, p.position)
    assert math.degrees(math.asin(d[1] / np.linalg.norm(d))) == pytest.approx(85.0)


def test_timing_summary_from_frames():
    frames = [FrameRecord(i, 0, i / 60, 0.004 if i % 2 == 0 else None, i / 60 - 0.03, 1.0, 2.0,
                          dropped=(i == 5)) for i in range(60)]
    s = timing_summary(frames)
    assert s["fps_median"] == pytest.approx(30.0) and s["fps_p5"] == pytest.approx(30.0)
    assert s["dropped_share"] == pytest.approx(1 / 60) and s["latency_p50_ms"] == pytest.approx(30.0)
    assert math.isnan(timing_summary([])["fps_median"])


LIVE = live_text(reference="GT", render_px=(64, 36))


def test_a_simulated_live_session_logs_frames_and_timing(tmp_path, capsys):
    from data_schema.store import open_store
    from studyapp.cli import main
    from studyapp.runner.protocol import load_protocol

    f = tmp_path / "live.yaml"
    f.write_text(LIVE)
    p = load_protocol(f)
    assert p.live and p.n_frames == 0 and p.backend_of("LaFR") == "cpu"
    db = tmp_path / "s.db"
    assert main(["run", str(f), "--participant", "P1", "--simulate", "--db", str(db), "--quiet"]) == 0
    with open_store(db) as st:
        frames = st.frames("P1")
        rows = st.tidy_rows()
        scenes = st.session_scenes("P1-s1")
    from renderers.catalog import resolve

    # what replay checks: the protocol's folder and the content hash of each scene, recorded with the session
    assert scenes == {"folder": str(tmp_path.resolve()), "scenes": {"cornell": resolve("cornell").content_hash()}}
    assert len(rows) == 2 and {r["chosen"] for r in rows} <= {"GT", "LaFR"}
    assert len(frames) == 2 * 2 * 3  # 2 trials x 2 stimuli x 3 simulated frames
    assert all(r["render_s"] is not None and r["render_s"] > 0 for r in frames)
    lafr = [r for r in frames if r["stimulus"] == [i for i, c in enumerate(rows[0]["condition_a"] and
            (rows[0]["condition_a"], rows[0]["condition_b"])) if c == "LaFR"][0] and r["idx"] == rows[0]["trial"]]
    assert all((r["flip_s"] - r["gaze_t"]) == pytest.approx(0.052) for r in lafr)  # 50 ms + 2 ms nominal
    assert all(isinstance(rows[0][c], float) for c in ("fps_median", "latency_p95_ms"))
    capsys.readouterr()
    assert main(["sessions", "--db", str(db)]) == 0
    out = capsys.readouterr().out
    assert "trials below min_fps 45 flagged" in out and "FLAGGED trials 0, 1 (below min_fps)" in out
    assert main(["export", "--db", str(db), "--format", "frames", "--out", str(tmp_path / "frames.parquet")]) == 0
    import pandas as pd

    df = pd.read_parquet(tmp_path / "frames.parquet")
    assert len(df) == len(frames) and {"gaze_age_ms", "pos_x", "look_z", "dropped"} <= set(df.columns)


def test_replay_re_renders_the_logged_frames_and_scores_them_along_the_gaze(tmp_path, capsys):
    import json

    import numpy as np

    from data_schema.store import open_store
    from studyapp.cli import main

    f = tmp_path / "live.yaml"
    f.write_text(LIVE)
    db = tmp_path / "s.db"
    assert main(["run", str(f), "--participant", "P1", "--simulate", "--db", str(db), "--quiet"]) == 0
    with open_store(db) as st:
        logged = st.frames("P1", 0)
    out = tmp_path / "replay"
    assert main(["replay", "--db", str(db), "--participant", "P1", "--trial", "0", "--out", str(out),
                 "--quality", "--serial", "--cache", str(tmp_path / "cache")]) == 0
    rows = (out / "frames.csv").read_text().splitlines()
    assert len(rows) == 1 + len(logged)
    assert sorted(p.name for p in out.iterdir()) == ["conditions", "flips.csv", "frames.csv", "gaze.csv",
                                                      "ground_truth", "quality.csv", "quality.md", "shown"]
    assert sorted(p.name for p in (out / "conditions").iterdir()) == ["GT", "LaFR"]
    q = (out / "quality.csv").read_text().splitlines()
    assert len(q) == 1 + 3 * len(logged)  # fovea, periphery, all per frame
    # the GT condition replayed is the ground truth: zero error; LaFR has some, more in the periphery
    import pandas as pd

    t = pd.read_csv(out / "quality.csv")
    assert (t[t.image.str.startswith("conditions/GT/")]["mse"] == 0).all()
    lafr = t[t.image.str.startswith("conditions/LaFR/")]
    assert lafr[lafr.region == "periphery"]["mse"].mean() > lafr[lafr.region == "fovea"]["mse"].mean()
    # studyapp quality gives the same numbers from the files replay wrote
    capsys.readouterr()
    fov = load_protocol_fov(f)
    assert main(["quality", "--gt", str(out / "ground_truth"), "--gaze-csv", str(out / "gaze.csv"), "--fov-y",
                 str(fov), "--json", str(out / "conditions" / "LaFR")]) == 0
    recs = json.loads(capsys.readouterr().out)
    assert len(recs) == len(lafr)
    np.testing.assert_allclose([r["mse"] for r in recs], lafr["mse"].to_numpy(), rtol=1e-12)
    assert main(["replay", "--db", str(db), "--participant", "P1", "--trial", "99", "--out", str(tmp_path / "x")]) \
        == 2


def load_protocol_fov(path):
    from studyapp.runner.protocol import load_protocol

    return repr(load_protocol(path).display.fov_y_deg)


def test_the_simulated_observer_renders_vafr_thumbnails_at_their_own_nyquist_rate():
    """VaFR shades ~1e6 LP pixels whatever the image size; the observer's 64-pixel thumbnails cap the acuity
    curve at their Nyquist rate (preset auto), and VaFR still differs from GT less than LaFR does."""
    from data_schema.geometry import ViewingGeometry
    from renderers.catalog import resolve
    from renderers.registry import preview_params, render
    from renderers.stimuli import to_srgb8
    from studyapp.runner.observer import foveated_difference

    assert preview_params("vafr", {"stereo": "dup"}) == {"stereo": "dup", "preset": "auto"}
    assert preview_params("lafr", {"delta": 2.2}) == {"delta": 2.2}  # no preview hook: unchanged
    luma = np.array([0.2126, 0.7152, 0.0722])
    exposure = resolve("cornell").exposure
    geometry = ViewingGeometry(64, 36, 60.0, 40.0, 12.0)
    kw = {"gaze": (40.0, 12.0), "camera": {"fov_y": 60.0}}

    def gray(renderer, params):
        img, stats = render("cornell", renderer, params, 64, 36, **kw)
        return (to_srgb8(img, exposure) / 255.0) @ luma, stats

    ref, _ = gray("gt", {})
    vafr, stats = gray("vafr", preview_params("vafr", {}))
    lafr, _ = gray("lafr", {"delta": 2.2})
    assert stats["shading_points"] < 10_000  # ~1e6 without the cap
    ecc = geometry.eccentricity_map()
    assert foveated_difference(vafr, ref, ecc) < foveated_difference(lafr, ref, ecc)


FAMILIES = {
    "preference": ("family: preference", "design: {conditions: [GT, LaFR, LaFR8], repetitions: 1, n_picks: 2}",
                   "votes"),
    "yes_no_reference": ("family: yes_no", "design: {conditions: [LaFR, LaFR8], repetitions: 1, "
                         "reference: {condition: GT, label: This is the ground truth}}", "response"),
}


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_every_trial_family_runs_live(tmp_path, family):
    """Top two of N with live stimuli, and "is this the ground truth?" with the labelled ground truth shown
    live first (2AFC: the tests above); every stimulus of every trial has its frames logged."""
    from data_schema.store import open_store
    from studyapp.cli import main

    fam, design, dv = FAMILIES[family]
    text = (LIVE.replace("family: 2afc", fam).replace("design: {repetitions: 2}", design)
            .replace("  LaFR: {renderer: lafr", "  LaFR8: {renderer: lafr, params: {delta: 8.0}, backend: cpu}\n"
                     "  LaFR: {renderer: lafr")
            .replace("analysis: {dv: chosen, unit: participant, test: thurstone}",
                     f"analysis: {{dv: {dv}, unit: trial, test: summary_table}}"))
    f = tmp_path / "live.yaml"
    f.write_text(text)
    db = tmp_path / "s.db"
    assert main(["run", str(f), "--participant", "P1", "--simulate", "--db", str(db), "--quiet"]) == 0
    with open_store(db) as st:
        planned = st.planned("P1")
        frames = st.frames("P1")
    shown = {(r["idx"], r["stimulus"]) for r in frames}
    assert shown == {(t.idx, k) for t in planned for k in range(len(t.conditions))}
    if family == "yes_no_reference":
        assert planned[0].kind == "reference" and planned[0].conditions == ("GT",)
    else:
        assert all(len(t.conditions) == 3 for t in planned if t.kind == "trial")


def test_exploration_keys_cannot_answer_or_switch(tmp_path):
    from data_schema.errors import UserError
    from studyapp.runner.protocol import load_protocol

    explore = LIVE.replace("  motion: path\n", "  motion: explore\n").replace(
        "  camera_path: [{t: 0, yaw_deg: -3}, {t: 1, yaw_deg: 3}]\n", "")
    f = tmp_path / "live.yaml"
    f.write_text(explore)  # 2AFC's default switch keys are the arrows, which turn the camera
    with pytest.raises(UserError, match=r"keys.switch.left: key 'left' also moves the camera when exploring"):
        load_protocol(f, check_renderers=False)
    f.write_text(explore + 'keys: {switch: {q: 0, e: 1}, answer: {"1": A, "2": B}}\n')
    assert load_protocol(f, check_renderers=False).motion == "explore"


def test_the_ground_truth_of_the_lightcuts_thumbnails_has_fewer_samples():
    """sl_gt's preview (the simulated observer's 64-pixel frames, its reference included) caps the samples at
    256 + 256; the order of the conditions it answers from is measured to be kept (plugin.sl_gt_preview)."""
    from renderers.registry import preview_params

    assert preview_params("sl_gt", {}) == {"lspp": 256, "rspp": 256}
    assert preview_params("sl_gt", {"lspp": 64, "seed": 3}) == {"lspp": 64, "rspp": 256, "seed": 3}
    assert preview_params("fsl", {"alpha": 0.1}) == {"alpha": 0.1}


def test_simulated_live_samples_and_thumbnails_are_per_protocol():
    """Two protocols with the same condition and scene names (seed003_task1_live: 8-s paths; task2_live: 16-s
    explorations) do not share the simulated observer's gaze samples within one process (nor, by the same key,
    its ground-truth thumbnails and impairments)."""
    from pathlib import Path

    from studyapp.runner.live import live_stimulus
    from studyapp.runner.observer import SimulatedObserver
    from studyapp.runner.protocol import load_protocol

    protocols = Path(__file__).resolve().parents[1] / "protocols"
    times = []
    for name in ("seed003_task1_live", "seed003_task2_live"):
        p = load_protocol(protocols / f"{name}.yaml", check_renderers=False)
        obs = SimulatedObserver(p, "P1", 0, {})
        times.append([t for t, *_ in obs._live_samples(live_stimulus(p, "EC", "study"), "study")])
    assert times[0] != times[1] and max(times[0]) < 8.0 < max(times[1])
