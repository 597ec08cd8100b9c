"""``imply evaluate`` end to end on a tiny suite: known answers, two ways in, bad input, resuming."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from imply.cli import main
from imply.evaluate.config import EvaluateConfig
from imply.evaluate.harness import evaluate
from imply.evaluate.interface import ModelError
from imply.evaluate.rollouts_file import RolloutsFileError, write_rollouts_file
from imply.evaluate.standins import STANDINS, Collapse
from imply.evaluate.suite import load_suite, load_truth

FAST = EvaluateConfig(bootstrap=50)
TUTORIAL = Path(__file__).resolve().parents[2] / "docs" / "tutorials" / "evaluate.md"


class PowerLaw:
    """A displacements model that uses the calibration it is shown (slide ~ speed^2)."""

    kind = "displacements"
    name = "power law"
    batch_size = 4

    def __init__(self) -> None:
        self.calls = 0

    def rollout(self, request):
        self.calls += 1
        v = request.query_speeds
        if request.calibration_displacement is None:
            scale = np.full(len(request), 0.2)
        else:
            scale = (request.calibration_displacement / request.calibration_speeds**2).mean(axis=1)
        return scale[:, None] * v[None, :] ** 2


class Broken(PowerLaw):
    """Returns what ``spoil`` makes of a good output."""

    def __init__(self, spoil) -> None:
        super().__init__()
        self.spoil = spoil

    def rollout(self, request):
        return self.spoil(super().rollout(request))


class LatentOracle:
    """A latents model whose rollouts are its own encoding of the true rest frames (reads the truth)."""

    kind = "latents"
    name = "latent oracle"

    def __init__(self, suite) -> None:
        self.truth = load_truth(suite)
        self.index = {o: i for i, o in enumerate(suite.object_ids)}
        h, w, _ = suite.frame_shape
        self.projection = np.random.default_rng(0).standard_normal((h * w * 3 // 16, 24))

    def encode(self, frames):
        f = np.asarray(frames, dtype=np.float32)[:, ::4, ::4]  # coarse pixels, then a fixed projection
        return (f.reshape(len(f), -1) / 255.0) @ self.projection[: f[0].size]

    def rollout(self, request):
        idx = [self.index[o] for o in request.object_ids]
        rest = self.truth.rest_frames[idx]
        b, k = rest.shape[:2]
        return self.encode(rest.reshape(b * k, *rest.shape[2:])).reshape(b, k, -1)


def by_model(evaluations):
    return {ev.model: ev for ev in evaluations}


@pytest.fixture(scope="module")
def standin_evaluations(known_answers_suite):
    suite = load_suite(known_answers_suite)
    return evaluate([f(suite) for f in STANDINS.values()], suite=suite, settings=FAST)


def test_standins_show_the_known_answers_from_pixels(standin_evaluations):
    from imply.study.section4.through_evaluate import known_answers

    ev = by_model(standin_evaluations)
    auroc = known_answers(standin_evaluations)["standins"]
    oracle, blind, collapse = ev["oracle"], ev["object-blind"], ev["collapse"]
    assert oracle.readout.name == "frame difference" and oracle.readout.r2_check > 0.95
    # the oracle's rollouts are the truth: its anchored disagreement is the readout's noise
    assert oracle.condition("own").anchored_disagreement.value <= 1.5 * oracle.readout.error_check
    assert oracle.condition("own").track.value > 0.95
    # object-blind: anchoring exposes it, self-disagreement does not
    assert auroc["blind"]["auroc_anchored"] >= 0.9
    assert auroc["blind"]["auroc_self"] <= 0.75
    # jitter: both scores separate it
    assert auroc["jitter"]["auroc_anchored"] >= 0.9
    assert auroc["jitter"]["auroc_self"] >= 0.9
    # collapse: every set flagged static, none of the oracle's
    own = {d.condition: d for d in collapse.degenerate}["own"]
    assert own.static == own.n_sets
    assert all(d.static == 0 for d in oracle.degenerate)
    assert abs(blind.condition("own").track.value) < 0.6


def test_a_model_that_uses_its_calibration_prefers_its_own(tiny_suite):
    (ev,) = evaluate([PowerLaw()], suite=tiny_suite, settings=FAST)
    assert ev.own_vs_other.anchored_disagreement.value > 0.5
    assert ev.condition("own").error.value < ev.condition("other").error.value
    assert ev.selection_conditions is not None and ev.selection_conditions.n_candidates == 3
    lo, hi = ev.condition("own").error.low, ev.condition("own").error.high
    assert lo <= ev.condition("own").error.value <= hi


def test_latent_models_are_read_by_a_ridge_on_their_own_encoder(tiny_suite):
    suite = load_suite(tiny_suite)
    (ev,) = evaluate([LatentOracle(suite)], suite=suite, settings=FAST)
    assert ev.readout.name == "ridge on encode()"
    assert ev.readout.n_fit == len(suite.train_frames)
    assert np.isfinite(ev.readout.r2_check)


def _rows(ev, suite):
    """The readings of an evaluation as a rollouts file's rows (displacements kind)."""
    r = ev.readings
    c, s, n, k = r.displacement.shape
    grid = np.meshgrid(np.arange(c), np.arange(s), np.arange(n), np.arange(k), indexing="ij")
    ci, si, ni, ki = (g.ravel() for g in grid)
    return dict(
        object_id=suite.object_ids[ni],
        condition=np.array(r.conditions)[ci],
        speed=suite.query_speeds[ki],
        sample=si,
        output=r.displacement.ravel(),
    )


