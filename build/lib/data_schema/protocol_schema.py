"""Protocol files: YAML read with limits and line numbers, checked against ``protocol.schema.json``.

Reading is :mod:`data_schema.yamlfile` (size, depth and alias-expansion limits; YAML 1.2 booleans; duplicate
keys refused); checking is :mod:`data_schema.validation` (the ``jsonschema`` library, Draft 2020-12). Every
error names the file, the line and the field::

    protocols/x.yaml:14: design.repetitions: 0 is below the minimum 1
"""

from __future__ import annotations

from .validation import load_schema as _load_schema
from .validation import validate
from .yamlfile import LoadedYAML, YAMLFileError
from .yamlfile import load_yaml as _load_yaml

SCHEMA_NAME = "protocol"


class ProtocolError(YAMLFileError):
    """A protocol that cannot be used; the message is one line ``FILE:LINE: FIELD: problem``."""


def load_yaml(path) -> LoadedYAML:
    """Read a protocol file (limits, line numbers, YAML 1.2 booleans: :mod:`data_schema.yamlfile`)."""
    return _load_yaml(path, "protocol", ProtocolError)


def load_schema() -> dict:
    """The protocol JSON Schema as a dict."""
    return _load_schema(SCHEMA_NAME)


def validate_document(doc: LoadedYAML) -> dict:
    """Check ``doc`` against the protocol schema; raise the first error as :class:`ProtocolError`."""
    return validate(doc, SCHEMA_NAME, "a protocol")
