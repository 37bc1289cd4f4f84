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

Priors (``prior=``)
    Unanimous or near-unanimous comparisons make the plain maximum-likelihood estimate
    diverge, so the scores are maximum-a-posteriori estimates under one of three priors:

    ``"weak"`` (the default, all three estimators)
        A weak Gaussian prior on **every pairwise difference** of scores,

        .. math:: \\log p(q) = -\\sum_{i<j} \\frac{(q_i - q_j)^2}{2\\,\\tau^2},

        with ``tau = prior_sd`` (default 10 in the estimator's own units: 10 JOD for
        :func:`thurstone_jod`, 10 logits for the others). It depends only on differences,
        so the estimate does not depend on the choice of reference; it is weak enough that
        a 75/100 preference gives 1 JOD (ln 3 logits) to within 1e-3, yet keeps a 20/0
        preference finite (about 4.6 JOD). It is *not* pwcmp's prior: where several pairs
        are unanimous, pwcmp's data-derived prior pulls the extreme conditions in much
        harder (up to several JOD, see ``"pwcmp"``).
    ``"pwcmp"`` (:func:`thurstone_jod` only)
        pwcmp's data-derived prior, as ``pw_scale`` uses it by default (``'prior',
        'gaussian'``): see :func:`thurstone_jod`. With it the JOD scale reproduces pwcmp's
        output (differences to its published example: below 2e-6 JOD).
    ``"none"``
        Maximum likelihood. It exists only if every condition both won and lost against
        the others in a chain of comparisons (the directed graph "i beat j at least once"
        is strongly connected; Zermelo 1929, Ford 1957); otherwise a ``ValueError`` says
        so. Bootstrap intervals are NaN when some replicate has no maximum-likelihood
        estimate. Without a prior the Bradley-Terry scores are those of choix's ILSR.

    Every fit is a Newton iteration with the exact Hessian, run until the gradient vanishes
    to 1e-9 per comparison;
    a fit that does not get there raises :class:`ConvergenceError` instead of returning
    an unconverged estimate.

Selection encoding (:func:`thurstone_jod`, :func:`bradley_terry`)
    ``selection`` holds the *number* of the chosen condition: 1 when ``condition_1`` was
    chosen, 2 when ``condition_2`` was, as :func:`data_schema.store.export_pwcmp` writes it;
    an exported file scales without recoding. 0/1 codings are refused rather than guessed:
    pwcmp's own 0/1 columns have meant both "1 = condition_1 chosen" (``is_A_selected``) and
    "0 = condition_1 chosen" (``selection`` in its 2018-2022 examples).

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
from scipy import special

from data_schema.errors import UserError

from .vocabulary import PRIORS

__all__ = ["JOD_SIGMA", "ConvergenceError", "bradley_terry", "plackett_luce", "thurstone_jod"]


class ConvergenceError(UserError):
    """A scale whose fit did not converge (one line; never an unconverged estimate returned silently).

    A :class:`~data_schema.errors.UserError`: the data the user gave cannot be scaled (the CLI prints the one
    line and exits 2, no traceback)."""

#: Standard deviation of the Thurstone difference distribution in JOD units:
#: ``Phi(1 / JOD_SIGMA) = 0.75``, i.e. 1 JOD is the difference that 75 % of observers see.
JOD_SIGMA: float = float(1.0 / special.ndtri(0.75))  # 1.482602...

_LOG_SQRT_2PI = 0.5 * np.log(2.0 * np.pi)


# --------------------------------------------------------------------------------------
# validation helpers
# --------------------------------------------------------------------------------------


def _check_frame(data: Any, cols: Sequence[str]) -> pd.DataFrame:
    if not isinstance(data, pd.DataFrame):
        raise UserError(f"data must be a pandas DataFrame, got {type(data).__name__}")  # noqa: TRY004
    missing = [c for c in cols if c not in data.columns]
    if missing:
        raise UserError(f"data is missing column(s): {', '.join(map(repr, missing))}")
    return data


