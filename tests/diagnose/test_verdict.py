"""The verdict and its sentence, every branch: each effect kind, both speed effects at once, no gap, none of the
candidates, a partial explanation."""

from __future__ import annotations

import numpy as np
import pytest

from imply.diagnose.candidates import CANDIDATES, Model
from imply.diagnose.estimates import AcceptedEffect
from imply.diagnose.fit import JointFit, ObjectFit
from imply.diagnose.selection import Selection, StepResult
from imply.diagnose.shrinkage import LackOfFit, ObservableFit, Shrinkage
from imply.diagnose.verdict import NO_CANDIDATE, NO_GAP, NONE, judge, verdict_sentence


def _effect(name: str, magnitude: float, azimuth_deg: float | None = None) -> AcceptedEffect:
    c = CANDIDATES[name]
    return AcceptedEffect(
        effect=name, title=c.title, unit=c.unit, components={}, magnitude=magnitude, ci95=(0.0, 1.0), sd=0.1,
        at_bound=False, azimuth_deg=azimuth_deg, azimuth_ci95_deg=None if azimuth_deg is None else (0.0, 1.0),
        cls=name, fit_alias="",
    )  # fmt: skip


@pytest.mark.parametrize(
    ("effect", "expected"),
    [
        (_effect("tilt", 0.0212, 243.4), "The table slopes 0.0212 rad toward 243 degrees (table frame)"),
        (_effect("tilt", 0.01, 359.7), "The table slopes 0.01 rad toward 0 degrees (table frame)"),  # azimuth wraps
        (_effect("anisotropic", 0.14, 27.2), "Friction is 14% higher along 27 degrees than across it"),
        (_effect("anisotropic", 0.1, 179.8), "Friction is 10% higher along 0 degrees than across it"),  # an axis
        (_effect("speed_gain", 0.05), "The pusher runs 5.0% faster than commanded"),
        (_effect("speed_gain", -0.125), "The pusher runs 12.5% slower than commanded"),
        (_effect("speed_offset", -0.0144), "The pusher runs 0.0144 m/s slower than commanded"),
        (_effect("speed_offset", 0.03), "The pusher runs 0.03 m/s faster than commanded"),
        (_effect("viscous", 0.25), "The box feels viscous friction of 0.25 N s/m"),
        (_effect("air_drag", 142.0), "The box feels air drag as of a medium of 142 kg/m^3"),
        (_effect("pusher_softness", 0.03), "The pusher's contact is softer (solref time constant +0.03 s)"),
        (_effect("height", 0.1), "The boxes are 10% taller than the table's"),
        (_effect("height", -0.25), "The boxes are 25% shorter than the table's"),
        (_effect("torsional", 0.025), "Torsional friction (condim 4) of 0.025 m"),
        (_effect("rolling", 0.004), "Rolling friction (condim 6) of 0.004 m"),
    ],
)
def test_each_effect_says_itself(effect, expected):
    assert verdict_sentence([effect], 0.5) == f"{expected}; adding it closes 50% of the gap."


def test_every_candidate_has_a_clause():
    assert {e for e in CANDIDATES} == {"torsional", "rolling", "viscous", "pusher_softness", "tilt", "air_drag",
                                       "height", "speed_gain", "speed_offset", "anisotropic"}  # fmt: skip
    for c in CANDIDATES.values():
        assert c.title and c.unit and c.phrase
        assert c.clause(0.01, 10.0 if c.dim == 2 else None)


def test_speed_gain_and_offset_read_as_one_speed():
    both = [_effect("speed_gain", -0.2), _effect("air_drag", 142.0), _effect("speed_offset", -0.00689)]
    assert verdict_sentence(both, 1.2) == (
        "The pusher's speed is 20.0% below the command, less 6.9 mm/s; the box feels air drag as of a medium of "
        "142 kg/m^3; adding them closes the whole gap, down to the noise."
    )


