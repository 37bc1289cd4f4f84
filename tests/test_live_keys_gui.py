"""Keys are never lost in a live trial (issue 26, item 3), in a real window under Xvfb with xdotool, with a
CPU ground truth slow enough that one render takes over a second: Escape pressed during the first render ends
the trial before its first frame (no onset), a key pressed before the first frame is not taken as the answer,
and Escape pressed between flips (during a later render) ends the trial before the next flip. Either way the
render is cancelled (its ``cancel`` hook asks the keyboard between chunks), so Escape acts within 100 ms of
the key going down, not at the end of the render."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent / "gui"))
import psychopy  # noqa: E402,F401 - the GUI tests need it: a missing install is a failure, not a skip
from xvfb import Driver, Xvfb, require_tools  # noqa: E402

from test_live_gui import PROTOCOL as LIVE_PROTOCOL  # noqa: E402

W, H = 160, 90
SPP = 100  # about 1.2 s a render at 160 x 90 on this machine's CPU backend (the first adds numba's compile)
IDLE_RENDER_S = 1.2  # that render's time on the idle machine: how much slower a loaded machine runs


def _protocol() -> str:
    """test_live_gui's protocol with one slow condition: a CPU ground truth of ``SPP`` samples a pixel."""
    doc = yaml.safe_load(LIVE_PROTOCOL)
    doc["name"] = "live_keys"
    doc["display"].update(width_px=W, height_px=H)
    doc["conditions"] = {"GT": {"renderer": "gt", "params": {"spp": SPP}, "backend": "cpu"}}
    doc["stimulus"] = {"kind": "live", "duration_s": 0.5, "motion": "path", "gaze": "fixation"}
    doc["timing"] = {"black_s": 0.2}
    return yaml.safe_dump(doc)


@pytest.fixture(autouse=True)
def _tools():
    require_tools()


def _trial(index: int, protocol: Path) -> dict:
    return {"trial": {"index": index, "family": "yes_no", "question": "Acceptable?",
                      "answer_keys": {"y": "yes", "n": "no"}, "duration_s": 0.5, "black_before_s": 0.2,
                      "stimuli": [{"condition": "GT", "live": {"protocol": str(protocol), "condition": "GT",
                                                               "scene": "cornell", "duration_s": 0.5,
                                                               "backend": "cpu", "full_params": True}}]}}


def test_escape_and_early_keys_during_slow_live_renders(tmp_path):
    protocol = tmp_path / "keys.yaml"
    protocol.write_text(_protocol())
    spec = {"display": {"width_px": W, "height_px": H, "width_cm": 40.0, "distance_cm": 40.0},
            "steps": [_trial(0, protocol), _trial(1, protocol)], "watchdog_s": 85}
    with Xvfb() as x:
        drv = Driver(x, spec, tmp_path, timeout_s=90)
        try:
            # a key before the first frame (during the first render) is not the answer
            drv.wait_for("black", trial=0)
            time.sleep(0.6)
            x.key("y")
            drv.wait_for("onset", trial=0)
            drv.wait_for("question", trial=0)
            x.key("n")
            # Escape during the first render: the trial ends at once when the render returns, no frame shown
            drv.wait_for("black", trial=1)
            time.sleep(0.5)
            t_esc = time.monotonic()
            x.key("Escape")
            ev = drv.next_event()
            first_wait = time.monotonic() - t_esc
            assert ev["event"] == "pause", drv.events  # not "onset": the Escape was not lost
            x.key("r")
            # Escape between flips, during a later render: acts at the next flip (before it)
            drv.wait_for("onset", trial=1)
            t_esc = time.monotonic()
            x.key("Escape")
            ev = drv.next_event()
            between_wait = time.monotonic() - t_esc
            assert ev["event"] == "pause", drv.events
            x.key("e")
            out = drv.finish()
        finally:
            drv.kill()
    trials = out["trials"]
    print(f"Escape acted {first_wait:.2f} s after it was pressed during the first render, {between_wait:.2f} s "
          f"after it was pressed between flips; one render {trials[0]['frames'][1]['render_s']:.2f} s")
    assert trials[0]["answers"] == ["no"] and not trials[0]["escaped"], trials[0]
    assert trials[0]["rt_s"] > 0
    assert trials[1]["escaped"] and trials[1]["onset_s"] is None, trials[1]
    assert trials[2]["escaped"] and trials[2]["onset_s"] is not None, trials[2]
    assert out["pauses"] == ["resume", "end"]
    info = [i for i in out["trial_info"] if i["trial"] == 1]
    assert info[0].get("escaped_before_onset") and not info[1].get("escaped_before_onset"), info
    # The render is cancelled: Escape acts within 100 ms of the key going down (measured in the window's process,
    # from the key's own time stamp), not after the render (this run's second frame of trial 0: over a second;
    # the first adds numba's compile). On a machine loaded by other jobs every chunk of the render takes longer
    # in proportion, so the bound is scaled by how much slower the render ran than on the idle machine. Seen from
    # here the wait adds xdotool's and the pipe's delays.
    render_s = trials[0]["frames"][1]["render_s"]
    slower = max(1.0, render_s / IDLE_RENDER_S)
    latency = [i["escape_latency_s"] for i in info]
    print(f"Escape latency in the window's process: {latency[0] * 1000:.0f} ms during the first render, "
          f"{latency[1] * 1000:.0f} ms during a later render (renders {slower:.1f}x slower than idle)")
    assert render_s > 1.0, trials[0]["frames"]  # the renders are as slow as this test needs
    assert all(0.0 <= v < 0.1 * slower for v in latency), (latency, slower)
    assert first_wait < render_s and between_wait < render_s, (first_wait, between_wait, render_s)
