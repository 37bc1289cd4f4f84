"""Fair presentation in a real window under Xvfb (issue 26, item 1): a screenshot of every condition of every
shipped live protocol, each condition a short live trial at a tiny render size, shows the stimulus over the
same rectangle (the whole window) at the same size as the protocol's ground truth: the VaFR pair of seed 001
is one eye over the window, not a side-by-side stereo pair, on the monoscopic display the protocols declare.
A stereo display (``display.stereo: true``) shows the pair side by side, which the same measures tell apart.
The placement without a window is tested in tests/test_fair_display.py."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent / "gui"))
import psychopy  # noqa: E402,F401 - the GUI tests need it: a missing install is a failure, not a skip
from xvfb import Driver, Xvfb, missing_tools  # noqa: E402

from studyapp.runner.protocol import load_protocol  # noqa: E402

SHIPPED = Path(__file__).resolve().parents[1] / "studyapp" / "protocols"
# The fixed-design live protocols, in a real window. The adaptive ones (threshold_foveation_live,
# latency_threshold_live: 43 and 71 level conditions of the same renderers) take their layout from the same
# LiveStimulus.views, checked for every one of their conditions without a window in test_fair_display.py.
PROTOCOLS = sorted(SHIPPED.glob("seed*_live.yaml"))
WIN = (384, 216)  # the protocols' 1920x1080 display, a fifth a side
SCALE = 0.05  # 96 x 54 renders, upscaled 4x
SCENE = "interior"  # a scene of every shipped live protocol that fills the view (no black background)
BACKEND = os.environ.get("STUDYAPP_LIVE_TEST_BACKEND", "gpu")  # the protocols' live backend; cpu also works


@pytest.fixture(autouse=True)
def _gui_tools_installed():
    assert not missing_tools(), f"GUI tests need {missing_tools()} (Debian: xvfb, xdotool; ./run installs them)"


def _shoot(tmp_path: Path, protocol_path: Path) -> dict[str, np.ndarray]:
    """One live trial per condition in one window; the first screenshot of each (RGB, window size)."""
    protocol = load_protocol(protocol_path)
    d = protocol.display
    shots = tmp_path / "shots"
    steps = [{"trial": {"index": i, "family": "yes_no", "question": "", "answer_keys": {}, "duration_s": 0.2,
                        "black_before_s": 0.0,
                        "stimuli": [{"condition": c, "live": {"protocol": str(protocol_path), "condition": c,
                                                              "scene": SCENE, "scale": SCALE, "duration_s": 0.2,
                                                              "backend": BACKEND}}]}}
             for i, c in enumerate(protocol.conditions)]
    spec = {"display": {"width_px": WIN[0], "height_px": WIN[1], "width_cm": d.width_cm,
                        "distance_cm": d.distance_cm, "stereo": d.stereo},
            "presenter": {"screenshot_dir": str(shots)}, "steps": steps, "watchdog_s": 170}
    with Xvfb() as x:
        drv = Driver(x, spec, tmp_path, timeout_s=180)
        drv.finish()
    out = {}
    for i, c in enumerate(protocol.conditions):
        files = sorted(shots.glob(f"trial{i:04d}_live*.png"))
        assert files, f"no screenshot of {c}"
        out[c] = np.asarray(Image.open(files[0]).convert("RGB"), dtype=float)
    return out


def stimulus_rectangle(shot: np.ndarray) -> tuple[int, int, int, int]:
    """``(x0, y0, x1, y1)`` of the pixels that are not the window's black background."""
    ys, xs = np.nonzero(shot.max(axis=2) > 8)
    return int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1


def _blocks(img: np.ndarray, n: int = 8) -> np.ndarray:
    """Mean luminance of n x n-pixel blocks, mean removed (a coarse picture of where the scene's parts are)."""
    lum = img.mean(axis=2)
    h, w = (s // n * n for s in lum.shape)
    b = lum[:h, :w].reshape(h // n, n, w // n, n).mean(axis=(1, 3))
    return b - b.mean()


def likeness(a: np.ndarray, b: np.ndarray) -> float:
    """Correlation of two images' block means: about 1 for the same view at the same place and size."""
    x, y = _blocks(a).ravel(), _blocks(b).ravel()
    return float(x @ y / np.sqrt((x @ x) * (y @ y)))


def as_pair(img: np.ndarray) -> np.ndarray:
    """``img`` as a side-by-side stereo pair would show it: squeezed to half the width, twice."""
    h, w = img.shape[:2]
    half = np.asarray(Image.fromarray(img.astype(np.uint8)).resize((w // 2, h), Image.BILINEAR), dtype=float)
    return np.concatenate([half, half], axis=1)


def layout(shot: np.ndarray, gt: np.ndarray) -> str:
    """"window" if ``shot`` looks like the ground truth over the whole window, "pair" if like it side by side."""
    return "window" if likeness(shot, gt) > likeness(shot, as_pair(gt)) else "pair"


@pytest.mark.parametrize("path", PROTOCOLS, ids=[p.stem for p in PROTOCOLS])
def test_every_condition_fills_the_window_like_the_ground_truth(tmp_path, path):
    protocol = load_protocol(path)
    shots = _shoot(tmp_path, path)
    gt = shots[protocol.ground_truth]
    for cond, shot in shots.items():
        assert shot.shape[:2] == (WIN[1], WIN[0])
        assert stimulus_rectangle(shot) == (0, 0, *WIN), cond
        assert layout(shot, gt) == "window", (cond, likeness(shot, gt), likeness(shot, as_pair(gt)))
        if protocol.conditions[cond].eyes == 2:  # VaFR's left eye (sharp at this size): the ground truth's view
            assert likeness(shot, gt) > 0.95, (cond, likeness(shot, gt))


def test_a_stereo_display_shows_the_pair_side_by_side(tmp_path):
    text = (SHIPPED / "seed001_pilot_live.yaml").read_text()
    assert "refresh_hz: 60}" in text
    path = tmp_path / "stereo.yaml"
    path.write_text(text.replace("refresh_hz: 60}", "refresh_hz: 60, stereo: true}"))
    shots = _shoot(tmp_path, path)
    gt = shots["GT"]
    for cond, shot in shots.items():
        assert stimulus_rectangle(shot) == (0, 0, *WIN), cond
        expected = "pair" if cond.startswith("VaFR") else "window"
        assert layout(shot, gt) == expected, (cond, likeness(shot, gt), likeness(shot, as_pair(gt)))
