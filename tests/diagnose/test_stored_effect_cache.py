"""tests/stored/effect-cache, which the diagnosing tests start from, against the builder."""

from __future__ import annotations

import json

import numpy as np

from stored.make_effect_cache import STORED_EFFECT_CACHE, build


def test_the_stored_effect_tables_are_what_the_builder_gives(tiny_table, tmp_path):
    """viscous's table, the observables' baseline and the model floor built afresh (the same names, so the same
    digests) hold the stored files' numbers: the tests that read the stored cache read what the builder writes
    today."""
    build(tmp_path, effects=("viscous",), table=tiny_table, nthread=1)
    built = sorted(p.name for p in tmp_path.iterdir())
    assert [name.split("-")[0] for name in built] == ["effects", "floor", "observables"], built
    for name in built:
        stored = STORED_EFFECT_CACHE / name
        assert stored.is_file(), f"{name} is not in {STORED_EFFECT_CACHE}: python tests/stored/make_effect_cache.py"
        if name.endswith(".json"):
            fresh, kept = json.loads((tmp_path / name).read_text()), json.loads(stored.read_text())
            assert fresh.keys() == kept.keys()
            np.testing.assert_allclose(fresh["model_floor"]["rms"], kept["model_floor"]["rms"], rtol=1e-6)
            continue
        with np.load(tmp_path / name) as fresh, np.load(stored) as kept:
            assert fresh.files == kept.files
            for key in fresh.files:
                if fresh[key].dtype.kind == "f":
                    np.testing.assert_allclose(fresh[key], kept[key], rtol=0, atol=1e-9, err_msg=f"{name}: {key}")
                else:
                    assert json.loads(str(fresh[key])) == json.loads(str(kept[key])), f"{name}: {key}"
