"""The ``studyapp`` command line.

Every command reports bad input as one line ``studyapp: error: ...`` on stderr and exits with status 2;
nothing it writes is left half-written (files are written to a temporary name, then renamed).
"""

from __future__ import annotations

import argparse
import json
import re
import signal
import sys
from pathlib import Path

from data_schema.errors import EXIT_USAGE, CLIError, UserError

from . import __version__
from .commands import end_status as _end_progress
from .commands import status as _progress

# Command groups living in their own modules (see studyapp/commands/__init__.py). One line each.
COMMAND_MODULES = (
    "studyapp.commands.analyze",
    "studyapp.commands.quality",
    "studyapp.commands.render",
    "studyapp.commands.study",
    "studyapp.commands.lightcuts",
    "studyapp.commands.replay",
    "studyapp.commands.power",
)


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, not usage + message
        # "argument --seed: --seed=-1 is out of range ..." says the option twice: keep the second.
        message = re.sub(r"^argument (\S+): (?=\1=)", "", message)
        raise CLIError(f"{self.prog}: {message}")


# --- foveation ------------------------------------------------------------------------------------------------
def _foveation_table(fov_y: float, out: Path | None):
    """Compute Table 1 and the preset reductions; write them into ``out`` if given. Returns rows, md, paths."""
    from data_schema.atomic import write_text
    from renderers.foveation import table as T

    rows = T.table1(fov_y, progress=_progress)
    presets = T.preset_reductions(fov_y)
    _end_progress()
    md = T.table1_markdown(rows, presets, fov_y)
    paths = []
    if out is not None:
        paths = [write_text(out / "table1.md", md), write_text(out / "table1.csv", T.rows_csv(rows)),
                 write_text(out / "vafr_presets.csv", T.rows_csv(presets)),
                 write_text(out / "table1.json", json.dumps(T.rows_json(rows), indent=2) + "\n")]
    return rows, md, paths


def _out_folder(path) -> Path | None:
    """``--out DIR`` checked before any work: a device node, FIFO, socket or file is refused in one line."""
    from data_schema.atomic import real_folder

    if path is None:
        return None
    real_folder(path, "--out")
    return Path(path)


def cmd_foveation_table(args) -> int:
    from renderers.foveation import table as T

    _out_folder(args.out)
    rows, md, paths = _foveation_table(args.fov_y, Path(args.out) if args.out else None)
    if args.out:
        if not args.json:
            for p in paths:
                print(p)
    if args.json:
        print(json.dumps(T.rows_json(rows), indent=2))
    elif not args.out:
        print(md, end="")
    return 0


def cmd_foveation_plots(args) -> int:
    from renderers.foveation.plots import write_plots

    _out_folder(args.out)
    for p in write_plots(args.out, args.fov_y):
        print(p)
    return 0


# --- demo -----------------------------------------------------------------------------------------------------
#: Demo steps after the foveation table and plots: (command module, output sub-folder, what it shows).
DEMO_STEPS = (
    ("studyapp.commands.render", "render",
     "stimuli: the Cornell box with GT and the foveated renderers, on the CPU and the GPU backend"),
    ("studyapp.commands.lightcuts", "lightcuts", "a lightcuts stimulus: cornell_many (111,858 lights), fsl"),
    ("studyapp.commands.study", "", "simulated participants run two shipped protocols into fresh databases"),
    ("studyapp.commands.analyze", "analysis", "analysis of the simulated studies and of synthetic seed logs"),
    ("studyapp.commands.power", "thresholds", "a threshold study (threshold_foveation): simulated participants, "
     "psychometric fits, the speed at threshold (Pareto figure)"),
)


