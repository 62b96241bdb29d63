"""Measurement files are read by numpy's compiled parser; every file must read to the same
Measurements, bit for bit, as row by row, and every fault must still be named by file, line and
column (the row reader takes over wherever the compiled one cannot vouch for a file, and the
summary says so)."""

import sys

import numpy as np
import pytest
from fuzz_cases import MEASUREMENTS, MODEL
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from robots import arm6r

import robocal as rc
import robocal._files.measurements as reader

ROW_BY_ROW = "read row by row, not by the compiled parser"


def rows_only(*args, **kwargs):
    """The compiled parser stepping back without a word: the row reader reads every file."""
    raise reader.Unfit


def fallback_notes(data) -> list:
    return [n for n in data.extra.get("notes", ()) if ROW_BY_ROW in n]


@pytest.fixture
def model(tmp_path):
    (tmp_path / "model.yaml").write_text(MODEL)
    return rc.read_model(tmp_path / "model.yaml")


def both(path, model, monkeypatch, **kw):
    """(compiled, row by row) readings of ``path``; the compiled parser must have read it."""
    fast = rc.read_measurements(path, model, **kw)
    assert not fallback_notes(fast), "the compiled parser did not read this file"
    with monkeypatch.context() as m:
        m.setattr(reader, "_read_fast", rows_only)
        slow = rc.read_measurements(path, model, **kw)
    return fast, slow


def identical(a, b):
    for name in ("q", "positions", "mask", "rotations", "rot_mask", "sigma", "sigma_rot", "payload_mass"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x, y, equal_nan=True), name
    assert a.labels == b.labels and a.sha256 == b.sha256 and a.source == b.source
    assert a.marker_names == b.marker_names and a.joint_names == b.joint_names
    assert a.extra.keys() == b.extra.keys()
    for k in a.extra:
        if isinstance(a.extra[k], np.ndarray):
            assert np.array_equal(a.extra[k], b.extra[k]) and a.extra[k].dtype.kind == b.extra[k].dtype.kind, k
        elif k == "notes":  # the same notes, but the one saying which reader read the file
            assert [n for n in a.extra[k] if ROW_BY_ROW not in n] == [n for n in b.extra[k] if ROW_BY_ROW not in n]
        else:
            assert a.extra[k] == b.extra[k], k


def test_the_example_reads_the_same(tmp_path, model, monkeypatch):
    (tmp_path / "d.csv").write_text(MEASUREMENTS)
    identical(*both(tmp_path / "d.csv", model, monkeypatch))


@pytest.mark.parametrize("units, orientation", [("mm-deg", "quat_xyzw"), ("m-rad", "rpy"), ("mm-deg", "euler:ZYX")])
def test_6d_poses_with_sigmas_masks_payload_series_and_approach(tmp_path, monkeypatch, units, orientation):
    robot = arm6r(markers=(("a", (0.05, 0.02, 0.12)), ("b", (0.0, 0.1, 0.05))))
    _, data = rc.simulate(robot, 200, seed=5, orientation=True, noise_rot=1e-4)
    n = data.n_poses
    rng = np.random.default_rng(6)
    mask = data.mask.copy()
    mask[rng.random(mask.shape) < 0.2] = False
    extra = {"validation": rng.random(n) < 0.3, "series": np.array([f"s{i % 4}" for i in range(n)]),
             "approach": np.where(rng.random((n, robot.n_joints)) < 0.5, -1.0, 1.0)}
    data = data.__class__(q=data.q, positions=data.positions, marker_names=data.marker_names,
                          joint_names=data.joint_names, mask=mask, rotations=data.rotations, rot_mask=mask,
                          sigma=np.full(mask.shape, 2e-5), sigma_rot=np.full(mask.shape, 1e-4),
                          payload_mass=rng.uniform(0, 5, n), labels=tuple(f"P{i}" for i in range(n)), extra=extra)
    rc.write_measurements(data, tmp_path / "d.csv", model=robot, units=units, orientation=orientation)
    fast, slow = both(tmp_path / "d.csv", robot, monkeypatch)
    identical(fast, slow)
    assert fast.mask.sum() == mask.sum() and list(fast.extra["series"]) == list(extra["series"])


