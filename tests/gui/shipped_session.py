"""Run a shipped protocol's session with `studyapp run` in a real window under Xvfb and answer it with xdotool
(used by tests/test_shipped_screens_gui.py; not collected by pytest).

The window saves a back-buffer screenshot of the black interval before every trial and of the first frame of
every stimulus shown (``run --screenshot-dir``; a live trial: of every rendered frame); :func:`drive` presses
the keys a participant would and grabs the X screen itself where the window saves nothing (the end of a
labelled reference's second half).
"""

from __future__ import annotations

import re
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from PIL import Image, ImageGrab

from xvfb import PYTHON, ROOT, Xvfb, query

PROTOCOLS = ROOT / "studyapp" / "protocols"

#: psychtoolbox key names -> X keysyms (xdotool)
_XKEYS = {"left": "Left", "right": "Right", "return": "Return", "space": "space", "escape": "Escape"}


def xkey(name: str) -> str:
    if re.fullmatch(r"f\d+", name):
        return name.upper()
    return _XKEYS.get(name, name)


def short_copy(name: str, folder: Path, **presentation) -> Path:
    """The shipped protocol ``name`` written to ``folder`` with its timing shortened (sequences of 2 s at 1
    fps, live trials of 1.5 s, black intervals of 0.3 s, no frame-rate check, the gaze from the window's
    pointer instead of iohub's MouseGaze and its calibration), live conditions at their renderer's preview
    parameters (what ``run --simulate`` renders: sl_gt with 256 + 256 samples instead of 2048 + 2048) and
    ``presentation`` set; display, conditions, scenes, keys, labels and design are the shipped ones."""
    from renderers.registry import preview_params

    data = yaml.safe_load((PROTOCOLS / f"{name}.yaml").read_text())
    stim = data["stimulus"]
    if stim["kind"] == "live":
        stim["duration_s"] = 1.5
        stim["fps_check_s"] = 0
        stim["gaze"] = "mouse"  # the window's pointer: no iohub server to start (calibration is not shown)
        data.pop("eyetracker", None)
        for cond in data["conditions"].values():
            if cond.get("renderer"):
                cond["params"] = preview_params(cond["renderer"], cond.get("params", {}))
    elif stim.get("kind", "image") == "sequence":
        stim["duration_s"], stim["fps"] = 2.0, 1
    data["timing"]["black_s"] = 0.3
    if presentation:
        data["presentation"] = dict(presentation)
    out = folder / f"{name}.yaml"
    out.write_text(yaml.safe_dump(data, sort_keys=False))
    return out


def colour(i: int, k: int) -> tuple[int, int, int]:
    """The uniform colour of condition ``i``'s frame ``k`` (every channel in 60..190: never black, never a
    text colour; frame 1 differs from frame 0 in green)."""
    base = [(150, 70, 90), (70, 150, 90), (90, 80, 160), (160, 140, 60), (60, 120, 150),
            (130, 90, 130)][i % 6]
    return (base[0], min(190, base[1] + 30 * k), base[2])


def write_frames(protocol, scale: float) -> dict[str, int]:
    """Uniform frames for every stimulus the protocol's schedule may show, at the render size ``prepare
    --scale`` writes, where `studyapp run` looks for them; returns condition -> colour index. (Rendering the
    real set at --scale 0.05 took 10 min for seed001 here: VaFR's cost does not shrink with the size.)"""
    from studyapp.runner.stimuli import frame_paths, needed_stimuli

    g = protocol.render_geometry(scale)
    index = {c: i for i, c in enumerate(protocol.conditions)}
    for n in needed_stimuli(protocol):
        for k, f in enumerate(frame_paths(protocol, n.condition, n.scene, scale)):
            f.parent.mkdir(parents=True, exist_ok=True)
            Image.new("RGB", (g.width, g.height), colour(index[n.condition], k)).save(f)
    return index


def shots_of(shots: Path, idx: int, what: str) -> list[Path]:
    """Screenshots of trial ``idx`` named ``what`` (``black``, ``stim0``, ``live``...), in the order taken."""
    files = [f for f in shots.glob(f"trial{idx:04d}_{what}*.png") if not f.name.endswith(".tmp")]
    return sorted(files, key=lambda f: int(f.stem.rsplit("_", 1)[1]))


