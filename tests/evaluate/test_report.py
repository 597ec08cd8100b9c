"""The evaluation report: every file written, JSON that reads back with NaN as null, one comparison row per
model with the same columns, and a folder written whole or not at all."""

from __future__ import annotations

import csv
import json
import shutil

import numpy as np
import pytest

from imply.evaluate import report
from imply.evaluate.evaluation import (
    ConditionScores,
    Degenerate,
    Estimate,
    Evaluation,
    FrameQuality,
    OwnVsOther,
    Readings,
    ReadoutInfo,
    Selection,
    SelectionRow,
    SetScores,
)
from imply.io import MANIFEST, OutputError

CONDITIONS = ("own", "other", "none")
N_OBJECTS, N_SPEEDS = 12, 4
SUITE = "ab" * 32
NAN = float("nan")


def _estimate(rng: np.random.Generator, scale: float = 1.0) -> Estimate:
    value = scale * rng.uniform(0.2, 0.8)
    return Estimate(value, value - 0.1 * scale, value + 0.1 * scale)


def _readings(rng: np.random.Generator, *, conditions, n_samples: int, frames: bool) -> Readings:
    shape = (len(conditions), n_samples, N_OBJECTS, N_SPEEDS)
    speeds = np.linspace(0.4, 1.6, N_SPEEDS)
    truth = 0.02 * speeds**2 * rng.uniform(0.5, 2.0, (N_OBJECTS, 1))
    box_found = np.ones(shape, bool)
    if frames:
        box_found[1, 0, :2, 0] = False  # a couple of rollouts without a box
    per_frame = rng.uniform(0.5, 1.5, shape) if frames else np.full(shape, NAN)
    return Readings(
        conditions=tuple(conditions),
        object_ids=np.array([f"obj{i:03d}" for i in range(N_OBJECTS)]),
        query_speeds=speeds,
        displacement=truth * np.exp(rng.normal(0.0, 0.2, shape)),
        box_found=box_found,
        saliency_ratio=per_frame,
        psnr=20 * per_frame,
        true_displacement=truth,
        calibration_speeds=np.array([0.5, 1.5]),
        calibration_displacement=truth[:, [0, -1]],
    )


def make_evaluation(
    model: str, *, n_samples: int, frames: bool, seed: int, conditions=CONDITIONS, suite: str = SUITE
) -> Evaluation:
    """A hand-built evaluation with random readings and scores (a frames model with S = 1, or a latents one)."""
    rng = np.random.default_rng(seed)
    scores = tuple(
        ConditionScores(
            condition=c,
            n_objects=N_OBJECTS,
            track=_estimate(rng),
            error=_estimate(rng),
            self_disagreement=_estimate(rng, 0.1),
            anchored_disagreement=_estimate(rng, 0.3),
            # an undefined correlation (a constant score): must come out as null / n/a
            corr_self=Estimate(NAN, NAN, NAN) if c == "none" else _estimate(rng),
            corr_anchored=_estimate(rng),
        )
        for c in conditions
    )
    rules = ("lowest self", "lowest anchored", "random")
    by_conditions = Selection(
        "conditions", len(conditions), tuple(SelectionRow(rule, _estimate(rng), _estimate(rng)) for rule in rules)
    )
    by_samples = tuple(
        Selection(
            f"sample sets ({c})", n_samples, tuple(SelectionRow(r, _estimate(rng), _estimate(rng)) for r in rules)
        )
        for c in conditions
    )
    degenerate = tuple(
        Degenerate(
            c,
            n_sets=n_samples * N_OBJECTS,
            n_rollouts=n_samples * N_OBJECTS * N_SPEEDS,
            static=3 if (frames and c == "none") else 0,
            not_growing=1 if c == "other" else 0,
            no_box=2 if (frames and c == "other") else 0,
        )
        for c in conditions
    )
    return Evaluation(
        model=model,
        kind="frames" if frames else "latents",
        suite=suite,
        suite_version=1,
        readout=ReadoutInfo(
            name="frame difference" if frames else "ridge on encode()",
            fitted_on="the suite's real training clips" if frames else "the model's encode() of real training clips",
            n_fit=200,
            n_check=50,
            r2_check=0.97,
            error_check=0.05,
        ),
        n_objects=N_OBJECTS,
        n_speeds=N_SPEEDS,
        n_samples=n_samples,
        bootstrap=200,
        conditions=scores,
        own_vs_other=OwnVsOther(N_OBJECTS, _estimate(rng), _estimate(rng)) if "other" in conditions else None,
        selection_conditions=by_conditions if len(conditions) > 1 else None,
        selection_samples=by_samples if n_samples > 1 else (),
        spread={c: _estimate(rng, 0.1) for c in conditions} if n_samples > 1 else {},
        degenerate=degenerate,
        frame_quality=FrameQuality("own", _estimate(rng), _estimate(rng, 30)) if frames else None,
        readings=_readings(rng, conditions=conditions, n_samples=n_samples, frames=frames),
        sets=SetScores(*rng.random((4, len(conditions), n_samples, N_OBJECTS))),
    )


