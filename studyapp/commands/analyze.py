"""``studyapp analyze``: every table and figure of a study's analysis plan, from its log."""

from __future__ import annotations

import json
from pathlib import Path

from data_schema.errors import CLIError

from . import end_status, status


def _vocabulary():
    """``analysis.vocabulary``, the one declaration of the plan's names (cheap: the analysis package loads
    its statistics lazily)."""
    import analysis.vocabulary

    return analysis.vocabulary


HELP = "regenerate a study's tables and figures from its log (CSV, Parquet or study database)"
DESCRIPTION = """\
Analyse a study's trial log and write every table and figure its analysis plan asks for:
votes per mode and scene (seed 001 Fig 14-15), Kruskal-Wallis over all conditions, Kruskal-Wallis
on every pair with Holm-adjusted p in the seeds' '/' layout (seed 001 Tables 2-3), Dunn's test,
avg ± std / p / Cohen's d / effect-size label against the reference (seed 003 Tables 5-6), per-scene
and per-block breakdowns, Thurstone (JOD) / Bradley-Terry / Plackett-Luce scales with bootstrap
intervals, and logistic GEE odds ratios against the reference (--test ... gee).
Output: DIR/report.md, DIR/tables/*.md|.tex|.csv, DIR/figures/*.png, DIR/analysis.json. The plan
comes from the study database (its protocol's analysis block), from --plan, or from the options
below; options override the plan. An adaptive (threshold) protocol gets psignifit 4 fits per participant,
renderer and scene and pooled, the group table and the speed at threshold (Pareto figure) instead
(docs/thresholds.md). The same input gives byte-identical output."""


def register(sub, parser_class) -> None:
    voc = _vocabulary()
    UNITS, TESTS, PRIORS, DEFAULT_TESTS = voc.UNITS, voc.TESTS, voc.PRIORS, voc.DEFAULT_TESTS  # noqa: N806
    a = sub.add_parser("analyze", help=HELP, description=DESCRIPTION)
    a.add_argument("log", metavar="STUDY.db|LOG.csv|LOG.parquet", help="the trial log (tidy layout, one row "
                   "per trial; see data_schema/trial_log.py) or a study database")
    a.add_argument("--out", metavar="DIR", required=True, help="output folder (created if needed)")
    a.add_argument("--json", action="store_true", help="also print the results as JSON on stdout")
    a.add_argument("--plan", metavar="FILE", help="YAML file: a protocol with an 'analysis:' block, or the "
                   "block itself")
    a.add_argument("--reference", metavar="COND", help="reference condition (summary table, JOD zero); "
                   "default: the plan's, else the first condition")
    a.add_argument("--unit", choices=list(UNITS), help="unit of analysis (default: participant): "
                   + "; ".join(f"{k}: {v}" for k, v in UNITS.items()))
    a.add_argument("--test", choices=list(TESTS), nargs="+", metavar="TEST",
                   help="what to report, one or more of: " + "; ".join(f"{k}: {v}" for k, v in TESTS.items())
                   + f" (default: the plan's, else {' '.join(DEFAULT_TESTS)}; the votes table and the "
                   "Kruskal-Wallis omnibus test always)")
    a.add_argument("--prior", choices=list(PRIORS), help="prior of the paired-comparison scales (default: the "
                   "plan's, else weak): " + "; ".join(f"{k}: {v}" for k, v in PRIORS.items()))
    a.add_argument("--conditions", metavar="A,B,...", help="conditions in table order (all must occur)")
    a.add_argument("--paired", action="store_true", default=None,
                   help="paired Cohen's d_z over participants (needs --unit participant)")
    a.add_argument("--n-boot", type=int, metavar="N", help="bootstrap replicates of the scales (default 1000)")
    a.add_argument("--seed", type=int, metavar="N", help="bootstrap seed (default 0)")
    a.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    a.add_argument("--protocol", metavar="FILE", help="adaptive designs from a CSV/Parquet log: the protocol it "
                   "was run with (a study database records its own)")
    a.add_argument("--cost-scale", type=_cost_scale, default=1.0, metavar="S",
                   help="adaptive designs: count the cost at threshold on frames of the render size times S "
                   "(default 1: the study's size; smaller is faster, the counts of GT and LaFR shrink with it)")
    a.add_argument("--cache", metavar="DIR", help="adaptive designs: the stimulus cache the cost's frames are "
                   "read from or rendered into (default: none, rendered in memory)")
    a.add_argument("--frame-times", metavar="CSV", help="adaptive designs: the ladders' frame times on one "
                   "backend (benchmarks/bench_thresholds.py --ladder-times PROTOCOL --scale S, S the --cost-scale): "
                   "the Pareto table gains the time at threshold and GT's")
    a.set_defaults(func=cmd_analyze)


