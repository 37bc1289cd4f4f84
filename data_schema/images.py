"""Image and array files read safely: the size is checked from the header before anything is decoded.

Every reader of a PNG or a ``.npy`` file (the stimulus cache, stimulus sets, the presenter, ``studyapp
quality``) opens it here, so that one limit holds everywhere: an image of more than :data:`MAX_IMAGE_PIXELS`
pixels (8192 x 8192, 67 M pixels: 0.8 GB as linear float32 RGB, twice that once a metric works in float64) is
refused in one line naming the limit, e.g. ``big.png: 13000x13000 pixels is over the limit of 8192x8192
(67 M pixels) for an image``, before a byte of it is decoded or allocated.

- PNG (any format Pillow reads): :func:`open_image` opens the file (Pillow reads only the header), checks its
  size, then decodes it if asked; Pillow's own decompression-bomb warning and error (at 89 M and 179 M pixels)
  become the same line, a damaged file ``cannot read image PATH: <reason>``.
- ``.npy``: :func:`read_npy_header` reads the header (``numpy.lib.format``: magic, then the version's header;
  no pickles) and checks the dtype, the shape and that the file holds every byte the header declares;
  :func:`load_npy` then reads the array (or maps it, ``mmap=True``).

Pillow is imported lazily (this package needs only NumPy).
"""

from __future__ import annotations

import contextlib
import math
import os
import struct
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import UserError, first_line

#: The largest image any reader decodes: 8192 x 8192 pixels (a stimulus at 8K, 7680 x 4320, is 33 M).
MAX_IMAGE_SIDE = 8192
MAX_IMAGE_PIXELS = MAX_IMAGE_SIDE * MAX_IMAGE_SIDE
#: Array dtypes that an image file may hold (``studyapp quality`` compares 8-bit, 16-bit and float images).
IMAGE_DTYPE_KINDS = "uif"
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


class ImageTooLarge(UserError):
    """An image over :data:`MAX_IMAGE_PIXELS`."""


def limit_text() -> str:
    return f"{MAX_IMAGE_SIDE}x{MAX_IMAGE_SIDE} ({MAX_IMAGE_PIXELS / 1e6:.0f} M pixels)"


def check_image_pixels(path, width: int, height: int) -> None:
    """Refuse an image of ``width`` x ``height`` pixels over :data:`MAX_IMAGE_PIXELS` (one line naming the limit)."""
    if width * height > MAX_IMAGE_PIXELS:
        raise ImageTooLarge(f"{path}: {width}x{height} pixels is over the limit of {limit_text()} for an image")


def _png_header_size(path) -> tuple[int, int] | None:
    """Width and height from a PNG's IHDR chunk (None if the file does not start like a PNG)."""
    with contextlib.suppress(OSError), open(path, "rb") as fh:
        head = fh.read(24)
        if len(head) == 24 and head[:8] == _PNG_SIGNATURE and head[12:16] == b"IHDR":
            return struct.unpack(">II", head[16:24])
    return None


@contextlib.contextmanager
def open_image(path, *, load: bool = False):
    """Open an image file with Pillow and yield it once its size, read from the header, is within the limit.

    ``load=True`` decodes it too (inside the check, so that a damaged file is this one line). Refused in one
    line: over :data:`MAX_IMAGE_PIXELS` (:class:`ImageTooLarge`, Pillow's decompression-bomb cases included),
    and ``cannot read image PATH: <reason>`` for a file that is missing, not an image, truncated or damaged.
    """
    from PIL import Image

    from .atomic import input_file

    input_file(path, "image file")  # a FIFO would block Pillow's open
    try:
        with warnings.catch_warnings():  # over 89 M pixels: over our limit too, refused below in one line
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            im = Image.open(path)
    except Image.DecompressionBombError:
        size = _png_header_size(path)
        if size is None:
            raise ImageTooLarge(f"{path}: more than {2 * (Image.MAX_IMAGE_PIXELS or 0) / 1e6:.0f} M pixels is "
                                f"over the limit of {limit_text()} for an image") from None
        check_image_pixels(path, *size)
        raise ImageTooLarge(f"{path}: {size[0]}x{size[1]} pixels is over Pillow's limit of "
                            f"{Image.MAX_IMAGE_PIXELS} pixels (Image.MAX_IMAGE_PIXELS) for an image") from None
    except (OSError, SyntaxError, ValueError) as exc:  # missing, not an image
        raise UserError(f"cannot read image {path}: {first_line(exc)}") from None
    with im:
        check_image_pixels(path, *im.size)
        if load:
            try:
                im.load()
            except (OSError, SyntaxError, ValueError) as exc:  # truncated, damaged
                raise UserError(f"cannot read image {path}: {first_line(exc)}") from None
        yield im


