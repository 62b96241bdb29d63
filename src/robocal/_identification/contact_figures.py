"""The figures kit users judge a calibration from contacts by: the spread of each socket's seatings
and their consistency, the error of each known distance (the spacing error) and ball bar, and the
distance of plane contacts to their plane; and what contacts add to a calibration's record.

Every figure comes from the observations' errors with their own unknowns taken from their own
rows (``ContactRows.own_errors``): a socket's point at its seatings' mean centre, a plane fitted to
its contacts. The same numbers judge the fitted placements, the held-out ones and a validation set.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._base.arguments import accepts, is_a
from .._base.arrays import read_only
from .._model.contacts import Contacts
from .._model.measurements import Measurements
from .._model.parameters import parameter_vector
from .._model.robot import RobotModel
from .contact_blocks import ContactRows
from .identifiability import ContactIdentifiability


@dataclass(frozen=True, eq=False)
class ContactErrors:
    """What a kit's user judges a calibration by, for one model on one set of contacts (m):
    ``spread`` per socket (placement/socket) the RMS distance of the marker positions from their
    centroid; ``distance`` per placement and pair the centroids' distance minus the known length;
    ``plane`` per plane the RMS distance of its contacts from the plane (the known one, else the
    best-fitting); ``bar`` per pair the distance of the two ends minus the bar's length;
    ``consistency`` per socket the (mean, max) distance of its seated ball centres from their mean
    centre, the figure socket campaigns are judged by (``distance`` is then the spacing error:
    calibrated spacing minus the known one); ``seatings`` per socket each seating's distance."""

    spread: dict
    distance: dict
    plane: dict
    bar: dict
    consistency: dict = field(default_factory=dict)
    seatings: dict = field(default_factory=dict)

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
    ``contacts``): ``identifiability`` what each kind of contact reaches and what none does;
    ``nuisance`` name -> (estimate, std) of each socket point coordinate and plane parameter (SI);
    ``fit_before``/``fit_after`` and ``validation_before``/``validation_after`` the kit's figures
    (``ContactErrors``; validation None without held-out contacts); ``held_out`` the figures of each
    placement predicted by the fit on the others (None with a validation set or one placement);
    ``noise_ratio`` per kind of row the RMS residual in stated standard deviations; ``weak`` the
    parameters the rows cannot pin down (name, predicted std), held at nominal unless ``weak_kept``;
    ``rows`` the number of rows of each kind; ``source`` the contact file or folder;
    ``residual_dof`` the fit's degrees of freedom (rows less the robot's and the points' and
    planes' unknowns: what ``compare``'s F test counts)."""

    identifiability: ContactIdentifiability
    nuisance: dict
    fit_before: ContactErrors
    fit_after: ContactErrors
    validation_before: ContactErrors | None = None
    validation_after: ContactErrors | None = None
    held_out: ContactErrors | None = None
    noise_ratio: dict = field(default_factory=dict)
    weak: tuple[tuple[str, str], ...] = ()
    weak_kept: bool = False
    rows: dict = field(default_factory=dict)
    source: str = ""
    residual_dof: float = 0.0


def recordings(contacts: Contacts, data: Measurements | None) -> dict:
    """The number of recordings of each kind: seatings, plane contacts, bar ends, known distances
    (one per placement and pair) and tracker poses."""
    out = {k: int(sum(1 for x in contacts.kind if x == k)) for k in dict.fromkeys(contacts.kind)}
    pairs = len(contacts.distance_pairs())
    out.update({"distance": pairs} if pairs else {})
    out.update({"tracker": int(data.n_poses)} if data is not None else {})
    return out