def _cost_scale(text: str) -> float:
    from data_schema.ranges import SCALE, argtype

    return argtype("--cost-scale", SCALE)(text)


def adaptive_protocol(log: Path, protocol_file: str | None):
    """The protocol of an adaptive threshold study (None: a fixed design): ``--protocol``, else the one a study
    database recorded."""
    from studyapp.runner.protocol import load_protocol, protocol_from_data

    if protocol_file:
        protocol = load_protocol(protocol_file)
    elif log.suffix.lower() in (".db", ".sqlite", ".sqlite3"):
        from data_schema.store import open_store

        with open_store(log) as st:
            data = st.protocol_json()
        if not data or "adaptive" not in (data.get("design") or {}):
            return None
        protocol = protocol_from_data(data, f"{log}#protocol")
    else:
        return None
    return protocol if getattr(protocol, "adaptive", None) is not None else None


def write_thresholds(log: Path, protocol, out: Path, *, figures: bool = True, cost_scale: float = 1.0,
                     cache: str | None = None, n_boot: int | None = None, seed: int | None = None,
                     title: str | None = None, times: str | None = None) -> list[Path]:
    """A threshold study's report (fits, group table, Pareto table and figure) into ``out``, whole or not at
    all."""
    from analysis.io import read_log
    from analysis.report import write_threshold_report
    from data_schema.atomic import atomic_dir
    from studyapp.runner.threshold_study import analyze_thresholds

    res = analyze_thresholds(read_log(log), protocol, n_boot=2000 if n_boot is None else n_boot,
                             seed=seed or 0, cost_scale=cost_scale, cache_dir=Path(cache) if cache else None,
                             progress=_progress, times=Path(times) if times else None)
    with atomic_dir(out, marker="analysis.json") as tmp:
        paths = write_threshold_report(res, tmp, title=title or f"Thresholds of {log.name} ({protocol.name})",
                                       figures=figures, progress=_progress)
    return [out / p.relative_to(tmp) for p in paths]


def _progress(msg: str) -> None:
    status(msg, "analyze: ")


def load_plan(log: Path, plan_file: str | None):
    """The analysis plan: --plan file, else the database's protocol plan, else the defaults."""
    if plan_file:
        from data_schema.yamlfile import load_yaml

        data = load_yaml(plan_file, "analysis plan").data  # before importing the statistics (~2 s)
        from analysis.plan import plan_from_mapping

        if isinstance(data, dict) and "analysis" in data:
            data = data["analysis"]
        try:
            return plan_from_mapping(data)
        except ValueError as exc:
            raise CLIError(f"--plan {plan_file}: {exc}") from None
    from analysis.plan import plan_from_mapping

    if log.suffix.lower() in (".db", ".sqlite", ".sqlite3"):
        from data_schema.store import read_analysis_plan

        return plan_from_mapping(read_analysis_plan(log))
    return plan_from_mapping(None)


