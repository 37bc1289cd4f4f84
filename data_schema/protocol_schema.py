"""Protocol files: YAML read with line numbers and checked against ``protocol.schema.json``.

The schema is published as JSON Schema (draft 2020-12) so that editors can complete and check protocol files;
this module implements the subset of JSON Schema the schema uses (type, enum, const, properties, required,
additionalProperties, propertyNames, items, min/maxItems, uniqueItems, minProperties, minimum, maximum,
exclusiveMinimum, exclusiveMaximum, minLength, maxLength, pattern, $ref into ``$defs``) with no dependency
beyond PyYAML. Every error names the file, the line and the field::

    protocols/x.yaml:14: design.repetitions: 0 is below the minimum 1

YAML is read with YAML 1.2 booleans (only ``true``/``false``), so answers such as ``yes``/``no`` stay strings,
and duplicate keys are errors instead of silently keeping the last value.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from .errors import UserError

SCHEMA_PATH = Path(__file__).with_name("protocol.schema.json")


class ProtocolError(UserError):
    """A protocol that cannot be used; the message is one line ``FILE:LINE: FIELD: problem``."""


class _Loader(yaml.SafeLoader):
    """SafeLoader with YAML 1.2 booleans: ``yes``/``no``/``on``/``off`` stay strings."""


_Loader.yaml_implicit_resolvers = {k: [(tag, rx) for tag, rx in v if tag != "tag:yaml.org,2002:bool"]
                                   for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
_Loader.add_implicit_resolver("tag:yaml.org,2002:bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"),
                              list("tTfF"))


@dataclass(frozen=True)
class LoadedYAML:
    """A parsed YAML document and the 1-based line of every field path (tuple of keys/indices)."""

    data: Any
    lines: dict[tuple, int]
    path: Path

    def line_of(self, field: tuple) -> int:
        """Line of ``field`` or of its closest parent that has one (1 for the document)."""
        field = tuple(field)
        while field:
            if field in self.lines:
                return self.lines[field]
            field = field[:-1]
        return self.lines.get((), 1)

    def error(self, field: tuple, message: str) -> ProtocolError:
        name = format_field(field)
        return ProtocolError(f"{self.path}:{self.line_of(field)}: {name + ': ' if name else ''}{message}")


def format_field(field: tuple) -> str:
    """``("design", "conditions", 2)`` -> ``design.conditions[2]``."""
    out = ""
    for part in field:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _walk(node, path: tuple, lines: dict, file: Path) -> None:
    lines[path] = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        seen = set()
        for knode, vnode in node.value:
            key = knode.value
            if key in seen:
                raise ProtocolError(f"{file}:{knode.start_mark.line + 1}: {format_field(path + (key,))}: "
                                    "duplicate key")
            seen.add(key)
            _walk(vnode, path + (key,), lines, file)
            lines[path + (key,)] = knode.start_mark.line + 1
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _walk(item, path + (i,), lines, file)


def load_yaml(path) -> LoadedYAML:
    """Read a YAML file; syntax errors become :class:`ProtocolError` with file and line."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ProtocolError(f"{path}: no such protocol file") from None
    except UnicodeDecodeError as exc:
        raise ProtocolError(f"{path}: not UTF-8 text ({exc.reason})") from None
    try:
        node = yaml.compose(text, Loader=_Loader)
        data = yaml.load(text, Loader=_Loader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else 1
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ProtocolError(f"{path}:{line}: malformed YAML: {problem}") from None
    lines: dict[tuple, int] = {}
    if node is not None:
        _walk(node, (), lines, path)
    return LoadedYAML(data, lines, path)


def load_schema() -> dict:
    """The protocol JSON Schema as a dict."""
    return json.loads(SCHEMA_PATH.read_text(encoding="utf-8"))


_TYPES = {
    "object": lambda v: isinstance(v, dict),
    "array": lambda v: isinstance(v, list),
    "string": lambda v: isinstance(v, str),
    "integer": lambda v: isinstance(v, int) and not isinstance(v, bool),
    "number": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool),
    "boolean": lambda v: isinstance(v, bool),
    "null": lambda v: v is None,
}


def _describe(value) -> str:
    text = json.dumps(value, default=str) if not isinstance(value, str) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _same(a, b) -> bool:
    """JSON equality: ``True`` is not ``1``."""
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b
    return type(a) is type(b) and a == b or (isinstance(a, (int, float)) and isinstance(b, (int, float)) and a == b)


