"""One colour per method, the same in every plot that shows it.

``method_colours(methods)`` maps each name to a colour (``#rrggbb``), the names taken in sorted
order whatever order they come in: tab10 up to 10 methods, tab20 up to 20, else hues around the
circle. A report builds one such map over every method it shows (``bench.report.page.Page``) and
hands it to each plot, so that a method keeps its colour from figure to figure and section to
section; a plot drawn without a map makes one over the methods it shows.
"""
from __future__ import annotations

from typing import Iterable

__all__ = ["method_colours", "colour_of"]

_FALLBACK = "#7f7f7f"  # a method missing from the map handed to a plot (grey)


def method_colours(methods: Iterable[str]) -> dict[str, str]:
    """{method: "#rrggbb"} over the distinct names of ``methods``, coloured in sorted order (module doc)."""
    from matplotlib import colormaps  # noqa: PLC0415
    from matplotlib.colors import to_hex  # noqa: PLC0415
    names = sorted({str(m) for m in methods})
    n = len(names)
    if n <= 10:
        cs = [colormaps["tab10"](i) for i in range(n)]
    elif n <= 20:
        cs = [colormaps["tab20"](i) for i in range(n)]
    else:
        cs = [colormaps["hsv"](i / n) for i in range(n)]
    return {m: to_hex(c) for m, c in zip(names, cs)}


def colour_of(colours: dict | None, method, methods: Iterable[str] = ()) -> str:
    """The colour of ``method``: from ``colours`` when given (grey for a name it lacks), else from
    ``method_colours(methods)``."""
    table = colours if colours is not None else method_colours(methods)
    return table.get(str(method), _FALLBACK)
