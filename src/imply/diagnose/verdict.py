"""Step 6 of the diagnosis: the verdict, and the one sentence a lab engineer can act on.

The effects that forward selection accepted are the verdict if together they close at
least ``min_share`` of the held-out gap above the noise floor (both observables,
whitened: :attr:`imply.diagnose.shrinkage.Shrinkage.judged`); otherwise the verdict is
"none of the candidates" (a partial one, naming the best combination, where effects were
accepted but closed too little), with the unexplained residual. Where the final model
holds the discrepancy (the contact differs from the table's), effects with a fingerprint
no smooth discrepancy can make on the log's design
(:attr:`imply.diagnose.explanations.Explanations.fingerprinted`) are stated even then, and
beside a rest flagged as outside the library: the sentence says which part of the gap
they explain and what stays open. Without the discrepancy a rest left open may itself be
a directional mechanism outside the library (friction that varies along the table looks
like a tilt), and the fingerprint alone is not enough. With nothing accepted,
the sentence tells "no gap beyond noise" from a gap that no candidate explains.

Each effect says itself in the sentence through its candidate's ``clause``
(:mod:`imply.diagnose.candidates`); a speed gain and a speed offset found together are
said once, as one speed (:func:`imply.diagnose.candidates.speed_clause`).
"""

from __future__ import annotations

from dataclasses import dataclass

from imply.diagnose.candidates import CANDIDATES, DISCREPANCY, SPEED_GAIN, SPEED_OFFSET, TILT, speed_clause
from imply.diagnose.discrepancy import DiscrepancyReport, discrepancy_sentence
from imply.diagnose.estimates import AcceptedEffect
from imply.diagnose.explanations import Explanations, separators
from imply.diagnose.records import Record, json_field
from imply.diagnose.selection import Selection
from imply.diagnose.shrinkage import Shrinkage

NONE = "none"
EFFECTS, ALTERNATIVES, DISCREPANCY_ONLY, OUTSIDE, NOTHING, NOTHING_TO_EXPLAIN, FINGERPRINTED_ONLY = (
    "effects", "alternatives", "discrepancy", "outside_library", "none", "no_gap", "fingerprinted",
)  # fmt: skip
NO_GAP = "no gap beyond noise"
NO_CANDIDATE = "no candidate improves the fit beyond noise and the model's own accuracy"


@dataclass(frozen=True, kw_only=True)
class Verdict(Record):
    """The verdict: the accepted effects' alias classes (or ``none``), why, and its one sentence."""

    verdict: str  # the accepted effects' classes joined by "; ", or "none"
    effects: list[str]
    cls: str | None = json_field(key="class")  # the first accepted effect's class
    effect: str | None  # the first accepted effect
    reason: str
    partial: str | None  # "none" although effects were accepted: the best combination ("tilt+viscous")
    lr_critical: float | None  # the first step's critical likelihood ratio
    sentence: str
    # effects: library causes stated; alternatives: causes stated with others that fit as well; discrepancy: a
    # smooth discrepancy and no library cause; outside_library: the closest combination describes the residual;
    # fingerprinted: effects with a fingerprint stated, the rest of the gap flagged or open; none: nothing
    # explains the gap; no_gap: nothing to explain
    kind: str = json_field(default=EFFECTS)
    alternatives: list[str] = json_field(default_factory=list)  # library effects named as alternatives

    @property
    def is_none(self) -> bool:
        """No library effect is stated as the cause."""
        return self.verdict == NONE


def _clauses(effects: list[AcceptedEffect]) -> list[str]:
    """Each accepted effect in the verdict's words (a speed gain and offset together as one clause)."""
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


def restricted_clause(effect: str, magnitude: float, axis_deg: float) -> str:
    """The verdict's words for a two-component effect of which the pushes' directions show one combination:
    ``magnitude`` (signed) along ``axis_deg``."""
    if effect == "anisotropic":
        a = axis_deg % 180 if magnitude >= 0 else (axis_deg + 90) % 180
        return (f"friction along {a:.0f}/{a + 180:.0f} degrees is {abs(magnitude):.0%} higher than along "
                f"{(a + 90) % 360:.0f}/{(a + 270) % 360:.0f} degrees (these directions cannot show the anisotropy's "
                "axis)")  # fmt: skip
    toward = axis_deg % 360 if magnitude >= 0 else (axis_deg + 180) % 360
    return (f"the table slopes {abs(magnitude):.3g} rad toward {toward:.0f} degrees along the pushes' line (the slope "
            "across it cannot be seen from these directions)")  # fmt: skip


