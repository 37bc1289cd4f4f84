"""``yes_no``: one rendering, "is this the ground truth?" / "is the quality acceptable?".

Seed 003 §5: Task 1 (the labelled ground truth first, then each condition: "is this the ground truth?") and
Task 2 ("is the quality acceptable?"). A sequence plays once, then the question stays up until answered.
Answers ``yes``/``no``; ``response`` is 1 for yes. Simulated answer:
``P(yes) = Phi(s (c - D) + b)`` with the criterion ``c`` in JND.
"""

from __future__ import annotations

from ..errors import UserError
from .base import TrialFamily, phi


class YesNo(TrialFamily):
    name = "yes_no"
    title = "Yes/no judgements"
    kind = "score"
    min_conditions = 1
    log_columns = ("condition", "response")
    dvs = ("response",)
    record_dv = "response"
    default_dv = "response"
    scale_tests = ()
    gee_odds_caption = "odds of a yes against"
    gee_note = "of a yes against the reference"
    condition_columns = ("condition",)
    tests = ("summary_table", "pairwise_kruskal", "kruskal_dunn", "gee")
    catch_kinds = ("degraded",)
    loops = False
    has_correct_answer = True  # adaptive trials: "is this the ground truth?" -- "no" to a test stimulus detects it
    threshold_criterion = 0.5  # of "not the ground truth" answers, above the false-alarm rate the fit estimates
    guess_rate = None
    psignifit_type = "yes/no"

    def default_keys(self, n_conditions):
        return {"answer": {"y": "yes", "n": "no"}, "switch": {}}

    def answer_values(self, n_conditions):
        return {"yes", "no"}

    def stimuli_range(self, n_conditions):
        return (1, 1)

    def main_items(self, conditions, scene, repetitions, *, position_balance, flip_seed, stream):
        return [{"scene": scene, "conditions": (c,), "run": c, "item": f"{scene}/{c}"}
                for c in conditions for _ in range(repetitions)]

    def practice_groups(self, conditions):
        return [(c,) for c in conditions]

    def catch_item(self, i, good, bad):
        return ((bad,), "no") if i % 2 == 0 else ((good,), "yes")

    def adaptive_items(self, reference, test, scene, n, stream):
        return [{"scene": scene, "conditions": (test,), "run": test, "item": f"{scene}/{test}"} for _ in range(n)]

    def adaptive_correct(self, conditions, test, derived):
        return derived["response"] == 0  # "no, not the ground truth": the foveation was detected

    def interpret(self, conditions, answers, n_picks):
        if len(answers) != 1 or answers[0] not in ("yes", "no"):
            raise UserError(f"answer {list(answers)!r} is not yes/no")
        return {"chosen": "", "chosen_2": "", "response": int(answers[0] == "yes")}

    def tidy_columns(self, conditions):
        return {"condition": conditions[0]}

    def simulate(self, impairments, observer, rng, lapse, n_picks):
        (d,) = impairments
        x = observer.sensitivity * (observer.criterion - d) + observer.bias
        yes = rng.random() < 0.5 if lapse else rng.random() < phi(x)
        return ["yes" if yes else "no"], abs(x), 0


FAMILY = YesNo()
