"""The allowed values of every option, declared once: the library validates against these tables
and the command line offers them (without importing the numerical core)."""

LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")
INITIAL_BASES = ("model", "register")
POSE_CRITERIA = ("I", "D")
LIMIT_MARKER_MODES = ("first", "all")
LIMIT_CHUNK = 2048
