"""Replay shows what was seen (issue 26, item 5): a live session in a real window under Xvfb at a quarter of its
display's size (``run --scale 0.25``), one trial interrupted by Escape and resumed; then ``studyapp replay`` of
each trial. Every replayed window image (``shown/``) equals the screenshot of the same flip, the interrupted
attempt's included, at >= 40 dB PSNR: the same render size, eye layout (a monoscopic display shows the right
eye of a binocular renderer, ``stereo: dup, eye: right``, over the whole window; a stereo display both eyes side
by side) and backend. (LaFR stands in for VaFR's binocular ``rep``: the layout is the same, and VaFR renders
10-20 s a frame at this size on this machine.)"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from PIL import Image
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent / "gui"))
from test_live_gui import PROTOCOL as LIVE_PROTOCOL  # noqa: E402
from test_live_gui import _press_until, _psnr, _wait  # noqa: E402
from xvfb import ROOT, Xvfb, require_tools  # noqa: E402
from xvfb import query as _q  # noqa: E402

W, H = 384, 216  # the display; --scale 0.25 renders 96 x 54, magnified 4x by the window
BACKEND = os.environ.get("STUDYAPP_LIVE_TEST_BACKEND", "gpu")  # the live backend; cpu also works

def _protocol(stereo: bool) -> str:
    """test_live_gui's protocol in interior at the display size, without the key reminder: LaFR and LaFR_Dup
    (binocular: its right eye over the window on a mono display, side by side on a stereo one)."""
    doc = yaml.safe_load(LIVE_PROTOCOL)
    doc["name"] = "gui_replay"
    doc["display"].update(width_px=W, height_px=H, **({"stereo": True} if stereo else {}))
    doc["presentation"] = {"key_reminder": "off"}
    doc["scenes"] = ["interior"]
    dup = {"delta": 2.0, "stereo": "dup", **({} if stereo else {"eye": "right"})}
    doc["conditions"] = {"LaFR": {"renderer": "lafr", "params": {"delta": 2.0}, "backend": BACKEND},
                         "LaFR_Dup": {"renderer": "lafr", "params": dup, "backend": BACKEND}}
    doc["stimulus"].update(duration_s=1.0, fps_check_s=0.2)
    doc["stimulus"].pop("explore", None)
    doc["timing"] = {"black_s": 0.2}
    return yaml.safe_dump(doc)


def _attempt_shots(folder: Path, trial: int) -> list[dict[int, Path]]:
    """The screenshots of a trial's rendered frames, per attempt: frame -> file (an attempt starts again at a
    lower frame number; files are numbered in the order taken)."""
    shots = sorted(folder.glob(f"trial{trial:04d}_live*.png"), key=lambda p: int(p.stem.rsplit("_", 1)[1]))
    attempts: list[dict[int, Path]] = []
    last = None
    for s in shots:
        frame = int(s.name.split("_live")[1][:5])
        if last is None or frame <= last:
            attempts.append({})
        attempts[-1][frame] = s
        last = frame
    return attempts


def _session(tmp_path: Path, stereo: bool) -> tuple[Path, dict, Path]:
    """Run the study in a window: the first trial is interrupted by Escape after a few frames and resumed."""
    require_tools()
    proto = tmp_path / "replay.yaml"
    proto.write_text(_protocol(stereo))
    db, shots = tmp_path / "s.db", tmp_path / "shots"
    cmd = [sys.executable, "-m", "studyapp", "run", str(proto), "--participant", "P1", "--db", str(db),
           "--scale", "0.25", "--screenshot-dir", str(shots)]
    with Xvfb() as x:
        with open(tmp_path / "run.log", "w") as log:
            proc = subprocess.Popen(cmd, env=x.env, cwd=str(ROOT), stdout=log, stderr=subprocess.STDOUT)
            try:
                _wait(lambda: _q(db, "SELECT COUNT(*) FROM events WHERE kind = 'fps_check'") == [(1,)], 90, proc,
                      "the frame-rate check")
                planned = dict(_q(db, "SELECT idx, conditions FROM planned_trials ORDER BY idx"))
                import json

                display = json.loads(_q(db, "SELECT display FROM sessions")[0][0])
                wx, wy = display["window_pos_px"]
                x.xdotool("mousemove", str(wx + 250), str(wy + 70))  # the gaze, off the centre
                time.sleep(0.8)
                x.key("space")  # leave the instructions
                first, second = sorted(planned)
                _wait(lambda: len(list(shots.glob(f"trial{first:04d}_live*.png"))) >= 3, 60, proc,
                      "the first frames")
                x.key("Escape")
                _wait(lambda: _q(db, "SELECT COUNT(*) FROM events WHERE kind = 'pause'") == [(1,)], 20, proc,
                      "the pause")
                x.xdotool("mousemove", str(wx + 60), str(wy + 150))  # the retry is foveated elsewhere
                time.sleep(0.3)
                x.key("r")  # resume: the trial starts again
                _press_until(x, "y", lambda: _q(db, "SELECT COUNT(*) FROM responses") == [(1,)], 40, "the answer")
                _press_until(x, "n", lambda: _q(db, "SELECT COUNT(*) FROM responses") == [(2,)], 40, "the second")
                proc.wait(timeout=30)
            finally:
                if proc.poll() is None:
                    proc.kill()
                    proc.wait()
    assert proc.returncode == 0, (tmp_path / "run.log").read_text()[-2000:]
    return db, planned, shots


def _replay(db: Path, trial: int, out: Path) -> pd.DataFrame:
    r = subprocess.run([sys.executable, "-m", "studyapp", "replay", "--db", str(db), "--participant", "P1",
                        "--trial", str(trial), "--out", str(out), "--serial", "--every", "2",
                        "--cache", str(out.parent / "cache")],
                       cwd=str(ROOT), env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "note:" not in r.stderr, r.stderr  # this session recorded its layout
    return pd.read_csv(out / "frames.csv")


@pytest.mark.parametrize("stereo", [False, True], ids=["mono_display", "stereo_display"])
def test_replayed_frames_equal_the_screenshots_of_the_session(tmp_path, stereo):
    db, planned, shots = _session(tmp_path, stereo)
    first, second = sorted(planned)
    # the interrupted attempt's flips are kept apart from the answer's
    assert _q(db, "SELECT COUNT(*) FROM events WHERE kind = 'interrupted_attempt'") == [(1,)]
    psnr: dict[str, list[float]] = {}
    other: list[float] = []  # an interrupted frame against the retry's screenshot (another gaze): told apart
    for trial in (first, second):
        frames = _replay(db, trial, tmp_path / f"rep{trial}")
        attempts = _attempt_shots(shots, trial)
        assert len(attempts) == (2 if trial == first else 1), [sorted(a) for a in attempts]
        assert sorted(set(frames["attempt"])) == list(range(1, len(attempts) + 1))
        assert frames.groupby("attempt")["interrupted"].first().tolist() == [1] * (len(attempts) - 1) + [0]
        for r in frames.itertuples():
            stem = Path(r.file).stem
            assert stem == (f"interrupted{r.attempt}_frame_{r.frame:05d}" if r.interrupted else f"frame_{r.frame:05d}")
            shot = np.asarray(Image.open(attempts[r.attempt - 1][r.frame]).convert("RGB"))
            shown = np.asarray(Image.open(tmp_path / f"rep{trial}" / r.shown))
            assert shown.shape == shot.shape == (H, W, 3)
            # the condition's own image is the render at the session's size: a quarter of the display
            eyes = 2 if stereo and r.condition == "LaFR_Dup" else 1
            assert Image.open(tmp_path / f"rep{trial}" / r.file).size == (96 // eyes, 54)
            assert r.backend == BACKEND
            psnr.setdefault(f"{r.condition}{' (interrupted)' if r.interrupted else ''}", []).append(
                _psnr(shown, shot))
            if r.interrupted:
                other.append(_psnr(shown, np.asarray(Image.open(attempts[-1][min(attempts[-1])]).convert("RGB"))))
    layout = "stereo display" if stereo else "mono display"
    for cond, values in sorted(psnr.items()):
        print(f"{layout}, {cond}: {len(values)} frames, PSNR min {min(values):.1f} dB, median "
              f"{np.median(values):.1f} dB")
    print(f"{layout}: an interrupted frame against the retry's first screenshot: PSNR max {max(other):.1f} dB")
    assert any("interrupted" in k for k in psnr), psnr
    assert max(other) < 35.0, other
    assert all(min(v) >= 40.0 for v in psnr.values()), psnr
