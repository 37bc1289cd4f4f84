"""``studyapp render`` and ``studyapp scenes``: render one stimulus, list the built-in scenes."""

from __future__ import annotations

import json
import math
from pathlib import Path

from data_schema.errors import CLIError
from studyapp.progress import ticker

RENDER_HELP = "render a scene with a renderer (GT, VaFR, LMFR, LaFR, plug-ins) to an sRGB PNG"
RENDER_DESCRIPTION = (
    "Render a built-in scene (see 'studyapp scenes') or a YAML scene file with one renderer and write the "
    "tone-mapped sRGB PNG, plus the linear float32 image next to it (same name, .npy). --json prints the stats "
    "record (shading points, rays, seconds per stage, peak memory, skip counters).")


def register(sub, parser_class) -> None:
    r = sub.add_parser("render", help=RENDER_HELP, description=RENDER_DESCRIPTION)
    r.add_argument("--scene", required=True, metavar="NAME_OR_FILE", help="built-in scene name or YAML file")
    r.add_argument("--renderer", required=True, metavar="NAME", help="gt, vafr, lmfr, lafr or a plug-in")
    r.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                   help="renderer parameter (repeatable), e.g. --param fxaa=false --param delta=2.2")
    r.add_argument("--width", type=int, required=True, metavar="W", help="width in pixels")
    r.add_argument("--height", type=int, required=True, metavar="H", help="height in pixels")
    r.add_argument("--gaze", metavar="X,Y", help="gaze point in pixels (default: the centre)")
    r.add_argument("--out", required=True, metavar="FILE.png", help="output PNG (the .npy goes next to it)")
    r.add_argument("--json", action="store_true", help="print the stats record as JSON")
    r.add_argument("--backend", choices=("cpu", "gpu"), default="cpu",
                   help="cpu (Embree + numba, default) or gpu (OpenGL 4.3 compute through moderngl; EGL when no "
                        "window is open, Mesa's llvmpipe on machines without a GPU)")
    r.set_defaults(func=cmd_render)
    s = sub.add_parser("scenes", help="list the built-in scenes",
                       description="List the built-in procedural scenes with triangle and light counts, the length "
                                   "of one scene unit and the resulting walking speed when exploring (1.4 m/s "
                                   "unless a protocol's stimulus.explore.move_speed_m_s says otherwise).")
    s.add_argument("--json", action="store_true", help="print JSON instead of a table")
    s.set_defaults(func=cmd_scenes)
    lr = sub.add_parser("renderers", help="list the renderers and their parameters",
                        description="List every registered renderer (built-in and plug-ins) with its "
                                    "parameters: type, default and allowed values.")
    lr.set_defaults(func=cmd_renderers)


def parse_params(items: list[str]) -> dict:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise CLIError(f"--param {item!r} is invalid: use KEY=VALUE")
        out[key.strip()] = value.strip()
    return out


def parse_gaze(text: str | None):
    if text is None:
        return None
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise CLIError(f"--gaze {text!r} is invalid: use X,Y in pixels") from None
    return x, y


def cmd_render(args) -> int:
    from data_schema.atomic import check_target
    from renderers.catalog import resolve
    from renderers.registry import render
    from renderers.stimuli import write_png_and_npy

    out = Path(args.out)
    if out.suffix.lower() != ".png":
        raise CLIError(f"--out {args.out!r} is invalid: must end in .png")
    for target in (out, out.with_suffix(".npy")):
        check_target(target)
    params = parse_params(args.param)
    gaze = parse_gaze(args.gaze)
    scene = resolve(args.scene)
    with ticker(f"rendering {scene.name} with {args.renderer} ({args.backend})"):
        img, stats = render(scene, args.renderer, params, args.width, args.height, gaze=gaze,
                            backend=args.backend)
    write_png_and_npy(out, img, scene.exposure)
    if args.json:
        from renderers.stimuli import jsonable_stats

        print(json.dumps(jsonable_stats(stats), indent=2))
    else:
        s = stats["seconds"]
        device = f", {stats['gpu']['renderer']}" if "gpu" in stats else ""
        print(f"wrote {out} ({args.width}x{args.height}, {stats['shading_points']:,} shading points, "
              f"{s['total']:.2f} s{device})")
    return 0


