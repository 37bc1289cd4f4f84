"""A study's whole analysis, from the tidy trial log to named tidy tables.

:func:`analyze_log` follows an :class:`~analysis.plan.AnalysisPlan` and returns a
:class:`StudyAnalysis`: an ordered mapping of table name to tidy DataFrame, plus the notes
the report prints. Everything is computed from integer codes with ``numpy.bincount`` so that
a log of 10^7 trials is analysed in seconds; no per-trial Python loop.

Tables (per trial family present in the log; names are stable):

``<fam>_votes``
    votes per block, scene and condition (2AFC: times chosen and shown; preference: first
    and second choices, offered) - seed 001 Fig 14-15.
``<fam>_units``
    the dependent variable per unit of analysis and condition (what the tests compare).
``<fam>_omnibus``
    Kruskal-Wallis over all conditions (and per scene); always.
``<fam>_pairwise`` (test ``pairwise_kruskal``)
    Kruskal-Wallis on every pair, Holm across the pairs (seed 001 Tables 2-3), overall and
    per scene/block.
``<fam>_dunn`` (test ``kruskal_dunn``)
    Dunn's test (Holm) as the post-hoc of the omnibus test.
``<fam>_summary`` (test ``summary_table``)
    mean ± SD, p, Cohen's d and label of every condition against the reference (seed 003
    Tables 5-6), overall and per scene.
``<fam>_scale`` (the family's ``scale_tests``: ``thurstone``, ``bradley_terry`` / ``plackett_luce``)
    Thurstone Case V (JOD) and Bradley-Terry scores (2AFC) or Plackett-Luce scores
    (preference) with bootstrap intervals over participants, under the plan's prior; the family's
    ``scale_model`` picks the scaling (:data:`SCALES`).
``<fam>_gee`` (test ``gee``; yes/no and 2AFC)
    Logistic GEE odds ratios against the reference (:func:`analysis.gee.logistic_gee`).

Degenerate data never abort the report: an untestable pair has p = NaN with a note, an undefined
effect size d = NaN with the reason as its label, an inestimable odds ratio NaN with a note.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from data_schema import families
from data_schema.errors import UserError

from .gee import logistic_gee
from .plan import AnalysisPlan
from .scaling import bradley_terry, plackett_luce, thurstone_jod
from .stats import dunn, kruskal, pairwise_kruskal, summary_table
from .vocabulary import DV_FAMILIES

__all__ = ["StudyAnalysis", "analyze_log", "condition_order"]

ALL = "(all)"


@dataclass
class StudyAnalysis:
    """Named tidy tables (insertion order = report order) and the report's notes."""

    plan: AnalysisPlan
    families: list[str]
    conditions: dict[str, list[str]]
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    n_trials: dict[str, int] = field(default_factory=dict)
    n_participants: dict[str, int] = field(default_factory=dict)


def _present(cat: pd.Series) -> list[str]:
    """Categories of ``cat`` that occur, as strings."""
    codes = cat.cat.codes.to_numpy()
    used = np.bincount(codes[codes >= 0], minlength=len(cat.cat.categories)) > 0
    return [str(c) for c, u in zip(cat.cat.categories, used) if u]


def condition_order(seen: list[str], plan: AnalysisPlan, family: str) -> list[str]:
    """Conditions in table order: the plan's (all must occur in the log), else sorted."""
    seen_set = set(seen)
    if plan.conditions is None:
        return sorted(seen_set)
    unknown = [c for c in plan.conditions if c not in seen_set]
    if unknown:
        raise UserError(f"analysis plan names condition {unknown[0]!r}, which the {family} trials never show "
                         f"(the log has: {', '.join(sorted(seen_set))})")
    extra = sorted(seen_set - set(plan.conditions))
    if extra:
        raise UserError(f"the {family} trials show condition {extra[0]!r}, which the analysis plan does not "
                         f"list (plan: {', '.join(plan.conditions)})")
    return list(plan.conditions)


def _codes(series: pd.Series, categories: list[str]) -> np.ndarray:
    """Integer codes of ``series`` in ``categories`` (-1 for missing or other values)."""
    if isinstance(series.dtype, pd.CategoricalDtype):
        return series.cat.set_categories(categories).cat.codes.to_numpy().astype(np.int64)
    return pd.Categorical(series.astype(str), categories=categories).codes.astype(np.int64)


