"""Report folders: written whole or not at all, and never at the cost of files already there; byte-stable npz files."""

from __future__ import annotations

import json
import os
import stat
import sys

import numpy as np
import pandas as pd
import pytest

from imply import io
from imply.io import (
    MANIFEST,
    OutputError,
    atomic_path,
    check_folder,
    read_manifest,
    write_columns,
    write_csv,
    write_folder,
    write_npz,
)

NAMES = ("summary.json", "report.md")


def _writer(text: str):
    def write(folder):
        for name in NAMES:
            (folder / name).write_text(f"{name} {text}")

    return write


def test_new_folder_gets_the_files_and_a_manifest(tmp_path):
    out = tmp_path / "report"
    check_folder(out, NAMES, force=False)
    assert write_folder(out, _writer("one")) == sorted(NAMES)
    assert sorted(p.name for p in out.iterdir()) == sorted([*NAMES, MANIFEST])
    assert read_manifest(out) == set(NAMES)
    assert [p.name for p in tmp_path.iterdir()] == ["report"]  # no temporary folder left


def test_non_empty_folder_needs_force_and_keeps_what_it_did_not_write(tmp_path):
    out = tmp_path / "report"
    write_folder(out, _writer("one"))
    (out / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="is not empty"):
        check_folder(out, NAMES, force=False)
    check_folder(out, NAMES, force=True)
    write_folder(out, _writer("two"), force=True)
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "summary.json").read_text() == "summary.json two"


def test_force_removes_only_stale_files_of_its_own_manifest(tmp_path):
    out = tmp_path / "report"
    out.mkdir()
    (out / "old_plot.png").write_text("ours")
    (out / "notes.txt").write_text("mine")
    (out / MANIFEST).write_text(json.dumps({"files": ["old_plot.png", "../../escape", "/etc/passwd"]}))
    write_folder(out, _writer("x"), force=True)
    assert not (out / "old_plot.png").exists()
    assert (out / "notes.txt").read_text() == "mine"
    assert read_manifest(out) == set(NAMES)


def test_force_refuses_to_replace_a_file_it_did_not_write(tmp_path):
    out = tmp_path / "report"
    out.mkdir()
    (out / "summary.json").write_text("a file of the user's")
    with pytest.raises(OutputError, match="was not written by a previous report"):
        check_folder(out, NAMES, force=True)


def test_a_failing_writer_leaves_nothing(tmp_path):
    out = tmp_path / "report"

    def broken(folder):
        (folder / "summary.json").write_text("half")
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        write_folder(out, broken)
    assert list(tmp_path.iterdir()) == []


def _interrupted_at_line(k: int, codes: set, run) -> bool:
    """Run ``run(started)``, raising KeyboardInterrupt at the ``k``-th line that the functions of ``codes`` reach before
    ``started()`` is called (where a Ctrl-C would land between statements). Returns whether it was raised there."""
    reached, started, raised = 0, False, False

    def local(frame, event, arg):
        nonlocal reached, raised
        if event == "line" and not started:
            if reached == k:
                reached += 1
                raised = True
                raise KeyboardInterrupt
            reached += 1
        return local

    def start():
        nonlocal started
        started = True

    previous = sys.gettrace()
    sys.settrace(lambda frame, event, arg: local if frame.f_code in codes else None)
    try:
        run(start)
    except KeyboardInterrupt:
        assert raised, "a KeyboardInterrupt that the test did not raise"
    finally:
        sys.settrace(previous)
    return raised


@pytest.mark.parametrize("writer", ["atomic_path", "write_folder"])
def test_a_ctrl_c_between_any_two_statements_before_the_writer_starts_leaves_nothing(tmp_path, writer):
    """Seen: an interrupted training left an empty ``.checkpoint.XXXX.pt`` beside its checkpoint, the Ctrl-C having come
    between the temporary file's creation and the cleanup's knowing its name."""
    codes = {io._make_sibling.__code__, io._remove.__code__, io.write_folder.__code__}
    codes.add(atomic_path.__wrapped__.__code__)
    out = tmp_path / "out" / ("model.pt" if writer == "atomic_path" else "report")
    out.parent.mkdir()

    def run(start):
        if writer == "atomic_path":
            with atomic_path(out) as tmp:
                start()
                tmp.write_text("whole")
        else:
            write_folder(out, lambda folder: (start(), (folder / "summary.json").write_text("whole")))

    k = 0
    while _interrupted_at_line(k, codes, run):
        assert sorted(p.name for p in out.parent.iterdir()) == [], f"left behind, interrupted at line {k}"
        k += 1
    assert k >= 5  # the lines before the writer starts, each interrupted once
    # not interrupted: the output, with the usual permissions
    written = out if writer == "atomic_path" else out / "summary.json"
    assert written.read_text() == "whole"
    assert [p.name for p in out.parent.iterdir()] == [out.name]
    umask = _umask()
    assert stat.S_IMODE(written.stat().st_mode) == 0o666 & ~umask
    if writer == "write_folder":
        assert stat.S_IMODE(out.stat().st_mode) == 0o777 & ~umask


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask


def test_write_columns_writes_what_write_csv_writes(tmp_path):
    cols = {
        "object_id": ["a", "b,c", 'q"x'],
        "n": np.array([3, 2, 5]),
        "x": np.array([0.1, np.nan, 1e-20]),
        "y": np.array([1 / 3, 2.0, -5.5]),
    }
    write_csv(tmp_path / "pandas.csv", pd.DataFrame(cols))
    write_columns(tmp_path / "plain.csv", cols)
    assert (tmp_path / "pandas.csv").read_bytes() == (tmp_path / "plain.csv").read_bytes()


@pytest.mark.parametrize("compressed", [False, True])
def test_npz_bytes_depend_on_the_arrays_not_the_clock(tmp_path, monkeypatch, compressed):
    import time
    import zipfile

    arrays = {"tokens": np.arange(12.0).reshape(3, 4), "name": np.asarray("enc"), "grid": np.asarray([1, 4])}
    write_npz(tmp_path / "a.npz", compressed=compressed, **arrays)
    later = time.time() + 400 * 86400
    monkeypatch.setattr(time, "time", lambda: later)
    write_npz(tmp_path / "b", compressed=compressed, **arrays)  # no .npz appended
    assert (tmp_path / "a.npz").read_bytes() == (tmp_path / "b").read_bytes()
    with zipfile.ZipFile(tmp_path / "b") as zf:
        assert [i.filename for i in zf.infolist()] == ["tokens.npy", "name.npy", "grid.npy"]
        assert {i.compress_type for i in zf.infolist()} == {zipfile.ZIP_DEFLATED if compressed else zipfile.ZIP_STORED}
    with np.load(tmp_path / "b") as z:
        assert np.array_equal(z["tokens"], arrays["tokens"]) and str(z["name"]) == "enc"
