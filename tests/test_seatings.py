"""A folder of seatings (docs/formats.md): one headerless joint file per socket, one folder per
placement, seatings.yaml stating the joint order, the units, the deviation and the spacings. It reads
into the same Contacts as the contact file holding the same recordings, calibrates from the command
line with no script, and every bad input is one line naming the file and the line, column or key."""

import csv
import json
import os
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_one_line_error

import robocal as rc
from robocal.sim import socket_campaign

ROOT = Path(__file__).resolve().parents[1]
ARM7 = ROOT / "examples" / "arm7" / "model.yaml"
PLATE = {"hole_0": (0.0, 0.0, 0.0), "hole_1": (0.2, 0.0, 0.0), "hole_2": (0.0, 0.15, 0.0)}


@pytest.fixture(scope="module")
def arm7():
    return rc.read_model(ARM7)


@pytest.fixture(scope="module")
def session(arm7, tmp_path_factory):
    """A simulated socket campaign on a true arm (4 placements, 8 seatings per socket, one stated
    deviation) written as a contact file."""
    true = rc.perturb_model(arm7, rc.identifiability(arm7, parameters=("frames", "markers")).identified, rng=3)
    c = socket_campaign(true, placements=4, poses_per_socket=8, plate=PLATE, rng=3)
    c = replace(c, sigma=np.full(c.n_rows, 1.3e-5))
    path = tmp_path_factory.mktemp("seatings") / "sockets.csv"
    rc.io.write_contacts(c, path, arm7)
    return c, path


def as_seatings(csv_path: Path, folder: Path, joints, *, sep=",") -> Path:
    """The contact file's recordings laid out as a folder of seatings, the joint columns copied as
    written (in the order ``joints``)."""
    lines = csv_path.read_text().splitlines()
    directives = [ln[1:].strip() for ln in lines if ln.startswith("#")]
    rows = list(csv.DictReader([ln for ln in lines if not ln.startswith("#")]))
    units = next(d for d in directives if d.startswith("units:"))
    length, angle = (w.split("=")[1] for w in units.split()[1:])
    spacings = ""
    for d in directives:
        if d.startswith("distance:"):
            a, b, value, sigma = d.split()[1:]
            spacings += f"  - {{sockets: [{a}, {b}], length: {value}, sigma: {sigma.split('=')[1]}}}\n"
    folder.mkdir()
    (folder / "seatings.yaml").write_text(f"units: {length}-{angle}\njoints: [{', '.join(joints)}]\nmarker: ball\n"
                                          f"sigma: {rows[0]['sigma']}\ndistances:\n{spacings}")
    for r in rows:
        (folder / r["placement"]).mkdir(exist_ok=True)
        with open(folder / r["placement"] / f"{r['target']}.csv", "a") as fh:
            fh.write(sep.join(r[j] for j in joints) + "\n")
    return folder


def _same(a, b) -> None:
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.sigma, b.sigma)
    assert (a.marker, a.kind, a.target, a.placement) == (b.marker, b.kind, b.target, b.placement)
    assert a.distances == b.distances and a.planes == b.planes and a.bars == b.bars
    assert a.joint_names == b.joint_names


def test_a_folder_of_seatings_reads_as_the_contact_file_of_the_same_recordings(arm7, session, tmp_path):
    c, path = session
    from_csv = rc.io.read_contacts(path, arm7)
    folder = as_seatings(path, tmp_path / "campaign", arm7.joint_names)
    assert sorted(p.name for p in (folder / "P1").iterdir()) == ["hole_0.csv", "hole_1.csv", "hole_2.csv"]
    from_folder = rc.io.read_contacts(folder, arm7)
    _same(from_folder, from_csv)
    assert from_folder.placements() == ("P1", "P2", "P3", "P4") and len(from_folder.distances) == 3
    assert from_folder.labels[0] == "P1/hole_0.csv line 1" and from_folder.source == str(folder)
    np.testing.assert_allclose(from_folder.q, c.q, atol=1e-10)      # 9 decimals of a degree
    # the joint order is the manifest's: columns in another order, blank-separated, read the same
    shuffled = as_seatings(path, tmp_path / "shuffled", arm7.joint_names[::-1], sep="  ")
    _same(rc.io.read_contacts(shuffled, arm7), from_csv)
    assert rc.io.read_contacts(shuffled, arm7).sha256 != from_folder.sha256


def test_placements_and_sockets_are_read_in_natural_order(arm7, session, tmp_path):
    _, path = session
    folder = as_seatings(path, tmp_path / "campaign", arm7.joint_names)
    (folder / "P4").rename(folder / "P10")
    (folder / "P10" / "hole_2.csv").rename(folder / "P10" / "hole_10.csv")
    back = rc.io.read_contacts(folder, arm7)
    assert back.placements() == ("P1", "P2", "P3", "P10")
    assert [g.target for g in back.groups() if g.placement == "P10"] == ["hole_0", "hole_1", "hole_10"]


