"""Parameters: every identifiable quantity of a model, named, typed and placed once.

The full parameter vector of a model is, in order: the base pose (``base.x`` ... ``base.rz``),
each frame's kinds (``<frame>.gamma`` ... ``<frame>.k_beta``), each marker's kinds
(``<marker>.x`` ... ``<marker>.rz``). ``parameter_layout`` gives a record per entry (name, owner,
kind, quantity, SI unit, family, index); every other module asks it rather than reading names.

Rotation kinds of the base and the markers (rx, ry, rz) are the rotation vector of a correction
about the stored rotation: zero in any stored model, free of gimbal lock however far they turn
(docs/conventions.md).

The preference order of ``candidate_parameters`` decides which of a dependent group is kept
(earlier wins). It follows the paper and the habit of tracker users: the base first (so it absorbs
what frame 1 cannot show), then the markers, then frames from the base outwards (beta, alpha, d,
theta, r within a frame, so r of the second of two parallel axes is the one eliminated), then
compliances, then backlash (so a joint offset absorbs a backlash whose side never changes), then
transmission errors (so the offset carries a constant, and the geometry what a harmonic cannot be told
from).
"""

from __future__ import annotations

import fnmatch
import types
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .._base.arguments import (
    FLAG,
    NAMES,
    accepts,
    is_a,
    optional,
    vector_of,
)
from .._base.arrays import read_only
from .._base.errors import InputError, excerpt
from .._base.spatial import matrix_tuple, rotation_vector, small_rotation, vector3
from .robot import TRANSMISSION_KINDS, RobotModel

BASE_KINDS = ("x", "y", "z", "rx", "ry", "rz")
GEOMETRIC_KINDS = ("gamma", "b", "beta", "alpha", "d", "theta", "r")
COMPLIANCE_KINDS = ("k_theta", "k_alpha", "k_beta")
# half the lost motion of a revolute (theta) or prismatic (r) joint: the one matching the joint is used
BACKLASH_KINDS = ("backlash_theta", "backlash_r")
FRAME_KINDS = GEOMETRIC_KINDS + COMPLIANCE_KINDS + BACKLASH_KINDS + TRANSMISSION_KINDS
MARKER_KINDS = ("x", "y", "z", "rx", "ry", "rz")

# the one table of kinds: the quantity each one measures, and the SI unit of each quantity
KIND_QUANTITY = types.MappingProxyType({
    "x": "length", "y": "length", "z": "length", "rx": "angle", "ry": "angle", "rz": "angle",
    "gamma": "angle", "b": "length", "beta": "angle", "alpha": "angle", "d": "length", "theta": "angle",
    "r": "length", "k_theta": "compliance", "k_alpha": "compliance", "k_beta": "compliance",
    "backlash_theta": "angle", "backlash_r": "length",
    **{k: "ratio" if k == "gear_scale" else "angle" for k in TRANSMISSION_KINDS},
})
SI_UNITS = types.MappingProxyType({"length": "m", "angle": "rad", "compliance": "rad/(N m)", "ratio": "1"})

# families a user names; "geometric" is base + markers + frames
FAMILIES = ("geometric", "compliance", "backlash", "transmission", "base", "markers", "frames")
# a parameter item holding one of these is a pattern (fnmatch): "*.theta", "j2.*", "*.k_theta"
PATTERN_CHARS = "*?["


@dataclass(frozen=True)
class Parameter:
    """One entry of the full parameter vector.

    ``owner`` is ``"base"``, a frame name or a marker name; ``role`` says which of the three;
    ``index`` is the position in ``parameter_vector``.
    """

    name: str
    owner: str
    role: str
    kind: str
    index: int

    @property
    def quantity(self) -> str:
        """"length", "angle", "compliance" or "ratio"."""
        return KIND_QUANTITY[self.kind]

    @property
    def unit(self) -> str:
        """The SI unit: m, rad, rad/(N m) or 1."""
        return SI_UNITS[self.quantity]

    @property
    def family(self) -> str:
        """"base", "markers", "frames" (geometric kinds of a frame), "compliance", "backlash" or
        "transmission"."""
        if self.role == "frame":
            if self.kind in BACKLASH_KINDS:
                return "backlash"
            if self.kind in TRANSMISSION_KINDS:
                return "transmission"
            return "compliance" if self.kind in COMPLIANCE_KINDS else "frames"
        return "base" if self.role == "base" else "markers"


