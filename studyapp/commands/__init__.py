"""Sub-commands of the ``studyapp`` CLI, one module per command group.

Each module defines ``register(subparsers, parser_class)`` which adds its sub-parsers and sets
``func=handler`` on them; a handler takes the parsed ``args`` and returns an exit status. Handlers raise
:class:`data_schema.errors.UserError` for bad input, which the CLI prints as one line with exit status 2
(any other exception is a bug and keeps its traceback). A command whose interruption (Ctrl-C, SIGTERM) leaves
something worth continuing sets ``interrupted_hint="..."`` too (``studyapp.cli.interrupted_hint``; the default
says nothing was written). Modules must import heavy packages (numba, pyvista, psychopy, matplotlib) inside handlers,
never at module level, so that ``studyapp --help`` stays fast.

Progress is shown through :mod:`studyapp.progress` only (re-exported here as ``status``/``end_status``).

A module may also define ``demo_step(out_dir: pathlib.Path, progress) -> list[pathlib.Path]`` for the
end-to-end demo.
"""

from studyapp.progress import end_status, status

__all__ = ["end_status", "status"]
