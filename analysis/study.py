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
    Kruskal-Wallis over all conditions (and per scene).
``<fam>_pairwise``
    Kruskal-Wallis on every pair, Holm across the pairs (seed 001 Tables 2-3), overall and
    per scene/block; ``<fam>_dunn``: Dunn's test (Holm) as the post-hoc of the omnibus test.
``<fam>_summary``
    mean ± SD, p, Cohen's d and label of every condition against the reference (seed 003
    Tables 5-6), overall and per scene.
``2afc_scale`` / ``preference_scale``
    Thurstone Case V (JOD) and Bradley-Terry scores (2AFC) or Plackett-Luce scores
    (preference) with bootstrap intervals over participants.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .plan import AnalysisPlan
from .scaling import bradley_terry, plackett_luce, thurstone_jod
from .stats import dunn, kruskal, pairwise_kruskal, summary_table

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
        raise ValueError(f"analysis plan names condition {unknown[0]!r}, which the {family} trials never show "
                         f"(the log has: {', '.join(sorted(seen_set))})")
    extra = sorted(seen_set - set(plan.conditions))
    if extra:
        raise ValueError(f"the {family} trials show condition {extra[0]!r}, which the analysis plan does not "
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
def _choice_counts(df: pd.DataFrame, family: str, conds: list[str]):
    """Per row: codes of the shown conditions (n_rows x m, -1 padded) and of the picks (n_rows x 2)."""
    if family == "2afc":
        a = _codes(df["condition_a"], conds)
        b = _codes(df["condition_b"], conds)
        ch = _codes(df["chosen"], conds)
        if np.any(a < 0) or np.any(b < 0):
            raise ValueError("2afc trials with an empty condition_a/condition_b")
        bad = (ch != a) & (ch != b)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"2afc trial {i}: chosen {df['chosen'].iloc[i]!r} is neither condition_a nor "
                             "condition_b")
        if np.any(a == b):
            raise ValueError("a 2afc trial compares a condition with itself")
        shown = np.stack([a, b], axis=1)
        picks = np.stack([ch, np.full_like(ch, -1)], axis=1)
    else:
        offered = df["conditions"].astype(str)
        cats = pd.Categorical(offered)
        sets = [s.split("|") for s in cats.categories]
        m = max(len(s) for s in sets)
        table = np.full((len(sets), m), -1, dtype=np.int64)
        for i, s in enumerate(sets):
            idx = [conds.index(c) if c in conds else -2 for c in s]
            if -2 in idx:
                raise ValueError(f"preference trials offer an unknown condition in {cats.categories[i]!r}")
            table[i, :len(idx)] = idx
        shown = table[cats.codes]
        c1 = _codes(df["chosen"], conds)
        c2 = _codes(df["chosen_2"], conds) if "chosen_2" in df.columns else np.full(len(df), -1)
        for name, c in (("chosen", c1), ("chosen_2", c2)):
            ok = (c < 0) | (shown == c[:, None]).any(axis=1)
            if not ok.all():
                i = int(np.flatnonzero(~ok)[0])
                raise ValueError(f"preference trial {i}: {name} is not among the offered conditions")
        if np.any(c1 < 0):
            raise ValueError("preference trials with an empty first choice (chosen)")
        picks = np.stack([c1, c2], axis=1)
    return shown, picks


def _votes_table(df, shown, picks, conds, family) -> pd.DataFrame:
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
    if family == "2afc":
        out = out.drop(columns=["first", "second"])
    out["share"] = np.where(out["shown"] > 0, out["votes"] / out["shown"].where(out["shown"] > 0, 1), np.nan)
    return out.sort_values(["block", "scene"], kind="stable").reset_index(drop=True)


def _unit_values_votes(df, shown, picks, conds, plan) -> pd.DataFrame:
    """votes (times chosen) per unit of analysis and condition."""
    k = len(conds)
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
        raise ValueError("fewer than two conditions with data: nothing to compare")
    r = kruskal(*groups)
    return {"H": r.H, "df": r.df, "p": r.p, "N": r.N, "degenerate": r.degenerate}


