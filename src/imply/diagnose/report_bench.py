"""The benchmark's report (Markdown) and the gap stage's paper part (numbers and claims)."""

from __future__ import annotations

import math

from imply.io import write_text
from imply.paper.parts import Claim, Number, write_part


def _f(x, spec: str = ".3f") -> str:
    return "n/a" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def write_benchmark(result: dict, cfg: dict, markdown_path: str, part_path: str) -> None:
    """Write the benchmark report and the part file ``results/paper/parts/gap.json``."""
    targets = cfg.get("targets", {"top1": 0.9, "false_alarm": 0.05, "shrinkage": 0.8})
    r = result
    numbers = {
        "gapTopOneAcc": Number(r["top1_big"], ".2f"),
        "gapTopOneN": Number(r["n_big"], "d"),
        "gapTopOneAccAll": Number(r["top1_all"], ".2f"),
        "gapLibraryN": Number(r["n_library"], "d"),
        "gapFalseAlarm": Number(r["false_alarm"], ".2f"),
        "gapNullN": Number(r["n_null"], "d"),
        "gapNoneRecall": Number(r["none_recall_outside"], ".2f"),
        "gapOutsideN": Number(r["n_outside"], "d"),
        "gapNoneRecallRemoved": Number(r["removed_none_recall"], ".2f"),
        "gapRemovedNoneOrAlias": Number(r["removed_none_or_alias"], ".2f"),
        "gapMagErr": Number(r["magnitude_rel_error_median"], ".2f"),
        "gapShrinkMedian": Number(r["shrinkage_median"], ".2f"),
        "gapAnchShrinkMedian": Number(r["anchored_shrinkage_median"], ".2f"),
        "gapNoiseSd": Number(float(cfg["noise_sd"]), ".3f"),
        "gapNullVisible": Number(r["null_visible_rms_median"], ".4f"),
    }

    def holds(x, ok) -> bool:
        return bool(isinstance(x, (int, float)) and math.isfinite(x) and ok(x))

    claims = [
        Claim("gap-top1", "gap", f"Top-1 accuracy >= {targets['top1']} for injected effects at least "
              f"{r['min_size_sd']:g}x the noise", holds(r["top1_big"], lambda x: x >= targets["top1"]),
              f"{_f(r['top1_big'], '.2f')} on {r['n_big']} cases"),
        Claim("gap-null", "gap", f"False alarms under the null <= {targets['false_alarm']:.0%}",
              holds(r["false_alarm"], lambda x: x <= targets["false_alarm"]),
              f"{_f(r['false_alarm'], '.2f')} on {r['n_null']} null logs"),
        Claim("gap-shrink", "gap", f"Median held-out shrinkage >= {targets['shrinkage']:.0%} of the gap above the "
              "noise floor", holds(r["shrinkage_median"], lambda x: x >= targets["shrinkage"]),
              f"median {_f(r['shrinkage_median'], '.2f')} on {r['n_big']} cases"),
    ]  # fmt: skip
    write_part(part_path, "gap", numbers, claims)

    lines = [
        "# Gap diagnostic benchmark",
        "",
        f"Synthetic push logs, one effect injected (label sealed), noise sd {cfg['noise_sd']} in log d, generator "
        f"timestep {cfg['timestep']} s{', measured mass in every log' if cfg.get('measured_mass') else ''}. "
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
        "## Claims",
        "",
    ]
    for c in claims:
        lines.append(f"- {'HOLDS' if c.holds else 'FAILS'}: {c.statement} ({c.detail})")
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
    write_text(markdown_path, "\n".join(lines) + "\n")
