"""Fair presentation on the display the protocol declares (issue 26, item 1), without a window: on a monoscopic
display every condition of every shipped live protocol covers the window at the same size (a binocular
renderer shows the one eye its ``eye`` parameter names, rendered at the full size), its cost counts both
eyes, and only a stereo display (``display.stereo: true``) shows a pair side by side. The screenshots of the
same are in tests/test_fair_display_gui.py."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from data_schema.geometry import EyeView
from studyapp.cli import main
from studyapp.runner.live import Pose, live_stimulus
from studyapp.runner.protocol import load_protocol

SHIPPED = Path(__file__).resolve().parents[1] / "studyapp" / "protocols"
PROTOCOLS = sorted(SHIPPED.glob("*_live.yaml"))
WINDOW = (1920, 1080)


def _placements(protocol) -> dict[str, list[EyeView]]:
    # cornell, the practice scene: every condition of the protocol, quick to load (adaptive designs: no practice)
    scene = protocol.practice["scene"] if protocol.practice else protocol.scenes[0]
    return {c: live_stimulus(protocol, c, scene).views(WINDOW) for c in protocol.conditions}


@pytest.mark.parametrize("path", PROTOCOLS, ids=[p.stem for p in PROTOCOLS])
def test_every_condition_of_a_shipped_live_protocol_covers_the_window_at_the_same_size(path):
    protocol = load_protocol(path)
    assert not protocol.display.stereo
    w, h = protocol.render_size
    for cond, views in _placements(protocol).items():
        eye = "left" if protocol.conditions[cond].eyes == 2 else "mono"
        assert views == [EyeView(eye, 0, 0, *WINDOW, w, h)], cond


def test_the_shipped_binocular_conditions_are_the_vafr_pair():
    binocular = {p.stem: sorted(c for c, v in load_protocol(p).conditions.items() if v.eyes == 2) for p in PROTOCOLS}
    assert binocular == {"seed001_2afc_live": ["VaFR_Dup", "VaFR_Rep"], "seed001_pilot_live": ["VaFR_Dup", "VaFR_Rep"],
                         "seed003_task1_live": [], "seed003_task2_live": [], "latency_threshold_live": [],
                         "threshold_foveation_live": []}


def _pilot(tmp_path, *replace) -> Path:
    text = (SHIPPED / "seed001_pilot_live.yaml").read_text()
    for old, new in replace:
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "pilot.yaml"
    path.write_text(text)
    return path


def test_a_stereo_display_shows_binocular_renderers_side_by_side_and_the_named_eye_otherwise(tmp_path):
    stereo = load_protocol(_pilot(tmp_path, ("refresh_hz: 60}", "refresh_hz: 60, stereo: true}")))
    views = _placements(stereo)
    assert views["VaFR_Dup"] == [EyeView("left", 0, 0, 960, 1080, 960, 1080),
                                 EyeView("right", 960, 0, 960, 1080, 960, 1080)]
    assert views["GT"] == [EyeView("mono", 0, 0, 1920, 1080, 1920, 1080)]
    right = load_protocol(_pilot(tmp_path, ("stereo: rep}", "stereo: rep, eye: right}")))
    views = _placements(right)
    assert views["VaFR_Rep"] == [EyeView("right", 0, 0, 1920, 1080, 1920, 1080)]  # rep's reprojected eye
    assert views["VaFR_Dup"] == [EyeView("left", 0, 0, 1920, 1080, 1920, 1080)]


@pytest.mark.parametrize("replace,expected", [
    ((("renderer: gt, quality", "renderer: gt, params: {eye: right}, quality"),),
     "conditions.GT.params.eye: eye: right means nothing for a one-view renderer (stereo: mono): "
     "remove it, or render both eyes (stereo: dup or rep)"),
    ((("stereo: rep}", "stereo: rep, eye: right}"), ("refresh_hz: 60}", "refresh_hz: 60, stereo: true}")),
     "conditions.VaFR_Rep.params.eye: the display is stereo (display.stereo: true) and shows both "
     "eyes side by side: remove eye, or set display.stereo: false to show this one eye"),
    ((("stereo: rep}", "stereo: rep, eye: centre}"),), "conditions.VaFR_Rep.params.eye"),
    ((("refresh_hz: 60}", "refresh_hz: 60, stereo: 1}"),), "display.stereo"),
])
def test_an_eye_that_chooses_nothing_is_refused_in_one_line(tmp_path, capsys, replace, expected):
    assert main(["validate", str(_pilot(tmp_path, *replace))]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and err.startswith("studyapp: error: ") and expected in err, err
    line = next(i for i, text in enumerate((tmp_path / "pilot.yaml").read_text().splitlines(), 1)
                if expected.split(".")[1] + ":" in text)  # the message names the condition's line
    assert f"pilot.yaml:{line}: " in err or expected == "display.stereo", err


def test_a_stereo_display_is_refused_for_prepared_stimuli(tmp_path, capsys):
    text = (PROTOCOLS[0].parent / "seed001_pilot.yaml").read_text()
    assert "refresh_hz: 60}" in text
    (tmp_path / "p.yaml").write_text(text.replace("refresh_hz: 60}", "refresh_hz: 60, stereo: true}"))
    assert main(["validate", str(tmp_path / "p.yaml")]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "display.stereo: a stereo display shows live binocular renderers" in err


@pytest.mark.parametrize("renderer,params", [("lafr", {"delta": 2.0}), ("gt", {}), ("vafr", {"preset": "auto"})])
def test_a_binocular_renderer_costs_both_eyes_and_returns_the_named_one(renderer, params):
    from renderers.registry import render

    mono = render("cornell", renderer, params, 32, 18)[1]
    for stereo in ("dup", "rep") if renderer == "vafr" else ("dup",):
        left, stats = render("cornell", renderer, {**params, "stereo": stereo}, 32, 18)
        right, stats_r = render("cornell", renderer, {**params, "stereo": stereo, "eye": "right"}, 32, 18)
        assert stats["eyes"] == 2 and left.shape == right.shape == (18, 32, 3)  # each eye at the full size
        assert np.array_equal(left, stats["eye_images"][0]) and np.array_equal(right, stats_r["eye_images"][1])
        assert not np.array_equal(left, right)  # the eyes' cameras are ipd apart
        # the cost counts both eyes whichever is shown: dup shades two views, rep one and the reprojection's holes
        assert stats["shading_points"] == stats_r["shading_points"]
        if stereo == "dup":
            assert stats["rays_primary"] == 2 * mono["rays_primary"]
        else:
            assert mono["shading_points"] < stats["shading_points"] < 2 * mono["shading_points"]


def test_the_live_window_shows_the_named_eye_over_the_window_and_times_both(monkeypatch):
    """LiveTrial._render on a monoscopic display: the gaze goes through the shown eye's full-window view, the
    texture gets that eye's image, and the render time is the whole binocular render's."""
    from studyapp.presentation import live_window as lw
    from studyapp.runner.live import LiveStimulus

    seen, shown = {}, []

    def fake_render(scene, renderer, params, w, h, gaze=None, camera=None, backend=None, cancel=None):
        seen.update(size=(w, h), gaze=gaze, eye=params.get("eye", "left"))
        eyes = [np.full((h, w, 3), 0.25, np.float32), np.full((h, w, 3), 0.75, np.float32)]
        return eyes[params.get("eye") == "right"], {"seconds": {"total": 0.125}, "eye_images": eyes}

    monkeypatch.setattr("renderers.registry.render", fake_render)
    monkeypatch.setattr("renderers.stimuli.to_srgb8", lambda im, exposure: im)
    surface = SimpleNamespace(update=lambda im: shown.append(float(im.mean())))
    monkeypatch.setattr(lw.LiveTrial, "_surfaces", lambda self, i: [surface] * len(self.views[i]))
    for eye, value in (("left", 0.25), ("right", 0.75)):
        lv = LiveStimulus("VaFR_Rep", "cornell", "vafr", {"stereo": "rep", "eye": eye}, "cpu", 0.0, None, "path",
                          1.0, 30.0, (32, 18))
        trial = object.__new__(lw.LiveTrial)
        trial.live, trial.views = [lv], [lv.views((320, 180))]
        trial.motions = [SimpleNamespace(pose=lambda *a: Pose((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)))]
        trial.p = SimpleNamespace(exposure=lambda scene: 1.0)
        shown.clear()
        seconds, _ = trial._render(0, 0.0, (240.0, 45.0), set(), (0.0, 0.0))
        assert seen == {"size": (32, 18), "gaze": (24.0, 4.5), "eye": eye}  # the full-window view's mapping
        assert shown == [value] and seconds == 0.125


STILL = """
schema_version: 1
name: still_pair
version: "1"
family: preference
question: "Which ones?"
display: {width_px: 64, height_px: 36, width_cm: 53.0, distance_cm: 40.95, fov_y_deg: 40}
scenes: [cornell]
conditions:
  GT: {renderer: gt}
  DUP: {renderer: lafr, params: {delta: 2.0, stereo: dup}}
  DUP_L: {renderer: lafr, params: {delta: 2.0, stereo: dup, eye: left}}
  DUP_R: {renderer: lafr, params: {delta: 2.0, stereo: dup, eye: right}}
design: {repetitions: 1}
simulation: {ground_truth: GT}
analysis: {dv: votes, unit: participant, test: summary_table}
"""


def test_prepare_writes_one_eye_of_a_binocular_renderer_at_the_display_size(tmp_path):
    """A prepared stimulus is one view, like a monoscopic display's live one: the named eye, not a pair."""
    from PIL import Image

    from studyapp.commands.study import main as study_main
    from studyapp.runner.stimuli import frame_paths

    f = tmp_path / "still.yaml"
    f.write_text(STILL)
    assert study_main(["prepare", str(f), "--cache", str(tmp_path / "cache"), "--serial"]) == 0
    p = load_protocol(f)
    img = {c: np.asarray(Image.open(frame_paths(p, c, "cornell")[0]).convert("RGB")) for c in p.conditions}
    assert {a.shape[:2] for a in img.values()} == {(36, 64)}
    assert np.array_equal(img["DUP"], img["DUP_L"]) and not np.array_equal(img["DUP_L"], img["DUP_R"])
