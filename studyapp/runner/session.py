"""Running a participant's session: schedule -> store -> presenter, one durable response at a time.

Order of events (what survives a crash at any point):

1. the protocol and the participant's state are checked against the study database (:func:`admit`: a
   different protocol version, an existing participant without ``resume``, ``resume`` without one, a session
   still running, a participant who answered everything are refused); ``studyapp run`` asks the same, read-only
   (:func:`check_admission`), before it prepares any stimulus;
2. the schedule is built (pure function of protocol, participant, seed) and every stimulus it needs is located
   (missing files are an error before anything is written: :func:`~studyapp.runner.stimuli.split_missing`);
3. the presenter is opened (a window checks its keyboard backend here);
4. a new participant's whole schedule is written in one transaction; a returning one (``resume``) must have
   the same seed and the identical schedule (hash), and continues at the first unanswered trial;
5. a live session in a window renders each condition x scene for a moment first (:mod:`.fpscheck`): the table is
   stored (``fps_check`` event) and printed; a condition below ``min_fps`` ends the session as ``refused`` before
   its first trial unless ``accept_slow``;
6. per trial: break message if due, ``present``, then the response is committed (fsync) before the next trial
   is preloaded and shown. Escape -> ``pause``: ``resume`` shows the trial again, ``end`` closes the session
   as ``ended`` (both are logged as events); a later ``--resume`` continues it. The flips of a live attempt
   that Escape interrupted are kept as an ``interrupted_attempt`` event (never as the answer's frames), and a
   live session records its window's layout (``live_layout``) at its start: ``studyapp replay`` shows both.
"""

from __future__ import annotations

import contextlib
import json
import platform
import re
import sqlite3
import sys
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

from data_schema import families
from data_schema.errors import UserError
from data_schema.names import check_name
from data_schema.store import PlannedRow, Store, StoreError, open_store, remove_database
from studyapp.presentation.base import Stimulus, TrialDisplay, TrialResult

from .fpscheck import TooSlow, measure, refusal, seconds_per_cell, table_lines, too_slow, trial_flags
from .live import instructions_text, layout_record, scene_record
from .protocol import Protocol
from .schedule import PlannedTrial, break_text, build_schedule, counterbalance_index, schedule_hash
from .stimuli import frame_paths, missing_line, missing_stimuli, prepare_command, split_missing, stimulus_root


@dataclass
class SessionSummary:
    session: str
    participant: str
    status: str
    answered: int  # answered trials of the whole schedule so far (references excluded)
    planned: int
    catch_correct: int
    catch_total: int
    catch_passed: bool | None


def software_versions(extra: dict | None = None) -> dict:
    import numpy

    from studyapp import __version__

    out = {"studyapp": __version__, "python": platform.python_version(), "sqlite": sqlite3.sqlite_version,
           "numpy": numpy.__version__, "platform": platform.platform()}
    out.update(extra or {})
    return out


class StimulusSet:
    """Stimulus lookup for one run: frame files per (condition, scene), empty where declared-only."""

    def __init__(self, protocol: Protocol, scale: float = 1.0, root: Path | None = None,
                 allow_declared: bool = False) -> None:
        self.protocol, self.scale, self.root = protocol, scale, root
        blocking, self.declared = split_missing(protocol, missing_stimuli(protocol, scale, root), allow_declared)
        if blocking:  # `run` refuses this before any rendering; a library caller (or a vanished set) lands here
            raise UserError(missing_line(protocol, blocking, stimulus_root(protocol, scale, root),
                                         prepare_command(str(protocol.path), scale, full=protocol.full)))

    def stimulus(self, condition: str, scene: str) -> Stimulus:
        if self.protocol.live:
            from .live import live_stimulus

            return Stimulus(condition=condition, frames=(), fps=0.0,
                            live=live_stimulus(self.protocol, condition, scene, self.scale))
        fps = self.protocol.fps if self.protocol.stimulus_kind == "sequence" else 0.0
        if (condition, scene) in self.declared:
            return Stimulus(condition=condition, frames=(), fps=fps)
        frames = frame_paths(self.protocol, condition, scene, self.scale, self.root)
        return Stimulus(condition=condition, frames=frames, fps=fps if len(frames) > 1 else 0.0)


