"""Tone mapping, image output and the content-addressed stimulus cache.

The cache key is the SHA-256 of: the scene's content hash (geometry, materials, lights, camera, display), the
renderer name, its full parameter dict (defaults filled in), the resolution, the gaze, the camera overrides and
the code version (a hash of every ``.py`` file of the ``renderers`` package), and the backend unless it is the
CPU. A stimulus is stored as ``<cache_dir>/<key[:2]>/<key>.png`` (8-bit sRGB) with the linear float32 image
``<key>.npy`` and the stats ``<key>.json`` next to it. Each file is written to a temporary name and renamed; the
PNG is renamed last, so its presence means the entry is complete.

An entry is verified before every use (:func:`check_entry`, through :func:`cached_entry`): its ``.json`` records
the image's shape and dtype and the SHA-256 of the ``.npy``'s data and of the PNG's bytes, and the files must
agree with it and with the frame asked for (the ``.npy``'s header read first, without allocating; the PNG's
size read from its header; the linear image finite). A damaged entry (a truncated or replaced file, NaN, a wrong
shape or dtype) is removed, reported on stderr (``cache: re-rendering 1 damaged entry: <png>: <reason>``) and
rendered again; it is never copied into a stimulus set or tabulated. A cached render costs one key, one lookup
and one pass over the entry's files (about 60 ms at 1920 x 1080).

The same entry is made in process (:func:`render_stimulus`) or split for a cluster (``studyapp.cluster``): the
client checks a frame and computes its key (:func:`frame_request`), a worker renders it into the entry's content
(:func:`render_entry`: names and parameters in, the image, stats and PNG bytes out) and the client writes it
(:func:`write_entry`); both routes give the same bytes.
"""

from __future__ import annotations

import functools
import hashlib
import json
import re
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from data_schema.errors import UserError, first_line


