"""Writing a study's analysis to a folder: report.md, tables (md, tex, csv), figures (png), analysis.json.

Layout of ``out_dir``::

    report.md                 every table and figure with the plan and the notes
    analysis.json             the tidy tables as lists of records (what ``--json`` prints)
    tables/<name>.csv         tidy results, full precision
    tables/<name>.md|.tex     the paper layouts (seed 001 Tables 2-3, seed 003 Tables 5-6, ...)
    figures/<name>.png        votes, scale and score plots

The same log and plan give byte-identical files (no dates, no software versions, fixed seeds).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from data_schema import families

from .study import ALL, StudyAnalysis
from .tables import (
    Table,
    fmt_num,
    gee_table,
    omnibus_table,
    pairwise_p_table,
    scale_table,
    summary_vs_reference_table,
    to_csv,
    to_latex,
    to_markdown,
    votes_table,
)

__all__ = ["report_json", "threshold_tables", "write_report", "write_threshold_report"]

_FAMILY_TITLE = {name: fam.title for name, fam in families.FAMILIES.items()}


def _json_value(v):
    if isinstance(v, (np.floating, float)):
        v = float(v)
        if math.isnan(v):
            return None
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return v
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.bool_,)):
        return bool(v)
    return v


def report_json(res: StudyAnalysis) -> dict:
    """The analysis as plain JSON-able data: plan, counts, notes and every tidy table as records."""
    tables = {}
    for name, df in res.tables.items():
        if name.endswith("_units"):
            continue  # one row per unit: in the CSV, not in the JSON summary
        tables[name] = [{k: _json_value(v) for k, v in rec.items()} for rec in df.to_dict("records")]
    return {"plan": res.plan.to_dict(), "families": res.families, "conditions": res.conditions,
            "n_trials": res.n_trials, "n_participants": res.n_participants, "notes": res.notes,
            "tables": tables}


def _group_title(block: str, scene: str) -> str:
    if block == ALL and scene == ALL:
        return "all trials"
    if scene == ALL:
        return f"block {block}"
    return f"scene {scene}"


def write_report(res: StudyAnalysis, out_dir, title: str = "Study analysis", figures: bool = True,
                 progress=None) -> list[Path]:
    """Write every table and figure of ``res`` into ``out_dir``; return the paths written."""
    from data_schema.atomic import write_text
    from data_schema.names import inside

    say = progress or (lambda msg: None)
    out = Path(out_dir)
    tdir, fdir = out / "tables", out / "figures"
    suffixes = group_suffixes(res)
    written: list[Path] = []
    labels = res.plan.labels
    md = [f"# {title}", ""]
    fam_counts = ", ".join(f"{_FAMILY_TITLE[f]}: {res.n_trials[f]:,} trials from {res.n_participants[f]} "
                           "participants" for f in res.families)
    md += [f"Log: {fam_counts}.", "", "Plan: " + ", ".join(
        f"{k}={' '.join(map(str, v)) if isinstance(v, list) else v}" for k, v in res.plan.to_dict().items()
        if k not in ("labels",) and v not in (None, {})), ""]
    md += [f"- {n}" for n in res.notes] + [""]

    def emit(name: str, table: Table | None, tidy: pd.DataFrame | None) -> None:
        if tidy is not None:
            written.append(write_text(inside(tdir, f"{name}.csv"), to_csv(tidy)))
        if table is not None:
            written.append(write_text(inside(tdir, f"{name}.md"), to_markdown(table)))
            written.append(write_text(inside(tdir, f"{name}.tex"), to_latex(table)))
            md.extend([to_markdown(table), ""])

    for fam in res.families:
        family = families.get(fam)
        order = res.conditions[fam]
        reference = res.plan.reference or order[0]
        md += [f"## {_FAMILY_TITLE[fam]}", ""]
        say(f"{fam}: tables")
        t = res.tables
        if f"{fam}_votes" in t:
            votes = t[f"{fam}_votes"]
            emit(f"{fam}_votes", votes_table(votes, order, f"Votes per condition and scene ({fam})", labels), votes)
            if figures:
                p = fdir / f"{fam}_votes.png"
                from .figures import votes_figure

                written.append(votes_figure(votes, order, p, f"User preference ({fam})", labels))
                md += [f"![votes]({p.relative_to(out).as_posix()})", ""]
        emit(f"{fam}_omnibus", omnibus_table(t[f"{fam}_omnibus"], f"Kruskal-Wallis over all conditions ({fam})"),
             t[f"{fam}_omnibus"])
        for name, what in (("pairwise", "Kruskal-Wallis test for pairwise comparisons"),
                           ("dunn", "Dunn's test after Kruskal-Wallis")):
            if f"{fam}_{name}" not in t:
                continue
            pw = t[f"{fam}_{name}"]
            written.append(write_text(tdir / f"{fam}_{name}.csv", to_csv(pw)))
            for (block, scene), grp in pw.groupby(["block", "scene"], sort=False):
                present = [c for c in order if c in set(grp["A"]) | set(grp["B"])]
                suffix = suffixes[str(block), str(scene)]
                cap = f"{what}, Holm-adjusted p ({fam}, {_group_title(block, scene)})"
                emit(f"{fam}_{name}_matrix{suffix}", pairwise_p_table(grp, present, cap, labels), None)
        if f"{fam}_summary" in t:
            sm = t[f"{fam}_summary"]
            written.append(write_text(tdir / f"{fam}_summary.csv", to_csv(sm)))
            for (block, scene), grp in sm.groupby(["block", "scene"], sort=False):
                suffix = suffixes[str(block), str(scene)]
                cap = f"Scores against {labels.get(reference, reference)} ({fam}, {_group_title(block, scene)})"
                emit(f"{fam}_summary_table{suffix}", summary_vs_reference_table(grp, reference, cap, labels), None)
        if f"{fam}_units" in t:
            written.append(write_text(tdir / f"{fam}_units.csv", to_csv(t[f"{fam}_units"])))
            if family.kind == "score" and figures:
                from .figures import scores_figure

                p = fdir / f"{fam}_scores.png"
                written.append(scores_figure(t[f"{fam}_units"], order, p, "Mean score per condition", labels))
                md += [f"![scores]({p.relative_to(out).as_posix()})", ""]
        if f"{fam}_gee" in t:
            g = t[f"{fam}_gee"]
            cap = (f"Logistic GEE ({fam}): {family.gee_odds_caption} {labels.get(reference, reference)}, "
                   "95 % Wald intervals "
                   "(participants as clusters, exchangeable working correlation, robust SEs)")
            emit(f"{fam}_gee", gee_table(g, cap, labels), g)
        scale_name = f"{fam}_scale"
        if scale_name in t:
            sc = t[scale_name]
            what, fig_title = _scale_titles(family, sc)
            ci = f", {res.plan.n_boot} bootstrap replicates over participants" if res.plan.n_boot else ""
            prior = f", prior {res.plan.prior}" if "jod" in sc.columns else ""  # pwcmp's prior: the JOD scale
            emit(scale_name, scale_table(sc, f"{what} scores, reference {reference} = 0{prior}{ci}", labels), sc)
            if figures:
                from .figures import scale_figure

                p = fdir / f"{fam}_scale.png"
                if res.plan.n_boot:
                    fig_title += f" (95 % bootstrap intervals, {res.plan.n_boot} replicates)"
                written.append(scale_figure(sc, p, fig_title, labels))
                md += [f"![scale]({p.relative_to(out).as_posix()})", ""]
    say("report")
    written.append(write_text(out / "analysis.json", json.dumps(report_json(res), indent=2, sort_keys=False)
                              + "\n"))
    written.append(write_text(out / "report.md", "\n".join(md).rstrip("\n") + "\n"))
    return written


def _scale_titles(family: families.TrialFamily, sc: pd.DataFrame) -> tuple[str, str]:
    """The scale table's caption words and the figure's title for the family's ``scale_model``: paired
    comparisons name the scales present (JOD column ``jod``, Bradley-Terry ``bt``), rankings Plackett-Luce."""
    if family.scale_model == "pairs":
        what = " and ".join(n for c, n in (("jod", "Thurstone Case V (JOD)"), ("bt", "Bradley-Terry"))
                            if c in sc.columns)
        return what, "Thurstone Case V scale" if "jod" in sc.columns else "Bradley-Terry scale"
    return "Plackett-Luce", "Plackett-Luce scale"


def _slug(s: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in str(s)).strip("_") or "x"


def group_suffixes(res: StudyAnalysis) -> dict[tuple[str, str], str]:
    """The file-name suffix of every (block, scene) group of ``res``'s tables: ``""`` for all trials, else
    ``_<slug>`` of the scene (or of the block, for a block's group).

    Every group gets its own files: labels whose suffixes would coincide, ignoring case as macOS and Windows do
    (scenes ``hall.v2`` and ``hall_v2``, ``Hall`` and ``hall``, a block and a scene both named ``hall``), are
    refused before anything is written, naming both (one table would silently replace the other).
    """
    from data_schema.errors import UserError
    from data_schema.names import name_key

    groups = {}
    for df in res.tables.values():
        if "block" in df.columns and "scene" in df.columns:
            groups.update(dict.fromkeys(zip(df["block"].astype(str), df["scene"].astype(str))))
    groups.pop((ALL, ALL), None)
    label = {g: ("block", g[0]) if g[1] == ALL else ("scene", g[1]) for g in groups}
    suffix, owner = {}, {}
    for item in sorted(set(label.values())):
        name = _slug(item[1])
        if name_key(name) in owner:
            other = owner[name_key(name)]
            raise UserError(f"{other[0]} {other[1]!r} and {item[0]} {item[1]!r} would both be written as tables "
                            f"named ..._{name}: rename one in the log")
        owner[name_key(name)] = item
        suffix[item] = "_" + name
    return {(ALL, ALL): "", **{g: suffix[label[g]] for g in groups}}


def _g(x: float) -> str:
    """A threshold or cost: 3 significant digits, ``n/a`` for NaN."""
    x = float(x)
    return "n/a" if math.isnan(x) else f"{x:.3g}"


def threshold_tables(res) -> dict[str, Table]:
    """The report's tables of a :class:`analysis.thresholds.ThresholdAnalysis`: the group table, every fit
    (not-estimable rows with their reason) and, with a cost, the Pareto table."""
    from .thresholds import POOLED

    # "correct": 2AFC the original picked; yes/no "not the ground truth" said to the test (detected)
    crit = f"{res.criterion:.0%} correct ({res.family})"
    g = res.group
    out = {"thresholds_group": Table(
        ("condition", "scene", "parameter", "n", "threshold", "95 % CI",
         f"SD ({g['axis'].iloc[0] if len(g) else ''})", "not estimable"),
        tuple((r.condition, r.scene, r.varied, str(r.n_participants), _g(r.threshold),
               f"{_g(r.ci_low)}–{_g(r.ci_high)}", fmt_num(r.sd_x, 3), str(r.n_not_estimable))
              for r in g.itertuples()),
        f"Thresholds at {crit}: mean over participants on the strength axis (a log domain: the geometric mean "
        f"level), between-participant SD, {res.n_boot} bootstrap replicates over participants")}
    f = res.fits
    out["thresholds_fits"] = Table(
        ("participant", "condition", "scene", "trials", "threshold", "95 % CI", "width", "lapse", "guess", "note"),
        tuple((r.participant, r.condition, r.scene, str(r.n_trials), _g(r.threshold),
               f"{_g(r.ci_low)}–{_g(r.ci_high)}" if r.estimable else "", fmt_num(r.width, 3) if r.estimable else "",
               fmt_num(r.lapse, 3) if r.estimable else "", fmt_num(r.guess, 3) if r.estimable else "", r.reason)
              for r in f.itertuples()),
        f"psignifit fits per participant and pooled ({POOLED}); threshold at {crit} with its 95 % credible "
        "interval, width on the strength axis")
    if res.pareto is not None:
        p = res.pareto
        out["thresholds_pareto"] = Table(
            ("condition", "scene", "threshold", f"{res.cost_label} at threshold", "95 % CI", "GT", "relative",
             "relative 95 % CI", "speed-up"),
            tuple((r.condition, r.scene, _g(r.threshold), _g(r.cost), f"{_g(r.cost_ci_low)}–{_g(r.cost_ci_high)}",
                   _g(r.gt_cost), fmt_num(r.relative_cost, 3),
                   f"{fmt_num(r.relative_cost_ci_low, 3)}–{fmt_num(r.relative_cost_ci_high, 3)}",
                   f"{fmt_num(r.speedup, 2)}x") for r in p.itertuples()),
            f"Speed at threshold: {res.cost_label} at the group threshold, its 95 % CI carried through "
            "from the threshold's, against the ground truth's")
        if "time_ms" in p.columns:
            out["thresholds_pareto_time"] = Table(
                ("condition", "scene", "threshold", "ms at threshold", "95 % CI", "GT ms", "time speed-up",
                 "speed-up 95 % CI"),
                tuple((r.condition, r.scene, _g(r.threshold), fmt_num(r.time_ms, 1),
                       f"{fmt_num(r.time_ms_ci_low, 1)}–{fmt_num(r.time_ms_ci_high, 1)}", fmt_num(r.gt_time_ms, 1),
                       f"{fmt_num(r.time_speedup, 2)}x",
                       f"{fmt_num(r.gt_time_ms / r.time_ms_ci_high, 2)}–"
                       f"{fmt_num(r.gt_time_ms / r.time_ms_ci_low, 2)}x") for r in p.itertuples()),
                f"Time at threshold: {res.time_label}, interpolated in log level and log time between the "
                "ladder's measured levels, its 95 % CI carried through from the threshold's, against GT's")
    return out


def _map_figures(fn, jobs: list, workers: int = 2):
    """``fn(*job)`` for every job, in order; in ``workers`` forked processes when there are several (each figure
    is drawn and saved whole by one process: the files do not depend on the split)."""
    import multiprocessing as mp

    if workers > 1 and len(jobs) >= 4 and "fork" in mp.get_all_start_methods():
        import concurrent.futures as cf

        with cf.ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("fork")) as ex:
            yield from ex.map(fn, *zip(*jobs))
        return
    for job in jobs:
        yield fn(*job)


def write_threshold_report(res, out_dir, title: str = "Threshold study", figures: bool = True,
                           progress=None) -> list[Path]:
    """Write a threshold study's analysis (:class:`analysis.thresholds.ThresholdAnalysis`) into ``out_dir``:
    report.md, analysis.json, tables/thresholds_*.csv|md|tex, figures/fits_<participant>.png (a panel per
    fit), figures/pareto.png."""
    from data_schema.atomic import write_text
    from data_schema.names import inside

    from .thresholds import POOLED, PRIOR_TEXT

    say = progress or (lambda msg: None)
    out = Path(out_dir)
    tdir, fdir = out / "tables", out / "figures"
    written: list[Path] = []
    n_p = res.trials["participant"].nunique()
    md = [f"# {title}", "", f"Log: {len(res.trials):,} adaptive trials from {n_p} participants.", "",
          f"Fit: {res.settings}.", "", f"Prior: {PRIOR_TEXT}.", ""]
    md += [f"- {n}" for n in (res.notes or [])] + [""]
    tables = threshold_tables(res)
    tidy = {"thresholds_group": res.group, "thresholds_fits": res.fits, "thresholds_pareto": res.pareto,
            "thresholds_pareto_curves": res.curves}
    for name in ("thresholds_pareto", "thresholds_pareto_time", "thresholds_group", "thresholds_fits"):
        if name not in tables:
            continue
        written.append(write_text(tdir / f"{name}.md", to_markdown(tables[name])))
        written.append(write_text(tdir / f"{name}.tex", to_latex(tables[name])))
        md += [to_markdown(tables[name]), ""]
        if name == "thresholds_pareto" and figures:
            from .figures import pareto_figure

            p = pareto_figure(res.curves, res.pareto, fdir / "pareto.png",
                              "Speed at threshold: cost against probability of detection (pooled fits; "
                              "points: group thresholds, bars: 95 % CI)", f"{res.cost_label} relative to GT")
            written.append(p)
            md += [f"![pareto]({p.relative_to(out).as_posix()})", ""]
    for name, df in tidy.items():
        if df is not None:
            written.append(write_text(tdir / f"{name}.csv", to_csv(df)))
    if figures:
        from .figures import psychometric_figure

        md += ["## Fits", ""]
        who = sorted(set(res.fits["participant"]) - {POOLED}) + [POOLED]
        jobs = [(res.trials if pid == POOLED else res.trials[res.trials["participant"] == pid],
                 res.fits[res.fits["participant"] == pid],
                 inside(fdir, f"fits_{'pooled' if pid == POOLED else _slug(pid)}.png"),
                 f"{pid}: proportion correct per level (marker area ∝ trials), fit, threshold and 95 % CI")
                for pid in who]
        for i, (pid, p) in enumerate(zip(who, _map_figures(psychometric_figure, jobs))):
            say(f"fit figures {i + 1}/{len(who)}")
            written.append(p)
            md += [f"![{pid}]({p.relative_to(out).as_posix()})", ""]
    doc = {"family": res.family, "criterion": res.criterion, "settings": res.settings, "prior": PRIOR_TEXT,
           "notes": res.notes or [], "tables": {k: [{c: _json_value(v) for c, v in rec.items()}
                                                    for rec in df.to_dict("records")]
                                                for k, df in tidy.items()
                                                if df is not None and k != "thresholds_pareto_curves"}}
    written.append(write_text(out / "analysis.json", json.dumps(doc, indent=2) + "\n"))
    written.append(write_text(out / "report.md", "\n".join(md).rstrip("\n") + "\n"))
    return written
