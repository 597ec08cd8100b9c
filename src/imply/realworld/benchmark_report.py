"""The benchmark's report (Markdown) and the gap stage's claims.

The gap stage's numbers are read by the registry (:mod:`imply.paper.registry`) from the
result of :func:`imply.realworld.benchmark.score_cases` and the lab benchmark's sealed score
(:func:`imply.realworld.lab_score.score_lab`); :func:`benchmark_claims` checks the targets
(config ``gap.benchmark.targets``, ``gap.contact_benchmark.targets``,
``gap.lab_benchmark.targets``) on those results.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

from imply.io import write_text
from imply.realworld.lab_score import ENGINES
from imply.results import Claim, Values, tally

RESULT = "imply.realworld.benchmark.score_cases"
LAB_RESULT = "imply.realworld.lab_score.score_lab"


def _f(x, spec: str = ".3f") -> str:
    return "n/a" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def _holds(x, ok) -> bool:
    return bool(isinstance(x, int | float) and math.isfinite(x) and ok(x))


# each target, by claim: the result's metric, its count, the target's key and whether the metric must stay at or
# below it (else at or above); the default and the observed diagnoses' claims check them alike
MAIN_TARGETS = {
    "null": ("false_alarm", "n_null", "false_alarm", True),
    "top1": ("top1_big", "n_big", "top1", False),
    "both": ("both_named_big", "n_double_big", "both_named", False),
    "outside": ("none_recall_outside", "n_outside", "none_outside", False),
    "magnitude": ("magnitude_rel_error_median", "n_magnitudes", "magnitude_error", True),
    "shrink": ("shrinkage_median", "n_shrinkage", "shrinkage", False),
}
CONTACT_TARGETS = {
    "contact-null": ("null_no_library", "n_null_no_library", "null_no_library", False),
    "contact-single": ("single_right", "n_single_right", "observed_single_right", False),
    "contact-wrong": ("wrong_single", "n_wrong_single", "wrong_single", True),
}


# the metrics of the targets above that are a share of logs (the others are medians)
SHARE_METRICS = {
    "false_alarm",
    "top1_big",
    "both_named_big",
    "none_recall_outside",
    "null_no_library",
    "single_right",
    "wrong_single",
}


def _tally(r: dict, target: tuple[str, str, str, bool]) -> dict[str, int]:
    """The count of logs behind a target's share (keyword arguments of a claim); empty for a median."""
    metric, n, _, _ = target
    return tally(r[metric], r[n]) if metric in SHARE_METRICS else {}


def _meets(r: dict, targets: dict, target: tuple[str, str, str, bool]) -> bool:
    """Whether result ``r`` meets one target of :data:`MAIN_TARGETS` or :data:`CONTACT_TARGETS`."""
    metric, _, key, at_most = target
    return _holds(r[metric], (lambda x: x <= targets[key]) if at_most else (lambda x: x >= targets[key]))


def benchmark_claims(v: Values, results: Mapping[str, Any]) -> list[Claim]:
    """One claim per target of the benchmark, and that its world is converged at least as closely as the table; then
    the lab benchmark's targets on its sealed set, where the stage has that result."""
    return claims_of(results[RESULT]) + lab_claims(results.get(LAB_RESULT))


