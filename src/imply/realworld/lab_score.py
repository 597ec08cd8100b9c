"""Scoring the diagnostic on the lab benchmark (:mod:`imply.realworld.lab`): each set diagnosed with and without its
calibration probes, scored as the contact benchmark is (:func:`imply.realworld.benchmark.score_contact_cases`).

Two readings beside every metric: over all of the set's logs (a log without probes is diagnosed alike either way),
and over the logs that carry probes alone, where the two variants differ only by the probes. The development set is
the one to choose on; the sealed set is scored once per design.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

from imply.diagnose.analysis import Summary
from imply.io import write_text
from imply.realworld.benchmark import CONTACT_SINGLE, score_contact_cases
from imply.realworld.separability import mark_log

VARIANTS = ("no_probes", "probes")  # the diagnosis without, then with, the logs' probes
# (key, words, target, whether the target is a floor); the targets are config gap.lab_benchmark.targets
METRICS = (
    ("null_no_library", "null logs stating no effect beyond the contact", "null_no_library", True),
    ("null_pusher_stated", "null logs stating a pusher cause", "pusher_unmeasured", False),
    ("among_named", "one big effect: among the named", "among_named", True),
    ("contenders_mean", "one big effect: contenders (mean)", "contenders_mean", False),
    ("single_right", "one big effect: the one cause, within tolerance", "single_right", True),
    ("told_right", "one big effect: its own hypothesis within tolerance (told the cause)", None, True),
    ("wrong_single", "outside effect: a library mechanism as the one cause", "wrong_single", False),
    ("contact_named", "MuJoCo variants with a table contact off: the contact named", "contact_named", True),
)
ENGINES = ("mujoco", "bullet", "sapien")


def observable_set(label: Mapping, variant: str) -> str:
    """The observable set (:data:`imply.realworld.separability.OBSERVABLE_SETS`) a log is read with under a variant:
    its probes where it has them and the variant uses them, else its stop times where it has them, else its
    displacements. (The probes' set holds the pusher's speed and the track too, which the default diagnosis leaves
    out: the marking is an upper bound there.)"""
    if variant == "probes" and label.get("probes"):
        return "probes"
    return "stop_time" if label.get("stop_time") else "displacement"


def separable_logs(
    labels: Mapping[str, dict], variant: str, *, alias_cos: float, min_size_sd: float, crossing_sd: float
) -> dict[str, bool]:
    """Each one-effect log's marking (:func:`imply.realworld.separability.mark_log`) under the observable set the
    variant reads it with: whether its effect is separable from its contact."""
    out = {}
    for cid, lab in labels.items():
        if lab["group"] in CONTACT_SINGLE:
            mark = mark_log(lab, alias_cos=alias_cos, min_size_sd=min_size_sd, crossing_sd=crossing_sd)
            out[cid] = bool(mark["sets"][observable_set(lab, variant)]["separable"])
    return out


def score_lab(
    labels: Mapping[str, dict],
    summaries: Mapping[str, Mapping[str, Summary]],
    *,
    targets: Mapping[str, float],
    min_size_sd: float,
    alias_cos: float,
    crossing_sd: float,
) -> dict:
    """Each variant's scores (``summaries``: {variant: {log id: summary}}) over all logs, over the probe logs, and
    over the one-effect logs whose effect is separable from their contact (``separable``) or not
    (``not_separable``) under the observables that variant reads."""
    with_probes = sorted(c for c, lab in labels.items() if lab.get("probes"))
    out: dict = {"targets": dict(targets), "min_size_sd": min_size_sd, "n_logs": len(labels)}
    out["n_probe_logs"] = len(with_probes)

    def score(ids, found):
        return score_contact_cases(
            {c: labels[c] for c in ids}, {c: found[c] for c in ids}, targets=targets, min_size_sd=min_size_sd
        )

    for name, found in summaries.items():
        marks = separable_logs(labels, name, alias_cos=alias_cos, min_size_sd=min_size_sd, crossing_sd=crossing_sd)
        out[name] = {
            "all": score(sorted(labels), found),
            "probe_logs": score(with_probes, found),
            "separable": score(sorted(c for c, sep in marks.items() if sep), found),
            "not_separable": score(sorted(c for c, sep in marks.items() if not sep), found),
            "probe_logs_separable": score(sorted(c for c, sep in marks.items() if sep and c in with_probes), found),
        }
    return out


def _cell(r: dict, key: str, engine: str | None) -> str:
    k = key if engine is None else f"{key}_{engine}"
    n = r.get(f"n_{k}")
    x = r.get(k)
    if x is None or x != x:
        return "–"
    if key == "contenders_mean":
        return f"{x:.1f}"
    return f"{x:.2f} ({round(x * n)}/{n})" if n is not None else f"{x:.2f}"


def lab_score_markdown(result: Mapping, set_name: str) -> str:
    """The lab benchmark's scores as a report: per metric, each variant over all logs and per engine."""
    lines = [
        f"# Lab benchmark: the {set_name} set diagnosed with and without its probes",
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
            "| metric | target | " + " | ".join(VARIANTS) + " | per engine, with probes |",
        ]
        lines.append("|---|---|" + "---|" * len(VARIANTS) + "---|")
        for key, words_, target, floor in METRICS:
            t = result["targets"].get(target) if target else None
            tt = "–" if t is None else (f"≥ {t:g}" if floor else f"≤ {t:g}")
            cells = [_cell(result[v][subset], key, None) for v in VARIANTS if v in result]
            last = result.get("probes", result.get(VARIANTS[0]))[subset]
            per = ", ".join(f"{e} {_cell(last, key, e)}" for e in ENGINES if last.get(f"n_{key}_{e}"))
            lines.append(f"| {words_} | {tt} | " + " | ".join(cells) + f" | {per or '–'} |")
        lines.append("")
    if "closed_loop" in result:
        lines += _closed_loop_lines(result["closed_loop"], result["targets"].get("closed_loop"))
    lines += ["## Confusion, with probes (true effect and world against the verdict's causes)", ""]
    conf = result.get("probes", result.get(VARIANTS[0]))["all"]["confusion"]
    cols = sorted({c for row in conf.values() for c in row})
    lines.append("| true | " + " | ".join(cols) + " |")
    lines.append("|---|" + "---|" * len(cols))
    for r, row in conf.items():
        lines.append(f"| {r} | " + " | ".join(str(row.get(c, 0) or "") for c in cols) + " |")
    return "\n".join(lines) + "\n"


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
        "## Closed loop: logs with several contenders, after the recommended next experiments or as many random pushes",
        "",
        f"Target: {tt}.",
        "",
        "| metric | next experiments | random pushes |",
        "|---|---|---|",
    ]
    for key, n_key, words in rows:
        cells = []
        for arm in ("next", "random"):
            r = loop.get(arm, {})
            x, n = r.get(key), r.get(n_key) if n_key else None
            if x is None or x != x:
                cells.append("–")
            elif n is None:
                cells.append(f"{x:.1f}")
            else:
                cells.append(f"{x:.2f} ({round(x * n)}/{n})")
        lines.append(f"| {words} | " + " | ".join(cells) + " |")
    return lines + [""]


