"""Scaling of pairwise-comparison and top-k choice data onto an interval quality scale.

Three maximum-a-posteriori (MAP) estimators, tidy DataFrame in and tidy DataFrame out:

:func:`thurstone_jod`
    Thurstone Case V in just-objectionable-difference (JOD) units, as in pwcmp
    (Perez-Ortiz & Mantiuk, 2017).
:func:`bradley_terry`
    Bradley-Terry log-strengths (logit scale).
:func:`plackett_luce`
    Plackett-Luce log-strengths for top-k-of-N partial rankings (multinomial logit for
    k = 1).

Regularisation (all three estimators)
    Unanimous or near-unanimous comparisons make the plain maximum-likelihood estimate
    diverge. Every estimator therefore maximises the log-likelihood plus a weak Gaussian
    prior on **every pairwise difference** of scores,

    .. math:: \\log p(q) = -\\sum_{i<j} \\frac{(q_i - q_j)^2}{2\\,\\tau^2},

    with ``tau = prior_sd`` (default 10 in the estimator's own units: 10 JOD for
    :func:`thurstone_jod`, 10 logits for the others). The prior depends only on
    differences, so the estimate does not depend on the choice of reference, and it is
    weak enough that a 75/100 preference gives 1 JOD (ln 3 logits) to within 1e-3, yet
    strong enough that a 20/0 preference stays finite (about 4.6 JOD). ``prior_sd=np.inf``
    switches it off (pure MLE; may then diverge for unanimous data). pwcmp uses a
    similar Gaussian prior on distances; a pseudo-count (add 0.5) was not used because
    it biases non-unanimous data as well.

NaN policy: rows with a missing condition or selection (or a missing first choice /
options set in :func:`plackett_luce`) are dropped. The comparison graph of the remaining
rows must be connected, or a ``ValueError`` is raised. Bootstrap replicates are fitted
without this check: a condition absent from a replicate is held in place by the prior,
so the interval stays finite (and wide).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pandas as pd
from scipy import optimize, special

__all__ = ["JOD_SIGMA", "bradley_terry", "plackett_luce", "thurstone_jod"]

#: Standard deviation of the Thurstone difference distribution in JOD units:
#: ``Phi(1 / JOD_SIGMA) = 0.75``, i.e. 1 JOD is the difference that 75 % of observers see.
JOD_SIGMA: float = float(1.0 / special.ndtri(0.75))  # 1.482602...

_LOG_SQRT_2PI = 0.5 * np.log(2.0 * np.pi)


# --------------------------------------------------------------------------------------
# validation helpers
# --------------------------------------------------------------------------------------


def _check_frame(data: Any, cols: Sequence[str]) -> pd.DataFrame:
    if not isinstance(data, pd.DataFrame):
        raise ValueError(f"data must be a pandas DataFrame, got {type(data).__name__}")  # noqa: TRY004
    missing = [c for c in cols if c not in data.columns]
    if missing:
        raise ValueError(f"data is missing column(s): {', '.join(map(repr, missing))}")
    return data


def _check_common(n_boot: Any, ci: Any, prior_sd: Any) -> tuple[int, float, float]:
    if isinstance(n_boot, bool) or not isinstance(n_boot, (int, np.integer)) or n_boot < 0:
        raise ValueError(f"n_boot must be a non-negative integer, got {n_boot!r}")
    try:
        ci_f = float(ci)
    except (TypeError, ValueError):
        raise ValueError(f"ci must be a number in (0, 1), got {ci!r}") from None
    if not 0.0 < ci_f < 1.0:
        raise ValueError(f"ci must be in (0, 1), got {ci!r}")
    try:
        tau = float(prior_sd)
    except (TypeError, ValueError):
        raise ValueError(f"prior_sd must be a positive number, got {prior_sd!r}") from None
    if not tau > 0.0:
        raise ValueError(f"prior_sd must be positive (np.inf for no prior), got {prior_sd!r}")
    return int(n_boot), ci_f, tau


def _sorted_labels(values: Any) -> list:
    uniq = list(dict.fromkeys(values))
    try:
        return sorted(uniq)
    except TypeError:
        return sorted(uniq, key=lambda v: (type(v).__name__, str(v)))


def _reference_index(labels: list, reference: Any) -> int:
    if len(labels) < 2:
        raise ValueError(f"need at least two conditions, got {len(labels)}")
    if reference is None:
        return 0
    if reference not in labels:
        raise ValueError(f"reference {reference!r} is not one of the conditions")
    return labels.index(reference)


def _check_connected(k: int, groups: list[np.ndarray]) -> None:
    """Raise ValueError unless the graph joining each group of condition indices is connected."""
    parent = list(range(k))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for g in groups:
        r0 = find(int(g[0]))
        for v in g[1:]:
            rv = find(int(v))
            if rv != r0:
                parent[rv] = r0
    n_comp = len({find(i) for i in range(k)})
    if n_comp > 1:
        raise ValueError(
            f"the comparison graph is disconnected ({n_comp} components); scores are not comparable"
        )


def _row_weights(df: pd.DataFrame, weight: str | None) -> np.ndarray:
    """Multiplicity of each row: 1, or the non-negative integer counts in column ``weight``."""
    if weight is None:
        return np.ones(len(df))
    w = pd.to_numeric(df[weight], errors="coerce").to_numpy(dtype=float)
    if not np.all(np.isfinite(w) & (w >= 0) & (w == np.rint(w))):
        raise ValueError(f"column {weight!r} must hold non-negative integer counts")
    return w


def _observer_codes(df: pd.DataFrame, observer: str | None) -> np.ndarray | None:
    if observer is None or observer not in df.columns:
        return None
    codes, _ = pd.factorize(df[observer], use_na_sentinel=True)
    if np.any(codes < 0):  # a missing observer id is its own cluster per row
        codes = codes.copy()
        bad = codes < 0
        codes[bad] = codes.max() + 1 + np.arange(bad.sum())
    return codes


# --------------------------------------------------------------------------------------
# optimisation
# --------------------------------------------------------------------------------------

Objective = Callable[[np.ndarray], tuple[float, np.ndarray, np.ndarray]]


def _map_fit(objective: Objective, k: int, ref: int, tau: float, x0: np.ndarray | None = None) -> np.ndarray:
    """Minimise ``objective(q) + prior(q)`` over ``q`` with ``q[ref] = 0``; return full ``q``."""
    free = np.array([i for i in range(k) if i != ref])
    inv_t2 = 0.0 if np.isinf(tau) else 1.0 / tau**2
    prior_h = inv_t2 * (k * np.eye(k) - np.ones((k, k)))

    def full(x: np.ndarray) -> np.ndarray:
        q = np.zeros(k)
        q[free] = x
        return q

    def fun(x: np.ndarray) -> tuple[float, np.ndarray]:
        q = full(x)
        f, g, _ = objective(q)
        s = q.sum()
        f = f + 0.5 * inv_t2 * (k * q @ q - s * s)
        g = g + inv_t2 * (k * q - s)
        return f, g[free]

    def hess(x: np.ndarray) -> np.ndarray:
        _, _, h = objective(full(x))
        return (h + prior_h)[np.ix_(free, free)]

    start = np.zeros(k - 1) if x0 is None else np.asarray(x0, dtype=float)[free]
    res = optimize.minimize(
        fun, start, jac=True, hess=hess, method="trust-exact", options={"gtol": 1e-9, "maxiter": 500}
    )
    q = full(res.x)
    if not np.all(np.isfinite(q)):  # pragma: no cover - the prior keeps the problem strictly convex
        raise RuntimeError("scaling did not converge to finite scores")
    return q


def _pairwise_objective(win: np.ndarray, lose: np.ndarray, w: np.ndarray, k: int, model: str) -> Objective:
    """Negative log-likelihood of aggregated pairwise outcomes ``win`` beat ``lose`` ``w`` times."""
    sigma = JOD_SIGMA if model == "thurstone" else 1.0

    def objective(q: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        x = (q[win] - q[lose]) / sigma
        if model == "thurstone":
            logcdf = special.log_ndtr(x)
            r = np.exp(-0.5 * x * x - _LOG_SQRT_2PI - logcdf)  # phi / Phi
            f = -np.sum(w * logcdf)
            d1 = -w * r / sigma  # d f / d q_win
            d2 = w * r * (x + r) / sigma**2
        else:  # logit / Bradley-Terry
            f = np.sum(w * np.logaddexp(0.0, -x))
            p_lose = special.expit(-x)
            d1 = -w * p_lose
            d2 = w * p_lose * (1.0 - p_lose)
        g = np.bincount(win, d1, k) - np.bincount(lose, d1, k)
        h = np.zeros((k, k))
        np.add.at(h, (win, win), d2)
        np.add.at(h, (lose, lose), d2)
        np.add.at(h, (win, lose), -d2)
        np.add.at(h, (lose, win), -d2)
        return float(f), g, h

    return objective


def _batched_pairwise_fit(counts: np.ndarray, ref: int, tau: float, model: str, q0: np.ndarray) -> np.ndarray:
    """MAP scores of many replicates at once: damped Newton on ``counts[b, i, j]`` (i beat j).

    The same objective as :func:`_pairwise_objective` plus the prior of :func:`_map_fit`, minimised for
    all ``B`` replicates together (batched Hessian solves), starting from ``q0``; used by the bootstrap,
    where thousands of small fits would otherwise cost a scipy call each. The objective is strictly convex
    (the prior), so Newton with step halving converges; the tolerance is 1e-10 on the step.
    """
    b_n, k, _ = counts.shape
    sigma = JOD_SIGMA if model == "thurstone" else 1.0
    inv_t2 = 0.0 if np.isinf(tau) else 1.0 / tau**2
    free = np.array([i for i in range(k) if i != ref])
    q = np.broadcast_to(np.asarray(q0, dtype=float), (b_n, k)).copy()

    def terms(q: np.ndarray, counts: np.ndarray, need_derivs: bool = True):
        x = (q[:, :, None] - q[:, None, :]) / sigma
        if model == "thurstone":
            logcdf = special.log_ndtr(x)
            f = -np.einsum("bij,bij->b", counts, logcdf)
        else:
            f = np.einsum("bij,bij->b", counts, np.logaddexp(0.0, -x))
        s = q.sum(axis=1)
        f = f + 0.5 * inv_t2 * (k * np.einsum("bi,bi->b", q, q) - s * s)
        if not need_derivs:
            return f, None, None
        if model == "thurstone":
            r = np.exp(-0.5 * x * x - _LOG_SQRT_2PI - logcdf)
            d1 = -counts * r / sigma
            d2 = counts * r * (x + r) / sigma**2
        else:
            p_lose = special.expit(-x)
            d1 = -counts * p_lose
            d2 = counts * p_lose * (1.0 - p_lose)
        g = d1.sum(axis=2) - d1.sum(axis=1) + inv_t2 * (k * q - s[:, None])
        sym = d2 + np.swapaxes(d2, 1, 2)
        h = -sym
        idx = np.arange(k)
        h[:, idx, idx] = sym.sum(axis=2)
        h = h + inv_t2 * (k * np.eye(k) - np.ones((k, k)))
        return f, g, h

    f, g, h = terms(q, counts)
    active = np.ones(b_n, dtype=bool)
    for _ in range(100):
        a = np.flatnonzero(active)
        if a.size == 0:
            break
        hf = h[a][:, free][:, :, free]
        step = np.zeros((a.size, k))
        step[:, free] = np.linalg.solve(hf, -g[a][:, free, None])[..., 0]
        t = np.ones(a.size)
        q_new = q[a] + step
        f_new, _, _ = terms(q_new, counts[a], need_derivs=False)
        for _halve in range(40):  # backtracking where the objective did not decrease
            bad = ~(f_new <= f[a] + 1e-12 * np.abs(f[a]))
            if not bad.any():
                break
            t[bad] *= 0.5
            q_new[bad] = q[a][bad] + t[bad, None] * step[bad]
            f_new[bad] = terms(q_new[bad], counts[a][bad], need_derivs=False)[0]
        q[a] = q_new
        f_a, g_a, h_a = terms(q[a], counts[a])
        f[a], g[a], h[a] = f_a, g_a, h_a
        done = np.max(np.abs(t[:, None] * step), axis=1) < 1e-10
        active[a[done]] = False
    return q


def _choice_objective(chosen: np.ndarray, mask: np.ndarray, w: np.ndarray, k: int) -> Objective:
    """Negative log-likelihood of choice events (multinomial logit on the available set)."""

    def objective(q: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        s = np.where(mask, q[None, :], -np.inf)
        lse = special.logsumexp(s, axis=1)
        p = np.exp(s - lse[:, None])
        f = -np.sum(w * (q[chosen] - lse))
        wp = p * w[:, None]
        g = wp.sum(axis=0) - np.bincount(chosen, w, k)
        h = np.diag(wp.sum(axis=0)) - wp.T @ p
        return float(f), g, h

    return objective


def _bootstrap(
    fit_weighted: Callable[[np.ndarray, np.ndarray], np.ndarray],
    n_rows: int,
    clusters: np.ndarray | None,
    q_hat: np.ndarray,
    n_boot: int,
    ci: float,
    seed: Any,
    fit_many: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Percentile bootstrap; each replicate is a vector of row multiplicities.

    ``fit_many`` (optional) fits a batch of replicates at once; replicates are drawn in the same order
    either way, so the intervals do not depend on it.
    """
    rng = np.random.default_rng(seed)
    reps = np.empty((n_boot, q_hat.size))
    batch = 64 if fit_many is not None else 1
    for start in range(0, n_boot, batch):
        ws = []
        for _b in range(start, min(n_boot, start + batch)):
            if clusters is None:
                w = np.bincount(rng.integers(0, n_rows, n_rows), minlength=n_rows).astype(float)
            else:
                n_c = int(clusters.max()) + 1
                mult = np.bincount(rng.integers(0, n_c, n_c), minlength=n_c)
                w = mult[clusters].astype(float)
            ws.append(w)
        if fit_many is not None:
            reps[start:start + len(ws)] = fit_many(np.stack(ws), q_hat)
        else:
            reps[start] = fit_weighted(ws[0], q_hat)
    alpha = (1.0 - ci) / 2.0
    lo = np.quantile(reps, alpha, axis=0)
    hi = np.quantile(reps, 1.0 - alpha, axis=0)
    return lo, hi


