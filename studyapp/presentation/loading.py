"""Stimulus loading: frame files decoded (in the background) and uploaded into textures the window draws.

The decoding runs on two threads (PIL releases the GIL); the upload runs on the window's thread (OpenGL's).
PsychoPy and pyglet are imported lazily, as in the rest of the presentation layer.
"""

from __future__ import annotations

import ctypes
import time
from pathlib import Path

import numpy as np

from data_schema.geometry import Placement

from ._texture import TextureRef
from .base import PresentationError, TrialDisplay
from .trial_logic import validate_trial


def decode_image(path: Path):
    """Open and fully decode an image file into a PIL image in ``RGB`` (or ``RGBA``) mode (its size checked from
    the header first: :func:`data_schema.images.open_image`)."""
    from data_schema.images import open_image

    try:
        with open_image(path, load=True) as im:
            return im if im.mode in ("RGB", "RGBA") else im.convert("RGB")
    except ValueError as exc:  # one line naming the file (a UserError)
        raise PresentationError(str(exc).replace("cannot read image", "cannot read stimulus frame", 1)) from None


def texture_stim(win, visual, size: tuple[float, float], pos: tuple[float, float], width: int, height: int,
                 data: np.ndarray | None = None, rgba: bool = False, nearest: bool = False):
    """A new ImageStim (``pix`` units, ``size`` and ``pos``) drawing a ``width`` x ``height`` texture uploaded
    here as it is (``data``: rows top first, 8 bits per channel; None: allocated only, filled later with
    :func:`update_texture`), no mipmaps, clamped edges, nearest or linear sampling. This skips the flip, RGBA
    conversion and mipmap generation that ``ImageStim(image=...)`` does, which is most of its cost for a large
    stimulus (see docs/benchmarks.md, section presentation)."""
    from pyglet import gl

    stim = visual.ImageStim(win, image=None, units="pix", size=size, pos=pos)
    filt = gl.GL_NEAREST if nearest else gl.GL_LINEAR
    fmt = gl.GL_RGBA if rgba else gl.GL_RGB
    gl.glBindTexture(gl.GL_TEXTURE_2D, stim._texID)
    for param, value in ((gl.GL_TEXTURE_MIN_FILTER, filt), (gl.GL_TEXTURE_MAG_FILTER, filt),
                         (gl.GL_TEXTURE_WRAP_S, gl.GL_CLAMP_TO_EDGE),
                         (gl.GL_TEXTURE_WRAP_T, gl.GL_CLAMP_TO_EDGE), (gl.GL_TEXTURE_MAX_LEVEL, 0)):
        gl.glTexParameteri(gl.GL_TEXTURE_2D, param, value)
    gl.glPixelStorei(gl.GL_UNPACK_ALIGNMENT, 1)
    pixels = None if data is None else data.ctypes.data_as(ctypes.POINTER(ctypes.c_ubyte))
    gl.glTexImage2D(gl.GL_TEXTURE_2D, 0, fmt, width, height, 0, fmt, gl.GL_UNSIGNED_BYTE, pixels)
    gl.glBindTexture(gl.GL_TEXTURE_2D, 0)
    stim.image = TextureRef(stim._texID)  # draw this texture as a top-row-first RGB image (no recolouring)
    return stim


def update_texture(stim, rgb8: np.ndarray) -> None:
    """Replace the texels of ``stim``'s RGB texture (made by :func:`texture_stim`) with ``rgb8`` (H, W, 3)."""
    from pyglet import gl

    data = np.ascontiguousarray(rgb8)
    gl.glBindTexture(gl.GL_TEXTURE_2D, stim._texID)
    gl.glPixelStorei(gl.GL_UNPACK_ALIGNMENT, 1)
    gl.glTexSubImage2D(gl.GL_TEXTURE_2D, 0, 0, 0, data.shape[1], data.shape[0], gl.GL_RGB,
                       gl.GL_UNSIGNED_BYTE, data.ctypes.data_as(ctypes.POINTER(ctypes.c_ubyte)))
    gl.glBindTexture(gl.GL_TEXTURE_2D, 0)


def release_stim(stim) -> None:
    """Free ``stim``'s GPU texture now. ImageStims sit in reference cycles, so waiting for the garbage
    collector would hold tens of MB per large stimulus; the ids are then removed so that ``__del__`` cannot delete a
    texture name that OpenGL has meanwhile handed to a new stimulus."""
    from pyglet import gl

    for attr in ("_texID", "_maskID"):
        if hasattr(stim, attr):
            gl.glDeleteTextures(1, ctypes.byref(getattr(stim, attr)))
            delattr(stim, attr)
    if hasattr(stim, "_pixbuffID"):
        gl.glDeleteBuffers(1, ctypes.byref(stim._pixbuffID))
        del stim._pixbuffID


