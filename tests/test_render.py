"""Renderers: GT against a brute-force reference, foveated renderers against GT, reprojection, AA, registry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from data_schema.geometry import ViewingGeometry
from renderers import render
from renderers.antialias import fxaa
from renderers.registry import Param, RendererPlugin, available, resolve_params
from renderers.scene import Camera, Material, PointLight, Scene, ViewSettings


# -- an independent brute-force reference (pure numpy Möller–Trumbore, per pixel and per light) ---------------
def _mt(orig, dirs, tri):
    """Closest-hit t and triangle index of rays (n, 3) against triangles (m, 3, 3); inf / -1 on a miss."""
    v0, v1, v2 = tri[:, 0], tri[:, 1], tri[:, 2]
    e1, e2 = v1 - v0, v2 - v0
    p = np.cross(dirs[:, None, :], e2[None])
    det = np.einsum("nmk,mk->nm", p, e1)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = orig[:, None, :] - v0[None]
    u = np.einsum("nmk,nmk->nm", s, p) * inv
    q = np.cross(s, e1[None])
    v = np.einsum("nk,nmk->nm", dirs, q) * inv
    t = np.einsum("nmk,mk->nm", q, e2) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    t = np.where(hit, t, np.inf)
    idx = np.argmin(t, axis=1)
    tmin = t[np.arange(len(t)), idx]
    return tmin, np.where(np.isfinite(tmin), idx, -1)


def _reference(scene: Scene, W: int, H: int) -> np.ndarray:
    cam = scene.camera
    f = np.subtract(cam.look_at, cam.position)
    f = f / np.linalg.norm(f)
    r = np.cross(f, cam.up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    th = math.tan(math.radians(cam.fov_y) / 2)
    X, Y = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    sx = (2 * X.ravel() / W - 1) * th * W / H
    sy = (1 - 2 * Y.ravel() / H) * th
    d = f + sx[:, None] * r + sy[:, None] * u
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(np.asarray(cam.position, float), d.shape)
    tri = scene.vertices[scene.faces].astype(np.float64)
    t, idx = _mt(o, d, tri)
    out = np.tile(np.asarray(scene.background), (len(d), 1))
    hit = idx >= 0
    P = o[hit] + d[hit] * t[hit, None]
    ids = idx[hit]
    n = np.cross(tri[ids, 1] - tri[ids, 0], tri[ids, 2] - tri[ids, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n[np.einsum("ij,ij->i", n, d[hit]) > 0] *= -1
    V = -d[hit]
    col = np.zeros((len(P), 3))
    mats = [scene.materials[m] for m in scene.material_ids[ids]]
    alb = np.empty((len(P), 3))
    for k, m in enumerate(mats):
        if m.texture == "checker":  # plane normal along y: texture coordinates (x, z)
            w = (math.floor(P[k, 0] / m.texture_scale) + math.floor(P[k, 2] / m.texture_scale)) % 2 == 0
            alb[k] = m.albedo if w else m.albedo2
        else:
            alb[k] = m.albedo
    for L in scene.point_lights:
        wi = np.asarray(L.position) - P
        dist = np.linalg.norm(wi, axis=1)
        wi /= dist[:, None]
        cos = np.einsum("ij,ij->i", n, wi)
        so = P + 1e-5 * scene.scale * n
        ts, _ = _mt(so, wi, tri)
        vis = (ts >= dist - 2e-5 * scene.scale) & (cos > 0)
        E = np.where(vis, cos, 0.0)[:, None] / dist[:, None] ** 2 * np.asarray(L.intensity)
        for k, m in enumerate(mats):
            fr = (0.0 if m.kind == "metallic" else 1 / math.pi) * alb[k]
            if m.kind != "diffuse":
                s = 2 / m.roughness ** 2 - 2
                h = wi[k] + V[k]
                nh = max(0.0, float(n[k] @ h / np.linalg.norm(h)))
                ks = alb[k] if m.kind == "metallic" else m.specular
                fr = fr + ks * (s + 8) / (8 * math.pi) * nh ** s
            col[k] += fr * E[k]
    for k, m in enumerate(mats):
        col[k] += np.asarray(m.emission) + (0 if m.kind == "metallic" else 1) * np.asarray(scene.ambient) * alb[k]
    out[hit] = col
    return out.reshape(H, W, 3)


def tiny_scene(ipd: float = 0.1) -> Scene:
    """Checker floor, a glossy occluder, a metallic wall, two point lights (one casting a shadow)."""
    V = np.array([[-3, 0, -1], [3, 0, -1], [3, 0, 5], [-3, 0, 5],          # floor
                  [-0.8, 0.6, 1.5], [0.8, 0.6, 1.5], [0.0, 1.6, 2.0],        # glossy triangle
                  [-3, 0, 5], [3, 0, 5], [3, 3, 5], [-3, 3, 5]], float)     # metallic back wall
    F = [[0, 1, 2], [0, 2, 3], [4, 5, 6], [7, 8, 9], [7, 9, 10]]
    mats = [Material("floor", albedo=(0.8, 0.8, 0.8), albedo2=(0.2, 0.3, 0.4), texture="checker",
                     texture_scale=0.5),
            Material("glossy", albedo=(0.6, 0.2, 0.2), kind="glossy", roughness=0.3, specular=0.2),
            Material("metal", albedo=(0.9, 0.8, 0.5), kind="metallic", roughness=0.4)]
    return Scene("tiny", V, F, [0, 0, 1, 2, 2], mats,
                 point_lights=[PointLight((0.3, 2.5, 1.2), (6, 6, 6)), PointLight((-2, 1.0, 0.0), (1, 2, 3))],
                 camera=Camera((0, 1.2, -2.5), (0, 0.6, 2.0), (0, 1, 0), 50.0),
                 display=ViewSettings(64, 48, ipd=ipd), ambient=(0.02, 0.02, 0.02), background=(0.1, 0.2, 0.3))


def test_gt_matches_brute_force_reference():
    sc = tiny_scene()
    img, stats = render(sc, "gt", {"light_cull": 0.0}, 64, 48)
    ref = _reference(sc, 64, 48)
    diff = np.abs(img - ref).max(axis=2)
    # Float32 (Embree) and float64 (reference) may disagree only on pixels whose ray grazes an edge.
    assert np.mean(diff > 1e-3 * ref.max()) < 0.02
    assert np.median(diff) < 1e-5
    assert stats["rays_primary"] == 64 * 48
    assert stats["shading_points"] == 64 * 48 - stats["missed_rays"]
    assert stats["lights_culled"] == 0
    # the scene has shadows, glossy and metallic pixels, and background
    assert stats["glossy_evaluations"] > 0 and stats["missed_rays"] > 0
    assert float(ref.max()) > 0.2


def test_light_culling_error_bound():
    """Dropped light is at most eps of a pixel's unshadowed estimate: with shadows off the bound is exact."""
    sc = tiny_scene()
    eps = 0.2
    full, _ = render(sc, "gt", {"light_cull": 0.0, "shadows": False}, 64, 48)
    culled, st_c = render(sc, "gt", {"light_cull": eps, "shadows": False}, 64, 48)
    assert st_c["lights_culled"] > 0
    w = np.array([0.2126, 0.7152, 0.0722], np.float32)
    drop = full @ w - culled @ w
    assert np.all(drop >= -1e-6)
    assert np.all(drop <= eps * (full @ w) + 1e-6)
    assert drop.max() > 0


