"""User tables in CSV or parquet: required columns and numeric cells, errors naming row and column."""

from __future__ import annotations

import pandas as pd
import pytest

from imply.input_files import InputError, read_table


def test_parquet_and_csv_read_alike(tmp_path):
    frame = pd.DataFrame({"object_id": ["a", "b"], "speed": [0.3, 0.5], "displacement": [0.02, 0.04]})
    frame.to_parquet(tmp_path / "log.parquet")
    frame.to_csv(tmp_path / "log.csv", index=False)
    cols = ["object_id", "speed", "displacement"]
    from_parquet = read_table(tmp_path / "log.parquet", cols, ["speed", "displacement"])
    from_csv = read_table(tmp_path / "log.csv", cols, ["speed", "displacement"])
    pd.testing.assert_frame_equal(from_parquet, from_csv, check_dtype=False)


def test_parquet_bad_cell_is_named(tmp_path):
    frame = pd.DataFrame({"object_id": ["a", "b"], "speed": [0.3, float("nan")], "displacement": [0.02, 0.04]})
    frame.to_parquet(tmp_path / "log.parquet")
    with pytest.raises(InputError, match=r"row 2, column speed: nan is not") as info:
        read_table(tmp_path / "log.parquet", ["object_id", "speed"], ["speed"])
    assert "line" not in str(info.value)  # a parquet file has no lines


def test_optional_numeric_columns_are_checked_when_present(tmp_path):
    (tmp_path / "log.csv").write_text("object_id,speed,mass\na,0.3,heavy\n")
    with pytest.raises(InputError, match="column mass: 'heavy'"):
        read_table(tmp_path / "log.csv", ["object_id", "speed"], ["speed"], ["mass"])
    (tmp_path / "empty.csv").write_text("object_id,speed\n")
    with pytest.raises(InputError, match="no data rows"):
        read_table(tmp_path / "empty.csv", ["object_id", "speed"], ["speed"])