def cmd_scenes(args) -> int:
    from renderers.catalog import BUILTIN_SCENES, builtin
    from studyapp.runner.live import WALK_M_S

    rows = [builtin(name).summary() for name in BUILTIN_SCENES]
    for r in rows:  # what exploring it means: the default walking pace in the scene's own units
        r["walk_units_per_s"] = WALK_M_S / r["metres_per_unit"]
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    print(f"{'scene':<14} {'triangles':>10} {'point':>6} {'dir.':>5} {'emissive':>9}  camera fov_y  1 unit  "
          f"walk {WALK_M_S:g} m/s")
    for r in rows:
        print(f"{r['name']:<14} {r['triangles']:>10,} {r['point_lights']:>6} {r['directional_lights']:>5} "
              f"{r['emissive_triangles']:>9}  {r['camera']['fov_y']:>11.1f}°  "
              f"{unit_name(r['metres_per_unit']):>6}  {r['walk_units_per_s']:,.4g} units/s")
    return 0


def unit_name(metres: float) -> str:
    """One scene unit in words: ``1 mm``, ``1 cm``, ``1 m``, else ``0.3048 m``."""
    for name, size in (("m", 1.0), ("cm", 0.01), ("mm", 0.001), ("km", 1000.0)):
        if math.isclose(metres, size, rel_tol=1e-9):
            return f"1 {name}"
    return f"{metres:g} m"


def cmd_renderers(args) -> int:
    from renderers.registry import available, foveation_strength

    for name, plugin in sorted(available().items()):
        print(f"{name}: {plugin.description}")
        strength = foveation_strength(name)
        print(f"    foveation strength: {strength.describe() + f'; lowers {strength.count}' if strength else 'none'}")
        for k, p in plugin.params.items():
            print(f"    {k} ({p.type.__name__}, default {p.default}; allowed {p.allowed()}): {p.help}")
    return 0


def demo_step(out_dir: Path, progress=None) -> list[Path]:
    """Render the Cornell box at 320x240 with GT and the foveated renderers on the CPU, then again on the GPU
    backend (llvmpipe where there is no GPU), and print how closely the two agree."""
    from data_schema.atomic import write_bytes, write_text
    from renderers.gpu import render as gpu_render
    from renderers.gpu.agreement import agreement
    from renderers.stimuli import entry_image, render_stimulus, write_png

    out_dir = Path(out_dir)
    cache = out_dir / "cache"
    gaze = (160.0, 120.0)
    written = []
    lines = ["# Rendered stimuli (demo)", "", "The Cornell box at 320x240, gaze at the centre, on both backends. "
             "Agreement: PSNR of the GPU's linear image against the CPU's (exposed, clipped to [0, 1]) and the "
             "share of pixels whose 8-bit PNG values differ by at most one level.", "",
             "| renderer | CPU file | GPU file | PSNR (dB) | within one level | shading points CPU / GPU |",
             "|---|---|---|---:|---:|---|"]
    for name, params in (("gt", {}), ("vafr", {}), ("lmfr", {}), ("lafr", {})):
        if progress:
            progress(f"render: cornell {name} (cpu)")
        png = render_stimulus("cornell", name, params, 320, 240, gaze, cache_dir=cache)
        target = out_dir / f"cornell_{name}.png"
        write_bytes(target, png.read_bytes())
        cpu_img = entry_image(png, (240, 320, 3))
        cpu_points = json.loads(png.with_suffix(".json").read_text())["shading_points"]
        if progress:
            progress(f"render: cornell {name} (gpu)")
        gpu_img, stats = gpu_render("cornell", name, params, 320, 240, gaze=gaze)
        gpu_target = write_png(out_dir / f"cornell_{name}_gpu.png", gpu_img)
        psnr, within = agreement(cpu_img, gpu_img)
        written += [target, gpu_target]
        lines.append(f"| {name} | {target.name} | {gpu_target.name} | {psnr:.1f} | {100 * within:.2f} % | "
                     f"{cpu_points:,} / {stats['shading_points']:,} |")
        print(f"      cornell {name}: GPU vs CPU {psnr:.1f} dB, {100 * within:.2f} % of pixels within one level, "
              f"shading points {cpu_points:,} / {stats['shading_points']:,}", flush=True)
    written.append(write_text(out_dir / "stimuli.md", "\n".join(lines) + "\n"))
    return written