def plane_scene() -> Scene:
    """A noise-textured plane filling the view (60° fov), lit by one point light."""
    V = np.array([[-10, -10, 5], [10, -10, 5], [10, 10, 5], [-10, 10, 5]], float)
    m = Material("m", albedo=(0.8, 0.7, 0.6), albedo2=(0.2, 0.25, 0.3), texture="noise", texture_scale=0.1)
    return Scene("plane", V, [[0, 1, 2], [0, 2, 3]], [0, 0], [m], point_lights=[PointLight((0, 0, 0), (20,) * 3)],
                 camera=Camera((0, 0, 0), (0, 0, 1), (0, 1, 0), 60.0))


def _band_psnr(img, gt, W, H, fov, bands):
    d = ViewingGeometry.create(W, H, fov)
    X, Y = d.pixel_centres()
    e = d.eccentricity(np.hypot(X - W / 2, Y - H / 2))
    out = []
    for a, b in bands:
        m = (e >= a) & (e < b)
        mse = float(np.mean((np.clip(img, 0, 1)[m] - np.clip(gt, 0, 1)[m]) ** 2))
        out.append(math.inf if mse == 0 else 10 * math.log10(1 / mse))
    return out


@pytest.fixture(scope="module")
def plane_gt():
    return render(plane_scene(), "gt", {}, 640, 480)[0]


