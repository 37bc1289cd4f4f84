"""The analysis plan: what ``studyapp analyze`` computes from a study's log.

A protocol carries its plan (``analysis:`` block); for a bare CSV log the plan comes from command-line
options or the defaults below. Every field is validated here, so a bad plan is one line naming the field.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

__all__ = ["TESTS", "UNITS", "AnalysisPlan", "plan_from_mapping"]

#: Unit of analysis: the rows the tests compare. ``participant`` aggregates every participant's trials into
#: one value per condition (votes, or mean score); ``participant_block`` and ``participant_scene`` keep one
#: value per participant and block (e.g. headset) or scene; ``trial`` uses the trials themselves (as seed 003
#: Tables 5-6 do: their SDs are those of 0/1 scores).
UNITS = ("participant", "participant_block", "participant_scene", "trial")
#: ``kruskal_holm``: Kruskal-Wallis on every pair of conditions, Holm across the pairs (seed 001 Tables 2-3),
#: plus the summary against the reference; ``mann_whitney``: only each condition against the reference
#: (seed 003 Tables 5-6; the two-sample Kruskal-Wallis equals this test).
TESTS = ("kruskal_holm", "mann_whitney")
DV = ("votes", "response")


@dataclass(frozen=True)
class AnalysisPlan:
    """What to compute. See :data:`UNITS` and :data:`TESTS`.

    Attributes
    ----------
    dv : {"votes", "response"} or None
        Dependent variable; default per trial family: ``votes`` (times chosen) for 2AFC and preference
        trials, ``response`` (1 = yes / acceptable) for yes/no trials.
    unit : str
        Unit of analysis (default ``participant``).
    reference : str or None
        Reference condition of the summary table (default: the first condition in ``conditions`` order)
        and the zero of the JOD scale.
    test : str
        ``kruskal_holm`` (default) or ``mann_whitney``.
    paired : bool
        Cohen's d as paired :math:`d_z` over participants (needs ``unit='participant'``); default False:
        the pooled-SD d of independent groups, as both seeds report.
    conditions : tuple of str or None
        Conditions in table order; names absent from the log are an error. Default: sorted.
    alpha : float
        Significance level used in the report's wording and the figures' markers.
    n_boot : int
        Bootstrap replicates of the scaling intervals (0 = none).
    seed : int
        Seed of every bootstrap, so the same log gives byte-identical output.
    per_scene : bool
        Also report every table per scene (and per block when the log has several).
    """

    dv: str | None = None
    unit: str = "participant"
    reference: str | None = None
    test: str = "kruskal_holm"
    paired: bool = False
    conditions: tuple[str, ...] | None = None
    alpha: float = 0.05
    n_boot: int = 1000
    seed: int = 0
    per_scene: bool = True
    labels: Mapping[str, str] = field(default_factory=dict)  # condition -> display name (tables, plots)

    def __post_init__(self):
        if self.dv is not None and self.dv not in DV:
            raise ValueError(f"analysis plan: dv={self.dv!r} is invalid: allowed {', '.join(DV)}")
        if self.unit not in UNITS:
            raise ValueError(f"analysis plan: unit={self.unit!r} is invalid: allowed {', '.join(UNITS)}")
        if self.test not in TESTS:
            raise ValueError(f"analysis plan: test={self.test!r} is invalid: allowed {', '.join(TESTS)}")
        if not isinstance(self.paired, bool):
            raise ValueError(f"analysis plan: paired must be true or false, got {self.paired!r}")
        if self.paired and self.unit != "participant":
            raise ValueError("analysis plan: paired=true needs unit=participant (one value per participant)")
        if isinstance(self.alpha, bool) or not isinstance(self.alpha, (int, float)) or not 0 < self.alpha < 1:
            raise ValueError(f"analysis plan: alpha={self.alpha!r} is invalid: allowed (0, 1)")
        if isinstance(self.n_boot, bool) or not isinstance(self.n_boot, int) or not 0 <= self.n_boot <= 100_000:
            raise ValueError(f"analysis plan: n_boot={self.n_boot!r} is invalid: allowed integers 0..100000")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"analysis plan: seed={self.seed!r} is invalid: allowed integers >= 0")
        if self.conditions is not None:
            conds = tuple(str(c) for c in self.conditions)
            if len(set(conds)) != len(conds):
                raise ValueError("analysis plan: conditions lists a condition twice")
            if len(conds) < 2:
                raise ValueError("analysis plan: conditions must name at least two conditions")
            object.__setattr__(self, "conditions", conds)
        if self.reference is not None:
            object.__setattr__(self, "reference", str(self.reference))
            if self.conditions is not None and self.reference not in self.conditions:
                raise ValueError(f"analysis plan: reference {self.reference!r} is not among the conditions")
        if not isinstance(self.labels, Mapping):
            raise ValueError("analysis plan: labels must map condition names to display names")
        object.__setattr__(self, "labels", {str(k): str(v) for k, v in dict(self.labels).items()})

    def with_overrides(self, **kw: Any) -> AnalysisPlan:
        """A copy with the given fields replaced (``None`` values are ignored)."""
        return replace(self, **{k: v for k, v in kw.items() if v is not None})

    def to_dict(self) -> dict:
        d = asdict(self)
        d["conditions"] = list(self.conditions) if self.conditions else None
        d["labels"] = dict(sorted(self.labels.items()))
        return d


#: Keys a study database adds to its plan for information (see data_schema.store.read_analysis_plan).
_INFORMATIONAL = ("family", "protocol")
_ALIASES = {"unit_of_analysis": "unit", "dependent_variable": "dv", "reference_condition": "reference",
            "order": "conditions", "bootstrap": "n_boot"}


def plan_from_mapping(data: Mapping[str, Any] | None) -> AnalysisPlan:
    """Build a plan from a protocol's ``analysis:`` block (unknown keys are an error).

    Accepts the field names of :class:`AnalysisPlan` and the aliases ``unit_of_analysis``,
    ``dependent_variable``, ``reference_condition``, ``order`` and ``bootstrap``, and the protocol schema's
    vocabulary (data_schema/protocol.schema.json): ``dv: chosen`` (= votes); ``test: summary_table``
    (= mann_whitney: each condition against the reference); ``pairwise_kruskal``, ``kruskal_dunn``,
    ``thurstone``, ``bradley_terry``, ``plackett_luce`` (= kruskal_holm, which reports all of them);
    ``by: [scene, block]`` (per-scene tables on; ``[]`` off). ``family`` and ``protocol`` are ignored.
    """
    if data is None:
        return AnalysisPlan()
    if not isinstance(data, Mapping):
        raise ValueError(f"analysis plan must be a mapping, got {type(data).__name__}")
    known = {f.name for f in fields(AnalysisPlan)}
    kw: dict[str, Any] = {}
    for key, value in data.items():
        if key in _INFORMATIONAL:
            continue
        if key == "by":  # the protocol schema's breakdown list: any breakdown turns per-scene tables on
            if not isinstance(value, (list, tuple)) or not set(value) <= {"scene", "block"}:
                raise ValueError("analysis plan: by must be a list of 'scene' and/or 'block'")
            kw["per_scene"] = bool(value)
            continue
        name = _ALIASES.get(str(key), str(key))
        if name not in known:
            raise ValueError(f"analysis plan: unknown field {key!r}: allowed {', '.join(sorted(known))}")
        kw[name] = value
    if isinstance(kw.get("test"), str):
        t = kw["test"].strip().lower().replace("-", "_").replace(" ", "_")
        kw["test"] = {"kruskal": "kruskal_holm", "pairwise_kruskal": "kruskal_holm", "kruskal_dunn": "kruskal_holm",
                      "thurstone": "kruskal_holm", "bradley_terry": "kruskal_holm", "plackett_luce": "kruskal_holm",
                      "summary_table": "mann_whitney", "kruskal_wallis": "kruskal_holm",
                      "kruskal_wallis+holm": "kruskal_holm", "kruskal_wallis_holm": "kruskal_holm",
                      "mannwhitney": "mann_whitney", "wilcoxon": "mann_whitney"}.get(t, t)
    if isinstance(kw.get("dv"), str):
        kw["dv"] = {"preference": "votes", "chosen": "votes", "score": "response", "scores": "response",
                    "choice": "votes"}.get(kw["dv"], kw["dv"])
    if "conditions" in kw and kw["conditions"] is not None:
        if isinstance(kw["conditions"], str) or not hasattr(kw["conditions"], "__iter__"):
            raise ValueError("analysis plan: conditions must be a list of condition names")
        kw["conditions"] = tuple(kw["conditions"])
    return AnalysisPlan(**kw)
