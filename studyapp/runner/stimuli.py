"""Stimulus sets: where a protocol's stimuli live, building them (``prepare``), and synthetic sets.

Layout (the same for prepared sets and for folders a lab rendered elsewhere)::

    <root>/<CONDITION>/<SCENE>.png                     still image
    <root>/<CONDITION>/<SCENE>/frame_00000.png ...     sequence (round(duration_s * fps) frames)

``root`` is the protocol's ``stimuli_dir`` (``scale<F>`` below it for ``--scale F``); a ``folder`` condition
reads ``<folder>/<SCENE>.png`` or ``<folder>/<SCENE>/*.png`` (sorted) instead. Renderer conditions are built by
``renderers.stimuli.render_stimulus`` (with its content-addressed cache); ``derive`` conditions are made from
another condition's frames by a Gaussian blur and seeded noise, here.
"""

from __future__ import annotations

import hashlib
import math
import shlex
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from data_schema.atomic import STALE_TEMPORARY_S, atomic_path, real_folder, remove_stale_temporaries, sole_writer
from data_schema.names import inside, printable
from data_schema.errors import UserError
from data_schema.ranges import SCALE

from .camera import frame_camera
from .images import gaussian_blur, load_rgb, save_png
from .protocol import Protocol


@dataclass(frozen=True)
class Needed:
    """One (condition, scene) stimulus the protocol's schedules can show."""

    condition: str
    scene: str


def stimulus_root(protocol: Protocol, scale: float = 1.0, root: Path | None = None) -> Path:
    base = Path(root) if root is not None else protocol.stimuli_dir
    return base if scale == 1.0 else base / f"scale{scale:g}"


def needed_stimuli(protocol: Protocol) -> list[Needed]:
    """Every (condition, scene) a schedule of ``protocol`` may show, sources of derived conditions first."""
    want: list[Needed] = []
    if protocol.live:  # rendered during the trial: nothing to prepare
        return want

    def add(cond, scene):
        c = protocol.conditions[cond]
        if c.derive_from:
            add(c.derive_from, scene)
        n = Needed(cond, scene)
        if n not in want:
            want.append(n)

    for scene in protocol.scenes:
        for cond in protocol.shown_conditions:  # an adaptive design: every level of its ladder
            add(cond, scene)
        if protocol.reference:
            add(protocol.reference, scene)
        if protocol.catch and protocol.catch["kind"] == "degraded":
            add(protocol.catch["good"], scene)
            add(protocol.catch["bad"], scene)
    if protocol.practice:
        for cond in protocol.practice["conditions"]:
            add(cond, protocol.practice["scene"])
        if protocol.reference:  # shown before the practice (runner.schedule._practice)
            add(protocol.reference, protocol.practice["scene"])
    if protocol.ground_truth:  # what the simulated observer compares against
        for scene in protocol.scenes + ((protocol.practice["scene"],) if protocol.practice else ()):
            add(protocol.ground_truth, scene)
    return want


def frame_paths(protocol: Protocol, condition: str, scene: str, scale: float = 1.0,
                root: Path | None = None) -> tuple[Path, ...]:
    """The frame files of one stimulus (they may not exist yet)."""
    cond = protocol.conditions[condition]
    if cond.folder is not None:
        single = inside(cond.folder, f"{scene}.png")
        seq_dir = inside(cond.folder, scene)
        if seq_dir.is_dir():
            frames = tuple(sorted(seq_dir.glob("*.png")))
            return frames if frames else (seq_dir / "frame_00000.png",)
        return (single,)
    base = inside(stimulus_root(protocol, scale, root), condition)  # names are checked at validation; proved here
    if protocol.n_frames == 1:
        return (inside(base, f"{scene}.png"),)
    seq_dir = inside(base, scene)
    return tuple(seq_dir / f"frame_{i:05d}.png" for i in range(protocol.n_frames))


