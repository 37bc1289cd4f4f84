"""Benchmark of the stochastic-lightcuts core: light-tree build and per-pixel sampling throughput.

Run:  .venv/bin/python benchmarks/bench_lightcuts.py [--repeats 3] [--smoke] [--write docs/benchmarks.md]

Synthetic scene on plain arrays (no scene model): a 1280×720 G-buffer of a floor (z = 0, normals up) under
lights scattered in a slab 0.5–1.5 above it, with 200 random occluding triangles between them for the shadow
rays. Times are medians of the repeats; every kernel is first compiled on a small frame (numba compiles on
first use and caches to disk). The machine is shared: the load average is printed with the figures. Budgets:
uniform cuts of 8 and 48 nodes per pixel (SL with a fixed light-sample count) and the foveated pipeline
(α = 0.1, MAX_lspp = 48) with and without the multi-resolution selection. Each row is one configuration in its own
child process (``harness.run_child``: its peak memory, wall time and the load after it); the raw rows go to
``benchmarks/results/bench_lightcuts_full.csv``. ``--smoke`` runs every configuration at tiny sizes.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.harness import (load_average, load_line, machine_line, median_seconds as _median,  # noqa: E402
                                print_row, replace_section, results_ref, run_child, write_csv)


def _lights(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    pos = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(0.5, 1.5, n)])
    return pos, rng.uniform(0, 1, (n, 3)) / n * 1e3


def _gbuffer(w: int, h: int):
    from renderers.lightcuts.sampling import GBuffer

    x, y = np.meshgrid((np.arange(w) + 0.5) / w * 2 - 1, ((np.arange(h) + 0.5) / h * 2 - 1) * h / w)
    pos = np.stack([x, y, np.zeros_like(x)], -1)
    nrm = np.zeros_like(pos)
    nrm[..., 2] = 1.0
    alb = np.where(((np.floor(x * 8) + np.floor(y * 8)) % 2 == 0)[..., None], [0.7, 0.7, 0.7], [0.3, 0.5, 0.2])
    return GBuffer.create(pos, nrm, alb)


def _occluder(seed: int = 1):
    from renderers.lightcuts.visibility import EmbreeOccluder

    rng = np.random.default_rng(seed)
    centres = np.column_stack([rng.uniform(-1, 1, 200), rng.uniform(-0.6, 0.6, 200), rng.uniform(0.1, 0.4, 200)])
    verts = (centres[:, None, :] + rng.normal(0, 0.05, (200, 3, 3))).reshape(-1, 3)
    return EmbreeOccluder(verts, np.arange(600).reshape(200, 3))


#: The sizes of a full run and of ``--smoke`` (tiny: it checks that every configuration runs, in seconds).
SIZES = {"full": {"lights": (250_000, 110_000), "frame": (1280, 720), "scene_frame": (1280, 720)},
         "smoke": {"lights": (4_000, 2_000), "frame": (64, 36), "scene_frame": (32, 18)}}


def configurations(size: str, repeats: int) -> list[list]:
    """The configurations of a run, one child process each: ``[kind, size, repeats, ...]``."""
    n_big, n_small = SIZES[size]["lights"]
    return ([["tree", size, repeats, n] for n in (n_big, n_small)]
            + [["sl", size, repeats, budget] for budget in (8, 48)]
            + [["foveated", size, repeats, mr] for mr in (True, False)]
            + [["plugin", size, repeats, name] for name in ("fsl", "sl_e")])


def measure(kind: str, size: str, repeats: int, arg) -> dict:
    """One configuration in this process: its median time over ``repeats`` and what its table row shows."""
    if kind == "tree":
        from renderers.lightcuts.tree import build_light_tree

        pos, rgb = _lights(arg)
        return {"kind": kind, "lights": arg, "median_s": _median(lambda: build_light_tree(pos, rgb), repeats)}
    if kind == "plugin":
        return _plugin(size, repeats, arg)
    from data_schema.geometry import ViewingGeometry
    from renderers.lightcuts.foveated import foveated_lightcuts
    from renderers.lightcuts.fpsm import eccentricity_map
    from renderers.lightcuts.sampling import stochastic_lightcuts
    from renderers.lightcuts.tree import build_light_tree

    n = SIZES[size]["lights"][1]
    tree = build_light_tree(*_lights(n))
    w, h = SIZES[size]["frame"]
    occ = _occluder()
    # compile every kernel once on a small frame; the large renders below are then timed without a warm-up
    small, small_lr = _gbuffer(64, 40), _gbuffer(8, 5)
    if kind == "sl":
        stochastic_lightcuts(tree, small, 4, occluded=occ)
        bw, bh = (w, h) if arg == 8 else (w // 2, h // 2)
        gb = _gbuffer(bw, bh)
        t_free = _median(lambda: stochastic_lightcuts(tree, gb, arg, seed=1), repeats, warm=False)
        runs = []
        t_occ = _median(lambda: runs.append(stochastic_lightcuts(tree, gb, arg, seed=1, occluded=occ)), repeats,
                        warm=False)
        return {"kind": kind, "lights": n, "budget": arg, "width": bw, "height": bh, "median_s": t_free,
                "samples": int(runs[-1].samples.sum()), "median_occluded_s": t_occ,
                "shadow_rays": int(runs[-1].shadow_rays)}
    foveated_lightcuts(tree, small, small_lr, eccentricity_map(ViewingGeometry.create(64, 40, 90.0)),
                       np.zeros((40, 64, 2)), 0.1, 48, occluded=occ, multires=arg)
    g, gl = _gbuffer(w, h), _gbuffer(w // 8, h // 8)
    ecc = eccentricity_map(ViewingGeometry.create(w, h, 90.0))
    vel = np.zeros((h, w, 2))
    runs = []
    t = _median(lambda: runs.append(foveated_lightcuts(tree, g, gl, ecc, vel, 0.1, 48, seed=1, occluded=occ,
                                                        multires=arg)), repeats, warm=False)
    r = runs[-1]
    return {"kind": kind, "lights": n, "multires": arg, "width": w, "height": h, "median_s": t,
            "mean_samples": float(r.samples.mean()), "reused": float(r.reused.sum() / max(r.samples.sum(), 1)),
            "steps": {k: float(v) for k, v in r.timings.items()}}


def _plugin(size: str, repeats: int, name: str) -> dict:
    """``cornell_many`` (111,858 mesh lights) through a renderer plug-in (issue 6 item 8)."""
    from renderers import registry
    from renderers.lightcuts.scenes import cornell_many

    params = {"fsl": {"alpha": 0.1}, "sl_e": {"lspp": 8, "rspp": 8}}[name]
    w, h = SIZES[size]["scene_frame"]
    sc = cornell_many()
    registry.render(sc, "fsl", {}, 64, 36)  # compile
    out = []
    t = _median(lambda: out.append(registry.render(sc, name, params, w, h)[1]), repeats, warm=False)
    st = out[-1]
    return {"kind": "plugin", "renderer": name, "params": params, "width": w, "height": h, "median_s": t,
            "frame_s": st["seconds"]["total"], "mean_spp": float(np.mean(st["spp"])),
            "glossy_rays": int(st["glossy_rays"]), "steps": {k: float(v) for k, v in st.get("steps", {}).items()}}


def table_row(r: dict) -> str:
    """A measured configuration as its row of the report's table."""
    if r["kind"] == "tree":
        target = "≤ 1 s" if r["lights"] >= 250_000 else ""
        return f"| tree build | {r['lights']:,} lights | {r['median_s']:.3f} s | {target} |"
    frame = f"{r['width']}×{r['height']}"
    if r["kind"] == "sl":
        return (f"| SL, {r['budget']} nodes/pixel | {frame}, {r['lights'] // 1000}k lights | {r['median_s']:.2f} s "
                f"without shadows ({r['samples'] / r['median_s'] / 1e6:.2f} M samples/s) | "
                f"{r['median_occluded_s']:.2f} s with {r['shadow_rays'] / 1e6:.1f} M shadow rays |")
    if r["kind"] == "foveated":
        steps = ", ".join(f"{k} {v:.2f}" for k, v in r["steps"].items())
        return (f"| foveated, α = 0.1, {'with' if r['multires'] else 'without'} multi-resolution selection | "
                f"{frame}, {r['lights'] // 1000}k lights | {r['median_s']:.2f} s (mean {r['mean_samples']:.1f} "
                f"samples/pixel, {r['reused']:.0%} reused) | steps (s): {steps} |")
    steps = ", ".join(f"{k} {v:.1f}" for k, v in r["steps"].items())
    return (f"| plug-in `{r['renderer']}` {r['params']} | cornell_many {frame}, 111,858 lights | {r['median_s']:.1f} s "
            f"(frame {r['frame_s']:.1f} s, mean {r['mean_spp']:.1f} light samples/pixel, "
            f"{r['glossy_rays'] / 1e6:.2f} M glossy rays) | "
            f"{'target ≤ 30 s; steps (s): ' + steps if r['renderer'] == 'fsl' else 'reference'} |")


