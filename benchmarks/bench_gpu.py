"""Benchmark of the GPU backend (issue 13 items 5 and 6): agreement with the CPU backend, and speed.

``--agreement``: on cornell, temple, street_night and interior at 320 x 240 (gaze at the centre), every method
(gt, VaFR with and without FXAA in dup and rep, LMFR, LaFR) rendered on both backends; for each case the PSNR of
the GPU's linear image against the CPU's (exposed, clipped to [0, 1], peak 1), the share of pixels whose 8-bit
PNGs agree within one level, and the work counters of both. Writes section ``gpu-agreement`` of
``docs/benchmarks.md`` and the raw rows to ``benchmarks/results/bench_gpu_agreement.csv``.

Speed (default): milliseconds per frame and per stage for every method on temple at 640x480, 1280x720 and
2468x2740 (medians over ``--repeats``; a size whose single frame takes over a minute is measured once), each
configuration in its own process (``benchmarks/harness.py``) for the peak memory; the GPU/CPU ratio for VaFR and
GT at 640x480 measured in the same run. Runs unchanged on a machine with a GPU (EGL, no display). Writes section
``gpu`` of ``docs/benchmarks.md`` and the raw rows to ``benchmarks/results/bench_gpu.csv`` (``benchmarks/harness.py``).

    python benchmarks/bench_gpu.py --agreement          # ~15 min on 2 cores with llvmpipe
    python benchmarks/bench_gpu.py                      # speed, ~30 min on 2 cores with llvmpipe
    python benchmarks/bench_gpu.py --sizes 640x480 --methods gt,vafr-dup --repeats 3
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.harness import (  # noqa: E402
    DOC, LLVMPIPE_NOTE, ONCE_SECONDS, gpu_device_line, machine_line, print_row, replace_section,
    run_child, timed_frames, write_csv)

AGREEMENT_SCENES = ("cornell", "temple", "street_night", "interior")
AGREEMENT_CASES = {
    "gt": ("gt", {}),
    "vafr dup FXAA": ("vafr", {"stereo": "dup", "eye": "right"}),
    "vafr dup no-FXAA": ("vafr", {"stereo": "dup", "eye": "right", "fxaa": False}),
    "vafr rep FXAA": ("vafr", {"stereo": "rep", "eye": "right"}),
    "vafr rep no-FXAA": ("vafr", {"stereo": "rep", "eye": "right", "fxaa": False}),
    "lmfr": ("lmfr", {}),
    "lafr": ("lafr", {}),
}
COUNTERS = ("shading_points", "rays_primary", "rays_shadow", "missed_rays", "offscreen_lp_pixels",
            "reshaded_pixels", "lights_culled")


def agreement_rows(scenes, cases, size=(320, 240), progress=print) -> list[dict]:
    """Render each (scene, case) on both backends; one row of agreement figures and counters each."""
    from renderers import render as cpu_render
    from renderers.catalog import resolve
    from renderers.gpu import render as gpu_render
    from renderers.gpu.agreement import agreement

    W, H = size
    rows = []
    for scene in scenes:
        exposure = resolve(scene).exposure
        for label, (name, params) in cases.items():
            a, sa = cpu_render(scene, name, params, W, H)
            b, sb = gpu_render(scene, name, params, W, H)
            psnr, within = agreement(a, b, exposure)
            r = {"scene": scene, "case": label, "width": W, "height": H, "psnr_db": psnr, "within_one": within,
                 "cpu_s": sa["seconds"]["total"], "gpu_s": sb["seconds"]["total"]}
            for k in COUNTERS:
                r[f"cpu_{k}"], r[f"gpu_{k}"] = sa.get(k, 0), sb.get(k, 0)
            rows.append(r)
            progress(f"{scene} {label}: {psnr:.1f} dB, {100 * within:.2f} % within one level, shading points "
                     f"{sa['shading_points']:,} / {sb['shading_points']:,}")
    return rows


def agreement_section(rows, elapsed: float) -> list[str]:
    worst = min(rows, key=lambda r: r["within_one"])
    lines = [
        "## GPU backend against the CPU backend (issue 13 item 5)", "",
        machine_line(), gpu_device_line(),
        f"Command: `python benchmarks/bench_gpu.py --agreement` ({elapsed / 60:.1f} min). Scenes at "
        f"{rows[0]['width']}x{rows[0]['height']}, gaze at the centre; dup and rep report the right eye (rep's is "
        "reprojected). PSNR: the GPU's linear image against the CPU's, exposed and clipped to [0, 1] (peak 1); "
        "within 1: share of pixels whose 8-bit sRGB PNGs differ by at most one level in every channel. "
        "Thresholds: >= 35 dB and >= 99 %.", "",
        f"Worst case: {min(r['psnr_db'] for r in rows):.1f} dB PSNR; {100 * worst['within_one']:.2f} % within one "
        f"level ({worst['scene']} {worst['case']}). Shading points equal in "
        f"{sum(r['cpu_shading_points'] == r['gpu_shading_points'] for r in rows)} of {len(rows)} cases "
        "(rep: the re-shaded holes may differ by a few pixels where float32 rasterisation of the warped grid "
        "flips a pixel at the warp's boundary).", "",
        "| scene | case | PSNR (dB) | within 1 | shading points CPU / GPU | shadow rays CPU / GPU | re-shaded CPU / GPU |"
        " CPU s | GPU s |",
        "|---|---|---:|---:|---|---|---|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['case']} | {r['psnr_db']:.1f} | {100 * r['within_one']:.2f} % | "
                     f"{r['cpu_shading_points']:,} / {r['gpu_shading_points']:,} | "
                     f"{r['cpu_rays_shadow']:,} / {r['gpu_rays_shadow']:,} | "
                     f"{r['cpu_reshaded_pixels']:,} / {r['gpu_reshaded_pixels']:,} | {r['cpu_s']:.2f} | "
                     f"{r['gpu_s']:.2f} |")
    return lines


# -- speed ---------------------------------------------------------------------------------------------------------
SPEED_SCENE = "temple"
SIZES = ("640x480", "1280x720", "2468x2740")
METHODS = {
    "gt": ("gt", {}),
    "vafr-dup": ("vafr", {"stereo": "dup"}),
    "vafr-rep": ("vafr", {"stereo": "rep"}),
    "lmfr": ("lmfr", {}),
    "lafr": ("lafr", {}),
}
STAGES = ("visibility", "shading", "antialias", "inverse_map")
#: Targets for a GPU (issue 13 item 6), frame milliseconds on temple.
TARGETS = {("vafr-dup", "2468x2740"): 1000.0 / 90.0, ("gt", "2468x2740"): 1000.0 / 30.0}


def measure_one(backend: str, method: str, size: str, repeats: int) -> dict:
    """Frame times of one configuration in this process (:func:`timed_frames`), medians per stage."""
    name, params = METHODS[method]
    frames = timed_frames(backend, SPEED_SCENE, name, params, size, repeats)
    med = {k: float(np.median([f["seconds"][k] for f in frames])) for k in (*STAGES, "total")}
    out = {"backend": backend, "method": method, "size": size, "frames": len(frames),
           "eyes": frames[0].get("eyes", 1), **{f"{k}_ms": 1e3 * v for k, v in med.items()},
           "shading_points": frames[0]["shading_points"], "rays_shadow": frames[0]["rays_shadow"],
           "device": frames[0].get("gpu", {}).get("renderer", "cpu"),
           "timing": frames[0].get("gpu", {}).get("timing", "wall clock")}
    return out


def run_config(backend: str, method: str, size: str, repeats: int) -> dict:
    """:func:`measure_one` in a child process (its peak resident memory: :func:`benchmarks.harness.run_child`)."""
    return run_child([os.path.abspath(__file__), "--one", backend, method, size, "--repeats", str(repeats)],
                     f"{backend} {method} {size}")


def speed_rows(methods, sizes, repeats: int, progress=print) -> list[dict]:
    rows = []
    for size in sizes:
        for method in methods:
            backends = ("gpu", "cpu") if size == "640x480" and method in ("gt", "vafr-dup") else ("gpu",)
            for backend in backends:
                r = run_config(backend, method, size, repeats)
                rows.append(r)
                progress(f"{backend} {method} {size}: {r['total_ms']:,.0f} ms/frame ({r['frames']} frames), "
                         f"peak {r['peak_mb']:,.0f} MB")
    return rows


def speed_section(rows, elapsed: float, repeats: int) -> list[str]:
    gpu = [r for r in rows if r["backend"] == "gpu"]
    lines = [
        "## GPU backend: speed (issue 13 item 6)", "",
        machine_line(), gpu_device_line(),
        f"Command: `python benchmarks/bench_gpu.py` ({elapsed / 60:.1f} min). Scene {SPEED_SCENE} (517,090 "
        f"triangles, 31 point lights), gaze at the centre; median of {repeats} frames after a first full-size frame "
        f"(a configuration whose first frame took over {ONCE_SECONDS:.0f} s is that frame alone: `frames` = 1); "
        "each configuration in its own process, peak MB its maximum resident set. vafr-dup renders "
        "both eyes (binocular), vafr-rep the left eye and the reprojected right one; the others one eye. Stage "
        f"times: {gpu[0]['timing'] if gpu else ''}.", "",
        LLVMPIPE_NOTE, "",
        "| method | size | backend | frame ms | ms per eye | visibility | shading | antialias | inverse map | "
        "shading points | shadow rays | peak MB | frames | load |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['method']} | {r['size']} | {r['backend']} | {r['total_ms']:,.0f} | "
                     f"{r['total_ms'] / r['eyes']:,.0f} | " + " | ".join(f"{r[k + '_ms']:,.0f}" for k in STAGES)
                     + f" | {r['shading_points']:,} | {r['rays_shadow']:,} | {r['peak_mb']:,.0f} | {r['frames']} | "
                     f"{r.get('load', float('nan')):.1f} |")
    lines.append("")
    for method in ("vafr-dup", "gt"):
        pair = {r["backend"]: r for r in rows if r["method"] == method and r["size"] == "640x480"}
        if len(pair) == 2:
            lines.append(f"- {method} at 640x480, same run: GPU backend {pair['gpu']['total_ms']:,.0f} ms, CPU "
                         f"backend {pair['cpu']['total_ms']:,.0f} ms per frame: GPU/CPU time ratio "
                         f"{pair['gpu']['total_ms'] / pair['cpu']['total_ms']:.2f}.")
    for (method, size), target in TARGETS.items():
        r = next((r for r in gpu if r["method"] == method and r["size"] == size), None)
        what = "binocular VaFR, both eyes" if method == "vafr-dup" else "GT"
        fps = "90 fps per eye" if method == "vafr-dup" else "30 fps"
        got = f"measured {r['total_ms']:,.0f} ms here ({r['device']})" if r else "not measured in this run"
        lines.append(f"- Target on a GPU: {what} at {size} on temple at {fps}, i.e. <= {target:.1f} ms per "
                     f"frame; {got}.")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agreement", action="store_true", help="the agreement table (item 5) instead of speed")
    ap.add_argument("--scenes", default=",".join(AGREEMENT_SCENES))
    ap.add_argument("--cases", default=",".join(AGREEMENT_CASES), help="agreement cases (comma-separated)")
    ap.add_argument("--methods", default=",".join(METHODS), help="speed: methods (comma-separated)")
    ap.add_argument("--sizes", default=",".join(SIZES), help="speed: sizes WxH (comma-separated)")
    ap.add_argument("--repeats", type=int, default=3, help="speed: frames per configuration (median)")
    ap.add_argument("--one", nargs=3, metavar=("BACKEND", "METHOD", "SIZE"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    if args.one:
        print_row(measure_one(*args.one, args.repeats))
        return 0
    if args.agreement:
        rows = agreement_rows(args.scenes.split(","), {k: AGREEMENT_CASES[k] for k in args.cases.split(",")})
        write_csv(rows, "bench_gpu_agreement.csv")
        replace_section(DOC, "gpu-agreement", agreement_section(rows, time.perf_counter() - t0))
        return 0
    rows = speed_rows(args.methods.split(","), args.sizes.split(","), args.repeats)
    write_csv(rows, "bench_gpu.csv")
    replace_section(DOC, "gpu", speed_section(rows, time.perf_counter() - t0, args.repeats))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
