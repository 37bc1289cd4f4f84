"""Perfect binary light tree over point lights (Lin & Yuksel 2020; seed 003 Algorithm 1 line 3).

Layout (heap, 1-based): the light count ``n_lights`` is rounded up to a power of two ``N``; the root is node 1,
the children of node ``k`` are ``2k`` and ``2k + 1``, and the leaves are nodes ``N .. 2N - 1``. The tree has
``levels = log2(N) + 1`` levels (the ``n`` of seed 003 Eq 9). Node 0 is unused.

Lights are sorted by the 3-D Morton code of their position (10 bits per axis inside the lights' bounding
box; ties keep the input order), so that the leaves under a node are spatially close. Padding leaves
(``n_lights <= i < N``) have zero intensity and sit at the position of the last real light, so they never
enlarge a bounding box and never get sampled.

Node data:

* ``bmin``, ``bmax`` (2N, 3): axis-aligned bounding box, the union of the children's boxes (a leaf's box is
  its light's position);
* ``intensity`` (2N,): scalar importance ``I = r + g + b`` of a leaf (as in Lin & Yuksel's demo) and the sum
  of the children's ``I`` for an internal node.

Why scalar node intensity plus RGB leaves: sampling needs one number per node (a probability), and the
estimator ``f(l) / p(l)`` stays unbiased for any probabilities that are positive wherever ``f`` is non-zero;
``r + g + b > 0`` exactly when a light has any colour, so the condition holds. The RGB intensity is used only
when a light is shaded (``light_rgb``), which saves two thirds of the node memory and keeps the tree build
a single pass of sums.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from data_schema.errors import UserError

MORTON_BITS = 10  # per axis: a 30-bit code


@dataclass(frozen=True)
class LightTree:
    """A perfect binary light tree in heap layout (see the module docstring).

    Attributes
    ----------
    n_lights : int
        Real lights.
    n_leaves : int
        ``N``, the power of two ``>= n_lights``; leaves are nodes ``N .. 2N - 1``.
    levels : int
        ``log2(N) + 1``.
    order : (n_lights,) int64
        ``order[i]`` is the input index of the light at leaf ``N + i``.
    light_pos : (N, 3) float64
        Leaf positions in leaf order (padding repeats the last real light).
    light_rgb : (N, 3) float64
        Leaf RGB intensities (radiant intensity, W/sr per channel; padding is 0).
    bmin, bmax : (2N, 3) float64
        Node bounding boxes.
    intensity : (2N,) float64
        Node scalar intensity ``sum(r + g + b)`` over the leaves below.
    scene_radius : float
        Half the diagonal of the lights' bounding box (at least 1e-9); sets the distance clamp.
    light_nrm : (N, 3) float64 or None
        Unit emitter normals of one-sided lights (points sampled on emissive triangles), in leaf order; their
        intensity towards direction ``w`` is ``I max(0, n_l . w)``; zero rows and ``None``: isotropic lights. The node
        bounds ignore the orientation (it only lowers a contribution), so they stay conservative.
    """

    n_lights: int
    n_leaves: int
    levels: int
    order: np.ndarray
    light_pos: np.ndarray
    light_rgb: np.ndarray
    bmin: np.ndarray
    bmax: np.ndarray
    intensity: np.ndarray
    scene_radius: float
    light_nrm: np.ndarray | None = None

    def leaf_node(self, light_index):
        """Heap node of input light ``light_index`` (vectorised)."""
        inv = np.empty(self.n_lights, dtype=np.int64)
        inv[self.order] = np.arange(self.n_lights)
        return self.n_leaves + inv[np.asarray(light_index)]


def _spread_bits(x: np.ndarray) -> np.ndarray:
    """Insert two zero bits between each of the low 10 bits of ``x`` (uint64)."""
    x = x & np.uint64(0x3FF)
    x = (x | (x << np.uint64(16))) & np.uint64(0x030000FF)
    x = (x | (x << np.uint64(8))) & np.uint64(0x0300F00F)
    x = (x | (x << np.uint64(4))) & np.uint64(0x030C30C3)
    x = (x | (x << np.uint64(2))) & np.uint64(0x09249249)
    return x


def morton_codes(positions: np.ndarray) -> np.ndarray:
    """30-bit 3-D Morton codes of ``positions`` quantised to 10 bits per axis inside their bounding box."""
    p = np.asarray(positions, dtype=np.float64)
    lo = p.min(axis=0)
    ext = p.max(axis=0) - lo
    ext[ext <= 0] = 1.0
    q = np.clip(((p - lo) / ext * 1024.0).astype(np.int64), 0, 1023).astype(np.uint64)
    return (_spread_bits(q[:, 0]) << np.uint64(2)) | (_spread_bits(q[:, 1]) << np.uint64(1)) | _spread_bits(q[:, 2])


def validate_lights(positions, intensities) -> tuple[np.ndarray, np.ndarray]:
    """Check light arrays; return float64 ``(n, 3)`` positions and RGB intensities.

    ``intensities`` may be ``(n,)`` (grey) or ``(n, 3)`` (RGB). Raises ValueError naming the parameter.
    """
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise UserError(f"light positions has shape {pos.shape}: must be (n_lights, 3)")
    if pos.shape[0] == 0:
        raise UserError("lights: the scene has zero lights; at least 1 light is needed")
    rgb = np.asarray(intensities, dtype=np.float64)
    if rgb.ndim == 1:
        rgb = np.repeat(rgb[:, None], 3, axis=1)
    if rgb.shape != pos.shape:
        raise UserError(f"light intensities has shape {np.shape(intensities)}: must be ({pos.shape[0]},) "
                         f"or ({pos.shape[0]}, 3)")
    if not np.all(np.isfinite(pos)):
        raise UserError("light positions must be finite (found NaN or inf)")
    if not np.all(np.isfinite(rgb)):
        raise UserError("light intensities must be finite (found NaN or inf)")
    if np.any(rgb < 0):
        i = int(np.argwhere(rgb < 0)[0, 0])
        raise UserError(f"light intensities must be >= 0: light {i} has {rgb[i].tolist()}")
    return pos, rgb


def build_light_tree(positions, intensities, normals=None) -> LightTree:
    """Build the perfect binary light tree of point lights (vectorised, one pass per level).

    Parameters
    ----------
    positions : (n, 3) array_like
        Light positions.
    intensities : (n,) or (n, 3) array_like
        Radiant intensities, >= 0 (grey or RGB); for one-sided lights the intensity along the normal.
    normals : (n, 3) array_like, optional
        Emitter normals of one-sided (mesh) lights, normalised here; a zero row marks an isotropic point light
        (scenes mixing point lights and emissive triangles).

    Returns
    -------
    LightTree
    """
    pos, rgb = validate_lights(positions, intensities)
    n = pos.shape[0]
    n_leaves = 1 << max(0, int(n - 1).bit_length())
    levels = n_leaves.bit_length()  # log2(N) + 1
    order = np.argsort(morton_codes(pos), kind="stable")
    light_pos = np.empty((n_leaves, 3))
    light_pos[:n] = pos[order]
    light_pos[n:] = light_pos[n - 1]
    light_rgb = np.zeros((n_leaves, 3))
    light_rgb[:n] = rgb[order]
    bmin = np.empty((2 * n_leaves, 3))
    bmax = np.empty((2 * n_leaves, 3))
    inten = np.zeros(2 * n_leaves)
    bmin[n_leaves:] = light_pos
    bmax[n_leaves:] = light_pos
    inten[n_leaves:] = light_rgb.sum(axis=1)
    bmin[0] = bmax[0] = 0.0
    width = n_leaves
    while width > 1:
        half = width // 2
        par = slice(half, width)
        left = slice(width, 2 * width, 2)
        right = slice(width + 1, 2 * width, 2)
        np.minimum(bmin[left], bmin[right], out=bmin[par])
        np.maximum(bmax[left], bmax[right], out=bmax[par])
        np.add(inten[left], inten[right], out=inten[par])
        width = half
    radius = max(0.5 * float(np.linalg.norm(bmax[1] - bmin[1])), 1e-9)
    light_nrm = None
    if normals is not None:
        nrm = np.asarray(normals, dtype=np.float64)
        if nrm.shape != pos.shape:
            raise UserError(f"light normals has shape {nrm.shape}: must be ({n}, 3)")
        length = np.linalg.norm(nrm, axis=1)
        if not np.all(np.isfinite(length)):
            raise UserError("light normals must be finite (found NaN or inf)")
        light_nrm = np.zeros((n_leaves, 3))
        light_nrm[:n] = (nrm / np.where(length > 0, length, 1.0)[:, None])[order]
    return LightTree(n, n_leaves, levels, order, light_pos, light_rgb, bmin, bmax, inten, radius, light_nrm)
