"""The benchmarks' report helpers: the command a section records reruns the same arguments, and a section is
replaced without touching the others."""

import shlex

from hypothesis import given, strategies as st

from benchmarks._report import command_line, peak_rss_mb, replace_section, without_time_report


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
    from benchmarks.bench_gpu import run_child

    script = tmp_path / "child.py"
    script.write_text("raise RuntimeError('renderer produced negative radiance')\n")
    try:
        run_child(str(script), [], "gpu yard sl_gt")
    except RuntimeError as exc:
        assert str(exc).splitlines()[0] == "gpu yard sl_gt failed:"
        assert str(exc).splitlines()[-1] == "RuntimeError: renderer produced negative radiance"
    else:
        raise AssertionError("a failing child must raise")
