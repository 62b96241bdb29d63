"""Outputs: every command that writes refuses to replace what is not a regular file (a device, a
FIFO, a link to a pipe), leaves no temporary behind even when killed (the next run removes it),
gives its files the mode the umask says, and refuses a file over the pose limit before reading it."""

import os
import signal
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from conftest import assert_one_line_error
from fuzz_cases import MEASUREMENTS, MODEL

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
LIMIT_ARGS = ("--repeatability-mm", "0.05", "--encoder-resolution", "0.01deg,0.01mm,0.01mm,0.01deg,0.01deg,0.01deg",
              "--length-quantum-mm", "0.01", "--angle-quantum-deg", "0.001", "--samples", "200")


@pytest.fixture
def files(tmp_path):
    (tmp_path / "model.yaml").write_text(MODEL)
    (tmp_path / "data.csv").write_text(MEASUREMENTS)
    return tmp_path


def writers(d: Path, result_json: Path | None = None):
    """Every command that writes, as (argv with OUT where its output goes, output name inside a folder
    output or None)."""
    th8 = EXAMPLES / "th8"
    out = [(("calibrate", d / "model.yaml", d / "data.csv", "--out", "OUT"), "result.json"),
           (("calibrate", d / "model.yaml", d / "data.csv", "--out", "OUT", "--report"), "report.html"),
           (("calibrate", EXAMPLES / "arm7" / "model.yaml", "--contacts", EXAMPLES / "arm7" / "sockets.csv",
             "--out", "OUT"), "result.json"),
           (("simulate", d / "model.yaml", "--out", "OUT", "--poses", "5"), None),
           (("limit", d / "model.yaml", *LIMIT_ARGS, "--out", "OUT"), None),
           (("plan", d / "model.yaml", "--poses", "10", "--out", "OUT"), None),
           (("plan-sockets", EXAMPLES / "arm7" / "model.yaml", "--placements", "3", "--poses-per-socket", "20",
             "--out", "OUT"), None),
           (("compensate", th8 / "model.yaml", th8 / "true_model.yaml", th8 / "targets.csv", "--out", "OUT"), None),
           (("export", th8 / "model.yaml", "--format", "urdf", "--out", "OUT"), None),
           (("import-dh", EXAMPLES / "dh" / "ur5-dh.csv", "--out", "OUT"), None),
           (("import-urdf", EXAMPLES / "urdf" / "gen3_like.urdf", "--out", "OUT", "--marker-mm", "tcp,0,0,120"), None)]
    if result_json is not None:
        out.append((("report", result_json, "--out", "OUT"), None))
    return out


def _ids(d=Path(".")):
    return [f"{argv[0]}{'-' + str(k) if k else ''}" for k, (argv, _) in enumerate(writers(d, d))]


@pytest.fixture(scope="module")
def result_json(tmp_path_factory):
    from robocal.cli import main

    d = tmp_path_factory.mktemp("result")
    (d / "m.yaml").write_text(MODEL)
    (d / "d.csv").write_text(MEASUREMENTS)
    assert main(["calibrate", str(d / "m.yaml"), str(d / "d.csv"), "--out", str(d / "o")]) in (0, 3)
    return d / "o" / "result.json"


def _place(argv, inside, node_path: Path, folder: Path):
    """argv with OUT replaced so that the output (or the file ``inside`` a folder output) is ``node_path``."""
    target = folder if inside else node_path
    return [str(target) if a == "OUT" else a for a in argv]


def _node(kind: str, where: Path, pipe_w: int) -> Path:
    if kind == "device":
        try:
            os.mknod(where, 0o666 | stat.S_IFCHR, os.makedev(1, 3))  # the system's /dev/null
        except PermissionError:
            pytest.skip("mknod needs root")
    elif kind == "fifo":
        os.mkfifo(where)
    else:  # a link to this process's pipe, as /dev/stdout is a link to /proc/self/fd/1
        where.symlink_to(f"/proc/self/fd/{pipe_w}")
    return where


