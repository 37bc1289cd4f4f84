"""Fuzzing the stimulus cache and the image readers (issue 25 items 7 and 9): damaged entries, huge headers.

Cache entries of a tiny protocol are damaged at random (a file truncated, bytes flipped, NaN in the linear image,
a wrong shape or dtype, another entry's PNG or record swapped in, a ``.npy`` header claiming a huge shape, a
file removed); ``prepare --serial`` must report every damaged entry in one stderr line, render it again and end
with a stimulus set byte-identical to an undamaged run (so nothing damaged was copied), and leave a sound cache.
The renders are a deterministic stand-in for ``renderers.registry.render`` so that the examples stay fast; the
cache (keys, entries, verification, copying) is the real one. Image and array headers claiming any size are
refused from the header, in one line naming the limit, without allocating the image. Bounded to about 15 s.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import re
import shutil
import struct
import tempfile
import tracemalloc
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from data_schema.errors import UserError
from data_schema.images import MAX_IMAGE_PIXELS, ImageTooLarge, load_npy, open_image, read_npy_header
from test_runner_prepare import TINY  # two conditions, one scene, two frames at 64 x 36

LIMIT = "over the limit of 8192x8192 (67 M pixels) for an image"


def fake_render(scene, renderer, params, width, height, gaze=None, camera=None, backend="cpu"):
    """A deterministic image per frame (its arguments seed it), as fast as a lookup."""
    seed = hashlib.sha256(repr((renderer, sorted(params.items()), camera, tuple(gaze))).encode()).digest()
    img = np.random.default_rng(int.from_bytes(seed[:8], "little")).random((height, width, 3), dtype=np.float32)
    return img, {"seconds": {"total": 0.0}, "shading_points": width * height}


@contextlib.contextmanager
def fast_renders():
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("renderers.registry.render", fake_render)
        yield


def run_prepare(protocol: Path, root: Path, cache: Path) -> tuple[int, str]:
    """``studyapp prepare --serial`` into ``root`` with ``cache``: (exit status, stderr)."""
    from studyapp.cli import main

    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        code = main(["prepare", str(protocol), "--stimuli", str(root), "--cache", str(cache), "--serial"])
    return code, err.getvalue()


def tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.name.startswith(".")}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The tiny protocol, its undamaged stimulus set and cache (4 entries: 2 conditions x 2 frames)."""
    d = tmp_path_factory.mktemp("ref")
    (d / "tiny.yaml").write_text(TINY)
    with fast_renders():
        code, err = run_prepare(d / "tiny.yaml", d / "stim", d / "cache")
    assert code == 0, err
    entries = sorted((d / "cache").glob("??/*.png"))
    assert len(entries) == 4 and len(tree(d / "stim")) == 4
    return Reference(d, tree(d / "stim"), tree(d / "cache"), [e.relative_to(d / "cache") for e in entries])


class Reference(tuple):
    """(folder, stimulus set, cache, entries): named briefly in hypothesis' reports (not by its bytes)."""

    def __new__(cls, *items):
        return super().__new__(cls, items)

    def __repr__(self) -> str:
        return f"Reference({self[0]})"


def _flip(data: bytes, at: int) -> bytes:
    b = bytearray(data)
    b[at % len(b)] ^= 0xFF  # any byte of a PNG, an .npy header or its data: the entry no longer checks
    return bytes(b)


def damage(png: Path, kind: str, where: int, other: Path) -> None:
    """Damage the cache entry of ``png`` in one of the ways ``KINDS`` names (``where`` picks a byte; ``other`` is
    another entry's PNG, undamaged, for the swaps)."""
    npy, meta = png.with_suffix(".npy"), png.with_suffix(".json")
    if kind == "truncate_png":
        png.write_bytes(png.read_bytes()[: where % png.stat().st_size])
    elif kind == "truncate_npy":
        npy.write_bytes(npy.read_bytes()[: where % npy.stat().st_size])
    elif kind == "truncate_json":  # any cut short of the closing brace leaves no JSON
        meta.write_bytes(meta.read_bytes()[: where % (meta.stat().st_size - 1)])
    elif kind == "flip_png":
        png.write_bytes(_flip(png.read_bytes(), where))
    elif kind == "flip_npy":
        npy.write_bytes(_flip(npy.read_bytes(), where))
    elif kind == "nan":
        a = np.load(npy)
        a.reshape(-1)[where % a.size] = np.nan
        np.save(npy, a)
    elif kind == "wrong_shape":
        a = np.load(npy)
        np.save(npy, a[:-1])
    elif kind == "wrong_dtype":
        np.save(npy, np.load(npy).astype(np.float64))
    elif kind == "swap_png":
        shutil.copyfile(other, png)
    elif kind == "swap_json":
        shutil.copyfile(other.with_suffix(".json"), meta)
    elif kind == "huge_npy_header":
        with open(npy, "wb") as fh:
            np.lib.format.write_array_header_1_0(
                fh, {"descr": "<f4", "fortran_order": False, "shape": (100_000, 100_000, 3)})
    elif kind in ("remove_npy", "remove_json"):
        (npy if kind == "remove_npy" else meta).unlink()
    else:
        raise AssertionError(kind)


