"""Benchmark of the lightcuts renderers on the GPU backend (issue 16 items 1 and 3): agreement with the CPU
versions, and speed.

``--agreement``: cornell_many at 160 x 90 (the scene camera, gaze at the centre), seeds 0-31, every method
(``fsl``, ``fsl`` without multi-resolution selection, ``sl_e`` / ``sl_f`` / ``sl_p`` with the uniform counts of
:data:`METHODS`, ``sl_as``, ``sl_gt`` with ``--agreement-gt-samples`` light + glossy samples) on both backends with
the same seeds, and on the GPU with 32 other seeds. Per pixel over the seeds
(:func:`renderers.gpu.agreement.seed_agreement`): the share of pixels whose means agree within 4 standard errors,
and whose variance ratio GPU / CPU lies in [0.8, 1.25]. Writes section ``gpu-lightcuts-agreement`` of
``docs/benchmarks.md`` and the raw rows to ``benchmarks/results/bench_gpu_lightcuts_agreement.csv``.

Speed (default): milliseconds per frame of every method on every scene at 1280x720 and 2160x2160 (one eye: the
lightcuts renderers are monocular; a binocular frame is two), medians of ``--repeats`` frames after a first
full-size frame (one frame when it took over a minute), each configuration in its own process with
its peak memory (:func:`benchmarks.harness.run_child`); the GPU / CPU time ratio of every method on cornell_many at
the ``--ratio-size`` sizes (default 320x180; a speed size too: then the CPU frame follows each GPU one) in the
same run. ``--repeats`` is one count or one per size. Runs unchanged on a machine with a GPU (EGL, no display).
Writes section ``gpu-lightcuts`` of ``docs/benchmarks.md`` and ``benchmarks/results/bench_gpu_lightcuts.csv`` (the
raw rows; ``--section`` names both), rewritten after every configuration (a run stopped early leaves what it measured, and names what it did not).

``--gt-model PASSES,CHUNKS``: sl_gt alone. Its seed-size frames (2048 + 2048 samples: 43 light passes, 256 glossy
dispatches) take hours on llvmpipe, longer than a working session; each configuration renders a frame of PASSES
passes and CHUNKS dispatches and predicts the whole frame from its step times (:func:`gt_frame_ms`), checked against
the whole frames that the speed sections' raw rows in ``benchmarks/results/`` hold (:func:`whole_gt_frames`).

    python benchmarks/bench_gpu_lightcuts.py --agreement      # ~20 min on 2 cores with llvmpipe
    python benchmarks/bench_gpu_lightcuts.py                  # every method, scene and size (GT: --gt-samples)
    python benchmarks/bench_gpu_lightcuts.py --sizes 1280x720 --scenes cornell_many --methods fsl,sl_e
    python benchmarks/bench_gpu_lightcuts.py --scenes cornell_many --repeats 3,1 --ratio-size 1280x720,2160x2160
    python benchmarks/bench_gpu_lightcuts.py --gt-model 2,16 --repeats 1 --section gpu-lightcuts-gt-model
"""

from __future__ import annotations

import argparse
import csv
import glob
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.harness import (  # noqa: E402
    DOC, LLVMPIPE_NOTE, RESULTS, command_line, gpu_device_line, machine_line, print_row, replace_section,
    results_ref, run_child, timed_frames, write_csv)

SCENES = ("cornell_many", "study", "yard", "sponza_vpl")
SIZES = ("1280x720", "2160x2160")
#: Every method with the counts it is measured with: SL_e about Ours' mean samples per pixel (seed 003 Table 2:
#: 5-10), SL_f / SL_p the uniform counts of equal foveal / peripheral MSE of the tables (docs/lightcuts.md:
#: 36-48 and 3-6); sl_gt's samples are --gt-samples.
METHODS = {
    "fsl": ("fsl", {}),
    "fsl'": ("fsl", {"multires": False}),
    "sl_e": ("sl_e", {"lspp": 8, "rspp": 8}),
    "sl_f": ("sl_f", {"lspp": 40, "rspp": 40}),
    "sl_p": ("sl_p", {"lspp": 5, "rspp": 5}),
    "sl_as": ("sl_as", {}),
    "sl_gt": ("sl_gt", {}),
}
STEPS = ("gbuffer", "low_res", "fpsm", "cuts", "select", "shade", "glossy")
RATIO_SIZE = "320x180"
AGREEMENT_SIZE = (160, 90)
AGREEMENT_SEEDS = 32
OTHER_SEEDS = 1000  # the GPU's independent streams: seeds 1000-1031