@pytest.fixture(scope="module", autouse=True)
def small_figures():
    dpi, report.PNG_DPI = report.PNG_DPI, 100
    yield
    report.PNG_DPI = dpi


@pytest.fixture(scope="module")
def evaluations() -> list[Evaluation]:
    """A frames model with one sample set, a latents one with three, and one asked only with its own calibration."""
    return [
        make_evaluation("pixels", n_samples=1, frames=True, seed=1),
        make_evaluation("latent | v2", n_samples=3, frames=False, seed=2),
        make_evaluation("own only", n_samples=1, frames=False, seed=3, conditions=("own",)),
    ]


@pytest.fixture(scope="module")
def written(tmp_path_factory, evaluations):
    """The report of ``evaluations`` (written once; copy it before changing it) and the names returned."""
    out = tmp_path_factory.mktemp("written") / "report"
    return out, report.write_report(evaluations, out)


@pytest.fixture
def plain() -> Evaluation:
    return make_evaluation("plain", n_samples=1, frames=False, seed=4, conditions=("own",))


def _copy(written, tmp_path):
    out = tmp_path / "report"
    shutil.copytree(written[0], out)
    return out


def _files(folder) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def _comparison_table(text: str) -> list[list[str]]:
    """The cells of the first table after '## Comparison' (a '\\|' inside a cell is not a separator)."""
    lines = text.split("## Comparison", 1)[1].splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("|"))
    table = []
    for line in lines[start:]:
        if not line.startswith("|"):
            break
        cells = line.replace("\\|", "\0").strip().strip("|").split("|")
        table.append([c.strip().replace("\0", "|") for c in cells])
    return table


