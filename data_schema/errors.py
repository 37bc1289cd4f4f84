"""User errors: the one exception family every part of studyapp raises for bad input.

Bad input (a protocol, scene, log, option or file the user gave) raises :class:`UserError` or a subclass,
with a one-line message that names the problem and, where there is one, the way out. The CLI catches exactly
this family and prints ``studyapp: error: <message>`` with exit status 2; anything else is a bug and keeps its
traceback. ``UserError`` is a ``ValueError`` so that library callers who catch ``ValueError`` still do.

This module imports nothing, so the statistics (``import analysis``), the store and the renderers can all use it.
"""

from __future__ import annotations

EXIT_USAGE = 2


class UserError(ValueError):
    """Bad input; the message is one line naming the problem (and the file or option it came from)."""

    def __init__(self, message: str) -> None:
        # One line, always: a multi-line message from a library is cut to its first line here.
        text = str(message).strip()
        super().__init__(text.splitlines()[0] if text else type(self).__name__)


#: The CLI's own errors (bad options); the same family.
CLIError = UserError


def first_line(exc: BaseException) -> str:
    """The first line of ``exc``'s message (its type's name when it has none): a library's error in one line."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
