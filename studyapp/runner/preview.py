"""``studyapp run PROTOCOL --preview``: a windowed dry run (issue 26, item 9).

Every condition of every scene (:func:`preview_cells`) is shown once in the window as the participant would
see it, labelled with the condition and the scene and answered with no key: a sequence or a live stimulus
plays for its duration, a still image stays until SPACE. Escape pauses as in a session (R resumes the
preview, E ends it). Then a live protocol's frame-rate check (:mod:`.fpscheck`) is run in the same window at
the same ``--scale`` and its table printed; a condition below ``min_fps`` is marked in the table, never
refused (a preview is for finding that out).

Nothing is stored: the preview opens no study database (none is created or read; no participant, seed or
schedule), it collects no answers, and writes nothing but the console lines.
"""

from __future__ import annotations

from collections.abc import Callable

from data_schema import families

from studyapp.presentation.base import CONTINUE_KEY, ESCAPE, END_KEY, RESUME_KEY, TrialDisplay, key_text

from .fpscheck import measure, seconds_per_cell, table_lines
from .protocol import Protocol


def preview_cells(protocol: Protocol) -> list[tuple[str, str]]:
    """The (condition, scene) pairs a preview shows, scene by scene: the design's conditions, then the reference
    (the ground truth shown before a trial) where the design does not hold it."""
    conds = list(protocol.design_conditions)
    if protocol.reference and protocol.reference not in conds:
        conds.append(protocol.reference)
    return [(c, s) for s in protocol.scenes for c in conds]


def preview_text(protocol: Protocol, n: int) -> str:
    """The screen before the preview: what it shows and the keys."""
    return (f"Preview of {protocol.name}: each of its {n} condition x scene pairs is shown once, labelled; "
            "nothing is recorded.\n\n"
            + ("Each plays for its duration. " if protocol.stimulus_kind in ("sequence", "live")
               else f"Press {key_text(CONTINUE_KEY)} for the next one. ")
            + f"{key_text(ESCAPE)} pauses: then {key_text(RESUME_KEY)} resumes, {key_text(END_KEY)} ends the preview.")


def preview_trials(protocol: Protocol, stimuli) -> list[TrialDisplay]:
    """One labelled, unanswered display per :func:`preview_cells` pair (``stimuli``: the run's
    :class:`~studyapp.runner.session.StimulusSet`)."""
    cells = preview_cells(protocol)
    timed = protocol.stimulus_kind in ("sequence", "live")
    out = []
    for k, (cond, scene) in enumerate(cells):
        out.append(TrialDisplay(
            index=k, family=families.single_stimulus().name, stimuli=(stimuli.stimulus(cond, scene),), question="",
            answer_keys={} if timed else {CONTINUE_KEY: "seen"},
            duration_s=protocol.duration_s if timed else None, black_before_s=protocol.black_s,
            label=f"preview {k + 1} / {len(cells)}: {cond} in {scene}", scene=scene, kind="reference",
            key_reminder=protocol.key_reminder))
    return out


def run_preview(protocol: Protocol, stimuli, presenter_factory: Callable, scale: float = 1.0,
                console: Callable[[str], None] = print) -> dict:
    """Show :func:`preview_trials` in the presenter's window, then (live) the frame-rate check; print the table.

    Returns ``{"shown": pairs shown, "planned": pairs, "ended": ended with Escape then E, "rows": the check's
    rows (empty: pre-rendered, or ended)}``."""
    if protocol.live:  # a live render too small for a renderer: refused before the window opens
        from .live import check_live_sizes

        check_live_sizes(protocol, scale)
    presenter = presenter_factory(stimuli, protocol.display)
    presenter.open(protocol.display)
    trials = preview_trials(protocol, stimuli)
    shown, ended, rows = 0, False, []
    try:
        presenter.instructions(preview_text(protocol, len(trials)))
        for d in trials:
            presenter.preload(d)
            while presenter.present(d).escaped:
                if presenter.pause() == "end":
                    ended = True
                    break
            if ended:
                break
            shown += 1
        check = getattr(presenter, "fps_check_frames", None)
        seconds = seconds_per_cell(protocol)
        if protocol.live and check is not None and not ended and seconds:
            presenter.message("Measuring the frame rate of each condition ...", 0.0)
            rows = measure(protocol, scale, check, seconds)
    finally:
        presenter.close()
    console(f"preview: {shown} of {len(trials)} condition x scene pairs shown" + (" (ended with E)" if ended else "")
            + "; nothing was recorded")
    if rows:
        for line in table_lines(rows, protocol.min_fps):
            console(line)
    elif protocol.live and not ended:
        console("frame-rate check: off (stimulus.fps_check_s: 0)" if not seconds else
                "frame-rate check: none (no window)")
    return {"shown": shown, "planned": len(trials), "ended": ended, "rows": rows}
