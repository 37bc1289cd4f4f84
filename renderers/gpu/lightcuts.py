"""The lightcuts renderers on the GPU (issue 16 item 1): ``fsl``, ``sl`` (``sl_e``, ``sl_f``, ``sl_p``), ``sl_as``
and ``sl_gt`` as OpenGL compute passes, the GPU versions of :mod:`renderers.lightcuts.plugin`.

The scene is the uploaded one of the other GPU renderers (BVH, triangles, materials: :mod:`.upload`); the light
tree is the CPU's (:func:`renderers.lightcuts.plugin.scene_light_tree`, seed 003 Algorithm 1 line 3), uploaded
once per scene into an image (``shaders/lightcuts.glsl``). A frame is the CPU plug-in's steps (seed 003 Fig 9)
as passes, each timed:

* ``gbuffer`` — primary rays through the pixel centres (``lc_gbuffer.comp``): position, normal, albedo,
  specular colour, emission + ambient; ``fsl`` also the ``w/8 × h/8`` low-resolution G-buffer (Algorithm 1 line 7);
* ``low_res`` (``fsl``) — stochastic lightcuts of ``MAX_lspp`` nodes per low-resolution pixel, and ``LS'``, its
  samples sorted by leaf (``lc_low_res.comp``);
* ``fpsm`` (``fsl``; ``sl_as``'s AFSM in ``gbuffer``) — the FPSM of Eq 1–8 and the budgets ``#L`` from the
  G-buffer and the low-resolution image (:mod:`renderers.gpu.fpsm`);
* ``cuts``, ``select``, ``shade`` — per tile of pixels: the cuts refined to ``#L`` nodes (``lc_cut.comp``), one
  light per node by hierarchical importance sampling or, for ``fsl``, Algorithm 2's reuse of ``LS'``
  (``lc_select.comp``), the Lambertian estimates and their shadow rays through the BVH (``lc_shade.comp``);
* ``glossy`` — the one-bounce glossy pass (``lc_glossy.comp``), skipped when no material is glossy or metallic.

The per-pixel bodies of the cuts, select, low_res and shade passes are the CPU's pixel kernels translated
(``_kernels.cut_pixel``, ``sample_pixel``, ``shade_pixel``, ``multires.select_pixel``, ``sort_pixel``:
:func:`renderers.gpu.codegen.lightcuts_glsl`), reading and writing the buffers of
``bindings.FAMILIES["lc_buffers"]``; the glossy pass's bounce runs the same cut_pixel, sample_pixel and
shade_pixel on each ray's hit (``lightcuts_bounce_glsl``), its lobe ``glossy.lobe_sample`` (``glossy_glsl``),
as the CPU's ``glossy_pass`` does; the shaders keep the plumbing (invocation index, tiles, counters) and the
shadow rays through the BVH. The random numbers are the CPU's (counter-based: seed, pixel id, slot), so both
backends draw the same samples up to the float32 rounding of positions and probabilities: seed for seed the
images agree closely, and over seeds their per-pixel means and variances
(``benchmarks/bench_gpu_lightcuts.py --agreement``).
"""

from __future__ import annotations

import math

import numpy as np

from data_schema.errors import UserError

from ..lightcuts import plugin as LC
from ..lightcuts.fpsm import check_alpha, check_reading
from ..lightcuts.glossy import glossy_offset
from ..lightcuts.sampling import clamp2
from .bindings import TREE_TEXELS, TREE_UNIFORMS
from .context import WAY_OUT
from .fpsm import fpsm_controls, read_map
from .frame import Frame
from .upload import camera_uniforms

