"""The verdict as data (adequacy, identification, causes, contenders) and its words, every kind, verbatim.

The verdict is judged on hand-made tables of weighed hypotheses; the renderer is fed
hand-made records and never reads text back (its source is checked for string parsing).
"""

from __future__ import annotations

import ast
import inspect
from types import SimpleNamespace

import pytest

from imply.diagnose.conclusion import render
from imply.diagnose.conclusion.next_pushes import PairSeparation, PushDesign
from imply.diagnose.conclusion.render import clauses, verdict_text
from imply.diagnose.conclusion.verdict import Adequacy, Identification, adequacy, explanations, judge
from imply.diagnose.inference.discrepancy import DiscrepancyReport
from imply.diagnose.inference.estimates import AcceptedEffect, EffectEstimate
from imply.diagnose.inference.hypotheses import NO_EFFECT, Hypothesis
from imply.diagnose.physics.candidates import CANDIDATES


def _estimate(name: str, magnitude: float, azimuth_deg: float | None = None) -> EffectEstimate:
    c = CANDIDATES[name]
    return EffectEstimate(
        effect=name,
        title=c.title,
        unit=c.unit,
        components={},
        magnitude=magnitude,
        ci95=(0.0, 1.0),
        sd=0.1,
        at_bound=False,
        azimuth_deg=azimuth_deg,
        azimuth_ci95_deg=None if azimuth_deg is None else (0.0, 1.0),
    )


def _accepted(e: EffectEstimate) -> AcceptedEffect:
    return AcceptedEffect(**e.__dict__, cls=e.effect, fit_alias="")


def _h(
    effects: list[str],
    weight: float,
    *,
    disc: bool = False,
    bound: tuple[str, ...] = (),
    magnitudes: dict[str, float] | None = None,
) -> Hypothesis:
    label = "+".join(sorted(effects) + (["discrepancy"] if disc else [])) or NO_EFFECT
    mags = magnitudes or {}
    return Hypothesis(
        label=label,
        effects=list(effects),
        discrepancy=disc,
        log_evidence=0.0,
        weight=weight,
        chi2=1.0,
        heldout_chi2=1.0,
        n_parameters=len(effects),
        at_bound=list(bound),
        estimates=[_estimate(e, mags.get(e, 0.05), 0.0 if CANDIDATES[e].dim == 2 else None) for e in effects],
    )


def _judge(table, share=0.95):
    return judge(sorted(table, key=lambda h: -h.weight), share=share, min_share=0.8, contender_ratio=0.05)


# -- each effect in words -----------------------------------------------------------------


@pytest.mark.parametrize(
    ("effect", "expected"),
    [
        (_estimate("tilt", 0.0212, 243.4), "the table slopes 0.0212 rad toward 243 degrees (table frame)"),
        (_estimate("tilt", 0.01, 359.7), "the table slopes 0.01 rad toward 0 degrees (table frame)"),  # azimuth wraps
        (_estimate("anisotropic", 0.14, 27.2), "friction is 14% higher along 27 degrees than across it"),
        (_estimate("anisotropic", 0.1, 179.8), "friction is 10% higher along 0 degrees than across it"),  # an axis
        (_estimate("speed_gain", 0.05), "the pusher runs 5.0% faster than commanded"),
        (_estimate("speed_gain", -0.125), "the pusher runs 12.5% slower than commanded"),
        (_estimate("speed_offset", -0.0144), "the pusher runs 0.0144 m/s slower than commanded"),
        (_estimate("viscous", 0.25), "the box feels viscous friction of 0.25 N s/m"),
        (_estimate("air_drag", 142.0), "the box feels air drag as of a medium of 142 kg/m^3"),
        (_estimate("pusher_softness", 0.03), "the pusher's contact is softer (solref time constant +0.03 s)"),
        (_estimate("height", -0.25), "the boxes are 25% shorter than the table's"),
        (_estimate("torsional", 0.025), "torsional friction (condim 4) of 0.025 m"),
        (_estimate("rolling", 0.004), "rolling friction (condim 6) of 0.004 m"),
    ],
)
def test_each_effect_says_itself(effect, expected):
    assert clauses([effect]) == [expected]


def test_speed_gain_and_offset_read_as_one_speed():
    both = [_estimate("speed_gain", -0.2), _estimate("air_drag", 142.0), _estimate("speed_offset", -0.00689)]
    assert clauses(both) == [
        "the pusher's speed is 20.0% below the command, less 6.9 mm/s",
        "the box feels air drag as of a medium of 142 kg/m^3",
    ]
    crossing = clauses([_estimate("speed_offset", 0.0233), _estimate("speed_gain", -0.2)])
    assert crossing == [
        "the pusher's speed is 20.0% below the command, plus 23 mm/s (faster than commanded below "
        "0.12 m/s, slower above)"
    ]


