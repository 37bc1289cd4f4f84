"""Image quality (MSE, PSNR, SSIM) in the fovea and periphery, the error heat map and `studyapp quality`."""

import json
import math
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.quality import (
    QUALITY_COLUMNS,
    eccentricity_map,
    error_heatmap,
    fovea_radius_px,
    image_quality,
    region_masks,
    squared_error_map,
)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _row(df, region):
    return df.set_index("region").loc[region]


# --- geometry -----------------------------------------------------------------------------------------------
@settings(max_examples=40)
@given(w=st.integers(1, 40), h=st.integers(1, 40), fov=st.floats(1.0, 170.0),
       gx=st.floats(-100.0, 140.0), gy=st.floats(-100.0, 140.0))
def test_eccentricity_matches_display_geometry(w, h, fov, gx, gy):
    from data_schema.geometry import ViewingGeometry

    g = ViewingGeometry.create(w, h, fov, (gx, gy))
    x, y = g.pixel_centres()
    expected = g.eccentricity(np.hypot(x - gx, y - gy))
    got = eccentricity_map(w, h, fov, (gx, gy))
    assert got.shape == (h, w)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_eccentricity_by_hand_and_default_gaze_is_centre():
    # fov 90 deg, H = 4: c_r = 2 tan 45 / 4 = 0.5. Gaze at the centre (2, 2); pixel (0, 0) has centre
    # (0.5, 0.5), r = 1.5 sqrt 2, e = atan(0.75 sqrt 2).
    e = eccentricity_map(4, 4, 90.0)
    assert e[0, 0] == pytest.approx(math.degrees(math.atan(0.5 * 1.5 * math.sqrt(2))), rel=1e-14)
    assert e[1, 1] == pytest.approx(math.degrees(math.atan(0.5 * 0.5 * math.sqrt(2))), rel=1e-14)
    np.testing.assert_array_equal(e, eccentricity_map(4, 4, 90.0, (2.0, 2.0)))
    np.testing.assert_allclose(e, e[::-1, ::-1], rtol=1e-15)  # symmetric about the centre


@settings(max_examples=40)
@given(w=st.integers(1, 30), h=st.integers(1, 30), fov=st.floats(5.0, 170.0), fovea=st.floats(0.1, 60.0),
       gx=st.floats(-50.0, 80.0), gy=st.floats(-50.0, 80.0))
def test_masks_partition_the_display(w, h, fov, fovea, gx, gy):
    m = region_masks(w, h, fov, (gx, gy), fovea)
    assert m.fovea.shape == m.periphery.shape == (h, w)
    assert m.fovea.dtype == bool and m.periphery.dtype == bool
    assert not np.any(m.fovea & m.periphery)
    assert np.all(m.fovea | m.periphery)
    e = eccentricity_map(w, h, fov, (gx, gy))
    assert np.all(e[m.fovea] <= fovea) and np.all(e[m.periphery] > fovea)


def test_fovea_with_gaze_at_a_corner_counted_by_hand():
    # W = H = 100, fov 90 -> c_r = 0.02; fovea 5 deg -> r = tan 5 / 0.02 = 4.3744 px, r^2 = 19.135.
    # Centres (i + .5, j + .5) with squared distance <= 19.135 from (0, 0): columns i = 0, 1, 2 take
    # j = 0..3 (4 each), i = 3 takes j = 0..2 (3), i >= 4 none: 15 pixels, all in the top-left 4 x 4 block.
    assert fovea_radius_px(100, 90.0, 5.0) == pytest.approx(math.tan(math.radians(5)) / 0.02, rel=1e-14)
    m = region_masks(100, 100, 90.0, (0.0, 0.0), 5.0)
    assert int(m.fovea.sum()) == 15
    assert m.fovea[:4, :4].sum() == 15 and not m.fovea[3, 3]
    assert int(m.periphery.sum()) == 100 * 100 - 15