def test_two_ways_in_give_one_result(tiny_suite, tmp_path):
    suite = load_suite(tiny_suite)
    (direct,) = evaluate([PowerLaw()], suite=suite, settings=FAST)
    path = tmp_path / "rollouts.npz"
    write_rollouts_file(path, kind="displacements", model="power law", suite=suite.checksum, **_rows(direct, suite))
    (from_file,) = evaluate(suite=suite, rollouts=[path], settings=FAST)
    assert json.dumps(from_file.to_dict(), sort_keys=True) == json.dumps(direct.to_dict(), sort_keys=True)
    # the same rows as a CSV of displacements
    import pandas as pd

    rows = _rows(direct, suite)
    rows["displacement"] = rows.pop("output")
    pd.DataFrame(rows).to_csv(tmp_path / "power law.csv", index=False)
    (from_csv,) = evaluate(suite=suite, rollouts=[tmp_path / "power law.csv"], settings=FAST)
    assert from_csv.model == "power law"
    assert json.dumps(from_csv.to_dict(), sort_keys=True) == json.dumps(direct.to_dict(), sort_keys=True)


@pytest.mark.parametrize(
    ("spoil", "message"),
    [
        (lambda d: d[:, :-1], r"shape \(\d+, \d+\), expected"),
        (lambda d: np.where(np.arange(d.shape[1]) == 2, np.nan, d), r"object .+, condition own, speed 0\.55 m/s.+NaN"),
        (lambda d: -d, r"negative displacement"),
        (lambda d: d.astype(str), r"must be real numbers"),
    ],
)
def test_a_model_breaking_the_interface_is_named(tiny_suite, spoil, message):
    with pytest.raises(ModelError, match=message):
        evaluate([Broken(spoil)], suite=tiny_suite, settings=FAST)


def test_frames_of_the_wrong_dtype_are_refused(tiny_suite):
    class Floats(Collapse):
        def rollout(self, request):
            return super().rollout(request).astype(np.float32)

    with pytest.raises(ModelError, match="frames must be uint8"):
        evaluate([Floats()], suite=tiny_suite, settings=FAST)


def test_a_rollouts_file_missing_a_rollout_names_it(tiny_suite, tmp_path):
    suite = load_suite(tiny_suite)
    (direct,) = evaluate([PowerLaw()], suite=suite, settings=FAST)
    rows = _rows(direct, suite)
    drop = 7
    cut = {k: np.delete(v, drop) for k, v in rows.items()}
    path = tmp_path / "missing.npz"
    write_rollouts_file(path, kind="displacements", model="m", **cut)
    obj, cond, speed = rows["object_id"][drop], rows["condition"][drop], rows["speed"][drop]
    with pytest.raises(RolloutsFileError, match=rf"no rollout of object {obj}, condition {cond}, speed {speed:g}"):
        evaluate(suite=suite, rollouts=[path], settings=FAST)
    dup = {k: np.append(v, v[:1]) for k, v in rows.items()}
    write_rollouts_file(path, kind="displacements", model="m", **dup)
    with pytest.raises(RolloutsFileError, match="a second rollout"):
        evaluate(suite=suite, rollouts=[path], settings=FAST)
    stranger = dict(rows, object_id=np.where(np.arange(len(rows["speed"])) == 3, "nobody", rows["object_id"]))
    write_rollouts_file(path, kind="displacements", model="m", **stranger)
    with pytest.raises(RolloutsFileError, match="row 3: object 'nobody' is not in the suite"):
        evaluate(suite=suite, rollouts=[path], settings=FAST)


