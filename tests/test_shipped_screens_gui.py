"""What a participant sees in every shipped protocol (issue 26, "Done when"): `studyapp run` in a real window
of the protocol's display (1920x1080) under Xvfb, answered with xdotool through its practice trial(s) into its
first main trial (an adaptive design, which has no practice: its first two trials), checked from the
screenshots the window saves (``run --screenshot-dir``: the black interval before each trial, the first frame
of each stimulus, every rendered live frame) and X-screen grabs of a labelled reference (a sequence: its
second half; a still image: before SPACE ends it).

Each session runs a copy of the shipped protocol with its timing shortened (tests/gui/shipped_session.py:
short_copy): pre-rendered stimuli are uniform frames of a colour per condition (an adaptive ladder: per
level, ``NAME(level)``; the level a trial showed is read from the session's ``adaptive`` row) written where
``prepare --scale`` writes them (rendering the real set at --scale 0.05 took 10 min here), live ones render
at 58x32 (:func:`scale_of`) with their renderer's preview parameters. The sessions of the selected protocols
(``-k``) run at once, each in its own Xvfb: the nine of the fixed designs about 3 min on the shared 2-core
machine at load 13-16 (each `run` takes 10-20 s to open its window there, and the live trials render on
llvmpipe), the four adaptive ones 26-38 s each at load 3.

Measures (pixels only):

- stimulus rectangle: the bounding box of the non-black pixels of each condition's first frame. Pre-rendered:
  it equals the viewport :func:`data_schema.geometry.eye_views` gives (the whole window on the shipped
  monoscopic display) for every condition shown, and the pixels inside are the condition's colour. Live (the
  content decides where pixels are black: the cornell boxes leave black around the box): every condition of a
  scene has the same box within one render pixel, inside the viewport, and in a scene whose view reaches the
  window's edges (driven up to the first main trial in one) the box is the viewport;
- text: the presenter's rendering of the same text over black (tests/gui/drive_presenter.py, one run in a
  window of the same size) gives the mask of fully inked pixels; the label ("This is the ground truth") and
  the "practice" tag are found where at least 90 % of their mask shows the text colour, at the reference's
  first frame and in every X grab of its second half (the last frame included); the progress text of the black
  interval ("practice", "1 / N") is the bottom 60 rows equal (max difference <= 8) to the rendering of the
  expected text, and unequal to the count that includes practice trials;
- key reminder: light text (every channel > 205) in the bottom band of 1.6 text heights, over the stimulus
  dimmed to 30 %; with ``presentation.key_reminder: off`` none, and the stimulus undimmed at the bottom edge.
"""

from __future__ import annotations

import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent / "gui"))
import psychopy  # noqa: E402,F401 - the GUI tests need it: a missing install is a failure, not a skip
from shipped_session import (colour, drive, load, short_copy, shots_of,  # noqa: E402
                             write_frames)
from xvfb import Driver, Xvfb, query, require_tools  # noqa: E402

from data_schema.geometry import eye_views  # noqa: E402
from studyapp.runner.adaptive import level_condition  # noqa: E402
from studyapp.runner.adaptive_run import varied_of  # noqa: E402
from studyapp.runner.live import live_stimulus  # noqa: E402
from studyapp.runner.protocol import load_protocol  # noqa: E402
from studyapp.runner.session import counted  # noqa: E402

PROTOCOL_DIR = Path(__file__).resolve().parents[1] / "studyapp" / "protocols"
NAMES = sorted(p.stem for p in PROTOCOL_DIR.glob("*.yaml"))
W, H = 1920, 1080  # every shipped protocol's display
SCREEN = f"{W}x{H}x24"
TEXT_H = 30  # the presenter's text height in a 1080-row window (1/36 of it)
BAND = round(1.6 * TEXT_H)  # the key reminder's band
LABEL = "This is the ground truth"
TAG_RGB = (255, 229, 153)  # "practice": PsychoPy rgb (1, 0.8, 0.2)
OFF = "seed001_pilot+off"  # seed001_pilot with presentation.key_reminder: off
BOXED = ("cornell", "cornell_many")  # scenes whose live start view leaves black around the box


def copy_of(name: str, folder: Path) -> Path:
    """The test's copy of a shipped protocol (``OFF``: with the key reminder turned off)."""
    return short_copy(name.split("+")[0], folder, **({"key_reminder": "off"} if name == OFF else {}))


