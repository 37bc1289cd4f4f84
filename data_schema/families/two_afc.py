"""``2afc``: two renderings of a scene, A and B (switch between them freely), pick the preferred one.

Seed 001 §5.3.3: the 10 pairs of five modes, each pair shown ``repetitions`` times per scene, the order
within a pair balanced across repetitions and participants. Answer ``A``/``B``; ``chosen`` is the condition
picked. Simulated answer (Thurstone Case V): ``P(A) = Phi(s (D_B - D_A) / sqrt 2 + b)``.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from ..errors import UserError
from .base import TrialFamily, phi


class TwoAFC(TrialFamily):
    name = "2afc"
    title = "2AFC preference"
    kind = "choice"
    min_conditions = 2
    log_columns = ("condition_a", "condition_b", "chosen")
    dvs = ("chosen", "votes")
    record_dv = "chosen"
    default_dv = "votes"
    scale_tests = ("thurstone", "bradley_terry")
    scale_model = "pairs"
    chosen_caption = "times chosen"
    gee_odds_caption = "odds of choosing each condition over"
    gee_note = "of choosing each condition over the reference, in the trials that show both"
    condition_columns = ("condition_a", "condition_b")
    tests = ("summary_table", "pairwise_kruskal", "kruskal_dunn", "thurstone", "bradley_terry", "gee")
    catch_kinds = ("degraded", "repeat")
    has_positions = True
    loops = True
    export_columns = {"pwcmp": ("condition_a", "condition_b", "chosen")}  # noqa: RUF012 - read only
    has_correct_answer = True  # adaptive trials: "which one is the original?"
    threshold_criterion = 0.75
    guess_rate = 0.5
    psignifit_type = "2AFC"

    def default_keys(self, n_conditions):
        return {"answer": {"1": "A", "2": "B"}, "switch": {"left": 0, "right": 1}}

    def answer_values(self, n_conditions):
        return {"A", "B"}

    def max_switch(self, n_conditions):
        return 1

    def stimuli_range(self, n_conditions):
        return (2, 2)

    def practice_problem(self, practice, n_design):
        return "2afc practice needs at least two conditions" if len(practice) < 2 else None

    def main_items(self, conditions, scene, repetitions, *, position_balance, flip_seed, stream):
        items = []
        for k, (a, b) in enumerate(itertools.combinations(conditions, 2)):
            if position_balance:
                flips = [0, 1] * (repetitions // 2) + ([(k + flip_seed) % 2] if repetitions % 2 else [])
            else:
                flips = [stream.below(2) for _ in range(repetitions)]
            for f in flips:
                items.append({"scene": scene, "conditions": (b, a) if f else (a, b), "run": f"{a}|{b}",
                              "item": f"{scene}/{a}|{b}"})
        return items

    def practice_groups(self, conditions):
        return [(conditions[0], c) if i % 2 == 0 else (c, conditions[0]) for i, c in enumerate(conditions[1:])]

    def catch_item(self, i, good, bad):
        return ((good, bad), "A") if i % 2 == 0 else ((bad, good), "B")

    def adaptive_items(self, reference, test, scene, n, stream):
        """The reference (the original) and the test in random order, the same number of times on each side
        when ``n`` is even."""
        sides = stream.shuffle([k % 2 for k in range(n)])
        return [{"scene": scene, "conditions": (test, reference) if f else (reference, test), "run": test,
                 "item": f"{scene}/{test}"} for f in sides]

    def adaptive_correct(self, conditions, test, derived):
        return derived["chosen"] != test  # picked the original

    def interpret(self, conditions, answers, n_picks):
        if len(answers) != 1 or answers[0] not in ("A", "B"):
            raise UserError(f"answer {list(answers)!r} is not A/B")
        return {"chosen": conditions[0 if answers[0] == "A" else 1], "chosen_2": "", "response": None}

    def tidy_columns(self, conditions):
        return {"condition_a": conditions[0], "condition_b": conditions[1]}

    def labels(self, n_stimuli):
        return ["A", "B"]

    def simulate(self, impairments, observer, rng, lapse, n_picks):
        da, db = impairments
        x = observer.sensitivity * (db - da) / math.sqrt(2.0) + observer.bias
        a = rng.random() < 0.5 if lapse else rng.random() < phi(x)
        margin = abs(x)
        return ["A" if a else "B"], margin, int(rng.poisson(1.0 + 2.0 * math.exp(-margin)))

    def shown_and_picks(self, df, conds, codes):
        a = codes(df["condition_a"], conds)
        b = codes(df["condition_b"], conds)
        ch = codes(df["chosen"], conds)
        if np.any(a < 0) or np.any(b < 0):
            raise UserError("2afc trials with an empty condition_a/condition_b")
        bad = (ch != a) & (ch != b)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise UserError(f"2afc trial {i}: chosen {df['chosen'].iloc[i]!r} is neither condition_a nor "
                             "condition_b")
        if np.any(a == b):
            raise UserError("a 2afc trial compares a condition with itself")
        return np.stack([a, b], axis=1), np.stack([ch, np.full_like(ch, -1)], axis=1)


FAMILY = TwoAFC()