@pytest.mark.parametrize("kwargs, msg", [
    ({"width": 0}, "width=0 is out of range"),
    ({"height": 2.5}, "height=2.5 is invalid: must be a whole number"),
    ({"fov_y_deg": 180.0}, r"fov_y_deg=180 is out of range: allowed \(0, 180\)"),
    ({"gaze": (1.0,)}, "gaze=.* is invalid"),
    ({"gaze": (float("nan"), 1.0)}, "must be finite"),
    ({"fovea_deg": 0.0}, r"fovea_deg=0 is out of range: allowed \(0, 90\)"),
])
def test_geometry_bad_input(kwargs, msg):
    args = {"width": 8, "height": 8, "fov_y_deg": 90.0, "gaze": None, "fovea_deg": 5.0} | kwargs
    with pytest.raises(ValueError, match=msg):
        region_masks(**args)


# --- metrics ------------------------------------------------------------------------------------------------
def _one_pixel_fovea():
    """8 x 8, fov 90 -> c_r = 0.25; gaze (0, 0); fovea e = atan(0.25) -> r = 1 px: only pixel (0, 0)."""
    return {"fov_y_deg": 90.0, "gaze": (0.0, 0.0), "fovea_deg": math.degrees(math.atan(0.25))}


def test_mse_psnr_by_hand_grey_float():
    ref = np.zeros((8, 8))
    img = np.full((8, 8), 0.1)
    img[0, 0] = 0.5
    q = image_quality(img, ref, **_one_pixel_fovea())
    assert list(q.columns) == list(QUALITY_COLUMNS)
    assert list(q["region"]) == ["fovea", "periphery", "all"]
    assert list(q["n_pixels"]) == [1, 63, 64]
    fovea, peri, whole = (_row(q, r) for r in ("fovea", "periphery", "all"))
    assert fovea.mse == pytest.approx(0.25, rel=1e-14)
    assert peri.mse == pytest.approx(0.01, rel=1e-12)
    assert whole.mse == pytest.approx((0.25 + 63 * 0.01) / 64, rel=1e-12)
    assert fovea.psnr == pytest.approx(10 * math.log10(1 / 0.25), rel=1e-12)  # 6.0206 dB
    assert peri.psnr == pytest.approx(20.0, rel=1e-12)
    assert whole.psnr == pytest.approx(10 * math.log10(64 / 0.88), rel=1e-12)


def test_mse_psnr_by_hand_rgb_and_uint8():
    ref = np.zeros((8, 8, 3))
    img = np.broadcast_to(np.array([0.1, 0.2, 0.3]), (8, 8, 3))
    # c_r = 0.25, fovea 20 deg: r = 1.46 px holds the 4 centre pixels (r = 0.71), not the next ring (1.58)
    q = image_quality(img, ref, fov_y_deg=90.0, fovea_deg=20.0)
    assert list(q["n_pixels"]) == [4, 60, 64]
    mse = (0.01 + 0.04 + 0.09) / 3
    assert _row(q, "all").mse == pytest.approx(mse, rel=1e-12)
    assert _row(q, "fovea").mse == pytest.approx(mse, rel=1e-12)
    np.testing.assert_allclose(squared_error_map(img, ref), np.full((8, 8), mse), rtol=1e-12)
    # uint8: data_range 255 by default; MSE in (8-bit units)^2
    q8 = image_quality(np.full((9, 9), 10, np.uint8), np.zeros((9, 9), np.uint8), fov_y_deg=60.0)
    assert list(q8["mse"]) == [100.0, 100.0, 100.0]
    assert _row(q8, "all").psnr == pytest.approx(10 * math.log10(255 ** 2 / 100), rel=1e-12)  # 28.13 dB
    # uint16: 65535; an explicit data_range overrides the default
    q16 = image_quality(np.full((9, 9), 300, np.uint16), np.full((9, 9), 200, np.uint16), fov_y_deg=60.0)
    assert _row(q16, "all").psnr == pytest.approx(10 * math.log10(65535 ** 2 / 1e4), rel=1e-12)
    q2 = image_quality(np.full((9, 9), 0.5), np.full((9, 9), 0.0), fov_y_deg=60.0, data_range=2.0)
    assert _row(q2, "all").psnr == pytest.approx(10 * math.log10(4 / 0.25), rel=1e-12)


@pytest.mark.parametrize("shape, dtype",
                         [((24, 31), np.float64), ((20, 17, 3), np.float32), ((16, 16, 3), np.uint8)])
