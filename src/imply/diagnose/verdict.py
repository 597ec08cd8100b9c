"""Step 6 of the diagnosis: the verdict, and the one sentence a lab engineer can act on.

The effects that forward selection accepted are the verdict if together they close at
least ``min_share`` of the held-out gap above the noise floor (both observables,
whitened: :attr:`imply.diagnose.shrinkage.Shrinkage.judged`); otherwise the verdict is
"none of the candidates" (a partial one, naming the best combination, where effects were
accepted but closed too little), with the unexplained residual. With nothing accepted,
the sentence tells "no gap beyond noise" from a gap that no candidate explains.

Each effect says itself in the sentence through its candidate's ``clause``
(:mod:`imply.diagnose.candidates`); a speed gain and a speed offset found together are
said once, as one speed (:func:`imply.diagnose.candidates.speed_clause`).
"""

from __future__ import annotations

from dataclasses import dataclass

from imply.diagnose.candidates import CANDIDATES, SPEED_GAIN, SPEED_OFFSET, speed_clause
from imply.diagnose.estimates import AcceptedEffect
from imply.diagnose.records import Record, json_field
from imply.diagnose.selection import Selection
from imply.diagnose.shrinkage import Shrinkage

NONE = "none"
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

    @property
    def is_none(self) -> bool:
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
        parts.append(CANDIDATES[e.effect].clause(e.magnitude, e.azimuth_deg))
    return parts


def verdict_sentence(effects: list[AcceptedEffect], share: float | None) -> str:
    """The verdict of accepted ``effects`` in one sentence, with the ``share`` of the gap they close."""
    text = "; ".join(_clauses(effects))
    text = text[0].upper() + text[1:]
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


def judge(selection: Selection, effects: list[AcceptedEffect], *, shrink: Shrinkage, min_share: float) -> Verdict:
    """The verdict on the accepted ``effects`` (as reported) given how far they close the gap."""
    steps = selection.steps
    critical = steps[0][0].critical if steps and steps[0] else None
    names = selection.fit.model.names
    judged = shrink.judged
    if not selection.accepted:
        first = steps[0] if steps else []
        no_gap = not any(r.lr > r.critical for r in first)
        return Verdict(verdict=NONE, effects=[], cls=None, effect=None, reason=NO_GAP if no_gap else NO_CANDIDATE,
                       partial=None, lr_critical=critical, sentence=none_sentence(shrink, best=[], no_gap=no_gap))  # fmt: skip
    if judged is not None and judged < min_share:
        return Verdict(
            verdict=NONE, effects=[], cls=None, effect=None, partial="+".join(names), lr_critical=critical,
            reason=f"the best candidates ({' + '.join(names)}) close only {judged:.0%} of the gap above the noise floor",
            sentence=none_sentence(shrink, best=names, no_gap=False),
        )  # fmt: skip
    return Verdict(
        verdict="; ".join(e.cls for e in effects), effects=[e.effect for e in effects], cls=effects[0].cls,
        effect=effects[0].effect, reason="improves beyond noise", partial=None, lr_critical=critical,
        # the share the verdict was judged on (both observables, whitened), as the "none" sentences quote it
        sentence=verdict_sentence(effects, judged if judged is not None else shrink.gap_share_closed),
    )  # fmt: skip
