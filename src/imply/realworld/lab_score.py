"""Scoring the diagnostic on the lab benchmark (:mod:`imply.realworld.lab`): each set diagnosed in three tiers, each
log alone, with its calibration probes, and against its reference session (with its probes where it has them), each
tier scored apart as the contact benchmark is (:func:`imply.realworld.benchmark.score_contact_cases`), per engine.

Readings beside every metric: over all of the set's logs (a log without probes is diagnosed alike alone and with
probes), over the logs that carry probes alone, and over the one-effect logs whose effect is separable from their
contact or not. The development set is the one to choose on; the sealed set is scored once per design.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

from imply.diagnose.analysis import Summary
from imply.io import write_text
from imply.realworld.benchmark import CONTACT_SINGLE, score_contact_cases
from imply.realworld.separability import mark_log

# the tiers: each log alone, with its probes, against its reference session (with its probes where it has them)
VARIANTS = ("no_probes", "probes", "reference")
VARIANT_WORDS = {"no_probes": "alone", "probes": "with probes", "reference": "with a reference"}
# (key, words, target, whether the target is a floor); the targets are config gap.lab_benchmark.targets
METRICS = (
    ("null_no_library", "null logs stating no effect beyond the contact", "null_no_library", True),
    ("null_no_change", "null logs stating no cause at all (no change)", "ref_null_no_change", True),
    ("null_pusher_stated", "null logs stating a pusher cause", "pusher_unmeasured", False),
    ("among_named", "one big effect: among the named", "among_named", True),
    ("contenders_mean", "one big effect: contenders (mean)", "contenders_mean", False),
    ("single_right", "one big effect: the one cause, within tolerance", None, True),
    (
        "single_right_readable",
        "one big effect its observables can tell from the others: the one cause, within tolerance",
        "ref_single_right",
        True,
    ),
    ("told_right", "one big effect: its own hypothesis within tolerance (told the cause)", None, True),
    ("wrong_effect_single", "effect logs: another library effect as the one cause", "wrong_effect_single", False),
    ("wrong_single", "outside effect: a library mechanism as the one cause", "ref_wrong_single", False),
    ("wrong_mechanism", "outside effect: a library mechanism as a cause", "wrong_mechanism", False),
    (
        "shrink_within",
        "one big effect: stated share of the gap within tolerance of the true",
        "ref_shrink_within",
        True,
    ),
    ("contact_named", "MuJoCo variants with a table contact off: the contact named", "contact_named", True),
)
ENGINES = ("mujoco", "bullet", "sapien")


def observable_set(label: Mapping, variant: str) -> str:
    """The observable set (:data:`imply.realworld.separability.OBSERVABLE_SETS`) a log is read with under a variant:
    its probes where it has them and the variant uses them (with probes, with a reference), else its stop times where
    it has them, else its displacements. (The probes' set holds the pusher's speed and the track too, which the default diagnosis leaves
    out: the marking is an upper bound there.)"""
    if variant in ("probes", "reference") and label.get("probes"):
        return "probes"
    return "stop_time" if label.get("stop_time") else "displacement"


def separable_logs(labels: Mapping[str, dict], marks: Mapping[str, dict], variant: str) -> dict[str, bool]:
    """Each one-effect log's marking (``marks``: :func:`imply.realworld.separability.mark_log` by log) under the
    observable set the variant reads it with: whether its effect is separable from its contact."""
    return {cid: bool(m["sets"][observable_set(labels[cid], variant)]["separable"]) for cid, m in marks.items()}


def score_lab(
    labels: Mapping[str, dict],
    summaries: Mapping[str, Mapping[str, Summary]],
    *,
    targets: Mapping[str, float],
    min_size_sd: float,
    alias_cos: float,
    crossing_sd: float,
    sizes: Mapping[str, dict] | None = None,
) -> dict:
    """Each variant's scores (``summaries``: {variant: {log id: summary}}) over all logs, over the probe logs, and
    over the one-effect logs whose effect is separable from their contact (``separable``) or not
    (``not_separable``) under the observables that variant reads; ``sizes``: each one-effect log's visible size with
    and without its effect (:func:`imply.realworld.benchmark.shrink_sizes`), for the share of the gap its cause
    closes."""
    with_probes = sorted(c for c, lab in labels.items() if lab.get("probes"))
    out: dict = {"targets": dict(targets), "min_size_sd": min_size_sd, "n_logs": len(labels)}
    out["n_probe_logs"] = len(with_probes)

    def score(ids, found):
        return score_contact_cases(
            {c: labels[c] for c in ids},
            {c: found[c] for c in ids},
            targets=targets,
            min_size_sd=min_size_sd,
            sizes=None if sizes is None else dict(sizes),
        )

    # every one-effect log marked once, under every observable set; each variant reads its own
    marked = {
        cid: mark_log(lab, alias_cos=alias_cos, min_size_sd=min_size_sd, crossing_sd=crossing_sd)
        for cid, lab in labels.items()
        if lab["group"] in CONTACT_SINGLE
    }
    for name, found in summaries.items():
        marks = separable_logs(labels, marked, name)
        out[name] = {
            "all": score(sorted(labels), found),
            "probe_logs": score(with_probes, found),
            "separable": score(sorted(c for c, sep in marks.items() if sep), found),
            "not_separable": score(sorted(c for c, sep in marks.items() if not sep), found),
            "probe_logs_separable": score(sorted(c for c, sep in marks.items() if sep and c in with_probes), found),
        }
    return out


def _value(x, n: int | None, *, mean: bool = False) -> str:
    """A table cell: a mean to one decimal, a share with its count where there is one; a dash for none."""
    if x is None or x != x:
        return "–"
    if mean:
        return f"{x:.1f}"
    return f"{x:.2f} ({round(x * n)}/{n})" if n is not None else f"{x:.2f}"


def _cell(r: dict, key: str, engine: str | None) -> str:
    k = key if engine is None else f"{key}_{engine}"
    return _value(r.get(k), r.get(f"n_{k}"), mean=key == "contenders_mean")


def lab_score_markdown(result: Mapping, set_name: str) -> str:
    """The lab benchmark's scores as a report: per metric, each variant over all logs and per engine."""
    last_tier = next(v for v in reversed(VARIANTS) if v in result)  # the tier the per-engine columns show
    lines = [
        f"# Lab benchmark: the {set_name} set diagnosed alone, with its probes, and against its reference session",
        "",
        f"{result['n_logs']} logs, {result['n_probe_logs']} of them with calibration probes. "
        f"Effects count as big at {result['min_size_sd']:g} noise sds or more on top of their world's contact.",
        "",
    ]
    for subset, words in (
        ("all", "all logs"),
        ("probe_logs", "the logs with probes"),
        ("separable", "the one-effect logs whose effect is separable from their contact"),
        ("not_separable", "the one-effect logs whose effect is not separable from their contact"),
        ("probe_logs_separable", "the one-effect logs with probes whose effect is separable from their contact"),
    ):
        lines += [
            f"## Over {words}",
            "",
            "| metric | target | "
            + " | ".join(VARIANT_WORDS[v] for v in VARIANTS if v in result)
            + " | per engine, with a reference |",
        ]
        lines.append("|---|---|" + "---|" * sum(v in result for v in VARIANTS) + "---|")
        for key, words_, target, floor in METRICS:
            t = result["targets"].get(target) if target else None
            tt = "–" if t is None else (f"≥ {t:g}" if floor else f"≤ {t:g}")
            cells = [_cell(result[v][subset], key, None) for v in VARIANTS if v in result]
            last = result[last_tier][subset]
            per = ", ".join(f"{e} {_cell(last, key, e)}" for e in ENGINES if last.get(f"n_{key}_{e}"))
            lines.append(f"| {words_} | {tt} | " + " | ".join(cells) + f" | {per or '–'} |")
        lines.append("")
    lines += _shrink_lines(result)
    if "closed_loop" in result:
        lines += _closed_loop_lines(result["closed_loop"], result["targets"].get("closed_loop"))
    lines += [
        f"## Confusion, {VARIANT_WORDS[last_tier]} (true effect and world against the verdict's causes)",
        "",
    ]
    conf = result[last_tier]["all"]["confusion"]
    cols = sorted({c for row in conf.values() for c in row})
    lines.append("| true | " + " | ".join(cols) + " |")
    lines.append("|---|" + "---|" * len(cols))
    for r, row in conf.items():
        lines.append(f"| {r} | " + " | ".join(str(row.get(c, 0) or "") for c in cols) + " |")
    return "\n".join(lines) + "\n"


