"""YAML files from users (protocols, scenes, analysis plans): read with limits, line numbers and YAML 1.2 booleans.

A file is refused, in one line and well under a second, before it can cost memory or time:

- larger than :data:`MAX_BYTES` (1 MB; the shipped protocols are about 4 KB);
- nested deeper than :data:`MAX_DEPTH` levels (PyYAML's composer recurses: 10,000 nested brackets would end in
  a RecursionError);
- more than :data:`MAX_NODES` nodes *after alias expansion* (a nine-level "billion laughs" alias bomb is a
  file of a few hundred bytes that expands to 10^9 nodes).

The limits are checked on the event stream (libyaml's parser where available), counting every alias as the
size of the node it repeats, so a bomb is refused before anything is built. Then the document is composed
with every field's line recorded (:class:`LoadedYAML`), duplicate keys are errors instead of silently keeping
the last value, and only ``true``/``false`` are booleans (YAML 1.2), so ``yes``/``no`` answers stay strings.

Values are JSON's kinds only (mappings, lists, strings, numbers, booleans, null): a plain ``2024-05-01`` stays a
string (YAML 1.2 has no timestamps) and the tags ``!!binary``, ``!!timestamp``, ``!!set``, ``!!omap`` and
``!!pairs`` are refused. A scalar its tag cannot convert (``!!float abc``, ``!!int 0b102``, ``!!bool maybe``)
and an integer outside 64 bits (a 5000-digit ``!!int``, which Python would not even convert) are one line
``FILE:LINE: malformed YAML: ...`` too.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from .errors import UserError

MAX_BYTES = 1 << 20
MAX_DEPTH = 64
MAX_NODES = 100_000
#: Integers must fit in a signed 64-bit integer (what SQLite and numpy hold); longer literals are refused unread.
INT_BITS = 63
_MAX_INT_CHARS = 100
#: Tags whose values JSON (and so the schemas and the study database) cannot hold.
_REFUSED_TAGS = ("binary", "timestamp", "set", "omap", "pairs")


class YAMLFileError(UserError):
    """A YAML file that cannot be used; the message is one line ``FILE:LINE: FIELD: problem``."""


def _scalar_text(node) -> str:
    """A node's value for a message: at most 40 characters, its length said when cut."""
    value = node.value if isinstance(node, yaml.ScalarNode) else f"<{node.id}>"
    return repr(value) if len(value) <= 40 else f"{value[:37]!r}... ({len(value):,} characters)"


def _short_tag(tag: str) -> str:
    return tag.replace("tag:yaml.org,2002:", "!!")


class _Loader(yaml.SafeLoader):
    """SafeLoader with YAML 1.2 booleans (``yes``/``no``/``on``/``off`` stay strings) and JSON's kinds only."""

    def construct_object(self, node, deep=False):
        """Any value its tag's constructor cannot convert is a YAML error at the node's line, not a traceback."""
        try:
            return super().construct_object(node, deep)
        except yaml.YAMLError:
            raise
        except (ValueError, TypeError, KeyError, AttributeError, OverflowError, IndexError):
            kind = _short_tag(node.tag).lstrip("!")
            raise yaml.constructor.ConstructorError(
                None, None, f"{_short_tag(node.tag)} {_scalar_text(node)} is not a valid {kind}",
                node.start_mark) from None

    def construct_yaml_int(self, node):
        text = self.construct_scalar(node)
        if len(text) > _MAX_INT_CHARS:  # not converted at all: a huge literal costs time (sexagesimal) or fails
            raise yaml.constructor.ConstructorError(
                None, None, f"integer {_scalar_text(node)} is outside the 64-bit range", node.start_mark)
        value = super().construct_yaml_int(node)
        if not -(1 << INT_BITS) <= value < (1 << INT_BITS):
            raise yaml.constructor.ConstructorError(
                None, None, f"integer {_scalar_text(node)} is outside the 64-bit range", node.start_mark)
        return value

    def refuse_tag(self, node):
        raise yaml.constructor.ConstructorError(
            None, None, f"tag {_short_tag(node.tag)} is not allowed (only mappings, lists, strings, numbers, "
            "booleans and null)", node.start_mark)


_Loader.add_constructor("tag:yaml.org,2002:int", _Loader.construct_yaml_int)
for _tag in _REFUSED_TAGS:
    _Loader.add_constructor(f"tag:yaml.org,2002:{_tag}", _Loader.refuse_tag)
_Loader.yaml_implicit_resolvers = {k: [(tag, rx) for tag, rx in v
                                       if tag not in ("tag:yaml.org,2002:bool", "tag:yaml.org,2002:timestamp")]
                                   for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
_Loader.add_implicit_resolver("tag:yaml.org,2002:bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"),
                              list("tTfF"))
_EventLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def format_field(field: tuple) -> str:
    """``("design", "conditions", 2)`` -> ``design.conditions[2]``."""
    out = ""
    for part in field:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