def test_cli_refuses_bad_input_in_one_line_and_writes_nothing(tiny_suite, tmp_path, capsys, monkeypatch):
    model = tmp_path / "bad_model.py"
    model.write_text(
        "import numpy as np\n"
        "class M:\n    kind = 'displacements'\n"
        "    def rollout(self, request):\n        return np.zeros((len(request), 2))\n"
        "def build():\n    return M()\n"
    )
    out = tmp_path / "report"
    code = main(["evaluate", "--model", f"{model}:build", "--suite", str(tiny_suite), "-o", str(out), "--no-progress"])
    errors = [line for line in capsys.readouterr().err.splitlines() if "error:" in line]
    assert code == 2 and len(errors) == 1 and "expected (6, 5)" in errors[0] and "condition own" in errors[0]
    assert not out.exists()
    code = main(["evaluate", "--model", "no_such_module:build", "--suite", str(tiny_suite), "-o", str(out)])
    assert code == 2 and "cannot import" in capsys.readouterr().err
    assert not out.exists()


def test_an_interrupted_evaluation_resumes_from_its_cached_batches(tiny_suite, tmp_path):
    class Interrupted(PowerLaw):
        def __init__(self, stop_after: int | None) -> None:
            super().__init__()
            self.stop_after = stop_after

        def rollout(self, request):
            if self.stop_after is not None and self.calls >= self.stop_after:
                raise KeyboardInterrupt
            return super().rollout(request)

    cache = tmp_path / "cache"
    first = Interrupted(stop_after=2)
    with pytest.raises(KeyboardInterrupt):
        evaluate([first], suite=tiny_suite, settings=FAST, cache_dir=cache)
    again = Interrupted(stop_after=None)
    (resumed,) = evaluate([again], suite=tiny_suite, settings=FAST, cache_dir=cache)
    fresh = PowerLaw()
    (whole,) = evaluate([fresh], suite=tiny_suite, settings=FAST)
    assert again.calls == fresh.calls - 2
    assert json.dumps(resumed.to_dict(), sort_keys=True) == json.dumps(whole.to_dict(), sort_keys=True)


def test_stochastic_models_are_asked_for_sample_sets_and_scored_among_them(tiny_suite):
    class Noisy(PowerLaw):
        stochastic = True

        def rollout(self, request):
            rng = np.random.default_rng([request.sample, hash(request.object_ids) % 2**32])
            return super().rollout(request) * np.exp(0.3 * rng.standard_normal((len(request), 1)))

    (ev,) = evaluate([Noisy()], suite=tiny_suite, settings=FAST, samples=4)
    assert ev.n_samples == 4 and ev.readings.displacement.shape[1] == 4
    assert len(ev.selection_samples) == 3 and set(ev.spread) == {"own", "other", "none"}
    assert ev.spread["none"].value > 0.1


def test_the_tutorial_example_model_evaluates_with_the_tutorial_command(tiny_suite, tmp_path, monkeypatch):
    """The evaluate tutorial's model file and its `imply evaluate` command, as written (faster bootstrap added)."""
    import shlex

    text = TUTORIAL.read_text()
    code = re.search(r"```python\n# my_model\.py\n(.*?)```", text, re.S)
    assert code, "the evaluate tutorial must hold the example model as a ```python block starting '# my_model.py'"
    command = re.search(r"```bash\n(imply evaluate --model my_model\.py:build .*?)\n```", text, re.S)
    assert command, "the evaluate tutorial must hold the command `imply evaluate --model my_model.py:build ...`"
    (tmp_path / "my_model.py").write_text(code.group(1))
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "suite").symlink_to(tiny_suite)
    monkeypatch.chdir(tmp_path)
    argv = shlex.split(command.group(1))
    assert argv[0] == "imply"
    assert main([*argv[1:], "--no-progress", "--bootstrap", "20"]) == 0
    out = tmp_path / argv[argv.index("-o") + 1]
    results = json.loads((out / "results.json").read_text())
    (model,) = results["models"]
    assert model["kind"] == "displacements" and model["model"] == "power law"
    assert (out / "report.md").is_file()
    assert not (tmp_path / f"{out.name}.cache").exists()


def test_saliency_moments_give_the_frame_difference_shift():
    from imply.readout import frame_diff_shift, saliency_moments

    rng = np.random.default_rng(3)
    first, last = rng.integers(0, 256, size=(2, 7, 12, 40, 3), dtype=np.uint8)
    m0, mass0 = saliency_moments(first)
    m1, _ = saliency_moments(last)
    np.testing.assert_allclose((m1 - m0) / mass0, frame_diff_shift(first, last), rtol=1e-9, atol=1e-9)
