"""The benchmark's report (Markdown) and the gap stage's claims.

The gap stage's numbers are read by the registry (:mod:`imply.paper.registry`) from the
result of :func:`imply.diagnose.benchmark.score_cases`; :func:`benchmark_claims` checks
the targets on them.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

from imply.io import write_text
from imply.paper.parts import Claim
from imply.paper.registry import Values

RESULT = "imply.diagnose.benchmark.score_cases"


def _f(x, spec: str = ".3f") -> str:
    return "n/a" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def benchmark_claims(v: Values, results: Mapping[str, Any]) -> list[Claim]:
    """The benchmark's targets (config ``gap.benchmark.targets``) as claims."""
    r = results[RESULT]
    targets = r["targets"]

    def holds(x, ok) -> bool:
        return bool(isinstance(x, (int, float)) and math.isfinite(x) and ok(x))

    return [
        Claim("gap-top1", "gap", f"Top-1 accuracy >= {targets['top1']} for injected effects at least "
              f"{r['min_size_sd']:g}x the noise", holds(v["gapTopOneAcc"], lambda x: x >= targets["top1"]),
              f"{_f(v['gapTopOneAcc'], '.2f')} on {v['gapTopOneN']} cases"),
        Claim("gap-null", "gap", f"False alarms under the null <= {targets['false_alarm']:.0%}",
              holds(v["gapFalseAlarm"], lambda x: x <= targets["false_alarm"]),
              f"{_f(v['gapFalseAlarm'], '.2f')} on {v['gapNullN']} null logs"),
        Claim("gap-shrink", "gap", f"Median held-out shrinkage >= {targets['shrinkage']:.0%} of the gap above the "
              "noise floor", holds(v["gapShrinkMedian"], lambda x: x >= targets["shrinkage"]),
              f"median {_f(v['gapShrinkMedian'], '.2f')} on {v['gapTopOneN']} cases"),
    ]  # fmt: skip


def write_benchmark_markdown(result: dict, path: str | os.PathLike) -> None:
    """Write the benchmark report (``results/gap/benchmark.md``) from :func:`score_cases`'s result."""
    r = result
    targets = r["targets"]
    checks = [
        ("top-1 accuracy", r["top1_big"], f">= {targets['top1']}", r["top1_big"] >= targets["top1"]),
        ("false alarms", r["false_alarm"], f"<= {targets['false_alarm']}", r["false_alarm"] <= targets["false_alarm"]),
        ("median shrinkage", r["shrinkage_median"], f">= {targets['shrinkage']}",
         r["shrinkage_median"] >= targets["shrinkage"]),
    ]  # fmt: skip
    lines = [
        "# Gap diagnostic benchmark",
        "",
        f"Synthetic push logs, one effect injected (label sealed), noise sd {r['noise_sd']} in log d, generator "
        f"timestep {r['timestep']} s{', measured mass in every log' if r['measured_mass'] else ''}. "
        f"Visible size: RMS log d left after the baseline fit of the noise-free log. Null logs: {r['n_null']}; library-effect logs: {r['n_library']} "
        f"({r['n_big']} with a visible size >= {r['min_size_sd']:g}x noise); outside-library logs: {r['n_outside']}.",
        "",
        "| metric | value |",
        "|---|---|",
        f"| top-1 accuracy, effects >= {r['min_size_sd']:g}x noise | {_f(r['top1_big'], '.2f')} (n={r['n_big']}) |",
        f"| top-1 accuracy, all library effects | {_f(r['top1_all'], '.2f')} (n={r['n_library']}) |",
        f"| false-alarm rate under the null | {_f(r['false_alarm'], '.2f')} (n={r['n_null']}) |",
        f"| recall of 'none', effects outside the library | {_f(r['none_recall_outside'], '.2f')} (n={r['n_outside']}) |",
        f"| recall of 'none', true effect removed (>= {r['min_size_sd']:g}x noise) | {_f(r['removed_none_recall'], '.2f')} |",
        f"| 'none' or an alias of the removed effect | {_f(r['removed_none_or_alias'], '.2f')} |",
        f"| median relative magnitude error (correct, >= {r['min_size_sd']:g}x) | {_f(r['magnitude_rel_error_median'], '.2f')} |",
        f"| median held-out shrinkage of the gap above the noise floor | {_f(r['shrinkage_median'], '.2f')} |",
        f"| median shrinkage of the anchored disagreement | {_f(r['anchored_shrinkage_median'], '.2f')} |",
        f"| median visible RMS of null logs (generator timestep gap) | {_f(r['null_visible_rms_median'], '.4f')} |",
        "",
        "## Targets",
        "",
    ]
    for name, value, target, met in checks:
        lines.append(f"- {'MET' if met else 'NOT MET'}: {name} {_f(value, '.2f')} (target {target})")
    cols = sorted({c for row in r["confusion"].values() for c in row})
    lines += ["", "## Confusion matrix (rows: injected effect; columns: top effect or none)", "",
              "| true \\ predicted | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols)]  # fmt: skip
    for t, row in r["confusion"].items():
        lines.append(f"| {t} | " + " | ".join(str(row.get(c, 0)) for c in cols) + " |")
    lines += ["", "## Cases", "", "| case | magnitude | visible RMS (x noise) | predicted | correct | removed-true prediction | share closed |",
              "|---|---|---|---|---|---|---|"]  # fmt: skip
    for c in r["cases"]:
        lines.append(f"| {c['case']} | {c['magnitude']:g} | {c['visible_rms']:.4f} ({c['size_sd']:.1f}) | "
                     f"{c['predicted']} | {'yes' if c['correct'] else 'no'} | {c['removed_predicted'] or ''} | "
                     f"{_f(c['gap_share_closed'], '.2f')} |")  # fmt: skip
    write_text(path, "\n".join(lines) + "\n")
