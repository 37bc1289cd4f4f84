"""Names of the lightcuts options shared by the renderer, the tables and the CLI (pure Python: importing this
module loads neither numpy nor numba, so ``studyapp --help`` stays fast).

* ``FPSM_READINGS`` — the readings of seed 003 Eq 4–8 that ``fsl``'s ``fpsm_reading`` selects
  (``fpsm.fpsm_map``); the first is the default.
* ``BUDGETS`` — the budget accountings of the comparison in ``tables.lightcut_tables``; the first is the
  default.
"""

FPSM_READINGS = ("derived", "blur", "retained")
BUDGETS = ("equal-time", "equal-samples")