def _summary(units: pd.DataFrame, conds: list[str], reference: str, plan: AnalysisPlan) -> pd.DataFrame:
    """summary_table row by row, so that one condition with an undefined d does not sink the report.

    A condition whose Cohen's d is undefined (both groups constant with different means: zero pooled SD)
    gets ``d = NaN`` and the label ``"undefined (zero SD)"`` - never a verbal effect-size label.
    """
    from .stats import mann_whitney

    rows = []
    for c in (c for c in conds if c != reference):
        try:
            rows.append(summary_table(units, "value", "condition", reference, order=[c], paired=plan.paired,
                                      subject="participant" if plan.paired else None))
        except ValueError as exc:
            if "standard deviation" not in str(exc):
                raise
            x = units.loc[units["condition"] == c, "value"].to_numpy(dtype=float)
            r = units.loc[units["condition"] == reference, "value"].to_numpy(dtype=float)
            rows.append(pd.DataFrame([{
                "condition": c, "n": x.size, "mean": x.mean(), "std": x.std(ddof=1) if x.size > 1 else np.nan,
                "n_ref": r.size, "mean_ref": r.mean(), "std_ref": r.std(ddof=1) if r.size > 1 else np.nan,
                "p": mann_whitney(x, r).p, "d": np.nan, "label": "undefined (zero SD)"}]))
    return pd.concat(rows, ignore_index=True).astype({"n": np.int64, "n_ref": np.int64})


def _with_group(df: pd.DataFrame, block: str, scene: str) -> pd.DataFrame:
    df = df.copy()
    df.insert(0, "scene", scene)
    df.insert(0, "block", block)
    return df


# --- scaling -------------------------------------------------------------------------------------------------
def _scale_2afc(df, shown, picks, conds, reference, plan) -> pd.DataFrame:
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
    jod = thurstone_jod(agg, **kw)
    bt = bradley_terry(agg, **kw)
    out = jod.rename(columns={"ci_low": "jod_ci_low", "ci_high": "jod_ci_high"})
    bt = bt.rename(columns={"score": "bt", "ci_low": "bt_ci_low", "ci_high": "bt_ci_high"})
    out = out.merge(bt.drop(columns=["n_comparisons"]), on="condition")
    out["order"] = [conds.index(c) for c in out["condition"]]
    return out.sort_values("order").drop(columns="order").reset_index(drop=True)


