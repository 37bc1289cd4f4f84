"""The benchmarks' report helpers: the command a section records reruns the same arguments, and a section is
replaced without touching the others."""

import shlex

from hypothesis import given, strategies as st

from benchmarks._report import command_line, replace_section


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
