"""One source for the per-pixel physics on both backends (issue 29 items 1-2).

The shading kernels of renderers/_shade.py (textures, the value-noise hash, the BRDF lobes and light terms) are
translated into GLSL by renderers/gpu/codegen.py; the constants both backends share live in renderers/constants.py.
These tests check the generated kernels against the numba ones value for value, that a kernel changed in a
temporary copy moves both backends' images together, and that the generator names what it cannot translate.
Needs OpenGL 4.3 through EGL (llvmpipe in CI): without it they fail, they do not skip.
"""

from __future__ import annotations

import importlib.util
import inspect
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from renderers import _shade, constants
from renderers.gpu import codegen

SHADERS = Path(codegen.__file__).parent / "shaders"


def _table():
    return {k: v for k, v in vars(constants).items()
            if k.isupper() and isinstance(v, (int, float)) and not isinstance(v, bool)}


def test_every_shared_constant_is_written_once():
    """constants_gen.glsl declares every constant of the table with its value; the CPU kernels use the table's
    objects; no hand-written shader repeats the acuity, luminance or shading literals."""
    glsl = codegen.constants_glsl()
    for k, v in _table().items():
        m = re.search(rf"const (int|float) {k} = ([^;]+);", glsl)
        assert m, k
        assert float(m.group(2)) == pytest.approx(v, rel=1e-15)
    for k in ("TEX_NOISE", "LIGHT_EMITTER", "INV_PI", "LUMA_G"):
        assert getattr(_shade, k) is getattr(constants, k)
    from renderers.lightcuts import fpsm, sampling

    assert fpsm.ACUITY_FLOOR is constants.ACUITY_FLOOR and sampling.LC_OFFSET_FRACTION is constants.LC_OFFSET_FRACTION
    hand = "\n".join(p.read_text() for p in sorted(SHADERS.glob("*")) if p.suffix in (".glsl", ".comp"))
    for literal in ("1.1715", "2.45", "0.2126", "0.7152", "0.0722", "73856093", "0.3183098861837907", "65535.0",
                    "9E3779B9", "umulExtended"):
        assert literal not in hand, literal


