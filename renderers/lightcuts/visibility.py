"""Shadow rays through Embree (``embreex``) on plain ``(vertices, faces)`` triangle arrays."""

from __future__ import annotations

import numpy as np

from data_schema.errors import UserError

from ..constants import LC_SHADOW_EPS


class EmbreeOccluder:
    """``occluded(origins, targets)``: True where a triangle lies between each origin and its target.

    Embree works in float32 and starts rays at ``t = 0``: offset origins off their surface (the renderer
    does, along the normal) and keep scenes near unit scale. The segment is shortened to
    ``(1 - end_eps)`` of its length so that a light sitting on an emitter triangle is not hidden by it.
    """

    def __init__(self, vertices, faces, end_eps: float = LC_SHADOW_EPS):
        from embreex import mesh_construction, rtcore_scene

        v = np.ascontiguousarray(vertices, dtype=np.float32)
        f = np.ascontiguousarray(faces, dtype=np.int32)
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
            raise UserError(f"vertices {v.shape} and faces {f.shape} must both be (n, 3)")
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise UserError("faces index a vertex outside vertices")
        self.end_eps = float(end_eps)
        self._scene = rtcore_scene.EmbreeScene()
        self._mesh = mesh_construction.TriangleMesh(self._scene, v, f) if len(f) else None

    def __call__(self, origins, targets) -> np.ndarray:
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(np.asarray(targets, dtype=np.float32) - o)
        if self._mesh is None or len(o) == 0:
            return np.zeros(len(o), dtype=bool)
        tfar = np.full(len(o), 1.0 - self.end_eps, dtype=np.float32)
        hit = self._scene.run(o, d, dists=tfar, query="OCCLUDED")
        return np.asarray(hit) >= 0
