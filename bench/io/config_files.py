"""A sample configuration TOML file read into a ``SampleConfig`` (the layout: ``bench.config.sample_config``;
the form: ``bench.io.codecs.bench_records``)."""
from __future__ import annotations

from pathlib import Path

from platebench.bench.config.sample_config import IMAGE_SIZE_PX, ConfigError, SampleConfig, read_toml
from platebench.bench.io.codecs import decode

__all__ = ["load_config"]


def load_config(path: Path | None, width: int | None = None, height: int | None = None) -> SampleConfig:
    """Read a TOML sample configuration (None: the reference experiment). ``width``, ``height``: the
    image size asked for beside the file (``--width``, ``--height``); it replaces the file's before the
    scene is checked, so that the lens distortion is checked, and named in its error, at the size
    that will be rendered. A size out of range is left to ``with_overrides``, which refuses it.
    Raises ConfigError naming the file (and the key) for a file or table it cannot read."""
    if path is None:
        return SampleConfig()
    path = Path(path)
    d = read_toml(path, "configuration")
    asked = {k: v for k, v in (("width", width), ("height", height))
             if isinstance(v, int) and not isinstance(v, bool) and IMAGE_SIZE_PX[0] <= v <= IMAGE_SIZE_PX[1]}
    try:
        if asked and isinstance(d, dict) and isinstance(d.get("scene", {}), dict):
            scene = d.get("scene", {})
            file_size = {k: scene[k] for k in asked if k in scene}
            if file_size:  # the file's own values are checked too, though the flags replace them
                decode(SampleConfig, {**d, "scene": {**scene, **dict.fromkeys(asked, IMAGE_SIZE_PX[0]),
                                                     **file_size, "distortion": {}}})
            d = {**d, "scene": {**d.get("scene", {}), **asked}}
        return decode(SampleConfig, d)
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}") from None