def test_every_candidate_has_a_clause_and_a_way_to_be_told_apart():
    for c in CANDIDATES.values():
        assert c.title and c.unit and c.phrase
        assert c.clause(0.01, 10.0 if c.dim == 2 else None)
        assert render.SEPARATE_BY[c.name]


# -- adequacy and identification ------------------------------------------------------------


def test_adequacy_from_the_share_closed():
    assert adequacy(None, no_gap=True, min_share=0.8) == Adequacy.NO_GAP
    assert adequacy(0.8, no_gap=False, min_share=0.8) == Adequacy.EXPLAINED
    assert adequacy(0.79, no_gap=False, min_share=0.8) == Adequacy.PARTLY_EXPLAINED
    assert adequacy(0.2, no_gap=False, min_share=0.8) == Adequacy.PARTLY_EXPLAINED
    assert adequacy(0.19, no_gap=False, min_share=0.8) == Adequacy.NOT_EXPLAINED
    assert adequacy(None, no_gap=False, min_share=0.8) == Adequacy.NO_GAP


def test_hypotheses_group_into_explanations_by_their_library_effects():
    groups = explanations([_h(["tilt"], 0.5), _h(["tilt"], 0.3, disc=True), _h([], 0.2, disc=True)])
    assert [g.effects for g in groups] == [["tilt"], []]
    assert groups[0].weight == pytest.approx(0.8) and groups[0].discrepancy_weight == pytest.approx(0.3)
    assert groups[0].label == "tilt"


def test_no_gap_when_the_baseline_leads():
    v = _judge([_h([], 0.9), _h(["viscous"], 0.1)], share=None)
    assert (v.adequacy, v.identification, v.effects) == (Adequacy.NO_GAP, Identification.NOTHING_TO_IDENTIFY, [])
    assert [c.effects for c in v.contenders] == [[], ["viscous"]]


def test_one_cause_where_every_contender_holds_it():
    # a speed offset in every contender; a gain beside it cannot be ruled out
    v = _judge([_h(["speed_offset"], 0.8), _h(["speed_offset", "speed_gain"], 0.2)])
    assert (v.adequacy, v.identification) == (Adequacy.EXPLAINED, Identification.ONE_CAUSE)
    assert v.effects == ["speed_offset"] and v.not_ruled_out == ["speed_gain"] and v.not_separable == []
    assert v.named == ["speed_offset", "speed_gain"]


def test_contenders_that_disagree_leave_it_undecided_and_state_only_what_they_share():
    v = _judge([_h(["tilt", "speed_gain"], 0.5, disc=True), _h(["tilt"], 0.4, disc=True), _h(["tilt", "viscous"], 0.1)])
    assert v.identification == Identification.ONE_CAUSE  # the tilt alone contends: the others add to it
    # a contender with the discrepancy explains without the gain or the viscous friction
    assert v.effects == ["tilt"] and v.not_separable == ["speed_gain", "viscous"] and v.not_ruled_out == []
    v = _judge([_h(["tilt", "speed_gain"], 0.5), _h(["tilt", "viscous"], 0.4), _h(["anisotropic"], 0.01)])
    assert v.identification == Identification.UNDECIDED and v.effects == ["tilt"]
    assert len(v.contenders) == 2  # the anisotropy is below 0.05 of the leading weight
    assert v.not_ruled_out == ["speed_gain", "viscous"]


def test_an_effect_the_discrepancy_explains_as_well_is_not_separable():
    v = _judge([_h(["speed_gain"], 0.6, disc=True), _h([], 0.4, disc=True)])
    assert v.identification == Identification.UNDECIDED and v.effects == []
    assert v.not_separable == ["speed_gain"] and v.not_ruled_out == []


def test_a_discrepancy_alone_is_no_library_cause():
    v = _judge([_h([], 0.97, disc=True), _h(["tilt"], 0.03, disc=True)])
    assert (v.identification, v.effects) == (Identification.NO_LIBRARY_CAUSE, [])


def test_an_effect_at_its_bound_or_a_gap_left_open_states_nothing():
    v = _judge([_h(["pusher_softness"], 0.99, bound=("pusher_softness",))])
    assert (v.identification, v.effects, v.at_bound) == (Identification.OUTSIDE_LIBRARY, [], ["pusher_softness"])
    v = _judge([_h(["speed_gain"], 0.99)], share=0.5)
    assert (v.adequacy, v.identification, v.effects) == (Adequacy.PARTLY_EXPLAINED, Identification.OUTSIDE_LIBRARY, [])
    # undecided over an open gap: nothing stated, even what every contender shares
    v = _judge([_h(["tilt", "speed_gain"], 0.5), _h(["tilt", "viscous"], 0.5)], share=0.5)
    assert (v.identification, v.effects) == (Identification.UNDECIDED, [])