def _run(dev, src, inputs: np.ndarray, n_out: int, defines=None):
    prog = dev.program("codegen_test.comp", defines or {}, source=src)
    b_in = dev.buffer(np.ascontiguousarray(inputs, dtype=np.float64))
    b_out = dev.buffer(reserve=8 * n_out * len(inputs))
    b_in.bind_to_storage_buffer(1)
    b_out.bind_to_storage_buffer(2)
    prog["u_n"] = len(inputs)
    prog.run(-(-len(inputs) // 64))
    dev.finish()
    out = np.frombuffer(b_out.read(), np.float64).reshape(len(inputs), n_out).copy()
    dev.release(b_in), dev.release(b_out)
    return out


_HEAD = """#version 430
layout(local_size_x = 64) in;
#include "shade_gen.glsl"
layout(std430, binding = 1) readonly buffer In { double v[]; };
layout(std430, binding = 2) writeonly buffer Out { double r[]; };
uniform int u_n;
"""


def test_generated_shading_kernels_are_the_cpus():
    """shade_gen.glsl evaluates the numba kernels' formulas: the textures (checker, brick, two octaves of value
    noise with numba's int64 hash) in double precision equal the CPU's to 1e-12; the lobes and light terms in
    float32 to float32 rounding."""
    from renderers.gpu.context import get_device

    dev = get_device()
    rng = np.random.default_rng(29)
    n = 2048
    # textures: kind, scale, p (also negative, large: the hash's sign extension and carries), n
    tex = np.column_stack([rng.integers(0, 4, n), rng.uniform(0.05, 3.0, n), rng.uniform(-2e3, 2e3, (n, 3)),
                           rng.normal(size=(n, 3))])
    src = _HEAD + """void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i < uint(u_n)) {
        uint b = 8u * i;
        r[i] = shade_texture_weight(int(v[b]), v[b + 1u], v[b + 2u], v[b + 3u], v[b + 4u], v[b + 5u], v[b + 6u],
                                    v[b + 7u]);
    }
}"""
    got = _run(dev, src, tex, 1)[:, 0]
    want = np.array([_shade.texture_weight(int(t[0]), *t[1:]) for t in tex])
    assert 0.2 < np.mean(want[tex[:, 0] == 3]) < 0.8  # the noise has structure
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)

    # lights: kind, light position, light direction/normal, p, n (unit), v (unit), metallic, glossy, exponent
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    vv = rng.normal(size=(n, 3))
    vv /= np.linalg.norm(vv, axis=1, keepdims=True)
    ld = rng.normal(size=(n, 3))
    ld /= np.linalg.norm(ld, axis=1, keepdims=True)
    lt = np.column_stack([rng.integers(0, 3, n), rng.uniform(-5, 5, (n, 3)), ld, rng.uniform(-5, 5, (n, 3)), nrm, vv,
                          rng.integers(0, 2, (n, 2)), rng.uniform(0.0, 200.0, n)])
    src = _HEAD + """void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i < uint(u_n)) {
        float x[22];
        for (int k = 0; k < 22; k++) x[k] = float(v[22u * i + uint(k)]);
        int kind = int(x[0]);
        vec4 w = shade_light_direction(kind, x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8], x[9]);
        float e = shade_irradiance_factor(kind, x[4], x[5], x[6], x[10], x[11], x[12], w.x, w.y, w.z, w.w);
        vec4 lobes = shade_material_lobes(x[16], x[17], x[18]);
        float sp = shade_specular_lobe(lobes.w, x[18], x[10], x[11], x[12], w.x, w.y, w.z, x[13], x[14], x[15]);
        float lum = shade_luminance(x[1], x[2], x[3]);
        double res[11] = double[11](w.x, w.y, w.z, w.w, e, lobes.x, lobes.y, lobes.z, lobes.w, sp, lum);
        for (int k = 0; k < 11; k++) r[11u * i + uint(k)] = res[k];
    }
}"""
    got = _run(dev, src, np.column_stack([lt, np.zeros((n, 3))]), 11)
    want = []
    for t in lt:
        kind = int(t[0])
        w = _shade.light_direction(kind, *t[1:4], *t[4:7], *t[7:10])
        e = _shade.irradiance_factor(kind, *t[4:7], *t[10:13], *w)
        lobes = _shade.material_lobes(t[16], t[17], t[18])
        sp = _shade.specular_lobe(lobes[3], t[18], *t[10:13], *w[:3], *t[13:16])
        want.append([*w, e, *lobes, sp, _shade.luminance(*t[1:4])])
    want = np.array(want)
    assert (want[:, 4] == 0).mean() > 0.2 and (want[:, 4] > 0).mean() > 0.2   # lit and unlit both drawn
    assert (want[:, 9] > 0).mean() > 0.2
    np.testing.assert_allclose(got, want, rtol=2e-4, atol=1e-6)


def test_generated_glossy_lobe_is_the_cpus():
    """glossy_gen.glsl's lobe_ray (seed 003 Algorithm 1 lines 16-17's per-ray sampling, called by lobe_sample)
    gives the numba kernel's direction and weight to float32 rounding, rays below the surface included."""
    from renderers.gpu.context import get_device
    from renderers.lightcuts import _kernels as K
    from renderers.lightcuts.glossy import lobe_ray

    rng = np.random.default_rng(17)
    n = 1024
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    view = rng.normal(size=(n, 3))
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    view *= np.sign(np.einsum("ij,ij->i", nrm, view))[:, None]    # the viewer above the surface, as for a hit
    frames = np.array([np.concatenate((K.tangent(*v), K.bitangent(*v))) for v in nrm])
    x = np.column_stack([nrm, frames, view, rng.uniform(0.0, 300.0, n), rng.uniform(0.0, 1.0, (n, 2)),
                         rng.integers(1, 9, n)])
    # lobe_sample's frame and uniforms (lightcuts_gen.glsl's, tested with the lightcuts) are the inputs' here
    head = """float x[18];
vec3 lc_tangent(float a, float b, float c) { return vec3(x[3], x[4], x[5]); }
vec3 lc_bitangent(float a, float b, float c) { return vec3(x[6], x[7], x[8]); }
float lc_uniform_f(uvec2 seed, uvec2 pixel, int slot) { return x[13 + (slot & 1)]; }
#include "glossy_gen.glsl"
"""
    src = _HEAD.replace('#include "shade_gen.glsl"', head) + """void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i < uint(u_n)) {
        for (int k = 0; k < 18; k++) x[k] = float(v[18u * i + uint(k)]);
        vec4 ray = glossy_lobe_sample(uvec2(0u), uvec2(0u), 0, x[0], x[1], x[2], x[9], x[10], x[11], x[12], int(x[15]));
        for (int k = 0; k < 4; k++) r[4u * i + uint(k)] = double(ray[k]);
    }
}"""
    got = _run(get_device(), src, np.column_stack([x, np.zeros((n, 2))]), 4)
    want = np.array([lobe_ray(*t[:15], int(t[15])) for t in x])
    assert 0.1 < (want[:, 3] == 0).mean() < 0.9   # rays above and below the surface both drawn
    np.testing.assert_allclose(got, want, rtol=1e-3, atol=1e-4)


def test_generated_gt_sample_offsets_are_the_cpus():
    """gt_gen.glsl's sample_offset (renderers/_gt.py: lowbias32 on numba's uint32 values, wrapping products, the
    strata in double precision) places every GT sample where the CPU does, bit for bit, at any pixel (large
    coordinates: the hash's wrap-around) and spp (1: the centre)."""
    from renderers import _gt
    from renderers.gpu.context import get_device

    rng = np.random.default_rng(5)
    n = 2048
    side = rng.integers(1, 17, n)
    x = np.column_stack([rng.integers(0, 1 << 16, (n, 2)), rng.integers(0, 1 << 30, n) % (side * side),
                         side * side, side])
    src = _HEAD.replace('#include "shade_gen.glsl"\n', "") + """uniform int u_s0, u_width;
float outbuf[1];      // the pixel filter's samples (unused here)
double gt_part[8];
#define SPP 1
#define SPP_SIDE 1
#include "gt_gen.glsl"
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i < uint(u_n)) {
        uint b = 5u * i;
        dvec2 o = gt_sample_offset(int(v[b]), int(v[b + 1u]), int(v[b + 2u]), int(v[b + 3u]), int(v[b + 4u]));
        r[2u * i] = o.x;
        r[2u * i + 1u] = o.y;
    }
}"""
    got = _run(get_device(), src, x, 2)
    want = np.array([_gt.sample_offset(*map(int, t)) for t in x])
    assert ((want > 0) & (want < 1)).all() and len(np.unique(want)) > n
    assert np.array_equal(got, want)


def _copy_of_shade(tmp_path, name: str, edits: list[tuple[str, str]]):
    """renderers/_shade.py with ``edits`` applied, imported as a package module of its own (relative imports
    resolved against ``renderers``)."""
    text = inspect.getsource(_shade)
    for old, new in edits:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = tmp_path / f"{name}.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location(f"renderers.{name}", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("old,new,message", [
    ("        return 1.0\n    ax, ay, az", "        return 1.0\n    for f in (1.0, 2.0):\n        scale = scale / f\n"
     "    ax, ay, az", "texture_weight: for loop over Tuple"),
    ("    h = h ^ (h >> 16)", "    h = h ^ (h >> 16)\n    h = h * x", "_hash3: int64 operation i64 Mult i64"),
    ("    return LUMA_R * r + LUMA_G * g + LUMA_B * b", "    return [r, g, b][0]", "luminance: subscript of List"),
    ("    return LUMA_R * r + LUMA_G * g + LUMA_B * b", "    return r, g, b, r, g", "luminance: tuple of 5 values"),
    ("    cos_t = nx * wx", "    cos_t = np.dot(nx, wx)\n    cos_t = nx * wx", "irradiance_factor: call of "),
    ("    cos_t = nx * wx", "    half = nx\n    cos_t = half * wx",
     "irradiance_factor: name 'half' is reserved in GLSL"),
    ("    cos_t = nx * wx", "    q = np.uint32(nx)\n    cos_t = nx * wx", "irradiance_factor: np.uint32 of a float"),
    ("    return LUMA_R * r + LUMA_G * g + LUMA_B * b", "    return np.uint32(int(r)) * 3",
     "luminance: uint32 operation Mult outside np.uint32(...)"),
], ids=["for-over-tuple", "int64-product", "list", "5-tuple", "numpy-call", "glsl-keyword", "uint32-of-float",
        "uint32-product"])
