"""Every measurement slot of the command line given an endless or non-regular input: /dev/zero,
/dev/urandom, a FIFO that a program writes into, a FIFO that none does, and a pipe as ``<(cat FILE)``
makes it. Each is refused in one line or read, within 5 s and 300 MB, and a stream is read once
(the pipe and the FIFO give the same outcome as the file itself)."""

import contextlib
import io
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TH8, ARM7 = ROOT / "examples" / "th8", ROOT / "examples" / "arm7"
SECONDS, PEAK_MB = 5.0, 300
ENCODERS = ["--encoder-resolution", "0.01deg,0.1mm,0.12mm,0.005deg,0.002deg,0.002deg", "--length-quantum-mm", "0.1",
            "--angle-quantum-deg", "0.001"]

# each case in a child forked from one process that imported robocal's modules once, so that a case's
# time and peak memory are those of a ``robocal`` process without its start-up; the parent kills a case
# at its deadline, and takes its peak from the kernel's accounting of the finished child (wait4)
RUNNER = r"""
import importlib, json, os, pkgutil, signal, sys, time
import matplotlib
matplotlib.use("Agg")
from robocal.cli import main
for m in pkgutil.walk_packages(importlib.util.find_spec("robocal").submodule_search_locations, "robocal."):
    if not m.name.endswith(".__main__"):
        importlib.import_module(m.name)  # imported once here, not in each case

def child(argv, out, closing):
    for fd in closing:
        os.close(fd)
    with open(out + ".out", "wb") as o, open(out + ".err", "wb") as e:
        os.dup2(o.fileno(), 1)
        os.dup2(e.fileno(), 2)
    code = 1
    try:
        code = main(argv)
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)

def writer(path_or_fd, content, closing):
    for fd in closing:
        os.close(fd)
    try:
        fd = os.open(path_or_fd, os.O_WRONLY) if isinstance(path_or_fd, str) else path_or_fd
        with open(fd, "wb") as fh:
            fh.write(content)
    finally:
        os._exit(0)

def run(case):
    kind, argv, content, out, deadline = case["kind"], case["argv"], case["content"], case["out"], case["seconds"]
    slot = argv.index("INPUT")
    helpers, closing = [], []
    if kind == "pipe":                       # what a shell's <(cat FILE) gives: /dev/fd/N, a pipe
        r, w = os.pipe()
        argv[slot] = f"/dev/fd/{r}"
        sys.stdout.flush()
        pid = os.fork()
        if pid == 0:
            writer(w, open(content, "rb").read(), [r])
        helpers.append(pid)
        closing = [w]
    elif kind == "fifo":
        argv[slot] = case["fifo"]
        sys.stdout.flush()
        pid = os.fork()
        if pid == 0:
            writer(case["fifo"], open(content, "rb").read(), [])
        helpers.append(pid)
    elif kind == "fifo-no-writer":
        argv[slot] = case["fifo"]
    elif kind == "file":
        argv[slot] = content
    else:
        argv[slot] = kind                    # /dev/zero, /dev/urandom, or a path as it is
    start = time.monotonic()
    sys.stdout.flush()
    pid = os.fork()
    if pid == 0:
        child(argv, out, closing)
    for fd in closing:
        os.close(fd)
    if kind == "pipe":
        os.close(r)
    killed = False
    while True:
        done, status, usage = os.wait4(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() - start > deadline:
            os.kill(pid, signal.SIGKILL)
            done, status, usage = os.wait4(pid, 0)
            killed = True
            break
        time.sleep(0.01)
    seconds = time.monotonic() - start
    for h in helpers:
        try:
            os.kill(h, signal.SIGKILL)
        except ProcessLookupError:
            pass
        os.waitpid(h, 0)
    return {"code": os.waitstatus_to_exitcode(status), "seconds": seconds, "killed": killed,
            "peak_mb": usage.ru_maxrss / 1024, "stderr": open(out + ".err", "rb").read().decode(errors="replace"),
            "argv": argv}

for case in json.loads(sys.argv[1]):
    print(json.dumps(run(case)), flush=True)
"""

