"""Range-checked logs (data-integrity issue, item B): a duplicated column, a yes/no response outside {0, 1}, a
practice/catch flag outside {0, 1} are each refused in one line naming the file, the column, the first bad line and
its value; the CLI exits 2 with that one line and writes nothing."""

from __future__ import annotations

import pandas as pd
import pytest

from analysis.io import LogError, read_log, validate_log
from analysis.synthetic import seed003_yes_no_log
from analysis.tables import to_csv
from studyapp.cli import main


@pytest.fixture(scope="module")
def log() -> pd.DataFrame:
    return seed003_yes_no_log(6, n_participants=3)


def _at(series: pd.Series, i: int, value) -> list:
    out = list(series.astype(object))
    out[i] = value
    return out


CASES = {
    "response 7": (lambda d: d.assign(response=_at(d.response, 5, 7)), "line 7: column response of a yes_no trial "
                   "must be 0 or 1, found 7"),
    "response -1": (lambda d: d.assign(response=_at(d.response, 0, -1)), "line 2: column response of a yes_no "
                    "trial must be 0 or 1, found -1"),
    "response 0.5": (lambda d: d.assign(response=_at(d.response, 3, 0.5)), "line 5: column response of a yes_no "
                     "trial must be 0 or 1, found 0.5"),
    "practice maybe": (lambda d: d.assign(practice=_at(pd.Series([0] * len(d)), 4, "maybe")),
                       "line 6: column practice (a flag) must be 0 or 1, found 'maybe'"),
    "practice 2": (lambda d: d.assign(practice=_at(pd.Series([0] * len(d)), 9, 2)),
                   "line 11: column practice (a flag) must be 0 or 1, found 2"),
    "catch -1": (lambda d: d.assign(catch=_at(pd.Series([0] * len(d)), 2, -1)),
                 "line 4: column catch (a flag) must be 0 or 1, found -1"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_out_of_domain_values_are_refused_in_one_line(tmp_path, log, case):
    mutate, message = CASES[case]
    p = tmp_path / "bad.csv"
    p.write_text(to_csv(mutate(log)))
    with pytest.raises(LogError) as err:
        read_log(p)
    assert str(err.value) == f"{p}: {message}"


def test_duplicated_column_is_refused(tmp_path, log):
    text = to_csv(log)
    header, rest = text.split("\n", 1)
    p = tmp_path / "dup.csv"
    p.write_text(header.replace("session", "scene", 1) + "\n" + rest)
    with pytest.raises(LogError, match=r"dup.csv: column 'scene' appears twice in the header \(columns 2 and 4\)$"):
        read_log(p)
    frame = pd.concat([log, log[["scene"]]], axis=1)  # a table with two 'scene' columns (e.g. from Parquet)
    with pytest.raises(LogError, match="column 'scene' appears twice"):
        validate_log(frame, "t.parquet")


def test_in_domain_values_are_read(tmp_path, log):
    ok = log.assign(practice=[""] * 2 + [0] * (len(log) - 3) + [1], catch=False,
                    response=log.response.astype(float))
    p = tmp_path / "ok.csv"
    p.write_text(to_csv(ok))
    back = read_log(p)
    assert len(back) == len(log) - 1  # the one practice trial; empty flags count as 0
    assert set(back.response) == {0.0, 1.0}
    # 2AFC rows carry no response: only yes/no rows are checked
    mixed = pd.concat([log, pd.DataFrame({"participant": ["P9"], "scene": ["s"], "family": ["2afc"],
                                          "condition_a": ["EC"], "condition_b": ["CC2"], "chosen": ["EC"]})])
    assert len(validate_log(mixed)) == len(mixed)


def test_row_numbers_for_frames(log):
    with pytest.raises(LogError, match=r"^frame: row 6: column response"):
        validate_log(log.assign(response=_at(log.response, 5, 3)), "frame")


@pytest.mark.parametrize("case", ["response 7", "practice maybe"])
def test_cli_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, log, case):
    mutate, message = CASES[case]
    p = tmp_path / "bad.csv"
    p.write_text(to_csv(mutate(log)))
    out = tmp_path / "x"
    assert main(["analyze", str(p), "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert captured.err == f"studyapp: error: {p}: {message}\n"
    assert not out.exists()


def test_cli_duplicated_column_exits_2(tmp_path, capsys, log):
    text = to_csv(log)
    header, rest = text.split("\n", 1)
    p = tmp_path / "bad.csv"
    p.write_text(header + ",response\n" + rest.replace("\n", ",1\n"))
    assert main(["analyze", str(p), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "column 'response' appears twice" in err and not (tmp_path / "x").exists()