def test_ssim_of_whole_image_equals_skimage_global_ssim(shape, dtype):
    from skimage.metrics import structural_similarity

    rng = np.random.default_rng(7)
    ref = rng.random(shape)
    img = np.clip(ref + rng.normal(0, 0.1, shape), 0, 1)
    if dtype == np.uint8:
        ref, img = (np.round(a * 255).astype(np.uint8) for a in (ref, img))
    else:
        ref, img = ref.astype(dtype), img.astype(dtype)
    rng_ = 255.0 if dtype == np.uint8 else 1.0
    expected = structural_similarity(img.astype(np.float64), ref.astype(np.float64), data_range=rng_,
                                     channel_axis=2 if len(shape) == 3 else None)
    q = image_quality(img, ref, fov_y_deg=100.0, fovea_deg=8.0)
    whole = _row(q, "all")
    assert whole.ssim == pytest.approx(expected, rel=1e-12)
    assert whole.n_ssim_pixels == (shape[0] - 6) * (shape[1] - 6)
    # the region means are means of one SSIM map: weighted by their pixel counts they give the whole
    f, p = _row(q, "fovea"), _row(q, "periphery")
    assert f.n_ssim_pixels + p.n_ssim_pixels == whole.n_ssim_pixels
    combined = (f.ssim * f.n_ssim_pixels + p.ssim * p.n_ssim_pixels) / whole.n_ssim_pixels
    assert combined == pytest.approx(expected, rel=1e-12)
    combined_mse = (f.mse * f.n_pixels + p.mse * p.n_pixels) / whole.n_pixels
    assert combined_mse == pytest.approx(whole.mse, rel=1e-12)


def test_identical_images_give_infinite_psnr_never_nan():
    rng = np.random.default_rng(3)
    a = rng.random((12, 14, 3))
    q = image_quality(a, a.copy(), fov_y_deg=100.0, fovea_deg=10.0)
    assert q["mse"].tolist() == [0.0, 0.0, 0.0]
    assert all(math.isinf(v) and v > 0 for v in q["psnr"])
    assert q["ssim"].tolist() == pytest.approx([1.0, 1.0, 1.0], abs=1e-12)
    assert not q[["mse", "psnr", "ssim"]].isna().any().any()
    assert all("PSNR +inf" in n for n in q["note"])


def test_gaze_far_outside_leaves_the_fovea_empty_not_nan():
    rng = np.random.default_rng(4)
    ref, img = rng.random((10, 10)), rng.random((10, 10))
    q = image_quality(img, ref, fov_y_deg=60.0, gaze=(1e4, -1e4), fovea_deg=5.0)
    f, p, whole = (_row(q, r) for r in ("fovea", "periphery", "all"))
    assert f.n_pixels == 0 and f.n_ssim_pixels == 0
    assert f.mse is pd.NA and f.psnr is pd.NA and f.ssim is pd.NA
    assert "no pixels" in f.note
    assert q["mse"].dtype == "Float64" and not np.isnan(q["mse"].to_numpy(dtype=float, na_value=0.0)).any()
    assert (p.mse, p.psnr, p.ssim, p.n_pixels) == (whole.mse, whole.psnr, whole.ssim, 100)
    # a fovea larger than the display leaves the periphery empty
    q2 = image_quality(img, ref, fov_y_deg=10.0, fovea_deg=80.0)
    assert _row(q2, "periphery").n_pixels == 0 and _row(q2, "periphery").mse is pd.NA
    assert _row(q2, "fovea").mse == _row(q2, "all").mse


def test_fovea_in_the_border_strip_has_mse_but_no_ssim():
    rng = np.random.default_rng(5)
    ref, img = rng.random((8, 8)), rng.random((8, 8))
    q = image_quality(img, ref, **_one_pixel_fovea())  # only pixel (0, 0): inside the 3-px border
    f = _row(q, "fovea")
    assert f.n_pixels == 1 and f.n_ssim_pixels == 0
    assert f.mse == pytest.approx((img[0, 0] - ref[0, 0]) ** 2, rel=1e-12)
    assert f.ssim is pd.NA and "border" in f.note


