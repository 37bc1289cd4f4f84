"""GPU backend: the EGL context, the capability and error lines, the GLSL generated from the foveation
kernels, the BVH, the plug-in route and the CLI (issue 13 items 1-4, 9). Needs OpenGL 4.3 through EGL (Mesa's
llvmpipe in CI): without it these tests fail, they do not skip."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from data_schema.errors import UserError

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PY = sys.executable


def _cli(args, env_extra=None, timeout=120):
    """Run ``python -m studyapp`` with no display: (returncode, stdout, stderr)."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["PYTHONPATH"] = os.pathsep.join([ROOT, env.get("PYTHONPATH", "")])
    env.update(env_extra or {})
    p = subprocess.run([PY, "-m", "studyapp", *args], capture_output=True, text=True, env=env, timeout=timeout,
                       cwd=ROOT)
    return p.returncode, p.stdout, p.stderr


def _one_error_line(stderr: str, *needles: str) -> str:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, stderr
    assert lines[0].startswith("studyapp: error: "), lines[0]
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def test_egl_context_opens_without_a_display():
    code = ("from renderers.gpu.context import get_device; d = get_device(); "
            "print(d.source, d.ctx.version_code, d.renderer)")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["PYTHONPATH"] = os.pathsep.join([ROOT, env.get("PYTHONPATH", "")])
    out = subprocess.run([PY, "-c", code], capture_output=True, text=True, env=env, timeout=60, check=True).stdout
    source, version, _ = out.split(" ", 2)
    assert source == "egl" and int(version) >= 430


def test_cli_backend_gpu_writes_the_png(tmp_path):
    rc, out, err = _cli(["render", "--scene", "cornell", "--renderer", "lmfr", "--width", "64", "--height", "48",
                         "--backend", "gpu", "--out", str(tmp_path / "a.png"), "--json"])
    assert rc == 0, err
    import json

    stats = json.loads(out)
    assert stats["backend"] == "gpu" and stats["shading_points"] > 0 and "llvmpipe" in stats["gpu"]["renderer"]
    assert (tmp_path / "a.png").stat().st_size > 0 and (tmp_path / "a.npy").exists()


@pytest.mark.parametrize("env,needles", [
    ({"MESA_GL_VERSION_OVERRIDE": "3.3"}, ("OpenGL 4.3 compute shaders are not available", "found OpenGL 3.3")),
    ({"__EGL_VENDOR_LIBRARY_FILENAMES": "/nonexistent.json"}, ("could not open an OpenGL context through EGL",)),
    ({"STUDYAPP_GPU_MEMORY_MB": "1"}, ("scene 'temple' is too large for the GPU's memory", "needs")),
], ids=["no-gl43", "no-egl-driver", "scene-too-large"])
def test_bad_device_one_line_exit_2(tmp_path, env, needles):
    rc, _, err = _cli(["render", "--scene", "temple", "--renderer", "gt", "--width", "16", "--height", "12",
                       "--backend", "gpu", "--out", str(tmp_path / "a.png")], env)
    assert rc == 2
    _one_error_line(err, *needles, "use --backend cpu")
    assert not (tmp_path / "a.png").exists()


def test_broken_shader_one_line_naming_it(tmp_path, monkeypatch, capsys):
    """A shader that fails to compile is a bug, but it reaches the user as one line: the shader's name and the
    compiler's first message, and the way out."""
    from renderers.gpu import context
    from studyapp.cli import main

    shaders = tmp_path / "shaders"
    shaders.mkdir()
    for f in context.SHADER_DIR.iterdir():
        (shaders / f.name).write_text(f.read_text())
    (shaders / "samples.comp").write_text((shaders / "samples.comp").read_text().replace(
        "cnt_add(C_SHADING_POINTS, 1u);", "cnt_add(C_SHADING_POINTS, undefined_count);"))
    monkeypatch.setattr(context, "SHADER_DIR", shaders)
    monkeypatch.setattr(context.get_device(), "_programs", {})
    rc = main(["render", "--scene", "cornell", "--renderer", "gt", "--width", "8", "--height", "6",
               "--backend", "gpu", "--out", str(tmp_path / "a.png")])
    assert rc == 2
    line = _one_error_line(capsys.readouterr().err, "GPU shader samples.comp failed to compile", "undefined_count",
                           "use --backend cpu")
    assert "error" in line


