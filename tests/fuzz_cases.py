"""Malformed inputs for every command, as hypothesis strategies, and the judge of one run.

Shared by the bounded fuzz test (tests/test_fuzz.py, in-process) and the large run
(benchmarks/fuzz_cli.py, one forked process per case with time and memory limits). A case is
``(files, argv)``: file name -> bytes, written into an empty folder, and the command line run there.
Files are mutated from the shipped th8 example (cut small so a well-formed case runs quickly) and
from a small URDF chain; the mutations are the ones that broke readers: alias and entity bombs,
deep nesting, cycles, duplicate keys, huge numbers, other encodings, empty and binary files.
"""

from __future__ import annotations

import functools
import json
import math
import re
import sqlite3
import tempfile
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

# values that broke number parsing, unit checks and argument types
NASTY = ("0", "-0", "-1", "1e308", "-1e308", "1e400", "99999999999999999999999999", "9" * 5000, "nan", "inf",
         "-inf", ".nan", ".inf", "abc", "", " ", "1,0", "0,1", ",", "1e-320", "0x10", "true", "null", "[]", "{}",
         "~", "é", "\x00", "1" * 100_000, "NaN", "Infinity", "-", "+", "1e", "mm", "deg", "base", "geometric",
         "100000000000", "2147483648", "-2147483649", "3.5", "1_000")
WORDS = ("geometric", "compliance", "base", "markers", "frames", "j2.alpha", "j1.theta", "tool.x", "xyz", "")

_NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w.])")


def every_reader() -> None:
    """Fuzzed measurement files (small) through the compiled parser too, which by default starts at a
    few MB: each case then meets both readers (the row reader wherever the compiled one steps back)."""
    import robocal._files.measurements as measurements

    measurements.FAST_BYTES = 0


def inline_result(path) -> str:
    """The result file at ``path`` with its per-pose arrays inline (the seed of the result-file cases:
    one file to mutate, as result_to_dict writes it)."""
    from robocal.io import read_result, result_to_json

    return result_to_json(read_result(path))


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
)
BAD_MODELS = (b'{"frames": 1}', b"[]", b"\xff\xfe", b'{"name": "x"}')


@st.composite
def store_file(draw, base: bytes) -> bytes:
    kind = draw(st.sampled_from(("good",) * 3 + ("edit",) * 4 + ("model", "flip", "cut", "empty", "binary")))
    if kind == "good":
        return base
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


CALIBRATE = {"--parameters": "geometric", "--known": "base", "--tol": "1e-6", "--loss": "soft_l1",
             "--limit-mm": "0.5", "--holdout": "0.2", "--seed": "1", "--noise-mm": "0.02", "--noise-deg": "0.01",
             "--out-units": "m-rad", "--units": "mm-deg", "--sep": ",", "--decimal": ".", "--orientation": "quat_xyzw",
             "--weak": "flag", "--on-outliers": "flag", "--write-failed": None, "--register-base": None,
             "--compare": None, "--instrument": "cmm", "--nonnegative-compliance": None,
             "--map": "=pose,tool_x_mm+j1_deg=tool_x_mm", "--header": MEASUREMENTS.splitlines()[0], "--diagnose": None}
SIMULATE = {"--seed": "3", "--noise-mm": "0.02", "--length-error-mm": "0.1,1", "--angle-error-deg": "0.01,0.1",
            "--parameters": "geometric", "--units": "m-rad", "--true-model": "true.yaml"}
IDENTIFIABILITY = {"--parameters": "geometric,compliance", "--known": "base", "--tol": "1e-6", "--poses": "30",
                   "--seed": "2"}
LIMIT = {"--seed": "1", "--markers": "all", "--chunk-size": "100", "--csv-units": "mm"}
COMPENSATE_PROGRAM = {"--tool": "TOOL", "--wobj": "TOOL", "--marker": "tool", "--tol-mm": "0.001",
                      "--tol-deg": "0.0001", "--force": None}
IMPORT_URDF = {"--base-link": "l0", "--tip-link": "l3", "--marker-mm": "tool,0,0,10", "--units": "m-rad"}
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


