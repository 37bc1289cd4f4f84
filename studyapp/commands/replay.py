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
(display pixels mapped onto the render; binocular conditions: onto the eye the gaze falls on, whose image is
written). The CPU renderers are the reference (--backend cpu, the default). Nothing is trusted that can be
checked: every frame row is checked, scene files are read from the folder of the protocol the session ran
and must have the content hash the session recorded (a session recorded before scene hashes: built-in scenes
are replayed with a warning, scene files refused). Writes DIR/conditions/<condition>/frame_NNNNN.png (+ .npy,
linear), DIR/ground_truth/frame_NNNNN.png (the protocol's ground truth at the same pose and gaze),
DIR/gaze.csv and DIR/frames.csv; --quality also writes the foveal and peripheral error of every frame at its
gaze (DIR/quality.csv, the same as `studyapp quality --gt DIR/ground_truth --gaze-csv DIR/gaze.csv`). Every
image is one Dask task (a local cluster by default, --scheduler for a running one, --serial in this process)
through the stimulus cache (--cache): frames already rendered are not rendered again."""


def register(sub, parser_class) -> None:
    from data_schema.ranges import INT64_MAX, Range, argtype

    r = sub.add_parser("replay", help=HELP, description=DESCRIPTION)
    r.add_argument("--db", metavar="STUDY.db", required=True, help="study database")
    r.add_argument("--participant", metavar="ID", required=True)
    r.add_argument("--trial", type=argtype("--trial", Range(0, INT64_MAX, integer=True)), required=True,
                   metavar="N", help="trial index in the participant's schedule (the export's 'trial' column)")
    r.add_argument("--out", metavar="DIR", required=True, help="output folder (created; an earlier replay is "
                   "replaced)")
    r.add_argument("--backend", choices=("cpu", "gpu"), default="cpu", help="renderer backend (default: cpu, "
                   "the reference)")
    r.add_argument("--every", type=argtype("--every", Range(1, INT64_MAX, integer=True)), default=1, metavar="K",
                   help="re-render every K-th rendered frame (default: all)")
    r.add_argument("--quality", action="store_true", help="also score every frame against the ground truth at "
                   "its gaze (fovea and periphery)")
    r.add_argument("--cache", metavar="DIR", default="stimulus_cache",
                   help="stimulus cache of the re-rendered frames (default: ./stimulus_cache): a stopped replay "
                        "resumes, frames already rendered are copied")
    from studyapp.cluster import add_arguments

    add_arguments(r)
    r.set_defaults(func=cmd_replay)


#: Output folders: one per condition under CONDITIONS, the ground truth apart (no condition name reaches it).
CONDITIONS, GROUND_TRUTH = "conditions", "ground_truth"


def replay_frames(db: Path, participant: str, trial: int) -> tuple[object, object, list[dict]]:
    """(protocol, the planned trial, its rendered frames) of a logged live trial, its scene checked against the
    session's record (:func:`check_scene`); one-line errors."""
    from data_schema.store import open_store
    from studyapp.runner.protocol import protocol_from_data

    with open_store(db) as st:
        data = st.protocol_json()
        planned = {t.idx: t for t in st.planned(participant)}
        frames = st.frames(participant, trial)  # every row checked by the store
        meta = st.meta()
        session = st.response_session(participant, trial)
        record = st.session_scenes(session) if session is not None else None
    if data is None:
        raise CLIError(f"{db}: the study database is empty: nothing to replay")
    if not planned:
        raise CLIError(f"{db}: no participant {participant!r}")
    if trial not in planned:
        raise CLIError(f"{db}: participant {participant!r} has no trial {trial} (0..{max(planned)})")
    rendered = [f for f in frames if f["render_s"] is not None]
    if record is None and rendered:  # before the protocol is read: its scene files would be looked for here
        _unrecorded(db, planned[trial].scene, session)
    protocol = protocol_from_data(data, f"{db}#protocol", check_renderers=True,
                                  folder=record["folder"] if record else None)
    if protocol.content_hash != meta.get("protocol_hash"):
        raise CLIError(f"{db}: the recorded protocol does not match its hash: the database is damaged")
    if not protocol.live:
        raise CLIError(f"{db}: protocol {protocol.name!r} has no live stimuli: nothing to replay")
    t = planned[trial]
    unknown = [c for c in t.conditions if c not in protocol.conditions]
    scenes = set(protocol.scenes) | ({protocol.practice["scene"]} if protocol.practice else set())
    if unknown or t.scene not in scenes:
        what = f"condition {unknown[0]!r}" if unknown else f"scene {t.scene!r}"
        raise CLIError(f"{db}: participant {participant!r}, trial {trial}: {what} is not in the recorded protocol: "
                       "the database was not written by studyapp (restore its last good copy)")
    if not rendered:
        raise CLIError(f"{db}: trial {trial} of participant {participant!r} has no logged frames (not answered "
                       "yet, or not a live trial)")
    check_scene(db, protocol, t.scene, session, record)
    return protocol, t, rendered


def _unrecorded(db: Path, scene: str, session: str | None) -> None:
    """A session that recorded no scene hashes (an older studyapp) cannot be checked: a scene file (its folder
    unknown too) is refused; a built-in scene is replayed with a warning (:func:`check_scene`)."""
    from renderers.catalog import BUILTIN_SCENES

    if scene not in BUILTIN_SCENES:
        raise CLIError(f"{db}: session {session} recorded no scene hashes (an older studyapp): scene file "
                       f"{scene!r} cannot be checked against the one it rendered, so it is not replayed")


def check_scene(db: Path, protocol, scene: str, session: str | None, record: dict | None) -> None:
    """Refuse to replay ``scene`` unless it is the scene the session rendered: its content hash (a scene file
    read from the protocol folder the session recorded) must equal the one recorded at the session's start.
    Without a record (an older studyapp) a built-in scene is replayed with a warning on stderr."""
    import sys

    from studyapp.runner.live import scene_hash

    if record is None:
        print(f"studyapp: warning: {db}: session {session} recorded no scene hashes (an older studyapp): built-in "
              f"scene {scene!r} is replayed unchecked", file=sys.stderr)
        return
    ref = protocol.scene_ref(scene)
    recorded = record["scenes"].get(scene)
    if recorded is None:
        raise CLIError(f"{db}: session {session} recorded no hash of scene {scene!r}: it cannot be checked, so it "
                       "is not replayed")
    now = scene_hash(ref)
    if now != recorded:
        raise CLIError(f"{db}: scene {scene!r} ({ref}) is not the one session {session} rendered (sha256 "
                       f"{now[:12]}, recorded {recorded[:12]}): restore it to replay the trial")


def cmd_replay(args) -> int:
    import json
    import shutil

    from data_schema.atomic import atomic_dir, atomic_files, check_dir_target, write_text
    from data_schema.geometry import eye_at, eye_views
    from data_schema.names import inside
    from renderers.catalog import resolve
    from studyapp import cluster
    from studyapp.progress import Bar
    from studyapp.runner.live import Pose

    spec = cluster.from_args(args)
    db, out = Path(args.db), check_dir_target(args.out, marker="frames.csv")
    protocol, planned, frames = replay_frames(db, args.participant, args.trial)
    frames = frames[:: args.every]
    geometry = protocol.render_geometry()
    display = (protocol.display.width_px, protocol.display.height_px)  # the window the gaze was logged in
    gt = protocol.ground_truth
    scene_ref = protocol.scene_ref(planned.scene)
    scene_camera = resolve(scene_ref).camera
    # One task per image: the condition's frame and, at the same pose and gaze, the ground truth's.
    jobs, targets, rows, gaze_rows = [], [], [], []
    for f in frames:
        cond = protocol.conditions[planned.conditions[f["stimulus"]]]
        pose = Pose((f["pos_x"], f["pos_y"], f["pos_z"]), (f["look_x"], f["look_y"], f["look_z"]))
        label = f"trial {args.trial}, condition {cond.name}, scene {planned.scene}, frame {f['frame']}"
        try:
            scene_camera.override(pose.camera(protocol.display.fov_y_deg))
        except ValueError as exc:
            raise CLIError(f"{db}: participant {args.participant!r}, {label}: the logged camera cannot render: "
                           f"{exc}") from None
        eyes = cond.eyes
        views = eye_views(display, (geometry.width, geometry.height), eyes, protocol.display.stereo, cond.eye)
        # Binocular: the eye shown (a stereo display: the one the gaze falls on), as the live window maps it.
        view = views[0] if f["gaze_x"] is None else eye_at(views, f["gaze_x"], f["gaze_y"])
        gaze = None if f["gaze_x"] is None else view.to_render(f["gaze_x"], f["gaze_y"])
        params = dict(cond.params) if eyes == 1 else {**cond.params, "eye": view.eye}
        what = {"scene": scene_ref, "width": view.render_width, "height": view.render_height, "gaze": gaze,
                "camera": pose.camera(protocol.display.fov_y_deg)}
        name = f"frame_{f['frame']:05d}.png"
        file = inside(out, CONDITIONS, cond.name, name).relative_to(out).as_posix()
        jobs.append((label, {**what, "renderer": cond.renderer, "params": params, "backend": args.backend}))
        targets.append(file)
        if gt is not None:
            g = protocol.conditions[gt]
            jobs.append((f"{label} (ground truth {gt})", {**what, "renderer": g.renderer,
                                                          "params": _same_eye(g, eyes, view.eye)}))
            targets.append(inside(out, GROUND_TRUTH, name).relative_to(out).as_posix())
        rows.append([f["frame"], cond.name, view.eye, f["flip_s"], "" if gaze is None else gaze[0],
                     "" if gaze is None else gaze[1], *pose.position, *pose.look_at, None, file])
        if gaze is not None:
            gaze_rows.append([file, gaze[0], gaze[1]])
    render_s = {}
    bar = Bar("frames")
    with atomic_dir(out, marker="frames.csv") as tmp:
        def copy(i, png):
            dst = inside(tmp, targets[i])
            with atomic_files([dst.with_suffix(".npy"), dst]) as (t_npy, t_png):
                shutil.copyfile(png.with_suffix(".npy"), t_npy)
                shutil.copyfile(png, t_png)
            render_s[targets[i]] = json.loads(png.with_suffix(".json").read_text())["seconds"]["total"]

        cluster.render_frames(jobs, Path(args.cache), spec, copy, bar)
        bar.close()
        for r in rows:
            r[-2] = render_s[r[-1]]
        write_text(inside(tmp, "frames.csv"), _csv(["frame", "condition", "eye", "flip_s", "gaze_x", "gaze_y",
                                                    "pos_x", "pos_y", "pos_z", "look_x", "look_y", "look_z",
                                                    "render_s", "file"], rows))
        write_text(inside(tmp, "gaze.csv"), _csv(["file", "gaze_x", "gaze_y"], gaze_rows))
        if args.quality and gt is not None and gaze_rows:
            _quality(tmp, protocol.display.fov_y_deg, gaze_rows)
    print(f"replayed {len(frames)} frame(s) of trial {args.trial} of {args.participant} into {out} on "
          f"{spec.describe()}")
    return 0


def _same_eye(gt, eyes: int, eye: str) -> dict:
    """The ground truth's parameters for a frame of ``eyes`` eyes: for a binocular frame, the same eye's camera
    where its renderer renders stereo pairs (else its own camera)."""
    from renderers.registry import get

    params = dict(gt.params)
    if eyes == 2 and {"stereo", "eye"} <= set(get(gt.renderer).params):
        params.update(stereo="dup", eye=eye)
    return params


def _quality(folder: Path, fov_y: float, gaze_rows: list) -> None:
    from data_schema.atomic import write_text
    from data_schema.names import inside

    from .quality import load_image, quality_markdown, quality_table

    paths = [inside(folder, r[0]) for r in gaze_rows]
    gaze = {p: (r[1], r[2]) for p, r in zip(paths, gaze_rows)}
    table, _ = quality_table(paths, lambda p: load_image(inside(folder, GROUND_TRUTH, p.name)), fov_y=fov_y,
                             gaze=gaze, fovea_deg=5.0, data_range=None)
    table["image"] = table["image"].map(lambda s: Path(s).relative_to(folder).as_posix())
    write_text(inside(folder, "quality.csv"), table.to_csv(index=False, lineterminator="\n"))
    write_text(inside(folder, "quality.md"), quality_markdown(table, gt=f"{GROUND_TRUTH}/<frame>", fov_y=fov_y,
                                                              gaze=None, fovea_deg=5.0,
                                                              shape=load_image(paths[0]).shape))


def _csv(header, rows) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()
