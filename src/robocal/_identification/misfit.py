"""Does a fit's orientation part fit? Tests on residuals, for data with or without stated noise.

A 6D campaign read with the wrong orientation convention (``euler:XYZ`` taken for ``euler:xyz``,
quaternion columns labelled in the wrong order) does not stop the solver: it converges, reports
standard deviations, and the estimates can even look plausible. ``calibrate`` warns about misfit
from the stated standard deviations when the data carry them; these tests also cover data
without them.
"""

from __future__ import annotations

import numpy as np

# Rotation residual RMS (angle of R_pred R_meas^T) above which no 6D instrument used for robot
# calibration explains the misfit: laser-tracker 6D probes are specified at about 0.01 degree,
# camera trackers and photogrammetry at 0.05-0.1 degree. A wrong Euler sequence or swapped
# quaternion components leaves tens of degrees.
MAX_ROTATION_RMS_RAD = np.deg2rad(0.5)
# Rotation residuals carried to the robot's size must stay within this factor of the position
# residuals: a tracker 6D probe (15 um, 0.01 deg) gives about 3 at 1 m, a camera tracker (0.1 mm,
# 0.1 deg) about 17. A hundred times means the two parts of the data disagree.
MAX_ROTATION_TO_POSITION = 100.0
# Residuals over this many stated standard deviations (RMS) do not fit the stated noise: the same
# bar as calibrate's test on sigma0.
MAX_STANDARDISED_RMS = 3.0
# Below this (m) a lever-arm disagreement is round-off, not misfit (noise-free simulations).
RESOLUTION_M = 1e-6


def characteristic_length(points_W) -> float:
    """RMS distance (m) of measured points ``(..., 3)`` (W, metres; NaN rows ignored) from their centroid.

    The lever arm over which an orientation error shows as a position error: the size of the
    measured workspace, which needs no model and no base pose.

    >>> characteristic_length([[1.0, 0, 0], [-1.0, 0, 0], [np.nan, np.nan, np.nan]])
    1.0
    """
    p = np.asarray(points_W, dtype=float).reshape(-1, 3)
    p = p[np.all(np.isfinite(p), axis=1)]
    if len(p) == 0:
        return 0.0
    return float(np.sqrt(np.mean(np.sum((p - p.mean(axis=0)) ** 2, axis=1))))


def misfit_notes(position_residuals_m, rotation_residuals_rad=None, *, characteristic_length_m: float,
                 sigma_rot_rad=None) -> list[str]:
    """Messages (empty when the orientations fit) about orientation residuals that no instrument explains.

    ``position_residuals_m``: ``(n, 3)`` predicted minus measured marker positions in W, metres,
    measured entries only. ``rotation_residuals_rad``: ``(n_rot, 3)`` rotation vectors of
    ``R_pred R_meas^T`` in W, radians, or None for points only (no message then).
    ``characteristic_length_m``: the robot's size, e.g. ``characteristic_length`` of the measured
    points. ``sigma_rot_rad``: stated standard deviation per rotation residual ``(n_rot,)`` (per
    component) or a scalar; None when the data state none.

    With stated standard deviations the test is theirs: the RMS of the standardised components
    above ``MAX_STANDARDISED_RMS``. Without them two facts that hold for any instrument:

    * the RMS rotation angle exceeds ``MAX_ROTATION_RMS_RAD`` (0.5 degree): no 6D instrument used
      for robot calibration is that poor, while a wrong convention leaves tens of degrees (the
      unweighted fit also spoils the positions then, so comparing with them alone would miss it);
    * the RMS rotation angle times ``characteristic_length_m`` exceeds ``MAX_ROTATION_TO_POSITION``
      times the RMS position residual: the orientations disagree with the positions, which a
      correct declaration with any real instrument does not produce (ignored below
      ``RESOLUTION_M``, 1 micrometre, where both are round-off).

    >>> rng = np.random.default_rng(0)
    >>> misfit_notes(rng.normal(0, 2e-5, (50, 3)), rng.normal(0, 1e-5, (50, 3)), characteristic_length_m=0.5)
    []
    >>> misfit_notes(rng.normal(0, 2e-5, (50, 3)), rng.normal(0, 0.5, (50, 3)),
    ...              characteristic_length_m=0.5)[0][:46]
    'orientation residuals of 48.0 degrees RMS: far'
    """
    if rotation_residuals_rad is None:
        return []
    rot = np.asarray(rotation_residuals_rad, dtype=float).reshape(-1, 3)
    pos = np.asarray(position_residuals_m, dtype=float).reshape(-1, 3)
    if len(rot) == 0:
        return []
    hint = ("check the orientation convention (quaternion component order, Euler sequence and whether it is "
            "intrinsic, uppercase, or extrinsic, lowercase), the angle unit and the marker names")
    if sigma_rot_rad is not None:
        s = np.broadcast_to(np.asarray(sigma_rot_rad, dtype=float), (len(rot),))
        ratio = float(np.sqrt(np.mean((rot / s[:, None]) ** 2)))
        if ratio > MAX_STANDARDISED_RMS:
            return [f"orientation residuals are {ratio:.1f} times their stated standard deviations: {hint}"]
        return []
    angle_rms = float(np.sqrt(np.mean(np.sum(rot ** 2, axis=1))))
    if angle_rms > MAX_ROTATION_RMS_RAD:
        return [f"orientation residuals of {np.rad2deg(angle_rms):.1f} degrees RMS: far more than any 6D "
                f"instrument gives (limit {np.rad2deg(MAX_ROTATION_RMS_RAD):.1f} degree); {hint}"]
    pos_rms = float(np.sqrt(np.mean(np.sum(pos ** 2, axis=1)))) if len(pos) else 0.0
    lever = angle_rms * float(characteristic_length_m)
    if lever > max(MAX_ROTATION_TO_POSITION * pos_rms, RESOLUTION_M):
        return [f"orientation residuals ({np.rad2deg(angle_rms):.3g} degrees RMS, {lever * 1e3:.3g} mm over "
                f"{characteristic_length_m:.3g} m) are more than {MAX_ROTATION_TO_POSITION:.0f} times the position "
                f"residuals ({pos_rms * 1e3:.3g} mm RMS): the orientations disagree with the positions; {hint}"]
    return []
