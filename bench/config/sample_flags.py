"""A sample's configuration from the command line's sample flags (``--config``, ``--bend-deg``, ...,
``--camera``, ``--realism``, ``--realism-seed``; declared by ``bench.cli._args.add_sample_flags``), and
the checks a command makes of it before any work. Every refusal is a ``UserValueError`` naming the flag."""
from __future__ import annotations

from dataclasses import replace

from platebench.bench.config.presets import with_camera_preset, with_realism
from platebench.bench.config.sample_config import SampleConfig, with_overrides
from platebench.errors import UserValueError

__all__ = ["config_from_args", "realism_camera_at_width", "refuse_robot_errors", "sample_moves"]


def config_from_args(args, cfg: SampleConfig) -> SampleConfig:
    """The ``SampleConfig`` of an argparse namespace holding the sample flags: ``cfg`` (the caller's
    configuration, ``--config``'s file as ``bench.io.config_files.load_config`` reads it at the size asked
    for: this layer does not read files), then the camera or realism preset, then each flag given.
    Raises ``UserValueError`` when both ``--camera`` and ``--realism`` are given, or ``--realism-seed``
    is outside 0 to 2^31-1; the configuration's own checks raise theirs."""
    if getattr(args, "camera", None) and getattr(args, "realism", None):
        raise UserValueError("--camera and --realism both choose the camera: give one (a realism preset names its "
                             "camera)")
    if getattr(args, "camera", None):
        cfg = with_camera_preset(cfg, args.camera)
    if getattr(args, "realism", None):
        cfg = with_realism(cfg, args.realism)
    if getattr(args, "realism_seed", None) is not None:
        if not 0 <= args.realism_seed < 2 ** 31:
            raise UserValueError(f"--realism-seed = {args.realism_seed} is out of range: allowed 0 to 2^31-1")
        cfg = replace(cfg, realism=cfg.realism.with_seed(args.realism_seed))
    out = with_overrides(cfg, bend_deg=args.bend_deg, width=args.width, height=args.height, spp=args.spp,
                         seed=args.seed, variant=args.variant, distance_m=args.distance_m,
                         bend_direction=args.bend_direction, bend_axis_deg=args.bend_axis_deg, grid=args.grid)
    return realism_camera_at_width(cfg, out, args.width)


def realism_camera_at_width(cfg: SampleConfig, out: SampleConfig, width: int | None) -> SampleConfig:
    """``out`` (``cfg`` with its flags applied) with a realism camera's pixel focal lengths scaled by
    ``width`` over its own width: the same field of view (and pixel aspect, lens) sampled by fewer or
    more pixels. Unchanged without a realism camera or a width."""
    if width is None or cfg.realism.camera == "ideal" or cfg.scene.f_px is None:
        return out
    k = out.scene.width / cfg.scene.width
    fy = None if cfg.scene.fy_px is None else cfg.scene.fy_px * k
    return replace(out, scene=replace(out.scene, f_px=cfg.scene.f_px * k, fy_px=fy))


def refuse_robot_errors(cfg: SampleConfig, command: str, allow_estimates: bool = False) -> None:
    """Raise ``UserValueError`` when ``command`` would silently drop the realism's robot, hand/eye (or,
    unless ``allow_estimates``, estimated-intrinsics) errors: it places its cameras itself."""
    rz = cfg.realism
    dropped = [s for s in ("robot_repeatability", "robot_accuracy", "hand_eye") + (() if allow_estimates else
                                                                                   ("calibration",)) if rz.on(s)]
    if dropped:
        raise UserValueError(f"--realism {rz.name}: {command} does not model {', '.join(dropped)} (it places its "
                             f"cameras itself); the preset's camera alone: --camera {rz.camera}")


def sample_moves(cfg: SampleConfig) -> bool:
    """True when the sample's realism adds an acquisition step (a robot, or estimates)."""
    return not cfg.realism.is_ideal