@st.composite
def case(draw, result_text: str | None = None):
    """(files, argv) of one run of one command."""
    command = draw(st.sampled_from(("calibrate", "calibrate", "simulate", "identifiability", "limit", "import-urdf",
                                    "compensate", "report" if result_text else "calibrate")
                                   + (STORE_COMMANDS if result_text else ())))
    if command in STORE_COMMANDS:
        return draw(store_case(command, result_text))
    good_model = draw(st.integers(0, 2)) > 0
    model = MODEL.encode() if good_model else draw(model_file())
    files = {"model.yaml": model}
    if command == "calibrate":
        files["data.csv"] = draw(csv_file()) if good_model or draw(st.booleans()) else MEASUREMENTS.encode()
        argv = ["calibrate", "model.yaml", "data.csv", "--out", draw(st.sampled_from(("out", "out", "model.yaml")))]
        argv += draw(options(CALIBRATE))
        if draw(st.integers(0, 4)) == 0:         # and keep it in a store (never the user's default one)
            argv += ["--record", _value(draw, "R"), "--store", "store.sqlite"] + draw(options({"--type": "th8"}))
    elif command == "simulate":
        argv = ["simulate", "model.yaml", "--out", "sim.csv", "--poses", _value(draw, "20")] + draw(options(SIMULATE))
    elif command == "identifiability":
        argv = ["identifiability", "model.yaml"] + draw(options(IDENTIFIABILITY))
        if draw(st.booleans()):
            files["data.csv"] = draw(csv_file())
            argv.insert(2, "data.csv")
    elif command == "limit":
        files["rep.csv"] = draw(csv_file(REPEATABILITY)) if good_model else REPEATABILITY.encode()
        source = ["--repeatability-csv", "rep.csv"] if draw(st.booleans()) else \
            ["--repeatability-mm", _value(draw, "0.05")]
        argv = ["limit", "model.yaml", *source, "--encoder-resolution",
                _value(draw, "0.01deg,0.01mm,0.01mm,0.01deg,0.01deg,0.01deg"),
                "--length-quantum-mm", _value(draw, "0.01"), "--angle-quantum-deg", _value(draw, "0.001"),
                "--samples", _value(draw, "200"), "--out", "limit.json"] + draw(options(LIMIT))
    elif command == "compensate":
        name = draw(st.sampled_from(sorted(PROGRAMS)))
        good = PROGRAMS[name].encode()
        files[name] = draw(program_file(PROGRAMS[name])) if good_model or draw(st.booleans()) else good
        out = draw(st.sampled_from(("out" + name[4:], "out" + name[4:], name)))
        argv = ["compensate", "model.yaml", "model.yaml", name, "--out", out] + draw(options(COMPENSATE_PROGRAM))
        if draw(st.integers(0, 4)) == 0:
            argv += ["--dialect", _value(draw, {"mod": "rapid", "dat": "krl", "src": "krl"}.get(name[5:], "urscript"))]
    elif command == "import-urdf":
        del files["model.yaml"]
        files["robot.urdf"] = draw(urdf_file())
        argv = ["import-urdf", "robot.urdf", "--out", "imported.yaml"] + draw(options(IMPORT_URDF))
    else:
        del files["model.yaml"]
        files["result.json"] = draw(result_file(result_text))
        argv = ["report", "result.json", "--out", "report.html"]
    return files, argv


@st.composite
def store_case(draw, command: str, result_text: str):
    """(files, argv) of record, history or verify on a store, its result or its measurements damaged."""
    files = {"store.sqlite": draw(store_file(store_bytes(result_text)))}
    robot = _value(draw, "R")
    if command == "record":
        if draw(st.booleans()):
            del files["store.sqlite"]           # a new store
        files["result.json"] = draw(result_file(result_text)) if draw(st.booleans()) else result_text.encode()
        return files, ["record", "result.json", "--robot", robot, "--store", "store.sqlite"] + draw(options(RECORD))
    if command == "history":
        who = [robot] if draw(st.integers(0, 2)) else ["--type", _value(draw, "th8")]
        return files, ["history", *who, "--store", "store.sqlite"] + draw(options(HISTORY))
    files["data.csv"] = draw(csv_file()) if draw(st.booleans()) else MEASUREMENTS.encode()
    return files, ["verify", robot, "data.csv", "--store", "store.sqlite"] + draw(options(VERIFY))


# -- the judge -----------------------------------------------------------------------------------

OUTCOMES = ("clean error", "ok result", "traceback", "hang", "over-memory", "non-finite output", "multi-line error")
_NON_FINITE = re.compile(r"(?<![\w.])[-+]?(?:\.?nan|\.?inf|infinity)(?![\w])", re.IGNORECASE)


def non_finite(folder: Path, before: set[str]) -> str | None:
    """The first output file of a run holding a non-finite number, or None."""
    for p in sorted(folder.rglob("*")):
        if not p.is_file() or p.name in before or p.suffix == ".html" or ".sqlite" in p.name:
            continue
        text = p.read_text(errors="replace")
        if p.suffix == ".json":
            if _json_nulls(json.loads(text)):
                return p.name
        elif _NON_FINITE.search(text):
            return p.name
    return None


def _json_nulls(d) -> bool:
    """A result or limit file whose headline numbers are null (the writer's form of NaN/inf)."""
    if d.get("schema", "").startswith("robocal.limit"):
        return any(d.get(k) is None for k in ("limit", "repeatability", "precision"))
    stats = d.get("stats", {})
    for s in [stats.get(k) for k in ("fit_before", "fit_after")]:
        if s and s.get("n") and any(s.get(f) is None for f in ("mean", "rms", "max")):
            return True
    return any(p.get("estimate") is None or p.get("std") is None or
               not all(math.isfinite(v) for v in (p["estimate"], p["std"])) for p in d.get("parameters", []))


def judge(code, err: str, folder: Path, before: set[str]) -> str:
    """The outcome of one finished run: exit code, its stderr, the folder it ran in."""
    if "Traceback" in err or code not in (0, 1, 2, 3):
        return "traceback"
    if code in (1, 2):
        lines = [ln for ln in err.splitlines() if not ln.startswith("robocal: warning:")]
        return "clean error" if len(lines) == 1 and len(lines[0]) < 1000 else "multi-line error"
    return "non-finite output" if non_finite(folder, before) else "ok result"