def test_speed_gain_and_offset_that_cross_say_where():
    # v' = 0.8 v + 0.0233: faster than commanded below 0.1165 m/s, slower above
    text = verdict_sentence([_effect("speed_offset", 0.0233), _effect("speed_gain", -0.2)], None)
    assert text == (
        "The pusher's speed is 20.0% below the command, plus 23 mm/s (faster than commanded below 0.12 m/s, slower "
        "above)."
    )
    text = verdict_sentence([_effect("speed_gain", 0.1), _effect("speed_offset", -0.03)], 0.9)
    assert text.startswith("The pusher's speed is 10.0% above the command, less 30 mm/s (slower than commanded "
                           "below 0.3 m/s, faster above)")  # fmt: skip


def test_share_closed_and_its_wording():
    tilt = _effect("tilt", 0.02, 90.0)
    assert verdict_sentence([tilt], 0.944).endswith("; adding it closes 94% of the gap.")
    assert verdict_sentence([tilt], -0.1).endswith("; adding it closes 0% of the gap.")
    assert verdict_sentence([tilt, _effect("viscous", 0.5)], 1.0).endswith(
        "; adding them closes the whole gap, down to the noise."
    )
    assert verdict_sentence([tilt], None).endswith("(table frame).")


# -- the verdict itself ----------------------------------------------------------------


def _fit(names: list[str]) -> JointFit:
    model = Model(tuple(CANDIDATES[n] for n in names))
    objects = ObjectFit(np.zeros(2), np.zeros(2), np.ones(2))
    return JointFit(model, np.zeros(model.dim), objects, np.zeros((2, model.dim, model.dim)), np.zeros((2, model.dim)))


def _step(name: str, lr: float, critical: float = 6.0) -> StepResult:
    return StepResult(CANDIDATES[name], _fit([name]), lr, 1, critical, 1.0, 0.1, 0.1, 0.0, lr > critical, [])


def _shrinkage(*, both: float | None, gap: float | None = 0.9) -> Shrinkage:
    part = ObservableFit(baseline_chi2=1.0, heldout_chi2=1.0, n=10)
    lof = LackOfFit(heldout_chi2=1.0, dof=1, p_value=0.5, in_sample_chi2=1.0, baseline_chi2=1.0, displacement=part)
    return Shrinkage(
        effects=[], effect=None, before_rms=0.0238, after_rms=0.02, noise_floor_rms=0.0182, gap_share_closed=gap,
        stop_time_share_closed=None, both_share_closed=both, lack_of_fit=lof, dispersion=1.0, anchored_before_mean=0.0,
        anchored_after_mean=0.0, anchored_floor=0.0, anchored_share_closed=None, unexplained_rms_above_floor=0.0198,
    )  # fmt: skip


def test_no_gap_beyond_noise():
    sel = Selection(_fit([]), [[_step("viscous", 2.0), _step("tilt", 1.0)]], [], None)
    v = judge(sel, [], shrink=_shrinkage(both=None, gap=None), min_share=0.8)
    assert (v.verdict, v.reason, v.partial, v.effects, v.lr_critical) == (NONE, NO_GAP, None, [], 6.0)
    assert v.sentence == ("No gap beyond noise: the table agrees with these pushes within their noise (RMS residual "
                          "0.0238 against a noise floor of 0.0182 in log d).")  # fmt: skip


def test_a_gap_no_candidate_explains():
    # one candidate beats its critical value but fails the other tests: a gap, and nothing accepted
    sel = Selection(_fit([]), [[_step("viscous", 9.0), _step("tilt", 1.0)]], [], None)
    v = judge(sel, [], shrink=_shrinkage(both=0.1), min_share=0.8)
    assert (v.verdict, v.reason, v.partial) == (NONE, NO_CANDIDATE, None)
    assert v.sentence == ("None of the candidate effects explains the gap (0.0198 RMS log d above the noise floor); "
                          "look for an effect outside the library.")  # fmt: skip