def missing_stimuli(protocol: Protocol, scale: float = 1.0, root: Path | None = None) -> list[tuple[Needed, Path]]:
    out = []
    for n in needed_stimuli(protocol):
        for f in frame_paths(protocol, n.condition, n.scene, scale, root):
            if not f.is_file():
                out.append((n, f))
                break
    return out


def split_missing(protocol: Protocol, missing: list[tuple[Needed, Path]],
                  allow_declared: bool) -> tuple[list[tuple[Needed, Path]], set[tuple[str, str]]]:
    """The missing sets a run cannot do without, and the (condition, scene) pairs it can.

    With ``allow_declared`` (``run --simulate``) the simulated observer needs no images of a condition that
    declares a ``quality`` (:mod:`studyapp.runner.observer`), except a folder condition: a lab's folder must be
    complete. Without it every missing set is needed.
    """
    blocking, declared = [], set()
    for need, path in missing:
        cond = protocol.conditions[need.condition]
        if allow_declared and cond.quality is not None and cond.folder is None:
            declared.add((need.condition, need.scene))
        else:
            blocking.append((need, path))
    return blocking, declared


def prepare_command(protocol: str, scale: float = 1.0, stimuli: str | None = None, full: bool = False) -> str:
    """The ``studyapp prepare`` command line that builds the stimulus set that ``validate``/``run`` with these
    options read (``protocol``: the argument as given, a file or a shipped protocol's name)."""
    parts = ["studyapp", "prepare", str(protocol)]
    if scale != 1.0:
        parts += ["--scale", repr(float(scale))]  # repr: the shortest text that reads back as the same float
    if stimuli:
        parts += ["--stimuli", str(stimuli)]
    return printable(shlex.join(parts + (["--full"] if full else [])))


def _names(missing: list[tuple[Needed, Path]], shown: int = 3) -> str:
    """``CONDITION/SCENE`` of the first ``shown`` sets, then how many more."""
    names = [f"{n.condition}/{n.scene}" for n, _ in missing]
    more = f" and {len(names) - shown} more" if len(names) > shown else ""
    return ", ".join(names[:shown]) + more


def _folder_files(protocol: Protocol, scenes: list[str]) -> str:
    """The file names a folder condition must hold for ``scenes`` (the first one or two, then how many)."""
    if protocol.n_frames == 1:
        names = [f"{s}.png" for s in scenes]
        shown = ", ".join(names[:2]) + (f" and {len(names) - 2} more" if len(names) > 2 else "")
        return f"{shown} (one PNG per scene)"
    last = f"frame_{protocol.n_frames - 1:05d}.png"
    more = f", and the same for {', '.join(scenes[1:3])}{' ...' if len(scenes) > 3 else ''}" if scenes[1:] else ""
    return (f"{scenes[0]}/frame_00000.png ... {scenes[0]}/{last} ({protocol.n_frames} PNG frames per scene, "
            f"read in name order{more})")


def missing_line(protocol: Protocol, missing: list[tuple[Needed, Path]], root: Path, command: str | None,
                 then: str = "") -> str:
    """One line about ``missing`` (from :func:`missing_stimuli`): for folder conditions, the folder their images
    must be put in and the expected file names; for the others, ``command`` that renders them (``then``: what
    else the user may do). ``root``: where the rendered sets live (:func:`stimulus_root`)."""
    folder = [(n, f) for n, f in missing if protocol.conditions[n.condition].folder is not None]
    rendered = [(n, f) for n, f in missing if protocol.conditions[n.condition].folder is None]
    parts = []
    if folder:
        scenes: dict[str, list[str]] = {}
        for n, _ in folder:
            scenes.setdefault(n.condition, []).append(n.scene)
        where = "; ".join(f"condition {c} reads a lab's own images from {printable(protocol.conditions[c].folder)}:"
                          f" put {_folder_files(protocol, s)} there" for c, s in scenes.items())
        parts.append(f"{len(folder)} stimulus set(s) of folder conditions missing ({_names(folder)}): {where} "
                     "(prepare renders only renderer and derived conditions)")
    if rendered:
        how = f": render them with `{command}`{then}" if command else ""
        parts.append(f"{len(rendered)} stimulus set(s) missing in {printable(root)} ({_names(rendered)}){how}")
    return "; ".join(parts)


