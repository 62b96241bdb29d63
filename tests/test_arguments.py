"""Every public function checks its arguments before any work: a bad value raises InputError naming
the argument and what is allowed (as scipy's least_squares does), and no internal error (numpy's,
LAPACK's, a TypeError or an AttributeError) reaches the caller for any argument."""

from __future__ import annotations

import functools
import importlib
import importlib.util
import inspect
import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import robocal as rc
from robocal.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
PUBLIC = ("robocal", "robocal.kinematics", "robocal.io", "robocal.sim", "robocal.limit", "robocal.report",
          "robocal.identification")
def public_functions() -> dict[str, object]:
    out = {}
    for mod in PUBLIC:
        m = importlib.import_module(mod)
        for name in m.__all__:
            obj = getattr(m, name)
            if inspect.isfunction(obj):
                out.setdefault(name, obj)
    return out


@functools.cache
def world():
    """A small robot, its data, results and files, shared by the valid calls below."""
    from robocal.identification import Problem
    from robocal.sim import RobotImperfections, socket_campaign

    model = rc.default_masses(rc.serial_model("rrr", [dict(), dict(alpha=-np.pi / 2, r=0.1), dict(d=0.4)],
                                              markers=[("tool", (0.3, 0.02, 0.05))]), 10.0)
    true, data = rc.simulate(model, 60, seed=2)   # (40 poses, seed 1: in_use_check divides by a zero fit mean)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(model, data)
        comparison = rc.compare(model, data)
    names = rc.candidate_parameters(model)
    arm7 = rc.read_model(ROOT / "examples" / "arm7" / "model.yaml")
    contacts = socket_campaign(arm7, placements=3, poses_per_socket=6, rng=0)
    arm7_names = rc.candidate_parameters(arm7)
    ident = rc.identifiability(model, data)
    problem = Problem(model, ident.identified, data=data, compliance=False)
    from robocal.identification import solve
    solution = solve(problem, rc.parameter_vector(model))
    J = rc.jacobian(model, data.q)[:, 0, :3, :].transpose(0, 2, 1).reshape(-1, len(rc.parameter_names(model)))
    lay = rc.kinematics.parameter_layout(model)
    rep = rc.read_repeatability_csv(ROOT / "examples" / "th8" / "repeatability.csv")
    return dict(
        rep=rep, repeatability=rc.iso9283_repeatability(rep.pose_ids, rep.points), model=model, true=true,
        data=data, result=result, comparison=comparison, q=data.q[:5], names=names,
        th8=rc.read_model(ROOT / "examples" / "th8" / "model.yaml"),
        contacts=contacts, arm7=arm7, arm7_names=arm7_names, cresult=rc.calibrate(arm7, contacts=contacts),
        cproblem=Problem(arm7, arm7_names, contacts=contacts, compliance=False),
        precision=rc.controller_precision(model, encoder_resolution=(1e-5,) * 3, length_quantum=1e-5,
                                          angle_quantum=1e-5, n_samples=200, rng=0),
        imp=RobotImperfections(encoder_resolution=(1e-5,) * 3, repeatability_sigma=1e-5,
                               instrument_noise_per_m=0.0),
        problem=problem, solution=solution, ident=ident, J=J,
        quantities=[lay[n].quantity for n in rc.parameter_names(model)],
        all_names=rc.parameter_names(model), **_world_of_programs_and_store(model, data, result))


def _world_of_programs_and_store(model, data, result) -> dict:
    """A six-axis arm with a program, and a store's records, for the programs' and the store's calls."""
    from robots import arm6r

    arm = arm6r()
    ev = rc.forward_kinematics(arm, np.radians([[10.0, -20, 30, 5, 40, 15], [-15, 10, 20, -5, 30, 0]]))
    cals = [rc.stored_calibration(result, "SN-1", robot_type="arm", at=f"2026-0{k}-01") for k in (1, 2)]
    h = rc.judge_changes(cals)
    v = rc.verify(model, data, rc.accuracy_at_calibration(rc.io.result_to_dict(result)))
    return dict(arm=arm, arm_P=ev.positions[:, 0], arm_R=ev.rotations[:, 0],
                program=rc.io.read_program(ROOT / "tests" / "programs" / "example.mod"), cals=cals, changes=h,
                verification=v, diagnosis=rc.diagnose(model, data, result),
                then=rc.accuracy_at_calibration(rc.io.result_to_dict(result)))


_OPEN: dict = {}          # test folder -> its open store (closed by the fixture below)


@pytest.fixture(autouse=True)
def _close_stores():
    yield
    while _OPEN:
        _OPEN.popitem()[1].close()


