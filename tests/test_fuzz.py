"""A bounded sample of the fuzz cases (tests/fuzz_cases.py), run in-process through the CLI entry:
every run ends in one clear error line or a result without non-finite numbers, never a traceback.
The large run with time and memory limits is benchmarks/fuzz_cli.py (benchmarks/README.md)."""

import contextlib
import io
import os
import tempfile
from pathlib import Path

import fuzz_cases
import pytest
from hypothesis import HealthCheck, given, settings

from robocal.cli import main


@pytest.fixture(scope="module")
def result_text(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    (d / "m.yaml").write_text(fuzz_cases.MODEL)
    (d / "d.csv").write_text(fuzz_cases.MEASUREMENTS)
    assert main(["calibrate", str(d / "m.yaml"), str(d / "d.csv"), "--out", str(d / "o")]) in (0, 3)
    return fuzz_cases.inline_result(d / "o" / "result.json")


def run_case(files: dict, argv: list) -> str:
    """Run one case in a fresh folder; its outcome (fuzz_cases.judge)."""
    here = os.getcwd()
    with tempfile.TemporaryDirectory() as folder:
        for name, data in files.items():
            Path(folder, name).write_bytes(data)
        err = io.StringIO()
        try:
            os.chdir(folder)
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
                code = main(argv)
        finally:
            os.chdir(here)
        return fuzz_cases.judge(code, err.getvalue(), Path(folder), set(files)), err.getvalue()


def test_fuzz_sample(result_text, monkeypatch):
    pytest.importorskip("matplotlib")
    import robocal._files.measurements as measurements

    monkeypatch.setattr(measurements, "FAST_BYTES", measurements.FAST_BYTES)  # restored after the test
    fuzz_cases.every_reader()

    @settings(max_examples=60, derandomize=True, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(fuzz_cases.case(result_text))
    def each(c):
        files, argv = c
        outcome, err = run_case(files, argv)
        assert outcome in ("clean error", "ok result"), (outcome, argv, err[-2000:])

    each()
