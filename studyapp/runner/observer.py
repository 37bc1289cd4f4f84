"""The simulated observer: a :class:`~studyapp.presentation.base.Presenter` with no window.

It answers every trial family from a psychometric model of a foveated image difference, so whole studies run
in seconds for dry runs, the demo, CI and power analysis.

Model
-----
*Foveated difference* of a stimulus image ``I`` from the ground truth ``G`` of the same scene (luma in [0, 1]),
weighted by cortical magnification (Horton & Hoyt 1991, ``M(e) ~ 1 / (e + e2)``, ``e2 = 2.3 deg``) with the
eccentricity ``e`` of every pixel from the display geometry and the fixation point::

    w(e) = e2 / (e + e2)
    d    = sqrt( sum_i w(e_i) (I_i - G_i)^2 / sum_i w(e_i) )

averaged over up to three evenly spaced frames of a sequence. The impairment in just-noticeable differences is
``D = d / jnd`` (``simulation.jnd``, default 0.02). While a condition has no stimuli yet, its declared
``quality`` q in [0, 1] stands in: ``D = 5 (1 - q)``; with images the images are always used.

*Participant* (seeded by the study seed and the participant id): sensitivity ``s = exp(N(0, sensitivity_sd))``,
bias ``b ~ N(0, bias_sd)``, lapse rate ``lambda`` (``simulation.lapse``). With ``Phi`` the standard normal CDF:

- ``yes_no``:     ``P(yes) = lambda/2 + (1 - lambda) Phi(s (c - D) + b)``, ``c = criterion_jnd``;
- ``2afc``:       ``P(A)   = lambda/2 + (1 - lambda) Phi(s (D_B - D_A) / sqrt 2 + b)`` (Thurstone Case V; b is
  the bias towards the first/left stimulus);
- ``preference``: utilities ``U_i = -s D_i + N(0, 1)`` (lapse: random order); the top ``n_picks`` are picked,
  stopping after the first when the second and third utilities are within 0.15 (undecided).

*Reaction time* from stimulus onset: the sequence duration (answers come after it) plus an ex-Gaussian
``mu_p + N(0, sigma) + Exp(tau)``, ``mu_p = rt_mu_s exp(N(0, 0.15))`` per participant, at least 0.15 s.

*Adaptive trials* (a threshold design: the trial carries the ``level`` of the varied parameter and its
``procedure``, ``COND@scene``). Where ``simulation.psychometric`` declares a psychometric function for the
varied condition, the observer is a known-truth one: with ``x`` the procedure's intensity of the level
(``data_schema.intensity.Axis``: log10 of the level for a log domain, negated where a lower level is
stronger foveation) and the declared threshold ``t`` (a level, mapped the same way), slope ``b``, lapse ``l``
and guess rate ``g`` (the family's chance rate: 2AFC 0.5; yes/no the declared false-alarm rate)::

    weibull (default):  P(correct) = 1 - l - (1 - g - l) exp(-10^(b (x - t_p)))   (Watson 2017 eq. 3)
    logistic:           P(correct) = g + (1 - g - l) / (1 + exp(-b (x - t_p)))

the same functions QUEST+ assumes, so its threshold estimates the declared ``t``. The participant's threshold
``t_p = t + N(0, threshold_sd)`` (intensity units, seeded by seed, participant, condition and scene). The
outcome (correct / detected) is drawn, then turned into the family's answer (the answer whose interpretation
gives that outcome). Where no function is declared, the image model above answers (the test's impairment
against the ground truth's 0): a *model* of detection from the foveal/peripheral error, not a measurement.

Every trial draws from its own generator seeded by (seed, participant, trial index), so a resumed session
answers exactly as an uninterrupted one.
"""

from __future__ import annotations

import hashlib
import math
import time
from dataclasses import dataclass
from typing import Literal

import numpy as np

from data_schema import families
from data_schema.errors import UserError
from data_schema.families import Observer
from data_schema.geometry import Display
from data_schema.intensity import Axis
from studyapp.presentation.base import Stimulus, TrialDisplay, TrialResult

from .images import load_gray
from .protocol import Protocol

