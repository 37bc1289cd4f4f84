"""Where foveated stochastic lightcuts part from seed 003, measured: readings of Eq 4–8 × budget accountings.

Run:  .venv/bin/python benchmarks/bench_lightcuts_readings.py [--width 192 --height 108] [--gt-samples 1024]
      [--readings derived,blur,retained] [--budgets equal-time,equal-samples] [--views ...] [--repeats 2]
      [--smoke] [--write docs/benchmarks.md]

For every view (``VIEWS``: the four scenes' cameras and the Cornell box seen from inside with a 100° field),
every reading of Eq 4–8 (``fsl``'s ``fpsm_reading``) and every budget accounting (``tables.BUDGETS``) it runs
``renderers.lightcuts.tables.lightcut_tables`` (α = 0.1, no α sweep) and reports the three quantities on which
this implementation disagreed with the seed —

* ``sl_f_over_ours``: SL_f's cost over Ours' (frame time, or rays per frame under equal samples; seed 2.5–3.9),
* ``periphery_sl_e_over_ours``: SL_e's peripheral MSE over Ours' (seed 1.2–1.6, Table 1),
* ``multires``: Ours' over Ours (frame time, or light-tree traversals under equal samples; seed 1.3–1.4) —

whether each has the seed's direction (> 1) and reaches the seed's lower bound, and what explains them: Ours'
light samples per pixel in the fovea and the periphery, the share of its samples spent in the periphery, the
fraction of peripheral pixels left with one light sample and their share of Ours' peripheral squared error,
the share of glossy pixels that get no glossy ray (``rspp = ceil(map · MAX_rspp) = 0``), the fraction of samples
reused by multi-resolution selection, and the time per step (Fig 9) of Ours and SL_f. ``--variance-renders N``
(``--variance-only`` for just this) adds, per view, the best peripheral MSE ratio any allocation of the same
number of samples could reach against a uniform count: with per-pixel variance ``σ²`` of a one-sample
estimate (from ``N`` renders of SL at 1 light sample + 1 glossy ray, clipped to [0, 1]), the allocation
``n ∝ σ`` (Neyman) gives ``mean(σ²) / mean(σ)²``. GT comes from the
stimulus cache (``--cache``), rendered once per view. Writes ``lightcuts_readings.csv`` and
``lightcuts_readings.md`` to ``benchmarks/results/`` (not committed); ``--write`` puts the Markdown into the
``lightcuts-readings`` section of that file. Each view x reading x accounting, and each view's variance renders,
runs in its own child process (``harness.run_child``: its peak memory, wall time and the load after it, in the
CSV's ``peak_mb``, ``wall_s``, ``load``). ``--smoke`` runs one tiny configuration of each kind. The machine load
(``os.getloadavg``) is printed with the figures: frame times on a shared machine
vary, the sample counts and MSE do not (fixed seeds).
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.harness import (load_average, machine_line, print_row, replace_section,  # noqa: E402
                                results_path, run_child, write_csv)

#: view name -> (scene, camera overrides). "cornell_inside" is the Cornell box seen from just inside its open
#: front with a 100° vertical field, close to the seed's HMD field (its scenes are seen through an HTC Cosmos).
VIEWS = {
    "cornell_many": ("cornell_many", None),
    "cornell_inside": ("cornell_many", {"position": (278.0, 273.0, 30.0), "look_at": (278.0, 273.0, 559.0),
                                        "fov_y": 100.0}),
    "study": ("study", None),
    "yard": ("yard", None),
    "sponza_vpl": ("sponza_vpl", None),
}
STEP_COLUMNS = ("gbuffer", "low_res", "fpsm", "cuts", "select", "shade", "glossy")
ALPHA = 0.1


def _causes(records: list[dict], im: dict, regions, max_rspp: int) -> dict:
    """The quantities that explain the ratios (see the module docstring) from one run's records and images."""
    def get(table, method, metric, region="all"):
        return next((r["value"] for r in records if (r["table"], r["method"], r["metric"], r["region"])
                     == (table, method, metric, region)), float("nan"))

    spp = np.asarray(im["ours_spp"], dtype=np.float64)
    shaded = spp > 0  # pixels whose primary ray hit a surface (misses draw no light sample)
    per, fov = regions.periphery & shaded, regions.fovea & shaded
    err = np.mean((np.clip(im["ours"], 0, 1) - np.clip(im["gt"], 0, 1)) ** 2, axis=-1)
    one = per & (spp == 1)
    no_glossy = per & np.asarray(im["glossy"]) & (np.ceil(np.asarray(im["fpsm"]) * max_rspp - 1e-9) == 0)
    e_per = max(float(err[regions.periphery].sum()), 1e-300)
    n_full = max(float(spp.sum()), 1.0)
    out = {
        "ours_spp_fovea": float(spp[fov].mean()) if fov.any() else float("nan"),
        "ours_spp_periphery": float(spp[per].mean()) if per.any() else float("nan"),
        "periphery_sample_share": float(spp[per].sum() / n_full),
        "periphery_px_at_1": float(one.sum() / max(per.sum(), 1)),
        "periphery_err_share_at_1": float(err[one].sum() / e_per),
        "periphery_err_share_no_glossy_ray": float(err[no_glossy].sum() / e_per),
        "reused_share": float((get("3", "Ours", "light_samples") - get("3", "Ours", "traversals")) / n_full),
        "mse_periphery_ours": get("1", "Ours", "mse", "periphery"),
        "mse_periphery_sl_e": get("1", "SL_e", "mse", "periphery"),
        "sl_e_lspp": get("3", "SL_e", "lspp"), "sl_f_lspp": get("3", "SL_f", "lspp"),
        "ms_ours": get("3", "Ours", "ms"), "ms_ours_no_multires": get("3", "Ours'", "ms"),
        "ms_sl_f": get("3", "SL_f", "ms"),
        "select_gain": get("fig9", "Ours'", "ms_select") / max(get("fig9", "Ours", "ms_select"), 1e-9),
    }
    for method, key in (("Ours", "ours"), ("SL_f", "sl_f")):
        for step in STEP_COLUMNS:
            out[f"ms_{step}_{key}"] = get("fig9", method, f"ms_{step}")
    return out


