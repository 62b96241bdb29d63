"""Malformed inputs for every command, as hypothesis strategies, and the judge of one run.

Shared by the bounded fuzz test (tests/test_fuzz.py, in-process) and the large run
(benchmarks/fuzz_cli.py, one forked process per case with time and memory limits). A case is
``(files, argv)``: file path -> bytes (a path may hold folders: a folder of seatings), written into
an empty folder, and the command line run there.
Files are mutated from the shipped th8 example (cut small so a well-formed case runs quickly) and
from a small URDF chain; the mutations are the ones that broke readers: alias and entity bombs,
deep nesting, cycles, duplicate keys, huge numbers, other encodings, empty and binary files. A
file's bytes may be a ``Node`` instead: a FIFO, a pipe, a socket, a folder, a link, a read-only
file or folder, made where the case runs (``Materialised``).
"""

from __future__ import annotations

import functools
import json
import math
import re
import sqlite3
import tempfile
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path

from hypothesis import strategies as st

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "th8"
MODEL = (EXAMPLE / "model.yaml").read_text()
MEASUREMENTS = "\n".join((EXAMPLE / "measurements.csv").read_text().splitlines()[:31]) + "\n"
REPEATABILITY = "\n".join((EXAMPLE / "repeatability.csv").read_text().splitlines()[:41]) + "\n"


def _urdf(n: int = 3) -> str:
    links = "".join(f'<link name="l{i}"><inertial><mass value="1"/><origin xyz="0 0 0.1"/></inertial></link>'
                    for i in range(n + 1))
    joints = "".join(f'<joint name="j{i + 1}" type="{"prismatic" if i == 1 else "revolute"}"><parent link="l{i}"/>'
                     f'<child link="l{i + 1}"/><origin xyz="0 0 0.3" rpy="0 {0.5 * (i % 2)} 0"/>'
                     f'<axis xyz="0 0 1"/><limit lower="-1" upper="1"/></joint>' for i in range(n))
    return f'<?xml version="1.0"?>\n<robot name="r">\n{links}\n{joints}\n</robot>\n'


URDF = _urdf()

# robot programs for the th8 model (docs/formats.md, "Robot programs"), one per dialect
PROGRAMS = {
    "prog.mod": (EXAMPLE / "program.mod").read_text(),
    "prog.dat": "DEFDAT prog\nDECL E6AXIS XP1={A1 -97.3,A2 604.2,A3 324.84,A4 -68.1,A5 -17.008,A6 -169.804,E1 0.0}\n"
                "DECL E6POS XP2={X 628.819,Y 962.752,Z 1135.675,A 10.0,B 20.0,C 30.0,S 'B011',T 'B000010'}\n"
                "DECL FRAME TOOL={X 0.0,Y 0.0,Z 100.0,A 0.0,B 0.0,C 0.0}\nENDDAT\n",
    "prog.src": "DEF prog( )\n  PTP {A1 -112.72, A2 469.4, A3 388.32, A4 39.23, A5 -25.59, A6 178.996} ; start\n"
                "  LIN {X 375.660, Y -912.608, Z 929.978, A 45.0, B -30.0, C 170.0, S 6, T 2}\nEND\n",
    "prog.script": "def prog():\n  home = [-1.698, 0.6042, 0.32484, -1.1886, -0.29684, -2.96364]\n"
                   "  movej(home, a=1.4)\n"
                   "  movel(p[0.628819, 0.962752, 1.135675, 0.1, 0.2, 0.3], a=1.2, v=0.25)\nend\n",
}


def _joint_programs() -> tuple[str, dict]:
    """The measurement file split as a campaign logged by a controller: the instrument's points
    (pose label, marker columns, set) and the joint readings as controller code, one joint target
    per pose named by its label (RAPID jointtarget, KRL E6AXIS; mm and deg like the file's)."""
    rows = [ln.split(",") for ln in MEASUREMENTS.splitlines()]
    joints = [i for i, h in enumerate(rows[0]) if h.startswith("j")]
    points = "\n".join(",".join(c for i, c in enumerate(r) if i not in joints) for r in rows) + "\n"
    rapid = "".join(f"  CONST jointtarget {r[0]} := [[{', '.join(r[i] for i in joints)}], "
                    "[9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];\n" for r in rows[1:])
    krl = "".join(f"DECL E6AXIS {r[0]}={{{','.join(f'A{k + 1} {r[i]}' for k, i in enumerate(joints))},E1 0.0}}\n"
                  for r in rows[1:])
    return points, {"joints.mod": f"MODULE campaign\n{rapid}ENDMODULE\n",
                    "joints.dat": f"DEFDAT campaign\n{krl}ENDDAT\n"}


POINTS, JOINT_PROGRAMS = _joint_programs()

# values that broke number parsing, unit checks and argument types
NASTY = ("0", "-0", "-1", "1e308", "-1e308", "1e400", "99999999999999999999999999", "9" * 5000, "nan", "inf",
         "-inf", ".nan", ".inf", "abc", "", " ", "1,0", "0,1", ",", "1e-320", "0x10", "true", "null", "[]", "{}",
         "~", "é", "\x00", "1" * 100_000, "NaN", "Infinity", "-", "+", "1e", "mm", "deg", "base", "geometric",
         "100000000000", "2147483648", "-2147483649", "3.5", "1_000")
WORDS = ("geometric", "compliance", "base", "markers", "frames", "j2.alpha", "j1.theta", "tool.x", "xyz", "")

_NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w.])")


def inline_result(path) -> str:
    """The result file at ``path`` with its per-pose arrays inline (the seed of the result-file cases:
    one file to mutate, as result_to_dict writes it)."""
    from robocal.io import read_result, result_to_json

    return result_to_json(read_result(path))


def base_results(folder: Path) -> tuple[str, str]:
    """The seeds of the result-file cases, made in ``folder``: real results of the small example
    campaign (measured points) and of the cut arm7 socket file (contacts), per-pose arrays inline."""
    from robocal.cli import main

    (folder / "m.yaml").write_text(MODEL)
    (folder / "d.csv").write_text(MEASUREMENTS)
    (folder / "arm7.yaml").write_text(ARM7_MODEL)
    (folder / "sockets.csv").write_text(SOCKETS)
    for argv in ([str(folder / "m.yaml"), str(folder / "d.csv"), "--out", str(folder / "points")],
                 [str(folder / "arm7.yaml"), "--contacts", str(folder / "sockets.csv"),
                  "--out", str(folder / "contacts")]):
        code = main(["calibrate", *argv])
        assert code in (0, 3), (argv, code)
    return inline_result(folder / "points" / "result.json"), inline_result(folder / "contacts" / "result.json")


def _base(draw, result_text) -> str:
    """One of the seeds of the result-file cases (``result_text``: one, or a tuple of them)."""
    return result_text if isinstance(result_text, str) else draw(st.sampled_from(result_text))


# -- text mutations ------------------------------------------------------------------------------

@st.composite
def mutated_text(draw, base: str) -> bytes:
    """``base`` with a few line, token or byte edits, then encoded (usually UTF-8)."""
    lines = base.splitlines()
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(("number", "number", "delete", "duplicate", "swap", "cut", "insert", "token")))
        i = draw(st.integers(0, max(len(lines) - 1, 0)))
        if not lines:
            break
        if op == "number":
            found = list(_NUMBER.finditer(lines[i]))
            if found:
                m = found[draw(st.integers(0, len(found) - 1))]
                lines[i] = lines[i][:m.start()] + draw(st.sampled_from(NASTY)) + lines[i][m.end():]
        elif op == "delete":
            del lines[i]
        elif op == "duplicate":
            lines.insert(i, lines[i])
        elif op == "swap":
            j = draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
        elif op == "cut":
            lines[i] = lines[i][:draw(st.integers(0, len(lines[i])))]
        elif op == "insert":
            lines.insert(i, draw(st.text(max_size=20)))
        else:
            words = re.split(r"([,:\s{}\[\]<>=\"]+)", lines[i])
            k = draw(st.integers(0, len(words) - 1))
            words[k] = draw(st.sampled_from(NASTY + WORDS))
            lines[i] = "".join(words)
    text = "\n".join(lines) + "\n"
    encoding = draw(st.sampled_from(("utf-8",) * 8 + ("utf-16", "latin-1")))
    return text.encode(encoding, errors="replace")


def alias_bomb(levels: int = 9, key: str = "name") -> str:
    rows = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    rows += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, levels)]
    return "\n".join(rows) + f"\n{key}: *a{levels - 1}\n"


def deep(depth: int, kind: str) -> str:
    if kind == "flow":
        return "[" * depth + "]" * depth
    if kind == "json":
        return '{"a": ' * depth + "1" + "}" * depth
    return "".join(" " * i + "- \n" for i in range(min(depth, 2000)))  # block sequences, each one deeper


@st.composite
def model_file(draw) -> bytes:
    kind = draw(st.sampled_from(("mutated",) * 6 + ("bomb", "deep", "duplicate", "anchor", "huge", "empty",
                                                     "binary", "big_name")))
    if kind == "mutated":
        return draw(mutated_text(MODEL))
    if kind == "bomb":
        return (MODEL + alias_bomb(draw(st.integers(3, 10)), draw(st.sampled_from(("name", "description", "x"))))
                ).encode()
    if kind == "deep":
        nest = deep(draw(st.sampled_from((50, 1000, 20_000, 100_000))), draw(st.sampled_from(("flow", "block"))))
        return MODEL.replace("gravity: [0, 0, -9.81]", "gravity: " + nest.replace("\n", " ")
                             if "\n" not in nest else "gravity:\n" + nest).encode()
    if kind == "duplicate":
        lines = MODEL.splitlines()
        i = draw(st.integers(0, len(lines) - 1))
        return ("\n".join(lines[:i + 1] + [lines[i]] + lines[i + 1:]) + "\nunits: {length: m, angle: rad}\n").encode()
    if kind == "anchor":
        return MODEL.replace("units: {length: mm, angle: deg}", "units: &u {length: mm, angle: deg}\nx: *u").encode()
    if kind == "huge":
        value = draw(st.sampled_from(("1" * 400, "1e400", "-1e400", "1" * 5000)))
        return MODEL.replace("r: 600", "r: " + value).encode()
    if kind == "empty":
        return draw(st.sampled_from((b"", b"\n", b"---\n", b"# nothing\n", b"[]", b"3", b"null")))
    if kind == "binary":
        return draw(st.binary(min_size=1, max_size=200))
    return MODEL.replace("name: th8-like", "name: " + "x" * draw(st.sampled_from((100, 1_000_000)))).encode()


@st.composite
def csv_file(draw, base: str = MEASUREMENTS) -> bytes:
    kind = draw(st.sampled_from(("mutated",) * 6 + ("quote", "nul", "huge", "empty", "binary", "quaternion",
                                                     "wide")))
    if kind == "mutated":
        return draw(mutated_text(base))
    if kind == "quote":
        return (base + '"unclosed,1,2\n' + "x" * 200_000 + "\n").encode()
    if kind == "nul":
        return base.replace(",", ",\x00", 1).encode()
    if kind == "huge":
        lines = base.splitlines()
        cells = lines[2].split(",")
        cells[draw(st.integers(1, len(cells) - 1))] = draw(st.sampled_from(("1e300", "1e308", "-1e308", "1" * 400)))
        lines[2] = ",".join(cells)
        return ("\n".join(lines) + "\n").encode()
    if kind == "empty":
        return draw(st.sampled_from((b"", b"\n", b"pose\n", base.splitlines()[0].encode() + b"\n")))
    if kind == "binary":
        return draw(st.binary(min_size=1, max_size=200))
    if kind == "quaternion":
        lines = base.splitlines()
        q = draw(st.sampled_from(("0,0,0,1", "0,0,0,0", "nan,0,0,1", "1e308,1e308,0,0", "a,b,c,d", "0,0,1", "")))
        lines[0] += ",tool_qx,tool_qy,tool_qz,tool_qw"
        lines[1:] = [ln + ",0,0,0,1" for ln in lines[1:]]
        lines[2] = lines[2][:-len(",0,0,0,1")] + "," + q
        return ("\n".join(lines) + "\n").encode()
    return (base.splitlines()[0] + ",x" * draw(st.sampled_from((10, 5000))) + "\n").encode()