# -- the renderer, verbatim ----------------------------------------------------------------


def _summary(table, *, share=0.95, effects=(), inclusion=None, discrepancy=None, next_pushes=None):
    v = _judge(table, share=share)
    shrink = SimpleNamespace(before_rms=0.0238, noise_floor_rms=0.0182, unexplained_rms_above_floor=0.0198)
    return SimpleNamespace(
        verdict=v,
        shrinkage=shrink,
        hypotheses=sorted(table, key=lambda h: -h.weight),
        effects=list(effects),
        inclusion=inclusion or {},
        discrepancy=discrepancy,
        next_pushes=next_pushes,
    )


def test_no_gap_in_words():
    s = _summary([_h([], 0.95), _h(["viscous"], 0.05)], share=None)
    assert verdict_text(s) == (
        "No gap beyond noise: the table agrees with these pushes within their noise (RMS residual 0.0238 against a "
        "noise floor of 0.0182 in log d), and no effect is needed. A small effect cannot be ruled out: the box feels "
        "viscous friction of 0.05 N s/m (weight 0.05)."
    )


def test_one_cause_in_words():
    tilt = {"tilt": 0.0212}
    s = _summary(
        [_h(["tilt"], 0.9, magnitudes=tilt), _h(["tilt", "viscous"], 0.1, magnitudes=tilt)],
        effects=[_accepted(_estimate("tilt", 0.0212, None))],
        inclusion={"tilt": 1.0, "viscous": 0.1},
    )
    assert verdict_text(s) == (
        "The gap is explained (the leading hypothesis closes 95% of the gap), and by one cause: the table slopes "
        "0.0212 rad toward 0 degrees (table frame) (weight 0.90): a tilted table is identified (no other description "
        "of the contact competes). These pushes cannot rule out viscous friction beside "
        "it (inclusion weight 0.10)."
    )


def test_undecided_in_words_with_the_next_pushes():
    design = PushDesign(
        contenders=["speed_gain+discrepancy", "discrepancy"],
        pushes=[],
        pairs=[
            PairSeparation(
                first="speed_gain+discrepancy",
                second="discrepancy",
                next_pushes_sd=4.25,
                log_design_sd=1.5,
                by_observable={"displacement": 1.0},
            )
        ],
    )
    design = PushDesign(**{**design.__dict__, "pushes": [object()] * 12})
    disc = DiscrepancyReport(
        coefficients={},
        rms_log_d=0.05,
        speed_trend=-0.2,
        speed_trend_rough_minus_smooth=0.0,
        speed_trend_heavy_minus_light=0.0,
    )
    s = _summary(
        [_h(["speed_gain"], 0.6, disc=True, magnitudes={"speed_gain": -0.1}), _h([], 0.4, disc=True)],
        discrepancy=disc,
        next_pushes=design,
    )
    assert verdict_text(s) == (
        "The gap is explained (the leading hypothesis closes 95% of the gap), and the pushes cannot tell 2 "
        "explanations apart: the pusher runs 10.0% slower than commanded, beside a smooth discrepancy (weight 0.60); "
        "a smooth discrepancy alone (no library effect) (weight 0.40); so its cause cannot be attributed. On these "
        "pushes a speed gain cannot be told "
        "from a smooth discrepancy between the table and the pushes. The discrepancy: relative to the table, these "
        "pushes' slides grow 18% less from the slowest push to the fastest. The 12 pushes in next_pushes.csv would "
        "separate the two leading explanations by 4.2 noise sds (as many pushes of this log's own kind: 1.5). "
        "Measurements that would tell them apart too: measure the pusher's actual speed; measure friction and the "
        "pusher's speed directly, and record stop times."
    )


