"""Figures of a study's analysis (matplotlib, imported lazily; PNG files are byte-stable).

* :func:`votes_figure` - votes per mode and scene, one panel per block (seed 001 Fig 14-15),
* :func:`scale_figure` - JOD (or Plackett-Luce) scores with bootstrap intervals,
* :func:`scores_figure` - mean yes/acceptable score per condition and scene with 95 % intervals,
* :func:`psychometric_figure` - a panel per threshold fit: data, fitted function, threshold and interval,
* :func:`pareto_figure` - cost against probability of detection per renderer, thresholds marked.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["pareto_figure", "psychometric_figure", "scale_figure", "scores_figure", "votes_figure"]

_PALETTE = ("#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e", "#e6ab02", "#a6761d", "#666666")


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    plt.rcParams.update({"svg.hashsalt": "studyapp", "font.size": 9})
    return plt


def _save(fig, path: Path) -> Path:
    from data_schema.atomic import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp:
        # No software/date metadata: the same data give byte-identical files.
        fig.savefig(tmp, format="png", dpi=150, metadata={"Software": None})
    fig.clf()
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path


def votes_figure(votes: pd.DataFrame, order: list[str], path: Path, title: str,
                 labels: dict | None = None) -> Path:
    """Grouped bars: x = scene, one bar per condition, one panel per block."""
    plt = _plt()
    labels = labels or {}
    blocks = list(dict.fromkeys(votes["block"]))
    fig, axes = plt.subplots(1, len(blocks), figsize=(4.2 * len(blocks) + 1.5, 3.4), squeeze=False,
                             sharey=True)
    for ax, b in zip(axes[0], blocks):
        sub = votes[votes["block"] == b]
        scenes = list(dict.fromkeys(sub["scene"]))
        x = np.arange(len(scenes))
        w = 0.8 / len(order)
        for i, c in enumerate(order):
            v = [int(sub[(sub["scene"] == s) & (sub["condition"] == c)]["votes"].sum()) for s in scenes]
            ax.bar(x + (i - (len(order) - 1) / 2) * w, v, w, label=labels.get(c, c),
                   color=_PALETTE[i % len(_PALETTE)])
        ax.set_xticks(x, scenes)
        ax.set_title(b if b else title)
        ax.set_ylabel("votes")
        ax.grid(axis="y", alpha=0.3)
    axes[0][-1].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def scale_figure(scale: pd.DataFrame, path: Path, title: str, labels: dict | None = None) -> Path:
    """Points with bootstrap intervals; JOD if present, else Bradley-Terry, else Plackett-Luce log-strength."""
    plt = _plt()
    labels = labels or {}
    col, lo, hi, unit = next(spec for spec in (
        ("jod", "jod_ci_low", "jod_ci_high", "JOD (1 JOD = 75 % preference)"),
        ("bt", "bt_ci_low", "bt_ci_high", "Bradley-Terry log-strength"),
        ("score", "ci_low", "ci_high", "Plackett-Luce score")) if spec[0] in scale.columns)
    fig, ax = plt.subplots(figsize=(5.5, 3.2))
    y = scale[col].to_numpy(float)
    x = np.arange(len(scale))
    if lo in scale.columns:
        err = np.vstack([y - scale[lo].to_numpy(float), scale[hi].to_numpy(float) - y])
        ax.errorbar(x, y, yerr=np.clip(err, 0, None), fmt="o", capsize=4, color=_PALETTE[0])
    else:
        ax.plot(x, y, "o", color=_PALETTE[0])
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_xticks(x, [labels.get(c, c) for c in scale["condition"]])
    ax.set_ylabel(unit)
    ax.set_title(title)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def scores_figure(units: pd.DataFrame, order: list[str], path: Path, title: str,
                  labels: dict | None = None) -> Path:
    """Mean score per condition with a normal 95 % interval of the mean (over the analysis units)."""
    plt = _plt()
    labels = labels or {}
    fig, ax = plt.subplots(figsize=(5.5, 3.2))
    means, half = [], []
    for c in order:
        v = units.loc[units["condition"] == c, "value"].to_numpy(float)
        means.append(v.mean() if v.size else np.nan)
        half.append(1.96 * v.std(ddof=1) / np.sqrt(v.size) if v.size > 1 else 0.0)
    x = np.arange(len(order))
    ax.bar(x, means, 0.6, yerr=half, capsize=4, color=[_PALETTE[i % len(_PALETTE)] for i in range(len(order))])
    ax.set_xticks(x, [labels.get(c, c) for c in order])
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("mean score (1 = yes / acceptable)")
    ax.set_title(title)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def _strength_xaxis(ax, axis_unit: str, stronger: str) -> None:
    """Levels on a log axis for a log domain; reversed where a lower level is stronger foveation, so that
    foveation always grows to the right."""
    if axis_unit == "log10":
        from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

        ax.set_xscale("log")
        ax.xaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))  # labels within one decade too
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_formatter(NullFormatter())
    if stronger == "lower":
        ax.invert_xaxis()


def psychometric_figure(trials: pd.DataFrame, fits: pd.DataFrame, path: Path, title: str,
                        level: str = "level", correct: str = "correct", labels: dict | None = None) -> Path:
    """One panel per fit (rows: conditions, columns: scenes) of one participant (or the pooled fits):
    proportion correct per level (marker area proportional to the trials at that level), the fitted
    psychometric function, the threshold at the criterion and its 95 % credible interval. A fit that is not
    estimable shows its data and the reason."""
    from data_schema.intensity import Axis

    from .thresholds import psychometric

    plt = _plt()
    labels = labels or {}
    conds = list(dict.fromkeys(fits["condition"]))
    scenes = list(dict.fromkeys(fits["scene"]))
    fig, axes = plt.subplots(len(conds), len(scenes), figsize=(3.0 * len(scenes) + 0.6, 2.4 * len(conds) + 0.6),
                             squeeze=False)
    for i, c in enumerate(conds):
        for j, s in enumerate(scenes):
            ax = axes[i][j]
            fit = fits[(fits["condition"] == c) & (fits["scene"] == s)]
            sub = trials[(trials["condition"] == c) & (trials["scene"] == s)]
            ax.set_title(f"{labels.get(c, c)}, {s}", fontsize=8)
            if fit.empty:
                ax.set_axis_off()
                continue
            r = fit.iloc[0]
            axis = Axis("log" if r["axis"] == "log10" else "linear", r["stronger"])
            if len(sub):
                agg = sub.groupby(level)[correct].agg(["mean", "size"]).reset_index()
                ax.scatter(agg[level], agg["mean"], s=12.0 * agg["size"], color=_PALETTE[2], alpha=0.55,
                           edgecolors="none", label="data (area ∝ trials)")
            ax.axhline(r["criterion"], color="0.7", lw=0.6, ls=":")
            if bool(r["estimable"]):
                lv = sub[level].to_numpy(float) if len(sub) else np.array([r["threshold"]])
                xs = np.linspace(*sorted(axis.to_intensity([lv.min(), lv.max()])), 200)
                lo_x, hi_x = min(xs[0], r["x_threshold"]), max(xs[-1], r["x_threshold"])
                xs = np.linspace(lo_x, hi_x, 200)
                ax.plot(axis.to_level(xs), psychometric(xs, r["x_threshold"], r["width"], r["guess"], r["lapse"],
                                                        r["criterion"]), color=_PALETTE[0], lw=1.2)
                ends = [v for v in (r["ci_low"], r["ci_high"])]
                ok = [np.isfinite(v) and v > 0 if r["axis"] == "log10" else np.isfinite(v) for v in ends]
                if all(ok):
                    ax.hlines(r["criterion"], ends[0], ends[1], color=_PALETTE[1], lw=2.0)
                ax.plot([r["threshold"]], [r["criterion"]], "o", color=_PALETTE[1], ms=4)
                ax.text(0.03, 0.95, f"threshold {r['threshold']:.3g}\n95 % CI {r['ci_low']:.3g}–{r['ci_high']:.3g}",
                        transform=ax.transAxes, va="top", fontsize=6.5)
            else:
                ax.text(0.03, 0.95, str(r["reason"]).replace("not estimable: ", "not estimable:\n"),
                        transform=ax.transAxes, va="top", fontsize=6.5, color="0.3")
            _strength_xaxis(ax, r["axis"], r["stronger"])
            ax.set_ylim(-0.03, 1.03)
            ax.set_xlabel(str(r["varied"]) or "level", fontsize=7)
            ax.set_ylabel("proportion correct", fontsize=7)
            ax.tick_params(labelsize=6.5)
            ax.grid(alpha=0.25)
    fig.suptitle(title, fontsize=9)
    # fixed margins in inches: tight_layout cost as much as drawing the figure, and a report has one per
    # participant
    w, h = fig.get_size_inches()
    fig.subplots_adjust(left=0.62 / w, right=1 - 0.15 / w, bottom=0.45 / h, top=1 - 0.5 / h, wspace=0.32,
                        hspace=0.5)
    return _save(fig, path)


def pareto_figure(curves: pd.DataFrame, table: pd.DataFrame, path: Path, title: str, cost_label: str,
                  labels: dict | None = None) -> Path:
    """The perceptual Pareto front: one panel per scene, one curve per condition of relative cost (x, log) against
    the probability of detection (y) over the procedure's domain, the threshold marked with the cost interval
    its credible interval carries."""
    plt = _plt()
    labels = labels or {}
    scenes = list(dict.fromkeys(curves["scene"]))
    conds = list(dict.fromkeys(curves["condition"]))
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.2 * len(scenes) + 1.6, 3.6), squeeze=False, sharey=True)
    for ax, s in zip(axes[0], scenes):
        for k, c in enumerate(conds):
            col = _PALETTE[k % len(_PALETTE)]
            cv = curves[(curves["condition"] == c) & (curves["scene"] == s)]
            if cv.empty:
                continue
            ax.plot(cv["relative_cost"], cv["p_detect"], color=col, lw=1.4, label=labels.get(c, c))
            t = table[(table["condition"] == c) & (table["scene"] == s)]
            if len(t) and np.isfinite(t["relative_cost"].iloc[0]):
                r = t.iloc[0]
                lo, hi = r["relative_cost_ci_low"], r["relative_cost_ci_high"]
                err = None
                if np.isfinite(lo) and np.isfinite(hi):
                    err = [[max(r["relative_cost"] - lo, 0.0)], [max(hi - r["relative_cost"], 0.0)]]
                ax.errorbar([r["relative_cost"]], [r["p_detect"]], xerr=err, fmt="o", color=col, capsize=3, ms=5)
        ax.axvline(1.0, color="0.6", lw=0.8, ls="--")
        ax.set_xscale("log")
        ax.set_title(s)
        ax.set_xlabel(cost_label)
        ax.grid(alpha=0.3, which="both")
    axes[0][0].set_ylabel("probability of detection")
    axes[0][0].set_ylim(-0.02, 1.02)
    axes[0][-1].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    return _save(fig, path)
