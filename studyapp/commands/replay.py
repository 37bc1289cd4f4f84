"""``studyapp replay``: re-render a logged live trial frame by frame from its camera poses and gaze trace."""

from __future__ import annotations

import csv
import io
from pathlib import Path

from data_schema.errors import CLIError

HELP = "re-render a logged live trial frame by frame (its camera poses and gaze), with the ground truth"
DESCRIPTION = """\
Re-render a live trial of a study database from its frame log: every frame rendered during the trial, with
the renderer and parameters of the condition shown, at the logged camera pose, foveated at the logged gaze
(display pixels mapped onto the render). The CPU renderers are the reference (--backend cpu, the default).
Writes DIR/<condition>/frame_NNNNN.png (+ .npy, linear), DIR/gt/frame_NNNNN.png (the protocol's ground truth
at the same pose), DIR/gaze.csv and DIR/frames.csv; --quality also writes the foveal and peripheral error of
every frame at its gaze (DIR/quality.csv, the same as `studyapp quality --gt DIR/gt --gaze-csv DIR/gaze.csv`).
Every image is one Dask task (a local cluster by default, --scheduler for a running one, --serial in this
process) through the stimulus cache (--cache): frames already rendered are not rendered again."""


def register(sub, parser_class) -> None:
    from data_schema.ranges import Range, argtype

    r = sub.add_parser("replay", help=HELP, description=DESCRIPTION)
    r.add_argument("--db", metavar="STUDY.db", required=True, help="study database")
    r.add_argument("--participant", metavar="ID", required=True)
    r.add_argument("--trial", type=argtype("--trial", Range(0, None, integer=True)), required=True, metavar="N",
                   help="trial index in the participant's schedule (the export's 'trial' column)")
    r.add_argument("--out", metavar="DIR", required=True, help="output folder (created; an earlier replay is "
                   "replaced)")
    r.add_argument("--backend", choices=("cpu", "gpu"), default="cpu", help="renderer backend (default: cpu, "
                   "the reference)")
    r.add_argument("--every", type=argtype("--every", Range(1, None, integer=True)), default=1, metavar="K",
                   help="re-render every K-th rendered frame (default: all)")
    r.add_argument("--quality", action="store_true", help="also score every frame against the ground truth at "
                   "its gaze (fovea and periphery)")
    r.add_argument("--cache", metavar="DIR", default="stimulus_cache",
                   help="stimulus cache of the re-rendered frames (default: ./stimulus_cache): a stopped replay "
                        "resumes, frames already rendered are copied")
    from studyapp.cluster import add_arguments

    add_arguments(r)
    r.set_defaults(func=cmd_replay)


def replay_frames(db: Path, participant: str, trial: int) -> tuple[object, object, list[dict]]:
    """(protocol, the planned trial, its rendered frames) of a logged live trial; one-line errors."""
    from data_schema.store import open_store
    from studyapp.runner.protocol import protocol_from_data

    with open_store(db) as st:
        data = st.protocol_json()
        planned = {t.idx: t for t in st.planned(participant)}
        frames = st.frames(participant, trial)
        meta = st.meta()
    if not planned:
        raise CLIError(f"{db}: no participant {participant!r}")
    if trial not in planned:
        raise CLIError(f"{db}: participant {participant!r} has no trial {trial} (0..{max(planned)})")
    protocol = protocol_from_data(data, f"{db}#protocol", check_renderers=True)
    if protocol.content_hash != meta.get("protocol_hash"):
        raise CLIError(f"{db}: the recorded protocol does not match its hash: the database is damaged")
    if not protocol.live:
        raise CLIError(f"{db}: protocol {protocol.name!r} has no live stimuli: nothing to replay")
    rendered = [f for f in frames if f["render_s"] is not None]
    if not rendered:
        raise CLIError(f"{db}: trial {trial} of participant {participant!r} has no logged frames (not answered "
                       "yet, or not a live trial)")
    return protocol, planned[trial], rendered


