"""Benchmark: run time against error of GT, VaFR, LMFR and LaFR on the built-in scenes (issue 4 item 7).

For each scene x resolution, GT and each foveated renderer are rendered, one Dask task per frame, in this process
by default (frame times of an unshared machine: the committed figures), on a local cluster with ``--workers N``
(its workers share the machine: frame times grow, errors are the same) or on a lab's cluster with ``--scheduler``
(a sweep over its machines; start them with ``dask worker --nthreads 1``, docs/distributed.md); every render's
per-stage seconds, shading points, rays and peak memory are recorded, and its error against GT
is measured on the 8-bit sRGB images (what participants see) in the fovea (e <= 5°, seed 001 Eq 3) and in the
periphery (e > 5°): MSE, PSNR and SSIM (scikit-image, on luma; in the periphery on up to 8 crops of 512 x 512
spread over the screen so that SSIM stays bounded at retinal resolution). Speed-ups are GT's total time over
the renderer's, measured in the same run on this machine.

The 1-spp GT aliases (one ray per pixel centre), so errors are also measured against a reference that does not:
GT with 16 stratified samples per pixel and a 1-px tent filter (``gt`` ``spp=16, filter=tent``; issue 13 item 7),
rendered up to ``--reference-max-pixels`` (default 4K; 16x the GT's cost) and reported beside the GT columns.

Unlike the other scripts, the configurations run as Dask tasks, not in ``harness.run_child`` children: spreading
them over workers is what this script measures (docs/benchmarks.md). Each row still carries its render's own peak
memory, ``peak_mb``: the process's high-water mark (VmHWM), reset before every render
(``/proc/self/clear_refs``), so it is per task; ``peak_mb_is_per_render`` says whether the reset succeeded (when it
did not, the figure is the process's peak so far).

Writes ``docs/benchmarks.md`` section ``render``; the raw rows and the plot go to ``benchmarks/results/``
(``bench_render.csv``, ``bench_render.png``; not committed).

    python benchmarks/bench_render.py                        # every scene x resolution (hours on 2 cores)
    python benchmarks/bench_render.py --plan "cornell:2K:VaFR/LaFR(1.8)"      # one scene, chosen methods
    python benchmarks/bench_render.py --plan "temple:2K+4K;temple:8K+retinal:VaFR/VaFR-noAA/LaFR(2.2)/LaFR(1.8)/LMFR(1.8);street_night:2K+8K:VaFR/VaFR-noAA/LaFR(1.8)/LMFR(1.8);interior:2K+8K:VaFR/VaFR-noAA/LaFR(1.8)/LMFR(1.8);street_day:2K+8K:VaFR/VaFR-noAA/LaFR(1.8)/LMFR(1.8);cornell:2K"
                                                             # the plan of the committed figures (~40 min)
"""

from __future__ import annotations

import argparse
import csv
import itertools
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.harness import DOC, machine_line, replace_section, results_path, results_ref, write_csv  # noqa: E402

RESOLUTIONS = {"2K": (2560, 1440), "4K": (3840, 2160), "8K": (7680, 4320), "retinal": (11520, 6480)}
METHODS = {
    "VaFR": ("vafr", {}),
    "VaFR-noAA": ("vafr", {"fxaa": False}),
    "VaFR-deferred": ("vafr", {"pipeline": "deferred"}),
    "LaFR(2.2)": ("lafr", {"delta": 2.2}),
    "LaFR(1.8)": ("lafr", {"delta": 1.8}),
    "LMFR(1.8)": ("lmfr", {"delta": 1.8}),
}
FOVEA_DEG = 5.0
#: The anti-aliased reference (issue 13 item 7).
REFERENCE = ("gt", {"spp": 16, "filter": "tent"})


def eccentricity_rows(W, H, fov, y0, y1):
    from data_schema.geometry import ViewingGeometry

    d = ViewingGeometry.create(W, H, fov)
    x = np.arange(W) + 0.5
    y = np.arange(y0, y1)[:, None] + 0.5
    return d.eccentricity(np.hypot(x[None, :] - W / 2, y - H / 2))


