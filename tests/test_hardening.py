"""Malformed files and arguments that once crashed, hung or wrote nonsense: each now ends in one
clear line (exit 2) or a sound result, quickly, and leaves nothing behind."""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import assert_one_line_error
from fuzz_cases import MEASUREMENTS, MODEL, REPEATABILITY, URDF, alias_bomb, deep, inline_result

import robocal as rc

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "th8"
LIMIT_ARGS = ("--encoder-resolution", "0.01deg,0.01mm,0.01mm,0.01deg,0.01deg,0.01deg", "--length-quantum-mm",
              "0.01", "--angle-quantum-deg", "0.001", "--samples", "200")


@pytest.fixture
def files(tmp_path):
    (tmp_path / "model.yaml").write_text(MODEL)
    (tmp_path / "data.csv").write_text(MEASUREMENTS)
    (tmp_path / "rep.csv").write_text(REPEATABILITY)
    return tmp_path


@pytest.fixture(scope="module")
def result_text(tmp_path_factory):
    """A real result.json of a small campaign."""
    from robocal.cli import main

    d = tmp_path_factory.mktemp("result")
    (d / "m.yaml").write_text(MODEL)
    (d / "d.csv").write_text(MEASUREMENTS)
    assert main(["calibrate", str(d / "m.yaml"), str(d / "d.csv"), "--out", str(d / "o")]) in (0, 3)
    return inline_result(d / "o" / "result.json")


def model_commands(d):
    """Every command that reads a model file, as argv."""
    return [("calibrate", d / "model.yaml", d / "data.csv", "--out", d / "out"),
            ("identifiability", d / "model.yaml", "--poses", "20"),
            ("simulate", d / "model.yaml", "--out", d / "sim.csv", "--poses", "5"),
            ("limit", d / "model.yaml", "--repeatability-mm", "0.05", *LIMIT_ARGS, "--out", d / "limit.json")]


def one_line(cli, argv, words=(), *, seconds=30.0):
    """A one-line error naming ``words``; ``seconds`` only catches a hang (bombs once took minutes)."""
    start = time.monotonic()
    code, out, err = cli(*argv)
    assert time.monotonic() - start < seconds, "took too long"
    assert_one_line_error(code, err, words, command=argv[0])
    assert len(err) < 600, len(err)
    return err


# -- model files -------------------------------------------------------------------------------

@pytest.mark.parametrize("key", ["name", "description", "gravity"])
def test_alias_bomb_refused_quickly_by_every_command(files, cli, key):
    (files / "model.yaml").write_text(MODEL + alias_bomb(10, key))
    for argv in model_commands(files):
        one_line(cli, argv, ["model.yaml", "alias", "line"])
    assert not (files / "out").exists() and not (files / "sim.csv").exists()


def test_self_reference_and_anchor_refused(files, cli):
    (files / "model.yaml").write_text(MODEL.replace("gravity: [0, 0, -9.81]", "gravity: &g [0, 0, *g]"))
    one_line(cli, model_commands(files)[1], ["alias"])


@pytest.mark.parametrize("text", [deep(100_000, "flow"), deep(2000, "block")])
def test_deeply_nested_model_refused(files, cli, text):
    (files / "model.yaml").write_text(MODEL.replace("gravity: [0, 0, -9.81]", "gravity:\n" + text))
    one_line(cli, model_commands(files)[1], ["model.yaml", "nested"])


@pytest.mark.parametrize("value", ["1" * 400, "1" * 5000, "-" + "9" * 40, "1e400", "1.0e400", "1e300"])
def test_huge_numbers_in_model_refused(files, cli, value):
    (files / "model.yaml").write_text(MODEL.replace("r: 600", f"r: {value}"))
    one_line(cli, model_commands(files)[1], ["model.yaml"])


def test_duplicate_key_refused_naming_key_and_both_lines(files, cli):
    # the second 'units' used to win silently: the example then fit with the base moved by 2 km
    (files / "model.yaml").write_text(MODEL + "units: {length: m, angle: rad}\n")
    n = MODEL.count("\n")
    one_line(cli, model_commands(files)[0], ["'units'", "twice", f"(lines 8 and {n + 1})"])
    assert not (files / "out").exists()


def test_non_string_unit_and_value_excerpt(files, cli):
    (files / "model.yaml").write_text(MODEL.replace("length: mm", "length: [mm]"))
    one_line(cli, model_commands(files)[1], ["units.length"])
    (files / "model.yaml").write_text(MODEL.replace("joint: revolute, mass: 80", "joint: " + "x" * 50_000))
    one_line(cli, model_commands(files)[1], ["characters"])


@pytest.mark.parametrize("raw", [b"", b"\x00\x01\x02binary", "units: é".encode("latin-1"),
                                 MODEL.encode("utf-16")])
