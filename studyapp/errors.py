"""Errors every part of studyapp reports the same way."""

from __future__ import annotations


class CLIError(Exception):
    """Bad input (protocol, scene, log, option): the CLI prints it as one line and exits with status 2."""


EXIT_USAGE = 2