def verdict_sentence(
    effects: list[AcceptedEffect], share: float | None, *, discrepancy_rms: float | None = None
) -> str:
    """The verdict of accepted ``effects`` in one sentence, with the ``share`` of the gap they close (with a
    smooth discrepancy of RMS ``discrepancy_rms`` in log d beside them, where one was fitted)."""
    text = "; ".join(_clauses(effects))
    text = text[0].upper() + text[1:]
    if discrepancy_rms is not None:
        text += f", beside a smooth discrepancy between the table and these pushes (RMS {discrepancy_rms:.2g} in log d)"
    if share is not None and share >= 1.0:
        # held out, the residual can land a little below the noise floor: the whole gap is closed
        text += f"; adding {'it' if len(effects) == 1 else 'them'} closes the whole gap, down to the noise."
    elif share is not None:
        text += f"; adding {'it' if len(effects) == 1 else 'them'} closes {max(share, 0.0):.0%} of the gap."
    else:
        text += "."
    return text


def none_sentence(shrink: Shrinkage, *, best: list[str], no_gap: bool) -> str:
    """The sentence of a "none" verdict: the ``best`` combination closes too little, no gap at all, or a gap no
    candidate explains."""
    if best:
        return (f"None of the candidate effects explains the gap: the best combination "
                f"({' + '.join(best)}) closes only {max(shrink.judged or 0, 0):.0%} of it, and "
                f"{shrink.unexplained_rms_above_floor:.3g} RMS log d remains above the noise floor; look for an effect "
                "outside the library.")  # fmt: skip
    if no_gap:
        return (f"No gap beyond noise: the table agrees with these pushes within their noise "
                f"(RMS residual {shrink.before_rms:.3g} against a noise floor of {shrink.noise_floor_rms:.3g} in log d).")  # fmt: skip
    return (f"None of the candidate effects explains the gap ({shrink.unexplained_rms_above_floor:.3g} RMS log d above "
            "the noise floor); look for an effect outside the library.")  # fmt: skip


def confounded_text(confounded: list[AcceptedEffect]) -> str:
    """The sentence naming library effects fitted beside the discrepancy that it can imitate on these pushes
    (empty without any): part of the discrepancy could as well be them."""
    if not confounded:
        return ""
    clauses = "; or ".join(_clauses(confounded))
    how = separators([e.effect for e in confounded])
    return (f" Part of the discrepancy could as well be this: {clauses} (the discrepancy can imitate "
            f"{'it' if len(confounded) == 1 else 'them'} on these pushes, so it is not stated as a cause)"
            + (f"; to tell them apart, {'; '.join(how)}." if how else "."))  # fmt: skip


def _alternatives_text(expl: Explanations, stated: set[str]) -> tuple[str, list[str]]:
    """The sentence naming what fits about as well as the stated terms, and the library effects it names."""
    parts, named, how = [], [], []
    for a in expl.alternatives:
        if a.effect not in stated:
            continue
        others = [n for n in a.instead if n != a.effect]
        if not others:
            continue
        words = [("a smooth discrepancy" if n == DISCREPANCY else CANDIDATES[n].phrase) for n in others]
        me = "the discrepancy" if a.effect == DISCREPANCY else CANDIDATES[a.effect].phrase
        parts.append(f"{me} could as well be {' or '.join(words)}")
        named += [n for n in others if n != DISCREPANCY]
        how += [h for h in a.separate_by if h not in how]
    if not parts:
        return "", []
    return f" Other explanations fit about as well: {'; '.join(parts)}; to tell them apart, {'; '.join(how)}.", named


def _fingerprinted_verdict(
    marked: list[AcceptedEffect], rest: list[AcceptedEffect], *, expl: Explanations, share: float | None,
    shrink: Shrinkage, outside: bool, critical: float | None, names: list[str],
) -> Verdict:  # fmt: skip
    """The verdict stating the fingerprinted effects ``marked`` alone, the ``rest`` of the final model describing
    what stays unexplained (flagged as outside the library, or closing too little)."""
    one = len(marked) == 1
    stated = "; ".join(_clauses(marked))
    parts = [stated[0].upper() + stated[1:] + ".",
             f"{'It leaves a mark' if one else 'They leave marks'} on these pushes that no smooth discrepancy can make "
             f"(such as a dependence on the push direction), so {'it is stated as a cause' if one else 'they are stated as causes'}."]  # fmt: skip
    if any(e.effect == TILT for e in marked):  # the mechanism outside the library known to leave much the same mark
        parts.append("Friction that varies along the table toward the same azimuth would leave much the same mark; to "
                     "tell them apart, push one object from several start positions.")  # fmt: skip
    closes = "the whole gap" if (share or 0.0) >= 1.0 else f"{max(share or 0.0, 0.0):.0%} of the gap"
    if outside:
        described = _clauses(rest) + (["a smooth discrepancy"] if expl.discrepancy else [])
        parts.append(f"The rest of the gap is most likely a mechanism outside the library (the final model: "
                     f"{expl.reason.split(': ')[0]}). The closest combination describes that rest, not its cause: "
                     f"{'; '.join(described)}; all together close {closes}.")  # fmt: skip
    else:
        parts.append(f"The rest of the gap is not explained: all terms together ({' + '.join(names)}) close only "
                     f"{closes}, and {shrink.unexplained_rms_above_floor:.3g} RMS log d remains above the noise floor; "
                     "look for an effect outside the library, or a contact that differs from the table's.")  # fmt: skip
    text = " ".join(parts)
    return Verdict(
        verdict="; ".join(e.cls for e in marked), effects=[e.effect for e in marked], cls=marked[0].cls,
        effect=marked[0].effect, partial="+".join(names), lr_critical=critical,
        reason="a fingerprinted effect; " + (expl.reason if outside else "the rest of the gap stays open"),
        sentence=text, kind=FINGERPRINTED_ONLY,
    )  # fmt: skip