def test_decimal_commas_semicolons_maps_profiles_and_a_header_given(tmp_path, model, monkeypatch):
    lines = MEASUREMENTS.splitlines()
    header, rows = lines[0].split(","), [ln.split(",") for ln in lines[1:]]
    rows[3][7:10] = ["", "", ""]                        # a marker not seen
    renamed = ["Index" if c == "pose" else "X" if c == "tool_x_mm" else c for c in header] + ["Temp"]
    text = "# units: length=mm angle=deg\n" + ";".join(renamed) + "\n" + "".join(
        ";".join(c.replace(".", ",") for c in r) + ";21,5\n" for r in rows)
    (tmp_path / "d.csv").write_text(text)
    (tmp_path / "p.yaml").write_text("robocal_profile: 1\ncolumns: {Index: pose, X: tool_x_mm}\nignore: [Temp]\n")
    fast, slow = both(tmp_path / "d.csv", model, monkeypatch, profile=tmp_path / "p.yaml")
    identical(fast, slow)
    assert any("decimal mark ','" in n for n in fast.extra["notes"])
    assert not fast.mask[3].any() and fast.labels[0] == "P01"
    (tmp_path / "h.csv").write_text("".join(",".join(r) + "\n" for r in rows))
    identical(*both(tmp_path / "h.csv", model, monkeypatch, header=header))


@pytest.mark.parametrize("edit, words", [
    (lambda r: r[5].__setitem__(2, "12x"), ["line 7", "'j2_mm'", "expected a number"]),
    (lambda r: r[5].__setitem__(2, ""), ["line 7", "'j2_mm'", "empty cell"]),
    (lambda r: r[8].__setitem__(8, ""), ["line 10", "tool_y_mm", "empty cell"]),
    (lambda r: r[2].__setitem__(1, "nan"), ["line 4", "'j1_deg'", "not a measurement"]),
    (lambda r: r[2].__setitem__(1, "1e13"), ["line 4", "'j1_deg'", "too large"]),
    (lambda r: r[9].append("7"), ["line 11", "cells where the header has"]),
    (lambda r: r[9].pop(), ["line 11", "cells where the header has"]),
    (lambda r: r[4].__setitem__(-1, "test"), ["line 6", "set must be fit or validation"]),
    (lambda r: r.insert(6, ["# a comment", ""]), None),
], ids=["text", "empty-joint", "partial-marker", "nan", "huge", "long-row", "short-row", "set", "comment"])
def test_faults_are_named_as_before(tmp_path, model, edit, words):
    lines = MEASUREMENTS.splitlines()
    rows = [ln.split(",") for ln in lines[1:]]
    edit(rows)
    (tmp_path / "d.csv").write_text(lines[0] + "\n" + "".join(",".join(c for c in r if c or len(r) > 2) + "\n"
                                                              for r in rows))
    if words is None:
        assert rc.read_measurements(tmp_path / "d.csv", model).n_poses == len(lines) - 1
        return
    with pytest.raises(rc.InputError) as e:
        rc.read_measurements(tmp_path / "d.csv", model)
    for w in words:
        assert w in str(e.value), (w, str(e.value))


@pytest.mark.parametrize("end", ["", "\n\n\n", "\r\n\r\n"], ids=["no-line-end", "blank-lines", "crlf-blank-lines"])
def test_the_last_rows_and_what_follows_them(tmp_path, model, monkeypatch, end):
    lines = MEASUREMENTS.splitlines()
    body = lines[1:] * 40
    newline = "\r\n" if end.startswith("\r") else "\n"
    (tmp_path / "d.csv").write_text(lines[0] + newline + newline.join(f"Q{i}" + b[b.index(","):] for i, b in
                                                                      enumerate(body)) + end, newline="")
    fast, slow = both(tmp_path / "d.csv", model, monkeypatch)
    identical(fast, slow)
    assert fast.n_poses == len(body) and fast.labels[-1] == f"Q{len(body) - 1}"


@pytest.mark.parametrize("change", ["crlf", "blank-line", "quoted-label", "comment-line", "trailing-separator",
                                    "bom", "spaces"])
def test_files_the_compiled_parser_leaves_to_the_row_reader_read_the_same(tmp_path, model, monkeypatch, change):
    lines = MEASUREMENTS.splitlines()
    if change == "crlf":
        text = "\r\n".join(lines) + "\r\n"
    elif change == "blank-line":
        text = "\n".join(lines[:5] + [""] + lines[5:]) + "\n"
    elif change == "quoted-label":
        text = "\n".join(lines[:3] + ['"P,3"' + lines[3][3:]] + lines[4:]) + "\n"
    elif change == "comment-line":
        text = "\n".join(lines[:3] + ["  # a note"] + lines[3:]) + "\n"
    elif change == "trailing-separator":
        text = "\n".join(ln + "," for ln in lines) + "\n"
    elif change == "bom":
        text = "\ufeff" + "\n".join(lines) + "\n"
    else:
        text = "\n".join(", ".join(ln.split(",")) for ln in lines) + "\n"
    (tmp_path / "d.csv").write_text(text, newline="")
    fast = rc.read_measurements(tmp_path / "d.csv", model)
    monkeypatch.setattr(reader, "_read_fast", rows_only)
    identical(fast, rc.read_measurements(tmp_path / "d.csv", model))