def srgb(a):
    """The 8-bit sRGB image as floats in [0, 1] (``a``: linear, or already 8-bit)."""
    from renderers.stimuli import to_srgb8

    a = np.asarray(a)
    return (a if a.dtype == np.uint8 else to_srgb8(a)).astype(np.float32) / 255.0


def errors(img, gt, fov):
    """MSE/PSNR in the fovea and the periphery (row blocks) and SSIM on luma crops."""
    from skimage.metrics import structural_similarity

    H, W = gt.shape[:2]
    sums = {"fovea": [0.0, 0], "periphery": [0.0, 0]}
    step = max(1, (1 << 21) // W)
    for y0 in range(0, H, step):
        y1 = min(H, y0 + step)
        e = eccentricity_rows(W, H, fov, y0, y1)
        d2 = ((srgb(img[y0:y1]) - srgb(gt[y0:y1])) ** 2).mean(axis=2)
        f = e <= FOVEA_DEG
        sums["fovea"][0] += float(d2[f].sum())
        sums["fovea"][1] += int(f.sum())
        sums["periphery"][0] += float(d2[~f].sum())
        sums["periphery"][1] += int((~f).sum())
    out = {}
    for k, (s, n) in sums.items():
        mse = s / max(n, 1)
        out[f"mse_{k}"] = mse
        out[f"psnr_{k}"] = math.inf if mse == 0 else 10 * math.log10(1.0 / mse)
    luma = lambda a: srgb(a) @ np.array([0.2126, 0.7152, 0.0722], np.float32)  # noqa: E731
    from data_schema.geometry import ViewingGeometry

    r5 = float(ViewingGeometry.create(W, H, fov).radius(FOVEA_DEG))
    c = int(min(r5, W / 2, H / 2))
    fy, fx = slice(H // 2 - c, H // 2 + c), slice(W // 2 - c, W // 2 + c)
    s_map = structural_similarity(luma(img[fy, fx]), luma(gt[fy, fx]), data_range=1.0, full=True)[1]
    m = eccentricity_rows(W, H, fov, fy.start, fy.stop)[:, fx] <= FOVEA_DEG
    out["ssim_fovea"] = float(s_map[m].mean())
    vals = []
    S = min(512, H // 4, W // 4)
    for cy in (H // 8, H // 2, 7 * H // 8):
        for cx in (W // 8, W // 2, 7 * W // 8):
            if cy == H // 2 and cx == W // 2:
                continue
            ys, xs = slice(max(0, cy - S // 2), max(0, cy - S // 2) + S), slice(max(0, cx - S // 2),
                                                                               max(0, cx - S // 2) + S)
            e = eccentricity_rows(W, H, fov, ys.start, ys.stop)[:, xs]
            s_map = structural_similarity(luma(img[ys, xs]), luma(gt[ys, xs]), data_range=1.0, full=True)[1]
            if (e > FOVEA_DEG).any():
                vals.append(float(s_map[e > FOVEA_DEG].mean()))
    out["ssim_periphery"] = float(np.mean(vals)) if vals else math.nan
    return out


#: (scene, renderer, params) already rendered once by this process (see :func:`render_task`).
_WARM: set = set()


def render_task(scene, name, params, W, H):
    """One frame (a Dask task, or in process): its 8-bit sRGB image (what the errors are measured on) and stats.

    A process's first render of a (scene, renderer, params) is preceded by an untimed 96 x 64 one, so that
    compiled kernels (numba caches) are loaded and the scene's BVH is built before any timing.
    """
    from renderers import render
    from renderers.stimuli import to_srgb8

    warm = (scene, name, repr(sorted(params.items())))
    if warm not in _WARM:
        render(scene, name, params, 96, 64)
        _WARM.add(warm)
    img, st = render(scene, name, params, W, H)
    return to_srgb8(img), st


def _fov(scene):
    from renderers.catalog import resolve

    return resolve(scene).camera.fov_y


def gt_row_task(gt, ref, scene, res):
    """The GT's row (its own error against the reference, where there is one)."""
    err_ref = None if ref is None else errors(gt[0], ref[0], _fov(scene))
    return row(scene, res, "GT", gt[1], None, gt[1]["seconds"]["total"], err_ref)


def errors_task(gt, ref, frame, scene, res, label):
    """A method's row: its errors against GT (and the reference, where there is one)."""
    fov = _fov(scene)
    return row(scene, res, label, frame[1], errors(frame[0], gt[0], fov), gt[1]["seconds"]["total"],
               None if ref is None else errors(frame[0], ref[0], fov))


def run(scenes, resolutions, methods, out_rows, progress=print, reference_max_pixels: int = 3840 * 2160,
        spec=None, client=None):
    """Render and measure ``scenes`` x ``resolutions`` x (GT, the reference up to ``reference_max_pixels``,
    ``methods``): one task per frame and one per row of error measurements (on the cluster, next to the frames:
    the client receives rows, never images), on ``spec`` (a ``studyapp.cluster.ClusterSpec``; default in
    process) through ``client``."""
    import uuid

    from benchmarks import bench_render as B  # tasks by reference: workers import this module
    from studyapp.cluster import SERIAL, Ref, Task, run_tasks

    run_id = uuid.uuid4().hex[:8]
    tasks = []
    for scene, res in itertools.product(scenes, resolutions):
        W, H = RESOLUTIONS[res]
        gt = f"bench-{run_id}-{scene}-{res}-GT"
        tasks.append(Task(gt, f"{scene} {res}: GT", B.render_task, (scene, "gt", {}, W, H), fetch=False))
        ref = None
        if W * H <= reference_max_pixels:
            ref = Ref(f"bench-{run_id}-{scene}-{res}-reference")
            tasks.append(Task(ref.name, f"{scene} {res}: 16-spp reference", B.render_task,
                              (scene, *REFERENCE, W, H), fetch=False))
        tasks.append(Task(f"{gt}-row", f"{scene} {res}: GT", B.gt_row_task, (Ref(gt), ref, scene, res)))
        for label in methods:
            name, params = METHODS[label]
            key = f"bench-{run_id}-{scene}-{res}-{label}"
            tasks += [Task(key, f"{scene} {res}: {label}", B.render_task, (scene, name, params, W, H), fetch=False),
                      Task(f"{key}-row", f"{scene} {res}: {label} errors", B.errors_task,
                           (Ref(gt), ref, Ref(key), scene, res, label))]
    rows = {}

    def done(task, r):
        rows[task.name] = r
        if r["method"] == "GT":
            progress(f"{r['scene']} {r['resolution']}: GT {r['total_s']:.1f} s")
        else:
            progress(f"{r['scene']} {r['resolution']}: {r['method']} {r['total_s']:.2f} s, speed-up "
                     f"{r['speedup_vs_gt']:.1f}x, foveal PSNR {r['psnr_fovea']:.1f} dB")

    run_tasks(tasks, spec or SERIAL, done, client=client)
    out_rows += [rows[t.name] for t in tasks if t.fetch]


def row(scene, res, label, st, err, gt_total, err_ref=None):
    s = st["seconds"]
    r = {"scene": scene, "resolution": res, "width": st["width"], "height": st["height"], "method": label,
         "total_s": s["total"], "visibility_s": s["visibility"], "shading_s": s["shading"],
         "antialias_s": s["antialias"], "inverse_map_s": s["inverse_map"],
         "speedup_vs_gt": gt_total / s["total"], "shading_points": st["shading_points"],
         "rays_primary": st["rays_primary"], "rays_shadow": st["rays_shadow"], "peak_mb": st["peak_mb"],
         "peak_mb_is_per_render": st.get("peak_mb_is_per_render", False), "lights_culled": st["lights_culled"],
         "offscreen_lp_pixels": st["offscreen_lp_pixels"]}
    for k in ("mse_fovea", "psnr_fovea", "ssim_fovea", "mse_periphery", "psnr_periphery", "ssim_periphery"):
        r[k] = None if err is None else err[k]
        r[f"{k}_ref"] = None if err_ref is None else err_ref[k]
    return r


def fmt(v, nd=2):
    if v is None:
        return "–"
    if isinstance(v, float):
        return "inf" if math.isinf(v) else f"{v:.{nd}f}"
    return f"{v:,}" if isinstance(v, int) else str(v)


def merged(rows, path):
    """Rows of an earlier run (CSV at ``path``) that this run did not re-measure, then this run's rows.

    A (scene, resolution) pair re-measured here replaces all of its earlier rows, so speed-ups always compare
    renders of one run.
    """
    if not os.path.exists(path):
        return list(rows)
    done = {(r["scene"], r["resolution"]) for r in rows}
    keep = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            if (r["scene"], r["resolution"]) in done:
                continue
            for k, v in r.items():
                if k not in ("scene", "resolution", "method"):
                    r[k] = None if v in ("", "None") else (int(v) if v.lstrip("-").isdigit() else float(v))
            keep.append(r)
    return keep + list(rows)


def write_outputs(rows, elapsed, merge=True, where="this process"):
    from data_schema.atomic import atomic_path

    if merge:
        rows = merged(rows, results_path("bench_render.csv"))
    write_csv(rows, "bench_render.csv")  # every key: rows of runs before the reference columns lack them
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 4.5))
        for label in sorted({r["method"] for r in rows} - {"GT"}):
            pts = [(r["total_s"], r["psnr_periphery"]) for r in rows if r["method"] == label]
            ax.scatter(*zip(*pts), label=label)
        ax.set_xscale("log")
        ax.set_xlabel("frame time (s, log)")
        ax.set_ylabel("peripheral PSNR vs GT (dB)")
        ax.legend(fontsize=8)
        ax.set_title("Run time against error (all scenes and resolutions)")
        with atomic_path(results_path("bench_render.png")) as tmp:
            fig.savefig(tmp, format="png", dpi=100)
        plt.close(fig)
    except ImportError:
        pass
    lines = ["## Renderers: run time against error (`benchmarks/bench_render.py`)", "", machine_line(),
             f"Wall time of the last benchmark run {elapsed / 60:.1f} min, rendered on {where} (a local cluster "
             "runs its workers side by side, each with cores / workers numba threads: frame times are then those "
             "of a shared machine). Times are one frame of one eye (mono; a binocular `dup` "
             "frame doubles every method, so the ratios hold per eye), ray-casting pipeline unless named, after "
             "the scene and BVH are built. Speed-up = GT total / method total in the same run. Errors on 8-bit "
             "sRGB against GT: fovea e <= 5°, periphery e > 5°; `ref` columns: against a 16-spp GT with a "
             "1-px tent filter (no aliasing; rendered up to 4K, – where not; the GT row then shows the 1-spp GT's "
             "own error). The machine's 2 cores are shared with other "
             "jobs, so single timings carry noise of tens of per cent. Raw rows and plot (not committed): "
             f"`{results_ref('bench_render.csv')}`, `{results_ref('bench_render.png')}`.", "",
             "| scene | res | method | total s | vis s | shade s | AA s | inv s | speed-up | shading pts | "
             "shadow rays | peak MB | PSNR fov | PSNR per | SSIM fov | SSIM per | PSNR fov ref | PSNR per ref | "
             "SSIM fov ref |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['resolution']} | {r['method']} | {fmt(r['total_s'])} | "
                     f"{fmt(r['visibility_s'])} | {fmt(r['shading_s'])} | {fmt(r['antialias_s'])} | "
                     f"{fmt(r['inverse_map_s'])} | {fmt(r['speedup_vs_gt'], 1)}x | {fmt(r['shading_points'])} | "
                     f"{fmt(r['rays_shadow'])} | {fmt(r['peak_mb'], 0)} | {fmt(r['psnr_fovea'], 1)} | "
                     f"{fmt(r['psnr_periphery'], 1)} | {fmt(r['ssim_fovea'], 3)} | {fmt(r['ssim_periphery'], 3)} | "
                     f"{fmt(r.get('psnr_fovea_ref'), 1)} | {fmt(r.get('psnr_periphery_ref'), 1)} | "
                     f"{fmt(r.get('ssim_fovea_ref'), 3)} |")
    lines += ["", *targets(rows)]
    replace_section(DOC, "render", lines)


def targets(rows):
    """The issue's target lines, evaluated on the rows measured."""
    out = ["Targets (issue 4):", ""]
    get = {(r["scene"], r["resolution"], r["method"]): r for r in rows}
    for scene in sorted({r["scene"] for r in rows}):
        for (res, goal), label in itertools.product((("8K", 20.0), ("retinal", 40.0)), ("VaFR", "VaFR-noAA")):
            r = get.get((scene, res, label))
            if r:
                ok = "met" if r["speedup_vs_gt"] >= goal else f"missed by {goal / r['speedup_vs_gt']:.2f}x"
                out.append(f"- {scene} {res}: {r['method']} is {r['speedup_vs_gt']:.1f}x faster than GT (target "
                           f">= {goal:.0f}x: {ok}); stages vis {r['visibility_s']:.2f} s, shade "
                           f"{r['shading_s']:.2f} s, AA {r['antialias_s']:.2f} s, inverse map "
                           f"{r['inverse_map_s']:.2f} s of {r['total_s']:.2f} s.")
        a, b = get.get((scene, "2K", "VaFR")), get.get((scene, "retinal", "VaFR"))
        if a and b:
            g = b["total_s"] / a["total_s"]
            out.append(f"- {scene}: VaFR total grows {g:.2f}x from 2K to retinal (target <= 1.5x: "
                       f"{'met' if g <= 1.5 else 'missed'}).")
        for res in RESOLUTIONS:
            v, la = get.get((scene, res, "VaFR")), get.get((scene, res, "LaFR(1.8)"))
            if v and la:
                ok = v["psnr_fovea"] >= la["psnr_fovea"] and v["total_s"] < la["total_s"]
                out.append(f"- {scene} {res}: VaFR+FXAA foveal PSNR {v['psnr_fovea']:.1f} dB in {v['total_s']:.2f} s "
                           f"vs LaFR(1.8) {la['psnr_fovea']:.1f} dB in {la['total_s']:.2f} s "
                           f"({'met' if ok else 'missed'}).")
        peaks = [r["peak_mb"] for r in rows if r["scene"] == scene and r["resolution"] == "retinal"]
        if peaks:
            out.append(f"- {scene} retinal: largest peak memory {max(peaks):.0f} MB (target <= 6144 MB: "
                       f"{'met' if max(peaks) <= 6144 else 'missed'}).")
    return out


def main(argv=None):
    from studyapp import cluster

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cluster.add_arguments(ap)
    ap.add_argument("--scenes", default="temple,street_night,interior,street_day")
    ap.add_argument("--resolutions", default="2K,4K,8K,retinal")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--fresh", action="store_true", help="drop the rows of earlier runs (default: keep the "
                    "scene x resolution pairs this run does not measure)")
    ap.add_argument("--reference-max-pixels", type=int, default=3840 * 2160,
                    help="render the 16-spp reference only up to this many pixels (0: never)")
    ap.add_argument("--plan", default=None, help="scene:res1+res2[:method1/method2];... (overrides --scenes, "
                    "--resolutions and, where given, --methods)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    rows = []
    methods = [m for m in args.methods.split(",") if m]
    plan = []
    if args.plan:
        for entry in args.plan.split(";"):
            parts = entry.split(":")
            plan.append((parts[0], parts[1].split("+"), parts[2].split("/") if len(parts) > 2 else methods))
    else:
        plan = [(s, args.resolutions.split(","), methods) for s in args.scenes.split(",")]
    spec = cluster.from_args(args)
    if spec == cluster.ClusterSpec():  # no cluster asked for: frame times of an unshared machine
        spec = cluster.SERIAL
    with cluster.connect(spec) as client:
        for scene, res, meths in plan:
            run([scene], res, meths, rows, progress=lambda m: print(m, flush=True),
                reference_max_pixels=args.reference_max_pixels, spec=spec, client=client)
            write_outputs(rows, time.perf_counter() - t0, merge=not args.fresh,
                          where=spec.describe())  # partial results survive
    print("\n".join(targets(rows)))


if __name__ == "__main__":
    main()