def claims_of(r: dict) -> list[Claim]:
    """The claims on a :func:`imply.realworld.benchmark.score_cases` result (its ``targets`` and ``world_error``)."""
    targets = r["targets"]
    w = r["world_error"]
    world_ok = (
        w["max"] is not None
        and w["table_max"] is not None
        and w["max"] <= w["table_max"]
        and w["rms"] <= w["table_rms"]
    )
    sd = r["min_size_sd"]
    return (
        [
            Claim(
                "gap-world",
                "gap",
                "The benchmark's world is converged at least as closely as the table (max and RMS error in log d)",
                bool(world_ok),
                f"world max {_f(w['max'], '.4f')}, RMS {_f(w['rms'], '.4f')}; table "
                f"max {_f(w['table_max'], '.4f')}, RMS {_f(w['table_rms'], '.4f')}",
            ),
            Claim(
                "gap-null",
                "gap",
                f"False alarms on null logs (heavy-tailed ones included) <= {targets['false_alarm']:.0%}",
                _meets(r, targets, MAIN_TARGETS["null"]),
                f"{_f(r['false_alarm'], '.3f')} on {r['n_null']} null logs ({_f(r['false_alarm_heavy'], '.2f')} on "
                f"{r['n_null_heavy']} heavy-tailed)",
                **_tally(r, MAIN_TARGETS["null"]),
            ),
            Claim(
                "gap-top1",
                "gap",
                f"Top-1 accuracy >= {targets['top1']} for one-effect logs whose effect is at least {sd:g}x the noise",
                _meets(r, targets, MAIN_TARGETS["top1"]),
                f"{_f(r['top1_big'], '.3f')} on {r['n_big']} logs",
                **_tally(r, MAIN_TARGETS["top1"]),
            ),
            Claim(
                "gap-both",
                "gap",
                f"Both effects named in >= {targets['both_named']:.0%} of two-effect logs (each effect "
                f"at least {sd:g}x the noise)",
                _meets(r, targets, MAIN_TARGETS["both"]),
                f"{_f(r['both_named_big'], '.3f')} on {r['n_double_big']} logs ({_f(r['both_named_all'], '.2f')} on all "
                f"{r['n_double']})",
                **_tally(r, MAIN_TARGETS["both"]),
            ),
            Claim(
                "gap-outside",
                "gap",
                f"Effects outside the library answered 'none of the candidates' in >= "
                f"{targets['none_outside']:.0%} of logs",
                _meets(r, targets, MAIN_TARGETS["outside"]),
                f"{_f(r['none_recall_outside'], '.3f')} on {r['n_outside']} logs "
                f"({_f(r['none_recall_outside_big'], '.2f')} on the {r['n_outside_big']} at least {sd:g}x the noise)",
                **_tally(r, MAIN_TARGETS["outside"]),
            ),
            Claim(
                "gap-magnitude",
                "gap",
                f"Median relative magnitude error <= {targets['magnitude_error']:.0%} (effects "
                "named, at least {:g}x the noise)".format(sd),
                _meets(r, targets, MAIN_TARGETS["magnitude"]),
                f"median {_f(r['magnitude_rel_error_median'], '.3f')} on {r['n_magnitudes']} effects",
            ),
            Claim(
                "gap-shrink",
                "gap",
                f"Median held-out shrinkage >= {targets['shrinkage']:.0%} of the gap above the noise floor",
                _meets(r, targets, MAIN_TARGETS["shrink"]),
                f"median {_f(r['shrinkage_median'], '.3f')} on {r['n_shrinkage']} logs",
            ),
        ]
        + contact_claims(r.get("contact"))
        + observed_claims(r)
    )


def observed_claims(r: dict) -> list[Claim]:
    """The targets with what a robot records (the pusher's measured speed and the box's track in every fit), on the
    result ``r`` whose ``observed`` holds the same logs' scores that way: the main benchmark's targets again, and on
    other contact models the nulls, the one cause and the outside effects."""
    o = r.get("observed")
    if not o:
        return []
    t = r["targets"]
    prefix = "With the pusher's speed and the box's track: "
    statements = {
        "null": f"false alarms on null logs <= {t['false_alarm']:.0%}",
        "top1": f"top-1 accuracy >= {t['top1']} for one big library effect",
        "both": f"both effects named in >= {t['both_named']:.0%} of logs with two big effects",
        "outside": f"effects outside the library answered 'none' in >= {t['none_outside']:.0%}",
        "magnitude": f"median relative magnitude error <= {t['magnitude_error']:.0%}",
        "shrink": f"median held-out shrinkage >= {t['shrinkage']:.0%}",
    }
    claims = [
        Claim(
            f"gap-observed-{cid}",
            "gap",
            prefix + statement,
            _meets(o, t, MAIN_TARGETS[cid]),
            f"{_f(o[MAIN_TARGETS[cid][0]])} on {o[MAIN_TARGETS[cid][1]]} logs",
            **_tally(o, MAIN_TARGETS[cid]),
        )
        for cid, statement in statements.items()
    ]
    c, c0 = o.get("contact"), r.get("contact")
    if not c or not c0:
        return claims
    ct = c0["targets"]
    statements = {
        "contact-null": f"null logs of another contact model: no library effect stated in >= {ct['null_no_library']:.0%}",
        "contact-single": f"in-library effects of at least {c0['min_size_sd']:g}x the noise on another contact model: "
        f"stated as the one cause within {ct['magnitude_within']:.0%} in >= {ct['observed_single_right']:.0%}",
        "contact-wrong": "effects outside the library on another contact model: a library mechanism the one cause in "
        f"<= {ct['wrong_single']:.0%}",
    }
    told = {
        "contact-single": f"; told the cause, its own hypothesis within tolerance in {_f(c.get('told_right'), '.2f')}"
    }
    return claims + [
        Claim(
            f"gap-observed-{cid}",
            "gap",
            prefix + statement,
            _meets(c, ct, CONTACT_TARGETS[cid]),
            f"{_f(c[CONTACT_TARGETS[cid][0]])} on {c[CONTACT_TARGETS[cid][1]]} logs{told.get(cid, '')}",
            **_tally(c, CONTACT_TARGETS[cid]),
        )
        for cid, statement in statements.items()
    ]


