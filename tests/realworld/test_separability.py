"""Separability of a log's effect from its contact, from the label's noise-free observables."""

from __future__ import annotations

import copy

import numpy as np

from imply.realworld.lab import JACOBIAN_STEP
from imply.realworld.separability import OBSERVABLE_SETS, mark_log, summarise


def _label(effect_signature: np.ndarray, contact_signature: np.ndarray, measured_mass: bool = False) -> dict:
    """A label of 2 objects x 3 speeds whose log d moves with log mass and log friction, plus two signatures."""
    obj = np.repeat([0, 1], 3)
    v = np.tile([0.3, 0.6, 0.9], 2)
    lm, lf = np.log([0.5, 1.2])[obj], np.log([0.2, 0.4])[obj]

    def run(dm=0.0, df=0.0, extra=0.0):
        log_d = 2 * np.log(v) - 0.4 * (lm + dm) - 0.9 * (lf + df) + 0.1 * (lm + dm) * np.log(v) + extra
        log_t = np.log(v) - 0.5 * (lf + df) + 0.2 * (lm + dm) + extra / 3
        return {
            "log_d": log_d.tolist(),
            "log_t": log_t.tolist(),
            "log_p": (np.log(v) - 0.05).tolist(),
            "log_c": (np.log(v)[:, None] + [[-2.0, -1.5, -1.0]]).tolist(),
            "ok": [True] * 6,
            "probes": {
                "kind": ["friction", "friction"],
                "object": [0, 1],
                "reading": [0.2, 0.4],
                "log_p": [np.nan] * 2,
                "log_d": [np.nan] * 2,
                "log_t": [np.nan] * 2,
                "ok": [True] * 2,
            },
        }

    table = run()
    contact = run(extra=contact_signature)
    return {
        "id": "log-000",
        "group": "single_contact",
        "engine": "mujoco",
        "contact": {"kinds": ["table_compliance"]},
        "probes": True,
        "measured_mass": measured_mass,
        "replicates": 2,
        "free_strokes": 2,
        "effects": [{"name": "viscous", "magnitude": 0.5, "in_library": True}],
        "noise": {"sd": 0.02, "stop_time_sd": 0.02, "pusher_speed_sd": 0.01, "friction_sd": 0.06},
        "objects": {"obj00": {}, "obj01": {}},
        "pushes": {"object": ["obj00"] * 3 + ["obj01"] * 3},
        "noise_free": {
            "table": table,
            "contact": contact,
            "all": run(extra=contact_signature + effect_signature),
            "log_mass": run(dm=JACOBIAN_STEP),
            "log_friction": run(df=JACOBIAN_STEP),
        },
    }


def test_an_effect_shaped_like_its_contact_is_not_separable_and_another_is():
    curve = np.array([0.0, 0.05, 0.2, 0.0, 0.05, 0.2])  # grows with speed: not a mass or friction change
    other = np.array([0.1, -0.1, 0.1, -0.1, 0.1, -0.1])
    same = mark_log(_label(0.5 * curve, 3.0 * curve), alias_cos=0.95, min_size_sd=2.0, crossing_sd=0.02)
    assert all(not s["separable"] and s["cos"] > 0.95 for s in same["sets"].values())
    # a contact six times the effect, along it: left unmodelled it moves the effect's amplitude about sixfold
    assert all(not s["readable"] and 5.0 < s["leak"] < 7.0 for s in same["sets"].values())
    apart = mark_log(_label(0.5 * other, 3.0 * curve), alias_cos=0.95, min_size_sd=2.0, crossing_sd=0.02)
    assert all(s["separable"] for s in apart["sets"].values()) and set(apart["sets"]) == set(OBSERVABLE_SETS)
    assert all(s["readable"] for s in apart["sets"].values())
    assert apart["big"]  # 0.05 in log d on every push, after the fit: far above 2 noise sds


def test_what_the_per_object_fit_absorbs_is_no_signature():
    """A contact that only looks like heavier boxes leaves nothing after the fit: no cosine, no null gap."""
    label = _label(np.zeros(6), np.zeros(6))
    label["effects"] = []
    heavier = label["noise_free"]["log_mass"]
    label["noise_free"]["all"] = heavier
    null = mark_log(label, alias_cos=0.95, min_size_sd=2.0, crossing_sd=0.02)
    assert null["null_gap_sd"] < 1e-6
    assert summarise([null])["mujoco"]["null_logs"] == 1


def _mark(label: dict) -> dict:
    return mark_log(label, alias_cos=0.95, min_size_sd=2.0, crossing_sd=0.02)


def test_a_log_that_weighs_its_boxes_is_marked_without_its_log_mass_run():
    """Its fit frees no mass direction: neither the log-mass run nor a push that run alone lost is read, so its label
    leaves the run out (imply.realworld.lab.marked_runs)."""
    curve = np.array([0.0, 0.05, 0.2, 0.0, 0.05, 0.2])
    other = np.array([0.1, -0.1, 0.1, -0.1, 0.1, -0.1])
    weighed = _label(0.5 * other, 3.0 * curve, measured_mass=True)
    lost, without = copy.deepcopy(weighed), copy.deepcopy(weighed)
    lost["noise_free"]["log_mass"]["ok"][0] = False
    del without["noise_free"]["log_mass"]
    assert _mark(weighed) == _mark(lost) == _mark(without)
    # unweighed, the mass direction is fitted: the same lost push no longer counts
    unweighed = _label(0.5 * other, 3.0 * curve)
    lost = copy.deepcopy(unweighed)
    lost["noise_free"]["log_mass"]["ok"][0] = False
    assert _mark(lost) != _mark(unweighed)


def test_a_null_log_is_marked_without_its_probes():
    """A null log's gap is its displacements': its label may hold no probe in any run."""
    label = _label(np.zeros(6), 2.0 * np.array([0.0, 0.05, 0.2, 0.0, 0.05, 0.2]))
    label["effects"] = []
    del label["noise_free"]["contact"]
    bare = copy.deepcopy(label)
    for run in bare["noise_free"].values():
        del run["probes"]
    assert _mark(label) == _mark(bare) and _mark(bare)["null_gap_sd"] > 1.0
