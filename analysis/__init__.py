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
A study's whole analysis (``studyapp analyze``)
    :func:`read_log`, :class:`AnalysisPlan` (names from :mod:`analysis.vocabulary`),
    :func:`analyze_log`, :func:`write_report`

Conventions: NaN observations are dropped (pairwise for paired data); inputs are
validated at the boundary and problems raise ``ValueError`` with a one-line message;
every p-value is two-sided and lies in [0, 1], or is NaN with a note where R gives NA
(a pair whose observations are all tied). Reference values in the tests come from
R 4.2.2 (``kruskal.test``, ``wilcox.test``, ``p.adjust``, geepack), pwcmp and choix.
"""

from .effect_size import (
    SAWILOWSKY_BINS,
    BootstrapCI,
    bootstrap_ci_d,
    cohens_d,
    d_with_reason,
    effect_size_label,
    hedges_g,
)
from .gee import logistic_gee
from .multicomp import adjust_pvalues, holm
from .io import LogError, read_log
from .plan import AnalysisPlan, plan_from_mapping
from .quality import (
    QUALITY_COLUMNS,
    RegionMasks,
    eccentricity_map,
    error_heatmap,
    fovea_radius_px,
    image_quality,
    region_masks,
    squared_error_map,
)
from .report import report_json, write_report
from .scaling import JOD_SIGMA, ConvergenceError, bradley_terry, plackett_luce, thurstone_jod
from .study import StudyAnalysis, analyze_log
from .stats import (
    KruskalResult,
    MannWhitneyResult,
    dunn,
    format_p,
    format_p_cell,
    kruskal,
    mann_whitney,
    pairwise_kruskal,
    pairwise_matrix,
    summary_table,
)

__all__ = [
    "AnalysisPlan",
    "LogError",
    "QUALITY_COLUMNS",
    "RegionMasks",
    "StudyAnalysis",
    "analyze_log",
    "eccentricity_map",
    "error_heatmap",
    "fovea_radius_px",
    "image_quality",
    "plan_from_mapping",
    "read_log",
    "region_masks",
    "report_json",
    "squared_error_map",
    "write_report",
    "BootstrapCI",
    "ConvergenceError",
    "JOD_SIGMA",
    "d_with_reason",
    "format_p_cell",
    "logistic_gee",
    "bradley_terry",
    "plackett_luce",
    "thurstone_jod",
    "KruskalResult",
    "MannWhitneyResult",
    "SAWILOWSKY_BINS",
    "adjust_pvalues",
    "bootstrap_ci_d",
    "cohens_d",
    "dunn",
    "effect_size_label",
    "format_p",
    "hedges_g",
    "holm",
    "kruskal",
    "mann_whitney",
    "pairwise_kruskal",
    "pairwise_matrix",
    "summary_table",
]
