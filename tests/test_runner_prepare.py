"""prepare: every needed frame built once (renderer calls, derived copies), camera paths, progress and ETA."""

import io
import itertools
import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from studyapp.progress import Bar
from studyapp.runner.camera import absolute_camera, camera_at
from studyapp.runner.images import load_gray, save_png
from studyapp.runner.protocol import load_protocol
from studyapp.runner.stimuli import (
    frame_paths,
    missing_stimuli,
    needed_stimuli,
    prepare,
    stimulus_root,
)

PROTOCOLS = Path(__file__).resolve().parents[1] / "protocols"


class FakeRenderer:
    """Stands in for renderers.stimuli.render_stimulus: a flat image whose grey level encodes the call."""

    def __init__(self, folder: Path):
        self.folder, self.calls, self.backends = folder, [], []

    def __call__(self, scene, renderer, params, width, height, gaze, camera=None, cache_dir=None, backend="cpu"):
        self.backends.append(backend)
        self.calls.append((scene, renderer, tuple(sorted(params.items())), width, height, tuple(gaze),
                           None if camera is None else tuple(sorted(camera.items()))))
        out = self.folder / f"r{len(self.calls)}.png"
        save_png(out, np.full((height, width, 3), (len(self.calls) % 200) / 255.0, dtype=np.float32))
        return out


def _load_text(tmp_path: Path, text: str):
    """The protocol of YAML ``text`` (written to ``tmp_path/p.yaml``), stimuli under ``tmp_path/stim``."""
    f = tmp_path / "p.yaml"
    f.write_text(text)
    return load_protocol(f, stimuli_dir=tmp_path / "stim", check_renderers=False)


def test_prepare_builds_every_missing_frame_once(tmp_path, monkeypatch):
    text = (PROTOCOLS / "seed001_2afc.yaml").read_text()
    text = text.replace("camera_path:\n    - {t: 0.0, yaw_deg: -8.0}\n    - {t: 1.0, yaw_deg: 8.0}",
                        "camera_path:\n    - {t: 0.0, position: [0, 1, 2]}\n    - {t: 1.0, position: [4, 1, 2]}")
    p = _load_text(tmp_path, text)
    fake = FakeRenderer(tmp_path)
    seen = []
    res = prepare(p, scale=0.05, render=fake, progress=lambda d, t, left: seen.append((d, t, left)))
    needs = needed_stimuli(p)
    n_render = sum(p.conditions[n.condition].renderer is not None for n in needs) * p.n_frames
    assert len(fake.calls) == res["rendered"] == n_render
    assert res["frames"] == len(needs) * p.n_frames
    assert missing_stimuli(p, 0.05) == []
    w, h = round(960 * 0.05), round(540 * 0.05)
    assert {c[3:6] for c in fake.calls} == {(w, h, (w / 2, h / 2))}
    # The camera moves linearly from x=0 to x=4 over the sequence's frames.
    n = p.n_frames
    assert n == round(p.duration_s * p.fps) > 2
    xs = sorted({dict(c[6])["position"][0] for c in fake.calls})
    assert xs == pytest.approx([4 * i / (n - 1) for i in range(n)])
    assert seen[-1][0] == seen[-1][1] == res["frames"]
    assert all(a[0] <= b[0] for a, b in itertools.pairwise(seen))
    assert seen[-1][2] == 0.0
    assert all(math.isfinite(x[2]) and x[2] >= 0 for x in seen)
    # Derived (catch) frames are a blurred, noisy copy of GT's: they differ from it but keep its mean level.
    gt = load_gray(frame_paths(p, "GT", "temple", 0.05)[0])
    bad = load_gray(frame_paths(p, "DEGRADED", "temple", 0.05)[0])
    assert gt.shape == bad.shape and not np.array_equal(gt, bad)
    assert abs(float(bad.mean()) - float(gt.mean())) < 0.05
    again = prepare(p, scale=0.05, render=fake)
    assert again["rendered"] == 0 and len(fake.calls) == n_render


def test_prepare_refuses_missing_folder_stimuli(tmp_path):
    text, n = re.subn(r"CC3: \{renderer: sl_as[^}]*\}", "CC3: {folder: lab}",
                      (PROTOCOLS / "seed003_task2.yaml").read_text())
    assert n == 1
    p = _load_text(tmp_path, text)
    fake = FakeRenderer(tmp_path)
    with pytest.raises(ValueError, match=r"\(CC3/study, CC3/interior, CC3/cornell_many and 2 more\): condition CC3 "
                                         r"reads a lab's own images from .*/lab: put study/frame_00000\.png \.\.\. "):
        prepare(p, 0.05, render=fake)
    assert fake.calls == [] and not (tmp_path / "stim").exists()  # refused before anything is rendered
    with pytest.raises(ValueError, match=r"--scale=1\.5 is out of range"):
        prepare(p, 1.5)