E2_DEG = 2.3
DEFAULT_FALSE_ALARMS = 0.05  # yes/no adaptive trials: "not the ground truth" to an undetectable test
DECLARED_SCALE_JND = 5.0
SIM_WIDTH = 64  # live stimuli: the simulated observer renders this many pixels across
LIVE_SAMPLES = 3  # ... at this many moments of each stimulus
#: Within one process: impairment per (frames, GT frames, geometry, jnd); a live stimulus's gaze samples, GT
#: thumbnails and impairment per protocol (its content hash: two protocols may share condition and scene names
#: with other motions, durations or ground truths, as seed003_task1_live and seed003_task2_live do).
_SHARED: dict[tuple, float] = {}


def _exposure(scene) -> float:
    from renderers.catalog import resolve

    return resolve(scene).exposure


def _key(*parts) -> int:
    return int.from_bytes(hashlib.sha256("|".join(map(str, parts)).encode()).digest()[:8], "little")


@dataclass(frozen=True)
class ObserverParams:
    """One simulated participant."""

    sensitivity: float
    bias: float
    lapse: float
    criterion: float
    rt_mu_s: float
    rt_sigma_s: float
    rt_tau_s: float


def participant_params(simulation: dict, participant: str, seed: int) -> ObserverParams:
    """Draw a participant's sensitivity, bias and RT location from the protocol's ``simulation`` block."""
    rng = np.random.default_rng(_key("participant", seed, participant))
    z = rng.standard_normal(3)
    return ObserverParams(sensitivity=float(math.exp(simulation["sensitivity_sd"] * z[0])),
                          bias=float(simulation["bias_sd"] * z[1]), lapse=float(simulation["lapse"]),
                          criterion=float(simulation["criterion_jnd"]),
                          rt_mu_s=float(simulation["rt_mu_s"] * math.exp(0.15 * z[2])),
                          rt_sigma_s=float(simulation["rt_sigma_s"]), rt_tau_s=float(simulation["rt_tau_s"]))


def foveated_difference(img: np.ndarray, gt: np.ndarray, ecc: np.ndarray) -> float:
    """Eccentricity-weighted RMS difference ``sqrt(sum w (I - G)^2 / sum w)``, ``w = e2 / (e + e2)``."""
    if img.shape != gt.shape or img.shape != ecc.shape:
        raise UserError(f"image shapes differ: stimulus {img.shape}, ground truth {gt.shape}, "
                         f"eccentricity map {ecc.shape}")
    w = E2_DEG / (ecc + E2_DEG)
    diff = (img.astype(np.float64) - gt.astype(np.float64)) ** 2
    return float(math.sqrt(float((w * diff).sum()) / float(w.sum())))


@dataclass(frozen=True)
class DeclaredFunction:
    """One participant's psychometric function of a varied condition, on the procedure's intensity axis."""

    condition: str
    spec: dict  # the procedure spec (scale, stronger): the intensity mapping
    threshold: float  # the participant's threshold t_p (intensity units)
    slope: float
    lapse: float
    guess: float
    function: str = "weibull"

    def intensity(self, level: float) -> float:
        """The intensity of parameter value ``level`` on the spec's axis (:class:`data_schema.intensity.Axis`)."""
        return Axis.of_spec(self.spec).to_intensity(level)

    def p_correct(self, x):
        """P(correct) at intensity ``x`` (module docstring)."""
        x = np.asarray(x, dtype=float)
        g, lam, b = self.guess, self.lapse, self.slope
        if self.function == "logistic":
            return g + (1.0 - g - lam) / (1.0 + np.exp(-b * (x - self.threshold)))
        return 1.0 - lam - (1.0 - g - lam) * np.exp(-np.power(10.0, b * (x - self.threshold)))

    def level_at(self, p: float) -> float:
        """The level at which P(correct) = ``p`` (the threshold at a family's criterion), by bisection."""
        lo, hi = self.threshold - 20.0 / self.slope, self.threshold + 20.0 / self.slope
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self.p_correct(mid) < p else (lo, mid)
        return Axis.of_spec(self.spec).to_level(0.5 * (lo + hi))


