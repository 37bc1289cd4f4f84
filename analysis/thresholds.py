"""Psychometric fits of adaptive threshold data with psignifit 4, and the group table.

A threshold study varies one parameter of a renderer (its foveation *strength*: VaFR's acuity scale, LaFR's
``delta``, ...) and records per trial the ``level`` shown and whether the answer was ``correct`` (2AFC: the
ground truth picked; yes/no: the test called "not the ground truth"). :func:`fit_thresholds` fits a psychometric
function per participant x condition x scene and pooled over the participants with psignifit 4 (Schuett,
Harmeling, Macke & Wichmann 2016, Vision Research 122, Eq 1)::

    psi(x) = gamma + (1 - gamma - lambda) S(x; m, w)

on the *intensity axis* ``x`` of :class:`data_schema.intensity.Axis` (``log10(level)`` for a log domain, ``level``
for a linear one; negated where a lower level is stronger foveation, so that detection always grows with ``x``;
the procedures' axis too), ``S`` a logistic sigmoid with
threshold ``m`` (``S(m) = 0.5``) and width ``w`` (``S`` rises from 0.05 to 0.95 over ``w``), ``gamma`` the
guess rate (fixed at 0.5 in 2AFC, fitted in yes/no) and ``lambda`` the lapse rate.

The **threshold** reported is the level at which the fitted (scaled) ``psi`` reaches the family's criterion
(2AFC: 0.75 correct; yes/no: 0.5 "not the ground truth"): ``x_c = S^-1((c - gamma) / (1 - gamma - lambda))``.
Its 95 % credible interval is the 2.5 and 97.5 % quantiles of ``x_c`` over psignifit's posterior grid (so the
lapse and guess uncertainty is carried through, not only the threshold parameter's); the point estimate is
``x_c`` at the maximum a-posteriori parameters (psignifit's default estimate).

Priors (psignifit 4's defaults, stated in every report through :data:`PRIOR_TEXT`): ``m`` uniform over the
stimulus range (the procedure's domain) with cosine fall-offs over half the range on either side; ``w`` uniform
between twice the smallest level step and the range, cosine fall-offs to the smallest step and to three times the
range; ``lambda ~ Beta(1, 10)``; yes/no ``gamma ~ Beta(1, 10)``; overdispersion ``eta`` fixed at 0 for one
participant's trials (independent trials of one observer) and ``eta ~ Beta(1, 10)`` for the pooled fit (where
participants differ).

Data that cannot give a threshold are never fitted and never given a number: fewer than :data:`MIN_TRIALS`
trials, one level only, every answer correct (ceiling) or every answer wrong (floor) give a row with
``estimable = False`` and the reason.

Nothing here imports psignifit or matplotlib at module level (``import analysis`` stays light).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from data_schema.intensity import Axis

__all__ = ["FIT_COLUMNS", "GROUP_COLUMNS", "MIN_TRIALS", "PARETO_COLUMNS", "POOLED", "PRIOR_TEXT",
           "FitSettings", "ThresholdAnalysis", "adaptive_trials", "detection", "fit_one", "fit_thresholds",
           "group_table", "pareto", "psychometric"]

#: The participant label of the fit pooled over participants.
POOLED = "(pooled)"
#: Fewer trials than this in a fit's data: not estimable.
MIN_TRIALS = 10
#: Credible interval level of the thresholds.
CI_LEVEL = 0.95

PRIOR_TEXT = ("psignifit 4 default priors: threshold uniform over the procedure's domain on the strength axis, "
              "cosine fall-off over half the domain on either side; width uniform between twice the smallest "
              "level step and the domain, cosine fall-offs; lapse Beta(1, 10); guess rate (yes/no) Beta(1, 10), "
              "2AFC guess rate fixed at 0.5; overdispersion eta fixed at 0 per participant, Beta(1, 10) pooled")

#: Columns of :func:`fit_thresholds`' table.
FIT_COLUMNS = ("participant", "condition", "scene", "varied", "n_trials", "n_levels", "criterion", "estimable",
               "reason", "threshold", "ci_low", "ci_high", "x_threshold", "x_ci_low", "x_ci_high", "width",
               "lapse", "guess", "eta", "axis", "stronger")
#: Columns of :func:`group_table`.
GROUP_COLUMNS = ("condition", "scene", "varied", "n_participants", "n_not_estimable", "axis", "mean_x", "sd_x",
                 "ci_low_x", "ci_high_x", "threshold", "ci_low", "ci_high", "n_boot")


#: Fit grids leaner than psignifit's defaults (threshold 40, width 40, lambda 20, gamma 20, eta 20 fine points;
#: 30/40/10/10/20 coarse): a study has hundreds of fits. tests/test_thresholds.py checks that the thresholds
#: agree with psignifit's defaults.
LEAN_GRID = (("threshold", 30), ("width", 24), ("lambda", 12), ("gamma", 12), ("eta", 10))
LEAN_COARSE = (("threshold", 20), ("width", 20), ("lambda", 6), ("gamma", 6), ("eta", 8))


@dataclass(frozen=True)
class FitSettings:
    """psignifit's settings (see the module docstring for eta)."""

    sigmoid: str = "logistic"
    #: Fine and coarse grid points per parameter; empty: psignifit's defaults.
    grid_steps: tuple[tuple[str, int], ...] = LEAN_GRID
    coarse_steps: tuple[tuple[str, int], ...] = LEAN_COARSE
    fix_eta_per_participant: bool = True

    def describe(self) -> str:
        grid = (", ".join(f"{k} {v}" for k, v in self.grid_steps) if self.grid_steps else
                "psignifit's defaults (threshold 40, width 40, lambda 20, gamma 20, eta 20)")
        return (f"psignifit 4, {self.sigmoid} sigmoid on the strength axis, posterior median at the criterion, "
                f"{CI_LEVEL:.0%} credible intervals from the posterior grid; fine grid points: {grid}")