#: Bytes of one tile's sample lists (16 per sample, ``CUT_MAX`` per pixel): bounds the per-sample memory.
TILE_BYTES = 1 << 26
#: Largest cut the GPU refines (each shading point keeps its cut in private memory).
MAX_CUT = 256
#: Work per invocation is bounded because llvmpipe cuts an invocation's loops short past 65,535 iterations in all
#: (shaders/common.glsl; the frame is then refused): a ray through the BVH of yard takes up to a few hundred.
#: Glossy rays per pixel in one dispatch, each a BVH hit, 4 bounce samples and their shadow rays (GT's 2048 are
#: cast in chunks; 64 reached the limit on yard at 1280 x 720).
GLOSSY_CHUNK = 8
#: Samples of each cut shaded in one dispatch, a shadow ray each (a 256-node cut reached the limit on yard).
SHADE_SLICE = 64
#: Pooled buffers of a G-buffer.
_GBUF = ("g_pos", "g_nrm", "g_alb", "g_ks", "g_base", "pix", "rad")


#: ``bounds``: the G-buffer points' box (min xyz, max xyz) and the FPSM's extreme rho, as ordered bits of +inf
#: (for the minima) and -inf (maxima).
_INF_KEYS = np.array([0xFF800000] * 3 + [0x007FFFFF] * 3 + [0xFF800000, 0x007FFFFF], dtype=np.uint32)


def tree_table(tree) -> np.ndarray:
    """The light tree as ``(6 N, 4)`` float32 texels (layout :data:`TREE_TEXELS`)."""
    n = tree.n_leaves
    t = np.zeros((6 * n, 4), dtype=np.float32)
    data = {"node_min": tree.bmin, "node_inten": tree.intensity, "node_max": tree.bmax, "light_rgb": tree.light_rgb,
            "light_nrm": tree.light_nrm}
    for name, arr in data.items():
        if arr is not None:
            first, step, texel, comps = TREE_TEXELS[name]
            c0 = "xyzw".index(comps[0])
            rows = slice(first * n + texel, first * n + texel + step * len(arr), step)
            t[rows, c0:c0 + len(comps)] = np.reshape(arr, (len(arr), len(comps)))
    return t


class DeviceTree:
    """A light tree in an RGBA32UI image and its uniforms."""

    def __init__(self, device, tree, scene_name: str):
        table = tree_table(tree)
        device.check_fits(f"the light tree of scene {scene_name!r}", {"light tree": table.nbytes})
        self.device = device
        self.tree = tree
        self.texture = device.table_texture(f"the light tree of scene {scene_name!r}", table)
        values = (int(tree.n_leaves), int(tree.levels), float(clamp2(tree)), int(tree.light_nrm is not None))
        self.uniforms = dict(zip(TREE_UNIFORMS, values))

    def release(self) -> None:
        self.device.release(self.texture)


def device_tree(ds) -> DeviceTree:
    """The light tree of a :class:`~renderers.gpu.upload.DeviceScene`, uploaded once (the latest scene's)."""
    trees = ds.device.cache.setdefault("light_trees", {})
    key = ds.scene.content_hash()
    if key not in trees:
        for old in trees.values():
            old.release()
        trees.clear()
        trees[key] = DeviceTree(ds.device, LC.scene_light_tree(ds.scene), ds.scene.name)
    return trees[key]


def _seed(seed: int) -> tuple[int, int]:
    """A 64-bit random stream as the (lo, hi) of a ``uvec2`` uniform."""
    seed = int(seed)
    return seed & 0xFFFFFFFF, (seed >> 32) & 0xFFFFFFFF


def _check_cut(name: str, budget: int) -> int:
    """The cut stride ``CUT_MAX`` for cuts of up to ``budget`` nodes: the next power of two (at least 4), so that
    few shader variants are compiled; refused above :data:`MAX_CUT`."""
    if budget > MAX_CUT:
        raise UserError(f"{name}={budget} is above the largest cut the GPU refines ({MAX_CUT} nodes): {WAY_OUT}")
    return max(4, 1 << (max(1, int(budget)) - 1).bit_length())