@dataclass(frozen=True)
class NpyHeader:
    """What a ``.npy`` file's header declares: ``offset`` is where the data begin."""

    shape: tuple[int, ...]
    dtype: np.dtype
    fortran_order: bool
    offset: int

    @property
    def nbytes(self) -> int:
        return math.prod(self.shape) * self.dtype.itemsize


def read_npy_header(path, *, dtypes: tuple[str, ...] | None = None,
                    shape: tuple[int, ...] | None = None) -> NpyHeader:
    """The header of the image array in ``path``, checked before any of the data are read.

    Refused in one line: not a ``.npy`` file; a dtype that is not numeric (``IMAGE_DTYPE_KINDS``) or not one of
    ``dtypes``; a shape other than ``(H, W)`` or ``(H, W, C)`` with C in 1..4, or other than ``shape`` when
    given; more than :data:`MAX_IMAGE_PIXELS` pixels; a file shorter or longer than the header declares.
    """
    from numpy.lib import format as npy_format

    from .atomic import input_file

    input_file(path, ".npy file")
    try:
        with open(path, "rb") as fh:
            version = npy_format.read_magic(fh)
            if version == (1, 0):
                dims, fortran, dtype = npy_format.read_array_header_1_0(fh)
            elif version == (2, 0):
                dims, fortran, dtype = npy_format.read_array_header_2_0(fh)
            else:
                raise ValueError(f".npy format version {version[0]}.{version[1]} is not supported")
            offset, size = fh.tell(), os.fstat(fh.fileno()).st_size
    except OSError as exc:
        raise UserError(f"cannot read image {path}: {(exc.strerror or first_line(exc)).lower()}") from None
    except (ValueError, SyntaxError, EOFError) as exc:  # numpy's message for a bad magic or header
        raise UserError(f"cannot read image {path}: not a .npy file ({first_line(exc)})") from None
    head = NpyHeader(tuple(int(n) for n in dims), np.dtype(dtype), bool(fortran), offset)
    if head.dtype.kind not in IMAGE_DTYPE_KINDS or head.dtype.fields is not None or head.dtype.subdtype:
        raise UserError(f"cannot read image {path}: dtype {head.dtype} is not an image's: use uint8, uint16 or float")
    if dtypes is not None and head.dtype.name not in dtypes:
        raise UserError(f"cannot read image {path}: dtype {head.dtype}, expected {' or '.join(dtypes)}")
    dims = head.shape
    if len(dims) not in (2, 3) or (len(dims) == 3 and not 1 <= dims[2] <= 4) or 0 in dims:
        raise UserError(f"cannot read image {path}: shape {dims} is not an image's: expected (H, W) or (H, W, C) "
                        "with C in 1..4")
    check_image_pixels(path, dims[1], dims[0])
    if shape is not None and dims != tuple(shape):
        raise UserError(f"cannot read image {path}: shape {dims}, expected {tuple(shape)}")
    if size != offset + head.nbytes:
        kind = "truncated" if size < offset + head.nbytes else "longer than its header declares"
        raise UserError(f"cannot read image {path}: {kind}: holds {size - offset} bytes of data, its header "
                        f"declares {head.nbytes}")
    return head


def load_npy(path, *, dtypes: tuple[str, ...] | None = None, shape: tuple[int, ...] | None = None,
             mmap: bool = False) -> np.ndarray:
    """The image array of a ``.npy`` file, its header checked first (:func:`read_npy_header`; no pickles).

    ``mmap=True`` maps the file read-only instead of reading it (for a pass over the data in bounded memory).
    """
    read_npy_header(path, dtypes=dtypes, shape=shape)
    try:
        return np.load(Path(path), mmap_mode="r" if mmap else None, allow_pickle=False)
    except (OSError, ValueError) as exc:  # changed since the header was read
        raise UserError(f"cannot read image {path}: {first_line(exc)}") from None