def test_spaces_around_labels_and_text(tmp_path, model, monkeypatch):
    lines = MEASUREMENTS.splitlines()
    text = lines[0] + "\n" + "\n".join(" " + ln.replace(",fit", ", fit ") for ln in lines[1:]) + "\n"
    (tmp_path / "d.csv").write_text(text)
    fast, slow = both(tmp_path / "d.csv", model, monkeypatch)
    identical(fast, slow)
    assert fast.labels[0] == "P01"


def test_sums_of_columns_read_the_same(tmp_path, model, monkeypatch):
    lines = MEASUREMENTS.splitlines()
    header, rows = lines[0].split(","), [ln.split(",") for ln in lines[1:]]
    k = [header.index(f"tool_{a}_mm") for a in "xyz"]
    rng = np.random.default_rng(8)
    out = []
    for i, r in enumerate(rows):
        d = rng.normal(0, 2, 3).round(6)
        target = [repr(float(float(r[j]) - v)) for j, v in zip(k, d)]
        cells = target + [repr(float(v)) for v in d] if i != 4 else [""] * 6  # row 4: the marker not seen
        out.append(r[:k[0]] + cells + r[k[2] + 1:])
    head = header[:k[0]] + ["x_t", "y_t", "z_t", "x_dif", "y_dif", "z_dif"] + header[k[2] + 1:]
    (tmp_path / "d.csv").write_text(",".join(head) + "\n" + "".join(",".join(r) + "\n" for r in out))
    sums = {f"{a}_t+{a}_dif": f"tool_{a}_mm" for a in "xyz"}
    fast, slow = both(tmp_path / "d.csv", model, monkeypatch, columns=sums)
    identical(fast, slow)
    assert not fast.mask[4].any() and fast.mask[5].all()
    out[6][k[0] + 3] = ""  # one part of a sum empty: the row reader names it
    (tmp_path / "d.csv").write_text(",".join(head) + "\n" + "".join(",".join(r) + "\n" for r in out))
    with pytest.raises(rc.InputError, match="line 8, column 'x_dif'"):
        rc.read_measurements(tmp_path / "d.csv", model, columns=sums)


def _split_files(tmp_path, *, points_sep=",", joints_sep=",", decimal=".", drop=(), extra_joint_rows=()):
    """The example as a file of points and a file of joint readings joined on ``pose`` (rows
    ``drop`` of the joint file left out, ``extra_joint_rows`` pose labels only the joint file has)."""
    lines = MEASUREMENTS.splitlines()
    header, rows = lines[0].split(","), [ln.split(",") for ln in lines[1:]]
    joint_cols = [k for k, c in enumerate(header) if c.startswith("j")]
    point_cols = [k for k in range(len(header)) if k not in joint_cols]

    def text(sep, cols, body):
        return "".join(sep.join(c.replace(".", decimal) for c in r) + "\n" for r in
                       [[header[k] for k in cols]] + [[r[k] for k in cols] for r in body])

    (tmp_path / "points.csv").write_text(text(points_sep, point_cols, rows))
    jrows = [r for i, r in enumerate(rows) if i not in drop][::-1] + [[p] + rows[0][1:] for p in extra_joint_rows]
    (tmp_path / "joints.csv").write_text(text(joints_sep, [0] + joint_cols, jrows))
    return tmp_path / "points.csv", tmp_path / "joints.csv"


@pytest.mark.parametrize("case", ["plain", "rows-left-out", "decimal-commas", "other-separator", "mapped"])
def test_joint_files_are_joined_by_the_compiled_parser_as_row_by_row(tmp_path, model, monkeypatch, case):
    kw: dict = {}
    if case == "decimal-commas":
        points, joints = _split_files(tmp_path, points_sep=";", joints_sep=";", decimal=",")
    elif case == "other-separator":
        points, joints = _split_files(tmp_path, joints_sep="\t")
    else:
        points, joints = _split_files(tmp_path, drop=(2, 7) if case == "rows-left-out" else (),
                                      extra_joint_rows=("Z1", "Z2") if case == "rows-left-out" else ())
    if case == "mapped":
        kw["columns"] = {"j1_deg": "j1_deg", "set": None}
    fast, slow = both(points, model, monkeypatch, joints=joints, **kw)
    identical(fast, slow)
    assert fast.extra["notes"]
    n = len(MEASUREMENTS.splitlines()) - 1
    assert fast.n_poses == (n - 2 if case == "rows-left-out" else n)
    if case == "rows-left-out":
        assert any("2 row(s) of" in note and "Z1, Z2" in note for note in fast.extra["notes"])


