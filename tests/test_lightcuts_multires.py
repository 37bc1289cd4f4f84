"""Multi-resolution selection (seed 003 Algorithm 2, Eq 9-10) against brute force; foveated pipeline."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from renderers.lightcuts import multires as MR
from renderers.lightcuts.foveated import foveated_lightcuts
from renderers.lightcuts.sampling import GBuffer, clamp2, cut_and_sample
from renderers.lightcuts.tree import build_light_tree
from renderers.lightcuts.visibility import EmbreeOccluder


def _leaves_below(node, n_leaves):
    out, stack = [], [node]
    while stack:
        k = stack.pop()
        if k >= n_leaves:
            out.append(k)
        else:
            stack += [2 * k, 2 * k + 1]
    return out


def _path_length(a, b):
    """Breadth-first search over the heap's parent/child edges."""
    seen, frontier, d = {a}, [a], 0
    while b not in seen:
        nxt = []
        for k in frontier:
            for m in (k // 2, 2 * k, 2 * k + 1):
                if m >= 1 and m < 64 and m not in seen:
                    seen.add(m)
                    nxt.append(m)
        frontier, d = nxt, d + 1
    return d


@pytest.mark.parametrize("levels", range(1, 8))
def test_eq9_leaf_range_matches_brute_force(levels):
    n_leaves = 1 << (levels - 1)
    for node in range(1, 2 * n_leaves):
        leaves = _leaves_below(node, n_leaves)
        assert MR.leaf_range(node, levels) == (min(leaves), max(leaves))
        assert max(leaves) - min(leaves) + 1 == len(leaves)


def test_tree_distance_matches_brute_force_and_printed_eq10_does_not():
    nodes = range(1, 32)  # a 5-level tree
    agree = 0
    for a in nodes:
        for b in nodes:
            d = _path_length(a, b)
            assert MR.tree_distance(a, b) == d
            e = MR.eq10_as_printed(a, b)
            agree += e == d
    # Eq 10 as printed: negative for siblings and for a node and itself, undefined at the root's children
    assert MR.eq10_as_printed(2, 3) < 0 and MR.eq10_as_printed(4, 4) < 0 and np.isnan(MR.eq10_as_printed(1, 1))
    assert agree < 0.2 * 31 * 31


@settings(max_examples=80)
@given(leaves=st.lists(st.integers(16, 31), max_size=12, unique=True), node=st.integers(1, 31),
       pad=st.integers(0, 3))
def test_lrls_finds_a_sample_under_the_node(leaves, node, pad):
    leaves = sorted(leaves)
    arr = np.array(leaves + [-1] * pad, dtype=np.int64)
    lo, hi = MR.leaf_range(node, 5)
    j = MR.lrls(arr[None], 0, len(leaves), lo, hi)
    under = [x for x in leaves if lo <= x <= hi]
    if under:
        assert j >= 0 and arr[j] == min(under)
    else:
        assert j == -1


def test_printed_lrls_condition_disagrees_somewhere():
    leaves = [20, 27]
    disagreements = 0
    for node in range(1, 32):
        lo, hi = MR.leaf_range(node, 5)
        printed = lo < leaves[0] or hi > leaves[-1]
        disagreements += printed != any(lo <= x <= hi for x in leaves)
    assert disagreements > 0


@settings(max_examples=60)
@given(data=st.data())
def test_n_light_picks_nearest_cut_node(data):
    leaves = sorted(data.draw(st.lists(st.integers(32, 63), min_size=1, max_size=10, unique=True)))
    # each sample's cut node: some ancestor of its leaf
    nodes = [x >> data.draw(st.integers(0, 5)) for x in leaves]
    node = data.draw(st.sampled_from(leaves)) >> data.draw(st.integers(0, 5))
    lo, hi = MR.leaf_range(node, 6)
    la, na = np.array(leaves, np.int64), np.array(nodes, np.int64)
    first = MR.lrls(la[None], 0, len(la), lo, hi)
    assert first >= 0
    j = MR.n_light(node, la, na, len(la), first, hi)
    cands = [i for i, x in enumerate(leaves) if lo <= x <= hi]
    dists = [_path_length(node, nodes[i]) for i in cands]
    assert j in cands and _path_length(node, nodes[j]) == min(dists)
    depths = np.array([x.bit_length() - 1 for x in nodes], np.int64)
    assert MR.n_light(node, la, na, len(la), first, hi, None, None, 0.0, depths) == j


def _image_scene(w=32, h=24, n_lights=200, seed=0):
    rng = np.random.default_rng(seed)
    lights = np.column_stack([rng.uniform(-1, 1, n_lights), rng.uniform(-1, 1, n_lights),
                              rng.uniform(0.5, 1.5, n_lights)])
    tree = build_light_tree(lights, rng.uniform(0, 1, (n_lights, 3)))

    def gbuf(ww, hh):
        x, y = np.meshgrid((np.arange(ww) + 0.5) / ww * 2 - 1, (np.arange(hh) + 0.5) / hh * 2 - 1)
        pos = np.stack([x, y, np.zeros_like(x)], -1)
        nrm = np.zeros_like(pos)
        nrm[..., 2] = 1
        alb = np.where((x > 0)[..., None], [0.7, 0.2, 0.2], [0.3, 0.6, 0.3])
        return GBuffer.create(pos, nrm, alb)

    x, y = np.meshgrid(np.arange(w) + 0.5 - w / 2, np.arange(h) + 0.5 - h / 2)
    ecc = np.arctan(np.hypot(x, y) / (h / 2) * np.tan(np.radians(30)))
    occ = EmbreeOccluder(np.array([[-0.5, -0.5, 0.3], [0.5, -0.5, 0.3], [0, 0.5, 0.3]]), [[0, 1, 2]])
    return tree, gbuf(w, h), gbuf(w // 8, h // 8), ecc, occ


def test_select_without_reuse_equals_hierarchical_sampling():
    tree, full, low, _, _ = _image_scene()
    c2 = clamp2(tree)
    ids = np.arange(full.n, dtype=np.int64)
    cut, size, leaf0, pdf0 = cut_and_sample(tree, full.position, full.normal, np.full(full.n, 6), ids, 9, 6)
    lrc, lrs, lrl, lrp = cut_and_sample(tree, low.position, low.normal, np.full(low.n, 6), ids[:low.n], 1, 6)
    ls = MR.sort_low_res_samples(lrc, lrs, lrl, lrp)
    leaf, pdf = np.empty_like(leaf0), np.empty_like(pdf0)
    w, h = full.shape[1], full.shape[0]
    args = (full.position, full.normal, ids, ids % w, ids // w)
    tail = (cut, size, tree.bmin, tree.bmax, tree.intensity, tree.n_leaves, tree.levels, c2, np.uint64(9), *ls,
            low.shape[1] / w, low.shape[0] / h, low.shape[1], low.shape[0], leaf, pdf)
    reused = MR.select_lights(*args, np.ones(full.n), *tail)
    assert reused.sum() == 0
    np.testing.assert_array_equal(leaf, leaf0)
    np.testing.assert_array_equal(pdf, pdf0)
    # map = 0: every node that has a low-resolution sample below it reuses one
    reused = MR.select_lights(*args, np.zeros(full.n), *tail)
    assert reused.sum() > 0
    lrl_sorted, lrn_sorted, lrp_sorted, counts, depths = ls
    np.testing.assert_array_equal(depths[lrl_sorted >= 0], [MR.depth(int(x)) for x in lrn_sorted[lrl_sorted >= 0]])
    for i in range(0, full.n, 7):
        q = (ids[i] // w * low.shape[0] // h) * low.shape[1] + (ids[i] % w) * low.shape[1] // w
        pool = set(lrl_sorted[q, :counts[q]].tolist())
        n_reuse = 0
        for s in range(size[i]):
            k = int(cut[i, s])
            if leaf[i, s] < 0:
                continue
            lo, hi = MR.leaf_range(k, tree.levels)
            assert lo <= leaf[i, s] <= hi
            can = any(lo <= x <= hi for x in pool)
            if can:
                assert leaf[i, s] in pool
                row = list(lrl_sorted[q, :counts[q]])
                j = row.index(leaf[i, s])
                src = int(lrn_sorted[q, j])
                if MR.depth(src) < MR.depth(k):  # (a) one ancestor cut node: intensity-share weight
                    expect = lrp_sorted[q, j] * tree.intensity[src] / tree.intensity[k]
                else:  # (b) cut nodes below k partition it: drawn in proportion to their intensity
                    cands = [int(lrn_sorted[q, c]) for c, x in enumerate(row) if lo <= x <= hi]
                    assert all(MR.depth(c) >= MR.depth(k) for c in cands)
                    expect = lrp_sorted[q, j] * tree.intensity[src] / sum(tree.intensity[c] for c in cands)
                assert pdf[i, s] == pytest.approx(expect)
                n_reuse += 1
        assert n_reuse == reused[i]


def test_foveated_pipeline_values():
    tree, full, low, ecc, occ = _image_scene()
    vel = np.zeros(full.shape + (2,))
    a = foveated_lightcuts(tree, full, low, ecc, vel, 0.1, 48, seed=2, occluded=occ)
    b = foveated_lightcuts(tree, full, low, ecc, vel, 0.1, 48, seed=2, occluded=occ, multires=False)
    for r in (a, b):
        assert r.radiance.shape == full.shape + (3,) and np.all(np.isfinite(r.radiance))
        assert np.all(r.radiance >= 0) and r.radiance.mean() > 0
        assert np.all((r.budget >= 1) & (r.budget <= 48)) and np.all(r.samples <= r.budget)
        assert set(r.timings) == {"low_res", "fpsm", "cuts", "select", "shade"}
    np.testing.assert_array_equal(a.budget, b.budget)
    assert a.reused.sum() > 0 and b.reused.sum() == 0
    # flat periphery below alpha: one sample; the foveal region (acuity above alpha) gets many more
    inner = ecc < np.radians(15)
    assert a.budget[0, 0] == 1 and a.budget.max() == 48
    assert a.budget[inner].mean() > 2 * a.budget[~inner].mean()
    assert a.samples[inner].mean() > a.samples[~inner].mean()
    again = foveated_lightcuts(tree, full, low, ecc, vel, 0.1, 48, seed=2, occluded=occ)
    assert again.radiance.tobytes() == a.radiance.tobytes()


@pytest.mark.parametrize("kw, match", [({"alpha": 0.0}, "alpha"), ({"alpha": 1.0}, "alpha"),
                                       ({"max_lspp": 0}, "max_lspp"), ({"max_lspp": -4}, "max_lspp")])
def test_foveated_bad_parameters(kw, match):
    tree, full, low, ecc, _ = _image_scene(n_lights=8)
    args = {"alpha": 0.1, "max_lspp": 48, **kw}
    with pytest.raises(ValueError, match=match):
        foveated_lightcuts(tree, full, low, ecc, np.zeros(full.shape + (2,)), args["alpha"], args["max_lspp"])


def test_n_light_breaks_ties_in_proportion_to_the_reuse_weight():
    leaves = np.array([32, 33, 34, 35], dtype=np.int64)  # cut nodes = the leaves themselves: all tied for node 8
    inten = np.zeros(64)
    inten[32:36] = [1.0, 3.0, 0.0, 4.0]
    pdfs = np.ones(4)
    lo, hi = MR.leaf_range(8, 6)
    assert (lo, hi) == (32, 35)
    us = (np.arange(4000) + 0.5) / 4000
    picks = np.array([MR.n_light(8, leaves, leaves, 4, 0, hi, pdfs, inten, u) for u in us])
    freq = np.bincount(picks, minlength=4) / len(us)
    np.testing.assert_allclose(freq, inten[32:36] / inten[32:36].sum(), atol=2e-3)
    assert MR.n_light(8, leaves, leaves, 4, 0, hi) == 0  # without weights: the first tied sample


def test_reuse_sample_draws_partitioning_cut_nodes_by_intensity():
    # node 2 (depth 1) of a 4-level tree; low-res cut nodes below it: 4 (leaves 16-19) and 10, 11 (20-21, 22-23)
    leaves = np.array([17, 21, 22], dtype=np.int64)
    nodes = np.array([4, 10, 11], dtype=np.int64)
    depths = np.array([2, 3, 3], dtype=np.int64)
    pdfs = np.array([0.5, 0.25, 0.8])
    inten = np.zeros(32)
    inten[[4, 10, 11]] = [2.0, 1.0, 5.0]
    inten[2] = 8.0
    lo, hi = MR.leaf_range(2, 5)
    first = MR.lrls(leaves[None], 0, 3, lo, hi)
    us = (np.arange(8000) + 0.5) / 8000
    out = [MR.reuse_sample(2, leaves[None], nodes[None], pdfs[None], depths[None], 0, 3, first, hi, inten, u)
           for u in us]
    picks = np.array([j for j, _ in out])
    np.testing.assert_allclose(np.bincount(picks, minlength=3) / len(us), [2 / 8, 1 / 8, 5 / 8], atol=1e-3)
    for j, pj in out[:: 500]:
        assert pj == pytest.approx(pdfs[j] * inten[nodes[j]] / 8.0)
    # case (a): the only candidate comes from an ancestor cut node (node 1 above node 5)
    j, pj = MR.reuse_sample(5, np.array([[21]], np.int64), np.array([[1]], np.int64), np.array([[0.1]]),
                            np.array([[0]], np.int64), 0, 1, 0, 23,
                            np.r_[16.0, 16.0, np.zeros(3), 4.0, np.zeros(26)], 0.3)
    assert j == 0 and pj == pytest.approx(0.1 * 16.0 / 4.0)


def test_low_res_samples_sorted_per_row_as_a_stable_argsort():
    """``sort_low_res_samples`` (the pixel kernel ``sort_pixel`` per row, generated for the GPU's LS') gives the
    arrays of a stable argsort by leaf with the empty entries last in slot order, and ``depth`` of every node."""
    rng = np.random.default_rng(1)
    n, width = 60, 12
    size = rng.integers(0, width + 1, n)
    cut = np.where(np.arange(width) < size[:, None], rng.integers(1, 64, (n, width)), 0)
    live = (np.arange(width) < size[:, None]) & (rng.random((n, width)) < 0.8)
    leaf = np.where(live, rng.integers(64, 72, (n, width)), -1)   # repeated leaves: ties keep the slot order
    pdf = np.where(live, rng.random((n, width)), 0.0)
    order = np.argsort(np.where(leaf >= 0, leaf, np.iinfo(np.int64).max), axis=1, kind="stable")
    leaves, nodes, pdfs, counts, depths = MR.sort_low_res_samples(cut, size.astype(np.int32), leaf, pdf)
    np.testing.assert_array_equal(leaves, np.take_along_axis(leaf, order, axis=1))
    np.testing.assert_array_equal(nodes, np.take_along_axis(cut, order, axis=1))
    np.testing.assert_array_equal(pdfs, np.take_along_axis(pdf, order, axis=1))
    np.testing.assert_array_equal(counts, live.sum(axis=1))
    np.testing.assert_array_equal(depths, np.floor(np.log2(np.maximum(nodes, 1))).astype(np.int64))