KINDS = ["/dev/zero", "/dev/urandom", "fifo", "pipe"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    return stream_files(tmp_path_factory.mktemp("streams"))


def stream_files(folder: Path) -> Path:
    """The files the slots' commands read besides the one in the slot, made in ``folder``: the th8
    campaign split into points and joint readings, and a store holding a calibration of robot R."""
    from robocal.cli import main

    lines = (TH8 / "measurements.csv").read_text().splitlines()
    header = lines[0].split(",")
    joints = [k for k, c in enumerate(header) if c.startswith("j")]
    others = [k for k in range(len(header)) if k not in joints]
    fit = [k for k, c in enumerate(header) if c != "set"]
    for name, cols in (("points.csv", others), ("joints.csv", [0] + joints), ("fit.csv", fit)):
        (folder / name).write_text("".join(",".join(ln.split(",")[k] for k in cols) + "\n" for ln in lines))
    seatings = folder / "seatings"
    shutil.copytree(ARM7 / "seatings", seatings)
    with contextlib.redirect_stdout(io.StringIO()):
        code = main(["calibrate", str(TH8 / "model.yaml"), str(TH8 / "measurements.csv"), "--known", "markers",
                     "--out", str(folder / "calibration"), "--record", "R", "--store", str(folder / "store.sqlite")])
    assert code in (0, 3)
    return folder


SLOTS = {  # the command, with INPUT in the measurement slot; the file a stream there carries
    "calibrate": (["calibrate", TH8 / "model.yaml", "INPUT", "--known", "markers"], TH8 / "measurements.csv"),
    "validate": (["calibrate", TH8 / "model.yaml", "{fit}", "--validate", "INPUT", "--known", "markers"],
                 TH8 / "verification.csv"),
    "joints": (["calibrate", TH8 / "model.yaml", "{points}", "--joints", "INPUT", "--known", "markers"],
               "{joints}"),
    "identifiability": (["identifiability", TH8 / "model.yaml", "INPUT"], TH8 / "measurements.csv"),
    "plan-candidates": (["plan", TH8 / "model.yaml", "--poses", "12", "--candidates", "INPUT"],
                        TH8 / "measurements.csv"),
    "compensate-targets": (["compensate", TH8 / "model.yaml", TH8 / "true_model.yaml", "INPUT"], TH8 / "targets.csv"),
    "limit-repeatability": (["limit", TH8 / "model.yaml", "--repeatability-csv", "INPUT", *ENCODERS],
                            TH8 / "repeatability.csv"),
    "contacts": (["calibrate", ARM7 / "model.yaml", "--contacts", "INPUT"], ARM7 / "sockets.csv"),
    "verify": (["verify", "R", "INPUT", "--store", "{store}", "--no-record"], TH8 / "verification.csv"),
    "compensate-program": (["compensate", TH8 / "model.yaml", TH8 / "true_model.yaml", "INPUT", "--dialect", "rapid"],
                           TH8 / "program.mod"),
}
OUTPUT = {"calibrate": "run", "plan": "plan.csv", "compensate": "commands.csv", "limit": "limit.json",
          "compensate-program": "program.mod"}


def _cases(slot: str, files: Path, kinds, tag: str) -> list[dict]:
    argv, content = SLOTS[slot]
    names = {"points": files / "points.csv", "fit": files / "fit.csv", "joints": files / "joints.csv",
             "store": files / "store.sqlite"}
    argv, content = [str(a).format(**names) for a in argv], str(content).format(**names)
    cases = []
    for k, kind in enumerate(kinds):
        out = files / f"{slot}-{tag}-{k}"
        fifo = files / f"{slot}-{tag}-{k}.fifo"
        if kind.startswith("fifo"):
            os.mkfifo(fifo)
        output = OUTPUT.get(slot, OUTPUT.get(argv[0]))
        extra = ["--out", str(out / output)] if output else []
        cases.append({"kind": kind, "argv": argv + extra, "content": content, "out": str(out),
                      "fifo": str(fifo), "seconds": SECONDS})
        out.mkdir()
    return cases


def _run(cases: list[dict]) -> list[dict]:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    p = subprocess.run([sys.executable, "-c", RUNNER, json.dumps(cases)], env=env, capture_output=True, text=True,
                       timeout=60 + SECONDS * len(cases))
    assert p.returncode == 0, p.stderr
    return [json.loads(line) for line in p.stdout.splitlines()]


@pytest.mark.parametrize("slot", list(SLOTS))
def test_every_measurement_slot_refuses_or_reads_a_stream_in_bounded_time_and_memory(slot, files):
    results = _run(_cases(slot, files, ["file", *KINDS], "streams"))
    reference = results[0]
    assert reference["code"] in (0, 3), reference["stderr"]   # the file itself: read and worked on
    for kind, r in zip(KINDS, results[1:]):
        what = (slot, kind, r["stderr"][-300:])
        assert not r["killed"] and r["seconds"] < SECONDS, what
        assert r["peak_mb"] < PEAK_MB, (*what, r["peak_mb"])
        assert "Traceback" not in r["stderr"], what
        if kind.startswith("/dev/"):
            lines = r["stderr"].strip().splitlines()
            assert r["code"] == 2 and len(lines) == 1 and kind in lines[0], what
        else:  # read once, as the file is
            assert r["code"] == reference["code"], what


def test_a_fifo_that_no_program_writes_into_is_refused(files):
    (result,) = _run(_cases("calibrate", files, ["fifo-no-writer"], "idle"))
    lines = result["stderr"].strip().splitlines()
    assert not result["killed"] and result["seconds"] < SECONDS, result
    assert result["code"] == 2 and len(lines) == 1 and "a FIFO that no program writes into" in lines[0], lines


def _in_place_of(path: Path, kind: str) -> Path:
    """``path`` replaced by a FIFO nothing writes into, or by a link to the device ``kind``."""
    path.unlink()
    if kind == "fifo":
        os.mkfifo(path)
    else:
        path.symlink_to(kind)
    return path


@pytest.mark.parametrize("kind", ["/dev/zero", "fifo"])
def test_a_socket_file_of_seatings_that_is_not_a_regular_file_is_refused(files, tmp_path, kind):
    seatings = tmp_path / "seatings"
    shutil.copytree(files / "seatings", seatings)
    _in_place_of(seatings / "P1" / "hole_0.csv", kind)
    argv = ["calibrate", str(ARM7 / "model.yaml"), "--contacts", "INPUT", "--out", str(tmp_path / "run")]
    (result,) = _run([{"kind": str(seatings), "argv": argv, "content": "", "out": str(tmp_path / "log"),
                       "seconds": SECONDS}])
    lines = result["stderr"].strip().splitlines()
    assert not result["killed"] and result["seconds"] < SECONDS, result
    said = "a link out of the campaign folder" if kind.startswith("/dev/") else "not a regular file"
    assert result["code"] == 2 and len(lines) == 1 and "hole_0.csv" in lines[0] and said in lines[0], lines


@pytest.mark.parametrize("node", ["/dev/zero", "fifo"])
def test_a_results_per_pose_file_that_is_a_device_or_a_fifo_is_refused_before_it_is_read(cli, tmp_path,
                                                                                        monkeypatch, node):
    """The per-pose file beside a result is one robocal wrote: a device or FIFO in its place is refused
    at once, not read up to the 4 GB a per-pose file may hold (the fuzz found /dev/zero there out of
    memory). The budget is made small so that reading it would end otherwise."""
    import robocal as rc

    code, _, err = cli("calibrate", TH8 / "model.yaml", TH8 / "measurements.csv", "--known", "markers", "--out",
                       tmp_path / "run")
    assert code in (0, 3), err
    sidecar = _in_place_of(tmp_path / "run" / "result.npz", node)
    monkeypatch.setattr(sys.modules[rc.io.read_result.__module__], "MAX_FILE_BYTES", 2 ** 16)
    code, _, err = cli("report", tmp_path / "run" / "result.json", "--out", tmp_path / "report.html")
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and str(sidecar) in lines[0], err
    assert ("a character device" if node.startswith("/dev") else "a FIFO") in lines[0], err
    assert not (tmp_path / "report.html").exists()
