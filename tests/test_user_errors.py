"""Every error class the product defines is a UserError (issue 27 item 3): the CLI catches exactly that family and
prints one line with exit status 2, so an error class outside it would reach the user as a traceback."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

from data_schema.errors import UserError

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("analysis", "data_schema", "renderers", "studyapp")


def _error_classes() -> list[tuple[str, str]]:
    """(module, class) of every class named ``*Error`` defined at the top level of a product module."""
    found = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
            found += [(module, node.name) for node in tree.body
                      if isinstance(node, ast.ClassDef) and node.name.endswith("Error")]
    return found


def test_every_error_class_of_the_product_is_a_user_error():
    classes = _error_classes()
    assert ("analysis.scaling", "ConvergenceError") in classes and len(classes) >= 8
    outside = [f"{m}.{c}" for m, c in classes if not issubclass(getattr(importlib.import_module(m), c), UserError)]
    assert not outside, f"not a UserError (a traceback on the CLI): {outside}"
