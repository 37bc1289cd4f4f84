"""GPU versions of the pipelines of :mod:`renderers.pipeline`: GT, the LP buffer (ray casting and deferred),
the LP filters, the inverse mapping, the foveal Gaussian and the reprojection of ``rep``.

Each function issues compute dispatches on a :class:`~renderers.gpu.frame.Frame`; images stay on the GPU
until :func:`read_image`.
"""

from __future__ import annotations

import math

import numpy as np

from .. import pipeline as cpu
from ..constants import LP_GAUSS_RADIUS, LP_GAUSS_SIGMA, LP_PAD_FXAA, LP_PAD_GAUSS
from .bindings import UNIFORMS
from .frame import C, Frame
from .upload import camera_uniforms


def read_image(buf, width: int, height: int) -> np.ndarray:
    """An (H, W, 3) float32 image from a buffer of 3 floats per pixel (row-major)."""
    img = np.empty((height, width, 3), dtype=np.float32)
    buf.read_into(img, size=img.nbytes)
    return img


def render_gt(fr: Frame, camera, width: int, height: int, spp: int = 1, pixel_filter: str = "box"):
    """GT into the pooled buffer ``image`` (3 floats per pixel); see :func:`renderers.pipeline.render_gt`.

    Rows are rendered in batches of at most :attr:`~renderers.gpu.frame.Frame.batch` samples; with the tent filter
    the sample rows around a batch boundary are carried over, so that every sample is traced once.
    """
    img = fr.pool.get("image", 12 * width * height)
    side = math.isqrt(spp)
    defines = {"SPP": spp, "SPP_SIDE": side}
    cam = camera_uniforms(camera, width, height)
    origin = camera.position
    rows = max(1, fr.batch // (width * spp))
    if spp == 1:
        for y0 in range(0, height, rows):
            n = (min(height, y0 + rows) - y0) * width
            with fr.timer("visibility"):
                fr.run_pass("gen_gt", n, fr.sample_buffers(n), {**cam, "u_y0": y0, "u_width": width,
                                                                "u_slot_base": y0 * width}, defines)
            fr.shade_batch(origin, n, img, n=n)
            fr.drain_counters()
        return img
    halo = 1 if pixel_filter == "tent" else 0
    row_bytes = 12 * width * spp
    tiles = [fr.pool.get(f"gt_tile{k}", row_bytes * (rows + 2 * halo)) for k in (0, 1)]
    for t, y0 in enumerate(range(0, height, rows)):
        y1 = min(height, y0 + rows)
        s0, n0, s1 = max(0, y0 - halo), min(height, y0 + halo), min(height, y1 + halo)
        n0 = s0 if y0 == 0 else n0
        buf, prev = tiles[t % 2], tiles[(t + 1) % 2]
        if n0 > s0:  # carry the sample rows [s0, n0) from the end of the previous tile
            fr.dev.ctx.copy_buffer(buf, prev, (n0 - s0) * row_bytes, read_offset=prev_rows * row_bytes)
        n = (s1 - n0) * width * spp
        with fr.timer("visibility"):
            fr.run_pass("gen_gt", n, fr.sample_buffers(n), {**cam, "u_y0": n0, "u_width": width,
                                                            "u_slot_base": (n0 - s0) * width * spp}, defines)
        fr.shade_batch(origin, n, buf, n=n)
        with fr.timer("antialias"):
            fr.run_pass("resolve", (y1 - y0) * width, {"outbuf": buf, "img": img},
                   {"u_width": width, "u_y0": y0, "u_s0": s0, "u_s1": s1, "u_tent": int(halo)}, defines)
        prev_rows = s1 - s0 - 2 * halo
        fr.drain_counters()
    return img


def _weights(w) -> tuple:
    """Filter weights as the uniform array ``u_w`` (:data:`renderers.gpu.bindings.UNIFORMS`), zero-padded."""
    size = int(UNIFORMS["u_w"].type.split("[")[1].rstrip("]"))
    if len(w) > size:
        raise ValueError(f"{len(w)} filter weights do not fit the shaders' u_w[{size}]")
    return tuple(float(x) for x in w) + (0.0,) * (size - len(w))


# -- the LP buffer -------------------------------------------------------------------------------------------------
def inverse_offsets(layout, u, v):
    """Screen offsets from the gaze of LP positions ``(u, v)``: the CPU's inverse kernel (float64) without the
    gaze shift (:func:`renderers.foveation._kernels.map_points`)."""
    from ..foveation import _kernels as K

    u = np.ascontiguousarray(u, dtype=np.float64)
    v = np.ascontiguousarray(v, dtype=np.float64)
    dx, dy = np.empty_like(u), np.empty_like(u)
    K.map_points(layout.kernel, K.INVERSE, u, v, layout.P, 0.0, 0.0, dx, dy)
    return dx, dy


class LPTables:
    """The LP layout of one mapping on the GPU: parameter vector, per-column table and (VaFR) the u(r) table.

    Built from the CPU's :class:`renderers.pipeline.LPLayout` (one source of truth): ``P`` is
    ``mapping._params_vector()``; column ``c`` holds ``r(c + 0.5)`` from ``mapping.inverse``, ``L[c] / 2 pi``,
    ``n[c]`` and ``L[c]``. VaFR's mapping does not depend on the gaze, so its tables (including the u(r) table,
    built out to the display's diagonal) serve every gaze; LMFR's and LaFR's ``P`` do (``ln(1 + R)``, R the
    farthest corner), so they are rebuilt per gaze without a table and the shaders evaluate the kernel
    generated from the CPU code (a table there would cost 14-118 ms of CPU per gaze at 2468 x 2740).
    """

    def __init__(self, fr: Frame, layout, mapping, offsets=None):
        self.layout = layout
        self.method = layout.method
        self.kernel = layout.kernel
        self.w, self.h, self.w_eff = layout.w, layout.h, layout.w_eff
        self.n_mask = int(layout.n.sum())
        self.c_r = mapping.display.c_r
        # r(c + 0.5): the inverse kernel at angle 0 (r cos 0 = r exactly), relative to the gaze
        r = inverse_offsets(layout, np.arange(self.w) + 0.5, np.zeros(self.w))[0]
        cols = np.column_stack([r, layout.L / (2 * math.pi), layout.n, layout.L]).astype(np.float32)
        dev = fr.dev
        vafr = self.method == "vafr"
        self.buffers = {"FP": dev.buffer(layout.P.astype(np.float32)),
                        "col_scale": dev.buffer(np.ones(self.w) if vafr else r)}
        self.images = {"t_cols": dev.float_texture("LP columns", cols),
                       "t_offs": offsets if offsets is not None else self.offset_table(fr, layout)}
        self.use_table = hasattr(layout, "utab")
        if self.use_table:
            self.buffers["utab"] = dev.buffer(np.column_stack([layout.utab, layout.exact]).astype(np.float32))
            self.inv_step, self.kmax = float(layout.inv_step), int(layout.utab.size - 2)

    @staticmethod
    def offset_table(fr: Frame, layout):
        """(w, h) RGBA32UI image of two float64 per LP pixel, gaze-independent: VaFR the screen offset of the
        pixel's centre from the gaze (the CPU's inverse kernel), LMFR/LaFR the unit vector of its row's angle
        ``2 pi (j + 0.5) / h`` (times the column's radius in the shader, as ``lmfr_inverse`` computes)."""
        jj, ii = np.mgrid[0:layout.h, 0:layout.w]
        if layout.method == "vafr":
            dx, dy = inverse_offsets(layout, ii.ravel() + 0.5, jj.ravel() + 0.5)
        else:
            th = 2.0 * math.pi * (jj.ravel() + 0.5) / float(layout.h)
            dx, dy = np.cos(th), np.sin(th)
        tex = fr.dev.image("LP offsets", (layout.w, layout.h), 4, dtype="u4")
        tex.write(np.column_stack([dx, dy]).astype(np.float64).tobytes())
        return tex

    def defines(self) -> dict:
        return {"METHOD": self.kernel, "USE_TABLE": int(self.use_table)}

    def uniforms(self, gaze) -> dict:
        u = {"u_gaze": tuple(float(g) for g in gaze), "u_gaze_d": tuple(float(g) for g in gaze), "u_lp_w": self.w,
             "u_lp_h": self.h, "u_w_eff": self.w_eff}
        if self.use_table:
            u.update(u_inv_step=self.inv_step, u_kmax=self.kmax)
        return u

    def release(self, dev, keep_offsets: bool = False) -> None:
        for b in self.buffers.values():
            dev.release(b)
        dev.release(self.images["t_cols"])
        if not keep_offsets:
            dev.release(self.images["t_offs"])


def lp_tables(fr: Frame, method: str, mapping_params: dict, geometry):
    """The :class:`LPTables` of a mapping for a viewing geometry (cached: VaFR per display, LMFR/LaFR per display
    and gaze)."""
    from ..foveation import mapping_for

    vafr = method == "vafr"
    key = (method, tuple(sorted(mapping_params.items())), geometry.width, geometry.height,
           float(geometry.fov_y_deg), None if vafr else tuple(geometry.gaze))
    tables = fr.dev.cache.setdefault("lp_tables", {})
    t = tables.get(key)
    if t is None:
        # VaFR: the gaze at a corner puts the farthest corner a diagonal away, so the table covers any gaze.
        mapping = mapping_for(method, geometry.with_gaze((0.0, 0.0)) if vafr else geometry, **mapping_params)
        offsets = None
        if not vafr:  # keep only the latest gaze of a kernel method; its row vectors do not depend on the gaze
            for k in [k for k in tables if k[:5] == key[:5]]:
                old = tables.pop(k)
                offsets = old.images["t_offs"]
                old.release(fr.dev, keep_offsets=True)
        t = LPTables(fr, cpu.LPLayout(mapping, table=vafr), mapping, offsets)
        tables[key] = t
    return t


def render_lp(fr: Frame, tables: LPTables, camera, width: int, height: int, gaze, pipeline: str):
    """Shade the LP buffer of one eye into the pooled image ``lp`` (w x h RGBA32F) and return it.

    The shaded pixels are those of :meth:`renderers.pipeline.LPLayout.shaded_pixels`: on screen, or read by a
    border pixel's bilinear fetch (marked on the CPU per gaze, :meth:`LPLayout.border_footprint`).
    """
    w, h = tables.w, tables.h
    lp = fr.pool.image("lp", (w, h))
    flags = fr.pool.get("flags", 4 * w * h)
    marks = np.flatnonzero(tables.layout.border_footprint(gaze)).astype(np.int32)
    cam = camera_uniforms(camera, width, height)
    uni = {**cam, **tables.uniforms(gaze), "u_out_w": w}
    out = {"OUT_IMAGE": 1, **tables.defines()}
    fr.reset_counter("samples")
    with fr.timer("visibility"):
        if marks.size:
            fr.run("lp_flags.comp", marks.size, {"marks": fr.upload("marks", marks), "flags": flags})
        fr.run("lp_mark.comp", w * h, {**fr.sample_buffers(tables.n_mask), **tables.buffers, "flags": flags}, uni,
               out, {**tables.images, "out_img": lp})
    if pipeline == "deferred":
        gbuf = fr.pool.get("gbuffer", 8 * width * height)
        with fr.timer("visibility"):
            fr.run_pass("gbuffer", width * height, {"gbuf": gbuf}, {**cam, "u_origin": tuple(camera.position),
                                                               "u_width": width})
            fr.run_pass("gen_deferred", tables.n_mask, {**fr.sample_buffers(tables.n_mask), **tables.buffers,
                                                       "gbuf": gbuf}, {**uni, "u_count_at": C["samples"]}, out,
                        tables.images)
    fr.shade_batch(camera.position, tables.n_mask, lp, count_at=C["samples"], traced=pipeline == "deferred",
                   uniforms={"u_out_w": w}, defines=out)
    return lp


def finish_lp(fr: Frame, tables: LPTables, lp, params: dict, width: int, height: int, exposure: float, gaze):
    """LP anti-aliasing, inverse mapping and (LMFR/LaFR) the foveal Gaussian, into the pooled buffer ``image``
    (3 floats per pixel); see :func:`renderers.pipeline.finish`."""
    from .. import antialias as AA

    w, h = tables.w, tables.h
    vafr = tables.method == "vafr"
    lp_aa = params.get("fxaa", False) if vafr else params.get("aa", False)
    uni = {**tables.uniforms(gaze), "u_width": width, "u_height": height}
    src = lp
    with fr.timer("antialias"):
        if lp_aa:
            fr.run("fill_rows.comp", h, {"flags": fr.pool.get("flags", 4 * w * h)}, {"u_lp_w": w}, images={"lp": lp})
            src = fr.pool.image("lp2", (w, h))
            if vafr:
                luma = fr.pool.image("luma", (w, h), 1)
                fr.run("lp_luma.comp", w * h, None, {"u_lp_w": w, "u_exposure": float(exposure)},
                       images={"src": lp, "luma": luma})
                fr.run("fxaa.comp", w * h, tables.buffers,
                       {**uni, "u_subpix": 0.75, "u_edge_threshold": 0.166, "u_edge_threshold_min": 0.0833},
                       {"PAD": LP_PAD_FXAA}, {**tables.images, "src": lp, "luma": luma, "dst": src})
            else:
                fr.run("gauss3.comp", w * h, tables.buffers,
                       {**uni, "u_w": _weights(AA._gauss1d(LP_GAUSS_SIGMA, LP_GAUSS_RADIUS))},
                       {"PAD": LP_PAD_GAUSS},
                       {**tables.images, "src": lp, "dst": src})
    img = fr.pool.get("image", 12 * width * height)
    post = lp_aa and not vafr
    mid = fr.pool.image("screen", (width, height)) if post else img
    with fr.timer("inverse_map"):
        fr.run("inverse_map.comp", width * height, {**tables.buffers, **({} if post else {"dst_buf": mid})}, uni,
               {**tables.defines(), "OUT_IMAGE": int(post)},
               {**tables.images, "src": src, **({"dst_img": mid} if post else {})})
    if post:
        with fr.timer("antialias"):
            fr.run("foveal.comp", width * height, {"dst_buf": img},
                   {**uni, "u_c_r": tables.c_r, "u_edges": tuple(float(e) for e in AA.FOVEAL_BANDS_DEG),
                    "u_radii": tuple(AA.FOVEAL_RADII), "u_w": _weights(AA.FOVEAL_WEIGHTS)},
                   {"OUT_IMAGE": 0}, {"src": mid})
    return img


def reproject(fr: Frame, tables: LPTables, left_lp, left, right, width: int, height: int, gaze):
    """Right-eye LP buffer (pooled image ``lp_right``) from the left one, as
    :func:`renderers.pipeline.reproject`: splat the left samples into the right view's LP buffer, forward grid
    warping with a depth test, re-shade the needed pixels nothing reached (counter ``holes``).

    Needs the left eye's sample list still in the sample buffers (call right after :func:`render_lp`).
    """
    w, h = tables.w, tables.h
    right_lp = fr.pool.image("lp_right", (w, h))
    zbuf = fr.pool.get("zbuf", 4 * w * h)
    zbuf.clear(chunk=np.array([np.inf], dtype=np.float32).tobytes())
    ztri = fr.pool.get("ztri", 4 * w * h)
    ztri.clear(chunk=np.array([np.inf], dtype=np.float32).tobytes())
    covered = fr.pool.get("covered", 4 * w * h)
    covered.clear()
    winner = fr.pool.get("winner", 4 * w * h)
    winner.clear()
    rep = {"warp": fr.pool.get("warp", 16 * w * h), "zbuf": zbuf, "covered": covered, "ztri": ztri,
           "flags": fr.pool.get("flags", 4 * w * h), "winner": winner, **tables.buffers}
    cam = camera_uniforms(right, width, height)
    uni = {**tables.uniforms(gaze), **cam, "u_left_pos": tuple(left.position), "u_right_pos": tuple(right.position),
           "u_out_w": w,
           "u_max_ratio": cpu.GRID_WARP_MAX_DEPTH_RATIO, "u_max_extent": cpu.GRID_WARP_MAX_EXTENT,
           "u_splat_margin": cpu.GRID_WARP_SPLAT_MARGIN}
    images = {**tables.images, "left_lp": left_lp, "right_lp": right_lp}
    fr.reset_counter("holes")
    with fr.timer("shading"):
        fr.run("rep_project.comp", tables.n_mask, {**fr.sample_buffers(tables.n_mask), **rep},
               {**uni, "u_count_at": C["samples"]}, tables.defines(), tables.images)
        if cpu.GRID_WARP:
            quads = max(0, (tables.w_eff - 1) * (h - 1))
            for phase in (1, 2, 3):
                fr.run("rep_warp.comp", quads, rep, uni, {"PHASE": phase}, images)
        for phase in (1, 2):
            fr.run("rep_splat.comp", w * h, rep, uni, {"PHASE": phase}, images)
        fr.run("rep_holes.comp", w * h, {**fr.sample_buffers(tables.n_mask), **rep}, uni, {"OUT_IMAGE": 1},
               {**images, "out_img": right_lp})
    fr.shade_batch(right.position, tables.n_mask, right_lp, count_at=C["holes"], uniforms={"u_out_w": w},
                   defines={"OUT_IMAGE": 1})
    return right_lp
