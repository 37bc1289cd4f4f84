"""The benchmark harness (benchmarks/harness.py): every script uses it and no script imports another; a child per
configuration with its peak memory and the load (in every script but the stated exceptions); the command a section
records reruns the same arguments; a section is replaced without touching the others; raw results go to the ignored
benchmarks/results/, not docs/."""

import ast
import datetime
import json
import shlex
import subprocess
from pathlib import Path

from hypothesis import given, strategies as st

from benchmarks import harness
from benchmarks.harness import command_line, peak_rss_mb, replace_section, run_child, without_time_report

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted((ROOT / "benchmarks").glob("bench_*.py"))


def test_recorded_command_keeps_empty_and_quoted_arguments():
    argv = ["--methods", "fsl,sl_e,fsl'", "--ratio-size", "", "--section", "gpu-lightcuts-gt"]
    line = command_line("benchmarks/bench_gpu_lightcuts.py", argv)
    assert line == ("python benchmarks/bench_gpu_lightcuts.py --methods \"fsl,sl_e,fsl'\" --ratio-size \"\" "
                    "--section gpu-lightcuts-gt")
    assert shlex.split(line)[2:] == argv


@given(st.lists(st.text(alphabet=st.characters(blacklist_categories=("Cs", "Cc"))), max_size=6))
def test_recorded_command_splits_back_into_its_arguments(argv):
    assert shlex.split(command_line("b.py", argv)) == ["python", "b.py", *argv]


def test_a_section_is_replaced_and_the_others_kept(tmp_path):
    doc = tmp_path / "benchmarks.md"
    replace_section(str(doc), "a", ["first a"])
    replace_section(str(doc), "b", ["only b"])
    replace_section(str(doc), "a", ["second a"])
    text = doc.read_text()
    assert "second a" in text and "first a" not in text and "only b" in text
    assert text.index("<!-- a:start -->") < text.index("<!-- b:start -->")


def test_a_failed_childs_error_is_its_last_line_not_the_time_report():
    # /usr/bin/time -v appends its report to the child's standard error, burying the child's error
    stderr = ("Traceback (most recent call last):\n  File \"x.py\", line 1\n"
              "RuntimeError: renderer 'sl_gt' produced negative radiance\n"
              "Command exited with non-zero status 1\n\tCommand being timed: \"python x.py\"\n\tUser time (seconds): 1.0\n"
              "\tMaximum resident set size (kbytes): 2048\n\tExit status: 1\n")
    assert without_time_report(stderr).splitlines()[-1] == "RuntimeError: renderer 'sl_gt' produced negative radiance"
    assert peak_rss_mb(stderr) == 2.0
    assert without_time_report("no report\n") == "no report\n"


def test_run_child_reports_the_childs_error(tmp_path):
    script = tmp_path / "child.py"
    script.write_text("raise RuntimeError('renderer produced negative radiance')\n")
    try:
        run_child([str(script)], "gpu yard sl_gt")
    except RuntimeError as exc:
        assert str(exc).splitlines()[0] == "gpu yard sl_gt failed:"
        assert str(exc).splitlines()[-1] == "RuntimeError: renderer produced negative radiance"
    else:
        raise AssertionError("a failing child must raise")


def _benchmark_imports(path: Path) -> set[str]:
    """The modules of ``benchmarks/`` (and sibling scripts) that ``path`` imports."""
    names = {p.stem for p in SCRIPTS} | {"harness", "_report"}
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            mods = [node.module or ""] + ([f"{node.module}.{a.name}" for a in node.names] if node.module else [])
        elif isinstance(node, ast.Import):
            mods = [a.name for a in node.names]
        else:
            continue
        for m in mods:
            parts = m.split(".")
            if parts[0] == "benchmarks" and len(parts) > 1:
                found.add(parts[1])
            elif parts[0] in names:
                found.add(parts[0])
    return found


def test_every_script_uses_the_harness_and_imports_no_other_script():
    assert len(SCRIPTS) >= 13
    for path in SCRIPTS:
        used = _benchmark_imports(path)
        assert "harness" in used, f"{path.name} does not use benchmarks/harness.py"
        others = used - {"harness", path.stem}  # bench_render imports itself: Dask tasks by reference
        assert not others, f"{path.name} imports {sorted(others)}: shared code belongs in the harness"


#: Scripts that measure sessions, windows or Dask workers (what they start is what they measure), not
#: configurations in children: the list docs/benchmarks.md's introduction states.
NO_CHILD_PER_CONFIGURATION = {"bench_render", "bench_live", "bench_presentation", "bench_cluster"}


def _calls_run_child(path: Path) -> bool:
    """Whether ``path`` calls ``run_child`` (``run_child(...)`` or ``harness.run_child(...)``)."""
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Call):
            f = node.func
            if (isinstance(f, ast.Name) and f.id == "run_child") or (isinstance(f, ast.Attribute)
                                                                     and f.attr == "run_child"):
                return True
    return False


def test_every_script_runs_each_configuration_in_a_child_but_the_stated_exceptions():
    names = {p.stem for p in SCRIPTS}
    assert NO_CHILD_PER_CONFIGURATION <= names
    missing = sorted(p.stem for p in SCRIPTS if p.stem not in NO_CHILD_PER_CONFIGURATION and not _calls_run_child(p))
    assert not missing, f"{missing} measure configurations without harness.run_child (one child per configuration)"
    intro = (ROOT / "docs" / "benchmarks.md").read_text(encoding="utf-8").split("\n<!-- ", 1)[0]
    assert all(f"`{n}.py`" in intro for n in NO_CHILD_PER_CONFIGURATION), "docs/benchmarks.md must state the exceptions"


def test_raw_results_are_ignored_and_not_in_docs():
    assert not [p.name for p in (ROOT / "docs").iterdir()
                if p.name.startswith("bench_") and p.suffix in (".csv", ".json", ".png")]
    assert Path(harness.RESULTS) == ROOT / "benchmarks" / "results"
    ignored = subprocess.run(["git", "check-ignore", "-q", "benchmarks/results/bench_gpu.csv"], cwd=ROOT)
    assert ignored.returncode == 0, "benchmarks/results/ must be in .gitignore"
    text = "\n".join(p.read_text(encoding="utf-8") for p in [*(ROOT / "docs").glob("*.md"), ROOT / "README.md"])
    assert "docs/bench_" not in text


def test_a_child_row_gets_its_peak_memory_wall_time_and_load(tmp_path):
    script = tmp_path / "child.py"
    script.write_text("import json, sys\nblock = bytearray(64 * 2**20)\nprint('noise')\n"
                      "print(json.dumps({'arg': sys.argv[1]}))\n")
    row = run_child([str(script), "x"], "child")
    assert row["arg"] == "x" and row["wall_s"] > 0 and row["load"] >= 0
    assert 64 <= row["peak_mb"] < 1024  # the child's 64 MB block counts, the parent's memory does not
    assert set(run_child([str(script), "y"], "child", row=False)) == {"peak_mb", "wall_s", "load"}


def test_the_machine_line_names_the_date_and_results_go_to_the_results_folder(tmp_path, monkeypatch):
    assert datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d") in harness.machine_line()
    monkeypatch.setattr(harness, "RESULTS", str(tmp_path / "results"))
    path = harness.write_csv([{"a": 1}, {"a": 2, "b": 3}], "x.csv")
    assert Path(path).read_text().splitlines() == ["a,b", "1,", "2,3"]
    assert json.loads(Path(harness.write_json({"k": [1]}, "x.json")).read_text()) == {"k": [1]}
