"""Paper tables from the analysis results: Markdown, LaTeX (booktabs) and CSV, byte-stable.

A :class:`Table` is a grid of already formatted strings plus a caption; :func:`to_markdown`,
:func:`to_latex` and :func:`to_csv` render it. The builders turn the tidy results of
:mod:`analysis.study` into the seeds' layouts:

* :func:`pairwise_p_table` - the '/' matrix of seed 001 Tables 2-3,
* :func:`summary_vs_reference_table` - avg ± std, p, Cohen's d, effect size of seed 003 Tables 5-6,
* :func:`votes_table`, :func:`scale_table`, :func:`omnibus_table`.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from data_schema.errors import UserError

from .stats import format_p, format_p_cell, pairwise_matrix

__all__ = [
    "Table",
    "fmt_num",
    "gee_table",
    "omnibus_table",
    "pairwise_p_table",
    "scale_table",
    "summary_vs_reference_table",
    "to_csv",
    "to_latex",
    "to_markdown",
    "votes_table",
]


@dataclass(frozen=True)
class Table:
    """Header + rows of strings, a caption, and an optional first-column header."""

    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    caption: str = ""
    label: str = ""


def fmt_num(x: float, decimals: int = 2) -> str:
    """Fixed decimals; ``'inf'``/``'-inf'``; ``'n/a'`` for NaN (never an empty cell for a number)."""
    x = float(x)
    if math.isnan(x):
        return "n/a"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    s = f"{x:.{decimals}f}"
    return "0." + "0" * decimals if s == "-0." + "0" * decimals else s


def to_markdown(t: Table) -> str:
    def esc(s: str) -> str:
        return s.replace("|", "\\|")

    lines = []
    if t.caption:
        lines += [f"**{t.caption}**", ""]
    lines.append("| " + " | ".join(esc(h) for h in t.header) + " |")
    lines.append("|" + "|".join("---" for _ in t.header) + "|")
    lines += ["| " + " | ".join(esc(c) for c in r) + " |" for r in t.rows]
    return "\n".join(lines) + "\n"


_TEX = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
        "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}"}


def _tex(s: str) -> str:
    s = "".join(_TEX.get(ch, ch) for ch in s)
    return s.replace("±", r"$\pm$").replace("<", r"$<$").replace(">", r"$>$")


def to_latex(t: Table) -> str:
    """A booktabs ``table`` environment (needs ``\\usepackage{booktabs}``)."""
    cols = "l" + "r" * (len(t.header) - 1)
    lines = [r"\begin{table}[t]", r"\centering"]
    if t.caption:
        lines.append(r"\caption{" + _tex(t.caption) + "}")
    if t.label:
        lines.append(r"\label{" + t.label + "}")
    lines += [r"\begin{tabular}{" + cols + "}", r"\toprule", " & ".join(_tex(h) for h in t.header) + r" \\",
              r"\midrule"]
    lines += [" & ".join(_tex(c) for c in r) + r" \\" for r in t.rows]
    lines += [r"\bottomrule", r"\end{tabular}", r"\end{table}"]
    return "\n".join(lines) + "\n"


def to_csv(df: pd.DataFrame) -> str:
    """Tidy CSV with full precision (``repr`` of floats: round-trips exactly), ``\\n`` line ends."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(df.columns))
    for row in df.itertuples(index=False, name=None):
        w.writerow([_csv_cell(v) for v in row])
    return buf.getvalue()


def _csv_cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, (float, np.floating)):
        v = float(v)
        return "" if math.isnan(v) else repr(v)
    if isinstance(v, (bool, np.bool_)):
        return "1" if v else "0"
    if isinstance(v, (np.integer,)):
        return str(int(v))
    return str(v)


def _name(c: str, labels: dict) -> str:
    return labels.get(c, c)


def pairwise_p_table(pairwise: pd.DataFrame, order: list[str], caption: str, labels: dict | None = None,
                     column: str = "p_adj") -> Table:
    """Seed 001 Tables 2-3: Holm-adjusted p of every pair; '/' on and below the diagonal.

    As in the seed, the last condition's row (all '/') is left out.
    """
    labels = labels or {}
    m = pairwise_matrix(pairwise, order=order, column=column)
    header = ("P values", *(_name(c, labels) for c in order))
    rows = tuple((_name(r, labels), *(str(v) for v in m.loc[r])) for r in order[:-1])
    return Table(header, rows, caption)


