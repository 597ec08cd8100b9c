"""The verdict: two separate answers, read off the weighed hypotheses (:mod:`imply.diagnose.inference.hypotheses`).

*Adequacy* says whether the gap is accounted for: ``no_gap`` where the baseline (no
effect, no discrepancy) carries the most weight or the baseline's held-out gap is inside
the noise floor; otherwise from the share of the held-out
gap above the noise floor that the leading hypothesis closes
(:attr:`imply.diagnose.inference.shrinkage.Shrinkage.judged`): ``explained`` at ``min_share`` or more,
``not_explained`` below ``1 - min_share``, ``partly_explained`` between.

*Identification* says what accounts for it. Hypotheses are grouped into *explanations*
by their library effects (with or without the discrepancy: one explanation); an
explanation's weight is its hypotheses' summed weight. The *contenders* are the
explanations whose weight is at least ``contender_ratio`` times the leading one's. An
effect in every contender is stated as a cause where the gap is explained, unless it sits
at the bound of its library range in any of them (then it is never stated: the pushes ask
for more than the library holds). The identification is

- ``nothing_to_identify``: no gap;
- ``one_cause``: the gap is explained and the effects every contender holds (the *core*)
  are themselves a contender, none of them at its bound: the other contenders only add
  effects the pushes cannot rule out, and the core is stated as the cause;
- ``no_library_cause``: the core is empty and a smooth discrepancy alone is the leading
  explanation (the contact differs from the table's; no library effect is needed);
- ``outside_library``: as ``one_cause``, but the gap is not explained (the library's best
  explanation leaves too much of it open) or an effect would go past the library's range:
  most likely a mechanism outside the library, and nothing is stated;
- ``undecided``: contenders that disagree (the core is no contender), each with its
  weight (the next pushes, :mod:`imply.diagnose.conclusion.next_pushes`, are designed to separate
  them). The core is stated where the gap is explained;
- ``contradicted``: the causes the tables would state are contradicted by the simulator
  (re-simulated, they close too little of the gap) or by the log's own calibration probes
  (:mod:`imply.diagnose.conclusion.simulator_check`), so nothing is stated
  (:func:`contradicted`).

The box-table contact is kept apart from the effects: a hypothesis's *contact* is the
discrepancy or a change of the contact's MJCF parameters (the library's ``CONTACT``
effects), and explanations are grouped by their effects beyond it, so that an effect
with or without a change of the contact is one explanation. A change of the contact is
stated beside the causes where the leading hypothesis holds it and hypotheses of at least
half the weight do. An effect of a contender that is not stated is *not separable* from the
contact where another contender describes the contact without it, and *not ruled out*
otherwise.

A stated cause beyond the contact has a *tier* (:class:`CauseTier`): *identified* where its
magnitude stays inside the leading hypothesis's 95% interval under every description of the
contact the explanation's weighed hypotheses keep (nothing, the discrepancy, a change of the
contact's MJCF parameters); *present, size uncertain* where a description moves it out,
with how much of the interval the contact's descriptions span. A gap with no stated cause
is one whose cause *cannot be attributed*. No threshold of its own: the interval decides.

Two thresholds, both in config ``gap.diagnose`` with their docs: ``min_share`` and
``contender_ratio``. The verdict is data; :mod:`imply.diagnose.conclusion.render` says it in words.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import StrEnum

from imply.diagnose.inference.hypotheses import NO_EFFECT, Hypothesis
from imply.diagnose.physics.candidates import CONTACT
from imply.diagnose.records import Record


class Adequacy(StrEnum):
    """Whether the gap is accounted for."""

    NO_GAP = "no_gap"
    EXPLAINED = "explained"
    PARTLY_EXPLAINED = "partly_explained"
    NOT_EXPLAINED = "not_explained"


class Identification(StrEnum):
    """What accounts for the gap."""

    NOTHING_TO_IDENTIFY = "nothing_to_identify"
    ONE_CAUSE = "one_cause"
    NO_LIBRARY_CAUSE = "no_library_cause"
    OUTSIDE_LIBRARY = "outside_library"
    UNDECIDED = "undecided"
    CONTRADICTED = "contradicted"


@dataclass(frozen=True, kw_only=True)
class Contender(Record):
    """An explanation still in contention: its library effects and their weight."""

    effects: list[str]  # library effects beyond the contact (none: the contact alone, or nothing)
    weight: float  # summed weight of its hypotheses (with and without the discrepancy or a change of the contact)
    discrepancy_weight: float  # the part of it from hypotheses that hold the discrepancy
    label: str  # its hypothesis of largest weight
    at_bound: list[str]  # effects of that hypothesis at the bound of their library range
    # the part of the weight from hypotheses that describe the contact (the discrepancy or a CONTACT effect)
    contact_weight: float = 0.0
    contact: list[str] = field(default_factory=list)  # the CONTACT effects of its hypothesis of largest weight


class Tier(StrEnum):
    """How firmly a stated cause is identified, against the ways the contact can be described."""

    IDENTIFIED = "identified"  # its magnitude holds across the contact's descriptions, within its interval
    SIZE_UNCERTAIN = "size_uncertain"  # present, but how the contact is described moves its size out of the interval


@dataclass(frozen=True, kw_only=True)
class CauseTier(Record):
    """A stated cause's tier: its magnitudes under every description of the contact the weighed hypotheses keep (the
    leading explanation's hypotheses of at least ``contender_ratio`` of its leading one's weight), against the
    leading hypothesis's 95% interval."""

    effect: str
    tier: Tier
    magnitude: float  # the leading hypothesis's
    ci95: tuple[float, float]  # the leading hypothesis's
    across_contact: tuple[float, float]  # the smallest and largest magnitude over the contact's descriptions
    contact_share: float  # how much of the interval's width the contact's descriptions span (1: all of it)
    descriptions: int  # how many descriptions of the contact were compared


