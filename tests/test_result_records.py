"""A calibration's result is read, never changed: frozen records whose arrays are read-only and
whose mappings are read-only views, grouped by what they describe, each field documented once."""

import dataclasses
import re
import warnings
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pytest
from robots import arm6r

import robocal as rc
from robocal._identification.holdout import AccuracyInUse, Coverage, UseStats
from robocal.identification import (
    CalibrationResult,
    Check,
    Comparison,
    ContactErrors,
    ContactFigures,
    ErrorStats,
    ErrorSummary,
    IdentifiabilityResult,
    LimitJudgement,
    NestedTest,
    ParameterEstimate,
    PoseSet,
    SolverRecord,
)
from robocal.sim import socket_campaign

ARM7 = Path(__file__).resolve().parents[1] / "examples" / "arm7" / "model.yaml"


def _quiet(fn, *a, **k):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*a, **k)


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """Results of every shape: 6D poses with a validation set and a limit, contacts with tracker
    points and held-out placements, each computed and read back from its files."""
    m = arm6r()
    _, data = rc.simulate(m, 40, orientation=True, noise=2e-5, noise_rot=1e-5, seed=3)
    fit, val = data.split(0.25, rng=1)
    six = _quiet(rc.calibrate, m, fit, validation=val, limit=1e-4)
    arm7 = rc.read_model(ARM7)
    true = rc.perturb_model(arm7, rc.identifiability(arm7, parameters=("frames", "markers")).identified, rng=7)
    contacts = socket_campaign(true, placements=4, poses_per_socket=8, joint_noise=2e-5, rng=7)
    tracker = rc.measure(true, rc.random_configurations(arm7, 15, 1), rng=1)
    kit = _quiet(rc.calibrate, arm7, tracker, contacts=contacts)
    folder = tmp_path_factory.mktemp("records")
    out = {"6D": six, "contacts": kit}
    for name, r in list(out.items()):
        rc.write_result(r, folder / f"{name}.json")
        out[f"{name}, read back"] = rc.read_result(folder / f"{name}.json")
    return out


def _reachable(obj, path="result", seen=None):
    """(path, value) of every record, mapping, sequence and array reachable from ``obj``."""
    seen = set() if seen is None else seen
    if id(obj) in seen or isinstance(obj, (str, bytes, int, float, bool, type(None), np.generic)):
        return
    seen.add(id(obj))
    yield path, obj
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        for f in dataclasses.fields(obj):
            yield from _reachable(getattr(obj, f.name), f"{path}.{f.name}", seen)
    elif isinstance(obj, Mapping):
        for k, v in obj.items():
            yield from _reachable(v, f"{path}[{k!r}]", seen)
    elif isinstance(obj, (tuple, list)):
        for i, v in enumerate(obj):
            yield from _reachable(v, f"{path}[{i}]", seen)


@pytest.mark.parametrize("which", ["6D", "contacts", "6D, read back", "contacts, read back"])
def test_nothing_a_caller_does_to_a_result_changes_it(results, which):
    result = results[which]
    kinds = {"array": 0, "mapping": 0, "record": 0}
    for path, v in _reachable(result):
        assert not isinstance(v, (list, dict, set)), f"{path} is a {type(v).__name__}: it can be changed"
        if isinstance(v, np.ndarray):
            kinds["array"] += 1
            with pytest.raises(ValueError, match="read-only"):
                v[(0,) * v.ndim] = 1.0 if v.size else v.flat[:1]
        elif isinstance(v, Mapping):
            kinds["mapping"] += 1
            with pytest.raises(TypeError):
                v["written"] = 1.0          # type: ignore[index]
        elif dataclasses.is_dataclass(v):
            kinds["record"] += 1
            name = dataclasses.fields(v)[0].name
            with pytest.raises(dataclasses.FrozenInstanceError):
                setattr(v, name, None)
    assert kinds["array"] >= 10 and kinds["mapping"] >= 3 and kinds["record"] >= 10, kinds


def test_arrays_given_to_a_result_are_copied_not_frozen_in_place(results):
    result = results["6D"]
    covariance = np.array(result.covariance)                 # a caller's own, writeable array
    made = dataclasses.replace(result, covariance=covariance, provenance={"software": "robocal"})
    covariance[0, 0] = -1.0
    assert made.covariance[0, 0] == result.covariance[0, 0] and covariance.flags.writeable
    assert dict(made.provenance) == {"software": "robocal"}


def test_the_groups_hold_the_figures_once(results):
    result = results["6D"]
    assert result.solver.success and result.solver.residual_dof > 0
    n_fit, n_val = len(result.fit.readings), len(result.validation.readings)
    assert result.stats.fit_after.n == n_fit and result.stats.validation_after.n == n_val
    assert result.fit.rotation_errors_after.shape == result.fit.errors_after.shape
    assert result.validation.residual_vectors.shape == (n_val, 1, 3)
    # no flat alias beside the groups
    for old in ("success", "sigma0", "errors_after", "readings", "validation_after", "residual_dof"):
        assert not hasattr(result, old), old
    kit = results["contacts"]
    assert not hasattr(kit.contacts, "residual_dof")
    assert results["contacts, read back"].solver.residual_dof == kit.solver.residual_dof > 0


@pytest.mark.parametrize("record", [CalibrationResult, Comparison, ErrorSummary, LimitJudgement, SolverRecord, PoseSet,
                                    NestedTest, ErrorStats, ParameterEstimate, IdentifiabilityResult, Check,
                                    ContactFigures, ContactErrors, AccuracyInUse, UseStats, Coverage])
def test_every_field_of_a_record_is_documented_once(record):
    doc = record.__doc__ or ""
    assert "Attributes\n    ----------\n" in doc, record.__name__
    documented = re.findall(r"^    (\w+) : ", doc.split("Attributes", 1)[1], flags=re.M)
    assert documented == [f.name for f in dataclasses.fields(record)]


def test_a_comparison_groups_each_test_with_its_figures():
    m = arm6r(masses=True)
    _, data = rc.simulate(m, 40, seed=4)
    cmp = _quiet(rc.compare, m, data, transmission=False)
    test = cmp.compliance_test
    assert 0.0 <= test.p_value <= 1.0 and test.f_statistic >= 0.0
    assert cmp.verdict == test.summary and cmp.backlash is None and cmp.backlash_test is None
    assert cmp.best is (cmp.combined if test.helped else cmp.geometric)
    assert list(cmp.results.values()) == [cmp.geometric, cmp.combined]
    with pytest.raises(TypeError):
        cmp.results["geometric"] = cmp.combined     # type: ignore[index]
    with pytest.raises(dataclasses.FrozenInstanceError):
        cmp.compliance_test = test          # type: ignore[misc]
