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
# the most frames and markers a model may hold (docs/formats.md): far beyond any robot, and the cost
# of a model's kinematics and of writing it grows with the square of the chain
MAX_FRAMES = 100
MAX_MARKERS = 100
# the largest model, profile, DH table or URDF file read, bytes: a model of MAX_FRAMES frames is tens of kB
MAX_MODEL_BYTES = 16 * 2 ** 20
# lines of a measurement file besides its poses (comments, the header, blank lines)
MAX_HEADER_LINES = 10_000
# Monte Carlo samples and configurations per chunk of ``limit``: 10^7 samples give the mean to
# 0.03 % of the deviations' spread; the work, samples x frames x (1 + markers / 5), is bounded too
# (about 30 s, benchmarks/README.md)
MAX_SAMPLES = 10_000_000
MAX_LIMIT_WORK = 1.2e8
MAX_CHUNK = 100_000
# pose selection (plan): operations of its updates, poses x candidates x rows x parameters^2 x
# (1 + 2 sweeps), and the size of the candidates' blocks, candidates x rows x parameters (doubles)
MAX_SELECTION_WORK = 2e10
MAX_SELECTION_BLOCKS = 4e6
# a contact file (docs/formats.md): rows, directive lines before the header, and groups (each a
# socket or plane of its own, three unknowns of the fit)
MAX_CONTACTS = 20_000
MAX_DIRECTIVES = 1_000
MAX_GROUPS = 1_000
# plan-sockets: placements simulated (about 0.1 s each: the solves that reach their seatings),
# seatings simulated for the largest design (about 1.5 ms each), rows linearised
# over the whole grid of designs (about 0.1 ms each), and the largest design's analysis, rows x
# columns^2 (the columns: its parameters and 3 per socket and placement; about 7 ns each): past
# these a plan runs for minutes (benchmarks/README.md)
MAX_PLACEMENTS = 50
MAX_SEATINGS = 5_000
MAX_GRID_ROWS = 100_000
MAX_DESIGN_WORK = 1e9
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