def _unchanged(kind: str, where: Path, pipe_r: int) -> None:
    st = os.lstat(where)
    if kind == "device":
        assert stat.S_ISCHR(st.st_mode) and st.st_rdev == os.makedev(1, 3)
    elif kind == "fifo":
        assert stat.S_ISFIFO(st.st_mode)
    else:
        assert stat.S_ISLNK(st.st_mode) and os.readlink(where).startswith("/proc/self/fd/")
    with pytest.raises(BlockingIOError):
        os.read(pipe_r, 1)  # nothing was written into the pipe


@pytest.mark.parametrize("kind", ["device", "fifo", "proc-fd-link"])
@pytest.mark.parametrize("number", range(len(_ids())), ids=_ids())
def test_every_writer_refuses_a_node_and_leaves_it_unchanged(tmp_path, cli, files, result_json, kind, number):
    argv, inside = writers(files, result_json)[number]
    folder = tmp_path / "out"
    folder.mkdir()
    r, w = os.pipe()
    os.set_blocking(r, False)
    try:
        node = _node(kind, folder / (inside or "out.file"), w)
        for force in ((), ("--force",)):
            code, out, err = cli(*_place(argv, inside, node, folder), *force)
            word = "device" if kind == "device" else "FIFO"
            assert_one_line_error(code, err, [str(node), word, "regular file"], command=argv[0])
            _unchanged(kind, node, r)
        assert [p.name for p in node.parent.iterdir()] == [node.name]
    finally:
        os.close(r)
        os.close(w)


def test_a_proc_fd_path_itself_is_refused(tmp_path, cli, files):
    r, w = os.pipe()
    os.set_blocking(r, False)
    try:
        code, _, err = cli("simulate", files / "model.yaml", "--out", f"/proc/self/fd/{w}", "--poses", "5", "--force")
        assert_one_line_error(code, err, [f"/proc/self/fd/{w}", "FIFO"], command="simulate")
        with pytest.raises(BlockingIOError):
            os.read(r, 1)
    finally:
        os.close(r)
        os.close(w)


def test_link_to_a_regular_file_is_replaced_and_its_target_kept(files, cli):
    target = files / "target.csv"
    target.write_text("keep me")
    (files / "s.csv").symlink_to(target)
    code, _, err = cli("simulate", files / "model.yaml", "--out", files / "s.csv", "--poses", "5", "--force")
    assert code == 0, err
    assert target.read_text() == "keep me" and not (files / "s.csv").is_symlink()
    assert (files / "s.csv").read_text().startswith("pose,")


def test_library_writer_refuses_a_node(tmp_path):
    from robocal._files.text import write_texts
    from robocal.errors import InputError

    os.mkfifo(tmp_path / "f")
    with pytest.raises(InputError, match="FIFO"):
        write_texts({tmp_path / "a.txt": "a", tmp_path / "f": "b"}, force=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]


# -- orphan temporaries --------------------------------------------------------------------------

KILLED_WRITE = textwrap.dedent("""
    import os, signal, sys
    from robocal._files import text
    def killed(src, dst):
        os.kill(os.getpid(), signal.SIGKILL)
    text.os.replace = killed
    text.write_texts({sys.argv[1]: "x" * 1000, sys.argv[2]: "y"})
""")


def test_temporaries_of_a_killed_run_are_removed_by_the_next_run(files, cli):
    out = files / "run"
    out.mkdir()
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    p = subprocess.run([sys.executable, "-c", KILLED_WRITE, str(out / "result.json"), str(out / "calibrated.yaml")],
                       env=env, capture_output=True, text=True, timeout=60)
    assert p.returncode == -signal.SIGKILL, p.stderr
    orphans = sorted(q.name for q in out.iterdir())
    assert len(orphans) == 2 and all(q.endswith(".tmp") and ".robocal-" in q for q in orphans), orphans
    other = files / "mine.robocal-1-0123456789abcdef.tmp"   # not a robocal temporary name: kept
    (out / other.name).write_text("a user's file")
    code, _, err = cli("calibrate", files / "model.yaml", files / "data.csv", "--out", out)
    assert code in (0, 3), err
    left = sorted(q.name for q in out.iterdir())
    assert not set(orphans) & set(left) and other.name in left and "result.json" in left


