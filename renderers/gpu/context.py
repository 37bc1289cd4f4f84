"""The OpenGL device: one moderngl context per process, its capability check, shader compilation, timing.

Where the context comes from:

* no window open (scripts, the CLI, CI): a standalone context through EGL, which needs no display
  (``moderngl.create_standalone_context(backend="egl")``); on a machine without a GPU Mesa's llvmpipe runs it;
* a PsychoPy (pyglet) window whose OpenGL context is current: ``moderngl.create_context()`` attaches to it, so
  the next stage can draw our output texture into that window.

Everything that can go wrong for a user becomes one :class:`~data_schema.errors.UserError` line naming the
cause and the way out (``--backend cpu``): moderngl or EGL missing, OpenGL older than 4.3 (no compute shaders), a
shader that does not compile (a bug, but still one line: the shader's name and the compiler's first message),
buffers larger than the GPU allows.
"""

from __future__ import annotations

import os
import re
import sys
import time
from pathlib import Path

import numpy as np

from data_schema.errors import UserError

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
WAY_OUT = "use --backend cpu"
#: Test/ops override of the GPU memory the backend may use (MB); default: what the device reports.
MEMORY_ENV = "STUDYAPP_GPU_MEMORY_MB"
REQUIRED_VERSION = 430
#: Texels per row of the scene-table textures (a power of two; every OpenGL 4.3 device allows 16384).
TEX_WIDTH = 4096
#: Interleaved stripes of workgroups per dispatch (``Device.dispatch``, ``common.glsl`` ``gid()``): any thread
#: count of llvmpipe up to this many gets an even share of every part of the image.
STRIPES = 64
#: Invocations per workgroup of every compute shader: ``expand_source`` declares it in each ``.comp`` file's
#: ``layout(local_size_x = ...)`` and ``Device.dispatch`` counts workgroups with it (one home for both).
LOCAL_SIZE = 64

_DEVICE: "Device | None" = None


def _first_line(text: str) -> str:
    for line in str(text).splitlines():
        if line.strip():
            return line.strip()
    return str(text).strip()


def _window_context_current() -> bool:
    """True when a pyglet (PsychoPy) window has made its OpenGL context current in this process."""
    pyglet = sys.modules.get("pyglet")
    if pyglet is None:
        return False
    try:
        return pyglet.gl.current_context is not None
    except Exception:  # an older or half-imported pyglet: no window of ours
        return False


def _create_context(source: str):
    try:
        import moderngl
    except ImportError:
        raise UserError("the GPU backend needs moderngl, which is not installed (pip install 'studyapp[gpu]'): "
                        f"install it or {WAY_OUT}") from None
    try:
        if source == "window":
            return moderngl.create_context()
        return moderngl.create_standalone_context(backend="egl")
    except Exception as exc:  # glcontext raises plain Exceptions with the loader's message
        what = "attach to the window's OpenGL context" if source == "window" else "open an OpenGL context through EGL"
        raise UserError(f"could not {what} ({_first_line(exc)}): install the Mesa EGL/GL drivers "
                        f"(Debian: libegl1 libegl-mesa0 libgl1-mesa-dri) or {WAY_OUT}") from None