def _store(tmp: Path, w):
    """A store of two calibrations of robot SN-1 (type arm), made once per test folder, open."""
    path = tmp / "store.sqlite"
    if tmp not in _OPEN:
        _OPEN[tmp] = rc.open_store(path, create=True)
        for k in (1, 2):
            _OPEN[tmp].record(w["result"], "SN-1", robot_type="arm", at=f"2026-0{k}-01")
    return _OPEN[tmp]


def valid_calls(tmp: Path) -> dict:
    """A valid call of every public function: name -> (positional args, keyword args)."""
    w = world()
    m, data, res, q = w["model"], w["data"], w["result"], w["q"]
    files = {"model": tmp / "model.yaml", "data": tmp / "data.csv", "result": tmp / "result.json",
             "dh": tmp / "dh.csv", "urdf": tmp / "robot.urdf", "contacts": tmp / "contacts.csv",
             "profile": tmp / "profile.yaml", "rep": ROOT / "examples" / "th8" / "repeatability.csv"}
    if not files["model"].exists():
        rc.write_model(m, files["model"])
        rc.write_measurements(data, files["data"], model=m)
        rc.write_result(res, files["result"])
        rc.write_mdh_csv(m, files["dh"])
        rc.io.write_urdf(m, files["urdf"])
        rc.io.write_contacts(w["contacts"], files["contacts"], w["arm7"])
        files["profile"].write_text("robocal_profile: 1\nunits: mm-deg\n")
        (tmp / "out").mkdir()
    X = np.eye(4)
    X[:3, 3] = (0.1, 0.2, 0.3)
    store = _store(tmp, w)
    history = rc.History("SN-1", tuple(w["cals"]), (), *w["changes"], 0.05, ("frames",))
    arm, P, R, prog = w["arm"], w["arm_P"], w["arm_R"], w["program"]
    return {
        # robocal
        "calibrate": ((m, data), {}),
        "compare": ((m, data), {}),
        "error_stats": ((np.array([1e-3, 2e-3]),), {}),
        "register_base": ((m, data), {}),
        "identifiability": ((m, data), {}),
        "status_table": ((w["ident"], [f.name for f in m.frames]), {}),
        "select_poses": ((m, 10), {"n_candidates": 60}),
        "predict_campaign": ((m, data.q), {"n_workspace": 50}),
        "compensate": ((m, q), {"nominal": m}),
        "joint_jacobian": ((m, q), {}),
        "simulate": ((m, 10), {}),
        "measure": ((m, q), {}),
        "perturb_model": ((m, w["names"]), {}),
        "random_configurations": ((m, 5), {}),
        "sampling_box": ((m,), {}),
        "serial_model": (("r", [dict()]), {}),
        "default_masses": ((m,), {"total_mass": 10.0}),
        "mdh_transform": ((m.frames[1],), {"q": 0.3}),
        "parallel_beta_frames": ((m.frames,), {}),
        "placement_parameters": ((X,), {}),
        "candidate_parameters": ((m,), {}),
        "model_from_vector": ((m, rc.parameter_vector(m)), {}),
        "parameter_names": ((m,), {}),
        "parameter_vector": ((m,), {}),
        "parameter_layout": ((m,), {}),
        "families": ((m,), {}),
        "matched_by_pattern": ((m, ["j*.d"]), {}),
        "evaluate": ((m, q), {}),
        "forward_kinematics": ((m, q), {}),
        "jacobian": ((m, q), {}),
        "gravity_loads": ((m, q), {}),
        "from_standard_dh": (([dict(joint="revolute", d=0.1)],), {"name": "dh"}),
        "mdh_table": ((m,), {}),
        "to_standard_dh": ((m,), {}),
        # files
        "read_model": ((files["model"],), {}),
        "write_model": ((m, tmp / "out" / "m.yaml"), {"force": True}),
        "model_from_dict": ((rc.model_to_dict(m),), {}),
        "model_to_dict": ((m,), {}),
        "model_to_yaml": ((m,), {}),
        "calibration_record": ((res,), {}),
        "read_calibration": ((files["model"],), {}),
        "read_measurements": ((files["data"], m), {}),
        "write_measurements": ((data, tmp / "out" / "d.csv"), {"model": m, "force": True}),
        "measurements_to_csv": ((data,), {"model": m}),
        "split_sets": ((data,), {}),
        "read_result": ((files["result"],), {}),
        "write_result": ((res, tmp / "out" / "r.json"), {"force": True}),
        "result_files": ((res, tmp / "out" / "r2.json"), {}),
        "sidecar_path": ((tmp / "out" / "r.json",), {}),
        "result_from_dict": ((rc.io.result_to_dict(res),), {}),
        "result_to_dict": ((res,), {}),
        "result_to_json": ((res,), {}),
        "limit_to_dict": ((rc.accuracy_limit(w["repeatability"], w["precision"]),), {}),
        "read_repeatability_csv": ((files["rep"],), {}),
        "read_urdf": ((files["urdf"],), {}),
        "read_bag": ((ROOT / "examples" / "th8" / "mocap.bag", w["th8"]),
                     {"joints": "/joint_states", "markers": {"tool": "/mocap/tool/pose"},
                      "rules": rc.io.StillRules(clock_offset=0.37)}),
        "urdf_text": ((m,), {}),
        "write_urdf": ((m, tmp / "out" / "r.urdf"), {"force": True}),
        "read_dh_table": ((files["dh"],), {}),
        "write_mdh_csv": ((m, tmp / "out" / "dh.csv"), {"force": True}),
        "mdh_csv": ((m,), {}),
        "dh_csv": ((m,), {}),
        "read_contacts": ((files["contacts"], w["arm7"]), {}),
        "write_contacts": ((w["contacts"], tmp / "out" / "c.csv", w["arm7"]), {"force": True}),
        "contacts_to_csv": ((w["contacts"], w["arm7"]), {}),
        "read_profile": ((files["profile"],), {}),
        "profile_from_dict": (({"robocal_profile": 1, "units": "mm-deg"},), {}),
        # limit
        "accuracy_limit": ((w["repeatability"], w["precision"]), {}),
        "controller_precision": ((m,), dict(encoder_resolution=(1e-5,) * 3, length_quantum=1e-5,
                                            angle_quantum=1e-5, n_samples=100, rng=0)),
        "predicted_controller_precision": ((m,), dict(encoder_resolution=(1e-5,) * 3, length_quantum=1e-5,
                                                      angle_quantum=1e-5, n_configurations=100, rng=0)),
        "iso9283_repeatability": ((w["rep"].pose_ids, w["rep"].points), {}),
        "rounded_parameters": ((m, 1e-5, 1e-5), {}),
        # sim
        "measure_campaign": ((w["true"], q, w["imp"]), {"rng": 0}),
        "accuracy_in_use": ((w["true"], m, m, q, w["imp"]), {"rng": 0}),
        "backlash_sides": ((w["true"], q, w["imp"]), {}),
        "stored_model": ((m, w["imp"]), {}),
        "approach_sides": ((q,), {}),
        "plan_sockets": ((w["arm7"],), dict(placements=(3,), poses_per_socket=(6,))),
        "socket_campaign": ((w["arm7"],), dict(placements=3, poses_per_socket=5, rng=0)),
        "plane_campaign": ((w["arm7"],), dict(planes=2, poses_per_plane=5, rng=0)),
        "bar_campaign": ((w["arm7"],), dict(pairs=5, rng=0)),
        "plate_placements": ((3,), {"rng": 0}),
        "attained": ((w["true"], q, w["imp"]), {"warmth": np.zeros(len(q)), "rng": 0}),
        "placement_errors": ((w["true"], m, rc.sim.PRESETS["gears"]), {"n": 5, "rng": 0}),
        "reach": ((m, rc.forward_kinematics(m, q).positions[:, 0]), {"rng": 0}),
        # identification
        "contact_errors": ((w["arm7"], w["contacts"]), {}),
        "contact_identifiability": ((w["cproblem"], w["arm7_names"]), {}),
        "analyse": ((w["J"], w["all_names"]), {}),
        "weakly_identifiable": ((w["J"], w["all_names"], w["quantities"], 1e-5), {}),
        "design_problem": ((m, data.q, w["names"]), {}),
        "solve": ((w["problem"], rc.parameter_vector(m)), {}),
        "covariance": ((w["solution"],), {}),
        "verdict": ((res.checks,), {}),
        "outlier_check": ((np.zeros((3, 3)), None, rc.Noise.of()), {"labels": ["a", "b", "c"]}),
        "outlier_bar": ((100,), {}),
        # report
        "render_report": ((res,), {}),
        "write_report": ((res, tmp / "out" / "r.html"), {"force": True}),
        "calibration_summary": ((res,), {}),
        "comparison_summary": ((w["comparison"],), {}),
        "identifiability_summary": ((m, w["ident"], "40 poses"), {}),
        "checks_lines": ((res.checks,), {}),
        "verdict_line": ((res,), {}),
        "fmt": ((1e-3,), {"unit": "m"}),
        # robot programs
        "arm_chain": ((arm,), {"marker": 0}),
        "posture": ((arm, np.zeros((2, 6))), {}),
        "inverse_kinematics": ((arm, P, R), {"iterations": 20}),
        "compensate_poses": ((arm, arm, P, R), {}),
        "read_program": ((ROOT / "tests" / "programs" / "example.mod",), {}),
        "program_joints": ((prog, arm), {}),
        "read_program_joints": ((ROOT / "tests" / "programs" / "example.mod", arm), {}),
        "compensate_program": ((prog, arm, arm), {}),
        # diagnosis, verification and the store
        "diagnose": ((m, data, res), {}),
        "diagnose_contacts": ((w["arm7"], w["contacts"], w["cresult"]), {}),
        "verify": ((m, data, w["then"]), {}),
        "positional_accuracy": ((np.zeros((3, 3)), np.ones((3, 3)), [0, 1, 1], 2), {}),
        "accuracy_at_calibration": ((rc.io.result_to_dict(res),), {}),
        "default_store_path": ((), {"environ": {"XDG_DATA_HOME": str(tmp)}}),
        "store_location": ((), {"option": str(tmp / "store.sqlite"), "environ": {}}),
        "open_store": ((tmp / "store.sqlite",), {}),
        "model_document": ((m,), {}),
        "stored_calibration": ((res, "SN-2"), {"robot_type": "arm", "at": "2026-03-01"}),
        "sidak_threshold": ((0.05, 10), {}),
        "judge_changes": ((w["cals"],), {}),
        "judge_overall": ((w["cals"],), {}),
        "compare_type": (("arm", w["cals"]), {}),
        "history": ((store, "SN-1"), {}),
        "type_comparison": ((store, "arm"), {}),
        "latest_usable": ((store, "SN-1"), {}),
        "verify_robot": ((store, "SN-1", data), {"save": False}),
        "change_line": ((w["changes"][0][0],), {}),
        "history_summary": ((history,), {}),
        "type_summary": ((rc.compare_type("arm", w["cals"]),), {}),
        "verification_summary": ((w["verification"], "SN-1", w["cals"][0]), {}),
        "render_history": ((history,), {}),
        "write_history": ((history, tmp / "out" / "h.html"), {"force": True}),
    }