def test_every_file_is_written(written):
    out, names = written
    expected = {
        "results.json",
        "report.md",
        "per_object.csv",
        "slides.png",
        "slides.pdf",
        "scores.png",
        "scores.pdf",
        "selection.png",
        "selection.pdf",
    }
    assert set(names) == expected
    assert {p.name for p in out.iterdir()} == expected | {MANIFEST}
    assert set(names) <= set(report.REPORT_FILES)
    text = (out / "report.md").read_text()
    for figure in ("slides", "scores", "selection"):
        assert f"]({figure}.png)" in text
        assert (out / f"{figure}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert (out / f"{figure}.pdf").read_bytes()[:5] == b"%PDF-"
    assert "bootstrap 95%" in text and "200 resamples" in text
    # a section per model, the degenerate sets flagged in words
    assert "## pixels" in text and "## latent | v2" in text and "## own only" in text
    assert "3 of 12 sets are static: a future where nothing moves scores as perfectly consistent" in text
    assert "2 of 48 rollouts have no box" in text
    assert "1 of 12 sets does not slide further when pushed faster" in text
    assert "Choosing among sample sets (own)" in text


def test_per_object_csv_has_a_row_per_model_condition_sample_object_and_speed(written, evaluations):
    with open(written[0] / "per_object.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == sum(ev.readings.displacement.size for ev in evaluations)
    assert len(rows) == (3 * 1 + 3 * 3 + 1 * 1) * N_OBJECTS * N_SPEEDS
    assert list(rows[0]) == [
        "model",
        "condition",
        "sample",
        "object_id",
        "speed_m_s",
        "read_displacement_m",
        "true_displacement_m",
        "box_found",
    ]
    ev = evaluations[1]
    # the second model, condition other (index 1), sample set 2, object 5: its K rows in speed order
    pick = [
        r
        for r in rows
        if (r["model"], r["condition"], r["sample"], r["object_id"]) == (ev.model, "other", "2", "obj005")
    ]
    assert len(pick) == N_SPEEDS
    assert float(pick[3]["read_displacement_m"]) == pytest.approx(ev.readings.displacement[1, 2, 5, 3], rel=1e-9)
    assert float(pick[3]["true_displacement_m"]) == pytest.approx(ev.readings.true_displacement[5, 3], rel=1e-9)
    assert float(pick[3]["speed_m_s"]) == pytest.approx(ev.readings.query_speeds[3])
    no_box = [r for r in rows if r["box_found"] == "False"]
    assert len(no_box) == 2 and {(r["model"], r["condition"]) for r in no_box} == {("pixels", "other")}


def test_results_json_reads_back_with_nan_as_null(written, evaluations):
    text = (written[0] / "results.json").read_text()
    assert "NaN" not in text
    doc = json.loads(text)
    assert (doc["format"], doc["version"], doc["suite"]) == ("imply-evaluation", 1, SUITE)
    assert [m["model"] for m in doc["models"]] == ["pixels", "latent | v2", "own only"]
    assert doc["models"][0] == json.loads(json.dumps(evaluations[0].to_dict()))
    none = next(c for c in doc["models"][0]["conditions"] if c["condition"] == "none")
    assert none["corr_self"] == {"value": None, "low": None, "high": None}
    rows = doc["comparison"]
    assert rows[1]["readout_r2_check"] == 0.97
    assert rows[0]["track_own"]["value"] == pytest.approx(evaluations[0].condition("own").track.value)
    assert rows[0]["corr_self_own"]["value"] == pytest.approx(evaluations[0].condition("own").corr_self.value)
    assert rows[2]["error_other"] is None and rows[2]["own_lower_self"] is None
    assert [r["static_sets"] for r in rows] == [3, 0, 0]


def test_comparison_has_one_row_per_model_with_the_same_columns(written, evaluations):
    header, rule, *rows = _comparison_table((written[0] / "report.md").read_text())
    assert set(rule) == {"---"}
    assert [row[0] for row in rows] == ["pixels", "latent | v2", "own only"]
    assert all(len(row) == len(header) for row in [rule, *rows])
    assert header[:4] == ["model", "kind", "readout", "readout R^2 (real check clips)"]
    for c in CONDITIONS:
        assert f"tracking r, {c}" in header and f"log error, {c}" in header
    # a condition the model was not asked in is n/a in its row, not a missing cell
    assert rows[2][header.index("log error, other")] == "n/a"
    assert rows[2][header.index("own < other, anchored (%)")] == "n/a"
    assert rows[0][header.index("r(self, error), own")] == evaluations[0].condition("own").corr_self.format(".2f")
    assert rows[0][header.index("degenerate: static / not growing / no box")] == "3 / 1 / 2"
    assert rows[0][header.index("log error, own")] == evaluations[0].condition("own").error.format(".3f")
    doc = json.loads((written[0] / "results.json").read_text())
    assert len(doc["comparison"]) == 3
    assert len({tuple(row) for row in doc["comparison"]}) == 1  # the same keys, in the same order


def test_second_write_needs_force_and_force_replaces(written, evaluations, plain, tmp_path):
    out = _copy(written, tmp_path)
    first = _files(out)
    with pytest.raises(OutputError, match="not empty"):
        report.write_report(evaluations[:1], out)
    assert _files(out) == first
    # a report without any selection: forced, it replaces the files and drops the stale selection figures
    names = report.write_report([plain], out, force=True)
    assert "selection.png" not in names
    assert not (out / "selection.png").exists() and not (out / "selection.pdf").exists()
    assert [m["model"] for m in json.loads((out / "results.json").read_text())["models"]] == ["plain"]
    assert [p.name for p in tmp_path.iterdir()] == ["report"]


def test_an_input_in_the_folder_is_never_replaced(written, plain, tmp_path):
    out = _copy(written, tmp_path)
    first = _files(out)
    with pytest.raises(OutputError, match="is an input"):
        report.write_report([plain], out, force=True, inputs=iter([out / "per_object.csv"]))  # a one-pass iterable
    assert _files(out) == first


def test_a_failure_while_writing_leaves_nothing_behind(written, plain, tmp_path, monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("figure failed")

    monkeypatch.setattr(report, "_scores_figure", broken)  # results.json, the CSV and a figure are written by then
    fresh = tmp_path / "fresh"
    with pytest.raises(RuntimeError, match="figure failed"):
        report.write_report([plain], fresh)
    assert list(tmp_path.iterdir()) == []
    # over an earlier report (forced): the earlier one is kept as it was
    out = _copy(written, tmp_path)
    first = _files(out)
    with pytest.raises(RuntimeError, match="figure failed"):
        report.write_report([plain], out, force=True)
    assert _files(out) == first
    assert [p.name for p in tmp_path.iterdir()] == ["report"]


def test_models_of_different_suites_or_one_name_are_refused(tmp_path, evaluations):
    other_suite = make_evaluation("elsewhere", n_samples=1, frames=False, seed=5, suite="cd" * 32)
    with pytest.raises(ValueError, match="different suites"):
        report.write_report([*evaluations, other_suite], tmp_path / "a")
    with pytest.raises(ValueError, match="named 'pixels'"):
        report.write_report([evaluations[0], evaluations[0]], tmp_path / "b")
    with pytest.raises(ValueError, match="no evaluations"):
        report.write_report([], tmp_path / "c")
    assert list(tmp_path.iterdir()) == []
