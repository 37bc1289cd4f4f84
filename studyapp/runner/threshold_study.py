"""A threshold study's analysis from its protocol: the strength axes, the family's criterion, the psychometric
fits, the group table and the speed at threshold (the perceptual Pareto front).

The protocol knows what analysis may not import: each varied condition's domain and direction
(``design.adaptive``), the family's threshold criterion and psignifit experiment type
(:mod:`data_schema.families`), and how to count a renderer's work (:mod:`renderers.cost`). The statistics are
:mod:`analysis.thresholds`.

Cost at threshold: the device-independent count the renderer's foveation strength lowers
(:class:`renderers.plugin_types.StrengthSpec`: primary rays for the ray tracers -- one per shading point --,
light samples for the lightcuts baselines) of one frame at the study's size, measured at every level of the
ladder (:func:`renderers.cost.cost_table`, through the stimulus cache) and interpolated linearly in log level and
log count in between (the count is monotone in the level); GT's count is its ground truth's at the same size.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from data_schema import families

from .protocol import Protocol

#: What the cost counts, per StrengthSpec.count.
COST_LABELS = {"rays_primary": "primary rays (shading points)", "light_samples": "light samples"}


def axes_of(protocol: Protocol) -> dict:
    """Varied condition -> :class:`analysis.thresholds.Axis` (scale, direction, the ladder's ends)."""
    from analysis.thresholds import Axis

    return {name: Axis(v.scale, v.stronger, (min(v.levels), max(v.levels)))
            for name, v in protocol.adaptive.varied.items()}


def ladder_cost(protocol: Protocol, scale: float = 1.0, cache_dir: Path | None = None,
                progress: Callable[[str], None] | None = None) -> tuple[Callable, Callable, str]:
    """``(cost(condition, scene, level), gt_cost(scene), label)`` of the protocol's ladders at its render size
    times ``scale`` (module docstring)."""
    from renderers.cost import cost_table
    from renderers.registry import foveation_strength

    w, h = (max(8, round(v * scale)) for v in protocol.render_size)
    camera = {"fov_y": protocol.display.fov_y_deg}
    ref = protocol.conditions[protocol.adaptive.reference]
    tables, labels = {}, set()

    def table(cond: str, scene: str):
        if (cond, scene) not in tables:
            if progress:
                progress(f"cost of {cond} on {scene} at {w}x{h}")
            c = protocol.conditions[cond]
            v = protocol.adaptive.varied[cond]
            t = cost_table(protocol.scene_ref(scene), c.renderer, v.levels, w, h, params=c.params,
                           reference=ref.renderer, reference_params=ref.params, camera=camera, cache_dir=cache_dir)
            tables[cond, scene] = t.sort_values("level")
            labels.add(COST_LABELS.get(foveation_strength(c.renderer).count, "work"))
        return tables[cond, scene]

    def cost(cond: str, scene: str, level: float) -> float:
        t = table(cond, scene)
        lv, work = np.log(t["level"].to_numpy(float)), np.log(np.maximum(t["work"].to_numpy(float), 1.0))
        return float(math.exp(np.interp(math.log(level), lv, work)))

    def gt_cost(scene: str) -> float:
        cond = next(iter(protocol.adaptive.varied))
        return float(table(cond, scene)["gt_work"].iloc[0])

    for cond in protocol.adaptive.varied:  # the label is known once the first table is made
        table(cond, protocol.scenes[0])
    label = " / ".join(sorted(labels)) + f" per frame at {w}x{h}"
    return cost, gt_cost, label


def analyze_thresholds(df, protocol: Protocol, *, n_boot: int = 2000, seed: int = 0, workers: int = 2,
                       cost: bool = True, cost_scale: float = 1.0, cache_dir: Path | None = None,
                       settings=None, progress: Callable[[str], None] | None = None):
    """The :class:`analysis.thresholds.ThresholdAnalysis` of a tidy log of ``protocol`` (adaptive)."""
    from analysis.thresholds import (
        FitSettings,
        ThresholdAnalysis,
        adaptive_trials,
        fit_thresholds,
        group_table,
        pareto,
    )
    from data_schema.errors import UserError

    if protocol.adaptive is None:
        raise UserError(f"protocol {protocol.name} has no adaptive design: no thresholds to fit")
    fam = families.get(protocol.family)
    settings = settings or FitSettings()
    trials = adaptive_trials(df)
    if trials.empty:
        raise UserError("the log has no answered adaptive trials (columns procedure, level, correct)")
    axes = axes_of(protocol)
    say = progress or (lambda msg: None)

    def tick(done, total):
        say(f"fits {done}/{total}")

    fits = fit_thresholds(trials, criterion=fam.threshold_criterion, experiment_type=fam.psignifit_type,
                          axes=axes, settings=settings, workers=workers, progress=tick)
    group = group_table(fits, n_boot=n_boot, seed=seed, axes=axes)
    notes = [f"Thresholds of {', '.join(f'{c} ({v.param})' for c, v in protocol.adaptive.varied.items())} "
             f"against {protocol.adaptive.reference} ({fam.title}); 'correct' as the trial log defines it."]
    res = ThresholdAnalysis(trials=trials, fits=fits, group=group, family=fam.name,
                            criterion=fam.threshold_criterion, settings=settings.describe(), notes=notes,
                            n_boot=n_boot)
    if cost:
        c, g, label = ladder_cost(protocol, cost_scale, cache_dir, progress=say)
        res.pareto, res.curves = pareto(fits, group, axes, c, g)
        res.cost_label = label
    return res


def simulate_adaptive(protocol: Protocol, participants: int | list[str], seed: int = 0,
                      trials: int | None = None):
    """Tidy adaptive trials (participant, condition, scene, procedure, varied, level, correct, estimate_mean,
    estimate_sd) of simulated participants answering every procedure of ``protocol`` from its declared
    psychometric functions (:func:`studyapp.runner.observer.declared_function`), ``trials`` per procedure
    (default the protocol's ``stop.trials``; its other stopping rules still apply).

    The procedures run one after the other, not interleaved: a simulated observer's answer depends on the level
    only, so the order changes nothing but the random draws. Seeded by (seed, participant, procedure).
    """
    import pandas as pd

    from data_schema.errors import UserError

    from .adaptive import procedure_id
    from .observer import _key, declared_function

    ids = [f"P{i + 1:02d}" for i in range(participants)] if isinstance(participants, int) else list(participants)
    rows = []
    for pid in ids:
        for cond, v in protocol.adaptive.varied.items():
            spec = protocol.adaptive.spec(cond)
            if trials is not None:
                spec["stop"] = {**spec["stop"], "trials": int(trials)}
            for scene in protocol.scenes:
                f = declared_function(protocol, cond, scene, pid, seed)
                if f is None:
                    raise UserError(f"condition {cond}: no declared psychometric function to simulate "
                                    "(simulation.psychometric)")
                proc_id = procedure_id(cond, scene)
                _, steps = run_procedure(spec, f, _key("procedure", seed, pid, proc_id))
                rows += [{"participant": pid, "condition": cond, "scene": scene, "trial": k, "procedure": proc_id,
                          "varied": v.param, **step} for k, step in enumerate(steps)]
    return pd.DataFrame(rows)


def quest_interval(proc, level: float = 0.95) -> tuple[float, float]:
    """The central ``level`` credible interval of a QUEST+ procedure's threshold (intensity units), from its
    posterior marginal on the threshold grid."""
    t = proc._coords["threshold"]  # the grid QUEST+ was built on (studyapp.runner.adaptive)
    c = np.cumsum(proc.marginal("threshold"))
    c /= c[-1]
    lo = t[min(int(np.searchsorted(c, (1 - level) / 2)), t.size - 1)]
    hi = t[min(int(np.searchsorted(c, (1 + level) / 2)), t.size - 1)]
    return float(lo), float(hi)


def run_procedure(spec: dict, observer, seed: int):
    """Run one procedure (:func:`studyapp.runner.adaptive.make_procedure`) to its stopping rule against a
    declared observer (:class:`studyapp.runner.observer.DeclaredFunction`). Returns the finished procedure and
    its trials: ``level``, ``correct``, ``estimate_mean``, ``estimate_sd`` after each one."""
    from .adaptive import make_procedure

    proc = make_procedure(spec, seed % 2**32)
    rng = np.random.default_rng([seed % 2**63, 1])
    steps = []
    while not proc.finished():
        level = proc.next_level()
        correct = bool(rng.random() < observer.p_correct(observer.intensity(level)))
        proc.update(level, correct)
        est = proc.estimate()
        steps.append({"level": float(level), "correct": int(correct), "estimate_mean": est["mean"],
                      "estimate_sd": est["sd"]})
    return proc, steps


def power_analysis(protocol: Protocol, participants: int, *, trials: int | None = None, replications: int = 20,
                   seed: int = 0, cost_scale: float = 0.25, settings=None, workers: int = 2,
                   progress: Callable[[int, int], None] | None = None):
    """What a study of ``participants`` simulated participants can expect: ``replications`` simulated studies
    (:func:`simulate_adaptive`), each fitted as ``studyapp analyze`` fits it (:mod:`analysis.thresholds`).

    Returns
    -------
    widths : DataFrame
        Per condition x scene: the median width of a participant's 95 % credible interval and of the group
        mean's 95 % bootstrap interval, in strength-axis units (log10 of the level for a log domain), and the
        share of not-estimable fits.
    pairs : DataFrame
        Per pair of varied conditions x scene: the share of replications in which a paired t-test over the
        participants tells their thresholds apart at the protocol's ``analysis.alpha`` (both on the strength
        axis where they vary the same parameter on the same axis; else on log10 of the cost at threshold, the
        ladder's count at ``cost_scale`` times the render size: different parameters have no common unit).
    """
    import itertools

    import pandas as pd
    from scipy import stats

    from analysis.thresholds import POOLED, FitSettings, fit_thresholds, group_table
    from data_schema.errors import UserError

    from .observer import declared_function

    fam = families.get(protocol.family)
    settings = settings or FitSettings()
    axes = axes_of(protocol)
    alpha = float(protocol.analysis.get("alpha", 0.05))
    varied = protocol.adaptive.varied
    pairs = list(itertools.combinations(varied, 2))
    for c in varied:  # every varied condition declares its observer: refused before any rendering
        for s in protocol.scenes:
            if declared_function(protocol, c, s, "P01", seed) is None:
                raise UserError(f"condition {c}: no declared psychometric function to simulate "
                                "(simulation.psychometric)")
    cost_fn = None
    if any((varied[a].param, varied[a].scale, varied[a].stronger) != (varied[b].param, varied[b].scale,
                                                                        varied[b].stronger) for a, b in pairs):
        cost_fn, _, _ = ladder_cost(protocol, cost_scale)
    n_fits = len(varied) * len(protocol.scenes) * participants
    widths, apart = [], []
    for r in range(replications):
        df = simulate_adaptive(protocol, participants, seed=seed * 1_000_003 + r, trials=trials)

        def tick(done, total, r=r):
            if progress:
                progress(r * n_fits + done, replications * n_fits)

        fits = fit_thresholds(df, criterion=fam.threshold_criterion, experiment_type=fam.psignifit_type,
                              axes=axes, settings=settings, pooled=False, workers=workers, progress=tick)
        group = group_table(fits, n_boot=500, seed=r, axes=axes)
        fits["ci_width_x"] = (fits["x_ci_high"] - fits["x_ci_low"]).abs()
        for (c, s), sub in fits.groupby(["condition", "scene"]):
            g = group[(group["condition"] == c) & (group["scene"] == s)].iloc[0]
            widths.append({"condition": c, "scene": s, "axis": axes[c].unit,
                           "participant_ci_width": float(sub["ci_width_x"].median()),
                           "group_ci_width": float(g["ci_high_x"] - g["ci_low_x"]),
                           "not_estimable": float((~sub["estimable"].astype(bool)).mean())})
        ok = fits[fits["estimable"].astype(bool) & (fits["participant"] != POOLED)]
        for a, b in pairs:
            same = cost_fn is None or (varied[a].param, varied[a].scale, varied[a].stronger) == (
                varied[b].param, varied[b].scale, varied[b].stronger)
            for s in protocol.scenes:
                xa = ok[(ok["condition"] == a) & (ok["scene"] == s)].set_index("participant")
                xb = ok[(ok["condition"] == b) & (ok["scene"] == s)].set_index("participant")
                both = xa.index.intersection(xb.index)
                if same:
                    va, vb = xa.loc[both, "x_threshold"], xb.loc[both, "x_threshold"]
                else:
                    va = np.log10([cost_fn(a, s, lv) for lv in xa.loc[both, "threshold"]])
                    vb = np.log10([cost_fn(b, s, lv) for lv in xb.loc[both, "threshold"]])
                p = float(stats.ttest_rel(va, vb).pvalue) if len(both) >= 2 else math.nan
                apart.append({"a": a, "b": b, "scene": s, "unit": "strength axis" if same else "log10 cost",
                              "told_apart": bool(p < alpha) if p == p else False})
    w = pd.DataFrame(widths).groupby(["condition", "scene", "axis"], sort=False).median().reset_index()
    pr = pd.DataFrame(apart).groupby(["a", "b", "scene", "unit"], sort=False)["told_apart"].mean().reset_index()
    pr = pr.rename(columns={"told_apart": "p_told_apart"})
    pr["alpha"] = alpha
    return w, pr
