"""`import analysis` stays light: analysts and CI need no PsychoPy, VTK, numba or matplotlib for statistics."""

import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_import_analysis_loads_no_heavy_packages():
    code = ("import sys, analysis; heavy = ('psychopy', 'vtk', 'pyvista', 'numba', 'matplotlib', 'statsmodels',"
            " 'renderers', 'studyapp', 'dask', 'distributed');"
            " print(sorted({m.split('.')[0] for m in sys.modules} & set(heavy)))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120,
                         env=dict(os.environ, PYTHONPATH=ROOT))
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
