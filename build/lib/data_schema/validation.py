"""Checking a user's YAML document against a JSON Schema (Draft 2020-12), with one-line ``FILE:LINE: FIELD``
messages.

The schemas (``protocol.schema.json``, ``scene.schema.json``) are published so that editors can complete and
check the files; the checking itself is the ``jsonschema`` library's, so every keyword of the draft counts
(``const``, ``oneOf``, ``if``/``then``, ...). This module only turns its first error into our message::

    protocols/x.yaml:14: design.repetitions: 0 is below the minimum 1

"First" is the error on the earliest line of the file (then the most relevant one there, as
``jsonschema.exceptions.best_match`` ranks them), so the same file always gives the same message. JSON
Schema has no notion of NaN or infinity; numbers in a document must be finite, checked here as well.
"""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

from .yamlfile import LoadedYAML

SCHEMA_DIR = Path(__file__).resolve().parent


@functools.lru_cache(maxsize=None)
def load_schema(name: str) -> dict:
    """A shipped schema (``protocol`` or ``scene``) as a dict."""
    return json.loads((SCHEMA_DIR / f"{name}.schema.json").read_text(encoding="utf-8"))


@functools.lru_cache(maxsize=None)
def _validator(name: str):
    import jsonschema

    schema = load_schema(name)
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def describe(value) -> str:
    text = repr(value) if isinstance(value, str) else json.dumps(value, default=str)
    return text if len(text) <= 40 else text[:37] + "..."


def _nonfinite(value, field=()):
    """The field of the first NaN or infinite number in ``value``, else None."""
    stack = [(value, tuple(field))]
    while stack:
        v, f = stack.pop()
        if isinstance(v, float) and not math.isfinite(v):
            return f, v
        if isinstance(v, dict):
            stack.extend((x, f + (k,)) for k, x in reversed(list(v.items())))
        elif isinstance(v, list):
            stack.extend((x, f + (i,)) for i, x in reversed(list(enumerate(v))))
    return None


def _message(err) -> tuple[tuple, str]:
    """``(field, message)`` for one ``jsonschema.ValidationError`` in the project's wording."""
    field = tuple(err.absolute_path)
    inst, kind, val = err.instance, err.validator, err.validator_value
    if kind == "required":
        missing = [k for k in val if isinstance(inst, dict) and k not in inst]
        return field, f"missing required field {missing[0]!r}" if missing else err.message
    if kind == "additionalProperties":
        props = err.schema.get("properties", {})
        extra = [k for k in inst if k not in props]
        if extra:
            return field + (extra[0],), f"unknown field (allowed: {', '.join(props)})"
    if kind == "propertyNames":
        return field, f"invalid name {describe(inst)}: {err.message}"
    if kind == "enum":
        return field, f"{describe(inst)} is not one of {', '.join(map(str, val))}"
    if kind == "const":
        return field, f"{describe(inst)} must be {describe(val)}"
    if kind == "type":
        types = val if isinstance(val, list) else [val]
        return field, f"{describe(inst)} is not of type {' or '.join(types)}"
    if kind == "minimum":
        return field, f"{inst} is below the minimum {val}"
    if kind == "maximum":
        return field, f"{inst} is above the maximum {val}"
    if kind == "exclusiveMinimum":
        return field, f"{inst} must be greater than {val}"
    if kind == "exclusiveMaximum":
        return field, f"{inst} must be less than {val}"
    if kind == "minLength":
        return field, "must not be empty" if val == 1 else f"shorter than {val} characters"
    if kind == "maxLength":
        return field, f"longer than {val} characters"
    if kind == "pattern":
        return field, f"{describe(inst)} does not match {val}"
    if kind == "minItems":
        return field, f"needs at least {val} item(s), has {len(inst)}"
    if kind == "maxItems":
        return field, f"allows at most {val} item(s), has {len(inst)}"
    if kind == "uniqueItems":
        seen = []
        for i, item in enumerate(inst):
            if item in seen:
                return field + (i,), f"{describe(item)} is listed twice"
            seen.append(item)
    if kind == "minProperties":
        return field, f"needs at least {val} entr{'y' if val == 1 else 'ies'}"
    if kind in ("oneOf", "anyOf") and err.context:
        import jsonschema

        return _message(jsonschema.exceptions.best_match(err.context))
    return field, err.message


def validate(doc: LoadedYAML, schema_name: str, what: str) -> dict:
    """Check ``doc`` against the shipped schema ``schema_name``; raise the first error as ``doc.error``.

    ``what`` names the document in the message for a non-mapping ("a protocol must be a YAML mapping").
    """
    import jsonschema

    if not isinstance(doc.data, dict):
        raise doc.error((), f"{what} must be a YAML mapping (key: value, ...)")
    bad = _nonfinite(doc.data)
    if bad is not None:
        raise doc.error(bad[0], f"{bad[1]} is not a finite number")
    errors = list(_validator(schema_name).iter_errors(doc.data))
    if errors:
        # A missing field is often the consequence of a misspelt one: report the misspelling first.
        located = [(e.validator == "required", doc.line_of(_message(e)[0]), e) for e in errors]
        first = min((req, line) for req, line, _ in located)
        err = jsonschema.exceptions.best_match([e for req, line, e in located if (req, line) == first])
        field, message = _message(err)
        raise doc.error(field, message)
    return doc.data