def test_generator_names_what_it_cannot_translate(tmp_path, old, new, message):
    mod = _copy_of_shade(tmp_path, "_shade_bad", [(old, new)])
    try:
        with pytest.raises(NotImplementedError, match=re.escape(message)):
            codegen.shade_glsl(mod)
    finally:
        sys.modules.pop("renderers._shade_bad", None)


def test_generator_names_a_missing_binding_and_a_value_of_nothing():
    """An array's shape without a binding for it, and the value of an external (the GPU's own fragment), which
    returns nothing: both named, not translated into GLSL that fails to compile."""
    import inspect

    from renderers import _warp, antialias

    tr = codegen.Translator(antialias, "aa_", bindings={"img": "img({0}, {1}, {2})", "steps": "S[{0}]",
                                                        "steps.size": "5"})
    names = tr.closure(antialias.GLSL_DOUBLE_ROOTS)
    tr.infer(names, {"fxaa_pixel": {"x": "int", "y": "int"}})
    with pytest.raises(NotImplementedError, match=re.escape("img.shape of an array without a 'img.shape' binding")):
        tr.emit(names)
    source = inspect.getsource(_warp).replace("            fragment((j % n[c])", "            zz = fragment((j % n[c])")
    tr = codegen.Translator(_warp, "rep_", source=source, bindings={k: "" for k in ("u", "phi", "z", "L", "n", "col",
                                                                                     "zbuf", "out", "covered")})
    tr.externals = {"fragment": ("rep_fragment", "void")}
    with pytest.raises(NotImplementedError, match="raster_triangle: zz takes the value of a call that returns nothing"):
        tr.infer(tr.closure(_warp.GLSL_FLOAT_ROOTS), {"warp_quad": {}})