def _scale_preference(df, shown, picks, conds, reference, plan) -> pd.DataFrame:
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
                        n_boot=plan.n_boot, seed=plan.seed, observer="observer")
    out["order"] = [conds.index(c) for c in out["condition"]]
    return out.sort_values("order").drop(columns="order").reset_index(drop=True)


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
    fams = [f for f in ("2afc", "preference", "yes_no") if (df["family"] == f).any()]
    res = StudyAnalysis(plan=plan, families=fams, conditions={})
    for fam in fams:
        sub = _compact(df.loc[(df["family"] == fam).to_numpy()].reset_index(drop=True))
        res.n_trials[fam] = len(sub)
        res.n_participants[fam] = len(sub["participant"].cat.categories)
        say(f"{fam}: {len(sub):,} trials")
        if fam == "yes_no":
            seen = _present(sub["condition"])
        elif fam == "2afc":
            seen = sorted(set(_present(sub["condition_a"])) | set(_present(sub["condition_b"])))
        else:
            seen = sorted({c for s in _present(sub["conditions"]) for c in s.split("|")})
        conds = condition_order(seen, plan, fam)
        if len(conds) < 2:
            raise ValueError(f"the {fam} trials show fewer than two conditions ({', '.join(conds) or 'none'}): "
                             "nothing to compare")
        res.conditions[fam] = conds
        reference = plan.reference if plan.reference is not None else conds[0]
        if reference not in conds:
            raise ValueError(f"reference condition {reference!r} does not occur in the {fam} trials "
                             f"(the log has: {', '.join(conds)})")
        dv = plan.dv or ("response" if fam == "yes_no" else "votes")
        if (dv == "response") != (fam == "yes_no"):
            raise ValueError(f"dv={dv!r} does not fit {fam} trials (use "
                             f"{'response' if fam == 'yes_no' else 'votes'})")
        if fam == "yes_no":
            shown = picks = None
        else:
            shown, picks = _choice_counts(sub, fam, conds)
            res.tables[f"{fam}_votes"] = _votes_table(sub, shown, picks, conds, fam)

        omni, pair_rows, dunn_rows, summ_rows, unit_frames = [], [], [], [], []
        for block, scene, mask in _group_frames(sub, plan):
            part = _compact(sub.loc[mask].reset_index(drop=True))
            if fam == "yes_no":
                units = _unit_values_response(part, conds, plan)
            else:
                units = _unit_values_votes(part, shown[mask], picks[mask], conds, plan)
            present = [c for c in conds if (units["condition"] == c).any()]
            if len(present) < 2:
                if block == ALL and scene == ALL:
                    raise ValueError(f"the {fam} trials have data for fewer than two conditions")
                continue
            if block == ALL and scene == ALL:
                unit_frames.append(units)
            o = _omnibus(units, present)
            omni.append({"block": block, "scene": scene, "test": "kruskal", **o})
            if plan.test == "kruskal_holm":
                pair_rows.append(_with_group(pairwise_kruskal(units, "value", "condition", order=present),
                                             block, scene))
                dunn_rows.append(_with_group(dunn(units, "value", "condition", order=present), block, scene))
            if reference in present:
                summ_rows.append(_with_group(_summary(units, present, reference, plan), block, scene))
        res.tables[f"{fam}_units"] = unit_frames[0]
        res.tables[f"{fam}_omnibus"] = pd.DataFrame(omni)
        if pair_rows:
            res.tables[f"{fam}_pairwise"] = pd.concat(pair_rows, ignore_index=True)
            res.tables[f"{fam}_dunn"] = pd.concat(dunn_rows, ignore_index=True)
        if summ_rows:
            res.tables[f"{fam}_summary"] = pd.concat(summ_rows, ignore_index=True)
        say(f"{fam}: scaling")
        if fam == "2afc":
            res.tables["2afc_scale"] = _scale_2afc(sub, shown, picks, conds, reference, plan)
        elif fam == "preference":
            res.tables["preference_scale"] = _scale_preference(sub, shown, picks, conds, reference, plan)
        res.notes.append(_unit_note(fam, plan, dv, reference))
    return res


def _unit_note(fam: str, plan: AnalysisPlan, dv: str, reference: str) -> str:
    unit = {"participant": "one value per participant and condition",
            "participant_block": "one value per participant, block and condition",
            "participant_scene": "one value per participant, scene and condition",
            "trial": "every trial is one observation"}[plan.unit]
    what = "votes (times chosen)" if dv == "votes" else "mean score (1 = yes/acceptable)"
    if plan.unit == "trial":
        what = "chosen (1/0) each time a condition was shown" if dv == "votes" else "score (1 = yes/acceptable)"
    d = "paired d_z over participants" if plan.paired else "pooled-SD Cohen's d of independent groups"
    tests = ("pairwise p: two-sided Kruskal-Wallis on each pair, Holm-adjusted across the pairs; "
             if plan.test == "kruskal_holm" else "")
    return (f"{fam}: dependent variable {what}; unit of analysis: {unit}; reference {reference!r}; {tests}"
            "p against the reference: two-sided Mann-Whitney (= two-group Kruskal-Wallis), unadjusted, as in "
            f"seed 003 Tables 5-6; effect size: {d} (condition minus reference, SDs with ddof = 1), "
            "Sawilowsky (2009) labels.")
