"""Many-light scenes: light counts, one-sided emitters, vectorised grids."""

import numpy as np

from renderers.lightcuts.scenes import SCENES, cornell_many, grid_triangles


def test_grid_triangles_cover_the_parallelogram_facing_the_normal():
    v, f = grid_triangles((1, 2, 3), (2, 0, 0), (0, 0, 3), 4, 5, (0, -1, 0))
    assert len(f) == 2 * 4 * 5 and len(v) == 5 * 6
    tri = v[f]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    np.testing.assert_allclose(0.5 * np.linalg.norm(cross, axis=1).sum(), 2 * 3)
    assert np.all(cross[:, 1] < 0) and np.allclose(cross[:, [0, 2]], 0)


def test_cornell_many_has_about_110k_one_sided_lights():
    sc = cornell_many()
    pos, nrm, rgb = sc.emitters()
    assert len(pos) == 2 * 173 * 173 + 2 * 2 * 1000 * 13 == 111_858
    assert sc.light_count() == len(pos)
    np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0)
    # the lamp faces down, the strips face into the room
    assert np.sum(nrm[:, 1] < -0.99) == 2 * 173 * 173
    assert np.all(pos[:, 0] > 0) and np.all(pos[:, 0] < 556) and np.all(pos[:, 1] < 548.8)
    # the lamp keeps the radiance of the original: power = L_e * area
    lamp = nrm[:, 1] < -0.99
    np.testing.assert_allclose(rgb[lamp].sum(axis=0), np.array([34.0, 24.0, 8.0]) * 130 * 105, rtol=1e-6)
    kinds = {m.kind for m in sc.materials}
    assert kinds == {"diffuse", "glossy"}
    assert "cornell_many" in SCENES


def test_study_and_yard_light_counts_and_materials():
    from renderers.lightcuts.scenes import study, yard

    st = study()
    assert len(st.emitters()[0]) == 2 * 120 * 120 + 2 * 2 * 3650 * 2 == 58_000
    assert {m.kind for m in st.materials} == {"diffuse", "glossy", "metallic"}
    yd = yard()
    pos, nrm, _ = yd.emitters()
    assert len(pos) == 25 * 1253 * 8 == 250_600
    # bulbs are octahedra emitting outwards: each face normal points away from its bulb's centre
    centre = pos.reshape(-1, 8, 3).mean(axis=1, keepdims=True)
    out = ((pos.reshape(-1, 8, 3) - centre) * nrm.reshape(-1, 8, 3)).sum(axis=2)
    assert np.all(out > 0)
    assert {m.kind for m in yd.materials} == {"diffuse", "glossy"}
    assert set(SCENES) == {"cornell_many", "study", "yard", "sponza_vpl"}


def test_sponza_vpls_face_the_light_and_carry_its_reflected_power():
    from renderers.lightcuts.scenes import sponza_vpl

    sc = sponza_vpl(n_vpl=3000)
    pos, nrm, rgb = sc.emitters()
    assert len(pos) == 3000 and sc.light_count() == 3001  # the point light itself + the VPLs
    light = np.array(sc.point_lights[0].position)
    assert np.all(((light - pos) * nrm).sum(axis=1) > 0)  # each VPL lies on a surface lit by the light
    np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0)
    # power: pi * I_vpl / albedo summed = Phi * hits / traced <= Phi = 4 pi I per channel
    total = np.pi * rgb.sum(axis=0)
    phi = 4 * np.pi * np.array(sc.point_lights[0].intensity)
    assert np.all(total > 0) and np.all(total < phi)
    assert sc.content_hash() != sponza_vpl(n_vpl=2000).content_hash()
    assert {m.kind for m in sc.materials} == {"diffuse"}


def test_demo_step_writes_the_stimulus_and_its_map(tmp_path):
    from PIL import Image

    from renderers.lightcuts.demo import demo_step

    said = []
    a = demo_step(tmp_path, said.append, width=64, height=36)
    assert [p.name for p in a] == ["cornell_many_fsl.png", "cornell_many_fpsm.png"] and said
    img = np.asarray(Image.open(a[0]))
    assert img.shape == (36, 64, 3) and img.max() > 50
    assert np.asarray(Image.open(a[1])).shape == (36, 64)
    b = demo_step(tmp_path / "again", None, width=64, height=36)
    assert a[0].read_bytes() == b[0].read_bytes()  # same seed, same bytes
