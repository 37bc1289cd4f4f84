"""Architecture rules that code review alone does not keep (docs/architecture.md): the layers, no import
cycles, the homes of the heavy libraries, no module importing a benchmark script."""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: The layers of docs/architecture.md: each package and the packages it may import (function-level imports
#: count). ``test_the_document_states_these_layers`` keeps the document's table equal to this.
LAYERS: dict[str, set[str]] = {
    "data_schema": set(),
    "renderers": {"data_schema"},
    "analysis": {"data_schema"},
    "studyapp": {"data_schema", "renderers", "analysis"},
}
#: Heavy or device libraries and the only places (path prefixes) that import them.
LIBRARY_HOMES: dict[str, tuple[str, ...]] = {
    "moderngl": ("renderers/gpu/",),  # the GPU backend; nothing else opens an OpenGL context
    "psychopy": ("studyapp/presentation/",),  # the window; the runner talks to a Presenter
    "dask": ("studyapp/cluster.py",),
    "distributed": ("studyapp/cluster.py",),
    "numba": ("renderers/",),  # compiled kernels: renderers only (`import analysis` stays light)
    "embreex": ("renderers/",),
    "pyvista": ("renderers/",),
    "vtk": ("renderers/",),
}


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


@functools.cache
def _tops(path: Path) -> frozenset[str]:
    """The top-level names ``path`` imports anywhere in the file (parsed once per test session)."""
    return frozenset(i.split(".")[0] for i in _imports(path))


def _product_files():
    for package in LAYERS:
        yield package, sorted((ROOT / package).rglob("*.py"))


@pytest.mark.parametrize("package", list(LAYERS))
def test_each_package_imports_only_its_layers(package):
    """``data_schema`` (the shared layer) imports none of the others; ``renderers`` and ``analysis`` only
    ``data_schema`` (renderers never import analysis, nor analysis renderers); ``studyapp`` all three; no
    product module imports ``benchmarks`` or ``tests``."""
    ours = set(LAYERS) | {"benchmarks", "tests"}
    bad = []
    for path in sorted((ROOT / package).rglob("*.py")):
        tops = _tops(path) & ours
        if tops - LAYERS[package] - {package}:
            bad.append(f"{path.relative_to(ROOT)} imports {sorted(tops - LAYERS[package] - {package})}")
    assert bad == []


def test_the_cpu_renderers_never_import_the_gpu_backend():
    """The GPU backend builds on the CPU modules (projection, scene tables, kernels turned into GLSL); the CPU
    side reaches a GPU version only through the plug-in's ``gpu="module:function"`` string, which the registry
    loads."""
    gpu = ROOT / "renderers" / "gpu"
    bad = [f"{p.relative_to(ROOT)}" for p in sorted((ROOT / "renderers").rglob("*.py"))
           if gpu not in p.parents and any(i == "renderers.gpu" or i.startswith("renderers.gpu.")
                                           for i in _imports(p, {"renderers.gpu"}))]
    assert bad == []


@pytest.mark.parametrize("library", list(LIBRARY_HOMES))
def test_heavy_libraries_are_imported_in_their_home_only(library):
    bad = []
    for _, files in _product_files():
        for path in files:
            rel = path.relative_to(ROOT).as_posix()
            if library in _tops(path) and not rel.startswith(LIBRARY_HOMES[library]):
                bad.append(rel)
    assert bad == []


def test_no_module_imports_a_benchmark_script():
    """Benchmark scripts share code through ``benchmarks/harness.py`` only; no script imports another and no
    product module imports any (``tests/`` may import a script to test it)."""
    scripts = {_module_name(p) for p in (ROOT / "benchmarks").glob("*.py")} - {"benchmarks.harness",
                                                                                  "benchmarks"}
    bad = []
    for path in sorted((ROOT / "benchmarks").glob("*.py")) + [p for _, fs in _product_files() for p in fs]:
        if "benchmarks" not in _tops(path):
            continue
        # a script may name itself (bench_render hands Dask its own functions)
        got = (_imports(path, scripts) & scripts) - {_module_name(path)}
        if got:
            bad.append(f"{path.relative_to(ROOT)} imports {sorted(got)}")
    assert scripts and bad == []


def _docstrings(tree: ast.AST) -> set[int]:
    """``id`` of every docstring node of ``tree`` (module, class, function)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) \
                    and isinstance(first.value.value, str):
                out.add(id(first.value))
    return out


def _family_literals(source: str, names) -> list[tuple[int, str]]:
    """(line, name) of every string literal of ``source`` equal to one of ``names``, docstrings left out
    (comments are not in the syntax tree)."""
    tree = ast.parse(source)
    docs = _docstrings(tree)
    return sorted((n.lineno, n.value) for n in ast.walk(tree)
                  if isinstance(n, ast.Constant) and n.value in names and id(n) not in docs)


def test_no_family_name_outside_the_families_package():
    """The family rule: product code asks the family object (data_schema.families) what it needs and never
    tests a family's name, so a string literal equal to a family name (``"2afc"``, ``"preference"``,
    ``"yes_no"``) appears only under data_schema/families/."""
    from data_schema.families import NAMES

    bad = []
    for _, files in _product_files():
        for path in files:
            rel = path.relative_to(ROOT).as_posix()
            if rel.startswith("data_schema/families/"):
                continue
            bad += [f"{rel}:{line}: {name!r}" for line, name in
                    _family_literals(path.read_text(encoding="utf-8"), set(NAMES))]
    assert bad == []


def test_the_family_literal_finder_skips_docstrings_and_comments():
    src = '''"""Module: the 2afc family."""
def f(fam):
    """yes_no"""
    # "preference" in a comment
    return fam == "2afc" or fam in ("yes_no",) or f"{fam}" == "2afc trials"
'''
    assert _family_literals(src, {"2afc", "preference", "yes_no"}) == [(5, "2afc"), (5, "yes_no")]


def test_the_document_states_these_layers():
    """docs/architecture.md's package table says what LAYERS enforces, row by row."""
    rows = {}
    for line in (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8").splitlines():
        m = re.match(r"\| `(\w+)/` \|.*\| ([^|]*) \|$", line)
        if m and m.group(1) in LAYERS:
            rows[m.group(1)] = set(re.findall(r"`(\w+)`", m.group(2))) & set(LAYERS)
    assert rows == LAYERS


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
