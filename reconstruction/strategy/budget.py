"""The sensing loop's budget of cure poses: how many the planner plans within by default and how many
``sense --max-cures`` allows. Plain numbers, so that the command line shows and checks them without
loading the loop (``planner`` takes them from here; its module doc says how the default was measured)."""
from __future__ import annotations

MAX_CURE_VIEWS = 24  # cure poses the view budget leaves room for (measured: ``planner``'s module doc)
MAX_CURES_ALLOWED = 2 * MAX_CURE_VIEWS  # ``sense --max-cures`` at most (each cure is a render and a ray cast)