def load(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB")).astype(int)


@dataclass
class Run:
    """What a driven session left: the screenshot folder, the X grabs taken, the trials driven, the output."""

    shots: Path
    grabs: dict = field(default_factory=dict)  # reference trial -> X-screen grabs (RGB) of its second half
    trials: list = field(default_factory=list)  # the PlannedTrials driven, in order
    live_first: dict = field(default_factory=dict)  # (trial, stimulus) -> index of a live shot of it
    db: Path | None = None  # the session's database
    stdout: str = ""
    stderr: str = ""
    seconds: float = 0.0


def _wait(what, timeout_s: float, proc, action=None, every_s: float = 0.6):
    """Poll ``what()`` until it is truthy; ``action()`` every ``every_s`` meanwhile; fail if the session
    exits."""
    deadline = time.monotonic() + timeout_s
    last = 0.0
    while True:
        got = what()
        if got:
            return got
        if proc.poll() is not None:
            raise AssertionError(f"the session exited ({proc.returncode}) while waiting")
        if time.monotonic() > deadline:
            raise AssertionError("timed out waiting")
        if action is not None and time.monotonic() - last > every_s:
            action()
            last = time.monotonic()
        time.sleep(0.03)


def drive(x: Xvfb, copy: Path, workdir: Path, scale: float, n_main: int = 1, timeout_s: float = 120.0) -> Run:
    """Run participant P1 of the protocol ``copy`` (cwd ``workdir``) and answer every trial up to and
    including the ``n_main``-th trial that is neither practice nor reference: each stimulus of a trial is
    shown once (switch keys), then the first answer key (two picks where the family picks two) is pressed; at
    the next trial Escape, then E, end the session. A reference's screen is grabbed from X near its end (a
    still reference, which stays until SPACE: for a second before SPACE is pressed)."""
    from studyapp.runner.protocol import load_protocol
    from studyapp.runner.schedule import build_schedule

    p = load_protocol(copy, check_renderers=False)
    schedule = build_schedule(p, "P1", 0)
    shots = workdir / "shots"
    shots.mkdir()
    run = Run(shots, db=workdir / "s.db")
    t0 = time.monotonic()
    err = open(workdir / "run.stderr", "w")
    proc = subprocess.Popen(
        [PYTHON, "-m", "studyapp", "run", str(copy), "--participant", "P1", "--db", str(workdir / "s.db"),
         "--scale", f"{scale:g}", "--screenshot-dir", str(shots), "--quiet", "--accept-slow"],
        cwd=str(workdir), env=x.env, stdout=subprocess.PIPE, stderr=err, text=True)
    what = "live" if p.live else "stim"
    answer_keys = [xkey(k) for k, a in p.answer_keys.items() if a != ""][: p.n_picks]
    db = workdir / "s.db"

    def answered(idx):
        return query(db, "SELECT 1 FROM responses WHERE participant = 'P1' AND idx = ?", idx)

    try:
        _wait(lambda: shots_of(shots, schedule[0].index, "black"), 90, proc, lambda: x.key("space"))
        mains = 0
        for t in schedule:
            run.trials.append(t)
            first = _wait(lambda: shots_of(shots, t.index, what), timeout_s, proc)[0]
            if t.kind == "reference" and p.duration_s is None:  # a still reference stays until SPACE: grab
                # the X screen for a while, then press SPACE until the next trial's black interval
                nxt = schedule[len(run.trials)].index
                grabs = run.grabs.setdefault(t.index, [])
                time.sleep(0.3)
                for _ in range(5):
                    grabs.append(np.asarray(ImageGrab.grab(xdisplay=x.display).convert("RGB")))
                    time.sleep(0.2)
                _wait(lambda: shots_of(shots, nxt, "black"), timeout_s, proc, lambda: x.key("space"), 1.5)
                continue
            if t.kind == "reference":  # plays without keys: grab the X screen from mid-way until it has ended
                # (timed from the shot's file, written just before the onset flip, not from when it was seen)
                nxt = schedule[len(run.trials)].index
                time.sleep(max(0.0, first.stat().st_mtime + 0.5 * p.duration_s - time.time()))
                grabs = run.grabs.setdefault(t.index, [])
                while not shots_of(shots, nxt, "black") and proc.poll() is None:
                    grabs.append(np.asarray(ImageGrab.grab(xdisplay=x.display).convert("RGB")))
                    time.sleep(0.1)
                continue
            # The shot is saved just before the first flip, and keys that went down before it are dropped:
            # press a moment later, and again until the press shows.
            time.sleep(0.3)
            for i in range(1, len(t.conditions)):  # show every stimulus of the trial once
                key = xkey(next(k for k, j in p.switch_keys.items() if j == i))
                if p.live:  # the frames rendered after the switch are the new stimulus'
                    seen = len(shots_of(shots, t.index, what))
                    run.live_first[(t.index, i)] = seen + 1  # the second frame after it (none in flight)
                    _wait(lambda: len(shots_of(shots, t.index, what)) >= seen + 2, timeout_s, proc,
                          lambda: x.key(key), 3.0)
                else:
                    _wait(lambda: shots_of(shots, t.index, f"stim{i}"), timeout_s, proc, lambda: x.key(key),
                          1.5)
            _wait(lambda: answered(t.index), timeout_s, proc, lambda: x.key(*answer_keys), 2.0)
            if t.kind not in ("practice", "reference"):
                mains += 1
                if mains == n_main:
                    break
        nxt = schedule[len(run.trials)]
        _wait(lambda: shots_of(shots, nxt.index, "black"), timeout_s, proc)
        deadline = time.monotonic() + 60
        while proc.poll() is None and time.monotonic() < deadline:  # Escape pauses, then E ends the session
            x.key("Escape")
            time.sleep(0.3)
            x.key("e")
            time.sleep(0.5)
        run.stdout = proc.communicate(timeout=30)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        err.close()
    run.stderr = (workdir / "run.stderr").read_text()
    run.seconds = time.monotonic() - t0
    assert proc.returncode == 0, run.stderr[-3000:]
    return run


if __name__ == "__main__":  # pragma: no cover - by hand: python tests/gui/shipped_session.py NAME SCALE DIR
    name, scale, folder = sys.argv[1], float(sys.argv[2]), Path(sys.argv[3])
    folder.mkdir(parents=True, exist_ok=True)
    with Xvfb(screen="1920x1080x24") as xv:
        from studyapp.runner.protocol import load_protocol

        c = short_copy(name, folder)
        if not load_protocol(c, check_renderers=False).live:
            write_frames(load_protocol(c, check_renderers=False), scale)
        r = drive(xv, c, folder, scale)
        print(r.stdout, r.stderr, f"{r.seconds:.1f} s")