def test_effects_that_close_too_little_are_a_partial_none():
    sel = Selection(_fit(["tilt", "viscous"]), [[_step("tilt", 30.0)], [_step("viscous", 12.0)]],
                    [CANDIDATES["tilt"], CANDIDATES["viscous"]], None)  # fmt: skip
    effects = [_effect("tilt", 0.02, 10.0), _effect("viscous", 0.5)]
    v = judge(sel, effects, shrink=_shrinkage(both=0.52, gap=0.95), min_share=0.8)
    assert (v.verdict, v.partial, v.effects, v.cls, v.effect) == (NONE, "tilt+viscous", [], None, None)
    assert v.reason == "the best candidates (tilt + viscous) close only 52% of the gap above the noise floor"
    assert v.sentence == ("None of the candidate effects explains the gap: the best combination (tilt + viscous) "
                          "closes only 52% of it, and 0.0198 RMS log d remains above the noise floor; look for an "
                          "effect outside the library.")  # fmt: skip


def test_accepted_effects_are_the_verdict_judged_on_both_observables():
    sel = Selection(_fit(["tilt"]), [[_step("tilt", 30.0)]], [CANDIDATES["tilt"]], None)
    effects = [_effect("tilt", 0.025, 292.6)]
    # judged on both observables (0.85) although displacement alone closes less
    v = judge(sel, effects, shrink=_shrinkage(both=0.85, gap=0.5), min_share=0.8)
    assert (v.verdict, v.effects, v.cls, v.effect, v.reason) == ("tilt", ["tilt"], "tilt", "tilt",
                                                                  "improves beyond noise")  # fmt: skip
    assert v.sentence == "The table slopes 0.025 rad toward 293 degrees (table frame); adding it closes 85% of the gap."
    # without stop times to judge on, displacement alone
    v = judge(sel, effects, shrink=_shrinkage(both=None, gap=0.9), min_share=0.8)
    assert v.sentence.endswith("closes 90% of the gap.")


# -- the discrepancy, alternatives, mechanisms outside the library, restricted effects ---------------------------


def _discrepancy(**kw):
    from imply.diagnose.discrepancy import DiscrepancyReport

    base = dict(coefficients={}, rms_log_d=0.04, speed_trend=-0.16, speed_trend_rough_minus_smooth=-0.08,
                speed_trend_heavy_minus_light=0.02, stop_time_offset=None, implied_mass_ratio=0.66, mimics=[])  # fmt: skip
    return DiscrepancyReport(**{**base, **kw})


def _explanations(**kw):
    from imply.diagnose.explanations import Explanations

    base = dict(causes=[], discrepancy=False, mimicked=[], mimicked_margin={}, alternatives=[], pinned=[],
                outside_library=False, reason=None, alt_margin=6.0)  # fmt: skip
    return Explanations(**{**base, **kw})


def test_discrepancy_sentence_says_how_the_table_differs():
    from imply.diagnose.discrepancy import discrepancy_sentence

    text = discrepancy_sentence(_discrepancy(), share=0.97)
    assert text == (
        "These pushes differ from the table by a smooth discrepancy that no library effect explains: relative to "
        "the table, their slides grow 15% less from the slowest push to the fastest (more so for rough objects than "
        "smooth ones, less so for heavy objects than light ones); fitted freely, the objects' implied masses are "
        "0.66x the weighed ones; the discrepancy closes 97% of the gap."
    )
    flat = discrepancy_sentence(_discrepancy(speed_trend=0.001, implied_mass_ratio=None, stop_time_offset=0.05,
                                             mimics=["speed_offset"]), share=1.2)  # fmt: skip
    assert flat == (
        "These pushes differ from the table by a smooth discrepancy that no library effect explains (RMS 0.04 in log "
        "d); their stop times are 5% longer; the discrepancy closes the whole gap, down to the noise. On these pushes "
        "it could also imitate a speed offset."
    )


def test_a_discrepancy_verdict_names_no_library_effect_and_leads_with_the_discrepancy():
    from imply.diagnose.candidates import discrepancy_candidate
    from imply.diagnose.explanations import Alternative

    d = discrepancy_candidate(stop_time=False, prior_sd=0.1, bound=1.0)
    sel = Selection(_fit([]), [[]], [d], None)
    alt = Alternative(effect="discrepancy", instead=["speed_offset"], margin=[3.0],
                      separate_by=["measure the pusher's actual speed"])  # fmt: skip
    v = judge(sel, [], shrink=_shrinkage(both=0.95), min_share=0.8, explanations=_explanations(
        discrepancy=True, alternatives=[alt]), discrepancy=_discrepancy())  # fmt: skip
    assert (v.verdict, v.kind, v.is_none, v.alternatives) == (NONE, "discrepancy", True, ["speed_offset"])
    assert v.sentence.startswith("These pushes differ from the table by a smooth discrepancy")
    assert v.sentence.endswith(" Other explanations fit about as well: the discrepancy could as well be a speed "
                               "offset; to tell them apart, measure the pusher's actual speed.")  # fmt: skip