def _params(method: str, gt_samples: int, seed: int | None = None) -> tuple[str, dict]:
    name, params = METHODS[method]
    if name == "sl_gt":
        params = {"lspp": gt_samples, "rspp": gt_samples}
    return name, params if seed is None else {**params, "seed": seed}


# -- agreement -----------------------------------------------------------------------------------------------------
def agreement_rows(methods, gt_samples: int, seeds: int = AGREEMENT_SEEDS, progress=print) -> list[dict]:
    """:func:`~renderers.gpu.agreement.seed_agreement` of each method, same seeds and other seeds."""
    from scipy import stats

    from renderers import registry
    from renderers.gpu.agreement import seed_agreement

    W, H = AGREEMENT_SIZE
    f_range = float(stats.f.cdf(1.25, seeds - 1, seeds - 1) - stats.f.cdf(0.8, seeds - 1, seeds - 1))
    rows = []
    for method in methods:
        t0 = time.perf_counter()

        def stack(backend, first):
            return np.stack([registry.render("cornell_many", *_params(method, gt_samples, first + s), W, H,
                                             backend=backend)[0] for s in range(seeds)])

        cpu = stack("cpu", 0)
        t1 = time.perf_counter()
        gpu = stack("gpu", 0)
        t2 = time.perf_counter()
        same, other = seed_agreement(cpu, gpu), seed_agreement(cpu, stack("gpu", OTHER_SEEDS))
        row = {"method": method, "params": json.dumps(_params(method, gt_samples)[1]), "width": W, "height": H,
               **{f"same_{k}": v for k, v in same.items()}, **{f"other_{k}": v for k, v in other.items()},
               "f_expected_within": f_range, "cpu_s": t1 - t0, "gpu_s": t2 - t1}
        rows.append(row)
        progress(f"{method}: same seeds {100 * same['means_within']:.2f} % means within 4 SE, "
                 f"{100 * same['ratio_within']:.2f} % variance ratios in [0.8, 1.25]; other seeds "
                 f"{100 * other['means_within']:.2f} % means ({time.perf_counter() - t0:.0f} s)")
    return rows