KINDS = ("truncate_png", "truncate_npy", "truncate_json", "flip_png", "flip_npy", "nan", "wrong_shape",
         "wrong_dtype", "swap_png", "swap_json", "huge_npy_header", "remove_npy", "remove_json")


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_prepare_renders_damaged_entries_again_and_copies_none(reference, data):
    ref_dir, ref_stim, ref_cache, entries = reference
    plans = [(e, data.draw(st.sampled_from(KINDS)), data.draw(st.integers(0, 1 << 20)))
             for e in data.draw(st.lists(st.sampled_from(entries), min_size=1, max_size=4, unique=True))]
    with tempfile.TemporaryDirectory() as tmp, fast_renders():
        tmp = Path(tmp)
        cache = tmp / "cache"
        shutil.copytree(ref_dir / "cache", cache)
        for e, kind, where in plans:
            damage(cache / e, kind, where, ref_dir / "cache" / next(x for x in entries if x != e))
        code, err = run_prepare(ref_dir / "tiny.yaml", tmp / "stim", cache)
        assert code == 0, err
        reports = [ln for ln in err.splitlines() if ln.startswith("cache: ")]
        assert all(ln.startswith("cache: re-rendering 1 damaged entry: ") for ln in reports), err
        assert sorted(ln.split(": ")[2] for ln in reports) == sorted(str(cache / e) for e, _, _ in plans), err
        assert tree(tmp / "stim") == ref_stim  # byte-identical: nothing damaged was copied
        assert tree(cache) == ref_cache  # every damaged entry rendered again, the same bytes


def test_every_kind_of_damage_is_named(reference):
    """Each kind of damage is found by the check that names it (the cheapest first: nothing huge is read)."""
    from renderers.stimuli import check_entry

    ref_dir, _, _, entries = reference
    expected = {"truncate_png": ".png: ", "truncate_npy": ".npy: truncated", "truncate_json": ".json: not readable",
                "flip_png": ".png: ", "flip_npy": ".npy: ", "nan": ".npy: 1 NaN or infinite value(s)",
                "wrong_shape": ".npy: shape (35, 64, 3), expected (36, 64, 3)",
                "wrong_dtype": ".npy: dtype float64, expected float32",
                "swap_png": ".png: its bytes differ from those recorded (damaged or replaced)",
                "swap_json": ".json: not this entry's record",
                "huge_npy_header": f".npy: 100000x100000 pixels is {LIMIT}",
                "remove_npy": ".npy: no such file or directory", "remove_json": ".json: missing"}
    with tempfile.TemporaryDirectory() as tmp:
        for kind in KINDS:
            cache = Path(tmp) / kind
            shutil.copytree(ref_dir / "cache", cache)
            png = cache / entries[0]
            assert check_entry(png, (36, 64, 3)) is None
            damage(png, kind, 5000, ref_dir / "cache" / entries[1])
            tracemalloc.start()
            why = check_entry(png, (36, 64, 3))
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            assert why is not None and why.startswith(expected[kind]), (kind, why)
            assert peak < 2_000_000, (kind, peak)  # the huge header allocated nothing
    # a sound entry asked for at another size is not this frame's
    assert check_entry(ref_dir / "cache" / entries[0], (36, 65, 3)).startswith(".json: records a float32 image")