def test_an_effect_pulled_past_its_bound_is_no_confident_verdict():
    from imply.diagnose.explanations import Pinned

    sel = Selection(_fit(["pusher_softness"]), [[_step("pusher_softness", 80.0)]], [CANDIDATES["pusher_softness"]],
                    None)  # fmt: skip
    ex = _explanations(causes=["pusher_softness"], pinned=[Pinned(effect="pusher_softness", drop_beyond_bound=40.0,
                       critical=3.84)], outside_library=True,
                       reason="a softer pusher would go past the library's largest magnitude: most likely a "
                       "mechanism outside the library")  # fmt: skip
    v = judge(sel, [_effect("pusher_softness", 0.08)], shrink=_shrinkage(both=0.9), min_share=0.8, explanations=ex)
    assert (v.verdict, v.kind, v.effects, v.partial) == (NONE, "outside_library", [], "pusher_softness")
    assert v.sentence == (
        "Most likely a mechanism outside the library: a softer pusher would go past the library's largest magnitude. "
        "The closest combination describes the residual, not its cause: the pusher's contact is softer (solref time "
        "constant +0.08 s); it closes 90% of the gap."
    )


def test_three_effects_at_once_describe_the_residual():
    names = ["viscous", "speed_gain", "speed_offset"]
    sel = Selection(_fit(names), [[_step(n, 30.0)] for n in names], [CANDIDATES[n] for n in names], None)
    ex = _explanations(causes=names, outside_library=True,
                       reason="3 library effects at once: most likely a mechanism outside the library")  # fmt: skip
    effects = [_effect("viscous", 0.3), _effect("speed_gain", -0.2), _effect("speed_offset", -0.00689)]
    v = judge(sel, effects, shrink=_shrinkage(both=1.03), min_share=0.8, explanations=ex)
    assert v.kind == "outside_library" and v.is_none
    assert v.sentence == (
        "Most likely a mechanism outside the library: 3 library effects at once. The closest combination describes "
        "the residual, not its cause: the box feels viscous friction of 0.3 N s/m; the pusher's speed is 20.0% below "
        "the command, less 6.9 mm/s; it closes the whole gap."
    )


def test_alternatives_are_named_with_what_separates_them():
    from imply.diagnose.explanations import Alternative

    sel = Selection(_fit(["viscous"]), [[_step("viscous", 30.0)]], [CANDIDATES["viscous"]], None)
    alt = Alternative(effect="viscous", instead=["air_drag", "discrepancy"], margin=[2.0, 4.0],
                      separate_by=["add heavy and light objects", "add faster pushes"])  # fmt: skip
    v = judge(sel, [_effect("viscous", 0.25)], shrink=_shrinkage(both=0.9), min_share=0.8,
              explanations=_explanations(causes=["viscous"], alternatives=[alt]))  # fmt: skip
    assert (v.kind, v.effects, v.alternatives) == ("alternatives", ["viscous"], ["air_drag"])
    assert v.sentence == (
        "The box feels viscous friction of 0.25 N s/m; adding it closes 90% of the gap. Other explanations fit about "
        "as well: viscous friction could as well be air drag or a smooth discrepancy; to tell them apart, add heavy "
        "and light objects; add faster pushes."
    )
    # a discrepancy beside a confident effect is said in the same sentence
    v = judge(sel, [_effect("viscous", 0.25)], shrink=_shrinkage(both=0.9), min_share=0.8,
              explanations=_explanations(causes=["viscous"], discrepancy=True), discrepancy=_discrepancy())  # fmt: skip
    assert v.kind == "effects"
    assert v.sentence == ("The box feels viscous friction of 0.25 N s/m, beside a smooth discrepancy between the table "
                          "and these pushes (RMS 0.04 in log d); adding it closes 90% of the gap.")  # fmt: skip


