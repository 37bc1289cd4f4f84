"""Write the GEE inputs of tests/test_analysis_gee.py and print geepack's estimates for them.

    python tests/reference/gee_geepack.py     (needs Rscript with geepack: apt-get install r-cran-geepack)

Inputs (all from analysis.synthetic, seeded): the seed 003 Table 5 yes/no log (reference EC, intercept model),
the seed 001 2AFC log's trials that show GT (1 = the other condition chosen; no intercept), and both again with a
seeded 60 % of the rows kept (unbalanced clusters, where the working correlation matters).
"""

import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from test_analysis_gee import gee_inputs  # noqa: E402

with tempfile.TemporaryDirectory() as tmp:
    for name, (frame, reference, intercept) in gee_inputs().items():
        frame.to_csv(Path(tmp) / f"{name}.csv", index=False)
        (Path(tmp) / f"{name}.txt").write_text(f"{reference} {'intercept' if intercept else 'none'}\n")
    subprocess.run(["Rscript", str(Path(__file__).with_name("gee_geepack.R")), tmp], check=True)
