"""The allowed values of every option, declared once: the library validates against these tables
and the command line offers them (without importing the numerical core)."""

LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")
INITIAL_BASES = ("model", "register")
POSE_CRITERIA = ("I", "D")
LIMIT_MARKER_MODES = ("first", "all")
LIMIT_CHUNK = 2048
# the most poses a measurement file or a simulated campaign may hold (docs/formats.md); a file is also
# bounded by memory: POSES_PER_GB poses per GB available when it is read (reading, solving by chunks
# and writing a calibration of 3D points take about 1 kB per pose, see benchmarks/README.md)
MAX_POSES = 10_000_000
POSES_PER_GB = 1_000_000
# Monte Carlo samples and configurations per chunk of ``limit``: past these it is hours or gigabytes
MAX_SAMPLES = 100_000_000
MAX_CHUNK = 100_000
OUTLIER_ACTIONS = ("refit", "flag")
WEAK_ACTIONS = ("eliminate", "flag")
# where a joint rests in its lost motion, pose by pose (RobotModel.backlash_side)
BACKLASH_SIDES = ("gravity", "approach")

# Measurement noise of each instrument class, one standard deviation per axis: position (m) and
# rotation (rad, for 6D probes). Used when the data state none (docs/checks.md).
INSTRUMENT_NOISE = {
    "tracker": (0.02e-3, 0.01 * 3.141592653589793 / 180),      # laser tracker, 6D probe
    "theodolite": (0.04e-3, 0.02 * 3.141592653589793 / 180),   # about 0.02 mm per metre at 2 m
    "cmm": (0.005e-3, 0.005 * 3.141592653589793 / 180),
    "camera": (0.1e-3, 0.1 * 3.141592653589793 / 180),         # motion capture, photogrammetry
}
DEFAULT_INSTRUMENT = "tracker"