@pytest.mark.parametrize(
    ("effect", "magnitude", "axis", "expected"),
    [
        ("anisotropic", 0.07, 0.0, "Friction along 0/180 degrees is 7% higher than along 90/270 degrees (these "
         "directions cannot show the anisotropy's axis)"),
        ("anisotropic", -0.07, 10.0, "Friction along 100/280 degrees is 7% higher than along 190/10 degrees (these "
         "directions cannot show the anisotropy's axis)"),
        ("tilt", -0.012, 30.0, "The table slopes 0.012 rad toward 210 degrees along the pushes' line (the slope "
         "across it cannot be seen from these directions)"),
    ],
)  # fmt: skip
def test_restricted_effects_say_only_what_the_directions_show(effect, magnitude, axis, expected):
    c = CANDIDATES[effect].restricted(np.array([1.0, 0.0]))
    e = AcceptedEffect(effect=effect, title=c.title, unit=c.unit, components={c.components[0]: magnitude},
                       magnitude=magnitude, ci95=(0.0, 1.0), sd=0.01, at_bound=False, azimuth_deg=axis,
                       cls=effect, fit_alias="")  # fmt: skip
    assert verdict_sentence([e], 0.9) == f"{expected}; adding it closes 90% of the gap."


def test_an_effect_the_discrepancy_can_imitate_is_named_beside_it_not_stated():
    from imply.diagnose.candidates import discrepancy_candidate

    d = discrepancy_candidate(stop_time=False, prior_sd=0.1, bound=1.0)
    sel = Selection(_fit(["speed_gain"]), [[_step("speed_gain", 80.0)]], [d, CANDIDATES["speed_gain"]], None)
    ex = _explanations(discrepancy=True, confounded=["speed_gain"])
    v = judge(sel, [_effect("speed_gain", -0.134)], shrink=_shrinkage(both=0.86), min_share=0.8, explanations=ex,
              discrepancy=_discrepancy())  # fmt: skip
    assert (v.verdict, v.kind, v.effects, v.alternatives) == (NONE, "discrepancy", [], ["speed_gain"])
    assert v.sentence.startswith("These pushes differ from the table by a smooth discrepancy")
    assert v.sentence.endswith(
        "the discrepancy closes 86% of the gap. Part of the discrepancy could as well be this: the pusher runs 13.4% "
        "slower than commanded (the discrepancy can imitate it on these pushes, so it is not stated as a cause); to "
        "tell them apart, measure the pusher's actual speed."
    )
    # an effect with a fingerprint the discrepancy cannot imitate stays a cause beside it
    both = judge(sel, [_effect("tilt", 0.02, 90.0), _effect("speed_gain", -0.134)], shrink=_shrinkage(both=0.9),
                 min_share=0.8, explanations=ex, discrepancy=_discrepancy())  # fmt: skip
    assert (both.effects, both.kind, both.alternatives) == (["tilt"], "alternatives", ["speed_gain"])
    assert both.sentence.startswith("The table slopes 0.02 rad toward 90 degrees (table frame), beside a smooth")


def test_bound_direction_says_which_library_bound_a_fit_sits_on():
    from imply.diagnose.candidates import discrepancy_candidate

    gain, tilt = CANDIDATES["speed_gain"], CANDIDATES["tilt"]
    assert gain.bound_direction(np.array([0.2])).tolist() == [1.0]
    assert gain.bound_direction(np.array([-0.2])).tolist() == [-1.0]
    assert gain.bound_direction(np.array([0.19])) is None
    assert np.allclose(tilt.bound_direction(np.array([0.0, -0.03])), [0.0, -1.0])
    assert tilt.bound_direction(np.array([0.02, 0.02])) is None
    # the discrepancy's box only keeps fits finite: it is no library bound
    d = discrepancy_candidate(stop_time=False, prior_sd=0.1, bound=1.0)
    assert d.bound_direction(np.ones(d.dim)) is None