def test_the_command_line_calibrates_a_folder_of_seatings_as_it_does_the_contact_file(cli, arm7, session,
                                                                                        tmp_path):
    _, path = session
    folder = as_seatings(path, tmp_path / "campaign", arm7.joint_names)
    runs = {}
    for name, source in (("folder", folder), ("file", path)):
        code, out, err = cli("calibrate", ARM7, "--contacts", source, "--out", tmp_path / name,
                             "--holdout-placement", "P4")
        assert code == 0, err
        assert "held-out socket spread" in out and "verdict: pass" in out
        runs[name] = json.loads((tmp_path / name / "result.json").read_text())
    assert runs["folder"]["parameters"] == runs["file"]["parameters"]
    assert runs["folder"]["contacts"]["validation_after"] == runs["file"]["contacts"]["validation_after"]
    assert str(folder) in rc.read_model(tmp_path / "folder" / "calibrated.yaml").description


def test_the_example_folder_of_seatings_calibrates(cli, arm7, tmp_path):
    example = ROOT / "examples" / "arm7" / "seatings"
    code, out, err = cli("calibrate", ARM7, "--contacts", example, "--out", tmp_path / "run",
                         "--holdout-placement", "P3")
    assert code == 0, err
    assert "verdict: pass" in out
    c = rc.io.read_contacts(example, arm7)
    assert c.placements() == ("P1", "P2", "P3") and c.n_rows == 90 and len(c.distances) == 3


def test_the_manifest_stands_for_its_folder(cli, arm7, tmp_path):
    """``--contacts FOLDER/seatings.yaml`` was read as a contact file and refused for its lack of a
    units directive; the manifest now stands for its folder. As the measurement file it is named."""
    example = ROOT / "examples" / "arm7" / "seatings"
    _same(rc.io.read_contacts(example / "seatings.yaml", arm7), rc.io.read_contacts(example, arm7))
    code, out, err = cli("calibrate", ARM7, "--contacts", example / "seatings.yaml", "--out", tmp_path / "run",
                         "--holdout-placement", "P3")
    assert code == 0 and "verdict: pass" in out, err
    code, _, err = cli("calibrate", ARM7, example / "seatings.yaml", "--out", tmp_path / "o")
    assert_one_line_error(code, err, [str(example / "seatings.yaml"), "manifest", "--contacts"], tmp_path / "o")


def test_notes_and_other_files_in_a_placement_are_skipped_and_listed(arm7, session, tmp_path):
    """A campaign folder as published: a notes file and the robot's own pose files beside the socket
    files. The manifest names the socket files; the others are skipped, never read as sockets, and
    the reader says which sockets it read in each placement and which files it skipped."""
    _, path = session
    folder = as_seatings(path, tmp_path / "campaign", arm7.joint_names)
    plain = rc.io.read_contacts(folder, arm7)
    for p in folder.iterdir():
        if p.is_dir():
            (p / "comments.txt").write_text("plate on the left of the table\n")
            (p / "hole_0_pose.csv").write_text("0.1,0.2,0.3,0,0,0,1\n")
    manifest = folder / "seatings.yaml"
    manifest.write_text(manifest.read_text() + 'sockets: "hole_?.csv"\n')
    got = rc.io.read_contacts(folder, arm7)
    assert np.array_equal(got.q, plain.q) and got.target == plain.target and got.placement == plain.placement
    assert got.notes[0].startswith("sockets read: P1 hole_0, hole_1, hole_2")
    assert got.notes[1].startswith(f"{2 * len(plain.placements())} file(s) not socket files, skipped: P1/comments.txt")


def test_sockets_whose_seatings_are_copies_of_one_reading_are_refused_in_one_line(cli, tmp_path):
    """Every socket file holding the same joint reading puts the spaced sockets at one point: the
    stated spacing has no direction to fit along (once a NaN Jacobian and an internal argument's name)."""
    import shutil
    folder = tmp_path / "copies"
    shutil.copytree(ROOT / "examples" / "arm7" / "seatings", folder)
    row = (folder / "P1" / "hole_0.csv").read_text().splitlines()[0] + "\n"
    for f in folder.glob("P*/hole_*.csv"):
        f.write_text(row * 10)
    code, _, err = cli("calibrate", ARM7, "--contacts", folder, "--out", tmp_path / "run")
    assert_one_line_error(code, err, ["sit at one point", "hole_0", "hole_1", "P1"], tmp_path / "run")


def _edit(rel, fn):
    def apply(folder: Path) -> None:
        p = folder / rel
        p.write_text(fn(p.read_text()))
    return apply


def _manifest(old, new):
    return _edit("seatings.yaml", lambda t: t.replace(old, new, 1))


def _line(text, k, fn):
    lines = text.splitlines(keepends=True)
    lines[k - 1] = fn(lines[k - 1])
    return "".join(lines)


def _outside_link(rel):
    def apply(folder: Path) -> None:
        outside = folder.parent / "elsewhere"
        outside.mkdir(exist_ok=True)
        (outside / "hole_0.csv").write_text((folder / "P1" / "hole_0.csv").read_text())
        target = outside / "hole_0.csv" if rel.endswith(".csv") else outside
        os.symlink(target, folder / rel)
    return apply