def test_empty_binary_and_other_encodings(files, cli, raw):
    (files / "model.yaml").write_bytes(raw)
    one_line(cli, model_commands(files)[1], ["model.yaml"])


# -- measurement and repeatability files ---------------------------------------------------------

@pytest.mark.parametrize("raw", ["pose,cycle,x_mm,y_mm,z_mm\n1,1,1,2,3\n1,2,1,é,3\n".encode("latin-1"),
                                 ('pose,cycle,x_mm,y_mm,z_mm\n"1,1,' + "x" * 200_000 + "\n").encode(),
                                 b"pose,cycle,x_mm,y_mm,z_mm\n1,1,1,2,\x003\n"])
def test_repeatability_csv_encoding_and_csv_errors(files, cli, raw):
    (files / "rep.csv").write_bytes(raw)
    one_line(cli, ("limit", files / "model.yaml", "--repeatability-csv", files / "rep.csv", *LIMIT_ARGS,
                   "--out", files / "limit.json"), ["rep.csv"])


def test_huge_cell_value_is_an_error_not_a_nonsense_result(files, cli):
    lines = MEASUREMENTS.splitlines()
    lines[3] = lines[3].replace(lines[3].split(",")[7], "1e300")
    (files / "data.csv").write_text("\n".join(lines) + "\n")
    one_line(cli, model_commands(files)[0], ["data.csv", "line 4", "too large"])
    assert not (files / "out").exists()


@pytest.mark.parametrize("quat", ["1e308,1e308,0,0", "0,0,0,0", "a,b,c,d"])
def test_malformed_quaternion_columns(files, cli, quat):
    lines = MEASUREMENTS.splitlines()
    lines[0] += ",tool_qx,tool_qy,tool_qz,tool_qw"
    lines[1:] = [ln + ",0,0,0,1" for ln in lines[1:]]
    lines[2] = lines[2][:-len(",0,0,0,1")] + "," + quat
    (files / "data.csv").write_text("\n".join(lines) + "\n")
    one_line(cli, model_commands(files)[0], ["data.csv", "line 3"])


def test_too_many_poses_refused(files, cli, monkeypatch):
    import robocal._files.measurements as m

    monkeypatch.setattr(m, "MAX_POSES", 10)
    one_line(cli, model_commands(files)[0], ["data.csv", "up to 10 poses"])


# -- URDF ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("urdf", [
    URDF.replace("</robot>", '<joint name="back" type="revolute"><parent link="l3"/><child link="l0"/>'
                             '<limit lower="-1" upper="1"/></joint></robot>'),
    URDF.replace('<parent link="l0"/>', '<parent link="l3"/>'),
])
def test_urdf_cycle_refused_before_walking(tmp_path, cli, urdf):
    (tmp_path / "r.urdf").write_text(urdf)
    for extra in ((), ("--tip-link", "l2")):
        one_line(cli, ("import-urdf", tmp_path / "r.urdf", "--out", tmp_path / "m.yaml", *extra), ["cycle"])


def test_urdf_depth_and_entity_bombs(tmp_path, cli):
    (tmp_path / "r.urdf").write_text(URDF.replace("</robot>", "<a>" * 100_000 + "</a>" * 100_000 + "</robot>"))
    one_line(cli, ("import-urdf", tmp_path / "r.urdf", "--out", tmp_path / "m.yaml"), ["nested"])
    (tmp_path / "r.urdf").write_text('<!DOCTYPE r [<!ENTITY a "aaaa">]>' + URDF)
    one_line(cli, ("import-urdf", tmp_path / "r.urdf", "--out", tmp_path / "m.yaml"), ["ENTITY"])


def test_import_urdf_writes_only_models_robocal_reads(tmp_path, cli):
    (tmp_path / "r.urdf").write_text(URDF.replace('"l3"', '"base"'))
    one_line(cli, ("import-urdf", tmp_path / "r.urdf", "--out", tmp_path / "m.yaml"), ["base"])
    assert not (tmp_path / "m.yaml").exists()
    code, _, err = cli("import-urdf", tmp_path / "r.urdf", "--out", tmp_path / "m.yaml", "--marker-mm", "base,0,0,1")
    assert code == 2 and not (tmp_path / "m.yaml").exists()


# -- result files and report ----------------------------------------------------------------------

def _edit(d, path, value):
    for k in path[:-1]:
        d = d[k]
    if value is KeyError:
        del d[path[-1]]
    else:
        d[path[-1]] = value


