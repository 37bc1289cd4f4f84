"""The scene catalogue: built-in scene names and units (:data:`METRES_PER_UNIT`), and :func:`resolve` (a name,
a YAML file or a Scene -> Scene).

Scenes are built once per process (built-in ones by name, scene files while they are unchanged), so a Dask
worker rendering many frames of a scene builds it, and its BVH, once.

Built-in scenes are registered here by name as ``"module:function"`` references, loaded on first use, so that
listing the names (protocol validation, ``studyapp scenes``) imports no scene code, and no scene module needs
to import another's catalogue (no import cycles between the scene generators).
"""

from __future__ import annotations

import functools
import importlib
from pathlib import Path

from data_schema.errors import UserError

from .scene import Scene, load_yaml

#: name -> generator ("module:function" returning a Scene).
BUILTIN_SCENES = {
    "cornell": "renderers.procedural:cornell",
    "temple": "renderers.procedural:temple",
    "street_night": "renderers.procedural:street_night",
    "interior": "renderers.procedural:interior",
    "street_day": "renderers.procedural:street_day",
    "cornell_many": "renderers.lightcuts.scenes:cornell_many",
    "study": "renderers.lightcuts.scenes:study",
    "yard": "renderers.lightcuts.scenes:yard",
    "sponza_vpl": "renderers.lightcuts.scenes:sponza_vpl",
}

#: name -> how long one of its units is, in metres (``Scene.metres_per_unit``; exploration speeds are declared in
#: metres per second and divided by it). Decided from each scene's real-world size:
METRES_PER_UNIT = {
    # The Cornell box as measured (Cornell data page): 556 x 549 x 559 millimetres, a box about 55 cm across,
    # not a room; the scene's own eye separation (display ipd 64) is 64 mm too. Walking pace crosses it in 0.4 s.
    "cornell": 0.001,
    "cornell_many": 0.001,  # the same box with many more emitters
    # The rest are modelled in metres: eye heights of 1.6-1.8 (the cameras), doors and storeys of 2-4, ipd 0.064.
    "temple": 1.0,  # a colonnade 15 m wide and 44 m long
    "street_night": 1.0,  # a street 24 m wide, 69 m long, façades 16 m high
    "interior": 1.0,  # a bar room 14 x 12 m, 4 m high
    "street_day": 1.0,  # street_night by day
    "study": 1.0,  # a room 6 x 5 m, 3 m high
    "yard": 1.0,  # a yard 40 x 40 m, walls 7 m high
    "sponza_vpl": 1.0,  # an atrium 30 x 12 m, 10 m high
}


def _load(ref: str):
    module, _, name = ref.partition(":")
    return getattr(importlib.import_module(module), name)


@functools.lru_cache(maxsize=None)
def builtin(name: str) -> Scene:
    """The built-in scene ``name`` (generated once per process)."""
    if name not in BUILTIN_SCENES:
        raise UserError(f"scene={name!r} is unknown: built-in scenes are {', '.join(BUILTIN_SCENES)}")
    scene = _load(BUILTIN_SCENES[name])()
    scene.metres_per_unit = METRES_PER_UNIT[name]
    return scene


def _scene_file(path: Path) -> Scene:
    """A scene file's Scene, built once per process while the file is unchanged (a Dask worker renders many
    frames of one scene)."""
    try:
        st = path.stat()
    except OSError:
        return load_yaml(path)  # its one-line error
    return _cached_scene_file(str(path), str(path.resolve()), st.st_mtime_ns, st.st_size)


@functools.lru_cache(maxsize=8)
def _cached_scene_file(path: str, resolved: str, mtime_ns: int, size: int) -> Scene:
    return load_yaml(Path(path))


def scene_exists(name: str, folder: Path | None = None) -> bool:
    """Whether ``name`` is a built-in scene or a scene file (``name``, ``name.yaml``) in ``folder``."""
    if name in BUILTIN_SCENES:
        return True
    return scene_file(name, folder) is not None


def scene_file(name: str, folder: Path | None = None) -> Path | None:
    """The scene file ``name`` or ``name.yaml``/``.yml`` (relative to ``folder``, default the current folder)."""
    base = Path(folder) if folder is not None else Path.cwd()
    for cand in (base / name, base / f"{name}.yaml", base / f"{name}.yml"):
        if cand.is_file():
            return cand
    return None


def resolve(scene, folder: Path | None = None) -> Scene:
    """A :class:`Scene` from a built-in name, a YAML path (absolute, or relative to ``folder``) or a Scene."""
    if isinstance(scene, Scene):
        s = scene
    elif isinstance(scene, (str, Path)):
        if str(scene) in BUILTIN_SCENES:
            s = builtin(str(scene))
        else:
            path = scene_file(str(scene), folder) or (Path(scene) if str(scene).endswith((".yaml", ".yml"))
                                                      else None)
            if path is None:
                raise UserError(f"scene={str(scene)!r} is neither a built-in scene ({', '.join(BUILTIN_SCENES)}) "
                                "nor a scene file")
            s = _scene_file(Path(path))
    else:
        raise UserError(f"scene={scene!r} is invalid: give a built-in name, a YAML path or a Scene")
    if s.light_count() == 0:
        raise UserError(f"scene {s.name!r} has no lights: add a point, directional or emissive light")
    return s