def trial_display(protocol: Protocol, t: PlannedTrial | PlannedRow, stimuli: StimulusSet, number: int,
                  total: int, display_px: tuple[float, float] | None) -> TrialDisplay:
    """What the presenter needs for one planned trial."""
    kind = t.kind
    ref = kind == "reference"
    return TrialDisplay(
        index=t.idx, family=t.family,
        stimuli=tuple(stimuli.stimulus(c, t.scene) for c in t.conditions),
        question="" if ref else protocol.question,
        answer_keys=({} if protocol.stimulus_kind in ("sequence", "live") else {"space": "seen"}) if ref
        else dict(protocol.answer_keys),
        switch_keys={} if ref else dict(protocol.switch_keys), fixation_px=display_px,
        duration_s=protocol.duration_s if protocol.stimulus_kind in ("sequence", "live") else None,
        black_before_s=protocol.black_s, label=protocol.reference_label if ref else "",
        n_picks=protocol.n_picks if families.get(protocol.family).has_picks else 1,
        progress=(number, total) if counted(t) else None, scene=t.scene, kind=kind,
        key_reminder=protocol.key_reminder)


def counted(t: PlannedTrial | PlannedRow) -> bool:
    """Whether ``t`` counts in the participant's progress ("3 / 96"): not practice, not a reference."""
    return t.kind not in ("reference", "practice")


def interpret(protocol: Protocol, t: PlannedRow, result: TrialResult) -> dict:
    """Map the presenter's answers to the logged chosen / chosen_2 / response (the family's rules)."""
    if t.kind == "reference":
        return {"chosen": "", "chosen_2": "", "response": None}
    ans = [a for a in result.answers if a != ""]
    if not ans:
        raise RuntimeError(f"presenter returned no answer for trial {t.idx}")
    try:
        return families.get(t.family).interpret(t.conditions, result.answers, protocol.n_picks)
    except ValueError as exc:
        raise RuntimeError(f"presenter answer for trial {t.idx}: {exc}") from None


def _correct(store: Store, pid: str, t: PlannedRow, answers: list[str], derived: dict) -> bool | None:
    if t.kind != "catch" or not t.expected:
        return None
    if t.expected.startswith("same:"):
        j = int(t.expected.split(":", 1)[1])
        row = store.conn.execute("SELECT chosen FROM responses WHERE participant = ? AND idx = ?",
                                 (pid, j)).fetchone()
        return row is not None and row[0] == derived["chosen"]
    return answers[:1] == [t.expected]


@dataclass
class Admission:
    """What the store says about a participant about to run (:func:`admit`)."""

    existing: dict | None  # the participant's row, None for a new participant
    seed: int
    schedule: list[PlannedTrial]
    schedule_hash: str
    unclosed: list[str]  # every trial is answered: sessions left running, to close as completed (nothing to show)


def check_participant_id(participant: str) -> None:
    """Refuse a participant id that is not a pseudonymous name (it becomes file names: replay, exports)."""
    if not re.fullmatch(r"[A-Za-z0-9_.-]{1,64}", participant or ""):
        raise UserError(f"--participant={participant!r} is invalid: a pseudonymous id of 1-64 letters, digits, "
                         "'_', '.' or '-' (no names or e-mail addresses)")
    check_name("participant", participant)  # '..', '.x', 'CON': not a file name (replay, exports)


def admit(store: Store, protocol: Protocol, pid: str, seed: int | None, resume: bool) -> Admission:
    """Every refusal of a run that the study database decides, asked of the store without writing to it.

    The database must have been written by this protocol (:meth:`Store.bind_protocol`); a participant who
    exists needs ``resume``, one who does not cannot resume; a session of the participant still running in
    another process is refused (:meth:`Store.check_not_running`); a resumed participant keeps the stored seed
    and schedule; a participant who answered everything has nothing to resume unless a session was left open.
    :func:`run_session` asks this before it shows anything, and ``studyapp run`` before it prepares stimuli
    (:func:`check_admission`).

    Raises
    ------
    StoreError
        One line naming the database, the participant and the way out.
    """
    store.bind_protocol(protocol.name, protocol.version, protocol.content_hash, protocol.data, record=False)
    existing = store.participant(pid)
    if existing and not resume:
        done = len(store.answered(pid))
        raise StoreError(f"{store.path}: participant {pid!r} already exists ({done} of {existing['n_planned']} "
                         "planned trials answered): use --resume to continue, or another --participant")
    if resume and not existing:
        raise StoreError(f"{store.path}: participant {pid!r} has no session to resume")
    if existing:
        store.check_not_running(pid)  # a second --resume while the first still runs (checked again at start)
        if seed is not None and seed != existing["seed"]:
            raise StoreError(f"{store.path}: participant {pid!r} was scheduled with --seed {existing['seed']}, "
                             f"not {seed}")
        seed = existing["seed"]
    seed = 0 if seed is None else seed
    schedule = build_schedule(protocol, pid, seed)
    s_hash = schedule_hash(schedule)
    if existing and existing["schedule_hash"] != s_hash:
        # A participant enrolled before breaks fell at scene changes (and before the practice reference) resumes
        # with the schedule stored then.
        legacy = build_schedule(protocol, pid, seed, legacy=True)
        if existing["schedule_hash"] == schedule_hash(legacy):
            schedule, s_hash = legacy, existing["schedule_hash"]
    if existing and existing["schedule_hash"] != s_hash:
        raise StoreError(f"{store.path}: the schedule of participant {pid!r} differs from the stored one "
                         "(protocol or scheduler changed): cannot resume")
    unclosed = []
    if existing and store.first_unanswered(pid) is None:
        # Every answer is recorded. A session stopped after its last answer but before it was closed (crash,
        # kill) is closed as completed; otherwise there is nothing to resume.
        unclosed = store.running_sessions(pid)
        if not unclosed:
            raise StoreError(f"{store.path}: participant {pid!r} has already answered every trial")
    return Admission(existing, seed, schedule, s_hash, unclosed)