@dataclass(frozen=True, eq=False)
class ParameterLayout:
    """The parameters of one model, in vector order, with lookups by name.

    ``frame0`` (n_frames,) and ``marker0`` (n_markers,) give the index of each frame's and each
    marker's first parameter (read-only).
    """

    parameters: tuple[Parameter, ...]
    frame0: np.ndarray
    marker0: np.ndarray
    by_name: types.MappingProxyType
    # made once: asked for at every step of a fit (480 names on a 19-joint tree with two markers)
    names: tuple[str, ...]

    @property
    def n_params(self) -> int:
        return len(self.parameters)

    def __getitem__(self, name: str) -> Parameter:
        return self.by_name[name]

    def __contains__(self, name) -> bool:
        return name in self.by_name

    def indices(self, names: Iterable[str]) -> np.ndarray:
        """Vector indices of ``names`` (KeyError for an unknown name)."""
        return np.array([self.by_name[n].index for n in names], dtype=int)


@accepts(model=is_a(RobotModel))
def parameter_layout(model: RobotModel) -> ParameterLayout:
    """The parameter records of ``model``, made once per model object and kept with it (an immutable
    record: its arrays are read-only).

    Parameters
    ----------
    {model}

    Returns
    -------
    ParameterLayout
        Every parameter's record (name, index, unit, family, quantity) in the vector's order.

    >>> import robocal as rc
    >>> lay = rc.kinematics.parameter_layout(rc.serial_model("r", [dict()]))
    >>> lay.names[6:9], int(lay.frame0[0])
    (('j1.gamma', 'j1.b', 'j1.beta'), 6)
    """
    return model.derived(parameter_layout, lambda: _make_parameter_layout(model))


def _make_parameter_layout(model: RobotModel) -> ParameterLayout:
    params: list[Parameter] = []

    def add(owner, role, kinds):
        first = len(params)
        params.extend(Parameter(f"{owner}.{k}", owner, role, k, first + i) for i, k in enumerate(kinds))
        return first

    add("base", "base", BASE_KINDS)
    frame0 = [add(f.name, "frame", FRAME_KINDS) for f in model.frames]
    marker0 = [add(m.name, "marker", MARKER_KINDS) for m in model.markers]
    return ParameterLayout(parameters=tuple(params), frame0=read_only(np.array(frame0, dtype=int)),
                           marker0=read_only(np.array(marker0, dtype=int)),
                           by_name=types.MappingProxyType({p.name: p for p in params}),
                           names=tuple(p.name for p in params))


def joint_variable_names(model: RobotModel) -> tuple[str, ...]:
    """Each frame's joint-variable parameter, in frame order: the offset its reading is added to
    (``theta`` of a revolute frame, ``r`` of a prismatic one; a fixed frame's ``theta``)."""
    return tuple(f"{f.name}.{'r' if f.joint == 'prismatic' else 'theta'}" for f in model.frames)


@accepts(model=is_a(RobotModel))
def parameter_names(model: RobotModel) -> tuple[str, ...]:
    """Names of the full parameter vector: ``base.x``..., ``<frame>.<kind>``, ``<marker>.<kind>``.

    Parameters
    ----------
    {model}

    Returns
    -------
    tuple of str
        Every parameter's name, in the layout order.
    """
    return parameter_layout(model).names