@pytest.mark.parametrize("fault, words", [
    ("repeated-key", ["appears twice"]), ("empty-key", ["empty key cell"]), ("no-match", ["no pose value is in both"]),
    ("column-in-both", ["is in both"]), ("text-reading", ["line 4", "expected a number"]),
])
def test_joint_file_faults_are_named_as_before(tmp_path, model, monkeypatch, fault, words):
    points, joints = _split_files(tmp_path)
    lines = joints.read_text().splitlines()
    if fault == "repeated-key":
        lines[5] = lines[3].split(",")[0] + lines[5][lines[5].index(","):]
    elif fault == "empty-key":
        lines[5] = lines[5][lines[5].index(","):]
    elif fault == "no-match":
        lines[1:] = ["X" + ln for ln in lines[1:]]
    elif fault == "column-in-both":
        lines = [ln + ",0" for ln in lines]
        lines[0] = lines[0][:-2] + ",tool_x_mm"
    else:
        lines[3] = lines[3][:lines[3].rindex(",")] + ",1x"
    joints.write_text("\n".join(lines) + "\n")
    with pytest.raises(rc.InputError) as e:
        rc.read_measurements(points, model, joints=joints)
    for w in words:
        assert w in str(e.value), (w, str(e.value))



@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
@given(data=st.data())
def test_mutated_files_read_the_same_by_both_readers(tmp_path_factory, model, data):
    """The fuzz's mutations of the example, alone or as points and joint readings joined on pose:
    the compiled reader gives the row reader's Measurements bit for bit, or the same one-line error."""
    from fuzz_cases import csv_file, split_joints

    folder = tmp_path_factory.mktemp("fuzz")
    joined = data.draw(st.booleans())
    if joined:
        points, joints = split_joints()
        which = data.draw(st.integers(0, 1))
        (folder / "d.csv").write_bytes(data.draw(csv_file(points)) if which == 0 else points.encode())
        (folder / "j.csv").write_bytes(data.draw(csv_file(joints)) if which == 1 else joints.encode())
    else:
        (folder / "d.csv").write_bytes(data.draw(csv_file()))
    kw = {"joints": folder / "j.csv"} if joined else {}

    def read(fast: bool):
        with pytest.MonkeyPatch.context() as mp:
            if not fast:
                mp.setattr(reader, "_read_fast", rows_only)
            try:
                return rc.read_measurements(folder / "d.csv", model, **kw)
            except rc.InputError as e:
                return str(e)

    fast, slow = read(True), read(False)
    if isinstance(slow, str) or isinstance(fast, str):
        assert fast == slow
    else:
        identical(fast, slow)


def _large(lines: list[str], rows: int) -> str:
    """The example's header and its rows repeated to ``rows`` poses of their own labels (a few MB)."""
    body = lines[1:]
    return lines[0] + "\n" + "".join(f"Q{i}" + body[i % len(body)][body[i % len(body)].index(","):] + "\n"
                                     for i in range(rows))


def test_a_large_file_is_read_compiled_without_pandas(tmp_path, model, monkeypatch):
    """The install the README gives has no pandas: a 4 MB tracker export is still parsed by the
    compiled reader, never cell by cell in Python."""
    (tmp_path / "d.csv").write_text(_large(MEASUREMENTS.splitlines(), 45_000))
    assert (tmp_path / "d.csv").stat().st_size > 4 * 2 ** 20
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas fails, as in that install
    parsed = []
    real = reader._parse_rows
    monkeypatch.setattr(reader, "_parse_rows", lambda *a, **k: parsed.append(1) or real(*a, **k))
    data = rc.read_measurements(tmp_path / "d.csv", model)
    assert data.n_poses == 45_000 and not parsed and not fallback_notes(data)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "rows"])