def cmd_replay(args) -> int:
    import json
    import shutil

    from data_schema.atomic import atomic_dir, atomic_files, check_dir_target, write_text
    from studyapp import cluster
    from studyapp.progress import Bar
    from studyapp.runner.live import Pose

    spec = cluster.from_args(args)
    db, out = Path(args.db), check_dir_target(args.out, marker="frames.csv")
    protocol, planned, frames = replay_frames(db, args.participant, args.trial)
    frames = frames[:: args.every]
    geometry = protocol.render_geometry()
    sx = geometry.width / protocol.display.width_px  # logged gaze: display pixels -> render pixels
    gt = protocol.ground_truth
    # One task per image: the condition's frame and, at the same pose and gaze, the ground truth's.
    jobs, targets, rows, gaze_rows = [], [], [], []
    for f in frames:
        cond = protocol.conditions[planned.conditions[f["stimulus"]]]
        pose = Pose((f["pos_x"], f["pos_y"], f["pos_z"]), (f["look_x"], f["look_y"], f["look_z"]))
        gaze = None if f["gaze_x"] is None else (min(geometry.width, max(0.0, f["gaze_x"] * sx)),
                                                min(geometry.height, max(0.0, f["gaze_y"] * sx)))
        what = {"scene": protocol.scene_ref(planned.scene), "width": geometry.width, "height": geometry.height,
                "gaze": gaze, "camera": pose.camera(protocol.display.fov_y_deg)}
        name = f"frame_{f['frame']:05d}.png"
        label = f"trial {args.trial}, condition {cond.name}, scene {planned.scene}, frame {f['frame']}"
        jobs.append((label, {**what, "renderer": cond.renderer, "params": cond.params, "backend": args.backend}))
        targets.append(f"{cond.name}/{name}")
        if gt is not None:
            g = protocol.conditions[gt]
            jobs.append((f"{label} (ground truth {gt})", {**what, "renderer": g.renderer, "params": g.params}))
            targets.append(f"gt/{name}")
        rows.append([f["frame"], cond.name, f["flip_s"], "" if gaze is None else gaze[0],
                     "" if gaze is None else gaze[1], *pose.position, *pose.look_at, None, f"{cond.name}/{name}"])
        if gaze is not None:
            gaze_rows.append([f"{cond.name}/{name}", gaze[0], gaze[1]])
    render_s = {}
    bar = Bar("frames")
    with atomic_dir(out, marker="frames.csv") as tmp:
        def copy(i, png):
            dst = tmp / targets[i]
            with atomic_files([dst.with_suffix(".npy"), dst]) as (t_npy, t_png):
                shutil.copyfile(png.with_suffix(".npy"), t_npy)
                shutil.copyfile(png, t_png)
            render_s[targets[i]] = json.loads(png.with_suffix(".json").read_text())["seconds"]["total"]

        cluster.render_frames(jobs, Path(args.cache), spec, copy, bar)
        bar.close()
        for r in rows:
            r[-2] = render_s[r[-1]]
        write_text(tmp / "frames.csv", _csv(["frame", "condition", "flip_s", "gaze_x", "gaze_y", "pos_x", "pos_y",
                                             "pos_z", "look_x", "look_y", "look_z", "render_s", "file"], rows))
        write_text(tmp / "gaze.csv", _csv(["file", "gaze_x", "gaze_y"], gaze_rows))
        if args.quality and gt is not None:
            _quality(tmp, protocol.display.fov_y_deg, gaze_rows)
    print(f"replayed {len(frames)} frame(s) of trial {args.trial} of {args.participant} into {out} on "
          f"{spec.describe()}")
    return 0


def _quality(folder: Path, fov_y: float, gaze_rows: list) -> None:
    from data_schema.atomic import write_text

    from .quality import load_image, quality_markdown, quality_table

    paths = [folder / r[0] for r in gaze_rows]
    gaze = {p: (r[1], r[2]) for p, r in zip(paths, gaze_rows)}
    table, _ = quality_table(paths, lambda p: load_image(folder / "gt" / p.name), fov_y=fov_y, gaze=gaze,
                             fovea_deg=5.0, data_range=None)
    table["image"] = table["image"].map(lambda s: str(Path(s).relative_to(folder)))
    write_text(folder / "quality.csv", table.to_csv(index=False, lineterminator="\n"))
    write_text(folder / "quality.md", quality_markdown(table, gt="gt/<frame>", fov_y=fov_y, gaze=None,
                                                       fovea_deg=5.0, shape=load_image(paths[0]).shape))


def _csv(header, rows) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()