@dataclass(frozen=True)
class LoadedYAML:
    """A parsed YAML document and the 1-based line of every field path (tuple of keys/indices)."""

    data: Any
    lines: dict[tuple, int]
    path: Path
    error_class: type = YAMLFileError

    def line_of(self, field: tuple) -> int:
        """Line of ``field`` or of its closest parent that has one (1 for the document)."""
        field = tuple(field)
        while field:
            if field in self.lines:
                return self.lines[field]
            field = field[:-1]
        return self.lines.get((), 1)

    def error(self, field: tuple, message: str) -> UserError:
        name = format_field(field)
        return self.error_class(f"{self.path}:{self.line_of(field)}: {name + ': ' if name else ''}{message}")


def _check_limits(text: str, path: Path, error_class: type) -> None:
    """Refuse a document deeper than MAX_DEPTH or larger than MAX_NODES nodes after alias expansion."""
    sizes: dict[str, int] = {}  # anchor -> expanded size of the node it names
    stack: list[list] = []  # open collections: [anchor, expanded size so far]
    expanded = 0

    def add(size: int, line: int) -> None:
        nonlocal expanded
        expanded += size
        if stack:
            stack[-1][1] += size
        if expanded > MAX_NODES:
            raise error_class(f"{path}:{line}: too many YAML nodes (more than {MAX_NODES:,} after expanding "
                              "aliases): refusing the file")

    try:
        events = list(_events(text))
    except yaml.YAMLError as exc:  # libyaml stops at its own depth limit (1000): say it as we do
        if "nesting depth" in str(exc):
            mark = getattr(exc, "problem_mark", None)
            raise error_class(f"{path}:{mark.line + 1 if mark else 1}: nested deeper than {MAX_DEPTH} levels: "
                              "refusing the file") from None
        raise
    for ev in events:
        line = ev.start_mark.line + 1 if ev.start_mark is not None else 1
        if isinstance(ev, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            if len(stack) >= MAX_DEPTH:
                raise error_class(f"{path}:{line}: nested deeper than {MAX_DEPTH} levels: refusing the file")
            add(1, line)
            stack.append([ev.anchor, 1])
        elif isinstance(ev, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            anchor, size = stack.pop()
            if stack:
                stack[-1][1] += size - 1  # the start counted 1 already
            if anchor:
                sizes[anchor] = size
        elif isinstance(ev, yaml.ScalarEvent):
            add(1, line)
            if ev.anchor:
                sizes[ev.anchor] = 1
        elif isinstance(ev, yaml.AliasEvent):
            add(sizes.get(ev.anchor, 1), line)


def _events(text: str):
    """The parse events, stopping at the first one past MAX_DEPTH (no need to parse the rest)."""
    depth = 0
    for ev in yaml.parse(text, Loader=_EventLoader):
        yield ev
        if isinstance(ev, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            depth += 1
            if depth > MAX_DEPTH:
                return
        elif isinstance(ev, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            depth -= 1


def _walk(node, path: tuple, lines: dict, file: Path, error_class: type) -> None:
    stack = [(node, path)]
    while stack:  # iterative: the depth is bounded, but no recursion is needed either
        node, path = stack.pop()
        lines.setdefault(path, node.start_mark.line + 1)
        if isinstance(node, yaml.MappingNode):
            seen = set()
            for knode, vnode in node.value:
                key = knode.value
                if key in seen:
                    raise error_class(f"{file}:{knode.start_mark.line + 1}: {format_field(path + (key,))}: "
                                      "duplicate key")
                seen.add(key)
                lines[path + (key,)] = knode.start_mark.line + 1
                stack.append((vnode, path + (key,)))
        elif isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                stack.append((item, path + (i,)))


def load_yaml(path, what: str = "YAML", error_class: type = YAMLFileError) -> LoadedYAML:
    """Read a user's YAML file within the limits above; every problem is one ``error_class`` line.

    Parameters
    ----------
    path : str or Path
    what : str
        What the file is ("protocol", "scene", "analysis plan"), for the messages.
    error_class : type
        The :class:`~data_schema.errors.UserError` subclass raised (and used by :meth:`LoadedYAML.error`).
    """
    from .atomic import input_file

    path = Path(path)
    try:
        size = path.stat().st_size
        if path.is_dir():
            raise error_class(f"{path}: is a folder, not a {what} file")
        input_file(path, f"{what} file", error_class)  # a FIFO would block read_text
        if size > MAX_BYTES:
            raise error_class(f"{path}: {what} file is {size / 1e6:.1f} MB, more than the {MAX_BYTES >> 20} MB "
                              "allowed: refusing to read it")
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise error_class(f"{path}: no such {what} file") from None
    except UnicodeDecodeError as exc:
        raise error_class(f"{path}: not UTF-8 text ({exc.reason})") from None
    except OSError as exc:
        raise error_class(f"{path}: cannot read the {what} file: {exc.strerror or exc}") from None
    try:
        _check_limits(text, path, error_class)
        node = yaml.compose(text, Loader=_Loader)
        data = yaml.load(text, Loader=_Loader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else 1
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise error_class(f"{path}:{line}: malformed YAML: {problem}") from None
    lines: dict[tuple, int] = {}
    if node is not None:
        _walk(node, (), lines, path, error_class)
    return LoadedYAML(data, lines, path, error_class)
