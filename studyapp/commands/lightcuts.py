"""``studyapp lightcuts tables``: seed 003's quality and performance tables on this app's many-light scenes."""

from __future__ import annotations

import json
from pathlib import Path

from data_schema.errors import CLIError
from renderers.lightcuts.options import BUDGETS, FPSM_READINGS

from . import end_status, status

DESCRIPTION = """\
Render the many-light scenes with foveated stochastic lightcuts (Ours = fsl) and its baselines (SL_e at equal
time, SL_as, SL_f / SL_p at equal foveal / peripheral MSE, GT = sl_gt with 2048 light + 2048 glossy samples)
and reproduce seed 003: Table 1 (MSE, MSE_d, MSE_g in fovea and periphery), Table 2 (samples per pixel),
Table 3 (ms per frame, incl. Ours without multi-resolution selection), Table 4 and Fig 8 (alpha = 0.025 ...
0.4), the per-step times of Fig 9, the FPSM and error maps (Fig 5-7), and the issue's targets as same-run
ratios. --json prints records {table, scene, method, metric, region, value}. --backend chooses the renderers'
backend: cpu (default), or gpu (their OpenGL versions; on a GPU the default size is the per-eye 2160x2160 of
issue 16, on llvmpipe, a software GPU, it stays 192x108). Frame times are on that backend. --budget chooses
the accounting of the comparison: equal-time (SL_e renders in Ours' frame time, speed-ups are time ratios)
or equal-samples (SL_e draws Ours' light samples and glossy rays per pixel, speed-ups are ratios of rays per
frame, the multi-resolution gain a ratio of light-tree traversals).
--fpsm-reading chooses Ours' reading of seed 003 Eq 4-8 (docs/lightcuts.md). The GT of every scene (the costly
render) is one Dask task into the stimulus cache first (a local cluster by default, --scheduler for a running
one, --serial in this process); the measured renders then run in this process, one at a time."""

SCENE_NAMES = ("cornell_many", "study", "yard", "sponza_vpl")
#: The file that marks an --out folder as this command's output (data_schema.atomic.atomic_dir replaces only such a
#: folder, an empty one or none).
MARKER = "lightcuts_records.json"
#: Default sizes: a quick run, and the per-eye HMD resolution of issue 16 item 3 (the GPU backend on a GPU).
SMALL_SIZE = (192, 108)
SEED_SIZE = (2160, 2160)



def register(sub, parser_class) -> None:
    lc = sub.add_parser("lightcuts", help="foveated stochastic lightcuts: seed 003's tables and figures",
                        description="Foveated stochastic lightcuts (seed 003) and its baselines.")
    lsub = lc.add_subparsers(dest="lc_command", metavar="SUBCOMMAND", parser_class=parser_class)
    lsub.required = True
    t = lsub.add_parser("tables", help="seed 003 Tables 1-4 and Fig 5-8 on the many-light scenes",
                        description=DESCRIPTION)
    t.add_argument("--json", action="store_true", help="print the records as JSON")
    t.add_argument("--out", metavar="DIR",
                   help=f"write tables (md), records (json) and figures (png) into DIR, a new or empty folder or an "
                        f"earlier output of this command (it holds {MARKER}), which is replaced whole")
    t.add_argument("--scenes", default=",".join(SCENE_NAMES), metavar="A,B",
                   help=f"scenes to render (default: {','.join(SCENE_NAMES)})")
    t.add_argument("--backend", choices=("cpu", "gpu"), default="cpu",
                   help="renderers' backend: cpu (default) or gpu (OpenGL 4.3 compute)")
    t.add_argument("--width", type=int, default=None,
                   help=f"width in pixels (default {SMALL_SIZE[0]}; {SEED_SIZE[0]} with --backend gpu on a GPU)")
    t.add_argument("--height", type=int, default=None,
                   help=f"height in pixels (default {SMALL_SIZE[1]}; {SEED_SIZE[1]} with --backend gpu on a GPU)")
    t.add_argument("--alpha", type=float, default=0.1, help="alpha of Tables 1-3, in (0, 1) (default 0.1)")
    t.add_argument("--gt-samples", type=int, default=2048, metavar="N",
                   help="GT light and glossy samples per pixel (default 2048, as seed 003)")
    t.add_argument("--seed", type=int, default=0, help="random stream (default 0)")
    t.add_argument("--budget", choices=BUDGETS, default=BUDGETS[0],
                   help=f"accounting of the comparison with SL_e and of the speed-ups (default {BUDGETS[0]})")
    t.add_argument("--fpsm-reading", choices=FPSM_READINGS, default=FPSM_READINGS[0],
                   help=f"Ours' reading of seed 003 Eq 4-8 (fsl's fpsm_reading; default {FPSM_READINGS[0]})")
    t.add_argument("--cache", metavar="DIR", default="stimulus_cache",
                   help="stimulus cache for the GT renders (default: ./stimulus_cache); GT is rendered once")
    from studyapp.cluster import add_arguments

    add_arguments(t)
    t.set_defaults(func=cmd_tables)


def _progress(msg: str) -> None:
    status(msg, "lightcuts: ")