@dataclass(frozen=True, kw_only=True)
class Verdict(Record):
    """The verdict as data: adequacy, identification, the causes stated and the contenders."""

    adequacy: Adequacy
    identification: Identification
    effects: list[str]  # library effects stated as causes (beyond the contact, then the contact's change)
    contenders: list[Contender]  # best first
    core: int  # the index in contenders of the one whose effects every contender holds (-1: none is)
    not_separable: list[str]  # effects of contenders that a contender with the discrepancy explains without them
    not_ruled_out: list[str]  # the contenders' effects outside the core that are not separable either
    at_bound: list[str]  # effects of contenders at their library bound, never stated
    share_closed: float | None  # of the held-out gap above the noise floor, by the leading hypothesis
    leading: str  # the label of the hypothesis of largest weight
    tiers: list[CauseTier] = field(default_factory=list)  # each stated cause beyond the contact: how firmly
    # the causes the tables stated before the simulator or the probes contradicted them (then none is stated)
    withdrawn: list[str] = field(default_factory=list)
    contradicted_by: list[str] = field(default_factory=list)  # "simulator", "probes"

    @property
    def is_none(self) -> bool:
        """No library effect is stated as a cause."""
        return not self.effects

    @property
    def named(self) -> list[str]:
        """Every library effect the verdict names: the causes, then the contenders' other effects (best first)."""
        out = list(self.effects)
        for c in self.contenders:
            out += [e for e in c.effects + c.contact if e not in out]
        return out


def beyond_contact(effects: list[str]) -> list[str]:
    """The effects that are not the box-table contact itself (:data:`imply.diagnose.physics.candidates.CONTACT`)."""
    return [e for e in effects if e not in CONTACT]


def describes_contact(h: Hypothesis) -> bool:
    """Whether a hypothesis describes a contact that differs from the table's (the discrepancy, or a CONTACT effect)."""
    return h.discrepancy or any(e in CONTACT for e in h.effects)


def explanations(table: list[Hypothesis]) -> list[Contender]:
    """The hypotheses grouped by their library effects beyond the contact, heaviest first: whether the contact is
    described by the discrepancy, by a change of its MJCF parameters or not at all, one explanation."""
    groups: dict[tuple[str, ...], list[Hypothesis]] = {}
    for h in table:
        groups.setdefault(tuple(sorted(beyond_contact(h.effects))), []).append(h)
    out = []
    for key, hs in groups.items():
        lead = max(hs, key=lambda h: h.weight)
        out.append(
            Contender(
                effects=[e for e in lead.effects if e in key],
                weight=float(sum(h.weight for h in hs)),
                discrepancy_weight=float(sum(h.weight for h in hs if h.discrepancy)),
                label=lead.label,
                at_bound=list(lead.at_bound),
                contact_weight=float(sum(h.weight for h in hs if describes_contact(h))),
                contact=[e for e in lead.effects if e in CONTACT],
            )
        )
    out.sort(key=lambda c: (-c.weight, c.label))
    return out


def contact_change(table: list[Hypothesis], leading: Hypothesis) -> list[str]:
    """The changes of the contact's MJCF parameters (CONTACT effects) the weighed hypotheses agree on: held by the
    leading hypothesis and by hypotheses of at least half the total weight."""
    total = sum(h.weight for h in table) or 1.0
    return [
        e for e in leading.effects if e in CONTACT and sum(h.weight for h in table if e in h.effects) >= 0.5 * total
    ]


def adequacy(share: float | None, *, no_gap: bool, min_share: float) -> Adequacy:
    """Adequacy from the share of the held-out gap the leading hypothesis closes (None: no gap to close)."""
    if no_gap or share is None:
        return Adequacy.NO_GAP
    if share >= min_share:
        return Adequacy.EXPLAINED
    if share < 1.0 - min_share:
        return Adequacy.NOT_EXPLAINED
    return Adequacy.PARTLY_EXPLAINED


