"""Shading-point counts of seed 001 Table 1 (§5.2) and the VaFR preset reductions (§3.3)."""

from __future__ import annotations

import csv
import io
import math
from dataclasses import asdict, dataclass

from . import make_mapping
from .vafr import PRESETS, SEED_PRESET_REDUCTION

#: Resolutions of seed 001 Table 1 (per eye).
TABLE1_RESOLUTIONS: dict[str, tuple[int, int]] = {
    "2K": (2560, 1440), "4K": (3840, 2160), "6K": (5760, 3240), "8K": (7680, 4320), "Retinal": (11520, 6480)}

#: The rows of Table 1: label -> (method, parameters); GT has no mapping.
TABLE1_METHODS: dict[str, tuple[str | None, dict]] = {
    "VaFR_Dup": ("vafr", {}),
    "LaFR(2.2)": ("lafr", {"delta": 2.2}),
    "LaFR(1.8)": ("lafr", {"delta": 1.8}),
    "LMFR(1.8)": ("lmfr", {"delta": 1.8}),
    "GT": (None, {}),
}

#: Seed 001 Table 1 as printed, in thousands of pixels per eye (LMFR(1.8) is not printed; it equals LaFR(1.8)).
SEED_TABLE1_K: dict[str, tuple[int, ...]] = {
    "VaFR_Dup": (1061, 1061, 1061, 1061, 1061),
    "LaFR(2.2)": (761, 1713, 3855, 6854, 15423),
    "LaFR(1.8)": (1137, 2560, 5760, 10240, 23040),
    "GT": (3686, 8294, 18662, 33177, 74649),
}
SEED_VAFR_POINTS = 1_061_735  # seed 001 Fig 4 caption

DEFAULT_FOV_Y_DEG = 100.0  # seed 001 §4.3 assumes a 100° vertical field of view


@dataclass
class Table1Row:
    method: str
    resolution: str
    width: int
    height: int
    lp_width: int
    lp_height: int
    shading_points: int
    shading_points_on_screen: int
    nominal_shading_points: int  # W H / delta^2 for the kernel methods (what the seed prints), else = count
    seed_thousands: int | None


def table1(fov_y_deg: float = DEFAULT_FOV_Y_DEG, resolutions=None, progress=None) -> list[Table1Row]:
    """Compute seed 001 Table 1 (shading points per eye) for every method and resolution."""
    resolutions = resolutions or TABLE1_RESOLUTIONS
    rows = []
    for label, (method, params) in TABLE1_METHODS.items():
        for k, (res, (W, H)) in enumerate(resolutions.items()):
            if progress:
                progress(f"{label} {res}")
            seed = SEED_TABLE1_K.get(label, SEED_TABLE1_K["LaFR(1.8)"] if label == "LMFR(1.8)" else None)
            seed_k = seed[k] if seed and res in TABLE1_RESOLUTIONS else None
            if method is None:
                rows.append(Table1Row(label, res, W, H, W, H, W * H, W * H, W * H, seed_k))
                continue
            m = make_mapping(method, W, H, fov_y_deg, **params)
            nominal = getattr(m, "nominal_shading_points", m.shading_points)
            lw, lh = m.lp_shape
            rows.append(Table1Row(label, res, W, H, lw, lh, m.shading_points, m.shading_points_on_screen,
                                  int(math.floor(nominal)), seed_k))
    return rows


@dataclass
class PresetRow:
    preset: str
    resolution: str
    shading_points: int
    reduction: float
    seed_reduction: float | None


def preset_reductions(fov_y_deg: float = DEFAULT_FOV_Y_DEG, resolutions=None) -> list[PresetRow]:
    """Shading load of each VaFR preset relative to the default pivots (seed 001 §3.3: 20 % and 8 %)."""
    resolutions = resolutions or TABLE1_RESOLUTIONS
    first = next(iter(resolutions.values()))
    base = make_mapping("vafr", *first, fov_y_deg).shading_points
    rows = []
    for preset in PRESETS:
        per_display = preset == "auto"  # the constant caps do not depend on the display
        for res, (W, H) in (resolutions.items() if per_display else [("any", first)]):
            n = make_mapping("vafr", W, H, fov_y_deg, preset=preset).shading_points
            rows.append(PresetRow(preset, res, n, 1.0 - n / base, SEED_PRESET_REDUCTION.get(preset)))
    return rows


def _fmt_k(n: int | None) -> str:
    return "" if n is None else f"{n:,}"


def table1_markdown(rows: list[Table1Row], presets: list[PresetRow], fov_y_deg: float) -> str:
    vafr = next(r for r in rows if r.method == "VaFR_Dup")
    m = make_mapping("vafr", vafr.width, vafr.height, fov_y_deg)
    out = ["# Shading points per eye (seed 001 Table 1)", "",
           f"Vertical field of view {fov_y_deg:g}°, gaze at the display centre. `points` counts the shaded LP "
           "pixels of our buffer; `on screen` those whose inverse falls inside the display; `W·H/δ²` is the "
           "nominal count the seed prints for the kernel methods (our buffer is rounded to whole pixels); "
           "`seed` is Table 1 as printed (thousands).", "",
           "| method | resolution | LP buffer | points | on screen | W·H/δ² | seed (K) |",
           "|---|---|---|---:|---:|---:|---:|"]
    for r in rows:
        out.append(f"| {r.method} | {r.resolution} ({r.width}×{r.height}) | {r.lp_width}×{r.lp_height} | "
                   f"{r.shading_points:,} | {r.shading_points_on_screen:,} | {r.nominal_shading_points:,} | "
                   f"{_fmt_k(r.seed_thousands)} |")
    out += ["", f"VaFR with the default pivots: {vafr.shading_points:,} shading points (seed Fig 4: "
            f"{SEED_VAFR_POINTS:,}; {100 * (vafr.shading_points / SEED_VAFR_POINTS - 1):+.3f} %), buffer "
            f"{vafr.lp_width}×{vafr.lp_height}. The seed's printed 932×1800 does not follow from its own pivots: "
            f"u({m.e_max:g}°) = {m.u_max:.2f} and the largest shading height is l({m.e_l_max:.1f}°) = "
            f"{m.l_max:.1f} (the seed states e' ≈ 45° and 1800); the continuous area of the semi-ellipse is "
            f"{m.continuous_shading_points():,.0f}.", "",
            "## VaFR presets (seed 001 §3.3, Fig 3)", "",
            "| preset | resolution | points | reduction | seed |", "|---|---|---:|---:|---:|"]
    for p in presets:
        seed = "" if p.seed_reduction is None else f"{100 * p.seed_reduction:.0f} %"
        out.append(f"| {p.preset} | {p.resolution} | {p.shading_points:,} | {100 * p.reduction:.1f} % | {seed} |")
    out += ["", "`auto` caps the acuity at the display's radial Nyquist rate (half its pixels per degree), so it "
            "depends on the resolution and field of view."]
    return "\n".join(out) + "\n"


def rows_csv(rows) -> str:
    buf = io.StringIO()
    dicts = [asdict(r) for r in rows]
    writer = csv.DictWriter(buf, fieldnames=list(dicts[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(dicts)
    return buf.getvalue()


def rows_json(rows) -> list[dict]:
    return [asdict(r) for r in rows]