def contact_claims(c: dict | None) -> list[Claim]:
    """The other-contact benchmark's targets (config ``gap.contact_benchmark.targets``), fixed before its first run."""
    if not c:
        return []
    t = c["targets"]

    def split(key: str) -> str:
        return (
            f"MuJoCo contact models {_f(c[f'{key}_mujoco'], '.2f')} on {c[f'n_{key}_mujoco']}, Bullet "
            f"{_f(c[f'{key}_bullet'], '.2f')} on {c[f'n_{key}_bullet']}"
        )

    return [
        Claim(
            "gap-contact-null",
            "gap",
            f"Null logs of another contact model: no library effect stated as a cause in >= {t['null_no_library']:.0%}",
            _meets(c, t, CONTACT_TARGETS["contact-null"]),
            f"{_f(c['null_no_library'])} on {c['n_null_no_library']} logs ({split('null_no_library')})",
            **_tally(c, CONTACT_TARGETS["contact-null"]),
        ),
        Claim(
            "gap-contact-named",
            "gap",
            f"In-library effects of at least {c['min_size_sd']:g}x the noise on another "
            f"contact model: among the explanations the verdict names in >= {t['among_named']:.0%}",
            _holds(c["among_named"], lambda x: x >= t["among_named"]),
            f"{_f(c['among_named'])} on "
            f"{c['n_among_named']} logs ({split('among_named')}); stated as the one cause in "
            f"{_f(c['one_cause'], '.2f')}, of which the true effect within {t['magnitude_within']:.0%} in "
            f"{_f(c['one_cause_right'], '.2f')} ({c['n_one_cause_right']} logs); told the cause, its own "
            f"hypothesis within {t['magnitude_within']:.0%} in {_f(c.get('told_right'), '.2f')}",
            **tally(c["among_named"], c["n_among_named"]),
        ),
        Claim(
            "gap-contact-contenders",
            "gap",
            f"... with at most {t['contenders_mean']:g} explanations in contention on average",
            _holds(c["contenders_mean"], lambda x: x <= t["contenders_mean"]),
            f"mean {_f(c['contenders_mean'], '.2f')}, largest {c['contenders_max']}",
        ),
        Claim(
            "gap-contact-wrong",
            "gap",
            f"Effects outside the library on another contact model: a library mechanism "
            f"stated as the one cause in <= {t['wrong_single']:.0%}",
            _meets(c, t, CONTACT_TARGETS["contact-wrong"]),
            f"{_f(c['wrong_single'])} on {c['n_wrong_single']} logs "
            f"({split('wrong_single')}); stated as a cause at all {_f(c['wrong_mechanism'], '.2f')}",
            **_tally(c, CONTACT_TARGETS["contact-wrong"]),
        ),
    ]