def neyman_bound(scene, camera, width: int, height: int, renders: int, periphery) -> float:
    """``mean(σ²) / mean(σ)²`` over the periphery: SL_e / Ours peripheral MSE at equal samples for the best
    allocation (``n ∝ σ``); ``σ²`` from ``renders`` one-sample SL renders (clipped to [0, 1], seeds 0..)."""
    from renderers import registry

    imgs = np.array([np.clip(registry.render(scene, "sl", {"lspp": 1, "rspp": 1, "seed": s}, width, height,
                                             camera=camera)[0], 0, 1) for s in range(renders)], dtype=np.float64)
    var = imgs.var(axis=0, ddof=1).mean(axis=-1)[periphery]
    sd = np.sqrt(var)
    return float(var.mean() / sd.mean() ** 2) if sd.mean() > 0 else float("nan")


def variance_one(args, view: str) -> dict:
    """The Neyman bound of one view, in this process (``--one variance VIEW``)."""
    from analysis.quality import region_masks
    from renderers.catalog import resolve
    from renderers.lightcuts.scenes import SCENES

    scene_name, camera = VIEWS[view]
    scene = SCENES[scene_name]()
    cam = resolve(scene).camera.override(camera)
    periphery = region_masks(args.width, args.height, cam.fov_y, None, 5.0).periphery
    return {"view": view, "bound": neyman_bound(scene, camera, args.width, args.height, args.variance_renders,
                                                periphery)}