def run(size: str, repeats: int) -> list[dict]:
    """Every configuration in its own child process (its peak memory, wall time and the load after it)."""
    rows = []
    for job in configurations(size, repeats):
        r = run_child([os.path.abspath(__file__), "--one", json.dumps(job)], " ".join(map(str, job)))
        rows.append(r)
        print(f"{' '.join(map(str, job))}: median {r['median_s']:.3f} s, peak {r['peak_mb']:.0f} MB, "
              f"wall {r['wall_s']:.1f} s, load {r['load']:.1f}", file=sys.stderr, flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--smoke", action="store_true", help="tiny sizes, one repeat: checks that every configuration "
                    "runs (seconds); its figures mean nothing")
    ap.add_argument("--write", metavar="MD", help="write the 'lightcuts' section into this Markdown file")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        print_row(measure(*json.loads(args.one)))
        return 0
    size, repeats = ("smoke", 1) if args.smoke else ("full", args.repeats)
    load0 = load_average()
    rows = run(size, repeats)
    write_csv([{**r, "steps": json.dumps(r.get("steps", {}))} for r in rows], f"bench_lightcuts_{size}.csv")
    lines = ["## Stochastic lightcuts core (`benchmarks/bench_lightcuts.py`)", "",
             machine_line() + f" Median of {repeats} run(s) after compiling the kernels on a small frame, one "
             f"child process per row (peak memory up to {max(r['peak_mb'] for r in rows):.0f} MB); load average "
             f"{load_line(load0, load_average())}. Synthetic floor under lights in a slab, 200 "
             "occluding triangles (see the script's docstring).", "",
             "| operation | input | time | note |", "|---|---|---|---|", *map(table_row, rows), "",
             "Reproduce: `.venv/bin/python benchmarks/bench_lightcuts.py --write docs/benchmarks.md` (raw rows: "
             f"`{results_ref(f'bench_lightcuts_{size}.csv')}`)"]
    print("\n".join(lines))
    if args.write:
        replace_section(args.write, "lightcuts", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
