"""Many-light scenes for the lightcuts renderers (issue 6 item 6), built on the scene model of ``renderers``.

* ``cornell_many`` — the Cornell box of ``renderers.procedural.cornell`` with its 18-triangle ceiling lamp
  replaced by ≈110k emissive triangles: the lamp as a 173×173 grid (59,858 triangles) and two coloured
  light strips just in front of the back wall (warm) and the red wall (cool), 26,000 triangles each
  (111,858 lights in all). Each
  triangle is one one-sided point light (``Scene.emitters``). Diffuse walls, glossy blocks.

The other scenes of the issue (``study`` ≈58k, ``yard`` ≥250k, ``sponza_vpl`` ≈120k virtual point lights) are
not built yet (see docs/lightcuts.md).
"""

from __future__ import annotations

import numpy as np

from renderers.scene import Material, Scene


def grid_triangles(origin, du, dv, nu: int, nv: int, normal) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of the parallelogram ``origin + s du + t dv`` split into ``nu × nv`` cells
    (``2 nu nv`` triangles), wound to face ``normal``. Vectorised."""
    o, du, dv = (np.asarray(a, dtype=np.float64) for a in (origin, du, dv))
    s, t = np.meshgrid(np.arange(nu + 1) / nu, np.arange(nv + 1) / nv, indexing="ij")
    verts = o + s[..., None] * du + t[..., None] * dv
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    if np.dot(np.cross(du, dv), normal) < 0:
        faces = faces[:, ::-1]
    return verts.reshape(-1, 3), faces


def cornell_many() -> Scene:
    from renderers.procedural import cornell

    base = cornell()
    names = [m.name for m in base.materials]
    lamp_id = names.index("light")
    keep = base.material_ids != lamp_id
    verts = [base.vertices.astype(np.float64)]
    faces = [base.faces[keep]]
    mids = [base.material_ids[keep]]
    materials = list(base.materials)
    materials.append(Material("strip_warm", albedo=(0.8, 0.8, 0.8), emission=(6.0, 3.0, 0.8)))
    materials.append(Material("strip_cool", albedo=(0.8, 0.8, 0.8), emission=(0.8, 2.0, 6.0)))
    n_v = len(verts[0])
    for (origin, du, dv, nu, nv, normal), mid in (
            (((213.0, 548.7, 227.0), (130.0, 0.0, 0.0), (0.0, 0.0, 105.0), 173, 173, (0, -1, 0)), lamp_id),
            (((30.0, 470.0, 558.7), (496.0, 0.0, 0.0), (0.0, 25.0, 0.0), 1000, 13, (0, 0, -1)),
             len(materials) - 2),
            (((555.5, 470.0, 30.0), (0.0, 0.0, 499.2), (0.0, 25.0, 0.0), 1000, 13, (-1, 0, 0)),
             len(materials) - 1)):
        v, f = grid_triangles(origin, du, dv, nu, nv, normal)
        verts.append(v)
        faces.append(f + n_v)
        mids.append(np.full(len(f), mid, dtype=np.int32))
        n_v += len(v)
    return Scene(name="cornell_many", vertices=np.concatenate(verts), faces=np.concatenate(faces),
                 material_ids=np.concatenate(mids), materials=materials, camera=base.camera,
                 display=base.display, ambient=base.ambient)


SCENES = {"cornell_many": cornell_many}