def table_one(args, view: str, reading: str, budget: str) -> dict:
    """One view x reading x budget accounting, in this process (``--one table VIEW READING BUDGET``)."""
    from analysis.quality import region_masks
    from renderers.catalog import resolve
    from renderers.lightcuts.scenes import SCENES
    from renderers.lightcuts.tables import lightcut_tables, summary_ratios

    scene_name, camera = VIEWS[view]
    scene = SCENES[scene_name]()
    cam = resolve(scene).camera.override(camera)
    regions = region_masks(args.width, args.height, cam.fov_y, None, 5.0)
    t0 = time.perf_counter()
    im: dict = {}
    rec = lightcut_tables(scene, args.width, args.height, alphas=(), alpha=ALPHA,
                          gt_lspp=args.gt_samples, gt_rspp=args.gt_samples, seed=args.seed,
                          camera=camera, images=im, cache_dir=args.cache, fpsm_reading=reading,
                          budget=budget, repeats=args.repeats)
    r = summary_ratios(rec, budget)
    return {"view": view, "reading": reading, "budget": budget,
            "sl_f_over_ours": r["speedup_vs_sl_f"],
            "periphery_sl_e_over_ours": r["peripheral_mse_sl_e_over_ours"],
            "multires": r["multires_speedup"], "fovea_sl_e_over_ours": r["foveal_mse_sl_e_over_ours"],
            **_causes(rec, im, regions, 48), "seconds": time.perf_counter() - t0}


def _child(args, one: list[str], label: str) -> dict:
    """``--one ...`` of this script with this run's options, in its own child process (``harness.run_child``:
    its peak memory, wall time and the load after it)."""
    opts = ["--width", str(args.width), "--height", str(args.height), "--gt-samples", str(args.gt_samples),
            "--seed", str(args.seed), "--repeats", str(args.repeats), "--cache", os.path.abspath(args.cache),
            "--variance-renders", str(args.variance_renders)]
    return run_child([os.path.abspath(__file__), *opts, "--one", *one], label)


def run_variance(args) -> dict:
    """The Neyman bound per view, one child process per view."""
    out = {}
    for view in args.views:
        r = _child(args, ["variance", view], f"variance {view}")
        out[view] = r["bound"]
        print(f"{view}: Neyman bound {out[view]:.2f} (peak {r['peak_mb']:.0f} MB, {r['wall_s']:.0f} s)",
              file=sys.stderr, flush=True)
    return out


def run(args) -> list[dict]:
    """Every view x reading x budget accounting, one child process each."""
    rows = []
    for view in args.views:
        for reading in args.readings:
            for budget in args.budgets:
                row = _child(args, ["table", view, reading, budget], f"{view} {reading} {budget}")
                rows.append(row)
                print(f"{view} {reading} {budget}: SL_f/Ours {row['sl_f_over_ours']:.2f}, periphery SL_e/Ours "
                      f"{row['periphery_sl_e_over_ours']:.2f}, multi-res {row['multires']:.2f} "
                      f"({row['seconds']:.0f} s, peak {row['peak_mb']:.0f} MB, load {row['load']:.1f})",
                      file=sys.stderr, flush=True)
    return rows


def _seed_low() -> dict:
    """Ratio -> the seed's lower bound (``tables.SEED_RATIOS``; the direction is "> 1")."""
    from renderers.lightcuts.tables import SEED_RATIOS

    return {"sl_f_over_ours": SEED_RATIOS["speedup_vs_sl_f"][0],
            "periphery_sl_e_over_ours": SEED_RATIOS["peripheral_mse_sl_e_over_ours"][0],
            "multires": SEED_RATIOS["multires_speedup"][0]}


def _mark(v: float, low: float) -> str:
    """✓✓ reaches the seed's lower bound, ✓ has its direction (> 1), ✗ neither."""
    if not np.isfinite(v):
        return "n/a"
    return f"{v:.2f} {'✓✓' if v >= low else '✓' if v > 1 else '✗'}"


