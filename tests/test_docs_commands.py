"""Every ``robocal`` command of the documents (README.md, docs/*.md, examples/*/README.md) and of every
``--help`` runs as written, on the files that ship, in a scratch folder after ``make demo`` and in
the order each gives them (later commands use earlier outputs); no two of them write the same file.
README's demo block is what ``make demo`` prints."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import importlib.util
import io
import json
import os
import re
import shlex
import shutil
import subprocess
import warnings
from pathlib import Path

import pytest

import robocal as rc
from robocal.cli import build_parser

ROOT = Path(__file__).resolve().parent.parent


def commands(path: Path, prompts=("    ", "$ ")) -> list[str]:
    """The commands of ``path``: lines starting with one of ``prompts`` + "robocal ", with their
    backslash-continued lines, in the order they appear."""
    return continued(path.read_text().splitlines(), prompts)


def continued(lines, prompts) -> list[str]:
    """The ``robocal`` commands of ``lines`` (after a prompt), each with its continuation lines."""
    out, current = [], None
    for line in lines:
        if current is not None:
            current += " " + line.strip().rstrip("\\").strip()
            if not line.rstrip().endswith("\\"):
                out.append(current)
                current = None
            continue
        prompt = next((p for p in prompts if line.startswith(p + "robocal ")), None)
        if prompt is not None:
            text = line[len(prompt):].rstrip()
            if text.endswith("\\"):
                current = text.rstrip("\\").strip()
            else:
                out.append(text)
    return out


def parsers() -> dict[str, argparse.ArgumentParser]:
    """The parser of ``robocal`` and of each command, by name ("robocal" for the top level)."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {"robocal": parser, **sub.choices}


def help_examples() -> list[str]:
    """The example commands of ``robocal --help`` and of each command's ``--help``, in that order."""
    return [c for p in parsers().values() for c in continued((p.epilog or "").splitlines(), ("  ",))]


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


README = commands(ROOT / "README.md")
CLI_MD = commands(ROOT / "docs" / "cli.md")
# every document that shows a robocal command, and the help's examples: each run on its own
EXAMPLES = {str(p.relative_to(ROOT)): commands(p)
            for p in [ROOT / "README.md", *sorted(ROOT.glob("docs/*.md")), *sorted(ROOT.glob("examples/*/README.md"))]
            if commands(p)}
EXAMPLES["--help"] = help_examples()


def test_the_documents_have_their_commands():
    names = {c.split()[1] for c in README + CLI_MD}
    assert {"plan", "calibrate", "compensate", "export", "import-dh", "import-urdf", "report"} <= names
    assert {"urdf", "mdh-csv", "dh-csv"} <= {c.split("--format ")[1].split()[0] for c in README if "--format" in c}


def _rounded_off(line: str) -> str:
    """``line`` with figures below 1e-10 (round-off, which differs between machines) as one mark."""
    return re.sub(r"\d+(?:\.\d+)?e-(?:1\d|[2-9]\d)\b", "(round-off)", line.rstrip())


@pytest.fixture(scope="module")
def after_demo(tmp_path_factory):
    """A folder as `make demo` leaves it (the examples, and runs/th8 written by the demo), and what
    the demo printed."""
    folder = tmp_path_factory.mktemp("clone")
    (folder / "examples").symlink_to(ROOT / "examples")
    spec = importlib.util.spec_from_file_location("th8_reproduce", ROOT / "examples" / "th8" / "reproduce.py")
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert demo.main(["--out", str(folder / "runs" / "th8")]) == 0
    return folder, printed.getvalue()


