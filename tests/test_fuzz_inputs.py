"""Hostile values inside the files and options users give (issue 25, items 9 and 10): one line, exit 2.

YAML tags that cannot convert (``!!float abc``, a 5000-digit ``!!int``), mesh files that are not meshes (a NUL
in the path, a folder, a FIFO, a device, an 8 GB sparse file, a PLY header claiming billions of vertices or
a face past the vertices), ``quality --data-range 1e300`` and trial logs with ``trial=inf``. Each case is a
command run through :func:`studyapp.cli.main`: exit 2, exactly one stderr line ``studyapp: error: ...`` naming
the problem, nothing written. Then a short hypothesis fuzz of the same readers (about 10 s in all), whose
failures are kept below as ``@example``.
"""

from __future__ import annotations

import csv
import io
import math
import os
import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from studyapp.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _files(folder: Path) -> dict[str, int]:
    """Every file under ``folder`` with its size (not its content: one of them is an 8 GB sparse file)."""
    return {str(p.relative_to(folder)): p.lstat().st_size for p in sorted(folder.rglob("*"))}


def _refused(argv, folder: Path, capsys, match: str) -> str:
    """Run the CLI: exit 2, one stderr line matching ``match``, no file added or changed under ``folder``."""
    before = _files(folder)
    capsys.readouterr()
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("studyapp: error: "), err
    assert match in err, err
    assert _files(folder) == before
    return err


# -- YAML: protocols, scene files, analysis plans ------------------------------------------------------------
BIG_INT = "9" * 5000
YAML_CASES = [
    ("!!float abc", "!!float 'abc' is not a valid float"),
    (f"!!int {BIG_INT}", "(5,000 characters) is outside the 64-bit range"),
    (BIG_INT, "(5,000 characters) is outside the 64-bit range"),
    ("!!int 0x" + "f" * 40, "is outside the 64-bit range"),
    ("9223372036854775808", "integer '9223372036854775808' is outside the 64-bit range"),
    ("!!int 0b102", "!!int '0b102' is not a valid int"),
    ("!!bool maybe", "!!bool 'maybe' is not a valid bool"),
    ("!!timestamp 2020-99-99", "tag !!timestamp is not allowed"),
    ("!!binary '@@@'", "tag !!binary is not allowed"),
    ("!!set {a: null}", "tag !!set is not allowed"),
]


@pytest.mark.parametrize("value,match", YAML_CASES)
def test_protocol_yaml_tag_errors_name_file_and_line(tmp_path, capsys, value, match):
    text = (ROOT / "protocols" / "seed001_2afc.yaml").read_text()
    lines = text.splitlines()
    n = next(i for i, ln in enumerate(lines) if ln.startswith("  repetitions:")) + 1
    f = tmp_path / "p.yaml"
    f.write_text(text.replace("  repetitions: 3", f"  repetitions: {value}"))
    err = _refused(["validate", f], tmp_path, capsys, match)
    assert f"p.yaml:{n}: malformed YAML: " in err


SCENE = """name: t
meshes:
  - {file: MESH}
lights:
  - {type: point, position: [0, 3, 0], intensity: [5, 5, 5]}
camera: {position: [0, 1.5, -3], look_at: [0, 0.5, 1], up: [0, 1, 0], fov_y: FOV}
display: {width: 16, height: 12}
"""


def _render(folder: Path, scene_text: str) -> list:
    f = folder / "s.yaml"
    f.write_text(scene_text)
    return ["render", "--scene", f, "--renderer", "gt", "--width", 16, "--height", 12,
            "--out", folder / "out" / "x.png"]


@pytest.mark.parametrize("value,match", YAML_CASES[:3])
def test_scene_yaml_tag_errors_name_file_and_line(tmp_path, mesh_file, capsys, value, match):
    scene = SCENE.replace("MESH", str(mesh_file / "floor.ply")).replace("FOV", value)
    err = _refused(_render(tmp_path, scene), tmp_path, capsys, match)
    assert "s.yaml:6: malformed YAML: " in err


@pytest.mark.parametrize("value,match", YAML_CASES[:3])
def test_analysis_plan_yaml_tag_errors_name_file_and_line(tmp_path, capsys, value, match):
    plan = tmp_path / "plan.yaml"
    plan.write_text(f"analysis:\n  alpha: {value}\n")
    err = _refused(["analyze", ROOT / "tests" / "data" / "tiny_log.csv", "--plan", plan,
                    "--out", tmp_path / "rep"], tmp_path, capsys, match)
    assert "plan.yaml:2: malformed YAML: " in err


