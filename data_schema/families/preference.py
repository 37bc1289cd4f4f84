"""``preference``: all N renderings of a scene (switch among them freely), pick the favourite and the second.

Seed 001 §5.3.1 (pilot): five modes per scene, "top two of N"; the participant may stop after one pick.
Answers are stimulus indices (``"0"`` .. ``"N-1"``; ``""`` ends picking early); ``chosen`` and ``chosen_2``
are the picked conditions. Simulated answer: utilities ``U_i = -s D_i + N(0, 1)``, the top ``n_picks``;
stopping after the first pick when the second and third utilities are within 0.15 (undecided).
"""

from __future__ import annotations

import numpy as np

from ..errors import UserError
from .base import TrialFamily


class Preference(TrialFamily):
    name = "preference"
    title = "Preference (top two of N)"
    kind = "choice"
    min_conditions = 2
    log_columns = ("conditions", "chosen")
    dvs = ("votes", "chosen")
    record_dv = "votes"
    default_dv = "votes"
    scale_tests = ("plackett_luce",)
    scale_model = "rankings"
    chosen_caption = "times chosen first"
    no_gee_note = "no logistic GEE for top-two-of-N choices (yes/no and 2AFC only)"
    condition_columns = ("conditions",)
    tests = ("summary_table", "pairwise_kruskal", "kruskal_dunn", "plackett_luce")
    catch_kinds = ()
    has_picks = True
    loops = True
    has_correct_answer = False  # a favourite is not right or wrong: no adaptive designs

    def default_n_picks(self, n_conditions):
        return 2

    def default_keys(self, n_conditions):
        """Digits 1..N show stimulus i, F1..FN pick it, ``return`` ends picking early (answer "")."""
        return {"answer": {**{f"f{i + 1}": str(i) for i in range(n_conditions)}, "return": ""},
                "switch": {str(i + 1): i for i in range(n_conditions)}}

    def answer_values(self, n_conditions):
        return {str(i) for i in range(n_conditions)} | {""}

    def stimuli_range(self, n_conditions):
        return (2, 64)

    def practice_problem(self, practice, n_design):
        if len(practice) != n_design:
            return f"preference practice offers as many conditions as the design ({n_design})"
        return None

    def main_items(self, conditions, scene, repetitions, *, position_balance, flip_seed, stream):
        return [{"scene": scene, "conditions": tuple(stream.shuffle(list(conditions))), "run": scene,
                 "item": f"{scene}/pref"} for _ in range(repetitions)]

    def practice_groups(self, conditions):
        return [tuple(conditions)]

    def interpret(self, conditions, answers, n_picks):
        picks = [a for a in answers if a != ""]
        if not picks:
            raise UserError("no pick")
        try:
            idx = [int(a) for a in picks]
        except ValueError:
            raise UserError(f"answer {list(answers)!r} is not a pick") from None
        if len(idx) > n_picks or len(set(idx)) != len(idx) or any(not 0 <= i < len(conditions) for i in idx):
            raise UserError(f"answer {list(answers)!r} is not a valid pick")
        return {"chosen": conditions[idx[0]], "chosen_2": conditions[idx[1]] if len(idx) > 1 else "",
                "response": None}

    def tidy_columns(self, conditions):
        return {"conditions": "|".join(conditions)}

    def labels(self, n_stimuli):
        return [str(i + 1) for i in range(n_stimuli)]

    def simulate(self, impairments, observer, rng, lapse, n_picks):
        n = len(impairments)
        if lapse:
            u = rng.standard_normal(n)
        else:
            u = np.array([-observer.sensitivity * d for d in impairments]) + rng.standard_normal(n)
        order = [int(i) for i in np.argsort(-u, kind="stable")]
        picks = order[:n_picks]
        if n_picks >= 2 and n >= 3 and u[order[1]] - u[order[2]] < 0.15:
            picks = picks[:1]
        return [str(i) for i in picks], float(u[order[0]] - u[order[1]]), int(rng.poisson(n + 1.0))

    def shown_and_picks(self, df, conds, codes):
        import pandas as pd

        offered = df["conditions"].astype(str)
        cats = pd.Categorical(offered)
        sets = [s.split("|") for s in cats.categories]
        m = max(len(s) for s in sets)
        table = np.full((len(sets), m), -1, dtype=np.int64)
        for i, s in enumerate(sets):
            idx = [conds.index(c) if c in conds else -2 for c in s]
            if -2 in idx:
                raise UserError(f"preference trials offer an unknown condition in {cats.categories[i]!r}")
            table[i, :len(idx)] = idx
        shown = table[cats.codes]
        c1 = codes(df["chosen"], conds)
        c2 = codes(df["chosen_2"], conds) if "chosen_2" in df.columns else np.full(len(df), -1)
        for name, c in (("chosen", c1), ("chosen_2", c2)):
            ok = (c < 0) | (shown == c[:, None]).any(axis=1)
            if not ok.all():
                i = int(np.flatnonzero(~ok)[0])
                raise UserError(f"preference trial {i}: {name} is not among the offered conditions")
        if np.any(c1 < 0):
            raise UserError("preference trials with an empty first choice (chosen)")
        return shown, np.stack([c1, c2], axis=1)


FAMILY = Preference()
