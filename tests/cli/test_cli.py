"""The `imply` command line: scoring a hand-made CSV, its refusals, and the sim commands."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from imply.cli import main
from imply.score_file import SCORE_COLUMNS
from sample_inputs import ROLLOUTS_CSV

GOOD = ROLLOUTS_CSV


def run_cli(*args: str) -> int:
    return main(list(args))


def test_score_writes_every_column(tiny_table_path, tmp_path):
    src = tmp_path / "rollouts.csv"
    src.write_text(GOOD)
    out = tmp_path / "scores.csv"
    assert run_cli("score", str(src), "--table", str(tiny_table_path), "-o", str(out)) == 0
    scores = pd.read_csv(out)
    assert list(scores.columns) == SCORE_COLUMNS
    assert list(scores.object_id) == ["a", "b"]
    assert list(scores.n_rollouts) == [3, 2]
    assert np.isfinite(scores.loc[0, "anchored_disagreement"])
    assert np.isnan(scores.loc[1, "anchored_disagreement"])  # b has no calibration pushes
    assert (scores.self_disagreement >= 0).all()


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda t: t.replace("displacement", "disp"), "missing column(s) displacement"),
        (lambda t: t.replace("b,rollout,0.4,0.05", "b,rollout,fast,0.05"), "row 6 (line 7), column speed"),
        (lambda t: t.replace("b,rollout,0.4,0.05", "b,rollout,0.4,nan"), "row 6 (line 7), column displacement"),
        (lambda t: t.replace("b,rollout,0.4,0.05", "b,rollout,0.4,-0.05"), "column displacement: -0.05 is negative"),
        (lambda t: t.replace("b,rollout,0.4,0.05", "b,rollout,3.0,0.05"), "column speed: 3 is outside"),
        (lambda t: t.replace("b,rollout,0.4,0.05", "b,prediction,0.4,0.05"), "column role"),
        (lambda t: t.replace("b,rollout,0.7,0.11\n", ""), "object 'b' has 1 rollout(s)"),
    ],
)
def test_score_refuses_bad_input_with_one_line_and_no_output(tiny_table_path, tmp_path, capsys, edit, message):
    src = tmp_path / "rollouts.csv"
    src.write_text(edit(GOOD))
    out = tmp_path / "scores.csv"
    assert run_cli("score", str(src), "--table", str(tiny_table_path), "-o", str(out)) == 2
    err = capsys.readouterr().err.strip()
    assert message in err
    assert len(err.splitlines()) == 1
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [src]  # no temporary file left either


def test_score_refuses_a_bad_table(tmp_path, capsys):
    src = tmp_path / "rollouts.csv"
    src.write_text(GOOD)
    bad = tmp_path / "table.npz"
    bad.write_text("nope")
    assert run_cli("score", str(src), "--table", str(bad), "-o", str(tmp_path / "s.csv")) == 2
    assert "--table" in capsys.readouterr().err
    assert run_cli("score", str(src), "--table", str(tmp_path / "none.npz"), "-o", str(tmp_path / "s.csv")) == 2


def test_export_xml_and_simulate_pushes_on_it(tmp_path):
    xml = tmp_path / "box.xml"
    assert run_cli("sim", "export-xml", "mass=0.8", "friction=0.3", "size=0.04,0.05,0.03", "-o", str(xml)) == 0
    text = xml.read_text()
    assert 'size="0.04 0.05 0.03"' in text and 'mass="0.8"' in text
    pushes = tmp_path / "pushes.csv"
    pushes.write_text("object_id,speed\nx,0.3\nx,0.6\n")
    log = tmp_path / "log.csv"
    assert run_cli("sim", "pushes", str(pushes), "--model", str(xml), "-o", str(log)) == 0
    frame = pd.read_csv(log)
    assert list(frame.columns[:4]) == ["object_id", "speed", "displacement", "stop_time"]
    assert frame.ok.all() and frame.displacement.iloc[1] > frame.displacement.iloc[0]


def test_pushes_with_physics_columns_on_the_builtin_scene(tmp_path, capsys):
    pushes = tmp_path / "pushes.csv"
    pushes.write_text("object_id,speed,mass,friction\nx,0.5,0.5,0.2\ny,0.5,1.5,0.2\n")
    out = tmp_path / "log.csv"
    assert run_cli("sim", "pushes", str(pushes), "-o", str(out)) == 0
    frame = pd.read_csv(out)
    assert frame.displacement.iloc[1] < frame.displacement.iloc[0]  # heavier box, shorter push
    pushes.write_text("object_id,speed,mass\nx,0.5,-1\n")
    assert run_cli("sim", "pushes", str(pushes), "-o", str(tmp_path / "o.csv")) == 2
    assert "row 1 (line 2), column mass" in capsys.readouterr().err


def test_pushes_filmed_on_a_user_model_give_a_track_the_diagnostic_reads(tmp_path):
    """`imply sim pushes --track-rate` writes the boxes' tracks beside the log; the track file reader accepts them,
    and their last frame agrees with the log's displacement (two code paths: the frames and the final state)."""
    from imply.diagnose.inputs.pushlog import read_pushlog
    from imply.diagnose.inputs.track_file import read_track, track_beside

    xml = tmp_path / "box.xml"
    assert run_cli("sim", "export-xml", "mass=0.8", "friction=0.3", "-o", str(xml)) == 0
    pushes = tmp_path / "pushes.csv"
    pushes.write_text("object_id,speed\nx,0.3\nx,0.6\nx,0.9\n")
    log = tmp_path / "log.csv"
    assert run_cli("sim", "pushes", str(pushes), "--model", str(xml), "--track-rate", "120", "-o", str(log)) == 0
    track = pd.read_csv(tmp_path / "log.track.csv")
    assert list(track.columns) == ["object_id", "push", "t", "x", "y", "yaw"] and set(track.push) == {1, 2, 3}
    frame = pd.read_csv(log)
    last = track.groupby("push").last()
    first = track.groupby("push").first()
    np.testing.assert_allclose((last.x - first.x).to_numpy(), frame.displacement.to_numpy(), rtol=0.02)
    # frames are taken at the simulation step nearest their due time
    np.testing.assert_allclose(np.diff(track[track.push == 1].t.to_numpy()[:3]), 1 / 120, rtol=0.02)
    tracked = read_track(track_beside(log), read_pushlog(log))
    assert (np.diff(tracked.crossing_times, axis=1) > 0).all()  # a quarter, then half, then three quarters

    # the log's stop time is the one the diagnostic's tables hold (the box's speed below 1 cm/s), not the settling
    from imply.diagnose.physics.effect_tables import simulate_observables
    from imply.sim.push_file import load_push_model

    tables = simulate_observables(load_push_model(xml), frame.speed, 0.8, 0.3)
    np.testing.assert_allclose(np.log(frame.stop_time.to_numpy()), tables.log_t, atol=1e-9)