def write_lab_score(result: Mapping, set_name: str, path: str | os.PathLike) -> None:
    write_text(path, lab_score_markdown(result, set_name))


def lab_claims(r: Mapping | None) -> list:
    """The lab benchmark's targets (config ``gap.lab_benchmark.targets``, fixed before any run) on the sealed set's
    :func:`score_lab` result, its closed loop included; none where the stage has no lab result."""
    from imply.realworld.benchmark_report import _f, _holds
    from imply.results import Claim

    if not r:
        return []
    t = r["targets"]
    w, wo = r["probes"], r["no_probes"]
    within = f"{t['magnitude_within']:.0%}"

    def at_least(x, key):
        return _holds(x, lambda v: v >= t[key])

    def at_most(x, key):
        return _holds(x, lambda v: v <= t[key])

    def share(res: Mapping, key: str, engine: bool = True) -> str:
        words = f"{_f(res.get(key), '.2f')} on {res.get(f'n_{key}', 0)}"
        per = [
            f"{e} {_f(res.get(f'{key}_{e}'), '.2f')}/{res.get(f'n_{key}_{e}')}"
            for e in ENGINES
            if engine and res.get(f"n_{key}_{e}")
        ]
        return words + (f" ({', '.join(per)})" if per else "")

    sep_w, sep_wo = w["probe_logs_separable"], wo["separable"]
    loop = r.get("closed_loop") or {}
    nxt, rnd = loop.get("next") or {}, loop.get("random") or {}
    return [
        Claim(
            "gap-lab-null",
            "gap",
            f"Lab benchmark, null logs (contacts and engines not the table's): no effect beyond the contact stated in "
            f">= {t['null_no_library']:.0%}, with and without probes",
            at_least(w["all"]["null_no_library"], "null_no_library")
            and at_least(wo["all"]["null_no_library"], "null_no_library"),
            f"with probes {share(w['all'], 'null_no_library')}; without {share(wo['all'], 'null_no_library')}",
        ),
        Claim(
            "gap-lab-pusher",
            "gap",
            "Lab benchmark, null logs read without the pusher's speed or free strokes: a pusher cause stated in "
            f"<= {t['pusher_unmeasured']:.0%}",
            at_most(wo["all"]["null_pusher_stated"], "pusher_unmeasured"),
            share(wo["all"], "null_pusher_stated"),
        ),
        Claim(
            "gap-lab-named",
            "gap",
            f"Lab benchmark, one big effect: among the named in >= {t['among_named']:.0%}, with at most "
            f"{t['contenders_mean']:g} contenders on average (with probes)",
            at_least(w["all"]["among_named"], "among_named")
            and at_most(w["all"]["contenders_mean"], "contenders_mean"),
            f"{share(w['all'], 'among_named')}; contenders {_f(w['all']['contenders_mean'], '.2f')}",
        ),
        Claim(
            "gap-lab-single-probes",
            "gap",
            f"Lab benchmark, one big effect separable from its contact, logs with probes: stated as the one cause "
            f"within {within} in >= {t['single_right']:.0%}",
            at_least(sep_w["single_right"], "single_right"),
            f"{share(sep_w, 'single_right')}; told the cause {_f(sep_w.get('told_right'), '.2f')}; not separable: "
            f"{_f(w['not_separable'].get('single_right'), '.2f')} on {w['not_separable'].get('n_single_right', 0)}, "
            f"told {_f(w['not_separable'].get('told_right'), '.2f')}",
        ),
        Claim(
            "gap-lab-single",
            "gap",
            f"Lab benchmark, one big effect separable from its contact, without probes: stated as the one cause within "
            f"{within} in >= {t['single_right_no_probes']:.0%}",
            at_least(sep_wo["single_right"], "single_right_no_probes"),
            f"{share(sep_wo, 'single_right')}; told the cause {_f(sep_wo.get('told_right'), '.2f')}; not separable: "
            f"{_f(wo['not_separable'].get('single_right'), '.2f')} on {wo['not_separable'].get('n_single_right', 0)}, "
            f"told {_f(wo['not_separable'].get('told_right'), '.2f')}",
        ),
        Claim(
            "gap-lab-wrong",
            "gap",
            f"Lab benchmark, effects outside the library: a library mechanism stated as the one cause in "
            f"<= {t['wrong_single']:.0%}, with and without probes",
            at_most(w["all"]["wrong_single"], "wrong_single") and at_most(wo["all"]["wrong_single"], "wrong_single"),
            f"with probes {share(w['all'], 'wrong_single')}; without {share(wo['all'], 'wrong_single')}",
        ),
        Claim(
            "gap-lab-contact",
            "gap",
            f"Lab benchmark, MuJoCo variants whose table contact is off: the contact named in >= {t['contact_named']:.0%}",
            at_least(w["all"]["contact_named"], "contact_named"),
            share(w["all"], "contact_named", engine=False),
        ),
        Claim(
            "gap-lab-loop",
            "gap",
            f"Lab benchmark, one big effect with several contenders, probes allowed: the one cause right within "
            f"{within} in >= {t['closed_loop']:.0%} once the recommended next experiments are run",
            at_least(nxt.get("one_cause_right"), "closed_loop"),
            f"{_f(nxt.get('one_cause_right'), '.2f')} on {nxt.get('n_single', 0)} logs; as many random pushes of the "
            f"log's design: {_f(rnd.get('one_cause_right'), '.2f')}; told the cause {_f(nxt.get('told_right'), '.2f')} "
            f"(random {_f(rnd.get('told_right'), '.2f')}); probes run per log {_f(nxt.get('probes_added_mean'), '.2f')}",
        ),
    ]