def _seed_of(*parts) -> int:
    return int.from_bytes(hashlib.sha256("|".join(map(str, parts)).encode()).digest()[:8], "little")


def degrade(rgb: np.ndarray, blur_sigma_px: float, noise: float, seed: int) -> np.ndarray:
    """A strongly degraded copy: Gaussian blur then additive Gaussian noise of SD ``noise``, clipped to [0, 1]."""
    out = gaussian_blur(np.asarray(rgb, dtype=np.float32), blur_sigma_px)
    if noise > 0:
        out = out + np.random.default_rng(seed).normal(0.0, noise, out.shape).astype(np.float32)
    return np.clip(out, 0.0, 1.0)


def make_derived(protocol: Protocol, need: Needed, scale: float = 1.0, root: Path | None = None,
                 max_frames: int | None = None) -> list[Path]:
    """Build a ``derive`` condition's frames from its source condition's frames (frames past ``max_frames``
    repeat the last one built, as in :func:`write_synthetic_stimuli`)."""
    cond = protocol.conditions[need.condition]
    src = frame_paths(protocol, cond.derive_from, need.scene, scale, root)
    dst = frame_paths(protocol, need.condition, need.scene, scale, root)
    if len(src) != len(dst):
        dst = tuple(dst[0].parent / f"frame_{i:05d}.png" for i in range(len(src))) if len(src) > 1 else dst
    out = []
    sigma = cond.blur_sigma_px * scale
    for i, (s, d) in enumerate(zip(src, dst)):
        if max_frames is not None and i >= max_frames:
            with atomic_path(d) as tmp:
                shutil.copyfile(out[-1], tmp)
            out.append(d)
            continue
        out.append(save_png(d, degrade(load_rgb(s), sigma, cond.noise, _seed_of(need.condition, need.scene, i))))
    return out


# -- prepare -----------------------------------------------------------------------------------------------
def render_function():
    """``renderers.stimuli.render_stimulus`` or a ValueError saying why it is not usable here."""
    try:
        from renderers.stimuli import render_stimulus
    except Exception as exc:  # noqa: BLE001 - any import failure: the renderers are not usable
        raise UserError(f"the renderers are not usable here ({type(exc).__name__}: {exc}): render the stimuli "
                         "elsewhere and use folder conditions, or use run --simulate (declared qualities)") from None
    return render_stimulus