def _session(name: str, folder: Path, out: dict) -> None:
    try:
        copy = copy_of(name, folder)
        p = load_protocol(copy, check_renderers=False)
        if not p.live:
            write_frames(p, scale_of(p))
        with Xvfb(screen=SCREEN) as x:
            out[name] = (p, drive(x, copy, folder, scale_of(p), n_main(p)))
        print(f"{name}: {out[name][1].seconds:.1f} s", file=sys.stderr)
    except BaseException as exc:  # reported by the test of this protocol
        out[name] = exc


def _references(folder: Path, texts: list[str], out: dict) -> None:
    """The presenter's own rendering over black of the label, the "practice" tag and each progress text."""
    try:
        black = folder / "black.png"
        Image.new("RGB", (16, 9)).save(black)
        still = [{"condition": "X", "frames": [str(black)], "fps": 0.0}]
        base = {"family": "yes_no", "stimuli": still, "question": "", "answer_keys": {}, "duration_s": 0.05,
                "black_before_s": 0.05, "key_reminder": "off"}
        steps = [{"trial": base | {"index": 0, "kind": "reference", "label": LABEL}},
                 {"trial": base | {"index": 1, "kind": "practice"}}]
        counts = [tuple(int(v) for v in t.split(" / ")) for t in texts if t != "practice"]
        steps += [{"trial": base | {"index": 2 + i, "progress": list(k)}} for i, k in enumerate(counts)]
        spec = {"display": {"width_px": W, "height_px": H, "width_cm": 53.0, "distance_cm": 45.0},
                "presenter": {"screenshot_dir": str(folder / "shots"), "fixation_rgb": None}, "steps": steps,
                "watchdog_s": 300}
        with Xvfb(screen=SCREEN) as x:
            Driver(x, spec, folder, timeout_s=320).finish()
        shots = folder / "shots"
        label, tag = load(shots_of(shots, 0, "stim0")[0]), load(shots_of(shots, 1, "stim0")[0])
        out["label_mask"] = label.min(axis=2) >= 250
        out["tag_mask"] = (np.abs(tag - TAG_RGB) <= 2).all(axis=2)
        out["progress"] = {"practice": load(shots_of(shots, 1, "black")[0])[H - 2 * TEXT_H:]}
        for i, (k, n) in enumerate(counts):
            out["progress"][f"{k} / {n}"] = load(shots_of(shots, 2 + i, "black")[0])[H - 2 * TEXT_H:]
        # each reference holds its text: a label and a tag of many fully inked pixels, a progress text of ink
        assert out["label_mask"].sum() > 500 and out["tag_mask"].sum() > 100
        assert all((r.max(axis=2) > 40).sum() > 50 for r in out["progress"].values())
    except BaseException as exc:
        out["error"] = exc


def _schedule(p):
    from studyapp.runner.schedule import build_schedule

    return build_schedule(p, "P1", 0)


def n_main(p) -> int:
    """How many main trials to drive: one, or (live) up to the first in a scene whose view reaches every edge
    of the window (cornell and cornell_many leave black around the box), so that a rectangle is measured
    against the viewport."""
    mains = [t for t in _schedule(p) if counted(t)]
    least = 1 if p.adaptive is None else 2  # adaptive: two levels shown (a yes/no trial shows one stimulus)
    if not p.live:
        return least
    return max(least, next(k + 1 for k, t in enumerate(mains) if t.scene not in BOXED))


def expected_progress(p) -> dict[int, tuple[str, str]]:
    """Trial index -> (the progress text of the black interval, the text if practice trials were counted) for
    each trial driven: "practice", or "k / N" with practice and references left out."""
    sched = _schedule(p)
    total, n_all = sum(counted(t) for t in sched), sum(t.kind != "reference" for t in sched)
    out, k, j, mains = {}, 0, 0, 0
    for t in sched:
        j += t.kind != "reference"
        if t.kind == "practice":  # any count would differ from "practice"
            out[t.index] = ("practice", "practice")
        elif counted(t):
            k += 1
            out[t.index] = (f"{k} / {total}", f"{j} / {n_all}")
            mains += 1
            if mains == n_main(p):
                return out
    return out


@pytest.fixture(scope="module")
def sessions(request, tmp_path_factory):
    """The session of every shipped protocol (and the reminder-off variant) whose test is selected (``-k``),
    and the reference renderings, at once."""
    require_tools()
    out, refs = {}, {}
    texts = set()
    selected = {i.callspec.params.get("name") for i in request.session.items if hasattr(i, "callspec")}
    names = [n for n in [*NAMES, OFF] if n in selected]
    for name in names:  # the copies' schedules (their content, hence their schedule seed, differs)
        copy = copy_of(name, tmp_path_factory.mktemp("copies"))
        pairs = expected_progress(load_protocol(copy, check_renderers=False)).values()
        texts |= {t for pair in pairs for t in pair}
    threads = [threading.Thread(target=_session, args=(n, tmp_path_factory.mktemp(n.replace("+", "_")), out))
               for n in names]
    threads.append(threading.Thread(target=_references,
                                    args=(tmp_path_factory.mktemp("refs"), sorted(texts), refs)))
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=400)
    if "error" in refs:
        raise refs["error"]
    return out, refs


