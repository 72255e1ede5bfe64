"""Parametric deformed plates with exact analytic ground truth (geometry only: numpy + trimesh).

Units: metres and radians. World frame: right-handed, +Z up; the undeformed plate
lies in z = 0, centred on the origin, length along X, width along Y. Material
coordinates uv: u in [-L/2, L/2] along X, v in [-W/2, W/2] along Y (metres).
Conventions of each deformation family are documented in plates/spec.py.
"""

from .plate import Plate, build_plate
from .spec import (
                   CylindricalBend,
                   Dent,
                   Dome,
                   Flat,
                   Fold,
                   PlateSpec,
                   PlateSpecError,
                   SCurve,
                   Twist,
                   reference_spec,
)

__all__ = ["PlateSpec", "PlateSpecError", "Flat", "CylindricalBend", "Fold", "Twist", "Dome",
           "Dent", "SCurve", "Plate", "build_plate", "reference_spec"]
