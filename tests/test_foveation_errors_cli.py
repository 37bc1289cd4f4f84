"""Bad input gives ValueError naming the parameter; the CLI prints one line and exits 2; CLI outputs."""

import json
import os
import subprocess
import sys

import pytest

from renderers.foveation import make_mapping
from studyapp.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.parametrize("method,args,params,name", [
    ("lmfr", (640, 480, 90), {"delta": 1.0}, "delta"),
    ("lafr", (640, 480, 90), {"delta": 0.5}, "delta"),
    ("lmfr", (640, 480, 90), {"alpha": 0.0}, "alpha"),
    ("lmfr", (640, 480, 90), {"alpha": -2}, "alpha"),
    ("lafr", (640, 480, 90), {"alpha": 1.0}, "alpha"),
    ("lafr", (640, 480, 90), {"beta": 0.0}, "beta"),
    ("vafr", (640, 480, 90), {"pivots": [(0, 40), (20, 10), (10, 6)]}, "increasing"),
    ("vafr", (640, 480, 90), {"pivots": [(0, 40), (10, 0)]}, "cpd"),
    ("vafr", (640, 480, 90), {"pivots": [(0, 40), (10, -3)]}, "cpd"),
    ("vafr", (640, 480, 90), {"e_max": 95}, "e_max"),
    ("vafr", (640, 480, 90), {"preset": "oculus"}, "preset"),
    ("vafr", (640, 480, 90), {"cap_cpd": 0}, "cap_cpd"),
    ("vafr", (0, 480, 90), {}, "width"),
    ("vafr", (640, -2, 90), {}, "height"),
    ("lmfr", (640.5, 480, 90), {}, "width"),
    ("vafr", (640, 480, 0), {}, "fov_y_deg"),
    ("vafr", (640, 480, 180), {}, "fov_y_deg"),
    ("lafr", (640, 480, float("nan")), {}, "fov_y_deg"),
    ("hmm", (640, 480, 90), {}, "method"),
    ("vafr", (640, 480, 90), {"bogus": 1}, "bogus"),
])
def test_invalid_parameters_raise_value_error_naming_them(method, args, params, name):
    with pytest.raises(ValueError) as info:
        make_mapping(method, *args, **params)
    msg = str(info.value)
    assert name in msg and "\n" not in msg
    if name not in ("increasing", "method", "bogus"):
        assert "allowed" in msg or "must" in msg


def test_lafr_undefined_when_its_fovea_covers_the_display():
    with pytest.raises(ValueError, match="foveal_boundary_deg"):
        make_mapping("lafr", 64, 64, 5)


def test_shading_rate_rejects_bad_direction_and_eccentricity():
    m = make_mapping("vafr", 640, 480, 90)
    with pytest.raises(ValueError, match="direction"):
        m.shading_rate(10, "diagonal")
    with pytest.raises(ValueError, match="e_deg"):
        m.shading_rate(95)


def test_cli_bad_input_is_one_line_exit_2(capsys):
    assert main(["foveation", "table", "--fov-y", "200"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--fov-y" in err and err.startswith("studyapp: error:")
    assert main(["foveation", "nonsense"]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    assert main(["foveation", "plots"]) == 2  # --out is required
    assert "--out" in capsys.readouterr().err


def test_cli_subprocess_no_traceback():
    env = dict(os.environ, PYTHONPATH=ROOT)
    p = subprocess.run([sys.executable, "-m", "studyapp", "foveation", "table", "--fov-y", "-3"], cwd=ROOT,
                       env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 2
    assert "Traceback" not in p.stderr and p.stderr.strip().count("\n") == 0
    p = subprocess.run([sys.executable, "-m", "studyapp", "--help"], cwd=ROOT, env=env, capture_output=True,
                       text=True, timeout=120)
    assert p.returncode == 0 and "foveation" in p.stdout and "demo" in p.stdout


def test_cli_table_json_records(capsys, monkeypatch):
    from renderers.foveation import table as T

    monkeypatch.setattr(T, "TABLE1_RESOLUTIONS", {"2K": (2560, 1440)})
    monkeypatch.setattr(T, "table1", lambda fov, progress=None, _f=T.table1: _f(fov, {"2K": (2560, 1440)}))
    monkeypatch.setattr(T, "preset_reductions", lambda fov, _f=T.preset_reductions: _f(fov, {"2K": (2560, 1440)}))
    assert main(["foveation", "table", "--json"]) == 0
    records = json.loads(capsys.readouterr().out)
    by = {r["method"]: r for r in records}
    assert set(by) == {"VaFR_Dup", "LaFR(2.2)", "LaFR(1.8)", "LMFR(1.8)", "GT"}
    for r in records:
        assert {"method", "width", "height", "shading_points", "shading_points_on_screen"} <= set(r)
    assert by["GT"]["shading_points"] == 2560 * 1440 == by["GT"]["shading_points_on_screen"]
    assert by["VaFR_Dup"]["shading_points"] == 1061630
    assert by["LaFR(1.8)"]["shading_points"] == 1422 * 800


def test_cli_table_and_plots_write_files(tmp_path, capsys, monkeypatch):
    from renderers.foveation import table as T

    monkeypatch.setattr(T, "table1", lambda fov, progress=None, _f=T.table1: _f(fov, {"2K": (2560, 1440)}))
    assert main(["foveation", "table", "--out", str(tmp_path / "t")]) == 0
    md = (tmp_path / "t" / "table1.md").read_text()
    assert "| VaFR_Dup | 2K (2560×1440) | 901×1638 | 1,061,630 |" in md
    assert (tmp_path / "t" / "table1.csv").read_text().startswith("method,resolution,width,height")
    assert main(["foveation", "plots", "--out", str(tmp_path / "p")]) == 0
    pngs = sorted(p.name for p in (tmp_path / "p").glob("*.png"))
    assert pngs == ["fig05_radial_1440x1700.png", "fig05_radial_2560x1440.png",
                    "fig08_resolution_1920x1080_to_7680x4320.png", "fig09_retinal_tuned.png",
                    "fig10_gaze_centre_vs_corner.png", "fig21_tangential.png"]
    for p in (tmp_path / "p").glob("*.png"):
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 20000
    assert not list((tmp_path / "p").glob(".*tmp"))  # nothing half-written left behind
    first = (tmp_path / "p" / "fig21_tangential.png").read_bytes()
    assert main(["foveation", "plots", "--out", str(tmp_path / "p")]) == 0
    assert (tmp_path / "p" / "fig21_tangential.png").read_bytes() == first  # byte-identical reruns
