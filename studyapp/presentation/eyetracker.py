"""A window's eye tracker: the gaze source, its calibration and a validation a participant can follow.

Three gaze sources (:class:`EyeTracker`):

- ``"mousegaze"``: ``psychopy.iohub``'s MouseGaze simulated tracker (the mouse is the gaze);
- ``"device"``: the protocol's ``eyetracker`` block (any iohub eye tracker, e.g.
  ``eyetracker.hw.sr_research.eyelink.EyeTracker``; MouseGaze is ``eyetracker.hw.mouse.EyeTracker``);
- ``"pointer"``: the window's own mouse pointer (no iohub).

Before the first trial (:meth:`EyeTracker.calibrate_and_validate`, with ``calibrate`` or
``max_validation_error_deg`` in the block):

1. **Instructions** on screen, generated from the keys and the gaze source (:func:`instructions_text`), until
   SPACE.
2. **Calibration**, the tracker's own, through iohub's ``runSetupProcedure`` with a complete calibration
   configuration built by PsychoPy itself (:func:`calibration_args`: ``target_attributes`` and its ``animate``
   keys included, so iohub's procedure never fails on a missing key). MouseGaze needs none: the mouse position
   *is* the gaze, exactly (iohub's MouseGaze "calibration" is a mock that calibrates nothing), so its
   calibration is recorded as not needed and only the validation runs.
3. **Validation** in the study's window, animated as iohub's calibration and validation procedures animate
   their target (:func:`target_frame`): the target moves from one position to the next along a
   minimum-jerk path over ``target_delay_s``, expands and contracts over ``target_duration_s`` (expansion
   ``1.5``, then down to its inner dot), then stays still for :data:`HOLD_S`; the gaze is sampled every
   flip and the samples of the last :data:`ACCURACY_S` of the still period (iohub's
   ``accuracy_period_start``; at least :data:`MIN_SAMPLES`, the still period extended on a slow window) give
   the target's angular error (:func:`target_error_deg`).
4. **Result**: a pass shows the mean error for a moment; a failure shows the mean, worst and per-target
   errors and offers the experimenter ``R`` repeat (calibration and validation, up to ``max_attempts``),
   ``S`` skip (continue with this accuracy, recorded as skipped) or ``E`` end (a one-line
   :class:`PresentationError`). The result (:func:`summary`) is stored with the session.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from data_schema.errors import first_line
from data_schema.geometry import Display
from studyapp.runner.protocol import MOUSE_GAZE_DEVICE

from .base import CONTINUE_KEY, END_KEY, ESCAPE, PresentationError, key_text

IOHUB_STOP_S = 5.0  # how long the iohub server may take to stop before it is killed
#: The experimenter's keys after a failed validation: repeat calibration and validation, skip (continue), end.
REPEAT_KEY, SKIP_KEY = "r", "s"
#: Target layouts, fractions of the window from its top-left corner, the first one first (iohub's calibration
#: layouts ``FIVE_POINTS`` and ``NINE_POINTS``, psychopy.iohub.devices.eyetracker.calibration.procedure).
TARGET_LAYOUTS = {
    5: ((0.5, 0.5), (0.1, 0.1), (0.9, 0.1), (0.9, 0.9), (0.1, 0.9)),
    9: ((0.5, 0.5), (0.1, 0.5), (0.9, 0.5), (0.1, 0.1), (0.5, 0.1), (0.9, 0.1), (0.9, 0.9), (0.5, 0.9),
        (0.1, 0.9)),
}
EXPAND_SCALE = 1.5  # the target's largest radius during its expand phase (PsychoPy's default expandScale)
HOLD_S = 0.6  # the target stays still this long after contracting: the gaze is measured then
#: The samples of the last ACCURACY_S of the still period count (iohub's ``accuracy_period_start``).
ACCURACY_S = 0.55
#: At least MIN_SAMPLES count: on a slow window the still period is extended by up to MAX_EXTRA_HOLD_S.
MIN_SAMPLES, MAX_EXTRA_HOLD_S = 3, 1.0
OUTER_DEG, INNER_DEG = 0.5, 0.12  # target radii (degrees of visual angle; at least 8 and 3 pixels)
PASS_SHOWN_S = 1.0  # how long a passed validation's result stays on screen


@dataclass(frozen=True)
class Timing:
    """A validation's pace: ``delay_s`` moving to a target, ``duration_s`` expanding and contracting on it,
    :data:`HOLD_S` still there."""

    delay_s: float = 1.0  # PsychoPy's default targetDelay
    duration_s: float = 1.5  # PsychoPy's default targetDur

    @property
    def per_target_s(self) -> float:
        return self.delay_s + self.duration_s + HOLD_S


@dataclass
class Screen:
    """What the eye tracker's procedures ask of the window they run in (the presenter provides it)."""

    win: object
    visual: object  # psychopy.visual
    show_text: Callable[[str, str], None]  # draw a text (and a dim line) into the back buffer
    wait_key: Callable[[list[str]], str]  # the next of these keys pressed (clears those pressed before)
    poll_keys: Callable[[list[str]], list[str]]  # keys pressed since the last poll
    now: Callable[[], float]  # the clock of win.flip()'s time stamps
    emit: Callable[..., None]  # report an event: emit(name, **info)


