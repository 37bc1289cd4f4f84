"""``studyapp power``: plan a threshold study by simulating it with the declared psychometric observer."""

from __future__ import annotations

from data_schema.ranges import SEED, Range, argtype

HELP = "plan a threshold study: expected CI widths and the chance to tell renderers apart (simulated)"
DESCRIPTION = """\
Simulate an adaptive threshold protocol with N participants answering from its declared psychometric
functions (simulation.psychometric), REPLICATIONS times, fit every simulated participant as 'studyapp
analyze' does (psignifit 4), and print per threshold the expected width of a participant's 95 % credible
interval and of the group mean's 95 % bootstrap interval (strength-axis units: log10 of the level for a
log domain), and per pair of renderers and scene the probability that a paired t-test over the
participants tells their thresholds apart at the protocol's analysis.alpha. The same seed gives the same
output."""


def register(sub, parser_class) -> None:
    p = sub.add_parser("power", help=HELP, description=DESCRIPTION)
    p.add_argument("protocol", metavar="PROTOCOL", help="an adaptive protocol file with simulation.psychometric, "
                   "or a shipped one by name (threshold_foveation)")
    p.add_argument("--participants", type=argtype("--participants", Range(1, 1000, integer=True)), required=True,
                   metavar="N", help="participants per simulated study, in [1, 1000]")
    p.add_argument("--trials", type=argtype("--trials", Range(2, 10000, integer=True)), metavar="T",
                   help="trials per procedure (default: the protocol's stop.trials)")
    p.add_argument("--replications", type=argtype("--replications", Range(1, 10000, integer=True)), default=20,
                   metavar="R",
                   help="simulated studies (default 20)")
    p.add_argument("--seed", type=argtype("--seed", SEED), default=0, metavar="S", help="seed (default 0)")
    p.add_argument("--cost-scale", type=argtype("--cost-scale", Range(0.0, 1.0, low_open=True)), default=0.25,
                   metavar="S", help="renderers varying different parameters are compared on their cost at "
                   "threshold, counted on frames of the render size times S (default 0.25)")
    p.set_defaults(func=cmd_power)


def cmd_power(args) -> int:
    from studyapp.progress import Bar
    from studyapp.runner.threshold_study import power_analysis

    from . import end_status, status
    from .study import _protocol

    protocol = _protocol(args.protocol)  # a file, or a shipped protocol by name
    if getattr(protocol, "adaptive", None) is None:
        from data_schema.errors import UserError

        raise UserError(f"{args.protocol}: protocol {protocol.name} has no adaptive design (design.adaptive)")
    status(f"cost of the ladders for protocol {protocol.name}", "power: ")
    widths, pairs = power_analysis(protocol, args.participants, trials=args.trials,
                                   replications=args.replications, seed=args.seed, cost_scale=args.cost_scale,
                                   progress=Bar("fits"))
    end_status()
    print(f"{protocol.name}: {args.participants} participants, "
          f"{args.trials or protocol.adaptive.cap} trials per procedure, {args.replications} simulated studies, "
          f"seed {args.seed}")
    print(format_power(widths, pairs))
    return 0


def format_power(widths, pairs) -> str:
    """The two tables as aligned text."""
    lines = ["", "expected 95 % interval widths (strength axis; log10 units for a log domain):",
             f"{'condition':<12} {'scene':<16} {'axis':<7} {'participant CI':>14} {'group CI':>9} "
             f"{'not estimable':>13}"]
    for r in widths.itertuples():
        lines.append(f"{r.condition:<12} {r.scene:<16} {r.axis:<7} {r.participant_ci_width:>14.3f} "
                     f"{r.group_ci_width:>9.3f} {r.not_estimable:>13.0%}")
    lines += ["", "probability that two renderers' thresholds are told apart (paired t-test, alpha "
              f"{pairs['alpha'].iloc[0] if len(pairs) else 0.05:g}):",
              f"{'renderers':<26} {'scene':<16} {'compared on':<14} {'P(told apart)':>13}"]
    for r in pairs.itertuples():
        lines.append(f"{r.a + ' vs ' + r.b:<26} {r.scene:<16} {r.unit:<14} {r.p_told_apart:>13.0%}")
    return "\n".join(lines)


#: The demo's threshold study: protocol, simulated participants.
DEMO_THRESHOLD = ("threshold_foveation", 8)


def demo_step(out_dir, progress=None) -> list:
    """The demo's threshold study: simulated participants (the protocol's declared psychometric observer, no
    images needed) run ``threshold_foveation`` into a fresh database, then its analysis as ``studyapp analyze``
    writes it, the cost of each ladder counted at the study's size (frames in ``out_dir/cost_cache``); ends with
    the Pareto table printed and the Pareto figure's path."""
    from pathlib import Path

    from data_schema import store

    from .analyze import write_thresholds
    from .study import SHIPPED, _protocol, simulated_study

    name, n = DEMO_THRESHOLD
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    p = _protocol(str(SHIPPED / f"{name}.yaml"), stimuli=str(out / "stimuli"))
    db = simulated_study(p, out / f"{name}.db", n, progress, allow_declared=True)
    written = [db, store.export_csv(db, out / f"{name}_trials.csv")]
    written += write_thresholds(db, p, out / "analysis", cache=str(out / "cost_cache"), n_boot=1000,
                                title=f"Simulated threshold study {name} ({n} participants)")
    table = (out / "analysis" / "tables" / "thresholds_pareto.md").read_text()
    print("\n" + table, flush=True)
    print(f"      Pareto figure: {out / 'analysis' / 'figures' / 'pareto.png'}", flush=True)
    return written