def _check_database(db_path: Path, resume: bool) -> None:
    if resume and not db_path.exists():
        raise StoreError(f"{db_path}: no such study database: nothing to resume")


def check_admission(protocol: Protocol, participant: str, db_path, seed: int | None = None,
                    resume: bool = False) -> Admission | None:
    """:func:`run_session`'s refusals that do not depend on stimuli (participant id, database, :func:`admit`),
    made read-only before any work that precedes the session (``run --prepare``); None for a new database."""
    check_participant_id(participant)
    db_path = Path(db_path)
    _check_database(db_path, resume)
    if not db_path.exists():
        return None
    with open_store(db_path) as store:
        return admit(store, protocol, participant, seed, resume)


def run_session(protocol: Protocol, participant: str, db_path, presenter_factory: Callable, seed: int | None = None,
                resume: bool = False, scale: float = 1.0, stimuli_root: Path | None = None,
                allow_declared: bool = False, on_started: Callable[[str], None] | None = None,
                progress: Callable[[int, int], None] | None = None, accept_slow: bool = False,
                console: Callable[[str], None] | None = None) -> SessionSummary:
    """Run (or resume) one participant's session; see the module docstring for the order of events.

    ``accept_slow``: run a live session whose frame-rate check finds a condition below ``min_fps`` (recorded in
    the ``fps_check`` event); ``console(line)`` shows the experimenter the check's table and every live trial
    below ``min_fps`` as it ends (default: stderr).

    ``presenter_factory(stimuli, display)`` returns the Presenter (a window or the simulated observer); it is
    called after every check has passed, so a refused run opens no window.
    """
    check_participant_id(participant)
    db_path = Path(db_path)
    created = not db_path.exists()
    _check_database(db_path, resume)
    store = open_store(db_path, "create" if created else "write")
    try:
        return _run(store, protocol, participant, presenter_factory, seed, resume, scale, stimuli_root,
                    allow_declared, on_started, progress, accept_slow, console or warn_line)
    finally:
        empty = created and not store.has_answers()
        store.close()
        if empty:  # a refused first run (or Ctrl-C before the first answer) leaves no database behind
            remove_database(db_path)