def lab_claims(r: Mapping | None) -> list[Claim]:
    """The lab benchmark's targets (config ``gap.lab_benchmark.targets``, fixed before any run) on the sealed set's
    :func:`score_lab` result: without a reference session (each log alone and with its probes: both must hold), and
    with one (overall and on each engine that has logs of the kind), its closed loop included; none where the stage
    has no lab result. The one cause right without a reference, and told the cause, are figures of the report, not
    claims: one log cannot carry them past the ceiling its contact sets."""
    if not r:
        return []
    t = r["targets"]
    w, wo = r["probes"], r["no_probes"]
    ref = (r.get("reference") or {}).get("all")
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

    def both(key: str, target: str, check) -> tuple[bool, str]:
        """Whether metric ``key`` holds ``target`` alone and with probes (``check``: at_least or at_most), and the
        detail of both."""
        holds = check(w["all"][key], target) and check(wo["all"][key], target)
        return holds, f"with probes {share(w['all'], key)}; alone {share(wo['all'], key)}"

    def every_engine(res: Mapping, key: str, target: str, check) -> bool:
        """``key`` holds ``target`` overall and on every engine with logs of the kind."""
        engines = [res.get(f"{key}_{e}") for e in ENGINES if res.get(f"n_{key}_{e}")]
        return check(res.get(key), target) and all(check(x, target) for x in engines)

    claims = [
        Claim(
            "gap-lab-null",
            "gap",
            f"Lab benchmark, null logs (contacts and engines not the table's): no effect beyond the contact stated in "
            f">= {t['null_no_library']:.0%}, alone and with probes",
            *both("null_no_library", "null_no_library", at_least),
        ),
        Claim(
            "gap-lab-pusher",
            "gap",
            "Lab benchmark, null logs read without the pusher's speed or free strokes: a pusher cause stated in "
            f"<= {t['pusher_unmeasured']:.0%}",
            at_most(wo["all"]["null_pusher_stated"], "pusher_unmeasured"),
            share(wo["all"], "null_pusher_stated"),
            **tally(wo["all"]["null_pusher_stated"], wo["all"].get("n_null_pusher_stated")),
        ),
        Claim(
            "gap-lab-named",
            "gap",
            f"Lab benchmark, one big effect: among the named in >= {t['among_named']:.0%}, with at most "
            f"{t['contenders_mean']:g} contenders on average, alone and with probes",
            *_joined(
                both("among_named", "among_named", at_least),
                (
                    at_most(w["all"]["contenders_mean"], "contenders_mean")
                    and at_most(wo["all"]["contenders_mean"], "contenders_mean"),
                    f"contenders with probes {_f(w['all']['contenders_mean'], '.2f')}, alone "
                    f"{_f(wo['all']['contenders_mean'], '.2f')}",
                ),
            ),
        ),
        Claim(
            "gap-lab-wrong",
            "gap",
            f"Lab benchmark, effects outside the library: a library mechanism stated as a cause in "
            f"<= {t['wrong_mechanism']:.0%}, alone and with probes",
            *both("wrong_mechanism", "wrong_mechanism", at_most),
        ),
        Claim(
            "gap-lab-wrong-effect",
            "gap",
            f"Lab benchmark, one-effect logs: another library effect stated as the one cause in "
            f"<= {t['wrong_effect_single']:.0%}, alone and with probes",
            *both("wrong_effect_single", "wrong_effect_single", at_most),
        ),
        Claim(
            "gap-lab-contact",
            "gap",
            f"Lab benchmark, MuJoCo variants whose table contact is off: the contact named in >= {t['contact_named']:.0%}",
            at_least(w["all"]["contact_named"], "contact_named"),
            share(w["all"], "contact_named", engine=False),
            **tally(w["all"]["contact_named"], w["all"].get("n_contact_named")),
        ),
    ]
    if not ref:
        return claims
    rows = (
        ("gap-lab-ref-null", "null logs: no change stated", "null_no_change", "ref_null_no_change", at_least),
        (
            "gap-lab-ref-single",
            f"one big effect its observables can tell from the others: stated as the one cause within {within}",
            "single_right_readable",
            "ref_single_right",
            at_least,
        ),
        ("gap-lab-ref-named", "one big effect: among the named", "among_named", "ref_among_named", at_least),
        (
            "gap-lab-ref-wrong-effect",
            "one-effect logs: another library effect stated as the one cause",
            "wrong_effect_single",
            "ref_wrong_effect_single",
            at_most,
        ),
        (
            "gap-lab-ref-wrong",
            "effects outside the library: a library effect stated as the one cause",
            "wrong_single",
            "ref_wrong_single",
            at_most,
        ),
        (
            "gap-lab-ref-shrink",
            f"one big effect: the stated share of the gap within {t['shrink_tolerance']:g} of the true share",
            "shrink_within",
            "ref_shrink_within",
            at_least,
        ),
        (
            "gap-lab-ref-contact",
            "MuJoCo variants whose table contact is off: the contact named in the standing gap",
            "contact_named",
            "ref_contact_named",
            at_least,
        ),
    )
    for cid, words, key, target, check in rows:
        sign = ">=" if check is at_least else "<="
        claims.append(
            Claim(
                cid,
                "gap",
                f"Lab benchmark with a reference session, {words}: {sign} {t[target]:.0%}, overall and on each engine",
                every_engine(ref, key, target, check),
                share(ref, key, engine=key != "contact_named"),
                **tally(ref.get(key), ref.get(f"n_{key}")),
            )
        )
    loop = r.get("closed_loop") or {}
    nxt, rnd = loop.get("next") or {}, loop.get("random") or {}
    claims.append(
        Claim(
            "gap-lab-ref-loop",
            "gap",
            f"Lab benchmark with a reference session, one big effect with several contenders: the one cause right within "
            f"{within} in >= {t['closed_loop']:.0%} once the recommended next experiments are run, and more often than "
            "after as many random pushes",
            at_least(nxt.get("one_cause_right"), "closed_loop")
            and _holds(nxt.get("one_cause_right"), lambda x: x > (rnd.get("one_cause_right") or 0.0)),
            f"{_f(nxt.get('one_cause_right'), '.2f')} on {nxt.get('n_single', 0)} logs; as many random pushes of the "
            f"log's design: {_f(rnd.get('one_cause_right'), '.2f')}; told the cause {_f(nxt.get('told_right'), '.2f')} "
            f"(random {_f(rnd.get('told_right'), '.2f')}); probes run per log {_f(nxt.get('probes_added_mean'), '.2f')}",
            **tally(nxt.get("one_cause_right"), nxt.get("n_single")),
        )
    )
    return claims