def ink(shot: np.ndarray, mask: np.ndarray, rgb, tol: int = 6) -> float:
    """The fraction of ``mask``'s pixels (fully inked text of the reference rendering) that show ``rgb``."""
    return float((np.abs(shot[mask] - rgb) <= tol).all(axis=1).mean())


def rectangle(shot: np.ndarray) -> tuple[int, int, int, int]:
    """``(x0, y0, x1, y1)`` of the pixels that are not the window's black background."""
    ys, xs = np.nonzero(shot.max(axis=2) > 8)
    return int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1


def band_ink(shot: np.ndarray, y0: int, y1: int) -> int:
    """Light text pixels in rows ``y0:y1`` (the stimulus under the band is dimmed below 80)."""
    return int((shot[y0:y1].min(axis=2) > 205).sum())


def shown_conditions(p, run, t) -> tuple[str, ...]:
    """``t``'s conditions as shown: an adaptive slot's varied condition as ``NAME(level)`` at the level its
    procedure chose (the session's ``adaptive`` row of the trial)."""
    test = varied_of(p, t.conditions) if t.kind == "trial" else None
    if test is None:
        return tuple(t.conditions)
    (level,), = query(run.db, "SELECT level FROM adaptive WHERE participant = 'P1' AND idx = ?", t.index)
    return tuple(level_condition(c, level) if c == test else c for c in t.conditions)


def first_shots(p, run, t) -> list[tuple[str, np.ndarray]]:
    """(condition as shown, screenshot of its first frame) for each stimulus of trial ``t`` (live: the first
    frame, then the second rendered after each switch)."""
    shown = shown_conditions(p, run, t)
    if not p.live:
        return [(c, load(shots_of(run.shots, t.index, f"stim{i}")[0])) for i, c in enumerate(shown)]
    live = shots_of(run.shots, t.index, "live")
    return [(c, load(live[run.live_first.get((t.index, i), 0)])) for i, c in enumerate(shown)]


def scale_of(p) -> float:
    """The test's --scale: live 58x32 renders (0.03 of 1920x1080, 0.06 of 960x540; at 0.02 seed001_2afc_live's
    catch condition COARSE, LaFR delta 8, has 3 log-polar rows and stops the session, as does the top of the
    threshold protocols' delta ladder at 29x16); pre-rendered the smallest of a few that keeps the render's
    aspect ratio exact (seed001 0.05: 48x27, seed003 0.125: 32x18, threshold_foveation 0.05: 48x27)."""
    if p.live:
        return round(0.03 * 1080 / p.render_size[1], 4)
    w, h = p.render_size
    for s in (0.05, 0.0625, 0.1, 0.125, 0.25, 0.5):
        g = p.render_geometry(s)
        if g.width * h == g.height * w:
            return s
    return 1.0


def viewport(p, cond: str) -> tuple[int, int, int, int]:
    """The rectangle :func:`data_schema.geometry.eye_views` gives a condition's stimulus in the window."""
    if p.live:
        views = live_stimulus(p, cond, p.scenes[0], scale_of(p)).views((W, H))
    else:
        g = p.render_geometry(scale_of(p))
        views = eye_views((W, H), (g.width, g.height), 1)  # prepare writes one view of every condition
    assert len(views) == 1, views
    v = views[0]
    return (v.x0, v.y0, v.x0 + v.width, v.y0 + v.height)


