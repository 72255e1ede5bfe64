"""The paper's corner (passive_boundary._corner): the meeting point of a side edge u(v) and a
top/bottom edge v(u), checked against analytic lines; edges whose fits do not meet are an error
(the general outline stereo takes over), never a NaN corner."""
from __future__ import annotations

import numpy as np
import pytest

from platebench.reconstruction.paper.passive_boundary import _corner
from platebench.reconstruction.paper.plate_region import ReconstructionError


def test_corner_of_two_straight_edges_is_their_intersection():
    rows = np.arange(100, 140, dtype=float)  # left side: u = 200 + 0.1 (v - 100)
    side = (rows, 200 + 0.1 * (rows - 100))
    cols = np.arange(200, 240, dtype=float)  # top: v = 98 + 0.05 (u - 200)
    top = (cols, 98 + 0.05 * (cols - 200))
    u, v = _corner(side, top, near_start_side=True, near_start_tb=True)
    # solve u = 200 + 0.1 (v - 100), v = 98 + 0.05 (u - 200)
    v_true = (98 + 0.05 * (0.1 * -100)) / (1 - 0.005)
    assert v == pytest.approx(v_true, abs=1e-6) and u == pytest.approx(200 + 0.1 * (v_true - 100), abs=1e-6)


def test_edges_whose_fits_do_not_meet_raise_instead_of_a_nan_corner():
    rows = np.arange(100, 140, dtype=float)
    cols = np.arange(200, 240, dtype=float)
    for a in (5.0, 0.5):  # steep parabolas: the fixed point runs away (5) or cycles (0.5)
        side = (rows, 200 + a * (rows - 100) ** 2)
        top = (cols, 98 + a * (cols - 200) ** 2)
        with pytest.raises(ReconstructionError, match="corner not found"):
            _corner(side, top, near_start_side=True, near_start_tb=True)