def _limit(name, value):
    def apply(folder: Path, monkeypatch) -> None:
        from robocal._files import seatings
        monkeypatch.setattr(seatings, name, value)
    return apply


BAD = [
    ("header", _edit("P1/hole_0.csv", lambda t: "j1,j2,j3,j4,j5,j6,j7\n" + t),
     ["P1/hole_0.csv", "line 1", "header", "no header"]),
    ("columns", _edit("P2/hole_1.csv", lambda t: _line(t, 3, lambda s: s.rsplit(",", 1)[0] + "\n")),
     ["P2/hole_1.csv", "line 3", "6 values for 7 joints"]),
    ("nan", _edit("P1/hole_2.csv", lambda t: _line(t, 2, lambda s: "1.0,nan," + s.split(",", 2)[2])),
     ["P1/hole_2.csv", "line 2, column 2 (j2)", "not a finite number"]),
    ("word", _edit("P1/hole_2.csv", lambda t: _line(t, 4, lambda s: "1.0,12x," + s.split(",", 2)[2])),
     ["P1/hole_2.csv", "line 4, column 2 (j2)", "expected a number, got '12x'"]),
    ("empty file", _edit("P3/hole_0.csv", lambda t: "\n"), ["P3/hole_0.csv", "no seating"]),
    ("empty folder", lambda f: [__import__("shutil").rmtree(p) for p in f.iterdir() if p.is_dir()],
     ["campaign", "no placement folder"]),
    ("empty placement", lambda f: (f / "P5").mkdir(), ["P5", "no socket file"]),
    ("file name", lambda f: (f / "P2" / "hole_1.csv").rename(f / "P2" / "hole 1.csv"),
     ["P2/hole 1.csv", "not a socket file"]),
    ("pattern", _manifest("sigma:", "sockets: hole_?.txt\nsigma:"), ["seatings.yaml", "sockets", "ending in .csv"]),
    ("no file matches", _manifest("sigma:", "sockets: peg_?.csv\nsigma:"), ["P1", "no socket file (peg_?.csv)"]),
    ("top csv", lambda f: (f / "hole_0.csv").write_text("1,2,3,4,5,6,7\n"),
     ["campaign/hole_0.csv", "outside a placement folder"]),
    ("placement name", lambda f: (f / "P2").rename(f / "P 2"), ["P 2", "placement folder's name"]),
    ("no manifest", lambda f: (f / "seatings.yaml").unlink(), ["campaign", "no seatings.yaml"]),
    ("missing key", _manifest("units: mm-deg\n", ""),
     ["seatings.yaml", "units: missing"]),
    ("unknown key", _manifest("sigma:", "sigmaa:"),
     ["seatings.yaml", "sigmaa", "did you mean 'sigma'"]),
    ("unit", _manifest("mm-deg", "mm-grad"),
     ["seatings.yaml", "units", "unknown angle unit 'grad'"]),
    ("joint", _manifest("j7]", "j8]"),
     ["seatings.yaml", "joints[6]", "'j8' is not a joint"]),
    ("joint twice", _manifest("j7]", "j6]"),
     ["seatings.yaml", "joints[6]", "'j6' given twice"]),
    ("marker", _manifest("marker: ball", "marker: bal"),
     ["seatings.yaml", "marker", "did you mean 'ball'"]),
    ("sigma", _manifest("sigma: 0.013", "sigma: -1"),
     ["seatings.yaml", "sigma", "positive number"]),
    ("spacing", _manifest("[hole_0, hole_1]", "[hole_0, hole_7]"),
     ["seatings.yaml", "distances[0].sockets", "socket 'hole_7' has no file"]),
    ("spacing length", _manifest("length: 200", "length: -200"),
     ["seatings.yaml", "distances[0].length", "positive number"]),
    ("link out", _outside_link("P1/hole_3.csv"), ["P1/hole_3.csv", "a link out of the campaign folder"]),
    ("placement link out", _outside_link("P9"), ["P9", "a link out of the campaign folder"]),
    ("files", _limit("MAX_SOCKET_FILES", 5), ["campaign", "more than 5 socket files"]),
    ("rows", _limit("MAX_SEATINGS", 50), ["hole_", "more than 50 seatings"]),
    ("entries", _limit("MAX_ENTRIES", 3), ["campaign", "more than 3 entries"]),
    ("bytes", _limit("MAX_CAMPAIGN_BYTES", 1000), ["campaign", "bytes; a folder of seatings holds up to 1,000"]),
    ("row", _limit("MAX_ROW_CHARS", 20), ["P1/hole_0.csv", "line 1", "characters; a joint file's rows hold up to 20"]),
]


@pytest.mark.parametrize("edit, words", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_folders_of_seatings_are_refused_in_one_line(cli, arm7, session, tmp_path, monkeypatch, edit, words):
    _, path = session
    folder = as_seatings(path, tmp_path / "campaign", arm7.joint_names)
    if edit.__code__.co_argcount == 2:
        edit(folder, monkeypatch)
    else:
        edit(folder)
    code, _, err = cli("calibrate", ARM7, "--contacts", folder, "--out", tmp_path / "run")
    assert_one_line_error(code, err, words, tmp_path / "run")
