"""``studyapp replay``: re-render a logged live trial frame by frame from its camera poses and gaze trace."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

from data_schema.errors import CLIError

HELP = "re-render a logged live trial frame by frame (its camera poses and gaze), with the ground truth"
DESCRIPTION = """\
Re-render a live trial of a study database from its frame log as the session showed it: every frame rendered
during the trial, the attempts that Escape interrupted included, with the renderer and parameters of the
condition shown, at the logged camera pose, foveated at the logged gaze, at the session's render size (its
--scale), in the session's eye layout (one eye over the window, or both side by side on a stereo display) and
on each condition's backend as the session recorded them (--backend overrides). Nothing is trusted that can be
checked: every frame row is checked, scene files are read from the folder of the protocol the session ran and
must have the content hash the session recorded (a session recorded before scene hashes: built-in scenes are
replayed with a warning, scene files refused). Writes DIR/conditions/<condition>/<frame>.png (+ .npy, linear:
the eye the gaze fell on, at its render size), DIR/ground_truth/<frame>.png (the protocol's ground truth at
the same pose, gaze and size), DIR/shown/<frame>.png (the whole window as it showed the frame), DIR/frames.csv
(one row per replayed frame: attempt, interrupted, session, backend, files), DIR/flips.csv (every logged flip
and the image it showed) and DIR/gaze.csv; <frame> is frame_NNNNN for the answered attempt and
interruptedK_frame_NNNNN for the K-th attempt Escape ended. A session of an older studyapp that recorded no
window layout is replayed as before (the protocol's render size without --scale, this studyapp's eye layout,
the CPU backend, no shown/) with a one-line note. --quality also writes the foveal and peripheral error of
every frame at its gaze (DIR/quality.csv, the same as `studyapp quality --gt DIR/ground_truth --gaze-csv
DIR/gaze.csv`). Every image is one Dask task (a local cluster by default, --scheduler for a running one,
--serial in this process) through the stimulus cache (--cache): frames already rendered are not rendered
again."""


def register(sub, parser_class) -> None:
    from data_schema.ranges import INT64_MAX, Range, argtype

    r = sub.add_parser("replay", help=HELP, description=DESCRIPTION)
    r.add_argument("--db", metavar="STUDY.db", required=True, help="study database")
    r.add_argument("--participant", metavar="ID", required=True)
    r.add_argument("--trial", type=argtype("--trial", Range(0, INT64_MAX, integer=True)), required=True,
                   metavar="N", help="trial index in the participant's schedule (the export's 'trial' column)")
    r.add_argument("--out", metavar="DIR", required=True, help="output folder (created; an earlier replay is "
                   "replaced)")
    r.add_argument("--backend", choices=("cpu", "gpu"), help="renderer backend of every image (default: each "
                   "condition's, as the session recorded it; cpu for a session that recorded none)")
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


#: Output folders: one per condition under CONDITIONS, the ground truth apart (no condition name reaches it),
#: the window as shown under SHOWN.
CONDITIONS, GROUND_TRUTH, SHOWN = "conditions", "ground_truth", "shown"


@dataclass
class Attempt:
    """One attempt at a live trial: ``number`` (1, 2, ... in the order shown), its ``session``, whether Escape
    ``interrupted`` it (no answer), its logged flips (checked rows), and the session's recorded window layout
    (:meth:`data_schema.store.Store.session_layout`; None: an older studyapp recorded none)."""

    number: int
    session: str | None
    interrupted: bool
    flips: list
    layout: dict | None

    def stem(self, frame: int) -> str:
        """The file name (without suffix) of a frame: ``frame_NNNNN``, ``interruptedK_frame_NNNNN``."""
        return f"interrupted{self.number}_frame_{frame:05d}" if self.interrupted else f"frame_{frame:05d}"


def replay_frames(db: Path, participant: str, trial: int) -> tuple[object, object, list[Attempt]]:
    """(protocol, the planned trial, its attempts: the interrupted ones, then the answered one) of a logged live
    trial, every session's scene checked against its record (:func:`check_scene`); one-line errors."""
    from data_schema.store import open_store
    from studyapp.runner.protocol import protocol_from_data

    with open_store(db) as st:
        data = st.protocol_json()
        planned = {t.idx: t for t in st.planned(participant)}
        meta = st.meta()
        attempts = [(a["session"], True, a["frames"]) for a in st.attempts(participant, trial)]
        answered = st.frames(participant, trial)  # every row checked by the store
        if answered:
            attempts.append((st.response_session(participant, trial), False, answered))
        sessions = list(dict.fromkeys(sid for sid, _, _ in attempts))
        records = {sid: st.session_scenes(sid) if sid is not None else None for sid in sessions}
        layouts = {sid: st.session_layout(sid) if sid is not None else None for sid in sessions}
    if data is None:
        raise CLIError(f"{db}: the study database is empty: nothing to replay")
    if not planned:
        raise CLIError(f"{db}: no participant {participant!r}")
    if trial not in planned:
        raise CLIError(f"{db}: participant {participant!r} has no trial {trial} (0..{max(planned)})")
    rendered = any(f["render_s"] is not None for _, _, flips in attempts for f in flips)
    for sid in sessions:  # before the protocol is read: its scene files would be looked for here
        if records[sid] is None and rendered:
            _unrecorded(db, planned[trial].scene, sid)
    folder = next((records[sid]["folder"] for sid in reversed(sessions) if records[sid]), None)
    protocol = protocol_from_data(data, f"{db}#protocol", check_renderers=True, folder=folder)
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
    for sid in sessions:
        check_scene(db, protocol, t.scene, sid, records[sid])
        layout = layouts[sid]
        if layout is not None and set(t.conditions) - set(layout["conditions"]):
            raise CLIError(f"{db}: session {sid} recorded no layout of condition "
                           f"{sorted(set(t.conditions) - set(layout['conditions']))[0]!r}: the database was not "
                           "written by studyapp (restore its last good copy)")
    # the interrupted attempts came first: the K-th attempt is the K-th interrupted one until the answered one
    return protocol, t, [Attempt(k + 1, sid, interrupted, flips, layouts[sid])
                         for k, (sid, interrupted, flips) in enumerate(attempts)]


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


