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

Time at threshold: the median frame time of every ladder level and of GT per scene, measured on one backend at the
same size by ``benchmarks/bench_thresholds.py --ladder-times`` (:data:`FRAME_TIME_COLUMNS`), read and checked
against the protocol by :func:`frame_times` and interpolated like the counts (log level, log time).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from data_schema import families
from data_schema.intensity import Axis

from .protocol import Protocol

#: What the cost counts, per StrengthSpec.count.
COST_LABELS = {"rays_primary": "primary rays (shading points)", "light_samples": "light samples"}


#: The columns of a frame-time CSV (benchmarks/bench_thresholds.py --ladder-times; GT rows have no param or level).
FRAME_TIME_COLUMNS = ("protocol", "backend", "width", "height", "condition", "renderer", "param", "level", "scene",
                      "median_ms", "repeats", "machine")


def axes_of(protocol: Protocol) -> dict:
    """Varied condition -> :class:`data_schema.intensity.Axis` (scale, direction, the ladder's ends)."""
    return {name: Axis(v.scale, v.stronger, (min(v.levels), max(v.levels)))
            for name, v in protocol.adaptive.varied.items()}


def cost_size(protocol: Protocol, scale: float = 1.0) -> tuple[int, int]:
    """The frame size the cost at threshold is counted and timed at: the protocol's render size times ``scale``
    (at least 8 pixels a side)."""
    w, h = (max(8, round(v * scale)) for v in protocol.render_size)
    return w, h


def log_interp(levels, values, level: float, floor: float) -> float:
    """``values`` (positive, one per ladder level) at ``level``: linear interpolation in log level and log value
    (exact for a power law; constant beyond the ladder's ends); values below ``floor`` count as ``floor``."""
    lv = np.log(np.asarray(levels, dtype=float))
    order = np.argsort(lv)
    v = np.log(np.maximum(np.asarray(values, dtype=float), floor))
    return float(math.exp(np.interp(math.log(level), lv[order], v[order])))


def frame_times(path: Path, protocol: Protocol, scale: float = 1.0) -> tuple[Callable, Callable, str]:
    """``(time_ms(condition, scene, level), gt_time_ms(scene), label)`` from a frame-time CSV
    (:data:`FRAME_TIME_COLUMNS`), checked against ``protocol`` before anything is fitted: one backend, the size
    of :func:`cost_size`, a row for every ladder level of every varied condition and for the reference on every
    scene (a :class:`~data_schema.errors.UserError` naming what is missing otherwise)."""
    import pandas as pd

    from data_schema.errors import UserError

    where = f"--frame-times {path}"
    try:
        df = pd.read_csv(path)
    except (OSError, ValueError) as exc:
        raise UserError(f"{where}: cannot read it as CSV ({str(exc).splitlines()[0] if str(exc) else exc})") from None
    lacking = [c for c in FRAME_TIME_COLUMNS if c not in df.columns]
    if lacking:
        raise UserError(f"{where}: lacks the column(s) {', '.join(lacking)} (write it with "
                        "benchmarks/bench_thresholds.py --ladder-times)")
    ms = pd.to_numeric(df["median_ms"], errors="coerce")
    if not (np.isfinite(ms) & (ms > 0)).all():
        raise UserError(f"{where}: median_ms must be a positive number in every row")
    names = sorted(set(df["protocol"].astype(str)))
    if names != [protocol.name]:
        raise UserError(f"{where}: measured for protocol {', '.join(names)}, not {protocol.name}")
    backends = sorted(set(df["backend"].astype(str)))
    if len(backends) != 1:
        raise UserError(f"{where}: holds {len(backends)} backends ({', '.join(backends)}): give one backend's times")
    w, h = cost_size(protocol, scale)
    sizes = sorted({f"{a}x{b}" for a, b in zip(df["width"], df["height"])})
    if sizes != [f"{w}x{h}"]:
        raise UserError(f"{where}: measured at {', '.join(sizes)}, the cost is counted at {w}x{h} (render size "
                        f"{protocol.render_size[0]}x{protocol.render_size[1]} x --cost-scale {scale:g}): measure "
                        f"with --scale {scale:g} or pass the --cost-scale it was measured at")
    ref = protocol.adaptive.reference
    df = df.assign(median_ms=ms, level=pd.to_numeric(df["level"], errors="coerce"))
    ladders, gt, missing = {}, {}, []
    for scene in protocol.scenes:
        rows = df[(df["condition"] == ref) & (df["scene"] == scene)]
        if rows.empty:
            missing.append(f"{ref} on {scene}")
        else:
            gt[scene] = float(rows["median_ms"].iloc[0])
        for cond, v in protocol.adaptive.varied.items():
            rows = df[(df["condition"] == cond) & (df["scene"] == scene) & (df["param"] == v.param)]
            pick = []
            for lv in v.levels:
                hit = rows[np.isclose(rows["level"], lv, rtol=1e-6, atol=0.0)]
                if hit.empty:
                    missing.append(f"{cond} {v.param}={lv:g} on {scene}")
                else:
                    pick.append((lv, float(hit["median_ms"].iloc[0])))
            ladders[cond, scene] = pick
    if missing:
        more = f" and {len(missing) - 4} more" if len(missing) > 4 else ""
        raise UserError(f"{where} does not match protocol {protocol.name}: no time for "
                        f"{', '.join(missing[:4])}{more}")

    def time_ms(cond: str, scene: str, level: float) -> float:
        lv, t = zip(*ladders[cond, scene])
        return log_interp(lv, t, level, floor=1e-6)

    machine = str(df["machine"].iloc[0]).rstrip(".")
    label = f"ms per frame at {w}x{h} on the {backends[0]} backend ({machine})"
    return time_ms, lambda scene: gt[scene], label