@pytest.mark.parametrize("image, reference, kwargs, msg", [
    (np.zeros((8, 8)), np.zeros((8, 9)), {}, r"image shape \(8, 8\) differs from reference shape \(8, 9\)"),
    (np.full((8, 8), np.nan), np.zeros((8, 8)), {}, "image contains 64 NaN or infinite"),
    (np.zeros((8, 8)), np.where(np.eye(8) > 0, np.inf, 0.0), {}, "reference contains 8 NaN or infinite"),
    (np.zeros((8, 8), np.int64), np.zeros((8, 8), np.int64), {}, "dtype int64: supported are uint8, uint16"),
    (np.zeros((8, 8), np.uint8), np.zeros((8, 8)), {}, "differ in scale"),
    (np.full((8, 8), 2.0), np.zeros((8, 8)), {}, r"outside \[0, 1\]: pass data_range"),
    (np.zeros((8, 8)), np.zeros((8, 8)), {"data_range": 0}, "data_range=0 is out of range"),
    (np.zeros((6, 20)), np.zeros((6, 20)), {}, "image is 20x6 pixels: SSIM needs at least 7x7"),
    (np.zeros((3, 8, 8)), np.zeros((3, 8, 8)), {}, "channels-last"),
    (np.zeros((8,)), np.zeros((8,)), {}, r"expected \(H, W\)"),
    (np.zeros((8, 8)), np.zeros((8, 8)), {"fov_y_deg": -1}, "fov_y_deg=-1 is out of range"),
])
def test_image_quality_bad_input(image, reference, kwargs, msg):
    args = {"fov_y_deg": 90.0} | kwargs
    with pytest.raises(ValueError, match=msg):
        image_quality(image, reference, **args)


def test_hdr_float_with_data_range_is_accepted():
    ref = np.full((8, 8), 4.0)
    q = image_quality(ref + 1.0, ref, fov_y_deg=90.0, data_range=10.0)
    assert _row(q, "all").psnr == pytest.approx(20.0, rel=1e-12)


def test_importing_analysis_quality_loads_no_heavy_package():
    """scikit-image, matplotlib and Pillow are imported inside the functions that draw or compute SSIM."""
    heavy = ["skimage", "matplotlib", "PIL", "numba", "renderers", "studyapp", "psychopy", "pyvista"]
    code = ("import sys, analysis.quality; loaded = {m.split('.')[0] for m in sys.modules}; "
            f"sys.exit(' '.join(sorted(loaded & {set(heavy)!r})) or None)")
    proc = subprocess.run([sys.executable, "-c", code], check=False, cwd=ROOT,
                          env=dict(os.environ, PYTHONPATH=ROOT), capture_output=True, text=True, timeout=120)
    assert (proc.returncode, proc.stderr.strip()) == (0, "")


# --- heat map -----------------------------------------------------------------------------------------------
def test_error_heatmap_writes_a_deterministic_png(tmp_path):
    from PIL import Image

    rng = np.random.default_rng(6)
    ref = rng.random((30, 40, 3))
    img = ref.copy()
    img[10:20, 10:20] += 0.05  # zero error elsewhere: drawn in the 'under' colour
    a = error_heatmap(img, ref, tmp_path / "sub" / "a.png", fov_y_deg=90.0, gaze=(15, 15), fovea_deg=10.0)
    b = error_heatmap(img, ref, tmp_path / "sub" / "b.png", fov_y_deg=90.0, gaze=(15, 15), fovea_deg=10.0)
    assert a == tmp_path / "sub" / "a.png"
    assert a.read_bytes() == b.read_bytes()
    with Image.open(a) as im:
        assert im.format == "PNG" and im.size[0] == 640 and im.size[1] > 100
        px = np.asarray(im.convert("RGB"))
    assert (px == [255, 0, 0]).all(axis=2).sum() > 20  # the red fovea circle is drawn
    assert sorted(p.name for p in (tmp_path / "sub").iterdir()) == ["a.png", "b.png"]  # no temp files left
    c = error_heatmap(ref, ref, tmp_path / "c.png", fov_y_deg=90.0, gaze=None, fovea_deg=5.0)
    assert c.stat().st_size > 1000
    with pytest.raises(ValueError, match="differs from reference shape"):
        error_heatmap(ref, ref[:, :-1], tmp_path / "d.png", fov_y_deg=90.0, gaze=None, fovea_deg=5.0)
    assert not (tmp_path / "d.png").exists()


