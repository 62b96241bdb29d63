"""Which parameters to consider: families, explicit names, and the preference order.

The preference order decides which of a dependent group is kept: earlier wins. It follows the
paper and the habit of tracker users: the base first (so it absorbs what frame 1 cannot show),
then the markers, then frames from the base outwards (beta, alpha, d, theta, r within a frame, so
r of the second of two parallel axes is the one eliminated), then compliances.
"""

from __future__ import annotations

from typing import Iterable

from ._errors import InputError
from ._kinematics import layout
from ._model import ANGLE_KINDS, RobotModel

FAMILIES = ("geometric", "compliance", "base", "markers", "frames")


def _frame_geometric(model: RobotModel, i: int) -> list[str]:
    f = model.frames[i]
    kinds = []
    # gamma and b only where a frame does not hang off its predecessor (Khalil-Kleinfinger trees)
    if f.parent != i - 1:
        kinds += ["gamma", "b"]
    if f.has_beta:
        kinds.append("beta")
    kinds += ["alpha", "d", "theta", "r"]
    return [f"{f.name}.{k}" for k in kinds]


def candidate_parameters(model: RobotModel, parameters: Iterable[str] = ("geometric",), *,
                         orientation: bool = False, known: Iterable[str] = ()) -> tuple[str, ...]:
    """Parameter names to consider, in preference order.

    ``parameters`` holds family names (``geometric`` = base + markers + frames, ``compliance``,
    ``base``, ``markers``, ``frames``) and/or explicit parameter names such as ``j2.alpha``.
    ``orientation``: the data hold orientations, so marker rotations are candidates too.
    ``known``: families or names to hold fixed at their model values (e.g. ``("base",)``).
    """
    if isinstance(parameters, str):
        parameters = (parameters,)
    if isinstance(known, str):
        known = (known,)
    all_names = set(layout(model).names)
    base = [f"base.{k}" for k in ("x", "y", "z", "rx", "ry", "rz")]
    markers = []
    for mk in model.markers:
        markers += [f"{mk.name}.{k}" for k in ("x", "y", "z")]
        if orientation:
            markers += [f"{mk.name}.{k}" for k in ("rx", "ry", "rz")]
    frames = [n for i in range(model.n_frames) for n in _frame_geometric(model, i)]
    compliance = [f"{f.name}.{k}" for f in model.frames for k in ("k_theta", "k_alpha", "k_beta")]
    fam = {"base": base, "markers": markers, "frames": frames, "geometric": base + markers + frames,
           "compliance": compliance}

    def expand(items, what):
        out = []
        for item in items:
            if item in fam:
                out += fam[item]
            elif item in all_names:
                out.append(item)
            else:
                raise InputError(f"unknown parameter or family {item!r}; families are {', '.join(FAMILIES)} "
                                 f"and names look like 'base.x', '{model.frames[0].name}.alpha'", where=what)
        return out

    chosen = set(expand(parameters, "parameters"))
    fixed = set(expand(known, "known"))
    if any(n.endswith(("k_theta", "k_alpha", "k_beta")) for n in chosen) and not model.has_masses:
        raise InputError("compliance parameters need link masses (or a payload); the model has none",
                         where="parameters")
    order = base + markers + frames + compliance
    extra = [n for n in chosen if n not in order]  # explicit names outside the default families
    return tuple(n for n in order + sorted(extra) if n in chosen and n not in fixed)


def is_angle(name: str) -> bool:
    """Whether a parameter is an angle (rad) rather than a length (m) or a compliance (rad/N m)."""
    return name.rsplit(".", 1)[1] in ANGLE_KINDS


def unit_of(name: str) -> str:
    kind = name.rsplit(".", 1)[1]
    if kind.startswith("k_"):
        return "rad/(N m)"
    return "rad" if kind in ANGLE_KINDS else "m"
