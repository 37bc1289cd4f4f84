"""Drive a real PsychoPyPresenter from a JSON spec (run under Xvfb by the GUI tests).

Spec: ``{"display": {...Display}, "presenter": {...kwargs}, "steps": [...], "result": path}``; a step
is ``{"instructions": text}``, ``{"trial": {...TrialDisplay}}`` (stimuli as ``{"condition", "frames",
"fps"}``, or ``{"condition", "live": {...}}``: :func:`make_live`), ``{"preload": {...}}``, ``{"prefetch":
{...}}``, ``{"message": text, "seconds": s}`` or ``{"rest": text, "seconds": s}`` (a break); ``"watchdog_s"``
(default 20) bounds the whole run. A trial
that comes back escaped is followed by ``pause()`` and, on "resume", shown again. Every presenter event is
printed as ``EVENT {json}`` (flushed), so the test knows when to press keys; the results are written as JSON
to ``result``.
"""

from __future__ import annotations

import dataclasses
import faulthandler
import json
import math
import sys
from pathlib import Path

from data_schema.geometry import Display
from studyapp.presentation.base import Stimulus, TrialDisplay
from studyapp.presentation.psychopy_window import PsychoPyPresenter


def emit(name: str, info: dict) -> None:
    print("EVENT " + json.dumps({"event": name, **info}), flush=True)


def make_live(d: dict):
    """A live stimulus of a protocol's condition: ``{"protocol", "condition", "scene", "scale", "duration_s",
    "backend", "full_params"}`` (renderer parameters of a thumbnail: the plug-in's preview, as ``run
    --simulate`` renders; with ``"full_params": true`` the protocol's own, e.g. for a slow render)."""
    from renderers.registry import preview_params
    from studyapp.runner.live import live_stimulus
    from studyapp.runner.protocol import load_protocol

    lv = live_stimulus(load_protocol(d["protocol"]), d["condition"], d["scene"], d.get("scale", 1.0))
    params = lv.params if d.get("full_params") else preview_params(lv.renderer, lv.params)
    return dataclasses.replace(lv, params=params, duration_s=d["duration_s"],
                               backend=d.get("backend", lv.backend))


def make_trial(d: dict) -> TrialDisplay:
    d = dict(d)
    d["stimuli"] = tuple(
        Stimulus(s["condition"], tuple(Path(f) for f in s.get("frames", ())), s.get("fps", 0.0),
                 make_live(s["live"]) if "live" in s else None) for s in d["stimuli"]
    )
    for k in ("fixation_px", "progress"):
        if d.get(k) is not None:
            d[k] = tuple(d[k])
    return TrialDisplay(**d)


def clean(x):
    if isinstance(x, float) and math.isnan(x):
        return None
    return x


def main(spec_path: str) -> int:
    spec = json.loads(Path(spec_path).read_text())
    faulthandler.dump_traceback_later(spec.get("watchdog_s", 20), exit=True)  # a hung window shows where, exits
    pres = PsychoPyPresenter(on_event=emit, **spec.get("presenter", {}))
    out = {"facts": pres.open(Display(**spec["display"])), "trials": [], "pauses": []}
    emit("opened", out["facts"])
    try:
        for step in spec["steps"]:
            if "instructions" in step:
                pres.instructions(step["instructions"])
            elif "message" in step:
                pres.message(step["message"], step["seconds"])
            elif "rest" in step:
                pres.rest(step["rest"], step["seconds"])
            elif "preload" in step:
                pres.preload(make_trial(step["preload"]))
            elif "prefetch" in step:
                pres.prefetch(make_trial(step["prefetch"]))
            else:
                trial = make_trial(step["trial"])
                while True:
                    r = pres.present(trial)
                    out["trials"].append(
                        {k: clean(v) for k, v in dataclasses.asdict(r).items()} | {"index": trial.index}
                    )
                    if not r.escaped:
                        break
                    choice = pres.pause()
                    out["pauses"].append(choice)
                    if choice == "end":
                        break
                if out["pauses"][-1:] == ["end"]:
                    break
        out["trial_info"] = pres.trial_info
        out["text_layout"] = {str(k): v for k, v in pres.text_layout.items()}
    finally:
        pres.close()
    Path(spec["result"]).write_text(json.dumps(out))
    emit("closed", {})
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