def _dense_unique(codes: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(codes, return_inverse=True)`` for codes in ``[0, size)`` in O(n + size), no sort."""
    present = np.bincount(codes, minlength=size) > 0
    remap = np.cumsum(present) - 1
    return np.flatnonzero(present), remap[codes]


def _compact(df: pd.DataFrame) -> pd.DataFrame:
    """Drop unused categories of every categorical column (bincount, not pandas' sort-based version)."""
    for c in df.columns:
        if isinstance(df[c].dtype, pd.CategoricalDtype):
            codes = df[c].cat.codes.to_numpy()
            cats = df[c].cat.categories
            used = np.bincount(codes[codes >= 0], minlength=len(cats)) > 0
            if used.all():
                continue
            remap = np.where(used, np.cumsum(used) - 1, -1)
            df[c] = pd.Categorical.from_codes(np.where(codes >= 0, remap[codes], -1), cats[used])
    return df


def _unit_keys(df: pd.DataFrame, unit: str) -> tuple[np.ndarray, pd.DataFrame]:
    """Code of each row's unit of analysis and a frame describing the units."""
    cols = {"participant": ["participant"], "participant_block": ["participant", "block"],
            "participant_scene": ["participant", "scene"], "trial": ["participant"]}[unit]
    codes = np.zeros(len(df), dtype=np.int64)
    mult = 1
    parts = []
    for c in reversed(cols):
        cc = df[c].cat.codes.to_numpy().astype(np.int64)
        codes += cc * mult
        mult *= len(df[c].cat.categories)
        parts.append(c)
    uniq, inv = _dense_unique(codes, mult)
    desc = {}
    rem = uniq.copy()
    for c in parts:  # reversed order: last column first
        n = len(df[c].cat.categories)
        desc[c] = np.asarray(df[c].cat.categories.astype(str))[rem % n]
        rem //= n
    return inv.astype(np.int64), pd.DataFrame({c: desc[c] for c in cols})


def _group_frames(df: pd.DataFrame, plan: AnalysisPlan) -> list[tuple[str, str, np.ndarray]]:
    """(block, scene, row mask) for the whole log and, with ``per_scene``, each block/scene."""
    out = [(ALL, ALL, np.ones(len(df), dtype=bool))]
    if not plan.per_scene:
        return out
    blocks = _present(df["block"])
    scenes = _present(df["scene"])
    bcode, scode = df["block"].cat.codes.to_numpy(), df["scene"].cat.codes.to_numpy()
    bcats = [str(c) for c in df["block"].cat.categories]
    scats = [str(c) for c in df["scene"].cat.categories]
    if len(blocks) > 1:
        for b in sorted(blocks):
            out.append((b, ALL, bcode == bcats.index(b)))
    if len(scenes) > 1:
        for s in sorted(scenes):
            out.append((ALL, s, scode == scats.index(s)))
    return out


# --- 2AFC and preference: votes ------------------------------------------------------------------------------
def _choice_counts(df: pd.DataFrame, family: families.TrialFamily, conds: list[str]):
    """Per row: codes of the shown conditions (n_rows x m, -1 padded) and of the picks (n_rows x 2): the
    family's reading of its answers (data_schema.families)."""
    return family.shown_and_picks(df, conds, _codes)


def _votes_table(df, shown, picks, conds, family: families.TrialFamily) -> pd.DataFrame:
    """Votes per block, scene and condition; first and second choices apart where the family picks several."""
    k = len(conds)
    bc = [str(c) for c in df["block"].cat.categories]
    sc = [str(c) for c in df["scene"].cat.categories]
    g = df["block"].cat.codes.to_numpy().astype(np.int64) * len(sc) + df["scene"].cat.codes.to_numpy()
    ng = len(bc) * len(sc)

    def count(cols: np.ndarray) -> np.ndarray:
        total = np.zeros(ng * k)
        for j in range(cols.shape[1]):
            c = cols[:, j]
            ok = c >= 0
            total += np.bincount(g[ok] * k + c[ok], minlength=ng * k)
        return total.reshape(ng, k)

    n_shown = count(shown)
    first = count(picks[:, :1])
    second = count(picks[:, 1:])
    rows = []
    for gi in range(ng):
        if n_shown[gi].sum() == 0:
            continue
        for ci, c in enumerate(conds):
            rows.append((bc[gi // len(sc)], sc[gi % len(sc)], c, int(first[gi, ci] + second[gi, ci]),
                         int(first[gi, ci]), int(second[gi, ci]), int(n_shown[gi, ci])))
    out = pd.DataFrame(rows, columns=["block", "scene", "condition", "votes", "first", "second", "shown"])
    if not family.has_picks:
        out = out.drop(columns=["first", "second"])
    out["share"] = np.where(out["shown"] > 0, out["votes"] / out["shown"].where(out["shown"] > 0, 1), np.nan)
    return out.sort_values(["block", "scene"], kind="stable").reset_index(drop=True)


def _unit_values_votes(df, shown, picks, conds, plan, dv="votes") -> pd.DataFrame:
    """votes (times chosen, first or second choice) or chosen (first choices) per unit and condition."""
    k = len(conds)
    if dv == "chosen":
        picks = picks[:, :1]
    if plan.unit == "trial":
        rows_i, cond_i = np.nonzero(np.stack([(shown == c).any(axis=1) for c in range(k)], axis=1))
        chosen = (picks[rows_i] == cond_i[:, None]).any(axis=1).astype(float)
        return pd.DataFrame({"participant": df["participant"].astype(str).to_numpy()[rows_i],
                             "unit": rows_i.astype(np.int64), "condition": np.asarray(conds, dtype=object)[cond_i],
                             "value": chosen})
    inv, units = _unit_keys(df, plan.unit)
    nu = len(units)
    votes = np.zeros(nu * k)
    seen = np.zeros(nu * k)
    for j in range(picks.shape[1]):
        ok = picks[:, j] >= 0
        votes += np.bincount(inv[ok] * k + picks[ok, j], minlength=nu * k)
    for j in range(shown.shape[1]):
        ok = shown[:, j] >= 0
        seen += np.bincount(inv[ok] * k + shown[ok, j], minlength=nu * k)
    votes, seen = votes.reshape(nu, k), seen.reshape(nu, k)
    ui, ci = np.nonzero(seen > 0)
    out = units.iloc[ui].reset_index(drop=True)
    out.insert(len(out.columns), "unit", ui.astype(np.int64))
    out["condition"] = np.asarray(conds, dtype=object)[ci]
    out["value"] = votes[ui, ci]
    out["shown"] = seen[ui, ci].astype(np.int64)
    return out


def _unit_values_response(df, conds, plan) -> pd.DataFrame:
    cond = _codes(df["condition"], conds)
    y = df["response"].to_numpy(dtype=float)
    ok = (cond >= 0) & np.isfinite(y)
    if plan.unit == "trial":
        idx = np.flatnonzero(ok)
        return pd.DataFrame({"participant": df["participant"].astype(str).to_numpy()[idx], "unit": idx,
                             "condition": np.asarray(conds, dtype=object)[cond[idx]], "value": y[idx]})
    inv, units = _unit_keys(df, plan.unit)
    k, nu = len(conds), len(units)
    s = np.bincount(inv[ok] * k + cond[ok], weights=y[ok], minlength=nu * k).reshape(nu, k)
    n = np.bincount(inv[ok] * k + cond[ok], minlength=nu * k).reshape(nu, k)
    ui, ci = np.nonzero(n > 0)
    out = units.iloc[ui].reset_index(drop=True)
    out.insert(len(out.columns), "unit", ui.astype(np.int64))
    out["condition"] = np.asarray(conds, dtype=object)[ci]
    out["value"] = s[ui, ci] / n[ui, ci]
    out["shown"] = n[ui, ci].astype(np.int64)
    return out


# --- tests on the unit values --------------------------------------------------------------------------------
def _omnibus(units: pd.DataFrame, conds: list[str]) -> dict:
    groups = [units.loc[units["condition"] == c, "value"].to_numpy() for c in conds]
    groups = [g for g in groups if g.size]
    if len(groups) < 2:
        raise UserError("fewer than two conditions with data: nothing to compare")
    r = kruskal(*groups)
    return {"H": r.H, "df": r.df, "p": r.p, "N": r.N, "degenerate": r.degenerate}


def _summary(units: pd.DataFrame, conds: list[str], reference: str, plan: AnalysisPlan) -> pd.DataFrame:
    """summary_table of the unit values; undefined effect sizes and untestable rows are NaN with a reason."""
    return summary_table(units, "value", "condition", reference, order=conds, paired=plan.paired,
                         subject="participant" if plan.paired else None)


def _with_group(df: pd.DataFrame, block: str, scene: str) -> pd.DataFrame:
    df = df.copy()
    df.insert(0, "scene", scene)
    df.insert(0, "block", block)
    return df


# --- scaling -------------------------------------------------------------------------------------------------
def _other_prior(plan: AnalysisPlan) -> str:
    """Prior of the Bradley-Terry and Plackett-Luce scales: pwcmp's prior exists for the JOD scale only."""
    return "none" if plan.prior == "none" else "weak"


def _scale_pairs(df, shown, picks, conds, reference, plan) -> pd.DataFrame:
    """Thurstone (JOD) and Bradley-Terry on (participant, winner, loser) counts (exact observer bootstrap)."""
    k = len(conds)
    p = df["participant"].cat.codes.to_numpy().astype(np.int64)
    win = picks[:, 0]
    lose = np.where(shown[:, 0] == win, shown[:, 1], shown[:, 0])
    key = (p * k + win) * k + lose
    counts = np.bincount(key, minlength=len(df["participant"].cat.categories) * k * k)
    uk = np.flatnonzero(counts)
    counts = counts[uk]
    agg = pd.DataFrame({"observer": uk // (k * k), "condition_1": np.asarray(conds, dtype=object)[(uk // k) % k],
                        "condition_2": np.asarray(conds, dtype=object)[uk % k], "selection": 1,
                        "count": counts})
    kw = {"reference": reference, "n_boot": plan.n_boot, "seed": plan.seed, "observer": "observer", "weight": "count"}
    parts = []
    if "thurstone" in plan.tests:
        jod = thurstone_jod(agg, prior=plan.prior, **kw)
        parts.append(jod.rename(columns={"ci_low": "jod_ci_low", "ci_high": "jod_ci_high"}))
    if "bradley_terry" in plan.tests:
        bt = bradley_terry(agg, prior=_other_prior(plan), **kw)
        parts.append(bt.rename(columns={"score": "bt", "ci_low": "bt_ci_low", "ci_high": "bt_ci_high"}))
    if not parts:
        return None
    out = parts[0]
    for extra in parts[1:]:
        out = out.merge(extra.drop(columns=["n_comparisons"]), on="condition")
    out["order"] = [conds.index(c) for c in out["condition"]]
    return out.sort_values("order").drop(columns="order").reset_index(drop=True)


def _scale_rankings(df, shown, picks, conds, reference, plan) -> pd.DataFrame:
    """Plackett-Luce on (participant, offered set, first, second) counts."""
    k = len(conds)
    p = df["participant"].cat.codes.to_numpy().astype(np.int64)
    setc = pd.Categorical(df["conditions"].astype(str)).codes.astype(np.int64)
    nset = int(setc.max()) + 1
    key = ((p * nset + setc) * (k + 1) + picks[:, 0] + 1) * (k + 1) + picks[:, 1] + 1
    _uk, first_idx, counts = np.unique(key, return_index=True, return_counts=True)
    names = np.asarray(conds + [None], dtype=object)
    agg = pd.DataFrame({
        "observer": p[first_idx], "options": df["conditions"].astype(str).to_numpy()[first_idx],
        "first": names[picks[first_idx, 0]], "second": names[picks[first_idx, 1]], "count": counts})
    # plackett_luce has no weight column: expand the aggregated rows (bounded by participants x sets x picks).
    agg = agg.loc[agg.index.repeat(agg["count"])].reset_index(drop=True)
    out = plackett_luce(agg, ranking_cols=("first", "second"), options_col="options", reference=reference,
                        n_boot=plan.n_boot, seed=plan.seed, observer="observer", prior=_other_prior(plan))
    out["order"] = [conds.index(c) for c in out["condition"]]
    return out.sort_values("order").drop(columns="order").reset_index(drop=True)


#: A family's ``scale_model`` -> the scaling of its choices and the note on its priors.
SCALES = {
    "pairs": (_scale_pairs, lambda plan: f"scales: prior {plan.prior!r} (JOD), {_other_prior(plan)!r} "
                                         "(Bradley-Terry)"),
    "rankings": (_scale_rankings, lambda plan: f"Plackett-Luce prior {_other_prior(plan)!r}"),
}


def _scales(family: families.TrialFamily, plan: AnalysisPlan) -> bool:
    """Whether the plan asks for one of the family's scales."""
    return family.scale_model is not None and bool(set(family.scale_tests) & set(plan.tests))


# --- logistic GEE --------------------------------------------------------------------------------------------
def _gee(sub: pd.DataFrame, family: families.TrialFamily, shown, picks, conds: list[str],
         reference: str) -> pd.DataFrame:
    """yes/no: every answer by condition (treatment coding, reference = baseline); 2AFC: the trials that show
    the reference, 1 when the other condition was chosen (no intercept: odds of beating the reference)."""
    part = sub["participant"].astype(str).to_numpy()
    if family.kind == "score":
        data = pd.DataFrame({"participant": part, "condition": sub["condition"].astype(str).to_numpy(),
                             "y": sub["response"].to_numpy(dtype=float)})
        return logistic_gee(data, "y", "condition", "participant", reference, order=conds, intercept=True)
    ref = conds.index(reference)
    with_ref = (shown[:, 0] == ref) | (shown[:, 1] == ref)
    other = np.where(shown[:, 0] == ref, shown[:, 1], shown[:, 0])[with_ref]
    data = pd.DataFrame({"participant": part[with_ref], "condition": np.asarray(conds, dtype=object)[other],
                         "y": (picks[with_ref, 0] == other).astype(float)})
    order = [c for c in conds if c != reference and (data["condition"] == c).any()]
    if not order:
        raise UserError(f"gee: no {family.name} trial shows the reference {reference!r} with another condition")
    return logistic_gee(data, "y", "condition", "participant", reference, order=order, intercept=False)


# --- driver --------------------------------------------------------------------------------------------------
def analyze_log(df: pd.DataFrame, plan: AnalysisPlan | None = None, progress=None) -> StudyAnalysis:
    """Run the plan on a validated tidy log (see :func:`analysis.io.read_log`).

    Raises
    ------
    ValueError
        One line naming the problem: unknown condition names in the plan, fewer than two
        conditions, a choice that was not offered, a non-numeric response, ...
    """
    plan = plan or AnalysisPlan()
    say = progress or (lambda msg: None)
    fams = [f for f in families.NAMES if (df["family"] == f).any()]
    res = StudyAnalysis(plan=plan, families=fams, conditions={})
    for fam in fams:
        sub = _compact(df.loc[(df["family"] == fam).to_numpy()].reset_index(drop=True))
        res.n_trials[fam] = len(sub)
        res.n_participants[fam] = len(sub["participant"].cat.categories)
        say(f"{fam}: {len(sub):,} trials")
        family = families.get(fam)
        seen = sorted({c for col in family.condition_columns for s in _present(sub[col]) for c in s.split("|")})
        conds = condition_order(seen, plan, fam)
        if len(conds) < 2:
            raise UserError(f"the {fam} trials show fewer than two conditions ({', '.join(conds) or 'none'}): "
                             "nothing to compare")
        res.conditions[fam] = conds
        reference = plan.reference if plan.reference is not None else conds[0]
        if reference not in conds:
            raise UserError(f"reference condition {reference!r} does not occur in the {fam} trials "
                             f"(the log has: {', '.join(conds)})")
        dv = plan.dv or family.default_dv
        if fam not in DV_FAMILIES[dv]:
            fits = [d for d, fams in DV_FAMILIES.items() if fam in fams]
            raise UserError(f"dv={dv!r} does not fit {fam} trials (use {' or '.join(fits)})")
        if family.kind == "score":
            shown = picks = None
        else:
            shown, picks = _choice_counts(sub, family, conds)
            res.tables[f"{fam}_votes"] = _votes_table(sub, shown, picks, conds, family)

        omni, pair_rows, dunn_rows, summ_rows, unit_frames = [], [], [], [], []
        for block, scene, mask in _group_frames(sub, plan):
            part = _compact(sub.loc[mask].reset_index(drop=True))
            if family.kind == "score":
                units = _unit_values_response(part, conds, plan)
            else:
                units = _unit_values_votes(part, shown[mask], picks[mask], conds, plan, dv)
            present = [c for c in conds if (units["condition"] == c).any()]
            if len(present) < 2:
                if block == ALL and scene == ALL:
                    raise UserError(f"the {fam} trials have data for fewer than two conditions")
                continue
            if block == ALL and scene == ALL:
                unit_frames.append(units)
            o = _omnibus(units, present)
            omni.append({"block": block, "scene": scene, "test": "kruskal", **o})
            if "pairwise_kruskal" in plan.tests:
                pair_rows.append(_with_group(pairwise_kruskal(units, "value", "condition", order=present),
                                             block, scene))
            if "kruskal_dunn" in plan.tests:
                dunn_rows.append(_with_group(dunn(units, "value", "condition", order=present), block, scene))
            if "summary_table" in plan.tests and reference in present:
                summ_rows.append(_with_group(_summary(units, present, reference, plan), block, scene))
        res.tables[f"{fam}_units"] = unit_frames[0]
        res.tables[f"{fam}_omnibus"] = pd.DataFrame(omni)
        for name, rows in (("pairwise", pair_rows), ("dunn", dunn_rows), ("summary", summ_rows)):
            if rows:
                res.tables[f"{fam}_{name}"] = pd.concat(rows, ignore_index=True)
        if _scales(family, plan):
            say(f"{fam}: scaling")
            res.tables[f"{fam}_scale"] = SCALES[family.scale_model][0](sub, shown, picks, conds, reference, plan)
        if "gee" in plan.tests and "gee" in family.tests:
            say(f"{fam}: logistic GEE")
            res.tables[f"{fam}_gee"] = _gee(sub, family, shown, picks, conds, reference)
        res.notes.append(_unit_note(family, plan, dv, reference))
        res.notes += _degenerate_notes(res, fam)
    return res


def _degenerate_notes(res: StudyAnalysis, fam: str) -> list[str]:
    """One line per kind of undefined result in the family's tables (the tables say which row)."""
    notes = []
    for name, what in (("pairwise", "pairwise Kruskal-Wallis"), ("dunn", "Dunn"), ("summary", "summary")):
        t = res.tables.get(f"{fam}_{name}")
        if t is not None and t["note"].astype(str).str.startswith("not testable").any():
            notes.append(f"{fam}: {what}: pairs whose observations are all tied are not testable (p = NaN, shown "
                         "as 'not testable') and are left out of the Holm count, as R's p.adjust leaves out NA.")
    t = res.tables.get(f"{fam}_summary")
    if t is not None and t["label"].astype(str).str.startswith("undefined").any():
        notes.append(f"{fam}: summary: Cohen's d is undefined for some rows (zero SD, or too few observations): "
                     "shown as n/a with the reason.")
    t = res.tables.get(f"{fam}_gee")
    if t is not None and t["note"].astype(str).str.startswith("not estimable").any():
        notes.append(f"{fam}: GEE: some odds ratios are not estimable (see the note column).")
    return notes


def _unit_note(family: families.TrialFamily, plan: AnalysisPlan, dv: str, reference: str) -> str:
    unit = {"participant": "one value per participant and condition",
            "participant_block": "one value per participant, block and condition",
            "participant_scene": "one value per participant, scene and condition",
            "trial": "every trial is one observation"}[plan.unit]
    what = {"votes": "votes (times chosen, first or second choice)",
            "chosen": family.chosen_caption,
            "response": "mean score (1 = yes/acceptable)"}[dv]
    if plan.unit == "trial":
        what = {"votes": "chosen (1/0) each time a condition was shown",
                "chosen": "chosen first (1/0) each time a condition was shown",
                "response": "score (1 = yes/acceptable)"}[dv]
    d = "paired d_z over participants" if plan.paired else "pooled-SD Cohen's d of independent groups"
    parts = [f"{family.name}: dependent variable {what}; unit of analysis: {unit}; reference {reference!r}",
             "omnibus: Kruskal-Wallis over all conditions"]
    if "pairwise_kruskal" in plan.tests:
        parts.append("pairwise p: two-sided Kruskal-Wallis on each pair, Holm-adjusted across the pairs")
    if "kruskal_dunn" in plan.tests:
        parts.append("Dunn's test: two-sided, tie-corrected, Holm-adjusted")
    if "summary_table" in plan.tests:
        parts.append("p against the reference: two-sided Mann-Whitney (= two-group Kruskal-Wallis), unadjusted, "
                     f"as in seed 003 Tables 5-6; effect size: {d} (condition minus reference, SDs with ddof = 1), "
                     "Sawilowsky (2009) labels")
    if _scales(family, plan):
        parts.append(SCALES[family.scale_model][1](plan))
    if "gee" in plan.tests and "gee" not in family.tests:
        parts.append(family.no_gee_note)
    if "gee" in plan.tests and "gee" in family.tests:
        parts.append("logistic GEE (statsmodels; participants as clusters, exchangeable working correlation, robust "
                     "SEs): odds ratios with 95 % Wald intervals " + family.gee_note)
    return "; ".join(parts) + "."