def test_a_value_beyond_a_trailing_separator_is_refused_by_both_readers(tmp_path, model, monkeypatch, compiled):
    """A header that ends with a separator names no column there: a row with a value in that cell is
    refused, whichever reader reads the file (and however large it is)."""
    lines = _large(MEASUREMENTS.splitlines(), 45_000).splitlines()
    lines = [ln + "," for ln in lines]
    lines[3000] += "21.5"
    (tmp_path / "d.csv").write_text("\n".join(lines) + "\n")
    if not compiled:
        monkeypatch.setattr(reader, "_read_fast", rows_only)
    width = len(lines[0].split(",")) - 1
    with pytest.raises(rc.InputError) as e:
        rc.read_measurements(tmp_path / "d.csv", model)
    assert (e.value.where, e.value.detail) == ("line 3001", f"{width + 1} cells where the header has {width} columns")
    lines[3000] = lines[3000][:-len("21.5")]        # the same file with that cell empty: read, the same
    (tmp_path / "d.csv").write_text("\n".join(lines) + "\n")
    assert rc.read_measurements(tmp_path / "d.csv", model).n_poses == 45_000


def test_the_summary_says_when_the_row_reader_read_the_file(tmp_path, cli):
    (tmp_path / "model.yaml").write_text(MODEL)
    lines = MEASUREMENTS.splitlines()
    (tmp_path / "plain.csv").write_text(MEASUREMENTS)
    (tmp_path / "quoted.csv").write_text("\n".join(lines[:3] + ['"P,3"' + lines[3][3:]] + lines[4:]) + "\n")
    said = {}
    for name in ("plain", "quoted"):
        code, out, err = cli("calibrate", tmp_path / "model.yaml", tmp_path / f"{name}.csv", "--out",
                             tmp_path / name)
        assert code in (0, 3), err
        said[name] = [ln for ln in out.splitlines() if ROW_BY_ROW in ln]
    assert said["plain"] == []
    assert len(said["quoted"]) == 1 and said["quoted"][0].endswith(f"quoted.csv: {ROW_BY_ROW}: quoted cells")


@pytest.fixture(scope="module")
def arm7():
    from pathlib import Path

    return rc.read_model(Path(__file__).resolve().parents[1] / "examples" / "arm7" / "model.yaml")


def _contacts_both(path, model):
    """(compiled, row by row) readings of a contact file, each a Contacts or its one-line error."""
    import robocal._files.contacts as contacts
    from robocal.io import read_contacts

    def read():
        try:
            return read_contacts(path, model)
        except rc.InputError as e:
            return str(e)

    fast = read()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(contacts, "_compiled", rows_only)
        slow = read()
    return fast, slow


def same_contacts(a, b) -> None:
    if isinstance(a, str) or isinstance(b, str):
        assert a == b
        return
    for name in ("q", "sigma"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and np.array_equal(x, y), name
    for name in ("marker", "kind", "target", "placement", "labels", "distances", "planes", "bars", "sha256"):
        assert getattr(a, name) == getattr(b, name), name
    assert [n for n in a.notes if ROW_BY_ROW not in n] == [n for n in b.notes if ROW_BY_ROW not in n]


def test_a_contact_file_is_read_compiled_as_row_by_row(tmp_path, arm7):
    from fuzz_cases import SOCKETS

    lines = SOCKETS.splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("placement"))
    labelled = lines[:k] + [lines[k] + ",label"] + [ln + f", s{i} " for i, ln in enumerate(lines[k + 1:])]
    for name, text in (("plain", SOCKETS), ("labelled", "\n".join(labelled) + "\n")):
        (tmp_path / f"{name}.csv").write_text(text)
        fast, slow = _contacts_both(tmp_path / f"{name}.csv", arm7)
        same_contacts(fast, slow)
        assert not [n for n in fast.notes if ROW_BY_ROW in n]
    assert fast.labels[0] == "s0" and fast.labels[-1] == f"s{len(lines) - k - 2}"
    quoted = "\n".join(lines[:k + 1] + ['"' + lines[k + 1].replace(",", '","') + '"'] + lines[k + 2:]) + "\n"
    (tmp_path / "quoted.csv").write_text(quoted)
    fast, slow = _contacts_both(tmp_path / "quoted.csv", arm7)
    same_contacts(fast, slow)
    said = [n for n in fast.notes if ROW_BY_ROW in n]
    assert said == [f"reading {tmp_path / 'quoted.csv'}: {ROW_BY_ROW}: quoted cells"]


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
@given(data=st.data())
def test_mutated_contact_files_read_the_same_by_both_readers(tmp_path_factory, arm7, data):
    from fuzz_cases import contacts_file

    path = tmp_path_factory.mktemp("contacts") / "c.csv"
    path.write_bytes(data.draw(contacts_file()))
    same_contacts(*_contacts_both(path, arm7))
