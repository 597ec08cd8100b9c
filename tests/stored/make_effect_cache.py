"""Write ``effect-cache/``: the effect tables every diagnosing test reads, on the tiny table and the tests' coarse grid.

The tests copy these files into their run's effect-table cache (conftest ``effect_cache``) instead of simulating them
(a CPU-minute). A file's name carries the digest of what it was built from (scene, grids, levels, MuJoCo's version,
the tiny table's own digest), so a change there makes the tests build the table afresh. The gap stage's workflow test
(tests/workflow/test_gap_workflow.py) builds viscous's table, the observables' baseline and the model floor on the same
table and grid in its ``gap_tables`` rule, and holds them to these files (:func:`assert_stored`). Run this after
changing the effect library or how its tables are built:

    python tests/stored/make_effect_cache.py
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # the tests' helpers, when run as a script

STORED_EFFECT_CACHE = HERE / "effect-cache"
# the candidates the diagnosing tests name (--effects): tilt, speed_offset, viscous and speed_gain
TEST_EFFECTS = ("tilt", "speed_offset", "viscous", "speed_gain")


def tiny_table():
    """The tests' tiny table (conftest ``tiny_table``): the default scene on a 7 x 6 x 6 grid, with its 4-cell check."""
    import tempfile

    from conftest import build_tiny_table
    from imply.table import PushTable

    with tempfile.TemporaryDirectory() as folder:
        build_tiny_table(Path(folder) / "tiny.npz")
        return PushTable.load(Path(folder) / "tiny.npz")


def build(cache_dir: Path, *, effects=TEST_EFFECTS, table=None, nthread: int = 0) -> None:
    """The tables of ``effects`` against ``table`` (default: :func:`tiny_table`) on the tests' effect grid, simulated
    into ``cache_dir``, as a diagnosis with the default settings asks for them."""
    from imply.diagnose.analysis import DiagnosisConfig
    from imply.diagnose.physics import candidates
    from imply.diagnose.physics.effect_tables import CoarseGrid
    from imply.diagnose.run import effect_tables
    from sample_inputs import EFFECT_GRID_JSON

    effect_tables(
        tiny_table() if table is None else table,
        candidates.get(list(effects)),
        options=DiagnosisConfig(),
        grid=CoarseGrid.from_dict(json.loads(EFFECT_GRID_JSON)),
        cache_dir=cache_dir,
        nthread=nthread,
        progress=table is None,
    )


def assert_stored(built_dir: Path, names: list[str]) -> None:
    """Hold the effect-table files ``names`` in ``built_dir``, built afresh, to the stored files of the same names (the
    same names, so the same digests): the tests that read the stored cache read what the builder writes today."""
    for name in names:
        stored = STORED_EFFECT_CACHE / name
        assert stored.is_file(), f"{name} is not in {STORED_EFFECT_CACHE}: python tests/stored/make_effect_cache.py"
        if name.endswith(".json"):
            fresh, kept = json.loads((built_dir / name).read_text()), json.loads(stored.read_text())
            assert fresh.keys() == kept.keys()
            np.testing.assert_allclose(fresh["model_floor"]["rms"], kept["model_floor"]["rms"], rtol=1e-6)
            continue
        with np.load(built_dir / name) as fresh, np.load(stored) as kept:
            assert fresh.files == kept.files
            for key in fresh.files:
                if fresh[key].dtype.kind == "f":
                    np.testing.assert_allclose(fresh[key], kept[key], rtol=0, atol=1e-9, err_msg=f"{name}: {key}")
                else:
                    assert_same_json(json.loads(str(fresh[key])), json.loads(str(kept[key])), f"{name}: {key}")


def assert_same_json(fresh, kept, where: str) -> None:
    """``fresh`` and ``kept`` (parsed JSON) alike: the same keys, lists and strings, numbers to 1e-9 relative. The
    tables' accuracy figures (interpolation errors' root mean squares) differ in their last digits with the CPU's
    vector width (seen: 1e-12 apart between AVX2 and AVX-512 machines)."""
    if isinstance(kept, dict):
        assert isinstance(fresh, dict) and fresh.keys() == kept.keys(), (
            f"{where}: keys {sorted(fresh)} != {sorted(kept)}"
        )
        for key in kept:
            assert_same_json(fresh[key], kept[key], f"{where}.{key}")
    elif isinstance(kept, list):
        assert isinstance(fresh, list) and len(fresh) == len(kept), f"{where}: {fresh!r} != {kept!r}"
        for i, (a, b) in enumerate(zip(fresh, kept, strict=True)):
            assert_same_json(a, b, f"{where}[{i}]")
    elif isinstance(kept, float):
        assert isinstance(fresh, int | float), f"{where}: {fresh!r} != {kept!r}"
        np.testing.assert_allclose(fresh, kept, rtol=1e-9, atol=0, err_msg=where)
    else:
        assert fresh == kept, f"{where}: {fresh!r} != {kept!r}"


def main() -> None:
    shutil.rmtree(STORED_EFFECT_CACHE, ignore_errors=True)
    STORED_EFFECT_CACHE.mkdir()
    build(STORED_EFFECT_CACHE)
    print(f"wrote {', '.join(sorted(p.name for p in STORED_EFFECT_CACHE.iterdir()))} in {STORED_EFFECT_CACHE}")


if __name__ == "__main__":
    main()
