"""Sample configuration (plate, scene, render, sensor) from TOML files and CLI flags, and presets.

The command line's flags are checked and turned into configurations here, never in ``bench.cli``:
``sample_flags`` (a sample's flags), ``sensing`` and ``study`` (the sensing loop's and the studies'),
``sgbm_range`` (the SGBM search against a sample's rig), ``methods`` (the method names offered)."""
from platebench.bench.config.presets import *  # noqa: F401,F403
from platebench.bench.config.presets import __all__ as _presets
from platebench.bench.config.sample_config import *  # noqa: F401,F403
from platebench.bench.config.sample_config import __all__ as _config

__all__ = [*_config, *_presets]  # axes: ``platebench.bench.config.axes`` (parameter columns, sweep axes)
