"""The verdict in words: the one module that turns the diagnosis's data into the report's sentences.

Everything here reads typed records (:class:`imply.diagnose.conclusion.verdict.Verdict`, the
hypotheses' estimates, the shrinkage, the discrepancy's description, the next pushes) and
writes text; nothing reads text back. The first sentence states adequacy and
identification; the next ones say which effects are stated in every contender, which
cannot be told from a smooth discrepancy, which would go past the library's range, and
what the next pushes would do.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from imply.diagnose.conclusion.next_probes import NextProbe, probe_words
from imply.diagnose.conclusion.next_pushes import PushDesign
from imply.diagnose.conclusion.verdict import Adequacy, Contender, Identification, Tier, Verdict
from imply.diagnose.inference.discrepancy import DiscrepancyReport
from imply.diagnose.inference.estimates import EffectEstimate
from imply.diagnose.inference.hypotheses import Hypothesis
from imply.diagnose.inference.shrinkage import Shrinkage
from imply.diagnose.inputs.pushlog import TRACK_OBSERVABLES
from imply.diagnose.physics.candidates import CANDIDATES, DISCREPANCY, SPEED_GAIN, SPEED_OFFSET, speed_clause
from imply.sim.track import FRACTIONS

# the observables, as the report and the observables note name them
OBSERVABLE_WORDS = {
    "displacement": "displacement",
    "stop_time": "stop time",
    "pusher_speed": "the pusher's measured speed",
    **{
        name: f"the track's time to {100 * q:.0f}% of the travel"
        for name, q in zip(TRACK_OBSERVABLES, FRACTIONS, strict=True)
    },
    "track": "the box's track",
}


class Summary(Protocol):
    """What the renderer reads of a diagnosis (:class:`imply.diagnose.analysis.Summary` has it all)."""

    verdict: Verdict
    shrinkage: Shrinkage
    hypotheses: list[Hypothesis]
    effects: list[EffectEstimate]
    inclusion: dict[str, float]
    discrepancy: DiscrepancyReport | None
    next_pushes: PushDesign | None


LISTED = 4  # contenders a sentence lists (the report's table lists them all)

# what would tell an effect from the others in contention (by candidate; "discrepancy" for the model discrepancy)
SEPARATE_BY = {
    SPEED_GAIN: "measure the pusher's actual speed",
    SPEED_OFFSET: "measure the pusher's actual speed",
    "viscous": "record the box's track over time (viscous drag slows it in proportion to its speed)",
    "air_drag": "record the box's track over time (drag grows with the square of its speed)",
    "pusher_softness": "record the pusher's contact force or the box's speed during the stroke",
    "table_timeconst": "record the box's track over time (the table's contact shapes the launch, not the slide)",
    "table_dampratio": "record the box's track over time (the table's contact shapes the launch, not the slide)",
    "tilt": "push in more directions",
    "anisotropic": "push in more directions",
    "torsional": "record the box's rotation",
    "rolling": "record the box's rotation",
    "height": "measure the boxes' height",
    DISCREPANCY: "measure friction and the pusher's speed directly, and record stop times",
}


def probe_sentence(p: NextProbe) -> str:
    """One line on the probe recommended beside the next pushes: which, and why."""
    return (
        f"A calibration probe would tell them apart better than any single push: {probe_words(p)} "
        f"({p.separation_sd:.1f} noise sds between the closest two, against {p.best_push_sd:.1f} for the best push; "
        "next_probes.csv gives what each would read)."
    )


def restricted_clause(effect: str, magnitude: float, axis_deg: float) -> str:
    """The words for a two-component effect of which the pushes' directions show one combination: ``magnitude``
    (signed) along ``axis_deg``."""
    if effect == "anisotropic":
        a = axis_deg % 180 if magnitude >= 0 else (axis_deg + 90) % 180
        return (
            f"friction along {a:.0f}/{a + 180:.0f} degrees is {abs(magnitude):.0%} higher than along "
            f"{(a + 90) % 360:.0f}/{(a + 270) % 360:.0f} degrees (these directions cannot show the anisotropy's "
            "axis)"
        )
    toward = axis_deg % 360 if magnitude >= 0 else (axis_deg + 180) % 360
    return (
        f"the table slopes {abs(magnitude):.3g} rad toward {toward:.0f} degrees along the pushes' line (the slope "
        "across it cannot be seen from these directions)"
    )


def clauses(effects: list[EffectEstimate]) -> list[str]:
    """Each effect in words with its magnitude (a speed gain and offset together as one clause)."""
    by_name = {e.effect: e.magnitude for e in effects}
    both_speeds = {SPEED_GAIN, SPEED_OFFSET} <= set(by_name)
    parts = []
    for e in effects:
        if both_speeds and e.effect in (SPEED_GAIN, SPEED_OFFSET):
            if e.effect == SPEED_GAIN:  # said once, where the gain stands
                parts.append(speed_clause(by_name[SPEED_GAIN], by_name[SPEED_OFFSET]))
            continue
        if f"{e.effect}_along" in e.components:  # restricted to the one combination the directions show
            parts.append(restricted_clause(e.effect, e.magnitude, e.azimuth_deg or 0.0))
            continue
        parts.append(CANDIDATES[e.effect].clause(e.magnitude, e.azimuth_deg))
    return parts


def phrases(names: list[str]) -> str:
    """Effects by name in a sentence ("a speed gain or air drag")."""
    return " or ".join(CANDIDATES[n].phrase if n in CANDIDATES else n for n in names)


def separators(names: list[str]) -> list[str]:
    """The measurements that would tell the named terms apart (each said once, in the order of ``names``)."""
    out = []
    for n in names:
        how = SEPARATE_BY.get(n)
        if how and how not in out:
            out.append(how)
    return out


def _pct(x: float) -> str:
    return f"{abs(np.expm1(x)):.0%}"


def discrepancy_words(d: DiscrepancyReport) -> str:
    """How the table's slides differ from these pushes', as the fitted discrepancy describes it."""
    t = d.speed_trend
    if abs(t) >= 0.005:
        text = (
            f"relative to the table, these pushes' slides grow {_pct(t)} {'more' if t > 0 else 'less'} from the "
            "slowest push to the fastest"
        )
        details = []
        for value, hi, lo in (
            (d.speed_trend_rough_minus_smooth, "rough", "smooth"),
            (d.speed_trend_heavy_minus_light, "heavy", "light"),
        ):
            if abs(value) >= 0.01:
                more = (value < 0) == (t < 0)
                details.append(f"{'more' if more else 'less'} so for {hi} objects than {lo} ones")
        if details:
            text += f" ({', '.join(details)})"
    else:
        text = f"the smooth discrepancy is {d.rms_log_d:.2g} RMS in log d"
    if d.stop_time_offset is not None and abs(d.stop_time_offset) >= 0.01:
        text += f"; their stop times are {_pct(d.stop_time_offset)} {'longer' if d.stop_time_offset > 0 else 'shorter'}"
    if d.implied_mass_ratio is not None and abs(np.log(d.implied_mass_ratio)) >= 0.05:
        text += f"; fitted freely, the objects' implied masses are {d.implied_mass_ratio:.2g}x the weighed ones"
    return text


def _estimates(summary: Summary, label: str) -> list[EffectEstimate]:
    return next((h.estimates for h in summary.hypotheses if h.label == label), [])


def contender_words(summary: Summary, c: Contender) -> str:
    """One contender in words, with its magnitudes and weight."""
    if not c.effects and not c.contact:
        what = "a smooth discrepancy alone (no library effect)" if c.discrepancy_weight > 0 else "no effect at all"
    else:
        what = "; ".join(clauses(_estimates(summary, c.label)))
        if c.effects and c.discrepancy_weight >= 0.5 * c.weight:
            what += ", beside a smooth discrepancy"
    return f"{what} (weight {c.weight:.2f})"


# who contradicts a stated explanation, in words (imply.diagnose.conclusion.simulator_check)
CONTRADICTED_BY = {
    "simulator": "the simulator (put into it, the causes leave open far more of the gap than the tables say; see the "
    "report)",
    "probes": "the log's calibration probes (see the report)",
}


def _closes(share: float | None) -> str:
    if share is None or share >= 1.0:
        return "the whole gap, down to the noise"
    return f"{max(share, 0.0):.0%} of the gap"


def tier_words(v: Verdict) -> str:
    """How firmly each stated cause is identified (empty where none is stated beyond the contact)."""
    words = []
    for t in v.tiers:
        c = CANDIDATES[t.effect]
        if t.tier == Tier.IDENTIFIED:
            why = (
                "its size holds whichever way the contact is described"
                if t.descriptions > 1
                else "no other description of the contact competes"
            )
            words.append(f"{c.phrase} is identified ({why})")
        else:
            lo, hi = t.across_contact
            words.append(
                f"{c.phrase} is present, its size uncertain ({lo:.3g} to {hi:.3g} {c.unit} as the contact is "
                f"described, {t.contact_share:.0%} of its 95% interval)"
            )
    return "; ".join(words)


def headline(summary: Summary) -> str:
    """The first sentence: adequacy and identification."""
    v: Verdict = summary.verdict
    sh = summary.shrinkage
    # the explanation the verdict rests on: the contenders' common core where it is one of them, else the leading one
    stands = v.contenders[v.core] if v.core >= 0 else v.contenders[0]
    if v.adequacy == Adequacy.NO_GAP:
        return (
            f"No gap beyond noise: the table agrees with these pushes within their noise (RMS residual "
            f"{sh.before_rms:.3g} against a noise floor of {sh.noise_floor_rms:.3g} in log d), and no effect is "
            "needed."
        )
    adequacy = {
        Adequacy.EXPLAINED: f"The gap is explained (the leading hypothesis closes {_closes(v.share_closed)})",
        Adequacy.PARTLY_EXPLAINED: f"The gap is partly explained (the leading hypothesis closes {_closes(v.share_closed)})",
        Adequacy.NOT_EXPLAINED: (
            f"The gap is not explained by any hypothesis (the leading one closes "
            f"{_closes(v.share_closed)}, and {sh.unexplained_rms_above_floor:.3g} RMS log d "
            "remains above the noise floor)"
        ),
    }[v.adequacy]
    ident = {
        Identification.ONE_CAUSE: f", and by one cause: {contender_words(summary, stands)}",
        Identification.NO_LIBRARY_CAUSE: (
            f", by a contact that differs from the table's and no library effect: {contender_words(summary, stands)}"
        ),
        Identification.OUTSIDE_LIBRARY: (
            f"; the library's best explanation, {contender_words(summary, stands)}, "
            + (
                f"asks for {phrases(v.at_bound)} beyond the library's largest magnitude"
                if v.at_bound
                else "leaves too much of the gap open"
            )
            + ": most likely a mechanism outside the library, so no cause is stated"
        ),
        Identification.CONTRADICTED: (
            f"; the tables' best explanation, {phrases(v.withdrawn)}, is contradicted by "
            + " and by ".join(CONTRADICTED_BY[b] for b in v.contradicted_by)
            + ", so no cause is stated"
        ),
        Identification.UNDECIDED: (
            f", and the pushes cannot tell {len(v.contenders)} explanations apart: "
            + "; ".join(contender_words(summary, c) for c in v.contenders[:LISTED])
            + (
                f"; and {len(v.contenders) - LISTED} more with less weight (listed in the report)"
                if len(v.contenders) > LISTED
                else ""
            )
        ),
    }[v.identification]
    tiers = tier_words(v)
    if tiers:
        ident += f": {tiers}"
    elif v.identification == Identification.UNDECIDED and not v.effects:
        ident += "; so its cause cannot be attributed"
    return adequacy + ident + "."


def verdict_text(summary: Summary) -> str:
    """The verdict in words: the headline, then what is stated, what cannot be separated, and what to do next."""
    v = summary.verdict
    parts = [headline(summary)]
    if v.adequacy == Adequacy.NO_GAP and len(v.contenders) > 1:
        parts.append(
            "A small effect cannot be ruled out: "
            + "; ".join(contender_words(summary, c) for c in v.contenders[1:LISTED])
            + "."
        )
    if v.identification == Identification.UNDECIDED and v.effects:
        stated = [e for e in summary.effects if e.effect in v.effects]
        one = len(v.effects) == 1
        parts.append(
            f"Every one of them holds {'; '.join(clauses(stated))}, so {'it is' if one else 'they are'} "
            f"stated as {'a cause' if one else 'causes'}."
        )
    if v.not_ruled_out and v.identification not in (Identification.UNDECIDED, Identification.NOTHING_TO_IDENTIFY):
        weights = ", ".join(f"{summary.inclusion.get(e, 0.0):.2f}" for e in v.not_ruled_out)
        parts.append(f"These pushes cannot rule out {phrases(v.not_ruled_out)} beside it (inclusion weight {weights}).")
    if v.not_separable:
        parts.append(
            f"On these pushes {phrases(v.not_separable)} cannot be told from a smooth discrepancy between the "
            "table and the pushes."
        )
    if v.at_bound and v.identification != Identification.OUTSIDE_LIBRARY:
        one = len(v.at_bound) == 1
        named = phrases(v.at_bound)
        parts.append(
            f"{named[0].upper()}{named[1:]} would go past the library's largest "
            f"magnitude, so {'it is' if one else 'they are'} not stated."
        )
    lead = next((h for h in summary.hypotheses if h.label == v.leading), None)
    if summary.discrepancy is not None and lead is not None and lead.discrepancy:
        text = discrepancy_words(summary.discrepancy)
        parts.append(f"The discrepancy: {text}.")
    design = summary.next_pushes
    if design is not None and design.pushes:
        first = design.pairs[0]
        parts.append(
            f"The {len(design.pushes)} pushes in next_pushes.csv would separate the two leading explanations "
            f"by {first.next_pushes_sd:.1f} noise sds (as many pushes of this log's own kind: "
            f"{first.log_design_sd:.1f})."
        )
        if design.probe is not None:
            parts.append(probe_sentence(design.probe))
        undecided = [e for c in v.contenders for e in c.effects if e not in v.effects]
        how = separators(list(dict.fromkeys(undecided + ([DISCREPANCY] if v.not_separable else []))))
        if how:
            parts.append(f"Measurements that would tell them apart too: {'; '.join(how)}.")
    return " ".join(parts)


def _share_words(share: float | None) -> str:
    if share is None:
        return "n/a (no gap above the noise)"
    return f"{min(max(share, 0.0), 1.0):.0%}"


def reference_text(summary) -> str:
    """The verdict of a diagnosis against a reference session (``summary.reference``): the standing gap, what changed
    since the reference, and how far the new session's gap shrinks."""
    ref = summary.reference
    since = verdict_text(summary)
    if summary.verdict.adequacy == Adequacy.NO_GAP:
        since = (
            "nothing beyond noise changed since the reference: with the standing gap taken out, the table agrees "
            f"with these pushes (RMS residual {summary.shrinkage.before_rms:.3g} against a noise floor of "
            f"{summary.shrinkage.noise_floor_rms:.3g} in log d)."
        )
    else:
        since = since[0].lower() + since[1:]
    st = ref.standing
    sh = summary.cause_shrink
    return (
        f"The standing gap, read from the reference session ({st.n_pushes} pushes): "
        f"{st.headline[0].lower()}{st.headline[1:]} Since the reference, {since} "
        f"The new session's gap against the table ({sh.before_rms:.3g} RMS log d) shrinks by "
        f"{_share_words(sh.cause_share_closed)} once the cause of the change is added, and by "
        f"{_share_words(sh.cause_and_standing_share_closed)} once the standing gap is described too."
    )
