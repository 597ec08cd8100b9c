"""Write ``default_table.npz``: the default 19 x 25 x 21 table as ``imply.table.build_table`` gives it.

The tests read the default table from this file instead of building it (four CPU-minutes); the file is checked
against the current scene and grid on every run (its config digest) and, cell by cell on a sample, against the
builder itself (tests/test_table.py). Run this after changing the default scene, stepping or table grid:

    python tests/stored/make_default_table.py
"""

from __future__ import annotations

from pathlib import Path

import yaml

from imply.sim import SceneConfig
from imply.table import TableGrid, build_table

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
STORED_TABLE = HERE / "default_table.npz"


def default_scene_and_grid() -> tuple[SceneConfig, TableGrid]:
    """The scene and table grid of the repository's config.yaml."""
    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    return SceneConfig.from_dict(config["scene"]), TableGrid.from_dict(config["table"])


def main() -> None:
    scene, grid = default_scene_and_grid()
    build_table(scene, grid, nthread=0, progress=True).save(STORED_TABLE)
    print(f"wrote {STORED_TABLE}")


if __name__ == "__main__":
    main()