def test_plain_dates_stay_strings(tmp_path):
    from data_schema.yamlfile import load_yaml

    f = tmp_path / "d.yaml"
    f.write_text("when: 2024-05-01\nbig: 9223372036854775807\nsmall: -9223372036854775808\n")
    assert load_yaml(f).data == {"when": "2024-05-01", "big": 2 ** 63 - 1, "small": -2 ** 63}


# -- mesh files of scene files -------------------------------------------------------------------------------
def _ply(n_vertices, n_faces, fmt="binary_little_endian") -> bytes:
    return (f"ply\nformat {fmt} 1.0\nelement vertex {n_vertices}\nproperty float x\nproperty float y\n"
            f"property float z\nelement face {n_faces}\nproperty list uchar int vertex_indices\n"
            "end_header\n").encode()


TRIANGLE = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0)


def _mesh_case(folder: Path, case: str) -> str:
    """Make the hostile mesh file of ``case``; return the YAML text naming it."""
    if case == "nul":
        return '"a\\0b.ply"'
    if case == "folder":
        (folder / "m.ply").mkdir()
    elif case == "fifo":
        os.mkfifo(folder / "m.ply")
    elif case == "device":
        return "/dev/zero"
    elif case == "sparse":
        with open(folder / "m.ply", "wb") as fh:
            fh.truncate(8 << 30)  # 8 GB, sparse: VTK aborted (exit 134)
    elif case == "billions":
        (folder / "m.ply").write_bytes(_ply(4_000_000_000, 1) + bytes(100))
    elif case == "short":
        (folder / "m.ply").write_bytes(_ply(10_000_000, 1) + bytes(100))  # VTK: segmentation fault
    elif case == "index":
        (folder / "m.ply").write_bytes(_ply(3, 1) + TRIANGLE + struct.pack("<Biii", 3, 0, 1, 1_000_000))
    elif case == "obj_index":
        (folder / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999\n")
        return "m.obj"
    elif case == "obj_nan":
        (folder / "m.obj").write_text("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        return "m.obj"
    elif case == "obj_count":  # with the limits lowered to 2 by the test
        (folder / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        return "m.obj"
    elif case == "stl_header":
        (folder / "m.stl").write_bytes(bytes(80) + struct.pack("<I", 4_000_000_000) + bytes(100))
        return "m.stl"
    elif case == "format":
        (folder / "m.ply").write_bytes(b"")
        (folder / "m.ply").rename(folder / "m.vtk")
        return "m.vtk"
    return "m.ply"


@pytest.mark.parametrize("case,match", [
    ("nul", "meshes[0].file: mesh file 'a\\x00b.ply' contains a NUL character"),
    ("folder", "m.ply' is a folder, not a mesh file"),
    ("fifo", "m.ply' is not a regular file (a device, FIFO or socket)"),
    ("device", "'/dev/zero' is not a regular file (a device, FIFO or socket)"),
    ("sparse", "m.ply' is 8,590 MB, more than the 256 MB a mesh file may have"),
    ("billions", "m.ply' declares 4,000,000,000 vertices, more than the 10,000,000 a mesh may have"),
    ("short", "m.ply' declares 10,000,000 vertex elements of 12 bytes, more than its"),
    ("index", "m.ply' has a face with vertex index 1,000,000, outside the 3 vertices"),
    ("format", "m.vtk' has an unsupported format '.vtk': allowed .ply, .obj, .stl"),
    ("obj_index", "m.obj' has a face with vertex index 99,999,998, outside the 3 vertices"),
    ("obj_nan", "m.obj' has a vertex coordinate that is not a finite number"),
    ("obj_count", "m.obj' declares 3 vertices, more than the 2 a mesh may have"),
    ("stl_header", "m.stl' is neither ASCII STL nor binary STL of the size its header declares"),
])
def test_hostile_mesh_files_are_refused_before_decoding(tmp_path, capsys, monkeypatch, case, match):
    import renderers.scene

    if case == "obj_count":
        monkeypatch.setattr(renderers.scene, "MAX_MESH_VERTICES", 2)
    name = _mesh_case(tmp_path, case)
    err = _refused(_render(tmp_path, SCENE.replace("MESH", name).replace("FOV", "50")), tmp_path, capsys, match)
    assert "s.yaml:3: meshes[0].file: " in err


def test_ply_reader_matches_vtk(mesh_file, tmp_path):
    """The checked PLY reader gives VTK's vertices and triangles (binary and ASCII, triangles and quads)."""
    import pyvista as pv

    from renderers.scene import _read_ply

    sphere = pv.Sphere(theta_resolution=8, phi_resolution=6)
    for binary in (True, False):
        sphere.save(str(tmp_path / "s.ply"), binary=binary)
        v, f = _read_ply(tmp_path / "s.ply", (tmp_path / "s.ply").stat().st_size, "w")
        np.testing.assert_allclose(v, sphere.points, rtol=1e-6)
        assert np.array_equal(f, np.asarray(sphere.faces).reshape(-1, 4)[:, 1:])
    v, f = _read_ply(mesh_file / "floor.ply", (mesh_file / "floor.ply").stat().st_size, "w")
    assert v.shape == (9, 3) and f.shape == (8, 3)  # 4 quads, two triangles each
    assert sorted(np.unique(f).tolist()) == list(range(9))


# -- quality --data-range -------------------------------------------------------------------------------------
@pytest.mark.parametrize("value,match", [
    ("1e300", "--data-range=1e+300 is out of range: allowed [1e-06, 1e+12]"),
    ("1e155", "--data-range=1e+155 is out of range"),  # L^2 was inf: PSNR inf for different images
    ("1e-300", "--data-range=1e-300 is out of range"),
    ("nan", "--data-range=nan is invalid: must be a finite number"),
])
def test_quality_data_range_is_bounded(tmp_path, capsys, value, match):
    from PIL import Image

    rng = np.random.default_rng(0)
    gt = (rng.random((12, 16, 3)) * 255).astype(np.uint8)
    Image.fromarray(gt).save(tmp_path / "gt.png")
    Image.fromarray(255 - gt).save(tmp_path / "st.png")
    _refused(["quality", tmp_path / "st.png", "--gt", tmp_path / "gt.png", "--fov-y", 60, "--data-range", value,
              "--out", tmp_path / "out"], tmp_path, capsys, match)


def test_psnr_at_the_ends_of_the_data_range():
    from analysis.quality import DATA_RANGE, image_quality

    ref = np.zeros((9, 9))
    for rng in (DATA_RANGE.low, DATA_RANGE.high):
        q = image_quality(ref + 0.5, ref, fov_y_deg=60.0, data_range=rng)
        assert q["psnr"].iloc[-1] == pytest.approx(20 * math.log10(rng) - 10 * math.log10(0.25))
        assert np.isfinite(q["ssim"].astype(float)).all()


# -- trial logs -----------------------------------------------------------------------------------------------
LOG = "participant,family,scene,condition,response,trial\n" + "".join(
    f"P{p},yes_no,s,{c},{r},{t}\n" for p in (1, 2, 3) for t, (c, r) in enumerate([("A", 1), ("B", 0), ("A", 1)]))


@pytest.mark.parametrize("column,value,match", [
    ("trial", "inf", "line 2: column trial (the 0-based trial index) must be a whole number in [0, 2**63), "
                     "found inf"),
    ("trial", "1e300", "line 2: column trial (the 0-based trial index) must be a whole number in [0, 2**63), "
                       "found 1e+300"),
    ("trial", "-1", "column trial (the 0-based trial index) must be a whole number in [0, 2**63), found -1"),
    ("trial", "1.5", "found 1.5"),
    ("trial", "abc", "found 'abc'"),
    ("rt_s", "inf", "line 2: column rt_s must be a finite number (or empty), found inf"),
    ("rt_s", "-inf", "column rt_s must be a finite number (or empty), found -inf"),
    ("participant", "", "line 2: column participant must not be empty, found ''"),
    ("scene", "  ", "line 2: column scene must not be empty"),
    ("participant", "x" * 100_000, "wrote"),  # a huge name is a name
])
def test_log_values_are_checked(tmp_path, capsys, column, value, match):
    header, first, *rest = LOG.splitlines()
    cols = header.split(",") + ([] if column in header.split(",") else [column])
    cells = dict(zip(header.split(","), first.split(",")))
    cells[column] = value
    text = "\n".join([",".join(cols), ",".join(cells.get(c, "") for c in cols), *[
        r + ("" if column in header.split(",") else ",0.5") for r in rest]]) + "\n"
    f = tmp_path / "log.csv"
    f.write_text(text)
    argv = ["analyze", f, "--out", tmp_path / "rep", "--no-figures", "--n-boot", 0]
    if match == "wrote":
        assert main([str(a) for a in argv]) == 0
        return
    _refused(argv, tmp_path, capsys, f"log.csv: {match}" if match.startswith("line") else match)


# -- the fuzz (bounded: about 10 s in all) ---------------------------------------------------------------------
def FUZZ(n: int):  # noqa: N802 - a decorator factory
    return settings(max_examples=n, deadline=None, suppress_health_check=[
        HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


TAGS = ["", "!!int ", "!!float ", "!!bool ", "!!null ", "!!str ", "!!binary ", "!!timestamp ", "!!set ",
        "!!omap ", "!!pairs ", "!!map ", "!!seq ", "!foo ", "!!python/object:os.system "]
SCALAR_TEXT = st.one_of(
    st.text(alphabet="0123456789abcdefxob_:.-+eE ", max_size=30), st.sampled_from(
        ["", ".inf", "-.nan", "1_000.5", "0x" + "f" * 30, "0b102", "0o99", "1:2:3", "190:20:30", "2020-99-99",
         "2001-12-14t21:59:43.10-05:00", "maybe", "~", "[1]", "{a: 1}", "'q'", BIG_INT, "1e400", "-0"]))


@FUZZ(150)
@given(tag=st.sampled_from(TAGS), value=SCALAR_TEXT, place=st.sampled_from(["b: {}", "{}: b", "b: [x, {}]"]))
@example(tag="!!float ", value="abc", place="b: {}")
@example(tag="!!int ", value=BIG_INT, place="{}: b")
@example(tag="!!timestamp ", value="nonsense", place="b: [x, {}]")
@example(tag="", value="2020-99-99", place="b: {}")
@example(tag="!!bool ", value="", place="b: {}")
def test_fuzzed_yaml_scalars(tmp_path_factory, tag, value, place):
    """Any tag on any scalar (a value, a key, an item): JSON-kind data, or one YAMLFileError line naming the file."""
    from data_schema.yamlfile import YAMLFileError, load_yaml

    f = tmp_path_factory.mktemp("y") / "f.yaml"
    f.write_text("a: 1\n" + place.format(tag + value) + "\n")
    try:
        data = load_yaml(f).data
    except YAMLFileError as exc:
        assert "\n" not in str(exc) and str(exc).startswith(f"{f}:"), exc
        return

    def json_kind(v) -> bool:
        if isinstance(v, dict):
            return all(isinstance(k, (str, int, float, bool, type(None))) and json_kind(x) for k, x in v.items())
        if isinstance(v, list):
            return all(json_kind(x) for x in v)
        if isinstance(v, int) and not isinstance(v, bool):
            return -2 ** 63 <= v < 2 ** 63
        return isinstance(v, (str, float, bool, type(None)))

    assert json_kind(data), data


PLY_TYPES = ["char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "float64", "long"]


@st.composite
def ply_files(draw) -> bytes:
    fmt = draw(st.sampled_from(["ascii", "binary_little_endian", "binary_big_endian", "binary"]))
    nv = draw(st.sampled_from([0, 1, 3, 4, 100, 10 ** 7, 2 ** 31, 2 ** 32 + 3, 4 * 10 ** 9]))
    nf = draw(st.sampled_from([0, 1, 2, 5, 10 ** 6]))
    vprops = draw(st.lists(st.sampled_from(["x", "y", "z", "nx"]), min_size=0, max_size=4))
    head = ["ply", f"format {fmt} 1.0", f"element vertex {nv}"]
    lists = ["list uchar int", "list uchar uint", "list int int", "list char short", "list float int",
             "list uchar float"]
    head += [f"property {draw(st.sampled_from(PLY_TYPES + lists[:1]))} {p}" for p in vprops]
    head += [f"element face {nf}", f"property {draw(st.sampled_from(lists + PLY_TYPES[:2]))} vertex_indices"]
    if draw(st.booleans()):
        head.append("end_header")
    body = draw(st.one_of(st.binary(max_size=200), st.text(alphabet="0123456789 -.\nenaif", max_size=200)
                          .map(str.encode)))
    return ("\n".join(head) + "\n").encode() + body


@FUZZ(200)
@given(ply=ply_files())
@example(ply=_ply(3, 1) + TRIANGLE + struct.pack("<Biii", 3, 0, 1, 1_000_000))
@example(ply=_ply(3, 1) + TRIANGLE + struct.pack("<B", 255) + bytes(40))
@example(ply=_ply(3, 1, "ascii") + b"0 0 0\n1 0 0\n0 1 0\n3 0 1 -7\n")
@example(ply=_ply(100, 1, "ascii") + b"0 0 0\n" * 3)
@example(ply=b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty char x\nproperty char x\n"
              b"element face 0\nproperty list uchar int vertex_indices\nend_header\n")
@example(ply=b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
              b"element face 1\nproperty uchar vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3\n")
@example(ply=b"ply\nformat ascii 1.0\nelement vertex 3\nproperty list uchar int x\nproperty float y\n"
              b"property float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n"
              b"1 0 0 0\n2 1 1 0 0\n1 0 1 0\n")
@example(ply=b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty char x\nelement face 1\n"
              b"property list int int vertex_indices\nend_header\n\x00")
@example(ply=b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty char x\nelement face 1\n"
              b"property list int int vertex_indices\nend_header\n\x00\x00\x00 ")
def test_fuzzed_ply_files(tmp_path_factory, ply):
    """Any PLY bytes: finite-shaped vertices and in-range triangles, or one SceneError line (VTK crashed)."""
    from renderers.scene import MAX_MESH_TRIANGLES, SceneError, _read_mesh

    f = tmp_path_factory.mktemp("ply") / "m.ply"
    f.write_bytes(ply)
    try:
        v, t = _read_mesh(f, "s.yaml:3: meshes[0].file")
    except SceneError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("s.yaml:3: meshes[0].file: mesh file "), exc
        return
    assert v.ndim == 2 and v.shape[1] == 3 and t.ndim == 2 and t.shape[1] == 3
    assert 0 < len(t) <= MAX_MESH_TRIANGLES and t.min() >= 0 and t.max() < len(v)


NUMBER_CELLS = st.one_of(
    st.sampled_from(["", "inf", "-inf", "nan", "NaN", "1e300", "-1", "1.5", "abc", "9" * 400, "0x10", "1e18",
                     "9223372036854775808", " 3 ", "true", "1_0"]),
    st.integers(-2 ** 70, 2 ** 70).map(str), st.floats().map(repr), st.text(max_size=6))


@FUZZ(60)
@given(trial=st.lists(NUMBER_CELLS, min_size=3, max_size=3), rt=st.lists(NUMBER_CELLS, min_size=3, max_size=3))
@example(trial=["inf", "0", "1"], rt=["0.5", "0.5", "0.5"])
@example(trial=["0", "1", "2"], rt=["0.5", "-inf", "0.5"])
def test_fuzzed_log_numbers(tmp_path_factory, trial, rt):
    """Any cells in trial and rt_s: a clean int64/float64 log, or one LogError line naming line and column."""
    from analysis.io import LogError, read_log

    f = tmp_path_factory.mktemp("log") / "log.csv"
    with open(f, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["participant", "family", "scene", "condition", "response", "trial", "rt_s"])
        w.writerows(["P1", "yes_no", "s", c, 1, t, r] for c, t, r in zip("ABA", trial, rt))
    try:
        df = read_log(f)
    except LogError as exc:
        assert "\n" not in str(exc) and str(exc).startswith(f"{f}: ")
        return
    assert df["trial"].dtype == np.int64 and (df["trial"] >= 0).all()
    assert df["rt_s"].dtype == np.float64 and not np.isinf(df["rt_s"]).any()


@FUZZ(60)
@given(text=st.one_of(st.floats().map(repr), st.text(max_size=8),
                      st.sampled_from(["1e300", "1e-300", "1e155", "0", "-1", "1e12", "1e-6", "255"])))
@example(text="1e300")
@example(text="1e-300")
def test_fuzzed_data_range(text):
    """Any --data-range: refused in one line, or a value for which PSNR and SSIM of two images are finite."""
    import argparse

    from analysis.quality import image_quality
    from studyapp.commands.quality import _data_range

    try:
        rng = _data_range(text)
    except argparse.ArgumentTypeError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("--data-range=")
        return
    ref = np.zeros((9, 9))
    q = image_quality(ref + 0.5, ref, fov_y_deg=60.0, data_range=rng)
    assert np.isfinite(q["psnr"].astype(float)).all() and np.isfinite(q["ssim"].astype(float)).all()


@pytest.mark.parametrize("column,value,match", [
    ("trial", math.inf, "row 2: column trial (the 0-based trial index) must be a whole number in [0, 2**63), "
                        "found inf"),
    ("trial", 1e300, "row 2: column trial (the 0-based trial index) must be a whole number in [0, 2**63)"),
    ("participant", math.nan, "row 2: column participant must not be empty, found nan"),
])
def test_parquet_log_values_are_checked(tmp_path, capsys, column, value, match):
    import pandas as pd

    df = pd.read_csv(io.StringIO(LOG), dtype={"participant": object, "trial": float})
    df.loc[1, column] = value
    df.to_parquet(tmp_path / "log.parquet")
    _refused(["analyze", tmp_path / "log.parquet", "--out", tmp_path / "rep", "--no-figures"], tmp_path, capsys,
             f"log.parquet: {match}")
