"""The sensing loop's budget of cure poses: how many the planner plans within by default and how many
``sense --max-cures`` allows. Plain numbers, so that the command line shows and checks them without
loading the loop (``planner`` takes them from here; docs/findings/design-record.md, "The cure budget",
says how the default was chosen)."""
from __future__ import annotations

MAX_CURE_VIEWS = 24  # cure poses the view budget leaves room for
MAX_CURES_ALLOWED = 2 * MAX_CURE_VIEWS  # ``sense --max-cures`` at most (each cure is a render and a ray cast)
# On a real rig whose poses disagree by more than the confirmation distance (its hand/eye residuals), a
# loop whose verification views and this many cures have confirmed no outline point by a second pose
# stops: its cures are planned as if the poses were where they were commanded, and when not one pair of
# poses agrees on an edge (a rig's poses centimetres off), more poses planned alike confirm nothing
# either (``loop.cure_stage``). Never on the ideal bench, where a curl's first cures may confirm nothing
# and later ones close the loop. A quarter of the budget.
FRUITLESS_CURES = MAX_CURE_VIEWS // 4