# --- CLI ----------------------------------------------------------------------------------------------------
@pytest.fixture
def stimuli(tmp_path):
    from PIL import Image

    rng = np.random.default_rng(11)
    gt = (rng.random((24, 32, 3)) * 255).astype(np.uint8)
    noisy = np.clip(gt.astype(int) + rng.integers(-12, 13, gt.shape), 0, 255).astype(np.uint8)
    folder = tmp_path / "stimuli"
    folder.mkdir()
    Image.fromarray(gt).save(folder / "gt.png")
    Image.fromarray(gt).save(folder / "a_same.png")
    Image.fromarray(noisy).save(folder / "b_noisy.png")
    (folder / "notes.txt").write_text("not an image")
    return folder, gt, noisy


def _main(monkeypatch, argv):
    from studyapp import cli

    if "studyapp.commands.quality" not in cli.COMMAND_MODULES:
        modules = (*cli.COMMAND_MODULES, "studyapp.commands.quality")
        monkeypatch.setattr(cli, "COMMAND_MODULES", modules)
    return cli.main(argv)


def test_cli_quality_over_a_folder(tmp_path, stimuli, monkeypatch, capsys):
    folder, gt, noisy = stimuli
    out = tmp_path / "out"
    argv = ["quality", "--gt", str(folder / "gt.png"), "--fov-y", "90", "--gaze", "8,6", "--fovea-deg", "10",
            "--out", str(out), str(folder)]
    assert _main(monkeypatch, argv) == 0
    printed = capsys.readouterr().out.split()
    assert sorted(os.path.basename(p) for p in printed) == [
        "heatmap_a_same.png", "heatmap_b_noisy.png", "quality.csv", "quality.md"]
    table = pd.read_csv(out / "quality.csv", keep_default_na=False)
    assert list(table.columns) == ["image"] + list(QUALITY_COLUMNS)
    assert len(table) == 2 * 3  # the GT and the .txt are skipped
    assert [os.path.basename(p) for p in table["image"]] == ["a_same.png"] * 3 + ["b_noisy.png"] * 3
    expected = image_quality(noisy, gt, fov_y_deg=90.0, gaze=(8, 6), fovea_deg=10.0)
    got = table.iloc[3:].reset_index(drop=True)
    np.testing.assert_allclose(got["mse"].astype(float), expected["mse"].astype(float), rtol=1e-12)
    np.testing.assert_allclose(got["ssim"].astype(float), expected["ssim"].astype(float), rtol=1e-12)
    assert list(got["n_pixels"]) == list(expected["n_pixels"])
    assert list(table["psnr"].iloc[:3]) == [math.inf] * 3  # written as "inf"
    assert (out / "quality.csv").read_text().count(",0.0,inf,1.0,") == 3
    md = (out / "quality.md").read_text()
    assert "| b_noisy.png" not in md and f"| {folder / 'b_noisy.png'} | fovea |" in md and "∞" in md
    first = (out / "quality.csv").read_bytes(), (out / "heatmap_b_noisy.png").read_bytes()
    assert _main(monkeypatch, argv) == 0  # same input -> byte-identical output
    assert ((out / "quality.csv").read_bytes(), (out / "heatmap_b_noisy.png").read_bytes()) == first


def test_cli_quality_json_and_npy(tmp_path, stimuli, monkeypatch, capsys):
    _folder, gt, _ = stimuli
    np.save(tmp_path / "gt.npy", gt / 255.0)
    np.save(tmp_path / "half.npy", gt / 510.0)
    argv = ["quality", "--gt", str(tmp_path / "gt.npy"), "--fov-y", "90", "--gaze=0,24", "--json",
            str(tmp_path / "half.npy")]
    assert _main(monkeypatch, argv) == 0
    records = json.loads(capsys.readouterr().out)
    assert [r["region"] for r in records] == ["fovea", "periphery", "all"]
    assert 0 < records[0]["n_pixels"] < 24 * 32  # the fovea around the bottom-left corner
    argv[5] = "--gaze=-1000,1000"  # a gaze outside the image is refused, as `render` refuses it
    assert _main(monkeypatch, argv) == 2
    assert records[2]["mse"] == pytest.approx(float(np.mean((gt / 510.0) ** 2)), rel=1e-12)
    assert records[2]["n_pixels"] == 24 * 32