def test_the_pixel_kernels_of_the_lp_passes_are_the_cpus_filters():
    """The Gaussian pixel kernel that the GPU's LP and foveal filters are generated from (antialias.gauss_pixel) is
    bit for bit scipy's separable correlate1d (antialias.blur) on the CPU; the row filling (_lp.fill_rows) copies
    each unshaded pixel's last shaded left neighbour; and the generated GLSL calls them by name."""
    from renderers import _lp, antialias as AA

    rng = np.random.default_rng(29)
    img = (rng.random((23, 31, 3)) ** 3 * 4).astype(np.float32)
    for b in (1, 2, 3):
        r = AA.FOVEAL_RADII[b]
        out = np.empty_like(img)
        k = AA.FOVEAL_WEIGHTS[AA.FOVEAL_STRIDE * (b - 1):]
        AA._gaussian(img, np.ascontiguousarray(k), r, 0, out)
        assert np.array_equal(out, AA.blur(img, AA.FOVEAL_SIGMAS[b], r))
    shaded = rng.random((23, 31)) < 0.5
    filled = img.copy()
    _lp.fill_rows(filled, shaded)
    src = np.maximum.accumulate(np.where(shaded, np.arange(31), 0), axis=1)
    assert np.array_equal(filled, img[np.arange(23)[:, None], src])
    assert "vec3 lp_inverse_pixel(int x, float y)" in codegen.lp_glsl("inverse")
    assert "void lp_fill_row(int j, int w)" in codegen.lp_glsl("fill")
    assert "float aa_foveal_pixel(" in codegen.antialias_glsl("foveal")
    assert "dvec2 gt_sample_offset(int px, int py, int s, int spp, int side)" in codegen.gt_glsl()