# ------------------------------------------------------------------------------------------------ pure parts
def min_jerk(t: float) -> float:
    """Minimum-jerk progress ``10 t^3 - 15 t^4 + 6 t^5`` (0..1 over ``t`` = 0..1), the path iohub's procedures
    move their target along (written there as ``60 (t^5/10 - t^4/4 + t^3/6)``)."""
    t = min(max(t, 0.0), 1.0)
    return t * t * t * (10.0 - 15.0 * t + 6.0 * t * t)


def target_frame(elapsed_s: float, frm: tuple[float, float] | None, to: tuple[float, float], timing: Timing,
                 outer: float, inner: float) -> tuple[tuple[float, float], float, str]:
    """The target ``elapsed_s`` after it left ``frm`` for ``to`` (``frm`` None: it appears at ``to``): its
    position, outer radius and phase (``move``, ``expand``, ``contract``, ``still``).

    Moving (``timing.delay_s``): along the minimum-jerk path at radius ``outer``; then expanding to
    ``EXPAND_SCALE * outer`` and contracting to ``inner`` (``timing.duration_s``, half each, linear, as
    iohub's validation does with ``expand_scale > 1`` and ``contract_target``); then still at ``inner``.
    """
    t = elapsed_s
    if frm is not None:
        if t < timing.delay_s:
            k = min_jerk(t / timing.delay_s)
            return ((1 - k) * frm[0] + k * to[0], (1 - k) * frm[1] + k * to[1]), outer, "move"
        t -= timing.delay_s
    half = timing.duration_s / 2.0
    if t < half:
        return to, outer + (EXPAND_SCALE - 1.0) * outer * t / half, "expand"
    if t < timing.duration_s:
        mu = (t - half) / half
        return to, EXPAND_SCALE * outer * (1 - mu) + inner * mu, "contract"
    return to, inner, "still"


def target_error_deg(samples_px, target_px: tuple[float, float], geometry) -> float:
    """Mean angular distance (degrees) of the gaze ``samples_px`` (window pixels) from the target: each
    sample's eccentricity seen from the target as the centre of projection (seed 001 Eq 3,
    ``e = atan(c_r r)``), averaged over the samples as iohub's validation averages its per-sample errors;
    ``inf`` without samples."""
    s = np.asarray(samples_px, dtype=np.float64).reshape(-1, 2)
    if not len(s):
        return float("inf")
    r = np.hypot(s[:, 0] - target_px[0], s[:, 1] - target_px[1])
    return float(np.mean(geometry.with_gaze(target_px).eccentricity(r)))


def attempt_result(targets: list[dict], limit: float | None) -> dict:
    """One validation attempt from its per-target rows (``error_deg`` inf where no gaze came): mean and worst
    error of the targets with gaze, how many had none, and whether it passed (every target seen, the mean
    within ``limit``; no limit: every target seen)."""
    errors = [t["error_deg"] for t in targets if math.isfinite(t["error_deg"])]
    missing = len(targets) - len(errors)
    mean = float(np.mean(errors)) if errors else float("inf")
    worst = float(np.max(errors)) if errors else float("inf")
    return {"targets": targets, "mean_error_deg": mean, "max_error_deg": worst,
            "targets_without_gaze": missing,
            "passed": bool(errors) and not missing and (limit is None or mean <= limit)}


