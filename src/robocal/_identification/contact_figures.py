"""The figures kit users judge a calibration from contacts by: the spread of each socket's seatings
and their consistency, the error of each known distance (the spacing error) and ball bar, and the
distance of plane contacts to their plane; and what contacts add to a calibration's record.

Every figure comes from the observations' errors with their own unknowns taken from their own
rows (``ContactRows.own_errors``): a socket's point at its seatings' mean centre, a plane fitted to
its contacts. The same numbers judge the fitted placements, the held-out ones and a validation set.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields

import numpy as np

from .._base.arguments import accepts, is_a
from .._base.arrays import frozen_mapping, read_only
from .._model.contacts import Contacts
from .._model.measurements import Measurements
from .._model.parameters import parameter_vector
from .._model.robot import RobotModel
from .contact_blocks import ContactRows
from .identifiability import ContactIdentifiability


@dataclass(frozen=True, eq=False)
class ContactErrors:
    """What a kit's user judges a calibration by, for one model on one set of contacts; every
    mapping read-only.

    Attributes
    ----------
    spread : Mapping
        Per socket ("placement/socket") the RMS distance of the marker positions from their
        centroid, m.
    distance : Mapping
        Per placement and pair the centroids' distance minus the known length, m (for sockets the
        spacing error: calibrated spacing minus the known one).
    plane : Mapping
        Per plane the RMS distance of its contacts from the plane (the known one, else the
        best-fitting), m.
    bar : Mapping
        Per pair the distance of the two ends minus the bar's length, m.
    consistency : Mapping
        Per socket the (mean, max) distance of its seated ball centres from their mean centre, m:
        the figure socket campaigns are judged by.
    seatings : Mapping
        Per socket each seating's distance from that centre, m (read-only arrays).
    """

    spread: Mapping[str, float]
    distance: Mapping[str, float]
    plane: Mapping[str, float]
    bar: Mapping[str, float]
    consistency: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    seatings: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for f in fields(self):
            object.__setattr__(self, f.name, frozen_mapping(getattr(self, f.name)))

    @property
    def mean_spread(self) -> float | None:
        return float(np.mean(list(self.spread.values()))) if self.spread else None

    @property
    def distance_rms(self) -> float | None:
        return float(np.sqrt(np.mean(np.square(list(self.distance.values()))))) if self.distance else None

    @property
    def consistency_mean(self) -> float | None:
        """The mean distance of every seated ball centre from its socket's mean centre (m)."""
        d = list(self.seatings.values())
        return float(np.mean(np.concatenate(d))) if d else None

    @property
    def consistency_by_placement(self) -> float | None:
        """The mean over placements of each placement's mean seating distance from its socket's mean
        centre (m): the aggregate published per placement, beside the pooled ``consistency_mean``."""
        per: dict = {}
        for label, d in self.seatings.items():
            per.setdefault(label.split("/")[0], []).append(np.asarray(d))
        return float(np.mean([np.mean(np.concatenate(v)) for v in per.values()])) if per else None

    @property
    def consistency_max(self) -> float | None:
        """The largest distance of a seated ball centre from its socket's mean centre (m)."""
        return float(max(m for _, m in self.consistency.values())) if self.consistency else None

    @property
    def spacing_mean(self) -> float | None:
        """The mean absolute spacing error (calibrated minus known distance, m)."""
        return float(np.mean(np.abs(list(self.distance.values())))) if self.distance else None

    @property
    def spacing_max(self) -> float | None:
        """The largest absolute spacing error (m)."""
        return float(np.max(np.abs(list(self.distance.values())))) if self.distance else None


