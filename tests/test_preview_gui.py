"""``studyapp run PROTOCOL --preview`` (issue 26, item 9) in a real window under Xvfb at a tiny size: every
condition of every scene is shown once (a live protocol and a pre-rendered one), nothing is recorded (no
database anywhere), and a live protocol's frame-rate table is printed at the end; the refusals of options that
belong to a participant's session are one line."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent / "gui"))
from xvfb import ROOT, Xvfb, require_tools  # noqa: E402

from test_live_gui import PROTOCOL as LIVE_PROTOCOL  # noqa: E402

W, H = 96, 54


def _protocol(kind: str) -> str:
    """test_live_gui's protocol at 96x54 with a ground truth and LaFR in two scenes: live (CPU, along the path) or
    pre-rendered still images."""
    doc = yaml.safe_load(LIVE_PROTOCOL)
    doc["name"] = f"preview_{kind}"
    doc["display"].update(width_px=W, height_px=H)
    doc["scenes"] = ["cornell", "temple"]
    doc["conditions"] = {"GT": {"renderer": "gt"}, "LaFR": {"renderer": "lafr", "params": {"delta": 2.0}}}
    if kind == "live":
        for cond in doc["conditions"].values():
            cond["backend"] = "cpu"
        doc["stimulus"] = {"kind": "live", "duration_s": 0.6, "motion": "path", "gaze": "fixation",
                           "fps_check_s": 0.3, "min_fps": 60}
    else:
        doc["stimulus"] = {"kind": "image", "render_px": [W, H]}
    doc["timing"] = {"black_s": 0.2}
    return yaml.safe_dump(doc)


@pytest.fixture(autouse=True)
def _tools():
    require_tools()


def _preview(x, tmp_path: Path, proto: Path, shots: Path) -> str:
    """Run the preview, pressing SPACE every half second (the start screen, still images) until it exits."""
    cmd = [sys.executable, "-m", "studyapp", "run", str(proto), "--preview", "--screenshot-dir", str(shots),
           "--stimuli", str(tmp_path / "stimuli")]
    log = tmp_path / f"{proto.stem}.log"
    with open(log, "w") as out:
        proc = subprocess.Popen(cmd, env=x.env, cwd=str(tmp_path), stdout=out, stderr=subprocess.STDOUT)
        end = time.monotonic() + 120
        try:
            while proc.poll() is None and time.monotonic() < end:
                time.sleep(0.5)
                x.key("space")
        finally:
            if proc.poll() is None:
                proc.kill()
        assert proc.wait() == 0, log.read_text()[-3000:]
    return log.read_text()


def _shown(shots: Path) -> dict[int, list[Path]]:
    out: dict[int, list[Path]] = {}
    for f in shots.glob("trial*_*.png"):
        if "_black_" not in f.name:
            out.setdefault(int(f.name[5:9]), []).append(f)
    return out


def test_preview_shows_every_condition_of_every_scene_records_nothing_and_prints_the_frame_rate_table(tmp_path):
    live, still = tmp_path / "live.yaml", tmp_path / "still.yaml"
    live.write_text(_protocol("live"))
    still.write_text(_protocol("still"))
    prep = subprocess.run([sys.executable, "-m", "studyapp", "prepare", str(still), "--serial", "--stimuli",
                           str(tmp_path / "stimuli")], cwd=str(tmp_path), capture_output=True, text=True)
    assert prep.returncode == 0, prep.stderr
    with Xvfb() as x:
        out_live = _preview(x, tmp_path, live, tmp_path / "shots_live")
        out_still = _preview(x, tmp_path, still, tmp_path / "shots_still")
    print(out_live, out_still, sep="\n")
    for out, shots in ((out_live, tmp_path / "shots_live"), (out_still, tmp_path / "shots_still")):
        assert "preview: 4 of 4 condition x scene pairs shown; nothing was recorded" in out, out
        shown = _shown(shots)
        assert sorted(shown) == [0, 1, 2, 3], sorted(shown)  # GT, LaFR in cornell, then in temple
        for files in shown.values():  # each shows a rendered image, not a black screen
            assert np.asarray(Image.open(sorted(files)[-1]).convert("L")).mean() > 5
    lines = out_live.splitlines()
    head = lines.index("frame-rate check (min_fps 60):")
    table = lines[head + 2:head + 6]
    assert [r.split()[:2] for r in table] == [["GT", "cornell"], ["GT", "temple"], ["LaFR", "cornell"],
                                              ["LaFR", "temple"]], lines
    # a rate below min_fps is marked, never refused: the preview ran to its end either way
    assert all(float(r.split()[3]) > 0 and r.endswith("BELOW min_fps") == (float(r.split()[3]) < 60) for r in table)
    assert "frame-rate check" not in out_still
    assert not list(tmp_path.rglob("*.db")) and not list(Path(ROOT).glob("preview_*.db"))


@pytest.mark.parametrize("extra, named", [(["--participant", "P1"], "--participant"),
                                          (["--db", "x.db", "--resume"], "--db, --resume"),
                                          (["--simulate"], "--simulate")])
def test_preview_refuses_the_options_of_a_session_in_one_line(tmp_path, extra, named, capsys):
    from studyapp.cli import main

    proto = tmp_path / "live.yaml"
    proto.write_text(_protocol("live"))
    assert main(["run", str(proto), "--preview", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"studyapp: error: --preview records nothing and has no participant: drop {named}"]
    assert main(["run", str(proto)]) == 2
    assert "--participant (or --preview for a dry run)" in capsys.readouterr().err
    assert not list(tmp_path.glob("*.db"))


def test_run_help_documents_the_preview(capsys):
    from studyapp.cli import main

    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())  # argparse wraps lines
    assert ("--preview a windowed dry run: every condition of every scene once, labelled, in the window "
            "(pre-rendered or live, at --scale), then a live protocol's frame-rate table; no participant, no answers "
            "collected, no database opened or created") in text