def test_a_live_runs_temporary_is_left_alone(tmp_path):
    from robocal._files.text import remove_orphans

    live = tmp_path / f".a.txt.robocal-{os.getppid()}-0123456789abcdef.tmp"
    dead = tmp_path / ".a.txt.robocal-999999999-0123456789abcdef.tmp"
    link = tmp_path / ".b.txt.robocal-999999998-0123456789abcdef.tmp"
    live.write_text("")
    dead.write_text("")
    link.symlink_to(live)
    assert remove_orphans(tmp_path) == (str(dead),)
    assert live.exists() and link.is_symlink() and not dead.exists()


# -- the mode the umask gives ----------------------------------------------------------------------

@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_written_files_get_the_mode_of_the_umask(files, cli, umask):
    old = os.umask(umask)
    try:
        code, _, err = cli("calibrate", files / "model.yaml", files / "data.csv", "--out", files / "run")
        assert code in (0, 3), err
        code, _, err = cli("simulate", files / "model.yaml", "--out", files / "s.csv", "--poses", "5")
        assert code == 0, err
    finally:
        os.umask(old)
    written = [files / "s.csv"] + list((files / "run").iterdir())
    assert len(written) >= 2
    for p in written:
        assert stat.S_IMODE(os.stat(p).st_mode) == 0o666 & ~umask, p


# -- size limits before reading --------------------------------------------------------------------

def test_a_file_over_the_pose_limit_is_refused_before_it_is_read(files):
    """1,000,000 rows over a 100-pose limit: refused in one line with a small peak (measured in a
    child process, whose peak is its own)."""
    header, row = MEASUREMENTS.splitlines()[0], MEASUREMENTS.splitlines()[1]
    with open(files / "big.csv", "w") as fh:
        fh.write(header + "\n")
        block = (row + "\n") * 10_000
        for _ in range(100):
            fh.write(block)
    script = textwrap.dedent("""
        import sys
        import robocal._files.measurements as m
        m.MAX_POSES = 100
        from robocal.cli import main
        code = main(["calibrate", sys.argv[1], sys.argv[2], "--out", sys.argv[3]])
        # VmHWM: this process's own peak (ru_maxrss may carry the parent's from before the exec)
        status = open("/proc/self/status").read()
        print(code, next(ln.split()[1] for ln in status.splitlines() if ln.startswith("VmHWM:")))
    """)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    p = subprocess.run([sys.executable, "-c", script, str(files / "model.yaml"), str(files / "big.csv"),
                        str(files / "out")], env=env, capture_output=True, text=True, timeout=120)
    code, peak_kb = map(int, p.stdout.split())
    assert code == 2 and "big.csv" in p.stderr and "up to 100 poses" in p.stderr, p.stderr
    assert len(p.stderr.strip().splitlines()) == 1
    assert peak_kb < 200 * 1024, peak_kb
    assert not (files / "out").exists()


def test_a_file_beyond_what_memory_bounds_is_refused_before_it_is_read(files, cli, monkeypatch):
    from robocal._files import text

    monkeypatch.setattr(text, "available_memory", lambda: 2 ** 30 * 20 / 1_000_000)  # room for 20 poses
    code, _, err = cli("calibrate", files / "model.yaml", files / "data.csv", "--out", files / "out")
    assert_one_line_error(code, err, ["data.csv", "30 rows", "memory available", "up to 20 poses", "per GB"])
    monkeypatch.setattr(text, "available_memory", lambda: None)  # unknown: the fixed limit alone
    code, _, err = cli("calibrate", files / "model.yaml", files / "data.csv", "--out", files / "out")
    assert code in (0, 3), err
