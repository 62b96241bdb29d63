"""The diagnosis of calibrations from contacts (docs/diagnosis.md, "Calibrations from contacts"):
each mistake injected into simulated socket campaigns of a 6-axis arm is named first, seed after
seed; clean campaigns, and robots with effects a geometric model does not hold (joint compliance,
gear errors), get no cause; tracker points fitted beside the contacts stay in every refit; large
campaigns are thinned group by group. The counts over more seeds: benchmarks/diagnosis_corpus.py
--contacts."""

from __future__ import annotations

import functools
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from robots import arm6r
from scipy.spatial.transform import Rotation

import robocal as rc
from robocal._diagnosis import contacts as cd
from robocal._diagnosis import reference as dg
from robocal.errors import InputError
from robocal.identification import diagnose_contacts
from robocal.sim import bar_campaign, plane_campaign, socket_campaign

SEEDS = range(5)
POSES_PER_SOCKET = 12
ENCODER = 2e-5          # rad: encoder-level joint noise (the seating scatter is the campaign's own)
MAX_NFEV = 20           # the calibrations' budget per solve: a mistaken campaign converges nowhere anyway
NAMED = np.log10(dg.NAMED_FACTOR)
ARM7 = Path(__file__).resolve().parents[1] / "examples" / "arm7" / "model.yaml"


def arm(masses: bool = False) -> rc.RobotModel:
    """The 6R arm of tests/robots.py with its base at the origin of W, so that the plates of
    ``socket_campaign`` (in a box about 0.5 m in front of the origin) are within its reach."""
    return arm6r(masses=masses).replace(base_position=(0.0, 0.0, 0.0))


@functools.cache
def truth(seed: int, effect: str = "") -> rc.RobotModel:
    """The true arm: the nominal's identifiable geometry perturbed; with ``effect="compliance"`` its
    shoulder and elbow also bend under gravity (1e-5 rad/(N m)), which a geometric model lacks."""
    m = arm(masses=bool(effect))
    true = rc.perturb_model(m, rc.identifiability(m, parameters=("frames", "markers")).identified, rng=seed)
    if effect == "compliance":
        true = true.replace(frames=tuple(replace(f, k_theta=1e-5 if i in (1, 2) else 0.0)
                                         for i, f in enumerate(true.frames)))
    return true


@functools.cache
def campaign(seed: int, effect: str = "") -> rc.Contacts:
    """Three placements of the 3-socket plate, ``POSES_PER_SOCKET`` seatings a socket, spacings stated;
    with ``effect="gears"`` each joint turns by a periodic error of its own angle (0.02 deg, two
    harmonics) that the readings do not show."""
    c = socket_campaign(truth(seed, effect), placements=3, poses_per_socket=POSES_PER_SOCKET, joint_noise=ENCODER,
                        rng=seed)
    if effect == "gears":
        a, b = np.random.default_rng(seed + 1000).uniform(0.0, 2 * np.pi, (2, 6))

        def error(q):
            return np.deg2rad(0.02) * (np.sin(q + a) + 0.5 * np.sin(2 * q + b))

        q = c.q - error(c.q)
        c = replace(c, q=c.q - error(q))        # readings that turn the joints to where they went
    return c