def _run(store, protocol, pid, presenter_factory, seed, resume, scale, stimuli_root, allow_declared, on_started,
         progress, accept_slow=False, console=None) -> SessionSummary:
    adm = admit(store, protocol, pid, seed, resume)
    existing, seed, schedule, s_hash = adm.existing, adm.seed, adm.schedule, adm.schedule_hash
    if adm.unclosed:
        for sid in adm.unclosed:
            store.event(sid, "closed", "all trials were answered before the session stopped")
            store.end_session(sid, "completed")
        return _summary(store, protocol, pid, adm.unclosed[-1], "completed")
    stimuli = StimulusSet(protocol, scale, stimuli_root, allow_declared)
    # The window is the participant's display at any --scale: a smaller render is shown upscaled over it.
    display = protocol.display
    presenter = presenter_factory(stimuli, display)
    measured = presenter.open(display)
    try:
        if not existing:
            store.bind_protocol(protocol.name, protocol.version, protocol.content_hash, protocol.data)
            rows = [PlannedRow(t.index, t.kind, t.family, t.scene, t.block, t.conditions, t.expected,
                               t.break_before) for t in schedule]
            store.enrol(pid, counterbalance_index(pid), seed, s_hash, rows)
        previous = store.last_session(pid) if resume else None
        rendered = protocol.render_geometry(scale)
        display_info = {**asdict(display), "ppd": display.ppd, "fov_y_deg": display.fov_y_deg, "scale": scale,
                        "render_px": [rendered.width, rendered.height], "fixation": list(protocol.fixation),
                        **{k: measured[k] for k in ("window_size_px", "window_pos_px", "window_matches_display",
                                                    "eyetracker", "gl_renderer", "gpu") if k in measured}}
        sid = store.start_session(pid, protocol.content_hash, seed, software_versions(measured.get("software")),
                                  display_info, measured, str(measured.get("presenter", type(presenter).__name__)),
                                  resumed_from=previous, scenes=scene_record(protocol) if protocol.live else None)
        if protocol.live:  # what replay shows: the window's size, each condition's backend and eye layout
            window = measured.get("window_size_px") or (display.width_px, display.height_px)
            store.event(sid, "live_layout", json.dumps(layout_record(protocol, scale, window), sort_keys=True))
        validation = measured.get("validation")
        if validation:  # the eye tracker's accuracy, measured before the first trial (presentation.eyetracker)
            if validation["error_deg"] is None:  # skipped with no gaze measured: the event only
                store.event(sid, "validation", json.dumps(validation))
            else:
                store.record_validation(sid, validation["error_deg"], json.dumps(validation))
        if on_started:
            on_started(sid)
        try:
            _fps_check(store, protocol, sid, presenter, scale, accept_slow, console or warn_line)
            status = _loop(store, protocol, pid, sid, presenter, stimuli, scale, resume, progress,
                           console or warn_line)
        except BaseException as exc:  # Ctrl-C, SIGTERM, a full disk: committed answers stay; the session says so
            if isinstance(exc, TooSlow):  # closed as refused already
                raise
            with contextlib.suppress(StoreError):
                store.event(sid, "interrupted", "Ctrl-C or SIGTERM" if isinstance(exc, KeyboardInterrupt)
                            else str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__)
                store.end_session(sid, "interrupted")
            raise
    finally:
        presenter.close()
    return _summary(store, protocol, pid, sid, status)


def _fps_check(store, protocol, sid, presenter, scale, accept_slow, console) -> None:
    """The frame-rate check before the first trial (:mod:`.fpscheck`), in a presenter that renders live frames
    (a window: ``fps_check_frames``); the simulated observer renders nothing, so a simulated run has no check."""
    check = getattr(presenter, "fps_check_frames", None)
    seconds = seconds_per_cell(protocol) if protocol.live else 0.0
    if check is None or not seconds:
        return
    rows = measure(protocol, scale, check, seconds)
    slow = too_slow(rows, protocol.min_fps)
    accepted = sorted({r["condition"] for r in slow}) if accept_slow else []
    clean = [{k: (None if isinstance(v, float) and v != v else v) for k, v in r.items()} for r in rows]  # JSON: no NaN
    store.event(sid, "fps_check", json.dumps({"seconds": seconds, "scale": scale, "min_fps": protocol.min_fps,
                                              "rows": clean, "accepted_slow": accepted}, sort_keys=True))
    for line in table_lines(rows, protocol.min_fps):
        console(line)
    if slow and not accept_slow:
        line = refusal(slow, protocol.min_fps)
        store.event(sid, "refused", line)
        store.end_session(sid, "refused")
        raise TooSlow(line)
    if accepted:
        console(f"--accept-slow: the trials of {', '.join(accepted)} are flagged")


def _slow_trial(t, frames, min_fps) -> list[str]:
    """The console lines of a finished live trial below ``min_fps`` (per stimulus, from its rendered frames)."""
    if not frames or not min_fps:
        return []
    import numpy as np

    from data_schema.timing import rates

    per = []
    for i in range(len(t.conditions)):
        own = [f for f in frames if f.stimulus == i]
        r = rates([f.flip_s for f in own], [f.render_s for f in own]) if own else np.array([])
        per.append(float(np.median(r)) if r.size else float("nan"))
    return trial_flags(t.idx, t.conditions, t.scene, per, min_fps)


def _summary(store, protocol, pid, sid, status) -> SessionSummary:
    prog = next(p for p in store.progress() if p["participant"] == pid)
    passed = None
    if prog["catch_planned"]:
        frac = protocol.catch["pass_fraction"] if protocol.catch else 0.75
        passed = prog["catch_correct"] >= frac * prog["catch_planned"] if status == "completed" else None
    return SessionSummary(sid, pid, status, prog["answered"], prog["planned"], prog["catch_correct"],
                          prog["catch_planned"], passed)