def test_cli_quality_prints_markdown_without_out(stimuli, monkeypatch, capsys):
    folder, _, _ = stimuli
    argv = ["quality", "--gt", str(folder / "gt.png"), "--fov-y", "90", str(folder / "a_same.png")]
    assert _main(monkeypatch, argv) == 0
    out = capsys.readouterr().out
    assert out.startswith("# Image quality against ground truth")
    assert out.count("| ∞ |") == 3 and "centre (16, 12)" in out


@pytest.mark.parametrize("case, msg", [
    ("missing_gt", "--gt .*nope.png: no such file"),
    ("size_mismatch", r"small.png: image shape \(10, 10, 3\) differs from reference shape \(24, 32, 3\)"),
    ("unreadable", "cannot read image .*broken.png"),
    ("unsupported", "unsupported type '.txt'"),
    ("missing_input", "cannot read image .*ghost.png: no such file or folder"),
    ("empty_folder", "holds no .png or .npy images"),
    ("only_gt", "no stimuli to compare"),
    ("bad_gaze", "--gaze='1;2' is invalid"),
    ("bad_fovea", r"--fovea-deg=95 is out of range: allowed \(0, 90\)"),
    ("bad_fov", r"--fov-y=0 is out of range"),
    ("pickled_npy", "cannot read image .*obj.npy"),
])
def test_cli_quality_bad_input_is_one_line_exit_2(tmp_path, stimuli, monkeypatch, capsys, case, msg):
    from PIL import Image

    folder, _, _ = stimuli
    gt = str(folder / "gt.png")
    opts = ["--fov-y", "90"]
    target = str(folder / "a_same.png")
    if case == "missing_gt":
        gt = str(tmp_path / "nope.png")
    elif case == "size_mismatch":
        Image.fromarray(np.zeros((10, 10, 3), np.uint8)).save(tmp_path / "small.png")
        target = str(tmp_path / "small.png")
    elif case == "unreadable":
        (tmp_path / "broken.png").write_bytes(b"\x89PNG not really")
        target = str(tmp_path / "broken.png")
    elif case == "unsupported":
        target = str(folder / "notes.txt")
    elif case == "missing_input":
        target = str(tmp_path / "ghost.png")
    elif case == "empty_folder":
        (tmp_path / "empty").mkdir()
        target = str(tmp_path / "empty")
    elif case == "only_gt":
        target = gt
    elif case == "bad_gaze":
        opts += ["--gaze", "1;2"]
    elif case == "bad_fovea":
        opts += ["--fovea-deg", "95"]
    elif case == "bad_fov":
        opts = ["--fov-y", "0"]
    elif case == "pickled_npy":
        np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
        target = str(tmp_path / "obj.npy")
    assert _main(monkeypatch, ["quality", "--gt", gt, *opts, target]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("studyapp: error: ")
    assert __import__("re").search(msg, err), err


def test_cli_quality_16bit_png_and_repeated_names(tmp_path, monkeypatch, capsys):
    from PIL import Image

    from studyapp.commands.quality import heatmap_names, load_image

    ref = np.full((9, 9), 1000, np.uint16)
    for sub in ("x", "y"):
        (tmp_path / sub).mkdir()
        Image.fromarray(ref + (100 if sub == "y" else 0)).save(tmp_path / sub / "s.png")
    Image.fromarray(ref).save(tmp_path / "gt.png")
    assert load_image(tmp_path / "gt.png").dtype == np.uint16
    names = heatmap_names([tmp_path / "x" / "s.png", tmp_path / "y" / "s.png"])
    assert names == ["heatmap_s.png", "heatmap_s_2.png"]
    argv = ["quality", "--gt", str(tmp_path / "gt.png"), "--fov-y", "90", "--json",
            "--out", str(tmp_path / "o"),
            str(tmp_path / "x"), str(tmp_path / "y")]
    assert _main(monkeypatch, argv) == 0
    records = json.loads(capsys.readouterr().out)
    assert records[5]["psnr"] == pytest.approx(10 * math.log10(65535 ** 2 / 100 ** 2), rel=1e-12)
    assert records[2]["psnr"] is None and "PSNR +inf" in records[2]["note"]
    assert (tmp_path / "o" / "heatmap_s.png").exists() and (tmp_path / "o" / "heatmap_s_2.png").exists()