def cmd_analyze(args) -> int:
    from data_schema.atomic import atomic_dir, check_dir_target

    log = Path(args.log)
    protocol = adaptive_protocol(log, args.protocol)
    if protocol is not None:  # an adaptive design: psychometric fits and the Pareto front, not the fixed tests
        out = check_dir_target(args.out, marker="analysis.json")
        if args.cache:
            from data_schema.atomic import real_folder

            real_folder(args.cache, "--cache")
        paths = write_thresholds(log, protocol, out, figures=not args.no_figures, cost_scale=args.cost_scale,
                                 cache=args.cache, n_boot=args.n_boot, seed=args.seed, times=args.frame_times)
        end_status()
        print(f"wrote {len(paths)} files into {args.out} (report: {Path(args.out) / 'report.md'})")
        return 0
    plan = load_plan(log, args.plan)
    from analysis.io import read_log
    from analysis.report import report_json, write_report
    from analysis.study import analyze_log

    conditions = None
    if args.conditions is not None:
        conditions = tuple(c.strip() for c in args.conditions.split(",") if c.strip())
    tests = tuple(dict.fromkeys(args.test)) if args.test else None
    plan = plan.with_overrides(reference=args.reference, unit=args.unit, tests=tests, prior=args.prior,
                               conditions=conditions, paired=args.paired, n_boot=args.n_boot, seed=args.seed)
    out = check_dir_target(args.out, marker="analysis.json")
    df = read_log(log)
    _progress(f"{len(df):,} trials read")
    result = analyze_log(df, plan, progress=_progress)
    # Into a temporary folder first: a full disk or Ctrl-C leaves no half-written report behind.
    with atomic_dir(out, marker="analysis.json") as tmp:
        paths = write_report(result, tmp, title=f"Analysis of {log.name}", figures=not args.no_figures,
                             progress=_progress)
    paths = [out / p.relative_to(tmp) for p in paths]
    end_status()
    if args.json:
        print(json.dumps(report_json(result), indent=2))
    else:
        print(f"wrote {len(paths)} files into {args.out} (report: {Path(args.out) / 'report.md'})")
    return 0


def demo_step(out_dir: Path, progress=None) -> list[Path]:
    """Analyse the demo's simulated studies (their databases, with their protocols' plans) and synthetic logs
    of the seeds' sizes (seed 001's 4,500-trial 2AFC study, seed 003 Tables 5-6)."""
    from analysis.io import read_log, validate_log
    from analysis.plan import AnalysisPlan
    from analysis.report import write_report
    from analysis.study import analyze_log
    from analysis.synthetic import SEED001_MODES, SEED003_TABLES, seed001_2afc_log, seed003_yes_no_log
    from analysis.tables import to_csv
    from data_schema.atomic import write_text
    from data_schema.names import inside

    written = []
    # 1. The studies the simulated participants just ran (studyapp.commands.study.demo_step), if any.
    for db in sorted((Path(out_dir).parent / "study").glob("*.db")):
        if progress:
            progress(f"analyze: {db.name}")
        plan = load_plan(db, None).with_overrides(n_boot=200)
        written += write_report(analyze_log(read_log(db), plan), inside(out_dir, f"simulated_{db.stem}"),
                                title=f"Simulated study {db.stem} (studyapp run --simulate)")
    # 2. Synthetic logs of the seeds' sizes: seed 001 Table 3 layout, seed 003 Tables 5-6.
    log = seed001_2afc_log(seed=0)
    written.append(write_text(out_dir / "synthetic_seed001_2afc" / "log.csv", to_csv(log)))
    plan = AnalysisPlan(conditions=SEED001_MODES, reference="GT", n_boot=200)
    written += write_report(analyze_log(validate_log(log), plan), out_dir / "synthetic_seed001_2afc",
                            title="Synthetic seed 001 2AFC study (4,500 trials)")
    for table in (5, 6):
        log = seed003_yes_no_log(table, seed=0)
        d = out_dir / f"synthetic_seed003_table{table}"
        written.append(write_text(d / "log.csv", to_csv(log)))
        plan = AnalysisPlan(unit="trial", tests=("summary_table", "gee"), reference="EC",
                            conditions=tuple(SEED003_TABLES[table]), n_boot=0)
        written += write_report(analyze_log(validate_log(log), plan), d,
                                title=f"Synthetic seed 003 Task {table - 4} (Table {table})")
    return written
