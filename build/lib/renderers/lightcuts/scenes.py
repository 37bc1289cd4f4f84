"""Many-light scenes for the lightcuts renderers (issue 6 item 6), built on the scene model of ``renderers``.

* ``cornell_many`` — the Cornell box of ``renderers.procedural.cornell`` with its 18-triangle ceiling lamp
  replaced by ≈110k emissive triangles: the lamp as a 173×173 grid (59,858 triangles) and two coloured
  light strips just in front of the back wall (warm) and the red wall (cool), 26,000 triangles each
  (111,858 lights in all). Each
  triangle is one one-sided point light (``Scene.emitters``). Diffuse walls, glossy blocks.

* ``study`` — a 6 × 3 × 5 m room: a ceiling panel of 120×120 cells (28,800 triangles) and two LED strips along
  the upper edges of the side walls (2 × 14,600 triangles): 58,000 lights; diffuse walls, textured floor,
  glossy desk and shelves, a metallic vase.
* ``yard`` — an open yard at night: 10,000-cell ground, houses, glossy jars, and 31,325 string-light bulbs
  (octahedra, 8 emissive triangles each) hung on 25 strings between poles: 250,600 lights.

* ``sponza_vpl`` — a Sponza-like atrium (floor, walls, two colonnades of 8 columns, galleries, red and green
  curtains; all diffuse) lit by one point light whose indirect light is 120,000 virtual point lights: light
  paths traced from the point light (uniform directions, fixed seed) leave a VPL at their first hit, a one-sided
  cosine emitter on the surface with intensity ``Φ/N · albedo / π`` (``Φ = 4π I`` per channel) along the hit
  normal. ``VPLScene.emitters()`` appends them to the emissive triangles, so every renderer of the scene model
  (and its content hash) sees the same lights.
"""

from __future__ import annotations

import numpy as np

from data_schema.errors import UserError
from renderers.procedural import MeshBuilder, cornell
from renderers.scene import Camera, Material, Scene


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


def _octahedron(radius: float) -> tuple[np.ndarray, np.ndarray]:
    v = radius * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64)
    f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return v, f


def study() -> Scene:

    b = MeshBuilder()
    for m in (Material("wall", albedo=(0.7, 0.68, 0.62)),
              Material("floor", albedo=(0.55, 0.4, 0.28), albedo2=(0.35, 0.24, 0.16), texture="noise",
                       texture_scale=0.4),
              Material("desk", albedo=(0.45, 0.3, 0.2), kind="glossy", roughness=0.25, specular=0.1),
              Material("shelf", albedo=(0.3, 0.35, 0.5), kind="glossy", roughness=0.4, specular=0.06),
              Material("vase", albedo=(0.9, 0.75, 0.4), kind="metallic", roughness=0.2),
              Material("panel", emission=(3.0, 2.9, 2.6)),
              Material("led", emission=(1.5, 0.6, 0.2))):
        b.material(m)
    W, H, D = 6.0, 3.0, 5.0
    b.quad((0, 0, 0), (W, 0, 0), (W, 0, D), (0, 0, D), "floor", (0, 1, 0))
    b.quad((0, H, 0), (W, H, 0), (W, H, D), (0, H, D), "wall", (0, -1, 0))
    b.quad((0, 0, D), (W, 0, D), (W, H, D), (0, H, D), "wall", (0, 0, -1))
    b.quad((0, 0, 0), (0, 0, D), (0, H, D), (0, H, 0), "wall", (1, 0, 0))
    b.quad((W, 0, 0), (W, 0, D), (W, H, D), (W, H, 0), "wall", (-1, 0, 0))
    b.box((2.0, 0.0, 3.0), (4.0, 0.75, 4.0), "desk")
    for i in range(3):
        b.box((0.05, 0.4 + 0.7 * i, 0.8), (0.45, 0.45 + 0.7 * i, 4.2), "shelf")
    b.cylinder((3.5, 0.75, 3.5), 0.12, 0.4, "vase", segments=32)
    lights = (((2.0, H - 0.001, 1.5), (2.0, 0, 0), (0, 0, 2.0), 120, 120, (0, -1, 0), "panel"),
              ((0.002, H - 0.2, 0.1), (0, 0, 4.8), (0, 0.1, 0), 3650, 2, (1, 0, 0), "led"),
              ((W - 0.002, H - 0.2, 0.1), (0, 0, 4.8), (0, 0.1, 0), 3650, 2, (-1, 0, 0), "led"))
    for origin, du, dv, nu, nv, normal, mat in lights:
        b.add(*grid_triangles(origin, du, dv, nu, nv, normal), mat)
    cam = Camera((3.0, 1.6, 0.3), (3.0, 1.0, 4.0), (0.0, 1.0, 0.0), 70.0)
    return b.scene("study", camera=cam, ambient=(0.01, 0.01, 0.01))