def prepare(protocol: Protocol, scale: float = 1.0, root: Path | None = None, cache_dir: Path | None = None,
            progress: Callable[[int, int, float], None] | None = None, render=None, cluster=None) -> dict:
    """Build every missing stimulus of ``protocol``: render renderer conditions, derive degraded ones.

    Every missing frame of a renderer condition is one task (:func:`studyapp.cluster.render_frames`) on
    ``cluster`` (a :class:`~studyapp.cluster.ClusterSpec`; default: in this process), rendered into the
    content-addressed cache (a damaged entry is rendered again and reported: :func:`renderers.stimuli.cached_entry`)
    and copied into the stimulus folder atomically as it arrives, so a killed ``prepare`` resumes where it stopped
    (first removing the temporary files that a kill left mid-copy in the folders it writes:
    :func:`~data_schema.atomic.remove_stale_temporaries`). ``render`` replaces
    :func:`renderers.stimuli.render_stimulus` in process (tests). ``progress(done_frames, total_frames,
    seconds_left)`` is called after every frame; the time left is the frames left times the wall time per frame
    so far. Returns counts (``removed``: stale temporary files) and the elapsed time.
    """
    from studyapp.cluster import SERIAL

    SCALE.check("--scale", scale)
    geometry = protocol.render_geometry(scale)
    root_dir = stimulus_root(protocol, scale, root)
    cache = Path(cache_dir) if cache_dir is not None else root_dir.parent / ".cache"
    real_folder(root_dir, "--stimuli")  # /dev/null, a FIFO, a file: refused before anything is rendered
    real_folder(cache, "--cache")
    folder = [(n, f) for n, f in missing_stimuli(protocol, scale, root) if protocol.conditions[n.condition].folder]
    if folder:  # a lab's own images: where to put them, before anything is rendered
        raise UserError(missing_line(protocol, folder, root_dir, None))
    todo = []
    for need in needed_stimuli(protocol):
        cond = protocol.conditions[need.condition]
        frames = frame_paths(protocol, need.condition, need.scene, scale, root)
        if not all(f.is_file() for f in frames):
            todo.append((need, cond, frames))
    if not todo:
        return {"frames": 0, "rendered": 0, "cached": 0, "removed": 0, "seconds": 0.0}
    with sole_writer(root_dir, "prepare") as alone:  # a second prepare of this set is refused in one line
        # Temporary files in these folders were left by a killed prepare (with the lock, any age is stale).
        folders = {f.parent for _, _, frames in todo for f in frames}
        removed = sum(remove_stale_temporaries(d, 0.0 if alone else STALE_TEMPORARY_S) for d in folders)
        res = _build(protocol, todo, geometry, scale, root, cache, cluster or SERIAL, render, progress)
    return {**res, "removed": removed + res["removed"]}


def _build(protocol: Protocol, todo, geometry, scale: float, root, cache: Path, spec, render, progress) -> dict:
    """Render and derive the frames of ``todo`` (:func:`prepare`'s list of incomplete stimuli)."""
    from studyapp.cluster import render_frames

    total = sum(len(fr) for _, _, fr in todo)
    jobs, targets = [], []
    for need, cond, frames in todo:
        if cond.renderer:
            for i, dst in enumerate(frames):
                if dst.is_file():
                    continue
                jobs.append((f"condition {need.condition}, scene {need.scene}, frame {i}",
                             {"scene": protocol.scene_ref(need.scene), "renderer": cond.renderer,
                              "params": dict(cond.params), "width": geometry.width, "height": geometry.height,
                              "gaze": geometry.gaze, "camera": frame_camera(protocol, need.scene, i),
                              "backend": protocol.backend_of(need.condition)}))
                targets.append(dst)
    if jobs and render is None:
        render = render_function()  # one line if the renderers are not usable here
    t0 = time.perf_counter()
    count = {"done": total - len(jobs) - sum(len(fr) for _, c, fr in todo if not c.renderer)}

    def copied(i, png):
        dst = targets[i]
        dst.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(dst) as tmp:
            shutil.copyfile(png, tmp)
        count["done"] += 1

    def rendered(done, n, left):
        if progress:
            progress(count["done"], total, left)

    res = render_frames(jobs, cache, spec, copied, rendered, render=render if spec.in_process else None)
    for need, cond, frames in todo:
        if not cond.renderer:
            make_derived(protocol, need, scale, root)
            count["done"] += len(frames)
            if progress:
                progress(count["done"], total, 0.0)
    return {"frames": total, "rendered": res["rendered"], "cached": res["cached"], "removed": res["removed"],
            "seconds": time.perf_counter() - t0}