@pytest.mark.parametrize("field,value", [("stimuli_dir", "../elsewhere"), ("stimuli_dir", "/tmp/abs"),
                                         ("folder", "../../lab"), ("folder", "/etc")])
def test_protocol_paths_stay_inside_the_protocol_folder(tmp_path, field, value):
    text = (PROTOCOLS / "seed003_task2.yaml").read_text()
    if field == "stimuli_dir":
        text = re.sub(r"^stimuli_dir: .*$", f"stimuli_dir: {value}", text, flags=re.MULTILINE)
    else:
        text = re.sub(r"CC3: \{renderer: sl_as[^}]*\}", f"CC3: {{folder: {value}}}", text)
    f = tmp_path / "sub" / "p.yaml"
    f.parent.mkdir()
    f.write_text(text)
    with pytest.raises(ValueError, match=rf"p\.yaml:\d+: .*{field}: '{re.escape(value)}' is outside the protocol's folder"):
        load_protocol(f, check_renderers=False)
    if field == "stimuli_dir":  # given on the command line, a folder elsewhere is fine
        assert load_protocol(f, stimuli_dir=tmp_path / "elsewhere", check_renderers=False).stimuli_dir == \
            tmp_path / "elsewhere"


def test_camera_keyframes_interpolate():
    p = load_protocol(PROTOCOLS / "seed003_task2.yaml", check_renderers=False)
    n = p.n_frames
    assert camera_at(p, 0) == {"yaw_deg": -12.0}
    assert camera_at(p, n - 1) == {"yaw_deg": -12.0}
    assert n == 8  # 16.0 s at 0.5 fps; keyframes -12 deg at t=0 and t=1, +12 deg at t=0.5
    assert camera_at(p, 3)["yaw_deg"] == pytest.approx(-12 + 24 * (3 / 7) / 0.5)
    assert camera_at(p, 4)["yaw_deg"] == pytest.approx(12 - 24 * (4 / 7 - 0.5) / 0.5)


def test_yaw_offsets_turn_the_scene_camera():
    from renderers.catalog import resolve

    cam = resolve("cornell").camera
    out = absolute_camera("cornell", {"yaw_deg": 90.0})
    _, r, _ = cam.basis()
    d = np.subtract(out["look_at"], out["position"])
    assert np.dot(d / np.linalg.norm(d), r) == pytest.approx(1.0, abs=1e-9)
    assert np.linalg.norm(d) == pytest.approx(np.linalg.norm(np.subtract(cam.look_at, cam.position)))
    assert absolute_camera("cornell", {"position": [1, 2, 3]}) == {"position": [1, 2, 3]}


def test_progress_bar_reports_counts_and_time_left():
    buf = io.StringIO()
    bar = Bar("frames", stream=buf)
    for i in range(1, 21):
        bar(i, 20, (20 - i) * 3.0)
    lines = buf.getvalue().splitlines()
    assert lines[0].startswith("frames: |") and lines[0].endswith("| 1/20 [00:00<00:57]")
    assert lines[-1].endswith("| 20/20 [00:00<00:00]") and "#" * 40 in lines[-1]
    assert any(x.endswith("| 10/20 [00:00<00:30]") for x in lines)
    assert len(lines) == 11  # not a terminal: one line per 10 %


TINY = """
schema_version: 1
name: tiny
version: "1"
family: 2afc
question: "Which one?"
display: {width_px: 64, height_px: 36, width_cm: 53.0, distance_cm: 40.95, fov_y_deg: 40}
scenes: [cornell]
conditions:
  GT: {renderer: gt}
  LaFR: {renderer: lafr, params: {delta: 4.0}}
stimulus:
  kind: sequence
  duration_s: 1.0
  fps: 2
  camera_path: [{t: 0, yaw_deg: -2}, {t: 1, yaw_deg: 2}]
design: {repetitions: 2}
simulation: {ground_truth: GT}
analysis: {dv: chosen, unit: participant, test: thurstone}
"""