def psychometric(x, threshold_x: float, width: float, guess: float, lapse: float, criterion: float,
                 sigmoid: str = "logistic"):
    """``psi(x)`` of a fit (psignifit's Eq 1) given its threshold *at the criterion* ``threshold_x``.

    ``S`` is parameterised by its midpoint ``m``; ``m`` is recovered from ``x_c`` so that
    ``psi(threshold_x) = criterion``. Used for the figures (the fitted curve) and the Pareto front.
    """
    from scipy import stats

    dist = {"logistic": stats.logistic, "norm": stats.norm}[sigmoid]
    # S(x) = F((x - m) / s), width = s (F^-1(0.95) - F^-1(0.05))
    s = width / (dist.ppf(0.95) - dist.ppf(0.05))
    q = (criterion - guess) / (1.0 - guess - lapse)
    m = threshold_x - s * dist.ppf(min(max(q, 1e-9), 1 - 1e-9))
    return guess + (1.0 - guess - lapse) * dist.cdf((np.asarray(x, dtype=float) - m) / s)


def _not_estimable(n: int, levels: np.ndarray, k: int, min_trials: int) -> str:
    """Why these data give no threshold ("" when they can be fitted)."""
    if n < min_trials:
        return f"not estimable: {n} trials, fewer than {min_trials}"
    if np.unique(levels).size < 2:
        return "not estimable: one level only"
    if k == n:
        return "not estimable: at ceiling (every trial correct)"
    if k == 0:
        return "not estimable: at floor (no trial correct)"
    return ""


def _weighted_quantiles(values: np.ndarray, weights: np.ndarray, qs: Sequence[float]) -> list[float]:
    order = np.argsort(values, kind="stable")
    v, w = values[order], weights[order]
    c = np.cumsum(w)
    c /= c[-1]
    return [float(v[min(np.searchsorted(c, q), v.size - 1)]) for q in qs]