def agreement_section(rows, elapsed: float, gt_samples: int, command: str) -> list[str]:
    n, (W, H) = rows[0]["same_seeds"], AGREEMENT_SIZE
    lines = [
        "## Lightcuts on the GPU backend against the CPU backend (issue 16 item 1)", "",
        machine_line(), gpu_device_line(),
        f"Command: `{command}` ({elapsed / 60:.1f} min). cornell_many "
        f"at {W}x{H} (scene camera, gaze at the centre), seeds 0-{n - 1} on both backends; sl_gt with "
        f"{gt_samples} + {gt_samples} samples. Per pixel and channel over the {n} seeds: the means agree when "
        "they differ by at most 4 standard errors sqrt((s_cpu^2 + s_gpu^2) / n); the variance ratio s_gpu^2 / "
        "s_cpu^2 should lie in [0.8, 1.25]; a pixel passes when its three channels do (pixels where both backends "
        "give the same value for every seed, the background, are left out of the variance ratio). Targets: "
        ">= 95 % of the pixels for both.", "",
        "The GPU draws the CPU's random numbers (the counter-based generator, seed x pixel x slot), so seed for seed "
        "both backends take the same samples up to float32 rounding: the first columns. With independent streams "
        f"(GPU seeds {OTHER_SEEDS}-{OTHER_SEEDS + n - 1}, last columns) the means must still agree (the same "
        f"expectation), while a per-pixel variance ratio of two independent {n}-sample variances scatters: for "
        "normal samples with equal variances it lies in [0.8, 1.25] for only "
        f"{100 * rows[0]['f_expected_within']:.0f} % of the channels (F({n - 1}, {n - 1}) distribution), so the "
        "ratio criterion can only be met with shared streams; the independent columns show the ratio's median "
        "and its per-channel share against that expectation.", "",
        "| method | params | same seeds: means within 4 SE | variance ratio in [0.8, 1.25] | median ratio | "
        "other seeds: means within 4 SE | median ratio | ratio in range per channel (F expects) | lit pixels | "
        "CPU s | GPU s |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['method']} | `{r['params']}` | {100 * r['same_means_within']:.2f} % | "
                     f"{100 * r['same_ratio_within']:.2f} % | {r['same_median_ratio']:.4f} | "
                     f"{100 * r['other_means_within']:.2f} % | {r['other_median_ratio']:.3f} | "
                     f"{100 * r['other_ratio_within_channels']:.1f} % ({100 * r['f_expected_within']:.1f} %) | "
                     f"{r['same_pixels'] - r['same_deterministic']:,} | {r['cpu_s']:.0f} | {r['gpu_s']:.0f} |")
    return lines


# -- speed ---------------------------------------------------------------------------------------------------------
def measure_one(backend: str, scene: str, method: str, size: str, repeats: int, gt_samples: int,
                gt_model: tuple[int, int] | None = None) -> dict:
    """Frame times of one configuration in this process (:func:`benchmarks.harness.timed_frames`), medians. With
    ``gt_model`` (sl_gt only), a frame of that many light passes and glossy chunks, and the frame of
    ``gt_samples`` predicted from it (:func:`gt_model_row`)."""
    name, params = _params(method, gt_samples)
    if gt_model:
        params = gt_model_params(*gt_model)
    frames = timed_frames(backend, scene, name, params, size, repeats)
    med = lambda get: float(np.median([get(f) for f in frames]))  # noqa: E731
    row = {"backend": backend, "scene": scene, "method": method, "size": size, "frames": len(frames),
            "params": json.dumps(params), "total_ms": 1e3 * med(lambda f: f["seconds"]["total"]),
            **{f"{s}_ms": 1e3 * med(lambda f: f["steps"].get(s, 0.0)) for s in STEPS},
            "light_samples": frames[0]["light_samples"], "glossy_rays": frames[0]["glossy_rays"],
            "rays_shadow": frames[0]["rays_shadow"], "device": frames[0].get("gpu", {}).get("renderer", "cpu"),
            "timing": frames[0].get("gpu", {}).get("timing", "wall clock")}
    return gt_model_row(row, *gt_model, gt_samples) if gt_model else row


# -- sl_gt's frame from a few of its passes ------------------------------------------------------------------------
def gt_units() -> tuple[int, int]:
    """sl_gt's nodes per light pass (its default ``max_lspp``) and ray slots per glossy dispatch on the GPU
    (:func:`renderers.gpu.lightcuts.run_sl_gt`: ``ceil(lspp / max_lspp)`` passes of ``max_lspp`` nodes; the glossy
    pass in dispatches of ``GLOSSY_CHUNK`` slots)."""
    from renderers.gpu.lightcuts import GLOSSY_CHUNK
    from renderers.lightcuts.plugin import SL_GT

    return SL_GT.params["max_lspp"].default, GLOSSY_CHUNK


