"""A toy peer method in one module: the recipe of docs/extending.md ("A peer method").

``constant_depth`` answers every pixel of the left view with the depth of the world origin (the point
the rig looks at), a plane facing the left camera. Registered with ``register_method`` it runs in the
calling process; declared as an entry point of ``platebench.methods`` (tests/test_recipe_method.py
installs one) it runs as a plug-in, in a process of its own.
"""
from __future__ import annotations

import numpy as np

from platebench.reconstruction.methods import Depth, MethodInputs, register_method


@register_method("toy", "a plane at the depth of the world origin (toy)", "depth", images=("left_passive",))
def constant_depth(inputs: MethodInputs) -> Depth:
    """A plane at the depth of the world origin (toy)."""
    z0 = float(inputs.rig.left.depth(np.zeros((1, 3)))[0])  # metres along the left optical axis
    h, w = inputs.images["left_passive"].shape
    return Depth(np.full((h, w), z0), metrics={"plane_depth_mm": z0 * 1e3}, notes=("one plane, no matching",))
