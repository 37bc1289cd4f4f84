"""Study commands: ``prepare``, ``run``, ``sessions``, ``export``, ``validate`` (and the demo step).

``run`` without ``--simulate`` opens a PsychoPy window through
``studyapp.presentation.psychopy_window.PsychoPyPresenter``; scheduling, logging and the simulated observer
never import PsychoPy. Also runnable as ``python -m studyapp.commands.study ...`` (same exit codes).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from data_schema.errors import CLIError
from studyapp.progress import Bar

#: What a stopped ``prepare`` (or the prepare of ``run --prepare``) and a stopped ``run`` leave
#: (``studyapp: interrupted (...)``, studyapp.cli).
PREPARE_INTERRUPTED = "frames rendered so far are kept in the cache: run the same prepare again to continue"
RUN_INTERRUPTED = "committed answers are kept: continue a session with --resume"

#: The shipped replications (package data: a wheel install has them too).
SHIPPED = Path(__file__).resolve().parents[1] / "protocols"


def _protocol(path: str, stimuli: str | None = None, check_renderers: bool = True, full: bool = False):
    """A protocol file, or a shipped protocol by name (``studyapp run seed001_2afc ...``); a shipped one keeps
    its stimuli under the current folder (``./stimuli/<name>``), not inside the installed package. ``full``:
    its full-size variant (the protocol's ``full`` block)."""
    from studyapp.runner.protocol import load_protocol

    p = Path(path)
    if not p.exists() and not p.suffix and (SHIPPED / f"{path}.yaml").exists():
        return load_protocol(SHIPPED / f"{path}.yaml", stimuli_dir=stimuli, check_renderers=check_renderers,
                             output_base=Path.cwd(), full=full)
    return load_protocol(p, stimuli_dir=stimuli, check_renderers=check_renderers, full=full)


def _fmt_seconds(s: float) -> str:
    if not math.isfinite(s):
        return "?"
    s = round(s)
    return f"{s // 3600}h{s % 3600 // 60:02d}m" if s >= 3600 else (f"{s // 60}m{s % 60:02d}s" if s >= 60 else f"{s}s")


def checked_protocol(args, stimuli: str | None = None):
    """The protocol ``args.protocol`` (``--full``: its full-size variant) after every check of ``validate``.

    Schema, cross-references, renderer names, parameters and geometry, scenes, live fields (with the renderers
    imported even for a simulated run, which renders live stimuli too), and a schedule built (participant P1,
    seed 0). ``validate`` and ``run`` (simulated or not) both call this one function, ``run`` before any database
    is created or opened for writing and before any stimulus is prepared, so that a protocol ``validate`` refuses
    is refused by ``run`` in the same line, leaving nothing behind.

    Returns
    -------
    (Protocol, list of PlannedTrial)
        The protocol and the schedule of participant P1, seed 0.
    """
    from studyapp.runner.schedule import build_schedule

    p = _protocol(args.protocol, stimuli, check_renderers=True, full=args.full)
    return p, build_schedule(p, "P1", 0)


# -- handlers ------------------------------------------------------------------------------------------------
def cmd_validate(args) -> int:
    from studyapp.runner.protocol import renderer_names
    from studyapp.runner.stimuli import missing_line, missing_stimuli, prepare_command, stimulus_root

    p, sched = checked_protocol(args, args.stimuli)
    if p.live:  # what `run --scale` refuses before its session starts
        from studyapp.runner.live import check_live_sizes

        check_live_sizes(p, args.scale)
    print(f"{p.path}: valid")
    print(p.describe())
    kinds = {k: sum(t.kind == k for t in sched) for k in ("practice", "reference", "trial", "catch")}
    print("schedule (participant P1, seed 0): " + ", ".join(f"{v} {k}" for k, v in kinds.items() if v))
    if renderer_names() is None and any(c.renderer for c in p.conditions.values()):
        print("renderer names not checked: renderers.registry is not importable here")
    if p.live:
        backends = sorted({p.backend_of(c) for c, cond in p.conditions.items() if cond.renderer})
        g = p.render_geometry(args.scale)
        print(f"stimuli: rendered during the trials at {g.width}x{g.height} ({', '.join(backends)} backend), "
              "nothing to prepare")
        return 0
    root = stimulus_root(p, args.scale)
    missing = missing_stimuli(p, args.scale)
    print(f"stimuli: complete in {root}" if not missing else "stimuli: " + missing_line(
        p, missing, root, prepare_command(args.protocol, args.scale, args.stimuli, args.full)))
    return 0


def cmd_prepare(args) -> int:
    from studyapp.runner.stimuli import prepare, stimulus_root

    p = _protocol(args.protocol, args.stimuli, full=args.full)
    spec = _cluster_for(args, p)
    bar = Bar("frames")
    res = prepare(p, scale=args.scale, progress=bar, cache_dir=Path(args.cache) if args.cache else None,
                  cluster=spec)
    bar.close()
    _report_prepared(p, res, spec, stimulus_root(p, args.scale))
    return 0


def _report_prepared(p, res: dict, spec, root: Path, stream=None) -> None:
    """What :func:`~studyapp.runner.stimuli.prepare` did (``prepare``, and ``run --prepare`` on stderr)."""
    if res["removed"]:
        print(f"removed {res['removed']} temporary file(s) that a stopped prepare had left", file=stream)
    print(f"{p.name}: {res['frames']} frame(s) built ({res['rendered']} rendered, {res['cached']} from the cache) "
          f"on {spec.describe()} in {_fmt_seconds(res['seconds'])} -> {root}", file=stream)


def _cluster_for(args, p):
    """Where ``prepare`` (or ``run --prepare``) renders: the cluster options; ``--full`` on one machine only with
    ``--yes-on-one-machine``."""
    from studyapp import cluster

    spec = cluster.from_args(args)
    if args.full and spec.scheduler is None and not args.yes_on_one_machine:
        w, h = p.render_size
        raise CLIError(f"--full renders {p.name} at {w}x{h} with its full-size parameters, a cluster's work (its "
                       "render_budget states the hours): give a running cluster with --scheduler tcp://HOST:PORT "
                       "(docs/distributed.md), or add --yes-on-one-machine to render it on this machine anyway")
    return spec


def _presenter_factory(args, protocol):
    if args.simulate:
        from studyapp.runner.observer import SimulatedObserver
        from studyapp.runner.session import ground_truth_stimuli

        def make(stimuli, display):
            return SimulatedObserver(protocol, args.participant, args.seed if args.seed is not None else 0,
                                     ground_truth_stimuli(protocol, stimuli), delay_s=args.sim_delay)
        return make

    def make_window(stimuli, display):
        try:
            from studyapp.presentation.psychopy_window import PsychoPyPresenter
        except ImportError as exc:
            raise CLIError(f"the PsychoPy presenter is not available ({exc}); use --simulate for a dry run") from None
        kw = {"eyetracker": args.eyetracker}
        if protocol.live and protocol.gaze_source == "mouse":  # the window's mouse stands in for the eye
            kw = {"eyetracker": "pointer", "required_tracker": True}
        elif protocol.live and protocol.gaze_source == "tracker":
            kw = {"eyetracker": "device", "tracker": protocol.eyetracker, "required_tracker": True}
        gpu = protocol.live and any(protocol.backend_of(c) == "gpu" for c, cond in protocol.conditions.items()
                                    if cond.renderer)
        return PsychoPyPresenter(gaze_log=args.gaze_log, screenshot_dir=args.screenshot_dir, gpu=gpu, **kw)
    return make_window


def _stimuli_for_run(args, p, db: Path) -> list[str]:
    """``run``'s stimulus policy: never render unasked.

    The missing sets a run needs (:func:`~studyapp.runner.stimuli.split_missing`: ``--simulate`` needs none of a
    condition that declares a quality) are refused in one line naming them and the ``prepare`` command, or with
    ``--prepare`` rendered first; a folder condition's are refused either way, naming the folder and its files.
    Before either, the database's refusals (:func:`~studyapp.runner.session.check_admission`; none for
    ``db`` None: ``--preview``). Returns the notes to print once the session has started.
    """
    from studyapp.runner.session import check_admission
    from studyapp.runner.stimuli import (missing_line, missing_stimuli, prepare, prepare_command, render_function,
                                         split_missing, stimulus_root)

    missing = missing_stimuli(p, args.scale)
    blocking, declared = split_missing(p, missing, args.simulate)
    if db is not None and (blocking or (missing and args.prepare) or (args.resume and args.seed is None)):
        # The database's refusals (another protocol, the participant's state) come before any rendering.
        adm = check_admission(p, args.participant, db, args.seed, args.resume)
        if adm is not None:
            args.seed = adm.seed  # the simulated observer answers with the participant's stored seed
        if adm is not None and adm.unclosed:  # every trial answered: run_session only closes the session
            missing = blocking = []
    if (blocking and not args.prepare) or any(p.conditions[n.condition].folder for n, _ in blocking):
        folder_only = [(n, f) for n, f in blocking if p.conditions[n.condition].folder]
        then = ", then run again" if folder_only else ", or add --prepare to render them first" + (
            " (or declare a quality for each of their conditions)" if args.simulate else "")
        raise CLIError(missing_line(p, blocking, stimulus_root(p, args.scale),
                                    prepare_command(args.protocol, args.scale, args.stimuli, args.full), then))
    if missing and args.prepare:
        spec = _cluster_for(args, p)
        if any(p.conditions[n.condition].renderer for n, _ in missing):
            render_function()  # one line if the renderers are not usable here, before the note below
        print(f"{len(missing)} stimulus set(s) missing: preparing them first (--prepare)", file=sys.stderr)
        args.interrupted_hint = PREPARE_INTERRUPTED  # a stop now stops the prepare: no session exists yet
        bar = Bar("frames") if not args.quiet else None
        res = prepare(p, scale=args.scale, progress=bar, cluster=spec)
        if bar:
            bar.close()
        args.interrupted_hint = RUN_INTERRUPTED
        _report_prepared(p, res, spec, stimulus_root(p, args.scale), sys.stderr)
    elif declared:
        return [f"note: {len(declared)} stimulus set(s) missing: the simulated observer uses the declared "
                "qualities for them (add --prepare to simulate from images)"]
    return []


def cmd_run(args) -> int:
    from studyapp.presentation.base import PresentationError
    from studyapp.runner.session import run_session

    from data_schema.atomic import check_target, real_file, real_folder

    if args.preview:
        return _cmd_preview(args)
    if not args.participant:
        raise CLIError("the following arguments are required: --participant (or --preview for a dry run)")
    p, _ = checked_protocol(args, args.stimuli)  # validate's checks, before anything is created or rendered
    db = Path(args.db) if args.db else Path(f"{p.name}.db")
    real_file(db, "--db")  # a FIFO would block SQLite's open, a device node is no database: refuse before
    if args.gaze_log:
        check_target(args.gaze_log, inputs=[db], option="--gaze-log")
    if args.screenshot_dir:
        real_folder(args.screenshot_dir, "--screenshot-dir")
    notes = _stimuli_for_run(args, p, db)  # printed once the session has started (errors stay one line)

    session_started = False

    def started(sid):
        nonlocal session_started
        session_started = True
        for note in notes:
            print(note, file=sys.stderr)
        print(f"session {sid} started ({db})", flush=True)

    bar = Bar("trials") if not args.quiet else None
    try:
        summary = run_session(p, args.participant, db, _presenter_factory(args, p), seed=args.seed,
                              resume=args.resume, scale=args.scale, stimuli_root=None, allow_declared=args.simulate,
                              on_started=started, progress=(lambda d, t: bar(d, t)) if bar else None,
                              accept_slow=getattr(args, "accept_slow", False))
    except PresentationError as exc:  # no display, keyboard backend not ptb, an unreadable frame, ...
        if not session_started:
            raise
        raise PresentationError(f"{exc} (answers given so far are saved: continue with --resume)") from None
    catch = ""
    if summary.catch_total:
        verdict = {True: "passed", False: "FAILED", None: "pending"}[summary.catch_passed]
        catch = f"; catch trials {summary.catch_correct}/{summary.catch_total} correct ({verdict})"
    print(f"session {summary.session}: {summary.status}, {summary.answered}/{summary.planned} trials answered{catch}")
    return 0


#: The options of a participant's session, refused with ``run --preview`` (no participant, nothing stored).
_NOT_WITH_PREVIEW = ("participant", "db", "resume", "seed", "simulate", "accept_slow", "gaze_log")


def _cmd_preview(args) -> int:
    """``run --preview``: every condition of every scene once in the window, nothing stored, then the frame-rate
    table (:mod:`studyapp.runner.preview`)."""
    from studyapp.runner.preview import run_preview
    from studyapp.runner.session import StimulusSet

    given = [f"--{o.replace('_', '-')}" for o in _NOT_WITH_PREVIEW if getattr(args, o, None) not in (None, False)]
    if given:
        raise CLIError(f"--preview records nothing and has no participant: drop {', '.join(given)}")
    p, _ = checked_protocol(args, args.stimuli)
    _stimuli_for_run(args, p, None)  # a missing set: refused, or rendered first with --prepare
    run_preview(p, StimulusSet(p, args.scale), _presenter_factory(args, p), args.scale)
    return 0


def cmd_sessions(args) -> int:
    from data_schema.store import open_store

    db = Path(args.db)
    with open_store(db) as st:
        meta = st.meta()
        sessions = st.sessions()
        prog = st.progress()
        proto = st.protocol_json() or {}
        frac = _recorded_number(db, proto, "catch", "pass_fraction", 0.75)
        min_fps = _recorded_number(db, proto, "stimulus", "min_fps", None)
        flips = st.trial_flips()
        checks = {s["id"]: c for s in sessions if (c := st.fps_check(s["id"])) is not None}
        tidy = st.tidy_rows() if flips or checks else []
        # every trial that logged frames, references included (the tidy log has no references)
        trial_session = {k: st.response_session(*k) for k in flips}
        # trials of a condition below min_fps in the frame-rate check, run with --accept-slow
        check_slow = {(r["participant"], r["trial"]) for r in tidy if r["fps_check_slow"]}
    print(f"{db}: protocol {meta.get('protocol_name')} {meta.get('protocol_version')} "
          f"(sha256 {meta.get('protocol_hash', '')[:12]})")
    print(f"{'session':<16} {'participant':<12} {'status':<12} {'answers':>7}  {'started (UTC)':<27} resumed from")
    for s in sessions:
        print(f"{s['id']:<16} {s['participant']:<12} {s['status']:<12} {s['responses']:>7}  {s['started_utc']:<27} "
              f"{s['resumed_from'] or ''}")
    print(f"{'participant':<12} {'answered':>8} {'planned':>8}  catch trials (pass: >= {frac:.0%} correct)")
    for r in prog:
        catch = "-"
        if r["catch_planned"]:
            verdict = "pending" if r["answered"] < r["planned"] else (
                "passed" if r["catch_correct"] >= frac * r["catch_planned"] else "FAILED")
            catch = f"{r['catch_correct']}/{r['catch_planned']} {verdict}"
        print(f"{r['participant']:<12} {r['answered']:>8} {r['planned']:>8}  {catch}")
    if checks:
        _print_fps_checks(checks, check_slow, {(r["participant"], r["trial"]): r["session"] for r in tidy})
    if flips:
        _print_timing_qa(sessions, flips, trial_session, min_fps, check_slow)
    return 0


def _print_fps_checks(checks: dict, check_slow: set, trial_session: dict) -> None:
    """Each live session's frame-rate check before its first trial (:mod:`studyapp.runner.fpscheck`), and the
    trials flagged because it was run with ``--accept-slow`` (``check_slow``: (participant, trial))."""
    from studyapp.runner.fpscheck import table_lines

    nan = float("nan")
    for sid, rec in checks.items():
        rows = [{k: (nan if v is None else v) for k, v in r.items()} for r in rec["rows"]]
        lines = table_lines(rows, rec.get("min_fps"))
        print(f"session {sid}: {lines[0]}")
        for line in lines[1:]:
            print(line)
        if rec["accepted_slow"]:
            mine = sorted(k[1] for k in check_slow if trial_session.get(k) == sid)
            print(f"  run with --accept-slow: trials of {', '.join(rec['accepted_slow'])} flagged ("
                  + (f"trials {', '.join(map(str, mine))})" if mine else "none answered yet)"))


def _recorded_number(db: Path, proto: dict, section: str, key: str, default):
    """``proto[section][key]`` of a recorded protocol: a finite number (or ``default`` where absent)."""
    block = proto.get(section)
    value = block.get(key) if isinstance(block, dict) else None
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise CLIError(f"{db}: the recorded protocol's {section}.{key}={value!r} is not a number: the database was "
                       "not written by studyapp (restore its last good copy)")
    return float(value)


def _print_timing_qa(sessions, flips, trial_session, min_fps, check_slow=frozenset()) -> None:
    """Live trials: frame rate and gaze-to-flip latency per session, pooled over the flips of every trial;
    each trial's frame rate and frame time percentiles from its frame rows; flagged: trials with no frame rate
    (no stimulus with two rendered frames) and trials below the protocol's min_fps."""
    import numpy as np

    from data_schema.timing import format_fps, pooled, rates, summary

    floor = f"; trials below min_fps {min_fps:g} flagged" if min_fps else ""
    print(f"timing (live trials, pooled over their flips{floor}; trials with fewer than two rendered frames "
          "of a stimulus flagged)")
    print(f"{'session':<16} {'trials':>6} {'fps p50':>8} {'fps p5':>7} {'dropped':>8} {'lat p50':>8} {'lat p95':>8}"
          "  flagged")
    for s in sessions:
        keys = [k for k, sid in trial_session.items() if sid == s["id"] and k in flips]
        if not keys:
            continue
        t = pooled([flips[k] for k in keys])
        few = [str(k[1]) for k in keys if not rates(flips[k][0], flips[k][1], flips[k][4]).size]
        slow = [str(k[1]) for k in keys if min_fps and str(k[1]) not in few
                and not summary(*flips[k])["fps_median"] >= min_fps]
        flagged = "; ".join(([f"trials {', '.join(few)} (< 2 rendered frames)"] if few else [])
                            + ([f"trials {', '.join(slow)} (below min_fps)"] if slow else []))
        print(f"{s['id']:<16} {len(keys):>6} {format_fps(t['fps_median']):>8} {format_fps(t['fps_p5']):>7} "
              f"{t['dropped_share']:>7.1%} {t['latency_p50_ms']:>6.0f}ms {t['latency_p95_ms']:>6.0f}ms  "
              f"{('FLAGGED ' + flagged) if flagged else '-'}")
        for k in sorted(keys, key=lambda k: k[1]):  # each trial's frame times, from its frame rows
            ms = 1000.0 / rates(flips[k][0], flips[k][1], flips[k][4])
            times = (f"frame time p50 {np.percentile(ms, 50):.0f}ms p95 {np.percentile(ms, 95):.0f}ms"
                     if ms.size else "fewer than two rendered frames")
            one = summary(*flips[k])
            print(f"  trial {k[1]:<4} {k[0]:<12} fps p50 {format_fps(one['fps_median']):>6} "
                  f"p5 {format_fps(one['fps_p5']):>6}  {times}"
                  + ("  FLAGGED: below min_fps in the frame-rate check (--accept-slow)" if k in check_slow else ""))


def cmd_export(args) -> int:
    from data_schema import store
    from data_schema.atomic import check_target

    check_target(args.out, inputs=[args.db])
    fn = {"csv": store.export_csv, "parquet": store.export_parquet, "pwcmp": store.export_pwcmp,
          "frames": store.export_frames}[args.format]
    out = fn(args.db, args.out)
    print(out)
    return 0


# -- registration -------------------------------------------------------------------------------------------
def _full_option(parser) -> None:
    parser.add_argument("--full", action="store_true",
                        help="the protocol's full-size variant (its full block: render size and parameters such as "
                             "the seed's ground-truth samples; stimuli in STIMULI_DIR/full)")


def _set_options(parser, scale_help: str) -> None:
    """``--scale`` and ``--stimuli``: which stimulus set (``validate``, ``prepare`` and ``run`` alike)."""
    from data_schema.ranges import SCALE, argtype

    parser.add_argument("--scale", type=argtype("--scale", SCALE), default=1.0, metavar="F", help=scale_help)
    parser.add_argument("--stimuli", metavar="DIR", help="stimulus folder (default: the protocol's stimuli_dir)")


def _render_options(parser, one_machine_help: str) -> None:
    """Where ``prepare`` and ``run --prepare`` render: the cluster options and ``--yes-on-one-machine``."""
    from studyapp.cluster import add_arguments

    parser.add_argument("--yes-on-one-machine", action="store_true", help=one_machine_help)
    add_arguments(parser)


def register(subparsers, parser_class) -> None:
    from data_schema.ranges import SEED, argtype

    v = subparsers.add_parser("validate", help="check a study protocol (schema, references, schedule)",
                              description="Check a protocol YAML file against data_schema/protocol.schema.json "
                                          "and its cross-references; print its design and schedule size.")
    v.add_argument("protocol", metavar="PROTOCOL", help="protocol YAML file (or the name of a shipped one)")
    _set_options(v, "report the stimulus set prepared with --scale F as missing or complete (a live protocol: "
                    "the size rendered during its trials)")
    _full_option(v)
    v.set_defaults(func=cmd_validate)

    pr = subparsers.add_parser("prepare", help="render a protocol's whole stimulus set",
                               description="Build every stimulus of a protocol through the renderer registry "
                                           "and the stimulus cache, with a progress bar and the time left: one "
                                           "Dask task per frame on a local cluster (one worker per core), a "
                                           "running cluster (--scheduler) or in this process (--serial). Frames "
                                           "already in the cache are not rendered again, so a stopped prepare "
                                           "resumes where it stopped.")
    pr.add_argument("protocol", metavar="PROTOCOL")
    _set_options(pr, "shrink the resolution by F in (0, 1] for dry runs (stimuli in STIMULI_DIR/scaleF)")
    pr.add_argument("--cache", metavar="DIR", help="renderer cache folder (default: next to the stimuli)")
    _full_option(pr)
    _render_options(pr, "with --full and no --scheduler: render the full-size set on this machine anyway")
    pr.set_defaults(func=cmd_prepare, interrupted_hint=PREPARE_INTERRUPTED)

    from studyapp.presentation.base import END_KEY, ESCAPE, REPEAT_KEY, RESUME_KEY, SKIP_KEY

    r = subparsers.add_parser(
        "run", help="run (or resume) a participant's session",
        description="Run a participant's session of a protocol in a PsychoPy window, or with the simulated "
                    "observer (--simulate). Every answer is committed to the study database before the next trial. "
                    f"In the window, {ESCAPE.capitalize()} pauses the session at once (the trial is shown again): "
                    f"then {RESUME_KEY.upper()} resumes, {END_KEY.upper()} ends it (continue later with --resume). "
                    "With an eye tracker, calibration instructions and animated dots come first; after a failed "
                    f"validation the experimenter sees the error and presses {REPEAT_KEY.upper()} (repeat), "
                    f"{SKIP_KEY.upper()} (skip) or {END_KEY.upper()} (end). "
                    "Stimuli: a pre-rendered protocol's stimulus set must be prepared first; a missing set is "
                    "refused in one line naming it and the `studyapp prepare` command, unless --prepare is given "
                    "(then it is rendered first, with a progress bar and the time left). The database and the "
                    "participant (another protocol's database, an unknown or finished participant, a session still "
                    "running) are checked before anything is rendered. A live protocol renders during its trials, "
                    "at its render size times --scale; before its first trial each condition x scene is rendered "
                    "for stimulus.fps_check_s seconds (default 2) in the window and a condition below min_fps stops "
                    "the session (unless --accept-slow); --simulate has no such check. --preview is a windowed "
                    "dry run: every condition of every scene once, labelled, nothing stored, then the frame-rate "
                    "table.")
    r.add_argument("protocol", metavar="PROTOCOL")
    r.add_argument("--participant", metavar="ID", help="pseudonymous participant id (required, except with --preview)")
    r.add_argument("--preview", action="store_true",
                   help="a windowed dry run: every condition of every scene once, labelled, in the window "
                        "(pre-rendered or live, at --scale), then a live protocol's frame-rate table; no "
                        "participant, no answers collected, no database opened or created")
    r.add_argument("--db", metavar="FILE", help="study database (default: <protocol name>.db)")
    r.add_argument("--simulate", action="store_true",
                   help="simulated observer, no window; it needs no images of a condition that declares a quality "
                        "(it uses the declared quality), so only the other missing sets are refused")
    r.add_argument("--resume", action="store_true", help="continue at the participant's first unanswered trial")
    r.add_argument("--seed", type=argtype("--seed", SEED), metavar="N",
                   help="schedule seed (default: 0; stored per participant)")
    _set_options(r, "use the stimulus set prepared with --scale F (default: 1); a live protocol renders its "
                    "trials at its render size times F (the window stays the display's size)")
    r.add_argument("--prepare", action="store_true",
                   help="render the missing stimulus sets first (as `studyapp prepare` with the same PROTOCOL, "
                        "--scale, --stimuli, --full and cluster options), then run; without it a missing set is "
                        "refused")
    r.add_argument("--accept-slow", action="store_true",
                   help="live: run even if the frame-rate check before the first trial finds a condition below the "
                        "protocol's min_fps (recorded with the session; its slow trials are flagged on the console "
                        "and by `studyapp sessions`)")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    _full_option(r)
    r.add_argument("--eyetracker", choices=("mousegaze",),
                   help="record gaze through psychopy.iohub and flag trials where it left the fovea "
                        "(mousegaze: the mouse simulates the eye, for testing)")
    r.add_argument("--gaze-log", metavar="FILE", help="with --eyetracker: write gaze samples to this CSV")
    r.add_argument("--sim-delay", type=float, default=0.0, help=__import__("argparse").SUPPRESS)
    r.add_argument("--screenshot-dir", help=__import__("argparse").SUPPRESS)  # tests: back-buffer shots
    _render_options(r, "with --prepare --full and no --scheduler: render the full-size set on this machine")
    r.set_defaults(func=cmd_run, interrupted_hint=RUN_INTERRUPTED)

    s = subparsers.add_parser("sessions", help="list the sessions of a study database",
                              description="List sessions (status, answers, resumes) and per-participant progress.")
    s.add_argument("--db", metavar="FILE", required=True, help="study database")
    s.set_defaults(func=cmd_sessions)

    e = subparsers.add_parser("export", help="export the trial log (tidy CSV/Parquet, pwcmp)",
                              description="Export the tidy trial log (data_schema/trial_log.py columns) as CSV "
                                          "or Parquet, or the 2AFC trials in pwcmp's layout.")
    e.add_argument("--db", metavar="FILE", required=True, help="study database")
    e.add_argument("--format", choices=("csv", "parquet", "pwcmp", "frames"), default="csv",
                   help="csv/parquet: the tidy trial log (with live trials' timing columns); pwcmp: 2AFC trials in "
                        "pwcmp's layout; frames: every flip of the live trials (Parquet, or CSV for --out *.csv)")
    e.add_argument("--out", metavar="FILE", required=True)
    e.set_defaults(func=cmd_export)


# -- demo ----------------------------------------------------------------------------------------------------
#: (shipped protocol, simulated participants): the pre-rendered replications, and a live one (rendered at 64
#: pixels across along a synthetic gaze path by the simulated observer).
DEMO_PROTOCOLS = (("seed003_task1", 5), ("seed001_2afc", 3), ("seed001_pilot_live", 2))
DEMO_SCALE = 0.25


def demo_step(out_dir: Path, progress) -> list[Path]:
    """Run two shipped protocols with simulated participants (seed 003 Task 1: 5, seed 001 2AFC: 3).

    Stimuli: a synthetic set (procedural 'ground truth' degraded by each condition's declared quality with
    eccentricity-dependent blur and noise) at ``--scale 0.25``, so the observer answers from images. Writes a
    fresh database per protocol, the tidy CSVs and the pwcmp file into ``out_dir/study``.
    """
    from data_schema import families, store
    from studyapp.runner.stimuli import write_synthetic_stimuli

    out = Path(out_dir) / "study"
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for name, n_participants in DEMO_PROTOCOLS:
        p = _protocol(str(SHIPPED / f"{name}.yaml"), stimuli=str(out / "stimuli" / name), check_renderers=False)
        if progress:
            progress(f"{name}: synthetic stimuli")
        write_synthetic_stimuli(p, DEMO_SCALE, max_frames=2)
        db = simulated_study(p, out / f"{name}.db", n_participants, progress, scale=DEMO_SCALE)
        written += [db, store.export_csv(db, out / f"{name}_trials.csv")]
        if "pwcmp" in families.get(p.family).exports:
            written.append(store.export_pwcmp(db, out / f"{name}_pwcmp.csv"))
    return written


def simulated_study(protocol, db: Path, n: int, progress=None, **session) -> Path:
    """A fresh database ``db`` of ``n`` simulated participants ``P01``.. (seed 0) answering ``protocol``;
    ``session``: :func:`studyapp.runner.session.run_session`'s options (``scale``, ``allow_declared``)."""
    from studyapp.runner.observer import SimulatedObserver
    from studyapp.runner.session import ground_truth_stimuli, run_session

    for suffix in ("", "-wal", "-shm"):
        Path(str(db) + suffix).unlink(missing_ok=True)
    for i in range(1, n + 1):
        pid = f"P{i:02d}"
        if progress:
            progress(f"{protocol.name}: simulated participant {pid}")
        run_session(protocol, pid, db, lambda st, d, pid=pid: SimulatedObserver(
            protocol, pid, 0, ground_truth_stimuli(protocol, st)), seed=0, **session)
    return db


def main(argv=None) -> int:
    """Stand-alone entry (``python -m studyapp.commands.study``): the studyapp CLI with these commands added
    if it does not list them yet (same one-line errors and exit codes)."""
    from studyapp import cli

    if __name__ not in cli.COMMAND_MODULES and "studyapp.commands.study" not in cli.COMMAND_MODULES:
        cli.COMMAND_MODULES = tuple(cli.COMMAND_MODULES) + ("studyapp.commands.study",)
    return cli.main(argv)


if __name__ == "__main__":
    raise SystemExit(main())