def summary_vs_reference_table(summary: pd.DataFrame, reference: str, caption: str,
                               labels: dict | None = None, decimals: int = 2) -> Table:
    """Seed 003 Tables 5-6: con., avg ± std. dev., p value, Cohen's d, effect size ('/' for the reference).

    ``d`` is printed with its sign (condition minus reference); the seed prints magnitudes.
    """
    labels = labels or {}
    if summary.empty:
        raise UserError("empty summary: nothing to tabulate")
    first = summary.iloc[0]
    rows = [(_name(reference, labels), (f"{fmt_num(first['mean_ref'], decimals)} ± "
             f"{fmt_num(first['std_ref'], decimals)}"), "/", "/", "/")]
    for r in summary.itertuples(index=False):
        rows.append((_name(r.condition, labels), f"{fmt_num(r.mean, decimals)} ± {fmt_num(r.std, decimals)}",
                     format_p_cell(r.p), fmt_num(r.d, decimals), str(r.label)))
    return Table(("con.", "avg. ± std. dev.", "p value", "Cohen's d", "effect size"), tuple(rows), caption)


def gee_table(gee: pd.DataFrame, caption: str, labels: dict | None = None) -> Table:
    """Logistic GEE odds ratios: condition, answers, rate, OR [95 % CI], p; 'n/a' and the note when undefined."""
    labels = labels or {}
    rows = []
    for r in gee.itertuples(index=False):
        if math.isnan(r.odds_ratio):
            rows.append((_name(r.condition, labels), str(r.n), fmt_num(r.rate, 2), "n/a", "n/a", str(r.note)))
            continue
        rows.append((_name(r.condition, labels), str(r.n), fmt_num(r.rate, 2),
                     f"{fmt_num(r.odds_ratio, 2)} [{fmt_num(r.ci_low, 2)}, {fmt_num(r.ci_high, 2)}]",
                     format_p(r.p), str(r.note)))
    return Table(("con.", "answers", "rate", "odds ratio [95% CI]", "p value", "note"), tuple(rows), caption)


def votes_table(votes: pd.DataFrame, order: list[str], caption: str, labels: dict | None = None) -> Table:
    """Votes per condition (rows) and block/scene (columns), with the total (seed 001 Fig 14-15 data)."""
    labels = labels or {}
    keys = list(dict.fromkeys(zip(votes["block"], votes["scene"])))
    multi_block = len({b for b, _ in keys}) > 1
    header = ["condition", *[(f"{b} / {s}" if multi_block and b else s) for b, s in keys], "total", "share"]
    rows = []
    for c in order:
        sel = votes[votes["condition"] == c]
        cells = []
        for b, s in keys:
            v = sel[(sel["block"] == b) & (sel["scene"] == s)]["votes"]
            cells.append(str(int(v.iloc[0])) if len(v) else "0")
        tot, shown = int(sel["votes"].sum()), int(sel["shown"].sum())
        rows.append((_name(c, labels), *cells, str(tot), fmt_num(tot / shown if shown else float("nan"), 3)))
    return Table(tuple(header), tuple(rows), caption)


def scale_table(scale: pd.DataFrame, caption: str, labels: dict | None = None) -> Table:
    """Scores with their bootstrap intervals (JOD and Bradley-Terry, or Plackett-Luce)."""
    labels = labels or {}
    cols = [c for c in ("jod", "bt", "score") if c in scale.columns]
    names = {"jod": "JOD", "bt": "Bradley-Terry", "score": "Plackett-Luce"}
    header = ["condition"]
    for c in cols:
        header.append(names[c])
        lo = "jod_ci_low" if c == "jod" else ("bt_ci_low" if c == "bt" else "ci_low")
        if lo in scale.columns:
            header.append(f"{names[c]} 95% CI")
    rows = []
    for r in scale.to_dict("records"):
        cells = [_name(r["condition"], labels)]
        for c in cols:
            cells.append(fmt_num(r[c], 2))
            lo, hi = {"jod": ("jod_ci_low", "jod_ci_high"), "bt": ("bt_ci_low", "bt_ci_high"),
                      "score": ("ci_low", "ci_high")}[c]
            if lo in r:
                cells.append(f"[{fmt_num(r[lo], 2)}, {fmt_num(r[hi], 2)}]")
        rows.append(tuple(cells))
    return Table(tuple(header), tuple(rows), caption)


def omnibus_table(omnibus: pd.DataFrame, caption: str) -> Table:
    rows = tuple((str(r.block), str(r.scene), fmt_num(r.H, 3), str(int(r.df)), format_p(r.p), str(int(r.N)))
                 for r in omnibus.itertuples(index=False))
    return Table(("block", "scene", "H", "df", "p", "N"), rows, caption)
