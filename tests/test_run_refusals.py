"""``run`` (simulated or not) makes every check ``validate`` makes, before anything is created (issue 25, item 6).

Both call ``studyapp.commands.study.checked_protocol``. Before, ``run --simulate`` skipped the renderer checks:
a live condition ``lafr`` with ``delta: -1`` created a database, stored an answer, then died, leaving an
interrupted session (each ``--resume`` added another); a pre-rendered one ran to the end on declared qualities.
Now each bad protocol below is refused by ``validate``, ``run --simulate`` and ``run`` in the same one line,
exit 2, and the folder holds nothing but the protocol afterwards (no database, no -wal/-shm, no stimuli).
"""

from __future__ import annotations

import pytest
import test_live

from studyapp.cli import main


def replaced(text: str, *pairs: tuple[str, str]) -> str:
    """``text`` with each ``(old, new)`` replaced; every ``old`` must be there."""
    for old, new in pairs:
        assert old in text, old
        text = text.replace(old, new)
    return text


# test_live's small live study with declared qualities (for a simulated run without stimuli), no caps
LIVE = replaced(test_live.LIVE, ("{renderer: gt, backend: cpu}", "{renderer: gt, backend: cpu, quality: 1.0}"),
                (", latency_ms: 50, max_fps: 30}", ", quality: 0.5}"), ("  duration_s: 2.0\n", "  duration_s: 1.0\n"),
                ("  min_fps: 45\n", ""), ("repetitions: 2", "repetitions: 1"))
# the same study pre-rendered: its simulated observer answers from the declared qualities (nothing rendered)
SEQUENCE = replaced(LIVE, ("  kind: live\n", "  kind: sequence\n  fps: 2\n"),
                    ("  motion: path\n  gaze: fixation\n", ""), (", backend: cpu", ""))

# (protocol, replaced, replacement, the refusal's field and problem)
CASES = {
    "bad renderer parameter": ("delta: 4.0", "delta: -1", "conditions.LaFR.params: lafr.delta=-1 is out of range"),
    "unknown renderer": ("renderer: lafr", "renderer: nosuch", "conditions.LaFR.renderer: unknown renderer 'nosuch'"),
    "unknown scene": ("scenes: [cornell]", "scenes: [nosuch]", "scenes[0]: unknown scene 'nosuch'"),
    "geometry": ("display: {width_px: 320, height_px: 180, width_cm: 30.0, distance_cm: 40.0",
                 "display: {width_px: 64, height_px: 3338, width_cm: 1.0, distance_cm: 100.84",
                 "conditions.LaFR.renderer: lafr cannot render for this display"),
}


def _write(tmp_path, text):
    (tmp_path / "p.yaml").write_text(text)
    return "p.yaml"


def _refusal(argv, capsys) -> str:
    assert main(argv) == 2
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("studyapp: error: p.yaml:"), err
    return lines[0]


def _refused_alike(tmp_path, capsys, text, expected) -> None:
    proto = _write(tmp_path, text)
    line = _refusal(["validate", proto], capsys)
    assert expected in line
    for extra in (["--simulate"], []):
        assert _refusal(["run", proto, "--participant", "P1", "--quiet", *extra], capsys) == line
        assert _refusal(["run", proto, "--participant", "P1", "--quiet", "--resume", *extra], capsys) == line
        assert sorted(p.name for p in tmp_path.iterdir()) == ["p.yaml"]  # no database, -wal, -shm, stimuli


@pytest.mark.parametrize("kind", ["live", "sequence"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_run_refuses_what_validate_refuses_and_leaves_nothing(case, kind, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    old, new, expected = CASES[case]
    text = {"live": LIVE, "sequence": SEQUENCE}[kind]
    if case == "geometry":
        text = text.replace("render_px: [64, 36]", "render_px: [64, 3338]")
    assert old in text
    _refused_alike(tmp_path, capsys, text.replace(old, new), expected)


@pytest.mark.parametrize("old,new,expected", [
    ("  gaze: fixation\n", "  gaze: fixation\n  explore: {bounds: {cornell: [[0, 0, 0], [-1, 1, 1]]}}\n",
     "stimulus.explore: explore settings belong to motion: explore"),
    ("motion: path", "motion: explore", "stimulus.camera_path: explore moves the camera"),
    ("[{t: 0, yaw_deg: -3}, {t: 1, yaw_deg: 3}]", "[{t: 0, position: [0, 1, 0], look_at: [0, 9, 0]}]",
     "stimulus.camera_path[0]: in scene cornell at t = 0: the view direction is parallel to the scene's up"),
    ("[{t: 0, yaw_deg: -3}, {t: 1, yaw_deg: 3}]", "[{t: 0, yaw_deg: -3}, {t: 0, yaw_deg: 3}]",
     "stimulus.camera_path[1].t: 0 is not after the previous keyframe's t = 0"),
    ("duration_s: 1.0", "duration_s: 0.01", "stimulus.duration_s: 0.01 s is shorter than two refreshes"),
])
def test_run_refuses_contradictory_live_fields_as_validate_does(old, new, expected, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert old in LIVE
    _refused_alike(tmp_path, capsys, LIVE.replace(old, new), expected)


def test_a_valid_protocol_still_runs_simulated(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    proto = _write(tmp_path, SEQUENCE)
    assert main(["validate", proto]) == 0
    assert main(["run", proto, "--participant", "P1", "--simulate", "--quiet"]) == 0
    assert "session P1-s1: completed, 1/1 trials answered" in capsys.readouterr().out
    assert (tmp_path / "tiny_live.db").is_file()