def grid_shape(groups: int, max_groups: int) -> tuple[int, int]:
    """The 2-D grid ``(gx, gy)`` of a dispatch of ``groups`` workgroups, each side at most ``max_groups``: the
    fewest rows, then the narrowest width that holds them, so ``gx * gy - groups < gy``.

    Full rows (``gx = max_groups``) would pad a 2160 x 2160 frame's 72,960 workgroups to 131,070, and llvmpipe,
    which hands each thread one contiguous half of the grid, would give its second thread the idle half."""
    gy = -(-groups // max_groups)
    return -(-groups // gy), gy


class Device:
    """A moderngl context with the checks and helpers the GPU renderers need.

    Parameters
    ----------
    ctx : moderngl.Context
    source : {"egl", "window"}
        Where the context came from (reported in the stats).
    """

    def __init__(self, ctx, source: str):
        self.ctx = ctx
        self.source = source
        info = ctx.info
        self.version = str(info.get("GL_VERSION", "?"))
        self.renderer = str(info.get("GL_RENDERER", "?"))
        self.vendor = str(info.get("GL_VENDOR", "?"))
        if ctx.version_code < REQUIRED_VERSION:
            raise UserError(f"OpenGL 4.3 compute shaders are not available (found OpenGL {self.version}, "
                            f"{self.renderer}): {WAY_OUT}")
        self.max_block = int(info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE", 1 << 27))
        self.max_groups = int(info.get("GL_MAX_COMPUTE_WORK_GROUP_COUNT", (65535,))[0])
        self.max_texture = int(info.get("GL_MAX_TEXTURE_SIZE", 16384))
        import moderngl

        self._nearest = moderngl.NEAREST
        self.software = "llvmpipe" in self.renderer.lower() or "softpipe" in self.renderer.lower()
        self._programs: dict[tuple, object] = {}
        self.allocated = 0
        #: What lives as long as this context: uploaded scenes, LP tables, the frame buffer pool (by name).
        self.cache: dict[str, dict] = {}

    # -- memory --------------------------------------------------------------------------------------------------
    def memory_budget(self) -> float | None:
        """Bytes of GPU memory the backend may use (None if the device does not say)."""
        env = os.environ.get(MEMORY_ENV)
        if env:
            return float(env) * 1e6
        if self.software:  # llvmpipe's buffers live in system memory
            from ..registry import _available_bytes

            return _available_bytes() * 0.5
        return None

    def check_fits(self, what: str, sizes: dict[str, int]) -> None:
        """Refuse (one line) when one of ``sizes`` exceeds the largest storage buffer or their sum the budget."""
        for name, nbytes in sizes.items():
            if nbytes > self.max_block:
                raise UserError(f"{what} is too large for the GPU's memory: its {name} needs {nbytes / 1e6:,.0f} MB "
                                f"in one buffer, the GPU allows {self.max_block / 1e6:,.0f} MB ({self.renderer}): "
                                f"{WAY_OUT}")
        total = sum(sizes.values())
        budget = self.memory_budget()
        if budget is not None and self.allocated + total > budget:
            raise UserError(f"{what} is too large for the GPU's memory: needs {total / 1e6:,.0f} MB, "
                            f"{max(0.0, budget - self.allocated) / 1e6:,.0f} MB available ({self.renderer}): "
                            f"{WAY_OUT}")

    def buffer(self, data=None, *, reserve: int = 0):
        """A storage buffer with ``data`` (bytes-like) or ``reserve`` zeroed bytes; GL errors become one line."""
        try:
            if data is not None:
                buf = self.ctx.buffer(memoryview(data).cast("B") if not isinstance(data, bytes) else data)
            else:
                buf = self.ctx.buffer(reserve=max(4, int(reserve)))
        except Exception as exc:
            raise UserError(f"the GPU could not allocate a buffer ({_first_line(exc)}): {WAY_OUT}") from None
        self.allocated += buf.size
        return buf

    def table_texture(self, what: str, table: np.ndarray):
        """An RGBA32UI texture holding the rows of ``table`` (n, 4k) float32/int32 as 32-bit words, ``k`` texels
        per row, :data:`TEX_WIDTH` texels per texture row (read with ``fetch`` in ``shaders/scene.glsl``)."""
        words = np.ascontiguousarray(table).view(np.uint32).reshape(-1)
        texels = max(1, -(-words.size // 4))
        rows = -(-texels // TEX_WIDTH)
        if rows > self.max_texture:
            raise UserError(f"{what} is too large for the GPU's memory: {texels:,} texels, the GPU's textures hold "
                            f"{TEX_WIDTH * self.max_texture:,} ({self.renderer}): {WAY_OUT}")
        data = np.zeros(rows * TEX_WIDTH * 4, dtype=np.uint32)
        data[:words.size] = words
        try:
            tex = self.ctx.texture((TEX_WIDTH, rows), 4, data.tobytes(), dtype="u4")
        except Exception as exc:
            raise UserError(f"the GPU could not allocate {what} ({_first_line(exc)}): {WAY_OUT}") from None
        tex.filter = (self._nearest, self._nearest)
        self.allocated += data.nbytes
        tex.nbytes = data.nbytes
        return tex

    def float_texture(self, what: str, table: np.ndarray):
        """An RGBA32F image of the rows of ``table`` (n, 4) float32, :data:`TEX_WIDTH` per texture row."""
        rows = -(-len(table) // TEX_WIDTH)
        data = np.zeros((rows * TEX_WIDTH, 4), dtype=np.float32)
        data[:len(table)] = table
        tex = self.image(what, (TEX_WIDTH, rows))
        tex.write(data.tobytes())
        return tex

    def image(self, what: str, size: tuple[int, int], components: int = 4, dtype: str = "f4"):
        """A 32-bit float (``f4``) or unsigned (``u4``) image (texture) of ``size`` for ``imageLoad``/``Store``."""
        nbytes = 4 * components * size[0] * size[1]
        self.check_fits(what, {what: nbytes})
        if max(size) > self.max_texture:
            raise UserError(f"{what} of {size[0]}x{size[1]} exceeds the GPU's largest texture ({self.max_texture}): "
                            f"{WAY_OUT}")
        try:
            tex = self.ctx.texture(tuple(size), components, dtype=dtype)
        except Exception as exc:
            raise UserError(f"the GPU could not allocate {what} ({_first_line(exc)}): {WAY_OUT}") from None
        self.allocated += nbytes
        tex.nbytes = nbytes
        return tex

    def release(self, buf) -> None:
        if buf is not None:
            self.allocated -= getattr(buf, "nbytes", None) or buf.size
            buf.release()

    # -- shaders -------------------------------------------------------------------------------------------------
    def program(self, name: str, defines: dict | None = None, source: str | None = None):
        """The compiled compute shader ``shaders/<name>`` with ``defines`` (cached).

        ``source`` replaces the file's text (tests use it to force a compile error).
        """
        defines = dict(defines or {})
        key = (name, tuple(sorted(defines.items())), source)
        prog = self._programs.get(key)
        if prog is None:
            text = expand_source(name, defines, source)
            try:
                prog = self.ctx.compute_shader(text)
            except Exception as exc:
                raise UserError(f"GPU shader {name} failed to compile ({compiler_message(exc)}): this is a bug in "
                                f"studyapp, please report it; {WAY_OUT}") from None
            self._programs[key] = prog
        return prog

    def dispatch(self, prog, n: int, local: int = LOCAL_SIZE) -> None:
        """Run ``prog`` over ``n`` invocations of a 1-D problem (2-D grid when the group count exceeds the limit).

        The shader reads its index with ``gid()`` from ``common.glsl``, which deals the blocks of ``local``
        invocations to the workgroups in :data:`STRIPES` interleaved stripes: llvmpipe hands each of its threads
        one contiguous range of workgroups per dispatch (Mesa's ``lp_cs_tpool``), so where the work is uneven over
        the image (glossy pixels, occluded corners) one core would otherwise idle while the other finishes.
        """
        groups = max(1, -(-int(n) // local))
        rows = -(-groups // STRIPES)
        padded = rows * STRIPES  # at most STRIPES - 1 idle workgroups
        gx, gy = grid_shape(padded, self.max_groups)
        if "u_groups_x" in prog:
            prog["u_groups_x"] = gx
        if "u_group_rows" in prog:
            prog["u_group_rows"] = rows
            prog["u_stripes"] = STRIPES
        if "u_n" in prog:
            prog["u_n"] = int(n)
        if "u_loop_probe" in prog:  # common.glsl's check of llvmpipe's loop limit
            prog["u_loop_probe"] = 2
        prog.run(gx, gy, 1)

    def barrier(self) -> None:
        self.ctx.memory_barrier()

    def yield_to_window(self) -> None:
        """In a window's context: unbind our program so the window's own drawing finds the state it expects
        (PsychoPy's fixed-function stimuli draw with program 0)."""
        if self.source == "window":
            from pyglet import gl

            self.ctx.memory_barrier()
            gl.glUseProgram(0)

    def finish(self) -> None:
        self.ctx.finish()


def compiler_message(exc) -> str:
    """The first error line of a GLSL compiler log (Mesa: ``0:12(3): error: ...``)."""
    text = str(exc)
    for line in text.splitlines():
        if "error" in line.lower() and not line.strip().lower().startswith("glsl compiler failed"):
            return line.strip()
    return _first_line(text)


_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.M)


def expand_source(name: str, defines: dict, source: str | None = None) -> str:
    """GLSL text of ``name``: ``#include "file"`` expanded (once each), ``#version`` and ``defines`` first and, for a
    compute shader (``.comp``), its workgroup size :data:`LOCAL_SIZE`; shader files hold neither."""
    seen: set[str] = set()

    def load(fname: str, text: str | None = None) -> str:
        if text is None:
            if fname in seen:
                return ""
            seen.add(fname)
            text = generated_source(fname) or (SHADER_DIR / fname).read_text(encoding="utf-8")
        return _INCLUDE.sub(lambda m: load(m.group(1)), text)

    body = load(name, source)
    head, sep, rest = body.partition("\n")
    if not head.startswith("#version"):
        head, rest = f"#version {REQUIRED_VERSION}", body
    lines = [f"#define {k} {_glsl_value(v)}" for k, v in defines.items()]
    if name.endswith(".comp") and "local_size_x" not in rest:   # the plumbing every compute shader shares
        lines.append(f"layout(local_size_x = {LOCAL_SIZE}) in;")
    return "\n".join([head, *lines, rest])


def _glsl_value(v) -> str:
    if isinstance(v, bool):
        return "1" if v else "0"
    if isinstance(v, float):
        return repr(v) if "e" in repr(v) or "." in repr(v) else repr(v) + ".0"
    return str(v)


def generated_source(fname: str) -> str | None:
    """GLSL generated from the CPU code (:mod:`.codegen`) and from the resource tables (:mod:`.bindings`), or None
    for a file in ``shaders/``. This table is the one list of the generated files (docs/gpu.md describes them)."""
    from functools import partial

    from . import bindings, codegen

    makers = {
        "constants_gen.glsl": codegen.constants_glsl, "int64_gen.glsl": codegen.int64_glsl,
        "foveation_gen.glsl": codegen.foveation_glsl, "projection_gen.glsl": codegen.projection_glsl,
        "shade_gen.glsl": codegen.shade_glsl, "lights_gen.glsl": partial(codegen.lights_glsl, roots="GLSL_LIGHT_ROOTS"),
        "light_loop_gen.glsl": partial(codegen.lights_glsl, roots="GLSL_POINT_ROOTS"), "gt_gen.glsl": codegen.gt_glsl,
        "lp_u_gen.glsl": partial(codegen.lp_glsl, "u"), "lp_inverse_gen.glsl": partial(codegen.lp_glsl, "inverse"),
        "lp_fill_gen.glsl": partial(codegen.lp_glsl, "fill"), "lp_needed_gen.glsl": partial(codegen.lp_glsl, "needed"),
        "gauss_gen.glsl": partial(codegen.antialias_glsl, "gauss"),
        "foveal_gen.glsl": partial(codegen.antialias_glsl, "foveal"),
        "luma_gen.glsl": partial(codegen.antialias_glsl, "luma"), "fxaa_gen.glsl": codegen.fxaa_glsl,
        "warp_gen.glsl": codegen.warp_glsl, "lightcuts_gen.glsl": codegen.lightcuts_glsl,
        "lc_shade_gen.glsl": codegen.lightcuts_shade_glsl, "lc_bounce_gen.glsl": codegen.lightcuts_bounce_glsl,
        "glossy_gen.glsl": codegen.glossy_glsl, "fpsm_gen.glsl": codegen.fpsm_glsl,
        "lc_buffers_gen.glsl": bindings.lc_buffers_glsl, "lc_tree_gen.glsl": bindings.tree_glsl,
        **{f"{family}_decl_gen.glsl": partial(bindings.decl_glsl, family) for family in bindings.FAMILIES},
    }
    make = makers.get(fname)
    return None if make is None else make()


def get_device() -> Device:
    """The process's :class:`Device` (created on first use; attached to a current window context if any)."""
    global _DEVICE
    if _DEVICE is None:
        source = "window" if _window_context_current() else "egl"
        _DEVICE = Device(_create_context(source), source)
    return _DEVICE


def reset_device() -> None:
    """Forget the process's device; its GL objects and caches go with the context."""
    global _DEVICE
    if _DEVICE is not None:
        try:
            _DEVICE.ctx.release()
        except Exception:
            pass
    _DEVICE = None


class StageTimer:
    """Seconds per stage of one frame.

    On a GPU: ``GL_TIME_ELAPSED`` timer queries around each stage's commands, read back once at the end of the
    frame (reading earlier would stall the pipeline). Mesa's llvmpipe runs compute dispatches synchronously
    on the CPU and its timer queries report 0 ns, so there each stage is timed by the wall clock up to a
    ``glFinish``. :attr:`method` says which.
    """

    def __init__(self, device: Device):
        self.device = device
        self.queries = not device.software
        self.method = "GPU timer queries" if self.queries else "wall clock + glFinish (llvmpipe timer queries read 0)"
        self._open: list[tuple[str, object]] = []
        self._wall: dict[str, float] = {}

    def __call__(self, stage: str):
        return _StageScope(self, stage)

    def seconds(self) -> dict[str, float]:
        out = dict(self._wall)
        if self.queries:
            out = {}
            for stage, q in self._open:
                out[stage] = out.get(stage, 0.0) + q.elapsed * 1e-9
                q.release()
        self._open.clear()
        self._wall.clear()
        return out


class _StageScope:
    def __init__(self, timer: StageTimer, stage: str):
        self.timer, self.stage = timer, stage

    def __enter__(self):
        t = self.timer
        if t.queries:
            self.q = t.device.ctx.query(time=True)
            t._open.append((self.stage, self.q))
            self.q.__enter__()
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        t = self.timer
        if t.queries:
            self.q.__exit__(*exc)
        else:
            t.device.finish()
        t._wall[self.stage] = t._wall.get(self.stage, 0.0) + time.perf_counter() - self.t0