def test_a_cluster_prepare_checks_the_entries_it_will_take(reference, tmp_path):
    """On a cluster, render_frames takes an entry that is there only after check_entry passed it: the damaged
    one is reported, removed and rendered again (one task: a local cluster of one runs it in this process)."""
    from studyapp import cluster
    from studyapp.runner.protocol import load_protocol
    from studyapp.runner.stimuli import prepare

    ref_dir, ref_stim, _, entries = reference
    cache = tmp_path / "cache"
    shutil.copytree(ref_dir / "cache", cache)
    damage(cache / entries[2], "nan", 3, ref_dir / "cache" / entries[0])
    p = load_protocol(ref_dir / "tiny.yaml", stimuli_dir=tmp_path / "stim")
    err = io.StringIO()
    with fast_renders(), contextlib.redirect_stderr(err):
        res = prepare(p, cache_dir=cache, cluster=cluster.ClusterSpec(workers=2))
    assert err.getvalue() == (f"cache: re-rendering 1 damaged entry: {cache / entries[2]}: .npy: 1 NaN or "
                              "infinite value(s)\n")
    assert res["rendered"] == 1
    assert tree(tmp_path / "stim") == ref_stim
    assert (cache / entries[2]).with_suffix(".npy").read_bytes() == \
        (ref_dir / "cache" / entries[2]).with_suffix(".npy").read_bytes()

def test_a_nan_ground_truth_is_rendered_again_before_it_is_tabulated(tmp_path, capsys):
    """``lightcuts tables`` reads its GT from the cache: a damaged one is rendered again (the real sl_gt)."""
    from renderers.lightcuts.tables import gt_frame
    from renderers.stimuli import entry_image, render_stimulus

    request = gt_frame("study", 24, 16, gt_lspp=4, gt_rspp=4)
    png = render_stimulus(**request, cache_dir=tmp_path)
    gt = entry_image(png, (16, 24, 3))
    assert np.isfinite(gt).all() and gt.max() > 0
    a = np.load(png.with_suffix(".npy"))
    a[:] = np.nan
    np.save(png.with_suffix(".npy"), a)
    capsys.readouterr()
    again = render_stimulus(**request, cache_dir=tmp_path)
    assert again == png
    np.testing.assert_array_equal(entry_image(again, (16, 24, 3)), gt)
    assert capsys.readouterr().err == (f"cache: re-rendering 1 damaged entry: {png}: .npy: 1152 NaN or infinite "
                                       "value(s)\n")


# -- image and array headers of any size ---------------------------------------------------------------------
def png_header(width: int, height: int) -> bytes:
    """A PNG that is only a header (IHDR, then IEND): Pillow reads its size, there is nothing to decode."""
    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
            + chunk(b"IEND", b""))


SIDES = st.one_of(st.integers(1, 20_000), st.integers(1, 2 ** 31 - 1), st.sampled_from([8192, 8193, 13000]))


@settings(max_examples=60, deadline=None)
@given(width=SIDES, height=SIDES, channels=st.sampled_from([None, 1, 3, 4]),
       dtype=st.sampled_from(["<f4", "<f8", "|u1", "<u2"]))
@example(width=13000, height=13000, channels=3, dtype="<f4")
@example(width=8192, height=8192, channels=3, dtype="|u1")
def test_headers_of_any_size_are_checked_before_decoding(width, height, channels, dtype):
    over = width * height > MAX_IMAGE_PIXELS
    with tempfile.TemporaryDirectory() as tmp:
        png, npy = Path(tmp) / "big.png", Path(tmp) / "big.npy"
        png.write_bytes(png_header(width, height))
        shape = (height, width) if channels is None else (height, width, channels)
        with open(npy, "wb") as fh:
            np.lib.format.write_array_header_2_0(fh, {"descr": dtype, "fortran_order": False, "shape": shape})
        tracemalloc.start()
        try:
            for path, read in ((png, lambda: open_image(png, load=True).__enter__()), (npy, lambda: load_npy(npy))):
                with pytest.raises(UserError) as exc:
                    read()
                msg = str(exc.value)
                if over:
                    assert isinstance(exc.value, ImageTooLarge) and msg == f"{path}: {width}x{height} pixels is {LIMIT}"
                else:  # within the limit: refused only because the file holds no pixel data
                    assert msg.startswith(f"cannot read image {path}: ") and "\n" not in msg, msg
            assert tracemalloc.get_traced_memory()[1] < 2_000_000
        finally:
            tracemalloc.stop()
    if not over:
        with tempfile.TemporaryDirectory() as tmp:  # the header alone is accepted
            npy = Path(tmp) / "h.npy"
            with open(npy, "wb") as fh:
                np.lib.format.write_array_header_1_0(fh, {"descr": dtype, "fortran_order": False, "shape": shape})
            with pytest.raises(UserError, match="truncated: holds 0 bytes of data"):
                read_npy_header(npy)


