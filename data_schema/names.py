"""Names that become path components (minimal stand-in: helper H1 writes the full module)."""

from __future__ import annotations

from pathlib import Path, PurePath

from .errors import UserError


def inside(folder, *parts) -> Path:
    """``folder / parts...``, proved to lie under ``folder`` (no absolute part, no ``..``), else UserError."""
    folder = Path(folder)
    for part in parts:
        p = PurePath(str(part))
        if p.is_absolute() or ".." in p.parts or "\x00" in str(part):
            raise UserError(f"{part!r} is not a name inside {folder}: refused to write there")
    result = folder.joinpath(*map(str, parts))
    if not result.resolve().is_relative_to(folder.resolve()):
        raise UserError(f"{result}: lies outside {folder}: refused to write there")
    return result