class GBuffer:
    """The pooled buffers of one G-buffer of ``width × height`` rays (``prefix`` names them)."""

    def __init__(self, lc: LightcutsFrame, prefix: str, width: int, height: int):
        self.width, self.height, self.n = width, height, width * height
        self.lc = lc
        self.buffers = {b: lc.fr.pool.get(f"lc_{prefix}_{b}", 16 * self.n) for b in _GBUF}

    def read(self, name: str, dtype=np.float32) -> np.ndarray:
        """Buffer ``name`` as an ``(n, 4)`` array."""
        out = np.empty((self.n, 4), dtype=dtype)
        self.buffers[name].read_into(out, size=out.nbytes)
        return out


class LightcutsFrame:
    """One frame of a lightcuts renderer on the GPU: the passes of the module docstring on a
    :class:`~renderers.gpu.frame.Frame`."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.fr = Frame(ctx.tracer)
        self.tree = device_tree(ctx.tracer)
        self.cam = camera_uniforms(ctx.camera, ctx.width, ctx.height)
        self.origin = tuple(float(x) for x in ctx.camera.position)
        self.shadows = int(bool(ctx.scene.shadows))
        self.common = {"bounds": self.fr.upload("lc_bounds", _INF_KEYS), "ctl": self.fr.pool.get("lc_ctl", 16)}
        self.lr_ls = self.lr_pix = None
        self.lr_size = (1, 1)

    def step(self, name: str):
        return self.fr.timer(name)

    def run(self, shader: str, n: int, buffers: dict, uniforms: dict, cut_max: int = 1,
            defines: dict | None = None) -> None:
        self.fr.run(shader, n, {**self.common, **buffers}, {**self.tree.uniforms, **uniforms},
                    {"CUT_MAX": cut_max, "MULTIRES": 0, **(defines or {})}, {"t_tree": self.tree.texture})

    def gbuffer(self, prefix: str, width: int, height: int, full: bool) -> GBuffer:
        """Trace the G-buffer of ``width × height`` rays spread over the screen (the frame's when ``full``)."""
        g = GBuffer(self, prefix, width, height)
        step = (self.ctx.width / width, self.ctx.height / height)
        self.run("lc_gbuffer.comp", g.n, g.buffers, {**self.cam, "u_origin": self.origin, "u_width": width,
                                                   "u_step": step, "u_full": int(full)})
        return g

    def lightcuts(self, g: GBuffer, budget: int | None, cut_max: int, seeds, *, id_base: int = 0,
                  multires: bool = False, steps=("cuts", "select", "shade"), low_res: bool = False) -> None:
        """Stochastic lightcuts over ``g``'s pixels in tiles: cuts of ``budget`` nodes (None: each pixel's
        ``ctl`` budget), one light per node (Algorithm 2 with ``multires``), shading with shadow rays into ``rad``.
        ``seeds``: one random stream (an int), or several (sl_gt's passes), each of which draws and shades its
        own lights on the same cuts (a cut depends on the shading point alone), their radiance summed in ``rad``.
        ``low_res`` also sorts each pixel's samples into ``LS'``."""
        seeds = [seeds] if isinstance(seeds, int) else list(seeds)
        tile = max(1, min(g.n, TILE_BYTES // (16 * cut_max)))
        smp = self.fr.pool.get("lc_smp", 16 * tile * cut_max)
        bufs = {**g.buffers, "smp": smp}
        if low_res:
            self.lr_ls = self.fr.pool.get("lc_lr_ls", 16 * g.n * cut_max)
            self.lr_pix, self.lr_size = g.buffers["pix"], (g.width, g.height)
        if multires:
            bufs.update({"lr_ls": self.lr_ls, "lr_pix": self.lr_pix})
        uni = {"u_id_base": int(id_base), "u_budget": -1 if budget is None else int(budget),
               "u_shadows": self.shadows, "u_width": g.width,
               "u_lr_scale": (self.lr_size[0] / g.width, self.lr_size[1] / g.height),
               "u_lr_width": self.lr_size[0], "u_lr_height": self.lr_size[1]}
        for first in range(0, g.n, tile):
            m = min(tile, g.n - first)
            with self.step(steps[0]):
                self.run("lc_cut.comp", m, bufs, {**uni, "u_first": first}, cut_max)
            for k, seed in enumerate(seeds):
                u = {**uni, "u_first": first, "u_seed": _seed(seed), "u_accumulate": int(k > 0)}
                with self.step(steps[1]):
                    self.run("lc_select.comp", m, bufs, u, cut_max, {"MULTIRES": int(multires)})
                with self.step(steps[2]):
                    for s0 in range(0, cut_max, SHADE_SLICE):
                        self.run("lc_shade.comp", m, bufs, {**u, "u_s0": s0, "u_s1": s0 + SHADE_SLICE}, cut_max)
                    if low_res:
                        self.run("lc_low_res.comp", m, {**bufs, "lr_ls": self.lr_ls}, u, cut_max)
                self.fr.drain_counters()  # each pass's counts, well below 32 bits

    def glossy(self, g: GBuffer, rspp: int | None, max_rspp: int, seed: int, lspp_bounce: int):
        """The glossy pass over ``g`` (``rspp`` rays per glossy pixel, None: each pixel's ``ctl``, at most
        ``max_rspp``): ``(glossy radiance (n, 3) or None, rays)``; nothing is cast for an all-diffuse scene."""
        if not LC.scene_has_glossy(self.ctx.scene) or max_rspp <= 0:
            return None, 0
        with self.step("glossy"):
            gloss = self.fr.pool.get("lc_gloss", 16 * g.n)
            uni = {**self.cam, "u_origin": self.origin, "u_width": g.width, "u_first": 0, "u_seed": _seed(seed),
                   "u_rspp": -1 if rspp is None else int(rspp), "u_bounce_seed": _seed(seed + 7919),
                   "u_bounce_lspp": int(lspp_bounce), "u_shadows": self.shadows,
                   "u_glossy_offset": float(glossy_offset(self.tree.tree))}
            before = self.fr.totals["glossy_rays"]
            for r0 in range(0, max_rspp, GLOSSY_CHUNK):
                self.run("lc_glossy.comp", g.n, {**g.buffers, "gloss": gloss}, {**uni, "u_r0": r0,
                                                                        "u_r1": r0 + GLOSSY_CHUNK},
                         _check_cut("lspp_bounce", lspp_bounce))
                self.fr.drain_counters()
            out = np.empty((g.n, 4), dtype=np.float32)
            gloss.read_into(out, size=out.nbytes)
        return out[:, :3], self.fr.totals["glossy_rays"] - before

    def finish(self, g: GBuffer, diffuse: np.ndarray, glossy, rays: int) -> np.ndarray:
        """Read back, compose (:func:`renderers.lightcuts.plugin.frame_output`), count and time the frame."""
        ctx = self.ctx
        base = g.read("g_base")[:, :3]
        glossy_mask = (g.read("g_pos")[:, 3] > 0) & (g.read("g_nrm")[:, 3] > 0)
        img = LC.frame_output(ctx, base, diffuse, glossy, glossy_mask, rays)
        ctx.extra["spp"] = g.read("pix", np.int32)[:, 1].astype(np.int64).reshape(ctx.height, ctx.width)
        steps = self.fr.timer.seconds()
        totals = self.fr.close()
        c = ctx.tracer.counters
        c.seconds["visibility"] += steps.get("gbuffer", 0.0)
        c.seconds["shading"] += sum(v for k, v in steps.items() if k != "gbuffer")
        LC._steps(ctx, steps)
        LC._count_samples(ctx, totals["light_samples"], totals["light_samples"] - totals["reused"])
        ctx.extra["gpu"] = {"renderer": self.fr.dev.renderer, "context": self.fr.dev.source,
                            "timing": self.fr.timer.method}
        return img


def _begin(ctx, name: str, cut: int):
    """A frame of renderer ``name`` (its cut size checked) with the frame's G-buffer traced."""
    cut = _check_cut(name, cut)
    lc = LightcutsFrame(ctx)
    with lc.step("gbuffer"):
        g = lc.gbuffer("full", ctx.width, ctx.height, True)
    return lc, g, cut


def _end(lc: LightcutsFrame, g: GBuffer, rspp: int | None, max_rspp: int, lspp_bounce: int = 1,
         passes: int = 1) -> np.ndarray:
    """The diffuse radiance (the mean of ``passes``), the glossy pass and the frame."""
    diffuse = g.read("rad")[:, :3] / passes
    glossy, rays = lc.glossy(g, rspp, max_rspp, lc.ctx.params["seed"], lspp_bounce)
    return lc.finish(g, diffuse, glossy, rays)


def run_sl_uniform(ctx):
    """``sl`` (``sl_e``, ``sl_f``, ``sl_p``) on the GPU (see :func:`renderers.lightcuts.plugin.run_sl_uniform`)."""
    p = ctx.params
    lc, g, cut = _begin(ctx, "sl.lspp", p["lspp"])
    lc.lightcuts(g, p["lspp"], cut, p["seed"])
    return _end(lc, g, p["rspp"], p["rspp"])


def run_sl_as(ctx):
    """``sl_as`` on the GPU: the AFSM (seed 003 Eq 1) of the G-buffer read back sets both budgets."""
    p = ctx.params
    lc, g, cut = _begin(ctx, "sl_as.max_lspp", p["max_lspp"])
    with lc.step("gbuffer"):
        fpsm_controls(lc, g, None, "afsm", 0.5, p["max_lspp"], p["max_rspp"])
    lc.lightcuts(g, None, cut, p["seed"])
    ctx.extra["afsm"] = read_map(lc, g)
    return _end(lc, g, None, p["max_rspp"])


def run_fsl(ctx):
    """``fsl`` on the GPU (seed 003 Algorithm 1; see :func:`renderers.lightcuts.plugin.run_fsl`)."""
    p = ctx.params
    w, h = ctx.width, ctx.height
    lc, g, cut = _begin(ctx, "fsl.max_lspp", p["max_lspp"])
    wl, hl = LC._low_res(w, h)
    with lc.step("gbuffer"):
        low = lc.gbuffer("low", wl, hl, False)
    lc.lightcuts(low, p["max_lspp"], cut, p["seed"], id_base=w * h, steps=("low_res",) * 3, low_res=True)
    with lc.step("fpsm"):
        fpsm_controls(lc, g, low, check_reading(p["fpsm_reading"]), check_alpha(p["alpha"]), p["max_lspp"],
                      p["max_rspp"])
    lc.lightcuts(g, None, cut, p["seed"], multires=bool(p["multires"]))
    reused = int(g.read("pix", np.int32)[:, 2].sum())
    ctx.extra.update(fpsm=read_map(lc, g), reused=reused, fpsm_reading=p["fpsm_reading"])
    return _end(lc, g, None, p["max_rspp"])


def run_sl_gt(ctx):
    """``sl_gt`` on the GPU: ``ceil(lspp / max_lspp)`` passes of ``max_lspp`` nodes averaged, ``rspp`` glossy rays
    with 4-node bounces (see :func:`renderers.lightcuts.plugin.run_sl_gt`)."""
    p = ctx.params
    lc, g, cut = _begin(ctx, "sl_gt.max_lspp", p["max_lspp"])
    passes = max(1, math.ceil(p["lspp"] / p["max_lspp"]))
    lc.lightcuts(g, p["max_lspp"], cut, [p["seed"] * 100003 + k for k in range(passes)])
    ctx.extra["passes"] = passes
    return _end(lc, g, p["rspp"], p["rspp"], lspp_bounce=4, passes=passes)
