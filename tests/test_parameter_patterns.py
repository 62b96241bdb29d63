"""Parameter selection by pattern: '*.theta', 'j2.*', '*.k_theta', in the API and on the command line."""

import pytest
from robots import arm6r, torso

import robocal as rc
from robocal.kinematics import matched_by_pattern


def test_patterns_expand_to_the_candidates_they_match():
    model = torso()
    offsets = rc.candidate_parameters(model, ["*.theta"])
    assert sorted(offsets) == sorted(f"{f.name}.theta" for f in model.frames)
    assert rc.candidate_parameters(model, ["r1.*"]) == ("r1.gamma", "r1.b", "r1.beta", "r1.alpha", "r1.d",
                                                         "r1.theta", "r1.r")
    # no masses: compliances are not matched by a pattern
    assert not any(".k_" in n for n in rc.candidate_parameters(model, ["*"]))
    heavy = arm6r(masses=True)
    assert rc.candidate_parameters(heavy, ["*.k_theta"]) == tuple(f"j{i}.k_theta" for i in range(1, 7))
    # patterns and families together, known as a pattern too, preference order kept
    both = rc.candidate_parameters(heavy, ["base", "j2.*"], known=["*.k_*", "base.r?"])
    assert both == ("base.x", "base.y", "base.z", "j2.alpha", "j2.d", "j2.theta", "j2.r")  # j2 has no beta
    assert matched_by_pattern(heavy, ["geometric", "j1.[ad]*"]) == (("j1.[ad]*", ("j1.alpha", "j1.d")),)
    with pytest.raises(rc.InputError, match="pattern 'j9.*' matches no parameter"):
        rc.candidate_parameters(heavy, ["j9.*"])


def test_pattern_on_the_command_line_lists_the_names_matched(tmp_path, cli):
    model = arm6r()
    rc.write_model(model, tmp_path / "m.yaml")
    true, data = rc.simulate(model, 30, seed=2)
    rc.write_measurements(data, tmp_path / "d.csv", model=model)
    code, out, err = cli("calibrate", tmp_path / "m.yaml", tmp_path / "d.csv", "--out", tmp_path / "o",
                         "--parameters", "base,tool.*,*.theta")
    assert code in (0, 3), err
    line = next(ln for ln in out.splitlines() if "'*.theta' matched" in ln)
    assert all(f"j{i}.theta" in line for i in range(1, 7))
    assert "'tool.*' matched: tool.x, tool.y, tool.z" in out


def test_identifiability_command_lists_the_names_matched(tmp_path, cli):
    rc.write_model(arm6r(), tmp_path / "m.yaml")
    code, out, err = cli("identifiability", tmp_path / "m.yaml", "--parameters", "j2.*", "--poses", "30")
    assert code == 0, err
    assert "note: parameters 'j2.*' matched: j2.alpha, j2.d, j2.theta, j2.r" in out
