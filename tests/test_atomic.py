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
