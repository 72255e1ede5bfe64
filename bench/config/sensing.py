"""Defaults of the sensing loop and of its study that the command line shows and checks (plain values,
so that ``platebench sense`` and ``platebench study`` parse and refuse flags without loading the loop):
``bench.run.sensing.records`` and ``bench.run.study`` take them from here."""
from __future__ import annotations

from platebench.plates.spec import reference_spec

# The square grid the verification views and cures project (ROWSxCOLS@SQUARE_PX, ``bench.config.parse_grid``),
# "auto" by default (``bench.run.sensing.records.auto_verify_grid``): 6 arrays of 12 squares of 12 projector pixels (3 mm at 0.4 m;
# rows 48 px apart) at 640 px wide and more. Stage 3 keeps the sample's own pattern (the paper's 16
# squares by default) for the paper's pipeline and its counting test. The verdict's front check and its
# confirmations need square centres up to the plate's edges: measured over the false-boundary study's
# 61 plates at 640 x 480 (README, "What the bench measures"), this grid verifies the boundary on every
# plate pairs of reachable poses can verify, where the paper's 16 squares at every pose verify none.
VERIFY_GRID = "auto"

# The false-boundary study's cylinders (``bench.run.study.study_cases``)
DEFAULT_BENDS_DEG = (0.0, 60.0, 120.0, 180.0, 240.0, 300.0)  # bend angles, convex and concave
STUDY_AXES_DEG = (0.0, 30.0, 60.0, 90.0)  # bend axes from the plate's width direction
REFERENCE_ASPECT = reference_spec().length_m / reference_spec().width_m  # the paper's plate, length / width