def to_srgb8(img: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Linear RGB -> 8-bit sRGB: ``clip(exposure * x, 0, 1)``, then the sRGB transfer curve, rounded.

    Converted in row blocks so that the float64 temporaries stay small for any resolution.
    """
    img = np.asarray(img)
    out = np.empty(img.shape, dtype=np.uint8)
    step = max(1, (1 << 20) // max(1, img[0].size))
    for r0 in range(0, img.shape[0], step):
        x = np.clip(np.asarray(img[r0:r0 + step], dtype=np.float64) * exposure, 0.0, 1.0)
        s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
        out[r0:r0 + step] = np.round(s * 255.0)
    return out


def save_png(fh_or_path, img: np.ndarray, exposure: float = 1.0) -> None:
    """Write the tone-mapped sRGB PNG of a linear image to an open file or a path (deterministic bytes)."""
    from PIL import Image

    Image.fromarray(to_srgb8(img, exposure), "RGB").save(fh_or_path, format="PNG", optimize=False)


def save_npy(path, img: np.ndarray) -> None:
    """Write the linear float32 image as ``.npy``."""
    with open(path, "wb") as fh:
        np.save(fh, np.asarray(img, dtype=np.float32))


def write_png(path, img: np.ndarray, exposure: float = 1.0) -> Path:
    """Atomically write the tone-mapped sRGB PNG of a linear image (deterministic bytes)."""
    from data_schema.atomic import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp:
        save_png(tmp, img, exposure)
    return path


def write_npy(path, img: np.ndarray) -> Path:
    from data_schema.atomic import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp:
        save_npy(tmp, img)
    return path


def write_png_and_npy(png: Path, img: np.ndarray, exposure: float = 1.0) -> Path:
    """The PNG and its linear image (``.npy`` next to it) as a pair: both appear, or neither does."""
    from data_schema.atomic import atomic_files

    png = Path(png)
    with atomic_files([png.with_suffix(".npy"), png]) as (tmp_npy, tmp_png):
        save_npy(tmp_npy, img)
        save_png(tmp_png, img, exposure)
    return png


@functools.lru_cache(maxsize=1)
def code_version() -> str:
    """SHA-256 over the source files of the ``renderers`` package (any code change invalidates the cache)."""
    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        h.update(str(p.relative_to(root)).encode())
        h.update(p.read_bytes())
    return h.hexdigest()


def _canon(x):
    if isinstance(x, dict):
        return {str(k): _canon(v) for k, v in sorted(x.items())}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_canon(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x)
    if isinstance(x, (np.integer, int)) and not isinstance(x, bool):
        return int(x)
    return x


def stimulus_key(scene, renderer: str, params: dict, width: int, height: int, gaze, camera=None,
                 backend: str = "cpu") -> str:
    """The cache key (hex SHA-256) of a stimulus; ``scene`` must be resolved (a Scene). The backend enters the
    key only when it is not the CPU (whose keys stay as they were)."""
    doc = {"scene": scene.content_hash(), "renderer": renderer, "params": _canon(params), "width": int(width),
           "height": int(height), "gaze": _canon(list(gaze)), "camera": _canon(camera or {}),
           "code": code_version()}
    if backend != "cpu":
        doc["backend"] = backend
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


@dataclass(frozen=True)
class FrameRequest:
    """One stimulus frame as a task carries it to a worker: names and parameters, never meshes.

    ``scene`` is a built-in scene name or a scene file's path (or, in process only, a Scene); ``params`` are
    the renderer's full, checked parameters; ``key`` is the cache key the client computed
    (:func:`stimulus_key`), which the worker checks against its own code.
    """

    key: str
    scene: object
    renderer: str
    params: dict
    width: int
    height: int
    gaze: tuple[float, float]
    camera: dict | None = None
    backend: str = "cpu"


@dataclass
class CacheEntry:
    """The files of one cache entry: the linear image (``.npy``), the stats (``.json``) and the PNG."""

    key: str
    image: np.ndarray
    stats_json: str
    png: bytes


def frame_request(scene, renderer: str, params: dict | None, width: int, height: int, gaze=None,
                  camera: dict | None = None, backend: str = "cpu") -> FrameRequest:
    """Check a stimulus (one-line ValueError on bad input, before anything is rendered) and compute its key."""
    from data_schema.geometry import check_gaze

    from .catalog import resolve
    from .registry import check_resolution, get, resolve_params

    sc = resolve(scene)
    full = resolve_params(renderer, params)
    check_resolution(width, height, get(renderer).bytes_per_pixel)
    if gaze is None:
        gaze = (width / 2.0, height / 2.0)
    gaze = check_gaze(gaze, width, height)
    if camera:
        sc.camera.override(camera)
    key = stimulus_key(sc, renderer, full, width, height, gaze, camera, backend)
    return FrameRequest(key, scene, renderer, full, int(width), int(height), tuple(gaze), camera, backend)


def cached_png(cache_dir, key: str) -> Path:
    """The PNG of cache entry ``key`` (it exists only when the entry is complete)."""
    return Path(cache_dir) / key[:2] / f"{key}.png"


#: The field of an entry's ``.json`` that records what its ``.npy`` and PNG must be (:func:`check_entry`).
ENTRY_FIELD = "cache_entry"
#: An entry's ``.json`` is a small stats record: a larger one is not ours.
MAX_STATS_BYTES = 1 << 20


def _scan(img: np.ndarray) -> tuple[str, int]:
    """The SHA-256 of an image's data in C order and its count of non-finite values, in one pass over row blocks
    (a memory map is never read whole: bounded memory at any resolution)."""
    h, bad = hashlib.sha256(), 0
    step = max(1, (1 << 22) // max(1, img[0].nbytes))
    for r0 in range(0, img.shape[0], step):
        block = np.ascontiguousarray(img[r0:r0 + step])
        h.update(block.data)
        bad += int(block.size - np.count_nonzero(np.isfinite(block)))
    return h.hexdigest(), bad


def entry_record(image: np.ndarray, png: bytes) -> dict:
    """What an entry's ``.json`` records of its files (:data:`ENTRY_FIELD`): checked by :func:`check_entry`."""
    return {"shape": list(image.shape), "dtype": image.dtype.name, "npy_sha256": _scan(image)[0],
            "png_sha256": hashlib.sha256(png).hexdigest()}


def check_entry(png: Path, shape: tuple[int, ...]) -> str | None:
    """Why the cache entry of ``png`` may not be used for a linear image of ``shape`` ((H, W, 3)), or None.

    Cheapest checks first: the ``.json``'s record (:func:`entry_record`) against ``shape``; the PNG's size
    from its header, then its bytes' hash; the ``.npy``'s header (dtype, shape, length: nothing allocated,
    :func:`data_schema.images.read_npy_header`), then one pass over its data in a memory map (hash, finite).
    """
    from data_schema.images import load_npy, open_image

    png = Path(png)
    meta_file, npy = png.with_suffix(".json"), png.with_suffix(".npy")
    shape = tuple(int(n) for n in shape)
    for f in (meta_file, npy, png):  # a FIFO or a device would block or never end: not ours
        if f.exists() and not f.is_file():
            return f"{f.suffix}: not a regular file"
    try:
        if meta_file.stat().st_size > MAX_STATS_BYTES:
            return f".json: over {MAX_STATS_BYTES} bytes"
        meta = json.loads(meta_file.read_bytes())
    except FileNotFoundError:
        return ".json: missing"
    except (OSError, ValueError) as exc:
        return f".json: not readable ({first_line(exc)})"
    rec = meta.get(ENTRY_FIELD) if isinstance(meta, dict) else None
    if not isinstance(rec, dict) or meta.get("key") != png.stem:
        return ".json: not this entry's record"
    if rec.get("shape") != list(shape) or rec.get("dtype") != "float32":
        return f".json: records a {rec.get('dtype')} image of shape {rec.get('shape')}, expected float32 {shape}"
    try:
        with open_image(png) as im:  # the header only
            if im.format != "PNG" or im.size != (shape[1], shape[0]) or im.mode != "RGB":
                return f".png: a {im.format} {im.mode} image of {im.size[0]}x{im.size[1]} pixels, expected an " \
                       f"RGB PNG of {shape[1]}x{shape[0]}"
        with open(png, "rb") as fh:
            if hashlib.file_digest(fh, "sha256").hexdigest() != rec.get("png_sha256"):
                return ".png: its bytes differ from those recorded (damaged or replaced)"
    except (OSError, ValueError) as exc:
        return f".png: {first_line(exc).replace(f'cannot read image {png}: ', '').replace(f'{png}: ', '')}"
    try:
        image = load_npy(npy, dtypes=("float32",), shape=shape, mmap=True)
    except (OSError, ValueError) as exc:
        return f".npy: {first_line(exc).replace(f'cannot read image {npy}: ', '').replace(f'{npy}: ', '')}"
    digest, bad = _scan(image)
    del image  # unmapped
    if bad:
        return f".npy: {bad} NaN or infinite value(s)"
    if digest != rec.get("npy_sha256"):
        return ".npy: its data differ from those recorded (damaged or replaced)"
    return None


def report_damaged(damaged: list[tuple[Path, str]], stream=None) -> None:
    """Say on stderr, in one line, which damaged entries are rendered again and why (the first three)."""
    if not damaged:
        return
    n = len(damaged)
    shown = "; ".join(f"{png}: {why}" for png, why in damaged[:3]) + (f"; and {n - 3} more" if n > 3 else "")
    line = f"cache: re-rendering {n} damaged entr{'y' if n == 1 else 'ies'}: {shown}"
    stream = stream or sys.stderr
    try:  # above a progress bar, which is redrawn below it
        from tqdm import tqdm

        tqdm.write(line, file=stream)
    except ImportError:
        print(line, file=stream, flush=True)


def _discard(png: Path) -> None:
    """Remove an entry's files, the PNG (the mark of a complete entry) first."""
    for f in (png, png.with_suffix(".npy"), png.with_suffix(".json")):
        try:
            f.unlink()
        except FileNotFoundError:
            pass
        except OSError as exc:  # the entry is written over by the re-render, or that fails in one line
            if f == png:
                raise UserError(f"{png}: a damaged cache entry that cannot be removed "
                                f"({exc.strerror or exc}): remove it by hand") from None


def cached_entry(cache_dir, key: str, shape: tuple[int, ...]) -> Path | None:
    """The PNG of the sound, complete cache entry ``key`` of a linear image of ``shape``, else None.

    A damaged entry (:func:`check_entry`) is removed and reported (:func:`report_damaged`), so that it is
    rendered again.
    """
    png = cached_png(cache_dir, key)
    if not png.is_file():
        return None
    why = check_entry(png, shape)
    if why is None:
        return png
    _discard(png)
    report_damaged([(png, why)])
    return None


def entry_image(png: Path, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """The linear image of the cache entry of ``png`` (returned by :func:`render_stimulus`, which checked it),
    read with its header checked first (:func:`data_schema.images.load_npy`)."""
    from data_schema.images import load_npy

    return load_npy(Path(png).with_suffix(".npy"), dtypes=("float32",), shape=shape)


def render_entry(request: FrameRequest) -> CacheEntry:
    """Render one frame and return its cache entry's content (runs on a Dask worker, or in process).

    The scene comes from the catalogue's per-process cache (built once per worker). A key that differs from
    the client's means the worker runs other renderer code: refused, so that no entry lands under a wrong key.
    """
    import io

    from .catalog import resolve
    from .registry import render

    sc = resolve(request.scene)
    key = stimulus_key(sc, request.renderer, request.params, request.width, request.height, request.gaze,
                       request.camera, request.backend)
    if key != request.key:
        raise UserError(f"this worker's renderers differ from the client's (cache key {key[:12]} instead of "
                        f"{request.key[:12]}): install the same studyapp on every worker")
    img, stats = render(sc, request.renderer, request.params, request.width, request.height, gaze=request.gaze,
                        camera=request.camera, backend=request.backend)
    image = np.ascontiguousarray(img, dtype=np.float32)
    buf = io.BytesIO()
    save_png(buf, image, sc.exposure)
    stats_json = json.dumps({"key": key, **jsonable_stats(stats), ENTRY_FIELD: entry_record(image, buf.getvalue())},
                            indent=1, sort_keys=True) + "\n"
    return CacheEntry(key, image, stats_json, buf.getvalue())


def remove_stale_cache_temporaries(cache_dir) -> int:
    """Remove the temporary files that a killed writer left in the cache's entry folders; return how many."""
    from data_schema.atomic import remove_stale_temporaries

    folders = (d for d in Path(cache_dir).glob("??") if re.fullmatch("[0-9a-f]{2}", d.name))  # cached_png's
    return sum(map(remove_stale_temporaries, folders))


def write_entry(cache_dir, entry: CacheEntry) -> Path:
    """Write a cache entry (each file atomically; the PNG last, so its presence marks a complete entry)."""
    from data_schema.atomic import write_bytes, write_text

    png = cached_png(cache_dir, entry.key)
    write_npy(png.with_suffix(".npy"), entry.image)
    write_text(png.with_suffix(".json"), entry.stats_json)
    write_bytes(png, entry.png)
    return png


def render_stimulus(scene, renderer: str, params: dict | None, width: int, height: int, gaze=None,
                    camera: dict | None = None, cache_dir: Path = Path("stimulus_cache"),
                    backend: str = "cpu") -> Path:
    """Render (or look up, :func:`cached_entry`: a damaged entry is rendered again) a stimulus; returns the path
    of its cached sRGB PNG.

    The linear float32 image is stored next to it as ``.npy`` and the stats as ``.json``. Bad input raises a
    one-line ValueError before anything is written.
    """
    request = frame_request(scene, renderer, params, width, height, gaze, camera, backend)
    png = cached_entry(cache_dir, request.key, (request.height, request.width, 3))
    if png is not None:
        return png
    return write_entry(cache_dir, render_entry(request))


def jsonable_stats(stats: dict) -> dict:
    """The stats record with per-pixel arrays (e.g. the lightcuts' ``fpsm``, ``spp``) summarised for JSON."""
    import numpy as np

    def conv(v):
        if isinstance(v, dict):
            return {k: conv(x) for k, x in v.items()}
        if isinstance(v, np.ndarray):
            if v.size == 1:
                return v.item()
            return {"shape": list(v.shape), "mean": float(np.mean(v)), "min": float(np.min(v)),
                    "max": float(np.max(v))}
        if isinstance(v, np.generic):
            return v.item()
        if isinstance(v, (list, tuple)):
            return [conv(x) for x in v]
        return v

    return conv(stats)