# -- effects with a fingerprint the discrepancy cannot make -------------------------------------------------------


def test_a_fingerprinted_effect_is_stated_beside_a_discrepancy_when_the_rest_of_the_gap_stays_open():
    from imply.diagnose.candidates import discrepancy_candidate

    d = discrepancy_candidate(stop_time=False, prior_sd=0.1, bound=1.0)
    names = ["tilt", "speed_gain"]
    sel = Selection(_fit(names), [[_step(n, 30.0)] for n in names], [CANDIDATES[n] for n in names] + [d], None)
    effects = [_effect("tilt", 0.015, 24.0), _effect("speed_gain", -0.05)]
    ex = _explanations(causes=names, discrepancy=True, fingerprinted=["tilt"], removal_cost={"tilt": 40.0})
    v = judge(sel, effects, shrink=_shrinkage(both=0.55), min_share=0.8, explanations=ex, discrepancy=_discrepancy())
    assert (v.verdict, v.kind, v.effects, v.effect, v.partial, v.is_none) == (
        "tilt", "fingerprinted", ["tilt"], "tilt", "tilt+speed_gain", False)  # fmt: skip
    assert v.sentence == (
        "The table slopes 0.015 rad toward 24 degrees (table frame). It leaves a mark on these pushes that no smooth "
        "discrepancy can make (such as a dependence on the push direction), so it is stated as a cause. Friction that "
        "varies along the table toward the same azimuth would leave much the same mark; to tell them apart, push one "
        "object from several start positions. The rest of the gap is not explained: all terms together (tilt + speed_gain) close only 55% of the gap, and 0.0198 RMS "
        "log d remains above the noise floor; look for an effect outside the library, or a contact that differs from "
        "the table's."
    )
    # without a discrepancy in the final model the rest may be a directional mechanism outside the library: the
    # same fit is a partial "none", as it is without the fingerprint
    for without in (_explanations(causes=names, fingerprinted=["tilt"]), _explanations(causes=names, discrepancy=True)):
        plain = judge(sel, effects, shrink=_shrinkage(both=0.55), min_share=0.8, explanations=without)
        assert (plain.verdict, plain.kind, plain.partial) == (NONE, "none", "tilt+speed_gain")


def test_a_fingerprinted_effect_stays_a_cause_beside_a_rest_outside_the_library():
    from imply.diagnose.candidates import discrepancy_candidate

    d = discrepancy_candidate(stop_time=False, prior_sd=0.1, bound=1.0)
    names = ["anisotropic", "speed_gain", "viscous"]
    sel = Selection(_fit(names), [[_step(n, 30.0)] for n in names], [*(CANDIDATES[n] for n in names), d], None)
    effects = [_effect("anisotropic", 0.2, 30.0), _effect("speed_gain", -0.1), _effect("viscous", 0.4)]
    ex = _explanations(causes=names, discrepancy=True, fingerprinted=["anisotropic"], outside_library=True,
                       reason="3 library effects at once beside a smooth discrepancy: most likely a mechanism "
                       "outside the library")  # fmt: skip
    v = judge(sel, effects, shrink=_shrinkage(both=0.97), min_share=0.8, explanations=ex, discrepancy=_discrepancy())
    assert (v.verdict, v.kind, v.effects) == ("anisotropic", "fingerprinted", ["anisotropic"])
    assert v.sentence.endswith(
        "The rest of the gap is most likely a mechanism outside the library (the final model: 3 library effects at "
        "once beside a smooth discrepancy). The closest combination describes that rest, not its cause: "
        "the pusher runs 10.0% slower than commanded; the box feels viscous friction of 0.4 N s/m; a smooth "
        "discrepancy; all together close 97% of the gap."
    )