def _old_layout(db: Path, protocol, sessions: list) -> dict:
    """The layout of sessions that recorded none (an older studyapp): replayed as before (the protocol's
    render size without --scale, the display as the window, this studyapp's eye layout, the CPU backend), with
    a one-line note on stderr."""
    import sys

    from data_schema.geometry import eye_views

    g = protocol.render_geometry()
    window = (protocol.display.width_px, protocol.display.height_px)
    print(f"studyapp: note: {db}: session {', '.join(sessions)} recorded no window layout (an older studyapp): "
          f"replayed as before, at {g.width}x{g.height} on the cpu backend with this studyapp's eye layout (the "
          "size and layout shown may have differed); no shown/ images", file=sys.stderr)
    return {"window_px": window, "shown": False,
            "conditions": {c: {"backend": "cpu", "views": eye_views(window, (g.width, g.height), cond.eyes,
                                                                     protocol.display.stereo, cond.eye)}
                           for c, cond in protocol.conditions.items()}}


def cmd_replay(args) -> int:
    import json
    import shutil

    from data_schema.atomic import atomic_dir, atomic_files, check_dir_target, write_text
    from data_schema.geometry import eye_at
    from data_schema.names import inside
    from renderers.catalog import resolve
    from studyapp import cluster
    from studyapp.progress import Bar
    from studyapp.runner.live import Pose

    spec = cluster.from_args(args)
    db, out = Path(args.db), check_dir_target(args.out, marker="frames.csv")
    protocol, planned, attempts = replay_frames(db, args.participant, args.trial)
    old = [a.session or "?" for a in attempts if a.layout is None]
    fallback = _old_layout(db, protocol, list(dict.fromkeys(old))) if old else None
    work = [(a, f) for a in attempts for f in a.flips if f["render_s"] is not None][:: args.every]
    gt = protocol.ground_truth
    scene_ref = protocol.scene_ref(planned.scene)
    scene_camera = resolve(scene_ref).camera
    fov = protocol.display.fov_y_deg
    # One task per image: each eye the window showed of the frame and, at the gazed eye's pose, gaze and size,
    # the ground truth's.
    jobs, targets, rows, gaze_rows, shown = [], [], [], [], []
    for a, f in work:
        layout = a.layout or fallback
        cond = protocol.conditions[planned.conditions[f["stimulus"]]]
        rec = layout["conditions"][cond.name]
        backend = args.backend or rec["backend"]
        pose = Pose((f["pos_x"], f["pos_y"], f["pos_z"]), (f["look_x"], f["look_y"], f["look_z"]))
        label = (f"trial {args.trial}{' (interrupted attempt %d)' % a.number if a.interrupted else ''}, condition "
                 f"{cond.name}, scene {planned.scene}, frame {f['frame']}")
        try:
            scene_camera.override(pose.camera(fov))
        except ValueError as exc:
            raise CLIError(f"{db}: participant {args.participant!r}, {label}: the logged camera cannot render: "
                           f"{exc}") from None
        views = rec["views"]
        # the eye the gaze falls on (one eye over the window: that one), mapped as the live window maps it;
        # every eye is foveated there
        view = views[0] if f["gaze_x"] is None else eye_at(views, f["gaze_x"], f["gaze_y"])
        gaze = None if f["gaze_x"] is None else view.to_render(f["gaze_x"], f["gaze_y"])
        stem = a.stem(f["frame"])
        file = inside(out, CONDITIONS, cond.name, f"{stem}.png").relative_to(out).as_posix()
        eye_jobs = []
        for v in views:
            params = dict(cond.params) if cond.eyes == 1 else {**cond.params, "eye": v.eye}
            eye_jobs.append(len(jobs))
            jobs.append((label + ("" if v is view else f" ({v.eye} eye)"),
                         {"scene": scene_ref, "width": v.render_width, "height": v.render_height, "gaze": gaze,
                          "camera": pose.camera(fov), "renderer": cond.renderer, "params": params,
                          "backend": backend}))
            targets.append(file if v is view else None)
        if gt is not None:
            g = protocol.conditions[gt]
            jobs.append((f"{label} (ground truth {gt})",
                         {"scene": scene_ref, "width": view.render_width, "height": view.render_height, "gaze": gaze,
                          "camera": pose.camera(fov), "renderer": g.renderer,
                          "params": _same_eye(g, cond.eyes, view.eye),
                          "backend": args.backend or layout["conditions"].get(gt, {"backend": "cpu"})["backend"]}))
            targets.append(inside(out, GROUND_TRUTH, f"{stem}.png").relative_to(out).as_posix())
        show = (inside(out, SHOWN, f"{stem}.png").relative_to(out).as_posix()
                if layout.get("shown", True) else "")
        shown.append((show, layout["window_px"], views, eye_jobs))
        rows.append({"attempt": a.number, "interrupted": int(a.interrupted), "session": a.session or "",
                     "frame": f["frame"], "condition": cond.name, "eye": view.eye, "backend": backend,
                     "flip_s": f["flip_s"], "gaze_x": "" if gaze is None else gaze[0],
                     "gaze_y": "" if gaze is None else gaze[1], "pos_x": pose.position[0],
                     "pos_y": pose.position[1], "pos_z": pose.position[2], "look_x": pose.look_at[0],
                     "look_y": pose.look_at[1], "look_z": pose.look_at[2], "render_s": None, "file": file,
                     "shown": show})
        if gaze is not None:
            gaze_rows.append([file, gaze[0], gaze[1]])
    render_s, pngs = {}, {}
    bar = Bar("frames")
    with atomic_dir(out, marker="frames.csv") as tmp:
        def copy(i, png):
            pngs[i] = png
            if targets[i] is None:
                return
            dst = inside(tmp, targets[i])
            with atomic_files([dst.with_suffix(".npy"), dst]) as (t_npy, t_png):
                shutil.copyfile(png.with_suffix(".npy"), t_npy)
                shutil.copyfile(png, t_png)
            render_s[targets[i]] = json.loads(png.with_suffix(".json").read_text())["seconds"]["total"]

        cluster.render_frames(jobs, Path(args.cache), spec, copy, bar)
        bar.close()
        for (show, window, views, eye_jobs) in shown:
            if show:
                _write_shown(inside(tmp, show), window, views, [pngs[j] for j in eye_jobs])
        for r in rows:
            r["render_s"] = render_s[r["file"]]
        write_text(inside(tmp, "frames.csv"), _csv(list(rows[0]), [list(r.values()) for r in rows]))
        write_text(inside(tmp, "flips.csv"), _flips_csv(attempts, planned, rows))
        write_text(inside(tmp, "gaze.csv"), _csv(["file", "gaze_x", "gaze_y"], gaze_rows))
        if args.quality and gt is not None and gaze_rows:
            _quality(tmp, fov, gaze_rows)
    n_int = sum(a.interrupted for a in attempts)
    print(f"replayed {len(rows)} frame(s) of trial {args.trial} of {args.participant} "
          f"({len(attempts)} attempt(s), {n_int} interrupted by Escape) into {out} on {spec.describe()}")
    return 0


