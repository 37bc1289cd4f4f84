"""The analysis vocabulary, declared once: tests, units of analysis, dependent variables and scaling priors.

Everything that names an analysis choice reads it from here:

* :class:`analysis.plan.AnalysisPlan` validates its fields against these names (no value stands for another),
* ``studyapp analyze`` takes its ``--test``, ``--unit`` and ``--prior`` choices from them,
* the ``$defs.analysis`` block of ``data_schema/protocol.schema.json`` carries them as enums; it is generated
  by ``python -m analysis.vocabulary --write-schema`` (``--check`` exits 1 if the shipped file differs), and a
  test asserts the shipped file equals the generated one.

Every name maps to a one-line description (used in the schema, the CLI help and the docs).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from data_schema import families as _families

__all__ = ["DEFAULT_TESTS", "DVS", "PRIORS", "TESTS", "UNITS", "render_schema_block", "schema_path",
           "write_schema"]

#: What a plan's ``test`` list may ask for; each name is one set of tables of the report. The votes table and
#: the Kruskal-Wallis test over all conditions (``<family>_omnibus``) are always reported.
TESTS: dict[str, str] = {
    "summary_table": "each condition against the reference: mean ± SD, two-sided Mann-Whitney p (unadjusted), "
                     "Cohen's d and its label (seed 003 Tables 5-6)",
    "pairwise_kruskal": "Kruskal-Wallis on every pair of conditions, Holm-adjusted across the pairs "
                        "(seed 001 Tables 2-3)",
    "kruskal_dunn": "Dunn's two-sided post-hoc test on every pair after the Kruskal-Wallis omnibus test, "
                    "Holm-adjusted",
    "thurstone": "Thurstone Case V scale in JOD units with bootstrap intervals (2AFC trials)",
    "bradley_terry": "Bradley-Terry log-strengths with bootstrap intervals (2AFC trials)",
    "plackett_luce": "Plackett-Luce log-strengths of top-two-of-N choices with bootstrap intervals "
                     "(preference trials)",
    "gee": "logistic GEE (participants as clusters, exchangeable working correlation, robust SEs): odds ratios "
           "against the reference of yes answers, and of 2AFC choices in the trials that show the reference",
}

#: The plan's default when none is given (a bare CSV log): every seed-style table (``gee`` only when asked for).
DEFAULT_TESTS: tuple[str, ...] = ("summary_table", "pairwise_kruskal", "kruskal_dunn", "thurstone",
                                  "bradley_terry", "plackett_luce")

#: Units of analysis: the rows the rank tests and the summary table compare.
UNITS: dict[str, str] = {
    "participant": "one value per participant and condition (votes, or mean score)",
    "participant_block": "one value per participant, block (e.g. headset) and condition",
    "participant_scene": "one value per participant, scene and condition",
    "trial": "every trial is one observation (as seed 003 Tables 5-6)",
}

#: Dependent variables; each fits some trial families only.
DVS: dict[str, str] = {
    "response": "yes/no trials: the answer, 1 = yes / acceptable",
    "chosen": "2AFC and preference trials: times a condition was the (first) choice",
    "votes": "2AFC and preference trials: times a condition was chosen, first or second choice",
}
#: Trial families each dependent variable fits (each family declares its dvs: data_schema.families).
DV_FAMILIES: dict[str, tuple[str, ...]] = {
    dv: tuple(name for name, fam in _families.FAMILIES.items() if dv in fam.dvs) for dv in DVS}

#: Priors of the paired-comparison scales (:func:`analysis.scaling.thurstone_jod`).
PRIORS: dict[str, str] = {
    "none": "no prior: maximum likelihood (refused when it does not exist, e.g. a condition won every comparison)",
    "weak": "Gaussian prior, SD 10, on every pairwise difference of scores (the default)",
    "pwcmp": "pwcmp's data-derived prior (pw_scale defaults) for the JOD scale; Bradley-Terry and "
             "Plackett-Luce keep the weak prior",
}
DEFAULT_PRIOR = "weak"


def schema_path() -> Path:
    """``data_schema/protocol.schema.json`` (beside the ``data_schema`` package)."""
    return Path(__file__).resolve().parents[1] / "data_schema" / "protocol.schema.json"


def _one_of(names) -> str:
    return "^(" + "|".join(names) + ")$"


def schema_block(current: dict | None = None) -> dict:
    """The ``$defs.analysis`` block with the vocabulary's enums (other properties of ``current`` are kept)."""
    block = dict(current or {})
    block.setdefault("description", "The analysis plan studyapp analyze follows.")
    block.setdefault("type", "object")
    block.setdefault("additionalProperties", False)
    block.setdefault("required", ["dv", "unit", "test"])
    props = dict(block.get("properties", {}))
    props["dv"] = {"description": "Dependent variable: " + "; ".join(f"{k}: {v}" for k, v in DVS.items()) + ".",
                   "enum": list(DVS)}
    props["unit"] = {"description": "Unit of analysis: " + "; ".join(f"{k}: {v}" for k, v in UNITS.items())
                     + ".", "enum": list(UNITS)}
    props["test"] = {"description": "What to report, one name or a list (the votes table and the Kruskal-Wallis "
                     "omnibus test always): " + "; ".join(f"{k}: {v}" for k, v in TESTS.items()) + ".",
                     "type": ["string", "array"], "pattern": _one_of(TESTS), "minItems": 1, "uniqueItems": True,
                     "items": {"enum": list(TESTS)}}
    props["prior"] = {"description": "Prior of the paired-comparison scales: "
                      + "; ".join(f"{k}: {v}" for k, v in PRIORS.items()) + ".", "enum": list(PRIORS)}
    order = ["dv", "unit", "paired", "reference", "test", "prior"]
    block["properties"] = {k: props[k] for k in order if k in props} | {k: v for k, v in props.items()
                                                                          if k not in order}
    return block