def cmd_demo(args) -> int:
    import importlib
    import time

    from renderers.foveation.plots import write_plots

    out = _out_folder(args.out)
    fov_dir = out / "foveation"
    n = 2 + len(DEMO_STEPS)
    print(f"[1/{n}] foveation table (seed 001 Table 1) -> {fov_dir}", flush=True)
    _, md, written = _foveation_table(args.fov_y, fov_dir)
    print(f"[2/{n}] shading-rate plots (seed 001 Fig 5, 8, 9, 10, 21) -> {fov_dir}", flush=True)
    written += write_plots(fov_dir, args.fov_y)
    print(md)
    for i, (module, sub, what) in enumerate(DEMO_STEPS, start=3):
        print(f"[{i}/{n}] {what} -> {out / sub}", flush=True)
        t0 = time.perf_counter()
        step = importlib.import_module(module).demo_step
        paths = step(out / sub, _progress)
        _end_progress()
        written += paths
        print(f"      {len(paths)} files in {time.perf_counter() - t0:.1f} s", flush=True)
        for p in paths:
            if p.name == "report.md":
                print(f"      report: {p}")
    print(f"Demo output: {len(written)} files under {out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    from data_schema.ranges import FOV_Y, argtype

    fov_arg = argtype("--fov-y", FOV_Y)
    p = _Parser(prog="studyapp", description=(
        "Perceptual user studies of foveated rendering. Render stimuli with GT and foveated renderers "
        "(render, scenes, renderers), run studies from protocol files with PsychoPy or a simulated observer "
        "(validate, prepare, run, sessions, export), and regenerate the papers' tables and figures from the "
        "logs (analyze, quality). 'studyapp demo' runs everything end to end. Bad input: one line "
        "'studyapp: error: ...' and exit status 2."))
    p.add_argument("--version", action="version", version=f"studyapp {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    fov = sub.add_parser("foveation", help="log-polar foveation mappings: shading-point table and rate plots",
                         description="Shading-point counts (seed 001 Table 1) and shading-rate plots "
                                     "(seed 001 Fig 5, 8, 9, 10, 21) of VaFR, LMFR and LaFR.")
    fsub = fov.add_subparsers(dest="fov_command", metavar="SUBCOMMAND", parser_class=_Parser)
    fsub.required = True
    t = fsub.add_parser("table", help="shading points per eye at 2K ... retinal (seed 001 Table 1)",
                        description="Print seed 001 Table 1 (shading points per eye for VaFR_Dup, LaFR(2.2), "
                                    "LaFR(1.8), LMFR(1.8), GT at 2K, 4K, 6K, 8K and retinal resolution) as "
                                    "Markdown, and the VaFR preset reductions.")
    t.add_argument("--json", action="store_true",
                   help="print a JSON list of records (method, width, height, shading_points, "
                        "shading_points_on_screen, ...) instead of Markdown")
    t.add_argument("--out", metavar="DIR", help="also write table1.md, table1.csv, table1.json and "
                                                "vafr_presets.csv into DIR")
    t.add_argument("--fov-y", type=fov_arg, default=100.0, metavar="DEG",
                   help="vertical field of view in degrees, in (0, 180) (default: 100)")
    t.set_defaults(func=cmd_foveation_table)
    pl = fsub.add_parser("plots", help="PNG plots of shading rate vs eccentricity",
                         description="Write PNG plots of radial (and tangential) shading rate against "
                                     "eccentricity, with the acuity curve, reproducing seed 001 Figures 5, 8, "
                                     "9, 10 and 21.")
    pl.add_argument("--out", metavar="DIR", required=True, help="folder for the PNG files (created if needed)")
    pl.add_argument("--fov-y", type=fov_arg, default=100.0, metavar="DEG",
                    help="vertical field of view in degrees, in (0, 180) (default: 100)")
    pl.set_defaults(func=cmd_foveation_plots)

    d = sub.add_parser("demo", help="the end-to-end demo (writes everything into one folder)",
                       description="Run the end-to-end demo into one folder: the foveation table and plots, "
                                   "a small rendered stimulus set, simulated participants running shipped "
                                   "protocols, and the analysis of their logs and of synthetic seed-sized logs.")
    d.add_argument("--out", metavar="DIR", default="demo_out", help="output folder (default: demo_out)")
    d.add_argument("--fov-y", type=fov_arg, default=100.0, metavar="DEG",
                   help="vertical field of view in degrees, in (0, 180) (default: 100)")
    d.set_defaults(func=cmd_demo, interrupted_hint="the steps finished so far are kept in the output folder")

    import importlib

    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub, _Parser)
    return p


#: What ``studyapp: interrupted (...)`` adds when a command is stopped by Ctrl-C or SIGTERM, unless the command
#: registered its own hint with ``parser.set_defaults(interrupted_hint=...)`` (``run``: its --resume hint,
#: ``prepare``: the frame cache). Commands write through temporary files, so a stopped one leaves nothing.
INTERRUPTED_HINT = "nothing was written"


def interrupted_hint(args) -> str:
    """The hint printed when the command of ``args`` (None: not parsed yet) is interrupted."""
    return getattr(args, "interrupted_hint", None) or INTERRUPTED_HINT


class Terminated(KeyboardInterrupt):
    """SIGTERM, handled like Ctrl-C: the command stops cleanly (a session is marked, nothing half-written)."""


def _on_sigterm(signum, frame):
    raise Terminated()


def main(argv=None) -> int:
    parser = build_parser()
    if signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, None):
        signal.signal(signal.SIGTERM, _on_sigterm)
    args = None
    try:
        args = parser.parse_args(argv)
        return args.func(args)
    except UserError as exc:  # bad input: one line; any other exception is a bug and keeps its traceback
        print(f"studyapp: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except BrokenPipeError:  # e.g. 'studyapp renderers | head': the reader left, nothing to report
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:
        print(f"studyapp: error: {exc.strerror or exc}: {exc.filename or ''}".rstrip(": "), file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt as exc:
        what = "terminated" if isinstance(exc, Terminated) else "interrupted"
        print(f"studyapp: {what} ({interrupted_hint(args)})", file=sys.stderr)
        return 143 if isinstance(exc, Terminated) else 130


if __name__ == "__main__":
    raise SystemExit(main())
