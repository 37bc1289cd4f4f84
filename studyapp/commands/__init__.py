"""Sub-commands of the ``studyapp`` CLI, one module per command group.

Each module defines ``register(subparsers, parser_class)`` which adds its sub-parsers and sets
``func=handler`` on them; a handler takes the parsed ``args`` and returns an exit status. Handlers raise
:class:`studyapp.errors.CLIError` (or ``ValueError``) for bad input, which the CLI prints as one line with
exit status 2. Modules must import heavy packages (numba, pyvista, psychopy, matplotlib) inside handlers,
never at module level, so that ``studyapp --help`` stays fast.

A module may also define ``demo_step(out_dir: pathlib.Path, progress) -> list[pathlib.Path]`` for the
end-to-end demo.
"""

import sys


def status(msg: str, prefix: str = "") -> None:
    """One overwritten status line on stderr (only on a terminal: logs and pipes stay clean)."""
    if sys.stderr.isatty():
        print(f"\r\033[K{prefix}{msg}"[:200], end="", file=sys.stderr, flush=True)


def end_status() -> None:
    """Clear the status line."""
    if sys.stderr.isatty():
        print("\r\033[K", end="", file=sys.stderr, flush=True)
