"""Stochastic lightcuts: unbiasedness against the brute-force sum, exact full cuts, pdfs, determinism."""

import numpy as np
import pytest

from renderers.lightcuts import _kernels as K
from renderers.lightcuts.sampling import GBuffer, clamp2, exact_direct, ray_offset_for, stochastic_lightcuts
from renderers.lightcuts.tree import build_light_tree
from renderers.lightcuts.visibility import EmbreeOccluder


def _scene(n_lights=40, n_pix=12, seed=1, one_sided=False):
    rng = np.random.default_rng(seed)
    lp = rng.uniform([-1, -1, 0.3], [1, 1, 1.5], size=(n_lights, 3))
    li = rng.uniform(0, 1, size=(n_lights, 3)) * rng.choice([0.1, 1, 5], size=(n_lights, 1))
    li[::7] = 0.0  # some dark lights
    pos = np.column_stack([rng.uniform(-1, 1, n_pix), rng.uniform(-1, 1, n_pix), np.zeros(n_pix)])
    nrm = rng.normal(size=(n_pix, 3)) * [0.4, 0.4, 1]
    nrm[:, 2] = np.abs(nrm[:, 2])
    nrm[0] = [1, 0, 0.0]  # grazing normal: about half the lights behind
    alb = rng.uniform(0.2, 0.9, size=(n_pix, 3))
    # an occluding triangle between part of the floor and part of the lights
    verts = np.array([[-0.8, -0.8, 0.2], [0.5, -0.8, 0.2], [-0.8, 0.5, 0.2]])
    ln = None
    if one_sided:  # mostly facing down; every fifth light isotropic (zero normal)
        ln = rng.normal(size=(n_lights, 3)) - [0, 0, 1.5]
        ln[::5] = 0.0
    return build_light_tree(lp, li, ln), pos, nrm, alb, EmbreeOccluder(verts, [[0, 1, 2]])


def _moments(tree, g, budget, occ):
    """Exact mean and variance of the estimator by enumerating every cut node's leaves and their pdfs."""
    c2 = clamp2(tree)
    N = tree.n_leaves
    cut = np.zeros((g.n, budget), dtype=np.int64)
    size = K.build_cuts(g.position, g.normal, np.full(g.n, budget), tree.bmin, tree.bmax, tree.intensity, N,
                        c2, cut, np.zeros((g.n, budget)))
    mean = np.zeros((g.n, 3))
    var = np.zeros((g.n, 3))
    for i in range(g.n):
        p, n = g.position[i], g.normal[i]
        t, b = K.tangent(*n), K.bitangent(*n)
        lights = tree.light_pos[:tree.n_lights]
        d = lights - p
        cosnum = d @ n
        d2 = (d * d).sum(axis=1)
        geo = np.where(cosnum > 0, cosnum / np.sqrt(d2) / np.maximum(d2, c2), 0.0)
        vis = ~occ(np.tile(p + ray_offset_for(tree, g) * n, (tree.n_lights, 1)), lights)
        if tree.light_nrm is not None:
            ln = tree.light_nrm[:tree.n_lights]
            em = np.maximum(-(ln * d).sum(axis=1) / np.sqrt(d2), 0)
            geo = geo * np.where(np.any(ln != 0, axis=1), em, 1.0)
        f = g.albedo[i] / np.pi * tree.light_rgb[:tree.n_lights] * (geo * vis)[:, None]
        for k in cut[i, :size[i]]:
            k = int(k)
            span = N >> (k.bit_length() - 1)
            js = [j for j in range(k * span - N, (k + 1) * span - N) if j < tree.n_lights]
            live = K.node_live(p, n, t, b, tree.bmin, tree.bmax, tree.intensity, k)
            pdf = np.array([K.leaf_pdf(p, n, t, b, tree.bmin, tree.bmax, tree.intensity, N, k, j + N, c2)
                            if live else 0.0 for j in js])
            fk = f[js]
            # unbiased only if every light that contributes can be drawn
            assert np.all(pdf[np.any(fk > 0, axis=1)] > 0)
            ok = pdf > 0
            mean[i] += (fk[ok]).sum(axis=0)
            var[i] += (fk[ok] ** 2 / pdf[ok, None]).sum(axis=0) - fk[ok].sum(axis=0) ** 2
    return mean, var


@pytest.mark.parametrize("budget, one_sided", [(1, False), (3, False), (8, False), (3, True)])
def test_mean_converges_to_exact_sum(budget, one_sided):
    tree, pos, nrm, alb, occ = _scene(one_sided=one_sided)
    g1 = GBuffer.create(pos, nrm, alb)
    exact = exact_direct(tree, g1, occluded=occ)
    assert np.all(exact >= 0) and exact.max() > 0
    mean, var = _moments(tree, g1, budget, occ)
    # analytically unbiased: sum over cut nodes of E[f / pdf] is the brute-force sum
    np.testing.assert_allclose(mean, exact, rtol=1e-10, atol=1e-15)
    reps = 3000
    g = GBuffer.create(np.tile(pos, (reps, 1)), np.tile(nrm, (reps, 1)), np.tile(alb, (reps, 1)))
    res = stochastic_lightcuts(tree, g, budget, seed=11, occluded=occ)
    est = res.radiance.reshape(reps, len(pos), 3)
    se = np.sqrt(var / reps)
    # Monte Carlo: the mean of many estimates lies within 4 (exact) standard errors of the exact sum
    assert np.all(np.abs(est.mean(axis=0) - exact) <= 4 * se + 1e-12 * (1 + exact))
    assert np.all(res.samples <= budget) and res.samples.max() >= 1


