"""Threshold studies: known-truth recovery of the adaptive procedures, coverage of their intervals, the speed
of the analysis (issue 28 items 4 and 6), and the frame times of a protocol's ladders (item 5).

Run:  .venv/bin/python benchmarks/bench_thresholds.py [--participants 200] [--speed-participants 25] [--smoke]
                                                      [--write docs/benchmarks.md]
      .venv/bin/python benchmarks/bench_thresholds.py --ladder-times PROTOCOL [--backend cpu|gpu] [--scale 0.1]
                                                      [--repeats 3] [--write docs/benchmarks.md]

Ladder times: every level of every varied condition of an adaptive protocol and its reference (GT), on every
scene, rendered as its stimulus (the protocol's camera, gaze at the centre) at the render size times ``--scale``
on one backend; one child process per condition x scene (a warm-up frame at 64x48 first: compilation, scene
upload or BVH build), the median of ``--repeats`` frames per level (the renderer's own frame time). The raw rows
(one per condition x scene x level, GT per scene) go to
``benchmarks/results/ladder_times_<protocol>_<backend>_<W>x<H>.csv``: the ``--frame-times`` CSV of ``studyapp
analyze`` (give it the same ``--cost-scale``).

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

Recovery and speed each run in their own child process (``harness.run_child``: its peak memory, wall time and the
load after it), as the ladder times do per condition x scene; their rows go to
``benchmarks/results/bench_thresholds.csv``. ``--smoke`` runs both parts over 3 and 1 participants.
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
    from studyapp.runner.threshold_study import run_procedure

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
        lo, hi = proc.credible_interval(0.95)
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
    from data_schema.intensity import grid

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


def ladder_one(protocol: str, cond: str, scene: str, backend: str, scale: float, repeats: int) -> dict:
    """The frame times of one condition's ladder (or the reference's one frame) on one scene, in this process."""
    import statistics

    from benchmarks.harness import gpu_device_line, machine_line
    from renderers import registry
    from studyapp.commands.study import _protocol
    from studyapp.runner.threshold_study import cost_size

    p = _protocol(protocol)
    w, h = cost_size(p, scale)
    c = p.conditions[cond]
    v = p.adaptive.varied.get(cond)
    ref, cam = p.scene_ref(scene), {"fov_y": p.display.fov_y_deg}
    machine = machine_line() + (" " + gpu_device_line() if backend == "gpu" else "")
    registry.render(ref, c.renderer, c.params, 64, 48, camera=cam, backend=backend)
    rows = []
    for level in (v.levels if v else [None]):
        params = {**c.params, v.param: level} if v else c.params
        ms = [1e3 * registry.render(ref, c.renderer, params, w, h, camera=cam, backend=backend)[1]["seconds"]["total"]
              for _ in range(repeats)]
        rows.append({"protocol": p.name, "backend": backend, "width": w, "height": h, "condition": cond,
                     "renderer": c.renderer, "param": v.param if v else "", "level": "" if level is None else level,
                     "scene": scene, "median_ms": statistics.median(ms), "repeats": repeats, "machine": machine})
    return {"rows": rows}


def ladder_times(protocol: str, backend: str, scale: float, repeats: int, argv: list[str]) -> tuple[list, list]:
    """The ladder rows of ``protocol`` (a child process per condition x scene) and the report's lines."""
    from benchmarks.harness import command_line, load_line, run_child, write_csv
    from studyapp.commands.study import _protocol

    protocol = os.path.abspath(protocol) if os.path.exists(protocol) else protocol  # the child runs in ROOT
    p = _protocol(protocol)
    if p.adaptive is None:
        raise SystemExit(f"bench_thresholds.py: {p.name} has no adaptive design: no ladder to time")
    rows, t0, load0 = [], time.perf_counter(), os.getloadavg()
    for scene in p.scenes:
        for cond in (p.adaptive.reference, *p.adaptive.varied):
            out = run_child([os.path.abspath(__file__), "--one-ladder", protocol, cond, scene, "--backend", backend,
                             "--scale", str(scale), "--repeats", str(repeats)], f"{cond} on {scene}")
            rows += [{**r, "peak_mb": round(out["peak_mb"], 1)} for r in out["rows"]]
            print(f"{cond} on {scene}: " + ", ".join(f"{r['median_ms']:,.0f}" for r in out["rows"]) + " ms",
                  file=sys.stderr, flush=True)
    w, h = rows[0]["width"], rows[0]["height"]
    name = f"ladder_times_{p.name}_{backend}_{w}x{h}.csv"
    write_csv(rows, name)
    lines = [f"## Ladder frame times: {p.name} on the {backend} backend at {w}x{h} (bench_thresholds.py)", "",
             f"`{command_line('benchmarks/bench_thresholds.py', argv)}` ({(time.perf_counter() - t0) / 60:.1f} min); "
             f"{rows[0]['machine']} Median of {repeats} frames per level after a 64x48 warm-up frame, one process "
             f"per condition x scene; raw rows: benchmarks/results/{name} (`studyapp analyze --frame-times`, "
             f"with `--cost-scale {scale:g}`). Load average (1, 5, 15 min): {load_line(load0, os.getloadavg())}; "
             "at a small --scale and under load the millisecond times are noisy.", "",
             "| condition | scene | parameter | levels | ms per frame at each level |",
             "|---|---|---|---|---|"]
    for scene in p.scenes:
        for cond in (p.adaptive.reference, *p.adaptive.varied):
            mine = [r for r in rows if r["condition"] == cond and r["scene"] == scene]
            lv = ", ".join(f"{r['level']:g}" for r in mine) if mine[0]["param"] else "-"
            lines.append(f"| {cond} | {scene} | {mine[0]['param'] or '-'} | {lv} | "
                         + ", ".join(f"{r['median_ms']:,.0f}" for r in mine) + " |")
    return rows, lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--participants", type=int, default=200)
    ap.add_argument("--speed-participants", type=int, default=25)
    ap.add_argument("--write", metavar="FILE", help="replace the thresholds section of this Markdown file")
    ap.add_argument("--ladder-times", metavar="PROTOCOL", help="time the ladders of this adaptive protocol (a file "
                    "or a shipped name) instead: the --frame-times CSV of studyapp analyze")
    ap.add_argument("--backend", choices=("cpu", "gpu"), default="cpu", help="ladder times: the backend")
    ap.add_argument("--scale", type=float, default=0.1, help="ladder times: the render size times this (default "
                    "0.1; 1 = the study's size)")
    ap.add_argument("--repeats", type=int, default=3, help="ladder times: frames per level (median)")
    ap.add_argument("--smoke", action="store_true", help="recovery over 3 participants and speed over 1: checks "
                    "that both parts run; their figures mean nothing")
    ap.add_argument("--one-ladder", nargs=3, metavar=("PROTOCOL", "COND", "SCENE"), help=argparse.SUPPRESS)
    ap.add_argument("--one", nargs=2, metavar=("PART", "N"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        from benchmarks.harness import print_row

        part, n = args.one[0], int(args.one[1])
        print_row({"lines": (recovery if part == "recovery" else speed)(n)})
        return 0
    if args.one_ladder:
        from benchmarks.harness import print_row

        print_row(ladder_one(*args.one_ladder, args.backend, args.scale, args.repeats))
        return 0
    if args.ladder_times:
        from benchmarks.harness import replace_section

        _, lines = ladder_times(args.ladder_times, args.backend, args.scale, args.repeats,
                                list(argv if argv is not None else sys.argv[1:]))
        print("\n".join(lines))
        if args.write:
            replace_section(args.write, "thresholds-ladder", lines)
        return 0
    from benchmarks.harness import command_line, load_line, machine_line, replace_section, write_csv

    if args.smoke:
        args.participants, args.speed_participants = 3, 1
    load0 = os.getloadavg()
    parts = recovery_and_speed(args.participants, args.speed_participants)
    name = f"bench_thresholds{'_smoke' if args.smoke else ''}.csv"
    write_csv([{k: v for k, v in r.items() if k != "lines"} for r in parts], name)
    lines = ["## Threshold studies: recovery, coverage and speed (bench_thresholds.py)", "",
             f"`{command_line('benchmarks/bench_thresholds.py', list(argv or sys.argv[1:]))}`; "
             f"{machine_line()} Recovery and speed each in its own child process (peak memory "
             + ", ".join(f"{r['part']} {r['peak_mb']:.0f} MB" for r in parts)
             + f"); load average {load_line(load0, os.getloadavg())}; raw rows: benchmarks/results/{name}.", ""]
    lines += parts[0]["lines"] + [""] + parts[1]["lines"]
    print("\n".join(lines))
    if args.write:
        replace_section(args.write, "thresholds", lines)
    return 0


def recovery_and_speed(participants: int, speed_participants: int) -> list[dict]:
    """The recovery and the speed parts, each in its own child process (its peak memory, wall time, load)."""
    from benchmarks.harness import run_child

    out = []
    for part, n in (("recovery", participants), ("speed", speed_participants)):
        r = run_child([os.path.abspath(__file__), "--one", part, str(n)], f"{part} ({n} participants)")
        out.append({"part": part, "participants": n, **r})
        print(f"{part}: peak {r['peak_mb']:.0f} MB, wall {r['wall_s']:.1f} s, load {r['load']:.1f}",
              file=sys.stderr, flush=True)
    return out


if __name__ == "__main__":
    sys.exit(main())