@accepts(model=is_a(RobotModel), reference=optional(is_a(RobotModel)))
def parameter_vector(model: RobotModel, reference: RobotModel | None = None) -> np.ndarray:
    """The model's values in the layout of ``parameter_names`` (SI).

    Rotation corrections (base and marker rx, ry, rz) are 0 for the model itself; with a
    ``reference`` of the same structure they are the corrections that turn the reference's stored
    rotations into this model's (R = R_ref exp([rx, ry, rz]x), a rotation vector), so that
    ``model_from_vector(reference, parameter_vector(model, reference))`` is ``model``.

    Parameters
    ----------
    {model, reference}

    Returns
    -------
    numpy.ndarray, shape (n_params,)
        The model's values, SI.
    """
    lay = parameter_layout(model)
    # a model's values never change: read once and kept with it (a calibration asks several times)
    p = model.derived(parameter_vector, lambda: read_only(_values(model, lay))).copy()
    if reference is not None:
        p[3:6] = rotation_vector(np.asarray(reference.base_rotation).T @ np.asarray(model.base_rotation))
        for m, (mk, mr) in enumerate(zip(model.markers, reference.markers)):
            relative = np.asarray(mr.rotation).T @ np.asarray(mk.rotation)
            p[lay.marker0[m] + 3:lay.marker0[m] + 6] = rotation_vector(relative)
    return p


def _values(model: RobotModel, lay: ParameterLayout) -> np.ndarray:
    """``parameter_vector`` of the model itself (rotation corrections 0)."""
    p = np.zeros(lay.n_params)
    p[0:3] = model.base_position
    for i, f in enumerate(model.frames):
        p[lay.frame0[i]:lay.frame0[i] + len(FRAME_KINDS)] = [getattr(f, k) for k in FRAME_KINDS]
    for m, mk in enumerate(model.markers):
        p[lay.marker0[m]:lay.marker0[m] + 3] = mk.position
    return p


@accepts(model=is_a(RobotModel), p=vector_of(lambda a: parameter_layout(a["model"]).n_params))
def model_from_vector(model: RobotModel, p: np.ndarray) -> RobotModel:
    """A new model holding the values ``p`` (rotation corrections composed into stored rotations).

    Parameters
    ----------
    {model, p}

    Returns
    -------
    RobotModel
        A new model holding the values ``p``.
    """
    lay = parameter_layout(model)
    p = np.asarray(p, dtype=float)
    Rb = np.asarray(model.base_rotation) @ small_rotation(*p[3:6])

    def values(i: int) -> dict[str, Any]:
        return {k: float(p[lay.frame0[i] + j]) for j, k in enumerate(FRAME_KINDS)}

    frames = tuple(replace(f, **values(i)) for i, f in enumerate(model.frames))
    markers = []
    for m, mk in enumerate(model.markers):
        q = p[lay.marker0[m]:lay.marker0[m] + len(MARKER_KINDS)]
        R = np.asarray(mk.rotation) @ small_rotation(*q[3:6])
        markers.append(replace(mk, position=vector3(q[:3]), rotation=matrix_tuple(R)))
    out = model.replace(base_position=vector3(p[0:3]), base_rotation=matrix_tuple(Rb), frames=frames,
                        markers=tuple(markers))
    out.derived(parameter_layout, lambda: lay)      # the same names: the layout is the same record
    return out


def _frame_geometric(model: RobotModel, i: int) -> list[str]:
    f = model.frames[i]
    kinds = []
    # gamma and b where a frame does not hang off its predecessor (Khalil-Kleinfinger trees), and on
    # every branch of a frame with several children, so that both arms' first frames are alike
    siblings = sum(1 for g in model.frames if g.parent == f.parent)
    if f.parent != i - 1 or siblings > 1:
        kinds += ["gamma", "b"]
    if f.has_beta:
        kinds.append("beta")
    kinds += ["alpha", "d", "theta", "r"]
    return [f"{f.name}.{k}" for k in kinds]