def test_console_script_is_installed():
    proc = subprocess.run([sys.executable, "-m", "imply.cli", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0 and "score" in proc.stdout


def test_score_ids_are_stripped_and_blank_lines_skipped_alike_in_both_readers(tiny_table_path, tmp_path):
    """The fast reader (pyarrow) and the careful one (pandas, taken when a line is blank) agree."""
    plain = tmp_path / "plain.csv"
    plain.write_text(GOOD)
    padded = tmp_path / "padded.csv"
    padded.write_text(GOOD.replace("b,rollout,0.4", "b  ,rollout,0.4").replace("a,rollout,0.55", "\n a,rollout,0.55"))
    outs = []
    for src in (plain, padded):
        out = tmp_path / f"{src.stem}-scores.csv"
        assert run_cli("score", str(src), "--table", str(tiny_table_path), "-o", str(out)) == 0
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]
    assert list(pd.read_csv(tmp_path / "padded-scores.csv").object_id) == ["a", "b"]


def test_score_output_matches_the_per_object_reference(tiny_table_path, tmp_path):
    """Vectorised grouping gives what scoring each object's rows on their own gives."""
    from imply.score import Scorer
    from imply.table import PushTable

    rng = np.random.default_rng(5)
    rows = []
    for i in range(30):
        speeds = rng.choice([0.25, 0.4, 0.55, 0.7, 0.85], size=rng.integers(2, 6), replace=False)
        rows += [(f"o{i}", "rollout", v, float(np.exp(rng.normal(-2.5, 0.5)))) for v in speeds]
        if i % 3:
            rows += [(f"o{i}", "calibration", v, float(np.exp(rng.normal(-2.5, 0.5)))) for v in (0.3, 0.8)]
    order = rng.permutation(len(rows))
    frame = pd.DataFrame([rows[j] for j in order], columns=["object_id", "role", "speed", "displacement"])
    src = tmp_path / "many.csv"
    frame.to_csv(src, index=False)
    out = tmp_path / "scores.csv"
    assert run_cli("score", str(src), "--table", str(tiny_table_path), "-o", str(out)) == 0
    got = pd.read_csv(out).set_index("object_id")
    scorer = Scorer(PushTable.load(tiny_table_path))
    for obj, g in frame.groupby("object_id"):
        r, c = g[g.role == "rollout"], g[g.role == "calibration"]
        s = scorer.score(
            r.speed.to_numpy()[None],
            r.displacement.to_numpy()[None],
            *((c.speed.to_numpy()[None], c.displacement.to_numpy()[None]) if len(c) else (None, None)),
        )
        assert got.loc[obj, "n_rollouts"] == len(r)
        assert got.loc[obj, "self_disagreement"] == pytest.approx(s.self_disagreement[0], rel=1e-8, abs=1e-10)
        if len(c):
            assert got.loc[obj, "anchored_disagreement"] == pytest.approx(s.anchored_disagreement[0], rel=1e-8)
        else:
            assert np.isnan(got.loc[obj, "anchored_disagreement"])
    assert list(got.index) == list(dict.fromkeys(frame.object_id))  # order of first appearance


def test_score_reads_parquet(tiny_table_path, tmp_path):
    src = tmp_path / "r.parquet"
    pd.read_csv(pd.io.common.StringIO(GOOD)).to_parquet(src)
    out = tmp_path / "s.csv"
    assert run_cli("score", str(src), "--table", str(tiny_table_path), "-o", str(out)) == 0
    assert list(pd.read_csv(out).n_rollouts) == [3, 2]


def test_score_does_not_import_the_heavy_stacks(tiny_table_path, tmp_path):
    """`imply score` starts fast: no torch, matplotlib, snakemake, nor pandas for a clean CSV."""
    src = tmp_path / "r.csv"
    src.write_text(GOOD)
    code = (
        "import sys\nfrom imply.cli import main\n"
        f"assert main(['score', {str(src)!r}, '--table', {str(tiny_table_path)!r}, '-o', {str(tmp_path / 's.csv')!r}]) == 0\n"
        "print(sorted(m for m in ('torch', 'matplotlib', 'snakemake', 'pandas') if m in sys.modules))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert proc.stdout.strip() == "[]"


def test_the_version_lives_in_one_place_and_the_citation_names_it(capsys):
    """`imply --version` prints the package's version; pyproject reads it from imply.__version__ and CITATION.cff
    states the same."""
    import tomllib
    from pathlib import Path

    import yaml

    import imply
    from imply.cli import main

    root = Path(__file__).resolve().parents[2]
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out.strip() == f"imply {imply.__version__}"
    project = tomllib.loads((root / "pyproject.toml").read_text())["project"]
    assert "version" not in project and project["dynamic"] == ["version"]
    assert str(yaml.safe_load((root / "CITATION.cff").read_text())["version"]) == imply.__version__