def yard() -> Scene:

    b = MeshBuilder()
    for m in (Material("ground", albedo=(0.4, 0.38, 0.33), albedo2=(0.25, 0.24, 0.22), texture="checker",
                       texture_scale=1.0),
              Material("house", albedo=(0.6, 0.55, 0.5), albedo2=(0.35, 0.3, 0.28), texture="brick",
                       texture_scale=0.5),
              Material("jar", albedo=(0.2, 0.35, 0.6), kind="glossy", roughness=0.15, specular=0.12),
              Material("pole", albedo=(0.3, 0.3, 0.3)),
              Material("bulb_warm", emission=(4.0, 2.8, 1.2)),
              Material("bulb_cool", emission=(1.2, 2.4, 4.0))):
        b.material(m)
    b.add(*grid_triangles((-20, 0, -20), (40, 0, 0), (0, 0, 40), 100, 50, (0, 1, 0)), "ground")
    for x, z, w, d, h in ((-12, 6, 6, 5, 5), (6, 8, 7, 6, 6), (-4, 14, 8, 4, 7)):
        b.box((x, 0, z), (x + w, h, z + d), "house")
    rng = np.random.default_rng(3)
    for _ in range(12):
        b.cylinder((rng.uniform(-8, 8), 0, rng.uniform(-2, 6)), rng.uniform(0.2, 0.4), rng.uniform(0.4, 1.0),
                   "jar", segments=24)
    n_strings, per = 25, 1253
    bv, bf = _octahedron(0.03)
    for k in range(n_strings):
        z = -4.0 + 0.5 * k
        x0, x1 = -10.0, 10.0
        b.cylinder((x0, 0, z), 0.05, 3.5, "pole", segments=8)
        b.cylinder((x1, 0, z), 0.05, 3.5, "pole", segments=8)
        t = np.linspace(0.0, 1.0, per)
        sag = 0.8 * 4.0 * t * (1.0 - t)  # parabolic sag of the string
        centres = np.column_stack([x0 + (x1 - x0) * t, 3.4 - sag, np.full(per, z)])
        b.instance(bv, bf, centres, "bulb_warm" if k % 2 == 0 else "bulb_cool")
    cam = Camera((0.0, 1.7, -9.0), (0.0, 2.0, 4.0), (0.0, 1.0, 0.0), 65.0)
    return b.scene("yard", camera=cam, ambient=(0.005, 0.005, 0.01))


class VPLScene(Scene):
    """A :class:`~renderers.scene.Scene` with extra one-sided point lights (``vpl_pos``, ``vpl_nrm``,
    ``vpl_rgb``) reported by :meth:`emitters` after the emissive triangles."""

    def __init__(self, *args, vpl_pos, vpl_nrm, vpl_rgb, **kw):
        super().__init__(*args, **kw)
        self.vpl = tuple(np.ascontiguousarray(a, dtype=np.float64).reshape(-1, 3)
                         for a in (vpl_pos, vpl_nrm, vpl_rgb))

    def emitters(self):
        if self._emitters is None:
            tp, tn, ti = super().emitters()
            vp, vn, vi = self.vpl
            self._emitters = (np.concatenate([tp, vp]), np.concatenate([tn, vn]), np.concatenate([ti, vi]))
        return self._emitters

    def content_hash(self) -> str:
        if self._hash is None:
            import hashlib

            h = hashlib.sha256(super().content_hash().encode())
            for a in self.vpl:
                h.update(a.tobytes())
            self._hash = h.hexdigest()
        return self._hash


