"""Both backends agree on every built-in scene and every material kind (issue 29 item 3), at small sizes.

GT, VaFR, LMFR and LaFR on the five few-light scenes (diffuse, checker/brick/noise textured, glossy, metallic and
emissive materials between them): >= 35 dB and >= 99 % of the 8-bit pixels within one level. The lightcuts
family on the many-light scenes (cornell_many is covered by tests/test_gpu_lightcuts.py): per pixel over seeds the
means within 4 standard errors (the statistics of that test). Needs OpenGL 4.3 through EGL (llvmpipe in CI).
"""

from __future__ import annotations

import numpy as np
import pytest

from renderers import registry
from renderers import render as cpu_render
from renderers.catalog import resolve
from renderers.gpu import render as gpu_render
from renderers.gpu.agreement import agreement, seed_agreement

W, H = 96, 54
SCENES = ("cornell", "temple", "street_night", "interior", "street_day")
#: VaFR sized for the image (preset auto) so that the test stays small; with and without FXAA.
METHODS = [("gt", {}), ("vafr", {"preset": "auto", "fxaa": False}), ("vafr", {"preset": "auto"}), ("lmfr", {}),
           ("lafr", {})]


def test_the_scenes_cover_every_material_kind():
    kinds = {(m.kind, m.texture != "none", m.emissive) for s in SCENES for m in resolve(s).materials}
    assert {k for k, _, _ in kinds} == {"diffuse", "glossy", "metallic"}
    assert any(t for _, t, _ in kinds) and any(e for _, _, e in kinds)
    textures = {m.texture for s in SCENES for m in resolve(s).materials}
    assert textures == {"none", "checker", "brick", "noise"}


@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("renderer,params", METHODS,
                         ids=[f"{r}-{'-'.join(f'{k}={v}' for k, v in p.items())}" for r, p in METHODS])
def test_gpu_agrees_with_cpu_on_every_scene(scene, renderer, params):
    a, sa = cpu_render(scene, renderer, params, W, H)
    b, sb = gpu_render(scene, renderer, params, W, H)
    psnr, within = agreement(a, b)
    assert float(a.max()) > 0 and sb["shading_points"] == sa["shading_points"]
    assert psnr >= 35.0, psnr
    assert within >= 0.99, within


LC_SCENES = ("study", "yard", "sponza_vpl")
SEEDS = 4


@pytest.mark.parametrize("scene", LC_SCENES)
@pytest.mark.parametrize("name", ("fsl", "sl_as"))
def test_lightcuts_agree_on_the_many_light_scenes(scene, name):
    """Same seeds: the GPU draws the CPU's random numbers; per pixel the means agree within 4 standard errors on
    >= 99.5 % of the pixels and the variances match (median ratio within 3 %)."""
    def stack(backend):
        return np.stack([registry.render(scene, name, {"seed": s}, 48, 27, backend=backend)[0] for s in range(SEEDS)])

    same = seed_agreement(stack("cpu"), stack("gpu"))
    assert same["pixels"] - same["deterministic"] > 500, same
    assert same["means_within"] >= 0.995, same
    assert 0.97 <= same["median_ratio"] <= 1.03, same
    assert same["ratio_within"] >= 0.9, same
