"""One frame on the GPU: buffers, dispatches, stage timing and the counters of the stats record.

The sample pipeline is the CPU's (renderers/tracer.py) cut into passes of one shader (``shaders/samples.comp``,
:data:`SAMPLE_PASSES`): ``trace`` (primary visibility), ``shade`` (contributions, culling, the lights left to
shadow-test), ``shadow`` (occlusion rays) and ``gather`` (radiance into each sample's output slot), after the
passes that make the samples (``gen_gt``, ``gbuffer`` and ``gen_deferred``) and before ``resolve`` (GT pixels).
Work counts are summed per workgroup on the GPU into a small counter buffer and read back once per frame into
:class:`~renderers.tracer.Counters`.
"""

from __future__ import annotations

import time

import numpy as np

from ..plugin_types import RenderCancelled
from .bindings import buffer_binding, check_uniforms, image_unit
from .context import LOCAL_SIZE, WAY_OUT, StageTimer

#: GPU counters (index = position). Those named like a Counters field are added to it at the end of a frame.
COUNTERS = ("samples", "holes", "rays_primary", "missed_rays", "shading_points", "glossy_evaluations",
            "lights_culled", "shadow_rays_skipped", "rays_shadow", "nonfinite", "offscreen_lp_pixels",
            "light_samples", "reused", "glossy_rays", "loop_limit")
C = {name: i for i, name in enumerate(COUNTERS)}
_COUNTER_DEFINES = {"COUNTERS": len(COUNTERS), **{f"C_{n.upper()}": i for n, i in C.items()}}
#: Switches of the shaders, off unless a pass sets them (GLSL's #if may not meet an undefined name).
_DEFAULT_DEFINES = {"OUT_IMAGE": 0, "USE_TABLE": 0, "METHOD": 0, "PAD": 1}
#: Samples per batch: bounds the per-sample buffers (16 B each of direction and radiance, 8 B hit, mask words).
BATCH = 1 << 20
#: The passes of ``shaders/samples.comp`` (``PASS``, each name defined as its number); from ``trace`` on they
#: read the traced samples.
SAMPLE_PASSES = ("gbuffer", "gen_gt", "gen_deferred", "resolve", "trace", "shade", "shadow", "gather")
_PASS_DEFINES = {name.upper(): k for k, name in enumerate(SAMPLE_PASSES)}


class Pool:
    """Grow-only named buffers of one device, reused across frames."""

    def __init__(self, device):
        self.device = device
        self.bufs: dict[str, object] = {}

    def get(self, name: str, nbytes: int):
        """Buffer ``name`` of at least ``nbytes`` (a new one is zeroed)."""
        nbytes = max(16, int(nbytes))
        buf = self.bufs.get(name)
        if buf is None or buf.size < nbytes:
            self.device.release(buf)
            self.device.check_fits("this frame", {name: nbytes})
            buf = self.bufs[name] = self.device.buffer(reserve=nbytes)
            buf.clear()
        return buf

    def image(self, name: str, size: tuple[int, int], components: int = 4):
        """Float32 image ``name`` of exactly ``size`` (w, h) (re-made when the size changes)."""
        tex = self.bufs.get(name)
        if tex is None or tex.size != tuple(size) or tex.components != components:
            self.device.release(tex)
            tex = self.bufs[name] = self.device.image(name, size, components)
        return tex


def pool_of(device) -> Pool:
    """The device's buffer pool."""
    pools = device.cache.setdefault("pool", {})
    if "pool" not in pools:
        pools["pool"] = Pool(device)
    return pools["pool"]


def set_uniforms(prog, values: dict) -> None:
    """Set the uniforms ``prog`` uses (the compiler drops unused ones; those are skipped, and an array's unused
    trailing elements: the leading values are set); a name no table declares is refused (:mod:`.bindings`)."""
    check_uniforms(values)
    for k, v in values.items():
        if k in prog:
            u = prog[k]
            n = getattr(u, "array_length", 1)
            if isinstance(v, tuple) and u.dimension == 1 and len(v) > n:   # an array the compiler shortened
                v = v[:n] if n > 1 else v[0]
            prog[k] = v


def bind(buffers: dict | None, images: dict | None = None) -> None:
    """Bind storage buffers {name: buffer} and images {name: texture} at the points :mod:`.bindings` gives their
    names (an unknown name is refused)."""
    points = [(buffer_binding(name), b) for name, b in (buffers or {}).items()]
    units = [(image_unit(name), tex) for name, tex in (images or {}).items()]
    for binding, b in points:
        b.bind_to_storage_buffer(binding)
    for unit, tex in units:
        tex.bind_to_image(unit, read=True, write=True)


