"""The tidy trial log: one row per answered trial, the contract between the study runner and the analysis.

The session store exports it (``studyapp export --format csv|parquet``) and ``studyapp analyze`` reads it,
from a CSV/Parquet file or straight from a study database. Column names and meanings are stable.

Columns (``REQUIRED`` must be present in every log; the others as the trial family needs):

========================  =====================================================================================
column                    meaning
========================  =====================================================================================
participant               pseudonymous participant id (str)
family                    trial family: ``2afc``, ``preference`` (top two of N) or ``yes_no`` (is this the GT? /
                          is the quality acceptable?)
scene                     scene name (str)
block                     grouping above the scene, e.g. the headset or the task (str; ``""`` if none)
session                   session id (str; ``""`` if not known)
trial                     0-based index of the trial in the participant's schedule (int)
condition                 ``yes_no``: the condition shown (str)
condition_a, condition_b  ``2afc``: the conditions shown first/left and second/right (str)
chosen                    ``2afc``: the condition chosen; ``preference``: the first choice (str)
chosen_2                  ``preference``: the second choice, ``""`` when the participant picked only one
conditions                ``preference``: the conditions offered, joined by ``|`` (str)
response                  ``yes_no``: 1 for yes/acceptable, 0 for no (int)
rt_s                      reaction time in seconds from stimulus onset (float; NaN if not measured)
practice, catch           1 for practice / catch trials (excluded from the analysis), else 0
fps_median, fps_p5        live trials: frames rendered per second, median and 5th percentile (float; NaN otherwise)
dropped_share             live trials: share of dropped flips (float)
latency_p50_ms,           live trials: gaze age at the flip in ms, median and 95th percentile (float)
latency_p95_ms
fps_check_slow            live trials: 1 if a condition shown was below ``min_fps`` in the session's frame-rate
                          check and the run went on with ``--accept-slow`` (a flagged trial), else 0
procedure                 adaptive designs: the procedure of the trial, ``CONDITION@SCENE`` (str)
varied                    adaptive: the varied renderer parameter, e.g. ``acuity_scale`` (str)
level                     adaptive: the parameter's value shown (float)
intensity                 adaptive: the level on the procedure's axis, where detection grows: log10 of the level
                          (or the level, scale: linear), negated where a lower value foveates more (float)
correct                   adaptive: 1 when the answer was correct -- 2afc: picked the original; yes_no: answered
                          "not the ground truth" to the test (detected) -- else 0
estimate_mean,            adaptive: the procedure's running threshold estimate after the trial, in intensity
estimate_sd               units (QUEST+: posterior mean and SD; staircase: mean and SD of the last reversals)
========================  =====================================================================================

The live columns summarise the trial's frames (:mod:`data_schema.timing`); the frames themselves are exported
as their own table (``studyapp export --format frames``).
"""

from __future__ import annotations

from .families import FAMILIES as _FAMILIES
from .families import NAMES
from .timing import COLUMNS as TIMING_COLUMNS

#: The trial families a log may hold (data_schema.families).
FAMILIES = NAMES
REQUIRED = ("participant", "family", "scene")

#: Family -> the columns it fills (declared by each family, :mod:`data_schema.families`).
FAMILY_COLUMNS = {name: fam.log_columns for name, fam in _FAMILIES.items()}

#: The columns of adaptive designs (empty for other trials).
ADAPTIVE_COLUMNS = ("procedure", "varied", "level", "intensity", "correct", "estimate_mean", "estimate_sd")

OPTIONAL = ("block", "session", "trial", "chosen_2", "rt_s", "practice", "catch", *TIMING_COLUMNS, "fps_check_slow",
            *ADAPTIVE_COLUMNS)

ALL_COLUMNS = ("participant", "session", "block", "scene", "trial", "family", "condition", "condition_a",
               "condition_b", "conditions", "chosen", "chosen_2", "response", "rt_s", "practice", "catch",
               *TIMING_COLUMNS, "fps_check_slow", *ADAPTIVE_COLUMNS)



def missing_columns(columns, family: str | None = None) -> list[str]:
    """Names of the required columns (for ``family`` if given) absent from ``columns``."""
    need = list(REQUIRED)
    if family is not None:
        need += FAMILY_COLUMNS[family]
    have = set(columns)
    return [c for c in need if c not in have]
