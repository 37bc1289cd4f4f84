"""Architecture rules that code review alone does not keep: no import cycles, one home per concept."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(path: Path, modules: set[str] | None = None) -> set[str]:
    """Every module ``path`` imports, anywhere in the file (function-level imports count: a cycle through a
    lazy import is still a cycle of concepts). ``from pkg import sub`` names the submodule ``pkg.sub`` when
    it is one of ``modules``, else ``pkg``."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            for a in node.names:
                sub = f"{mod}.{a.name}"
                out.add(sub if modules is not None and sub in modules else mod)
    return out


def _graph(top: str) -> dict[str, set[str]]:
    files = {_module_name(p): p for p in (ROOT / top.replace(".", "/")).rglob("*.py")}
    return {m: {i for i in _imports(p, set(files)) if i in files and i != m} for m, p in files.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return out


@pytest.mark.parametrize("package", ["renderers", "studyapp", "data_schema", "analysis"])
def test_no_import_cycles(package):
    assert _cycles(_graph(package)) == []


def test_the_cycle_finder_finds_cycles():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_data_schema_is_a_leaf():
    """The shared layer (errors, ranges, geometry, schemas, store) imports none of the packages built on it."""
    for path in (ROOT / "data_schema").rglob("*.py"):
        bad = {i.split(".")[0] for i in _imports(path)} & {"studyapp", "renderers", "analysis"}
        assert not bad, f"{path.name} imports {bad}"


def test_the_wheel_ships_the_protocols_and_schemas(tmp_path):
    """A wheel install can `studyapp validate seed001_2afc`: the protocols and the schemas are package data."""
    import subprocess
    import sys
    import zipfile

    import shutil

    src = tmp_path / "src"  # build from a copy: setuptools writes build/ next to the sources
    shutil.copytree(ROOT, src, symlinks=True, ignore=shutil.ignore_patterns(
        ".venv", ".git", "build", "demo_out", "__pycache__", ".hypothesis", "*.egg-info", "stimulus_cache"))
    res = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", str(src),
                          "-w", str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    [wheel] = tmp_path.glob("studyapp-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for name in ("seed001_2afc", "seed001_pilot", "seed003_task1", "seed003_task2"):
        assert f"studyapp/protocols/{name}.yaml" in names
    assert {"data_schema/protocol.schema.json", "data_schema/scene.schema.json"} <= names
    assert "data_schema/families/two_afc.py" in names


def test_shipped_protocols_by_name_keep_their_stimuli_in_the_current_folder(tmp_path, monkeypatch):
    from studyapp.commands.study import SHIPPED, _protocol

    monkeypatch.chdir(tmp_path)
    p = _protocol("seed001_2afc", check_renderers=False)
    assert p.path == SHIPPED / "seed001_2afc.yaml" and SHIPPED.parent.name == "studyapp"
    assert p.stimuli_dir == tmp_path / "stimuli" / "seed001"
