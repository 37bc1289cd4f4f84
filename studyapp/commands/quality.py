"""``studyapp quality``: MSE, PSNR and SSIM of stimuli against ground truth, fovea vs periphery.

One row per image x region (fovea, periphery, all); see :func:`analysis.quality.image_quality`.
With ``--out DIR`` writes ``quality.csv``, ``quality.md`` and one ``heatmap_<name>.png`` per image.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from data_schema.errors import CLIError

IMAGE_SUFFIXES = (".png", ".npy")
#: Columns of the CLI's table: the image, then :data:`analysis.quality.QUALITY_COLUMNS`.
TABLE_COLUMNS = ("image", "region", "mse", "psnr", "ssim", "n_pixels", "n_ssim_pixels", "note")


def _data_range(text: str) -> float:
    """``--data-range``: checked against :data:`analysis.quality.DATA_RANGE` (imported only when given)."""
    from analysis.quality import DATA_RANGE
    from data_schema.ranges import argtype

    return argtype("--data-range", DATA_RANGE)(text)


def register(subparsers, parser_class) -> None:
    from data_schema.ranges import FOV_Y, Range, argtype

    q = subparsers.add_parser(
        "quality", help="MSE, PSNR and SSIM of stimuli against GT in the fovea and the periphery",
        description="Compare every stimulus (PNG or .npy) with the ground-truth image: MSE, PSNR and SSIM "
                    "(scikit-image) inside the fovea (eccentricity <= --fovea-deg from the gaze, seed 001 "
                    "Eq 3), in the periphery and over the whole image; one row per image x region. Values "
                    "are compared as stored (sRGB PNG pixels are compared as sRGB values).")
    q.add_argument("inputs", nargs="+", metavar="FOLDER_OR_FILE",
                   help="stimuli: PNG or .npy files, or folders (their *.png and *.npy, not recursive; the "
                        "GT itself is skipped)")
    q.add_argument("--gt", required=True, metavar="GT", help="ground-truth image (PNG or .npy)")
    q.add_argument("--fov-y", type=argtype("--fov-y", FOV_Y), required=True, metavar="DEG",
                   help="vertical field of view of the display in degrees, in (0, 180)")
    q.add_argument("--gaze", metavar="X,Y", default=None,
                   help="gaze point in pixels, x right, y down (default: the image centre); write "
                        "negative values as --gaze=-10,5")
    q.add_argument("--fovea-deg", type=argtype("--fovea-deg", Range(0.0, 90.0, low_open=True, high_open=True)),
                   default=5.0, metavar="DEG",
                   help="fovea radius in degrees of eccentricity, in (0, 90) (default: 5)")
    q.add_argument("--data-range", type=_data_range, default=None, metavar="L",
                   help="peak-to-peak value range for PSNR/SSIM, in [1e-6, 1e12] (default: 255 for 8-bit, "
                        "65535 for 16-bit, 1 for float .npy)")
    q.add_argument("--gaze-csv", metavar="FILE",
                   help="each image at its own gaze: a CSV file,gaze_x,gaze_y (files relative to the CSV); with "
                        "--gt DIR each image is compared with the same-named GT frame (studyapp replay writes both)")
    q.add_argument("--out", metavar="DIR",
                   help="write quality.csv, quality.md and heatmap_<name>.png per image into DIR")
    q.add_argument("--json", action="store_true",
                   help="print a JSON list of records (one per image x region) instead of Markdown")
    q.set_defaults(func=cmd_quality)


# --- input --------------------------------------------------------------------------------------------------
def parse_gaze(text: str | None) -> tuple[float, float] | None:
    """``"X,Y"`` -> ``(x, y)``; None stays None."""
    if text is None:
        return None
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        x, y = (float(p) for p in parts)
    except ValueError:
        raise CLIError(f"--gaze={text!r} is invalid: expected X,Y in pixels, e.g. 960,540") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise CLIError(f"--gaze={text!r} is invalid: both coordinates must be finite")
    return x, y


def load_image(path: Path):
    """Read a PNG (via Pillow) or a .npy array (no pickles), its size checked from the header before it is
    decoded (:mod:`data_schema.images`: at most 8192x8192 pixels, one line naming the limit).

    PNG modes: grey (``L``, 16-bit ``I;16``/``I``) stays 2-D; everything else becomes 8-bit RGB
    (an alpha channel is dropped, palettes are expanded).
    """
    import numpy as np

    from data_schema.atomic import input_file
    from data_schema.images import load_npy, open_image

    input_file(path, "image file", CLIError)  # a folder, a FIFO (it would block) or a device: one line
    if not path.exists():
        raise CLIError(f"cannot read image {path}: no such file")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        return load_npy(path)
    if suffix != ".png":
        raise CLIError(f"cannot read image {path}: unsupported type {path.suffix or '(none)'!r}, "
                       "use .png or .npy")
    with open_image(path, load=True) as im:
        if im.mode in ("I;16", "I;16B", "I;16L", "I"):
            a = np.asarray(im)
            if a.min() < 0 or a.max() > 65535:
                raise CLIError(f"cannot read image {path}: 32-bit integer values outside 0..65535")
            return a.astype(np.uint16)
        if im.mode in ("1", "L", "LA"):
            return np.asarray(im.convert("L"))
        return np.asarray(im.convert("RGB"))


def collect_inputs(inputs, gt: Path) -> list[Path]:
    """Expand folders to their sorted *.png / *.npy files; skip the GT; keep order, drop duplicates."""
    gt_resolved = gt.resolve()
    out: list[Path] = []
    seen: set[Path] = set()
    for item in inputs:
        p = Path(item)
        if p.is_dir():
            found = sorted(f for f in p.iterdir() if f.is_file() and f.suffix.lower() in IMAGE_SUFFIXES)
            if not found:
                raise CLIError(f"folder {p} holds no .png or .npy images")
        elif p.exists():
            if p.suffix.lower() not in IMAGE_SUFFIXES:
                raise CLIError(f"cannot read image {p}: unsupported type {p.suffix or '(none)'!r}, "
                               "use .png or .npy")
            found = [p]
        else:
            raise CLIError(f"cannot read image {p}: no such file or folder")
        for f in found:
            r = f.resolve()
            if r != gt_resolved and r not in seen:
                seen.add(r)
                out.append(f)
    if not out:
        raise CLIError("no stimuli to compare: the inputs hold only the GT image")
    return out


def heatmap_names(paths: list[Path]) -> list[str]:
    """``heatmap_<stem>.png`` per input, with ``_2``, ``_3`` ... appended to repeated stems (ignoring case, as
    macOS and Windows do: ``A.png`` and ``a.png`` get two files)."""
    from data_schema.names import name_key

    names, used = [], set()
    for p in paths:
        base = f"heatmap_{p.stem}"
        name, k = f"{base}.png", 1
        while name_key(name) in used:
            k += 1
            name = f"{base}_{k}.png"
        used.add(name_key(name))
        names.append(name)
    return names


# --- output -------------------------------------------------------------------------------------------------
def _fmt(value, spec: str) -> str:
    import pandas as pd

    if value is pd.NA or value is None:
        return "—"
    if math.isinf(value):
        return "∞"
    return format(value, spec)


def quality_markdown(table, *, gt: str, fov_y: float, gaze, fovea_deg: float, shape) -> str:
    """The table as Markdown with the parameters in a header."""
    h, w = shape[:2]
    gaze_txt = f"({gaze[0]:g}, {gaze[1]:g})" if gaze is not None else f"centre ({w / 2:g}, {h / 2:g})"
    lines = [
        "# Image quality against ground truth",
        "",
        (f"GT: `{gt}` ({w} x {h} px); vertical FOV {fov_y:g}°; gaze {gaze_txt} px; fovea: eccentricity "
        f"<= {fovea_deg:g}° (seed 001 Eq 3)."),
        ("MSE in the input's units squared; PSNR in dB (∞: identical); SSIM: scikit-image (7 x 7 window) "
        "averaged over the region away from the 3-px border; — : empty region (see note)."),
        "",
        "| image | region | MSE | PSNR (dB) | SSIM | pixels | note |",
        "|---|---|---:|---:|---:|---:|---|",
    ]
    for r in table.itertuples(index=False):
        lines.append(f"| {r.image} | {r.region} | {_fmt(r.mse, '.6g')} | {_fmt(r.psnr, '.2f')} | "
                     f"{_fmt(r.ssim, '.4f')} | {r.n_pixels} | {r.note} |")
    return "\n".join(lines) + "\n"


def quality_records(table) -> list[dict]:
    """JSON-safe records: ``<NA>`` -> null, ``+inf`` PSNR -> null (the note says "PSNR +inf")."""
    import pandas as pd

    records = []
    for row in table.to_dict(orient="records"):
        rec = {}
        for k, v in row.items():
            if v is pd.NA or (isinstance(v, float) and not math.isfinite(v)):
                v = None
            elif hasattr(v, "item"):
                v = v.item()
            rec[k] = v
        records.append(rec)
    return records


def quality_table(paths: list[Path], gt_image, *, fov_y: float, gaze, fovea_deg: float, data_range,
                  out: Path | None = None) -> tuple[object, list[Path]]:
    """Compute the table over ``paths``; write a heat map per image into ``out`` if given.

    ``gt_image`` is one image or a function of the path (each image its own GT: a replayed live trial);
    ``gaze`` is one point, None (the centre) or a dict path -> point (each image at its own gaze)."""
    import pandas as pd

    from analysis.quality import error_heatmap, image_quality
    from data_schema.names import inside

    frames, written = [], []
    names = heatmap_names(paths)
    gt_of = gt_image if callable(gt_image) else (lambda path: gt_image)
    per_image_gaze = isinstance(gaze, dict)
    gaze_of = gaze.get if per_image_gaze else (lambda path: gaze)
    for path, hm_name in zip(paths, names):
        img = load_image(path)
        gt_image, gaze = gt_of(path), gaze_of(path)
        try:
            q = image_quality(img, gt_image, fov_y_deg=fov_y, gaze=gaze, fovea_deg=fovea_deg,
                              data_range=data_range)
            if out is not None:
                written.append(error_heatmap(img, gt_image, inside(out, hm_name), fov_y_deg=fov_y, gaze=gaze,
                                             fovea_deg=fovea_deg, title=f"squared error: {path.name}"))
        except ValueError as exc:
            raise CLIError(f"{path}: {exc}") from None
        q.insert(0, "image", str(path))
        if per_image_gaze:
            q.insert(1, "gaze_x", gaze_of(path)[0])
            q.insert(2, "gaze_y", gaze_of(path)[1])
        frames.append(q)
    return pd.concat(frames, ignore_index=True), written


def _report(table, md: str, written: list[Path], out: Path | None, as_json: bool) -> int:
    """Write ``quality.csv`` and ``quality.md`` into ``out`` (with the heat maps already ``written`` there), then
    print the JSON records, the files written, or the Markdown table."""
    from data_schema.atomic import write_text

    if out is not None:
        written = [write_text(out / "quality.csv", table.to_csv(index=False, lineterminator="\n")),
                   write_text(out / "quality.md", md)] + written
    if as_json:
        print(json.dumps(quality_records(table), indent=2))
    elif out is not None:
        for p in written:
            print(p)
    else:
        print(md, end="")
    return 0


def cmd_quality(args) -> int:
    if args.out:
        from data_schema.atomic import real_folder

        real_folder(args.out, "--out")  # /dev/null, a FIFO, a file: refused before any image is read
    gaze = parse_gaze(args.gaze)
    gt_path = Path(args.gt)
    if not gt_path.exists():
        raise CLIError(f"--gt {gt_path}: no such file")
    if gt_path.is_dir() or args.gaze_csv:  # a replayed live trial: each frame its own GT and gaze
        return _quality_along_gaze(args, gt_path)
    gt_image = load_image(gt_path)
    if gaze is not None:
        from data_schema.geometry import check_gaze

        h, w = gt_image.shape[:2]
        try:
            gaze = check_gaze(gaze, w, h)
        except ValueError as exc:
            raise CLIError(f"--gaze: {exc}") from None
    paths = collect_inputs(args.inputs, gt_path)
    out = Path(args.out) if args.out else None
    table, written = quality_table(paths, gt_image, fov_y=args.fov_y, gaze=gaze, fovea_deg=args.fovea_deg,
                                   data_range=args.data_range, out=out)
    md = quality_markdown(table, gt=str(gt_path), fov_y=args.fov_y, gaze=gaze, fovea_deg=args.fovea_deg,
                          shape=gt_image.shape)
    return _report(table, md, written, out, args.json)


def read_gaze_csv(path: Path, folder: Path) -> dict[Path, tuple[float, float]]:
    """``file,gaze_x,gaze_y`` rows (files relative to ``folder``) -> {path: (x, y)}."""
    import csv

    from data_schema.atomic import input_file

    input_file(path, "gaze CSV file")
    try:
        with open(path, encoding="utf-8", newline="") as fh:
            rows = list(csv.DictReader(fh))
    except OSError as exc:
        raise CLIError(f"--gaze-csv {path}: {exc.strerror or exc}") from None
    out = {}
    for i, r in enumerate(rows, start=2):
        try:
            out[(folder / r["file"]).resolve()] = (float(r["gaze_x"]), float(r["gaze_y"]))
        except (KeyError, TypeError, ValueError):
            raise CLIError(f"--gaze-csv {path}:{i}: needs columns file, gaze_x, gaze_y with numbers") from None
    return out


def _quality_along_gaze(args, gt_dir: Path) -> int:
    """Each input frame against the same-named frame of ``--gt DIR`` at its own gaze (``--gaze-csv``): the
    foveal and peripheral error along a participant's actual gaze (``studyapp replay`` writes both)."""
    from data_schema.geometry import check_gaze

    if not gt_dir.is_dir():
        raise CLIError(f"--gt {gt_dir}: with --gaze-csv, give the folder of the ground-truth frames")
    if not args.gaze_csv:
        raise CLIError(f"--gt {gt_dir} is a folder: give --gaze-csv FILE with each frame's gaze")
    gazes = read_gaze_csv(Path(args.gaze_csv), Path(args.gaze_csv).resolve().parent)
    # the images the CSV gives a gaze for (a replay folder also holds each frame's linear .npy)
    paths = [p for p in collect_inputs(args.inputs, gt_dir / ".none") if p.resolve() in gazes]
    if not paths:
        raise CLIError(f"--gaze-csv {args.gaze_csv}: gives no gaze for any of the images")
    gaze_of, gt_cache = {}, {}
    for p in paths:
        gt_file = gt_dir / p.name
        if not gt_file.is_file():
            raise CLIError(f"--gt {gt_dir}: no ground-truth frame {p.name}")
        gt_cache[p] = load_image(gt_file)
        h, w = gt_cache[p].shape[:2]
        try:
            gaze_of[p] = check_gaze(gazes[p.resolve()], w, h)
        except ValueError as exc:
            raise CLIError(f"--gaze-csv {args.gaze_csv}: {p.name}: {exc}") from None
    out = Path(args.out) if args.out else None
    table, written = quality_table(paths, gt_cache.__getitem__, fov_y=args.fov_y, gaze=gaze_of,
                                   fovea_deg=args.fovea_deg, data_range=args.data_range, out=out)
    md = quality_markdown(table, gt=f"{gt_dir}/<frame>", fov_y=args.fov_y, gaze=None, fovea_deg=args.fovea_deg,
                          shape=next(iter(gt_cache.values())).shape).replace(
        "gaze centre", "gaze of each frame (--gaze-csv), centre")
    return _report(table, md, written, out, args.json)