def _shrink_lines(result: Mapping) -> list[str]:
    """How far the gap shrinks against the truth, per tier: the share of the gap the stated cause closes against the
    share the effect accounts for in the noise-free logs."""
    tiers = [v for v in VARIANTS if v in result]
    tol = result["targets"].get("shrink_tolerance")
    lines = [
        "## How far the gap shrinks, against the truth (big one-effect logs)",
        "",
        "The true share: the effect's part of the gap the noise-free log leaves after each box's fit against the "
        "table (the world with the effect against the same world without it); the stated one: the share the "
        f"diagnosis says its stated cause closes (0 where it states none). Tolerance {tol if tol is not None else '–'}.",
        "",
        "| tier | within tolerance | median difference | largest difference |",
        "|---|---|---|---|",
    ]
    for v in tiers:
        r = result[v]["all"]
        lines.append(
            f"| {VARIANT_WORDS[v]} | {_cell(r, 'shrink_within', None)} | {_value(r.get('shrink_error_median'), None)} "
            f"| {_value(r.get('shrink_error_max'), None)} |"
        )
    return [*lines, ""]


def _closed_loop_lines(loop: Mapping, target: float | None) -> list[str]:
    """The closed loop's table: the recommended next experiments (pushes and probes) against as many random pushes
    of the log's own design."""
    rows = (
        ("one_cause_right", "n_single", "one big effect: the one cause, within tolerance"),
        ("told_right", "n_single", "one big effect: its own hypothesis within tolerance"),
        ("null_no_library", "n_null", "null logs stating no effect beyond the contact"),
        ("wrong_single", "n_outside", "outside effect: a library mechanism as the one cause"),
        ("contenders_mean", None, "contenders (mean)"),
        ("pushes_added_mean", None, "push rows added (mean)"),
        ("probes_added_mean", None, "probes run (mean)"),
    )
    tt = "–" if target is None else f"≥ {target:g} (the one cause right)"
    lines = [
        "## Closed loop, with a reference: logs with several contenders, after the recommended next experiments or as "
        "many random pushes",
        "",
        f"Target: {tt}.",
        "",
        "| metric | next experiments | random pushes |",
        "|---|---|---|",
    ]
    for key, n_key, words in rows:
        arms = [loop.get(arm, {}) for arm in ("next", "random")]
        cells = [_value(r.get(key), r.get(n_key) if n_key else None, mean=n_key is None) for r in arms]
        lines.append(f"| {words} | " + " | ".join(cells) + " |")
    return lines + [""]


def write_lab_score(result: Mapping, set_name: str, path: str | os.PathLike) -> None:
    write_text(path, lab_score_markdown(result, set_name))