def render_schema_block(block: dict, indent: int = 4) -> list[str]:
    """The block as the schema file writes it: one line per property (``json.dumps`` of its value)."""
    pad, inner = " " * indent, " " * (indent + 2)
    lines = [f'{pad}"analysis": {{']
    items = [(k, v) for k, v in block.items() if k != "properties"]
    for k, v in items:
        lines.append(f"{inner}{json.dumps(k)}: {json.dumps(v, ensure_ascii=False)},")
    lines.append(f'{inner}"properties": {{')
    props = list(block["properties"].items())
    for i, (k, v) in enumerate(props):
        comma = "," if i < len(props) - 1 else ""
        lines.append(f"{inner}  {json.dumps(k)}: {json.dumps(v, ensure_ascii=False)}{comma}")
    lines.append(f"{inner}}}")
    lines.append(f"{pad}}}")
    return lines


def _block_span(lines: list[str]) -> tuple[int, int]:
    """First and last line (inclusive) of the ``$defs.analysis`` block of the schema text."""
    start = next(i for i, ln in enumerate(lines) if ln.rstrip() == '    "analysis": {')
    end = next(i for i in range(start + 1, len(lines)) if lines[i].startswith("    }"))
    return start, end


def generated_schema_text(text: str) -> str:
    """The schema ``text`` with its ``$defs.analysis`` block regenerated; every other line unchanged."""
    lines = text.split("\n")
    start, end = _block_span(lines)
    current = json.loads(text)["$defs"]["analysis"]
    trailing = lines[end][len("    }"):]  # "," if another $defs entry follows
    new = render_schema_block(schema_block(current))
    new[-1] += trailing
    return "\n".join(lines[:start] + new + lines[end + 1:])


def write_schema(path: Path | None = None) -> bool:
    """Rewrite the ``$defs.analysis`` block of the schema file; return True if the file changed."""
    path = Path(path) if path is not None else schema_path()
    text = path.read_text(encoding="utf-8")
    new = generated_schema_text(text)
    if new == text:
        return False
    path.write_text(new, encoding="utf-8")
    return True


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv == ["--write-schema"]:
        changed = write_schema()
        print(f"{schema_path()}: {'rewritten' if changed else 'already up to date'}")
        return 0
    if argv == ["--check"]:
        text = schema_path().read_text(encoding="utf-8")
        if generated_schema_text(text) != text:
            print(f"{schema_path()}: $defs.analysis differs from analysis/vocabulary.py "
                  "(run: python -m analysis.vocabulary --write-schema)", file=sys.stderr)
            return 1
        return 0
    print("usage: python -m analysis.vocabulary --write-schema | --check", file=sys.stderr)
    return 2


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
