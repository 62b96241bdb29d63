"""Planning a socket-plate campaign before the robot is booked: how many placements of the plate and
how many seatings per socket, from the standard deviations each design predicts.

The largest design is simulated on the nominal robot (``socket_campaign``: random seatings within
the joint limits, the plate at random placements) and each smaller one is its first placements and
first seatings per socket (so more placements or seatings never predict worse). Each design's
contact problem is linearised there, and the covariance the fit would report with the stated
deviations is ``(J^T J)^-1`` (every row is already divided by its deviation). What the plate
reaches is what the largest design identifies; a smaller design that cannot identify some of it
loses them. The recommended design is the smallest of the grid (fewest seatings) that loses none
and whose predicted standard deviations all stay within the practical-identifiability bounds
(``WEAK_STD``, docs/checks.md). Parameters beyond their
bound even in the largest design are held at nominal, as the calibration holds them, and the
designs judged on the others.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._base.arguments import (
    MAPPING,
    NAMES,
    NON_NEGATIVE,
    SEED,
    accepts,
    is_a,
    optional,
    wholes,
)
from .._base.errors import InputError
from .._base.options import MAX_DESIGN_WORK, MAX_GRID_ROWS, MAX_PLACEMENTS, MAX_SEATINGS
from .._base.threads import one_blas_thread
from .._identification.identifiability import (
    DEFAULT_TOL,
    WEAK_STD,
    StackAnalysis,
    analyse_stack,
    kinds_reach,
    robot_part,
    weakly_identifiable,
)
from .._identification.problem import Problem
from .._model.contacts import Contacts
from .._model.parameters import candidate_parameters, parameter_layout
from .._model.robot import RobotModel
from .contacts import PLATE, socket_campaign

# the cost of a placement's solves, of a seating simulated, of a row linearised, and of a unit of
# the largest design's analysis (rows x columns^2), CPU seconds on one core (benchmarks/README.md)
SECONDS = {"placements": 0.1, "seatings": 1.5e-3, "rows": 1e-4, "analysis": 7e-9}


@dataclass(frozen=True)
class SocketDesign:
    """One design of the grid: ``placements`` of the plate, ``poses_per_socket`` seatings of each
    socket, the robot parameters it identifies with their predicted standard deviations (SI), the
    directions the plate cannot reach, the parameter furthest beyond (or closest to) its bound, and
    ``lost``: those the plate reaches (in the grid's largest design) that this design cannot
    identify; a design that loses any is beyond its bounds (``worst`` is the first, ``worst_ratio``
    infinite)."""

    placements: int
    poses_per_socket: int
    n_seatings: int
    predicted_std: dict
    units: dict                 # each parameter's SI unit
    unreachable: tuple[str, ...]
    worst: str
    worst_ratio: float          # predicted std over its bound for ``worst``
    lost: tuple[str, ...] = ()

    @property
    def meets_bounds(self) -> bool:
        return self.worst_ratio <= 1.0


@dataclass(frozen=True)
class SocketPlan:
    """Every design of the grid, the recommended one (None when none meets the bounds) and its
    simulated seatings, ready to be written as a contact file and measured. ``held``: parameters
    beyond their bound in every design, which the calibration holds at nominal (``weak="eliminate"``);
    the designs are then predicted, and the recommended one chosen, with them held."""

    designs: tuple[SocketDesign, ...]
    chosen: SocketDesign | None
    campaign: Contacts | None
    held: tuple[str, ...] = ()


def _analysis(model: RobotModel, campaign: Contacts, names) -> tuple[Problem, StackAnalysis]:
    """The structural analysis of a design over the candidates ``names`` at nominal, as the
    calibration's: the sockets' columns first, what they absorb leaving the robot."""
    prob = Problem(model, names, contacts=campaign, compliance=False)
    return prob, analyse_stack(prob, tuple(names), prob.start_vector(), tol=DEFAULT_TOL)


def _columns(stack: StackAnalysis, chosen) -> np.ndarray:
    """The reduced Jacobian's sockets' columns, then those of the robot parameters ``chosen``."""
    nn = stack.R.shape[1] - len(stack.names)
    return stack.R[:, np.r_[np.arange(nn), nn + np.array([stack.names.index(n) for n in chosen], dtype=int)]]


def _design(model: RobotModel, stack: StackAnalysis, n_seatings: int, placements: int, poses: int, target,
            unreachable, bounds: dict) -> SocketDesign:
    """A design judged on the parameters ``target``: those it cannot identify are ``lost`` (beyond
    any bound), the others predicted with ``(J^T J)^-1`` over them and the sockets."""
    lost = tuple(n for n in target if n not in stack.result.identified)
    kept = tuple(n for n in target if n not in lost)
    R = _columns(stack, kept)
    std = np.sqrt(np.diag(np.linalg.pinv(R.T @ R)))[R.shape[1] - len(kept):]
    lay = parameter_layout(model)
    ratios = {n: s / bounds[lay[n].quantity] for n, s in zip(kept, std)}
    worst = lost[0] if lost else max(ratios, key=lambda n: ratios[n])
    return SocketDesign(placements, poses, n_seatings, dict(zip(kept, map(float, std))),
                        {n: lay[n].unit for n in kept}, unreachable, worst,
                        math.inf if lost else float(ratios[worst]), lost)


def _held(model: RobotModel, stack: StackAnalysis, identified, bounds: dict) -> tuple[str, ...]:
    """What the calibration's rule (``weakly_identifiable``, the later member of a weak group going)
    holds at nominal on the design of ``stack`` (the grid's largest: held on every one), the sockets'
    columns taken out of the robot's first."""
    R = _columns(stack, identified)
    robot = robot_part(R, R.shape[1] - len(identified))     # as the calibration's analysis does
    lay = parameter_layout(model)
    found = weakly_identifiable(robot, identified, [lay[n].quantity for n in identified], 1.0, bounds=bounds)
    return tuple(n for n, _, _, _ in found)


def _check_cost(placements, per, n_sockets: int, n_params: int) -> None:
    """Refuse, before any work, a grid whose simulation or linearisation would run for minutes. The
    analysis of the largest design solves for 3 unknowns per socket and placement with the robot's
    parameters: its cost grows with rows x columns^2, and so with the cube of the placements."""
    largest, grid = n_sockets * placements[-1] * per[-1], n_sockets * sum(placements) * sum(per)
    rows = 3 * largest + n_sockets * (n_sockets - 1) // 2 * placements[-1]
    columns = n_params + 3 * n_sockets * placements[-1]
    for what, unit, n, top in (
            ("seatings to simulate for the largest design", "seatings", largest, MAX_SEATINGS),
            (f"rows to linearise over the {len(placements) * len(per)} designs", "rows", grid, MAX_GRID_ROWS),
            ("placements to simulate, each reached by its own solves", "placements", placements[-1], MAX_PLACEMENTS),
            (f"rows x columns^2 to analyse in the largest design ({rows:,} x {columns:,}^2)", "analysis",
             rows * columns ** 2, MAX_DESIGN_WORK)):
        if n > top:
            raise InputError(f"{n:,.0f} {what}; robocal plans up to {top:,.0f} (about {top * SECONDS[unit]:.0f} s): "
                             "compare fewer or smaller designs", where="placements")


@accepts(model=is_a(RobotModel), placements=wholes(1, 1000), poses_per_socket=wholes(1, 10_000),
         joint_noise=NON_NEGATIVE, seat_noise=NON_NEGATIVE, parameters=NAMES, bounds=optional(MAPPING), seed=SEED)
@one_blas_thread
def plan_sockets(model: RobotModel, *, placements=(3, 5, 7, 9), poses_per_socket=(20, 25, 30, 35),
                 joint_noise: float = 2e-5, seat_noise: float = 5e-6, parameters=("geometric",),
                 bounds: dict | None = None, seed: int = 0) -> SocketPlan:
    """The predicted standard deviations of every design of the grid ``placements`` x
    ``poses_per_socket`` (the default 3-socket plate with known spacing), and the recommended one.

    ``joint_noise`` (rad or m per reading) and ``seat_noise`` (m) are the deviations the fit will
    state; ``bounds`` the standard deviation each quantity must stay within (``{"length": m,
    "angle": rad}``, default ``WEAK_STD``); ``seed`` draws the simulated seatings and placements. What
    the plate identifies and cannot reach is found on the largest design; a smaller design that
    cannot identify some of it loses them (``SocketDesign.lost``) and is never recommended.

    Parameters
    ----------
    {model}
    placements : sequence of int
        Numbers of plate placements to consider.
    poses_per_socket : sequence of int
        Numbers of seatings per socket to consider.
    {joint_noise, seat_noise, parameters, bounds}
    seed : None, int or numpy.random.Generator
        Seed of the simulated seatings.

    Returns
    -------
    SocketPlan
        Each design's predicted standard deviations and the recommended one.

    >>> import robocal as rc
    >>> plan = plan_sockets(rc.read_model("examples/arm7/model.yaml"), placements=(3,), poses_per_socket=(20,))
    >>> plan.designs[0].n_seatings, plan.designs[0].unreachable
    (180, ('base',))
    """
    if not placements or not poses_per_socket or min(placements) < 1 or min(poses_per_socket) < 1:
        raise InputError("placements and poses per socket must be positive counts", where="placements")
    names = candidate_parameters(model, parameters)
    bounds = {**WEAK_STD, **(bounds or {})}
    placements, per = sorted(set(placements)), sorted(set(poses_per_socket))
    _check_cost(placements, per, len(PLATE), len(names))
    # one campaign of the largest design; each smaller one takes its first placements and first
    # seatings of each socket, so a larger design holds every row of a smaller one (never predicts worse)
    full = socket_campaign(model, placements=placements[-1], poses_per_socket=per[-1], joint_noise=joint_noise,
                           seat_noise=seat_noise, rng=np.random.default_rng(seed))
    row = np.arange(full.n_rows)
    seating, placement = row % per[-1], row // (full.n_rows // placements[-1])     # rows: placement, socket, seating
    campaigns = {(n_pl, n_po): full.subset((placement < n_pl) & (seating < n_po))
                 for n_pl in placements for n_po in per}
    stacks = {key: _analysis(model, c, names) for key, c in campaigns.items()}
    # what the plate reaches is what the largest design identifies (it holds every smaller one's
    # rows): every design is judged on all of it, and one that cannot identify some loses them
    largest = placements[-1], per[-1]
    prob, stack = stacks[largest]
    ident = kinds_reach(prob, stack, prob.start_vector())
    unreachable = tuple(u.name for u in ident.unreachable)

    def grid(target):
        return [_design(model, s, campaigns[key].q.shape[0], *key, target, unreachable, bounds)
                for key, (_, s) in stacks.items()]

    designs = grid(ident.identified)
    held: tuple[str, ...] = ()
    if not any(d.meets_bounds for d in designs):
        # what no design pins down, the calibration holds at nominal: the rest are judged without it
        held = _held(model, stack, ident.identified, bounds)
        if 0 < len(held) < len(ident.identified):
            designs = grid(tuple(n for n in ident.identified if n not in held))
        else:
            held = ()
    good = [d for d in designs if d.meets_bounds]
    chosen = min(good, key=lambda d: (d.n_seatings, d.placements)) if good else None
    return SocketPlan(tuple(designs), chosen,
                      None if chosen is None else campaigns[(chosen.placements, chosen.poses_per_socket)], held)