def markdown(rows: list[dict], args, load: tuple[float, float], bounds: dict) -> list[str]:
    low = _seed_low()
    lines = ["## Readings of Eq 4–8 × budget accountings (`benchmarks/bench_lightcuts_readings.py`)", "",
             machine_line() + f" {args.width}×{args.height}, α = {ALPHA}, GT {args.gt_samples} light + "
             f"{args.gt_samples} glossy samples per pixel, seed {args.seed}, Table 3 times the minimum of "
             f"{args.repeats} renders; load average {load[0]:.1f} at the start, {load[1]:.1f} at the end "
             f"(2 shared cores); one child process per row, peak memory up to "
             f"{max(r.get('peak_mb', float('nan')) for r in rows):.0f} MB.", "",
             "Ratios > 1 have the seed's direction (✓), ✓✓ reach the seed's lower bound (SL_f / Ours ≥ 2.5, "
             "peripheral MSE SL_e / Ours ≥ 1.2, multi-resolution gain ≥ 1.3). Equal time: SL_e renders in Ours' "
             "frame time, cost = frame time. Equal samples: SL_e draws Ours' light samples and glossy rays per "
             "pixel, cost = rays per frame, multi-res gain = light-tree traversals saved.", "",
             "| view | reading | budget | SL_f / Ours | periphery SL_e / Ours | multi-res | SL_e lspp | SL_f lspp |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['view']} | {r['reading']} | {r['budget']} | "
                     f"{_mark(r['sl_f_over_ours'], low['sl_f_over_ours'])} | "
                     f"{_mark(r['periphery_sl_e_over_ours'], low['periphery_sl_e_over_ours'])} | "
                     f"{_mark(r['multires'], low['multires'])} | {r['sl_e_lspp']:.0f} | {r['sl_f_lspp']:.0f} |")
    lines += ["", "What the readings do (first accounting's run; the map does not depend on the accounting). Samples "
              "per pixel over the pixels that hit a surface; the shares of Ours' peripheral squared error overlap "
              "(a glossy pixel without glossy ray also has one light sample); selection gain = Ours' / Ours time "
              "of the selection step (seed Fig 9: 4.4×); Ours ms = its frame time in the runs of each accounting "
              "(the same render: the spread is the timing noise of the shared machine).", "",
              "| view | reading | Ours spp fovea / periphery | samples in periphery | periphery px at 1 sample | "
              "their share of Ours' peripheral error | share in glossy px without glossy ray | samples reused | "
              "selection gain | Ours ms |", "|---|---|---|---|---|---|---|---|---|---|"]
    ms_runs: dict = {}
    for r in rows:
        ms_runs.setdefault((r["view"], r["reading"]), []).append(f"{r['ms_ours']:.0f}")
    for r in rows:
        if r["budget"] != args.budgets[0]:
            continue
        lines.append(f"| {r['view']} | {r['reading']} | {r['ours_spp_fovea']:.1f} / {r['ours_spp_periphery']:.1f} | "
                     f"{r['periphery_sample_share']:.0%} | {r['periphery_px_at_1']:.0%} | "
                     f"{r['periphery_err_share_at_1']:.0%} | {r['periphery_err_share_no_glossy_ray']:.0%} | "
                     f"{r['reused_share']:.0%} | {r['select_gain']:.2f} | "
                     f"{', '.join(ms_runs[(r['view'], r['reading'])])} |")
    if bounds:
        lines += ["", f"Best possible peripheral MSE ratio SL_e / Ours at equal samples (allocation ∝ σ, σ² from "
                  f"{args.variance_renders} one-sample renders): "
                  + ", ".join(f"{v} {b:.2f}" for v, b in bounds.items())]
    lines += ["", "Where the time goes (ms per step, Fig 9; first reading, equal time): Ours / SL_f", "",
              "| view | " + " | ".join(STEP_COLUMNS) + " | frame |", "|---|" + "---|" * (len(STEP_COLUMNS) + 1)]
    for r in rows:
        if r["budget"] != args.budgets[0] or r["reading"] != args.readings[0]:
            continue
        cells = [f"{r[f'ms_{s}_ours']:.0f} / {r[f'ms_{s}_sl_f']:.0f}" if np.isfinite(r[f"ms_{s}_sl_f"])
                 else f"{r[f'ms_{s}_ours']:.0f} / –" for s in STEP_COLUMNS]
        lines.append(f"| {r['view']} | " + " | ".join(cells) + f" | {r['ms_ours']:.0f} / {r['ms_sl_f']:.0f} |")
    lines += ["", "Reproduce: `PYTHONPATH=. .venv/bin/python benchmarks/bench_lightcuts_readings.py "
              f"--width {args.width} --height {args.height} --gt-samples {args.gt_samples} "
              f"--repeats {args.repeats}` (raw rows: `benchmarks/results/lightcuts_readings.csv`)"]
    return lines


