"""The exploring strategy (paper sections II, IV-B, V-B), one import for callers that want it all.

The pieces live in their own modules: ``poses`` (stages 1-2, pose refusal, reachability,
rotated poses), ``bending`` (bending curves, the L formula), ``cures`` (the paper's two cures),
``multiview`` (viewpoint consistency and the boundary verdict), ``detectors``, ``surface_model``
and ``planner`` (verification views, cure choice: ``decide``). World frame, metres, radians.
"""
from __future__ import annotations

from platebench.reconstruction.strategy.bending import (  # noqa: F401
    BendingCurve,
    bending_curve,
    boundary_edges,
    most_bending_curves,
    tangent_intersection_distance,
)
from platebench.reconstruction.strategy.cures import cure_move_back, cure_orient  # noqa: F401
from platebench.reconstruction.strategy.poses import (  # noqa: F401
    PoseError,
    Reach,
    SensorPose,
    cover_distance,
    ensure_in_view,
    half_fovs,
    most_bent_direction,
    rotated_pose,
    stage1_pose,
    stage2_pose,
    validate_pose,
)
