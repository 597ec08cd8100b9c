"""Write ``effect-cache/``: the effect tables every diagnosing test reads, on the tiny table and the tests' coarse grid.

The tests copy these files into their run's effect-table cache (conftest ``effect_cache``) instead of simulating them
(a CPU-minute). A file's name carries the digest of what it was built from (scene, grids, levels, MuJoCo's version,
the tiny table's own digest), so a change there makes the tests build the table afresh, and tests/diagnose/
test_stored_effect_cache.py rebuilds one of them to hold the files to the builder. Run this after changing the effect
library or how its tables are built:

    python tests/stored/make_effect_cache.py
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

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


def main() -> None:
    shutil.rmtree(STORED_EFFECT_CACHE, ignore_errors=True)
    STORED_EFFECT_CACHE.mkdir()
    build(STORED_EFFECT_CACHE)
    print(f"wrote {', '.join(sorted(p.name for p in STORED_EFFECT_CACHE.iterdir()))} in {STORED_EFFECT_CACHE}")


if __name__ == "__main__":
    main()