@pytest.mark.parametrize("renderer", ["vafr", "lmfr", "lafr"])
def test_foveated_matches_gt_in_fovea_and_degrades(renderer, plane_gt):
    img, stats = render(plane_scene(), renderer, {}, 640, 480)
    psnr = _band_psnr(img, plane_gt, 640, 480, 60.0, [(0, 5), (5, 10), (10, 20), (20, 30)])
    assert psnr[0] >= 35.0
    for a, b in zip(psnr, psnr[1:]):
        assert b <= a + 0.5, psnr
    assert stats["shading_points"] == stats["rays_primary"]
    assert stats["seconds"]["inverse_map"] > 0


def test_deferred_pipeline_shades_lp_samples_only(plane_gt):
    img, st = render(plane_scene(), "vafr", {"pipeline": "deferred"}, 640, 480)
    assert st["rays_primary"] == 640 * 480                   # visibility at native resolution
    assert st["shading_points"] == st["lp_pixels"] - st["offscreen_lp_pixels"]
    assert _band_psnr(img, plane_gt, 640, 480, 60.0, [(0, 5)])[0] >= 35.0


def test_lp_pixels_offscreen_are_skipped():
    _, st = render(plane_scene(), "vafr", {}, 160, 120, gaze=(10, 10))
    assert st["offscreen_lp_pixels"] > 0
    assert st["shading_points"] + st["offscreen_lp_pixels"] == st["lp_pixels"]


@pytest.mark.parametrize("pipeline", ["raycast", "deferred"])
def test_reprojection_without_parallax_reshades_nothing(pipeline):
    sc = tiny_scene(ipd=0.0)
    left, st = render(sc, "vafr", {"stereo": "rep", "eye": "left", "pipeline": pipeline}, 64, 48)
    right, st_r = render(sc, "vafr", {"stereo": "rep", "eye": "right", "pipeline": pipeline}, 64, 48)
    assert st["reshaded_pixels"] == 0 and st["reshaded_share"] == 0.0
    np.testing.assert_array_equal(left, right)


def test_reprojection_with_parallax_reshades_disocclusions():
    sc = tiny_scene(ipd=0.3)
    rep, st = render(sc, "vafr", {"stereo": "rep", "eye": "right"}, 64, 48)
    dup, st_d = render(sc, "vafr", {"stereo": "dup", "eye": "right"}, 64, 48)
    assert 0 < st["reshaded_share"] < 1
    assert st["shading_points"] < st_d["shading_points"]
    mse = float(np.mean((np.clip(rep, 0, 1) - np.clip(dup, 0, 1)) ** 2))
    assert 10 * math.log10(1 / mse) > 25.0


def test_shadowless_scene_casts_no_shadow_rays():
    sc = tiny_scene()
    sc.shadows = False
    _, st = render(sc, "gt", {}, 32, 24)
    assert st["rays_shadow"] == 0 and st["shadow_rays_skipped"] > 0


@settings(max_examples=25)
@given(st.integers(0, 2 ** 31 - 1), st.integers(4, 24), st.integers(4, 24))
def test_fxaa_is_a_local_convex_blend(seed, h, w):
    """FXAA output lies within the input's range; a constant image is unchanged."""
    img = np.random.default_rng(seed).random((h, w, 3), dtype=np.float32)
    out = fxaa(img)
    assert out.shape == img.shape
    assert out.min() >= img.min() - 1e-6 and out.max() <= img.max() + 1e-6
    const = np.full((h, w, 3), 0.4, np.float32)
    np.testing.assert_allclose(fxaa(const), const, atol=1e-7)


def test_fxaa_smooths_a_staircase_edge():
    y, x = np.mgrid[0:32, 0:32]
    img = np.repeat((y > 0.4 * x + 6).astype(np.float32)[..., None], 3, axis=2)
    out = fxaa(img)
    changed = np.abs(out - img).max(axis=2) > 1e-3
    assert changed.any()
    # only pixels next to the edge change
    edge = np.zeros_like(changed)
    edge[1:] |= img[1:, :, 0] != img[:-1, :, 0]
    edge[:-1] |= img[1:, :, 0] != img[:-1, :, 0]
    edge[:, 1:] |= img[:, 1:, 0] != img[:, :-1, 0]
    edge[:, :-1] |= img[:, 1:, 0] != img[:, :-1, 0]
    assert not (changed & ~edge).any()


def _with_entry_points(monkeypatch, *plugins):
    """The registry as if ``plugins`` were installed in the 'studyapp.renderers' entry-point group too."""
    from types import SimpleNamespace

    from renderers import registry

    real = list(registry._entry_points())
    extra = [SimpleNamespace(name=p.name, value=f"test:{p.name}", load=lambda p=p: (lambda: p)) for p in plugins]
    monkeypatch.setattr(registry, "_entry_points", lambda: real + extra)
    monkeypatch.setattr(registry, "_PLUGINS", None)


