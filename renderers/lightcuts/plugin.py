"""Renderer plug-ins of issue 6 on the scene model of ``renderers``: ``fsl``, ``sl_e``, ``sl_f``, ``sl_p``,
``sl_as``, ``sl_gt``.

Every plug-in renders one frame: primary rays through pixel centres (Embree via ``renderers.tracer``), a
G-buffer (hit position, face normal turned towards the camera, textured albedo of the scene's materials),
direct diffuse light from the scene's lights through a light tree (emissive triangles become one-sided point
lights at their centroids with ``L_e · area``, large ones split first, ``mesh_lights``; point lights are
isotropic; directional lights are not part of
the many-light model and are ignored, counted in ``extra["directional_lights_ignored"]``), plus emission and
ambient as in the built-in renderers. Glossy and metallic materials add the one-bounce glossy pass
(``glossy.py``, seed 003 Algorithm 1 line 16–17), skipped when the scene has none.

* ``fsl`` — ours: ``foveated_lightcuts`` (FPSM budgets, multi-resolution selection), ``rspp = ceil(MAX_rspp ·
  map)`` glossy rays per glossy pixel; ``fpsm_reading`` chooses the reading of Eq 4–8 (``fpsm.fpsm_map``).
* ``sl_e``, ``sl_f``, ``sl_p`` — stochastic lightcuts with a uniform ``lspp`` and ``rspp`` per pixel (the
  three differ only in how the tables choose the counts: equal time, equal foveal MSE, equal peripheral MSE).
* ``sl_as`` — counts ``ceil(AFSM · MAX)`` with Stengel's adaptive foveated sampling map (``fb_st`` of Eq 1; it
  does not go through Eq 4–8, so it has no ``fpsm_reading``).
* ``sl_gt`` — ground truth: ``passes`` independent SL estimates of ``MAX_lspp`` nodes averaged (2048 light
  samples per pixel by default) and 2048 glossy rays, in tiles.

Stats extras: ``steps`` (seconds per step of seed 003 Fig 9: ``gbuffer``, [``low_res``, ``fpsm``,] ``cuts``,
``select``, ``shade``, ``glossy``), ``light_samples`` (light samples drawn per frame, the low-resolution pass
included) and ``traversals`` (those that descended the light tree, i.e. not reused), ``spp``, ``glossy_rays``.

The velocity buffer is the screen motion from ``camera.previous`` (zero without one).
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit, prange

from renderers._shade import hit_surface
from renderers.plugin_types import Param, RendererPlugin, StrengthSpec
from renderers.projection import view_projection

from .foveated import foveated_lightcuts
from .fpsm import (ALPHA, FPSM_READINGS, acuity_map, budget_map, eccentricity_map, light_budget, screen_velocity,
                   spatiotemporal_feature)
from .glossy import glossy_pass
from .sampling import GBuffer, ray_offset_for, stochastic_lightcuts
from .tree import LightTree, build_light_tree
from .visibility import EmbreeOccluder

_TREES: dict[str, LightTree] = {}
_OCCLUDERS: dict[str, EmbreeOccluder] = {}


def split_triangles(tri: np.ndarray, times: int) -> np.ndarray:
    """Midpoint subdivision, ``times`` rounds: ``(m, 3, 3)`` triangles -> ``(m 4^times, 3, 3)``, same winding."""
    for _ in range(times):
        a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        tri = np.stack([np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))],
                       axis=1).reshape(-1, 3, 3)
    return tri


def mesh_lights(vertices, faces, emission, max_edge: float, max_splits: int = 4):
    """Point lights of emissive triangles: ``(positions, normals, intensities)``.

    Triangles whose longest edge exceeds ``max_edge`` are split ``ceil(log2(edge / max_edge))`` times (at most
    ``max_splits``: 4^k pieces); each piece is a one-sided light at its centroid with intensity
    ``L_e · area`` along its normal (the scene model's emitter, so the total power is unchanged).
    """
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    emission = np.asarray(emission, dtype=np.float64).reshape(-1, 3)
    edge = np.max(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2), axis=1) if len(tri) else np.zeros(0)
    with np.errstate(divide="ignore"):
        k = np.clip(np.ceil(np.log2(np.maximum(edge, 1e-300) / max_edge)), 0, max_splits).astype(int)
    pos, nrm, rgb = [np.zeros((0, 3))], [np.zeros((0, 3))], [np.zeros((0, 3))]
    for times in np.unique(k):
        sel = k == times
        sub = split_triangles(tri[sel], int(times))
        cross = np.cross(sub[:, 1] - sub[:, 0], sub[:, 2] - sub[:, 0])
        area2 = np.linalg.norm(cross, axis=1)
        ok = area2 > 0
        pos.append(sub[ok].mean(axis=1))
        nrm.append(cross[ok] / area2[ok, None])
        rgb.append(np.repeat(emission[sel], 4 ** int(times), axis=0)[ok] * 0.5 * area2[ok, None])
    return np.concatenate(pos), np.concatenate(nrm), np.concatenate(rgb)


def scene_light_tree(scene, max_edge_frac: float = 0.01) -> LightTree:
    """Light tree of a ``renderers.scene.Scene`` (built once per scene content).

    Emissive triangles become point lights (``mesh_lights``, split until their edges are below
    ``max_edge_frac`` of the scene diagonal); point lights are isotropic; a ``VPLScene``'s VPLs are added.
    """
    key = f"{scene.content_hash()}:{max_edge_frac}"
    tree = _TREES.get(key)
    if tree is None:
        em = np.array([m.emissive for m in scene.materials])[scene.material_ids]
        emission = np.array([m.emission for m in scene.materials])[scene.material_ids[em]]
        lights = [mesh_lights(scene.vertices, scene.faces[em], emission, max_edge_frac * scene.scale)]
        if getattr(scene, "vpl", None) is not None:
            lights.append(scene.vpl)
        if scene.point_lights:
            lights.append((np.array([L.position for L in scene.point_lights], dtype=np.float64),
                           np.zeros((len(scene.point_lights), 3)),
                           np.array([L.intensity for L in scene.point_lights], dtype=np.float64)))
        pos, nrm, rgb = (np.concatenate([x[i] for x in lights]) for i in range(3))
        tree = build_light_tree(pos, rgb, nrm)
        _TREES.clear()
        _TREES[key] = tree
    return tree


def scene_occluder(scene) -> EmbreeOccluder | None:
    if not scene.shadows:
        return None
    key = scene.content_hash()
    occ = _OCCLUDERS.get(key)
    if occ is None:
        occ = EmbreeOccluder(scene.vertices, scene.faces)
        _OCCLUDERS.clear()
        _OCCLUDERS[key] = occ
    return occ


@njit(cache=True, parallel=True)
def _hit_materials(P, Ng, mid, mat_f, mat_i, ambient, albedo, base, ks, s_exp, glossy):
    """Per hit: diffuse albedo (0 for metallic), emission + ambient, specular colour, exponent, glossy flag."""
    for i in prange(P.shape[0]):
        glossy[i] = hit_surface(i, mid[i], P, Ng, mat_f, mat_i, ambient, albedo, base, ks, s_exp)


class Hits:
    """G-buffer of rays ``origin + t d``: ``gbuf`` (GBuffer), ``base`` emission + ambient, ``ks``, ``s_exp``,
    ``glossy`` (bool), ``view`` (unit direction to the viewer) — flat arrays of the rays' count."""

    def __init__(self, tracer, origins, dirs, shape=None):
        sc = tracer.scene
        d = np.ascontiguousarray(dirs, dtype=np.float64)
        o = np.broadcast_to(np.asarray(origins, dtype=np.float64), d.shape)
        res = tracer.es.run(np.ascontiguousarray(o, dtype=np.float32), np.ascontiguousarray(d, dtype=np.float32),
                            output=1)
        prim = np.asarray(res["primID"])
        hit = prim >= 0
        pi = np.where(hit, prim, 0)
        t = np.asarray(res["tfar"], dtype=np.float64)
        P = np.where(hit[:, None], o + d * t[:, None], 0.0)
        tri = sc.vertices[sc.faces[pi]].astype(np.float64)
        Ng = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        Ng /= np.maximum(np.linalg.norm(Ng, axis=1, keepdims=True), 1e-300)
        Ng[np.einsum("ij,ij->i", Ng, d) > 0] *= -1.0
        n = len(d)
        self.albedo = np.zeros((n, 3))
        self.base = np.zeros((n, 3))
        self.ks = np.zeros((n, 3))
        self.s_exp = np.zeros(n)
        self.glossy = np.zeros(n, dtype=np.bool_)
        _hit_materials(P, Ng, sc.material_ids[pi], tracer.mat_f, tracer.mat_i, tracer.ambient, self.albedo,
                       self.base, self.ks, self.s_exp, self.glossy)
        self.glossy &= hit
        self.albedo[~hit] = 0.0  # a miss has no surface (the FPSM's albedo gradient sees the background as 0)
        self.base[~hit] = tracer.background
        self.hit = hit
        self.view = -d
        shape = (n,) if shape is None else tuple(shape)
        self.gbuf = GBuffer.create(P.reshape(shape + (3,)), np.where(hit[:, None], Ng, 0.0).reshape(shape + (3,)),
                                   self.albedo.reshape(shape + (3,)), valid=hit)
        tracer.counters.rays_primary += n
        tracer.counters.missed_rays += int(n - hit.sum())


def primary_hits(tracer, camera, width: int, height: int) -> Hits:
    from renderers.projection import camera_rays

    x, y = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    return Hits(tracer, np.asarray(camera.position, dtype=np.float64), camera_rays(camera, width, height, x, y),
                (height, width))


def _low_res(width: int, height: int) -> tuple[int, int]:
    """Seed 003: ``(w', h') = (w/8, h/8)`` (at least one pixel)."""
    return max(1, width // 8), max(1, height // 8)


def scene_has_glossy(scene) -> bool:
    """Whether a glossy or metallic material exists: the glossy pass runs only then (Algorithm 1 line 16)."""
    return any(m.kind in ("glossy", "metallic") for m in scene.materials)


def glossy_budget(fpsm_map, max_rspp: int) -> np.ndarray:
    """``fsl``'s glossy rays per pixel, ``MAX_rspp · map`` (Algorithm 1 line 17) rounded up; 0 where map is 0."""
    return budget_map(fpsm_map, max_rspp, 0)


def frame_output(ctx, base, diffuse, glossy, glossy_mask, rays: int) -> np.ndarray:
    """The frame ``base + diffuse + glossy`` and its extras (both backends; arrays ``(h·w, 3)``, ``glossy`` None
    when no glossy ray was cast)."""
    h, w = ctx.height, ctx.width
    img = base + diffuse.reshape(-1, 3)
    ctx.extra["diffuse_image"] = img.reshape(h, w, 3).astype(np.float32)
    if glossy is not None:
        img = img + glossy
        ctx.extra["glossy_image"] = glossy.reshape(h, w, 3).astype(np.float32)
    ctx.extra["glossy_rays"] = int(rays)
    ctx.extra["glossy_pass"] = scene_has_glossy(ctx.scene)
    ctx.extra["directional_lights_ignored"] = len(ctx.scene.directional_lights)
    ctx.extra["glossy_mask"] = np.asarray(glossy_mask).reshape(h, w).copy()
    return img.reshape(h, w, 3).astype(np.float32)  # linear, unexposed (the renderer output contract)


def _finish(ctx, hits: Hits, diffuse: np.ndarray, rspp, seed: int, lspp_bounce: int = 1) -> np.ndarray:
    """Emission + ambient + diffuse + the glossy pass (only if the scene has a glossy or metallic material)."""
    t0 = time.perf_counter()
    h, w = ctx.height, ctx.width
    tree, occ = scene_light_tree(ctx.scene), scene_occluder(ctx.scene)
    ctx.tracer.counters.shading_points += int(hits.hit.sum())  # every primary hit is shaded (missed rays not)
    gl, rays = None, 0
    if scene_has_glossy(ctx.scene) and hits.glossy.any():
        counts = np.where(hits.glossy, np.broadcast_to(np.asarray(rspp), (h, w)).reshape(-1), 0).astype(np.int64)
        gl, rays = glossy_pass(hits, counts, seed, lambda o, d: Hits(ctx.tracer, o, d), tree, occ, lspp_bounce,
                               ray_offset=ray_offset_for(tree, hits.gbuf))
    img = frame_output(ctx, hits.base, diffuse, gl, hits.glossy, rays)
    _steps(ctx, {"glossy": time.perf_counter() - t0})
    return img


def _steps(ctx, timings: dict) -> None:
    """Add seconds per step (seed 003 Fig 9) to ``extra["steps"]``."""
    steps = ctx.extra.setdefault("steps", {})
    for k, v in timings.items():
        steps[k] = round(steps.get(k, 0.0) + v, 6)


def _count_samples(ctx, light_samples: int, traversals: int) -> None:
    """The sample accounting of a frame: light samples drawn (shadow-ray candidates, every pass included) and
    how many of them descended the light tree (the rest were reused from the low-resolution pass)."""
    ctx.extra["light_samples"] = ctx.extra.get("light_samples", 0) + int(light_samples)
    ctx.extra["traversals"] = ctx.extra.get("traversals", 0) + int(traversals)


def _sl(ctx, budget, seed: int, hits: Hits | None = None):
    tree, occ = scene_light_tree(ctx.scene), scene_occluder(ctx.scene)
    t0 = time.perf_counter()
    if hits is None:
        hits = primary_hits(ctx.tracer, ctx.camera, ctx.width, ctx.height)
        _steps(ctx, {"gbuffer": time.perf_counter() - t0})
    t0 = time.perf_counter()
    timings: dict = {}
    res = stochastic_lightcuts(tree, hits.gbuf, budget, seed=seed, occluded=occ, timings=timings)
    ctx.tracer.counters.add_time("shading", t0)
    ctx.tracer.counters.rays_shadow += res.shadow_rays
    ctx.extra["spp"] = res.samples.reshape(ctx.height, ctx.width)
    _steps(ctx, timings)
    n = int(res.samples.sum())
    _count_samples(ctx, n, n)
    return hits, res.radiance


def run_sl_uniform(ctx):
    p = ctx.params
    hits, diffuse = _sl(ctx, int(p["lspp"]), p["seed"])
    return _finish(ctx, hits, diffuse, int(p["rspp"]), p["seed"])


def velocity_buffer(ctx, position, hit) -> np.ndarray:
    """Screen-space motion (pixels, (h, w, 2)) of the visible points ``position`` (h·w, 3) from the previous
    frame's camera to this one (seed 003 §3.1's velocity buffer); zero without a previous camera and where
    ``hit`` is false."""
    h, w = ctx.height, ctx.width
    if ctx.previous_camera is None:
        return np.zeros((h, w, 2))
    pos = np.asarray(position, dtype=np.float64).reshape(h, w, 3)
    vel = screen_velocity(pos, view_projection(ctx.camera, w, h), view_projection(ctx.previous_camera, w, h),
                          w, h)
    return np.where(np.asarray(hit).reshape(h, w, 1), vel, 0.0)


def _eccentricity(ctx):
    return eccentricity_map(ctx.geometry)


def afsm_budgets(ctx, normal, albedo, velocity) -> tuple[np.ndarray, np.ndarray]:
    """``sl_as``: Stengel's adaptive foveated sampling map (seed 003 Eq 1 with Eq 2's acuity, no luminance term)
    of the G-buffer ``(h, w, 3)`` maps, as light and glossy budgets ``ceil(AFSM · MAX)`` (also in
    ``extra["afsm"]``)."""
    h, w = ctx.height, ctx.width
    afsm = spatiotemporal_feature(acuity_map(_eccentricity(ctx)), np.reshape(normal, (h, w, 3)),
                                  np.reshape(albedo, (h, w, 3)), velocity)
    ctx.extra["afsm"] = afsm.astype(np.float32)
    max_rspp = ctx.params["max_rspp"]  # 0: no glossy rays (as on the GPU), not a budget of at least one
    rspp = light_budget(afsm, max_rspp) if max_rspp > 0 else np.zeros(afsm.shape, dtype=np.int64)
    return light_budget(afsm, ctx.params["max_lspp"]), rspp


def run_sl_as(ctx):
    """Stengel's adaptive foveated sampling map (Eq 1 without the luminance term) drives both counts."""
    p = ctx.params
    t0 = time.perf_counter()
    hits = primary_hits(ctx.tracer, ctx.camera, ctx.width, ctx.height)
    lspp, rspp = afsm_budgets(ctx, hits.gbuf.normal, hits.albedo, velocity_buffer(ctx, hits.gbuf.position, hits.hit))
    _steps(ctx, {"gbuffer": time.perf_counter() - t0})
    _, diffuse = _sl(ctx, lspp, p["seed"], hits)
    return _finish(ctx, hits, diffuse, rspp, p["seed"])


def run_fsl(ctx):
    p = ctx.params
    tree, occ = scene_light_tree(ctx.scene), scene_occluder(ctx.scene)
    h, w = ctx.height, ctx.width
    t0 = time.perf_counter()
    hits = primary_hits(ctx.tracer, ctx.camera, w, h)
    wl, hl = _low_res(w, h)
    from renderers.projection import camera_rays

    x, y = np.meshgrid((np.arange(wl) + 0.5) * w / wl, (np.arange(hl) + 0.5) * h / hl)
    low = Hits(ctx.tracer, np.asarray(ctx.camera.position, dtype=np.float64), camera_rays(ctx.camera, w, h, x, y),
               (hl, wl))
    ecc, vel = _eccentricity(ctx), velocity_buffer(ctx, hits.gbuf.position, hits.hit)
    _steps(ctx, {"gbuffer": time.perf_counter() - t0})
    t0 = time.perf_counter()
    res = foveated_lightcuts(tree, hits.gbuf, low.gbuf, ecc, vel, p["alpha"], p["max_lspp"], seed=p["seed"],
                             occluded=occ, multires=p["multires"], fpsm_reading=p["fpsm_reading"])
    ctx.tracer.counters.add_time("shading", t0)
    ctx.tracer.counters.rays_shadow += res.shadow_rays
    ctx.extra.update(fpsm=res.fpsm.map.astype(np.float32), spp=res.samples, reused=int(res.reused.sum()),
                     fpsm_reading=res.fpsm.reading)
    _steps(ctx, res.timings)
    n = int(res.samples.sum()) + res.low_res_samples
    _count_samples(ctx, n, n - int(res.reused.sum()))
    return _finish(ctx, hits, res.radiance, glossy_budget(res.fpsm.map, p["max_rspp"]), p["seed"])


def run_sl_gt(ctx):
    """Averages ``ceil(lspp / max_lspp)`` independent estimates of ``max_lspp`` nodes (progressive)."""
    p = ctx.params
    passes = max(1, math.ceil(p["lspp"] / p["max_lspp"]))
    hits = None
    acc = None
    for k in range(passes):
        ctx.check_cancel()
        hits, diffuse = _sl(ctx, int(p["max_lspp"]), p["seed"] * 100003 + k, hits)
        acc = diffuse if acc is None else acc + diffuse
    ctx.extra["passes"] = passes
    return _finish(ctx, hits, acc / passes, int(p["rspp"]), p["seed"], lspp_bounce=4)


def sl_gt_preview(params: dict) -> dict:
    """The ground truth's thumbnail (the simulated observer's 64-pixel frames, its reference included): at most
    256 light + 256 glossy samples per pixel instead of 2048 + 2048, 6-8x faster (64x36 on the CPU: 1.1-3.3 s
    instead of 7.7-16.7 s). Measured on the five seed 003 scenes at 36.7° (foveated difference, the observer's
    measure, gaze at (40, 12)): the 256-sample GT differs from the 2048-sample one by 0.001-0.037, 4-80x less than
    any condition does (EC, SL_e 8+8, SL_as, SL_f 40+40, SL_e 1+0: 0.003-0.46), and every condition's difference
    moves by at most 0.004 with the reference, so the order of the conditions, which the observer answers from,
    is kept on every scene (docs/live.md)."""
    return {**params, "lspp": min(int(params.get("lspp", 2048)), 256),
            "rspp": min(int(params.get("rspp", 2048)), 256)}


_SEED = {"seed": Param(int, 0, 0, 2 ** 31 - 1, help="random stream")}
_MAXES = {"max_lspp": Param(int, 48, 1, 4096, help="MAX_lspp (seed 003: 48)"),
          "max_rspp": Param(int, 48, 0, 4096, help="MAX_rspp (seed 003: 48)")}
_BPP = 200.0  # full-frame float64 buffers; the per-sample arrays are tiled

FSL = RendererPlugin(
    "fsl", "foveated stochastic lightcuts (seed 003): FPSM budgets, multi-resolution selection",
    {"alpha": Param(float, 0.1, ALPHA.low, ALPHA.high, high_open=True, help="maximum imperceptibility threshold"),
     **_MAXES, "multires": Param(bool, True, help="multi-resolution light-sample selection"),
     "fpsm_reading": Param(str, FPSM_READINGS[0], choices=FPSM_READINGS,
                           help="reading of seed 003 Eq 4-8: derived (Eq 7 with its sign corrected: rho = "
                                "sqrt(D / -2 ln(M - alpha))), blur (Eq 6 as a spatial blur: rho = 1/rho_derived, "
                                "edges first, flat regions incl. the fovea least) or retained (map = (M - alpha) / "
                                "(1 - alpha), no rho); docs/lightcuts.md"),
     **_SEED},
    run_fsl, bytes_per_pixel=_BPP, gpu="renderers.gpu.lightcuts:run_fsl",
    strength=StrengthSpec("alpha", "higher", "light_samples"))
#: Uniform counts; the presets differ only in how seed 003's tables choose the counts for a comparison with
#: fsl: equal time (sl_e), equal foveal MSE (sl_f), equal peripheral MSE (sl_p).
SL = RendererPlugin(
    "sl", "stochastic lightcuts, uniform light and glossy samples per pixel",
    {"lspp": Param(int, 8, 1, 4096, help="light samples (cut nodes) per pixel"),
     "rspp": Param(int, 8, 0, 4096, help="glossy rays per glossy pixel"), **_SEED},
    run_sl_uniform, bytes_per_pixel=_BPP, gpu="renderers.gpu.lightcuts:run_sl_uniform",
    strength=StrengthSpec("lspp", "lower", "light_samples"),
    presets={"sl_e": ("stochastic lightcuts, uniform counts (equal time to fsl)", {}),
             "sl_f": ("stochastic lightcuts, uniform counts (equal foveal MSE to fsl)", {}),
             "sl_p": ("stochastic lightcuts, uniform counts (equal peripheral MSE to fsl)", {})})
SL_AS = RendererPlugin("sl_as", "stochastic lightcuts driven by Stengel's adaptive foveated sampling map",
                       {**_MAXES, **_SEED}, run_sl_as, bytes_per_pixel=_BPP,
                       gpu="renderers.gpu.lightcuts:run_sl_as",
                       strength=StrengthSpec("max_lspp", "lower", "light_samples"))
SL_GT = RendererPlugin(
    "sl_gt", "ground truth: 2048 light samples + 2048 glossy rays per pixel, progressive",
    {"lspp": Param(int, 2048, 1, 1 << 20, help="light samples per pixel"),
     "rspp": Param(int, 2048, 0, (1 << 20) - 1, help="glossy rays per glossy pixel"),
     "max_lspp": Param(int, 48, 1, 4096, help="nodes per pass"), **_SEED},
    run_sl_gt, bytes_per_pixel=_BPP, gpu="renderers.gpu.lightcuts:run_sl_gt", preview=sl_gt_preview)