@pytest.mark.parametrize("document", list(EXAMPLES))
def test_every_example_runs_as_written(document, after_demo, tmp_path, monkeypatch, cli, capsys):
    # in a scratch folder as `make demo` leaves a clone, with a store of its own (the default one)
    capsys.readouterr()
    shutil.copytree(after_demo[0], tmp_path / "clone", symlinks=True)
    monkeypatch.chdir(tmp_path / "clone")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("ROBOCAL_STORE", str(tmp_path / "home" / "store.sqlite"))
    shown = console_outputs(ROOT / document) if document.endswith(".md") else {}
    not_run = []
    for command in EXAMPLES[document]:
        if command.split()[1] == "import-bag" and importlib.util.find_spec("rosbags") is None:
            not_run.append(command)                   # no later example reads what it writes
            continue
        code, out, err = cli(*shlex.split(command)[1:])
        assert code == 0, f"{document}: {command}\n{err}"
        lines = shown.get(command, [])
        if lines and not lines[0].startswith("# ("):  # not marked illustrative: the output as printed
            printed = [_rounded_off(line) for line in (out + err).splitlines()]
            for line in lines:
                if not line.strip().startswith("..."):
                    assert _rounded_off(line) in printed, f"{command}: shown but not printed: {line!r}"
    if not_run:
        pytest.skip(f"{len(not_run)} import-bag example(s) not run: the ros extra is not installed")


OUTPUTS = ("out", "true_model", "report", "store")


def _outputs(command: str) -> set[Path]:
    """The files and folders ``command`` writes, as its options name them."""
    args = build_parser().parse_args(shlex.split(command)[1:])
    return {Path(v) for dest in OUTPUTS if isinstance(v := getattr(args, dest, None), str)}


def test_no_two_examples_write_the_same_file_and_none_the_demos(after_demo, monkeypatch):
    # a newcomer runs README's commands, then docs/cli.md's, then a command's --help example: none
    # refuses to overwrite another's output, and none touches what `make demo` wrote
    monkeypatch.chdir(after_demo[0])  # where the options' files are read as they are parsed
    def clash(a: Path, b: Path) -> bool:
        return a == b or a in b.parents or b in a.parents

    found = []
    written = {document: [(c, o) for c in cs for o in _outputs(c)] for document, cs in EXAMPLES.items()}
    for document, outs in written.items():
        found += [f"{document}: {c} writes into the demo's runs/th8" for c, o in outs if clash(o, Path("runs/th8"))]
        for other, theirs in written.items():
            if other > document:
                found += [f"{document}: {c} and {other}: {d} both write {o} / {p}" for c, o in outs for d, p in theirs
                          if clash(o, p)]
    assert found == [], "\n".join(found)


def test_the_readme_shows_what_make_demo_prints(after_demo):
    # README's block of the demo's output, line by line in the order printed ("..." skips lines)
    text = (ROOT / "README.md").read_text()
    block = text.split("Its output (shortened):", 1)[1].split("```text\n", 1)[1].split("```", 1)[0]
    printed = [line.rstrip() for line in after_demo[1].splitlines()]
    at = 0
    for line in block.splitlines():
        if line.strip() in ("", "..."):
            continue
        # a line cut short at "(...)" is the start of the printed one
        head = line.rstrip().removesuffix("(...)")
        found = [i for i, p in enumerate(printed[at:], at) if p == line.rstrip() or head != line.rstrip()
                 and p.startswith(head)]
        assert found, f"README shows, the demo does not print (after line {at}): {line!r}"
        at = found[0] + 1


def test_every_document_named_exists():
    # a reader sent to "METHOD.md section 5" finds nothing: every .md a document or a --help names
    # is a file of the repository (from its root or beside the document), and every "section N" of
    # docs/method.md it cites is one of its numbered sections
    written = {"summary.md"}                            # what the demo writes, not a document
    texts = {str(p.relative_to(ROOT)): p.read_text() for p in
             [ROOT / "README.md", *ROOT.glob("docs/*.md"), *ROOT.glob("examples/*/README.md"),
              *ROOT.glob("benchmarks/*.md")]}
    texts.update({f"{n} --help": p.format_help() for n, p in parsers().items()})
    sections = set(re.findall(r"^## (\d+)\. ", (ROOT / "docs" / "method.md").read_text(), re.M))
    missing = []
    for where, text in texts.items():
        here = (ROOT / where).parent if where.endswith(".md") else ROOT
        text = " ".join(text.split())
        for name in set(re.findall(r"[\w./-]+\.md\b", text)) - written:
            if not (ROOT / name).is_file() and not (here / name).is_file():
                missing.append(f"{where}: {name}")
        for n in re.findall(r"method\.md,? sections? (\d+)", text):
            if n not in sections:
                missing.append(f"{where}: docs/method.md section {n}")
    assert missing == [], missing