def test_real_renderers_prepare_and_a_simulated_run_from_their_images(tmp_path):
    from studyapp.commands.study import main
    from studyapp.runner.protocol import renderer_names

    assert {"gt", "lafr"} <= renderer_names()
    f = tmp_path / "tiny.yaml"
    f.write_text(TINY)
    assert main(["prepare", str(f), "--cache", str(tmp_path / "cache"), "--serial"]) == 0
    p = load_protocol(f)
    frames = frame_paths(p, "LaFR", "cornell")
    assert len(frames) == 2 and all(x.is_file() for x in frames)
    a, b = load_gray(frames[0]), load_gray(frames[1])
    assert a.shape == (36, 64) and not np.array_equal(a, b)  # the camera turned between the frames
    db = tmp_path / "s.db"
    assert main(["run", str(f), "--participant", "P1", "--simulate", "--db", str(db), "--quiet"]) == 0
    from data_schema.store import read_trials

    df = read_trials(db)
    assert len(df) == 2 and set(df.chosen) <= {"GT", "LaFR"}


def test_synthetic_images_carry_the_declared_impairment(tmp_path):
    from studyapp.runner.observer import SimulatedObserver
    from studyapp.runner.session import StimulusSet, ground_truth_stimuli
    from studyapp.runner.stimuli import write_synthetic_stimuli

    p = load_protocol(PROTOCOLS / "seed003_task1.yaml", stimuli_dir=tmp_path / "s", check_renderers=False)
    write_synthetic_stimuli(p, 0.2, max_frames=1)
    st = StimulusSet(p, 0.2)
    obs = SimulatedObserver(p, "P1", 0, ground_truth_stimuli(p, st))
    for cond in p.design_conditions:
        stim = st.stimulus(cond, "yard")
        assert len(stim.frames) == p.n_frames  # read from the images, not declared
        want = 5 * (1 - p.conditions[cond].quality)
        assert obs.impairment(stim, "yard") == pytest.approx(want, rel=0.03, abs=0.02)


def test_frame_camera_carries_the_previous_frame():
    from studyapp.runner.camera import absolute_camera, frame_camera

    p = load_protocol(PROTOCOLS / "seed003_task2.yaml", check_renderers=False)
    assert "previous" not in frame_camera(p, "study", 0)
    cam = frame_camera(p, "study", 3)
    fov = {"fov_y": p.display.fov_y_deg}  # every frame has the display's visual angle
    assert cam["previous"] == {**absolute_camera("study", camera_at(p, 2)), **fov}
    assert {k: v for k, v in cam.items() if k != "previous"} == {**absolute_camera("study", camera_at(p, 3)), **fov}


def test_a_stimulus_prepared_for_a_20_degree_display_is_the_20_degree_render(tmp_path):
    """The protocol's display is the only source of the visual angle: the prepared frame equals `render` of
    the scene with a 20 degree camera (street_night's own camera has 60), and its fovea measures the
    protocol's degrees."""
    import json
    import math

    from data_schema.geometry import Display
    from renderers.registry import render
    from renderers.stimuli import to_srgb8
    from studyapp.runner.stimuli import prepare

    height_cm = 2 * 40.0 * math.tan(math.radians(10.0))  # 20 degrees high at 40 cm
    display = Display(96, 54, height_cm * 96 / 54, 40.0)
    assert display.fov_y_deg == pytest.approx(20.0, abs=1e-9)
    text = TINY.replace("display: {width_px: 64, height_px: 36, width_cm: 53.0, distance_cm: 40.95, fov_y_deg: 40}",
                        f"display: {{width_px: 96, height_px: 54, width_cm: {display.width_cm!r}, distance_cm: 40.0}}")
    text = text.replace("scenes: [cornell]", "scenes: [street_night]").replace("kind: sequence", "kind: image")
    text = text.replace("  duration_s: 1.0\n  fps: 2\n  camera_path: [{t: 0, yaw_deg: -2}, {t: 1, yaw_deg: 2}]\n", "")
    text = text.replace("LaFR: {renderer: lafr, params: {delta: 4.0}}", "VaFR: {renderer: vafr}")
    f = tmp_path / "p20.yaml"
    f.write_text(text)
    p = load_protocol(f)
    assert p.display.fov_y_deg == pytest.approx(20.0) and p.render_geometry().fov_y_deg == pytest.approx(20.0)
    prepare(p, cache_dir=tmp_path / "cache")
    from PIL import Image

    with Image.open(frame_paths(p, "VaFR", "street_night")[0]) as im:
        prepared = np.asarray(im.convert("RGB"))
    img, stats = render("street_night", "vafr", {}, 96, 54, gaze=(48.0, 27.0), camera={"fov_y": 20.0})
    from renderers.catalog import resolve

    assert resolve("street_night").camera.fov_y == 60.0
    np.testing.assert_array_equal(prepared, to_srgb8(img, resolve("street_night").exposure))
    assert stats["fov_y_deg"] == 20.0
    cached = [json.loads(x.read_text()) for x in (tmp_path / "cache").rglob("*.json")]
    vafr = [c for c in cached if c["renderer"] == "vafr"]
    assert [c["fov_y_deg"] for c in vafr] == [20.0]  # the renderer saw the protocol's degrees
    # its fovea: 5 degrees of eccentricity lie where the 20-degree display puts them
    from renderers.foveation import mapping_for

    m = mapping_for("vafr", p.render_geometry())
    assert float(m.display.radius(5.0)) == pytest.approx(math.tan(math.radians(5.0)) / p.render_geometry().c_r)
    assert float(m.display.radius(10.0)) == pytest.approx(54 / 2)  # the top edge is 10 degrees up