def declared_function(protocol: Protocol, condition: str, scene: str, participant: str,
                      seed: int) -> DeclaredFunction | None:
    """``simulation.psychometric[condition]`` (with its ``scenes[scene]`` overrides) for ``participant``: the
    threshold drawn around the declared one with ``threshold_sd``; None when the condition declares none."""
    decl = (protocol.simulation.get("psychometric") or {}).get(condition)
    adaptive = getattr(protocol, "adaptive", None)
    if decl is None or adaptive is None or condition not in adaptive.varied:
        return None
    decl = {**decl, **(decl.get("scenes") or {}).get(scene, {})}
    spec = adaptive.spec(condition)
    fam = families.get(protocol.family)
    guess = fam.guess_rate if fam.guess_rate is not None else float(decl.get("guess", DEFAULT_FALSE_ALARMS))
    sd = float(protocol.simulation.get("threshold_sd", 0.0))
    z = np.random.default_rng(_key("threshold", seed, participant, condition, scene)).standard_normal()
    return DeclaredFunction(condition, spec, Axis.of_spec(spec).to_intensity(float(decl["threshold"])) + sd * float(z),
                            float(decl.get("slope", 3.5)), float(decl.get("lapse", 0.02)), float(guess),
                            str(decl.get("function", "weibull")))


