"""The sensing loop: the paper's stages 1-3 on a simulated robot, verification views, cures chosen
from measured geometry, and a verdict that says whether the whole boundary was verified.

* ``loop``: ``run_sensing`` and its stages;
* ``sensor``: the simulated robot (renders a pose; ground truth beside it, for scoring only);
* ``records``: options and outcome classes (the frozen records of ``sensing.json``: ``bench.io.sensing_records``);
* ``scoring``: the loop's results against ground truth.
"""
from platebench.bench.io.sensing_records import (
    HIDDEN_BELOW,
    OUTCOME_TEXT,
    OUTCOMES,
    ActiveRecord,
    FinalRecord,
    SensingResult,
    StageRecord,
    ViewRecord,
    hidden,
)
from platebench.bench.run.sensing.loop import run_sensing, write_multiview
from platebench.bench.run.sensing.records import SensingOptions, outcome_class
from platebench.bench.run.sensing.scoring import merged_accuracy
from platebench.bench.run.sensing.sensor import SimulatedSensor
from platebench.reconstruction.strategy.poses import PoseError

__all__ = ["SensingOptions", "SensingResult", "run_sensing", "outcome_class", "OUTCOMES", "OUTCOME_TEXT",
           "HIDDEN_BELOW", "hidden", "merged_accuracy", "PoseError", "SimulatedSensor",
           "StageRecord", "ActiveRecord", "ViewRecord", "FinalRecord", "write_multiview"]
