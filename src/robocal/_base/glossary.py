"""The one description of each argument name public functions share (numpy docstring entries).

A docstring's Parameters section names shared arguments in braces, ``{model, q, rng}``, on a line of
its own; ``accepts`` writes each one's entry there (``name : type`` and its description), so an
argument means the same everywhere and is described once.
"""

from __future__ import annotations

import re
import textwrap

# name -> (type, description)
DESCRIPTIONS: dict[str, tuple[str, str]] = {
    "model": ('RobotModel', 'The robot model (nominal, unless said otherwise).'),
    "rng": ('None, int or numpy.random.Generator', 'Seed or generator of the random draws (None: fresh entropy).'),
    "seed": ('None, int or numpy.random.Generator', 'Seed or generator of the random draws.'),
    "path": ('str or os.PathLike', 'The file to read or write.'),
    "units": ('str', 'Length and angle units of the file or table, ``"mm-deg"``, ``"m-rad"``, ...'),
    "orientation": ('bool', 'Whether marker orientations count as well as positions.'),
    "tol": ('float', 'Relative tolerance in (0, 1).'),
    "result": ('CalibrationResult', "A calibration's result."),
    "parameters": ('str or sequence of str',
           'Parameter families (``geometric``, ``compliance``, ``base``, ``markers``, ``frames``, ``backlash``) '
           'and/or parameter names or patterns.'),
    "known": ('str or sequence of str', 'Families, names or patterns held at their model values.'),
    "marker": ('int', 'Index of the marker in the model (0 <= marker < n_markers).'),
    "q": ('array_like, shape (n_poses, n_joints)', 'Joint readings, rad or m.'),
    "force": ('bool', 'Overwrite an existing file.'),
    "data": ('Measurements', 'Joint readings with what the instrument measured.'),
    "markers": ('sequence', 'Markers as ``(name, (x, y, z))`` or ``(name, (x, y, z), R)`` in the tool frame, SI.'),
    "names": ('sequence of str', 'Parameter names (``parameter_names``).'),
    "contacts": ('Contacts', 'Joint-only contact recordings (sockets, planes, ball bars).'),
    "noise": ('float', 'Position noise of the instrument, m (one standard deviation per axis).'),
    "true_model": ('RobotModel', 'The true robot the simulation measures.'),
    "payload_mass": ('float or array_like of shape (n_poses,), optional',
           'Payload mass, kg, for every pose or one per pose.'),
    "imp": ('RobotImperfections', 'How the real robot, its controller and the instrument depart from the ideal.'),
    "joint_noise": ('float', 'Joint-reading noise, rad or m (one standard deviation).'),
    "seat_noise": ('float', 'Scatter of the seating of a probe in a socket or on a plane, m.'),
    "length_quantum": ('float', 'Resolution lengths are stored with in the controller, m (0: exact).'),
    "angle_quantum": ('float', 'Resolution angles are stored with in the controller, rad (0: exact).'),
    "name": ('str', "The robot's name."),
    "d": ('dict', 'The parsed file (YAML or JSON mapping).'),
    "source": ('str', 'Where ``d`` came from, for messages.'),
    "calibration": ('dict, optional', 'The calibration record to store with the model (``calibration_record``).'),
    "n": ('int', 'How many.'),
    "true": ('RobotModel', 'The true robot the campaign is simulated on.'),
    "loss": ('str', 'Least-squares loss: ``linear`` or a robust one (``soft_l1``, ``huber``, ``cauchy``, ``arctan``).'),
    "max_nfev": ('int, optional', "Most evaluations of the residuals (None: the solver's default)."),
    "targets_q": ('array_like, shape (n_poses, n_joints)',
           'Joint readings at which the nominal model puts the marker on the targets.'),
    "nominal": ('RobotModel', 'The nominal model (what the controller knew before calibration).'),
    "encoder_resolution": ('float or array_like of shape (n_joints,)',
           'Encoder resolution per joint reading, rad or m per count.'),
    "chunk_size": ('int', 'Configurations evaluated at once (bounds memory).'),
    "rows": ('sequence of dict', 'One row per frame.'),
    "joint_limits": ('sequence of (float, float), optional',
           'Lower and upper limit of each joint reading, rad or m (None: +-pi for revolute, [0, 1] m for '
           'prismatic).'),
    "noise_rot": ('float, optional', 'Orientation noise, rad (None: no orientation noise given).'),
    "labels": ('sequence of str', 'A label per pose, for messages (default ``pose i``).'),
    "p": ('array_like, shape (n_params,)', "Values in the model's parameter layout (``parameter_names``)."),
    "length_error": ('(float, float)', 'Range (lo, hi) of the magnitude of length errors, m.'),
    "angle_error": ('(float, float)', 'Range (lo, hi) of the magnitude of angle errors, rad.'),
    "compliance_error": ('(float, float), optional',
           'Range of compliance errors, rad/(N m) (None: compliances left alone).'),
    "targets": ('array_like, shape (n, 3)', 'Target positions of the marker in W, m.'),
    "extra": ('dict, optional', 'Extra sections of the report (e.g. an accuracy-limit record).'),
    "max_offset": ('float, optional', 'Largest offset along a joint axis accepted where two axes are parallel, m.'),
    "placements": ('int', 'Number of placements of the socket plate.'),
    "poses_per_socket": ('int', 'Seatings recorded per socket and placement.'),
    "bounds": ('dict, optional', 'Largest acceptable standard deviation per quantity (``length`` m, ``angle`` rad).'),
    "shown": ('sequence of str', 'Parameter names shown whatever their change (default: the largest changes).'),
    "weighted": ('bool', 'Show residuals weighed by their stated standard deviations.'),
    "J": ('array_like, shape (n_rows, n_params)', 'Identification Jacobian (columns: ``names``).'),
    "quantities": ('sequence of str', 'Quantity of each column: ``length``, ``angle`` or ``compliance``.'),
    "problem": ('Problem', 'The identification problem: a model on a stack of observation blocks.'),
    "repeatability": ('RepeatabilityResult or float', 'ISO 9283 repeatability (RP), or its value in m.'),
    "precision": ('PrecisionResult', 'The precision of the geometric control (``controller_precision``).'),
    "validation": ('Contacts, optional', 'Held-out recordings to judge the calibration on.'),
    "on_outliers": ('str', '``refit`` refits without outliers, ``flag`` only names them.'),
    "positions": ('array_like, shape (n_poses, 3), optional',
           'Target marker positions in W, m (default: where the nominal model puts the marker at ``targets_q``).'),
    "rotations": ('array_like, shape (n_poses, 3, 3), optional', 'Target marker orientations in W.'),
    "iterations": ('int', 'Most Newton iterations per target.'),
    "damping": ('float', 'Damping of the least-squares steps (>= 0).'),
    "max_step": ('float', 'Largest joint step per iteration, rad or m.'),
    "n_samples": ('int', 'Monte Carlo samples.'),
    "progress": ('callable, optional', 'Called as ``progress(done, total)`` after each chunk.'),
    "total_mass": ('float, optional',
           'Total mass of the links, kg (None: a density of ``DEFAULT_LINK_DENSITY`` kg per metre).'),
    "base": ('array_like, shape (4, 4), optional', 'Pose of the base in W (None: identity).'),
    "n_random": ('int', 'Random configurations used when ``data`` is None.'),
    "pose_ids": ('sequence', 'The pose of each measured point.'),
    "points": ('array_like, shape (n, 3)', 'Measured points, m.'),
    "frame": ('Frame', 'One frame of a model.'),
    "frames": ('sequence of Frame', 'Frames of a model.'),
    "reference": ('RobotModel, optional',
           'Model whose stored rotations the vector is relative to (default: ``model``).'),
    "n_workspace": ('int', 'Configurations within the joint limits the predicted error is averaged over.'),
    "n_configurations": ('int', 'Configurations the prediction is averaged over.'),
    "sep": ('str, optional', 'Column separator (None: detected).'),
    "decimal": ('str, optional', 'Decimal mark (None: detected).'),
    "columns": ('dict or ColumnMap, optional', 'File column -> robocal column (None to ignore a column).'),
    "unknown": ('str, optional', '``refuse`` (default) or ``ignore`` columns robocal does not know.'),
    "joints": ('str or os.PathLike, optional', 'A second file with the joint readings, joined on column ``key``.'),
    "key": ('str, optional', 'The column the two files are joined on (default ``pose``).'),
    "profile": ('str, os.PathLike or Profile, optional', 'An instrument profile giving any of these options.'),
    "path_or_string": ('str or os.PathLike', 'A URDF file, or its XML text.'),
    "base_link": ('str, optional', 'The link the model starts from (default: the root).'),
    "tip_link": ('str, optional', 'The link the model ends at (default: the single leaf).'),
    "candidates": ('array_like, shape (n_candidates, n_joints), optional',
           'Joint readings to choose from (default: ``n_candidates`` drawn within the joint limits).'),
    "n_candidates": ('int', 'Candidates drawn when ``candidates`` is None.'),
    "criterion": ('str', '``I`` (average prediction variance) or ``D`` (determinant).'),
    "sweeps": ('int', 'Passes of exchanges after the greedy selection.'),
    "base_position": ('array_like, shape (3,)', 'Position of the base frame in W, m.'),
    "base_rotation": ('array_like, shape (3, 3), optional', 'Orientation of the base frame in W (None: identity).'),
    "beta_tol": ('float', "Angle below which consecutive axes count as parallel (Hayati's beta), rad."),
    "gravity": ('array_like, shape (3,)', 'Gravity in W, m/s^2.'),
    "payload": ('Payload, optional', 'The payload (None: none, on the last frame).'),
    "description": ('str', 'Free text stored with the model.'),
    "n_poses": ('int, optional', 'Random configurations measured when ``q`` is None.'),
    "true_compliance": ('dict, optional', 'Exact true values of compliance parameters by name, rad/(N m).'),
    "frame_names": ('sequence of str', "The model's frame names."),
    "X": ('array_like, shape (4, 4)', 'A homogeneous transform.'),
    "limit": ('AccuracyLimit', 'The limit of absolute accuracy.'),
    "q_commanded": ('array_like, shape (n_poses, n_joints)', 'Commanded joint readings.'),
    "controller_model": ('RobotModel, optional', 'The model the controller computes with (None: the nominal).'),
    "recorded": ('array_like, shape (n_poses, n_joints)', 'Joint readings in the order they were visited.'),
    "plate": ('dict', 'Socket name -> position on the plate, m.'),
    "distance_sigma": ('float', 'Standard deviation of the known socket spacings, m.'),
    "known_distances": ('bool', 'Whether the socket spacings are known.'),
    "planes": ('int', 'Number of planes probed.'),
    "poses_per_plane": ('int', 'Contacts recorded per plane.'),
    "extent": ('float', 'Half-size of the probed area on each plane, m.'),
    "pairs": ('int', 'Ball-bar placements.'),
    "length": ('float', 'Ball-bar length, m.'),
    "length_sigma": ('float', 'Standard deviation of the ball-bar length, m.'),
    "box": ('array_like, shape (2, 3)', 'Lower and upper corner of the box plate centres are drawn in, m.'),
    "tilt_deg": ('float', 'Largest tilt of the plate, deg.'),
    "max_rounds": ('int', 'Random restarts per target.'),
    "comparison": ('Comparison', 'The result of ``compare``.'),
    "res": ('IdentifiabilityResult', 'The identifiability analysis.'),
    "where": ('str', 'What the analysis was made on (for the heading).'),
    "checks": ('sequence of Check', 'Checks of a calibration.'),
    "value": ('float or None', 'A value in SI units.'),
    "unit": ('str', 'Display unit of the value (``DISPLAY_UNITS``).'),
    "sign": ('bool', 'Always show the sign.'),
    "max_terms": ('int', 'Most terms shown in an absorbing combination.'),
    "n_rows": ('int, optional', 'Rows of the full problem when ``J`` is a reduced form (default: its rows).'),
    "sigma": ('float', 'Noise of the rows of ``J`` (one standard deviation), in their units.'),
    "moments": ('dict, optional', 'Known moments of the parameters (prior knowledge) by name.'),
    "approach": ('array_like, shape (n_poses, n_joints), optional', "Direction (+1 or -1) of each joint's last move."),
    "p0": ('array_like, shape (n_params,)', 'Starting parameter vector (full layout).'),
    "f_scale": ('float, optional', 'Residual scale at which a robust loss bends (None: estimated).'),
    "lower": ('array_like, shape (n_free,), optional', 'Lower bounds of the free parameters (-inf: none).'),
    "solution": ('Solution', 'A solution of ``solve``.'),
    "convention": ('str, optional',
                   "What a theta, d, a, alpha table means: ``classic`` or ``modified`` DH (Craig's layout)."),
    "per_pose": ('bool', 'Keep the per-pose arrays (in a sidecar file beside the result file).'),
    "folder": ('str or os.PathLike, optional', 'Where the per-pose file of the result is.'),
    "header": ('sequence of str, optional', 'The column names of a file without a header line.'),
    "store": ('Store', 'An open store of calibrations (``open_store``).'),
    "robot": ('str', "The robot's serial or name."),
    "h": ('History', "A robot's history (``history``)."),
}


_PLACEHOLDER = re.compile(r"^(?P<indent>[ \t]*)\{(?P<names>\w+(?:, \w+)*)\}[ \t]*$", re.M)


def expand(doc: str | None) -> str | None:
    """``doc`` with each ``{name, ...}`` line replaced by those names' entries.

    >>> print(expand("    {force}"))
        force : bool
            Overwrite an existing file.
    """
    if not doc:
        return doc

    def entries(m: re.Match) -> str:
        indent = m["indent"]
        out = []
        for name in m["names"].split(", "):
            typ, text = DESCRIPTIONS[name]
            out.append(f"{indent}{name} : {typ}")
            out += [f"{indent}    {line}" for line in textwrap.wrap(text, 96)]
        return "\n".join(out)

    return _PLACEHOLDER.sub(entries, doc)