@pytest.mark.parametrize("name", [*NAMES, OFF])
def test_shipped_protocol_screens(sessions, name):
    out, refs = sessions
    if isinstance(out.get(name), BaseException):
        raise out[name]
    p, run = out[name]
    index = {c: i for i, c in enumerate(p.conditions)}
    rects = {}
    progress = expected_progress(p)
    for t in run.trials:
        shots = first_shots(p, run, t)
        black = load(shots_of(run.shots, t.index, "black")[0])
        for cond, shot in shots:
            rect = rectangle(shot)
            if p.live:  # a scene may leave black around its content (cornell): compare within the scene
                x0, y0, x1, y1 = viewport(p, cond)
                inside = x0 <= rect[0] and y0 <= rect[1] and rect[2] <= x1 and rect[3] <= y1
                assert inside, (t.index, cond, rect)
                rects.setdefault(t.scene, {})[cond] = rect
            else:
                assert rect == viewport(p, cond), (t.index, cond, rect)
                rects.setdefault("all", {})[cond] = rect
            frame = None
            if not p.live:  # the condition's own frame over the rectangle (overlays aside)
                x0, y0, x1, y1 = rect
                inner = shot[y0 + 3 * TEXT_H:y1 - BAND, x0:x1]
                frame = [k for k in (0, 1)
                         if (np.abs(inner - colour(index[cond], k)) <= 2).all(axis=2).mean() > 0.98]
                assert frame, (t.index, cond)  # frame 1: the first flip after a switch used the old onset
            label = ink(shot, refs["label_mask"], (255, 255, 255))
            tag = ink(shot, refs["tag_mask"], TAG_RGB)
            reminder = band_ink(shot, H - BAND, H)
            # a reference's second half, grabbed from X until the next trial's black interval: the grabs that
            # show the stimulus (pre-rendered: its colour, frame 0 or 1; live: not the black screen)
            shown = [g for g in run.grabs.get(t.index, [])
                     if (tuple(g[H // 2, W // 4]) in (colour(index[cond], 0), colour(index[cond], 1))
                         if not p.live else (g.max(axis=2) > 8).mean() > 0.2)]
            end_label = min((ink(g.astype(int), refs["label_mask"], (255, 255, 255)) for g in shown),
                            default=None)
            when = "2nd half" if p.duration_s else "before SPACE"  # a sequence / a still reference
            half = "" if end_label is None else f" ({when}: {len(shown)} grabs, min {end_label:.2f})"
            print(f"SCREEN {name} trial {t.index} {t.kind} {t.scene} {cond}: frame {frame} rect {rect} label "
                  f"{label:.2f}{half} tag {tag:.2f} reminder ink {reminder}")
            if t.kind == "reference":
                assert label >= 0.9, (t.index, cond, label)
                assert shown and end_label >= 0.9, (t.index, "second half", len(shown), end_label)
                if not p.live and p.n_frames > 1:  # the sequence's last frame was grabbed: the label stayed
                    assert any(tuple(g[H // 2, W // 4]) == colour(index[cond], 1) for g in shown), t.index
                if p.duration_s is None:  # a still reference stays until SPACE: its key is recalled
                    assert reminder > 100, (t.index, cond, reminder)
                else:
                    assert reminder == 0  # a played reference has no keys
                continue
            assert label < 0.5, (t.index, cond, label)
            assert (tag >= 0.9) == (t.kind == "practice"), (t.index, cond, t.kind, tag)
            if name == OFF:
                assert reminder == 0, (t.index, cond, reminder)
                assert tuple(shot[H - 3, 2]) == colour(index[cond], frame[0])  # no band: the stimulus itself
            else:
                assert reminder > 100, (t.index, cond, reminder)
                if not p.live:
                    dimmed = 0.3 * np.array(colour(index[cond], frame[0]))  # under the band
                    np.testing.assert_allclose(shot[H - 3, 2], dimmed, atol=2)
        bottom = black[H - 2 * TEXT_H:]
        if t.kind == "reference":  # no progress text
            assert bottom.max() <= 8, t.index
        else:
            want, wrong = progress[t.index]
            print(f"SCREEN {name} trial {t.index} black: progress {want!r} max diff "
                  f"{np.abs(bottom - refs['progress'][want]).max()}, vs {wrong!r} "
                  f"{np.abs(bottom - refs['progress'][wrong]).max()}")
            assert np.abs(bottom - refs["progress"][want]).max() <= 8, (t.index, want)
            if wrong != want:
                assert np.abs(bottom - refs["progress"][wrong]).max() > 8, (t.index, "counts practice", wrong)
    assert run.trials[-1].kind in ("trial", "catch")
    assert any(t.kind == "practice" for t in run.trials) == bool(p.practice)  # adaptive designs have none
    if p.adaptive is not None:  # each main trial showed a level of its ladder
        levels = [shown_conditions(p, run, t) for t in run.trials if counted(t)]
        assert all(any("(" in c for c in shown) for shown in levels), levels
    for scene, by_cond in rects.items():  # one rectangle for every condition shown (within one render pixel)
        r = np.array(list(by_cond.values()))
        pixel = W / p.render_geometry(scale_of(p)).width + 1
        assert (r.max(axis=0) - r.min(axis=0) <= pixel).all(), (scene, by_cond)
    if p.live:  # a scene whose view reaches every edge shows it over the eye_views viewport exactly
        full = [s for s, by_cond in rects.items() if all(r == viewport(p, c) for c, r in by_cond.items())]
        assert full, rects
    assert "ended" in run.stdout, run.stdout
