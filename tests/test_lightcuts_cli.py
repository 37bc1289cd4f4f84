"""``studyapp lightcuts tables``: records, tables, figures and bad input (tiny renders)."""

import json

import pytest

from studyapp.cli import main

TINY = ["--scenes", "study", "--width", "32", "--height", "18", "--gt-samples", "16", "--serial"]


def test_tables_json_records_and_files(tmp_path, capsys):
    cache, out = tmp_path / "cache", tmp_path / "out"
    assert main(["lightcuts", "tables", *TINY, "--json", "--out", str(out), "--cache", str(cache)]) == 0
    records = json.loads(capsys.readouterr().out)
    gt_files = sorted(cache.rglob("*.npy"))
    assert len(gt_files) == 1  # GT stored once in the stimulus cache ...
    stamp = gt_files[0].stat().st_mtime_ns
    # the other budget accounting: SL_e changes, Ours does not, the GT is reused
    assert main(["lightcuts", "tables", *TINY, "--json", "--cache", str(cache), "--budget", "equal-samples",
                 "--out", str(tmp_path / "samples")]) == 0
    again = json.loads(capsys.readouterr().out)

    def errors(recs):  # Ours' and SL_as' errors do not depend on timing (SL_e's equal-time count does)
        return [r for r in recs if r["method"] in ("Ours", "SL_as") and r["metric"].startswith("mse")]

    assert errors(again) == errors(records)  # ... and reused: the same GT, the same seed
    assert gt_files[0].stat().st_mtime_ns == stamp
    assert records and all(set(r) == {"table", "scene", "method", "metric", "region", "value"} for r in records)
    assert {r["table"] for r in records} == {"1", "2", "3", "4", "fig8", "fig9"}
    assert {r["metric"] for r in records} >= {"mse", "mse_d", "spp", "ms"}
    assert {r["region"] for r in records} == {"fovea", "periphery", "all"}
    t3 = {r["method"] for r in records if r["table"] == "3" and r["metric"] == "ms"}
    assert t3 == {"Ours", "Ours'", "SL_as", "SL_f", "SL_p"}
    assert len([r for r in records if r["table"] == "4"]) == 5  # alpha = 0.025 ... 0.4
    assert all(r["value"] >= 0 for r in records)
    md = (out / "lightcuts_tables.md").read_text()
    assert "Table 1" in md and "| study | Ours |" in md and "Targets" in md
    ratios = json.loads((out / "lightcuts_ratios.json").read_text())["study"]
    t3v = {r["method"]: r["value"] for r in records if r["table"] == "3" and r["metric"] == "ms"}
    assert ratios["speedup_vs_sl_f"] == pytest.approx(t3v["SL_f"] / t3v["Ours"])
    for name in ("study_fpsm.png", "study_error_ours.png", "study_error_sl_e.png", "fig8_mse_vs_alpha.png"):
        assert (out / name).stat().st_size > 100
    assert "Fig 9: ms per step" in md and "(same-run ratios, equal-time)" in md
    md2 = (tmp_path / "samples" / "lightcuts_tables.md").read_text()
    assert "(same-run ratios, equal-samples)" in md2 and "speed-up, rays" in md2
    r2 = json.loads((tmp_path / "samples" / "lightcuts_ratios.json").read_text())["study"]
    t3 = {(r["method"], r["metric"]): r["value"] for r in again if r["table"] == "3"}
    assert r2["multires_speedup"] == pytest.approx(t3[("Ours'", "traversals")] / t3[("Ours", "traversals")])
    assert r2["speedup_vs_sl_f"] == pytest.approx((t3[("SL_f", "light_samples")] + t3[("SL_f", "glossy_rays")])
                                                  / (t3[("Ours", "light_samples")] + t3[("Ours", "glossy_rays")]))