def _write_shown(path: Path, window, views, pngs) -> None:
    """The window as it showed one frame (:func:`studyapp.runner.live.window_image`) as a PNG."""
    import numpy as np
    from PIL import Image

    from studyapp.runner.live import window_image

    images = [np.asarray(Image.open(p).convert("RGB")) for p in pngs]
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(window_image(window, views, images), "RGB").save(path, format="PNG", optimize=False)


def _flips_csv(attempts: list[Attempt], planned, rows: list[dict]) -> str:
    """Every logged flip in the order shown, and the window image it showed: the newest replayed rendered
    frame of its stimulus in its attempt (a flip between renders shows the last frame again; empty where
    --every skipped it)."""
    replayed = {(r["attempt"], r["interrupted"], r["frame"]): r["shown"] or r["file"] for r in rows}
    out = []
    for a in attempts:
        last: dict[int, str] = {}
        for f in a.flips:
            if f["render_s"] is not None:
                last[f["stimulus"]] = replayed.get((a.number, int(a.interrupted), f["frame"]), "")
            out.append([a.number, int(a.interrupted), a.session or "", f["frame"],
                        planned.conditions[f["stimulus"]], f["flip_s"], int(f["render_s"] is not None), f["dropped"],
                        last.get(f["stimulus"], "")])
    return _csv(["attempt", "interrupted", "session", "frame", "condition", "flip_s", "rendered", "dropped", "image"],
                out)


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