# --------------------------------------------------------------------------------------
# pairwise comparisons
# --------------------------------------------------------------------------------------


def _pairwise(
    data: Any,
    cond_a: str,
    cond_b: str,
    selection: str,
    reference: Any,
    n_boot: Any,
    ci: Any,
    seed: Any,
    prior_sd: Any,
    observer: str | None,
    model: str,
    score_name: str,
    weight: str | None = None,
) -> pd.DataFrame:
    df = _check_frame(data, [cond_a, cond_b, selection] + ([weight] if weight else []))
    n_boot_i, ci_f, tau = _check_common(n_boot, ci, prior_sd)
    df = df.dropna(subset=[cond_a, cond_b, selection])
    sel = df[selection]
    try:
        if isinstance(sel.dtype, pd.CategoricalDtype) or (
            sel.dtype == object and sel.map(lambda v: isinstance(v, str)).any()
        ):
            raise TypeError
        sel_v = sel.to_numpy(dtype=float)
    except (TypeError, ValueError):
        sel_v = np.array([np.nan])
    if not np.all((sel_v == 0.0) | (sel_v == 1.0)):
        raise ValueError(f"column {selection!r} must be binary (1 = {cond_a} chosen, 0 = {cond_b} chosen)")
    a_vals = df[cond_a].to_numpy(dtype=object)
    b_vals = df[cond_b].to_numpy(dtype=object)
    if np.any(a_vals == b_vals):
        raise ValueError(f"a row compares a condition with itself ({cond_a!r} == {cond_b!r})")
    labels = _sorted_labels(list(a_vals) + list(b_vals))
    k = len(labels)
    ref = _reference_index(labels, reference)
    ia = pd.Categorical(a_vals, categories=labels).codes.astype(np.intp)
    ib = pd.Categorical(b_vals, categories=labels).codes.astype(np.intp)
    _check_connected(k, [np.array([i, j]) for i, j in set(zip(ia.tolist(), ib.tolist()))])

    a_won = sel_v == 1.0
    win_row = np.where(a_won, ia, ib)
    lose_row = np.where(a_won, ib, ia)
    code_row = win_row * k + lose_row
    base_w = _row_weights(df, weight)

    def fit_weighted(w_rows: np.ndarray, x0: np.ndarray | None) -> np.ndarray:
        counts = np.bincount(code_row, w_rows * base_w, k * k)
        nz = np.flatnonzero(counts)
        obj = _pairwise_objective(nz // k, nz % k, counts[nz], k, model)
        return _map_fit(obj, k, ref, tau, x0)

    n = len(df)
    q = fit_weighted(np.ones(n), None)
    out = pd.DataFrame({"condition": labels, score_name: q})
    if n_boot_i > 0:
        clusters = _observer_codes(df, observer)

        def fit_many(w_reps: np.ndarray, x0: np.ndarray) -> np.ndarray:
            counts = np.stack([np.bincount(code_row, w * base_w, k * k) for w in w_reps]).reshape(-1, k, k)
            return _batched_pairwise_fit(counts, ref, tau, model, x0)

        lo, hi = _bootstrap(fit_weighted, n, clusters, q, n_boot_i, ci_f, seed, fit_many=fit_many)
        out["ci_low"] = lo
        out["ci_high"] = hi
    out["n_comparisons"] = np.rint(np.bincount(ia, base_w, k) + np.bincount(ib, base_w, k)).astype(np.int64)
    return out


def thurstone_jod(
    data: pd.DataFrame,
    cond_a: str = "condition_1",
    cond_b: str = "condition_2",
    selection: str = "selection",
    reference: Any = None,
    n_boot: int = 0,
    ci: float = 0.95,
    seed: Any = 0,
    *,
    prior_sd: float = 10.0,
    observer: str | None = "observer",
    weight: str | None = None,
) -> pd.DataFrame:
    """Thurstone Case V scaling of pairwise comparisons in JOD units (pwcmp convention).

    Parameters
    ----------
    data : pandas.DataFrame
        One row per comparison (long format).
    cond_a, cond_b : str
        Columns naming the two conditions shown in the trial.
    selection : str
        Column with the outcome: ``1`` (or ``True``) if ``cond_a`` was chosen, ``0`` (or
        ``False``) if ``cond_b`` was chosen. Any other value raises ``ValueError``; the
        chosen condition's *name* is deliberately not accepted (recode it first).
    reference : hashable, optional
        Condition fixed at 0 JOD. Default: the first condition in sorted order.
    n_boot : int
        Number of bootstrap replicates for a percentile confidence interval; ``0`` (the
        default) omits the ``ci_low``/``ci_high`` columns.
    ci : float
        Confidence level of the interval, in (0, 1).
    seed : int or numpy.random.Generator seed
        Seed of the bootstrap; the same seed gives identical output.
    prior_sd : float, keyword-only
        SD in JOD of the Gaussian prior on every pairwise difference (module docstring).
    observer : str or None, keyword-only
        If this column exists, the bootstrap resamples observers (all of an observer's rows
        together, the usual cluster bootstrap for repeated measures); otherwise, or with
        ``None``, it resamples rows.
    weight : str or None, keyword-only
        Column of non-negative integer counts: each row then stands for that many identical
        comparisons (aggregated logs; keep one row per observer and outcome so that the
        observer bootstrap stays exact). Default: every row counts once.

    Returns
    -------
    pandas.DataFrame
        One row per condition, sorted: ``condition``, ``jod``, ``ci_low``, ``ci_high``
        (only when ``n_boot > 0``), ``n_comparisons`` (rows in which it appeared).

    Notes
    -----
    The probability that condition :math:`A` is preferred over :math:`B` is

    .. math:: P(A \\succ B) = \\Phi\\left(\\frac{q_A - q_B}{\\sigma}\\right),
              \\qquad \\sigma = 1/\\Phi^{-1}(0.75) \\approx 1.4826,

    so a difference of 1 JOD means 75 % of observers prefer the better condition. The
    scores maximise :math:`\\sum n_{AB} \\log P(A \\succ B)` plus the log prior, with the
    reference held at 0 (trust-region Newton with the exact Hessian).

    References
    ----------
    Thurstone, L. L. (1927). A law of comparative judgment. *Psychological Review*, 34(4).
    Perez-Ortiz, M., & Mantiuk, R. K. (2017). A practical guide and software for analysing
    pairwise comparison experiments. arXiv:1712.03686 (pwcmp).

    Examples
    --------
    >>> df = pd.DataFrame({"condition_1": ["a"] * 100, "condition_2": ["b"] * 100,
    ...                    "selection": [1] * 75 + [0] * 25})
    >>> thurstone_jod(df, reference="b").round(2)
      condition  jod  n_comparisons
    0         a  1.0            100
    1         b  0.0            100
    """
    return _pairwise(
        data, cond_a, cond_b, selection, reference, n_boot, ci, seed, prior_sd, observer, "thurstone", "jod",
        weight,
    )


def bradley_terry(
    data: pd.DataFrame,
    cond_a: str = "condition_1",
    cond_b: str = "condition_2",
    selection: str = "selection",
    reference: Any = None,
    n_boot: int = 0,
    ci: float = 0.95,
    seed: Any = 0,
    *,
    prior_sd: float = 10.0,
    observer: str | None = "observer",
    weight: str | None = None,
) -> pd.DataFrame:
    """Bradley-Terry log-strengths of pairwise comparisons (logit scale).

    Parameters are those of :func:`thurstone_jod`; ``prior_sd`` is in logits.

    Returns
    -------
    pandas.DataFrame
        ``condition``, ``score`` (log-strength, reference = 0), ``ci_low``, ``ci_high``
        (only when ``n_boot > 0``), ``n_comparisons``.

    Notes
    -----
    .. math:: P(A \\succ B) = \\frac{e^{s_A}}{e^{s_A} + e^{s_B}}
              = \\operatorname{logit}^{-1}(s_A - s_B),

    so a 75/25 split is a difference of :math:`\\ln 3 \\approx 1.0986`. The scores are the
    MAP estimate under the weak Gaussian prior described in the module docstring.

    References
    ----------
    Bradley, R. A., & Terry, M. E. (1952). Rank analysis of incomplete block designs: I.
    The method of paired comparisons. *Biometrika*, 39(3/4), 324-345.
    Hunter, D. R. (2004). MM algorithms for generalized Bradley-Terry models. *Annals of
    Statistics*, 32(1), 384-406.
    """
    return _pairwise(
        data, cond_a, cond_b, selection, reference, n_boot, ci, seed, prior_sd, observer, "logit", "score",
        weight,
    )


# --------------------------------------------------------------------------------------
# Plackett-Luce
# --------------------------------------------------------------------------------------


def _is_missing(v: Any) -> bool:
    if v is None or v is pd.NA:
        return True
    try:
        return bool(pd.isna(v))
    except (TypeError, ValueError):
        return False


def _parse_options(v: Any, row: Any) -> list:
    if isinstance(v, str):
        opts = [s.strip() for s in v.split("|") if s.strip() != ""]
    elif isinstance(v, (list, tuple, set, frozenset, np.ndarray, pd.Series)):
        opts = list(v)
    else:
        raise ValueError(  # noqa: TRY004
            f"options in row {row!r} must be a list/tuple or a '|'-separated string, got {type(v).__name__}"
        )
    if len(set(opts)) != len(opts):
        raise ValueError(f"options in row {row!r} contain duplicates")
    if len(opts) < 2:
        raise ValueError(f"options in row {row!r} must offer at least two conditions")
    return opts


def plackett_luce(
    data: pd.DataFrame,
    ranking_cols: Sequence[str] = ("first", "second"),
    options_col: str = "options",
    reference: Any = None,
    n_boot: int = 0,
    ci: float = 0.95,
    seed: Any = 0,
    *,
    prior_sd: float = 10.0,
    observer: str | None = "observer",
) -> pd.DataFrame:
    """Plackett-Luce log-strengths from top-k-of-N choices (partial rankings).

    Parameters
    ----------
    data : pandas.DataFrame
        One row per trial.
    ranking_cols : sequence of str
        Columns with the chosen conditions, best first (default ``("first", "second")``).
        Later positions may be missing (NaN/None), e.g. a participant who picked only one;
        a position after a missing one must be missing too. Rows whose first choice is
        missing are dropped.
    options_col : str
        Column with the offered set: a list/tuple, or a ``'|'``-separated string (then the
        condition labels are strings; a non-string choice is matched by ``str``).
    reference, n_boot, ci, seed, prior_sd, observer
        As in :func:`thurstone_jod` (``prior_sd`` in logits).

    Returns
    -------
    pandas.DataFrame
        ``condition``, ``score`` (log-strength, reference = 0), ``ci_low``, ``ci_high``
        (only when ``n_boot > 0``), ``n_first``, ``n_second`` (times chosen at position 1
        and 2; ``n_second`` is 0 when ``ranking_cols`` has a single column), ``n_offered``.

    Notes
    -----
    A partial ranking :math:`c_1 \\succ c_2 \\succ \\dots \\succ c_m` from the offered set
    :math:`S` has likelihood

    .. math:: \\prod_{r=1}^{m} \\frac{e^{s_{c_r}}}{\\sum_{j \\in S \\setminus
              \\{c_1, \\dots, c_{r-1}\\}} e^{s_j}},

    i.e. a sequence of multinomial-logit choices; with first choices only this is the
    multinomial logit, and with two options it is Bradley-Terry. Scores are the MAP
    estimate under the weak Gaussian prior of the module docstring, reference fixed at 0.

    References
    ----------
    Luce, R. D. (1959). *Individual Choice Behavior*. Wiley.
    Plackett, R. L. (1975). The analysis of permutations. *Applied Statistics*, 24(2).
    Hunter, D. R. (2004). MM algorithms for generalized Bradley-Terry models. *Annals of
    Statistics*, 32(1), 384-406.
    """
    if isinstance(ranking_cols, str):
        ranking_cols = (ranking_cols,)
    ranking_cols = tuple(ranking_cols)
    if len(ranking_cols) == 0:
        raise ValueError("ranking_cols must name at least one column")
    df = _check_frame(data, [*ranking_cols, options_col])
    n_boot_i, ci_f, tau = _check_common(n_boot, ci, prior_sd)
    keep = [
        not _is_missing(f) and not (np.ndim(o) == 0 and _is_missing(o))
        for f, o in zip(df[ranking_cols[0]], df[options_col])
    ]
    df = df.loc[np.asarray(keep, dtype=bool)]

    trials: list[tuple[list, list]] = []
    for row, opts_raw, *choices in zip(df.index, df[options_col], *(df[c] for c in ranking_cols)):
        opts = _parse_options(opts_raw, row)
        ranked: list = []
        ended = False
        for c in choices:
            if _is_missing(c):
                ended = True
                continue
            if ended:
                raise ValueError(f"row {row!r} has a choice after a missing one in {ranking_cols!r}")
            if c not in opts and str(c) in opts:
                c = str(c)
            if c not in opts:
                raise ValueError(f"row {row!r}: choice {c!r} is not among the offered options")
            if c in ranked:
                raise ValueError(f"row {row!r}: condition {c!r} is ranked twice")
            ranked.append(c)
        trials.append((opts, ranked))

    labels = _sorted_labels([o for opts, _ in trials for o in opts])
    k = len(labels)
    ref = _reference_index(labels, reference)
    index = {lab: i for i, lab in enumerate(labels)}
    _check_connected(k, [np.array([index[o] for o in opts]) for opts, _ in trials])

    ev_row: list[int] = []
    ev_chosen: list[int] = []
    ev_mask: list[np.ndarray] = []
    n_pos = np.zeros((max(len(ranking_cols), 2), k), dtype=np.int64)
    n_offered = np.zeros(k, dtype=np.int64)
    for r, (opts, ranked) in enumerate(trials):
        avail = np.zeros(k, dtype=bool)
        avail[[index[o] for o in opts]] = True
        n_offered[avail] += 1
        for pos, c in enumerate(ranked):
            ci_idx = index[c]
            n_pos[pos, ci_idx] += 1
            if avail.sum() < 2:  # choosing the last remaining option carries no information
                break
            ev_row.append(r)
            ev_chosen.append(ci_idx)
            ev_mask.append(avail.copy())
            avail[ci_idx] = False
    rows = np.asarray(ev_row, dtype=np.intp)
    chosen = np.asarray(ev_chosen, dtype=np.intp)
    mask = np.asarray(ev_mask, dtype=bool).reshape(-1, k)

    def fit_weighted(w_rows: np.ndarray, x0: np.ndarray | None) -> np.ndarray:
        w = w_rows[rows]
        use = w > 0
        obj = _choice_objective(chosen[use], mask[use], w[use], k)
        return _map_fit(obj, k, ref, tau, x0)

    n = len(trials)
    q = fit_weighted(np.ones(n), None)
    out = pd.DataFrame({"condition": labels, "score": q})
    if n_boot_i > 0:
        clusters = _observer_codes(df, observer)
        lo, hi = _bootstrap(fit_weighted, n, clusters, q, n_boot_i, ci_f, seed)
        out["ci_low"] = lo
        out["ci_high"] = hi
    out["n_first"] = n_pos[0]
    out["n_second"] = n_pos[1]
    out["n_offered"] = n_offered
    return out
