"""Light tree invariants (issue 6 item 1/9): every light in one leaf, sums, boxes, Morton order."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from renderers.lightcuts.tree import build_light_tree, morton_codes


def _lights(n, seed):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 3)) * rng.uniform(0.1, 10), rng.uniform(0, 2, size=(n, 3))


@settings(max_examples=40)
@given(n=st.integers(1, 300), seed=st.integers(0, 2**31))
def test_tree_invariants(n, seed):
    pos, rgb = _lights(n, seed)
    t = build_light_tree(pos, rgb)
    N = t.n_leaves
    assert N >= n and N & (N - 1) == 0 and N < 2 * max(n, 1) + 1
    assert t.levels == int(np.log2(N)) + 1
    # every light in exactly one leaf
    assert np.array_equal(np.sort(t.order), np.arange(n))
    np.testing.assert_array_equal(t.light_pos[:n], pos[t.order])
    np.testing.assert_array_equal(t.light_rgb[:n], rgb[t.order])
    np.testing.assert_array_equal(t.leaf_node(np.arange(n)) - N, np.argsort(t.order))
    # padding leaves carry nothing
    assert np.all(t.light_rgb[n:] == 0) and np.all(t.intensity[N + n:] == 0)
    np.testing.assert_allclose(t.intensity[N:N + n], rgb[t.order].sum(axis=1))
    # node intensity = sum of children, boxes contain children
    k = np.arange(1, N)
    np.testing.assert_allclose(t.intensity[k], t.intensity[2 * k] + t.intensity[2 * k + 1], rtol=1e-12)
    for c in (2 * k, 2 * k + 1):
        assert np.all(t.bmin[k] <= t.bmin[c]) and np.all(t.bmax[k] >= t.bmax[c])
    np.testing.assert_allclose(t.intensity[1], rgb.sum(), rtol=1e-12)
    np.testing.assert_array_equal(t.bmin[1], pos.min(axis=0))
    np.testing.assert_array_equal(t.bmax[1], pos.max(axis=0))


def test_leaves_sorted_by_morton_code():
    pos, rgb = _lights(500, 3)
    t = build_light_tree(pos, rgb)
    codes = morton_codes(pos)[t.order]
    assert np.all(np.diff(codes.astype(np.int64)) >= 0)


def test_morton_code_interleaves_bits():
    # corners of the unit cube: x is the most significant bit of each triple
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=float)
    codes = morton_codes(pos)
    full = sum(1 << b for b in range(30))
    assert codes[0] == 0 and codes[4] == full
    assert codes[1] == sum(1 << (3 * b + 2) for b in range(10))
    assert codes[2] == sum(1 << (3 * b + 1) for b in range(10))
    assert codes[3] == sum(1 << (3 * b) for b in range(10))


def test_one_sided_light_normals_follow_the_leaf_order():
    pos, rgb = _lights(50, 4)
    nrm = np.random.default_rng(4).normal(size=(50, 3))
    t = build_light_tree(pos, rgb, nrm * 3.0)
    np.testing.assert_allclose(t.light_nrm[:50], (nrm / np.linalg.norm(nrm, axis=1)[:, None])[t.order])
    assert build_light_tree(pos, rgb).light_nrm is None
    assert np.all(build_light_tree(pos, rgb, np.zeros((50, 3))).light_nrm == 0)  # zero rows: isotropic
    with pytest.raises(ValueError, match="light normals must be finite"):
        build_light_tree(pos, rgb, np.full((50, 3), np.nan))


def test_grey_intensity_and_single_light():
    t = build_light_tree([[1.0, 2.0, 3.0]], [2.0])
    assert t.n_leaves == 1 and t.levels == 1
    assert t.intensity[1] == 6.0
    np.testing.assert_array_equal(t.bmin[1], [1, 2, 3])


@pytest.mark.parametrize("pos, inten, match", [
    (np.zeros((0, 3)), np.zeros((0, 3)), "zero lights"),
    (np.zeros((2, 3)), np.array([[1, 1, 1], [1, -0.5, 1]]), "intensities must be >= 0"),
    (np.zeros((2, 2)), np.ones((2, 3)), "positions has shape"),
    (np.zeros((2, 3)), np.ones((3, 3)), "intensities has shape"),
    (np.array([[0, 0, np.nan], [0, 0, 0]]), np.ones(2), "positions must be finite"),
])
def test_bad_lights(pos, inten, match):
    with pytest.raises(ValueError, match=match):
        build_light_tree(pos, inten)