NAN, INF = math.nan, math.inf
Q2 = np.zeros((2, 2))              # readings of the wrong width for the 3-joint robot
# (function, argument, bad value): each must raise InputError naming the argument
BAD = [
    ("calibrate", "tol", -1.0), ("calibrate", "tol", 0.0), ("calibrate", "tol", 2.0), ("calibrate", "tol", NAN),
    ("calibrate", "f_scale", -1.0), ("calibrate", "f_scale", 0.0), ("calibrate", "f_scale", INF),
    ("calibrate", "limit", -1.0), ("calibrate", "limit", 0.0), ("calibrate", "limit", "1 mm"),
    ("calibrate", "max_nfev", 0), ("calibrate", "max_nfev", 2.5), ("calibrate", "parameters", 5),
    ("calibrate", "known", [1, 2]), ("calibrate", "validation", "data.csv"), ("calibrate", "noise", "laser"),
    ("calibrate", "loss", "l2"), ("calibrate", "weak", "drop"), ("calibrate", "model", None),
    ("calibrate", "data", np.zeros((3, 3))), ("calibrate", "nonnegative_compliance", "yes"),
    ("compare", "tol", 2.0), ("compare", "model", "model.yaml"), ("compare", "alpha", 1.5), ("compare", "backlash", 1),
    ("error_stats", "norms", [1.0, -1.0]), ("error_stats", "norms", [1.0, INF]), ("register_base", "data", None),
    ("register_base", "model", "m"),
    ("evaluate", "q", Q2), ("evaluate", "p", np.zeros(3)), ("evaluate", "jacobian", "yes"),
    ("evaluate", "columns", [-1]), ("evaluate", "payload_mass", np.ones(4)), ("evaluate", "approach", Q2),
    ("evaluate", "compliance", 1), ("forward_kinematics", "q", "q"), ("forward_kinematics", "frames", None),
    ("jacobian", "columns", [99]), ("jacobian", "columns", ["j9.d"]), ("gravity_loads", "payload_mass", -1.0),
    ("gravity_loads", "q", [[0.0, NAN, 0.0]]),
    ("verdict", "checks", 1), ("verdict", "checks", ["pass"]), ("outlier_check", "noise", None),
    ("outlier_check", "residuals", np.zeros(3)), ("outlier_check", "sigma", np.ones(2)),
    ("outlier_check", "labels", ["a"]),
    ("outlier_bar", "n_points", -1), ("outlier_bar", "n_points", 1.5),
    ("attained", "q", Q2), ("attained", "imp", None), ("attained", "warmth", np.zeros(2)),
    ("attained", "warmth", np.full(5, 1.5)), ("attained", "rng", "x"), ("attained", "robot_seed", -1),
    ("placement_errors", "n", 0), ("placement_errors", "marker", 1), ("placement_errors", "model", None),
    ("arm_chain", "marker", 1), ("arm_chain", "model", None),
    ("posture", "q", Q2), ("posture", "marker", -1), ("posture", "model", "arm"),
    ("inverse_kinematics", "positions", np.zeros((2, 2))), ("inverse_kinematics", "rotations", np.zeros((3, 3, 3))),
    ("inverse_kinematics", "want", np.full((2, 3), 2)), ("inverse_kinematics", "turn_from", Q2),
    ("inverse_kinematics", "hints", np.zeros((2, 5))), ("inverse_kinematics", "tol", 0.0),
    ("inverse_kinematics", "iterations", 0), ("inverse_kinematics", "model", None),
    ("compensate_poses", "calibrated", None), ("compensate_poses", "positions", [[NAN, 0.0, 0.0]] * 2),
    ("compensate_poses", "marker", 2), ("compensate_poses", "want", [[0, 1]]),
    ("read_program", "path", 3), ("read_program", "dialect", "vplus"),
    ("program_joints", "program", "prog.mod"), ("program_joints", "model", None),
    ("read_program_joints", "model", "m"), ("read_program_joints", "dialect", 1),
    ("compensate_program", "program", None), ("compensate_program", "nominal", None),
    ("compensate_program", "marker", 3), ("compensate_program", "tool", 1), ("compensate_program", "tol", -1.0),
    ("compensate_program", "tol_rot", 0.0),
    ("diagnose", "result", None), ("diagnose", "noise", "laser"), ("diagnose", "parameters", 3),
    ("diagnose", "data", Q2),
    ("diagnose_contacts", "contacts", None), ("diagnose_contacts", "result", None),
    ("diagnose_contacts", "result", "result.json"), ("diagnose_contacts", "noise", "laser"),
    ("diagnose_contacts", "data", Q2), ("diagnose_contacts", "model", "arm7"),
    ("verify", "then", None), ("verify", "alpha", 0.7), ("verify", "register", "no"), ("verify", "data", None),
    ("positional_accuracy", "measured", np.zeros((2, 3))), ("positional_accuracy", "pose_index", [0, 1, 2]),
    ("positional_accuracy", "n_commanded", 0), ("positional_accuracy", "predicted", [[NAN, 0.0, 0.0]] * 3),
    ("accuracy_at_calibration", "d", None), ("default_store_path", "environ", 5),
    ("store_location", "option", 5), ("store_location", "environ", "HOME"),
    ("open_store", "location", 3), ("open_store", "create", "yes"), ("model_document", "model", None),
    ("stored_calibration", "result", {}), ("stored_calibration", "robot", ""), ("stored_calibration", "at", 3),
    ("stored_calibration", "robot_type", 5), ("stored_calibration", "source", None),
    ("stored_calibration", "recorded_at", "yesterday"),
    ("sidak_threshold", "alpha", 1.0), ("sidak_threshold", "m", -1),
    ("judge_changes", "calibrations", [1]), ("judge_changes", "alpha", 0.0), ("judge_changes", "families", 3),
    ("judge_overall", "calibrations", [1]), ("judge_overall", "alpha", 0.0), ("judge_overall", "families", 3),
    ("compare_type", "robot_type", None), ("compare_type", "calibrations", None), ("compare_type", "alpha", 2.0),
    ("history", "store", "store.sqlite"), ("history", "robot", 1), ("history", "families", ["joints"]),
    ("type_comparison", "store", None), ("type_comparison", "robot_type", ""), ("type_comparison", "alpha", -1.0),
    ("latest_usable", "store", None), ("latest_usable", "robot", None),
    ("verify_robot", "data", None), ("verify_robot", "alpha", 0.9), ("verify_robot", "save", "no"),
    ("verify_robot", "at", "noon"), ("verify_robot", "register", 1),
    ("change_line", "c", None), ("history_summary", "h", None), ("type_summary", "t", None),
    ("verification_summary", "v", None), ("verification_summary", "robot", 3),
    ("verification_summary", "calibration", None), ("render_history", "h", "SN-1"),
    ("write_history", "h", None), ("write_history", "force", "yes"), ("write_history", "path", 3),
    ("identifiability", "tol", -1.0), ("identifiability", "n_random", 0), ("identifiability", "rng", -1),
    ("identifiability", "data", Q2), ("identifiability", "parameters", None), ("identifiability", "orientation", 1),
    ("status_table", "result", None), ("status_table", "frame_names", 3),
    ("select_poses", "n", 0), ("select_poses", "n", 2.0), ("select_poses", "criterion", "A"),
    ("select_poses", "n_candidates", -5), ("select_poses", "sweeps", -1), ("select_poses", "candidates", Q2),
    ("predict_campaign", "noise", 0.0), ("predict_campaign", "q", Q2), ("predict_campaign", "n_workspace", 0),
    ("compensate", "targets_q", Q2), ("compensate", "marker", 3), ("compensate", "iterations", 0),
    ("compensate", "tol", -1.0), ("compensate", "damping", NAN), ("compensate", "max_step", 0.0),
    ("compensate", "positions", np.zeros((5, 2))),
    ("joint_jacobian", "q", [[NAN, 0.0, 0.0]]), ("joint_jacobian", "model", 1),
    ("simulate", "n_poses", 0), ("simulate", "noise", -1e-5), ("simulate", "length_error", (1e-3, 1e-4)),
    ("simulate", "angle_error", (-1.0, 1.0)), ("simulate", "seed", "abc"), ("simulate", "q", Q2),
    ("simulate", "true_compliance", [1.0]), ("simulate", "payload_mass", -2.0),
    ("measure", "noise", INF), ("measure", "noise_rot", -1.0), ("measure", "q", "q.csv"),
    ("measure", "orientation", None),
    ("perturb_model", "names", ["j9.theta"]), ("perturb_model", "length_error", 1e-3), ("perturb_model", "rng", 1.5),
    ("random_configurations", "n", -1), ("random_configurations", "rng", "seed"),
    ("sampling_box", "model", "rrr"),
    ("serial_model", "rows", [dict(alpha="x")]), ("serial_model", "rows", [dict(wrist=1.0)]),
    ("serial_model", "rows", 3), ("serial_model", "base_position", (0.0, 0.0)),
    ("serial_model", "base_rotation", np.eye(2)), ("serial_model", "beta_tol", 0.0),
    ("serial_model", "gravity", (0.0, 0.0, NAN)), ("serial_model", "markers", [("tool",)]),
    ("serial_model", "name", 7),
    ("default_masses", "total_mass", 0.0), ("default_masses", "total_mass", -3.0),
    ("mdh_transform", "q", NAN), ("mdh_transform", "frame", {"alpha": 0.1}),
    ("parallel_beta_frames", "tol", -0.1), ("parallel_beta_frames", "frames", [1, 2]),
    ("placement_parameters", "X", np.eye(3)),
    ("candidate_parameters", "parameters", 3.0), ("candidate_parameters", "orientation", "no"),
    ("model_from_vector", "p", np.zeros(3)), ("model_from_vector", "p", "p"),
    ("parameter_names", "model", None), ("parameter_layout", "model", None),
    ("parameter_vector", "reference", "nominal"),
    ("families", "orientation", 0), ("matched_by_pattern", "parameters", 1),
    ("from_standard_dh", "rows", 1), ("from_standard_dh", "name", None), ("from_standard_dh", "base", np.eye(3)),
    ("mdh_table", "units", "furlong"), ("to_standard_dh", "max_offset", -1.0),
    ("read_model", "path", 3), ("read_model", "path", ""),
    ("write_model", "units", "m"), ("write_model", "force", "yes"), ("write_model", "calibration", [1]),
    ("model_from_dict", "source", 1), ("model_to_dict", "units", 5), ("model_to_yaml", "model", {}),
    ("calibration_record", "result", {}), ("read_calibration", "path", 3),
    ("compensate", "ranges", [[1.0, 0.0]] * 3), ("compensate", "approach", np.ones((1, 2))),
    ("read_measurements", "model", "model.yaml"), ("read_measurements", "units", "inch-deg"),
    ("read_measurements", "columns", ["a"]), ("read_measurements", "joints", 0), ("read_measurements", "profile", 1),
    ("read_measurements", "targets", None),
    ("write_measurements", "data", None), ("measurements_to_csv", "units", "m"), ("split_sets", "data", []),
    ("read_result", "path", None), ("result_files", "per_pose", "yes"), ("sidecar_path", "path", 3),
    ("read_dh_table", "convention", "craig"), ("write_result", "result", None), ("result_from_dict", "source", None),
    ("result_to_dict", "result", 1), ("result_to_json", "result", "x"), ("limit_to_dict", "limit", 1.0),
    ("read_bag", "path", 3), ("read_bag", "model", "model.yaml"), ("read_bag", "joints", 3),
    ("read_bag", "markers", {"tool": "mocap"}), ("read_bag", "markers", {}), ("read_bag", "joint_names", 3),
    ("read_bag", "rules", {"clock_offset": 0.37}), ("read_bag", "orientation", "yes"),
    ("read_repeatability_csv", "units", "inch"), ("read_urdf", "tip_link", 3), ("urdf_text", "model", None),
    ("write_urdf", "force", 1), ("read_dh_table", "name", 1), ("write_mdh_csv", "units", "deg"),
    ("mdh_csv", "model", None), ("dh_csv", "max_offset", 0.0),
    ("read_contacts", "model", None), ("write_contacts", "contacts", None), ("contacts_to_csv", "units", "x"),
    ("read_profile", "path", 1.5), ("profile_from_dict", "source", 2),
    ("controller_precision", "encoder_resolution", (1e-5, 1e-5)), ("controller_precision", "n_samples", 0),
    ("controller_precision", "length_quantum", -1.0), ("controller_precision", "chunk_size", 0),
    ("controller_precision", "markers", "some"), ("controller_precision", "progress", 5),
    ("predicted_controller_precision", "marker", 1), ("predicted_controller_precision", "angle_quantum", NAN),
    ("predicted_controller_precision", "n_configurations", -1),
    ("iso9283_repeatability", "points", np.zeros((4, 2))), ("iso9283_repeatability", "pose_ids", 5),
    ("rounded_parameters", "length_quantum", -1.0), ("accuracy_limit", "precision", None),
    ("accuracy_limit", "repeatability", -1.0),
    ("measure_campaign", "imp", None), ("measure_campaign", "q_commanded", Q2), ("measure_campaign", "rng", -2),
    ("measure_campaign", "imp", rc.sim.RobotImperfections(backlash=(1e-4,) * 2)),
    ("measure_campaign", "true_model", None), ("measure_campaign", "labels", 3),
    ("measure_campaign", "robot_seed", -1), ("measure_campaign", "payload_mass", [1.0, 2.0]),
    ("accuracy_in_use", "marker", -1), ("accuracy_in_use", "controller_model", "m"),
    ("accuracy_in_use", "imp", rc.sim.RobotImperfections(encoder_resolution=(1e-5,) * 6)),
    ("backlash_sides", "payload_mass", [[1.0]]), ("stored_model", "imp", {}),
    ("approach_sides", "q", [1.0, 2.0]),
    ("plan_sockets", "placements", ()), ("plan_sockets", "poses_per_socket", (0,)), ("plan_sockets", "seed", -1),
    ("plan_sockets", "joint_noise", -1.0),
    ("socket_campaign", "placements", 0), ("socket_campaign", "plate", [1, 2]), ("socket_campaign", "marker", 5),
    ("socket_campaign", "distance_sigma", 0.0), ("plane_campaign", "planes", 0), ("plane_campaign", "extent", -1.0),
    ("bar_campaign", "pairs", 0), ("bar_campaign", "length", INF), ("plate_placements", "n", 0),
    ("plate_placements", "tilt_deg", 100.0), ("plate_placements", "box", np.zeros(3)),
    ("reach", "targets", np.zeros((2, 2))), ("reach", "targets", np.full((1, 3), 9.0)), ("reach", "max_rounds", 0),
    ("calibrate", "contacts", "c.csv"), ("solve", "linear_rows", np.zeros((2, 2))),
    ("contact_errors", "contacts", "c.csv"),
    ("contact_identifiability", "names", ["j1.nope"]), ("contact_identifiability", "tol", 1.0),
    ("analyse", "J", np.zeros(3)), ("analyse", "names", ["a"]), ("analyse", "max_terms", 0),
    ("weakly_identifiable", "sigma", 0.0), ("weakly_identifiable", "quantities", ["length"]),
    ("design_problem", "names", ["x.y"]), ("design_problem", "q", Q2),
    ("solve", "problem", None), ("solve", "p0", np.zeros((2, 2))), ("solve", "loss", "l2"),
    ("solve", "tol", 0.0), ("solve", "f_scale", -1.0), ("covariance", "solution", None),
    ("render_report", "result", None), ("render_report", "extra", [1]), ("write_report", "force", None),
    ("calibration_summary", "weighted", "no"), ("calibration_summary", "shown", 1),
    ("comparison_summary", "comparison", None), ("identifiability_summary", "where", 5),
    ("checks_lines", "checks", [1]), ("verdict_line", "result", None), ("fmt", "unit", "furlong"),
    ("fmt", "value", "1.0"), ("fmt", "sign", 1),
]