def test_too_many_lights_and_cpu_only_renderers(monkeypatch):
    """The built-in GPU renderers refuse many-light scenes (the lightcuts renderers take them); a plug-in without
    a GPU version is refused on the GPU backend."""
    from dataclasses import replace

    from renderers import registry
    from renderers.gpu import render

    with pytest.raises(UserError, match="111,858 lights.*lightcuts renderers.*use --backend cpu"):
        render("cornell_many", "gt", {}, 8, 6)
    plugins = registry.available()
    monkeypatch.setattr(registry, "_PLUGINS", {**plugins, "cpu_only": replace(plugins["gt"], name="cpu_only",
                                                                               gpu=None)})
    with pytest.raises(UserError, match="renderer .cpu_only. has no GPU version: use --backend cpu"):
        render("cornell", "cpu_only", {}, 8, 6)


def test_generated_foveation_glsl_matches_the_cpu_kernels():
    """The GPU evaluates the forward and inverse mappings from the CPU's parameter vector with GLSL generated
    from renderers/foveation/_kernels.py: same values (float32) for all three methods."""
    from renderers.foveation import make_mapping
    from renderers.gpu.bindings import buffer_binding
    from renderers.gpu.context import get_device

    dev = get_device()
    src = """#version 430
layout(local_size_x = 64) in;
#include "lp_map_decl_gen.glsl"
#include "foveation_gen.glsl"
layout(std430, binding = 1) readonly buffer In { vec2 pts[]; };
layout(std430, binding = 2) writeonly buffer Out { vec4 res[]; };
uniform int u_n;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i < uint(u_n)) res[i] = vec4(fov_point(METHOD, FOV_FORWARD, pts[i].x, pts[i].y),
                                     fov_point(METHOD, FOV_INVERSE, pts[i].x, pts[i].y));
}
"""
    rng = np.random.default_rng(3)
    for method, kernel in (("vafr", 0), ("lmfr", 1), ("lafr", 2)):
        m = make_mapping(method, 1280, 720, 90.0, (500.0, 300.0))
        d = rng.uniform(-700, 700, size=(512, 2))
        w, h = m.lp_shape
        uv = np.column_stack([rng.uniform(0.5, w - 1, 512), rng.uniform(0, h, 512)])
        fu, fv = m.forward(d[:, 0] + 500.0, d[:, 1] + 300.0)
        ix, iy = m.inverse(uv[:, 0], uv[:, 1])
        prog = dev.program("fov_test.comp", {"METHOD": kernel}, source=src)
        fp = dev.buffer(m._params_vector().astype(np.float32))
        pin_f = dev.buffer(d.astype(np.float32))
        pin_i = dev.buffer(uv.astype(np.float32))
        out = dev.buffer(reserve=16 * 512)
        res = []
        for pts in (pin_f, pin_i):
            fp.bind_to_storage_buffer(buffer_binding("FP"))
            pts.bind_to_storage_buffer(1), out.bind_to_storage_buffer(2)
            prog["u_n"] = 512
            prog.run(8)
            dev.finish()
            res.append(np.frombuffer(out.read(), np.float32).reshape(512, 4))
        # float32: within 1e-3 LP pixel of the CPU's float64 (a 0.01-pixel budget is what the CPU's own u(r)
        # table allows), and 1e-2 screen pixel back
        np.testing.assert_allclose(res[0][:, 0], fu, rtol=0, atol=1e-3)
        np.testing.assert_allclose(res[0][:, 1], fv, rtol=0, atol=1e-3)
        np.testing.assert_allclose(res[1][:, 2] + 500.0, ix, rtol=0, atol=1e-2)
        np.testing.assert_allclose(res[1][:, 3] + 300.0, iy, rtol=0, atol=1e-2)
        for b in (fp, pin_f, pin_i, out):
            dev.release(b)