def _loop(store, protocol, pid, sid, presenter, stimuli, scale, resume, progress, console=None) -> str:
    planned = store.planned(pid)
    answered = store.answered(pid)
    total = sum(t.kind != "reference" for t in planned)
    # the experimenter's count (progress callback), then the participant's (practice not counted)
    number = sum(1 for t in planned if t.kind != "reference" and t.idx in answered)
    shown_total = sum(counted(t) for t in planned)
    shown = sum(1 for t in planned if counted(t) and t.idx in answered)
    gaze = protocol.render_geometry(scale).gaze if protocol.fixation_mark else None
    text = instructions_text(protocol)
    presenter.instructions(("Welcome back. " if resume else "") + text)
    todo = [t for t in planned if t.idx not in answered]
    # a presenter that renders live frames in real time (a window) is checked against min_fps; the simulated
    # observer's few sampled frames have no frame rate to flag
    floor = protocol.min_fps if protocol.live and hasattr(presenter, "fps_check_frames") else None
    first = True
    displays = {}

    def display_of(t, done=None):
        """The trial's display; ``done`` = counted trials answered before it (default: so far)."""
        if t.idx not in displays:
            done = shown if done is None else done
            displays[t.idx] = trial_display(protocol, t, stimuli, done + counted(t), shown_total, gaze)
        return displays[t.idx]

    if todo:
        presenter.preload(display_of(todo[0]))
    for k, t in enumerate(todo):
        if t.break_before and not first and protocol.breaks:
            br = protocol.breaks
            store.event(sid, "break", f"before trial {t.idx}")
            store.checkpoint()
            presenter.rest(break_text(protocol, planned, t.idx), float(br.get("seconds", 30.0)))
        first = False
        d = display_of(t)
        prefetch = getattr(presenter, "prefetch", None)  # optional: decode the next trial during this one
        if prefetch is not None and k + 1 < len(todo):
            prefetch(display_of(todo[k + 1], shown + counted(t)))
        while True:
            result = presenter.present(d)
            if not result.escaped:
                break
            if result.frames:  # the flips of the interrupted attempt, kept apart from the answer's for replay
                store.record_attempt(sid, pid, t.idx, result.frames)
            store.event(sid, "pause", f"trial {t.idx}")
            choice = presenter.pause()
            store.event(sid, choice, f"trial {t.idx}")
            if choice == "end":
                store.end_session(sid, "ended")
                return "ended"
        derived = interpret(protocol, t, result)
        store.commit_response(pid, t.idx, sid, result.answers, chosen=derived["chosen"],
                              chosen_2=derived["chosen_2"], response=derived["response"], rt_s=result.rt_s,
                              onset_s=result.onset_s, dropped_frames=result.dropped_frames,
                              switches=result.switches, gaze_left_fovea=result.gaze_left_fovea,
                              correct=_correct(store, pid, t, result.answers, derived), frames=result.frames)
        for line in _slow_trial(t, result.frames, floor):
            (console or warn_line)(line)
        if t.kind != "reference":
            number += 1
        shown += counted(t)
        displays.pop(t.idx, None)
        if progress:
            progress(number, total)
        if k + 1 < len(todo):
            presenter.preload(display_of(todo[k + 1]))
    store.end_session(sid, "completed")
    presenter.message("Thank you! The session is complete.", 2.0)
    return "completed"


def ground_truth_stimuli(protocol: Protocol, stimuli: StimulusSet) -> dict[str, Stimulus]:
    """Scene -> ground-truth stimulus (for the simulated observer)."""
    gt = protocol.ground_truth
    scenes = set(protocol.scenes) | ({protocol.practice["scene"]} if protocol.practice else set())
    if gt is None:
        return {}
    out = {}
    for s in sorted(scenes):
        try:
            out[s] = stimuli.stimulus(gt, s)
        except KeyError:
            continue
        if out[s].frames and not all(Path(f).is_file() for f in out[s].frames):
            out[s] = Stimulus(gt, (), out[s].fps)
    return out


def write_line(msg: str) -> None:
    print(msg, file=sys.stdout, flush=True)


def warn_line(msg: str) -> None:
    """A line for the experimenter's console (stderr: the participant's answers never go there)."""
    print(msg, file=sys.stderr, flush=True)