@pytest.mark.parametrize("header, message", [
    ({"descr": "|O", "fortran_order": False, "shape": (2, 2)}, "dtype object is not an image's"),
    ({"descr": "<c16", "fortran_order": False, "shape": (2, 2)}, "dtype complex128 is not an image's"),
    ({"descr": "<f4", "fortran_order": False, "shape": (2, 2, 5)}, r"shape \(2, 2, 5\) is not an image's"),
    ({"descr": "<f4", "fortran_order": False, "shape": (7,)}, r"shape \(7,\) is not an image's"),
    ({"descr": "<f4", "fortran_order": False, "shape": (0, 4)}, r"shape \(0, 4\) is not an image's"),
])
def test_npy_headers_that_are_no_image_are_refused(tmp_path, header, message):
    npy = tmp_path / "x.npy"
    with open(npy, "wb") as fh:
        np.lib.format.write_array_header_1_0(fh, header)
        fh.write(b"\0" * 64)
    with pytest.raises(UserError, match=f"cannot read image {npy}: {message}"):
        load_npy(npy)


def test_quality_refuses_a_13000_pixel_square_png_in_one_line(tmp_path):
    """The issue's case: `studyapp quality` on a 13000x13000 PNG took > 2.8 GB, then a MemoryError traceback. Now
    one line, exit 2, and the process's peak memory (VmHWM: this process image's own, not the forked parent's)
    is the imports' (13000 x 13000 x 3 bytes would be 507 MB)."""
    import os
    import subprocess
    import sys

    from PIL import Image

    root = Path(__file__).resolve().parents[1]
    big = tmp_path / "big.png"
    big.write_bytes(png_header(13000, 13000))
    Image.new("RGB", (16, 16)).save(tmp_path / "gt.png")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")])}
    code = ("import sys\nfrom studyapp.cli import main\nrc = main(sys.argv[1:])\n"
            "print([ln.split()[1] for ln in open('/proc/self/status') if ln.startswith('VmHWM:')][0])\n"
            "sys.exit(rc)")
    for gt, image in ((big, tmp_path / "gt.png"), (tmp_path / "gt.png", big)):
        p = subprocess.run([sys.executable, "-c", code, "quality", "--gt", str(gt), "--fov-y", "90", str(image)],
                           capture_output=True, text=True, env=env, timeout=120)
        assert p.returncode == 2 and p.stderr == f"studyapp: error: {big}: 13000x13000 pixels is {LIMIT}\n"
        assert int(p.stdout) < 300_000, p.stdout  # kB


def test_a_damaged_or_huge_stimulus_frame_is_one_line(tmp_path):
    """Stimulus frames (the simulated observer's and the presenter's readers) go through the same check."""
    from studyapp.presentation.base import PresentationError
    from studyapp.presentation.psychopy_window import decode_image
    from studyapp.runner.images import load_gray

    f = tmp_path / "frame.png"
    f.write_bytes(png_header(64, 36))  # a header, no pixels
    with pytest.raises(UserError, match=f"^cannot read image {re.escape(str(f))}: "):
        load_gray(f)
    with pytest.raises(PresentationError, match=f"^cannot read stimulus frame {re.escape(str(f))}: "):
        decode_image(f)
    f.write_bytes(png_header(9000, 9000))
    with pytest.raises(ImageTooLarge, match=f"^{re.escape(f'{f}: 9000x9000 pixels is {LIMIT}')}$"):
        load_gray(f)
    with pytest.raises(PresentationError, match=f"^{re.escape(f'{f}: 9000x9000 pixels is {LIMIT}')}$"):
        decode_image(f)


def test_the_cache_record_is_what_check_entry_compares(reference):
    ref_dir, _, _, entries = reference
    png = ref_dir / "cache" / entries[0]
    rec = json.loads(png.with_suffix(".json").read_text())["cache_entry"]
    assert rec["shape"] == [36, 64, 3] and rec["dtype"] == "float32"
    assert rec["png_sha256"] == hashlib.sha256(png.read_bytes()).hexdigest()
    assert rec["npy_sha256"] == hashlib.sha256(np.load(png.with_suffix(".npy")).tobytes()).hexdigest()
    with open_image(png) as im:
        assert im.size == (64, 36)


def test_a_fifo_in_an_entry_is_damage_not_a_hang(reference, tmp_path):
    import os

    from renderers.stimuli import check_entry

    ref_dir, _, _, entries = reference
    cache = tmp_path / "cache"
    shutil.copytree(ref_dir / "cache", cache)
    for suffix in (".json", ".npy"):
        f = (cache / entries[0]).with_suffix(suffix)
        saved = f.read_bytes()
        f.unlink()
        os.mkfifo(f)
        assert check_entry(cache / entries[0], (36, 64, 3)) == f"{suffix}: not a regular file"
        f.unlink()
        f.write_bytes(saved)
    assert check_entry(cache / entries[0], (36, 64, 3)) is None