class SimulatedObserver:
    """Answers trials with the model in the module docstring; implements the Presenter interface.

    Parameters
    ----------
    protocol : Protocol
    participant : str
    seed : int
    ground_truth : dict
        Scene -> the ground-truth :class:`Stimulus` of that scene (frames may be empty when not rendered).
    delay_s : float
        Wall-clock seconds to spend per trial (tests that kill a session mid-way).
    """

    def __init__(self, protocol: Protocol, participant: str, seed: int, ground_truth: dict[str, Stimulus],
                 delay_s: float = 0.0) -> None:
        self.protocol = protocol
        self.participant = participant
        self.seed = seed
        self.ground_truth = ground_truth
        self.params = participant_params(protocol.simulation, participant, seed)
        self.delay_s = float(delay_s)
        self._ecc: dict[tuple, np.ndarray] = {}
        self._impairment: dict[tuple, float] = {}
        self._clock = 0.0
        self.shown: list[int] = []

    # -- Presenter interface ------------------------------------------------------------------------------
    def open(self, display: Display) -> dict:
        return {"refresh_hz": float(display.refresh_hz), "keyboard_backend": "simulated", "presenter": "simulated",
                "dropped_frames_total": 0}

    def instructions(self, text: str) -> None:
        self._clock += 2.0

    def preload(self, trial: TrialDisplay) -> None:
        if self.declared(trial) is not None:
            return  # a declared psychometric function answers: no images needed
        for s in trial.stimuli:
            self.impairment(s, trial.scene)

    def pause(self) -> Literal["resume", "end"]:
        return "resume"

    def message(self, text: str, seconds: float) -> None:
        self._clock += float(seconds)

    def rest(self, text: str, seconds: float) -> None:
        self._clock += float(seconds)

    def close(self) -> None:
        pass

    def present(self, trial: TrialDisplay) -> TrialResult:
        if self.delay_s:
            time.sleep(self.delay_s)
        rng = np.random.default_rng(_key("trial", self.seed, self.participant, trial.index))
        p = self.params
        self._clock += trial.black_before_s
        onset = self._clock
        lapse = rng.random() < p.lapse
        switches = 0
        declared = self.declared(trial)
        if declared is not None and trial.kind != "reference":
            answers, margin = self._psychometric_answer(trial, declared, rng)
        elif trial.kind == "reference":
            answers = ["seen"] if trial.answer_keys else []
            margin = 0.0
        else:
            impairments = [self.impairment(st, trial.scene) for st in trial.stimuli]
            answers, margin, switches = families.get(trial.family).simulate(
                impairments, Observer(p.sensitivity, p.bias, p.criterion), rng, lapse, trial.n_picks)
        rt = (trial.duration_s or 0.0) + max(0.15, p.rt_mu_s * (1.0 + 0.3 * math.exp(-margin))
                                              + rng.normal(0.0, p.rt_sigma_s) + rng.exponential(p.rt_tau_s))
        frames = self._live_frames(trial, onset) if any(st.live for st in trial.stimuli) else []
        self._clock += rt
        self.shown.append(trial.index)
        return TrialResult(answers=answers, rt_s=float(rt), onset_s=float(onset), dropped_frames=0,
                           switches=switches, gaze_left_fovea=None, escaped=False, frames=frames)

    # -- adaptive trials: a declared psychometric function ------------------------------------------------------
    def declared(self, trial: TrialDisplay) -> DeclaredFunction | None:
        """The declared psychometric function of an adaptive trial's varied condition for this participant
        (None: not an adaptive trial, or nothing declared: the image model answers)."""
        if getattr(trial, "level", None) is None or not getattr(trial, "procedure", ""):
            return None
        cond, _, scene = trial.procedure.partition("@")
        return declared_function(self.protocol, cond, scene or trial.scene, self.participant, self.seed)

    def _psychometric_answer(self, trial: TrialDisplay, f: DeclaredFunction, rng) -> tuple[list[str], float]:
        """Draw the outcome at the trial's level, then the family's answer that gives it."""
        x = f.intensity(trial.level)
        pc = f.p_correct(x)
        correct = bool(rng.random() < pc)
        fam = families.get(trial.family)
        conditions = tuple(st.condition for st in trial.stimuli)
        test = next((c for c in conditions if c == f.condition or c.startswith(f"{f.condition}(")), f.condition)
        for answer in sorted(fam.answer_values(len(conditions))):
            derived = fam.interpret(conditions, [answer], 1)
            if bool(fam.adaptive_correct(conditions, test, derived)) == correct:
                return [answer], abs(x - f.threshold) * f.slope
        raise UserError(f"family {trial.family}: no answer is {'correct' if correct else 'wrong'} for "
                        f"{list(conditions)}")

    # -- live stimuli: a few frames rendered along a synthetic gaze path ------------------------------------
    def _live_frames(self, trial: TrialDisplay, onset: float) -> list:
        """The frame log of a simulated live trial: the frames the image model rendered (flip times on the
        simulated clock), for every stimulus shown."""
        from .live import FrameRecord

        out = []
        for i, st in enumerate(trial.stimuli):
            for k, (t, gaze, pose, render_s) in enumerate(self._live_samples(st.live, trial.scene)):
                x, y = gaze
                flip = onset + i * st.live.duration_s + t
                age = st.live.latency_ms / 1000.0 + 0.002  # the controlled delay + a nominal 2 ms tracker age
                out.append(FrameRecord(len(out), i, flip, render_s, flip - age, x, y, pose.position, pose.look_at,
                                       False))
        return out

    def _live_samples(self, live, scene: str) -> list:
        """``LIVE_SAMPLES`` moments of a live stimulus: (t, gaze in render pixels, pose, render seconds), the
        gaze from a synthetic path (fixations and saccades) seeded by the scene, shared by all conditions."""
        from .live import synthetic_gaze

        key = ("samples", self.protocol.content_hash, live.condition, scene)
        if key not in _SHARED:
            w, h = SIM_WIDTH, max(8, round(SIM_WIDTH * live.render_size[1] / live.render_size[0]))
            rng = np.random.default_rng(_key("gaze", scene))
            path = synthetic_gaze(live.duration_s, w, h, rng)
            motion = live.motion_model()
            samples = []
            for k in range(LIVE_SAMPLES):
                t = live.duration_s * (k + 0.5) / LIVE_SAMPLES
                _, gx, gy = min(path, key=lambda s: abs(s[0] - t))
                # the gaze as a tracker reports it: display pixels
                d = self.protocol.display
                samples.append((t, (gx * d.width_px / w, gy * d.height_px / h), motion.pose(t), float("nan")))
            _SHARED[key] = samples
        return _SHARED[key]

    def _live_impairment(self, stim: Stimulus, scene: str) -> float:
        """Impairment of a live stimulus: its frames rendered at a small size along the synthetic gaze path,
        against the ground truth's frames at the same poses and gaze (CPU renderers, the reference)."""
        import time as _time

        from renderers.registry import preview_params, render
        from renderers.stimuli import to_srgb8

        live = stim.live
        gt_cond = self.protocol.ground_truth
        if gt_cond is None:
            raise UserError("live stimuli need a ground truth to simulate answers: set simulation.ground_truth")
        gt = self.protocol.conditions[gt_cond]
        w, h = self._thumbnail_size(live, gt)
        luma = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
        samples = self._live_samples(live, scene)
        params = preview_params(live.renderer, live.params)  # a thumbnail: no work it cannot show
        ds = []
        d = self.protocol.display
        for k, (t, (gx, gy), pose, _) in enumerate(samples):
            gaze = (gx * w / d.width_px, gy * h / d.height_px)
            cam = pose.camera(live.fov_y_deg)
            ref_key = ("gt-frame", self.protocol.content_hash, scene, k, w, h)
            if ref_key not in _SHARED:  # the ground truth's thumbnail too (sl_gt: fewer samples)
                ref, _ = render(live.scene, gt.renderer, preview_params(gt.renderer, gt.params), w, h, gaze=gaze,
                                camera=cam)
                _SHARED[ref_key] = (to_srgb8(ref, _exposure(live.scene)) / 255.0) @ luma
            t0 = _time.perf_counter()
            img, _ = render(live.scene, live.renderer, params, w, h, gaze=gaze, camera=cam)
            samples[k] = (t, (gx, gy), pose, _time.perf_counter() - t0)
            img = (to_srgb8(img, _exposure(live.scene)) / 255.0) @ luma
            ecc = self.protocol.render_geometry().resized(w, h).with_gaze(gaze).eccentricity_map()
            ds.append(foveated_difference(img, _SHARED[ref_key], ecc))
        return float(np.mean(ds)) / float(self.protocol.simulation["jnd"])

    def _thumbnail_size(self, live, gt) -> tuple[int, int]:
        """The thumbnail size of a live stimulus: :data:`SIM_WIDTH` pixels across, or twice that and so on up to
        the render size where a renderer cannot render so small (a LaFR buffer of too few rows); the render size
        passed validation, so a protocol that validates is always simulated."""
        from renderers.registry import check_geometry, preview_params

        full_w, full_h = live.render_size
        w = SIM_WIDTH
        while w < full_w:
            h = max(8, round(w * full_h / full_w))
            geometry = self.protocol.render_geometry().resized(w, h)
            try:
                for cond in (live, gt):
                    check_geometry(cond.renderer, preview_params(cond.renderer, cond.params), geometry)
                return w, h
            except UserError:
                w *= 2
        return full_w, full_h

    # -- the image model ----------------------------------------------------------------------------------
    def _eccentricity(self, shape: tuple[int, int]) -> np.ndarray:
        """Eccentricity of every pixel of an image of ``shape``: the stimuli's viewing geometry (the display's
        visual angle, the fixation point) at that resolution."""
        if shape not in self._ecc:
            h, w = shape
            self._ecc[shape] = self.protocol.render_geometry().resized(w, h).eccentricity_map()
        return self._ecc[shape]

    def impairment(self, stim: Stimulus, scene: str) -> float:
        """Impairment ``D`` (JND) of ``stim`` against the scene's ground truth (cached per stimulus)."""
        key = (stim.condition, scene, stim.frames)
        if key in self._impairment:
            return self._impairment[key]
        if stim.live is not None:
            shared = ("live", self.protocol.content_hash, stim.condition, scene,
                      float(self.protocol.simulation["jnd"]))
            if shared not in _SHARED:
                _SHARED[shared] = self._live_impairment(stim, scene)
            else:
                self._live_samples(stim.live, scene)
            self._impairment[key] = _SHARED[shared]
            return _SHARED[shared]
        gt = self.ground_truth.get(scene)
        shared = None
        if stim.frames and gt is not None and gt.frames:
            shared = (stim.frames, gt.frames, self.protocol.display.fov_y_deg, self.protocol.fixation,
                      float(self.protocol.simulation["jnd"]))
            if shared in _SHARED:  # the measure does not depend on the participant
                self._impairment[key] = _SHARED[shared]
                return _SHARED[shared]
        if shared is not None:
            n = len(stim.frames)
            idx = sorted({round(k * (n - 1) / 2) for k in range(3)}) if n > 1 else [0]
            ds = []
            for i in idx:
                img = load_gray(stim.frames[i])
                ref = load_gray(gt.frames[i % len(gt.frames)])
                ds.append(foveated_difference(img, ref, self._eccentricity(img.shape)))
            value = float(np.mean(ds)) / float(self.protocol.simulation["jnd"])
        else:
            q = self.protocol.conditions[stim.condition].quality
            if q is None:
                raise UserError(f"condition {stim.condition}: no stimuli for scene {scene} and no declared "
                                 "quality for the simulated observer")
            value = DECLARED_SCALE_JND * (1.0 - float(q))
        self._impairment[key] = value
        if shared is not None:
            if len(_SHARED) > 4096:
                _SHARED.clear()
            _SHARED[shared] = value
        return value
