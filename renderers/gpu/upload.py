"""A scene uploaded to the GPU once: BVH, triangles, materials, lights; per frame only camera and gaze change.

:func:`device_scene` is the factory the renderer registry calls instead of building a CPU
:class:`~renderers.tracer.Tracer`. Uploads are cached on the device (``Device.cache``) by ``Scene.content_hash()`` (geometry and
materials) and ``shadows`` (which lights cast shadow rays); each call returns a fresh :class:`DeviceScene` view
with its own :class:`~renderers.tracer.Counters`, so every render reports its own work.
"""

from __future__ import annotations

import time
import weakref

import numpy as np

from ..projection import tan_half_fov
from ..tracer import Counters, pack_scene
from . import bvh as B
from .bindings import image_unit
from .context import TEX_WIDTH, WAY_OUT, Device, get_device

#: The built-in GPU renderers keep the per-light contributions of a point in registers: scenes with more lights
#: (the many-light scenes) are rendered by the lightcuts renderers, which sample a light tree instead
#: (:mod:`renderers.gpu.lightcuts`).
MAX_LIGHTS = 256

_BVH_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def scene_bvh(scene) -> B.BVH:
    """The scene's BVH (built once per Scene object)."""
    b = _BVH_CACHE.get(scene)
    if b is None:
        b = B.build(scene.vertices, scene.faces)
        _BVH_CACHE[scene] = b
    return b


def _material_table(mat_f: np.ndarray, mat_i: np.ndarray) -> np.ndarray:
    """4 vec4 per material: the 14 columns of ``mat_f`` in order (renderers.tracer.pack_scene; the generated
    kernels index them as the CPU does, ``scene.glsl``'s ``material(m, c)``), then the texture kind ``mat_i[:, 0]``."""
    m = np.zeros((len(mat_f), 16), dtype=np.float32)
    m[:, :14], m[:, 14] = mat_f, mat_i[:, 0]
    return m


def _light_table(p: dict) -> np.ndarray:
    """3 vec4 per light: (position, kind), (intensity, casts shadows), (direction, 0)."""
    k = len(p["L_kind"])
    t = np.zeros((max(k, 1), 12), dtype=np.float32)
    t[:k, 0:3], t[:k, 3] = p["L_pos"], p["L_kind"]
    t[:k, 4:7], t[:k, 7] = p["L_int"], p["L_cast"]
    t[:k, 8:11] = p["L_dir"]
    return t


class _Upload:
    """GPU buffers of one scene (geometry + materials) and one light table."""

    def __init__(self, device: Device, scene, shadows: bool):
        t0 = time.perf_counter()
        k = scene.light_count()
        packed = pack_scene(scene, shadows)
        tree = scene_bvh(scene)
        tris = tree.tris.copy()
        tris.view(np.int32)[:, 7] = scene.material_ids[tree.tris.view(np.int32)[:, 3]]
        mats = _material_table(packed["mat_f"], packed["mat_i"])
        # the light table of the built-in renderers (a placeholder where they refuse the scene: check_lights)
        lights = _light_table(packed) if k <= MAX_LIGHTS else np.zeros((1, 12), dtype=np.float32)
        tables = {"BVH": tree.nodes, "triangles": tris, "materials": mats, "lights": lights}
        device.check_fits(f"scene {scene.name!r}", {k: v.nbytes for k, v in tables.items()})
        self.device = device
        self.textures = [device.table_texture(f"scene {scene.name!r} {k}", v) for k, v in tables.items()]
        self.light_count = k
        self.ambient = tuple(float(x) for x in packed["ambient"])
        self.background = tuple(float(x) for x in packed["background"])
        self.bvh_depth = tree.depth
        self.n_nodes = len(tree.nodes)
        self.seconds = time.perf_counter() - t0

    def release(self):
        for t in self.textures:
            self.device.release(t)
        self.textures = []


class DeviceScene:
    """What a GPU renderer receives as ``ctx.tracer``: the uploaded scene, the settings, the counters.

    Parameters
    ----------
    scene : Scene
    shadows : bool
        Cast shadow rays (also needs ``scene.shadows`` and the light's flag).
    light_cull : float
        ``eps`` of the light culling of :mod:`renderers._shade`.
    device : Device, optional
    """

    def __init__(self, scene, *, shadows: bool = True, light_cull: float = 0.01, device: Device | None = None):
        self.device = device or get_device()
        self.scene = scene
        key = (scene.content_hash(), bool(shadows and scene.shadows))
        uploads = self.device.cache.setdefault("uploads", {})
        up = uploads.get(key)
        if up is None:
            up = uploads[key] = _Upload(self.device, scene, key[1])
        self.upload = up
        self.light_cull = float(light_cull)
        self.counters = Counters()
        self.offset = 1e-5 * scene.scale
        self.far = 4.0 * scene.scale
        self.light_count = max(up.light_count, 1)
        self.mask_words = (min(self.light_count, MAX_LIGHTS) + 31) // 32
        #: ``cancel()`` -> True stops the render before its next dispatch (:meth:`.frame.Frame.run`).
        self.cancel = None

    def check_lights(self) -> None:
        """Refuse (one line) a scene with more lights than the built-in GPU renderers shade per point."""
        if self.upload.light_count > MAX_LIGHTS:
            from data_schema.errors import UserError

            raise UserError(f"scene {self.scene.name!r} has {self.upload.light_count:,} lights; the GPU renderers "
                            f"gt, vafr, lmfr and lafr shade up to {MAX_LIGHTS} per point (the lightcuts renderers "
                            f"fsl, sl_*, sl_gt sample a light tree): {WAY_OUT}")

    def bind_scene(self) -> None:
        for name, tex in zip(("t_nodes", "t_tris", "t_mats", "t_lights"), self.upload.textures):
            tex.bind_to_image(image_unit(name), read=True, write=False)

    def scene_uniforms(self) -> dict:
        return {"u_ambient": self.upload.ambient, "u_background": self.upload.background,
                "u_light_cull": self.light_cull, "u_offset": self.offset, "u_far": self.far}

    def defines(self) -> dict:
        return {"LIGHT_COUNT": self.light_count, "MASK_WORDS": self.mask_words, "TEX_WIDTH": TEX_WIDTH}


def device_scene(scene, params: dict) -> DeviceScene:
    """The registry's factory for the GPU backend (``params``: the resolved renderer parameters)."""
    return DeviceScene(scene, shadows=bool(params.get("shadows", True)),
                       light_cull=float(params.get("light_cull", 0.0)))


def camera_uniforms(camera, width: int, height: int) -> dict:
    """Uniforms of ``shaders/camera.glsl`` for a :class:`~renderers.scene.Camera`: its basis, ``t = tan(fov/2)``
    (:func:`renderers.projection.tan_half_fov`) and the screen size; the shader evaluates
    :func:`renderers.projection.camera_rays` with them."""
    f, r, u = camera.basis()
    return {"u_cam_f": tuple(map(float, f)), "u_cam_r": tuple(map(float, r)), "u_cam_u": tuple(map(float, u)),
            "u_tan": tan_half_fov(camera), "u_screen": (float(width), float(height))}