def test_outside_the_library_and_no_library_cause_in_words():
    s = _summary([_h(["pusher_softness"], 1.0, bound=("pusher_softness",), magnitudes={"pusher_softness": 0.08})])
    assert verdict_text(s) == (
        "The gap is explained (the leading hypothesis closes 95% of the gap); the library's best explanation, the "
        "pusher's contact is softer (solref time constant +0.08 s) (weight 1.00), asks for a softer pusher beyond the "
        "library's largest magnitude: most likely a mechanism outside the library, so no cause is stated."
    )
    s = _summary([_h(["speed_gain"], 1.0)], share=0.1)
    assert verdict_text(s).startswith(
        "The gap is not explained by any hypothesis (the leading one closes 10% of the gap, and 0.0198 RMS log d "
        "remains above the noise floor); the library's best explanation, the pusher runs 5.0% faster than commanded "
        "(weight 1.00), leaves too much of the gap open: most likely a mechanism outside the library"
    )
    s = _summary([_h([], 1.0, disc=True)], share=0.85)
    assert verdict_text(s) == (
        "The gap is explained (the leading hypothesis closes 85% of the gap), by a contact that differs from the "
        "table's and no library effect: a smooth discrepancy alone (no library effect) (weight 1.00)."
    )


def test_the_renderer_never_parses_text():
    tree = ast.parse(inspect.getsource(render))
    parsing = {"split", "rsplit", "partition", "rpartition", "find", "rfind", "index", "startswith", "endswith"}
    calls = {n.func.attr for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)}
    assert not calls & parsing
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert "re" not in imported


def test_the_contact_is_kept_apart_from_the_effects():
    """An effect with and without a change of the table's contact is one explanation; the change is stated beside
    the effect where hypotheses of half the weight hold it, as the MJCF edit that closes the gap."""
    table = [
        _h(["table_timeconst", "viscous"], 0.5),
        _h(["viscous"], 0.2, disc=True),
        _h(["table_timeconst"], 0.2, disc=True),
        _h(["speed_gain"], 0.1),
    ]
    groups = explanations(table)
    assert [g.effects for g in groups] == [["viscous"], [], ["speed_gain"]]
    assert groups[0].weight == pytest.approx(0.7) and groups[0].contact == ["table_timeconst"]
    assert groups[0].contact_weight == pytest.approx(0.7) and groups[2].contact_weight == 0.0
    v = judge(table, share=0.9, min_share=0.8, contender_ratio=0.5)
    # viscous stands on its own (the other contenders are the contact alone): one cause, the contact's change beside it
    assert v.identification == Identification.ONE_CAUSE and v.effects == ["viscous", "table_timeconst"]
    assert "table_timeconst" in v.named
    # the contact alone leads: no library cause, and its change stated
    alone = judge(
        [_h(["table_timeconst"], 0.8), _h([], 0.15, disc=True), _h(["viscous"], 0.05)],
        share=0.9,
        min_share=0.8,
        contender_ratio=0.05,
    )
    assert alone.identification == Identification.NO_LIBRARY_CAUSE and alone.effects == ["table_timeconst"]
    # a change held by less than half the weight is not stated
    split = judge(
        [_h(["table_timeconst"], 0.4), _h([], 0.6, disc=True)], share=0.9, min_share=0.8, contender_ratio=0.05
    )
    assert split.identification == Identification.NO_LIBRARY_CAUSE and split.effects == []


def test_the_contact_change_is_said_as_an_mjcf_edit():
    assert clauses([_estimate("table_timeconst", 1.0986)]) == [
        "the table contact is softer: solref time constant 0.02 -> 0.06 s in the MJCF"
    ]


def test_a_cause_is_identified_only_where_the_contact_does_not_move_its_size():
    """Every stated estimate has the interval (0, 1): a description of the contact under which the magnitude leaves it
    makes the cause present, its size uncertain, with the span it moves over."""
    holds = _judge(
        [
            _h(["viscous"], 0.6, magnitudes={"viscous": 0.5}),
            _h(["table_timeconst", "viscous"], 0.3, magnitudes={"viscous": 0.7, "table_timeconst": 0.4}),
            _h(["viscous"], 0.1, disc=True, magnitudes={"viscous": 0.3}),
        ]
    )
    assert holds.effects == ["viscous"] and [(t.effect, t.tier) for t in holds.tiers] == [("viscous", "identified")]
    assert holds.tiers[0].descriptions == 3 and holds.tiers[0].across_contact == (0.3, 0.7)
    table = [
        _h(["viscous"], 0.6, magnitudes={"viscous": 0.5}),
        _h(["table_timeconst", "viscous"], 0.4, magnitudes={"viscous": 1.6, "table_timeconst": 0.4}),
    ]
    t = _judge(table).tiers[0]
    assert t.tier == "size_uncertain" and t.across_contact == (0.5, 1.6) and t.contact_share == pytest.approx(1.1)
    said = render.headline(_summary(table))
    assert said.endswith(
        ": viscous friction is present, its size uncertain (0.5 to 1.6 N s/m as the contact is described, 110% of its "
        "95% interval)."
    )
