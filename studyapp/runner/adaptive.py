"""Adaptive psychophysical procedures as pure, seeded state machines: QUEST+ and transformed up-down staircases.

A procedure places the next stimulus level of one varied renderer parameter from the answers so far. It is a
pure function of ``(spec, seed, history)``: :func:`replay` rebuilds it exactly from the stored ``(level,
correct)`` pairs, which is how a resumed session proposes the level an uninterrupted run would have.

The intensity axis
------------------
Procedures work on an *intensity* ``x`` in which detection increases: the renderer parameter ``v`` mapped by
the domain's ``scale`` and the direction in which foveation gets ``stronger`` (``x = ±log10(v)`` or ``±v``),
one mapping for the runner and analysis: :class:`data_schema.intensity.Axis` (``Procedure.axis``). Thresholds
and their SDs (``estimate()``) are in intensity units; ``level`` (what :meth:`Procedure.next_level` returns and
a trial stores) is always the parameter's own value ``v``.

``correct`` is what the procedure updates on: for 2AFC "picked the original", for yes/no "answered *not the
ground truth* to the test stimulus" (detected).

The spec
--------
One procedure's ``spec`` (a dict, as :func:`studyapp.runner.protocol` resolves it from ``design.adaptive``)::

    method: quest_plus | staircase
    levels: [v1, v2, ...]            # the stimulus domain: a pre-rendered ladder or a live grid (>= 2 levels)
    scale: log | linear
    stronger: higher | lower
    guess: 0.5                       # lower asymptote; a list for a yes/no false-alarm grid
    stop: {trials: 40, reversals: 8, sd_below: 0.05}   # trials is required (a cap); the others stop earlier
    # quest_plus
    function: weibull | logistic
    threshold: [x...] or int         # grid of thresholds in intensity units (int: points across the domain)
    slope: [b...]                    # grid of slopes (per intensity unit); default from the domain's span
    lapse: [l...]                    # grid of lapse rates; default [0, 0.02, 0.05]
    # staircase
    rule: 1-up-2-down | 1-up-3-down | 1-up-1-down
    steps: [4, 2, 1]                 # step sizes in ladder positions, the k-th used after k reversals
    start: v                         # start level (default: the strongest, most detectable, level)
    estimate_reversals: 6            # the running estimate is the mean intensity of the last ones

The psychometric functions (Watson 2017, J. Vision 17(3):10, eq. 3 for the Weibull in log units; questplus
implements both placement and update, Watson 2017 eqs. 9-16)::

    weibull (log scale):   p(x) = 1 - l - (1 - g - l) exp(-10^(b (x - t)))
    weibull (linear):      p(x) = 1 - l - (1 - g - l) exp(-(x / t)^b)            (x > 0 only)
    logistic:              p(x) = g + (1 - g - l) / (1 + exp(-b (x - t)))

Transformed up-down rules (Levitt 1971, JASA 49(2B):467, Table I) converge on p = 0.5^(1/n) correct for
1-up-n-down: 70.7 % (n = 2), 79.4 % (n = 3).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from data_schema.errors import UserError
from data_schema.intensity import Axis

METHODS = ("quest_plus", "staircase")
FUNCTIONS = ("weibull", "logistic")
RULES = {"1-up-1-down": 1, "1-up-2-down": 2, "1-up-3-down": 3}
DEFAULT_LAPSE = (0.0, 0.02, 0.05)
DEFAULT_THRESHOLD_POINTS = 31
#: yes/no QUEST+: the false-alarm (guess) rates the posterior spans unless the protocol gives its own.
DEFAULT_YES_NO_GUESS = (0.0, 0.05, 0.1, 0.2)
_OUTCOMES = ("Correct", "Incorrect")


class AdaptiveSpecError(UserError):
    """A procedure spec that cannot run; one line naming the field."""


def _levels_by_intensity(spec: dict) -> list[float]:
    """The spec's levels sorted by increasing intensity."""
    axis = Axis.of_spec(spec)
    return sorted((float(v) for v in spec["levels"]), key=axis.to_intensity)