def ladder_cost(protocol: Protocol, scale: float = 1.0, cache_dir: Path | None = None,
                progress: Callable[[str], None] | None = None) -> tuple[Callable, Callable, str]:
    """``(cost(condition, scene, level), gt_cost(scene), label)`` of the protocol's ladders at its render size
    times ``scale`` (module docstring)."""
    from renderers.cost import cost_table
    from renderers.registry import foveation_strength

    w, h = cost_size(protocol, scale)
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
        return log_interp(t["level"], t["work"], level, floor=1.0)

    def gt_cost(scene: str) -> float:
        cond = next(iter(protocol.adaptive.varied))
        return float(table(cond, scene)["gt_work"].iloc[0])

    for cond in protocol.adaptive.varied:  # the label is known once the first table is made
        table(cond, protocol.scenes[0])
    label = " / ".join(sorted(labels)) + f" per frame at {w}x{h}"
    return cost, gt_cost, label


def analyze_thresholds(df, protocol: Protocol, *, n_boot: int = 2000, seed: int = 0, workers: int = 2,
                       cost: bool = True, cost_scale: float = 1.0, cache_dir: Path | None = None,
                       settings=None, progress: Callable[[str], None] | None = None,
                       times: Path | None = None):
    """The :class:`analysis.thresholds.ThresholdAnalysis` of a tidy log of ``protocol`` (adaptive); ``times``: a
    frame-time CSV (:func:`frame_times`) for the time at threshold."""
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
    timing = frame_times(Path(times), protocol, cost_scale) if times is not None and cost else None

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
        t, gt_t, res.time_label = timing or (None, None, "")
        res.pareto, res.curves = pareto(fits, group, axes, c, g, time=t, gt_time=gt_t)
        res.cost_label = label
        if timing is None:
            w, h = cost_size(protocol, cost_scale)
            notes.append(f"Frame time at threshold: not measured. Measure the ladders with `python "
                         f"benchmarks/bench_thresholds.py --ladder-times {protocol.name} --scale {cost_scale:g} "
                         f"[--backend gpu]` ({w}x{h}) and pass its CSV as `studyapp analyze --frame-times`.")
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