@accepts(model=is_a(RobotModel), orientation=FLAG)
def families(model: RobotModel, *, orientation: bool = False) -> dict[str, list[str]]:
    """The names each family stands for, in preference order.

    ``orientation``: the data hold orientations, so marker rotations belong to ``markers``.

    Parameters
    ----------
    {model}
    orientation : bool
        Whether orientations are measured.

    Returns
    -------
    dict
        Family name -> parameter names.
    """
    base = [f"base.{k}" for k in BASE_KINDS]
    marker_kinds = MARKER_KINDS if orientation else MARKER_KINDS[:3]
    markers = [f"{mk.name}.{k}" for mk in model.markers for k in marker_kinds]
    frames = [n for i in range(model.n_frames) for n in _frame_geometric(model, i)]
    # a frame with several children: its theta and r move every branch as the children's gamma and b
    # do together, so they come last and the branches keep alike parameters
    branching = {f.parent for f in model.frames if sum(g.parent == f.parent for g in model.frames) > 1}
    last = [f"{model.frames[i].name}.{k}" for i in sorted(branching - {-1}) for k in ("theta", "r")]
    frames = [n for n in frames if n not in last] + last
    # a fixed frame (a placement, often written as a matrix) has no joint to yield: no compliance
    compliance = [f"{f.name}.{k}" for f in model.frames if f.joint != "fixed" for k in COMPLIANCE_KINDS]
    return {"base": base, "markers": markers, "frames": frames, "geometric": base + markers + frames,
            "compliance": compliance, "backlash": backlash_names(model), "transmission": transmission_names(model)}


def backlash_names(model: RobotModel) -> list[str]:
    """The backlash parameter of every moving frame: ``backlash_theta`` or ``backlash_r`` by its joint."""
    return [f"{f.name}.backlash_{'theta' if f.joint == 'revolute' else 'r'}" for f in model.frames
            if f.joint != "fixed"]


def transmission_terms(model: RobotModel, i: int) -> tuple[str, ...]:
    """The transmission kinds frame ``i`` can carry: a moving joint's gear scale; a revolute joint's
    harmonics of its angle, and of its motor's where the frame states a reduction ratio."""
    f = model.frames[i]
    if f.joint == "fixed":
        return ()
    if f.joint == "prismatic":
        return ("gear_scale",)
    return tuple(k for k in TRANSMISSION_KINDS if f.reduction or not k.startswith("motor_"))


def transmission_names(model: RobotModel) -> list[str]:
    """The transmission parameters of every moving frame (``transmission_terms``), frame by frame."""
    return [f"{f.name}.{k}" for i, f in enumerate(model.frames) for k in transmission_terms(model, i)]


@accepts(model=is_a(RobotModel), parameters=NAMES, orientation=FLAG, known=NAMES)
def candidate_parameters(model: RobotModel, parameters: Iterable[str] = ("geometric",), *,
                         orientation: bool = False, known: Iterable[str] = ()) -> tuple[str, ...]:
    """Parameter names to consider, in preference order.

    ``parameters`` holds family names (``geometric`` = base + markers + frames, ``compliance``,
    ``backlash``, ``transmission``, ``base``, ``markers``, ``frames``), explicit parameter names such
    as ``j2.alpha`` and/or patterns such as ``*.theta`` or ``j2.*`` (see ``matched_by_pattern``).
    ``orientation``: the data hold orientations, so marker rotations are candidates too.
    ``known``: families or names to hold fixed at their model values (e.g. ``("base",)``).

    Parameters
    ----------
    {model, parameters}
    orientation : bool
        Whether orientations are measured (markers' rotation parameters become candidates).
    {known}

    Returns
    -------
    tuple of str
        The parameter names, in preference order.
    """
    args = (_as_items(parameters), bool(orientation), _as_items(known))
    # kept with the model (a calibration asks again): a tuple of names, which nobody can change
    return model.derived((candidate_parameters, args), lambda: _candidates(model, *args))


def _as_items(items) -> tuple:
    return (items,) if isinstance(items, str) else tuple(items)


