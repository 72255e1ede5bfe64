"""The method names the command line offers and checks (``compare --methods``): the registry's
(``reconstruction.methods``), every method that runs in the calling process in the registry's order,
and the set ``compare`` runs by default."""
from __future__ import annotations

from platebench.reconstruction import peers as _builtin_peers  # noqa: F401  (importing it registers them)
from platebench.reconstruction.methods import builtin_names, default_names

__all__ = ["builtin_names", "default_names"]
