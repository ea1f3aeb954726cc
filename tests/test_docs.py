"""Issue 15 (item 10): the documents the README, the docs and every command's --help point
to are in the repository, and the README covers the inputs a new user brings."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from automodal.cli import main

ROOT = Path(__file__).resolve().parents[1]
COMMANDS = sorted(main.commands)
_PATH = re.compile(r"(?<![\w/.-])((?:docs|automodal|tests|benchmarks|sample_data)/[\w./-]*\w)")


def referenced_paths(text: str) -> set[str]:
    """Repository paths named in ``text`` (``docs/cli.md``, ``automodal/io/uff.py`` ...)."""
    return {m.rstrip(".") for m in _PATH.findall(text) if "*" not in m}


def help_text(command: str | None) -> str:
    args = ([command] if command else []) + ["--help"]
    done = CliRunner().invoke(main, args)
    assert done.exit_code == 0, done.output
    return done.output


@pytest.mark.parametrize("source", ["README.md", *sorted(
    str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))])
def test_every_path_a_document_names_exists(source):
    missing = sorted(p for p in referenced_paths((ROOT / source).read_text(encoding="utf-8"))
                     if not (ROOT / p).exists())
    assert not missing, f"{source} names missing files: {missing}"


@pytest.mark.parametrize("command", [None, *COMMANDS])
def test_every_path_the_help_names_exists(command):
    text = " ".join(help_text(command).split())
    missing = sorted(p for p in referenced_paths(text) if not (ROOT / p).exists())
    assert not missing, f"--help of {command or 'automodal'} names missing files: {missing}"


def test_readme_covers_the_inputs_and_reads_any_file():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for word in ("automodal convert", "UFF", "CSV", "time records", "docs/frf-file.md",
                 "docs/time-input.md", "docs/cli.md", "--geometry"):
        assert word in readme, word
    python = re.search(r"```python\n(.*?)```", readme, re.S)
    assert python and "automodal.read(" in python.group(1)
    assert "read_frf" not in python.group(1)  # the HDF5-only reader