def test_only_a_significant_directional_effect_the_discrepancy_cannot_imitate_is_fingerprinted(monkeypatch):
    from imply.diagnose import explanations

    costs = {"tilt": 40.0, "anisotropic": 3.0, "speed_gain": 50.0, "viscous": 60.0}
    monkeypatch.setattr(explanations, "_removal_cost", lambda problem, fit, name, fold_of: costs[name])
    dispersion = {"value": 0.5 * 100}  # held-out chi-square of the final fit, over 100 rows
    monkeypatch.setattr(explanations, "_cv", lambda problem, fit, fold_of: dispersion["value"])
    problem = type("P", (), {"n_rows": 100})()
    r = {"tilt": 0.7, "anisotropic": 0.3, "speed_gain": 0.2, "viscous": 0.1}
    causes = [CANDIDATES[n] for n in costs]

    def marked(**kw):
        return explanations.fingerprinted(problem, None, kw.pop("causes", causes), **{
            "mimic_r": r, "pinned": set(), "fold_of": None, "margin": 6.0, "n_tried": 10, **kw})  # fmt: skip

    # speed_gain and viscous: no dependence on direction, however little the discrepancy imitates them;
    # anisotropic: its removal costs too little; tilt: 49% of its change is within the discrepancy's reach
    assert marked() == {"tilt": 40.0}
    assert marked(mimic_r={**r, "tilt": 0.71}) == {}  # 50.4%: more within its reach than beyond
    assert marked(pinned={"tilt"}) == {}
    assert marked(mimic_r={}) == {}
    dispersion["value"] = 3.0 * 100  # a gap left open: every chi-square difference counts 3 times less
    assert marked() == {"tilt": 40.0 / 3}
    dispersion["value"] = 5.0 * 100
    # 8 is past the margin (6) but not the selection's critical value, chi2(1 - 0.05 / 10, 2 dof) = 10.6
    assert marked() == {}
    assert marked(n_tried=1) == {"tilt": 8.0}  # chi2(0.95, 2 dof) = 5.99: the margin governs
    dispersion["value"] = 8.0 * 100
    assert marked(n_tried=1) == {}


def test_why_a_final_model_is_no_confident_verdict():
    from imply.diagnose.candidates import discrepancy_candidate
    from imply.diagnose.explanations import Pinned, outside_reason

    d = discrepancy_candidate(stop_time=False, prior_sd=0.1, bound=1.0)
    two = Model((CANDIDATES["speed_offset"], CANDIDATES["viscous"]))
    assert outside_reason([], two) is None
    # effects the discrepancy can imitate are counted too: the sentence never says "0 library effects"
    assert outside_reason([], Model((*two.candidates, d))) == (
        "2 library effects at once beside a smooth discrepancy: most likely a mechanism outside the library"
    )
    assert outside_reason([], Model((*two.candidates, CANDIDATES["tilt"]))) == (
        "3 library effects at once: most likely a mechanism outside the library"
    )
    pin = [Pinned(effect="viscous", drop_beyond_bound=20.0, critical=3.84)]
    assert outside_reason(pin, two) == (
        "viscous friction would go past the library's largest magnitude: most likely a mechanism outside the library"
    )


def test_an_effect_the_pushes_prefer_to_the_discrepancy_is_not_confounded_with_it():
    from imply.diagnose.candidates import discrepancy_candidate
    from imply.diagnose.explanations import preferred_to_discrepancy

    d = discrepancy_candidate(stop_time=False, prior_sd=0.1, bound=1.0)

    def tried(c, gain):
        return StepResult(c, _fit([]), 50.0, c.dim, 6.0, gain, 0.1, 0.1, 0.0, True, [])

    viscous, offset = CANDIDATES["viscous"], CANDIDATES["speed_offset"]
    # step 1: viscous beats the discrepancy by 500; step 2 (the discrepancy in the model): nothing to compare with
    steps = [[tried(viscous, 1972.0), tried(d, 1472.0)], [tried(offset, 30.0)]]
    assert preferred_to_discrepancy(Selection(_fit([]), steps, [viscous, offset], None), 6.0) == {"viscous"}
    # within the margin of the discrepancy, or below it: the prior, not the pushes, shares the gap out
    close = [[tried(viscous, 1475.0), tried(d, 1472.0)]]
    assert preferred_to_discrepancy(Selection(_fit([]), close, [viscous], None), 6.0) == set()
    below = [[tried(offset, 61.8), tried(d, 285.5)]]
    assert preferred_to_discrepancy(Selection(_fit([]), below, [offset], None), 6.0) == set()
