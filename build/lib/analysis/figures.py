"""Figures of a study's analysis (matplotlib, imported lazily; PNG files are byte-stable).

* :func:`votes_figure` - votes per mode and scene, one panel per block (seed 001 Fig 14-15),
* :func:`scale_figure` - JOD (or Plackett-Luce) scores with bootstrap intervals,
* :func:`scores_figure` - mean yes/acceptable score per condition and scene with 95 % intervals.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["scale_figure", "scores_figure", "votes_figure"]

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
