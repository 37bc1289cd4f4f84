"""Statistics for perceptual user studies of foveated rendering.

Light on purpose: depends only on numpy, scipy (``scipy.special``) and pandas; statsmodels is
imported by :func:`logistic_gee` when it runs.

Omnibus and post-hoc rank tests
    :func:`kruskal`, :func:`mann_whitney`, :func:`dunn`, :func:`pairwise_kruskal`,
    :func:`pairwise_matrix`, :func:`format_p`, :func:`format_p_cell`
Multiple comparisons
    :func:`holm`, :func:`adjust_pvalues`
Effect sizes
    :func:`cohens_d`, :func:`d_with_reason`, :func:`hedges_g`, :func:`effect_size_label`,
    :func:`bootstrap_ci_d`
Tables
    :func:`summary_table`
Paired-comparison scaling (2AFC, top-k of N)
    :func:`thurstone_jod`, :func:`bradley_terry`, :func:`plackett_luce` (priors ``none``, ``weak``,
    ``pwcmp``)
Repeated binary answers
    :func:`logistic_gee` (odds ratios against a reference; statsmodels GEE)
Image quality against GT, fovea and periphery (scikit-image, imported lazily)
    :func:`image_quality`, :func:`eccentricity_map`, :func:`region_masks`, :func:`error_heatmap`
Threshold studies (adaptive designs; psignifit 4, imported when a fit runs)
    :func:`fit_thresholds`, :func:`group_table`, :func:`pareto`, :func:`write_threshold_report`
A study's whole analysis (``studyapp analyze``)
    :func:`read_log`, :class:`AnalysisPlan` (names from :mod:`analysis.vocabulary`),
    :func:`analyze_log`, :func:`write_report`

Submodules load on first use (``analysis.kruskal`` imports :mod:`analysis.stats` then), so ``import
analysis.vocabulary`` or ``analysis.plan`` costs no numpy/pandas/scipy import.

Conventions: NaN observations are dropped (pairwise for paired data); inputs are
validated at the boundary and problems raise ``ValueError`` with a one-line message;
every p-value is two-sided and lies in [0, 1], or is NaN with a note where R gives NA
(a pair whose observations are all tied). Reference values in the tests come from
R 4.2.2 (``kruskal.test``, ``wilcox.test``, ``p.adjust``, geepack), pwcmp and choix.
"""

import importlib

#: Public name -> submodule that defines it.
_EXPORTS = {
    "effect_size": ("SAWILOWSKY_BINS", "BootstrapCI", "bootstrap_ci_d", "cohens_d", "d_with_reason",
                    "effect_size_label", "hedges_g"),
    "gee": ("logistic_gee",),
    "multicomp": ("adjust_pvalues", "holm"),
    "io": ("LogError", "read_log"),
    "plan": ("AnalysisPlan", "plan_from_mapping"),
    "quality": ("QUALITY_COLUMNS", "RegionMasks", "eccentricity_map", "error_heatmap", "fovea_radius_px",
                "image_quality", "region_masks", "squared_error_map"),
    "report": ("report_json", "write_report", "write_threshold_report"),
    "scaling": ("JOD_SIGMA", "ConvergenceError", "bradley_terry", "plackett_luce", "thurstone_jod"),
    "study": ("StudyAnalysis", "analyze_log"),
    "thresholds": ("Axis", "FitSettings", "ThresholdAnalysis", "fit_thresholds", "group_table", "pareto"),
    "stats": ("KruskalResult", "MannWhitneyResult", "dunn", "format_p", "format_p_cell", "kruskal",
              "mann_whitney", "pairwise_kruskal", "pairwise_matrix", "summary_table"),
}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}
__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name not in _WHERE:
        raise AttributeError(f"module 'analysis' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
