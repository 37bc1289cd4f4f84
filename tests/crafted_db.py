"""Small live study databases for tests, and crafted rows with valid checksums (what a hostile file holds).

:func:`live_db` writes a live session through the store as ``studyapp run`` does (schedule, session with its
scene record, one answer per trial with its frame log along the condition's camera path), without rendering
anything: a database in a fraction of a second. :func:`craft` then changes rows of any table and recomputes
their checksums (:func:`data_schema.store.row_crc`), so the file passes every integrity check and only the
values themselves can be refused (a BLOB, which has no checksum, leaves a row that is refused as damaged).
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

LIVE = """
schema_version: 1
name: tiny_live
version: "1"
family: 2afc
question: "Which one?"
display: {width_px: 320, height_px: 180, width_cm: 30.0, distance_cm: 40.0, refresh_hz: 60}
scenes: [SCENE]
conditions:
  REF: {renderer: gt, backend: cpu}
  COND: {renderer: lafr, params: PARAMS, backend: cpu, latency_ms: 50, max_fps: 30}
stimulus:
  kind: live
  render_px: RENDER
  duration_s: 2.0
  motion: path
  gaze: fixation
  min_fps: 45
  camera_path: [{t: 0, yaw_deg: -3}, {t: 1, yaw_deg: 3}]
design: {repetitions: REPS}
simulation: {ground_truth: REF}
analysis: {dv: chosen, unit: participant, test: thurstone}
"""

#: A scene file (meshes from the ``mesh_file`` fixture's folder): a floor and a cube moved by ``{x}``.
BOX = """name: box
meshes:
  - {{file: floor.ply}}
  - {{file: cube.stl, translate: [{x}, 0, 0]}}
lights:
  - {{type: point, position: [0, 3, 0], intensity: [5, 5, 5]}}
camera: {{position: [0, 1.5, -3], look_at: [0, 0.5, 1], up: [0, 1, 0], fov_y: 50}}
"""


def live_text(scene: str = "cornell", condition: str = "LaFR", params: str = "{delta: 4.0}", repetitions: int = 2,
              reference: str = "Ref", render_px: tuple[int, int] = (32, 18)) -> str:
    """A tiny live 2AFC protocol: the ground truth ``reference`` against a LaFR ``condition``."""
    return (LIVE.replace("SCENE", scene).replace("COND", condition).replace("PARAMS", params)
            .replace("REPS", str(repetitions)).replace("REF", reference).replace("RENDER", str(list(render_px))))


def live_protocol(folder: Path, **kw) -> Path:
    """:func:`live_text` written to ``folder/live.yaml``."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "live.yaml"
    path.write_text(live_text(**kw))
    return path


def live_db(protocol: Path, db: Path, frames_per_stimulus: int = 3, gaze=None, scenes: bool = True,
            layout: bool = True, scale: float = 1.0) -> Path:
    """A completed live session of participant P1 of ``protocol`` in a new database ``db``.

    Every stimulus of every trial logs ``frames_per_stimulus`` rendered flips 1/30 s apart along its camera
    path, the gaze at display pixel ``gaze`` (default: the centre) 52 ms old. The session records its window
    layout (the display's size, renders at ``scale``) as ``run`` does. ``scenes=False``: no scene record,
    ``layout=False``: no layout (sessions of an older studyapp)."""
    import json

    from data_schema.store import PlannedRow, open_store
    from studyapp.runner.live import FrameRecord, layout_record, live_stimulus, scene_record
    from studyapp.runner.protocol import load_protocol
    from studyapp.runner.schedule import build_schedule, counterbalance_index, schedule_hash

    p = load_protocol(protocol)
    sched = build_schedule(p, "P1", 0)
    gx, gy = gaze if gaze is not None else (p.display.width_px / 2, p.display.height_px / 2)
    with open_store(db, "create") as st:
        st.bind_protocol(p.name, p.version, p.content_hash, p.data)
        st.enrol("P1", counterbalance_index("P1"), 0, schedule_hash(sched),
                 [PlannedRow(t.index, t.kind, t.family, t.scene, t.block, t.conditions, t.expected, t.break_before)
                  for t in sched])
        sid = st.start_session("P1", p.content_hash, 0, {}, {}, {}, "test",
                               scenes=scene_record(p) if scenes else None)
        if layout:
            st.event(sid, "live_layout", json.dumps(layout_record(p, scale, (p.display.width_px,
                                                                             p.display.height_px))))
        for t in sched:
            frames = []
            for i, cond in enumerate(t.conditions):
                motion = live_stimulus(p, cond, t.scene).motion_model()
                for k in range(frames_per_stimulus):
                    flip = 1.0 + i * 2.0 + k / 30
                    pose = motion.pose(k / 30)
                    frames.append(FrameRecord(len(frames), i, flip, 0.01, flip - 0.052, gx, gy, pose.position,
                                              pose.look_at, False))
            st.commit_response("P1", t.index, sid, ["A"], chosen=t.conditions[0], rt_s=1.0, onset_s=1.0,
                               frames=frames)
        st.end_session(sid, "completed")
    return db


def craft(db: Path, table: str, where: dict, changes: dict) -> int:
    """Set ``changes`` (column -> value) in the rows of ``table`` matching ``where``, with valid checksums;
    returns the number of rows changed."""
    from data_schema.store import COLUMNS, PRIMARY_KEYS, row_crc

    cols, pk = COLUMNS[table], PRIMARY_KEYS[table]
    con = sqlite3.connect(db, isolation_level=None)
    try:
        cond = " AND ".join(f"{k} = ?" for k in where) or "1"
        rows = con.execute(f"SELECT {', '.join(cols)} FROM {table} WHERE {cond}", tuple(where.values())).fetchall()
        at = " AND ".join(f"{k} = ?" for k in pk)
        for row in rows:
            old = dict(zip(cols, row))
            new = {**old, **{c: v for c, v in changes.items() if c in cols}}
            key = tuple(new[k] for k in pk)
            con.execute(f"UPDATE {table} SET {', '.join(f'{c} = ?' for c in cols)} WHERE {at}",
                        (*(new[c] for c in cols), *(old[k] for k in pk)))
            back = con.execute(f"SELECT {', '.join(cols)} FROM {table} WHERE {at}", key).fetchone()
            try:
                crc = row_crc(table, back)
            except TypeError:  # a BLOB has no checksum: the file is refused as damaged
                crc = "no checksum"
            con.execute(f"UPDATE {table} SET crc = ? WHERE {at}", (crc, *key))
        return len(rows)
    finally:
        con.close()
