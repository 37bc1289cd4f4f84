"""Renderer plug-ins fsl / sl_* on the scene model: values, glossy pass skipped for diffuse scenes, errors."""

import numpy as np
import pytest

from renderers import registry
from renderers.lightcuts.plugin import scene_light_tree, split_triangles
from renderers.procedural import MeshBuilder
from renderers.scene import Camera, Material


def _diffuse_scene(glossy=False):
    b = MeshBuilder()
    b.material(Material("floor", albedo=(0.6, 0.6, 0.6)))
    b.material(Material("box", albedo=(0.5, 0.3, 0.2), kind="glossy" if glossy else "diffuse", roughness=0.3,
                        specular=0.2))
    b.material(Material("lamp", emission=(5.0, 5.0, 4.0)))
    b.quad((-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2), "floor", (0, 1, 0))
    b.box((-0.4, 0, -0.4), (0.4, 0.8, 0.4), "box")
    b.grid_quad((-0.5, 2.0, -0.5), (1, 0, 0), (0, 0, 1), 4, "lamp", normal=(0, -1, 0))
    cam = Camera((0.0, 1.5, -3.5), (0.0, 0.4, 0.0), (0.0, 1.0, 0.0), 50.0)
    return b.scene("tiny" + ("_glossy" if glossy else ""), camera=cam)


def test_light_tree_from_emitters():
    sc = _diffuse_scene()
    pos, nrm, rgb = sc.emitters()
    assert len(pos) == 32
    whole = scene_light_tree(sc, max_edge_frac=1.0)  # no triangle is split
    assert whole.n_lights == 32
    np.testing.assert_allclose(whole.intensity[1], rgb.sum())
    np.testing.assert_allclose(whole.light_nrm[:32], nrm[whole.order])
    # split until the edges are below 1 % of the scene diagonal: 4^k pieces each, same power and normals
    fine = scene_light_tree(sc)
    k = round(np.log(fine.n_lights / 32) / np.log(4))
    assert k >= 1 and fine.n_lights == 32 * 4 ** k
    np.testing.assert_allclose(fine.intensity[1], rgb.sum(), rtol=1e-12)
    np.testing.assert_allclose(fine.light_nrm[:fine.n_lights], np.tile([0.0, -1.0, 0.0], (fine.n_lights, 1)),
                               atol=1e-12)


def test_split_triangles_tile_the_triangle():
    tri = np.array([[[0.0, 0, 0], [2, 0, 0], [0, 3, 0]]])
    sub = split_triangles(tri, 2)
    assert sub.shape == (16, 3, 3)
    area = 0.5 * np.linalg.norm(np.cross(sub[:, 1] - sub[:, 0], sub[:, 2] - sub[:, 0]), axis=1)
    np.testing.assert_allclose(area, 3.0 / 16)
    normal = np.cross(sub[:, 1] - sub[:, 0], sub[:, 2] - sub[:, 0])
    assert np.all(normal[:, 2] > 0)  # winding kept
    np.testing.assert_allclose(sub.reshape(-1, 3).mean(axis=0), tri[0].mean(axis=0))


def test_all_diffuse_scene_casts_no_glossy_ray():
    img, st = registry.render(_diffuse_scene(), "fsl", {}, 48, 32)
    assert st["glossy_rays"] == 0 and st["glossy_pass"] is False
    assert np.all(np.isfinite(img)) and img.mean() > 0
    img, st = registry.render(_diffuse_scene(glossy=True), "fsl", {}, 48, 32)
    assert st["glossy_pass"] is True and st["glossy_rays"] > 0


@pytest.mark.parametrize("name, params", [("fsl", {}), ("fsl", {"multires": False}), ("sl_e", {"lspp": 4}),
                                          ("sl_as", {}), ("sl_f", {"lspp": 16}), ("fsl", {"fpsm_reading": "blur"}),
                                          ("fsl", {"fpsm_reading": "retained"})])
def test_plugins_agree_with_ground_truth_on_average(name, params):
    sc = _diffuse_scene(glossy=True)
    gt, _ = registry.render(sc, "sl_gt", {"lspp": 192, "rspp": 64}, 48, 32)
    img, st = registry.render(sc, name, params, 48, 32)
    assert img.shape == (32, 48, 3) and np.all(np.isfinite(img)) and img.min() >= 0
    # same scene, same light model: image means agree within a few percent
    assert abs(img.mean() - gt.mean()) < 0.05 * gt.mean()
    assert st["rays_shadow"] > 0


