"""Names that become path components: the one rule for condition, scene and participant names.

A condition name becomes a stimulus folder and a replay folder, a scene name a file or folder inside it; a
participant id is held to the same rule, so that any output named after it stays one plain file name. :func:`check_name` refuses, at validation, every name that would not
be one plain path component on Linux, macOS and Windows alike (``.``/``..``, separators, NUL and other control
characters, Windows' reserved characters and device names, a leading dot: hidden files and our temporary files
start with one); :func:`check_unique` two names that one case-insensitive file system (macOS, Windows) would
store as the same file. :func:`inside` is the last line of defence where a command builds a path from a name:
it proves that the path lies under its output folder before anything is written there.
"""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Iterable
from pathlib import Path, PurePosixPath, PureWindowsPath

from .errors import UserError

#: The longest allowed name, in characters (a name is one path component; most file systems allow 255 bytes).
MAX_NAME_CHARS = 100
#: The longest allowed name in UTF-8 bytes: a name plus a suffix such as ``.png`` stays under 255 bytes.
MAX_NAME_BYTES = 200
#: Characters Windows forbids in file names (besides the separators and control characters).
WINDOWS_RESERVED_CHARS = '<>:"|?*'
#: Windows' reserved device names: not a file name there, with any extension (``con.txt``), in any case.
WINDOWS_DEVICE_NAMES = frozenset({"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(1, 10)),
                                  *(f"LPT{i}" for i in range(1, 10))})
_DEVICE = re.compile(r"[^.]*")


def _problem(name) -> str | None:
    """Why ``name`` cannot be one path component, or None when it can."""
    if not isinstance(name, str):
        return f"is a {type(name).__name__}, not text"
    if not name:
        return "is empty"
    if name in (".", ".."):
        return "is a folder reference, not a name"
    if len(name) > MAX_NAME_CHARS:
        return f"is longer than {MAX_NAME_CHARS} characters"
    for ch in name:
        if ch in "/\\":
            return f"holds the path separator {ch!r}"
        cat = unicodedata.category(ch)
        if cat == "Cc":
            return f"holds the control character {ch!r}"
        if cat == "Cs":
            return f"holds the lone surrogate {ch!r} (not valid Unicode)"
        if ch in WINDOWS_RESERVED_CHARS:
            return f"holds {ch!r}, which Windows forbids in file names"
    if len(name.encode("utf-8")) > MAX_NAME_BYTES:
        return f"is longer than {MAX_NAME_BYTES} bytes in UTF-8"
    if name.startswith("."):
        return "starts with a dot (hidden files and temporary files do)"
    if name[-1] in ". ":
        return "ends in a dot or a space (Windows drops it)"
    if _DEVICE.match(name).group().rstrip(" ").upper() in WINDOWS_DEVICE_NAMES:
        return "is a device name on Windows (CON, PRN, AUX, NUL, COM1-9, LPT1-9, with any extension)"
    return None


def check_name(kind: str, name) -> str:
    """Return ``name`` if it can be one path component everywhere; else raise a one-line :class:`UserError`.

    Parameters
    ----------
    kind : str
        What the name names, for the message (``condition``, ``scene``, ``participant``).
    name : str
        The name.

    Raises
    ------
    UserError
        ``condition name '..': is a folder reference, not a name: choose another name``: empty, over
        :data:`MAX_NAME_CHARS` characters, ``.``/``..``, a leading dot, a separator (``/``, ``\\``), NUL or any
        control character, one of ``<>:"|?*``, a trailing dot or space, a Windows device name.
    """
    problem = _problem(name)
    if problem is not None:
        raise UserError(f"{kind} name {name!r}: {problem}: choose another name")
    return name


def name_key(name: str) -> str:
    """The key under which a case-insensitive file system stores ``name`` (NFC, case-folded)."""
    return unicodedata.normalize("NFC", unicodedata.normalize("NFC", name).casefold())


def check_unique(kind: str, names: Iterable[str]) -> None:
    """Refuse two ``names`` that are equal ignoring case and Unicode normalisation, naming both (the same name
    given twice is one name: a list's duplicates are the schema's to refuse).

    Raises
    ------
    UserError
        ``condition names 'GT' and 'gt' are the same file name on macOS and Windows (case is ignored there):
        rename one``.
    """
    seen: dict[str, str] = {}
    for name in names:
        key = name_key(name)
        if key in seen and seen[key] != name:
            raise UserError(f"{kind} names {seen[key]!r} and {name!r} are the same file name on macOS and Windows "
                            "(case and Unicode normalisation are ignored there): rename one")
        seen.setdefault(key, name)


def printable(path) -> str:
    """``path`` for a one-line message: control characters (a line break, NUL) escaped."""
    text = str(path)
    return text if text.isprintable() else repr(text)[1:-1]


def inside(folder, *parts) -> Path:
    """``Path(folder).joinpath(*parts)``, proved to lie under ``folder`` (resolved, symlinks included).

    Raises
    ------
    UserError
        ``<path>: would be written outside <folder>: refusing (name '..')`` for an absolute part, a ``..``
        component, a NUL, or a symlink inside ``folder`` that leads out of it.
    """
    base = Path(folder)
    texts = [str(p) for p in parts]
    for text in texts:
        pure = (PurePosixPath(text), PureWindowsPath(text))
        if "\0" in text or any(p.anchor or ".." in p.parts for p in pure):
            shown = printable(base / text.replace(chr(0), "?"))
            raise UserError(f"{shown}: would be written outside {printable(base)}: refusing (name {text!r})")
    path = base.joinpath(*texts)
    try:
        escaped = not path.resolve().is_relative_to(base.resolve())
    except (OSError, RuntimeError, ValueError):  # a symlink loop, a NUL in folder: not provably inside
        escaped = True
    if escaped:
        raise UserError(f"{printable(path)}: would be written outside {printable(base)}: refusing (name "
                        f"{texts[-1] if texts else ''!r})")
    return path
