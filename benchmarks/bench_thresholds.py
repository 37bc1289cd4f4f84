"""Threshold studies: known-truth recovery of the adaptive procedures, coverage of their intervals, and the speed
of the analysis (issue 28 items 4 and 6).

Run:  .venv/bin/python benchmarks/bench_thresholds.py [--participants 200] [--speed-participants 25]
                                                      [--write docs/benchmarks.md]

Recovery: ``--participants`` simulated participants answer threshold_foveation's VaFR procedure on temple (the
shipped QUEST+ settings, 40 trials, its 7-level acuity_scale ladder) from the protocol's declared psychometric
function (threshold_sd 0: every participant has the declared threshold). Reported: the median QUEST+ threshold
(posterior mean) against the declared one (log10 units), the share of 95 % posterior intervals that cover it, the
same for psignifit's 95 % credible interval of the threshold at 75 % correct fitted to each participant's 40
trials (against the declared function's 75 % level); a 1-up-2-down staircase (80 trials, single ladder steps)
on a 24-level ladder over the same domain and the proportion correct at its estimate (target 70.7 %, Levitt
1971).

Speed: 25 participants x 3 renderers x 2 scenes x 60 trials simulated (not timed), then timed: 150 psignifit fits
plus 6 pooled ones, the group table (2,000 bootstrap replicates), the report with a fit figure per participant
and the pooled one (the Pareto front's cost needs renders of the ladders and is left out here). The fit's
settings are printed with the figures.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)


def recovery(n: int) -> list[str]:
    import numpy as np

    from analysis.thresholds import FitSettings, fit_one
    from studyapp.commands.study import SHIPPED, _protocol
    from studyapp.runner.observer import declared_function
    from studyapp.runner.threshold_study import quest_interval, run_procedure

    p = _protocol(str(SHIPPED / "threshold_foveation.yaml"))
    p.simulation["threshold_sd"] = 0.0
    spec = p.adaptive.spec("VaFR")
    truth = declared_function(p, "VaFR", "temple", "P01", 0)
    at75 = truth.intensity(truth.level_at(0.75))
    est, cover, fit_cover, fit_err = [], [], [], []
    t0 = time.perf_counter()
    for i in range(n):
        proc, steps = run_procedure(spec, truth, 10_000 + i)
        est.append(proc.estimate()["mean"])
        lo, hi = quest_interval(proc)
        cover.append(lo <= truth.threshold <= hi)
        x = np.array([truth.intensity(s["level"]) for s in steps])
        y = np.array([s["correct"] for s in steps], float)
        if 0 < y.sum() < y.size:
            xr = sorted(truth.intensity(v) for v in (min(spec["levels"]), max(spec["levels"])))
            f = fit_one(x, y, criterion=0.75, experiment_type="2AFC", x_range=tuple(xr), settings=FitSettings(),
                        pooled=False)
            fit_cover.append(f["x_ci_low"] <= at75 <= f["x_ci_high"])
            fit_err.append(f["x_threshold"] - at75)
    t_q = time.perf_counter() - t0
    # a staircase converges on its target when its steps are small: 24 levels over the same domain
    from studyapp.runner.adaptive import grid

    fine = grid("log", min(spec["levels"]), max(spec["levels"]), 24)
    st = {**spec, "levels": fine, "method": "staircase", "rule": "1-up-2-down", "steps": [1],
          "stop": {"trials": 80}}
    for k in ("function", "threshold", "slope", "lapse", "guess"):
        st.pop(k, None)
    pc = [float(truth.p_correct(run_procedure(st, truth, 20_000 + i)[0].estimate()["mean"])) for i in range(n)]
    est = np.asarray(est)
    return [
        f"Recovery over {n} simulated participants (threshold_foveation, VaFR on temple, declared threshold "
        f"acuity_scale {p.simulation['psychometric']['VaFR']['threshold']:g}, {truth.threshold:.3f} on the intensity "
        f"axis (-log10), slope {truth.slope:g}, lapse {truth.lapse:g}; 75 % correct at acuity_scale "
        f"{truth.level_at(0.75):.3g}; {t_q:.0f} s):",
        "",
        "| measure | value | target |",
        "|---|---|---|",
        f"| median QUEST+ threshold after 40 trials - declared (log10) | {np.median(est) - truth.threshold:+.3f} "
        "| within ±0.1 |",
        f"| QUEST+ estimates, 5-95 % range (log10) | {np.percentile(est, 5) - truth.threshold:+.3f} to "
        f"{np.percentile(est, 95) - truth.threshold:+.3f} | |",
        f"| QUEST+ 95 % posterior intervals covering the declared threshold | {np.mean(cover):.1%} | 90-99 % |",
        f"| psignifit 95 % intervals (threshold at 75 %, 40 trials) covering the declared 75 % level "
        f"| {np.mean(fit_cover):.1%} ({len(fit_cover)} fits) | 90-99 % |",
        f"| median psignifit threshold at 75 % - declared (log10) | {np.median(fit_err):+.3f} | |",
        f"| 1-up-2-down staircase, 80 trials on a 24-level ladder: median P(correct) at its estimate (mean of the "
        f"last 6 reversals) | {np.median(pc):.1%} | 70.7 % |",
    ]


def speed(n: int) -> list[str]:
    from analysis.report import write_threshold_report
    from analysis.thresholds import FitSettings
    from studyapp.commands.study import SHIPPED, _protocol
    from studyapp.runner.threshold_study import analyze_thresholds, simulate_adaptive

    p = _protocol(str(SHIPPED / "threshold_foveation.yaml"))
    df = simulate_adaptive(p, n, seed=0, trials=60)
    settings = FitSettings()
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = analyze_thresholds(df, p, n_boot=2000, workers=2, cost=False, settings=settings)
        t_fit = time.perf_counter() - t0
        paths = write_threshold_report(res, tmp, figures=True)
        total = time.perf_counter() - t0
    n_fits = len(res.fits)
    return [
        f"Speed: {n} participants x 3 renderers x 2 scenes x 60 trials ({len(df):,} trials), analysed in "
        f"**{total:.1f} s** (target < 120 s): {n_fits} psignifit fits and the group table in {t_fit:.1f} s "
        f"(2 worker processes), report with {sum(x.suffix == '.png' for x in paths)} figures in "
        f"{total - t_fit:.1f} s.",
        "",
        f"Fit settings: {settings.describe()}; eta fixed at 0 per participant, free in the pooled fits; "
        "psignifit's own MAP search is skipped (the threshold is the posterior median at the criterion).",
    ]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--participants", type=int, default=200)
    ap.add_argument("--speed-participants", type=int, default=25)
    ap.add_argument("--write", metavar="FILE", help="replace the thresholds section of this Markdown file")
    args = ap.parse_args(argv)
    from benchmarks.harness import command_line, machine_line, replace_section

    lines = ["## Threshold studies: recovery, coverage and speed (bench_thresholds.py)", "",
             f"`{command_line('benchmarks/bench_thresholds.py', list(argv or sys.argv[1:]))}`; "
             f"{machine_line()} Load average at the start: {os.getloadavg()[0]:.1f}.", ""]
    lines += recovery(args.participants) + [""] + speed(args.speed_participants)
    print("\n".join(lines))
    if args.write:
        replace_section(args.write, "thresholds", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
