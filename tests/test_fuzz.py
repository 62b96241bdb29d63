"""A fixed-seed sample of the fuzz cases (tests/fuzz_cases.py), every command, run in-process through
the CLI entry by two forked workers: every run ends in one clear error line or a sound result (finite,
read back, reproducing its source), never a traceback or a hang. The large run with time and memory
limits is benchmarks/fuzz_cli.py (benchmarks/README.md)."""

import contextlib
import io
import multiprocessing
import os
import signal
import tempfile
from pathlib import Path

import fuzz_cases
import pytest
from hypothesis import HealthCheck, Phase, given, seed, settings

from robocal.cli import main

# cases of the sample, split over this many forked workers (each its own seed), and the CPU time one
# case may take before it counts as a hang (CPU, not wall-clock time: the machine may be shared)
SAMPLE = 2000
WORKERS = 2
HANG_SECONDS = 20


@pytest.fixture(scope="module")
def result_text(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    (d / "m.yaml").write_text(fuzz_cases.MODEL)
    (d / "d.csv").write_text(fuzz_cases.MEASUREMENTS)
    assert main(["calibrate", str(d / "m.yaml"), str(d / "d.csv"), "--out", str(d / "o")]) in (0, 3)
    return fuzz_cases.inline_result(d / "o" / "result.json")


def run_case(files: dict, argv: list) -> tuple[str, str]:
    """Run one case in a fresh folder; its outcome (fuzz_cases.judge) and its stderr."""
    here = os.getcwd()
    with tempfile.TemporaryDirectory() as folder:
        for name, data in files.items():
            Path(folder, name).parent.mkdir(parents=True, exist_ok=True)
            Path(folder, name).write_bytes(data)
        err = io.StringIO()
        try:
            os.chdir(folder)
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
                code = main(argv)
        finally:
            os.chdir(here)
        return fuzz_cases.judge(code, err.getvalue(), Path(folder), set(files), argv), err.getvalue()


class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang


def _share(job) -> list:
    """In a worker: ``n`` cases drawn with seed ``k``; the bad ones as (outcome, argv, stderr)."""
    k, n, text = job
    bad = []
    signal.signal(signal.SIGPROF, _alarm)

    @seed(k)
    @settings(max_examples=n, deadline=None, database=None, phases=[Phase.generate],
              suppress_health_check=list(HealthCheck))
    @given(fuzz_cases.case(text, weights=fuzz_cases.SAMPLE_WEIGHTS))
    def each(c):
        files, argv = c
        signal.setitimer(signal.ITIMER_PROF, HANG_SECONDS)
        try:
            outcome, err = run_case(files, argv)
        except _Hang:
            outcome, err = "hang", ""
        finally:
            signal.setitimer(signal.ITIMER_PROF, 0)
        if outcome not in ("clean error", "ok result"):
            bad.append((outcome, argv[:12], err[-1500:]))

    each()
    return bad


def test_fuzz_sample(result_text, monkeypatch):
    pytest.importorskip("matplotlib")
    import robocal._files.measurements as measurements

    monkeypatch.setattr(measurements, "FAST_BYTES", measurements.FAST_BYTES)  # restored after the test
    fuzz_cases.every_reader()                                                 # the workers inherit it
    jobs = [(k, SAMPLE // WORKERS, result_text) for k in range(WORKERS)]
    with multiprocessing.get_context("fork").Pool(WORKERS) as pool:
        bad = [b for share in pool.map(_share, jobs) for b in share]
    assert not bad, bad[:3]
