"""What a trial family is: the one declaration every part of studyapp reads (the jsPsych plug-in idea).

A family (``2afc``, ``preference``, ``yes_no``) declares here, and nowhere else:

- its **parameters** in a protocol: how many conditions it needs, whether it has positions to balance or picks
  to count, the catch-trial kinds it allows, what a practice set must look like;
- its **answer keys**: the default key map, the answers a key may record, the stimuli a key may switch to;
- its **schedule items**: the trials of one scene, of a practice set, and a catch trial;
- how its answers are **logged and interpreted**: the presenter's answers -> ``chosen``/``chosen_2``/
  ``response``, and the tidy log's family columns;
- its **analysis**: the dependent variables it supports and the default one, the tests and the scaling tests
  that apply (and the kind of data they scale), the report's captions, its export formats, its threshold
  criterion, and, for choice families, the shown/picked condition codes of every trial (vectorised);
- its **simulated answer**: what the simulated observer answers given the impairment of each stimulus.

The protocol schema, the scheduler, the presenter, the store, the simulated observer and the analysis all ask
the family object (:func:`data_schema.families.get`) and never test a family's name (tests/test_architecture.py);
adding a family is a module here and its tests.
This package imports numpy only (``import analysis`` stays light).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Observer:
    """The simulated participant's parameters a family's answer model needs (see studyapp.runner.observer)."""

    sensitivity: float
    bias: float
    criterion: float


def phi(x: float) -> float:
    """Standard normal CDF."""
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


class TrialFamily:
    """Base class of the trial families; a family module defines one subclass and one instance."""

    name: str = ""
    title: str = ""
    #: "choice" (the participant picks among the shown conditions) or "score" (a yes/no answer per stimulus).
    kind: str = "choice"
    min_conditions: int = 2
    #: Columns of the tidy trial log this family fills (data_schema.trial_log).
    log_columns: tuple[str, ...] = ()
    #: Dependent variables of the analysis that fit this family; ``record_dv`` is what a protocol's analysis
    #: plan names for it, ``default_dv`` what the analysis uses when the plan names none.
    dvs: tuple[str, ...] = ()
    record_dv: str = ""
    default_dv: str = ""
    #: Paired-comparison scaling tests that apply (analysis.vocabulary names) and the kind of choice data they
    #: scale: ``"pairs"`` (winner/loser counts: Thurstone, Bradley-Terry) or ``"rankings"`` (first/second pick
    #: of an offered set: Plackett-Luce); None: no scale.
    scale_tests: tuple[str, ...] = ()
    scale_model: str | None = None
    #: Columns holding the conditions a trial showed (``|``-separated lists allowed).
    condition_columns: tuple[str, ...] = ()
    #: The analysis tests (analysis.vocabulary) that apply to this family.
    tests: tuple[str, ...] = ()
    #: The report's and the analysis notes' words for this family (analysis.study, analysis.report): the
    #: ``chosen`` dependent variable, the logistic GEE's odds ratio (table caption and note), and the note when
    #: the plan asks for a GEE the family has none of.
    chosen_caption: str = ""
    gee_odds_caption: str = ""
    gee_note: str = ""
    no_gee_note: str = ""
    catch_kinds: tuple[str, ...] = ()
    has_positions: bool = False  # which condition is shown first/left can be balanced
    has_picks: bool = False  # the participant picks up to n_picks favourites
    loops: bool = True  # sequences loop while the participant switches among the stimuli
    #: Export layouts beyond the tidy log that this family's trials are written in (data_schema.store's
    #: exporters): layout -> the tidy-log columns it takes, in order. ``pwcmp``: the condition shown
    #: first/left, the one shown second/right, the one chosen.
    export_columns: dict[str, tuple[str, ...]] = {}  # noqa: RUF012 - read only, like the tuples above
    #: Adaptive designs (studyapp.runner.adaptive): whether a trial has a correct answer a procedure can adapt
    #: on (2AFC: picked the original; yes/no: said "not the ground truth" to a test stimulus, i.e. detected),
    #: the proportion of such answers that defines the threshold, the chance rate (None: a free false-alarm
    #: rate, estimated by the fit) and psignifit's experiment type.
    has_correct_answer: bool = False
    threshold_criterion: float | None = None
    guess_rate: float | None = None
    psignifit_type: str | None = None

    # -- protocol parameters and keys ------------------------------------------------------------------------
    @property
    def exports(self) -> tuple[str, ...]:
        """Export formats of its trial log (data_schema.store): the tidy log's, and the layouts it declares in
        :attr:`export_columns` (pwcmp's table needs paired comparisons)."""
        return ("csv", "parquet", *self.export_columns)

    def default_n_picks(self, n_conditions: int) -> int:
        return 1

    def default_keys(self, n_conditions: int) -> dict:
        raise NotImplementedError

    def answer_values(self, n_conditions: int) -> set[str]:
        raise NotImplementedError

    def max_switch(self, n_conditions: int) -> int:
        """Largest stimulus index a switch key may name."""
        return n_conditions - 1

    def practice_problem(self, practice: Sequence[str], n_design: int) -> str | None:
        """Why a practice set does not fit this family (None: it fits)."""
        return None

    def stimuli_range(self, n_conditions: int) -> tuple[int, int]:
        """How many stimuli one trial shows (min, max)."""
        raise NotImplementedError

    # -- schedule ----------------------------------------------------------------------------------------------
    def main_items(self, conditions: Sequence[str], scene: str, repetitions: int, *, position_balance: bool,
                   flip_seed: int, stream) -> list[dict]:
        """The answered trials of one scene, before ordering: dicts with ``scene``, ``conditions`` (display
        order), ``run`` (what counts as the same condition for run-length limits) and ``item`` (what counts as
        the same item for repeat distances). ``flip_seed`` selects the orientation of an odd repetition."""
        raise NotImplementedError

    def practice_groups(self, conditions: Sequence[str]) -> list[tuple[str, ...]]:
        raise NotImplementedError

    def adaptive_items(self, reference: str, test: str, scene: str, n: int, stream) -> list[dict]:
        """The ``n`` trials of one adaptive procedure (``test`` varied against ``reference``), before ordering:
        dicts like :meth:`main_items`'. Families without a correct answer have none."""
        raise NotImplementedError

    def adaptive_correct(self, conditions: Sequence[str], test: str, derived: dict) -> bool:
        """Whether the answer to an adaptive trial that showed ``conditions`` counts as correct (detected);
        ``derived`` is :meth:`interpret`'s result."""
        raise NotImplementedError

    def catch_item(self, i: int, good: str, bad: str) -> tuple[tuple[str, ...], str]:
        """Conditions and the expected answer of the ``i``-th degraded catch trial (alternating sides)."""
        raise NotImplementedError

    # -- answers: logged and interpreted -----------------------------------------------------------------------
    def interpret(self, conditions: Sequence[str], answers: Sequence[str], n_picks: int) -> dict:
        """The presenter's answers -> ``{"chosen", "chosen_2", "response"}``; ValueError if they are not this
        family's answers."""
        raise NotImplementedError

    def tidy_columns(self, conditions: Sequence[str]) -> dict:
        """The tidy log's condition columns of a trial that showed ``conditions``."""
        raise NotImplementedError

    def labels(self, n_stimuli: int) -> list[str]:
        """How the stimuli of a trial are named to the participant (corner label)."""
        return [""] * n_stimuli

    # -- the simulated participant ---------------------------------------------------------------------------
    def simulate(self, impairments: Sequence[float], observer: Observer, rng: np.random.Generator, lapse: bool,
                 n_picks: int) -> tuple[list[str], float, int]:
        """``(answers, decision margin, switches)`` given each stimulus' impairment in JND."""
        raise NotImplementedError

    # -- analysis ----------------------------------------------------------------------------------------------
    def shown_and_picks(self, df, conds: list[str], codes) -> tuple[np.ndarray, np.ndarray]:
        """Choice families: per trial the codes of the shown conditions (n x m, -1 padded) and of the picks
        (n x 2, -1 where none). ``codes(series, conds)`` maps names to indices (-1 for empty)."""
        raise NotImplementedError