def test_prepare_renders_each_condition_on_its_backend(tmp_path):
    text = (PROTOCOLS / "seed001_2afc.yaml").read_text()
    text = text.replace("LaFR(2.2): {renderer: lafr, params: {delta: 2.2}, quality: 0.55}",
                        "LaFR(2.2): {renderer: lafr, params: {delta: 2.2}, quality: 0.55, backend: gpu}")
    p = _load_text(tmp_path, text)
    fake = FakeRenderer(tmp_path)
    prepare(p, scale=0.05, render=fake)
    by_backend = {}
    for call, backend in zip(fake.calls, fake.backends):
        by_backend.setdefault(backend, set()).add(call[2])
    # only the condition that asks for the GPU goes there (the key of its cache entry includes the backend)
    assert by_backend["gpu"] == {(("delta", 2.2),)}
    assert (("delta", 2.2),) not in by_backend["cpu"] and (("delta", 1.8),) in by_backend["cpu"]


def _seed001(tmp_path):
    """seed001_2afc at scale 0.05 with a fake renderer: its stimulus set, complete, cached in ``tmp_path/cache``."""
    p = _load_text(tmp_path, (PROTOCOLS / "seed001_2afc.yaml").read_text())
    fake = FakeRenderer(tmp_path)
    assert prepare(p, scale=0.05, render=fake, cache_dir=tmp_path / "cache")["removed"] == 0
    return p, fake


def test_a_resumed_prepare_removes_what_a_killed_one_left_and_nothing_else(tmp_path):
    """A prepare killed mid-copy leaves the frame missing and its temporary file beside it: the next prepare
    removes that file (any age: it holds the set's lock) and the cache's stale ones (over 10 minutes old: the
    cache has no lock), and leaves every file that is not an atomic write's temporary of ours."""
    p, fake = _seed001(tmp_path)
    frame = frame_paths(p, "VaFR_Rep", "temple", 0.05)[3]
    frame.unlink()
    killed = frame.parent / f".{frame.name}.k9_x2abc.tmp"  # mkstemp's name for it
    killed.write_bytes(b"half a PNG")
    theirs = tmp_path / "theirs.txt"
    theirs.write_text("a user's file")
    kept = [frame.parent / ".notes.tmp", frame.parent / f"{frame.name}.k9_x2abc.tmp",
            frame.parent / f".{frame.name}.TOO_LONG_X.tmp", frame_paths(p, "GT", "temple", 0.05)[0].parent / ".x"]
    for f in kept:
        f.write_text("not ours")
    link = frame.parent / f".{frame.name}.linkabcd.tmp"
    link.symlink_to(theirs)
    cache = tmp_path / "cache"
    old, fresh, elsewhere = (cache / "ab" / ".e.png.old12345.tmp", cache / "ab" / ".e.png.new12345.tmp",
                             cache / "notes" / ".e.png.old12345.tmp")
    for f in (old, fresh, elsewhere):
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_bytes(b"x")
    hour_ago = time.time() - 3600
    for f in (old, elsewhere, *kept):
        os.utime(f, (hour_ago, hour_ago))
    res = prepare(p, scale=0.05, render=fake, cache_dir=cache)
    assert res["removed"] == 2 and res["rendered"] == 1 and frame.is_file()
    assert not killed.exists() and not old.exists()
    assert all(f.exists() for f in (*kept, fresh, elsewhere)) and link.is_symlink()
    assert theirs.read_text() == "a user's file"
    assert missing_stimuli(p, 0.05) == []