def diagnosed(contacts, model=None, data=None):
    """(calibration, its diagnosis) of ``contacts`` on the nominal arm. The diagnosis uses only the
    calibration's identified parameters and calibrated model, and refits with the linear loss from
    it: so that a mistaken campaign's calibration costs little, rows standing out are flagged (not
    refitted), a solve has ``MAX_NFEV`` evaluations, and the first placement stands for the
    validation set (no placement predicted by the others: their refits ignore the budget)."""
    model = model or arm()
    first = contacts.subset(np.array(contacts.placement) == contacts.placement[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rc.calibrate(model, contacts=contacts, data=data, validation=first, on_outliers="flag",
                                    max_nfev=MAX_NFEV)
    return result, result.diagnosis


# -- the mistakes: (contacts, rng) -> (changed contacts, the hypothesis to come first, words of its cause)

def _joint(rng) -> int:
    return int(rng.integers(6))


def _readings(seed: int, joints: list, change) -> rc.Contacts:
    """The campaign of ``seed`` with the columns ``joints`` of its readings changed by ``change``."""
    c = campaign(seed)
    q = c.q.copy()
    q[:, joints] = change(q[:, joints])
    return replace(c, q=q)


def sign_flipped(seed, rng):
    j = _joint(rng)
    return _readings(seed, [j], np.negative), "joint sign", (f"j{j + 1}'s", "wrong sign")


def degrees_as_radians(seed, rng):
    j = _joint(rng)
    return _readings(seed, [j], np.degrees), "unit factor", (f"j{j + 1}", "degrees read as radians")


def radians_as_degrees(seed, rng):
    j = _joint(rng)
    return _readings(seed, [j], np.radians), "unit factor", (f"j{j + 1}", "radians read as degrees")


def adjacent_swapped(seed, rng):
    j = int(rng.integers(5))
    return _readings(seed, [j, j + 1], lambda q: q[:, ::-1]), "joints swapped", (f"j{j + 1} and j{j + 2}",)


def wrong_socket(seed, rng):
    c = campaign(seed)
    i = int(rng.integers(c.n_rows))
    target = list(c.target)
    target[i] = {"A": "B", "B": "C", "C": "A"}[target[i]]
    return replace(c, target=tuple(target)), "wrong socket", (c.labels[i], f"seated in {c.target[i]}")


def placement_merged(seed, rng):
    """The third placement's seatings labelled as the second's (a folder named wrongly): the second
    placement's seatings lie on two set-ups."""
    c = campaign(seed)
    first = c.labels[c.placement.index("P3")]
    return replace(c, placement=tuple("P2" if p == "P3" else p for p in c.placement)), "setup moved", \
        (f"from {first} on", "placement P2")


def plate_moved(seed, rng):
    """The plate pushed by 3 mm and turned by half a degree during the second placement, from a
    seating of its second socket on: those seatings' readings are of the moved plate's sockets."""
    c, true = campaign(seed), truth(seed)
    rows = np.array([i for i, p in enumerate(c.placement) if p == "P2"])
    start = int(rows[POSES_PER_SOCKET + int(rng.integers(2, POSES_PER_SOCKET - 2))])
    moved = np.arange(start, rows[-1] + 1)
    P = rc.forward_kinematics(true, c.q[moved]).positions[:, 0]
    axis = rng.normal(size=3)
    turn = Rotation.from_rotvec(axis / np.linalg.norm(axis) * np.radians(0.5)).as_matrix()
    shift = rng.normal(size=3)
    goal = P.mean(axis=0) + (P - P.mean(axis=0)) @ turn.T + 3e-3 * shift / np.linalg.norm(shift)
    q = c.q.copy()
    q[moved] = rc.sim.reach(true, goal, rng=rng) + rng.normal(0.0, ENCODER, (len(moved), 6))
    return replace(c, q=q), "setup moved", (f"from {c.labels[start]} on", "placement P2")


def spacing_typo(seed, rng):
    c = campaign(seed)
    k = int(rng.integers(len(c.distances)))
    d = c.distances[k]
    distances = c.distances[:k] + (replace(d, length=d.length + 0.01),) + c.distances[k + 1:]
    return replace(c, distances=distances), "spacing stated", (f"sockets {d.a} and {d.b}",)


def joint_rehomed(seed, rng):
    """One joint (not the first, whose offset the plate's pose takes up) rehomed a few tenths of a
    degree off before the second placement: its readings there are off by a constant."""
    c = campaign(seed)
    j = 1 + int(rng.integers(5))
    q = c.q.copy()
    q[np.array([p == "P2" for p in c.placement]), j] += np.radians(rng.uniform(0.2, 0.6))
    return replace(c, q=q), "joint rehomed", (f"j{j + 1}'s", "placement P2")


MISTAKES = (sign_flipped, degrees_as_radians, radians_as_degrees, adjacent_swapped, wrong_socket, placement_merged,
            plate_moved, spacing_typo, joint_rehomed)


def injected(mistake, seed: int):
    """The mistake injected into the clean campaign of ``seed`` (its own generator per mistake)."""
    rng = np.random.default_rng([seed, MISTAKES.index(mistake)])
    return mistake(seed, rng)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("mistake", MISTAKES, ids=lambda f: f.__name__)
def test_each_mistake_is_named_first(mistake, seed):
    contacts, expected, words = injected(mistake, seed)
    result, diagnosis = diagnosed(contacts)
    cause = diagnosis.cause
    assert cause is not None and cause.hypothesis == expected, (diagnosis.summary,
                                                                [(f.hypothesis, f.score) for f in diagnosis.findings])
    assert cause.score >= NAMED and all(w in cause.cause for w in words), (cause.cause, words)
    assert cause.rms_after is not None and cause.rms_before is not None and cause.fix
    assert "stated deviations RMS" in cause.evidence
    assert diagnosis.summary.startswith(("decisive: ", "possible cause: "))


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("effect", ["", "compliance", "gears"])
def test_no_cause_is_named_without_a_mistake(effect, seed):
    """Clean campaigns, and robots beyond a geometric model (their residuals systematic, the checks
    perhaps failing): nothing tested explains them, and the diagnosis says so."""
    _, diagnosis = diagnosed(campaign(seed, effect), model=arm(masses=bool(effect)))
    assert diagnosis.findings == (), diagnosis.summary
    assert diagnosis.summary.startswith("nothing tested explains the misfit")
    assert len(diagnosis.tested) == len(cd.CONTACT_HYPOTHESES)


def _tracker(seed: int, n: int = 30):
    """Tracker points of the true arm at random readings, beside the contacts."""
    true = truth(seed)
    q = rc.random_configurations(true, n, np.random.default_rng(seed + 7))
    return rc.sim.measure(true, q, noise=1e-5, rng=seed + 8)


@pytest.mark.parametrize("seed", SEEDS[:2])
def test_tracker_points_beside_the_contacts_stay_in_every_refit(seed):
    """With tracker points the base is identified: a mistake of the contacts is still named first,
    each refit starts from the nominal base registered on the points, and a clean campaign gets no
    cause."""
    data = _tracker(seed)
    contacts, expected, _ = injected(sign_flipped, seed)
    result, diagnosis = diagnosed(contacts, data=data)
    assert any(p.name.startswith("base.") for p in result.parameters)
    assert diagnosis.cause is not None and diagnosis.cause.hypothesis == expected, diagnosis.summary
    assert diagnosed(campaign(seed), data=data)[1].findings == ()
    away = arm().replace(base_position=(0.05, -0.03, 0.02))       # a nominal base 6 cm from the true one
    assert diagnosed(campaign(seed), model=away, data=data)[1].findings == ()
    assert diagnosed(contacts, model=away, data=data)[1].cause.hypothesis == expected


def test_a_finding_names_what_to_check():
    """The wrong socket names the seating, the set-up the placement and its first moved seating, the
    spacing the sockets and the spacing stated; the evidence gives the refit's residuals in stated
    deviations against the reference's."""
    contacts, _, _ = injected(wrong_socket, 0)
    moved = next(i for i in range(contacts.n_rows) if contacts.target[i] != campaign(0).target[i])
    cause = diagnosed(contacts)[1].cause
    assert cause.items == (contacts.labels[moved],) and cause.rms_after < cause.rms_before / 10
    contacts, _, _ = injected(placement_merged, 0)
    cause = diagnosed(contacts)[1].cause
    assert cause.items == ("P2", contacts.labels[campaign(0).placement.index("P3")])
    contacts, _, _ = injected(spacing_typo, 0)
    cause = diagnosed(contacts)[1].cause
    wrong = next(d for d, o in zip(contacts.distances, campaign(0).distances) if d.length != o.length)
    assert cause.items == (f"{wrong.a}-{wrong.b}",) and f"{wrong.length * 1e3:.3g} mm stated" in cause.fix


def test_a_split_is_found_where_the_calibration_is_dragged_far_from_the_robot():
    """Seed 5's merged placements drag the calibration to 51 mm RMS with 15 implausible changes: at
    its marker positions the best split is 6 seatings late; at the nominal robot's it is the first
    seating of the third placement, as it should be."""
    contacts, _, _ = injected(placement_merged, 5)
    cause = diagnosed(contacts)[1].cause
    assert cause is not None and cause.items == ("P2", contacts.labels[campaign(5).placement.index("P3")])


def test_one_wrong_spacing_alone_scales_the_robot_and_is_named_by_its_implausible_changes():
    """With a single stated spacing, a wrong one fits as well as the right one (the robot and the
    points scale alike): the calibration's changes are implausible, the refit at the spacing the
    nominal robot measures makes them plausible."""
    c = campaign(1)
    one = replace(c, distances=c.distances[:1])
    assert diagnosed(one)[1].findings == ()
    wrong = replace(one, distances=(replace(one.distances[0], length=one.distances[0].length * 1.05),))
    diagnosis = diagnosed(wrong)[1]
    assert diagnosis.cause is not None and diagnosis.cause.hypothesis == "spacing stated", diagnosis.summary
    assert "implausible change(s) become plausible" in diagnosis.cause.evidence


@pytest.mark.parametrize("seed", range(3))
def test_unknown_planes_that_any_refit_fits_exactly_name_nothing(seed):
    """Contacts on unknown planes fix shape only: a refit can collapse them (the points of each plane
    on a line fit any plane exactly). On a clean campaign every hypothesis' refit from the nominal
    model did so (a score of 21 before such refits were set aside); fitting far below the stated
    deviations is no evidence of a cause."""
    c = plane_campaign(truth(seed), planes=4, poses_per_plane=25, joint_noise=ENCODER, rng=seed)
    assert diagnosed(c)[1].findings == ()


def test_a_ball_bar_campaign_names_a_joint_sign_and_nothing_on_clean_pairs():
    c = bar_campaign(truth(0), pairs=50, joint_noise=ENCODER, rng=0)
    assert diagnosed(c)[1].findings == ()
    q = c.q.copy()
    q[:, 2] *= -1.0
    cause = diagnosed(replace(c, q=q))[1].cause
    assert cause is not None and (cause.hypothesis, cause.items) == ("joint sign", ("j3",))


def test_large_campaigns_are_thinned_group_by_group_and_bars_by_whole_pairs():
    c = campaign(0)
    thin = cd._thinned(c, most=40)
    assert 36 <= thin.n_rows <= 45
    assert [(g.placement, g.target) for g in thin.groups()] == [(g.placement, g.target) for g in c.groups()]
    assert all(len(g.rows) >= cd.MIN_GROUP for g in thin.groups())
    assert set(thin.labels) <= set(c.labels) and list(thin.labels) == sorted(thin.labels, key=c.labels.index)
    assert cd._thinned(c) is c
    bars = bar_campaign(truth(0), pairs=30, rng=0)
    thin = cd._thinned(bars, most=20)
    assert thin.n_rows == 20 and all(len(g.rows) == 2 for g in thin.groups())


def test_contacts_of_another_robot_and_results_without_a_calibration_are_refused():
    c = campaign(0)
    result = diagnosed(c)[0]
    with pytest.raises(InputError) as err:
        diagnose_contacts(arm(), replace(c, q=c.q[:, :5]), result)
    assert err.value.where == "contacts" and "5 joint columns" in str(err.value)
    with pytest.raises(InputError) as err:
        diagnose_contacts(arm(), c, replace(result, parameters=()))
    assert err.value.where == "result" and "no parameter" in str(err.value)
    with pytest.raises(InputError) as err:
        diagnose_contacts(rc.read_model(ARM7), c, result)
    assert err.value.where == "contacts"


def test_the_docs_list_every_hypothesis():
    text = (ARM7.parents[2] / "docs" / "diagnosis.md").read_text()
    section = text.split("## Calibrations from contacts")[1].split("\n## ")[0]
    assert [h.__name__.replace("_", " ") for h in cd.CONTACT_HYPOTHESES] == \
        [line.split("|")[1].strip() for line in section.splitlines() if line.startswith("| ") and "---" not in line][1:]