def test_registry_params_and_plugins(monkeypatch):
    p = resolve_params("lafr", {"delta": "2.2", "aa": "false"})
    assert p["delta"] == 2.2 and p["aa"] is False and p["beta"] == 0.7
    with pytest.raises(ValueError, match="delta"):
        resolve_params("lmfr", {"delta": "0.5"})
    with pytest.raises(ValueError, match="unknown"):
        resolve_params("nope", {})
    calls = []

    def run(ctx):
        calls.append(ctx.params["level"])
        return np.full((ctx.height, ctx.width, 3), ctx.params["level"], np.float32)

    _with_entry_points(monkeypatch, RendererPlugin("flat_test", "constant image",
                                                   {"level": Param(float, 0.5, 0.0, 1.0)}, run))
    img, st = render(tiny_scene(), "flat_test", {"level": "0.25"}, 8, 6)
    assert img.shape == (6, 8, 3) and float(img[0, 0, 0]) == 0.25 and calls == [0.25]
    assert set(st["seconds"]) >= {"visibility", "shading", "antialias", "inverse_map", "total"}


def test_one_registration_route_entry_points_only(monkeypatch):
    """Every renderer, built-in ones included, comes from the 'studyapp.renderers' entry-point group; a
    package adds one the same way; presets are listed as renderers of their own."""
    from importlib.metadata import entry_points

    names = {ep.name for ep in entry_points(group="studyapp.renderers")}
    assert names == {"gt", "vafr", "lmfr", "lafr", "fsl", "sl", "sl_as", "sl_gt"}
    assert set(available()) == names | {"sl_e", "sl_f", "sl_p"}
    assert available()["sl_e"].preset_of == "sl" and available()["sl_e"].run is available()["sl"].run
    plugin = RendererPlugin("ep_flat", "entry-point test", {"v": Param(float, 0.75, 0.0, 1.0)},
                            lambda ctx: np.full((ctx.height, ctx.width, 3), ctx.params["v"], np.float32))
    _with_entry_points(monkeypatch, plugin)
    assert "ep_flat" in available()
    img, _ = render(tiny_scene(), "ep_flat", {}, 4, 3)
    assert float(img.max()) == 0.75


def test_a_broken_output_contract_is_a_bug_and_bad_values_are_refused_in_one_line(monkeypatch):
    """A wrong dtype is the plug-in's bug (RuntimeError); negative or non-finite radiance, which parameters can
    cause, is never returned: one UserError line naming the renderer and the parameters set."""
    from data_schema.errors import UserError

    bad = RendererPlugin("bad64", "float64 output", {}, lambda ctx: np.zeros((ctx.height, ctx.width, 3)))
    neg = RendererPlugin("neg", "negative radiance", {},
                         lambda ctx: np.full((ctx.height, ctx.width, 3), -1.0, np.float32))
    inf = RendererPlugin("inf", "one infinite pixel", {"v": Param(float, 0.5, 0.0, None)},
                         lambda ctx: np.pad(np.full((1, 1, 3), np.inf, np.float32),
                                            ((0, ctx.height - 1), (0, ctx.width - 1), (0, 0)),
                                            constant_values=ctx.params["v"]))
    _with_entry_points(monkeypatch, bad, neg, inf)
    with pytest.raises(RuntimeError, match="broke the output contract"):
        render(tiny_scene(), "bad64", {}, 4, 3)
    with pytest.raises(UserError) as err:
        render(tiny_scene(), "neg", {}, 4, 3)
    assert str(err.value) == "renderer 'neg' (default parameters) produced negative radiance (-1): refused"
    with pytest.raises(UserError) as err:
        render(tiny_scene(), "inf", {"v": 0.25}, 4, 3)
    assert str(err.value) == "renderer 'inf' (v=0.25) produced non-finite pixels: refused"