def _candidates(model: RobotModel, parameters: tuple, orientation: bool, known: tuple) -> tuple[str, ...]:
    """``candidate_parameters``, made anew."""
    lay = parameter_layout(model)
    fam = families(model, orientation=orientation)

    def expand(items, what):
        out = []
        for item in (items,) if isinstance(items, str) else items:
            if item in fam:
                out += fam[item]
            elif is_pattern(item):
                out += _matching(model, item, fam, what)
            elif item in lay:
                out.append(item)
            else:
                raise InputError(f"unknown parameter or family {excerpt(item)}; families are {', '.join(FAMILIES)} "
                                 f"and names look like 'base.x', '{model.frames[0].name}.alpha'", where=what)
        return out

    chosen = set(expand(parameters, "parameters"))
    fixed = set(expand(known, "known"))
    if any(lay[n].family == "compliance" for n in chosen) and not model.has_masses:
        raise InputError("compliance parameters need link masses (or a payload); the model has none: "
                         "assume them from the geometry with robocal.default_masses(model, total_mass) "
                         "(--assume-masses, with --total-mass KG for compliances in absolute units, on the "
                         "command line)",
                         where="parameters")
    if model.backlash_side == "gravity" and any(lay[n].family == "backlash" for n in chosen) \
            and not model.has_masses:
        raise InputError("gravity-sided backlash needs link masses (or a payload); the model has none: give "
                         "masses or choose the approach-sided model", where="parameters")
    order = fam["geometric"] + fam["compliance"] + fam["backlash"] + fam["transmission"]
    extra = [n for n in chosen if n not in order]  # explicit names outside the default families
    out = tuple(n for n in order + sorted(extra) if n in chosen and n not in fixed)
    if not out:
        raise InputError(f"no parameter left to identify: the known ones ({', '.join(map(str, known))}) cover "
                         "every parameter chosen", where="known")
    return out


def is_pattern(item: str) -> bool:
    return any(c in item for c in PATTERN_CHARS)


def _pattern_pool(model: RobotModel, fam: dict) -> list[str]:
    """What a pattern may match: the geometric candidates, and compliances when there are masses."""
    return fam["geometric"] + (fam["compliance"] if model.has_masses else [])


def _matching(model: RobotModel, pattern: str, fam: dict, what: str) -> list[str]:
    found = [n for n in _pattern_pool(model, fam) if fnmatch.fnmatchcase(n, pattern)]
    if not found:
        raise InputError(f"pattern {pattern!r} matches no parameter; names look like 'base.x', "
                         f"'{model.frames[0].name}.theta', '{model.markers[0].name}.x'", where=what)
    return found


@accepts(model=is_a(RobotModel), parameters=NAMES, orientation=FLAG)
def matched_by_pattern(model: RobotModel, parameters: Iterable[str], *,
                       orientation: bool = False) -> tuple[tuple[str, tuple[str, ...]], ...]:
    """``(pattern, names)`` for each pattern among ``parameters``: the candidate names it matches.

    Patterns are shell-style (``*`` any text, ``?`` one character, ``[..]`` a set), matched against
    the whole name among the families' candidates (geometric, and compliance when the model has
    masses): ``*.theta`` every joint offset, ``j2.*`` frame j2's parameters, ``*.k_theta`` every
    torsion compliance.

    Parameters
    ----------
    {model}
    parameters : str or sequence of str
        Parameter names or patterns (``j*.d``).
    orientation : bool
        Whether orientations are measured.

    Returns
    -------
    tuple of (str, tuple of str)
        Each pattern with the names it matches.

    >>> from robocal.kinematics import serial_model
    >>> m = serial_model("rr", [dict(), dict(d=0.5)])
    >>> matched_by_pattern(m, ["geometric", "*.theta"])
    (('*.theta', ('j1.theta', 'j2.theta')),)
    """
    fam = families(model, orientation=orientation)
    items = (parameters,) if isinstance(parameters, str) else parameters
    return tuple((p, tuple(_matching(model, p, fam, "parameters"))) for p in items if is_pattern(p))


def has_compliance_parameters(model: RobotModel, names: Iterable[str]) -> bool:
    """Whether any of ``names`` is a compliance of ``model``."""
    lay = parameter_layout(model)
    return any(lay[n].family == "compliance" for n in names)


def has_backlash_parameters(model: RobotModel, names: Iterable[str]) -> bool:
    """Whether any of ``names`` is a backlash of ``model``."""
    lay = parameter_layout(model)
    return any(lay[n].family == "backlash" for n in names)


def needs_compliance(model: RobotModel, names) -> bool:
    """Whether evaluating ``names`` on ``model`` needs the gravity moments."""
    return model.has_compliance or has_compliance_parameters(model, names)
