"""GPU backend against the CPU renderers (issue 13 items 3, 5, 7, 8): Cornell box at 160 x 120 on llvmpipe.

For every method the GPU's linear image agrees with the CPU's to >= 35 dB PSNR and its 8-bit PNG within one
level on >= 99 % of the pixels, and the work counters are equal (shading points exactly; the others up to the
float32/float64 ties of the light culling). These tests need OpenGL 4.3 through EGL: without it they fail.
"""

from __future__ import annotations

import numpy as np
import pytest

from renderers import render as cpu_render
from renderers.gpu import render as gpu_render
from renderers.gpu.agreement import agreement

W, H = 160, 120
#: (renderer, params): every method, FXAA on and off, mono/dup/rep, raycast/deferred, GT with spp.
CASES = [
    ("gt", {}),
    ("gt", {"spp": 4, "filter": "tent"}),
    ("vafr", {"stereo": "dup", "eye": "right"}),
    ("vafr", {"stereo": "rep", "eye": "right", "fxaa": False, "preset": "pimax_crystal"}),
    ("vafr", {"pipeline": "deferred", "preset": "auto"}),
    ("lmfr", {}),
    ("lafr", {}),
]
EXACT = ("offscreen_lp_pixels", "reshaded_pixels", "missed_rays")
TIES = ("rays_shadow", "shadow_rays_skipped", "glossy_evaluations", "lights_culled", "missed_rays")


@pytest.mark.parametrize("renderer,params", CASES, ids=[f"{r}-{'-'.join(f'{k}={v}' for k, v in p.items())}"
                                                         for r, p in CASES])
def test_gpu_agrees_with_cpu(renderer, params):
    a, sa = cpu_render("cornell", renderer, params, W, H)
    b, sb = gpu_render("cornell", renderer, params, W, H)
    assert b.shape == a.shape and b.dtype == np.float32 and np.isfinite(b).all()
    psnr, within = agreement(a, b)
    assert psnr >= 35.0, psnr
    assert within >= 0.99, within
    if params.get("stereo") in ("dup", "rep"):  # both eyes come back: a binocular presenter shows both
        assert len(sb["eye_images"]) == len(sa["eye_images"]) == 2
        for ea, eb in zip(sa["eye_images"], sb["eye_images"]):
            assert eb.shape == ea.shape and agreement(ea, eb)[1] >= 0.99
    for k in EXACT if params.get("stereo") != "rep" else EXACT[:1]:
        assert sb[k] == sa[k], (k, sa[k], sb[k])
    # Shading points and rays exactly; rep's re-shaded holes to 0.01 % (float32 rasterisation of the warped grid
    # may flip a pixel on the warp's boundary).
    for k in ("shading_points", "rays_primary"):
        assert sb[k] - sb["reshaded_pixels"] == sa[k] - sa["reshaded_pixels"], (k, sa[k], sb[k])
    assert abs(sb["reshaded_pixels"] - sa["reshaded_pixels"]) <= 1e-4 * sa["shading_points"]
    for k in TIES:  # float32 vs float64 ties in the culling order: a few per million
        assert abs(sb[k] - sa[k]) <= max(10, 1e-4 * sa[k]), (k, sa[k], sb[k])
    assert set(sa) - {"gpu", "backend"} <= set(sb)
    assert set(sb["seconds"]) == set(sa["seconds"]) and sb["seconds"]["total"] > 0
    if params.get("stereo") == "rep":
        assert sa["reshaded_pixels"] > 0 and sb["reshaded_share"] == pytest.approx(sa["reshaded_share"], rel=1e-3)


def test_skipped_work_is_counted():
    """Misses are not shaded, off-screen LP pixels not traced, lights behind a point or culled get no shadow
    ray, the glossy lobe is evaluated only on glossy materials (issue 13 item 8)."""
    _, st = gpu_render("cornell", "lmfr", {}, W, H)
    assert st["shading_points"] + st["missed_rays"] == st["rays_primary"]
    assert st["offscreen_lp_pixels"] > 0 and st["rays_primary"] + st["offscreen_lp_pixels"] == st["lp_pixels"]
    assert 0 < st["rays_shadow"] < st["shading_points"] * st["lights"]
    assert st["rays_shadow"] + st["shadow_rays_skipped"] == st["shading_points"] * st["lights"]
    assert st["lights_culled"] > 0
    assert 0 < st["glossy_evaluations"] < st["shading_points"] * st["lights"]
    _, st = gpu_render("cornell", "gt", {"shadows": False, "light_cull": 0.0}, 32, 24)
    assert st["rays_shadow"] == 0 and st["lights_culled"] == 0


def test_gaze_follows_without_reupload():
    """Per frame only camera and gaze change: the scene upload is reused, the image moves with the gaze."""
    from renderers.gpu.context import get_device

    a, _ = gpu_render("cornell", "lafr", {}, W, H, gaze=(40, 30))
    uploads = dict(get_device().cache["uploads"])
    b, st = gpu_render("cornell", "lafr", {}, W, H, gaze=(120, 90))
    assert get_device().cache["uploads"] == uploads and st["setup_seconds"] < 1.0
    c, _ = cpu_render("cornell", "lafr", {}, W, H, gaze=(120, 90))
    assert agreement(c, b)[1] >= 0.99 and agreement(a, b)[1] < 0.9


@pytest.mark.parametrize("scene,renderer,params", [
    ("cornell", "gt", {"spp": 4, "filter": "tent"}),
    ("cornell", "vafr", {"stereo": "rep", "eye": "right"}),
    ("cornell", "vafr", {"pipeline": "deferred", "preset": "auto"}),
    ("cornell", "lmfr", {}),
    ("cornell_many", "fsl", {}),
    ("cornell_many", "sl_as", {}),
    ("cornell_many", "sl_gt", {"lspp": 96, "rspp": 16}),
], ids=lambda v: v if isinstance(v, str) else None)
def test_dealing_workgroups_in_stripes_changes_no_pixel(monkeypatch, scene, renderer, params):
    """``Device.dispatch`` deals workgroups in interleaved stripes (so llvmpipe's threads share uneven work): the
    same invocations run, only in another order, so every pipeline gives the same frame and counts as with the
    workgroups dealt in order (STRIPES = 1)."""
    import renderers.gpu.context as C

    frames = []
    for stripes in (1, C.STRIPES):
        monkeypatch.setattr(C, "STRIPES", stripes)
        frames.append(gpu_render(scene, renderer, params, 96, 54))
    (a, sa), (b, sb) = frames
    assert float(a.max()) > 0
    np.testing.assert_array_equal(a, b)
    for k in ("shading_points", "rays_primary", "rays_shadow", "light_samples", "glossy_rays"):
        if k in sa:
            assert sa[k] == sb[k], (k, sa[k], sb[k])