@st.composite
def urdf_file(draw) -> bytes:
    kind = draw(st.sampled_from(("mutated",) * 5 + ("cycle", "self", "entity", "deep", "huge", "empty", "binary",
                                                     "branch", "base_marker")))
    if kind == "mutated":
        return draw(mutated_text(URDF.replace("><", ">\n<")))
    if kind == "cycle":
        return URDF.replace("</robot>", '<joint name="back" type="revolute"><parent link="l3"/><child link="l1"/>'
                            '<axis xyz="0 0 1"/><limit lower="-1" upper="1"/></joint></robot>').encode()
    if kind == "self":
        return URDF.replace('<child link="l1"/>', '<child link="l0"/>').encode()
    if kind == "entity":
        bomb = '<!DOCTYPE r [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]>'
        return URDF.replace('<robot name="r">', bomb + '<robot name="&b;">').encode()
    if kind == "deep":
        n = draw(st.sampled_from((100, 10_000, 200_000)))
        return URDF.replace("</robot>", "<a>" * n + "</a>" * n + "</robot>").encode()
    if kind == "huge":
        value = draw(st.sampled_from(("1e400", "1" * 400, "nan")))
        return URDF.replace('xyz="0 0 0.3"', 'xyz="0 0 ' + value + '"', 1).encode()
    if kind == "empty":
        return draw(st.sampled_from((b"", b"<robot/>", b'<robot name="r"></robot>', b"<?xml version='1.0'?>")))
    if kind == "binary":
        return draw(st.binary(min_size=1, max_size=200))
    if kind == "branch":
        return _urdf(draw(st.integers(0, 12))).replace("</robot>", '<link name="x"/><joint name="jx" type="fixed">'
                                                       '<parent link="l0"/><child link="x"/></joint></robot>').encode()
    return URDF.replace('name="l3"', 'name="base"').replace('link="l3"', 'link="base"').encode()


# -- result files: edits of a real one ------------------------------------------------------------

def _paths(d, prefix=()):
    yield prefix
    if isinstance(d, dict):
        for k, v in d.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(d, list):
        for i, v in enumerate(d[:3]):
            yield from _paths(v, prefix + (i,))