def test_the_checks_doc_says_where_each_threshold_it_names_is_defined():
    # "every threshold is in checks.py, holdout.py or identifiability.py" while CARRIED_ALONE was in
    # solve.py: each constant docs/checks.md names is defined in a file its statement names
    doc = (ROOT / "docs" / "checks.md").read_text()
    statement = " ".join(doc.split("Every threshold below", 1)[1].split("\n\n", 1)[0].split())
    defined = {}
    for path in (ROOT / "src" / "robocal").rglob("*.py"):
        for name in re.findall(r"^([A-Z][A-Z0-9_]+)(?:: [^=\n]+)? = ", path.read_text(), re.M):
            defined.setdefault(name, []).append(path)
    named = {n for n in re.findall(r"`([A-Z][A-Z0-9_]{2,})`", doc) if n in defined}
    assert len(named) >= 20
    unsaid = [f"{n}: {', '.join(p.name for p in defined[n])}" for n in sorted(named)
              if not any(p.name in statement for p in defined[n])]
    assert unsaid == [], unsaid


def test_the_result_file_doc_names_every_column_of_the_identifiability_table(after_demo):
    # docs/formats.md listed the geometric and compliance columns only; the demo's result holds
    # backlash and transmission ones too
    rows = json.loads((after_demo[0] / "runs" / "th8" / "result.json").read_text())["identifiability_table"]
    doc = next(line for line in (ROOT / "docs" / "formats.md").read_text().splitlines()
               if line.startswith("| `identifiability_table` |"))
    assert re.findall(r"`(\w+)`", doc.split("docs/conventions.md:", 1)[1]) == [k for k in rows[0] if k != "frame"]
    assert "`frame`" in doc and {r["frame"] for r in rows} == {"j1", "j2", "j3", "j4", "j5", "j6"}


def test_the_bag_reader_doc_names_where_its_campaign_keeps_each_part():
    # "returns a BagCampaign: the Measurements, the model, ..." left the reader to guess `.data`
    doc = " ".join((ROOT / "docs" / "formats.md").read_text().split())
    said = doc.split("`robocal.io.read_bag(", 1)[1].split("## ", 1)[0]
    assert [f"`.{f.name}`" for f in dataclasses.fields(rc.io.BagCampaign) if f"`.{f.name}`" not in said] == []
    assert [f"`{f.name}`" for f in dataclasses.fields(rc.io.Left) if f"`{f.name}`" not in said] == []


def test_folds_are_described_as_the_cross_validation_makes_them():
    # calibrate --help said "consecutive blocks of poses, or the file's series": a campaign of random
    # poses is cross-validated on folds drawn at random, which the help and docs/cli.md must say
    model = rc.read_model(ROOT / "examples" / "th8" / "model.yaml")
    _, data = rc.simulate(model, 40, seed=1, noise=2e-5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        grouping = rc.calibrate(model, data, known=("markers",)).in_use.grouping
    assert grouping == "5 folds drawn at random"
    shown = " ".join(parsers()["calibrate"].format_help().split("\n  --folds K", 1)[1].split("\n  --")[0].split())
    row = next(line for line in (ROOT / "docs" / "cli.md").read_text().splitlines() if line.startswith("| `--folds"))
    for said in (shown, row):
        assert "drawn at random" in said and "series" in said and "consecutive poses" in said, said


def test_the_readme_says_when_the_postgresql_tests_are_skipped():
    store_tests = (ROOT / "tests" / "test_store.py").read_text()
    readme = (ROOT / "README.md").read_text()
    variable = re.search(r'PG_ENV = "(\w+)"', store_tests).group(1)
    default = re.search(r'PG_DEFAULT = "([^"]+)"', store_tests).group(1)
    assert f"`{variable}`" in readme and default in readme
    assert re.search(r"Without a server the PostgreSQL half .* is skipped", " ".join(readme.split()))


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