def test_translator_refuses_what_it_does_not_know():
    import types

    from renderers.gpu.codegen import Translator

    tr = Translator(types.ModuleType("fake"), "t_", source="def f(x, P):\n    try:\n        x -= 1\n    except ValueError:\n"
                    "        x = 0.0\n    return x\n")
    names = tr.closure(["f"])
    tr.infer(names)
    with pytest.raises(NotImplementedError, match="f: statement Try"):
        tr.emit(names)


def test_bvh_covers_every_triangle_once():
    from renderers.catalog import resolve
    from renderers.gpu import bvh

    sc = resolve("interior")
    b = bvh.build(sc.vertices, sc.faces)
    ints = b.nodes.view(np.int32).reshape(-1, 2, 8)
    lo, hi = b.nodes.reshape(-1, 2, 8)[..., 0:3], b.nodes.reshape(-1, 2, 8)[..., 4:7]
    ref, count = ints[..., 3], ints[..., 7]
    leaf = count > 0
    ids = np.concatenate([np.arange(a, a + c) for a, c in zip(ref[leaf], count[leaf])])
    assert np.array_equal(np.sort(ids), np.arange(sc.n_triangles))
    assert np.array_equal(np.sort(b.tris.view(np.int32)[:, 3]), np.arange(sc.n_triangles))
    tri = b.tris.reshape(-1, 3, 4)[..., :3]
    verts = np.stack([tri[:, 0], tri[:, 0] + tri[:, 1], tri[:, 0] + tri[:, 2]], axis=1)
    for (n, s) in np.argwhere(leaf):  # every leaf box holds its triangles (up to float rounding of e1, e2)
        v = verts[ref[n, s]:ref[n, s] + count[n, s]].reshape(-1, 3)
        assert (v >= lo[n, s] - 1e-4).all() and (v <= hi[n, s] + 1e-4).all()
    parent = np.full(len(ints), -1)
    for (n, s) in np.argwhere(~leaf):  # inner children: boxes inside the parent's entry, one parent each
        c = ref[n, s]
        assert parent[c] == -1 and c > n
        parent[c] = n
        assert (lo[c] >= lo[n, s]).all() and (hi[c] <= hi[n, s]).all()
    assert (parent[1:] >= 0).all() and b.depth <= bvh.MAX_DEPTH


