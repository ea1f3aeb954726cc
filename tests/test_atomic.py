"""atomic_path: a target is replaced whole or not at all."""

from __future__ import annotations

import pytest

from automodal.io.atomic import atomic_path


def test_temporary_path_is_hidden_beside_the_target_and_keeps_the_suffix(tmp_path):
    target = tmp_path / "report.json"
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path
        assert tmp.name.startswith(".report.json.")
        assert tmp.suffix == ".json"
        assert not tmp.exists()
        tmp.write_text("{}")
    assert target.read_text() == "{}"
    assert [p.name for p in tmp_path.iterdir()] == ["report.json"]


def test_existing_target_is_replaced(tmp_path):
    target = tmp_path / "a.txt"
    target.write_text("old")
    with atomic_path(str(target)) as tmp:
        tmp.write_text("new")
    assert target.read_text() == "new"


def test_failure_keeps_the_old_target_and_removes_the_temporary(tmp_path):
    target = tmp_path / "a.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError, match="half way"), atomic_path(target) as tmp:
        tmp.write_text("partial")
        raise RuntimeError("half way")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_failure_without_old_target_leaves_nothing(tmp_path):
    target = tmp_path / "a.txt"
    with pytest.raises(KeyboardInterrupt), atomic_path(target) as tmp:
        tmp.write_text("partial")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_block_that_writes_nothing_fails_without_creating_the_target(tmp_path):
    target = tmp_path / "a.txt"
    with pytest.raises(FileNotFoundError), atomic_path(target):
        pass
    assert list(tmp_path.iterdir()) == []


def test_hdf5_in_memory_writes_the_whole_file_on_success_only(tmp_path):
    import h5py
    import numpy as np

    from automodal.io.atomic import hdf5_in_memory

    target = tmp_path / "r.h5"
    with hdf5_in_memory(target) as f:
        f["x"] = np.arange(5.0)
        assert not target.exists()
    with h5py.File(target, "r") as f:
        np.testing.assert_array_equal(f["x"][()], np.arange(5.0))
    with pytest.raises(RuntimeError), hdf5_in_memory(target) as f:
        f["y"] = 1.0
        raise RuntimeError("stop")
    with h5py.File(target, "r") as f:
        assert list(f) == ["x"]
    assert [p.name for p in tmp_path.iterdir()] == ["r.h5"]


def _full_disk(monkeypatch, free: int = 1000):
    import shutil
    from collections import namedtuple

    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda _: usage(10**9, 10**9 - free, free))


def test_a_full_disk_refuses_an_frf_file_in_one_line(tmp_path, monkeypatch):
    """HDF5 crashed (segmentation fault) when the disk filled under it: a large file is
    written only where the disk has room for its data."""
    from pathlib import Path

    from click.testing import CliRunner

    from automodal.cli import main

    sample = Path(__file__).resolve().parents[1] / "sample_data" / "chain6.h5"
    _full_disk(monkeypatch)
    out = tmp_path / "copy.h5"
    result = CliRunner().invoke(main, ["convert", str(sample), str(out)])
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "cannot write" in lines[0] and "No space left" in lines[0]
    assert not list(tmp_path.iterdir())


def test_a_failed_write_of_a_report_image_is_one_line(tmp_path, monkeypatch):
    """A report is built in memory; the write of its image that the disk refuses is an
    exit 2 with one line, and no file is left."""
    import errno
    from pathlib import Path

    from click.testing import CliRunner

    from automodal.cli import main

    def refuse(self, data):
        raise OSError(errno.ENOSPC, "No space left on device", str(self))

    sample = Path(__file__).resolve().parents[1] / "sample_data" / "chain6.h5"
    monkeypatch.setattr(Path, "write_bytes", refuse)
    out = tmp_path / "r.h5"
    result = CliRunner().invoke(main, ["identify", str(sample), "-o", str(out), "--quiet",
                                       "--bootstrap", "20"])
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "No space left" in lines[0], result.stderr
    assert not list(tmp_path.iterdir())