@pytest.mark.parametrize("one_sided", [False, True])
def test_cut_of_all_leaves_is_exact(one_sided):
    tree, pos, nrm, alb, occ = _scene(n_lights=23, one_sided=one_sided)
    g = GBuffer.create(pos, nrm, alb)
    res = stochastic_lightcuts(tree, g, tree.n_leaves, seed=3, occluded=occ)
    np.testing.assert_allclose(res.radiance, exact_direct(tree, g, occluded=occ), rtol=1e-10, atol=1e-14)


def test_descend_pdf_matches_leaf_pdf_and_sums_to_one():
    tree, pos, nrm, _, _ = _scene(n_lights=30)
    c2 = clamp2(tree)
    for i in range(4):
        p, n = pos[i], nrm[i] / np.linalg.norm(nrm[i])
        t, b = K.tangent(*n), K.bitangent(*n)
        for node in (1, 2, 5):
            if not K.node_live(p, n, t, b, tree.bmin, tree.bmax, tree.intensity, node):
                continue
            pdfs = np.array([K.leaf_pdf(p, n, t, b, tree.bmin, tree.bmax, tree.intensity, tree.n_leaves, node,
                                        leaf, c2) for leaf in range(tree.n_leaves, 2 * tree.n_leaves)])
            assert abs(pdfs.sum() - 1) < 1e-12
            for s in range(20):
                u = K.uniform(7, i, s)
                leaf, pdf = K.descend(p, n, t, b, tree.bmin, tree.bmax, tree.intensity, tree.n_leaves, node,
                                      u, c2)
                assert (leaf >> (leaf.bit_length() - node.bit_length())) == node
                assert pdf == pytest.approx(pdfs[leaf - tree.n_leaves], rel=1e-12)
                assert tree.intensity[leaf] > 0


def test_geometry_bound_is_an_upper_bound_of_cosine():
    tree, pos, nrm, _, _ = _scene(n_lights=60, n_pix=20, seed=5)
    N = tree.n_leaves
    for i in range(len(pos)):
        p, n = pos[i], nrm[i] / np.linalg.norm(nrm[i])
        t, b = K.tangent(*n), K.bitangent(*n)
        assert abs(np.dot(t, n)) < 1e-12 and abs(np.dot(b, n)) < 1e-12 and abs(np.dot(t, b)) < 1e-12
        d = tree.light_pos[:tree.n_lights] - p
        cos = d @ n / np.linalg.norm(d, axis=1)
        for k in range(1, N):
            depth = k.bit_length() - 1
            span = N >> depth
            lo, hi = k * span - N, min((k + 1) * span - N, tree.n_lights)
            if lo >= hi:
                continue
            gb = K.geom_bound(p, n, t, b, tree.bmin, tree.bmax, k)
            assert gb >= cos[lo:hi].max() - 1e-12


def test_deterministic_and_tile_independent():
    tree, pos, nrm, alb, occ = _scene()
    g = GBuffer.create(pos, nrm, alb)
    a = stochastic_lightcuts(tree, g, 4, seed=5, occluded=occ, tile=5)
    b = stochastic_lightcuts(tree, g, 4, seed=5, occluded=occ)
    c = stochastic_lightcuts(tree, g, 4, seed=6, occluded=occ)
    assert a.radiance.tobytes() == b.radiance.tobytes()
    assert not np.array_equal(a.radiance, c.radiance)


def test_zero_budget_and_invalid_pixels_are_black():
    tree, pos, nrm, alb, _ = _scene()
    valid = np.ones(len(pos), bool)
    valid[3] = False
    g = GBuffer.create(pos, nrm, alb, valid=valid)
    budget = np.full(len(pos), 4)
    budget[5] = 0
    res = stochastic_lightcuts(tree, g, budget)
    assert np.all(res.radiance[[3, 5]] == 0) and res.samples[3] == 0 and res.samples[5] == 0
    assert res.radiance[np.r_[0:3, 6:len(pos)]].sum() > 0


@pytest.mark.parametrize("kw, match", [({"budget": -1}, "budget must be >= 0"),
                                       ({"budget": 1.5}, "whole numbers"),
                                       ({"budget": 2, "seed": -1}, "seed")])
def test_bad_budget(kw, match):
    tree, pos, nrm, alb, _ = _scene()
    with pytest.raises(ValueError, match=match):
        stochastic_lightcuts(tree, GBuffer.create(pos, nrm, alb), **kw)


def test_bad_gbuffer():
    with pytest.raises(ValueError, match="normal has shape"):
        GBuffer.create(np.zeros((4, 3)), np.zeros((3, 3)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="position must be finite"):
        GBuffer.create(np.full((2, 3), np.nan), np.ones((2, 3)), np.ones((2, 3)))
