"""The SGBM peer's disparity search checked against a sample's rig before any render (``platebench
compare``): OpenCV runs a search only when ``width - (minDisparity + numDisparities) > blockSize // 2``
(numDisparities a positive multiple of 16, ``reconstruction.peers.sgbm.disparity_range``; blockSize
``reconstruction.peers.sgbm.BLOCK_SIZE``)."""
from __future__ import annotations

from platebench.errors import UserValueError

__all__ = ["check_sgbm_range"]


def check_sgbm_range(rig, depth_range_m: tuple[float, float] | None, method: str = "sgbm") -> None:
    """Raise ``UserValueError`` when the SGBM search for ``depth_range_m`` (nearest, farthest depth in
    metres; None: the rig's default range) cannot run on ``rig``'s images (a ``scenes.rig.StereoRig``),
    naming the method (``sgbm`` or ``sgbm-passive``), the range asked for and the nearest depth allowed."""
    from platebench.reconstruction.peers.sgbm import BLOCK_SIZE, default_depth_range, disparity_range  # noqa: PLC0415

    block = BLOCK_SIZE
    try:
        rng = depth_range_m if depth_range_m is not None else default_depth_range(rig)
        d_min, n_disp = disparity_range(rig, rng)
    except ValueError as e:
        raise UserValueError(f"{method}: {e}") from None
    width = rig.left.width
    end = width - block // 2 - 1  # the largest minDisparity + numDisparities OpenCV accepts
    if d_min + n_disp > end:
        fb = rig.left.f_px * rig.baseline_m
        what = (f"--min-depth-mm {depth_range_m[0] * 1e3:g} to --max-depth-mm {depth_range_m[1] * 1e3:g}"
                if depth_range_m is not None else f"the default depth range {rng[0] * 1e3:.1f}-{rng[1] * 1e3:.1f} mm")
        raise UserValueError(f"{method}: {what} asks for disparities {d_min} to {d_min + n_disp} px (numDisparities "
                             f"{n_disp}, a multiple of 16), beyond the {width} px wide images: allowed a search that "
                             f"ends by {end} px (minDisparity + numDisparities < width - blockSize/2), i.e. "
                             f"--min-depth-mm above about {fb / max(end - 16, 1) * 1e3:.1f} here")