def test_a_kernel_change_moves_both_backends_together(tmp_path, monkeypatch):
    """Change BRDF terms (the Blinn-Phong normalisation (s + 8) / 8 pi -> (s + 2) / 2 pi, the Lambert weight 1 / pi
    -> 0.6 / pi) and a texture constant (brick mortar 0.05 -> 0.2 of a brick) in a temporary copy of renderers/_shade.py: the CPU (numba) and the GPU
    (GLSL generated from the copy) images both change, by the same amount, and still agree."""
    from renderers import render as cpu_render
    from renderers import tracer
    from renderers.gpu import render as gpu_render
    from renderers.gpu.agreement import agreement
    from renderers.gpu.context import get_device

    w, h = 96, 72
    before = cpu_render("cornell", "gt", {}, w, h)[0], gpu_render("cornell", "gt", {}, w, h)[0]
    mod = _copy_of_shade(tmp_path, "_shade_changed", [
        ("(s_exp + 8.0) / (8.0 * math.pi)", "(s_exp + 2.0) / (2.0 * math.pi)"),
        ("kd = 0.0 if metallic_flag > 0.5 else INV_PI", "kd = 0.0 if metallic_flag > 0.5 else 0.6 * INV_PI"),
        ("fs < 0.05 or", "fs < 0.2 or")])
    try:
        monkeypatch.setattr(tracer, "S", mod)
        monkeypatch.setattr(codegen, "_shade_glsl_cached", lambda: codegen._shade_glsl(mod))
        monkeypatch.setattr(codegen, "_lights_glsl_cached", lambda roots: codegen._lights_glsl(mod, roots))
        monkeypatch.setattr(get_device(), "_programs", {})   # compile the changed shaders (restored afterwards)
        after = cpu_render("cornell", "gt", {}, w, h)[0], gpu_render("cornell", "gt", {}, w, h)[0]
    finally:
        sys.modules.pop("renderers._shade_changed", None)
    assert agreement(before[0], before[1])[0] >= 35.0
    for b, a in zip(before, after):
        assert agreement(b, a)[0] < 30.0   # a visible change on each backend
    psnr, within = agreement(after[0], after[1])
    assert psnr >= 35.0 and within >= 0.99, (psnr, within)
    d_cpu, d_gpu = after[0] - before[0], after[1] - before[1]
    assert np.abs(d_gpu - d_cpu).max() <= 0.02 * np.abs(d_cpu).max()   # the same change


def test_an_acuity_constant_changed_in_the_table_moves_both_fpsms(monkeypatch):
    """Change seed 003 Eq 2's slope in renderers/constants.py (2.45 -> 1.2 per radian: a wider fovea): the CPU's
    FPSM (numpy) and the GPU's (GLSL generated from fpsm.acuity and the table) both change and still agree."""
    from renderers import registry
    from renderers.gpu.context import get_device
    from renderers.lightcuts import fpsm

    def maps():
        args = ("cornell_many", "fsl", {"max_rspp": 2}, 57, 33)
        return (registry.render(*args, gaze=(20, 12))[1]["fpsm"],
                registry.render(*args, gaze=(20, 12), backend="gpu")[1]["fpsm"])

    before = maps()
    monkeypatch.setattr(constants, "ACUITY_SLOPE", 1.2)
    monkeypatch.setattr(fpsm, "ACUITY_SLOPE", 1.2)
    monkeypatch.setattr(codegen, "constants_glsl", codegen.constants_glsl.__wrapped__)   # re-read the table
    monkeypatch.setattr(codegen, "fpsm_glsl", codegen.fpsm_glsl.__wrapped__)
    monkeypatch.setattr(get_device(), "_programs", {})
    after = maps()
    np.testing.assert_allclose(before[1], before[0], rtol=0, atol=1e-4)
    np.testing.assert_allclose(after[1], after[0], rtol=0, atol=1e-4)
    for b, a in zip(before, after):
        assert float(np.mean(a - b)) > 0.02   # a wider fovea: the map rises on both backends