def check_spec(spec: dict) -> None:
    """Raise :class:`AdaptiveSpecError` (one line) when ``spec`` cannot run or can never stop."""
    method = spec.get("method", "quest_plus")
    if method not in METHODS:
        raise AdaptiveSpecError(f"procedure {method!r} is not one of {', '.join(METHODS)}")
    levels = spec.get("levels")
    if not isinstance(levels, (list, tuple)) or len(levels) < 2:
        raise AdaptiveSpecError("a ladder of one level cannot be adapted: give at least 2 levels")
    for v in levels:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise AdaptiveSpecError(f"level {v!r} is not a finite number")
    if len(set(float(v) for v in levels)) != len(levels):
        raise AdaptiveSpecError("the ladder repeats a level")
    scale = spec.get("scale", "log")
    if scale not in ("log", "linear"):
        raise AdaptiveSpecError(f"scale {scale!r} is not log or linear")
    if scale == "log" and min(float(v) for v in levels) <= 0:
        raise AdaptiveSpecError("a log domain needs positive levels")
    stop = spec.get("stop") or {}
    trials = stop.get("trials")
    if not isinstance(trials, int) or isinstance(trials, bool) or trials < 1:
        raise AdaptiveSpecError("the stopping rule can never stop: stop.trials (a cap of at least 1 trial per "
                                "procedure) is required")
    if method == "quest_plus":
        if "reversals" in stop:
            raise AdaptiveSpecError("stop.reversals applies to a staircase, QUEST+ has no reversals: use trials "
                                    "or sd_below")
        sd = stop.get("sd_below")
        if sd is not None and not (isinstance(sd, (int, float)) and sd > 0):
            raise AdaptiveSpecError("the stopping rule can never stop: stop.sd_below must be above 0")
        function = spec.get("function", "weibull")
        if function not in FUNCTIONS:
            raise AdaptiveSpecError(f"function {function!r} is not one of {', '.join(FUNCTIONS)}")
    else:
        if "sd_below" in stop:
            raise AdaptiveSpecError("stop.sd_below applies to QUEST+, a staircase has no posterior: use trials "
                                    "or reversals")
        rev = stop.get("reversals")
        if rev is not None and (not isinstance(rev, int) or rev < 1):
            raise AdaptiveSpecError(f"stop.reversals={rev!r} is invalid: must be a whole number >= 1")
        if spec.get("rule", "1-up-2-down") not in RULES:
            raise AdaptiveSpecError(f"rule {spec.get('rule')!r} is not one of {', '.join(RULES)}")
        steps = spec.get("steps", [1])
        if not steps or any(not isinstance(s, int) or isinstance(s, bool) or s < 1 for s in steps):
            raise AdaptiveSpecError("steps must be whole numbers of ladder positions, at least 1")
        start = spec.get("start")
        if start is not None and float(start) not in [float(v) for v in levels]:
            raise AdaptiveSpecError(f"start level {start!r} is not on the ladder")


# -- the procedures --------------------------------------------------------------------------------------------
class Procedure:
    """An adaptive procedure over one varied parameter; subclasses implement the placement and the update."""

    method: str = ""

    def __init__(self, spec: dict, seed: int) -> None:
        check_spec(spec)
        self.spec = dict(spec)
        self.seed = int(seed)
        self.axis = Axis.of_spec(spec)
        self.levels = _levels_by_intensity(spec)
        self.x = [self.axis.to_intensity(v) for v in self.levels]
        self.history: list[tuple[float, bool]] = []

    # the contract ---------------------------------------------------------------------------------------------
    def next_level(self) -> float:
        """The parameter value of the next trial (one of ``levels``)."""
        raise NotImplementedError

    def update(self, level: float, correct: bool) -> None:
        """Record the answer to a trial at ``level`` (which must be one of the levels)."""
        self._index(level)
        self.history.append((float(level), bool(correct)))
        self._update(self._index(level), bool(correct))

    def finished(self) -> bool:
        """True once the stopping rule holds (always by ``stop.trials``)."""
        return len(self.history) >= int(self.spec["stop"]["trials"])

    def estimate(self) -> dict:
        """The running threshold estimate: ``mean`` and ``sd`` in intensity units, ``level`` its parameter value,
        ``trials``."""
        raise NotImplementedError

    def state(self) -> dict:
        """A JSON-serialisable summary of everything the procedure's next step depends on."""
        return {"method": self.method, "trials": len(self.history),
                "history": [[v, c] for v, c in self.history],
                "next_level": None if self.finished() else self.next_level(),
                "finished": self.finished(), "estimate": self.estimate()}

    # helpers --------------------------------------------------------------------------------------------------
    def _index(self, level: float) -> int:
        v = float(level)
        for i, lv in enumerate(self.levels):
            if math.isclose(lv, v, rel_tol=1e-9, abs_tol=1e-12):
                return i
        raise AdaptiveSpecError(f"level {level!r} is not one of the procedure's levels")

    def _update(self, index: int, correct: bool) -> None:
        raise NotImplementedError