def _posterior(data: np.ndarray, experiment_type: str, x_range: tuple[float, float], settings: FitSettings,
               eta_fixed: bool):
    """psignifit 4's posterior over its parameter grid, exactly as ``psignifit.psignifit`` computes it (bounds,
    default priors, a coarse grid to find where the mass is, then the fine grid), without its final
    Nelder-Mead search for the MAP point, which costs ~50x the grid here (scipy.stats called per level and
    step). Returns (posterior mass, {parameter: grid values}, the sigmoid); the axes are the sorted names."""
    from psignifit import Configuration
    from psignifit._parameter import masked_parameter_bounds, parameter_bounds, parameter_grid
    from psignifit._posterior import posterior_grid
    from psignifit._priors import setup_priors

    kw = {}
    if settings.grid_steps:
        kw["grid_steps"] = dict(settings.grid_steps)
    if settings.coarse_steps:
        kw["steps_moving_bounds"] = dict(settings.coarse_steps)
    conf = Configuration(experiment_type=experiment_type, sigmoid=settings.sigmoid, stimulus_range=x_range,
                         fixed_parameters={"eta": 0.0} if eta_fixed else None, verbose=False, **kw)
    sigmoid = conf.make_sigmoid()
    width_min = float(np.diff(np.unique(data[:, 0])).min())  # psignifit's default for the levels tested
    bounds = parameter_bounds(min_width=width_min, experiment_type=conf.experiment_type, stimulus_range=x_range,
                              alpha=conf.width_alpha, nafc_choices=conf.experiment_choices)
    if eta_fixed:
        bounds["eta"] = (0.0, 0.0)
    priors = setup_priors(custom_priors=None, bounds=bounds, stimulus_range=x_range, width_min=width_min,
                          width_alpha=conf.width_alpha, beta_prior=conf.beta_prior,
                          threshold_prop_correct=conf.thresh_PC)
    grid = parameter_grid(bounds, conf.steps_moving_bounds)
    coarse, _ = posterior_grid(data, sigmoid=sigmoid, priors=priors, grid=grid)
    grid = parameter_grid(masked_parameter_bounds(grid, coarse >= conf.max_bound_value), conf.grid_steps)
    post, _ = posterior_grid(data, sigmoid=sigmoid, priors=priors, grid=grid)
    return post, grid, sigmoid


def fit_one(x: np.ndarray, correct: np.ndarray, *, criterion: float, experiment_type: str,
            x_range: tuple[float, float], settings: FitSettings, pooled: bool) -> dict:
    """One psignifit fit of trials at strength ``x`` with outcomes ``correct`` (0/1).

    Returns ``x_threshold`` (the posterior median of the level at ``criterion``), its credible interval
    ``x_ci_low``/``x_ci_high`` (posterior quantiles), and the posterior means of ``width``, ``lapse``,
    ``guess`` and ``eta``.
    """
    xs, idx = np.unique(x, return_inverse=True)
    data = np.column_stack([xs, np.bincount(idx, weights=correct), np.bincount(idx)]).astype(float)
    with warnings.catch_warnings():  # psignifit's advice warnings; degenerate data were refused before
        warnings.simplefilter("ignore")
        post, grid, sig = _posterior(data, experiment_type, x_range, settings,
                                     eta_fixed=settings.fix_eta_per_participant and not pooled)
    names = sorted(grid)  # psignifit's posterior axes are the sorted parameter names
    g = dict(zip(names, np.meshgrid(*[np.atleast_1d(np.asarray(grid[n], dtype=float)) for n in names],
                                    indexing="ij")))
    with np.errstate(all="ignore"):  # gamma + lambda = 1 at a grid corner: q = +-inf, handled below
        q = (criterion - g["gamma"]) / (1.0 - g["gamma"] - g["lambda"])
        xc = sig.inverse(np.clip(q, 1e-12, 1 - 1e-12), g["threshold"], g["width"])
    # a criterion above the upper asymptote is never reached: beyond every level
    xc = np.where(q >= 1.0, np.inf, np.where(q <= 0.0, -np.inf, xc)).ravel()
    w = post.ravel()
    lo, mid, hi = _weighted_quantiles(xc, w, ((1 - CI_LEVEL) / 2, 0.5, (1 + CI_LEVEL) / 2))

    def mean(name):
        return float((g[name].ravel() * w).sum())

    return {"x_threshold": mid, "x_ci_low": lo, "x_ci_high": hi, "width": mean("width"), "lapse": mean("lambda"),
            "guess": mean("gamma"), "eta": mean("eta")}