def test_generated_fpsm_kernels_are_the_cpus():
    """fpsm_gen.glsl evaluates the CPU's per-pixel FPSM kernels (seed 003 Eq 3's contrast and feature, Eq 4-7's
    rho under each reading, Eq 8's map, the spline weights of the upsampling) to float32 rounding, and the budget
    (double precision) exactly. The stencil kernels (Sobel, blur, resampling) are checked on whole maps by
    tests/test_gpu_lightcuts.py::test_gpu_fpsm_is_the_cpus."""
    from renderers.gpu.context import get_device
    from renderers.lightcuts import fpsm

    rng = np.random.default_rng(3)
    n = 1024

    def f32(a):   # inputs the GPU holds exactly
        return a.astype(np.float32).astype(np.float64)

    st, lu, alpha = f32(rng.uniform(0, 1, n)), f32(rng.uniform(0, 1, n)), f32(rng.uniform(0.01, 0.9, n))
    mean_st = f32(st + rng.normal(0, 0.05, n) * (rng.uniform(size=n) < 0.8))   # some flat: D = 0
    mean_lu = f32(lu + rng.normal(0, 0.05, n) * (rng.uniform(size=n) < 0.8))
    inp = np.column_stack([st, lu, mean_st, mean_lu, alpha, rng.integers(0, 3, n), f32(rng.normal(0, 0.5, n)),
                           f32(rng.uniform(-0.01, 1.0, n)), rng.integers(1, 64, n), rng.integers(0, 2, n),
                           2 * rng.integers(0, 2, n) + 1])
    src = """#version 430
layout(local_size_x = 64) in;
float fp_img(int c, int k) { return 0.0; }
float fp_gbuf(int k, int c) { return 0.0; }
float fp_low[1];
#include "fpsm_gen.glsl"
layout(std430, binding = 1) readonly buffer In { double v[]; };
layout(std430, binding = 2) writeonly buffer Out { double r[]; };
uniform int u_n;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i < uint(u_n)) {
        float x[11];
        for (int k = 0; k < 11; k++) x[k] = float(v[11u * i + uint(k)]);
        float rho = fpsm_rho_at(x[0], x[1], x[2], x[3], x[4], int(x[5]));
        vec4 w = fpsm_spline_weights(fract(x[7]), int(x[10]));
        double res[10] = double[10](rho, fpsm_map_at(rho, 0.1, 2.0), fpsm_contrast_at(x[6], x[7], 0.01),
                                    fpsm_feature(x[0], x[6]), fpsm_budget(x[7], int(x[8]), int(x[9])), w.x, w.y,
                                    w.z, w.w, 0.0);
        for (int k = 0; k < 10; k++) r[10u * i + uint(k)] = res[k];
    }
}"""
    got = _run(get_device(), src, inp, 10)
    want = []
    for s, u, ms, mu, a, reading, band, m, most, least, order in inp:
        rho = fpsm.rho_at(s, u, ms, mu, a, int(reading))
        want.append([rho, fpsm.map_at(rho, 0.1, 2.0), fpsm.contrast_at(band, m, 0.01), fpsm.feature(s, band),
                     fpsm.budget(m, int(most), int(least)), *fpsm.spline_weights(m % 1.0, int(order)), 0.0])
    want = np.array(want)
    assert np.isinf(want[:, 0]).mean() > 0.1 and (np.isfinite(want[:, 0]) & (want[:, 0] > 0)).mean() > 0.3
    np.testing.assert_allclose(got[:, :4], want[:, :4], rtol=2e-4, atol=1e-6)
    np.testing.assert_array_equal(got[:, 4], want[:, 4])
    np.testing.assert_allclose(got[:, 5:], want[:, 5:], rtol=0, atol=1e-6)
def test_generated_fxaa_is_the_cpus_to_the_bit(monkeypatch):
    """fxaa_gen.glsl is renderers/antialias.py fxaa_pixel in numba's types (float32 sums of the image's values,
    float64 elsewhere): on the GPU's own LP buffer the GPU's FXAA equals the CPU's bit for bit, edge decisions and
    all (street_day's daylight edges, where a float32 port differed on 94 LP pixels by up to 0.15)."""
    from renderers import antialias
    from renderers.gpu import pipelines, render

    seen = {}
    finish = pipelines.finish_lp

    def spy(fr, tables, lp, params, *args):
        img = finish(fr, tables, lp, params, *args)

        def read(tex):
            return np.frombuffer(tex.read(), np.float32).reshape(tables.h, tables.w, -1)[..., :3]
        seen.update(lp=read(lp), out=read(fr.pool.image("lp2", (tables.w, tables.h))), n=tables.layout.n.copy())
        return img

    monkeypatch.setattr(pipelines, "finish_lp", spy)
    render("street_day", "vafr", {"preset": "auto"}, 96, 54)
    cpu = antialias.lp_filter(seen["lp"].copy(), seen["n"], "fxaa")
    filtered = np.arange(cpu.shape[0])[:, None] < seen["n"][None, :]   # the rows the inverse mapping reads
    assert filtered.sum() > 10000 and (cpu != seen["lp"]).any(axis=-1)[filtered].sum() > 1000
    assert np.array_equal(cpu[filtered], seen["out"][filtered])


