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