def test_fsl_reports_its_map_and_steps():
    _, st = registry.render(_diffuse_scene(), "fsl", {"alpha": 0.2}, 48, 32)
    assert st["fpsm"].shape == (32, 48) and 0 <= st["fpsm"].min() and st["fpsm"].max() <= 1
    assert set(st["steps"]) == {"gbuffer", "low_res", "fpsm", "cuts", "select", "shade", "glossy"}
    assert np.all(st["spp"] <= 48) and st["fpsm_reading"] == "derived"
    # sample accounting: the low-resolution pass (6 x 4 pixels, up to 48 samples each) is counted, reused
    # samples are light samples that did not descend the tree
    extra = st["light_samples"] - int(st["spp"].sum())
    assert 0 < extra <= 6 * 4 * 48 and st["traversals"] == st["light_samples"] - st["reused"]
    _, su = registry.render(_diffuse_scene(), "sl", {"lspp": 3}, 48, 32)
    assert su["light_samples"] == su["traversals"] == int(su["spp"].sum()) > 0
    assert set(su["steps"]) == {"gbuffer", "cuts", "select", "shade", "glossy"}
    assert all(v >= 0 for v in su["steps"].values())


@pytest.mark.parametrize("name, params, match", [("fsl", {"alpha": 0}, "fsl.alpha"),
                                                 ("fsl", {"alpha": 1.5}, "fsl.alpha"),
                                                 ("fsl", {"max_lspp": 0}, "fsl.max_lspp"),
                                                 ("sl_e", {"lspp": -1}, "sl_e.lspp")])
def test_bad_parameters_name_the_parameter(name, params, match):
    with pytest.raises(ValueError, match=match):
        registry.render(_diffuse_scene(), name, params, 16, 16)


def test_scene_without_lights_is_a_one_line_error():
    b = MeshBuilder()
    b.material(Material("floor"))
    b.quad((-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1), "floor", (0, 1, 0))
    sc = b.scene("dark", camera=Camera((0.0, 1.0, -2.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 50.0))
    for name in ("fsl", "sl_e", "sl_gt"):
        with pytest.raises(ValueError, match="(no|zero) lights") as err:
            registry.render(sc, name, {}, 8, 8)
        assert "\n" not in str(err.value)
    # only a directional light: the scene model accepts it, the many-light tree has nothing to hold
    from renderers.scene import DirectionalLight

    sc.directional_lights.append(DirectionalLight((0.0, -1.0, 0.0), (1.0, 1.0, 1.0)))
    with pytest.raises(ValueError, match="zero lights"):
        registry.render(sc, "fsl", {}, 8, 8)


def test_shading_points_are_the_primary_hits():
    _, st = registry.render(_diffuse_scene(), "sl_e", {"lspp": 2}, 48, 32)
    # the camera sees the floor's edge and the sky: some rays miss, every hit is shaded once
    hits = st["spp"] > 0
    assert 0 < st["shading_points"] < 48 * 32
    assert st["shading_points"] == int(hits.sum())


def test_view_projection_maps_each_ray_back_to_its_pixel():
    from renderers.projection import camera_rays, view_projection

    rng = np.random.default_rng(3)
    for _ in range(5):
        cam = Camera(tuple(rng.normal(size=3)), tuple(rng.normal(size=3) + 5.0), (0.0, 1.0, 0.0),
                     float(rng.uniform(20, 120)))
        w, h = int(rng.integers(16, 300)), int(rng.integers(16, 300))
        x, y = rng.uniform(0, w, 50), rng.uniform(0, h, 50)
        p = np.asarray(cam.position) + camera_rays(cam, w, h, x, y) * rng.uniform(0.5, 50, (50, 1))
        c = np.c_[p, np.ones(50)] @ view_projection(cam, w, h).T
        assert np.allclose((c[:, 0] / c[:, 3] + 1) * w / 2, x, atol=1e-8)
        assert np.allclose((1 - c[:, 1] / c[:, 3]) * h / 2, y, atol=1e-8)


def test_velocity_buffer_follows_the_camera_motion():
    scene = _diffuse_scene()
    cam = scene.camera
    still = {"previous": {"position": cam.position}}
    _, st0 = registry.render(scene, "fsl", {}, 48, 32)
    _, st1 = registry.render(scene, "fsl", {}, 48, 32, camera=still)
    assert np.array_equal(st0["fpsm"], st1["fpsm"])  # no motion: the same map as without a previous camera
    # the camera moved 0.3 to the right since the previous frame: every visible point moved left on screen
    _, right = cam.basis()[:2]
    prev = {"position": tuple(np.subtract(cam.position, 0.3 * right)),
            "look_at": tuple(np.subtract(cam.look_at, 0.3 * right))}
    from renderers.lightcuts import plugin as P

    seen = {}
    orig = P.screen_velocity

    def spy(*a, **k):
        seen["v"] = orig(*a, **k)
        return seen["v"]

    P.screen_velocity = spy
    try:
        _, st2 = registry.render(scene, "fsl", {}, 48, 32, camera={"previous": prev})
    finally:
        P.screen_velocity = orig
    vx = seen["v"][..., 0]
    assert np.all(vx[np.abs(vx) > 0] < 0) and (vx < -0.1).mean() > 0.5
    assert not np.array_equal(st0["fpsm"], st2["fpsm"])  # parallax edges raise the spatio-temporal feature
    with pytest.raises(ValueError, match="camera.previous is invalid"):
        registry.render(scene, "fsl", {}, 48, 32, camera={"previous": 3})
