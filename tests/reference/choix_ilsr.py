"""Bradley-Terry maximum-likelihood scores of pwcmp's example data by choix's ILSR (tests/test_analysis_pwcmp.py).

The constants CHOIX_ILSR in the test were printed by this script (choix 0.4.1; ``pip install choix``):

    python tests/reference/choix_ilsr.py

Data: pwcmp_ex3_tmo_cmp_data.csv (pwcmp's example, MIT licence; ``selection`` 0 = condition_1 chosen), the
'peniches' scene left out as pwcmp's example does. Scores are centred by choix; the test compares differences.
"""

from pathlib import Path

import choix
import numpy as np
import pandas as pd

data = pd.read_csv(Path(__file__).with_name("pwcmp_ex3_tmo_cmp_data.csv"))
data = data[data.scene != "peniches"]
conds = sorted(set(data.condition_1) | set(data.condition_2))
from importlib.metadata import version  # noqa: E402

print(f"CHOIX_VERSION = {version('choix')!r}")
print(f"CHOIX_CONDITIONS = {conds!r}")
print("CHOIX_ILSR = {")
for group, g in [("all", data)] + list(data.groupby("scene")):
    winners = np.where(g.selection == 0, g.condition_1, g.condition_2)
    losers = np.where(g.selection == 0, g.condition_2, g.condition_1)
    pairs = [(conds.index(w), conds.index(l)) for w, l in zip(winners, losers)]
    params = choix.ilsr_pairwise(len(conds), pairs, alpha=0.0, max_iter=100_000, tol=1e-14)
    print(f"    {group!r}: [{', '.join(repr(float(v)) for v in params - params[0])}],")
print("}")
