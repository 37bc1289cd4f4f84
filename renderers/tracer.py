"""Visibility with Embree (``embreex``) and shading of hit points, in bounded chunks.

:class:`Tracer` wraps one :class:`~renderers.scene.Scene`: the Embree BVH, the packed material and light tables
and the counters of a render. Rays are float32 (Embree's precision); shadow-ray origins are offset along the
normal by ``1e-5`` of the scene's diagonal.
"""

from __future__ import annotations

import time
import weakref
from dataclasses import dataclass, field

import numpy as np

from . import _shade as S
from .plugin_types import RenderCancelled
from .projection import camera_rays
from .scene import Camera, Scene

#: Points shaded per chunk: bounds the (points x lights) temporaries (~ CHUNK * lights * 17 bytes).
CHUNK = 1 << 15
#: Points shaded per chunk of a cancellable render (:attr:`Tracer.cancel` set): half a chunk, 30-50 ms of
#: shading on this machine's 2 cores (cornell, idle), so a cancelled render stops within the live window's
#: 100-ms bound for Escape. Smaller chunks cost more than they gain (each parallel kernel call synchronises its
#: threads: an eighth of a chunk made a render 2.5x slower on a loaded machine). The image does not depend on
#: the chunk size (every point is shaded on its own).
CANCEL_CHUNK = CHUNK >> 1
_BVH_CACHE: "weakref.WeakKeyDictionary[Scene, object]" = weakref.WeakKeyDictionary()


@dataclass
class Counters:
    """Work done and skipped during one render (see the stats record of :func:`renderers.render`)."""

    shading_points: int = 0
    rays_primary: int = 0
    rays_shadow: int = 0
    missed_rays: int = 0
    offscreen_lp_pixels: int = 0
    shadow_rays_skipped: int = 0
    glossy_evaluations: int = 0
    lights_culled: int = 0
    reshaded_pixels: int = 0
    seconds: dict = field(default_factory=lambda: {"visibility": 0.0, "shading": 0.0, "antialias": 0.0,
                                                   "inverse_map": 0.0, "total": 0.0})

    def add_time(self, stage: str, t0: float) -> float:
        t = time.perf_counter()
        self.seconds[stage] += t - t0
        return t


def embree_scene(scene: Scene):
    """The committed Embree scene of ``scene`` (built once per Scene object)."""
    es = _BVH_CACHE.get(scene)
    if es is None:
        from embreex import mesh_construction, rtcore_scene

        es = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(es, scene.vertices, scene.faces)
        _BVH_CACHE[scene] = es
    return es


def pack_scene(sc: Scene, shadows: bool) -> dict:
    """Material and light tables of ``sc`` as the shading kernels read them (also uploaded by the GPU backend).

    ``mat_f`` (m, 14) float64 and ``mat_i`` (m, 2) int64 (see :func:`._shade.shade_contributions`); lights in the
    order point lights, emissive triangles, directional lights: ``L_pos``, ``L_int``, ``L_dir`` (k, 3),
    ``L_kind`` (k,), ``L_cast`` (k,) bool (``shadows`` and the light's own flag); ``ambient``, ``background``.
    """
    mats = sc.materials
    mat_f = np.array([[*m.albedo, *m.albedo2, *m.emission, m.texture_scale, 2.0 / m.roughness ** 2 - 2.0,
                       m.specular, float(m.kind == "metallic"), float(m.kind == "glossy")] for m in mats],
                     dtype=np.float64)
    mat_i = np.array([[S.TEX_NONE + ("none", "checker", "brick", "noise").index(m.texture),
                       ("diffuse", "glossy", "metallic").index(m.kind)] for m in mats], dtype=np.int64)
    pos, inten, dirs, kind, cast = [], [], [], [], []
    for L in sc.point_lights:
        pos.append(L.position), inten.append(L.intensity), dirs.append((0, 0, 0))
        kind.append(S.LIGHT_POINT), cast.append(L.shadows)
    ep, en, ei = sc.emitters()
    for p, n, i in zip(ep, en, ei):
        pos.append(p), inten.append(i), dirs.append(n), kind.append(S.LIGHT_EMITTER), cast.append(True)
    for L in sc.directional_lights:
        d = np.asarray(L.direction) / np.linalg.norm(L.direction)
        pos.append((0, 0, 0)), inten.append(L.irradiance), dirs.append(d)
        kind.append(S.LIGHT_DIRECTIONAL), cast.append(L.shadows)
    return {"mat_f": mat_f, "mat_i": mat_i,
            "L_pos": np.array(pos, dtype=np.float64).reshape(-1, 3),
            "L_int": np.array(inten, dtype=np.float64).reshape(-1, 3),
            "L_dir": np.array(dirs, dtype=np.float64).reshape(-1, 3),
            "L_kind": np.array(kind, dtype=np.int64),
            "L_cast": np.array(cast, dtype=np.bool_) & bool(shadows),
            "ambient": np.asarray(sc.ambient, dtype=np.float64),
            "background": np.asarray(sc.background, dtype=np.float32)}