@pytest.mark.parametrize("argv, message", [
    (["--alpha", "1.5"], "alpha=1.5 is out of range"),
    (["--alpha", "0"], "alpha=0 is out of range"),
    (["--scenes", "nowhere"], "unknown scene 'nowhere'"),
    (["--width", "2"], "--width=2 is out of range"),
    (["--budget", "equal-money"], "argument --budget: invalid choice: 'equal-money'"),
    (["--fpsm-reading", "literal"], "argument --fpsm-reading: invalid choice: 'literal'"),
])
def test_bad_input_is_one_line_exit_2(tmp_path, capsys, argv, message):
    assert main(["lightcuts", "tables", *TINY, *argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "o").exists()


def test_tables_on_the_gpu_backend(tmp_path, capsys, monkeypatch):
    """--backend gpu renders every method and the GT with the GPU versions (GT cached under its own key); the
    default size is the seed's 2160x2160 per eye on a GPU and stays small on a software rasteriser (llvmpipe)."""
    from renderers.gpu.context import get_device
    from studyapp.commands import lightcuts as cmd

    cache = tmp_path / "cache"
    assert main(["lightcuts", "tables", *TINY, "--backend", "gpu", "--json", "--cache", str(cache),
                 "--out", str(tmp_path / "gpu")]) == 0
    records = json.loads(capsys.readouterr().out)
    assert {r["table"] for r in records} == {"1", "2", "3", "4", "fig8", "fig9"}
    assert "Table 3: ms per frame (GPU backend)" in (tmp_path / "gpu" / "lightcuts_tables.md").read_text()
    assert main(["lightcuts", "tables", *TINY, "--json", "--cache", str(cache), "--out", str(tmp_path / "cpu")]) == 0
    cpu = json.loads(capsys.readouterr().out)
    assert len(sorted(cache.rglob("*.npy"))) == 2  # one GT per backend
    spp = lambda recs: {r["method"]: r["value"] for r in recs if r["table"] == "2" and r["region"] == "all"}  # noqa
    for method in ("Ours", "SL_as"):  # the same samples per pixel on both backends (SL_e's is timed)
        assert spp(records)[method] == pytest.approx(spp(cpu)[method], rel=0.02), method
    dev = get_device()
    assert dev.software and cmd.frame_size("gpu", None, None) == cmd.SMALL_SIZE
    monkeypatch.setattr(dev, "software", False)
    assert cmd.frame_size("gpu", None, None) == cmd.SEED_SIZE == (2160, 2160)
    assert cmd.frame_size("gpu", 320, None) == (320, 2160) and cmd.frame_size("cpu", None, None) == (192, 108)


def test_tables_without_opengl_43_is_one_line_exit_2(tmp_path):
    import os
    import subprocess
    import sys

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env.update(PYTHONPATH=os.pathsep.join([root, env.get("PYTHONPATH", "")]), MESA_GL_VERSION_OVERRIDE="3.3")
    p = subprocess.run([sys.executable, "-m", "studyapp", "lightcuts", "tables", *TINY, "--backend", "gpu",
                        "--out", str(tmp_path / "o")], capture_output=True, text=True, env=env, timeout=120)
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert lines[0].startswith("studyapp: error: OpenGL 4.3 compute shaders are not available")
    assert not (tmp_path / "o").exists()


def _no_rendering(monkeypatch):
    """Stand-ins for the renders: the command's own checks and output only (the GT step must not run)."""
    import numpy as np

    from renderers.lightcuts import tables
    from studyapp.commands import lightcuts as cmd

    def gts(*args):
        raise AssertionError("rendered before --out was checked")

    def fake_tables(scene, width, height, images=None, **kw):
        img = np.full((height, width, 3), 0.5, np.float32)
        images.update(gt=img, ours=img, sl_e=img, sl_as=img, fpsm=img[..., 0])
        return [{"table": "1", "scene": scene.name, "method": "Ours", "metric": "mse", "region": "all",
                 "value": 0.0}]

    monkeypatch.setattr(cmd, "_ground_truths", gts)
    monkeypatch.setattr(tables, "lightcut_tables", fake_tables)


def test_out_is_checked_before_any_rendering_and_a_users_folder_is_kept(tmp_path, capsys, monkeypatch):
    _no_rendering(monkeypatch)
    mine = tmp_path / "lightcuts_tables.md"
    mine.write_text("my notes")
    for out, message in ((mine, f"{mine}: is a regular file, not a folder"),
                         (tmp_path, f"{tmp_path}: is a folder with other files in it (no lightcuts_records.json)")):
        assert main(["lightcuts", "tables", *TINY, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err, err
    assert mine.read_text() == "my notes" and sorted(p.name for p in tmp_path.iterdir()) == [mine.name]
    for out, cache in ((tmp_path / "o", tmp_path / "o" / "cache"), (tmp_path / "c" / "o", tmp_path / "c")):
        assert main(["lightcuts", "tables", *TINY, "--out", str(out), "--cache", str(cache)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "overlap: the --out folder is replaced whole" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == [mine.name]


def test_out_is_a_marked_folder_replaced_whole(tmp_path, capsys, monkeypatch):
    from studyapp.commands import lightcuts as cmd

    _no_rendering(monkeypatch)
    monkeypatch.setattr(cmd, "_ground_truths", lambda *args: None)
    out = tmp_path / "out"
    for run in range(2):
        assert main(["lightcuts", "tables", *TINY, "--out", str(out)]) == 0
        printed = capsys.readouterr().out.splitlines()
        assert printed[:3] == [str(out / n) for n in ("lightcuts_tables.md", cmd.MARKER, "lightcuts_ratios.json")]
        assert sorted(printed) == sorted(str(p) for p in out.iterdir())  # every file it wrote, and only those
        (out / "stale.txt").write_text("from an earlier run")  # replaced whole by the next run
    assert json.loads((out / cmd.MARKER).read_text())[0]["method"] == "Ours"
    assert [p.name for p in tmp_path.iterdir()] == ["out"]  # no temporary folder left