class LoadedTrial:
    """A trial's stimuli decoded into textures: ``frames[i]`` is the list of ImageStims of stimulus ``i``."""

    def __init__(self, trial: TrialDisplay, frames: list[list], placements: list[Placement], load_s: float):
        self.trial = trial
        self.frames = frames
        self.placements = placements
        self.load_s = load_s

    def release(self) -> None:
        """Free the GPU textures now (:func:`release_stim`)."""
        for seq in self.frames:
            for stim in seq:
                release_stim(stim)
        self.frames = []


class StimulusLoader:
    """Decodes trials' frame files (in the background with :meth:`prefetch`) and uploads them into the window
    (:meth:`load`); holds at most one trial loaded ahead (:meth:`preload`, :meth:`take`)."""

    def __init__(self):
        self.win = None
        self.visual = None
        self._loaded: dict[int, LoadedTrial] = {}
        self._prefetched: dict[int, list] = {}  # trial index -> futures of decoded frames, in order
        self._pool = None

    def attach(self, win, visual) -> None:
        """The window to upload into and PsychoPy's ``visual`` module."""
        self.win, self.visual = win, visual

    def load_image_stim(self, path: Path, placement: Placement | None = None):
        """Decode ``path`` and upload it (:meth:`image_stim`); return ``(stim, placement)``."""
        return self.image_stim(decode_image(path), placement, name=str(path))

    def image_stim(self, im, placement: Placement | None = None, name: str = "image"):
        """Upload a decoded PIL image (``RGB`` or ``RGBA``) into a new ImageStim placed by ``placement`` (fit
        to the window if None); return ``(stim, placement)``.

        The rows are uploaded as they are (:func:`texture_stim`) with nearest-texel sampling at ``scale = 1``,
        so the window shows the file's pixel values unchanged.
        """
        w, h = im.size
        if placement is None:
            ww, wh = (int(v) for v in self.win.size)
            placement = Placement.fit(ww, wh, w, h)
        elif (w, h) != (placement.img_w, placement.img_h):
            raise PresentationError(
                f"{name}: frame size {w}x{h} differs from the sequence's first frame "
                f"{placement.img_w}x{placement.img_h}"
            )
        stim = texture_stim(self.win, self.visual, placement.size, placement.centre_pix, w, h, np.asarray(im),
                            rgba=im.mode == "RGBA", nearest=placement.scale == 1.0)
        return stim, placement

    def _decoder(self):
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="studyapp-decode")
        return self._pool

    def prefetch(self, trial: TrialDisplay) -> None:
        """Start decoding ``trial``'s frame files in the background; at most two trials are kept prefetched
        (the oldest is dropped)."""
        validate_trial(trial)
        if trial.index in self._prefetched or trial.index in self._loaded:
            return
        pool = self._decoder()
        self._prefetched[trial.index] = [
            pool.submit(decode_image, Path(f)) for s in trial.stimuli for f in s.frames
        ]
        while len(self._prefetched) > 2:
            for fut in self._prefetched.pop(next(iter(self._prefetched))):
                fut.cancel()

    def load(self, trial: TrialDisplay) -> LoadedTrial:
        """Decode every frame (two threads: PIL releases the GIL while decoding, or already done by
        :meth:`prefetch`) and upload them in order on this thread (OpenGL's)."""
        t0 = time.perf_counter()
        frames, placements = [], []
        if trial.stimuli and trial.stimuli[0].live is not None:  # rendered during the trial
            return LoadedTrial(trial, [], [], 0.0)
        decoded = iter(
            self._prefetched.pop(trial.index, None)
            or [self._decoder().submit(decode_image, Path(f)) for s in trial.stimuli for f in s.frames]
        )
        for s in trial.stimuli:
            seq, placement = [], None
            for f in s.frames:
                stim, placement = self.image_stim(next(decoded).result(), placement, name=str(f))
                seq.append(stim)
            frames.append(seq)
            placements.append(placement)
        return LoadedTrial(trial, frames, placements, time.perf_counter() - t0)

    def is_loaded(self, index: int) -> bool:
        return index in self._loaded

    def preload(self, trial: TrialDisplay) -> None:
        """Load ``trial`` now and keep it (any other loaded trial is released)."""
        self.release_all()
        self._loaded = {trial.index: self.load(trial)}

    def take(self, index: int) -> LoadedTrial | None:
        """The trial loaded by :meth:`preload`, handed over (None if it was not)."""
        return self._loaded.pop(index, None)

    def release_all(self) -> None:
        for item in self._loaded.values():
            item.release()
        self._loaded.clear()

    def close(self) -> None:
        """Release the textures, cancel the decoding, stop the threads."""
        self.release_all()
        for futures in self._prefetched.values():
            for fut in futures:
                fut.cancel()
        self._prefetched.clear()
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