def _infer_axis(levels: np.ndarray, correct: np.ndarray) -> Axis:
    """An axis for a condition with none declared: log if every level is > 0; detection's direction from the
    sign of the level-correctness correlation over all its trials."""
    scale = "log" if np.all(levels > 0) else "linear"
    x = Axis(scale).to_intensity(levels)
    r = np.corrcoef(x, correct)[0, 1] if np.std(x) > 0 and np.std(correct) > 0 else 1.0
    return Axis(scale, "higher" if not r < 0 else "lower")


def _fit_task(task: tuple) -> dict:
    key, x, y, kw = task
    return {**key, **fit_one(x, y, **kw)}


def fit_thresholds(df: pd.DataFrame, *, criterion: float, experiment_type: str,
                   axes: Mapping[str, Axis] | None = None, settings: FitSettings = FitSettings(),
                   participant: str = "participant", condition: str = "condition", scene: str = "scene",
                   level: str = "level", correct: str = "correct", varied: str | None = "varied",
                   pooled: bool = True, min_trials: int = MIN_TRIALS, workers: int = 1,
                   progress: Callable[[int, int], None] | None = None) -> pd.DataFrame:
    """Fit every participant x condition x scene (and, with ``pooled``, every condition x scene over all
    participants, ``participant == POOLED``).

    Parameters
    ----------
    df : DataFrame
        Tidy trials: one row per answered adaptive trial.
    criterion : float
        The family's threshold criterion on the scaled function (2AFC 0.75, yes/no 0.5).
    experiment_type : str
        psignifit's experiment type (``"2AFC"``, ``"yes/no"``).
    axes : mapping, optional
        Condition -> :class:`Axis`; conditions without one get an inferred axis (log if all levels > 0; the
        direction from the data), and the table says so in ``reason``.
    workers : int
        Processes for the fits (the results do not depend on it).
    progress : callable, optional
        ``progress(done, total)`` after every fit.

    Returns
    -------
    DataFrame with :data:`FIT_COLUMNS`; ``threshold``, ``ci_low``, ``ci_high`` in level units, the ``x_*``
    columns on the strength axis (``axis``: log10 or linear), NaN with ``estimable = False`` and the reason in
    ``reason`` where the data give no threshold.
    """
    missing = [c for c in (participant, condition, scene, level, correct) if c not in df.columns]
    if missing:
        raise ValueError(f"threshold data lack the column(s) {', '.join(missing)}")
    d = df.dropna(subset=[level, correct])
    axes = dict(axes or {})
    notes = {}
    for cond, sub in d.groupby(condition, sort=False):
        if cond not in axes:
            axes[cond] = _infer_axis(sub[level].to_numpy(float), sub[correct].to_numpy(float))
            notes[cond] = f"axis inferred ({axes[cond].scale}, stronger {axes[cond].stronger})"
    groups = [(str(p), c, s, sub) for (p, c, s), sub in d.groupby([participant, condition, scene], sort=True)]
    if pooled:
        groups += [(POOLED, c, s, sub) for (c, s), sub in d.groupby([condition, scene], sort=True)]
    rows, tasks = [], []
    for p, c, s, sub in groups:
        ax = axes[c]
        lv = sub[level].to_numpy(float)
        y = sub[correct].to_numpy(float)
        n, k = int(y.size), int(y.sum())
        row = {"participant": p, "condition": c, "scene": s,
               "varied": str(sub[varied].iloc[0]) if varied and varied in sub.columns else "",
               "n_trials": n, "n_levels": int(np.unique(lv).size), "criterion": float(criterion),
               "axis": ax.unit, "stronger": ax.stronger}
        if ax.scale == "log" and np.any(lv <= 0):
            reason = "not estimable: a level <= 0 on a log axis"
        else:
            reason = _not_estimable(n, lv, k, min_trials)
        row["reason"] = reason or notes.get(c, "")
        row["estimable"] = not reason
        rows.append(row)
        if not reason:
            kw = {"criterion": criterion, "experiment_type": experiment_type, "x_range": ax.x_range(lv),
                  "settings": settings, "pooled": p == POOLED}
            tasks.append(({"_i": len(rows) - 1}, ax.to_intensity(lv), y, kw))
    results = _run(tasks, workers, progress)
    for r in results:
        i = r.pop("_i")
        rows[i].update(r)
    out = pd.DataFrame(rows)
    for col in ("x_threshold", "x_ci_low", "x_ci_high", "width", "lapse", "guess", "eta"):
        if col not in out.columns:
            out[col] = np.nan
    ends = []
    for _, r in out.iterrows():
        ax = axes[r["condition"]]
        lv = ax.to_level([r["x_threshold"], r["x_ci_low"], r["x_ci_high"]])
        lo, hi = np.sort(lv[1:])  # a "lower" axis swaps the interval's ends
        ends.append((lv[0], lo, hi))
    out[["threshold", "ci_low", "ci_high"]] = pd.DataFrame(ends, index=out.index, dtype=float) if ends else np.nan
    return out.loc[:, list(FIT_COLUMNS)].reset_index(drop=True) if len(out) else pd.DataFrame(
        columns=list(FIT_COLUMNS))


