"""Names that become path components (issue 25, item 2): one rule (data_schema/names.py) applied at protocol
validation and to ``run --participant``; ``inside`` proves a built path stays in its folder; analyze's per-scene
file names are injective."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

from data_schema.errors import UserError
from data_schema.names import check_name, check_unique, inside
from studyapp.cli import main
from studyapp.runner.protocol import load_protocol

ROOT = Path(__file__).resolve().parents[1]
PROTOCOL = ROOT / "studyapp" / "protocols" / "seed001_2afc.yaml"


@pytest.mark.parametrize("name,problem", [
    ("", "is empty"),
    (".", "is a folder reference, not a name"),
    ("..", "is a folder reference, not a name"),
    (".hidden", "starts with a dot"),
    ("a/b", "holds the path separator '/'"),
    ("a\\b", "holds the path separator '\\\\'"),
    ("a\0b", "holds the control character '\\x00'"),
    ("a\nb", "holds the control character '\\n'"),
    ("a\x7fb", "holds the control character '\\x7f'"),
    ("a:b", "holds ':', which Windows forbids"),
    ("a*", "holds '*', which Windows forbids"),
    ('a"b', "holds '\"', which Windows forbids"),
    ("trailing.", "ends in a dot or a space"),
    ("trailing ", "ends in a dot or a space"),
    ("CON", "is a device name on Windows"),
    ("con.txt", "is a device name on Windows"),
    ("Lpt9", "is a device name on Windows"),
    ("nul.tar.gz", "is a device name on Windows"),
    ("x" * 101, "is longer than 100 characters"),
    ("\U0001f600" * 60, "is longer than 200 bytes in UTF-8"),
    ("a\ud800", "lone surrogate"),
])
def test_check_name_refuses_in_one_line(name, problem):
    with pytest.raises(UserError) as exc:
        check_name("condition", name)
    msg = str(exc.value)
    assert msg.startswith(f"condition name {name!r}: ") and problem in msg and msg.endswith(": choose another name")
    assert "\n" not in msg


@pytest.mark.parametrize("name", ["GT", "LaFR(2.2)", "VaFR_Rep", "hall.v2", "street_night", "é", "COM10",
                                  "console", "a b", "x" * 100, "P01"])
def test_check_name_accepts_plain_names(name):
    assert check_name("scene", name) == name


def test_check_unique_ignores_case_and_normalisation():
    check_unique("condition", ["GT", "LaFR(2.2)", "GT"])  # the same name twice is one name
    with pytest.raises(UserError, match=r"^condition names 'GT' and 'gt' are the same file name on macOS and "
                                        r"Windows .*: rename one$"):
        check_unique("condition", ["GT", "A", "gt"])
    with pytest.raises(UserError, match="scene names 'caf\u00e9' and 'CAFE\u0301'"):
        check_unique("scene", ["caf\u00e9", "CAFE\u0301"])


def test_inside_proves_the_path_stays_in_its_folder(tmp_path):
    assert inside(tmp_path, "GT", "hall.png") == tmp_path / "GT" / "hall.png"
    for part in ("..", "../x", "/etc/passwd", "a/../../x", "C:\\x", "..\\x", "a\0b"):
        with pytest.raises(UserError, match=r": would be written outside .*: refusing \(name "):
            inside(tmp_path, part)
    (tmp_path / "out").symlink_to(tmp_path.parent)
    with pytest.raises(UserError, match=re.escape(f"{tmp_path}/out/x: would be written outside {tmp_path}: "
                                                  "refusing (name 'x')")):
        inside(tmp_path, "out", "x")


def _protocol(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "p.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def _renamed(old: str, new: str) -> str:
    """seed001_2afc with condition ``old`` renamed ``new`` everywhere it is referred to."""
    text = PROTOCOL.read_text(encoding="utf-8")
    text = re.sub(rf"(?m)^  {re.escape(old)}:", f"  {new!r}:".replace("'", '"'), text)
    return re.sub(rf"(?<=[\[ ]){re.escape(old)}(?=[,\]}}])", f'"{new}"', text)


@pytest.mark.parametrize("name", [".", ".."])
def test_validate_refuses_dot_condition_names(name, tmp_path, capsys):
    path = _protocol(tmp_path, _renamed("GT", name))
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert re.match(rf"studyapp: error: {re.escape(str(path))}:\d+: conditions\.{re.escape(name)}: condition name "
                    rf"'{re.escape(name)}': is a folder reference, not a name: choose another name$", err), err


@pytest.mark.parametrize("edit,message", [
    (lambda t: t.replace("scenes: [street_night, interior, temple]", "scenes: [street_night, CON, temple]"),
     r"scenes\[1\]: scene name 'CON': is a device name on Windows"),
    (lambda t: _renamed("LaFR(1.8)", "gt"),
     r"conditions: condition names 'gt' and 'GT' are the same file name on macOS and Windows"),
    (lambda t: re.sub(r"(?m)^stimuli_dir: .*$", 'stimuli_dir: "."', t),
     r"stimuli_dir: '\.' is the protocol's folder .* itself: give a subfolder"),
    (lambda t: re.sub(r"(?m)^stimuli_dir: .*$", 'stimuli_dir: "stimuli/.."', t),
     r"stimuli_dir: 'stimuli/\.\.' is the protocol's folder .* itself: give a subfolder"),
])
def test_protocol_names_and_stimuli_dir_are_checked(edit, message, tmp_path):
    path = _protocol(tmp_path, edit(PROTOCOL.read_text(encoding="utf-8")))
    with pytest.raises(UserError, match=message) as exc:
        load_protocol(path, check_renderers=False)
    assert "\n" not in str(exc.value)


def test_shipped_protocols_pass_the_name_rule():
    for path in sorted((ROOT / "studyapp" / "protocols").glob("*.yaml")):
        p = load_protocol(path, check_renderers=False)
        check_unique("condition", p.conditions)
        assert p.stimuli_dir != path.parent.resolve()


def test_run_refuses_a_dot_participant(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    path = _protocol(tmp_path, PROTOCOL.read_text(encoding="utf-8"))
    assert main(["run", str(path), "--participant", "..", "--simulate", "--quiet", "--db", "s.db"]) == 2
    err = capsys.readouterr().err
    assert err == "studyapp: error: participant name '..': is a folder reference, not a name: choose another name\n"
    assert sorted(os.listdir(tmp_path)) == ["p.yaml"]


def test_analyze_refuses_per_scene_files_that_would_collide_naming_both(tmp_path, capsys):
    """Scenes hall.v2 and hall_v2 (or Hall_V2) share a table name once slugged, ignoring case: refused before
    anything is written, naming both (before, one table replaced the other: "wrote 13 files", 9 existed)."""
    from analysis.synthetic import seed001_2afc_log
    from analysis.tables import to_csv

    log = seed001_2afc_log(seed=0)
    log = log[log["block"] == log["block"].iloc[0]]
    for other in ("hall_v2", "Hall_V2"):
        log["scene"] = log["scene"].map({"street_night": "hall.v2", "interior": other, "temple": "temple",
                                         "hall.v2": "hall.v2", "hall_v2": other, "Hall_V2": other})
        (tmp_path / "log.csv").write_text(to_csv(log), encoding="utf-8")
        out = tmp_path / "out"
        assert main(["analyze", str(tmp_path / "log.csv"), "--out", str(out), "--no-figures", "--n-boot", "0",
                     "--test", "summary_table"]) == 2
        err = capsys.readouterr().err
        first, second = sorted(["hall.v2", other], key=str)
        assert err == (f"studyapp: error: scene {first!r} and scene {second!r} would both be written as tables "
                       "named ..._hall_v2: rename one in the log\n"), err
        assert not out.exists()
    log["scene"] = log["scene"].map({"hall.v2": "hall.v2", "Hall_V2": "hall-v2", "temple": "temple"})
    (tmp_path / "log.csv").write_text(to_csv(log), encoding="utf-8")
    assert main(["analyze", str(tmp_path / "log.csv"), "--out", str(out), "--no-figures", "--n-boot", "0",
                 "--test", "summary_table"]) == 0
    printed = int(re.search(r"wrote (\d+) files", capsys.readouterr().out).group(1))
    assert printed == len([p for p in out.rglob("*") if p.is_file()])
    tables = sorted(p.name for p in (out / "tables").glob("2afc_summary_table_*.md"))
    assert tables == ["2afc_summary_table_hall-v2.md", "2afc_summary_table_hall_v2.md",
                      "2afc_summary_table_temple.md"], tables

