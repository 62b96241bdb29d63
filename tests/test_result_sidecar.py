"""result.json keeps what a user reads; the per-pose arrays go to a NumPy sidecar beside it, read
back by read_result and the report, checked against the SHA-256 the JSON names."""

import io
import json

import numpy as np
import pytest
from conftest import assert_one_line_error
from fuzz_cases import MEASUREMENTS, MODEL

import robocal as rc
from robocal.io import result_files, result_to_dict


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    from robocal.cli import main

    d = tmp_path_factory.mktemp("sidecar")
    (d / "m.yaml").write_text(MODEL)
    (d / "d.csv").write_text(MEASUREMENTS)
    assert main(["calibrate", str(d / "m.yaml"), str(d / "d.csv"), "--out", str(d / "o"), "--holdout", "0.3"]) in (0, 3)
    return d / "o"


ARRAYS = tuple((which, name) for which in ("fit", "validation")
               for name in ("errors_before", "errors_after", "residual_vectors", "measured_positions", "readings"))


def test_the_json_holds_no_per_pose_array_and_reads_back_whole(run):
    d = json.loads((run / "result.json").read_text())
    assert set(d["errors"]) == {"unit", "rotation_unit", "markers", "file"}
    assert d["errors"]["file"]["name"] == "result.npz" and d["errors"]["file"]["n_fit"] > 0
    result = rc.read_result(run / "result.json")
    inline = rc.io.result_from_dict(result_to_dict(result))
    for which, name in ARRAYS:
        a, b = getattr(getattr(result, which), name), getattr(getattr(inline, which), name)
        assert a is not None and a.shape[0] > 0 and np.array_equal(a, b, equal_nan=True), (which, name)
    with np.load(run / "result.npz", allow_pickle=False) as z:
        assert np.array_equal(z["fit_after"], result.fit.errors_after)


def test_the_json_does_not_grow_with_the_campaign(run):
    result = rc.read_result(run / "result.json")
    d = result_to_dict(result)
    d["errors"].update({k: np.repeat(np.asarray(v, dtype=float), 50, axis=0).tolist() for k, v in d["errors"].items()
                        if isinstance(v, list) and v and k != "markers" and not k.startswith("validation")})
    big = rc.io.result_from_dict(d)
    small_json, small_npz = result_files(result, run / "x.json").values()
    big_json, big_npz = result_files(big, run / "x.json").values()
    assert len(big_npz) > 20 * len(small_npz)
    assert abs(len(big_json) - len(small_json)) < 100  # the counts and the hash change, nothing else


def test_left_out_on_request(run, tmp_path):
    result = rc.read_result(run / "result.json")
    rc.write_result(result, tmp_path / "r.json", per_pose=False)
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]
    back = rc.read_result(tmp_path / "r.json")
    assert back.fit.errors_after.shape == (0, 1) and back.stats.fit_after.n == result.stats.fit_after.n


@pytest.mark.parametrize("spoil, words", [
    (lambda p: p.unlink(), ["result.npz", "not found"]),
    (lambda p: p.write_bytes(p.read_bytes()[:-10]), ["result.npz", "SHA-256"]),
    (lambda p: p.write_bytes(b"x" + p.read_bytes()[1:]), ["result.npz", "SHA-256"]),
], ids=["missing", "truncated", "edited"])
def test_a_spoiled_sidecar_is_one_line(run, tmp_path, cli, spoil, words):
    for name in ("result.json", "result.npz"):
        (tmp_path / name).write_bytes((run / name).read_bytes())
    spoil(tmp_path / "result.npz")
    code, _, err = cli("report", tmp_path / "result.json", "--out", tmp_path / "r.html")
    assert_one_line_error(code, err, words, command="report")
    assert not (tmp_path / "r.html").exists()


@pytest.mark.parametrize("content", ["pickle", "not-npz", "unknown-array", "path"])
def test_a_sidecar_that_matches_its_hash_but_is_not_ours_is_refused(run, tmp_path, content):
    import hashlib

    d = json.loads((run / "result.json").read_text())
    buf = io.BytesIO()
    if content == "pickle":
        np.savez(buf, fit_before=np.array([{"a": 1}], dtype=object))
    elif content == "unknown-array":
        with np.load(run / "result.npz") as z:
            np.savez(buf, **{k: z[k] for k in z.files}, extra=np.zeros(3))
    elif content == "not-npz":
        buf.write(b"PK\x03\x04 not a zip at all")
    else:
        buf.write((run / "result.npz").read_bytes())
        d["errors"]["file"]["name"] = "../result.npz"
    (tmp_path / "result.npz").write_bytes(buf.getvalue())
    d["errors"]["file"]["sha256"] = hashlib.sha256(buf.getvalue()).hexdigest()
    (tmp_path / "result.json").write_text(json.dumps(d))
    with pytest.raises(rc.InputError) as e:
        rc.read_result(tmp_path / "result.json")
    assert len(str(e.value).splitlines()) == 1 and "result" in str(e.value)