# -- synthetic stimulus sets (demo, tests, dry runs without renderers) --------------------------------------
def synthetic_scene(width: int, height: int, scene: str, frame: int = 0) -> np.ndarray:
    """A procedural 'ground truth' image with fine detail everywhere (gratings, checks, edges), RGB in [0, 1]."""
    rng = np.random.default_rng(_seed_of("scene", scene))
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    x = x + 1.5 * frame
    img = np.zeros((height, width, 3), dtype=np.float32)
    for c in range(3):
        f1, f2 = rng.uniform(0.05, 0.35, 2)
        th = rng.uniform(0, np.pi)
        img[..., c] = 0.5 + 0.22 * np.sin(f1 * (x * np.cos(th) + y * np.sin(th))) \
            + 0.12 * np.sin(f2 * (x * np.sin(th) - y * np.cos(th)))
    check = ((x // max(2, width // 40) + y // max(2, width // 40)) % 2).astype(np.float32)
    img += 0.15 * (check[..., None] - 0.5) * rng.uniform(0.5, 1.0, 3).astype(np.float32)
    return np.clip(img, 0.0, 1.0)


def foveated_degrade(rgb: np.ndarray, ecc: np.ndarray, quality: float, seed: int) -> np.ndarray:
    """Stand-in for a foveated renderer of declared ``quality`` in [0, 1]: blur and noise that grow with
    eccentricity, ``w(e) = min(1, e / 10 deg)``, scaled by ``1 - quality`` (quality 1 returns the input)."""
    k = 1.0 - float(quality)
    if k <= 0:
        return rgb
    w = np.minimum(1.0, ecc / 10.0).astype(np.float32)[..., None]
    blurred = gaussian_blur(rgb, 0.5 + 4.0 * k)
    noise = np.random.default_rng(seed).normal(0.0, 0.12 * k, rgb.shape).astype(np.float32)
    mix = np.clip(0.25 * k + w * (0.3 + k), 0.0, 1.0)
    return np.clip(rgb * (1 - mix) + blurred * mix + noise * (0.2 + w), 0.0, 1.0)


def write_synthetic_stimuli(protocol: Protocol, scale: float = 1.0, root: Path | None = None,
                            max_frames: int | None = None) -> Path:
    """Write a synthetic stimulus set for every stimulus the protocol needs (no renderer involved).

    The ground truth of a scene is :func:`synthetic_scene`; a renderer condition is :func:`foveated_degrade`
    of it at the condition's declared ``quality`` q (1.0 if none is declared), with the difference from the
    ground truth scaled so that the simulated observer measures the impairment it would assume for the declared
    quality, ``D = 5 (1 - q)`` JND (see :mod:`studyapp.runner.observer`): images and declared qualities then
    tell the same story. A derived condition is made from its source as :func:`prepare` would; folder
    conditions (a lab's own images) are left alone. Sequences get ``max_frames`` frames at most (the files are
    named as the protocol expects; later frames repeat the last one).
    """
    from .observer import DECLARED_SCALE_JND, foveated_difference

    geometry = protocol.render_geometry(scale)
    ecc = geometry.eccentricity_map()
    jnd = float(protocol.simulation["jnd"])
    luma = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)

    def calibrated(gt, img, q):
        target = jnd * DECLARED_SCALE_JND * (1.0 - q)
        for _ in range(3):  # the clip to [0, 1] shrinks the difference a little: repeat
            d = foveated_difference(img @ luma, gt @ luma, ecc)
            if d <= 0 or abs(d - target) <= 0.01 * target:
                break
            img = np.clip(gt + (img - gt) * (target / d), 0.0, 1.0)
        return img

    base = stimulus_root(protocol, scale, root)
    for need in needed_stimuli(protocol):
        cond = protocol.conditions[need.condition]
        frames = frame_paths(protocol, need.condition, need.scene, scale, root)
        if cond.folder is not None:  # a lab's own images: never overwritten
            continue
        if cond.derive_from:
            make_derived(protocol, need, scale, root, max_frames)
            continue
        q = 1.0 if cond.quality is None else cond.quality
        for i, f in enumerate(frames):
            j = i if max_frames is None else min(i, max_frames - 1)
            if j < i:
                with atomic_path(f) as tmp:
                    shutil.copyfile(frames[j], tmp)
                continue
            gt = synthetic_scene(geometry.width, geometry.height, need.scene, j)
            save_png(f, calibrated(gt, foveated_degrade(gt, ecc, q, _seed_of(need.condition, need.scene, j)), q))
    return base