def main(argv=None) -> int:
    from renderers.lightcuts.options import BUDGETS, FPSM_READINGS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=192)
    ap.add_argument("--height", type=int, default=108)
    ap.add_argument("--gt-samples", type=int, default=1024)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeats", type=int, default=2, help="renders per Table 3 time (the minimum is kept)")
    ap.add_argument("--views", default=",".join(VIEWS))
    ap.add_argument("--readings", default=",".join(FPSM_READINGS))
    ap.add_argument("--budgets", default=",".join(BUDGETS))
    ap.add_argument("--cache", default="stimulus_cache", help="stimulus cache for the GT renders")
    ap.add_argument("--variance-renders", type=int, default=16, metavar="N",
                    help="one-sample renders per view for the Neyman bound (0: skip)")
    ap.add_argument("--variance-only", action="store_true", help="only the Neyman bound per view")
    ap.add_argument("--from-csv", metavar="CSV", help="report the rows of an earlier run's CSV instead of measuring "
                    "(pass that run's --width/--height/--gt-samples/--repeats/--seed)")
    ap.add_argument("--smoke", action="store_true", help="tiny: cornell_many at 32x18, GT 4 samples, the first "
                    "reading and accounting, 2 variance renders, one repeat (checks that it runs; figures mean "
                    "nothing)")
    ap.add_argument("--write", metavar="MD", help="write the 'lightcuts-readings' section into this Markdown file")
    ap.add_argument("--one", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.smoke:
        args.width, args.height, args.gt_samples, args.repeats, args.variance_renders = 32, 18, 4, 1, 2
        args.views, args.readings, args.budgets = ("cornell_many", FPSM_READINGS[0], BUDGETS[0])
        if args.cache == ap.get_default("cache"):  # its tiny GT renders stay out of the stimulus cache
            args.cache = results_path("smoke_cache")
    for name, allowed in (("views", VIEWS), ("readings", FPSM_READINGS), ("budgets", BUDGETS)):
        values = [v.strip() for v in getattr(args, name).split(",") if v.strip()]
        bad = [v for v in values if v not in allowed]
        if bad or not values:
            ap.error(f"--{name}: {bad[0] if bad else '(none)'!r} is unknown: allowed {', '.join(allowed)}")
        setattr(args, name, values)
    if args.variance_renders == 1 or args.variance_renders < 0:
        ap.error("--variance-renders: must be 0 or >= 2")
    if args.one:
        kind, *rest = args.one
        print_row(variance_one(args, *rest) if kind == "variance" else table_one(args, *rest))
        return 0
    load0 = load_average()[0]
    bounds = run_variance(args) if args.variance_renders else {}
    if args.variance_only:
        print("\n".join(f"{v}: {b:.3f}" for v, b in bounds.items()))
        return 0
    if args.from_csv:
        with open(args.from_csv, encoding="utf-8", newline="") as f:
            rows = [{k: (v if k in ("view", "reading", "budget") else float(v)) for k, v in r.items()}
                    for r in csv.DictReader(f)]
        keep = set(args.views) & {r["view"] for r in rows}
        rows = [r for r in rows if r["view"] in keep]
        args.readings = list(dict.fromkeys(r["reading"] for r in rows))
        args.budgets = list(dict.fromkeys(r["budget"] for r in rows))
        load = (rows[0]["load"], rows[-1]["load"])
    else:
        rows = run(args)
        load = (load0, load_average()[0])
    lines = markdown(rows, args, load, bounds)
    print("\n".join(lines))
    if not args.from_csv:
        from data_schema.atomic import write_text

        write_csv(rows, "lightcuts_readings.csv")
        write_text(results_path("lightcuts_readings.md"), "\n".join(lines) + "\n")
    if args.write:
        replace_section(args.write, "lightcuts-readings", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