class Tracer:
    """Traces and shades points of one scene; accumulates :class:`Counters`.

    Parameters
    ----------
    scene : Scene
    shadows : bool
        Cast shadow rays (also requires ``scene.shadows`` and the light's own flag).
    light_cull : float
        ``eps`` of the light-culling rule in :mod:`._shade` (0 disables culling).
    """

    def __init__(self, scene: Scene, *, shadows: bool = True, light_cull: float = 0.01):
        self.scene = scene
        self.es = embree_scene(scene)
        self.counters = Counters()
        self.light_cull = float(light_cull)
        self.offset = 1e-5 * scene.scale
        self.far = 4.0 * scene.scale
        self._pack(shadows and scene.shadows)
        #: ``cancel()`` -> True stops the render between chunks (:class:`~renderers.plugin_types.RenderCancelled`):
        #: every ray cast and every chunk of shaded points (:attr:`chunk`) asks it.
        self.cancel = None

    @property
    def chunk(self) -> int:
        """Points shaded per chunk: :data:`CANCEL_CHUNK` when the render can be cancelled, else :data:`CHUNK`."""
        return CHUNK if self.cancel is None else CANCEL_CHUNK

    def check_cancel(self) -> None:
        if self.cancel is not None and self.cancel():
            raise RenderCancelled

    def _pack(self, shadows: bool):
        vars(self).update(pack_scene(self.scene, shadows))

    # -- visibility --------------------------------------------------------------------------------------------
    def intersect(self, origin: np.ndarray, dirs: np.ndarray):
        """Closest hits of rays from ``origin`` (3,) along ``dirs`` (n, 3): ``(primID, tfar, Ng)``."""
        self.check_cancel()
        n = len(dirs)
        o = np.broadcast_to(np.asarray(origin, dtype=np.float32), (n, 3))
        res = self.es.run(np.ascontiguousarray(o), np.ascontiguousarray(dirs, dtype=np.float32), output=1)
        self.counters.rays_primary += n
        return res["primID"], res["tfar"], res["Ng"]

    def trace(self, camera: Camera, width: int, height: int, x, y):
        """Primary visibility of screen positions ``(x, y)``: ``(primID, tfar)`` (miss: primID -1)."""
        t0 = time.perf_counter()
        d = camera_rays(camera, width, height, x, y)
        prim, tfar, _ = self.intersect(np.asarray(camera.position), d)
        self.counters.add_time("visibility", t0)
        return prim, tfar

    # -- shading -----------------------------------------------------------------------------------------------
    def shade_hits(self, origin, dirs: np.ndarray, prim: np.ndarray, tfar: np.ndarray) -> np.ndarray:
        """Radiance (n, 3) float32 of rays ``origin + t dirs`` that hit ``prim`` at ``tfar`` (miss: background)."""
        n = len(dirs)
        out = np.empty((n, 3), dtype=np.float32)
        hit = prim >= 0
        out[~hit] = self.background
        self.counters.missed_rays += int(n - np.count_nonzero(hit))
        idx = np.nonzero(hit)[0]
        step = self.chunk
        for c0 in range(0, len(idx), step):
            sel = idx[c0:c0 + step]
            self.check_cancel()
            out[sel] = self._shade_chunk(origin, dirs[sel], prim[sel], tfar[sel])
        return out

    def _shade_chunk(self, origin, d, prim, t):
        sc = self.scene
        t0 = time.perf_counter()
        d = np.ascontiguousarray(d, dtype=np.float64)
        n = len(d)
        P = np.empty((n, 3))
        Ng = np.empty((n, 3))
        V = np.empty((n, 3))
        S.hit_geometry(np.asarray(origin, dtype=np.float64), d, np.ascontiguousarray(t, dtype=np.float64),
                       np.ascontiguousarray(prim), sc.vertices, sc.faces, P, Ng, V)
        mid = sc.material_ids[prim]
        k = len(self.L_kind)
        contrib = np.empty((n, k, 3), dtype=np.float32)
        base = np.empty((n, 3), dtype=np.float32)
        need = np.empty((n, k), dtype=np.bool_)
        counts = np.empty((n, 2), dtype=np.int64)
        S.shade_contributions(P, Ng, V, mid, self.mat_f, self.mat_i, self.L_pos, self.L_int, self.L_dir,
                              self.L_kind, self.ambient, self.light_cull, contrib, base, need, counts)
        c = self.counters
        c.shading_points += n
        c.glossy_evaluations += int(counts[:, 0].sum())
        c.lights_culled += int(counts[:, 1].sum())
        n_need = int(np.count_nonzero(need))
        n_cast = int(np.count_nonzero(need[:, self.L_cast])) if self.L_cast.any() else 0
        c.shadow_rays_skipped += n * k - n_cast
        t0 = c.add_time("shading", t0)
        if n_cast:
            orig = np.empty((n_cast, 3), dtype=np.float32)
            dirs = np.empty((n_cast, 3), dtype=np.float32)
            dists = np.empty(n_cast, dtype=np.float32)
            pairs = np.empty(n_cast, dtype=np.int64)
            S.shadow_rays(P, Ng, need, self.L_cast, self.L_pos, self.L_dir, self.L_kind, self.offset, self.far,
                          orig, dirs, dists, pairs)
            t0 = c.add_time("shading", t0)
            hit = self.es.run(orig, dirs, dists=dists, query="OCCLUDED")
            c.rays_shadow += n_cast
            t0 = c.add_time("visibility", t0)
            S.clear_occluded(need, pairs, hit)
        del n_need
        out = np.empty((n, 3), dtype=np.float32)
        S.accumulate(contrib, need, base, out)
        c.add_time("shading", t0)
        return out

    def render_points(self, camera: Camera, width: int, height: int, x, y, keep_hits: bool = False):
        """Ray-cast and shade screen positions ``(x, y)`` (any shape, flattened): radiance (n, 3) float32.

        With ``keep_hits`` also the hit triangle ids and distances (for reprojection).
        """
        x = np.asarray(x, dtype=np.float64).ravel()
        y = np.asarray(y, dtype=np.float64).ravel()
        out = np.empty((x.size, 3), dtype=np.float32)
        if keep_hits:
            prims = np.empty(x.size, dtype=np.int32)
            tfars = np.empty(x.size, dtype=np.float32)
        step = 4 * CHUNK
        org = np.asarray(camera.position, dtype=np.float64)
        for c0 in range(0, x.size, step):
            t0 = time.perf_counter()
            d = camera_rays(camera, width, height, x[c0:c0 + step], y[c0:c0 + step])
            prim, tfar, _ = self.intersect(org, d)
            self.counters.add_time("visibility", t0)
            out[c0:c0 + step] = self.shade_hits(org, d, prim, tfar)
            if keep_hits:
                prims[c0:c0 + step], tfars[c0:c0 + step] = prim, tfar
        return (out, prims, tfars) if keep_hits else out