def judge(
    selection: Selection,
    effects: list[AcceptedEffect],
    *,
    shrink: Shrinkage,
    min_share: float,
    explanations: Explanations | None = None,
    discrepancy: DiscrepancyReport | None = None,
) -> Verdict:
    """The verdict on the accepted ``effects`` (the final model's library effects, as reported) given how far the
    final model closes the gap, what else fits as well (``explanations``) and the fitted ``discrepancy``."""
    steps = selection.steps
    critical = steps[0][0].critical if steps and steps[0] else None
    names = selection.fit.model.names
    judged = shrink.judged
    share = judged if judged is not None else shrink.gap_share_closed
    if not selection.accepted:
        first = steps[0] if steps else []
        no_gap = not any(r.lr > r.critical for r in first)
        return Verdict(verdict=NONE, effects=[], cls=None, effect=None, reason=NO_GAP if no_gap else NO_CANDIDATE,
                       partial=None, lr_critical=critical, sentence=none_sentence(shrink, best=[], no_gap=no_gap),
                       kind=NOTHING_TO_EXPLAIN if no_gap else NOTHING)  # fmt: skip
    expl = explanations
    # beside a smooth discrepancy (the contact differs from the table's), a fingerprinted effect stands whatever the
    # rest does; without one, an open rest may be a directional mechanism outside the library, and nothing stands
    marked = [e for e in effects if expl is not None and expl.discrepancy and e.effect in expl.fingerprinted]
    low = judged is not None and judged < min_share
    if marked and (low or expl.outside_library):
        return _fingerprinted_verdict(marked, [e for e in effects if e not in marked], expl=expl, share=share,
                                      shrink=shrink, outside=not low, critical=critical, names=names)  # fmt: skip
    if low:
        return Verdict(
            verdict=NONE, effects=[], cls=None, effect=None, partial="+".join(names), lr_critical=critical,
            reason=f"the best candidates ({' + '.join(names)}) close only {judged:.0%} of the gap above the noise floor",
            sentence=none_sentence(shrink, best=names, no_gap=False), kind=NOTHING,
        )  # fmt: skip
    if expl is not None and expl.outside_library:
        clauses = "; ".join(_clauses(effects)) if effects else "a smooth discrepancy"
        final = "+".join([e.effect for e in effects] + ([DISCREPANCY] if expl.discrepancy else []))
        return Verdict(
            verdict=NONE, effects=[], cls=None, effect=None, partial=final, lr_critical=critical, reason=expl.reason,
            sentence=(f"Most likely a mechanism outside the library: {expl.reason.split(': ')[0]}. The closest "
                      f"combination describes the residual, not its cause: {clauses}; it closes "
                      + ("the whole gap." if (share or 0.0) >= 1.0 else f"{max(share or 0.0, 0.0):.0%} of the gap.")),
            kind=OUTSIDE,
        )  # fmt: skip
    confounded = [e for e in effects if expl is not None and e.effect in expl.confounded]
    effects = [e for e in effects if e not in confounded]
    part = confounded_text(confounded)
    if not effects and discrepancy is not None:
        alt, named = _alternatives_text(expl, {DISCREPANCY}) if expl is not None else ("", [])
        return Verdict(
            verdict=NONE, effects=[], cls=None, effect=None, partial=None, lr_critical=critical,
            reason="a smooth discrepancy explains the gap; no library effect can be told from it",
            sentence=discrepancy_sentence(discrepancy, share=share) + part + alt, kind=DISCREPANCY_ONLY,
            alternatives=named + [e.effect for e in confounded],
        )  # fmt: skip
    text = verdict_sentence(effects, share, discrepancy_rms=discrepancy.rms_log_d if discrepancy else None) + part
    alt, named = _alternatives_text(expl, {e.effect for e in effects}) if expl is not None else ("", [])
    named = named + [e.effect for e in confounded]
    return Verdict(
        verdict="; ".join(e.cls for e in effects), effects=[e.effect for e in effects], cls=effects[0].cls,
        effect=effects[0].effect, reason="improves beyond noise", partial=None, lr_critical=critical,
        # the share the verdict was judged on (both observables, whitened), as the "none" sentences quote it
        sentence=text + alt, kind=ALTERNATIVES if named or alt else EFFECTS, alternatives=named,
    )  # fmt: skip