def _check_common(n_boot: Any, ci: Any, prior: Any, prior_sd: Any,
                  allowed: Sequence[str] = ("none", "weak")) -> tuple[int, float, str, float]:
    """Validate the shared arguments; return ``(n_boot, ci, prior, tau)`` (tau = inf without the weak prior)."""
    if isinstance(n_boot, bool) or not isinstance(n_boot, (int, np.integer)) or n_boot < 0:
        raise UserError(f"n_boot must be a non-negative integer, got {n_boot!r}")
    try:
        ci_f = float(ci)
    except (TypeError, ValueError):
        raise UserError(f"ci must be a number in (0, 1), got {ci!r}") from None
    if not 0.0 < ci_f < 1.0:
        raise UserError(f"ci must be in (0, 1), got {ci!r}")
    if prior not in allowed:
        known = [p for p in PRIORS if p in allowed]
        raise UserError(f"prior={prior!r} is invalid here: allowed {', '.join(known)}")
    try:
        tau = float(prior_sd)
    except (TypeError, ValueError):
        raise UserError(f"prior_sd must be a positive number, got {prior_sd!r}") from None
    if not tau > 0.0:
        raise UserError(f"prior_sd must be positive (np.inf for no prior), got {prior_sd!r}")
    if prior == "weak" and np.isinf(tau):
        prior = "none"
    return int(n_boot), ci_f, prior, (tau if prior == "weak" else np.inf)


def _sorted_labels(values: Any) -> list:
    uniq = list(dict.fromkeys(values))
    try:
        return sorted(uniq)
    except TypeError:
        return sorted(uniq, key=lambda v: (type(v).__name__, str(v)))


def _reference_index(labels: list, reference: Any) -> int:
    if len(labels) < 2:
        raise UserError(f"need at least two conditions, got {len(labels)}")
    if reference is None:
        return 0
    if reference not in labels:
        raise UserError(f"reference {reference!r} is not one of the conditions")
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
        raise UserError(
            f"the comparison graph is disconnected ({n_comp} components); scores are not comparable"
        )


def _row_weights(df: pd.DataFrame, weight: str | None) -> np.ndarray:
    """Multiplicity of each row: 1, or the non-negative integer counts in column ``weight``."""
    if weight is None:
        return np.ones(len(df))
    w = pd.to_numeric(df[weight], errors="coerce").to_numpy(dtype=float)
    if not np.all(np.isfinite(w) & (w >= 0) & (w == np.rint(w))):
        raise UserError(f"column {weight!r} must hold non-negative integer counts")
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


def _gtol(total_weight: float) -> float:
    """Gradient tolerance of a converged fit: 1e-9 per comparison (the objective is a sum over comparisons)."""
    return 1e-9 * (1.0 + float(total_weight))