def _finite(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def summary(attempts: list[dict], status: str, limit: float | None, calibration: dict) -> dict:
    """What is stored with the session: ``status`` (``passed`` or ``skipped``), the last attempt's mean and
    worst target error (degrees; None where no gaze came), the limit, the calibration, and every attempt with
    its per-target errors (JSON: no infinities)."""
    def clean(a: dict) -> dict:
        return {"mean_error_deg": _finite(a["mean_error_deg"]), "max_error_deg": _finite(a["max_error_deg"]),
                "targets_without_gaze": a["targets_without_gaze"], "passed": a["passed"],
                "aborted": a.get("aborted", False),
                "targets": [dict(t, error_deg=_finite(t["error_deg"])) for t in a["targets"]]}
    last = attempts[-1]
    return {"status": status, "error_deg": _finite(last["mean_error_deg"]),
            "max_error_deg": _finite(last["max_error_deg"]), "limit_deg": limit, "n_attempts": len(attempts),
            "calibration": calibration, "attempts": [clean(a) for a in attempts]}


def instructions_text(n_targets: int, mouse_is_gaze: bool, calibrates: bool) -> str:
    """The participant's instructions before the dots, from the gaze source and the keys."""
    follow = ("Follow it with the mouse pointer (here the mouse stands in for your eyes)" if mouse_is_gaze
              else "Follow it with your eyes")
    lines = ["Eye-tracker check", ""]
    if calibrates:
        lines.append("First the eye tracker calibrates itself: follow its targets with your eyes.")
    lines += [f"A dot appears in the centre of the screen, then moves to {n_targets - 1} other places. "
              f"{follow} and keep looking at its centre while it shrinks and stays still.", "",
              f"Press {key_text(CONTINUE_KEY)} to start ({key_text(ESCAPE)} stops the check)."]
    return "\n".join(lines)


def result_text(result: dict, limit: float | None, can_repeat: bool, note: str = "") -> str:
    """The experimenter's screen after a failed validation: the errors, ``note`` (a calibration that did not
    succeed) and the keys."""
    def deg(v):
        return f"{v:.2f}°" if math.isfinite(v) else "no gaze"
    bound = f" (limit {limit:g}°)" if limit is not None else ""
    blind = result.get("targets_without_gaze", 0)
    what = ("The check was stopped." if result.get("aborted")
            else f"Mean error {deg(result['mean_error_deg'])}{bound}, worst target "
                 f"{deg(result['max_error_deg'])}" + (f"; {blind} target(s) without gaze." if blind else "."))
    per = "   ".join(f"{k + 1}: {deg(t['error_deg'])}" for k, t in enumerate(result["targets"]))
    keys = ([f"{key_text(REPEAT_KEY)}: repeat calibration and check"] if can_repeat else []) + [
        f"{key_text(SKIP_KEY)}: skip (continue with this accuracy)", f"{key_text(END_KEY)}: end the session"]
    return "\n".join(["Eye-tracker check failed", "", what, per, *([note] if note else []), "",
                      "   ".join(keys)])


# ------------------------------------------------------------------------------------------------ iohub
def check_iohub_device(device: str) -> None:
    """Raise a one-line error unless ``device`` (``eyetracker.hw.<maker>.EyeTracker``) names an iohub device
    class that is installed, resolved the way iohub resolves it (its module or a plug-in's entry point)."""
    from psychopy.iohub.devices import importDeviceModule

    module, _, cls = device.rpartition(".")
    try:
        found = hasattr(importDeviceModule(f"psychopy.iohub.devices.{module}"), cls)
    except Exception:  # noqa: BLE001 - iohub raises ModuleNotFoundError or the plug-in's own import error
        found = False
    if not found:
        raise RuntimeError(f"no iohub device {device!r} is installed (e.g. eyetracker.hw.mouse.EyeTracker, "
                           "eyetracker.hw.sr_research.eyelink.EyeTracker with its psychopy plug-in)")


def free_udp_port() -> int:
    """A UDP port free on this machine now. iohub's client and server talk over one fixed port (9036) by
    default, so two sessions on one machine (or tests in parallel) would each read the other's tracker: every
    session gets a port of its own."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def calibration_args(win, tracker, timing: Timing, n_targets: int, outer_px: float, inner_px: float) -> dict:
    """iohub's calibration configuration for ``tracker``, complete (``target_attributes`` with its ``animate``
    keys, layout, pacing, colours), built by PsychoPy's own ``EyetrackerCalibration`` and the tracker class's
    ``getCalibrationDict`` (the path PsychoPy Builder's calibration routine takes)."""
    from psychopy import visual
    from psychopy.hardware.eyetracker import EyetrackerCalibration

    target = visual.TargetStim(win, name="calibration_target", radius=outer_px, innerRadius=inner_px,
                               fillColor=(0.0, 0.0, 0.0), borderColor=(1, 1, 1), lineWidth=2,
                               innerFillColor=(1, -1, -1), innerBorderColor=(-1, -1, -1), innerLineWidth=1,
                               colorSpace="rgb", units="pix")
    layout = {5: "FIVE_POINTS", 9: "NINE_POINTS"}[n_targets]
    calib = EyetrackerCalibration(win, tracker, target, units="pix", colorSpace="rgb", progressMode="time",
                                  targetDur=timing.duration_s, expandScale=EXPAND_SCALE, targetLayout=layout,
                                  randomisePos=False, movementAnimation=True, targetDelay=timing.delay_s,
                                  textColor="white")
    return dict(calib)


class EyeTracker:
    """The gaze source of a window (see the module docstring).

    Parameters
    ----------
    kind : ``"mousegaze"``, ``"device"`` or ``"pointer"``.
    spec : the protocol's ``eyetracker`` block (``device``, ``settings``, ``calibrate``,
        ``max_validation_error_deg``, ``max_attempts``, ``targets``, ``target_delay_s``,
        ``target_duration_s``).
    """

    def __init__(self, kind: str, spec: dict | None = None):
        self.kind = kind
        self.spec = dict(spec or {})
        self._io = None
        self._device = None
        self._pointer = None
        self._win = None
        self._locate: Callable[[], tuple[int, int]] = lambda: (0, 0)

    # ------------------------------------------------------------------ start / stop
    @property
    def device(self) -> str:
        """The iohub device class path (MouseGaze for ``"mousegaze"``; none for ``"pointer"``)."""
        return MOUSE_GAZE_DEVICE if self.kind == "mousegaze" else self.spec.get("device", "")

    @property
    def mouse_is_gaze(self) -> bool:
        return self.kind == "pointer" or self.device == MOUSE_GAZE_DEVICE

    @property
    def wants_validation(self) -> bool:
        return bool(self.spec.get("calibrate") or self.spec.get("max_validation_error_deg"))

    def start(self, win, logging, window_location: Callable[[], tuple[int, int]]) -> dict:
        """Start iohub with MouseGaze or the protocol's device (or take the window's pointer); a fact dict
        (``{"ok": False, "reason": ...}`` if unusable). ``window_location()``: the window's top-left corner on
        its screen (iohub's gaze is in screen coordinates)."""
        self._win, self._locate = win, window_location
        if self.kind == "pointer":
            from psychopy import event

            self._pointer = event.Mouse(win=win, visible=False)
            return {"kind": "pointer", "ok": True}
        try:
            from psychopy.iohub import launchHubServer

            if self.kind == "device":
                check_iohub_device(self.device)
                cfg = {self.device: {"name": "tracker", **(self.spec.get("settings") or {})}}
            else:
                controls = {"move": [], "blink": ["LEFT_BUTTON"], "saccade_threshold": 0.5}
                cfg = {MOUSE_GAZE_DEVICE: {"name": "tracker", "controls": controls}}
            level = logging.console.level
            logging.console.setLevel(logging.ERROR)  # "fullScr should be True": not for a tracker
            try:
                self._io = launchHubServer(window=win, udp_port=free_udp_port(), **cfg)
            finally:
                logging.console.setLevel(level)
            self._device = self._io.getDevice("tracker")
            if self._device is None:
                raise RuntimeError(f"iohub could not create the device {next(iter(cfg))}")
            self._device.setRecordingState(True)
        except Exception as exc:  # noqa: BLE001 - the tracker's own failure, reported in one line
            self.stop()
            return {"kind": self.kind, "ok": False, "reason": first_line(exc)}
        return {"kind": self.kind, "ok": True}

    def stop(self) -> None:
        """Stop recording and the iohub server process (a hub left running keeps this process alive)."""
        io, device, self._io, self._device, self._pointer = self._io, self._device, None, None, None
        if device is not None:
            with contextlib.suppress(Exception):
                device.setRecordingState(False)
        if io is None:
            return
        import io as io_module
        import threading

        from psychopy.iohub.devices import Computer

        # iohub's quit() waits for its server process without a timeout, and a server stuck in a device's
        # shutdown would hang the study here: give it IOHUB_STOP_S, then kill it.
        server = Computer.iohub_process

        def quit_hub():
            with contextlib.suppress(Exception), contextlib.redirect_stdout(io_module.StringIO()):
                io.quit()  # (iohub prints the server's exit code)

        quitting = threading.Thread(target=quit_hub, daemon=True, name="studyapp-iohub-quit")
        quitting.start()
        quitting.join(IOHUB_STOP_S)
        if quitting.is_alive() and server is not None:
            with contextlib.suppress(Exception):
                server.kill()
            quitting.join(2.0)

    # ------------------------------------------------------------------ gaze
    def gaze_window_px(self) -> tuple[float, float] | None:
        """The newest gaze sample in window pixels (x right, y down, top-left origin), or None."""
        ww, wh = (int(v) for v in self._win.size) if self._win is not None else (0, 0)
        if self._pointer is not None:
            x, y = self._pointer.getPos()  # pix units: origin at the window centre, y up
            return (float(x) + ww / 2.0, wh / 2.0 - float(y))
        if self._device is None:
            return None
        g = self._device.getLastGazePosition()
        if g is None or len(g) < 2:
            return None
        # iohub reports display coordinates (origin at the screen centre, y up): use the window position
        screen = self._win.winHandle.screen
        wx, wy = self._locate()
        return (float(g[0]) + screen.width / 2.0 - wx, screen.height / 2.0 - float(g[1]) - wy)

    # ------------------------------------------------------------------ calibration and validation
    def _timing(self) -> Timing:
        s = self.spec
        return Timing(float(s.get("target_delay_s", Timing.delay_s)), float(s.get("target_duration_s",
                                                                                    Timing.duration_s)))

    def _radii(self, display: Display) -> tuple[float, float]:
        return max(8.0, OUTER_DEG * display.ppd), max(3.0, INNER_DEG * display.ppd)

    def calibrate(self, display: Display) -> dict:
        """The tracker's own calibration through iohub (see the module docstring); what was done."""
        if self.mouse_is_gaze:
            return {"done": False, "reason": "not needed: the mouse is the gaze (MouseGaze)"}
        outer, inner = self._radii(display)
        args = calibration_args(self._win, self._device, self._timing(), int(self.spec.get("targets", 5)),
                                outer, inner)
        try:
            result = self._device.runSetupProcedure(args)
        except Exception as exc:  # noqa: BLE001 - the tracker's own failure, shown to the experimenter
            return {"done": False, "reason": f"the tracker's calibration failed: {first_line(exc)}"}
        finally:
            self._win.flip()  # the tracker's own window may have covered this one
        status = result.get("RESULT") if isinstance(result, dict) else result
        if status == "CALIBRATION_OK" or status is True:
            return {"done": True, "result": "CALIBRATION_OK"}
        return {"done": False, "reason": f"the tracker's calibration returned {status!r}"}

    def validate(self, screen: Screen, display: Display, attempt: int) -> dict:
        """One validation in the window (see the module docstring); the attempt's result
        (:func:`attempt_result`), ``aborted`` if Escape stopped it."""
        win, now = screen.win, screen.now
        ww, wh = (int(v) for v in win.size)
        geometry = display.geometry()
        timing = self._timing()
        outer, inner = self._radii(display)
        target = screen.visual.TargetStim(win, radius=outer, innerRadius=inner, fillColor=(0.0, 0.0, 0.0),
                                          borderColor=(1, 1, 1), lineWidth=2, innerFillColor=(1, -1, -1),
                                          innerBorderColor=(-1, -1, -1), innerLineWidth=1, colorSpace="rgb",
                                          units="pix")
        layout = TARGET_LAYOUTS[int(self.spec.get("targets", 5))]
        period = 1.0 / display.refresh_hz
        targets, prev = [], None
        screen.poll_keys([ESCAPE])  # forget keys pressed before the dots
        for k, (fx, fy) in enumerate(layout):
            to = (fx * ww, fy * wh)
            end = (timing.delay_s if prev else 0.0) + timing.duration_s + HOLD_S
            samples, t0 = [], None
            while True:
                elapsed = 0.0 if t0 is None else now() - t0
                if elapsed >= end and (len(samples) >= MIN_SAMPLES or elapsed >= end + MAX_EXTRA_HOLD_S):
                    break
                (x, y), radius, _ = target_frame(elapsed, prev, to, timing, outer, inner)
                target.pos = (x - ww / 2.0, wh / 2.0 - y)
                target.radius = radius
                target.draw()
                t_flip = win.flip()
                if t0 is None:
                    t0 = t_flip
                    screen.emit("validation_target", attempt=attempt, target=k, x=to[0], y=to[1])
                g = self.gaze_window_px()
                if g is not None and t_flip - t0 >= end - ACCURACY_S:
                    samples.append(g)
                # no faster than the display's refresh: a window without vsync (Xvfb) would otherwise take the
                # CPU from iohub's server process, whose gaze then lags or drops out
                time.sleep(max(0.0, t_flip + period - now()))
                if screen.poll_keys([ESCAPE]):
                    targets.append({"x_px": to[0], "y_px": to[1], "error_deg": float("inf"), "n_samples": 0})
                    return dict(attempt_result(targets, None), passed=False, aborted=True)
            error = target_error_deg(samples, to, geometry)
            targets.append({"x_px": to[0], "y_px": to[1], "error_deg": error, "n_samples": len(samples)})
            prev = to
        win.flip()
        return attempt_result(targets, self.spec.get("max_validation_error_deg"))

    def calibrate_and_validate(self, screen: Screen, display: Display) -> dict:
        """Instructions, calibration, validation and the experimenter's choice after a failure (see the module
        docstring); the stored result (:func:`summary`). Raises :class:`PresentationError` when the
        experimenter ends the session."""
        spec = self.spec
        limit = spec.get("max_validation_error_deg")
        max_attempts = int(spec.get("max_attempts", 3))
        calibrates = bool(spec.get("calibrate")) and not self.mouse_is_gaze
        n = int(spec.get("targets", 5))
        attempts, calibration = [], {"done": False, "reason": "not asked (calibrate: false)"}
        win_flip = screen.win.flip
        while True:
            text = instructions_text(n, self.mouse_is_gaze, calibrates)
            screen.show_text(text, "")
            win_flip()
            screen.emit("validation_instructions", attempt=len(attempts), text=text,
                        window_pos_px=self._locate())
            if screen.wait_key([CONTINUE_KEY, ESCAPE]) == CONTINUE_KEY:
                if spec.get("calibrate"):
                    calibration = self.calibrate(display)
                    screen.emit("calibration", attempt=len(attempts), **calibration)
                result = self.validate(screen, display, len(attempts))
            else:
                result = dict(attempt_result([], None), passed=False, aborted=True)
            attempts.append(result)
            screen.emit("validation", attempt=len(attempts) - 1, error_deg=_finite(result["mean_error_deg"]),
                        max_error_deg=_finite(result["max_error_deg"]), passed=result["passed"],
                        targets_deg=[_finite(t["error_deg"]) for t in result["targets"]])
            if result["passed"]:
                screen.show_text(f"Eye-tracker check passed: mean error {result['mean_error_deg']:.2f}°", "")
                win_flip()
                screen.emit("validation_passed", error_deg=result["mean_error_deg"])
                time.sleep(PASS_SHOWN_S)
                return summary(attempts, "passed", limit, calibration)
            can_repeat = len(attempts) < max_attempts
            note = "" if calibration["done"] or not calibrates else f"Calibration: {calibration['reason']}."
            text = result_text(result, limit, can_repeat, note)
            screen.show_text(text, f"attempt {len(attempts)} of {max_attempts}")
            win_flip()
            screen.emit("validation_failed", attempt=len(attempts) - 1, can_repeat=can_repeat, text=text)
            key = screen.wait_key(([REPEAT_KEY] if can_repeat else []) + [SKIP_KEY, END_KEY])
            if key == SKIP_KEY:
                return summary(attempts, "skipped", limit, calibration)
            if key == END_KEY:
                err = result["mean_error_deg"]
                what = f"mean error {err:.2f}°" if math.isfinite(err) else "no gaze measured"
                bound = f", limit {limit:g}°" if limit is not None else ""
                raise PresentationError(f"eye-tracker validation failed ({what}{bound}, {len(attempts)} "
                                        "attempt(s)): the experimenter ended the session")