def _logistic_pf(x, t, b, g, lam):
    return g + (1.0 - g - lam) / (1.0 + np.exp(-b * (x - t)))


def default_slopes(spec: dict, span: float) -> list[float]:
    """Slope grid whose 10-90 % rise width runs from span/16 to span (seven points, geometric)."""
    # Weibull (log form): the 10-90 % rise is log10(ln 0.1 / ln 0.9) / b = 1.34 / b; logistic: 2 ln 9 / b.
    k = 1.3410 if spec.get("function", "weibull") == "weibull" else 2.0 * math.log(9.0)
    return [float(v) for v in np.geomspace(k / span, 16.0 * k / span, 7)]


class QuestPlusProcedure(Procedure):
    """QUEST+ (Watson 2017) through the ``questplus`` package: entropy-minimising placement over ``levels``."""

    method = "quest_plus"

    def __init__(self, spec: dict, seed: int) -> None:
        super().__init__(spec, seed)
        import questplus  # the reference implementation PsychoPy's QuestPlusHandler wraps

        span = self.x[-1] - self.x[0]
        thr = spec.get("threshold", DEFAULT_THRESHOLD_POINTS)
        if isinstance(thr, int):
            thr = np.linspace(self.x[0], self.x[-1], thr)
        slopes = spec.get("slope") or default_slopes(spec, span)
        lapses = spec.get("lapse", list(DEFAULT_LAPSE))
        guess = spec.get("guess", 0.5)
        params = {"threshold": np.asarray(thr, float), "slope": np.asarray(slopes, float),
                  "lower_asymptote": np.atleast_1d(np.asarray(guess, float)),
                  "lapse_rate": np.atleast_1d(np.asarray(lapses, float))}
        function = spec.get("function", "weibull")
        linear = spec.get("scale", "log") == "linear"
        if function == "weibull" and linear and min(self.x) <= 0:
            raise AdaptiveSpecError("a Weibull on a linear domain needs positive intensities: use function: "
                                    "logistic or scale: log")
        self._qp = questplus.QuestPlus(
            stim_domain={"intensity": np.asarray(self.x, float)}, param_domain=params,
            outcome_domain={"response": list(_OUTCOMES)}, func="weibull",
            stim_scale="linear" if linear else "log10", stim_selection_method="min_entropy")
        if function == "logistic":
            # questplus has no logistic; its likelihood table is replaced, its update and placement are kept.
            xr_like = self._qp.likelihoods
            x = xr_like.coords["intensity"]
            p = _logistic_pf(x, xr_like.coords["threshold"], xr_like.coords["slope"],
                             xr_like.coords["lower_asymptote"], xr_like.coords["lapse_rate"])
            self._qp.likelihoods = xr_like.copy(data=np.stack(
                [p.transpose(*xr_like.dims[1:]).values, 1.0 - p.transpose(*xr_like.dims[1:]).values]))
        # questplus builds the likelihood table (outcome x intensity x parameters) and the prior; the update and
        # the placement below are its own formulas (Watson 2017 eqs. 9-16) on flat numpy arrays, ~20x faster
        # than its xarray ones and checked against them step by step (tests/test_adaptive.py).
        like = self._qp.likelihoods.transpose("response", "intensity", *params)
        self._param_names = tuple(params)
        self._param_shape = tuple(len(params[k]) for k in params)
        self._like = np.ascontiguousarray(like.values.reshape(2, len(self.x), -1), dtype=float)
        self._post = np.asarray(self._qp.prior.transpose(*params).values, float).ravel().copy()
        self._coords = {k: np.asarray(v, float) for k, v in params.items()}
        self._next: float | None = None

    def expected_entropies(self) -> np.ndarray:
        """Expected posterior entropy after a trial at each level (Watson 2017 eqs. 12-15)."""
        joint = self._like * self._post  # (outcome, level, params)
        pk = joint.sum(axis=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            new = joint / pk[..., None]
            h = -np.where(new > 0, new * np.log(np.where(new > 0, new, 1.0)), 0.0).sum(axis=-1)
        return (pk * h).sum(axis=0)

    def next_level(self) -> float:
        if self._next is None:
            self._next = self.levels[int(np.argmin(self.expected_entropies()))]
        return self._next

    def _update(self, index: int, correct: bool) -> None:
        post = self._post * self._like[0 if correct else 1, index]
        self._post = post / post.sum()
        self._next = None

    def finished(self) -> bool:
        if super().finished():
            return True
        sd_below = self.spec["stop"].get("sd_below")
        return sd_below is not None and bool(self.history) and self.estimate()["sd"] < float(sd_below)

    def marginal(self, name: str) -> np.ndarray:
        """The posterior of parameter ``name`` (threshold, slope, lower_asymptote, lapse_rate) on its grid."""
        axes = tuple(i for i, k in enumerate(self._param_names) if k != name)
        return self._post.reshape(self._param_shape).sum(axis=axes)

    def posterior(self, name: str = "threshold") -> tuple[np.ndarray, np.ndarray]:
        """Parameter ``name``'s grid (intensity units for the threshold) and its marginal posterior on it."""
        return self._coords[name].copy(), self.marginal(name)

    def credible_interval(self, level: float = 0.95) -> tuple[float, float]:
        """The central ``level`` credible interval of the threshold (intensity units): the grid points where
        the marginal posterior's cumulative sum first reaches (1 - level) / 2 and (1 + level) / 2."""
        t, marg = self.posterior("threshold")
        c = np.cumsum(marg)
        c /= c[-1]
        lo = t[min(int(np.searchsorted(c, (1 - level) / 2)), t.size - 1)]
        hi = t[min(int(np.searchsorted(c, (1 + level) / 2)), t.size - 1)]
        return float(lo), float(hi)

    def estimate(self) -> dict:
        t = self._coords["threshold"]
        marg = self.marginal("threshold")
        mean = float(np.sum(marg * t))
        sd = float(math.sqrt(max(float(np.sum(marg * (t - mean) ** 2)), 0.0)))
        out = {"mean": mean, "sd": sd, "level": self.axis.to_level(mean), "trials": len(self.history)}
        for name in ("slope", "lapse_rate", "lower_asymptote"):
            out[name] = float(np.sum(self.marginal(name) * self._coords[name]))
        return out


class StaircaseProcedure(Procedure):
    """A transformed up-down staircase (Levitt 1971) on the ladder: 1 wrong -> one step stronger (up), n right
    in a row -> one step weaker (down); the step size (in ladder positions) shrinks after reversals."""

    method = "staircase"

    def __init__(self, spec: dict, seed: int) -> None:
        super().__init__(spec, seed)
        self.n_down = RULES[spec.get("rule", "1-up-2-down")]
        self.steps = [int(s) for s in spec.get("steps", [1])]
        start = spec.get("start")
        self.pos = len(self.levels) - 1 if start is None else self._index(start)
        self.run = 0  # consecutive correct answers at the current level
        self.direction = 0  # +1 last move up (stronger), -1 down, 0 none yet
        self.reversals: list[float] = []  # intensities at which the direction changed

    def next_level(self) -> float:
        return self.levels[self.pos]

    def _update(self, index: int, correct: bool) -> None:
        self.pos = index  # the level the trial was shown at (interleaving never moves it)
        move = 0
        if correct:
            self.run += 1
            if self.run >= self.n_down:
                move, self.run = -1, 0
        else:
            move, self.run = +1, 0
        if move:
            if self.direction and move != self.direction:
                self.reversals.append(self.x[self.pos] + 0.0)  # + 0.0: no -0.0
            self.direction = move
            step = self.steps[min(len(self.reversals), len(self.steps) - 1)]
            self.pos = int(min(max(self.pos + move * step, 0), len(self.levels) - 1))

    def finished(self) -> bool:
        if super().finished():
            return True
        need = self.spec["stop"].get("reversals")
        return need is not None and len(self.reversals) >= int(need)

    def estimate(self) -> dict:
        k = int(self.spec.get("estimate_reversals", 6))
        last = self.reversals[-k:] if self.reversals else [self.x[self.pos]]
        mean = float(np.mean(last))
        sd = float(np.std(last, ddof=1)) if len(last) > 1 else None
        return {"mean": mean, "sd": sd, "level": self.axis.to_level(mean), "trials": len(self.history),
                "reversals": len(self.reversals)}

    def state(self) -> dict:
        out = super().state()
        out.update(position=self.pos, run=self.run, direction=self.direction,
                   reversal_intensities=list(self.reversals))
        return out


def make_procedure(spec: dict, seed: int) -> Procedure:
    """A fresh procedure for ``spec`` (see the module docstring); :class:`AdaptiveSpecError` when it cannot run."""
    check_spec(spec)
    cls = QuestPlusProcedure if spec.get("method", "quest_plus") == "quest_plus" else StaircaseProcedure
    return cls(spec, seed)


def replay(spec: dict, seed: int, history: Iterable[Sequence]) -> Procedure:
    """The procedure after the answers ``history`` (``(level, correct)`` pairs, in order): the exact state an
    uninterrupted run reached, so its :meth:`Procedure.next_level` is the level that run would show next."""
    proc = make_procedure(spec, seed)
    for level, correct in history:
        proc.update(float(level), bool(correct))
    return proc


# -- a protocol's adaptive design --------------------------------------------------------------------------------
def level_condition(condition: str, level: float) -> str:
    """The name of ``condition`` rendered at ``level`` (a stimulus folder name): ``VaFR(0.316228)``."""
    return f"{condition}({float(level):.6g})"


def procedure_id(condition: str, scene: str) -> str:
    """The id of the procedure of ``condition`` on ``scene``: ``VaFR@temple`` (the export's ``procedure``)."""
    return f"{condition}@{scene}"


@dataclass(frozen=True)
class Varied:
    """A condition's varied parameter: name, scale, direction of stronger foveation, the levels (ladder)."""

    condition: str
    param: str
    scale: str
    stronger: str
    levels: tuple[float, ...]
    start: float | None = None


@dataclass(frozen=True)
class AdaptiveDesign:
    """``design.adaptive`` of a protocol, checked (:func:`studyapp.runner.protocol.load_protocol`)."""

    reference: str
    varied: dict[str, Varied]
    procedure: dict = field(default_factory=dict)
    stop: dict = field(default_factory=dict)
    guess: tuple[float, ...] = (0.5,)

    @property
    def cap(self) -> int:
        """Trials planned per procedure (``stop.trials``)."""
        return int(self.stop["trials"])

    def spec(self, condition: str) -> dict:
        """The :func:`make_procedure` spec of ``condition``'s procedures."""
        v = self.varied[condition]
        out = {"method": "quest_plus", **self.procedure, "levels": list(v.levels), "scale": v.scale,
               "stronger": v.stronger, "stop": dict(self.stop),
               "guess": self.guess[0] if len(self.guess) == 1 else list(self.guess)}
        if v.start is not None:
            out["start"] = v.start
        return out

    def level_conditions(self) -> dict[str, tuple[str, float]]:
        """Every ``condition(level)`` name -> (condition, level), conditions in order, levels ascending."""
        return {level_condition(c, lv): (c, lv) for c, v in self.varied.items() for lv in v.levels}


__all__ = ["AdaptiveDesign", "AdaptiveSpecError", "Procedure", "QuestPlusProcedure", "StaircaseProcedure", "Varied",
           "check_spec", "level_condition", "make_procedure", "procedure_id", "replay"]