def trace_vpls(scene: Scene, light_pos, light_intensity, n: int, seed: int = 0, batch: int = 1 << 16):
    """``n`` virtual point lights of one isotropic point light: ``(positions, normals, intensities)``.

    Paths leave in uniform directions (batches of ``batch``, fixed ``seed``) until ``n`` of them hit the scene;
    every traced path carries ``Φ / N_traced`` (escaping paths included), so the VPLs' total power is the
    light's power reflected by the first hit.
    """
    from renderers.tracer import Tracer

    from .plugin import Hits

    rng = np.random.default_rng(seed)
    tracer = Tracer(scene, shadows=False)
    pos, nrm, alb = [], [], []
    found = traced = 0
    while found < n:
        z = rng.uniform(-1.0, 1.0, batch)
        phi = rng.uniform(0.0, 2.0 * np.pi, batch)
        r = np.sqrt(1.0 - z * z)
        hits = Hits(tracer, np.asarray(light_pos, dtype=np.float64),
                    np.column_stack([r * np.cos(phi), r * np.sin(phi), z]))
        idx = np.nonzero(hits.hit)[0][: n - found]
        traced += batch if found + int(hits.hit.sum()) <= n else int(idx[-1]) + 1
        found += len(idx)
        pos.append(hits.gbuf.position[idx])
        nrm.append(hits.gbuf.normal[idx])
        alb.append(hits.albedo[idx])
        if traced > 1000 * n:
            raise UserError("light paths escape the scene: no surface around the light")
    nrm = np.concatenate(nrm)
    flux = 4.0 * np.pi * np.asarray(light_intensity, dtype=np.float64) / traced
    return np.concatenate(pos) + 1e-4 * scene.scale * nrm, nrm, flux * np.concatenate(alb) / np.pi


def sponza_vpl(n_vpl: int = 120_000) -> Scene:
    from renderers.scene import Camera, PointLight

    b = MeshBuilder()
    for m in (Material("stone", albedo=(0.62, 0.58, 0.5), albedo2=(0.45, 0.42, 0.36), texture="brick",
                       texture_scale=0.8),
              Material("floor", albedo=(0.55, 0.52, 0.48), albedo2=(0.4, 0.38, 0.35), texture="checker",
                       texture_scale=1.0),
              Material("column", albedo=(0.7, 0.66, 0.58)),
              Material("red", albedo=(0.6, 0.08, 0.06)),
              Material("green", albedo=(0.1, 0.5, 0.12))):
        b.material(m)
    L, W, H = 30.0, 12.0, 10.0
    b.add(*grid_triangles((-L / 2, 0, -W / 2), (L, 0, 0), (0, 0, W), 60, 24, (0, 1, 0)), "floor")
    for z, nz in ((-W / 2, 1), (W / 2, -1)):
        b.add(*grid_triangles((-L / 2, 0, z), (L, 0, 0), (0, H, 0), 30, 10, (0, 0, nz)), "stone")
    for x, nx in ((-L / 2, 1), (L / 2, -1)):
        b.add(*grid_triangles((x, 0, -W / 2), (0, 0, W), (0, H, 0), 12, 10, (nx, 0, 0)), "stone")
    for side in (-1, 1):
        zc = side * 3.0
        for i in range(8):
            b.cylinder((-12.25 + 3.5 * i, 0, zc), 0.35, 4.0, "column", segments=24, flutes=12, flute_depth=0.08)
        b.box((-L / 2, 4.0, min(zc, side * W / 2)), (L / 2, 4.4, max(zc, side * W / 2)), "stone")
        for i in range(7):
            x0 = -12.25 + 3.5 * i + 0.6
            b.add(*grid_triangles((x0, 1.2, zc + side * 0.5), (2.3, 0, 0), (0, 2.6, 0), 4, 4, (0, 0, -side)),
                  "red" if (i + (side > 0)) % 2 else "green")
    base = b.scene("sponza_vpl", camera=Camera((-13.0, 1.8, 0.0), (10.0, 2.5, 0.0), (0.0, 1.0, 0.0), 60.0),
                   point_lights=[PointLight((0.0, 8.5, 0.0), (400.0, 380.0, 340.0))])
    vpos, vnrm, vrgb = trace_vpls(base, (0.0, 8.5, 0.0), (400.0, 380.0, 340.0), n_vpl, seed=7)
    return VPLScene(name=base.name, vertices=base.vertices, faces=base.faces, material_ids=base.material_ids,
                    materials=base.materials, point_lights=base.point_lights, camera=base.camera,
                    display=base.display, vpl_pos=vpos, vpl_nrm=vnrm, vpl_rgb=vrgb)


SCENES = {"cornell_many": cornell_many, "study": study, "yard": yard, "sponza_vpl": sponza_vpl}