def test_importing_renderers_and_analysis_loads_no_gl():
    code = ("import sys, renderers, analysis, renderers.registry, renderers.gpu; "
            "print([m for m in sys.modules if m.split('.')[0] in ('moderngl', 'glcontext')])")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([ROOT, os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([PY, "-c", code], capture_output=True, text=True, env=env, timeout=60, check=True).stdout
    assert out.strip() == "[]"


def test_window_context_is_used_when_one_is_current(tmp_path):
    """Inside a pyglet (PsychoPy) window the backend attaches to the window's OpenGL context and leaves no
    program bound for the window's own drawing (Xvfb: the virtual screen ./run installs)."""
    script = tmp_path / "win.py"
    script.write_text(
        "import pyglet\n"
        "from pyglet import gl\n"
        "win = pyglet.window.Window(64, 48, visible=False)\n"
        "win.switch_to()\n"
        "from renderers.gpu import render\n"
        "from renderers.gpu.context import get_device\n"
        "img, st = render('cornell', 'lmfr', {}, 64, 48)\n"
        "prog = gl.GLint()\n"
        "gl.glGetIntegerv(gl.GL_CURRENT_PROGRAM, prog)\n"
        "gl.glClearColor(0.0, 1.0, 0.0, 1.0)\n"
        "gl.glClear(gl.GL_COLOR_BUFFER_BIT)\n"
        "px = (gl.GLubyte * 4)()\n"
        "gl.glReadPixels(1, 1, 1, 1, gl.GL_RGBA, gl.GL_UNSIGNED_BYTE, px)\n"
        "print(get_device().source, st['gpu']['context'], prog.value, list(px), img.mean() > 0)\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([ROOT, os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run(["xvfb-run", "-a", PY, str(script)], capture_output=True, text=True, env=env,
                         timeout=120, check=True).stdout.split()
    assert out[:3] == ["window", "window", "0"] and out[3:7] == ["[0,", "255,", "0,", "255]"] and out[7] == "True"


_GID_SRC = """#version 430
layout(local_size_x = 64) in;
#include "common.glsl"
layout(std430, binding = 1) buffer Hits { uint hits[]; };
layout(std430, binding = 2) buffer Group { uint group_of[]; };
layout(std430, binding = 3) buffer Grid { uint grid_groups; };
void main() {
    uint i = gid();
    if (gl_WorkGroupID.x == 0u && gl_WorkGroupID.y == 0u && gl_LocalInvocationID.x == 0u)
        grid_groups = gl_NumWorkGroups.x * gl_NumWorkGroups.y;
    if (i < uint(u_n)) {
        atomicAdd(hits[i], 1u);
        group_of[i] = gl_WorkGroupID.x + gl_WorkGroupID.y * uint(u_groups_x);
    }
}
"""


@pytest.mark.parametrize("n, max_groups", [(1, None), (64 * 64 + 5, None), (100_000, None), (100_000, 7),
                                           (64 * 1000, 999), (64 * 1000, 700)])
def test_dispatch_covers_every_index_once_with_the_work_interleaved(monkeypatch, n, max_groups):
    """Every index of a dispatch runs exactly once (1-D and 2-D grids), and the first half of the workgroups in
    dispatch order (llvmpipe's first thread) covers about half of every quarter of the problem: uneven work
    (glossy pixels in one part of the image) is shared by the threads. With blocks dealt in order the first half
    would cover the first two quarters alone; with a 2-D grid of full rows (a second row mostly idle, as at
    2160 x 2160) the first thread would get nearly all the work."""
    from renderers.gpu.context import get_device

    dev = get_device()
    if max_groups:
        monkeypatch.setattr(dev, "max_groups", max_groups)
    prog = dev.program("gid_test.comp", {}, source=_GID_SRC)
    hits, group_of, grid = dev.buffer(reserve=4 * n), dev.buffer(reserve=4 * n), dev.buffer(reserve=4)
    hits.clear()
    for binding, buf in enumerate((hits, group_of, grid), start=1):
        buf.bind_to_storage_buffer(binding)
    dev.dispatch(prog, n)
    dev.finish()
    counts = np.frombuffer(hits.read(), dtype=np.uint32)
    groups = np.frombuffer(group_of.read(), dtype=np.uint32)
    dispatched = int(np.frombuffer(grid.read(), dtype=np.uint32)[0])  # the grid's workgroups, idle ones included
    for buf in (hits, group_of, grid):
        dev.release(buf)
    assert (counts == 1).all()
    needed = -(-n // 64)
    assert needed <= dispatched < needed + 64 + dispatched // dev.max_groups  # padding: stripes and grid rows
    if n >= 64 * 64 * 4:
        # llvmpipe's first thread: the first half of the grid in dispatch order (not of the busy workgroups)
        first_half = groups < dispatched / 2
        shares = [q.mean() for q in np.array_split(first_half, 4)]
        assert all(0.4 < s < 0.6 for s in shares), shares


@settings(max_examples=300, deadline=None)
@given(groups=st.integers(1, 10**8), max_groups=st.integers(1, 70_000))
def test_the_grid_holds_the_work_with_less_than_a_row_of_idle_groups(groups, max_groups):
    from renderers.gpu.context import grid_shape

    assume(groups <= max_groups**2)
    gx, gy = grid_shape(groups, max_groups)
    assert 1 <= gx <= max_groups and 1 <= gy <= max_groups
    assert 0 <= gx * gy - groups < gy  # llvmpipe's threads each get a contiguous part of gx * gy: little idle
    assert gy == -(-groups // max_groups)  # the fewest rows


_LOOP_SRC = """#version 430
layout(local_size_x = 64) in;
#include "common.glsl"
layout(std430, binding = 1) writeonly buffer Out { int out_[]; };
uniform int u_iters;
void main() {
    cnt_begin();
    uint i = gid();
    if (i < uint(u_n)) {  // (the dispatch's idle invocations past u_n do not loop)
        int k = 0;
        for (int q = 0; q < u_iters; q++) k++;
        out_[i] = k;
    }
    cnt_end();
}
"""


@pytest.mark.parametrize("iters", [1_000, 70_000])
def test_loops_that_llvmpipe_cuts_short_are_counted(iters):
    """llvmpipe ends an invocation's loops early once it has run 65,535 loop iterations in all; common.glsl's probe
    counts those invocations (C_LOOP_LIMIT). A GPU has no such limit: there the loop runs to the end."""
    from renderers.gpu.context import get_device
    from renderers.gpu.frame import _COUNTER_DEFINES, COUNTERS

    dev = get_device()
    prog = dev.program("loop_limit_test.comp", dict(_COUNTER_DEFINES), source=_LOOP_SRC)
    n = 128
    out, counters = dev.buffer(reserve=4 * n), dev.buffer(np.zeros(len(COUNTERS), dtype=np.uint32))
    out.bind_to_storage_buffer(1)
    counters.bind_to_storage_buffer(5)
    prog["u_iters"] = iters
    dev.dispatch(prog, n)
    dev.finish()
    k = np.frombuffer(out.read(), dtype=np.int32)
    cut = int(np.frombuffer(counters.read(), dtype=np.uint32)[COUNTERS.index("loop_limit")])
    if iters > 65_535 and "llvmpipe" in dev.renderer:
        assert (k < iters).all() and cut == n
    else:
        assert (k == iters).all() and cut == 0
    dev.release(out)
    dev.release(counters)


def test_a_frame_with_loops_cut_short_is_refused():
    """A frame in which any invocation reached llvmpipe's loop limit is refused with one line, not returned."""
    import types

    from renderers.gpu.context import get_device
    from renderers.gpu.frame import COUNTERS, Frame

    fr = Frame(types.SimpleNamespace(device=get_device(), counters=types.SimpleNamespace(seconds={}, reshaded_pixels=0)))
    fr.counter_buf.write(np.eye(len(COUNTERS), dtype=np.uint32)[COUNTERS.index("loop_limit")] * 3)
    with pytest.raises(RuntimeError) as err:
        fr.close()
    assert str(err.value).startswith("3 GPU shader invocations reached llvmpipe's limit of 65,535 loop iterations")
    assert "\n" not in str(err.value)


def test_shader_resources_have_one_home():
    """Binding points, image units and uniform types are written once (renderers/gpu/bindings.py): the shader files
    declare none themselves, the generated declarations carry the table's numbers and types, and the host refuses a
    name no table declares, naming it."""
    import re

    from renderers.gpu import bindings, context
    from renderers.gpu.frame import bind, set_uniforms

    for f in sorted(context.SHADER_DIR.iterdir()):
        hand = [line for line in f.read_text().splitlines()
                if re.match(r"\s*(layout\(.*binding|uniform\s)", line)]
        assert not hand, (f.name, hand)
    samples = context.generated_source("samples_decl_gen.glsl")
    assert "layout(std430, binding = 6) buffer B_samples { vec4 samples[]; };" in samples
    assert "layout(binding = 4, rgba32f) uniform restrict writeonly image2D out_img;" in samples
    assert "uniform float u_w[33];" in context.generated_source("filters_decl_gen.glsl")
    assert context.generated_source("nothing_decl_gen.glsl") is None
    assert bindings.buffer_binding("hits") == 7 and bindings.buffer_binding("ctl") == 7  # lc_buffers
    assert bindings.image_unit("t_offs") == 6
    with pytest.raises(KeyError, match="'hitz'"):
        bind({"hitz": None})
    with pytest.raises(KeyError, match="'t_ofs'"):
        bind(None, {"t_ofs": None})
    with pytest.raises(KeyError, match="'u_widht'"):
        set_uniforms(None, {"u_width": 1, "u_widht": 2})