def _pivot_md(records: list[dict], table: str, rows: tuple[str, ...], cols: tuple[str, ...], fmt: str,
              caption: str) -> str:
    """A Markdown table of the records of ``table``: one row per ``rows`` key, one column per ``cols`` key."""
    sel = [r for r in records if r["table"] == table]
    row_keys = list(dict.fromkeys(tuple(r[k] for k in rows) for r in sel))
    col_keys = list(dict.fromkeys(tuple(r[k] for k in cols) for r in sel))
    val = {(tuple(r[k] for k in rows), tuple(r[k] for k in cols)): r["value"] for r in sel}
    head = [*rows, *(" ".join(map(str, c)) for c in col_keys)]
    lines = [f"**{caption}**", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for rk in row_keys:
        cells = [format(val[(rk, ck)], fmt) if (rk, ck) in val else "" for ck in col_keys]
        lines.append("| " + " | ".join([*map(str, rk), *cells]) + " |")
    return "\n".join(lines) + "\n"


def frame_size(backend: str, width: int | None, height: int | None) -> tuple[int, int]:
    """The size to render: as given, else :data:`SEED_SIZE` on a GPU (``backend="gpu"`` on a device that is not a
    software rasteriser) and :data:`SMALL_SIZE` otherwise. With ``backend="gpu"`` the device is opened here, before
    any task starts, so that no OpenGL 4.3 is one line (a user error) however the size is chosen."""
    default = SMALL_SIZE
    if backend == "gpu":
        from renderers.gpu.context import get_device

        dev = get_device()
        if not dev.software:
            default = SEED_SIZE
        elif width is None or height is None:
            _progress(f"{dev.renderer} is a software rasteriser: default size {SMALL_SIZE[0]}x{SMALL_SIZE[1]} "
                      f"(the seed's {SEED_SIZE[0]}x{SEED_SIZE[1]} per eye on a GPU)")
    return (default[0] if width is None else width, default[1] if height is None else height)


def tables_markdown(records: list[dict], ratios: dict[str, dict], budget: str = "equal-time",
                    backend: str = "cpu") -> str:
    parts = [
        _pivot_md(records, "1", ("scene", "method"), ("metric", "region"), ".3e",
                  "Table 1: MSE against GT (images clipped to [0, 1]); mse_d / mse_g over diffuse / glossy pixels"),
        _pivot_md([r for r in records if r["metric"] == "spp"], "2", ("scene", "method"), ("region",), ".1f",
                  "Table 2: mean light samples per pixel"),
        _pivot_md([r for r in records if r["metric"] == "ms"], "3", ("scene",), ("method",), ".0f",
                  f"Table 3: ms per frame ({backend.upper()} backend)"),
        _pivot_md(records, "4", ("scene",), ("method",), ".0f", "Table 4: ms per frame of Ours for each alpha"),
        _pivot_md(records, "fig8", ("scene", "method"), ("metric", "region"), ".3e",
                  "Fig 8 data: MSE of Ours for each alpha"),
        _pivot_md(records, "fig9", ("scene", "method"), ("metric",), ".1f", "Fig 9: ms per step"),
    ]
    unit = "time" if budget == "equal-time" else "rays"
    multi = "time" if budget == "equal-time" else "tree traversals"
    lines = [f"**Targets (same-run ratios, {budget})**", "",
             f"| scene | Ours vs SL_f speed-up, {unit} (≥ 2.5) | SL_e / Ours foveal MSE (≥ 1.9) "
             f"| SL_e / Ours peripheral MSE (≥ 1.2) | multi-res speed-up, {multi} (≥ 1.3) | time falls with alpha |",
             "|---|---|---|---|---|---|"]

    def f(v):
        return "n/a" if v is None else (("yes" if v else "no") if isinstance(v, bool) else f"{v:.2f}")

    for scene, r in ratios.items():
        lines.append(f"| {scene} | {f(r['speedup_vs_sl_f'])} | {f(r['foveal_mse_sl_e_over_ours'])} | "
                     f"{f(r['peripheral_mse_sl_e_over_ours'])} | {f(r['multires_speedup'])} | "
                     f"{f(r['time_falls_with_alpha'])} |")
    return "\n".join(parts) + "\n" + "\n".join(lines) + "\n"


def _write_figures(out: Path, records: list[dict], images: dict[str, dict], fov_y: dict[str, float]) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    import numpy as np

    from analysis.quality import error_heatmap
    from data_schema.atomic import atomic_path
    from renderers.lightcuts.demo import _png

    written = []
    for scene, im in images.items():
        written.append(_png(out / f"{scene}_ours.png", im["ours"]))
        written.append(_png(out / f"{scene}_gt.png", im["gt"]))
        written.append(_png(out / f"{scene}_fpsm.png", im["fpsm"]))
        for name in ("ours", "sl_e", "sl_as"):
            img = np.clip(im[name], 0, 1)
            written.append(error_heatmap(img, np.clip(im["gt"], 0, 1), out / f"{scene}_error_{name}.png",
                                         fov_y_deg=fov_y[scene], gaze=None, fovea_deg=5.0,
                                         title=f"{scene}: squared error of {name} against GT"))
    fig8 = [r for r in records if r["table"] == "fig8" and r["metric"] == "mse"]
    if fig8:
        scenes = list(dict.fromkeys(r["scene"] for r in fig8))
        fig, axes = plt.subplots(1, len(scenes), figsize=(3.6 * len(scenes), 3.0), squeeze=False)
        for ax, s in zip(axes[0], scenes):
            for region, style in (("fovea", "o-"), ("periphery", "s--")):
                pts = [(float(r["method"].split("=")[1].rstrip(")")), r["value"]) for r in fig8
                       if r["scene"] == s and r["region"] == region]
                if pts:
                    a, v = zip(*sorted(pts))
                    ax.plot(a, v, style, label=region)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel("alpha")
            ax.set_title(s)
            ax.grid(alpha=0.3)
        axes[0][0].set_ylabel("MSE against GT")
        axes[0][-1].legend(frameon=False)
        fig.tight_layout()
        path = out / "fig8_mse_vs_alpha.png"
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png", dpi=130, metadata={"Software": None})
        plt.close(fig)
        written.append(path)
    return written


def _ground_truths(args, scenes, width: int, height: int) -> None:
    """Every scene's GT (the costly render: 2048 + 2048 samples per pixel) into the stimulus cache first, one
    Dask task per scene (studyapp.cluster); the measured renders of the tables then run here, one at a time, so
    that their frame times are not disturbed."""
    from renderers.lightcuts.tables import gt_frame
    from studyapp import cluster
    from studyapp.progress import Bar

    spec = cluster.from_args(args)
    n = args.gt_samples
    frames = [(f"scene {name}, ground truth sl_gt {n} + {n}",
               gt_frame(name, width, height, gt_lspp=n, gt_rspp=n, seed=args.seed, backend=args.backend))
              for name in scenes]
    bar = Bar("ground truths")
    cluster.render_frames(frames, Path(args.cache), spec, progress=bar)
    bar.close()


def cmd_tables(args) -> int:
    from renderers.lightcuts.fpsm import check_alpha
    from renderers.lightcuts.scenes import SCENES
    from renderers.lightcuts.tables import lightcut_tables, summary_ratios

    scenes = [s.strip() for s in args.scenes.split(",") if s.strip()]
    unknown = [s for s in scenes if s not in SCENES]
    if unknown or not scenes:
        raise CLIError(f"--scenes: unknown scene {unknown[0] if unknown else '(none)'!r}: "
                       f"allowed {', '.join(SCENES)}")
    for name, v, lo in (("--width", args.width, 16), ("--height", args.height, 16), ("--gt-samples",
                                                                                      args.gt_samples, 1)):
        if v is not None and not lo <= v <= 8192:
            raise CLIError(f"{name}={v} is out of range: allowed [{lo}, 8192]")
    check_alpha(args.alpha)
    if args.out:  # refused now, not after the rendering
        from data_schema.atomic import check_dir_target

        out = check_dir_target(args.out, MARKER).resolve()
        cache = Path(args.cache).resolve()
        if cache == out or out in cache.parents or cache in out.parents:
            raise CLIError(f"--cache {args.cache} and --out {args.out} overlap: the --out folder is replaced whole, "
                           "so keep the stimulus cache outside it")
    width, height = frame_size(args.backend, args.width, args.height)  # opens the GPU: errors before any task
    _ground_truths(args, scenes, width, height)
    records, ratios, images, fov_y = [], {}, {}, {}
    for name in scenes:
        scene = SCENES[name]()
        im: dict = {}
        recs = lightcut_tables(scene, width, height, alpha=args.alpha, gt_lspp=args.gt_samples,
                               gt_rspp=args.gt_samples, seed=args.seed, progress=_progress, images=im,
                               cache_dir=Path(args.cache), fpsm_reading=args.fpsm_reading, budget=args.budget,
                               backend=args.backend)
        records += recs
        ratios[scene.name] = summary_ratios(recs, args.budget)
        images[scene.name] = im
        fov_y[scene.name] = scene.camera.fov_y
    end_status()
    md = tables_markdown(records, ratios, args.budget, args.backend)
    if args.out:
        from data_schema.atomic import atomic_dir, write_text

        out = Path(args.out)
        with atomic_dir(out, MARKER) as tmp:  # the whole folder, or nothing
            written = [write_text(tmp / "lightcuts_tables.md", md),
                       write_text(tmp / MARKER, json.dumps(records, indent=1) + "\n"),
                       write_text(tmp / "lightcuts_ratios.json", json.dumps(ratios, indent=1) + "\n"),
                       *_write_figures(tmp, records, images, fov_y)]
        if not args.json:
            for p in written:
                print(out / p.name)
    if args.json:
        print(json.dumps(records, indent=1))
    elif not args.out:
        print(md, end="")
    return 0


def demo_step(out_dir: Path, progress=None) -> list[Path]:
    """A lightcuts stimulus: ``cornell_many`` (111,858 lights) rendered by ``fsl`` and its FPSM."""
    from renderers.lightcuts.demo import demo_step as lc_demo

    return lc_demo(Path(out_dir), progress)
