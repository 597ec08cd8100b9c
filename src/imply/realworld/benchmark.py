"""Scoring the diagnostic against the gap benchmark's sealed labels.

The logs come from :mod:`imply.realworld` (a separate code path: its own stepping and
effect mechanisms, no tables); each label holds the injected effects, the noise and the
noise-free observables. A log's *visible size* is the RMS log displacement left after
each object's baseline (mass, friction) fit of its noise-free displacements (friction
alone where the log carries weighed masses, as the diagnostic fits): what no choice of
mass and friction absorbs, and so what the diagnostic can possibly see. An effect is
*big* when its visible size is at least ``min_size_sd`` times the log's noise sd; in a
two-effect log each effect's size is that of the same log with the effect alone.

Scores (library effects are named by their alias class: an effect the diagnostic
reports as aliased with the one named counts as named; an effect counts as accepted or
named only where the verdict states it as a cause, :func:`stated`, not where the final
model holds it to describe a rest the verdict leaves open or names it beside the
discrepancy):

- false alarms: null logs (Gaussian and heavy-tailed) with any effect accepted;
- top-1: one-effect logs with a big identifiable effect whose first stated cause is it;
- both named: two-effect logs with both effects big whose stated causes name both;
- none recall: logs with an effect outside the library answered "none of the candidates"
  (all of them, and those whose effect is big);
- magnitude error: median relative error of the magnitude of every big effect named (by
  its own name), in one- and two-effect logs; the azimuth error of tilts and
  anisotropies beside it;
- shrinkage: median share of the held-out gap above the noise floor closed, over the
  logs with a big library effect (0 where the verdict is "none").
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pandas as pd

from imply.diagnose.analysis import Summary
from imply.diagnose.conclusion.verdict import Identification
from imply.diagnose.inference.estimates import AcceptedEffect
from imply.diagnose.inputs.observables import Observables
from imply.diagnose.physics.candidates import CONTACT
from imply.realworld.cases import BenchmarkConfig

log = logging.getLogger("imply")


def visible_size(label: dict, table, what: str = "all", grid: int = 61) -> float:
    """RMS log d of the noise-free log ``what`` ("all" or one effect's name) after each object's baseline fit."""
    from imply.diagnose.inference.fit import Problem
    from imply.diagnose.inputs.pushlog import PushLog
    from imply.diagnose.physics.candidates import Model

    nf = label["noise_free"][what]
    p = label["pushes"]
    keep = np.asarray(p["kept"], bool) & np.asarray(nf["ok"], bool) & np.isfinite(nf["log_d"])
    names = np.asarray(p["object"])[keep]
    objects = list(dict.fromkeys(names))
    index = {o: i for i, o in enumerate(objects)}
    mass = np.array([round(label["objects"][o]["mass"], 3) for o in objects]) if label["measured_mass"] else None
    if mass is not None:
        mass = np.clip(mass, *table.mass_range)
    v = np.clip(np.asarray(p["speed"], float)[keep], *table.speed_range)
    pl = PushLog(
        path="<noise-free>",
        frame=pd.DataFrame(),
        objects=objects,
        obj=np.array([index[o] for o in names]),
        speed=v,
        displacement=np.exp(np.asarray(nf["log_d"], float)[keep]),
        direction=np.asarray(p["direction"], float)[keep],
        has_direction=True,
        mass=mass,
    )
    prob = Problem.of(pl, table, None, grid=grid, observables=Observables(stop_time=False, probes=False))
    fit = prob.initial_fit(Model())
    return float(np.sqrt(fit.sse.sum() / v.size))


def stated(summary: Summary) -> list[AcceptedEffect]:
    """The effects the verdict states as causes (of the final model's: not those it names only beside the
    discrepancy, or uses only to describe a rest it leaves open)."""
    if summary.verdict.is_none:
        return []
    return [e for e in summary.effects if e.effect in summary.verdict.effects]


def _classes(summary: Summary) -> list[set[str]]:
    """Each stated effect's alias class (as a set of candidate names)."""
    return [set(e.cls.split("+")) if e.cls else {e.effect} for e in stated(summary)]


PUSHER_CAUSES = ("speed_gain", "speed_offset", "pusher_softness")


def classes_beyond_contact(classes: list[set[str]]) -> list[set[str]]:
    """The classes that are not the box-table contact itself (:data:`imply.diagnose.physics.candidates.CONTACT`): on a
    world whose contact differs from the table's, naming the contact is never wrong, and an effect stated beside
    it is still the one effect."""
    return [c for c in classes if not c <= set(CONTACT)]


def _named(true: str, summary: Summary) -> bool:
    return any(true in cls for cls in _classes(summary))


def wrong_share(correct: pd.Series) -> float:
    """The share of logs whose verdict is wrong (nan for none): counted, so that 2 of 40 reads 0.05 exactly and
    a target of at most 5% is judged on the count, not on ``1 - 0.95``'s rounding."""
    return float((~correct.astype(bool)).sum() / len(correct)) if len(correct) else float("nan")


def true_theta(e: dict) -> dict:
    return {
        "magnitude": abs(e["magnitude"]) if e["name"] in ("tilt", "anisotropic") else e["magnitude"],
        "azimuth_deg": None if e.get("azimuth") is None else float(np.degrees(e["azimuth"])),
    }


def _angle_error(a: float, b: float, period: float) -> float:
    d = (a - b) % period
    return float(min(d, period - d))


def visible_sizes(labels: dict[str, dict], table, *, progress: bool = True) -> dict[str, dict]:
    """Each log's visible sizes: ``{"all": x, effect: x}`` (:func:`visible_size` of each noise-free part)."""
    from tqdm.auto import tqdm

    return {
        cid: {what: visible_size(lab, table, what) for what in lab["noise_free"]}
        for cid, lab in tqdm(labels.items(), desc="visible sizes", unit="log", disable=not progress)
    }


def measured(labels: dict[str, dict]) -> dict[str, dict]:
    """The labels of the logs a lab could have written: those whose world settled at least one of their pushes
    (``pushes.kept``). A world that settles none (a box creeping down a tilted table on regularised friction, say)
    leaves a log with no rows, which is neither diagnosed (``imply study gap diagnose-many`` passes it by) nor scored."""
    kept = {cid: lab for cid, lab in labels.items() if any(lab["pushes"]["kept"])}
    for cid in sorted(set(labels) - set(kept)):
        log.warning("log %s left out: its world settled none of its %d pushes", cid, len(labels[cid]["pushes"]["kept"]))
    return kept


def find_summaries(labels: dict[str, dict], report_dirs: list[Path]) -> dict[str, Summary]:
    """Each log's diagnosis summary, from the folder of report folders that holds it."""
    summaries = {}
    for cid in labels:
        found = [r / cid / "summary.json" for r in report_dirs if (r / cid / "summary.json").is_file()]
        if not found:
            raise FileNotFoundError(f"no diagnosis for log {cid} in {', '.join(map(str, report_dirs))}")
        with open(found[0]) as fh:
            summaries[cid] = Summary.from_dict(json.load(fh))
    return summaries


def world_error(accuracy: dict) -> dict:
    """The world's measured error (:func:`imply.realworld.accuracy.measure_error`) and the table's, in log d."""
    fin = (accuracy.get("against_finer") or {}).get("log_d") or {}
    ref = (accuracy.get("against_reference") or {}).get("log_d") or {}
    fin_t = (accuracy.get("against_finer") or {}).get("log_stop_time") or {}
    tab = accuracy.get("table_numerical_error") or {}
    return {
        "max": fin.get("max_abs"),
        "rms": fin.get("rms"),
        "n": fin.get("n"),
        "ref_max": ref.get("max_abs"),
        "ref_rms": ref.get("rms"),
        "ref_n": ref.get("n"),
        "stop_max": fin_t.get("max_abs"),
        "stop_rms": fin_t.get("rms"),
        "table_max": tab.get("max_abs_log_d"),
        "table_rms": tab.get("rms_log_d"),
        "factor": (accuracy.get("against_finer") or {}).get("factor"),
    }


def score_cases(
    labels: dict[str, dict],
    summaries: dict[str, Summary],
    sizes: dict[str, dict],
    *,
    config: BenchmarkConfig,
    accuracy: dict,
) -> dict:
    """Benchmark metrics from sealed labels, diagnose summaries and visible sizes (per log: {"all": x, effect: x}).

    Besides every log's row and the rates (``false_alarm``, ``top1_big``, ``both_named_big``,
    ``none_recall_outside``, ``magnitude_rel_error_median``, ``shrinkage_median``, ...), the
    result holds what they were judged by (``min_size_sd``, ``targets``, ``noise_sd``) and
    the world's measured numerical error beside the table's (``world_error``).
    """
    min_size_sd = config.min_size_sd
    rows, mags = [], []
    for cid in sorted(labels):
        lab, s = labels[cid], summaries[cid]
        group = lab["group"]
        true = [e["name"] for e in lab["effects"]]
        sd = lab["noise"]["sd"]
        size = sizes[cid]["all"]
        eff_sizes = {n: sizes[cid].get(n, size) for n in true}
        accepted = [e.effect for e in stated(s)]
        predicted = accepted[0] if accepted else "none"
        big_each = {n: bool(eff_sizes[n] >= min_size_sd * sd) for n in true}
        if group in ("null_gaussian", "null_heavy"):
            correct = not accepted
        elif group in ("outside", "single_unidentifiable"):
            correct = not accepted
        elif group == "single":
            cls = _classes(s)
            correct = bool(cls) and true[0] in cls[0]
        else:  # double
            correct = all(_named(n, s) for n in true)
        exact = None
        if group in ("single", "double"):
            named = _classes(s)
            exact = len(named) == len(true) and all(_named(n, s) for n in true)
        for e in lab["effects"]:
            if group not in ("single", "double") or not big_each[e["name"]]:
                continue
            hit = next((r for r in stated(s) if r.effect == e["name"]), None)
            if hit is None:
                continue
            t = true_theta(e)
            rel = abs(hit.magnitude - t["magnitude"]) / abs(t["magnitude"]) if t["magnitude"] else None
            az = None
            if t["azimuth_deg"] is not None and hit.azimuth_deg is not None:
                period = 180.0 if e["name"] == "anisotropic" else 360.0
                az = _angle_error(hit.azimuth_deg, t["azimuth_deg"], period)
            mags.append(
                {
                    "case": cid,
                    "effect": e["name"],
                    "true": t["magnitude"],
                    "estimate": hit.magnitude,
                    "relative_error": rel,
                    "azimuth_error_deg": az,
                    "in_ci": bool(hit.ci95[0] <= t["magnitude"] <= hit.ci95[1]),
                }
            )
        sh = s.shrinkage
        kept = lab.get("rows_kept") or []
        flagged = {tuple(kept[r.row]) for r in s.outliers.get("displacement", []) if kept}
        true_out = {(int(j), int(r)) for r, j in lab["outliers"]}
        rows.append(
            {
                "case": cid,
                "group": group,
                "effects": "+".join(true) or "null",
                "noise": lab["noise"]["kind"],
                "noise_sd": sd,
                "stop_time": lab["stop_time"],
                "measured_mass": lab["measured_mass"],
                "visible_rms": size,
                "size_sd": size / sd,
                "big": all(big_each.values()) if true else False,
                "predicted": predicted,
                "accepted": "+".join(accepted) or "none",
                "correct": bool(correct),
                "exact": exact,
                "gap_share_closed": sh.gap_share_closed if accepted else 0.0,
                # the share of the gap the stated causes close against the true one (one-effect logs)
                "true_share": true_cause_share({"all": size}) if group == "single" else None,
                "stated_share": stated_cause_share(s),
                "resimulated_share": resimulated_cause_share(s),
                "anchored_share_closed": sh.anchored_share_closed if accepted else 0.0,
                "before_rms": sh.before_rms,
                "after_rms": sh.after_rms,
                "true_outliers": len(true_out),
                "flagged_outliers": len(flagged),
                "flagged_true": len(flagged & true_out),
                "seconds": s.seconds,
            }
        )
    frame = pd.DataFrame(rows)
    mag = pd.DataFrame(
        mags, columns=["case", "effect", "true", "estimate", "relative_error", "azimuth_error_deg", "in_ci"]
    )

    def rate(mask) -> tuple[float, int]:
        sub = frame[mask]
        return (float(sub["correct"].mean()) if len(sub) else float("nan")), int(len(sub))

    g = frame["group"]
    null = g.isin(["null_gaussian", "null_heavy"])
    fa_all = wrong_share(frame.loc[null, "correct"])
    fa_gauss = wrong_share(frame.loc[g == "null_gaussian", "correct"])
    fa_heavy = wrong_share(frame.loc[g == "null_heavy", "correct"])
    single, double, out = g == "single", g == "double", g == "outside"
    top1_big, n_big = rate(single & frame["big"])
    top1_all, n_single = rate(single)
    both_big, n_both_big = rate(double & frame["big"])
    both_all, n_double = rate(double)
    none_out, n_out = rate(out)
    none_out_big, n_out_big = rate(out & frame["big"])
    unident, n_unident = rate(g == "single_unidentifiable")
    lib_big = (single | double) & frame["big"]
    shares = frame.loc[lib_big, "gap_share_closed"].astype(float)
    anch = frame.loc[lib_big, "anchored_share_closed"].astype(float)
    exact = frame.loc[lib_big, "exact"].astype(float)
    truth = np.where(
        g == "outside", "outside:" + frame["effects"], np.where(g == "double", "two effects", frame["effects"])
    )
    truth = np.where(g == "null_heavy", "null (heavy-tailed)", truth)
    confusion = pd.crosstab(pd.Series(truth, name="true"), frame["predicted"]).sort_index()
    rel = mag["relative_error"].dropna().astype(float)
    az = mag["azimuth_error_deg"].dropna().astype(float)
    out_rows = frame["true_outliers"] > 0
    tolerance = float(config.targets.get("shrink_tolerance", 0.15))
    shrink = shrink_scores(frame, single & frame["big"], tolerance)
    resim = shrink_scores(frame, single & frame["big"], tolerance, column="resimulated_share", prefix="resim_shrink")
    return {
        **shrink,
        **resim,
        "cases": rows,
        "magnitudes": mags,
        "confusion": {r: {c: int(confusion.loc[r, c]) for c in confusion.columns} for r in confusion.index},
        "n_logs": int(len(frame)),
        "false_alarm": fa_all,
        "n_null": int(null.sum()),
        "false_alarm_gaussian": fa_gauss,
        "n_null_gaussian": int((g == "null_gaussian").sum()),
        "false_alarm_heavy": fa_heavy,
        "n_null_heavy": int((g == "null_heavy").sum()),
        "top1_big": top1_big,
        "n_big": n_big,
        "top1_all": top1_all,
        "n_single": n_single,
        "both_named_big": both_big,
        "n_double_big": n_both_big,
        "both_named_all": both_all,
        "n_double": n_double,
        "none_recall_outside": none_out,
        "n_outside": n_out,
        "none_recall_outside_big": none_out_big,
        "n_outside_big": n_out_big,
        "none_unidentifiable": unident,
        "n_unidentifiable": n_unident,
        "exact_set_big": float(exact.mean()) if len(exact) else float("nan"),
        "magnitude_rel_error_median": float(rel.median()) if len(rel) else float("nan"),
        "n_magnitudes": int(len(rel)),
        "magnitude_in_ci": float(mag["in_ci"].mean()) if len(mag) else float("nan"),
        "azimuth_error_median_deg": float(az.median()) if len(az) else float("nan"),
        "n_azimuths": int(len(az)),
        "shrinkage_median": float(np.nanmedian(shares)) if shares.notna().any() else float("nan"),
        "n_shrinkage": int(shares.notna().sum()),
        "anchored_shrinkage_median": float(np.nanmedian(anch)) if anch.notna().any() else float("nan"),
        "null_visible_rms_median": float(frame.loc[null, "visible_rms"].median()) if null.any() else float("nan"),
        "null_visible_rms_max": float(frame.loc[null, "visible_rms"].max()) if null.any() else float("nan"),
        "outliers_true": int(frame["true_outliers"].sum()),
        "outlier_recall": float(frame["flagged_true"].sum() / max(frame["true_outliers"].sum(), 1)),
        "outliers_flagged": int(frame["flagged_outliers"].sum()),
        "outliers_flagged_in_gaussian_logs": int(frame.loc[~out_rows, "flagged_outliers"].sum()),
        "stop_time_logs": int(frame["stop_time"].sum()),
        "measured_mass_logs": int(frame["measured_mass"].sum()),
        "seconds_per_log_median": float(frame["seconds"].dropna().median()) if frame["seconds"].notna().any() else None,
        "min_size_sd": min_size_sd,
        "targets": dict(config.targets),
        "noise_sd": config.noise.sd,
        "noise": config.noise.to_dict(),
        "world_error": world_error(accuracy),
        "world_accuracy": accuracy,
    }


# -- the benchmark of other contact models ----------------------------------------------------------------------
# the groups of the contact benchmark and of the lab benchmark (imply.realworld.lab: one per world)
CONTACT_NULL = ("null_contact", "null_engine", "null_bullet", "null_sapien")
CONTACT_SINGLE = ("single_contact", "single_engine", "single_bullet", "single_sapien")
CONTACT_OUTSIDE = ("outside_contact", "outside_engine", "outside_bullet", "outside_sapien")


def effect_size_on_contact(label: dict, name: str) -> float:
    """RMS log d an effect adds on top of its log's contact model, each object's mean change removed (what no
    choice of one object's friction absorbs, roughly): the noise-free log with the effect against the same
    world without it (``noise_free["contact"]``)."""
    nf = label["noise_free"]
    base = nf.get("contact")
    if base is None:
        return float("nan")
    obj = np.asarray(label["pushes"]["object"])
    ok = np.asarray(nf["all"]["ok"], bool) & np.asarray(base["ok"], bool) & np.asarray(label["pushes"]["kept"], bool)
    diff = np.asarray(nf["all"]["log_d"], float) - np.asarray(base["log_d"], float)
    out = []
    for o in np.unique(obj[ok]):
        sel = ok & (obj == o)
        out.append(diff[sel] - diff[sel].mean())
    resid = np.concatenate(out) if out else np.zeros(0)
    return float(np.sqrt(np.mean(resid**2))) if resid.size else float("nan")


def restricted_truth(e: dict, hit) -> float:
    """The true magnitude of what a restricted (one-combination) estimate measures: the true effect projected on
    the direction the design identifies."""
    az = np.radians(hit.azimuth_deg or 0.0)
    mult = 2.0 if e["name"] == "anisotropic" else 1.0
    return float(abs(e["magnitude"]) * np.cos(mult * (e["azimuth"] - az)))


def stated_error(e: dict, summary: Summary) -> float | None:
    """The relative error of the magnitude the verdict states for the true effect ``e`` (a label's effect): against
    its projection on the identified direction where the estimate is restricted to one (None: not stated)."""
    hit = next((h for h in stated(summary) if h.effect == e["name"]), None)
    if hit is None:
        return None
    restricted = any(k.endswith("_along") for k in hit.components)
    t = restricted_truth(e, hit) if restricted else true_theta(e)["magnitude"]
    return abs(hit.magnitude - t) / abs(t) if t else None


def told_error(e: dict, summary: Summary) -> float | None:
    """The relative magnitude error of the true effect ``e``'s own hypothesis (that effect alone, with or without the
    discrepancy: the heavier), whatever the verdict (None: not fitted alone, as where the library marks it not
    identifiable). A verdict that stated the true effect alone would state this magnitude, so the share of logs where
    it is within tolerance is what a verdict rule could reach on these fits if it were told the cause."""
    own = [h for h in summary.hypotheses if h.effects == [e["name"]] and h.estimates]
    if not own:
        return None
    hit = max(own, key=lambda h: h.weight).estimates[0]
    restricted = any(k.endswith("_along") for k in hit.components)
    t = restricted_truth(e, hit) if restricted else true_theta(e)["magnitude"]
    return abs(hit.magnitude - t) / abs(t) if t else None


def told_within(e: dict, summary: Summary, within: float) -> bool:
    """Whether :func:`told_error` is at most ``within`` (False where the effect was not fitted alone)."""
    told = told_error(e, summary)
    return told is not None and told <= within


def named_classes(summary: Summary) -> list[set[str]]:
    """The alias class (a set of candidate names) of every library effect the verdict names: the causes, then the
    contenders' other effects."""
    effects = summary.aliasing.effects
    return [
        set(effects[n].cls.split("+")) if n in effects and effects[n].identifiable else {n}
        for n in summary.verdict.named
    ]


SCORED_COLUMNS = (
    "group",
    "engine",
    "effects",
    "identification",
    "causes",
    "effect_causes",
    "contact_kinds",
    "contact_named",
    "n_contenders",
    "seconds",
    "pusher_stated",
    "one_cause",
    "big",
    "among_named",
    "named",
    "one_cause_right",
    "told_right",
    "readable",
    "wrong_effect_single",
    "true_share",
    "stated_share",
    "resimulated_share",
)


SPEED_ERRORS = ("speed_gain", "speed_offset")


def true_cause_share(sizes: dict) -> float | None:
    """The share of a one-effect log's gap (the RMS log d its noise-free observables leave after each object's
    baseline fit: :func:`visible_size`) that its effect accounts for: the gap with the effect (``sizes["all"]``)
    against the same world's without it (``sizes["contact"]``; 0 where the label has no such run: a world of the
    table's physics). None where the log has no gap."""
    total = sizes.get("all")
    if total is None or not np.isfinite(total) or total <= 1e-9:
        return None
    return float((total - sizes.get("contact", 0.0)) / total)


def stated_cause_share(summary: Summary) -> float:
    """The share of the log's gap the diagnosis says its stated causes close (``cause_shrink``; 0 where it states
    none or sees no gap above the noise)."""
    sh = summary.cause_shrink
    share = sh.cause_share_closed if sh is not None else None
    return 0.0 if share is None or not summary.verdict.effects else float(share)


def resimulated_cause_share(summary: Summary) -> float:
    """The share of the log's gap the stated causes close once re-simulated in the corrected scene
    (:mod:`imply.diagnose.conclusion.simulator_check`; 0 where no cause is stated or nothing was re-simulated)."""
    c = summary.simulator
    share = c.share_closed if c is not None else None
    return 0.0 if share is None or not summary.verdict.effects else float(share)


def shrink_sizes(labels: dict[str, dict], table, groups: tuple[str, ...], *, progress: bool = True) -> dict[str, dict]:
    """:func:`visible_size` of the noise-free log with and without its effect (``all``, ``contact`` where the label
    has it) for the logs of ``groups``: what :func:`true_cause_share` reads."""
    from tqdm.auto import tqdm

    chosen = {cid: lab for cid, lab in labels.items() if lab["group"] in groups}
    return {
        cid: {what: visible_size(lab, table, what) for what in ("all", "contact") if what in lab["noise_free"]}
        for cid, lab in tqdm(chosen.items(), desc="true shares", unit="log", disable=not progress)
    }


def shrink_scores(
    frame: pd.DataFrame, mask: pd.Series, tolerance: float, *, column: str = "stated_share", prefix: str = "shrink"
) -> dict:
    """How close the stated share of the gap (``column``: as the tables predict it, or ``resimulated_share``) comes to
    the true one over the logs ``mask`` of ``frame`` (column ``true_share``): the share within ``tolerance``, the
    median and largest absolute difference, under keys starting ``prefix``."""
    sub = frame.loc[mask & frame["true_share"].notna()] if "true_share" in frame else frame.iloc[:0]
    err = (sub[column].astype(float) - sub["true_share"].astype(float)).abs() if len(sub) else pd.Series()
    return {
        f"{prefix}_within": float((err <= tolerance).mean()) if len(err) else float("nan"),
        f"n_{prefix}_within": int(len(err)),
        f"{prefix}_error_median": float(err.median()) if len(err) else float("nan"),
        f"{prefix}_error_max": float(err.max()) if len(err) else float("nan"),
        f"{prefix}_tolerance": tolerance,
    }


def score_contact_cases(
    labels: dict[str, dict],
    summaries: dict[str, Summary],
    *,
    targets: dict,
    min_size_sd: float,
    sizes: dict[str, dict] | None = None,
) -> dict:
    """The other-contact benchmark's metrics from sealed labels and diagnose summaries.

    - ``null_no_library``: null logs whose verdict states no library effect as a cause;
    - ``among_named``: one-effect logs (effect at least ``min_size_sd`` noise sds on top of the contact model) whose
      true effect (its alias class) is among the effects the verdict names (stated, or in a contender);
      ``contenders_mean`` / ``contenders_max``: how many explanations those verdicts keep in contention;
    - ``one_cause``: the share of those logs whose verdict says "one cause", and ``one_cause_right``: of these, the
      share whose cause is the true effect alone (its alias class, no other effect stated beside it) with magnitude
      within ``targets["magnitude_within"]``;
    - ``single_right``: one-effect logs whose verdict states the true effect as the one cause (alone) with
      magnitude within that;
    - ``named``: one-effect logs whose verdict states the true effect as a cause with magnitude within that;
    - ``told_right``: one-effect logs whose true effect's own hypothesis (:func:`told_error`) has its magnitude within
      that, whatever the verdict: the reach of ``single_right`` on these fits;
    - ``wrong_single``: logs with an effect outside the library whose verdict states a library mechanism as the one
      cause; ``wrong_mechanism``: ... states one as a cause at all;
    - ``wrong_effect_single``: one-effect logs (any size) whose verdict states another library effect as the one
      cause;
    - ``null_no_change``: null logs whose verdict states no cause at all, not even a change of the contact (against a
      reference session, what "nothing changed" means);
    - ``single_right_readable``: ``single_right`` over the big one-effect logs whose effect the log's observables can
      tell from the other library effects once a reference takes the contact out: all but the speed errors, which
      need the pusher's speed or its free strokes (a log with probes);
    - ``shrink_within`` (with ``sizes``, :func:`shrink_sizes`): big one-effect logs whose stated share of the gap
      (:func:`stated_cause_share`) is within ``targets["shrink_tolerance"]`` of the true one
      (:func:`true_cause_share`), with the median and largest difference.

    Against a reference session (a summary with ``reference``), the contact is named where the reference's own
    verdict names it: the standing gap is where the contact shows.
    """
    rows = []
    within = float(targets.get("magnitude_within", 0.3))
    for cid in sorted(labels):
        lab, s = labels[cid], summaries[cid]
        group = lab["group"]
        true = [e["name"] for e in lab["effects"]]
        v = s.verdict
        causes = [e.effect for e in stated(s)]
        classes = classes_beyond_contact(_classes(s))
        kinds = (lab.get("contact") or {}).get("kinds") or []
        row = {
            "case": cid,
            "group": group,
            "engine": lab.get("engine", "mujoco"),
            "design": lab.get("design", "random"),
            "effects": "+".join(true) or "null",
            "adequacy": str(v.adequacy),
            "identification": str(v.identification),
            "causes": "+".join(causes) or "none",
            "effect_causes": "+".join(c for c in causes if c not in CONTACT) or "none",
            "contact_kinds": "+".join(kinds) or "engine",
            "contact_named": any(set(c) & set(CONTACT) for c in named_classes(s))
            or (s.reference is not None and bool(set(s.reference.standing.named) & set(CONTACT))),
            "contenders": " | ".join("+".join(c.effects) or "none" for c in v.contenders),
            "n_contenders": len(v.contenders),
            "sentence": s.sentence,
            "seconds": s.seconds,
            "stop_time": lab["stop_time"],
            "measured_mass": lab["measured_mass"],
            "probes": bool(lab.get("probes", False)),
            # a cause of the pusher's (its speed or its contact), which only its measured speed or a free stroke shows
            "pusher_stated": bool(set(causes) & set(PUSHER_CAUSES)),
            # one effect beyond the contact, stated where the verdict identifies (the contact may be stated beside it)
            "one_cause": v.identification == Identification.ONE_CAUSE and len(classes) == 1,
        }
        if group in CONTACT_SINGLE:
            e = lab["effects"][0]
            size = effect_size_on_contact(lab, e["name"])
            named_cls = any(e["name"] in c for c in classes)
            rel = stated_error(e, s)
            named = bool(named_cls and rel is not None and rel <= within)
            row.update(told_error=told_error(e, s), told_right=told_within(e, s, within))
            true_share = true_cause_share(sizes[cid]) if sizes is not None and cid in sizes else None
            row.update(
                true_share=true_share,
                stated_share=stated_cause_share(s),
                resimulated_share=resimulated_cause_share(s),
                readable=bool(e["name"] not in SPEED_ERRORS or lab.get("probes")),
                wrong_effect_single=bool(row["one_cause"] and not named_cls),
                size=size,
                big=bool(size >= min_size_sd * lab["noise"]["sd"]),
                named_class=named_cls,
                relative_error=rel,
                named=named,
                among_named=any(e["name"] in c for c in named_classes(s)),
                one_cause_right=bool(row["one_cause"] and named and len(classes) == 1),
            )
        rows.append(row)
    # every column the scores read, so that an empty subset (no logs of a kind) scores as nan
    frame = pd.DataFrame(rows).reindex(columns=list(dict.fromkeys([*(rows[0] if rows else {}), *SCORED_COLUMNS])))
    frame = frame.astype({c: str for c in ("group", "engine", "effects", "causes", "effect_causes", "contact_kinds")})
    g = frame["group"]

    def share(mask, column) -> tuple[float, int]:
        sub = frame[mask]
        return (float(sub[column].astype(float).mean()) if len(sub) else float("nan")), int(len(sub))

    null = g.isin(CONTACT_NULL)
    frame["no_library"] = frame["effect_causes"] == "none"
    frame["wrong"] = frame["effect_causes"] != "none"
    # a MuJoCo contact variant whose box-table contact is off (table_compliance): the library names its change
    compliant = frame["contact_kinds"].str.contains("table_compliance")
    frame["wrong_single"] = frame["wrong"] & frame["one_cause"]
    frame["no_change"] = frame["causes"] == "none"
    any_single = g.isin(CONTACT_SINGLE)
    single = g.isin(CONTACT_SINGLE) & frame.get("big", pd.Series(False, index=frame.index)).fillna(False).astype(bool)
    outside = g.isin(CONTACT_OUTSIDE)
    out = {"cases": rows, "n_logs": int(len(frame)), "targets": dict(targets), "min_size_sd": min_size_sd}
    for key, mask, column in (
        ("null_no_library", null, "no_library"),
        ("among_named", single, "among_named"),
        ("named", single, "named"),
        ("one_cause", single, "one_cause"),
        ("single_right", single, "one_cause_right"),
        ("told_right", single, "told_right"),
        ("wrong_single", outside, "wrong_single"),
        ("wrong_effect_single", any_single, "wrong_effect_single"),
        ("null_no_change", null, "no_change"),
        ("single_right_readable", single & frame["readable"].fillna(False).astype(bool), "one_cause_right"),
        ("wrong_mechanism", outside, "wrong"),
        ("contact_named", compliant, "contact_named"),
        ("null_pusher_stated", null, "pusher_stated"),
    ):
        out[key], out[f"n_{key}"] = share(mask, column)
        for engine in ("mujoco", "bullet", "sapien"):
            out[f"{key}_{engine}"], out[f"n_{key}_{engine}"] = share(mask & (frame["engine"] == engine), column)
    out["one_cause_right"], out["n_one_cause_right"] = share(single & frame["one_cause"], "one_cause_right")
    tolerance = float(targets.get("shrink_tolerance", 0.15))
    out.update(shrink_scores(frame, single, tolerance))
    out.update(shrink_scores(frame, single, tolerance, column="resimulated_share", prefix="resim_shrink"))
    for engine in ("mujoco", "bullet", "sapien"):
        part = shrink_scores(frame, single & (frame["engine"] == engine), tolerance)
        out[f"shrink_within_{engine}"], out[f"n_shrink_within_{engine}"] = (
            part["shrink_within"],
            part["n_shrink_within"],
        )
    n_cont = frame.loc[single, "n_contenders"] if len(frame) else pd.Series(dtype=float)
    out["contenders_mean"] = float(n_cont.mean()) if len(n_cont) else float("nan")
    out["contenders_max"] = int(n_cont.max()) if len(n_cont) else 0
    truth = np.where(g.isin(CONTACT_NULL), "null", frame["effects"]) + " (" + frame["engine"] + ")"
    pred = np.where(frame["causes"] != "none", frame["causes"], frame["identification"])
    pred = np.where(frame["identification"] == "undecided", "undecided: " + frame["causes"], pred)
    confusion = pd.crosstab(pd.Series(truth, name="true"), pd.Series(pred, name="verdict")).sort_index()
    out["confusion"] = {r: {c: int(confusion.loc[r, c]) for c in confusion.columns} for r in confusion.index}
    out["seconds_per_log_median"] = float(frame["seconds"].median()) if len(frame) else None
    return out
