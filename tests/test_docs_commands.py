"""Every ``robocal`` command in README.md and docs/cli.md runs as written, on the files that ship,
in the order the documents give them (later commands use earlier outputs)."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
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


def console_outputs(path: Path) -> dict[str, list[str]]:
    """The output shown under each ``$ robocal`` command of a console block of ``path``, by command."""
    out: dict[str, list[str]] = {}
    current = None
    for line in path.read_text().splitlines():
        if line.startswith("$ robocal "):
            current = line[2:].rstrip().rstrip("\\").strip()
            out[current] = []
        elif line.startswith("```"):
            current = None
        elif current is not None and not line.startswith("      "):  # not a continuation line
            out[current].append(line)
    return out


README = commands(ROOT / "README.md", "    ")
CLI_MD = commands(ROOT / "docs" / "cli.md", "$ ")


def test_the_documents_have_their_commands():
    names = {c.split()[1] for c in README + CLI_MD}
    assert {"plan", "calibrate", "compensate", "export", "import-dh", "import-urdf", "report"} <= names
    assert {"urdf", "mdh-csv", "dh-csv"} <= {c.split("--format ")[1].split()[0] for c in README if "--format" in c}


def _rounded_off(line: str) -> str:
    """``line`` with figures below 1e-10 (round-off, which differs between machines) as one mark."""
    return re.sub(r"\d+(?:\.\d+)?e-(?:1\d|[2-9]\d)\b", "(round-off)", line.rstrip())


@pytest.fixture(scope="module")
def after_demo(tmp_path_factory):
    """A folder as `make demo` leaves it: the examples, and runs/th8 written by the demo."""
    import importlib.util

    folder = tmp_path_factory.mktemp("clone")
    (folder / "examples").symlink_to(ROOT / "examples")
    spec = importlib.util.spec_from_file_location("th8_reproduce", ROOT / "examples" / "th8" / "reproduce.py")
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    assert demo.main(["--out", str(folder / "runs" / "th8")]) == 0
    return folder


@pytest.mark.parametrize("document", ["README", "cli.md"])
def test_every_documented_command_runs_as_written(document, after_demo, tmp_path, monkeypatch, cli, capsys):
    capsys.readouterr()
    shutil.copytree(after_demo, tmp_path / "clone", symlinks=True)
    monkeypatch.chdir(tmp_path / "clone")
    shown = console_outputs(ROOT / "docs" / "cli.md") if document == "cli.md" else {}
    for command in README if document == "README" else CLI_MD:
        code, out, err = cli(*shlex.split(command)[1:])
        assert code == 0, f"{command}\n{err}"
        lines = shown.get(command, [])
        if lines and not lines[0].startswith("# ("):  # not marked illustrative: the output as printed
            printed = [_rounded_off(line) for line in (out + err).splitlines()]
            for line in lines:
                if not line.strip().startswith("..."):
                    assert _rounded_off(line) in printed, f"{command}: shown but not printed: {line!r}"


def test_make_demo_installs_what_the_demo_needs_and_make_test_the_tests():
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    env = dict(os.environ, MAKEFLAGS="")

    def dry(target):
        run = subprocess.run(["make", "-n", "-B", target], cwd=ROOT, capture_output=True, text=True, env=env)
        assert run.returncode == 0, run.stderr
        return [line for line in run.stdout.splitlines() if "pip install" in line and " -e " in line]

    demo, test = dry("demo"), dry("test")
    assert len(demo) == 1 and '".[report]"' in demo[0] and "test" not in demo[0]
    assert len(test) == 1 and '".[test,report]"' in test[0]

