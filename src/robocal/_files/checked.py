"""What a writer checks of what it is about to write (docs/formats.md): the text reads back with
robocal's own reader, and the model read back reproduces the one it came from: its markers'
geometric forward kinematics (no compliance, no backlash: the exports hold the geometry only)
agree to ``FK_TOL`` at readings spread over the joint limits. A model that fails is refused with
one line saying by how much, and nothing is written."""

from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from .._base.errors import InputError
from .._model.kinematics import evaluate
from .._model.robot import TRANSMISSION_KINDS, RobotModel

# metres: how far a marker of a written model may be from the source model's
FK_TOL = 1e-9
# readings compared, and the box they are drawn from where the limits are wider or open
# (radians for angles, metres for lengths): beyond it a reading says nothing more of the geometry
SAMPLES = 16
READING_BOX = {"angle": 2 * np.pi, "length": 10.0}


def sample_readings(model: RobotModel, n: int = SAMPLES, rng=0) -> np.ndarray:
    """``n`` readings (n, n_joints) spread within the joint limits, each limit clipped to ``READING_BOX``.

    Parameters
    ----------
    model : RobotModel
    n : int
        Number of readings.
    rng : seed or numpy Generator

    Returns
    -------
    numpy.ndarray
        (n, n_joints) readings; the first row is the point of the clipped limits nearest zero.
    """
    box = np.array([READING_BOX[k] for k in model.reading_quantities])
    lo, hi = (np.clip(np.asarray(v, dtype=float), -box, box) for v in (model.lower_limits, model.upper_limits))
    q = lo + (np.maximum(hi, lo) - lo) * np.random.default_rng(rng).random((n, model.n_joints))
    q[0] = np.clip(0.0, lo, np.maximum(hi, lo))
    return q


def within_limits(model: RobotModel, q) -> np.ndarray:
    """Per row of readings ``q`` (N, n_joints): every reading within the model's joint limits.

    Parameters
    ----------
    model : RobotModel
    q : array_like
        (N, n_joints) readings, SI.

    Returns
    -------
    numpy.ndarray
        (N,) bool; False where a reading is beyond a limit or not finite.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    return np.all(np.isfinite(q) & (q >= model.lower_limits) & (q <= model.upper_limits), axis=1)


def marker_gap(model: RobotModel, back: RobotModel, pairs) -> float:
    """The largest distance, m, between marker ``a`` of ``model`` and marker ``b`` of ``back`` over
    ``pairs`` ((a, b) indices), at :func:`sample_readings` of ``model`` (``back`` takes the readings of
    the same names); inf when it is not finite.

    Parameters
    ----------
    model, back : RobotModel
        The source and the model read back; ``back``'s joints are some of ``model``'s.
    pairs : sequence of (int, int)

    Returns
    -------
    float
    """
    q = sample_readings(model)
    model = without_transmission(model)       # an export carries the geometry only
    with np.errstate(all="ignore"):
        a = evaluate(model, q, compliance=False, backlash=False).positions
        b = evaluate(back, q[:, [model.joint_names.index(n) for n in back.joint_names]], compliance=False,
                     backlash=False).positions
        gap = np.max(np.linalg.norm(a[:, [i for i, _ in pairs]] - b[:, [j for _, j in pairs]], axis=-1))
    return float(gap) if np.isfinite(gap) else float("inf")


def without_transmission(model: RobotModel) -> RobotModel:
    """``model`` with its transmission terms zero: the geometry an export carries."""
    if not model.has_transmission:
        return model
    zero: dict[str, Any] = dict.fromkeys(TRANSMISSION_KINDS, 0.0)
    return model.replace(frames=tuple(replace(f, **zero) for f in model.frames))


def check_reproduces(model: RobotModel, back: RobotModel, what: str, *, source: str | None = None,
                     pairs=None, chain: bool = True) -> None:
    """Raise InputError unless ``back`` (``model`` written as ``what`` and read back) has its joints
    (all of them, or with ``chain=False`` some, as a chain to one marker of a tree has) and, marker
    by marker (``pairs``, default by name), its forward kinematics to ``FK_TOL``.

    Parameters
    ----------
    model, back : RobotModel
    what : str
        What was written, for the message ("the URDF", ...).
    source : str, optional
        The file the model came from, for the message.
    pairs : sequence of (int, int), optional
        (marker of ``model``, marker of ``back``); default the markers of the same name.
    chain : bool
        ``back`` must have every joint of ``model``.
    """
    def refuse(detail: str):
        return InputError(f"{what} would not reproduce the model ({detail}); nothing written", source=source)

    unknown = [n for n in back.joint_names if n not in model.joint_names]
    if unknown or (chain and back.n_joints != model.n_joints):
        raise refuse(f"joints {', '.join(back.joint_names)} read back for {', '.join(model.joint_names)}")
    if pairs is None:
        missing = [n for n in model.marker_names if n not in back.marker_names]
        if missing:
            raise refuse(f"marker {missing[0]!r} missing")
        pairs = [(i, back.marker_names.index(n)) for i, n in enumerate(model.marker_names)]
    gap = marker_gap(model, back, pairs)
    if not gap <= FK_TOL:
        raise refuse(f"a marker moves by {gap:.3g} m, more than {FK_TOL:g} m: the model's values are out of range "
                     "for this format")


def read_back_dh(text: str, name: str):
    """The model a DH table's ``text`` reads back as (through a file, as a user would read it)."""
    from .dh import read_dh_table

    with tempfile.TemporaryDirectory(prefix="robocal-check-") as folder:
        path = Path(folder) / "table.csv"
        path.write_text(text, encoding="utf-8")
        return read_dh_table(path, name=name)