def _newton(fgh: Callable[..., tuple[float, np.ndarray, np.ndarray | None]], x0: np.ndarray, gtol: float,
            max_iter: int = 200) -> tuple[np.ndarray, float]:
    """Minimise by Newton's method with backtracking; return ``(x, max |gradient|)``.

    Where the Hessian is not positive definite (pwcmp's prior is not convex) it is shifted by a multiple of the
    identity until it is. A full step is taken when it decreases ``f`` (Armijo) or, once ``f`` no longer changes
    beyond rounding, when it decreases the gradient; otherwise the step is halved. The loop ends when the
    gradient is below ``1e-4 gtol`` or no step makes progress; the caller checks the gradient against ``gtol``.
    """
    x = np.asarray(x0, dtype=float).copy()
    f, g, h = fgh(x)

    def gmax(v: np.ndarray) -> float:
        return float(np.max(np.abs(v))) if v.size else 0.0

    for _ in range(max_iter):
        if gmax(g) <= 1e-4 * gtol:  # well inside the tolerance: one Newton step past gtol costs little
            break
        shift = 0.0
        while True:
            try:
                chol = np.linalg.cholesky(h + shift * np.eye(x.size))
                break
            except np.linalg.LinAlgError:
                shift = max(2.0 * shift, 1e-8 * (1.0 + float(np.max(np.abs(np.diag(h))))))
        step = -np.linalg.solve(chol.T, np.linalg.solve(chol, g))
        slope = float(g @ step)
        f_new, g_new, h_new = fgh(x + step)
        at_rounding = abs(f_new - f) <= 1e-13 * (1.0 + abs(f))
        if np.isfinite(f_new) and (f_new <= f + 1e-4 * slope or (at_rounding and gmax(g_new) < gmax(g))):
            x, f, g, h = x + step, f_new, g_new, h_new
            continue
        t = 0.5
        while t > 1e-12:
            f_new = fgh(x + t * step, hess=False)[0]
            if np.isfinite(f_new) and f_new <= f + 1e-4 * t * slope:
                break
            t *= 0.5
        else:
            break  # no step decreases f: at the floor of floating-point noise
        x = x + t * step
        f, g, h = fgh(x)
    return x, gmax(g)


def _map_fit(objective: Objective, k: int, ref: int, tau: float, total_weight: float,
             x0: np.ndarray | None = None) -> np.ndarray:
    """Minimise ``objective(q) + weak prior(q)`` over ``q`` with ``q[ref] = 0``; return full ``q``.

    ``objective(q)`` returns ``(f, gradient, Hessian)``. Raises :class:`ConvergenceError` unless the gradient
    ends below :func:`_gtol`.
    """
    free = np.array([i for i in range(k) if i != ref])
    inv_t2 = 0.0 if np.isinf(tau) else 1.0 / tau**2
    prior_h = inv_t2 * (k * np.eye(k) - np.ones((k, k)))

    def full(x: np.ndarray) -> np.ndarray:
        q = np.zeros(k)
        q[free] = x
        return q

    def fgh(x: np.ndarray, hess: bool = True):
        q = full(x)
        f, g, h = objective(q)
        s = q.sum()
        f = f + 0.5 * inv_t2 * (k * q @ q - s * s)
        g = (g + inv_t2 * (k * q - s))[free]
        if not hess:
            return f, g, None
        return f, g, (h + prior_h)[np.ix_(free, free)]

    start = np.zeros(k - 1) if x0 is None else np.asarray(x0, dtype=float)[free]
    x, gmax = _newton(fgh, start, _gtol(total_weight))
    q = full(x)
    if not (np.all(np.isfinite(q)) and gmax <= _gtol(total_weight)):
        raise ConvergenceError(f"the scale's fit did not converge (largest gradient {gmax:.3g}, needed "
                               f"{_gtol(total_weight):.3g})")
    return q


def _strongly_connected(win: np.ndarray, lose: np.ndarray, k: int) -> bool:
    """Is the directed graph ``win -> lose`` on ``k`` nodes strongly connected (every node reaches every node)?"""
    adj = np.zeros((k, k), dtype=bool)
    adj[win, lose] = True

    def reach(a: np.ndarray) -> int:
        seen = np.zeros(k, dtype=bool)
        seen[0] = True
        frontier = seen.copy()
        while frontier.any():
            nxt = a[frontier].any(axis=0) & ~seen
            seen |= nxt
            frontier = nxt
        return int(seen.sum())

    return reach(adj) == k and reach(adj.T) == k