def schema_errors(instance, schema: dict, root: dict | None = None, field: tuple = ()):
    """Yield ``(field, message)`` for every violation of ``schema`` (the subset listed in the module doc)."""
    root = schema if root is None else root
    if "$ref" in schema:
        ref = schema["$ref"]
        if not ref.startswith("#/$defs/"):
            raise ValueError(f"unsupported $ref {ref!r}")
        yield from schema_errors(instance, root["$defs"][ref[len("#/$defs/"):]], root, field)
        return
    if "enum" in schema and not any(_same(instance, e) for e in schema["enum"]):
        yield field, f"{_describe(instance)} is not one of {', '.join(map(str, schema['enum']))}"
        return
    typ = schema.get("type")
    if typ is not None:
        types = typ if isinstance(typ, list) else [typ]
        if not any(_TYPES[t](instance) for t in types):
            yield field, f"{_describe(instance)} is not of type {' or '.join(types)}"
            return
    if isinstance(instance, (int, float)) and not isinstance(instance, bool):
        if isinstance(instance, float) and not math.isfinite(instance):
            yield field, f"{instance} is not a finite number"
        if "minimum" in schema and instance < schema["minimum"]:
            yield field, f"{instance} is below the minimum {schema['minimum']}"
        if "maximum" in schema and instance > schema["maximum"]:
            yield field, f"{instance} is above the maximum {schema['maximum']}"
        if "exclusiveMinimum" in schema and instance <= schema["exclusiveMinimum"]:
            yield field, f"{instance} must be greater than {schema['exclusiveMinimum']}"
        if "exclusiveMaximum" in schema and instance >= schema["exclusiveMaximum"]:
            yield field, f"{instance} must be less than {schema['exclusiveMaximum']}"
    if isinstance(instance, str):
        if "minLength" in schema and len(instance) < schema["minLength"]:
            yield field, "must not be empty" if schema["minLength"] == 1 else \
                f"shorter than {schema['minLength']} characters"
        if "maxLength" in schema and len(instance) > schema["maxLength"]:
            yield field, f"longer than {schema['maxLength']} characters"
        if "pattern" in schema and not re.search(schema["pattern"], instance):
            yield field, f"{_describe(instance)} does not match {schema['pattern']}"
    if isinstance(instance, list):
        if "minItems" in schema and len(instance) < schema["minItems"]:
            yield field, f"needs at least {schema['minItems']} item(s), has {len(instance)}"
        if "maxItems" in schema and len(instance) > schema["maxItems"]:
            yield field, f"allows at most {schema['maxItems']} item(s), has {len(instance)}"
        if schema.get("uniqueItems"):
            seen = []
            for i, item in enumerate(instance):
                if item in seen:
                    yield field + (i,), f"{_describe(item)} is listed twice"
                seen.append(item)
        if "items" in schema:
            for i, item in enumerate(instance):
                yield from schema_errors(item, schema["items"], root, field + (i,))
    if isinstance(instance, dict):
        for key in schema.get("required", ()):
            if key not in instance:
                yield field, f"missing required field {key!r}"
        if "minProperties" in schema and len(instance) < schema["minProperties"]:
            yield field, f"needs at least {schema['minProperties']} entr{'y' if schema['minProperties'] == 1 else 'ies'}"
        props = schema.get("properties", {})
        extra = schema.get("additionalProperties", True)
        names = schema.get("propertyNames")
        for key, value in instance.items():
            if not isinstance(key, str):
                yield field + (key,), f"key {key!r} must be a string"
                continue
            if names is not None:
                for _, msg in schema_errors(key, names, root, field + (key,)):
                    yield field + (key,), f"invalid name: {msg}"
            if key in props:
                yield from schema_errors(value, props[key], root, field + (key,))
            elif extra is False:
                allowed = ", ".join(props)
                yield field + (key,), f"unknown field (allowed: {allowed})"
            elif isinstance(extra, dict):
                yield from schema_errors(value, extra, root, field + (key,))


def validate_document(doc: LoadedYAML, schema: dict | None = None) -> dict:
    """Check ``doc`` against the protocol schema; raise the first error as :class:`ProtocolError`."""
    schema = load_schema() if schema is None else schema
    if not isinstance(doc.data, dict):
        raise doc.error((), "a protocol must be a YAML mapping (name: ..., conditions: ..., ...)")
    for field, message in schema_errors(doc.data, schema):
        raise doc.error(field, message)
    return doc.data
