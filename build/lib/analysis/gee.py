"""Logistic GEE of repeated binary answers: odds ratios against a reference condition.

Participants answer many trials, so their answers are not independent; the seeds' rank tests on per-participant
means sidestep this, and a generalised estimating equation (GEE) models it directly: a logistic model of every
single answer, participants as clusters, an exchangeable working correlation within a participant and robust
(sandwich) standard errors, which stay valid when the working correlation is wrong (Liang & Zeger 1986).

statsmodels is imported when :func:`logistic_gee` is called, not with :mod:`analysis`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd
from scipy import special

from data_schema.errors import UserError

from ._validation import as_float_1d, check_frame, levels_in_order, py_scalar

__all__ = ["GEE_COLUMNS", "logistic_gee"]

#: Columns of :func:`logistic_gee`'s result, in order.
GEE_COLUMNS = ("condition", "n", "events", "rate", "log_or", "se", "odds_ratio", "ci_low", "ci_high", "z", "p",
               "n_participants", "working_corr", "note")
_Z975 = float(special.ndtri(0.975))


def _empty_row(cond: Any, y: np.ndarray, note: str) -> dict:
    return {"condition": cond, "n": int(y.size), "events": int(y.sum()), "rate": float(y.mean()) if y.size else np.nan,
            "log_or": np.nan, "se": np.nan, "odds_ratio": np.nan, "ci_low": np.nan, "ci_high": np.nan,
            "z": np.nan, "p": np.nan, "n_participants": 0, "working_corr": np.nan, "note": note}


def logistic_gee(
    data: pd.DataFrame,
    dv: str,
    between: str,
    subject: str,
    reference: Any,
    order: Sequence[Any] | None = None,
    intercept: bool = True,
    maxiter: int = 200,
    ctol: float = 1e-10,
) -> pd.DataFrame:
    """Logistic GEE of 0/1 answers by condition, participants as clusters; odds ratios with Wald tests.

    Parameters
    ----------
    data : DataFrame
        One row per answer (trial).
    dv : str
        Column of the 0/1 answers (NaN rows are dropped).
    between : str
        Column of the condition labels.
    subject : str
        Column of the participant (cluster) ids.
    reference : scalar
        The reference condition.
    order : sequence, optional
        Conditions in output order (default: categorical order, else sorted).
    intercept : bool
        True (yes/no answers): ``logit P(y = 1) = b0 + b_c`` with treatment coding, so ``odds_ratio`` is the
        odds of a yes under condition c over the odds under the reference (which must be in ``data``).
        False (2AFC choices against the reference, ``y = 1`` when condition c was chosen over the
        reference): ``logit P(y = 1) = b_c``, so ``odds_ratio`` is the odds of choosing c over the reference
        (1 = no preference) and ``data`` holds no reference rows.
    maxiter, ctol : int, float
        Iteration limit and convergence tolerance of statsmodels' GEE fit.

    Returns
    -------
    DataFrame
        One row per non-reference condition (:data:`GEE_COLUMNS`): ``n`` answers, ``events`` (answers = 1),
        ``rate``, ``log_or`` (the coefficient), ``se`` (robust), ``odds_ratio`` = exp(log_or), its 95 % Wald
        interval ``ci_low``/``ci_high`` = exp(log_or -+ 1.96 se), ``z`` = log_or / se, two-sided
        ``p`` = 2 Phi(-|z|), the number of participants and the estimated working correlation of the fit, and
        ``note`` ("" or why the row is NaN).

    Raises
    ------
    ValueError
        Missing columns, answers other than 0/1, an unknown reference, or no condition to compare.

    Notes
    -----
    statsmodels ``GEE`` with ``families.Binomial()`` (logit link), ``cov_struct.Exchangeable()`` and robust
    covariance, fitted with ``ddof_scale=0``: the working correlation is then estimated as geepack does by
    default, :math:`\\hat\\alpha = \\sum_i \\sum_{j<k} r_{ij} r_{ik} / (\\hat\\phi \\sum_i n_i(n_i - 1)/2)`
    with Pearson residuals :math:`r` and :math:`\\hat\\phi = \\sum r^2 / N`. The coefficients and standard
    errors agree with R's ``geepack::geeglm(y ~ condition, id = participant, family = binomial,
    corstr = "exchangeable")`` (data sorted by participant; ``control = geese.control(epsilon = 1e-12)``) to
    4e-15 (tests/test_analysis_gee.py; the issue asks 1e-6).

    **Undefined rows** (NaN with a ``note``, the others are still fitted): a condition whose answers are all 0
    or all 1 has an infinite log odds (separation) and is left out of the fit; with ``intercept=True`` the same
    for the reference makes every odds ratio undefined; fewer than two participants leave the robust variance
    undefined; a fit that does not converge is reported as such, never as numbers.

    References
    ----------
    Liang, K.-Y. & Zeger, S. L. (1986). Longitudinal data analysis using generalized linear models.
    *Biometrika*, 73(1), 13-22.
    Halekoh, U., Hojsgaard, S. & Yan, J. (2006). The R package geepack for generalized estimating equations.
    *Journal of Statistical Software*, 15(2), 1-11.
    """
    check_frame(data, {"dv": dv, "between": between, "subject": subject})
    y_all = as_float_1d(data[dv], f"column {dv!r}")
    labels = data[between]
    keep = ~np.isnan(y_all) & labels.notna().to_numpy() & data[subject].notna().to_numpy()
    y_all, lab, subj = y_all[keep], labels.to_numpy()[keep], data[subject].to_numpy()[keep]
    if not np.all((y_all == 0.0) | (y_all == 1.0)):
        raise UserError(f"column {dv!r} must hold 0/1 answers for a logistic GEE")
    levels = levels_in_order(labels[keep], order, between)
    reference = py_scalar(reference)
    if intercept and reference not in levels:
        raise UserError(f"reference {reference!r} has no answers in column {between!r}")
    conds = [c for c in levels if c != reference]
    if not conds:
        raise UserError(f"no condition other than the reference {reference!r} to compare")
    per = {c: y_all[lab == c] for c in levels}

    def separated(c: Any) -> str | None:
        """Why condition ``c``'s log odds cannot be estimated, or None."""
        y = per[c]
        if y.size == 0:
            return "no answers"
        if y.min() == y.max():
            return f"every answer {int(y[0])}: infinite log odds"
        return None

    notes = {c: (f"not estimable ({separated(c)})" if separated(c) else None) for c in conds}
    if intercept and separated(reference):
        notes = {c: f"not estimable (reference {reference!r}: {separated(reference)})" for c in conds}
    fit_conds = [c for c in conds if notes[c] is None]
    use = np.isin(lab, fit_conds + ([reference] if intercept else []))
    n_part = len(pd.unique(subj[use]))
    if fit_conds and n_part < 2:
        notes.update({c: "not estimable (fewer than 2 participants)" for c in fit_conds})
        fit_conds = []
    result: dict[Any, dict] = {c: _empty_row(c, per[c], notes[c] or "") for c in conds}
    if fit_conds:
        x_lab, y, groups = lab[use], y_all[use], pd.factorize(subj[use])[0]
        exog = (x_lab[:, None] == np.array(fit_conds, dtype=object)[None, :]).astype(float)
        if intercept:
            exog = np.column_stack([np.ones(len(y)), exog])
        params, bse, alpha, converged = _fit(y, exog, groups, maxiter, ctol)
        for idx, c in enumerate(fit_conds, start=1 if intercept else 0):
            row = result[c]
            row.update(n_participants=n_part, working_corr=alpha)
            if not converged:
                row["note"] = f"not estimable (GEE did not converge in {maxiter} iterations)"
                continue
            b, se = float(params[idx]), float(bse[idx])
            z = b / se
            row.update(log_or=b, se=se, odds_ratio=float(np.exp(b)), ci_low=float(np.exp(b - _Z975 * se)),
                       ci_high=float(np.exp(b + _Z975 * se)), z=z, p=float(min(1.0, 2.0 * special.ndtr(-abs(z)))))
    out = pd.DataFrame([result[c] for c in conds], columns=list(GEE_COLUMNS))
    return out.astype({"n": np.int64, "events": np.int64, "n_participants": np.int64})


def _fit(y: np.ndarray, exog: np.ndarray, groups: np.ndarray, maxiter: int, ctol: float):
    """statsmodels GEE (imported here: ``import analysis`` stays light); params, robust SEs, alpha, converged."""
    import warnings

    from statsmodels.genmod import cov_struct, families
    from statsmodels.genmod.generalized_estimating_equations import GEE
    from statsmodels.tools.sm_exceptions import ConvergenceWarning

    model = GEE(y, exog, groups=groups, family=families.Binomial(), cov_struct=cov_struct.Exchangeable())
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        # a fit that breaks down is reported through `converged` (the row's note), not as warnings on stderr
        warnings.simplefilter("ignore", ConvergenceWarning)
        warnings.simplefilter("ignore", RuntimeWarning)
        res = model.fit(maxiter=maxiter, ctol=ctol, ddof_scale=0)
    alpha = float(np.asarray(model.cov_struct.dep_params).ravel()[0])
    ok = bool(res.converged) and np.all(np.isfinite(res.params)) and np.all(np.isfinite(res.bse))
    return np.asarray(res.params), np.asarray(res.bse), alpha, ok