def test_prepare_says_how_many_temporary_files_it_removed(tmp_path, capsys, monkeypatch):
    """The command line says what the sweep removed, in one line before its summary, and only when it removed
    something."""
    from studyapp.cli import main
    from studyapp.runner import stimuli

    p, fake = _seed001(tmp_path)
    monkeypatch.setattr(stimuli, "render_function", lambda: fake)
    frame = frame_paths(p, "VaFR_Rep", "temple", 0.05)[2]
    args = ["prepare", str(p.path), "--scale", "0.05", "--stimuli", str(tmp_path / "stim"), "--serial",
            "--cache", str(tmp_path / "cache")]
    for left in (2, 0):
        frame.unlink()
        for k in range(left):
            (frame.parent / f".{frame.name}.kill{k}xyz.tmp").write_bytes(b"half a PNG")
        capsys.readouterr()
        assert main(args) == 0
        lines = capsys.readouterr().out.splitlines()
        said = [ln for ln in lines if ln.startswith("removed ")]
        assert said == ([f"removed {left} temporary file(s) that a stopped prepare had left"] if left else []), lines
        assert lines[-1].startswith("seed001_2afc: 8 frame(s) built (1 rendered, 0 from the cache)"), lines
        assert frame.is_file() and not list(frame.parent.glob(".*.tmp"))


def test_a_second_prepare_of_the_same_set_is_refused_in_one_line(tmp_path, capsys):
    from data_schema.atomic import sole_writer
    from studyapp.cli import main

    p, _ = _seed001(tmp_path)
    frame = frame_paths(p, "VaFR_Rep", "temple", 0.05)[0]
    frame.unlink()
    before = sorted(x.relative_to(tmp_path) for x in tmp_path.rglob("*"))
    with sole_writer(stimulus_root(p, 0.05), "prepare") as alone:
        assert alone
        code = main(["prepare", str(p.path), "--scale", "0.05", "--stimuli", str(tmp_path / "stim"), "--serial",
                     "--cache", str(tmp_path / "cache")])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
        assert err.endswith("scale0.05: another prepare is writing here: wait for it to end\n"), err
    assert sorted(x.relative_to(tmp_path) for x in tmp_path.rglob("*")) == before  # nothing written
    # the lock ends with its holder: the same prepare now runs
    assert prepare(p, scale=0.05, render=FakeRenderer(tmp_path), cache_dir=tmp_path / "cache")["rendered"] == 1


def test_a_killed_prepares_lock_does_not_block_the_next(tmp_path):
    p, _ = _seed001(tmp_path)
    root = stimulus_root(p, 0.05)
    code = ("import os, sys; from data_schema.atomic import sole_writer\n"
            "with sole_writer(sys.argv[1], 'prepare') as alone:\n    print(alone, flush=True); os.kill(os.getpid(), 9)")
    r = subprocess.run([sys.executable, "-c", code, str(root)], capture_output=True, text=True, timeout=60,
                       env={**os.environ, "PYTHONPATH": str(PROTOCOLS.parent)})
    assert r.returncode == -signal.SIGKILL and r.stdout == "True\n", r.stderr  # killed while it held the lock
    assert (root / ".prepare.lock").read_bytes() == b""
    frame_paths(p, "GT", "temple", 0.05)[0].unlink()
    assert prepare(p, scale=0.05, render=FakeRenderer(tmp_path), cache_dir=tmp_path / "cache")["rendered"] == 1


@given(st.text(st.characters(blacklist_characters="/\x00", blacklist_categories=("Cs",)), min_size=1, max_size=60)
       .filter(lambda n: n not in (".", "..") and len(n.encode()) < 200))
@example("frame\n.png")
@example(".hidden")
@example("é " * 30)
@settings(max_examples=40, deadline=None)
def test_every_temporary_an_atomic_write_makes_is_one_the_sweep_knows(name):
    """Whatever the target's name, its temporary file matches TEMPORARY_NAME (else a killed write's file would
    stay forever), and the sweep removes it once stale."""
    import tempfile

    from data_schema.atomic import TEMPORARY_NAME, _new_temporary, remove_stale_temporaries

    with tempfile.TemporaryDirectory() as d:
        tmp = _new_temporary(Path(d) / name)
        assert tmp.parent == Path(d) and TEMPORARY_NAME.fullmatch(tmp.name), tmp.name
        assert remove_stale_temporaries(d) == 0 and tmp.exists()  # a write under way is left alone
        assert remove_stale_temporaries(d, older_than_s=-1.0) == 1 and not any(Path(d).iterdir())
