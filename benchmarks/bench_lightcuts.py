"""Benchmark of the stochastic-lightcuts core: light-tree build and per-pixel sampling throughput.

Run:  .venv/bin/python benchmarks/bench_lightcuts.py [--repeats 3] [--write docs/benchmarks.md]

Synthetic scene on plain arrays (no scene model): a 1280×720 G-buffer of a floor (z = 0, normals up) under
lights scattered in a slab 0.5–1.5 above it, with 200 random occluding triangles between them for the shadow
rays. Times are medians of the repeats; every kernel is first compiled on a small frame (numba compiles on
first use and caches to disk). The machine is shared: the load average is printed with the figures. Budgets:
uniform cuts of 8 and 48 nodes per pixel (SL with a fixed light-sample count) and the foveated pipeline
(α = 0.1, MAX_lspp = 48) with and without the multi-resolution selection.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.harness import load_average, machine_line, median_seconds as _median, replace_section  # noqa: E402


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


def run(repeats: int) -> list[str]:
    from data_schema.geometry import ViewingGeometry
    from renderers.lightcuts.foveated import foveated_lightcuts
    from renderers.lightcuts.fpsm import eccentricity_map
    from renderers.lightcuts.sampling import stochastic_lightcuts
    from renderers.lightcuts.tree import build_light_tree

    rows = []
    for n in (250_000, 110_000):
        pos, rgb = _lights(n)
        t = _median(lambda pos=pos, rgb=rgb: build_light_tree(pos, rgb), repeats)
        rows.append(f"| tree build | {n:,} lights | {t:.3f} s | {'≤ 1 s' if n == 250_000 else ''} |")
    pos, rgb = _lights(110_000)
    tree = build_light_tree(pos, rgb)
    w, h = 1280, 720
    g = _gbuffer(w, h)
    occ = _occluder()
    # compile every kernel once on a small frame; the large renders below are then timed without a warm-up
    small, small_lr = _gbuffer(64, 40), _gbuffer(8, 5)
    stochastic_lightcuts(tree, small, 4, occluded=occ)
    for mr in (True, False):
        foveated_lightcuts(tree, small, small_lr, eccentricity_map(ViewingGeometry.create(64, 40, 90.0)), np.zeros((40, 64, 2)), 0.1,
                           48, occluded=occ, multires=mr)
    sample_rows = []
    for budget, (bw, bh) in ((8, (w, h)), (48, (w // 2, h // 2))):
        gb = g if bw == w else _gbuffer(bw, bh)
        t_free = _median(lambda gb=gb, budget=budget: stochastic_lightcuts(tree, gb, budget, seed=1), repeats,
                         warm=False)
        runs = []
        t_occ = _median(lambda gb=gb, budget=budget, runs=runs: runs.append(
            stochastic_lightcuts(tree, gb, budget, seed=1, occluded=occ)), repeats,
                        warm=False)
        res = runs[-1]
        n_s = int(res.samples.sum())
        sample_rows.append(
            f"| SL, {budget} nodes/pixel | {bw}×{bh}, 110k lights | {t_free:.2f} s without shadows "
            f"({n_s / t_free / 1e6:.2f} M samples/s) | {t_occ:.2f} s with {res.shadow_rays / 1e6:.1f} M shadow rays |")
    gl = _gbuffer(w // 8, h // 8)
    ecc = eccentricity_map(ViewingGeometry.create(w, h, 90.0))
    vel = np.zeros((h, w, 2))
    fov_rows = []
    for multires in (True, False):
        runs = []

        def once(runs=runs, multires=multires):
            runs.append(foveated_lightcuts(tree, g, gl, ecc, vel, 0.1, 48, seed=1, occluded=occ,
                                           multires=multires))

        tt = _median(once, repeats, warm=False)
        r = runs[-1]
        steps = ", ".join(f"{k} {v:.2f}" for k, v in r.timings.items())
        fov_rows.append(f"| foveated, α = 0.1, {'with' if multires else 'without'} multi-resolution selection | "
                        f"{w}×{h}, 110k lights | {tt:.2f} s (mean {r.samples.mean():.1f} samples/pixel, "
                        f"{r.reused.sum() / max(r.samples.sum(), 1):.0%} reused) | steps (s): {steps} |")
    return rows + sample_rows + fov_rows + scene_rows(repeats)


def scene_rows(repeats: int) -> list[str]:
    """``cornell_many`` (111,858 mesh lights) through the renderer plug-ins at 1280×720 (issue 6 item 8)."""
    from renderers import registry
    from renderers.lightcuts.scenes import cornell_many

    sc = cornell_many()
    registry.render(sc, "fsl", {}, 64, 36)  # compile
    rows = []
    for name, params in (("fsl", {"alpha": 0.1}), ("sl_e", {"lspp": 8, "rspp": 8})):
        out = []
        t = _median(lambda out=out, name=name, params=params: out.append(
            registry.render(sc, name, params, 1280, 720)[1]), repeats, warm=False)
        st = out[-1]
        steps = ", ".join(f"{k} {v:.1f}" for k, v in st.get("steps", {}).items())
        rows.append(f"| plug-in `{name}` {params} | cornell_many 1280×720, 111,858 lights | {t:.1f} s (frame "
                    f"{st['seconds']['total']:.1f} s, mean {np.mean(st['spp']):.1f} light samples/pixel, "
                    f"{st['glossy_rays'] / 1e6:.2f} M glossy rays) | "
                    f"{'target ≤ 30 s; steps (s): ' + steps if name == 'fsl' else 'reference'} |")
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--write", metavar="MD", help="write the 'lightcuts' section into this Markdown file")
    args = ap.parse_args(argv)
    rows = run(args.repeats)
    lines = ["## Stochastic lightcuts core (`benchmarks/bench_lightcuts.py`)", "",
             machine_line() + f" Median of {args.repeats} run(s) after compiling the kernels on a small frame; "
             f"load average at the end {load_average()[0]:.1f}. Synthetic floor under lights in a slab, 200 "
             "occluding triangles (see the script's docstring).", "",
             "| operation | input | time | note |", "|---|---|---|---|", *rows, "",
             "Reproduce: `.venv/bin/python benchmarks/bench_lightcuts.py --write docs/benchmarks.md`"]
    print("\n".join(lines))
    if args.write:
        replace_section(args.write, "lightcuts", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
