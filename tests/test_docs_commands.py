"""Every ``robocal`` command in README.md and docs/cli.md runs as written, on the files that ship,
in the order the documents give them (later commands use earlier outputs)."""

from __future__ import annotations

import os
import re
import shlex
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def commands(path: Path, prompt: str) -> list[str]:
    """The commands of ``path``: lines starting with ``prompt`` + "robocal ", with their
    backslash-continued lines."""
    out, current = [], None
    for line in path.read_text().splitlines():
        if current is not None:
            current += " " + line.strip().rstrip("\\").strip()
            if not line.rstrip().endswith("\\"):
                out.append(current)
                current = None
            continue
        if line.startswith(prompt + "robocal "):
            text = line[len(prompt):].rstrip()
            if text.endswith("\\"):
                current = text.rstrip("\\").strip()
            else:
                out.append(text)
    return out


README = commands(ROOT / "README.md", "    ")
CLI_MD = commands(ROOT / "docs" / "cli.md", "$ ")


def test_the_documents_have_their_commands():
    names = {c.split()[1] for c in README + CLI_MD}
    assert {"plan", "calibrate", "compensate", "export", "import-dh", "import-urdf", "report"} <= names
    assert {"urdf", "mdh-csv", "dh-csv"} <= {c.split("--format ")[1].split()[0] for c in README if "--format" in c}


@pytest.mark.parametrize("document", ["README", "cli.md"])
def test_every_documented_command_runs_as_written(document, tmp_path, monkeypatch, cli):
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    monkeypatch.chdir(tmp_path)
    for command in README if document == "README" else CLI_MD:
        code, out, err = cli(*shlex.split(command)[1:])
        assert code == 0, f"{command}\n{err}"

