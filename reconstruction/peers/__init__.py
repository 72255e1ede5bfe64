"""The built-in peer methods: each module registers its methods in ``reconstruction.methods.METHODS``
with the ``register_method`` decorator, and importing this package imports every module in it, so a
new peer is one module here (docs/extending.md, "A peer method")."""
from __future__ import annotations

import importlib
import pkgutil

for _module in pkgutil.iter_modules(__path__):
    importlib.import_module(f"{__name__}.{_module.name}")
