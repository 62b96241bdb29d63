"""A fixed-seed sample of the fuzz cases (tests/fuzz_cases.py), every command: 2,000 run in-process
through the CLI entry by two forked workers, each case under a CPU-time and a memory guard, and a
share of 100 run in forked children under the operating system's limits (the commands that ask for
the most work, where hangs and memory blow-ups were found). Every run ends in one clear error line
or a sound result (finite, read back, reproducing its source), never a traceback, a hang or a
memory blow-up. The large run is benchmarks/fuzz_cli.py (benchmarks/README.md)."""

import multiprocessing
from pathlib import Path

import fuzz_cases
import pytest
from hypothesis import HealthCheck, Phase, given, seed, settings

import robocal as rc

# cases of the sample run in-process (fuzz_cases.run_guarded: 20 s of CPU time, 1 GB of memory
# beyond the worker's) and in forked children (fuzz_cases.fork_case), split over this many forked
# workers, each its own seed
SAMPLE = 2000
FORKED = 100
WORKERS = 2


@pytest.fixture(scope="module")
def result_text(tmp_path_factory):
    return fuzz_cases.base_results(tmp_path_factory.mktemp("fuzz"))


def _share(job) -> list:
    """In a worker: ``n`` cases in-process and ``n_forked`` in children, drawn with seed ``k``; the bad
    ones as (outcome, command, argv, stderr)."""
    k, n, n_forked, text = job
    bad = []
    fuzz_cases.install_guard()

    def sample(n_cases, weights, run):
        @seed(k)
        @settings(max_examples=n_cases, deadline=None, database=None, phases=[Phase.generate],
                  suppress_health_check=list(HealthCheck))
        @given(fuzz_cases.case(text, weights=weights))
        def each(c):
            command, files, argv = c
            outcome, err = run(files, argv)
            if outcome not in ("clean error", "ok result"):
                bad.append((outcome, command, argv[:12], err[-1500:]))

        each()

    sample(n, fuzz_cases.SAMPLE_WEIGHTS, fuzz_cases.run_guarded)
    sample(n_forked, fuzz_cases.FORKED_WEIGHTS, fuzz_cases.run_forked)
    return bad


def test_fuzz_sample(result_text):
    pytest.importorskip("matplotlib")
    jobs = [(k, SAMPLE // WORKERS, FORKED // WORKERS, result_text) for k in range(WORKERS)]
    with multiprocessing.get_context("fork").Pool(WORKERS) as pool:
        bad = [b for share in pool.map(_share, jobs) for b in share]
    assert not bad, bad[:3]


def test_the_judge_reads_a_pose_named_like_a_number_as_a_name(tmp_path):
    # a target named '-inf' is compensated under its name (seed 1's case 6727): the judge counts
    # non-finite numbers, not names; a non-finite residual in the same file still counts
    rows = ["pose,j1_deg,residual_mm,status", "-inf,144.17,1.6e-08,ok", "P05,66.02,1.8e-12,ok"]
    out = tmp_path / "commands.csv"
    out.write_text("\n".join(rows) + "\n")
    assert fuzz_cases.non_finite(tmp_path, set()) is None
    out.write_text("\n".join(rows).replace("1.8e-12", "nan") + "\n")
    assert fuzz_cases.non_finite(tmp_path, set()) == "commands.csv"


def test_the_judge_reads_a_robot_named_like_a_number_in_a_urdf_as_a_name(tmp_path):
    # a model named 'Infinity' exported to URDF (seed 99's cases 26244 and 26245): its name stands
    # in the robot's name attribute; a non-finite origin in the same file still counts
    m = rc.read_model(Path(__file__).resolve().parents[1] / "examples" / "th8" / "model.yaml").replace(name="Infinity")
    out = tmp_path / "out.urdf"
    rc.io.write_urdf(m, out)
    assert 'name="Infinity"' in out.read_text()
    assert fuzz_cases.non_finite(tmp_path, set()) is None
    out.write_text(out.read_text().replace('xyz="', 'xyz="nan ', 1))
    assert fuzz_cases.non_finite(tmp_path, set()) == "out.urdf"


def test_the_judge_counts_a_child_stopped_by_its_cpu_limit_as_a_hang(tmp_path):
    # a calibration with --compare on nonsense stopped by SIGXCPU whose rusage read 19.95 s of the
    # 20 s limit was counted over-memory (the numbers family, seed 203); a SIGKILL before the limit
    # is the kernel's answer to memory
    import signal
    from types import SimpleNamespace

    usage = SimpleNamespace(ru_utime=19.9, ru_stime=0.05, ru_maxrss=100_000)
    assert fuzz_cases.forked_outcome(signal.SIGXCPU, usage, False, tmp_path, {}, ["calibrate"])[0] == "hang"
    assert fuzz_cases.forked_outcome(signal.SIGKILL, usage, False, tmp_path, {}, ["calibrate"])[0] == "over-memory"