def figures(rows: ContactRows, errors: np.ndarray) -> ContactErrors:
    """The kit's figures from each observation's own errors (n_obs, 3), ``ContactRows.own_errors``
    order; groups with an observation not predicted (NaN) are left out."""
    out: dict = {k: {} for k in ("spread", "distance", "plane", "bar", "consistency", "seatings")}
    for kind, label, idx in rows.obs_groups:
        v = errors[idx]
        if not np.isfinite(v[:, 0]).all():
            continue
        if kind == "socket":
            d = np.linalg.norm(v, axis=1)
            out["spread"][label] = float(np.sqrt(np.mean(d ** 2)))
            out["consistency"][label] = (float(d.mean()), float(d.max()))
            out["seatings"][label] = read_only(d)
        elif kind == "plane":
            out["plane"][label] = float(np.sqrt(np.mean(v[:, 0] ** 2)))
        else:
            out[kind][label] = float(v[0, 0])
    return ContactErrors(**out)


@accepts(model=is_a(RobotModel), contacts=is_a(Contacts))
def contact_errors(model: RobotModel, contacts: Contacts) -> ContactErrors:
    """The figures of ``ContactErrors`` for ``model`` at the readings of ``contacts``.

    Parameters
    ----------
    {model, contacts}

    Returns
    -------
    ContactErrors
        The residuals of each kind of contact.
    """
    rows = ContactRows.of(model, contacts, (), compliance=model.has_compliance)
    return figures(rows, rows.own_errors(parameter_vector(model)))


@dataclass(frozen=True, eq=False)
class ContactFigures:
    """What contacts add to the ``CalibrationResult`` of a calibration that fitted them (its
    ``contacts``). The fit's degrees of freedom (the rows less the robot's and the points' and
    planes' unknowns) are the result's ``solver.residual_dof``.

    Attributes
    ----------
    identifiability : ContactIdentifiability
        What each kind of contact reaches and what none does.
    nuisance : Mapping
        name -> (estimate, std) of each socket point coordinate and plane parameter, SI (m, rad),
        in the measurement frame W.
    fit_before : ContactErrors
        The kit's figures of the nominal model on the fitted contacts.
    fit_after : ContactErrors
        Those of the calibrated model.
    validation_before : ContactErrors or None
        The nominal model's on held-out contacts; None without them.
    validation_after : ContactErrors or None
        The calibrated model's on held-out contacts; None without them.
    held_out_before : ContactErrors or None
        The nominal model's figures of each placement predicted by the others (its base and
        markers registered on the others, as the accuracy in use's "before"); None with held-out
        contacts or one placement.
    held_out : ContactErrors or None
        The figures of each placement predicted by the fit on the others; None with held-out
        contacts (they judge the calibration instead) or one placement.
    noise_ratio : Mapping
        Per kind of row the RMS residual in stated standard deviations.
    weak : tuple of (str, str)
        The parameters the rows cannot pin down: (name, predicted standard deviation as text).
    weak_kept : bool
        Whether they were kept (else held at nominal).
    rows : Mapping
        The number of recordings of each kind.
    source : str
        The contact file or folder.
    """

    identifiability: ContactIdentifiability
    nuisance: Mapping[str, tuple[float, float]]
    fit_before: ContactErrors
    fit_after: ContactErrors
    validation_before: ContactErrors | None = None
    validation_after: ContactErrors | None = None
    held_out_before: ContactErrors | None = None
    held_out: ContactErrors | None = None
    noise_ratio: Mapping[str, float] = field(default_factory=dict)
    weak: tuple[tuple[str, str], ...] = ()
    weak_kept: bool = False
    rows: Mapping[str, int] = field(default_factory=dict)
    source: str = ""

    def __post_init__(self) -> None:
        for name in ("nuisance", "noise_ratio", "rows"):
            object.__setattr__(self, name, frozen_mapping(getattr(self, name)))
        object.__setattr__(self, "weak", tuple(tuple(w) for w in self.weak))


def recordings(contacts: Contacts, data: Measurements | None) -> dict:
    """The number of recordings of each kind: seatings, plane contacts, bar ends, known distances
    (one per placement and pair) and tracker poses."""
    out = {k: int(sum(1 for x in contacts.kind if x == k)) for k in dict.fromkeys(contacts.kind)}
    pairs = len(contacts.distance_pairs())
    out.update({"distance": pairs} if pairs else {})
    out.update({"tracker": int(data.n_poses)} if data is not None else {})
    return out