def _call(name, tmp_path, argument=None, value=None):
    if name == "read_bag" and importlib.util.find_spec("rosbags") is None:
        pytest.skip("the ros extra is not installed (pip install 'robocal[ros]')")
    fn = public_functions()[name]
    args, kwargs = valid_calls(tmp_path)[name]
    args, kwargs = list(args), dict(kwargs)
    if argument is not None:
        names = list(inspect.signature(fn).parameters)
        if argument in names and names.index(argument) < len(args):
            args[names.index(argument)] = value
        else:
            kwargs[argument] = value
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kwargs)


def test_the_tables_cover_every_public_function(tmp_path):
    functions = set(public_functions())
    assert set(valid_calls(tmp_path)) == functions, functions ^ set(valid_calls(tmp_path))
    assert {name for name, _, _ in BAD} == functions, functions - {name for name, _, _ in BAD}


@pytest.mark.parametrize("name, argument, value", BAD, ids=lambda v: repr(v)[:40])
def test_a_bad_argument_raises_input_error_naming_it(tmp_path, name, argument, value):
    _call(name, tmp_path)                                  # the valid call passes...
    with pytest.raises(InputError) as err:
        _call(name, tmp_path, argument, value)             # ...and the bad value is refused, by name
    assert err.value.where == argument or (err.value.where or "").startswith(argument + "["), str(err.value)


