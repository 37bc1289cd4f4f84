"""The analysis plan: what ``studyapp analyze`` computes from a study's log.

A protocol carries its plan (``analysis:`` block); for a bare CSV log the plan comes from command-line
options or the defaults below. Every field is validated here, so a bad plan is one line naming the field.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

from data_schema.errors import UserError

from .vocabulary import DEFAULT_PRIOR, DEFAULT_TESTS, DVS, PRIORS, TESTS, UNITS

__all__ = ["DVS", "PRIORS", "TESTS", "UNITS", "AnalysisPlan", "plan_from_mapping"]


#: Test names of earlier versions: refused, with the names that now say what they meant.
_RENAMED = {"kruskal_holm": "pairwise_kruskal, kruskal_dunn", "mann_whitney": "summary_table"}


def _allowed(field_name: str, value: Any, names) -> None:
    if not isinstance(value, str) or value not in names:
        hint = f" (renamed: use {_RENAMED[value]})" if field_name == "test" and value in _RENAMED else ""
        raise UserError(f"analysis plan: {field_name}={value!r} is invalid{hint}: allowed {', '.join(names)}")


@dataclass(frozen=True)
class AnalysisPlan:
    """What to compute; every name comes from :mod:`analysis.vocabulary`.

    Attributes
    ----------
    dv : {"votes", "chosen", "response"} or None
        Dependent variable (:data:`~analysis.vocabulary.DVS`); default per trial family: ``votes`` (times
        chosen, first or second choice) for 2AFC and preference trials, ``response`` (1 = yes / acceptable)
        for yes/no trials. ``chosen`` counts first choices only (the same as ``votes`` for 2AFC).
    unit : str
        Unit of analysis (:data:`~analysis.vocabulary.UNITS`, default ``participant``).
    reference : str or None
        Reference condition of the summary table and the GEE (default: the first condition in
        ``conditions`` order) and the zero of the scales.
    tests : tuple of str
        What to report (:data:`~analysis.vocabulary.TESTS`), in this order; default every seed-style table
        (:data:`~analysis.vocabulary.DEFAULT_TESTS`). The votes table and the Kruskal-Wallis omnibus test are
        always reported.
    prior : {"none", "weak", "pwcmp"}
        Prior of the paired-comparison scales (:data:`~analysis.vocabulary.PRIORS`, default ``weak``).
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
    tests: tuple[str, ...] = DEFAULT_TESTS
    prior: str = DEFAULT_PRIOR
    paired: bool = False
    conditions: tuple[str, ...] | None = None
    alpha: float = 0.05
    n_boot: int = 1000
    seed: int = 0
    per_scene: bool = True
    labels: Mapping[str, str] = field(default_factory=dict)  # condition -> display name (tables, plots)

    def __post_init__(self):
        if self.dv is not None:
            _allowed("dv", self.dv, DVS)
        _allowed("unit", self.unit, UNITS)
        _allowed("prior", self.prior, PRIORS)
        tests = (self.tests,) if isinstance(self.tests, str) else self.tests
        if not isinstance(tests, (list, tuple)) or not tests:
            raise UserError(f"analysis plan: test must name one or more of {', '.join(TESTS)}")
        for t in tests:
            _allowed("test", t, TESTS)
        if len(set(tests)) != len(tests):
            raise UserError("analysis plan: test lists a test twice")
        object.__setattr__(self, "tests", tuple(tests))
        if not isinstance(self.paired, bool):
            raise UserError(f"analysis plan: paired must be true or false, got {self.paired!r}")
        if self.paired and self.unit != "participant":
            raise UserError("analysis plan: paired=true needs unit=participant (one value per participant)")
        if isinstance(self.alpha, bool) or not isinstance(self.alpha, (int, float)) or not 0 < self.alpha < 1:
            raise UserError(f"analysis plan: alpha={self.alpha!r} is invalid: allowed (0, 1)")
        if isinstance(self.n_boot, bool) or not isinstance(self.n_boot, int) or not 0 <= self.n_boot <= 100_000:
            raise UserError(f"analysis plan: n_boot={self.n_boot!r} is invalid: allowed integers 0..100000")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise UserError(f"analysis plan: seed={self.seed!r} is invalid: allowed integers >= 0")
        if self.conditions is not None:
            conds = tuple(str(c) for c in self.conditions)
            if len(set(conds)) != len(conds):
                raise UserError("analysis plan: conditions lists a condition twice")
            if len(conds) < 2:
                raise UserError("analysis plan: conditions must name at least two conditions")
            object.__setattr__(self, "conditions", conds)
        if self.reference is not None:
            object.__setattr__(self, "reference", str(self.reference))
            if self.conditions is not None and self.reference not in self.conditions:
                raise UserError(f"analysis plan: reference {self.reference!r} is not among the conditions")
        if not isinstance(self.labels, Mapping):
            raise UserError("analysis plan: labels must map condition names to display names")
        object.__setattr__(self, "labels", {str(k): str(v) for k, v in dict(self.labels).items()})

    def with_overrides(self, **kw: Any) -> AnalysisPlan:
        """A copy with the given fields replaced (``None`` values are ignored)."""
        return replace(self, **{k: v for k, v in kw.items() if v is not None})

    def to_dict(self) -> dict:
        d = asdict(self)
        d["tests"] = list(self.tests)
        d["conditions"] = list(self.conditions) if self.conditions else None
        d["labels"] = dict(sorted(self.labels.items()))
        return d


#: Keys a study database adds to its plan for information (see data_schema.store.read_analysis_plan).
_INFORMATIONAL = ("family", "protocol")
_ALIASES = {"unit_of_analysis": "unit", "dependent_variable": "dv", "reference_condition": "reference",
            "order": "conditions", "bootstrap": "n_boot", "test": "tests"}


def plan_from_mapping(data: Mapping[str, Any] | None) -> AnalysisPlan:
    """Build a plan from a protocol's ``analysis:`` block (unknown keys and values are errors).

    Accepts the field names of :class:`AnalysisPlan`, the protocol schema's ``test`` (one name or a list: the
    ``tests`` field) and ``by: [scene, block]`` (per-scene tables on; ``[]`` off), and the field aliases
    ``unit_of_analysis``, ``dependent_variable``, ``reference_condition``, ``order`` and ``bootstrap``.
    Values must be names of :mod:`analysis.vocabulary`, exactly: no value stands for another. ``family`` and
    ``protocol`` (added by a study database) are ignored.
    """
    if data is None:
        return AnalysisPlan()
    if not isinstance(data, Mapping):
        raise UserError(f"analysis plan must be a mapping, got {type(data).__name__}")
    known = {f.name for f in fields(AnalysisPlan)}
    kw: dict[str, Any] = {}
    for key, value in data.items():
        if key in _INFORMATIONAL:
            continue
        if key == "by":  # the protocol schema's breakdown list: any breakdown turns per-scene tables on
            if not isinstance(value, (list, tuple)) or not set(value) <= {"scene", "block"}:
                raise UserError("analysis plan: by must be a list of 'scene' and/or 'block'")
            kw["per_scene"] = bool(value)
            continue
        name = _ALIASES.get(str(key), str(key))
        if name not in known:
            raise UserError(f"analysis plan: unknown field {key!r}: allowed {', '.join(sorted(known))}")
        kw[name] = value
    if "conditions" in kw and kw["conditions"] is not None:
        if isinstance(kw["conditions"], str) or not hasattr(kw["conditions"], "__iter__"):
            raise UserError("analysis plan: conditions must be a list of condition names")
        kw["conditions"] = tuple(kw["conditions"])
    return AnalysisPlan(**kw)