def judge(table: list[Hypothesis], *, share: float | None, min_share: float, contender_ratio: float) -> Verdict:
    """The verdict on the weighed hypotheses ``table`` (heaviest first), the leading one closing ``share`` of the
    held-out gap."""
    leading = max(table, key=lambda h: h.weight)
    groups = explanations(table)
    contenders = [g for g in groups if g.weight >= contender_ratio * groups[0].weight]
    no_gap = leading.label == NO_EFFECT
    bound = sorted({e for c in contenders for e in c.at_bound})
    share_adequacy = adequacy(share, no_gap=no_gap, min_share=min_share)
    explained = share_adequacy == Adequacy.EXPLAINED
    # the effects every contender holds; where they are an explanation in contention themselves, the other
    # contenders only add effects to them and the pushes have chosen them
    core = set(contenders[0].effects).intersection(*(c.effects for c in contenders[1:]))
    stands = next((c for c in contenders if set(c.effects) == core), None)
    if share_adequacy == Adequacy.NO_GAP:  # the baseline leads, or nothing is left above the noise floor to close
        ident = Identification.NOTHING_TO_IDENTIFY
    elif stands is None or (not core and (stands is not contenders[0] or stands.contact_weight == 0)):
        ident = Identification.UNDECIDED
    elif core and (not explained or core & set(bound)):
        ident = Identification.OUTSIDE_LIBRARY
    elif core:
        ident = Identification.ONE_CAUSE
    else:
        ident = Identification.NO_LIBRARY_CAUSE
    causes = [e for e in contenders[0].effects if e in core and e not in bound]
    causes += [e for e in contact_change(table, leading) if e not in bound]
    if not explained or ident == Identification.OUTSIDE_LIBRARY:  # no cause is stated for a gap left open
        causes = []
    with_disc = [set(c.effects) for c in contenders if c.contact_weight > 0]
    not_separable, open_ = [], []
    for c in contenders:
        for e in c.effects:
            if e in core or e in not_separable or e in open_ or e in bound:
                continue
            (not_separable if any(e not in w for w in with_disc) else open_).append(e)
    tiers = cause_tiers(table, contenders[0], [e for e in causes if e not in CONTACT], contender_ratio=contender_ratio)
    return Verdict(
        adequacy=share_adequacy,
        identification=ident,
        effects=causes,
        contenders=contenders,
        core=contenders.index(stands) if stands is not None else -1,
        not_separable=not_separable,
        not_ruled_out=open_,
        at_bound=bound,
        share_closed=share,
        leading=leading.label,
        tiers=tiers,
    )


def cause_tiers(
    table: list[Hypothesis], explanation: Contender, causes: list[str], *, contender_ratio: float
) -> list[CauseTier]:
    """Each cause's tier: across the explanation's hypotheses (the same effects beyond the contact, the contact
    described by nothing, the discrepancy or a change of its MJCF parameters) of at least ``contender_ratio`` of its
    heaviest one's weight, whether the cause's magnitude stays inside the heaviest one's 95% interval."""
    key = sorted(explanation.effects)
    group = [h for h in table if sorted(beyond_contact(h.effects)) == key]
    if not group:
        return []
    lead = max(group, key=lambda h: h.weight)
    kept = [h for h in group if h.weight >= contender_ratio * lead.weight]
    out = []
    for e in causes:
        found = {h.label: next((x for x in h.estimates if x.effect == e), None) for h in kept}
        found = {k: x for k, x in found.items() if x is not None}
        if lead.label not in found:
            continue
        ref = found[lead.label]
        lo, hi = float(min(ref.ci95)), float(max(ref.ci95))
        mags = [x.magnitude for x in found.values()]
        inside = all(lo <= m <= hi for m in mags)
        width = hi - lo
        out.append(
            CauseTier(
                effect=e,
                tier=Tier.IDENTIFIED if inside else Tier.SIZE_UNCERTAIN,
                magnitude=ref.magnitude,
                ci95=(lo, hi),
                across_contact=(float(min(mags)), float(max(mags))),
                contact_share=float((max(mags) - min(mags)) / width) if width > 0 else 0.0,
                descriptions=len(found),
            )
        )
    return out


def contradicted(verdict: Verdict, by: list[str]) -> Verdict:
    """``verdict`` with its stated causes withdrawn, as the simulator or the probes (``by``) contradict them."""
    if not by or not verdict.effects:
        return verdict
    return replace(
        verdict,
        identification=Identification.CONTRADICTED,
        effects=[],
        tiers=[],
        withdrawn=list(verdict.effects),
        contradicted_by=list(by),
    )