def gt_passes(lspp: int, rspp: int) -> tuple[int, int]:
    """sl_gt's light passes and glossy dispatches for ``lspp`` light + ``rspp`` glossy samples per pixel."""
    nodes, slots = gt_units()
    return -(-int(lspp) // nodes), -(-int(rspp) // slots)


def gt_model_params(passes: int, chunks: int) -> dict:
    """sl_gt's params for a frame of ``passes`` light passes and ``chunks`` glossy dispatches."""
    nodes, slots = gt_units()
    return {"lspp": passes * nodes, "rspp": chunks * slots}


def gt_pass_ms(row: dict) -> float:
    """The light passes' steps of an sl_gt frame (select + shade; the cuts are refined once for all passes)."""
    return row["select_ms"] + row["shade_ms"]


def gt_frame_ms(row: dict, passes: int, chunks: int, full_passes: int, full_chunks: int) -> float:
    """The time of sl_gt's frame of ``full_passes`` light passes and ``full_chunks`` glossy dispatches, predicted
    from ``row``, a frame of the same scene and size with ``passes`` and ``chunks``: its light-pass steps (select,
    shade) times ``full_passes / passes``, its glossy step times ``full_chunks / chunks``, the rest (G-buffer, the
    cuts, refined once for all passes, read-back) as measured. Every light pass samples the same cuts of the same
    pixels with other random numbers, and every glossy dispatch covers every pixel for ``GLOSSY_CHUNK`` ray slots,
    so the work grows linearly in both; the prediction is checked against whole frames where they were measured
    (:func:`model_section`)."""
    light = gt_pass_ms(row)
    return row["total_ms"] + light * (full_passes / passes - 1) + row["glossy_ms"] * (full_chunks / chunks - 1)


def gt_model_row(row: dict, passes: int, chunks: int, gt_samples: int) -> dict:
    """``row`` with the prediction of sl_gt's frame of ``gt_samples`` + ``gt_samples`` samples."""
    full_passes, full_chunks = gt_passes(gt_samples, gt_samples)
    return {**row, "passes": passes, "chunks": chunks, "full_passes": full_passes, "full_chunks": full_chunks,
            "predicted_ms": gt_frame_ms(row, passes, chunks, full_passes, full_chunks),
            "predicted_light_samples": row["light_samples"] * full_passes // passes}


def whole_gt_frames(gt_samples: int, folder: str = RESULTS) -> dict:
    """The whole sl_gt frames of ``gt_samples`` + ``gt_samples`` samples measured on the GPU in the speed sections'
    raw rows (``benchmarks/results/bench_gpu_lightcuts*.csv``, ``folder``): ``{(scene, size): row}``."""
    found = {}
    for path in sorted(glob.glob(os.path.join(folder, "bench_gpu_lightcuts*.csv"))):
        with open(path, newline="") as fh:
            for r in csv.DictReader(fh):
                if (r.get("method") == "sl_gt" and r.get("backend") == "gpu" and "predicted_ms" not in r
                        and json.loads(r.get("params") or "{}") == {"lspp": gt_samples, "rspp": gt_samples}):
                    found[(r["scene"], r["size"])] = {**r, "file": os.path.basename(path)}
    return found


def model_section(rows, plan, elapsed: float, gt_samples: int, command: str, model: tuple[int, int],
                  whole: dict) -> list[str]:
    """The section of sl_gt's frames predicted from ``model`` (light passes, glossy dispatches), checked against
    ``whole`` frames (:func:`whole_gt_frames`)."""
    passes, chunks = model
    scenes = list(dict.fromkeys(sc for _, sc, _, _, _ in plan))
    full_passes, full_chunks = gt_passes(gt_samples, gt_samples)
    nodes, slots = gt_units()
    lines = [
        f"## Lightcuts on the GPU backend: sl_gt's frame predicted from {passes} light pass(es) and {chunks} glossy "
        f"dispatch(es) on {', '.join(scenes)} (issue 16 item 3)", "",
        machine_line(), gpu_device_line(),
        f"Command: `{command}` ({elapsed / 60:.1f} min). sl_gt with {gt_samples} + {gt_samples} samples (the "
        f"seed's counts) is {full_passes} light passes of {nodes} nodes and {full_chunks} glossy dispatches of "
        f"{slots} ray slots; on llvmpipe a 2160x2160 frame takes hours. Each row is one frame of "
        f"{passes} pass(es) and {chunks} dispatch(es) (scene camera, gaze at the centre, one eye, after an untimed "
        "64x48 frame), and the whole frame predicted from its step times: light-pass steps (select + shade; the "
        f"cuts are refined once for all passes) x {full_passes} / {passes}, glossy x {full_chunks} / {chunks}, "
        "the rest as measured "
        "(`bench_gpu_lightcuts.gt_frame_ms`: each pass repeats the same sampling with other random numbers). "
        "`whole frame`: the same frame measured whole, where a speed section has it; the ratio checks the "
        "prediction.", "", LLVMPIPE_NOTE, "",
        "| scene | size | measured ms | light | glossy | predicted frame ms | predicted min | light samples "
        "(predicted) | whole frame ms | predicted / whole | peak MB | load |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        w = whole.get((r["scene"], r["size"]))
        check = (f"{float(w['total_ms']):,.0f} | {r['predicted_ms'] / float(w['total_ms']):.3f}" if w
                 else "not measured | -")
        lines.append(f"| {r['scene']} | {r['size']} | {r['total_ms']:,.0f} | {gt_pass_ms(r):,.0f} | "
                     f"{r['glossy_ms']:,.0f} | {r['predicted_ms']:,.0f} | {r['predicted_ms'] / 60e3:.1f} | "
                     f"{r['predicted_light_samples']:,} | {check} | {r['peak_mb']:,.0f} | {r['load']:.1f} |")
    sources = sorted({w["file"] for w in whole.values()})
    if sources:
        lines += ["", f"Whole frames from: {', '.join(f'`{results_ref(f)}`' for f in sources)} (raw rows, not "
                  "committed)."]
    return lines + _not_measured(rows, plan, lambda b, sc, m, z: f"{sc} {z}")


def _sizes(text: str) -> list[str]:
    return [z for z in text.split(",") if z]


def speed_plan(scenes, methods, sizes, repeats, ratio_sizes) -> list[tuple[str, str, str, str, int]]:
    """(backend, scene, method, size, repeats) in the order they run: per size, every scene and method on the GPU,
    each followed by the CPU on cornell_many when the size is a ratio size (so the ratios are complete as they
    come); then the ratio sizes that are not speed sizes, GPU and CPU per method. ``repeats`` is one count or one
    per size (ratio sizes that are not speed sizes take the first)."""
    reps = dict(zip(sizes, repeats)) if len(repeats) == len(sizes) else {z: repeats[0] for z in sizes}
    plan = []
    for size in sizes:
        for scene in scenes:
            for method in methods:
                plan.append(("gpu", scene, method, size, reps[size]))
                if scene == "cornell_many" and size in ratio_sizes:
                    plan.append(("cpu", scene, method, size, reps[size]))
    for size in ratio_sizes:
        if size not in sizes:
            plan += [(b, "cornell_many", m, size, repeats[0]) for m in methods for b in ("gpu", "cpu")]
    return plan


def speed_rows(plan, gt_samples: int, progress=print, done=None, gt_model: str = "") -> list[dict]:
    """Each configuration of ``plan`` in its own process (``gt_model``: ``--gt-model`` passed on); ``done(rows)``
    after each (the section is rewritten as the run goes, so a run stopped early leaves what it measured). A
    configuration that fails is one line and no row."""
    rows = []
    for backend, scene, method, size, repeats in plan:
        label = f"{backend} {scene} {method} {size}"
        try:
            r = run_child([os.path.abspath(__file__), "--one", backend, scene, method, size, "--repeats",
                           str(repeats), "--gt-samples", str(gt_samples)]
                          + (["--gt-model", gt_model] if gt_model else []), label)
        except RuntimeError as exc:
            progress(f"{label}: failed: {str(exc).splitlines()[-1]}")
            continue
        rows.append(r)
        progress(f"{label}: {r['total_ms']:,.0f} ms/frame ({r['frames']} frames), peak {r['peak_mb']:,.0f} MB, "
                 f"load {r['load']:.1f}")
        if done:
            done(rows)
    return rows


def speed_section(rows, plan, elapsed: float, gt_samples: int, command: str) -> list[str]:
    gpu = [r for r in rows if r["backend"] == "gpu"]
    timing = gpu[0]["timing"] if gpu else ""
    reps = sorted({(z, n) for _, _, _, z, n in plan}, key=lambda t: [int(v) for v in t[0].split("x")])
    scenes = list(dict.fromkeys(sc for _, sc, _, _, _ in plan))
    methods = list(dict.fromkeys(m for _, _, m, _, _ in plan))
    counts = [f"{m} `{json.dumps(METHODS[m][1])}`" for m in methods if m in METHODS and METHODS[m][1]]
    if "sl_gt" in methods:
        counts.append(f"sl_gt {gt_samples} + {gt_samples} samples (the seed: 2048 + 2048)")
    counts = "; ".join(counts) or "the methods' defaults"
    lines = [  # the title names what the section covers: a long run may be split into sections (--section)
        f"## Lightcuts on the GPU backend: speed of {', '.join(methods)} on {', '.join(scenes)} (issue 16 item 3)",
        "",
        machine_line(), gpu_device_line(),
        f"Command: `{command}` ({elapsed / 60:.1f} min). "
        "Scene cameras, gaze at the centre, one eye (the lightcuts renderers are monocular: a binocular frame is "
        "two); after an untimed 64x48 frame and a first full-size frame, the median of "
        f"{', '.join(f'{n} frame(s) at {z}' for z, n in reps)} (one frame, `frames` = 1, when the first full-size "
        "frame took over a minute); each configuration in its own process. Counts: "
        f"{counts}. Step times: {timing}.", "",
        LLVMPIPE_NOTE, "",
        "| scene | size | method | frame ms | " + " | ".join(STEPS) + " | light samples | glossy rays | "
        "peak MB | frames | load |",
        "|---|---|---|---:|" + "---:|" * len(STEPS) + "---:|---:|---:|---:|---:|"]
    for r in gpu:
        lines.append(f"| {r['scene']} | {r['size']} | {r['method']} | {r['total_ms']:,.0f} | "
                     + " | ".join(f"{r[s + '_ms']:,.0f}" for s in STEPS)
                     + f" | {r['light_samples']:,} | {r['glossy_rays']:,} | {r['peak_mb']:,.0f} | {r['frames']} | "
                     f"{r['load']:.1f} |")
    pairs = {(r["method"], r["size"], r["backend"]): r for r in rows if r["scene"] == "cornell_many"}
    ratio = [(m, z) for b, sc, m, z, _ in plan if b == "cpu"]
    if ratio:
        lines += ["", "GPU / CPU time ratio on cornell_many, same run (medians; CPU: the numba + Embree backend "
                  "on the same cores):", "",
                  "| size | method | GPU ms | CPU ms | GPU / CPU | frames GPU / CPU |", "|---|---|---:|---:|---:|---:|"]
        for m, z in ratio:
            g, c = pairs.get((m, z, "gpu")), pairs.get((m, z, "cpu"))
            if g and c:
                lines.append(f"| {z} | {m} | {g['total_ms']:,.0f} | {c['total_ms']:,.0f} | "
                             f"{g['total_ms'] / c['total_ms']:.2f} | {g['frames']} / {c['frames']} |")
    return lines + _not_measured(rows, plan, lambda b, sc, m, z: f"{b} {sc} {m} {z}")


def _not_measured(rows, plan, label) -> list[str]:
    """The line naming the configurations of ``plan`` with no row (a run stopped early or a failed one), each as
    ``label(backend, scene, method, size)``; none when all ran."""
    measured = {(r["backend"], r["scene"], r["method"], r["size"]) for r in rows}
    missing = [label(*c[:4]) for c in plan if tuple(c[:4]) not in measured]
    return ["", f"Not measured in this run (stopped or failed before they ran): {'; '.join(missing)}."] if missing \
        else []


#: Options: (flag, type, default, help).
OPTIONS = (
    ("--agreement-gt-samples", int, 256, "agreement: sl_gt's samples"),
    ("--seeds", int, AGREEMENT_SEEDS, "agreement: seeds per backend"),
    ("--methods", str, ",".join(METHODS), "methods (comma-separated)"),
    ("--scenes", str, ",".join(SCENES), "speed: scenes (comma-separated)"),
    ("--sizes", str, ",".join(SIZES), "speed: sizes WxH (comma-separated)"),
    ("--repeats", str, "3", "speed: frames per configuration (median): one count, or one per size"),
    ("--gt-samples", int, 2048, "speed: sl_gt's light and glossy samples"),
    ("--ratio-size", str, RATIO_SIZE, "speed: sizes of the GPU / CPU ratios on cornell_many, comma-separated "
     "(a speed size too: its GPU frames are reused; '': none)"),
    ("--section", str, "gpu-lightcuts", "speed: the section of docs/benchmarks.md (and the raw rows' file)"),
    ("--gt-model", str, "", "speed: sl_gt only, its frame of --gt-samples predicted from a frame of PASSES light "
     "passes and CHUNKS glossy dispatches ('PASSES,CHUNKS', e.g. 2,16; '': whole frames)"),
)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agreement", action="store_true", help="the statistical agreement (item 1) instead of speed")
    for flag, kind, default, text in OPTIONS:
        ap.add_argument(flag, type=kind, default=default, help=f"{text} (default {default})")
    ap.add_argument("--one", nargs=4, metavar=("BACKEND", "SCENE", "METHOD", "SIZE"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    model = _gt_model(args.gt_model)
    if args.one:
        print_row(measure_one(*args.one, int(args.repeats), args.gt_samples, model))
        return 0
    methods = args.methods.split(",")
    command = command_line("benchmarks/bench_gpu_lightcuts.py", argv if argv is not None else sys.argv[1:])
    if args.agreement:
        rows = agreement_rows(methods, args.agreement_gt_samples, args.seeds)
        write_csv(rows, "bench_gpu_lightcuts_agreement.csv")
        replace_section(DOC, "gpu-lightcuts-agreement",
                        agreement_section(rows, time.perf_counter() - t0, args.agreement_gt_samples,
                                          command))
        return 0
    repeats = [int(n) for n in args.repeats.split(",")]
    if model:  # sl_gt alone, no CPU ratios: the prediction is of the GPU's frame
        methods, args.ratio_size = ["sl_gt"], ""
    plan = speed_plan(args.scenes.split(","), methods, _sizes(args.sizes), repeats, _sizes(args.ratio_size))

    def done(rows):
        write_csv(rows, f"bench_{args.section.replace('-', '_')}.csv")
        elapsed = time.perf_counter() - t0
        replace_section(DOC, args.section,
                        model_section(rows, plan, elapsed, args.gt_samples, command, model,
                                      whole_gt_frames(args.gt_samples)) if model
                        else speed_section(rows, plan, elapsed, args.gt_samples, command))

    speed_rows(plan, args.gt_samples, done=done, gt_model=args.gt_model)
    return 0


def _gt_model(text: str) -> tuple[int, int] | None:
    """``--gt-model``: ``(passes, chunks)``, both at least 1 (None: whole frames)."""
    if not text:
        return None
    try:
        passes, chunks = (int(v) for v in text.split(","))
    except ValueError:
        passes = chunks = 0
    if passes < 1 or chunks < 1:
        print(f"--gt-model={text!r} is invalid: must be PASSES,CHUNKS, two whole numbers of at least 1",
              file=sys.stderr)
        raise SystemExit(2)
    return passes, chunks


if __name__ == "__main__":
    raise SystemExit(main())