@pytest.mark.parametrize("path, value", [
    (("stats", "fit_after"), KeyError), (("parameters", 0, "std"), "x"), (("errors", "fit_before"), []),
    (("errors", "fit_residual_vectors"), [[]]), (("identifiability",), {}), (("checks", 0), 3),
    (("nominal_model", "frames"), []), (("covariance",), [[1.0]]), (("stats", "fit_before", "n"), -1),
    (("errors", "markers"), [None]), (("provenance",), "x"), (("notes",), [1]),
    (("provenance", "data", "labels", 2), {}), (("provenance", "data", "n_poses"), "x"), (("provenance", "date"), []),
])
def test_report_on_a_broken_result_refuses_in_one_line(tmp_path, cli, result_text, path, value):
    pytest.importorskip("matplotlib")
    d = json.loads(result_text)
    _edit(d, path, value)
    (tmp_path / "r.json").write_text(json.dumps(d))
    one_line(cli, ("report", tmp_path / "r.json", "--out", tmp_path / "r.html"), ["r.json"])
    assert not (tmp_path / "r.html").exists()


def test_report_on_a_large_result_renders(tmp_path, cli, result_text):
    """A result of 5,000 poses once kept report busy for minutes (an artist per pose)."""
    pytest.importorskip("matplotlib")
    d = json.loads(result_text)
    for key, v in d["errors"].items():
        if isinstance(v, list) and v and key != "markers":
            d["errors"][key] = (v * (5000 // len(v) + 1))[:5000]
    (tmp_path / "r.json").write_text(json.dumps(d))
    start = time.monotonic()
    code, _, err = cli("report", tmp_path / "r.json", "--out", tmp_path / "r.html")
    assert code == 0, err
    assert time.monotonic() - start < 120, "hangs"


@pytest.mark.parametrize("text", ['{"schema": "robocal.result/1", "schema": "x"}', deep(100_000, "json"),
                                  deep(200, "json"), '{"nfev": NaN}', '{"nfev": ' + "9" * 5000 + "}",
                                  '{"x": 1e999}'])
def test_result_reader_refuses_duplicates_depth_and_numbers(tmp_path, cli, text):
    pytest.importorskip("matplotlib")
    (tmp_path / "r.json").write_text(text)
    one_line(cli, ("report", tmp_path / "r.json", "--out", tmp_path / "r.html"), ["r.json"])


def test_json_duplicate_names_both_lines(tmp_path):
    (tmp_path / "r.json").write_text('{\n"schema": "robocal.result/1",\n"loss": 1,\n"loss": 2\n}')
    with pytest.raises(rc.InputError, match=r"'loss' given twice \(lines 3 and 4\)"):
        rc.read_result(tmp_path / "r.json")


# -- arguments ------------------------------------------------------------------------------------

@pytest.mark.parametrize("argv, option", [
    (("simulate", "{m}", "--out", "{d}/s.csv", "--poses", "100000000000"), "--poses"),
    (("simulate", "{m}", "--out", "{d}/s.csv", "--poses", "5", "--seed", "-1"), "--seed"),
    (("simulate", "{m}", "--out", "{d}/s.csv", "--poses", "5", "--noise-mm", "-1"), "--noise-mm"),
    (("simulate", "{m}", "--out", "{d}/s.csv", "--poses", "5", "--noise-mm", "1e308"), "--noise-mm"),
    (("simulate", "{m}", "--out", "{d}/s.csv", "--poses", "5", "--length-error-mm", "1,0"), "--length-error-mm"),
    (("simulate", "{m}", "--out", "{d}/s.csv", "--poses", "5", "--parameters", ""), "--parameters"),
    (("identifiability", "{m}", "--tol", "1"), "--tol"),
    (("identifiability", "{m}", "--poses", "-3"), "--poses"),
    (("identifiability", "{m}", "--known", "geometric"), "known"),
    (("calibrate", "{m}", "{d}/data.csv", "--out", "{d}/o", "--known", "geometric"), "known"),
    (("calibrate", "{m}", "{d}/data.csv", "--out", "{d}/o", "--seed", "x"), "--seed"),
    (("calibrate", "{m}", "{d}/data.csv", "--out", "{d}/o", "--sep", '"'), "--sep"),
    (("calibrate", "{m}", "{d}/data.csv", "--out", "{d}/o", "--loss", "x" * 10_000), "--loss"),
    (("limit", "{m}", "--repeatability-mm", "-1", *LIMIT_ARGS, "--out", "{d}/l.json"), "--repeatability-mm"),
    (("limit", "{m}", "--repeatability-mm", "1", *LIMIT_ARGS, "--samples", "1e12", "--out", "{d}/l.json"),
     "--samples"),
    (("calibrate", "{m}"), "required"),
    (("simulate", "{m}", "--out", "{d}/s.csv", "--poses", "5", "--true-model", "9" * 5000), "..."),
])
def test_every_option_checked_at_parse_time_in_one_line(files, cli, argv, option):
    argv = [a.format(m=files / "model.yaml", d=files) for a in argv]
    one_line(cli, argv, [option])
    assert not (files / "o").exists() and not (files / "s.csv").exists()


def test_identifiability_never_reports_an_infinite_condition_number(files, cli):
    code, out, err = cli("identifiability", files / "model.yaml", "--tol", "0.999999", "--poses", "20")
    assert "inf" not in out
    if code:
        assert_one_line_error(code, err, ["identifiable"], command="identifiability")


# -- writing ---------------------------------------------------------------------------------------

def test_output_checked_before_the_work(files, cli):
    (files / "afile").write_text("x")
    for out in (files / "afile" / "run", files / "model.yaml"):
        code, stdout, err = cli("calibrate", files / "model.yaml", files / "data.csv", "--out", out)
        assert code == 2 and stdout == "" and "is a file, not a folder" in err and len(err.splitlines()) == 1
    code, stdout, err = cli("simulate", files / "model.yaml", "--out", files / "afile" / "s.csv", "--poses", "5")
    assert code == 2 and stdout == "" and "afile" in err and ".tmp" not in err


def test_symlinks_are_never_written_through(files, cli):
    """A link at the output's name or at the old predictable temporary name: its target is untouched."""
    out = files / "run"
    out.mkdir()
    target = files / "precious.txt"
    target.write_text("keep me")
    for name in ("result.json", f".result.json.{os.getpid()}.tmp", f".calibrated.yaml.{os.getpid()}.tmp"):
        (out / name).symlink_to(target)
    code, _, err = cli("calibrate", files / "model.yaml", files / "data.csv", "--out", out)
    assert code == 2 and "exists" in err and target.read_text() == "keep me"
    code, _, err = cli("calibrate", files / "model.yaml", files / "data.csv", "--out", out, "--force")
    assert code in (0, 3), err
    assert target.read_text() == "keep me"
    assert not (out / "result.json").is_symlink() and json.loads((out / "result.json").read_text())["schema"]
    assert sorted(p.name for p in out.iterdir() if p.name.endswith(".tmp")) == \
        sorted(n for n in (f".result.json.{os.getpid()}.tmp", f".calibrated.yaml.{os.getpid()}.tmp"))


def test_temporary_files_removed_on_interrupt(tmp_path, monkeypatch):
    from robocal._files import text

    real = os.fsync

    def interrupted(fd):
        real(fd)
        raise KeyboardInterrupt

    monkeypatch.setattr(text.os, "fsync", interrupted)
    with pytest.raises(KeyboardInterrupt):
        text.write_texts({tmp_path / "a.txt": "a", tmp_path / "b.txt": "b"})
    assert list(tmp_path.iterdir()) == []


def test_sigterm_leaves_no_temporary_file(tmp_path):
    (tmp_path / "model.yaml").write_text(MODEL)
    p = subprocess.Popen([sys.executable, "-m", "robocal", "simulate", str(tmp_path / "model.yaml"), "--out",
                          str(tmp_path / "s.csv"), "--poses", "100000"], stderr=subprocess.PIPE, text=True)
    time.sleep(3.0)
    p.terminate()
    _, err = p.communicate(timeout=60)
    assert "Traceback" not in err
    assert not [q for q in tmp_path.iterdir() if q.name.endswith(".tmp")]


def test_memory_error_is_one_line_with_the_size(files, cli, monkeypatch):
    import robocal._calibration

    def oom(*a, **k):
        raise MemoryError("Unable to allocate 13.3 GiB for an array with shape (1000000, 1784) and data type float64")

    monkeypatch.setattr(robocal._calibration, "calibrate", oom)
    one_line(cli, model_commands(files)[0], ["out of memory", "13.3 GiB"])


# -- determinism ----------------------------------------------------------------------------------

def _calibrate_with_threads(tmp_path, n):
    env = dict(os.environ, OPENBLAS_NUM_THREADS=str(n), OMP_NUM_THREADS=str(n), MKL_NUM_THREADS=str(n))
    out = tmp_path / f"t{n}"
    subprocess.run([sys.executable, "-m", "robocal", "calibrate", str(tmp_path / "model.yaml"),
                    str(tmp_path / "data.csv"), "--out", str(out), "--holdout", "0.3", "--seed", "7"],
                   env=env, capture_output=True, check=False)
    d = json.loads((out / "result.json").read_text())
    d["provenance"].pop("date", None)
    return d, (out / "calibrated.yaml").read_text() if (out / "calibrated.yaml").exists() else None


def test_bit_identical_across_thread_counts(files):
    one, yaml_one = _calibrate_with_threads(files, 1)
    two, yaml_two = _calibrate_with_threads(files, 2)
    assert one == two
    assert _strip_date(yaml_one) == _strip_date(yaml_two)


def _strip_date(text):
    return None if text is None else "\n".join(ln for ln in text.splitlines() if "date:" not in ln)