@settings(max_examples=20)
@given(st.sampled_from(["vafr", "lmfr", "lafr"]), st.floats(0, 200), st.floats(0, 150))
def test_table_inverse_map_matches_exact_kernel(method, gx, gy):
    """The u(r)-table inverse mapping equals the exact per-pixel mapping on a smooth LP buffer."""
    from renderers import _lp
    from renderers.foveation import make_mapping
    from renderers.pipeline import LPLayout

    lay = LPLayout(make_mapping(method, 200, 150, 60.0, (gx, gy)))
    assert lay.table_ok or method == "lafr"   # LaFR: exact kernel near the farthest corner (infinite slope)
    j, i = np.mgrid[0:lay.h, 0:lay.w]
    lp = np.stack([np.sin(i / 7.0), np.cos(j / 9.0), np.sin((i + j) / 11.0)], axis=2).astype(np.float32)
    fast = np.empty((150, 200, 3), np.float32)
    exact = np.empty_like(fast)
    _lp.inverse_map_table(lp, lay.utab, lay.inv_step, lay.exact, lay.kernel, lay.P, gx, gy, lay.Lr, lay.n,
                          lay.w_eff, 0.0, fast)
    _lp.inverse_map(lp, lay.kernel, lay.P, gx, gy, lay.L, lay.n, lay.w_eff, 0.0, 0.0, exact)
    # away from the angular seam (where both wrap), the two agree to interpolation accuracy
    X, Y = np.meshgrid(np.arange(200) + 0.5 - gx, np.arange(150) + 0.5 - gy)
    theta = np.mod(np.arctan2(Y, X), 2 * np.pi)
    away = (theta > 0.05) & (theta < 2 * np.pi - 0.05)
    assert np.abs(fast - exact)[away].max() < 0.02


@pytest.mark.parametrize("renderer", ["vafr", "lmfr", "lafr"])
def test_lp_filters_do_not_darken_the_screen_border(renderer):
    """Unshaded (off-screen) LP pixels are filled before the LP filters, so the border keeps GT's level."""
    sc = plane_scene()
    gt, _ = render(sc, "gt", {}, 160, 120)
    img, _ = render(sc, renderer, {}, 160, 120, gaze=(40, 30))
    border = np.zeros((120, 160), bool)
    border[:2] = border[-2:] = True
    border[:, :2] = border[:, -2:] = True
    assert abs(float(img[border].mean()) / float(gt[border].mean()) - 1.0) < 0.02


def test_grid_warping_fills_between_samples(monkeypatch):
    """Forward grid warping re-shades far fewer LP pixels than nearest-sample splatting, at the same quality."""
    import renderers.pipeline as pl

    sc = tiny_scene(ipd=0.3)
    dup, _ = render(sc, "vafr", {"stereo": "dup", "eye": "right"}, 64, 48)
    out = {}
    for warp in (False, True):
        monkeypatch.setattr(pl, "GRID_WARP", warp)
        rep, st = render(sc, "vafr", {"stereo": "rep", "eye": "right"}, 64, 48)
        mse = float(np.mean((np.clip(rep, 0, 1) - np.clip(dup, 0, 1)) ** 2))
        out[warp] = (st["reshaded_pixels"], 10 * math.log10(1 / mse))
    assert 0 < out[True][0] < out[False][0] / 3
    assert out[True][1] > 40.0 and out[False][1] > 40.0


FAST = {"gt": {}, "vafr": {"fxaa": False}, "lmfr": {}, "lafr": {}, "fsl": {"max_lspp": 4, "max_rspp": 2},
        "sl": {"lspp": 2, "rspp": 2}, "sl_e": {"lspp": 2, "rspp": 2}, "sl_f": {"lspp": 2, "rspp": 2},
        "sl_p": {"lspp": 2, "rspp": 2}, "sl_as": {"max_lspp": 4, "max_rspp": 2},
        "sl_gt": {"lspp": 4, "rspp": 2, "max_lspp": 4}}


@pytest.mark.parametrize("name", sorted(FAST))
def test_every_renderer_returns_unexposed_radiance_and_the_png_applies_exposure_once(name, tmp_path):
    """The output contract (renderers/plugin_types.py) for every registered renderer, exposure != 1."""
    import dataclasses

    from renderers.stimuli import render_stimulus, to_srgb8

    assert set(FAST) == set(available())  # every registered renderer is covered
    base = tiny_scene()
    bright = dataclasses.replace(base, exposure=3.0)
    img1, _ = render(base, name, FAST[name], 24, 18)
    img3, _ = render(bright, name, FAST[name], 24, 18)
    np.testing.assert_array_equal(img1, img3)  # the renderer does not apply the exposure
    png = render_stimulus(bright, name, FAST[name], 24, 18, cache_dir=tmp_path)
    from PIL import Image

    with Image.open(png) as im:
        got = np.asarray(im.convert("RGB"))
    np.testing.assert_array_equal(got, to_srgb8(np.load(png.with_suffix(".npy")), 3.0))  # applied once
    np.testing.assert_array_equal(np.load(png.with_suffix(".npy")), img3)
