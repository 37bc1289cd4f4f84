"""Shading-rate plots reproducing seed 001 Figures 5, 8, 9, 10 and 21 (matplotlib, imported lazily)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from data_schema.atomic import atomic_path

from . import make_mapping
from .reference import acuity_curve, guenter_step
from .table import DEFAULT_FOV_Y_DEG

PAPER_LAFR = {"alpha": 0.85, "beta": 0.7}
TUNED = {"delta": 8.0, "alpha": 0.78, "beta": 0.9}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path, plt) -> None:
    fig.tight_layout()
    with atomic_path(path) as tmp:
        # Fixed metadata so that the same inputs give byte-identical files.
        fig.savefig(tmp, dpi=120, format="png", metadata={"Software": None})
    plt.close(fig)


def _ecc(m, e_hi=None):
    e_hi = min(e_hi or m.display.max_eccentricity(), 89.0)
    return np.linspace(0.05, e_hi, 1200)


def _curves(ax, W, H, fov, gaze=None, *, lmfr=None, lafr=(), style="-", suffix="", vafr=True, direction="radial"):
    """Draw the rates of LMFR / LaFR variants / VaFR at one display; returns the eccentricity range."""
    e_top = 0.0
    if lmfr is not None:
        m = make_mapping("lmfr", W, H, fov, gaze, **lmfr)
        e = _ecc(m)
        ax.plot(e, m.shading_rate(e, direction), style, color="tab:orange",
                label=f"LMFR(δ={m.delta:g}, α={m.alpha:g}){suffix}")
        e_top = max(e_top, e[-1])
    for params, color in zip(lafr, ("tab:green", "tab:purple", "tab:brown")):
        m = make_mapping("lafr", W, H, fov, gaze, **params)
        e = _ecc(m)
        ax.plot(e, m.shading_rate(e, direction), style, color=color,
                label=f"LaFR(δ={m.delta:g}, α={m.alpha:g}, β={m.beta:g}){suffix}")
        e_top = max(e_top, e[-1])
    if vafr:
        m = make_mapping("vafr", W, H, fov, gaze)
        e = np.linspace(0.0, 60.0, 1200)
        ax.plot(e, m.shading_rate(e, direction), style, color="tab:blue", lw=2.2, label=f"VaFR (ours){suffix}")
    return max(e_top, 60.0)


def _finish(ax, title, e_top, y_top=45.0, ylabel="radial shading rate (cycles/degree)"):
    e = np.linspace(0.0, e_top, 1200)
    ax.plot(e, acuity_curve(e), ":", color="black", lw=1.6, label="visual acuity f(e) (Eq 12 pivots)")
    ax.set_xlim(0, e_top)
    ax.set_ylim(0, y_top)
    ax.set_xlabel("eccentricity e (degrees)")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")


def figure5(out: Path, fov: float, plt) -> list[Path]:
    """Seed Fig 5: Guenter's step, LMFR, LaFR and VaFR against acuity at LMFR's and LaFR's resolutions."""
    paths = []
    for W, H in ((2560, 1440), (1440, 1700)):
        fig, ax = plt.subplots(figsize=(7.5, 4.8))
        e_top = _curves(ax, W, H, fov, lmfr={"delta": 1.8}, lafr=({"delta": 1.8, **PAPER_LAFR},))
        disp_cpd = 0.5 * float(make_mapping("vafr", W, H, fov).display.dr_de(0.0))
        e = np.linspace(0.0, e_top, 2000)
        ax.plot(e, guenter_step(e, disp_cpd), "-", color="tab:red", lw=1.2,
                label=f"Guenter et al. layers (1, 1/2, 1/4 of {disp_cpd:.1f} cpd)")
        _finish(ax, f"Fig 5: shading rate at {W}×{H}, vertical FOV {fov:g}°, gaze at centre", e_top)
        p = out / f"fig05_radial_{W}x{H}.png"
        _save(fig, p, plt)
        paths.append(p)
    return paths


PAPER = {"lmfr": {"delta": 1.8}, "lafr": ({"delta": 1.8, **PAPER_LAFR},)}


def _layered_figure(out: Path, plt, name: str, title: str, layers: list[dict], **finish) -> Path:
    """One figure from layers of ``_curves`` keyword sets; the x range covers every layer."""
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    e_top = max(_curves(ax, **layer) for layer in layers)
    _finish(ax, title, e_top, **finish)
    p = out / name
    _save(fig, p, plt)
    return p


def figure8(out: Path, fov: float, plt) -> Path:
    """Seed Fig 8: LMFR and LaFR move with resolution (1920×1080 -> 7680×4320); VaFR does not."""
    return _layered_figure(out, plt, "fig08_resolution_1920x1080_to_7680x4320.png",
                           f"Fig 8: resolution dependence, 1920×1080 (dashed) vs 7680×4320 (solid), FOV {fov:g}°",
                           [dict(W=1920, H=1080, fov=fov, style="--", suffix=" 1920×1080", vafr=False, **PAPER),
                            dict(W=7680, H=4320, fov=fov, suffix=" 7680×4320", **PAPER)], y_top=60.0)


def figure9(out: Path, fov: float, plt) -> Path:
    """Seed Fig 9: retinal resolution, the papers' parameters and the tuned ones (δ=8, α=0.78, β=0.9)."""
    return _layered_figure(out, plt, "fig09_retinal_tuned.png",
                           f"Fig 9: retinal 11520×6480, paper (solid) and tuned (dashed) parameters, FOV {fov:g}°",
                           [dict(W=11520, H=6480, fov=fov, **PAPER),
                            dict(W=11520, H=6480, fov=fov, lmfr={"delta": TUNED["delta"]}, lafr=(TUNED,),
                                 style="--", suffix=" (tuned)", vafr=False)], y_top=120.0)


def figure10(out: Path, fov: float, plt) -> Path:
    """Seed Fig 10: gaze at the centre vs at a corner of a 2560×1440 display."""
    return _layered_figure(out, plt, "fig10_gaze_centre_vs_corner.png",
                           f"Fig 10: gaze at centre (solid) vs top-left corner (dashed), 2560×1440, FOV {fov:g}°",
                           [dict(W=2560, H=1440, fov=fov, suffix=" gaze centre", **PAPER),
                            dict(W=2560, H=1440, fov=fov, gaze=(0.5, 0.5), style="--", suffix=" gaze corner",
                                 **PAPER)])


def figure21(out: Path, fov: float, plt) -> Path:
    """Seed Fig 21: tangential shading rates (Eq 20 for LMFR / LaFR; Eq 19 for VaFR) at 2560×1440."""
    return _layered_figure(out, plt, "fig21_tangential.png",
                           f"Fig 21: tangential (dashed) vs radial (solid) shading rate, 2560×1440, FOV {fov:g}°",
                           [dict(W=2560, H=1440, fov=fov, style="--", suffix=" tangential", direction="tangential",
                                 **PAPER),
                            dict(W=2560, H=1440, fov=fov, vafr=False, suffix=" radial", **PAPER)],
                           ylabel="shading rate (cycles/degree)")


def write_plots(out_dir, fov_y_deg: float = DEFAULT_FOV_Y_DEG) -> list[Path]:
    """Write every figure into ``out_dir`` (created if needed); returns the PNG paths."""
    out = Path(out_dir)
    os.makedirs(out, exist_ok=True)
    plt = _pyplot()
    paths = figure5(out, fov_y_deg, plt)
    paths += [figure8(out, fov_y_deg, plt), figure9(out, fov_y_deg, plt), figure10(out, fov_y_deg, plt),
              figure21(out, fov_y_deg, plt)]
    return paths