class Frame:
    """Dispatch helper for one render with a :class:`~renderers.gpu.upload.DeviceScene`."""

    def __init__(self, ds):
        self.ds = ds
        self.dev = ds.device
        self.pool = pool_of(self.dev)
        self.timer = StageTimer(self.dev)
        self.counter_buf = self.pool.get("counters", 4 * len(COUNTERS))
        self.counter_buf.clear()
        self.totals = dict.fromkeys(COUNTERS, 0)
        self.t0 = time.perf_counter()

    # -- dispatch ---------------------------------------------------------------------------------------------
    def defines(self, extra: dict | None = None) -> dict:
        return {**_COUNTER_DEFINES, **_DEFAULT_DEFINES, **self.ds.defines(), **(extra or {})}

    def run(self, name: str, n: int, buffers: dict | None = None, uniforms: dict | None = None,
            defines: dict | None = None, images: dict | None = None, local: int = LOCAL_SIZE) -> None:
        """Dispatch ``shaders/<name>`` over ``n`` invocations with storage ``buffers`` {name: buffer} and
        ``images`` {name: texture} (:mod:`.bindings`) bound next to the scene and the counters.
        A render that can be cancelled is asked first (:meth:`check_cancel`)."""
        self.check_cancel()
        prog = self.dev.program(name, self.defines(defines))
        self.ds.bind_scene()
        self.counter_buf.bind_to_storage_buffer(buffer_binding("counters"))
        bind(buffers, images)
        set_uniforms(prog, {**self.ds.scene_uniforms(), **(uniforms or {})})
        self.dev.dispatch(prog, n, local)
        self.dev.barrier()

    def run_pass(self, name: str, n: int, buffers: dict | None = None, uniforms: dict | None = None,
                 defines: dict | None = None, images: dict | None = None) -> None:
        """:meth:`run` pass ``name`` of the sample pipeline (:data:`SAMPLE_PASSES`) over ``n`` invocations (the
        count of counter ``u_count_at`` when given)."""
        self.run("samples.comp", n, buffers, {"u_count_at": -1, **(uniforms or {})},
                 {**(defines or {}), **_PASS_DEFINES, "PASS": _PASS_DEFINES[name.upper()]}, images)

    def check_cancel(self) -> None:
        """Stop the render if its ``cancel`` hook says so (the live window's Escape): llvmpipe runs each dispatch
        to its end in this thread, so between dispatches is where a frame can stop. The window's drawing state is
        restored before :class:`RenderCancelled` is raised; an open stage timer ends as the exception leaves its
        scope, and the frame's buffers are the device's pool, kept for the next frame."""
        cancel = self.ds.cancel
        if cancel is not None and cancel():
            self.dev.yield_to_window()
            raise RenderCancelled

    @property
    def batch(self) -> int:
        """Samples per GT batch: :data:`BATCH`, an eighth of it when the render can be cancelled (more dispatches,
        each asked first; the same pixels)."""
        return BATCH if self.ds.cancel is None else BATCH >> 3

    def upload(self, name: str, data: np.ndarray):
        """``data`` in the pooled buffer ``name`` (grown as needed)."""
        buf = self.pool.get(name, data.nbytes)
        buf.write(np.ascontiguousarray(data))
        return buf

    def reset_counter(self, name: str) -> None:
        self.counter_buf.write(np.zeros(1, dtype=np.uint32), offset=4 * C[name])

    def counters_now(self) -> np.ndarray:
        return np.frombuffer(self.counter_buf.read(size=4 * len(COUNTERS)), dtype=np.uint32).copy()

    def drain_counters(self) -> np.ndarray:
        """Add the GPU counters to the frame totals and zero them (call before they could overflow 32 bits)."""
        now = self.counters_now()
        for name, v in zip(COUNTERS, now):
            self.totals[name] += int(v)
        self.counter_buf.clear()
        return now

    # -- the sample pipeline ----------------------------------------------------------------------------------
    def sample_buffers(self, capacity: int) -> dict:
        w = self.ds.mask_words
        return {"samples": self.pool.get("samples", 16 * capacity), "hits": self.pool.get("hits", 8 * capacity),
                "masks": self.pool.get("masks", 4 * w * capacity), "partial": self.pool.get("partial", 16 * capacity)}

    def shade_batch(self, origin, capacity: int, out, *, count_at: int = -1, n: int | None = None,
                    traced: bool = False, uniforms: dict | None = None, defines: dict | None = None,
                    images: dict | None = None) -> None:
        """Trace, shade, shadow-test and gather the batch already in the sample buffers.

        ``n`` samples, or as many as counter ``count_at`` says (lists built on the GPU; ``capacity`` bounds
        them). ``traced``: the hits are already there (deferred pipeline: from the G-buffer).
        """
        out_image = bool((defines or {}).get("OUT_IMAGE"))
        bufs = self.sample_buffers(capacity)
        images = dict(images or {})
        if out_image:
            images["out_img"] = out
        else:
            bufs["outbuf"] = out
        uni = {"u_origin": tuple(float(x) for x in origin), "u_count_at": int(count_at), **(uniforms or {})}
        size = capacity if n is None else n
        if not traced:
            with self.timer("visibility"):
                self.run_pass("trace", size, bufs, uni, defines, images)
        with self.timer("shading"):
            self.run_pass("shade", size, bufs, uni, defines, images)
        with self.timer("visibility"):
            self.run_pass("shadow", size, bufs, uni, defines, images)
        with self.timer("shading"):
            self.run_pass("gather", size, bufs, uni, defines, images)

    # -- end of frame -----------------------------------------------------------------------------------------
    def close(self) -> dict:
        """Read the counters and stage times into the device scene's :class:`Counters`; returns the totals."""
        self.drain_counters()
        c = self.ds.counters
        for name, v in self.totals.items():
            if hasattr(c, name) and name != "samples":
                setattr(c, name, getattr(c, name) + v)
        c.reshaded_pixels += self.totals["holes"]
        if self.totals["nonfinite"]:
            raise ValueError(f"the GPU renderer produced {self.totals['nonfinite']:,} non-finite samples")
        if self.totals["loop_limit"]:
            raise RuntimeError(
                f"{self.totals['loop_limit']:,} GPU shader invocations reached llvmpipe's limit of 65,535 loop "
                f"iterations (it cuts their loops short, so the frame would be wrong): this is a bug in studyapp, "
                f"please report it; {WAY_OUT}")
        for stage, sec in self.timer.seconds().items():
            c.seconds[stage] = c.seconds.get(stage, 0.0) + sec
        self.dev.yield_to_window()
        return self.totals