def _run(tasks: list, workers: int, progress) -> list[dict]:
    """The fits, in order; in ``workers`` processes when there are enough of them to pay for the start-up."""
    total = len(tasks)
    out = []
    import multiprocessing as mp

    if workers > 1 and total >= 4 and "fork" in mp.get_all_start_methods():
        import concurrent.futures as cf

        # fork: the workers inherit the imported modules (spawn would re-import the caller's main script)
        with cf.ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("fork")) as ex:
            for r in ex.map(_fit_task, tasks, chunksize=max(1, total // (4 * workers))):
                out.append(r)
                if progress:
                    progress(len(out), total)
        return out
    for t in tasks:
        out.append(_fit_task(t))
        if progress:
            progress(len(out), total)
    return out


def group_table(fits: pd.DataFrame, n_boot: int = 2000, seed: int = 0, axes: Mapping[str, Axis] | None = None,
                ) -> pd.DataFrame:
    """Per condition x scene over the participants' estimable fits: mean threshold on the strength axis
    (for a log axis, the geometric mean level), between-participant SD, and a percentile bootstrap CI of the
    mean (participants resampled with replacement, ``n_boot`` replicates, seeded).

    A group with no estimable participant gets NaN and its count of not estimable ones; a group of one has no
    SD and no interval (NaN).
    """
    rows = []
    rng = np.random.default_rng(seed)
    per = fits[fits["participant"] != POOLED]
    for (c, s), sub in per.groupby(["condition", "scene"], sort=False):
        ok = sub[sub["estimable"].astype(bool)]
        x = ok["x_threshold"].to_numpy(float)
        x = x[np.isfinite(x)]
        ax = (axes or {}).get(c) or Axis("log" if (sub["axis"] == "log10").all() else "linear",
                                         str(sub["stronger"].iloc[0]))
        mean = float(x.mean()) if x.size else math.nan
        sd = float(x.std(ddof=1)) if x.size > 1 else math.nan
        lo = hi = math.nan
        if x.size > 1 and n_boot > 0:
            boots = x[rng.integers(0, x.size, size=(n_boot, x.size))].mean(axis=1)
            lo, hi = (float(v) for v in np.quantile(boots, [(1 - CI_LEVEL) / 2, (1 + CI_LEVEL) / 2]))
        lv = ax.to_level([mean, lo, hi])
        lv_lo, lv_hi = np.sort(lv[1:])
        rows.append({"condition": c, "scene": s, "varied": sub["varied"].iloc[0], "n_participants": int(x.size),
                     "n_not_estimable": int(len(sub) - len(ok)), "axis": ax.unit, "mean_x": mean, "sd_x": sd,
                     "ci_low_x": lo, "ci_high_x": hi, "threshold": float(lv[0]),
                     "ci_low": float(lv_lo), "ci_high": float(lv_hi),
                     "n_boot": int(n_boot)})
    return pd.DataFrame(rows, columns=list(GROUP_COLUMNS))


#: Columns of :func:`pareto`'s table.
PARETO_COLUMNS = ("condition", "scene", "varied", "threshold", "ci_low", "ci_high", "p_detect", "cost",
                  "cost_ci_low", "cost_ci_high", "gt_cost", "relative_cost", "relative_cost_ci_low",
                  "relative_cost_ci_high", "speedup")
#: The time columns :func:`pareto` adds when given the frame times.
PARETO_TIME_COLUMNS = ("time_ms", "time_ms_ci_low", "time_ms_ci_high", "gt_time_ms", "time_speedup")


def detection(p, guess: float):
    """Probability of detection from the proportion correct (high-threshold correction for guessing):
    ``(p - gamma) / (1 - gamma)``, clipped to [0, 1] (2AFC ``gamma = 0.5``; yes/no: the fitted false-alarm
    rate)."""
    return np.clip((np.asarray(p, dtype=float) - guess) / (1.0 - guess), 0.0, 1.0)


def _carried(at: Callable[[float], float], g) -> tuple[float, float, float]:
    """``at`` at a group row's threshold and at its CI's ends, the ends in increasing order (a cost may fall as
    the level grows)."""
    k, lo, hi = at(g["threshold"]), at(g["ci_low"]), at(g["ci_high"])
    return (k, *sorted((lo, hi))) if np.isfinite(lo) and np.isfinite(hi) else (k, lo, hi)


def pareto(fits: pd.DataFrame, group: pd.DataFrame, axes: Mapping[str, Axis],
           cost: Callable[[str, str, float], float], gt_cost: Callable[[str], float],
           n_points: int = 41, time: Callable[[str, str, float], float] | None = None,
           gt_time: Callable[[str], float] | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The perceptual Pareto front: what each renderer costs at its threshold, against the ground truth.

    Parameters
    ----------
    fits, group : DataFrame
        :func:`fit_thresholds` (its pooled rows give the curves) and :func:`group_table` (the thresholds and
        their CIs).
    axes : mapping
        Condition -> :class:`Axis` (the curve spans its domain, else the pooled fit's interval).
    cost : callable
        ``cost(condition, scene, level)``: a device-independent count (shading points, rays, light samples)
        of rendering the condition with its varied parameter at ``level``; must be monotone in the level.
    gt_cost : callable
        ``gt_cost(scene)``: the same count for the ground truth.
    time, gt_time : callable, optional
        The same for the frame time (ms) on one backend, measured at the ladder's levels; with them the table
        gains :data:`PARETO_TIME_COLUMNS`.

    Returns
    -------
    table : DataFrame (:data:`PARETO_COLUMNS`, then :data:`PARETO_TIME_COLUMNS` with ``time``)
        Per condition x scene: the group threshold and CI, the probability of detection there, the cost at the
        threshold and at the CI's ends (the interval carried through), relative to GT's, and the speed-up
        ``gt_cost / cost``; with ``time`` the same for the frame time (``time_speedup = gt_time_ms / time_ms``).
    curves : DataFrame
        ``condition, scene, level, relative_cost, p_detect``: the pooled fit over the domain.
    """
    pooled = fits[(fits["participant"] == POOLED) & fits["estimable"].astype(bool)]
    rows, curve_rows = [], []
    for _, g in group.iterrows():
        c, s = g["condition"], g["scene"]
        ref = float(gt_cost(s))
        pf = pooled[(pooled["condition"] == c) & (pooled["scene"] == s)]
        guess = float(pf["guess"].iloc[0]) if len(pf) else 0.5
        crit = float(fits.loc[fits["condition"] == c, "criterion"].iloc[0])

        def at(level, fn=cost):
            return float(fn(c, s, float(level))) if np.isfinite(level) and level > 0 else math.nan

        k, klo, khi = _carried(at, g)
        row = {"condition": c, "scene": s, "varied": g["varied"], "threshold": g["threshold"],
               "ci_low": g["ci_low"], "ci_high": g["ci_high"], "p_detect": float(detection(crit, guess)),
               "cost": k, "cost_ci_low": klo, "cost_ci_high": khi, "gt_cost": ref,
               "relative_cost": k / ref, "relative_cost_ci_low": klo / ref,
               "relative_cost_ci_high": khi / ref, "speedup": ref / k if k else math.nan}
        if time is not None:
            t, tlo, thi = _carried(lambda lv: at(lv, time), g)
            gt_ms = float(gt_time(s))
            row.update(time_ms=t, time_ms_ci_low=tlo, time_ms_ci_high=thi, gt_time_ms=gt_ms,
                       time_speedup=gt_ms / t if t else math.nan)
        rows.append(row)
        if len(pf):
            r = pf.iloc[0]
            ax = axes[c]
            ends = ax.to_intensity(np.asarray(ax.bounds)) if ax.bounds is not None else np.array(
                [r["x_ci_low"] - 2 * r["width"], r["x_ci_high"] + 2 * r["width"]])
            xs = np.linspace(float(np.min(ends)), float(np.max(ends)), n_points)
            p = detection(psychometric(xs, r["x_threshold"], r["width"], r["guess"], r["lapse"], crit), guess)
            for lv, pd_ in zip(ax.to_level(xs).tolist(), p):  # the whole curve at once, as before the move
                curve_rows.append({"condition": c, "scene": s, "level": lv, "relative_cost": at(lv) / ref,
                                   "p_detect": float(pd_)})
    columns = list(PARETO_COLUMNS) + (list(PARETO_TIME_COLUMNS) if time is not None else [])
    return (pd.DataFrame(rows, columns=columns),
            pd.DataFrame(curve_rows, columns=["condition", "scene", "level", "relative_cost", "p_detect"]))


@dataclass
class ThresholdAnalysis:
    """A threshold study's analysis (what :func:`analysis.report.write_threshold_report` writes).

    ``trials``: the adaptive trials fitted (participant, condition, scene, level, correct); ``fits``,
    ``group``: :func:`fit_thresholds`, :func:`group_table`; ``pareto``, ``curves``: :func:`pareto` (None without a
    cost); ``cost_label``: what the cost counts; ``time_label``: the frame times' unit, size, backend and machine
    ("" when not measured: then ``pareto`` has no time columns); ``family``, ``criterion``: the threshold's definition;
    ``settings``: :meth:`FitSettings.describe`; ``notes``: lines for the report.
    """

    trials: pd.DataFrame
    fits: pd.DataFrame
    group: pd.DataFrame
    family: str
    criterion: float
    settings: str
    pareto: pd.DataFrame | None = None
    curves: pd.DataFrame | None = None
    cost_label: str = ""
    time_label: str = ""
    notes: list[str] | None = None
    n_boot: int = 0


def adaptive_trials(df: pd.DataFrame) -> pd.DataFrame:
    """The answered adaptive trials of a tidy log, with ``condition`` and ``scene`` taken from the procedure id
    (``COND@scene``: the varied condition, not the level condition ``COND(level)`` the trial showed)."""
    if "procedure" not in df.columns or "correct" not in df.columns:
        return df.iloc[0:0].assign(level=[], correct=[])
    d = df[df["procedure"].fillna("").astype(str).str.contains("@") & df["correct"].notna()].copy()
    if "practice" in d.columns:
        d = d[~d["practice"].fillna(False).astype(bool)]
    parts = d["procedure"].astype(str).str.partition("@")
    d["condition"], d["scene"] = parts[0], parts[2]
    d["level"] = d["level"].astype(float)
    d["correct"] = d["correct"].astype(float)
    return d.reset_index(drop=True)
