"""Shared by the benchmark scripts: replace one named section of docs/benchmarks.md atomically, and read peak
memory from ``/usr/bin/time -v``.

Each script owns the block between ``<!-- NAME:start -->`` and ``<!-- NAME:end -->``; other sections are kept.
"""

from __future__ import annotations

import os
import platform
import shlex
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def machine_line() -> str:
    """One line naming the machine the figures were measured on."""
    return (f"Machine: {os.cpu_count()} cores, {platform.processor() or platform.machine()}, "
            f"Python {platform.python_version()}.")


def command_line(script: str, argv: list[str]) -> str:
    """The shell command that reruns ``script`` with ``argv``, for the report: arguments a shell would split or
    drop (empty, spaces, quotes) are quoted, in double quotes where that is enough (easier to read)."""
    def quote(arg: str) -> str:
        if arg and shlex.quote(arg) == arg:
            return arg
        return f'"{arg}"' if not any(c in arg for c in '"$`\\!') else shlex.quote(arg)
    return " ".join(["python", script, *map(quote, argv)])


def peak_rss_mb(time_v_report: str) -> float:
    """The maximum resident set size (MB) in ``/usr/bin/time -v``'s report, NaN when it has none."""
    line = next((ln for ln in time_v_report.splitlines() if "Maximum resident set size" in ln), None)
    return int(line.split(":")[1]) / 1024.0 if line else float("nan")


def without_time_report(stderr: str) -> str:
    """A child's standard error without the report ``/usr/bin/time -v`` appends to it (which would bury the
    child's own last line, its error)."""
    cuts = [i for i in (stderr.find("Command exited with non-zero status"), stderr.find("\tCommand being timed:"))
            if i >= 0]
    return stderr[:min(cuts)].rstrip("\n") if cuts else stderr


def replace_section(path: str, name: str, lines: list[str]) -> None:
    """Write ``lines`` as the section ``name`` of the Markdown file ``path`` (appended if new)."""
    sys.path.insert(0, ROOT)
    from data_schema.atomic import write_text

    start, end = f"<!-- {name}:start -->", f"<!-- {name}:end -->"
    block = "\n".join([start, *lines, end]) + "\n"
    old = open(path, encoding="utf-8").read() if os.path.exists(path) else "# Benchmarks\n\n"
    if start in old:
        head, rest = old.split(start, 1)
        tail = rest.split(end, 1)[1].lstrip("\n")
        new = head + block + ("\n" + tail if tail else "")
    else:
        new = old.rstrip("\n") + "\n\n" + block
    write_text(path, new)