@st.composite
def result_file(draw, base: str) -> bytes:
    kind = draw(st.sampled_from(("edit",) * 8 + ("deep", "duplicate", "nan", "huge", "large", "empty", "binary",
                                                 "bytes")))
    if kind == "bytes":
        return draw(mutated_text(base))
    if kind == "deep":
        return deep(draw(st.sampled_from((100, 10_000, 200_000))), "json").encode()
    if kind == "duplicate":
        return base.replace('"loss"', '"loss": "x", "loss"', 1).encode()
    if kind == "nan":
        text = base.replace('"nfev": ', '"nfev": NaN, "x": ', 1)
        return text.replace('"sigma0_m": ', '"sigma0_m": Infinity, "y": ', 1).encode()
    if kind == "huge":
        return base.replace('"nfev": ', '"nfev": ' + "9" * draw(st.sampled_from((30, 5000))) + ', "x": ', 1).encode()
    if kind == "empty":
        return draw(st.sampled_from((b"", b"{}", b"[]", b"null", b'{"schema": "robocal.result/1"}')))
    if kind == "binary":
        return draw(st.binary(min_size=1, max_size=200))
    d = json.loads(base)
    if kind == "large":
        errors = d["errors"]
        n = draw(st.sampled_from((1000, 5000)))
        for key, v in list(errors.items()):
            if isinstance(v, list) and v and key != "markers":
                errors[key] = (v * (n // len(v) + 1))[:n]
        return json.dumps(d).encode()
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p in _paths(d) if p]
        path = paths[draw(st.integers(0, len(paths) - 1))]
        parent = d
        for k in path[:-1]:
            parent = parent[k]
        op = draw(st.sampled_from(("delete", "value", "value", "empty")))
        if op == "delete":
            del parent[path[-1]]
        elif op == "empty":
            parent[path[-1]] = [] if isinstance(parent[path[-1]], list) else {}
        else:
            parent[path[-1]] = draw(st.sampled_from((None, True, 0, -1, 1e308, -1e308, 10 ** 30, "x", [], {}, [[]],
                                                     [None], {"a": 1}, "1" * 1000, 2 ** 63)))
    return json.dumps(d).encode()


# -- stores of calibrations: a real one, damaged ------------------------------------------------------

@functools.lru_cache(maxsize=2)
def store_bytes(result_text: str) -> bytes:
    """A store holding the result twice as calibrations of robot R (type th8)."""
    import robocal as rc

    result = rc.io.result_from_dict(json.loads(result_text))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "store.sqlite"
        with rc.open_store(path, create=True) as store:
            for at in ("2026-01-01", "2026-06-01"):
                store.record(result, "R", robot_type="th8", at=at)
        return path.read_bytes()


# edits of a store's content that keep it a SQLite file
STORE_EDITS = (
    "UPDATE robocal_schema SET version = 99", "UPDATE robocal_schema SET version = 'x'", "DELETE FROM robocal_schema",
    "INSERT INTO robocal_schema VALUES (2)", "UPDATE robocal_schema SET version = 1",
    "DROP TABLE robocal_verifications",
    "DROP TABLE robocal_calibrations", "UPDATE robocal_calibrations SET parameters = '[1, 2]'",
    "UPDATE robocal_calibrations SET parameters = 'not json'", "UPDATE robocal_calibrations SET estimates = x'00'",
    "UPDATE robocal_calibrations SET estimates = randomblob(8 * 54)",
    "UPDATE robocal_calibrations SET checks = '[[1]]'",
    "UPDATE robocal_calibrations SET accuracy = '{\"rms\": \"x\"}'",
    "UPDATE robocal_calibrations SET accuracy = '{\"rms\": -1, \"n\": 0, \"source\": \"x\"}'",
    "UPDATE robocal_calibrations SET accuracy = '[]'", "UPDATE robocal_calibrations SET in_use = '5'",
    "UPDATE robocal_calibrations SET calibrated_model = 'nope'", "UPDATE robocal_calibrations SET inputs = '[]'",
    "UPDATE robocal_calibrations SET calibrated_at = 'yesterday'", "UPDATE robocal_calibrations SET robot = 7",
    "UPDATE robocal_calibrations SET verdict = x'ff'", "UPDATE robocal_models SET document = x'789c'",
    "UPDATE robocal_models SET document = zeroblob(10)", "DELETE FROM robocal_models",
    "UPDATE robocal_calibrations SET correlation = x'00'",
    "UPDATE robocal_calibrations SET correlation = randomblob(length(correlation))",
    "UPDATE robocal_calibrations SET correlation = substr(correlation, 1, length(correlation) / 2)",
)
BAD_MODELS = (b'{"frames": 1}', b"[]", b"\xff\xfe", b'{"name": "x"}')
# another application's SQLite databases: never made a store, left byte for byte
FOREIGN_TABLES = ("CREATE TABLE accounts (id INTEGER PRIMARY KEY, name TEXT)",
                  "CREATE TABLE robocal_schema (version INTEGER); CREATE TABLE invoices (n INTEGER)",
                  "CREATE TABLE t (x); PRAGMA user_version = 7")
# --store values that name no SQLite file: URLs of other schemes
OTHER_URLS = ("mysql://cal@plant/robocal", "sqlite:///store.sqlite", "https://plant/store", "file:store.sqlite")


@functools.lru_cache(maxsize=len(FOREIGN_TABLES))
def foreign_bytes(script: str) -> bytes:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "other.db"
        c = sqlite3.connect(path)
        c.executescript(script)
        c.commit()
        c.close()
        return path.read_bytes()


@st.composite
def store_file(draw, base: bytes) -> bytes:
    kind = draw(st.sampled_from(("good",) * 3 + ("edit",) * 4 + ("model", "flip", "cut", "empty", "binary", "foreign")))
    if kind == "good":
        return base
    if kind == "foreign":
        return foreign_bytes(draw(st.sampled_from(FOREIGN_TABLES)))
    if kind == "empty":
        return draw(st.sampled_from((b"", b"SQLite format 3\x00", b"\x00" * 4096)))
    if kind == "binary":
        return draw(st.binary(min_size=1, max_size=300))
    if kind == "cut":
        return base[:draw(st.integers(0, len(base) - 1))]
    if kind == "flip":
        data = bytearray(base)
        for _ in range(draw(st.integers(1, 8))):
            data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
        return bytes(data)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "s.sqlite"
        path.write_bytes(base)
        with sqlite3.connect(path) as c:
            try:
                if kind == "model":
                    c.execute("UPDATE robocal_models SET document = ?",
                              (zlib.compress(draw(st.sampled_from(BAD_MODELS))),))
                else:
                    for edit in draw(st.lists(st.sampled_from(STORE_EDITS), min_size=1, max_size=2)):
                        c.execute(edit)
            except sqlite3.Error:
                pass                    # an edit the schema refuses: the store stays as it was
        c.close()
        return path.read_bytes()


# -- command lines -------------------------------------------------------------------------------

def _value(draw, good):
    return draw(st.sampled_from((good,) * 3 + NASTY[:30])) if draw(st.booleans()) else good


@st.composite
def options(draw, table: dict) -> list[str]:
    """Some of ``table``'s options (name -> a good value, None for a flag), each maybe spoiled."""
    argv = []
    for name, good in table.items():
        if draw(st.integers(0, 3)) == 0:
            argv += [name] if good is None else [name, _value(draw, good)]
    return argv


ARM7 = Path(__file__).resolve().parents[1] / "examples" / "arm7"
ARM7_MODEL = (ARM7 / "model.yaml").read_text()
TRUE_MODEL = (EXAMPLE / "true_model.yaml").read_text()
TARGETS = (EXAMPLE / "targets.csv").read_text()
DH_TABLE = (Path(__file__).resolve().parents[1] / "examples" / "dh" / "ur5-dh.csv").read_text()
DH_HEADER = next(ln for ln in DH_TABLE.splitlines() if ln.startswith("name,"))


def _sockets() -> str:
    """The arm7 socket file cut to 8 seatings per socket on three placements."""
    lines = (ARM7 / "sockets.csv").read_text().splitlines()
    head = [ln for ln in lines if ln.startswith(("#", "placement"))]
    rows = [ln for ln in lines[len(head):] if ln.split(",")[0] in ("P1", "P2", "P3")]
    keep = [r for k, r in enumerate(rows) if k % 20 < 8]
    return "\n".join(head + keep) + "\n"


SOCKETS = _sockets()
PROFILE = """robocal_profile: 1
name: tracker export
sep: ","
decimal: "."
units: mm-deg
key: pose
columns:
  pose: pose
ignore: []
unknown: refuse
"""
LIMIT_FILE = '{"schema": "robocal.limit/1", "unit": "m", "limit": 0.0005, "repeatability": 0.0002}\n'


def long_dh(n: int) -> str:
    """A classic DH table of ``n`` revolute joints (a chain far longer than any robot)."""
    rows = [f"j{i},revolute,0,{100 + i % 7},{50 * (i % 3)},{90 * (i % 2)},-180,180,,,,,," for i in range(n)]
    head = DH_HEADER
    return "# convention: classic\n" + head + "\n" + "\n".join(rows) + "\ntool,marker,,,,,,,0,0,100,0,0,0\n"


@st.composite
def dh_file(draw) -> bytes:
    kind = draw(st.sampled_from(("mutated",) * 6 + ("long", "quote", "nul", "huge", "empty", "binary", "mdh")))
    if kind == "mutated":
        return draw(mutated_text(DH_TABLE))
    if kind == "long":
        return long_dh(draw(st.sampled_from((20, 200, 2000, 100_000)))).encode()
    if kind == "quote":
        return (DH_TABLE + '"unclosed,1,2\n' + "x" * draw(st.sampled_from((10, 200_000))) + "\n").encode()
    if kind == "nul":
        return DH_TABLE.replace(",", ",\x00", 1).encode()
    if kind == "huge":
        return DH_TABLE.replace("-425", draw(st.sampled_from(("1e300", "1e12", "-1e11", "1" * 400, "nan", "inf")))
                                ).encode()
    if kind == "empty":
        return draw(st.sampled_from((b"", b"\n", DH_HEADER.encode() + b"\n", b"frame,r\n")))
    if kind == "binary":
        return draw(st.binary(min_size=1, max_size=200))
    return draw(mutated_text(MDH_TABLE))


MDH_TABLE = """frame,parent,joint,reading,beta_deg,alpha_deg,d_mm,theta_deg,r_mm,lower_deg,upper_deg,x_mm,y_mm,z_mm,\
roll_deg,pitch_deg,yaw_deg
base,world,base,,,,,,,,,0.0,0.0,0.0,0.0,0.0,0.0
j1,base,revolute,j1,0.0,0.0,0.0,0.0,340.0,-170.0,170.0,,,,,,
j2,j1,revolute,j2,0.0,-90.0,0.0,0.0,0.0,-120.0,120.0,,,,,,
j3,j2,revolute,j3,0.0,90.0,0.0,0.0,400.0,-170.0,170.0,,,,,,
ball,j3,marker,,,,,,,,,30.0,20.0,100.0,0.0,0.0,0.0
"""


@st.composite
def contacts_file(draw) -> bytes:
    kind = draw(st.sampled_from(("mutated",) * 6 + ("distances", "rows", "groups", "quote", "nul", "empty", "binary",
                                                     "sigma")))
    if kind == "mutated":
        return draw(mutated_text(SOCKETS))
    lines = SOCKETS.splitlines()
    head = [ln for ln in lines if ln.startswith(("#", "placement"))]
    rows = lines[len(head):]
    if kind == "distances":
        n = draw(st.sampled_from((50, 5000, 100_000)))
        extra = [f"# distance: A B {200 + k * 1e-6:.6f} sigma=0.002" for k in range(n)]
        return "\n".join(head[:2] + extra + head[2:] + rows).encode() + b"\n"
    if kind == "rows":
        n = draw(st.sampled_from((2000, 300_000)))
        return "\n".join(head + (rows * (n // len(rows) + 1))[:n]).encode() + b"\n"
    if kind == "groups":
        n = draw(st.sampled_from((100, 5000, 50_000)))
        many = [f"Q{k // 3},{'ABC'[k % 3]}{k},socket,ball," + ",".join(r.split(",")[4:]) for k, r in
                enumerate((rows * (n // len(rows) + 1))[:n])]
        return "\n".join(head + many).encode() + b"\n"
    if kind == "quote":
        return (SOCKETS + '"P9,A,socket\n' + "x" * 200_000 + "\n").encode()
    if kind == "nul":
        return SOCKETS.replace(",socket", ",\x00socket", 1).encode()
    if kind == "empty":
        return draw(st.sampled_from((b"", b"\n", "\n".join(head).encode() + b"\n", b"# robocal contacts\n")))
    if kind == "binary":
        return draw(st.binary(min_size=1, max_size=200))
    value = draw(st.sampled_from(("0", "1e-300", "1e300", "-1", "nan", "")))
    return "\n".join(head + [r.rsplit(",", 1)[0] + "," + value for r in rows]).encode() + b"\n"


@st.composite
def profile_file(draw) -> bytes:
    kind = draw(st.sampled_from(("mutated",) * 5 + ("tag", "bomb", "deep", "empty", "binary", "columns")))
    if kind == "mutated":
        return draw(mutated_text(PROFILE))
    if kind == "tag":
        return PROFILE.replace("name: tracker export", "name: " + draw(st.sampled_from(
            ("!!float abc", "!!int x", "!!binary x", "!!python/object:os.system x", "!!timestamp q", "!!set {a}",
             "!!omap [a]", "!!str")))).encode()
    if kind == "bomb":
        return (PROFILE + alias_bomb(draw(st.integers(3, 10)), "zz")).encode()
    if kind == "deep":
        return PROFILE.replace("ignore: []", "ignore: " + deep(draw(st.sampled_from((50, 20_000))), "flow")).encode()
    if kind == "empty":
        return draw(st.sampled_from((b"", b"robocal_profile: 1\n", b"[]", b"null")))
    if kind == "binary":
        return draw(st.binary(min_size=1, max_size=200))
    n = draw(st.sampled_from((100, 100_000)))
    return (PROFILE + "".join(f"  c{k}: tool_x\n" for k in range(n))).encode()


@st.composite
def limit_file(draw) -> bytes:
    kind = draw(st.sampled_from(("value", "value", "mutated", "schema", "deep", "empty", "binary")))
    if kind == "value":
        v = draw(st.sampled_from(("0", "-1", "1e-300", "1e308", "1e400", "NaN", "null", '"x"', "true", "[]",
                                  "1" * 5000, "2", "1e-12", "0.0005")))
        return LIMIT_FILE.replace("0.0005", v).encode()
    if kind == "mutated":
        return draw(mutated_text(LIMIT_FILE))
    if kind == "schema":
        return LIMIT_FILE.replace("robocal.limit/1", draw(st.sampled_from(("robocal.result/1", "", "x")))).encode()
    if kind == "deep":
        return deep(draw(st.sampled_from((100, 200_000))), "json").encode()
    if kind == "empty":
        return draw(st.sampled_from((b"", b"{}", b"[]", b"null")))
    return draw(st.binary(min_size=1, max_size=200))


@st.composite
def yaml_tag_model(draw, base: str = MODEL) -> bytes:
    """A model with a YAML tag where a number is expected."""
    tag = draw(st.sampled_from(("!!float abc", "!!float 1e400", "!!int x", "!!int 1e3", "!!float", "!!bool x",
                                "!!null x", "!!float .nan", "!!binary x", "!!timestamp x")))
    return base.replace("r: 600", f"r: {tag}", 1).encode()


@st.composite
def limits_model(draw, base: str = MODEL) -> bytes:
    """A model with huge, tiny or inverted joint limits."""
    lo, hi = draw(st.sampled_from((("-1e11", "1e11"), ("-1e300", "1e300"), ("0", "0"), ("-1e-300", "1e-300"),
                                   ("1e11", "1e11"), ("-99999999999", "99999999999"), ("5", "5.000000000001"))))
    return re.sub(r"limits: \[[^\]]*\]", f"limits: [{lo}, {hi}]", base, count=draw(st.integers(1, 6))).encode()


def _model(draw, base: str = MODEL) -> bytes:
    kind = draw(st.integers(0, 8))
    if kind < 5:
        return base.encode()
    if kind == 5:
        return draw(yaml_tag_model(base))
    if kind == 6:
        return draw(limits_model(base))
    return draw(mutated_text(base)) if base is not MODEL else draw(model_file())


CALIBRATE = {"--parameters": "geometric", "--known": "base", "--tol": "1e-6", "--loss": "soft_l1",
             "--limit-mm": "0.5", "--holdout": "0.2", "--seed": "1", "--noise-mm": "0.02", "--noise-deg": "0.01",
             "--out-units": "m-rad", "--units": "mm-deg", "--sep": ",", "--decimal": ".", "--orientation": "quat_xyzw",
             "--weak": "flag", "--on-outliers": "flag", "--write-failed": None, "--register-base": None,
             "--compare": None, "--instrument": "cmm", "--nonnegative-compliance": None,
             "--map": "=pose,tool_x_mm+j1_deg=tool_x_mm", "--header": MEASUREMENTS.splitlines()[0], "--diagnose": None,
             "--folds": "3", "--register-validation": None}
SIMULATE = {"--seed": "3", "--noise-mm": "0.02", "--length-error-mm": "0.1,1", "--angle-error-deg": "0.01,0.1",
            "--parameters": "geometric", "--units": "m-rad", "--true-model": "true.yaml"}
IDENTIFIABILITY = {"--parameters": "geometric,compliance", "--known": "base", "--tol": "1e-6", "--poses": "30",
                   "--seed": "2"}
LIMIT = {"--seed": "1", "--markers": "all", "--chunk-size": "100", "--csv-units": "mm"}
COMPENSATE_PROGRAM = {"--tool": "TOOL", "--wobj": "TOOL", "--marker": "tool", "--tol-mm": "0.001",
                      "--tol-deg": "0.0001", "--force": None}
IMPORT_URDF = {"--base-link": "l0", "--tip-link": "l3", "--marker-mm": "tool,0,0,10", "--units": "m-rad"}
PLAN = {"--criterion": "D", "--parameters": "geometric", "--known": "base", "--tol": "1e-6", "--instrument": "cmm",
        "--noise-mm": "0.02", "--seed": "4", "--out-units": "m-rad"}
PLAN_SOCKETS = {"--joint-noise-deg": "0.001", "--length-std-mm": "1", "--angle-std-deg": "0.1", "--seed": "2"}
COMPENSATE = {"--marker": "tool", "--position-only": None, "--tol-mm": "0.001", "--tol-deg": "0.0001",
              "--out-units": "m-rad", "--units": "mm-deg"}
CONTACTS = {"--parameters": "geometric", "--known": "base", "--tol": "1e-6", "--loss": "soft_l1",
            "--holdout-placement": "P3", "--write-failed": None, "--instrument": "cmm", "--noise-mm": "0.02",
            "--on-outliers": "flag", "--out-units": "m-rad", "--holdout": "0.4", "--seed": "2", "--compare": None,
            "--register-validation": None, "--register-base": None, "--diagnose": None, "--weak": "flag",
            "--limit-mm": "0.5", "--backlash-side": "approach", "--noise-deg": "0.01", "--folds": "3",
            "--nonnegative-compliance": None, "--report": None}
BIG_COUNTS = ("1000", "100000", "99999999999", "1000000")

RECORD = {"--type": "th8", "--at": "2026-09-01T00:00:00Z"}
HISTORY = {"--alpha": "0.05", "--report": "history.html", "--force": None}
VERIFY = {"--register-base": None, "--alpha": "0.01", "--no-record": None, "--at": "2026-10-01", "--units": "mm-deg"}
STORE_COMMANDS = ("record", "history", "verify")


@st.composite
def program_file(draw, base: str) -> bytes:
    """A robot program, mutated or broken the ways that break program readers."""
    kind = draw(st.sampled_from(("mutated",) * 6 + ("deep", "unclosed", "huge", "empty", "binary", "many")))
    if kind == "mutated":
        return draw(mutated_text(base))
    if kind == "deep":
        n = draw(st.sampled_from((40, 1000, 100_000)))
        return (base + "\nCONST robtarget deep := " + "[" * n + "1" + "]" * n + ";\n").encode()
    if kind == "unclosed":
        return base.replace("]", "", 1).replace("}", "", 1).replace(")", "", 1).encode()
    if kind == "huge":
        return re.sub(r"\d+\.\d+", draw(st.sampled_from(("1e400", "1" * 400, "-1e308", "0.0"))), base, count=3).encode()
    if kind == "empty":
        return draw(st.sampled_from((b"", b"\n", b"MODULE m\nENDMODULE\n", b"DEF a()\nEND\n")))
    if kind == "binary":
        return bytes(range(256)) * 4
    line = next((ln for ln in base.splitlines() if re.search(r"\d", ln)), "")
    return (base + ("\n" + line) * draw(st.sampled_from((100, 5000)))).encode()


def split_joints(base: str = MEASUREMENTS) -> tuple[str, str]:
    """``base`` as a file of points (every column but the joints') and a file of joint readings
    (``pose`` and the joints' columns), joined on ``pose`` (``--joints``)."""
    rows = [ln.split(",") for ln in base.splitlines()]
    joints = [k for k, c in enumerate(rows[0]) if k == 0 or c.startswith("j")]
    points = [k for k in range(len(rows[0])) if k == 0 or k not in joints]
    texts = ["".join(",".join(r[k] for k in cols if k < len(r)) + "\n" for r in rows) for cols in (points, joints)]
    return texts[0], texts[1]


# -- one strategy per command: a command or reader added later joins here and in COMMANDS ---------

@st.composite
def calibrate_case(draw, result_text=None):
    files = {"model.yaml": _model(draw)}
    good_model = files["model.yaml"] == MODEL.encode()
    files["data.csv"] = draw(csv_file()) if good_model or draw(st.booleans()) else MEASUREMENTS.encode()
    argv = ["calibrate", "model.yaml", "data.csv", "--out", draw(st.sampled_from(("out", "out", "model.yaml")))]
    argv += draw(options(CALIBRATE))
    reader = draw(st.integers(0, 6))
    if reader == 0:   # an instrument profile
        files["profile.yaml"] = draw(profile_file())
        argv += ["--profile", "profile.yaml"]
    elif reader == 1:  # a limit file given as --limit-mm
        files["limit.json"] = draw(limit_file())
        argv += ["--limit-mm", "limit.json"]
    elif reader == 2:  # and keep it in a store (never the user's default one)
        argv += ["--record", _value(draw, "R"), "--store", "store.sqlite"] + draw(options({"--type": "th8"}))
    elif reader == 3:  # held-out measurements to judge on, maybe from another set-up
        files["val.csv"] = draw(csv_file()) if draw(st.booleans()) else MEASUREMENTS.encode()
        argv += ["--validate", "val.csv"] + (["--register-validation"] if draw(st.booleans()) else [])
    elif reader == 4:  # the joint readings in a file of their own, joined on pose; one of the two mutated
        points, joints = split_joints()
        mutated = draw(st.integers(0, 2))
        files["data.csv"] = draw(csv_file(points)) if mutated == 0 else points.encode()
        files["joints.csv"] = draw(csv_file(joints)) if mutated == 1 else joints.encode()
        argv += ["--joints", "joints.csv"]
    return files, argv


# numbers a valid campaign may hold that make its fit degenerate or ill-posed (mm and degrees)
JITTERS = (0.0, 1e-12, 1e-6, 1e-3, 1.0, 100.0)
POSITION_FACTORS = (-1.0, 1e-3, 0.999, 1.0001, 1e3)
NUMBER_OPTIONS = {"--compare": None,
                  "--parameters": ("geometric", "geometric,compliance", "geometric,backlash", "base", "markers"),
                  "--known": ("markers", "base", "j2.*"), "--loss": ("soft_l1", "huber", "linear"),
                  "--weak": ("flag",), "--on-outliers": ("flag", "refit"), "--folds": ("2", "3", "10", "50"),
                  "--holdout": ("0.1", "0.5", "0.9"), "--limit-mm": ("0.001", "0.5", "100"),
                  "--noise-mm": ("1e-6", "0.02", "5"), "--instrument": ("cmm", "theodolite"), "--seed": ("3",),
                  "--diagnose": None, "--register-base": None, "--nonnegative-compliance": None}


@st.composite
def numbers_case(draw, result_text=None):
    """calibrate on the example's campaign with valid files and options whose numbers make the fit
    degenerate or ill-posed: few poses, copies, missing points, a joint that never moves, readings a
    whole turn off, points scaled, shifted, jittered or all alike."""
    lines = MEASUREMENTS.splitlines()
    head, rows = lines[0], [ln.split(",") for ln in lines[1:]]
    order = draw(st.permutations(range(len(rows))))
    rows = [rows[i] for i in order[:draw(st.sampled_from((4, 12, 20, 30, 30, 30)))]]
    rows += [list(rows[draw(st.integers(0, len(rows) - 1))]) for _ in range(draw(st.sampled_from((0, 0, 1, 5))))]
    joints, points = range(1, 7), range(7, 10)
    for _ in range(draw(st.integers(0, 3))):
        op = draw(st.sampled_from(("blank", "still", "turn", "scale", "shift", "jitter", "alike", "swap", "set")))
        k = draw(st.integers(0, len(rows) - 1))
        if op == "blank":               # a point not measured on some rows
            for r in rows[k:k + draw(st.integers(1, len(rows)))]:
                for c in points:
                    r[c] = ""
        elif op in ("still", "turn", "swap"):
            j = draw(st.sampled_from(joints))
            i = draw(st.sampled_from(joints))
            for r in rows:
                if op == "still":
                    r[j] = rows[k][j]
                elif op == "turn" and draw(st.booleans()):
                    r[j] = repr(float(r[j]) + 360.0)
                elif op == "swap":
                    r[j], r[i] = r[i], r[j]
        elif op in ("scale", "shift", "jitter", "alike"):
            factor = draw(st.sampled_from(POSITION_FACTORS))
            shift = draw(st.sampled_from((1e6, -3e4, 0.5)))
            size = draw(st.sampled_from(JITTERS))
            cols = points if op != "jitter" or draw(st.booleans()) else joints
            source = list(rows[k])
            for r in rows:
                for c in cols:
                    cell = source[c] if op == "alike" else r[c]
                    if cell and r[c]:               # a point not measured stays so
                        v = float(cell)
                        v = v * factor if op == "scale" else v + shift if op == "shift" else \
                            v + draw(st.floats(-size, size)) if op == "jitter" else v
                        r[c] = repr(v)
        else:                           # which rows are held out
            kind = draw(st.sampled_from(("fit", "validation", "mixed")))
            for n, r in enumerate(rows):
                r[10] = kind if kind != "mixed" else ("fit", "validation")[n % 2]
    files = {"model.yaml": MODEL.encode(),
             "data.csv": ("\n".join([head] + [",".join(r) for r in rows]) + "\n").encode()}
    argv = ["calibrate", "model.yaml", "data.csv", "--out", "out"]
    for name, values in NUMBER_OPTIONS.items():
        if draw(st.integers(0, 3)) == 0 and not (name == "--parameters" and "--compare" in argv):
            argv += [name] if values is None else [name, draw(st.sampled_from(values))]
    return files, argv


@st.composite
def simulate_case(draw, result_text=None):
    files = {"model.yaml": _model(draw)}
    argv = ["simulate", "model.yaml", "--out", "sim.csv", "--poses", _value(draw, "20")]
    return files, argv + draw(options(SIMULATE))


@st.composite
def identifiability_case(draw, result_text=None):
    files = {"model.yaml": _model(draw)}
    argv = ["identifiability", "model.yaml"] + draw(options(IDENTIFIABILITY))
    if draw(st.booleans()):
        files["data.csv"] = draw(csv_file())
        argv.insert(2, "data.csv")
    return files, argv


@st.composite
def limit_case(draw, result_text=None):
    files = {"model.yaml": _model(draw)}
    good_model = files["model.yaml"] == MODEL.encode()
    files["rep.csv"] = draw(csv_file(REPEATABILITY)) if good_model else REPEATABILITY.encode()
    source = ["--repeatability-csv", "rep.csv"] if draw(st.booleans()) else \
        ["--repeatability-mm", _value(draw, "0.05")]
    argv = ["limit", "model.yaml", *source, "--encoder-resolution",
            _value(draw, "0.01deg,0.01mm,0.01mm,0.01deg,0.01deg,0.01deg"),
            "--length-quantum-mm", _value(draw, "0.01"), "--angle-quantum-deg", _value(draw, "0.001"),
            "--samples", _value(draw, "200"), "--out", "limit.json"] + draw(options(LIMIT))
    return files, argv


@st.composite
def import_urdf_case(draw, result_text=None):
    urdf = _urdf(draw(st.sampled_from((50, 500, 5000)))).encode() if draw(st.integers(0, 15)) == 0 \
        else draw(urdf_file())
    return {"robot.urdf": urdf}, ["import-urdf", "robot.urdf", "--out", "imported.yaml"] + draw(options(IMPORT_URDF))


@st.composite
def report_case(draw, result_text=None):
    return {"result.json": draw(result_file(_base(draw, result_text)))}, ["report", "result.json", "--out",
                                                                         "report.html"]


@st.composite
def plan_case(draw, result_text=None):
    files = {"model.yaml": _model(draw)}
    big = draw(st.integers(0, 9)) == 0
    n = draw(st.sampled_from(BIG_COUNTS)) if big else _value(draw, draw(st.sampled_from(("6", "12", "20"))))
    argv = ["plan", "model.yaml", "--poses", n, "--out", "poses.csv"]
    if draw(st.booleans()):
        files["cand.csv"] = draw(csv_file()) if draw(st.booleans()) else MEASUREMENTS.encode()
        argv += ["--candidates", "cand.csv"]
    else:
        argv += ["--n-candidates", draw(st.sampled_from(BIG_COUNTS)) if draw(st.integers(0, 9)) == 0
                 else _value(draw, draw(st.sampled_from(("100", "300"))))]
    return files, argv + draw(options(PLAN))


@st.composite
def plan_sockets_case(draw, result_text=None):
    files = {"model.yaml": _model(draw, ARM7_MODEL)}
    big = draw(st.integers(0, 9)) == 0

    def counts(good):
        if big and draw(st.booleans()):
            return draw(st.sampled_from(("1000", "1,1000", "1000,999,998", ",".join(map(str, range(1, 200))))))
        return _value(draw, good)
    argv = ["plan-sockets", "model.yaml", "--placements", counts("3"), "--poses-per-socket", counts("8")]
    if draw(st.booleans()):
        argv += ["--out", "sockets.csv"]
    return files, argv + draw(options(PLAN_SOCKETS))


@st.composite
def import_dh_case(draw, result_text=None):
    argv = ["import-dh", "table.csv", "--out", "imported.yaml"]
    if draw(st.integers(0, 3)) == 0:
        argv += ["--units", _value(draw, "m-rad")]
    if draw(st.integers(0, 3)) == 0:
        argv += ["--name", draw(st.sampled_from(("r", "", "x" * 10_000, "é", "a: b")))]
    return {"table.csv": draw(dh_file())}, argv


@st.composite
def export_case(draw, result_text=None):
    base = draw(st.sampled_from((MODEL, TRUE_MODEL, ARM7_MODEL)))
    files = {"model.yaml": _model(draw, base)}
    fmt = draw(st.sampled_from(("urdf", "mdh-csv", "dh-csv")))
    argv = ["export", "model.yaml", "--format", fmt, "--out", "out." + ("urdf" if fmt == "urdf" else "csv")]
    if draw(st.booleans()):
        argv += ["--units", _value(draw, "m-rad")]
    if draw(st.integers(0, 3)) == 0:
        argv += ["--allow-ill-conditioned"]
    return files, argv


@st.composite
def compensate_case(draw, result_text=None):
    files = {"nominal.yaml": _model(draw), "calibrated.yaml": _model(draw, TRUE_MODEL)}
    files["targets.csv"] = draw(csv_file(TARGETS)) if draw(st.integers(0, 2)) else TARGETS.encode()
    argv = ["compensate", "nominal.yaml", "calibrated.yaml", "targets.csv", "--out", "commands.csv"]
    return files, argv + draw(options(COMPENSATE))


@st.composite
def contacts_case(draw, result_text=None):
    files = {"model.yaml": _model(draw, ARM7_MODEL)}
    files["sockets.csv"] = draw(contacts_file()) if draw(st.integers(0, 2)) else SOCKETS.encode()
    argv = ["calibrate", "model.yaml", "--contacts", "sockets.csv", "--out", "out"] + draw(options(CONTACTS))
    if draw(st.integers(0, 3)) == 0:    # and keep it in a store (never the user's default one)
        argv += ["--record", _value(draw, "R"), "--store", "store.sqlite"]
    return files, argv


def _seatings() -> dict[str, str]:
    """The arm7 folder of seatings (relative path -> text), cut to 4 seatings per socket."""
    root = ARM7 / "seatings"
    out = {}
    for p in sorted(root.rglob("*")):
        if p.is_file():
            text = p.read_text()
            out[p.relative_to(root).as_posix()] = text if p.suffix != ".csv" else \
                "".join(text.splitlines(keepends=True)[:4])
    return out


SEATINGS = _seatings()
_SEATING_ROW = next(v for k, v in SEATINGS.items() if k.endswith(".csv")).splitlines()[0] + "\n"
SEATING_NAMES = ("P1/hole 0.csv", "P1/hole_0.txt", "hole_0.csv", "P1/.hole_0.csv", "P 1/hole_0.csv",
                 "P1/hole_0.CSV", "P1/" + "h" * 100 + ".csv", "P1/sub/hole_0.csv", "P4/hole_0.csv", "README.md",
                 "P1/hole_é.csv", "P1/hole_00.csv", "P10/hole_1.csv")


@st.composite
def seatings_folder(draw) -> dict[str, bytes]:
    """A folder of seatings under ``campaign/`` (path -> bytes): the manifest or a joint file mutated,
    files renamed, dropped or added, the bounds stretched (rows, files), empty and binary files."""
    files = {k: v.encode() for k, v in SEATINGS.items()}
    csvs = sorted(k for k in files if k.endswith(".csv"))
    kind = draw(st.sampled_from(("manifest",) * 4 + ("joints",) * 4 + ("rename", "drop", "extra", "rows", "files",
                                                                         "wide", "empty", "binary")))
    if kind == "manifest":
        files["seatings.yaml"] = draw(mutated_text(SEATINGS["seatings.yaml"]))
    elif kind == "joints":
        name = draw(st.sampled_from(csvs))
        files[name] = draw(mutated_text(SEATINGS[name]))
    elif kind == "rename":
        files[draw(st.sampled_from(SEATING_NAMES))] = files.pop(draw(st.sampled_from(csvs)))
    elif kind == "drop":
        for name in draw(st.sets(st.sampled_from(sorted(files)), min_size=1)):
            del files[name]
    elif kind == "extra":
        files[draw(st.sampled_from(SEATING_NAMES))] = draw(st.sampled_from((b"", b"1,2,3\n", files[csvs[0]])))
    elif kind == "rows":
        files[draw(st.sampled_from(csvs))] = _SEATING_ROW.encode() * draw(st.sampled_from((2_000, 30_000)))
    elif kind == "files":
        n = draw(st.sampled_from((60, 1_200)))
        files.update({f"P{k // 3 + 1}/hole_{k % 3}.csv": _SEATING_ROW.encode() * 2 for k in range(n)})
    elif kind == "wide":
        wide = (_SEATING_ROW.strip() + ",") * draw(st.sampled_from((2, 5_000))) + "1\n"
        files[draw(st.sampled_from(csvs))] = wide.encode()
    elif kind == "empty":
        files[draw(st.sampled_from(csvs))] = draw(st.sampled_from((b"", b"\n", b"\n\n\n", b" , \n")))
    else:
        files[draw(st.sampled_from(csvs + ["seatings.yaml"]))] = draw(st.binary(min_size=1, max_size=200))
    return {"campaign/" + k: v for k, v in files.items()}


@st.composite
def seatings_case(draw, result_text=None):
    """calibrate --contacts on a folder of seatings (_files/seatings.py), the folder damaged."""
    files = {"model.yaml": _model(draw, ARM7_MODEL)}
    files.update(draw(seatings_folder()) if draw(st.integers(0, 3)) else
                 {"campaign/" + k: v.encode() for k, v in SEATINGS.items()})
    return files, ["calibrate", "model.yaml", "--contacts", "campaign", "--out", "out"] + draw(options(CONTACTS))


@st.composite
def compensate_program_case(draw, result_text=None):
    """compensate on a robot program (each dialect's example, mutated), written as a program."""
    files = {"model.yaml": _model(draw)}
    name = draw(st.sampled_from(sorted(PROGRAMS)))
    files[name] = draw(program_file(PROGRAMS[name])) if draw(st.integers(0, 2)) else PROGRAMS[name].encode()
    out = draw(st.sampled_from(("out" + name[4:], "out" + name[4:], name)))
    argv = ["compensate", "model.yaml", "model.yaml", name, "--out", out] + draw(options(COMPENSATE_PROGRAM))
    if draw(st.integers(0, 4)) == 0:
        argv += ["--dialect", _value(draw, {"mod": "rapid", "dat": "krl", "src": "krl"}.get(name[5:], "urscript"))]
    return files, argv


@st.composite
def store_case(draw, command: str, result_text):
    """(files, argv) of record, history or verify on a store, its result or its measurements damaged."""
    result_text = _base(draw, result_text)
    files = {"store.sqlite": draw(store_file(store_bytes(result_text)))}
    robot = _value(draw, "R")
    store = "store.sqlite" if draw(st.integers(0, 9)) else draw(st.sampled_from(OTHER_URLS))
    if command == "record":
        if draw(st.booleans()):
            del files["store.sqlite"]           # a new store
        files["result.json"] = draw(result_file(result_text)) if draw(st.booleans()) else result_text.encode()
        return files, ["record", "result.json", "--robot", robot, "--store", store] + draw(options(RECORD))
    if command == "history":
        who = [robot] if draw(st.integers(0, 2)) else ["--type", _value(draw, "th8")]
        return files, ["history", *who, "--store", store] + draw(options(HISTORY))
    if draw(st.integers(0, 2)) == 0:            # seatings, as a robot calibrated from them is verified
        files.update(draw(seatings_folder()) if draw(st.booleans()) else
                     {"campaign/" + k: v.encode() for k, v in SEATINGS.items()})
        return files, ["verify", robot, "--contacts", "campaign", "--store", store] + draw(options(VERIFY))
    files["data.csv"] = draw(csv_file()) if draw(st.booleans()) else MEASUREMENTS.encode()
    return files, ["verify", robot, "data.csv", "--store", store] + draw(options(VERIFY))


@st.composite
def joints_program_case(draw, result_text=None):
    """calibrate or identifiability on an instrument's points whose joint readings are controller
    code (``--joints joints.mod``), either file mutated."""
    name = draw(st.sampled_from(sorted(JOINT_PROGRAMS)))
    files = {"model.yaml": _model(draw)}
    files["points.csv"] = draw(csv_file(POINTS)) if draw(st.integers(0, 2)) == 0 else POINTS.encode()
    files[name] = draw(program_file(JOINT_PROGRAMS[name])) if draw(st.integers(0, 2)) else JOINT_PROGRAMS[name].encode()
    if draw(st.booleans()):
        argv = ["calibrate", "model.yaml", "points.csv", "--out", "out"] + draw(options(CALIBRATE))
    else:
        argv = ["identifiability", "model.yaml", "points.csv"] + draw(options(IDENTIFIABILITY))
    argv += ["--joints", name] + (["--key", _value(draw, "pose")] if draw(st.integers(0, 4)) == 0 else [])
    return files, argv


@functools.lru_cache(maxsize=2)
def sidecar_files(result_text: str) -> tuple[str, bytes, dict]:
    """The result as calibrate writes it: result.json naming its per-pose file result.npz, that
    file's bytes, and its arrays."""
    import io

    import numpy as np

    import robocal as rc
    from robocal.io import result_files

    result = rc.io.result_from_dict(json.loads(result_text))
    with tempfile.TemporaryDirectory() as folder:
        files = result_files(result, Path(folder) / "result.json")
        text, blob = (files[Path(folder) / n] for n in ("result.json", "result.npz"))
    with np.load(io.BytesIO(blob), allow_pickle=False) as z:
        return text, blob, {k: z[k] for k in z.files}


def _npz(arrays: dict) -> bytes:
    import io

    import numpy as np

    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


@st.composite
def sidecar_pair(draw, result_text: str) -> dict:
    """result.json and result.npz, one of them damaged; where the arrays are changed the JSON's
    SHA-256 follows (else only the hash check would be reached)."""
    import hashlib

    import numpy as np

    text, blob, arrays = sidecar_files(result_text)
    kind = draw(st.sampled_from(("good", "array", "array", "array", "flip", "cut", "missing", "name", "json")))
    if kind == "flip":
        data = bytearray(blob)
        for _ in range(draw(st.integers(1, 4))):
            data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
        blob = bytes(data)
    elif kind == "cut":
        blob = blob[:draw(st.integers(0, len(blob) - 1))]
    elif kind == "array":
        arrays = dict(arrays)
        key = draw(st.sampled_from(sorted(arrays)))
        edit = draw(st.sampled_from(("drop", "nan", "inf", "shape", "int", "empty", "extra", "huge", "text", "3d")))
        a = arrays[key]
        if edit == "drop":
            del arrays[key]
        elif edit in ("nan", "inf", "huge"):
            value = {"nan": np.nan, "inf": np.inf, "huge": 1e308}[edit]
            if a.size:
                a = a.copy()
                a.flat[draw(st.integers(0, a.size - 1))] = value
            else:       # no poses (a calibration from contacts alone): a row of it where none belongs
                a = np.full((1,) + a.shape[1:], value)
            arrays[key] = a
        elif edit == "shape":
            arrays[key] = a[:-1] if len(a) else a
        elif edit == "int":
            arrays[key] = a.astype(np.int64)
        elif edit == "empty":
            arrays[key] = np.empty((0,) + a.shape[1:])
        elif edit == "extra":
            arrays["x"] = np.zeros(3)
        elif edit == "text":
            arrays[key] = np.array(["a"] * max(len(a), 1))
        else:
            arrays[key] = a.reshape(a.shape + (1,))
        blob = _npz(arrays)
        text = text.replace(hashlib.sha256(sidecar_files(result_text)[1]).hexdigest(), hashlib.sha256(blob).hexdigest())
    files = {"result.json": text.encode(), "result.npz": blob}
    if kind == "missing":
        del files["result.npz"]
    elif kind == "name":
        name = draw(st.sampled_from(("../result.npz", "/tmp/result.npz", "result.json", "x.npz", "", "r\x00.npz")))
        files["result.json"] = text.replace('"name": "result.npz"', f'"name": {json.dumps(name)}').encode()
    elif kind == "json":
        files["result.json"] = draw(result_file(text))
    return files


@st.composite
def sidecar_case(draw, result_text=None):
    """report or record on a result whose per-pose arrays are in its result.npz sidecar."""
    files = draw(sidecar_pair(_base(draw, result_text)))
    if draw(st.booleans()):
        return files, ["report", "result.json", "--out", "report.html"]
    return files, ["record", "result.json", "--robot", _value(draw, "R"), "--store", "store.sqlite"]


# -- inputs that are not regular files' bytes, and read-only folders ---------------------------------

class Node:
    """An input that is not a regular file, made where the case runs (``materialise``): ``kind`` one of
    NODE_KINDS; ``data`` what a FIFO or pipe carries, a read-only file holds, or where a link points."""

    __slots__ = ("kind", "data")

    def __init__(self, kind: str, data: bytes = b""):
        self.kind, self.data = kind, data

    def __repr__(self) -> str:
        return f"Node({self.kind!r}, {self.data[:60]!r})"


NODE_KINDS = ("fifo", "fifo-idle", "pipe", "socket", "folder", "link", "readonly", "readonly-folder")
# what may stand in an input's place: a device named on the command line, or a node at its path
DEVICES = ("/dev/zero", "/dev/urandom", "/dev/null")
STREAM_KINDS = DEVICES + ("fifo", "fifo", "fifo-idle", "pipe", "pipe", "socket", "folder", "link", "readonly")
# options whose value is a path written, never read
OUTPUT_OPTIONS = ("--out", "--report", "--true-model")


def input_slots(files: dict, argv: list[str]) -> list[tuple[int | None, str]]:
    """Every input of a case: (its index in ``argv`` or None, its path): the files (and folders of
    files) the command line names, a store's path, and the files read through another (a result's
    sidecar, the files of a folder of seatings)."""
    slots, named = [], set()
    for k, a in enumerate(argv):
        if k and argv[k - 1] in OUTPUT_OPTIONS:
            continue
        if a in files or (k and argv[k - 1] == "--store" and "://" not in a) or \
                (a and any(n.startswith(a + "/") for n in files)):
            slots.append((k, a))
            named.add(a)
    slots += [(None, n) for n in files if n not in named and not isinstance(files[n], Node)]
    return slots


def _plain(data) -> bytes:
    return data.data if isinstance(data, Node) else data


@st.composite
def streams_case(draw, result_text=None):
    """Another command's case with one input (any slot) a device, a FIFO fed its bytes or never fed,
    a pipe as a shell's ``<(cat FILE)`` gives it (/dev/fd/N), a socket, a folder, a link to a device,
    or a file only readable: refused in one line or read as the file is, nothing left behind."""
    command, files, argv = draw(case(result_text, [n for n in COMMANDS if n not in WRAPPERS + NOT_WRAPPED]))
    files, argv = dict(files), list(argv)
    k, path = draw(st.sampled_from(input_slots(files, argv)))
    kind = draw(st.sampled_from(STREAM_KINDS))
    data = files.get(path, b"")
    if path not in files and any(n.startswith(path + "/") for n in files):
        kind = draw(st.sampled_from(DEVICES + ("socket", "fifo-idle", "link")))  # a folder's place
        files = {n: v for n, v in files.items() if not n.startswith(path + "/")}
    if kind in DEVICES and k is not None:
        argv[k] = kind
        return files, argv
    if kind in DEVICES or (kind == "pipe" and k is None):
        kind = "link" if kind in DEVICES else "fifo"
    files[path] = Node(kind, draw(st.sampled_from(DEVICES)).encode() if kind == "link" else _plain(data))
    return files, argv


def _moved(files: dict, argv: list[str], into: str, inputs: bool) -> tuple[dict, list[str]]:
    """The case with its outputs (and with ``inputs``, its inputs) in the folder ``into``."""
    slots = {k for k, _ in input_slots(files, argv) if k is not None}
    argv = [into + "/" + a if (k and argv[k - 1] in OUTPUT_OPTIONS) or (inputs and k in slots) else a
            for k, a in enumerate(argv)]
    if inputs:
        files = {into + "/" + n: v for n, v in files.items()}
    return files, argv


@st.composite
def read_only_case(draw, result_text=None):
    """Another command's case in a read-only folder: its outputs written there, its inputs and store
    there too, or its inputs (the store among them) only readable; a folder the command cannot write
    is refused in one line with nothing left behind, and reading needs no write access."""
    command, files, argv = draw(case(result_text, [n for n in COMMANDS if n not in WRAPPERS + NOT_WRAPPED]))
    how = draw(st.sampled_from(("outputs", "everything", "inputs")))
    if how == "inputs":
        store = [argv[k + 1] for k, a in enumerate(argv[:-1]) if a == "--store"]
        names = [n for n in files if not isinstance(files[n], Node)]
        chosen = store if store and store[0] in files and draw(st.booleans()) else names
        return {n: Node("readonly", v) if n in chosen else v for n, v in files.items()}, argv
    files, argv = _moved(dict(files), list(argv), "ro", how == "everything")
    return {**files, "ro": Node("readonly-folder")}, argv


def _tooled(program: str, name: str) -> tuple[str, list[str]]:
    """``program`` declaring a tool and a work object other than those its motions use, and the
    names of the tools and work objects ``--tool``/``--wobj`` may take (declared, the controller's
    own, or none of them)."""
    if name.endswith(".mod"):
        decl = ("  PERS tooldata tOther := [TRUE, [[10, -20, 200], [0.9238795, 0, 0.3826834, 0]], "
                "[1, [0, 0, 50], [1, 0, 0, 0], 0, 0, 0]];\n"
                "  PERS wobjdata wOther := [FALSE, TRUE, \"\", [[100, 50, 20], [0.9659258, 0, 0, 0.2588190]], "
                "[[0, 0, 0], [1, 0, 0, 0]]];\n")
        return program.replace("  CONST jointtarget jP02", decl + "  CONST jointtarget jP02", 1), \
            ["tOther", "wOther", "tSphere", "tool0", "wobj0", "tNone"]
    if name.endswith(".dat"):
        decl = "DECL FRAME T2={X 10.0,Y -20.0,Z 200.0,A 30.0,B 10.0,C 0.0}\nDECL FRAME B2={X 100.0,Y 50.0,Z 20.0," \
               "A 30.0,B 0.0,C 0.0}\n"
        return program.replace("ENDDAT", decl + "ENDDAT", 1), ["T2", "B2", "TOOL", "TOOL_DATA[1]", "BASE_DATA[2]", "X"]
    if name.endswith(".src"):
        return program, ["TOOL_DATA[1]", "BASE_DATA[1]", "$NULLFRAME", "X"]
    decl = "  tcp2 = p[0.01, -0.02, 0.2, 0.0, 0.5, 0.0]\n  base2 = p[0.1, 0.05, 0.02, 0.0, 0.0, 0.5]\n" \
           "  set_tcp(p[0.0, 0.0, 0.12, 0.0, 0.0, 0.0])\n"
    return program.replace("  home = ", decl + "  home = ", 1), ["tcp2", "base2", "home", "x"]


@st.composite
def tools_case(draw, result_text=None):
    """A robot program compensated with ``--tool``/``--wobj`` naming frames other than those its
    motions were written with (a tool the program declares but does not move with, the flange, an
    undeclared name): each target solved in the frames named or refused; against its own model every
    target keeps its numbers."""
    name = draw(st.sampled_from(sorted(PROGRAMS)))
    program, frames = _tooled(PROGRAMS[name], name)
    files = {"model.yaml": MODEL.encode(), name: program.encode()}
    calibrated = "model.yaml"
    if draw(st.integers(0, 3)) == 0:
        files["true.yaml"], calibrated = TRUE_MODEL.encode(), "true.yaml"
    argv = ["compensate", "model.yaml", calibrated, name, "--out", "out" + name[4:]]
    for option in ("--tool", "--wobj"):
        if draw(st.booleans()):
            argv += [option, draw(st.sampled_from(frames))]
    return files, argv + draw(options({"--marker": "tool", "--force": None}))


# command -> (weight, strategy of (files, argv)). The readers and commands of later work join here:
# add a strategy above (mutations of a shipped example, the sizes that could hang it) and a line
# below; the judge (check_output) then learns what a sound output of it is.
COMMANDS = {
    "calibrate": (3, calibrate_case), "simulate": (1, simulate_case), "identifiability": (1, identifiability_case),
    "limit": (1, limit_case), "import-urdf": (2, import_urdf_case), "report": (1, report_case),
    "plan": (2, plan_case), "plan-sockets": (1, plan_sockets_case), "import-dh": (2, import_dh_case),
    "export": (2, export_case), "compensate": (2, compensate_case), "contacts": (2, contacts_case),
    "compensate-program": (2, compensate_program_case), "record": (1, functools.partial(store_case, "record")),
    "history": (1, functools.partial(store_case, "history")), "verify": (1, functools.partial(store_case, "verify")),
    "joints-program": (2, joints_program_case), "sidecar": (2, sidecar_case), "seatings": (2, seatings_case),
    "streams": (4, streams_case), "read-only": (3, read_only_case), "tools": (1, tools_case),
    "numbers": (3, numbers_case),
}
# the families that take another command's case and change where its inputs and outputs are, and
# the family they leave alone (the same files as calibrate's, each case a calibration)
WRAPPERS = ("streams", "read-only")
NOT_WRAPPED = ("numbers",)
# the commands whose cases start from a result file (``result_text``)
NEEDS_RESULT = ("report", *STORE_COMMANDS, "sidecar")


# the in-process sample of the test suite (tests/test_fuzz.py): the same cases, the slow command
# (plan-sockets simulates its seatings, about a second a run) drawn less often, and so the families
# that repeat the commands' own cases elsewhere (and may wait: a FIFO never written into is refused
# after two seconds); not numbers, whose every case is a calibration (seconds, and with --compare on
# nonsense tens of them, the fuzz's hang bar): benchmarks/fuzz_cli.py --commands numbers runs it
SAMPLE_WEIGHTS = {**{n: 4 * w for n, (w, _) in COMMANDS.items()}, "plan-sockets": 1, "streams": 4, "read-only": 4,
                  "tools": 2, "numbers": 0}
# its share run in forked children (fork_case): the commands whose cases ask for the most work or
# memory (large counts, long chains and tables, bombs), where a guard inside the process could come
# too late (a long call into compiled code) and the operating system's limits are the real test
FORKED_WEIGHTS = {"plan": 3, "plan-sockets": 1, "import-urdf": 3, "import-dh": 3, "contacts": 2,
                  "compensate-program": 2, "calibrate": 2, "joints-program": 1}


@st.composite
def case(draw, result_text: str | None = None, commands=None, weights=None):
    """(command, files, argv) of one run of one command (of ``commands``, default those ``weights``
    names or every one), drawn by ``weights`` (command -> whole number, default COMMANDS's);
    ``command`` is the COMMANDS key."""
    names = [n for n in (commands or weights or COMMANDS) if result_text or n not in NEEDS_RESULT]
    weights = weights or {n: w for n, (w, _) in COMMANDS.items()}
    command = draw(st.sampled_from([n for n in names for _ in range(weights[n])]))
    files, argv = draw(COMMANDS[command][1](result_text))
    return command, files, argv


# -- the judge -----------------------------------------------------------------------------------

OUTCOMES = ("clean error", "ok result", "traceback", "hang", "over-memory", "non-finite output", "unreadable output",
            "wrong output", "multi-line error", "written beside a failure")
_NON_FINITE = re.compile(r"(?<![\w.])[-+]?(?:\.?nan|\.?inf|infinity)(?![\w])", re.IGNORECASE)
# an output's forward kinematics against its source's, metres (the writers' own check)
FK_TOL = 1e-9


def non_finite(folder: Path, before: set[str]) -> str | None:
    """The first output file of a run holding a non-finite number, or None. A compensated program
    keeps every word of its source but its targets' numbers: those the program check reads back (the
    program reader refuses a non-finite literal); a result's per-pose file (.npz) is read back with
    its result by the calibrate check."""
    from robocal._files.programs import EXTENSIONS

    for p in sorted(folder.rglob("*")):
        given = p.relative_to(folder).as_posix() in before   # an input (a path: a folder of seatings holds some)
        if not p.is_file() or given or p.suffix in (".html", ".npz", *EXTENSIONS) or ".sqlite" in p.name:
            continue
        text = p.read_text(errors="replace")
        if p.suffix == ".json":
            try:
                d = json.loads(text)
            except ValueError:
                return p.name
            if _json_nulls(d):
                return p.name
        elif p.suffix in (".yaml", ".yml"):
            if _yaml_non_finite(text):
                return p.name
        elif _NON_FINITE.search(_outside_labels(p, text)):
            return p.name
    return None


def _yaml_non_finite(text: str) -> bool:
    """Whether a YAML output holds a non-finite number (``.inf``, ``.nan``): its values as YAML reads
    them, so that a name that reads like one (a joint named 'Infinity') is the string it is."""
    import yaml

    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError:
        return bool(_NON_FINITE.search(text))
    stack = [doc]
    while stack:
        v = stack.pop()
        if isinstance(v, dict):
            stack.extend(v.values())
        elif isinstance(v, list):
            stack.extend(v)
        elif isinstance(v, float) and not math.isfinite(v):
            return True
    return False


# the attributes of a URDF that name things (a robot named 'Infinity' is no number)
URDF_NAMES = ("name", "link", "type", "filename")


def _outside_labels(path: Path, text: str) -> str:
    """The text of an output where numbers may stand: a CSV whose first column names its poses
    loses that column (a pose the user named '-inf' keeps its name, and is no number); a URDF keeps
    its elements' text and the attributes that are not names (``URDF_NAMES``), its comments dropped."""
    if path.suffix == ".urdf":
        try:
            root = ET.fromstring(text)
        except ET.ParseError:
            return text
        return "\n".join([v for e in root.iter() for k, v in e.attrib.items() if k not in URDF_NAMES]
                         + [e.text for e in root.iter() if e.text])
    if path.suffix != ".csv" or not text.lower().startswith("pose,"):
        return text
    import csv

    return "\n".join(",".join(row[1:]) for row in csv.reader(text.splitlines()))


def _json_nulls(d) -> bool:
    """A result or limit file whose headline numbers are null (the writer's form of NaN/inf)."""
    if not isinstance(d, dict):
        return True
    if d.get("schema", "").startswith("robocal.limit"):
        return any(d.get(k) is None for k in ("limit", "repeatability", "precision"))
    stats = d.get("stats", {})
    for s in [stats.get(k) for k in ("fit_before", "fit_after")]:
        if s and s.get("n") and any(s.get(f) is None for f in ("mean", "rms", "max")):
            return True
    return any(p.get("estimate") is None or p.get("std") is None or
               not all(math.isfinite(v) for v in (p["estimate"], p["std"])) for p in d.get("parameters", []))


def _sample_q(model, n: int = 16):
    """Readings spread within the model's limits, clipped to +-2 pi rad and +-10 m where they are wider."""
    import numpy as np

    rng = np.random.default_rng(1)
    box = np.array([10.0 if k == "length" else 2 * np.pi for k in model.reading_quantities])
    lo, hi = np.array(model.joint_limits, dtype=float).reshape(-1, 2).T
    lo, hi = np.clip(lo, -box, box), np.clip(hi, -box, box)
    return lo + (np.maximum(hi, lo) - lo) * rng.random((n, model.n_joints))


def _fk_gap(model, back, markers=None) -> float:
    """The largest distance between the markers of ``model`` and of ``back`` (same names) at readings within
    the limits, geometry only (exports hold no compliance or backlash); ``markers`` maps each of ``back``'s
    markers to ``model``'s (default by name)."""
    import numpy as np

    from robocal._model.kinematics import evaluate

    q = _sample_q(model)
    qb = q[:, [model.joint_names.index(n) for n in back.joint_names]]
    a = evaluate(model, q, compliance=False, backlash=False).positions
    b = evaluate(back, qb, compliance=False, backlash=False).positions
    idx = [model.marker_names.index(n) for n in (markers or back.marker_names)]
    return float(np.max(np.linalg.norm(a[:, idx] - b, axis=-1)))


def _check_export(argv, folder: Path) -> str | None:
    import robocal as rc
    from robocal.io import read_dh_table, read_urdf

    model = rc.read_model(folder / argv[1])
    out = folder / argv[argv.index("--out") + 1]
    try:
        if argv[argv.index("--format") + 1] == "urdf":
            tips = [j.get("link") for j in ET.parse(out).getroot().iter("child")][-len(model.markers):]
            gap = max(_fk_gap(model, read_urdf(out, tip_link=t), [m]) for t, m in zip(tips, model.marker_names))
        else:
            back = read_dh_table(out)
            if back.n_joints != model.n_joints:
                return "wrong output"
            gap = _fk_gap(model, back)
    except rc.InputError:
        return "unreadable output"
    return None if gap <= FK_TOL else "wrong output"


def _check_model(argv, folder: Path) -> str | None:
    import robocal as rc

    try:
        rc.read_model(folder / argv[argv.index("--out") + 1])
    except rc.InputError:
        return "unreadable output"
    return None


def _within(model, q) -> bool:
    import numpy as np

    lo, hi = np.array(model.joint_limits, dtype=float).reshape(-1, 2).T
    return bool(np.all((q >= lo - 1e-12 * np.maximum(1, abs(lo))) & (q <= hi + 1e-12 * np.maximum(1, abs(hi)))))


def _check_plan(argv, folder: Path) -> str | None:
    import robocal as rc

    model = rc.read_model(folder / argv[1])
    try:
        data = rc.read_measurements(folder / argv[argv.index("--out") + 1], model, targets=True)
    except rc.InputError:
        return "unreadable output"
    return None if _within(model, data.q) else "wrong output"


def _numbers(target) -> list[float]:
    return [n.value for part in (target.joints, target.position, target.orientation) for n in part]


def _check_program(argv, folder: Path) -> str | None:
    """A compensated program reads back with the same targets; the fuzz compensates a model against
    itself, so every target reached keeps its numbers."""
    from robocal.io import read_program

    dialect = argv[argv.index("--dialect") + 1] if "--dialect" in argv else None
    source, out = folder / argv[3], folder / argv[argv.index("--out") + 1]
    try:
        back = read_program(out, dialect=dialect)
    except Exception:  # noqa: BLE001 - whatever stops the reader, the output is not a program it takes
        return "unreadable output"
    if source == out or argv[1] != argv[2]:  # (against another model its targets move)
        return None
    before = read_program(source, dialect=dialect)
    if [t.kind for t in back.targets] != [t.kind for t in before.targets]:  # (inline ones are named by line)
        return "wrong output"
    for a, b in zip(before.targets, back.targets):
        x, y = _numbers(a), _numbers(b)
        if len(x) != len(y) or any(abs(u - v) > 1e-6 * max(1.0, abs(u)) for u, v in zip(x, y)):
            return "wrong output"
    return None


def _check_compensate(argv, folder: Path) -> str | None:
    import csv

    from robocal._files.programs import EXTENSIONS

    if "--dialect" in argv or Path(argv[3]).suffix.lower() in EXTENSIONS:
        return _check_program(argv, folder)

    import numpy as np

    import robocal as rc

    model, nominal = rc.read_model(folder / argv[2]), rc.read_model(folder / argv[1])
    rows = list(csv.reader((folder / argv[argv.index("--out") + 1]).read_text().splitlines()))
    header, body = rows[0], rows[1:]
    units = "m-rad" if "--out-units" in argv and argv[argv.index("--out-units") + 1] == "m-rad" else "mm-deg"
    scale = [(1e-3 if units == "mm-deg" else 1.0) if k == "length" else (math.pi / 180 if units == "mm-deg" else 1.0)
             for k in model.reading_quantities]
    for row in body:
        if len(row) != len(header):
            return "unreadable output"
        q = np.array([float(v) * s for v, s in zip(row[1:1 + model.n_joints], scale)])
        if row[-1] == "ok" and not (_within(model, q[None]) and _within(nominal, q[None])):
            return "wrong output"
    return None


def _check_sockets(argv, folder: Path) -> str | None:
    import robocal as rc
    from robocal.io import read_contacts

    if "--out" not in argv or not (folder / argv[argv.index("--out") + 1]).exists():
        return None
    try:
        read_contacts(folder / argv[argv.index("--out") + 1], rc.read_model(folder / argv[1]))
    except rc.InputError:
        return "unreadable output"
    return None


def _check_calibrate(argv, folder: Path) -> str | None:
    """The result reads back with its per-pose file, and the calibrated model (when written) too."""
    import robocal as rc

    out = folder / argv[argv.index("--out") + 1]
    if not (out / "result.json").exists():
        return None
    try:
        rc.read_result(out / "result.json")
        if (out / "calibrated.yaml").exists():
            rc.read_model(out / "calibrated.yaml")
    except rc.InputError:
        return "unreadable output"
    return None


# what a sound output of each command is, beyond finite numbers: it reads back and, for the
# writers of models and commands, reproduces its source (later commands add their check here)
OUTPUT_CHECKS = {"calibrate": _check_calibrate, "export": _check_export, "import-dh": _check_model,
                 "import-urdf": _check_model,
                 "plan": _check_plan, "compensate": _check_compensate, "plan-sockets": _check_sockets}


def check_output(argv, folder: Path) -> str | None:
    """'wrong output' or 'unreadable output' when a run that succeeded wrote something unsound, else None."""
    check = OUTPUT_CHECKS.get(argv[0]) if argv else None
    try:
        return check(argv, folder) if check else None
    except Exception:  # noqa: BLE001 - an output the checker cannot even take apart is not sound
        return "unreadable output"


def written_beside(folder: Path, files: dict) -> bool:
    """Whether a failed run left a file or folder that was not there (its streams aside) or changed
    an input (a store among them)."""
    there = {p.relative_to(folder).as_posix() for p in folder.rglob("*") if not p.is_symlink()}
    given = set(files) | {str(q) for n in files for q in Path(n).parents if str(q) != "."}
    if there - given - {"stdout.txt", "stderr.txt"}:
        return True
    return any(not isinstance(v, Node) and (folder / n).read_bytes() != v for n, v in files.items())


def judge(code, err: str, folder: Path, before: set[str], argv=None, files=None, changed: bool = False) -> str:
    """The outcome of one finished run: exit code, its stderr, the folder it ran in, its command line
    (and with ``files``, the inputs it was given, which a failed run leaves as they were; ``changed``:
    a node among them was replaced or written into, ``Materialised.close``)."""
    if "Traceback" in err or code not in (0, 1, 2, 3):
        return "traceback"
    if code in (1, 2):
        lines = [ln for ln in err.splitlines() if not ln.startswith("robocal: warning:")]
        if len(lines) == 1 and ": error: out of memory" in lines[0]:  # the CLI's word for a MemoryError
            return "over-memory"
        if files is not None and (changed or written_beside(folder, files)):
            return "written beside a failure"
        return "clean error" if len(lines) == 1 and len(lines[0]) < 1000 else "multi-line error"
    if non_finite(folder, before):
        return "non-finite output"
    return (check_output(argv, folder) if code == 0 else None) or "ok result"


# -- a case's files made in its folder ------------------------------------------------------------

_FS_IOC_GETFLAGS, _FS_IOC_SETFLAGS, _FS_IMMUTABLE_FL = 0x80086601, 0x40086602, 0x10


def _mark_read_only(path: Path, on: bool) -> None:
    """Make ``path`` read-only (or writable again): its mode, and for root, whom modes do not stop,
    the file system's immutable flag (what ``chattr +i`` sets)."""
    import fcntl
    import os
    import struct

    if on:
        path.chmod(0o555 if path.is_dir() else 0o444)
    if os.geteuid() == 0:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        try:
            flags = struct.unpack("i", fcntl.ioctl(fd, _FS_IOC_GETFLAGS, struct.pack("i", 0)))[0]
            flags = flags | _FS_IMMUTABLE_FL if on else flags & ~_FS_IMMUTABLE_FL
            fcntl.ioctl(fd, _FS_IOC_SETFLAGS, struct.pack("i", flags))
        except OSError:
            pass  # a file system without the flag: the mode alone
        finally:
            os.close(fd)
    if not on:
        path.chmod(0o755 if path.is_dir() else 0o644)


def _feed(path: Path, data: bytes) -> None:
    """Write ``data`` into the FIFO at ``path`` once a reader opens it (a thread of the runner)."""
    import os

    try:
        fd = os.open(path, os.O_WRONLY)
    except OSError:
        return
    try:
        with open(fd, "wb") as fh:
            fh.write(data)
    except OSError:
        pass  # the reader left before the end (a refusal, a budget): as a shell's writer would see it


class Materialised:
    """A case's files made in ``folder``: regular files written, then each ``Node``: a FIFO fed its
    bytes by a thread when a reader opens it (or never), a pipe filled and its writing end closed
    (``argv`` names it /dev/fd/N, as a shell's ``<(cat FILE)`` does), a socket, a folder, a link,
    read-only files and folders. ``close`` takes them down again."""

    def __init__(self, folder: Path, files: dict, argv: list[str]):
        import os
        import socket
        import threading

        self.folder, self.files, self.argv = folder, files, list(argv)
        self.feeders, self.pipes, self.marked = [], [], []
        for name, data in files.items():
            if not isinstance(data, Node):
                (folder / name).parent.mkdir(parents=True, exist_ok=True)
                (folder / name).write_bytes(data)
        for name, node in files.items():
            if not isinstance(node, Node):
                continue
            path = folder / name
            path.parent.mkdir(parents=True, exist_ok=True)
            if node.kind in ("fifo", "fifo-idle"):
                os.mkfifo(path)
                if node.kind == "fifo":
                    self.feeders.append((path, threading.Thread(target=_feed, args=(path, node.data), daemon=True)))
                    self.feeders[-1][1].start()
            elif node.kind == "pipe":
                self.argv = [f"/dev/fd/{self._pipe(node.data)}" if a == name else a for a in self.argv]
            elif node.kind == "socket":
                with socket.socket(socket.AF_UNIX) as s:
                    s.bind(str(path))
            elif node.kind in ("folder", "readonly-folder"):
                path.mkdir(exist_ok=True)
            elif node.kind == "link":
                path.symlink_to(node.data.decode())
            else:
                path.write_bytes(node.data)
        for name, node in sorted(files.items(), key=lambda kv: -kv[0].count("/")):  # files before their folders
            if isinstance(node, Node) and node.kind in ("readonly", "readonly-folder"):
                _mark_read_only(folder / name, True)
                self.marked.append(folder / name)

    def _pipe(self, data: bytes) -> int:
        """A pipe holding ``data`` (as much as it takes), its writing end closed; its reading end."""
        import contextlib
        import fcntl
        import os

        r, w = os.pipe()
        with contextlib.suppress(OSError):  # (a system that keeps pipes small: the rest is cut)
            fcntl.fcntl(w, fcntl.F_SETPIPE_SZ, 1 << 20)
        os.set_blocking(w, False)
        try:
            while data:
                data = data[os.write(w, data[:1 << 16]):]
        except BlockingIOError:
            pass  # the pipe is full: the rest is cut, as a writer killed there leaves it
        os.close(w)
        self.pipes.append(r)
        return r

    def close(self) -> bool:
        """Stop the feeders, close the pipes, lift the read-only marks, and put each node that carried
        bytes back as a regular file (the judge reads the inputs); whether a node was replaced or
        written into meanwhile."""
        import os

        for path, thread in self.feeders:
            for _ in range(100):  # a writer still waiting for a reader, or blocked on a full FIFO
                if not thread.is_alive():
                    break
                try:
                    os.close(os.open(path, os.O_RDONLY | os.O_NONBLOCK))
                except OSError:
                    break
                thread.join(0.05)
        for r in self.pipes:
            os.close(r)
        for path in reversed(self.marked):
            _mark_read_only(path, False)
        changed = False
        for name, node in self.files.items():
            if isinstance(node, Node):
                changed |= not self._intact(name, node)
        return changed

    def _intact(self, name: str, node: Node) -> bool:
        """Whether the node at ``name`` is still what was made (a node that carried bytes becomes a
        regular file of them)."""
        import os
        import stat

        path = self.folder / name
        try:
            mode = path.lstat().st_mode
        except OSError:
            return node.kind == "pipe" and not self._restore(path, node.data)
        if node.kind == "link":
            return stat.S_ISLNK(mode) and os.readlink(path) == node.data.decode()
        if node.kind == "socket":
            return stat.S_ISSOCK(mode)
        if node.kind in ("folder", "readonly-folder"):
            return stat.S_ISDIR(mode) and (node.kind != "folder" or not any(path.iterdir()))
        if node.kind == "readonly":
            return stat.S_ISREG(mode) and path.read_bytes() == node.data
        if not stat.S_ISFIFO(mode):
            return False
        path.unlink()
        return not self._restore(path, node.data)

    @staticmethod
    def _restore(path: Path, data: bytes) -> bool:
        path.write_bytes(data)
        return False


def preview(files: dict, n: int) -> dict:
    """The first ``n`` bytes of each of a case's files (a node as its kind and bytes)."""
    return {k: (f"<{v.kind}> " + repr(v.data[:n])) if isinstance(v, Node) else v[:n] for k, v in files.items()}


def keep_case(folder: Path, files: dict, argv: list[str], err: str) -> None:
    """A case written down to be run again: its regular files, nodes.txt naming its nodes, argv.txt,
    stderr.txt."""
    folder.mkdir(parents=True)
    nodes = []
    for name, data in files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        if isinstance(data, Node):
            nodes.append(f"{name}: {data.kind}" + (f" -> {data.data.decode()}" if data.kind == "link" else ""))
            data = b"" if data.kind == "link" else data.data
            if nodes[-1].endswith("folder"):
                (folder / name).mkdir(exist_ok=True)
                continue
        (folder / name).write_bytes(data)
    (folder / "nodes.txt").write_text("".join(n + "\n" for n in nodes))
    (folder / "argv.txt").write_text("\n".join(argv) + "\n")
    (folder / "stderr.txt").write_text(err)


# -- one case in a forked child, under limits the operating system enforces -----------------------
# (benchmarks/fuzz_cli.py runs every case so, tests/test_fuzz.py a share of its sample): 20 s of CPU
# time (the machine may be shared: wall-clock time is not the program's), a wall-clock backstop for
# a case that sleeps or waits, and 1 GB of memory beyond what the parent already holds

CPU_SECONDS = 20
WALL_SECONDS = 120.0
MEMORY_BYTES = 1 << 30


def _vm_size() -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    return 0


def _rss() -> int:
    """This process's resident memory, bytes."""
    with open("/proc/self/status") as fh:
        return next((int(line.split()[1]) * 1024 for line in fh if line.startswith("VmRSS:")), 0)


def fork_case(folder: Path, argv: list[str]) -> int:
    """Start ``robocal.cli.main(argv)`` in a forked child running in ``folder`` (its streams to
    stdout.txt and stderr.txt there); the child's pid."""
    import os
    import resource
    import sys
    import traceback

    pid = os.fork()
    if pid:
        return pid
    code = 99
    try:
        from robocal.cli import main

        os.chdir(folder)
        limit = _vm_size() + MEMORY_BYTES
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        resource.setrlimit(resource.RLIMIT_CPU, (CPU_SECONDS, CPU_SECONDS + 5))
        out = os.open("stdout.txt", os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
        err = os.open("stderr.txt", os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
        os.dup2(out, 1)
        os.dup2(err, 2)
        sys.stdout = open(1, "w", closefd=False)  # noqa: SIM115 - the child's streams until it exits
        sys.stderr = open(2, "w", closefd=False)  # noqa: SIM115
        code = main(argv)
    except BaseException:  # noqa: BLE001 - whatever escapes main is what we count
        traceback.print_exc()
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code if isinstance(code, int) and 0 <= code < 99 else 99)


def poll_case(pid: int, start: float):
    """(status, rusage, killed) of the child once it has ended, killing it past WALL_SECONDS from
    ``start`` (time.monotonic); None while it runs."""
    import os
    import signal
    import time

    done, status, usage = os.wait4(pid, os.WNOHANG)
    if done:
        return status, usage, False
    if time.monotonic() - start > WALL_SECONDS:
        os.kill(pid, signal.SIGKILL)
        _, status, usage = os.wait4(pid, 0)
        return status, usage, True
    return None


def forked_outcome(status, usage, killed: bool, folder: Path, files: dict, argv: list[str],
                   changed: bool = False) -> tuple[str, str]:
    """The outcome of a forked case (``judge``'s, or hang and over-memory from how the child ended)
    and its stderr (``changed``: ``Materialised.close``'s word)."""
    import os
    import signal

    err = (folder / "stderr.txt").read_text(errors="replace") if (folder / "stderr.txt").exists() else ""
    cpu = usage.ru_utime + usage.ru_stime
    signalled = os.WTERMSIG(status) if os.WIFSIGNALED(status) else None
    # SIGXCPU comes only from the CPU limit (whose accounting may read a few ms under it); a SIGKILL
    # past the limit's hard value is the same, one before it the kernel's answer to memory
    if killed or signalled == signal.SIGXCPU or (signalled == signal.SIGKILL and cpu >= CPU_SECONDS):
        return "hang", err
    # the child's peak counts the pages it shares with this process (a long run's runner grows): those aside
    if os.WIFSIGNALED(status) or usage.ru_maxrss * 1024 > _rss() + MEMORY_BYTES + (400 << 20) or "MemoryError" in err:
        return "over-memory", err
    return judge(os.WEXITSTATUS(status), err, folder, set(files) | {"stdout.txt", "stderr.txt"}, argv, files,
                 changed), err


def run_forked(files: dict, argv: list) -> tuple[str, str]:
    """Run one case in a forked child (``fork_case``) in a fresh folder; its outcome and stderr."""
    import time

    with tempfile.TemporaryDirectory() as folder:
        made = Materialised(Path(folder), files, argv)
        try:
            start = time.monotonic()
            pid = fork_case(Path(folder), made.argv)
            while (ended := poll_case(pid, start)) is None:
                time.sleep(0.002)
        finally:
            changed = made.close()
        return forked_outcome(*ended, Path(folder), files, argv, changed)


# -- one case in this process, under guards (tests/test_fuzz.py's sample, fuzz_cli.py --in-process) ----

class Hang(BaseException):
    """The CPU-time guard went off (a BaseException: no handler of the program swallows it)."""


def _alarm(signum, frame):
    raise Hang


# a case in-process that waits (a FIFO, a lock) spends no CPU time: this much wall-clock time stops it
WALL_GUARD_SECONDS = 60.0


def install_guard() -> None:
    """Let ``run_guarded``'s guards interrupt a case (SIGPROF for CPU time and SIGALRM for wall-clock
    time raise Hang)."""
    import signal

    signal.signal(signal.SIGPROF, _alarm)
    signal.signal(signal.SIGALRM, _alarm)


def run_in_process(files: dict, argv: list) -> tuple[str, str]:
    """Run one case in-process in a fresh folder; its outcome (``judge``) and its stderr."""
    import contextlib
    import io
    import os

    from robocal.cli import main

    here = os.getcwd()
    with tempfile.TemporaryDirectory() as folder:
        made = Materialised(Path(folder), files, argv)
        err = io.StringIO()
        try:
            os.chdir(folder)
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
                code = main(made.argv)
        finally:
            os.chdir(here)
            changed = made.close()
        return judge(code, err.getvalue(), Path(folder), set(files), argv, files, changed), err.getvalue()


def run_guarded(files: dict, argv: list) -> tuple[str, str]:
    """``run_in_process`` with CPU_SECONDS of CPU time (after ``install_guard``) and MEMORY_BYTES of
    address space beyond the process's; an exception escaping the program counts as a traceback."""
    import resource
    import signal
    import traceback

    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    resource.setrlimit(resource.RLIMIT_AS, (_vm_size() + MEMORY_BYTES, hard))
    signal.setitimer(signal.ITIMER_PROF, CPU_SECONDS)
    signal.setitimer(signal.ITIMER_REAL, WALL_GUARD_SECONDS)
    try:
        return run_in_process(files, argv)
    except Hang:
        return "hang", ""
    except MemoryError:
        return "over-memory", ""
    except Exception:  # noqa: BLE001 - whatever escapes main is what we count
        return "traceback", traceback.format_exc()
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.setitimer(signal.ITIMER_REAL, 0)
        resource.setrlimit(resource.RLIMIT_AS, (hard, hard))