def test_generated_camera_rays_are_the_cpus_to_the_bit():
    """camera.glsl's rays are renderers/projection.py plane_offsets and ray_direction, generated in double
    precision (precise): the CPU's float64 rays rounded to float32, bit for bit, at pixel centres and at
    arbitrary positions of a large and a small display."""
    from renderers.catalog import resolve
    from renderers.gpu.context import get_device
    from renderers.gpu.upload import camera_uniforms
    from renderers.projection import camera_rays

    dev = get_device()
    rng = np.random.default_rng(27)
    src = _HEAD.replace('"shade_gen.glsl"', '"camera.glsl"') + """void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i < uint(u_n)) {
        vec3 d = camera_ray_d(dvec2(v[2u * i], v[2u * i + 1u]));
        r[3u * i] = double(d.x); r[3u * i + 1u] = double(d.y); r[3u * i + 2u] = double(d.z);
    }
}"""
    for scene, (w, h) in (("temple", (2468, 2740)), ("street_day", (96, 54))):
        cam = resolve(scene).camera
        xy = np.concatenate([rng.uniform(0, 1, (4000, 2)) * (w, h), rng.integers(0, (w, h), (4000, 2)) + 0.5])
        prog = dev.program("codegen_test.comp", {}, source=src)   # the cached program that _run dispatches
        for k, v in camera_uniforms(cam, w, h).items():
            prog[k] = v
        got = _run(dev, src, xy, 3)
        want = camera_rays(cam, w, h, xy[:, 0], xy[:, 1]).astype(np.float32)
        assert np.array_equal(got.astype(np.float32), want)


def test_integer_remainder_keeps_pythons_sign(tmp_path):
    """``a % b`` of ints is Python's (the divisor's sign) on the GPU too: GLSL leaves ``%`` of negative operands
    undefined (the wrapped LP rows, the warp's rows and the GT strata go through it)."""
    from renderers.gpu.context import get_device

    path = tmp_path / "imod_kernels.py"
    path.write_text("def rem(a, b):\n    r = a % b\n    r %= b\n    return r\n")
    spec = importlib.util.spec_from_file_location("imod_kernels", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    tr = codegen.Translator(mod, "t_")
    tr.infer(["rem"], {"rem": {"a": "int", "b": "int"}})
    glsl = tr.emit(["rem"], helpers=False)
    assert glsl.count("int py_imod(int a, int b)") == 1 and "%" not in glsl.split("#endif")[1]
    src = _HEAD.replace('#include "shade_gen.glsl"', glsl) + """void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i < uint(u_n)) r[i] = double(t_rem(int(v[2u * i]), int(v[2u * i + 1u])));
}"""
    pairs = np.array([(a, b) for a in range(-9, 10) for b in (-7, -3, -1, 1, 2, 5)], dtype=np.float64)
    got = _run(get_device(), src, pairs, 1)[:, 0]
    assert np.array_equal(got, [(int(a) % int(b)) % int(b) for a, b in pairs])


def test_hand_maintained_glsl_is_at_most_half():
    """Issue 29: the hand-maintained GLSL (shaders/*.glsl, *.comp) stays at most half of the 2,136 lines it was
    before the per-pixel physics was generated (docs/gpu.md lists what is generated and what is not); every file
    that the shaders include and that is not in shaders/ is generated."""
    from renderers.gpu.context import SHADER_DIR, generated_source

    files = sorted([*SHADER_DIR.glob("*.glsl"), *SHADER_DIR.glob("*.comp")])
    lines = sum(len(f.read_text(encoding="utf-8").splitlines()) for f in files)
    assert lines <= 2136 // 2, lines
    included = {m for f in files for m in re.findall(r'#include "([^"]+)"', f.read_text(encoding="utf-8"))}
    missing = [n for n in included if not (SHADER_DIR / n).exists() and generated_source(n) is None]
    assert not missing and any(n.endswith("_gen.glsl") for n in included), missing