def _joined(*parts: tuple[bool, str]) -> tuple[bool, str]:
    """Several checks as one claim's: all must hold; their details joined."""
    return all(ok for ok, _ in parts), "; ".join(detail for _, detail in parts)


def write_benchmark_markdown(result: dict, path: str | os.PathLike) -> None:
    """Write the benchmark report (``results/gap/benchmark.md``) from :func:`score_cases`'s result."""
    r = result
    targets = r["targets"]
    claims = claims_of(r)
    w = r["world_error"]
    sd = r["min_size_sd"]
    noise = r["noise"]
    lines = [
        "# Gap diagnostic benchmark",
        "",
        f"{r['n_logs']} push logs from the converged world of `imply.realworld` (RK4 on uniform steps, effects "
        "through its own mechanisms, no tables; labels sealed apart): "
        f"{r['n_null_gaussian']} null logs with Gaussian noise (sd {noise.get('sd', 0.02)}), {r['n_null_heavy']} null "
        f"logs with heavy-tailed noise (Student-t, sd {noise.get('heavy_sd', 0.03)}) and gross outliers, "
        f"{r['n_single']} logs with one library effect, {r['n_unidentifiable']} with one the library marks not "
        f"identifiable, {r['n_double']} with two library effects at once, {r['n_outside']} with one effect outside "
        f"the library. Objects across the table's whole range, magnitudes drawn continuously, directional effects at "
        f"random azimuths; {r['measured_mass_logs']} logs carry weighed masses and {r['stop_time_logs']} stop times. "
        f"An effect is *big* when the RMS log d it leaves after the baseline fit of the noise-free log is at least "
        f"{sd:g}x the log's noise sd.",
        "",
        f"The world's own numerical error (against the same pushes stepped {w['factor']} times finer, {w['n']} pushes): "
        f"max {_f(w['max'], '.4f')}, RMS {_f(w['rms'], '.4f')} in log d (stop time: max {_f(w['stop_max'], '.4f')}, RMS "
        f"{_f(w['stop_rms'], '.4f')}); nominal pushes against `imply.sim.reference`: max {_f(w['ref_max'], '.4f')}, "
        f"RMS {_f(w['ref_rms'], '.4f')}. The table's measured error: max {_f(w['table_max'], '.4f')}, RMS "
        f"{_f(w['table_rms'], '.4f')}. Null logs' visible RMS (noise-free, after the baseline fit): median "
        f"{_f(r['null_visible_rms_median'], '.4f')}, max {_f(r['null_visible_rms_max'], '.4f')}.",
        "",
        "| target | measured | n | target value |",
        "|---|---|---|---|",
        f"| false alarms, null logs | {_f(r['false_alarm'])} | {r['n_null']} | <= {targets['false_alarm']} |",
        f"| ... Gaussian / heavy-tailed nulls | {_f(r['false_alarm_gaussian'])} / {_f(r['false_alarm_heavy'])} | "
        f"{r['n_null_gaussian']} / {r['n_null_heavy']} | |",
        f"| top-1, one big library effect | {_f(r['top1_big'])} | {r['n_big']} | >= {targets['top1']} |",
        f"| both named, two big effects | {_f(r['both_named_big'])} | {r['n_double_big']} | >= {targets['both_named']} |",
        f"| 'none', effects outside the library | {_f(r['none_recall_outside'])} | {r['n_outside']} | >= "
        f"{targets['none_outside']} |",
        f"| median relative magnitude error | {_f(r['magnitude_rel_error_median'])} | {r['n_magnitudes']} | <= "
        f"{targets['magnitude_error']} |",
        f"| median held-out shrinkage of the gap above the noise floor | {_f(r['shrinkage_median'])} | "
        f"{r['n_shrinkage']} | >= {targets['shrinkage']} |",
        "",
        "| more | value | n |",
        "|---|---|---|",
        f"| top-1, all one-effect logs | {_f(r['top1_all'])} | {r['n_single']} |",
        f"| both named, all two-effect logs | {_f(r['both_named_all'])} | {r['n_double']} |",
        f"| exactly the true effects (no extra), big library logs | {_f(r['exact_set_big'])} | |",
        f"| 'none', big effects outside the library | {_f(r['none_recall_outside_big'])} | {r['n_outside_big']} |",
        f"| 'none', effects the library marks not identifiable | {_f(r['none_unidentifiable'])} | "
        f"{r['n_unidentifiable']} |",
        f"| true magnitude inside the reported 95% interval | {_f(r['magnitude_in_ci'])} | {r['n_magnitudes']} |",
        f"| median azimuth error (tilt, anisotropy), degrees | {_f(r['azimuth_error_median_deg'], '.1f')} | "
        f"{r['n_azimuths']} |",
        f"| median shrinkage of the anchored disagreement | {_f(r['anchored_shrinkage_median'])} | |",
        f"| gross outliers flagged (recall) | {_f(r['outlier_recall'])} | {r['outliers_true']} |",
        f"| pushes flagged in logs without gross outliers | {r['outliers_flagged_in_gaussian_logs']} | |",
        f"| median diagnosis time per log, s | {_f(r['seconds_per_log_median'], '.2f')} | |",
        *_shrink_rows(r),
        "",
        "## Claims",
        "",
    ]
    for c in claims:
        lines.append(f"- {'HOLDS' if c.holds else 'FAILS'}: {c.statement} ({c.detail})")
    cols = sorted({c for row in r["confusion"].values() for c in row}, key=lambda c: (c == "none", c))
    lines += [
        "",
        "## Confusion matrix (rows: what the log carries; columns: the first cause stated, or none)",
        "",
        "| true \\ predicted | " + " | ".join(cols) + " |",
        "|---|" + "---|" * len(cols),
    ]
    for t, row in r["confusion"].items():
        lines.append(f"| {t} | " + " | ".join(str(row.get(c, 0)) for c in cols) + " |")
    lines += [
        "",
        "## Logs",
        "",
        "| log | carries | noise | T | mass | visible RMS (x noise) | accepted | correct | share closed |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for c in r["cases"]:
        lines.append(
            f"| {c['case']} | {c['effects']} ({c['group']}) | {c['noise']} | {'y' if c['stop_time'] else ''} | "
            f"{'y' if c['measured_mass'] else ''} | {c['visible_rms']:.4f} ({c['size_sd']:.1f}) | "
            f"{c['accepted']} | {'yes' if c['correct'] else 'no'} | {_f(c['gap_share_closed'], '.2f')} |"
        )
    lines += contact_markdown(r.get("contact"))
    lines += observed_markdown(r)
    write_text(path, "\n".join(lines) + "\n")


# (label, key, format, target key or None, direction) of the side-by-side table
MAIN_ROWS = (
    ("false alarms, null logs", "false_alarm", ".3f", "false_alarm", "<="),
    ("top-1, one big library effect", "top1_big", ".3f", "top1", ">="),
    ("both named, two big effects", "both_named_big", ".3f", "both_named", ">="),
    ("'none', effects outside the library", "none_recall_outside", ".3f", "none_outside", ">="),
    ("median relative magnitude error", "magnitude_rel_error_median", ".3f", "magnitude_error", "<="),
    ("median held-out shrinkage", "shrinkage_median", ".3f", "shrinkage", ">="),
    ("median diagnosis time per log, s", "seconds_per_log_median", ".2f", None, ""),
)
CONTACT_ROWS = (
    ("null logs: no library effect stated", "null_no_library", ".3f", "null_no_library", ">="),
    ("one big effect: among the named", "among_named", ".3f", "among_named", ">="),
    ("... explanations in contention, mean", "contenders_mean", ".2f", "contenders_mean", "<="),
    ("... stated as the one cause", "one_cause", ".3f", None, ""),
    ("... the true effect the one cause, within tolerance", "single_right", ".3f", None, ""),
    ("... told the cause: its own hypothesis within tolerance", "told_right", ".3f", None, ""),
    ("outside effects: a library mechanism the one cause", "wrong_single", ".3f", "wrong_single", "<="),
    ("median diagnosis time per log, s", "seconds_per_log_median", ".2f", None, ""),
)


def observed_markdown(r: dict) -> list[str]:
    """The same logs diagnosed with every observable they carry (the pusher's measured speed and the box's track),
    beside the default diagnosis: one table per benchmark."""
    o = r.get("observed")
    if not o:
        return []
    lines = [
        "",
        "# With what a robot records",
        "",
        "The same logs, diagnosed again with the pusher's measured speed and the box's track in every "
        "hypothesis's fit (options `use_pusher_speed` and `use_track`), beside the default diagnosis "
        "(displacement, and stop time where the log has it).",
        "",
    ]

    def table(title: str, rows, without: dict, with_: dict, targets: dict) -> list[str]:
        out = [f"## {title}", "", "| | default | with pusher speed and track | target |", "|---|---|---|---|"]
        for label, key, spec, tkey, direction in rows:
            target = f"{direction} {targets[tkey]}" if tkey and tkey in targets else ""
            out.append(f"| {label} | {_f(without.get(key), spec)} | {_f(with_.get(key), spec)} | {target} |")
        return out + [""]

    lines += table("Main benchmark", MAIN_ROWS, r, o, r["targets"])
    if r.get("contact") and o.get("contact"):
        lines += table("Other contact models", CONTACT_ROWS, r["contact"], o["contact"], r["contact"]["targets"])
    return lines


def _shrink_rows(r: Mapping) -> list[str]:
    """Table rows: how far the stated share of the gap (the share the stated cause closes) comes from the true share
    the effect accounts for in the noise-free log, over the big one-effect logs (a figure, no target here)."""
    tol = r.get("shrink_tolerance")
    return [
        f"| stated share of the gap within {_f(tol, 'g')} of the true share, big one-effect logs | "
        f"{_f(r.get('shrink_within'))} | {r.get('n_shrink_within', 0)} |",
        f"| ... median and largest difference | {_f(r.get('shrink_error_median'))}, {_f(r.get('shrink_error_max'))} | |",
        f"| the same share re-simulated in the corrected scene, within {_f(tol, 'g')} of the true share | "
        f"{_f(r.get('resim_shrink_within'))} | {r.get('n_resim_shrink_within', 0)} |",
        f"| ... median and largest difference | {_f(r.get('resim_shrink_error_median'))}, "
        f"{_f(r.get('resim_shrink_error_max'))} | |",
    ]


def contact_markdown(c: dict | None) -> list[str]:
    """The other-contact benchmark's section of the report: its claims, the closed loop, the confusion matrix and
    every log's verdict."""
    if not c:
        return []
    lines = [
        "",
        "# Other contact models",
        "",
        f"{c['n_logs']} push logs from worlds whose contact is not the table's (MuJoCo with a contact model of its "
        "own, and the Bullet engine), with and without effects; labels sealed apart. An effect counts when the "
        f"RMS log d it adds on top of its log's contact model (each object's mean change removed) is at least "
        f"{c['min_size_sd']:g}x the noise sd. Median diagnosis time per log "
        f"{_f(c['seconds_per_log_median'], '.2f')} s.",
        "",
        "## Claims",
        "",
    ]
    for cl in contact_claims(c):
        lines.append(f"- {'HOLDS' if cl.holds else 'FAILS'}: {cl.statement} ({cl.detail})")
    lines += ["", "| | value | logs |", "|---|---|---|", *_shrink_rows(c)]
    loop = c.get("closed_loop")
    if loop:
        lines += [
            "",
            "## Closed loop (logs with several explanations in contention: the recommended next pushes against as many random pushes of "
            "the log's own design, each run in the same world and appended, then diagnosed again)",
            "",
            "| | next pushes | random pushes of the log's design |",
            "|---|---|---|",
        ]
        n, r = loop["next"], loop["random"]
        lines += [
            f"| one-effect logs: the true effect the one cause, within tolerance | {_f(n['one_cause_right'])} | "
            f"{_f(r['one_cause_right'])} ({n['n_single']} logs) |",
            f"| ... told the cause: its own hypothesis within tolerance, whatever the verdict | "
            f"{_f(n.get('told_right'))} | {_f(r.get('told_right'))} |",
            f"| null logs: no library effect stated | {_f(n['null_no_library'])} | {_f(r['null_no_library'])} "
            f"({n['n_null']} logs) |",
            f"| outside effects: a library mechanism the one cause | {_f(n['wrong_single'])} | {_f(r['wrong_single'])} "
            f"({n['n_outside']} logs) |",
            f"| explanations in contention, mean | {_f(n['contenders_mean'], '.2f')} | {_f(r['contenders_mean'], '.2f')} |",
            f"| pushes appended per log, mean | {_f(n['pushes_added_mean'], '.1f')} | {_f(r['pushes_added_mean'], '.1f')} |",
        ]
    cols = sorted({k for row in c["confusion"].values() for k in row})
    lines += [
        "",
        "## Confusion matrix (rows: what the log carries, and its engine; columns: the causes stated, or the "
        "identification)",
        "",
        "| true \\ verdict | " + " | ".join(cols) + " |",
        "|---|" + "---|" * len(cols),
    ]
    for t, row in c["confusion"].items():
        lines.append(f"| {t} | " + " | ".join(str(row.get(k, 0)) for k in cols) + " |")
    lines += [
        "",
        "## Logs",
        "",
        "| log | carries | engine | design | adequacy | identification | causes | contenders |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in c["cases"]:
        lines.append(
            f"| {row['case']} | {row['effects']} ({row['group']}) | {row['engine']} | {row['design']} | "
            f"{row['adequacy']} | {row['identification']} | {row['causes']} | {row['contenders']} |"
        )
    return lines