def _pwcmp_objective(counts: np.ndarray) -> Objective:
    """pwcmp's ``pw_scale`` objective (default ``'prior', 'gaussian'``) for the ``k x k`` win-count matrix.

    ``counts[i, j]`` = times i was chosen over j. Returns f, its gradient and its Hessian, all exact (the
    formula is in :func:`thurstone_jod`). Everything is computed per ordered pair ``a`` on the distances
    ``x_a = (q_i - q_j) / sigma`` and mapped back to ``q`` by the chain rule.
    """
    k = counts.shape[0]
    d = np.asarray(counts, dtype=float)
    n_ij = d + d.T
    unanimous = (n_ij > 0) & ~((d > 0) & (d.T > 0))
    k_adj = d.copy()  # pwcmp's D_wUA: unanimous answers moved to the closest non-unanimous split
    k_adj[unanimous & (d == 0)] = 1.0
    k_adj[unanimous & (d != 0)] -= 1.0
    i, j = np.nonzero(n_ij > 0)  # every compared pair in both orientations, as pwcmp's nnz_d
    d_a, d_t, n_b, k_b = d[i, j], d[j, i], n_ij[i, j], k_adj[i, j]
    m_b = n_b - k_b
    jac = np.zeros((i.size, k))  # d x / d q, times sigma
    jac[np.arange(i.size), i] = 1.0
    jac[np.arange(i.size), j] -= 1.0
    sigma = JOD_SIGMA

    def objective(q: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        x = (q[i] - q[j]) / sigma
        lp, lm = special.log_ndtr(x), special.log_ndtr(-x)
        log_phi = -0.5 * x * x - _LOG_SQRT_2PI
        r, s = np.exp(log_phi - lp), np.exp(log_phi - lm)  # phi/Phi(x), phi/Phi(-x)
        lp2, lm2 = -r * (x + r), -s * (s - x)  # second derivatives of log Phi(x), log Phi(-x)
        # w[a, b]: pair b's (adjusted) answers at pair a's distance, normalised over a; prior[a] = sum_b w[a, b]
        big_l = lp[:, None] * k_b[None, :] + lm[:, None] * m_b[None, :]
        w = np.exp(big_l - special.logsumexp(big_l, axis=0)[None, :])
        prior = w.sum(axis=1)
        f = -float(np.sum(d_a * lp + d_t * lm)) - float(np.sum(np.log(prior + 0.1)))
        u = 1.0 / (prior + 0.1)
        v = u @ w
        dl = r[:, None] * k_b[None, :] - s[:, None] * m_b[None, :]  # d L[a, b] / d x_a
        t = w * dl
        p_row = t.sum(axis=1)
        grad_x = -(d_a * r - d_t * s) - np.sum(t * (u[:, None] - v[None, :]), axis=1)
        # Hessian in x: likelihood (diagonal) + prior (dense); M = d prior / d x
        dll = lp2[:, None] * k_b[None, :] + lm2[:, None] * m_b[None, :]
        m_mat = np.diag(p_row) - w @ t.T
        diag = -(d_a * lp2 + d_t * lm2) - np.sum(w * (dl * dl + dll) * (u[:, None] - v[None, :]), axis=1)
        h_x = ((t * (u[:, None] - v[None, :])) @ t.T + (u * u * p_row)[:, None] * m_mat
               - (t @ w.T) @ ((u * u)[:, None] * m_mat) + (t @ t.T) * u[None, :] - (t * v[None, :]) @ t.T)
        h_x = 0.5 * (h_x + h_x.T)
        h_x[np.diag_indices_from(h_x)] += diag
        return f, jac.T @ grad_x / sigma, jac.T @ h_x @ jac / sigma**2

    return objective


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


def _batched_pairwise_fit(counts: np.ndarray, ref: int, tau: float, model: str,
                          q0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MAP scores of many replicates at once: damped Newton on ``counts[b, i, j]`` (i beat j).

    The same objective as :func:`_pairwise_objective` plus the prior of :func:`_map_fit`, minimised for
    all ``B`` replicates together (batched Hessian solves), starting from ``q0``; used by the bootstrap,
    where thousands of small fits would otherwise cost a call each. With the weak prior the objective is
    strictly convex, so Newton with step halving converges. Returns the scores and, per replicate, whether
    the gradient ended below :func:`_gtol` (without a prior a replicate may have no maximum-likelihood
    estimate).
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
    gtol = np.array([_gtol(c) for c in counts.sum(axis=(1, 2))])
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
        small_g = np.max(np.abs(g_a[:, free]), axis=1) <= gtol[a]
        active[a[small_g | (np.max(np.abs(t[:, None] * step), axis=1) < 1e-13)]] = False
    converged = np.max(np.abs(g[:, free]), axis=1) <= gtol
    return q, converged & np.all(np.isfinite(q), axis=1)


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


def _selection_codes(sel: pd.Series, selection: str, cond_a: str, cond_b: str) -> np.ndarray:
    """The ``selection`` column as 1 (``cond_a`` chosen) / 2 (``cond_b`` chosen), or a one-line ValueError."""
    numeric = pd.api.types.is_numeric_dtype(sel) and not pd.api.types.is_bool_dtype(sel)
    values = sel.to_numpy(dtype=float) if numeric else np.full(len(sel), np.nan)
    bad = ~((values == 1.0) | (values == 2.0))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        v = sel.iloc[i]
        v = v.item() if isinstance(v, np.generic) else v
        hint = (" (a 0/1 coding is ambiguous: pwcmp's is_A_selected has 1 = condition_1 chosen, its older "
                "selection column 0 = condition_1 chosen; recode to 1/2)") if v in (0, 1, True, False) else ""
        raise UserError(f"column {selection!r} must hold 1 ({cond_a} chosen) or 2 ({cond_b} chosen), as "
                         f"studyapp's pwcmp export writes; row {sel.index[i]!r} has {v!r}{hint}")
    return values


def _pairwise(
    data: Any,
    cond_a: str,
    cond_b: str,
    selection: str,
    reference: Any,
    n_boot: Any,
    ci: Any,
    seed: Any,
    prior: Any,
    prior_sd: Any,
    observer: str | None,
    model: str,
    score_name: str,
    weight: str | None = None,
) -> pd.DataFrame:
    df = _check_frame(data, [cond_a, cond_b, selection] + ([weight] if weight else []))
    allowed = ("none", "weak", "pwcmp") if model == "thurstone" else ("none", "weak")
    n_boot_i, ci_f, prior, tau = _check_common(n_boot, ci, prior, prior_sd, allowed)
    df = df.dropna(subset=[cond_a, cond_b, selection])
    sel_v = _selection_codes(df[selection], selection, cond_a, cond_b)
    a_vals = df[cond_a].to_numpy(dtype=object)
    b_vals = df[cond_b].to_numpy(dtype=object)
    if np.any(a_vals == b_vals):
        raise UserError(f"a row compares a condition with itself ({cond_a!r} == {cond_b!r})")
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

    def has_mle(counts: np.ndarray) -> bool:
        nz = np.flatnonzero(counts)
        return _strongly_connected(nz // k, nz % k, k)

    def fit_weighted(w_rows: np.ndarray, x0: np.ndarray | None) -> np.ndarray:
        counts = np.bincount(code_row, w_rows * base_w, k * k)
        if prior == "pwcmp":
            return _map_fit(_pwcmp_objective(counts.reshape(k, k)), k, ref, np.inf, counts.sum(), None)
        if prior == "none" and not has_mle(counts):
            return np.full(k, np.nan)
        nz = np.flatnonzero(counts)
        obj = _pairwise_objective(nz // k, nz % k, counts[nz], k, model)
        return _map_fit(obj, k, ref, tau, counts.sum(), x0)

    n = len(df)
    if prior == "none" and not has_mle(np.bincount(code_row, base_w, k * k)):
        raise UserError("without a prior the maximum-likelihood scale does not exist: some conditions won "
                         "(or lost) every comparison with the rest; use prior='weak' or 'pwcmp'")
    q = fit_weighted(np.ones(n), None)
    out = pd.DataFrame({"condition": labels, score_name: q})
    if n_boot_i > 0:
        clusters = _observer_codes(df, observer)
        fit_many = None
        if prior != "pwcmp":

            def fit_many(w_reps: np.ndarray, x0: np.ndarray) -> np.ndarray:
                counts = np.stack([np.bincount(code_row, w * base_w, k * k) for w in w_reps])
                ok = np.array([prior != "none" or has_mle(c) for c in counts])
                reps = np.full((len(w_reps), k), np.nan)
                if ok.any():
                    fitted, converged = _batched_pairwise_fit(counts[ok].reshape(-1, k, k), ref, tau, model, x0)
                    if not converged.all():
                        raise ConvergenceError(f"{int((~converged).sum())} bootstrap fit(s) did not converge")
                    reps[ok] = fitted
                return reps

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
    prior: str = "weak",
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
        Column with the outcome: ``1`` if ``cond_a`` was chosen, ``2`` if ``cond_b`` was
        (the layout :func:`data_schema.store.export_pwcmp` writes: ``observer, session, scene,
        condition_1, condition_2, selection``). Any other value, 0/1 codings and the chosen
        condition's *name* included, raises ``ValueError`` (see the module docstring).
    reference : hashable, optional
        Condition fixed at 0 JOD. Default: the first condition in sorted order.
    n_boot : int
        Number of bootstrap replicates for a percentile confidence interval; ``0`` (the
        default) omits the ``ci_low``/``ci_high`` columns.
    ci : float
        Confidence level of the interval, in (0, 1).
    seed : int or numpy.random.Generator seed
        Seed of the bootstrap; the same seed gives identical output.
    prior : {"weak", "pwcmp", "none"}, keyword-only
        ``"weak"`` (default): a Gaussian prior with SD ``prior_sd`` JOD on every pairwise
        difference, which barely moves non-unanimous data; ``"pwcmp"``: pwcmp's data-derived
        prior (Notes), which pulls unanimous pairs in much harder: with several unanimous
        pairs the extreme conditions differ by up to several JOD between the two;
        ``"none"``: maximum likelihood (module docstring).
    prior_sd : float, keyword-only
        SD in JOD of the weak prior (``np.inf`` = no prior).
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
    reference held at 0 (Newton's method to a vanishing gradient, see the module docstring).

    **pwcmp's prior** (``prior="pwcmp"``; ``pw_scale.m`` of pwcmp, default ``'gaussian'``
    prior, as in its 2020-2025 versions). Over the ordered pairs :math:`a = (i, j)` that were
    compared (both orientations, as pwcmp counts them), with :math:`P_a = \\Phi((q_i - q_j)/\\sigma)`,
    :math:`n_a = n_{ij} + n_{ji}` and :math:`k_a` the count :math:`n_{ij}`, except that a
    unanimous pair's 0 becomes 1 and its :math:`n` becomes :math:`n - 1` (pwcmp's ``D_wUA``),
    the prior weight of pair :math:`a` is how well its distance explains every pair's
    answers,

    .. math:: \\pi_a = \\sum_b \\frac{P_a^{k_b} (1 - P_a)^{n_b - k_b}}
                                   {\\sum_{a'} P_{a'}^{k_b} (1 - P_{a'})^{n_b - k_b}},

    and the scores minimise

    .. math:: -\\sum_a \\big[n_{ij} \\log P_a + n_{ji} \\log (1 - P_a)\\big]
              - \\sum_a \\log(\\pi_a + 0.1)

    (the likelihood term is pwcmp's: summed over both orientations, so each pair's
    log-likelihood counts twice). pwcmp centres its scores (mean 0, or the first condition
    at 0); only differences are defined, and here the reference is 0. The terms are
    computed in log space, so large counts do not underflow as they can in ``pw_scale.m``.
    On pwcmp's published example (``examples/ex3_tmo_cmp_scaled.csv`` of its 2022 commit
    80ab538, 7 tone-mapping operators, 5 scenes and all scenes) the scores agree with pwcmp's
    to 1.4e-6 JOD.

    References
    ----------
    Thurstone, L. L. (1927). A law of comparative judgment. *Psychological Review*, 34(4).
    Perez-Ortiz, M., & Mantiuk, R. K. (2017). A practical guide and software for analysing
    pairwise comparison experiments. arXiv:1712.03686 (pwcmp; github.com/mantiuk/pwcmp).

    Examples
    --------
    >>> df = pd.DataFrame({"condition_1": ["a"] * 100, "condition_2": ["b"] * 100,
    ...                    "selection": [1] * 75 + [2] * 25})
    >>> thurstone_jod(df, reference="b").round(2)
      condition  jod  n_comparisons
    0         a  1.0            100
    1         b  0.0            100
    """
    return _pairwise(
        data, cond_a, cond_b, selection, reference, n_boot, ci, seed, prior, prior_sd, observer, "thurstone",
        "jod", weight,
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
    prior: str = "weak",
    prior_sd: float = 10.0,
    observer: str | None = "observer",
    weight: str | None = None,
) -> pd.DataFrame:
    """Bradley-Terry log-strengths of pairwise comparisons (logit scale).

    Parameters are those of :func:`thurstone_jod`; ``prior`` is ``"weak"`` (default, SD
    ``prior_sd`` logits) or ``"none"`` (maximum likelihood: then the scores equal those of
    choix's ``ilsr_pairwise``, Maystre & Grossglauser 2015, to 1e-8).

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
        data, cond_a, cond_b, selection, reference, n_boot, ci, seed, prior, prior_sd, observer, "logit",
        "score", weight,
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
        raise UserError(  # noqa: TRY004
            f"options in row {row!r} must be a list/tuple or a '|'-separated string, got {type(v).__name__}"
        )
    if len(set(opts)) != len(opts):
        raise UserError(f"options in row {row!r} contain duplicates")
    if len(opts) < 2:
        raise UserError(f"options in row {row!r} must offer at least two conditions")
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
    prior: str = "weak",
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
    reference, n_boot, ci, seed, prior, prior_sd, observer
        As in :func:`bradley_terry` (``prior`` ``"weak"`` or ``"none"``, ``prior_sd`` in logits).

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
        raise UserError("ranking_cols must name at least one column")
    df = _check_frame(data, [*ranking_cols, options_col])
    n_boot_i, ci_f, prior, tau = _check_common(n_boot, ci, prior, prior_sd)
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
                raise UserError(f"row {row!r} has a choice after a missing one in {ranking_cols!r}")
            if c not in opts and str(c) in opts:
                c = str(c)
            if c not in opts:
                raise UserError(f"row {row!r}: choice {c!r} is not among the offered options")
            if c in ranked:
                raise UserError(f"row {row!r}: condition {c!r} is ranked twice")
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

    # "i was chosen while j was still available": the MLE exists iff this graph is strongly connected (Hunter 2004)
    ev_i, ev_j = np.nonzero(mask)
    ev_win, ev_lose = chosen[ev_i], ev_j
    not_self = ev_win != ev_lose

    def has_mle(w: np.ndarray) -> bool:
        keep = not_self & (w[ev_i] > 0)
        return _strongly_connected(ev_win[keep], ev_lose[keep], k)

    def fit_weighted(w_rows: np.ndarray, x0: np.ndarray | None) -> np.ndarray:
        w = w_rows[rows]
        if prior == "none" and not has_mle(w):  # a bootstrap replicate without a maximum-likelihood estimate
            return np.full(k, np.nan)
        use = w > 0
        obj = _choice_objective(chosen[use], mask[use], w[use], k)
        return _map_fit(obj, k, ref, tau, w.sum(), x0)

    n = len(trials)
    if prior == "none" and not has_mle(np.ones(len(rows))):
        raise UserError("without a prior the maximum-likelihood scale does not exist (some conditions were "
                         "always or never chosen over the others); use prior='weak'")
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
