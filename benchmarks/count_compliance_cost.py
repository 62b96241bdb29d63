"""Instruction counts of calibrate() with and without compliance, for a ratio that timing noise cannot blur.

    PY=$(python -c "import sys; print(sys.executable)")     # the interpreter itself, not a shim
    for mode in none g c; do
        PYTHONHASHSEED=0 OPENBLAS_NUM_THREADS=1 valgrind --tool=callgrind --callgrind-out-file=cg.$mode.out \
            $PY benchmarks/count_compliance_cost.py $mode 1000
    done
    # (Ir of c - Ir of none) / (Ir of g - Ir of none) is the cost ratio of three calibrations each

A fixed hash seed makes the three runs' common part count the same: with random string hashes
the totals move by a few million instructions from run to run, which at 48 poses is a few
percent of one calibration.

Mode ``none`` only prepares (imports, simulation, one warm-up call of each kind), ``g`` adds three
geometric calibrations, ``c`` three with compliance, on the same data.
"""
import sys
import warnings

sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from bench_identify import arm6r

import robocal as rc

warnings.simplefilter("ignore")
m = arm6r(True)
both = ("geometric", "compliance")
_, data = rc.simulate(m, int(sys.argv[2]), seed=1, parameters=both,
                      true_compliance={"j2.k_theta": 4e-6, "j3.k_theta": 6e-6})
rc.calibrate(m, data, parameters=("geometric",))          # warm caches (theory analysis)
rc.calibrate(m, data, parameters=both)
mode = sys.argv[1]
for _ in range(3):
    if mode == "g":
        rc.calibrate(m, data)
    elif mode == "c":
        rc.calibrate(m, data, parameters=both)
