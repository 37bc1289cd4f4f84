"""Fuzzing the CLI around its input schemas (issue 10, case 11): protocols, scene files and trial logs.

Hypothesis generates documents near the valid ones (a shipped protocol, a small scene, a tidy log) with
values, types and keys changed, deleted or added. For every example the command must end with exit 0, or
exit 2 and exactly one stderr line ``studyapp: error: ...`` (an exception escaping ``main`` fails the test with
its traceback), and no file outside the command's output may change. Bounded to about a minute in all; failing
examples are kept in hypothesis' example database (and belong in ``@example`` once fixed).
"""

from __future__ import annotations

import csv
import hashlib
import io
import math
from pathlib import Path

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from studyapp.cli import main

ROOT = Path(__file__).resolve().parents[1]


def FUZZ(n: int):  # noqa: N802 - a decorator factory
    return settings(max_examples=n, deadline=None, suppress_health_check=[
        HealthCheck.function_scoped_fixture, HealthCheck.too_slow, HealthCheck.data_too_large])

SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(-3, 3), st.integers(-2 ** 70, 2 ** 70),
    st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -1.0, 1e308, 0.5, 16385]),
    st.text(max_size=12), st.sampled_from(["", "../..", "/etc/passwd", "yes", "no", "GT", "cornell", "nan",
                                           "1e999", "temple", "A", "B", "checker", "point", "ä\u202e"]))
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                       st.dictionaries(st.text(max_size=8), inner, max_size=3)),
                      max_leaves=8)


def _paths(doc, prefix=()):
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from _paths(v, prefix + (i,))


def _mutate(doc, data) -> object:
    """Apply 1-3 random edits (replace a value, delete a key or item, add a key) to a copy of ``doc``."""
    doc = yaml.safe_load(yaml.safe_dump(doc))
    for _ in range(data.draw(st.integers(1, 3))):
        paths = [p for p in _paths(doc) if p]
        if not paths:
            break
        path = data.draw(st.sampled_from(paths))
        parent = doc
        for part in path[:-1]:
            parent = parent[part]
        action = data.draw(st.sampled_from(["replace", "replace", "delete", "add"]))
        if action == "replace":
            parent[path[-1]] = data.draw(VALUES)
        elif action == "delete":
            del parent[path[-1]]
        elif isinstance(parent, dict):
            parent[data.draw(st.text(min_size=1, max_size=8))] = data.draw(VALUES)
        else:
            parent.append(data.draw(VALUES))
    return doc


def _dump(doc, data) -> str:
    text = yaml.safe_dump(doc, allow_unicode=True, sort_keys=False)
    if data.draw(st.integers(0, 9)) == 0:  # now and then a raw-text edit: truncation or stray characters
        cut = data.draw(st.integers(0, len(text)))
        text = text[:cut] + data.draw(st.sampled_from(["", "]", "{", ":", "&a", "*a", "\t", "- ", "'"])) + \
            text[cut:]
    return text


def _digests(folder: Path, skip: str) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and skip not in p.relative_to(folder).parts}


def _check(argv, folder: Path, capsys) -> int:
    before = _digests(folder, "out")
    capsys.readouterr()
    code = main([str(a) for a in argv])
    _, err = capsys.readouterr()
    assert code in (0, 2), (code, err)
    if code == 2:
        assert err.count("\n") == 1 and err.startswith("studyapp: error: "), err
    assert "Traceback" not in err
    assert _digests(folder, "out") == before, "a file outside the output changed"
    return code


# -- protocols ------------------------------------------------------------------------------------------------
PROTOCOL = yaml.safe_load((ROOT / "protocols" / "seed001_2afc.yaml").read_text())


@FUZZ(120)
@given(data=st.data())
def test_fuzzed_protocols(tmp_path_factory, capsys, data):
    folder = tmp_path_factory.mktemp("proto")
    f = folder / "p.yaml"
    f.write_text(_dump(_mutate(PROTOCOL, data), data), encoding="utf-8")
    _check(["validate", f], folder, capsys)


# -- scene files ----------------------------------------------------------------------------------------------
SCENE = {
    "name": "fuzz",
    "materials": {"floor": {"albedo": [0.7, 0.7, 0.7], "texture": "checker", "texture_scale": 0.5},
                  "box": {"albedo": [0.6, 0.3, 0.2], "kind": "glossy", "roughness": 0.3}},
    "meshes": [{"file": "floor.ply", "material": "floor"}, {"file": "cube.stl", "material": "box"}],
    "lights": [{"type": "point", "position": [0, 3, 0], "intensity": [5, 5, 5]},
               {"type": "directional", "direction": [0, -1, 0.2], "irradiance": [1, 1, 1]}],
    "camera": {"position": [0, 1.5, -3], "look_at": [0, 0.5, 1], "up": [0, 1, 0], "fov_y": 50},
    "display": {"width": 16, "height": 12},
    "exposure": 1.0,
}


@FUZZ(60)
@given(data=st.data())
def test_fuzzed_scene_files(tmp_path_factory, mesh_file, capsys, data):
    folder = tmp_path_factory.mktemp("scene")
    for m in ("floor.ply", "cube.stl"):
        (folder / m).write_bytes((mesh_file / m).read_bytes())
    f = folder / "s.yaml"
    f.write_text(_dump(_mutate(SCENE, data), data), encoding="utf-8")
    renderer = data.draw(st.sampled_from(["gt", "vafr", "lafr"]))
    _check(["render", "--scene", f, "--renderer", renderer, "--width", 16, "--height", 12,
            "--out", folder / "out" / "x.png"], folder, capsys)


# -- trial logs -----------------------------------------------------------------------------------------------
def _log_rows(data) -> list[dict]:
    family = data.draw(st.sampled_from(["yes_no", "2afc", "preference", "rating", ""]))
    rows = []
    for p in range(data.draw(st.integers(0, 4))):
        for t in range(data.draw(st.integers(1, 4))):
            a, b = data.draw(st.sampled_from([("A", "B"), ("B", "A"), ("A", "A"), ("", "B")]))
            rows.append({"participant": f"P{p}", "family": family, "scene": "s", "trial": t,
                         "condition": a, "condition_a": a, "condition_b": b, "conditions": f"{a}|{b}|C",
                         "chosen": data.draw(st.sampled_from([a, b, "C", "", "Z"])), "chosen_2": "",
                         "response": data.draw(st.sampled_from([0, 1, 1, 0, 7, -1, 0.5, "", "yes", math.nan])),
                         "rt_s": data.draw(st.sampled_from([0.5, "", -1, "inf"])),
                         "practice": data.draw(st.sampled_from([0, 0, 0, 1, "maybe"])), "catch": 0})
    return rows


@FUZZ(80)
@given(data=st.data())
def test_fuzzed_logs(tmp_path_factory, capsys, data):
    folder = tmp_path_factory.mktemp("log")
    rows = _log_rows(data)
    columns = list(rows[0]) if rows else ["participant", "family", "scene"]
    columns = [c for c in columns if data.draw(st.integers(0, 12)) > 0]  # now and then a column is missing
    if data.draw(st.integers(0, 9)) == 0 and columns:
        columns.append(columns[0])  # a duplicated column name
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([r.get(c, "") for c in columns])
    f = folder / "log.csv"
    f.write_text(buf.getvalue(), encoding="utf-8")
    _check(["analyze", f, "--out", folder / "out" / "rep", "--n-boot", 0, "--no-figures"], folder, capsys)