def check_export(model: RobotModel, text: str, fmt: str, *, source: str | None = None) -> None:
    """Raise InputError unless the export ``text`` (format ``fmt``: urdf, mdh-csv, dh-csv) reads back
    as a model that reproduces ``model`` (:func:`check_reproduces`).

    Parameters
    ----------
    model : RobotModel
    text : str
        What the exporter made of ``model``.
    fmt : str
    source : str, optional
        The model's file, for the message.
    """
    what = {"urdf": "the URDF", "mdh-csv": "the modified-DH table", "dh-csv": "the classic DH table"}[fmt]
    try:
        if fmt != "urdf":
            check_reproduces(model, read_back_dh(text, model.name), what, source=source)
            return
        from .urdf import read_urdf

        joints = ET.fromstring(text).findall("joint")
        moving = sorted(j.get("name", "") for j in joints if j.get("type") != "fixed" and j.find("mimic") is None)
        if moving != sorted(model.joint_names):
            raise InputError(f"{what} would not reproduce the model (joints {', '.join(moving)} written for "
                             f"{', '.join(model.joint_names)}); nothing written", source=source)
        # the writer puts one fixed joint per marker last, its child the marker's link
        for m, j in enumerate(joints[-len(model.markers):]):
            child = j.find("child")
            back = read_urdf(text, tip_link=None if child is None else child.get("link"))
            check_reproduces(model, back, what, source=source, pairs=[(m, 0)], chain=False)
    except InputError as e:
        if e.detail.startswith(what):
            raise
        raise InputError(f"{what} would not read back ({e}); nothing written", source=source) from None


def check_model_text(model: RobotModel, text: str, *, source: str | None = None) -> None:
    """Raise InputError unless the model file ``text`` reads back as a model reproducing ``model``.

    Parameters
    ----------
    model : RobotModel
    text : str
        The YAML :func:`model_to_yaml` made of ``model``.
    source : str, optional
        Where ``model`` came from, for the message.
    """
    from .model import model_from_dict
    from .text import load_yaml

    try:
        back = model_from_dict(load_yaml(text, "model"), source="model")
    except InputError as e:
        raise InputError(f"the model file would not read back ({e.where or ''}: {e.detail}); nothing written",
                         source=source) from None
    check_reproduces(model, back, "the model file", source=source)