# values of the wrong kind for most arguments: each must pass or raise InputError, nothing else
ODD = (-1, NAN, "bogus", object(), None, [[1.0, 2.0], [3.0]])


@pytest.mark.parametrize("name", sorted(public_functions()))
def test_no_internal_error_escapes_a_public_function(tmp_path, monkeypatch, name):
    monkeypatch.chdir(tmp_path)              # a writer given a plain name as path writes here
    escaped = []
    for argument, p in inspect.signature(public_functions()[name]).parameters.items():
        if p.kind in (p.VAR_KEYWORD, p.VAR_POSITIONAL):
            continue
        for value in ODD:
            try:
                _call(name, tmp_path, argument, value)
            except InputError:
                pass
            except Exception as e:  # noqa: BLE001 - what escapes is what this test counts
                escaped.append(f"{argument}={value!r:.30}: {type(e).__name__}: {e}"[:200])
    assert not escaped, "\n".join(escaped)


@pytest.mark.parametrize("name", sorted(public_functions()))
def test_every_public_function_has_numpy_parameters_and_returns_sections(name):
    fn = public_functions()[name]
    doc = inspect.getdoc(fn) or ""
    assert "\nParameters\n----------\n" in doc and "\nReturns\n-------\n" in doc, name
    listed = [line.split(" : ")[0] for line in doc.splitlines() if " : " in line and not line.startswith(" ")]
    listed += [line for line in doc.splitlines() if line.startswith("**")]
    wanted = [("**" if p.kind is p.VAR_KEYWORD else "") + p.name
              for p in inspect.signature(fn).parameters.values()]
    assert listed == wanted, (name, listed, wanted)


def _calls(fn, *codes) -> list[int]:
    """How many times each code object runs during ``fn()``."""
    counts = [0] * len(codes)

    def profile(frame, event, arg):
        if event == "call" and frame.f_code in codes:
            counts[codes.index(frame.f_code)] += 1

    sys.setprofile(profile)
    try:
        fn()
    finally:
        sys.setprofile(None)
    return counts


def test_a_calibration_runs_the_argument_checks_of_calibrate_only():
    """The checks run once, at the public face: robocal's own calls between its functions (the
    solve, the covariance, the analysis, the statistics...) check nothing again."""
    from robocal._identification.calibrate import check_inputs

    w = world()
    checking = rc.parameter_vector.__code__         # what every checked public function runs first
    assert _calls(lambda: rc.parameter_vector(w["model"]), checking) == [1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert _calls(lambda: rc.calibrate(w["model"], w["data"]), checking, check_inputs.__code__) == [0, 1]
        assert _calls(lambda: rc.compare(w["model"], w["data"], tol=1e-8), checking, check_inputs.__code__) == [1, 1]
