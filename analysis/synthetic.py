"""Synthetic trial logs shaped like the seeds' studies (for the demo, the tests and the benchmarks).

Every generator is a pure function of its arguments and ``seed``: the same call gives the same log.

:func:`seed001_2afc_log`
    The 2AFC study of seed 001 §5.3.3: 25 participants x 2 headsets x 3 scenes x 10 pairs of five
    modes x 3 repetitions = 4,500 trials; choices drawn from a Thurstone Case V observer.
:func:`seed003_yes_no_log`
    Seed 003 §5 Task 1 (50 trials: EC, CC1-CC4 x 5 scenes x 2) or Task 2 (40 trials: EC, CC2-CC4), 32
    participants, binary scores whose per-condition means are those of the seed's Tables 5 and 6.
:func:`synthetic_2afc_log`
    A 2AFC log of any size (the 10^7-trial benchmark), generated without Python loops over trials.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pandas as pd
from scipy import special

from data_schema.errors import UserError
from data_schema.families.two_afc import FAMILY as TWO_AFC
from data_schema.families.yes_no import FAMILY as YES_NO

from .scaling import JOD_SIGMA

__all__ = ["SEED001_MODES", "SEED001_TRUE_JOD", "SEED003_TABLES", "seed001_2afc_log", "seed003_yes_no_log",
           "synthetic_2afc_log"]

SEED001_MODES = ("VaFR_Rep", "VaFR_Dup", "LaFR(2.2)", "LaFR(1.8)", "GT")
#: Assumed true quality (JOD) of the five modes: VaFR clearly preferred, the others close together, as in
#: seed 001 Table 3 (VaFR vs others p < 0.05, LaFR/GT pairs p > 0.5).
SEED001_TRUE_JOD = {"VaFR_Rep": 0.75, "VaFR_Dup": 0.70, "LaFR(2.2)": 0.0, "LaFR(1.8)": 0.05, "GT": 0.02}
SEED001_SCENES = ("street_night", "interior", "temple")
SEED001_HEADSETS = ("vive_pro_eye", "pimax_crystal")

#: Seed 003 Tables 5 and 6: condition -> (avg, std, Cohen's d, label) as printed (EC is the reference).
SEED003_TABLES = {
    5: {"EC": (0.79, 0.40, None, None), "CC1": (0.96, 0.19, 0.53, "medium"),
        "CC2": (0.17, 0.37, 1.62, "very large"), "CC3": (0.38, 0.49, 0.92, "large"),
        "CC4": (0.85, 0.36, 0.15, "very small")},
    6: {"EC": (0.86, 0.35, None, None), "CC2": (0.18, 0.39, 1.83, "very large"),
        "CC3": (0.50, 0.50, 0.80, "large"), "CC4": (0.47, 0.50, 0.90, "large")},
}
#: Seed 003's p-values as printed (Tables 5-6), for the comparison in the docs.
SEED003_P = {5: {"CC1": "<0.001", "CC2": "<0.001", "CC3": "<0.001", "CC4": "0.063"},
             6: {"CC2": "<0.001", "CC3": "<0.001", "CC4": "<0.001"}}
SEED003_SCENES = ("study", "room", "cornellbox", "yard", "sponza")


def seed001_2afc_log(seed: int = 0, n_participants: int = 25, headsets=SEED001_HEADSETS,
                     scenes=SEED001_SCENES, reps: int = 3, true_jod: dict | None = None,
                     observer_sd: float = 0.3) -> pd.DataFrame:
    """The seed 001 2AFC log: every participant sees the 10 pairs x ``reps`` per scene and headset.

    Each participant has their own scale, ``true_jod`` plus Gaussian noise (SD ``observer_sd`` JOD), and
    prefers A over B with probability :math:`\\Phi((q_A - q_B)/\\sigma)`, :math:`\\sigma = 1.4826`
    (Thurstone Case V, 1 JOD = 75 %). Pair order and position are shuffled per scene as in §5.3.3.
    """
    q = dict(SEED001_TRUE_JOD if true_jod is None else true_jod)
    modes = list(q)
    rng = np.random.default_rng(seed)
    pairs = list(combinations(range(len(modes)), 2))
    rows = []
    for p in range(n_participants):
        pid = f"P{p + 1:02d}"
        for h in headsets:
            qp = np.array([q[m] for m in modes]) + rng.normal(0.0, observer_sd, len(modes))
            for s in scenes:
                trials = [pr for pr in pairs for _ in range(reps)]
                order = rng.permutation(len(trials))
                flips = rng.random(len(trials)) < 0.5
                u = rng.random(len(trials))
                for t, idx in enumerate(order):
                    i, j = trials[idx]
                    if flips[t]:
                        i, j = j, i
                    p_a = special.ndtr((qp[i] - qp[j]) / JOD_SIGMA)
                    chosen = modes[i] if u[t] < p_a else modes[j]
                    rows.append((pid, f"{pid}-{h}", h, s, len(rows), TWO_AFC.name, modes[i], modes[j], chosen))
    df = pd.DataFrame(rows, columns=["participant", "session", "block", "scene", "trial", "family",
                                     "condition_a", "condition_b", "chosen"])
    df["trial"] = df.groupby("participant").cumcount()
    return df


def seed003_yes_no_log(task: int = 5, seed: int = 0, n_participants: int = 32, reps: int = 2,
                       scenes=SEED003_SCENES) -> pd.DataFrame:
    """Binary scores with the per-condition means of seed 003 Table 5 (Task 1) or Table 6 (Task 2).

    Each condition gets ``n = n_participants x len(scenes) x reps`` trials (320 in the seed), of which
    ``c`` are 1 (yes / acceptable), spread over participants and scenes by a seeded permutation. With
    0/1 scores the SD follows from the count, so ``c`` is chosen to print as the table's mean and SD
    (:func:`_count_for`): with the sample SD (ddof = 1) where such a count exists, else with the
    population SD (Table 5's EC, 0.79 ± 0.40, exists only that way for 320 trials).
    """
    if task not in SEED003_TABLES:
        raise UserError(f"task={task!r} is invalid: allowed 5 (Table 5, Task 1) or 6 (Table 6, Task 2)")
    rng = np.random.default_rng(seed)
    table = SEED003_TABLES[task]
    cells = [(p, s, r) for p in range(n_participants) for s in scenes for r in range(reps)]
    n = len(cells)
    frames = []
    for cond, (mean, sd, _d, _label) in table.items():
        ones = _count_for(mean, sd, n)
        y = np.zeros(n, dtype=np.int64)
        y[rng.permutation(n)[:ones]] = 1
        frames.append(pd.DataFrame({
            "participant": [f"P{p + 1:02d}" for p, _, _ in cells], "block": f"task{task - 4}",
            "scene": [s for _, s, _ in cells], "family": YES_NO.name, "condition": cond, "response": y}))
    df = pd.concat(frames, ignore_index=True)
    df = df.sort_values(["participant", "scene"], kind="stable").reset_index(drop=True)
    df.insert(1, "session", df["participant"] + f"-task{task - 4}")
    df.insert(4, "trial", df.groupby("participant").cumcount())
    return df


def synthetic_2afc_log(n_trials: int, seed: int = 0, trials_per_participant: int = 600,
                       true_jod: dict | None = None, scenes=SEED001_SCENES) -> pd.DataFrame:
    """A 2AFC log of ``n_trials`` rows (vectorised; for benchmarks), Thurstone observers as above."""
    if n_trials < 1:
        raise UserError(f"n_trials={n_trials!r} is invalid: allowed >= 1")
    q = dict(SEED001_TRUE_JOD if true_jod is None else true_jod)
    modes = np.array(list(q), dtype=object)
    k = len(modes)
    rng = np.random.default_rng(seed)
    n_p = max(1, -(-n_trials // trials_per_participant))
    part = np.repeat(np.arange(n_p), trials_per_participant)[:n_trials]
    pairs = np.array(list(combinations(range(k), 2)))
    pr = pairs[rng.integers(0, len(pairs), n_trials)]
    flip = rng.random(n_trials) < 0.5
    a = np.where(flip, pr[:, 1], pr[:, 0])
    b = np.where(flip, pr[:, 0], pr[:, 1])
    qp = np.array([q[m] for m in modes])[None, :] + rng.normal(0.0, 0.3, (n_p, k))
    p_a = special.ndtr((qp[part, a] - qp[part, b]) / JOD_SIGMA)
    chosen = np.where(rng.random(n_trials) < p_a, a, b)
    width = len(str(n_p))
    pnames = np.array([f"P{i:0{width}d}" for i in range(n_p)], dtype=object)
    return pd.DataFrame({
        "participant": pd.Categorical.from_codes(part, pnames),
        "block": pd.Categorical.from_codes(np.zeros(n_trials, dtype=np.int64), ["hmd"]),
        "scene": pd.Categorical.from_codes((np.arange(n_trials) // 10) % len(scenes), list(scenes)),
        "trial": np.arange(n_trials) - part * trials_per_participant,
        "family": pd.Categorical.from_codes(np.zeros(n_trials, dtype=np.int64), [TWO_AFC.name]),
        "condition_a": pd.Categorical.from_codes(a, list(modes)),
        "condition_b": pd.Categorical.from_codes(b, list(modes)),
        "chosen": pd.Categorical.from_codes(chosen, list(modes)),
    })


def pooled_d_range(mean: float, sd: float, mean_ref: float, sd_ref: float, decimals: int = 2) -> tuple[float, float]:
    """Smallest and largest |pooled-SD Cohen's d| consistent with means and SDs printed to ``decimals``.

    With equal group sizes (as in seed 003: 320 trials per condition) the pooled SD is
    :math:`\\sqrt{(s_1^2 + s_2^2)/2}`; every printed value stands for an interval of half-width
    :math:`0.5\\cdot 10^{-decimals}`. The extremes of :math:`|m_1 - m_2| / s_p` over that box are attained
    at its corners.
    """
    h = 0.5 * 10.0 ** -decimals
    diff = abs(mean - mean_ref)
    lo_diff, hi_diff = max(0.0, diff - 2 * h), diff + 2 * h
    lo_sp = np.sqrt(((sd - h) ** 2 + (sd_ref - h) ** 2) / 2.0)
    hi_sp = np.sqrt(((sd + h) ** 2 + (sd_ref + h) ** 2) / 2.0)
    return float(lo_diff / hi_sp), float(hi_diff / lo_sp)


def binary_counts(mean: float, sd: float, n: int, ddof: int = 1, decimals: int = 2) -> np.ndarray:
    r"""Counts ``c`` of ones among ``n`` 0/1 scores whose mean and SD print as ``mean`` and ``sd``.

    The SD of 0/1 data is fixed by the count: :math:`s = \sqrt{c(n-c)/(n(n-\mathrm{ddof}))}`.
    """
    h = 0.5 * 10.0 ** -decimals + 1e-12
    c = np.arange(n + 1)
    sdv = np.sqrt(c * (n - c) / (n * (n - float(ddof))))
    return c[(np.abs(c / n - mean) <= h) & (np.abs(sdv - sd) <= h)]


def binary_d_range(mean: float, sd: float, mean_ref: float, sd_ref: float, n: int, n_ref: int,
                   ddof: int = 1, decimals: int = 2) -> tuple[float, float]:
    """|pooled-SD d| range of 0/1 data whose means and SDs (with ``ddof``) print as given.

    Returns ``(nan, nan)`` if no counts print as the given numbers. Cohen's d always uses the ddof = 1
    pooled SD (:func:`analysis.cohens_d`); ``ddof`` only decides which counts the printed SDs admit.
    """
    cx, cr = binary_counts(mean, sd, n, ddof, decimals), binary_counts(mean_ref, sd_ref, n_ref, ddof, decimals)
    if cx.size == 0 or cr.size == 0:
        return float("nan"), float("nan")
    mx, mr = cx[:, None] / n, cr[None, :] / n_ref
    vx = cx[:, None] * (n - cx[:, None]) / (n * (n - 1.0))
    vr = cr[None, :] * (n_ref - cr[None, :]) / (n_ref * (n_ref - 1.0))
    sp = np.sqrt(((n - 1) * vx + (n_ref - 1) * vr) / (n + n_ref - 2))
    d = np.abs(mx - mr) / sp
    return float(d.min()), float(d.max())


def _count_for(mean: float, sd: float, n: int) -> int:
    """The count of ones that prints as (mean, sd): sample SD if possible, else population SD, else the
    count nearest to ``mean * n``; ties go to the count nearest ``mean * n``."""
    for ddof in (1, 0):
        c = binary_counts(mean, sd, n, ddof)
        if c.size:
            return int(c[np.argmin(np.abs(c - mean * n))])
    return round(mean * n)


def _reachable(d_seed: float, lo: float, hi: float, decimals: int = 2) -> bool:
    """Does a d in [lo, hi] print as ``d_seed`` (rounded to ``decimals``)?"""
    h = 0.5 * 10.0 ** -decimals
    return bool(np.isfinite(lo) and lo <= d_seed + h and hi >= d_seed - h)


def seed003_comparison(seed: int = 0) -> pd.DataFrame:
    """Seed 003 Tables 5-6 against this package's summary table on the synthetic binary logs.

    Columns: ``table``, ``condition``, ``seed_mean``, ``seed_std``, ``seed_d``, ``seed_label``, ``mean``,
    ``std``, ``d`` (signed, condition minus EC), ``abs_d_error`` (| |d| - seed d |), ``label``, ``p``,
    ``seed_p``, ``d_min``/``d_max`` (the |d| range the seed's rounded means and SDs allow, see
    :func:`pooled_d_range`), ``seed_d_reachable`` (some d in that range prints as the seed's d),
    ``binary_d_min``/``binary_d_max`` (the range 0/1 scores of 320 trials per condition allow, see
    :func:`binary_d_range`) and ``seed_d_reachable_binary``.
    """
    from .io import validate_log
    from .plan import AnalysisPlan
    from .stats import format_p
    from .study import analyze_log

    rows = []
    for table, spec in SEED003_TABLES.items():
        log = seed003_yes_no_log(table, seed=seed)
        plan = AnalysisPlan(unit="trial", tests=("summary_table",), reference="EC", conditions=tuple(spec),
                            n_boot=0, per_scene=False)
        summ = analyze_log(validate_log(log), plan).tables["yes_no_summary"]
        m_ref, s_ref = spec["EC"][:2]
        for r in summ.itertuples(index=False):
            m, s, d_seed, lab_seed = spec[r.condition]
            d_min, d_max = pooled_d_range(m, s, m_ref, s_ref)
            b_min, b_max = binary_d_range(m, s, m_ref, s_ref, int(r.n), int(r.n_ref), ddof=1)
            if not np.isfinite(b_min):  # the printed SDs are population SDs (see seed003_yes_no_log)
                b_min, b_max = binary_d_range(m, s, m_ref, s_ref, int(r.n), int(r.n_ref), ddof=0)
            rows.append({"table": table, "condition": r.condition, "seed_mean": m, "seed_std": s,
                         "seed_d": d_seed, "seed_label": lab_seed, "mean": r.mean, "std": r.std, "d": r.d,
                         "abs_d_error": abs(abs(r.d) - d_seed), "label": r.label, "p": r.p,
                         "p_text": format_p(r.p), "seed_p": SEED003_P[table][r.condition],
                         "d_min": d_min, "d_max": d_max, "seed_d_reachable": _reachable(d_seed, d_min, d_max),
                         "binary_d_min": b_min, "binary_d_max": b_max,
                         "seed_d_reachable_binary": _reachable(d_seed, b_min, b_max)})
    return pd.DataFrame(rows)
