"""``PlateBenchDataset``: a PlateBench dataset as stereo pairs with exact ground truth, in numpy.

::

    from platebench.bench.io.dataset_reader import PlateBenchDataset
    ds = PlateBenchDataset("ds", images="active", shift="auto")
    for pair in ds:                      # or ds[i], len(ds)
        pair.left, pair.right            # (H, W) uint8/uint16 camera images
        pair.disparity                   # (H, W) float32 left disparity, px; inf = unknown
        pair.nonocc                      # (H, W) bool: also seen by the right camera
        pair.calib.depth_m(pair.disparity)   # z-depth (metres) back from the disparity

No torch needed; for a ``torch.utils.data.DataLoader`` return ``pair.to_dict()`` (numpy arrays
and numbers only) from a thin wrapper, or pass ``collate_fn=list``.

``root`` is a sample directory (``platebench render``), a sweep dataset (``platebench sweep``:
its ``samples/<id>/sample``) or any folder holding sample directories; samples are found by their
``sample.json`` and ordered by path. Each item is read from disk when asked for (nothing cached).

Nothing is read on trust (``bench.io.verify``): a symbolic link anywhere under ``root`` is refused
when the dataset is opened, as is a sample the sweep manifest lists as done whose folder is gone;
each item's files are checked against the checksums recorded when they were written (the sweep
manifest, the sample's result.json or its stamp) and its images against ``sample.json``'s pixel
checksums before they are used (``check()`` checks every sample at once). A file changed,
truncated or swapped with another sample's is refused, naming the sample.

Ground truth is derived from the sample's own maps when read (``evaluation.stereo_truth``),
nothing is added to the sample layout: the left disparity f B / Z - doffs, the right view's
disparity from the right depth, the non-occlusion mask (a left/right consistency check).

Shift (``shift``): disparities of the bench's rigs are large (about 500 px at 1280 x 960, f 2000
px, B 0.1 m, Z 0.4 m: outside what learned stereo handles). A shift s crops the left image to
columns [s, W) and the right one to [0, W - s): both W - s wide, every disparity becomes d - s,
and ``doffs`` grows by s, so Z = f B / (d + doffs) still holds (``calib``). ``shift="auto"``
takes, per sample, s = floor(min true disparity - ``min_disparity_px``) (default 16 px): the
plate's disparities then start at 16 to 17 px; ``shift=0`` (default) keeps the full images. Pixels
off the plate (the ground) have no true disparity; after a shift theirs may be negative.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from platebench.bench.files import require_dir
from platebench.bench.io.field_truth import load_field_truth
from platebench.bench.io.images import DatasetError, read_png
from platebench.bench.io.layout import SAMPLE, SAMPLES
from platebench.bench.io.middlebury import MiddleburyCalib
from platebench.bench.io.sample_files import read_json
from platebench.bench.io.verify import dataset_manifest, refuse_links, sample_checksums, verify_sample
from platebench.scenes.naming import LIGHTINGS

__all__ = ["PlateBenchDataset", "StereoPair", "find_samples", "MIN_DISPARITY_PX"]

MIN_DISPARITY_PX = 16


@dataclass(frozen=True)
class StereoPair:
    """One sample as a rectified stereo pair (left view is the reference), shifted by ``shift_px``.

    ``left``/``right``: (H, W) camera images (uint8/uint16 DN); ``disparity``/``disparity_right``:
    (H, W) float32 px, +inf unknown (Middlebury's disp0/disp1: left pixel u matches right u - d, right
    pixel u matches left u + d); ``mask``: (H, W) bool, true disparity known (the plate);
    ``nonocc``: (H, W) bool, known and seen by both cameras; ``depth``: (H, W) float32 left z-depth,
    metres, +inf unknown; ``calib``: the pair's Middlebury calibration (doffs includes the shift)."""

    sample_id: str
    sample_dir: Path
    left: np.ndarray
    right: np.ndarray
    disparity: np.ndarray
    disparity_right: np.ndarray
    mask: np.ndarray
    nonocc: np.ndarray
    depth: np.ndarray
    calib: MiddleburyCalib
    shift_px: int
    images: str

    def to_dict(self) -> dict:
        """Numpy arrays and plain numbers (for data loaders); calibration as f_px, baseline_m, doffs_px."""
        return {"sample_id": self.sample_id, "left": self.left, "right": self.right, "disparity": self.disparity,
                "disparity_right": self.disparity_right, "mask": self.mask, "nonocc": self.nonocc,
                "depth": self.depth, "f_px": self.calib.f_px, "baseline_m": self.calib.baseline_mm * 1e-3,
                "doffs_px": self.calib.doffs, "shift_px": self.shift_px}


def _is_sample(d: Path) -> bool:
    return (d / "sample.json").is_file() and (d / "images").is_dir() and not any(
        p.startswith((".tmp-", ".old-")) for p in d.parts)


def find_samples(root: Path) -> list[Path]:
    """Sample directories under ``root`` (``root`` itself if it is one), sorted by path."""
    root = require_dir(Path(root), "dataset directory", DatasetError)
    refuse_links(root)
    if _is_sample(root):
        return [root]
    return sorted(p.parent for p in root.rglob("sample.json") if _is_sample(p.parent))


def _check_pixels(d: Path, meta: dict, images: dict) -> None:
    """Each image's pixels against the sha256 ``sample.json`` recorded for them when rendered."""
    recorded = meta.get("images") if isinstance(meta.get("images"), dict) else {}
    for name, img in images.items():
        want = recorded.get(name)
        if want is not None and hashlib.sha256(np.ascontiguousarray(img).tobytes()).hexdigest() != want:
            raise DatasetError(f"{d / 'images' / (name + '.png')}: its pixels differ from those sample.json records "
                               f"for sample {d.name} (changed or swapped with another sample's): refusing the sample")


def _sample_id(root: Path, d: Path) -> str:
    if d == root:
        return d.name
    parts = [p for p in d.relative_to(root).parts if p not in ("samples", "sample")]
    return "-".join(parts) or d.name


def _shift_for(disparity: np.ndarray, min_disparity_px: float) -> int:
    known = disparity[np.isfinite(disparity)]
    if known.size == 0:
        return 0
    return max(0, int(math.floor(known.min() - min_disparity_px)))


class PlateBenchDataset:
    """The samples under ``root`` as ``StereoPair`` items (module doc).

    Args:
        root: a sample directory, a sweep dataset or a folder of samples.
        images: "passive" (plate under the overhead light) or "active" (the projected square grid).
        shift: 0 (full images), a whole number of px, or "auto" (module doc).
        min_disparity_px: with shift="auto", the smallest true disparity after the shift.
    """

    def __init__(self, root, *, images: str = "passive", shift: int | str = 0,
                 min_disparity_px: float = MIN_DISPARITY_PX):
        if images not in LIGHTINGS:
            raise DatasetError(f"images = {images!r} is not allowed: choose {' or '.join(LIGHTINGS)}")
        if not (shift == "auto" or (isinstance(shift, (int, np.integer)) and not isinstance(shift, bool)
                                    and shift >= 0)):
            raise DatasetError(f"shift = {shift!r} is not allowed: a whole number of px >= 0, or 'auto'")
        if not (math.isfinite(min_disparity_px) and min_disparity_px >= 0):
            raise DatasetError(f"min_disparity_px = {min_disparity_px} is out of range: allowed >= 0")
        self.root = Path(root)
        self.images = images
        self.shift = shift
        self.min_disparity_px = float(min_disparity_px)
        self.sample_dirs = find_samples(self.root)
        if not self.sample_dirs:
            raise DatasetError(f"{self.root}: holds no PlateBench sample (no sample.json with images/)")
        self._manifest = dataset_manifest(self.root)
        found = {d.resolve() for d in self.sample_dirs}
        for e in (self._manifest or {}).get("samples", []):
            d = self.root / SAMPLES / str(e.get("id")) / SAMPLE if isinstance(e, dict) else None
            if d is not None and e.get("status") == "ok" and d.resolve() not in found:
                raise DatasetError(f"{d}: sample {e.get('id')} is done in {self.root / 'manifest.json'} but its folder "
                                   "is missing or holds no sample: refusing the dataset")

    def _verify(self, d: Path) -> None:
        """``d``'s files that an item is made of against their recorded checksums (``bench.io.verify``):
        every recorded file but the camera images of the other lighting and the linear-radiance EXRs."""
        checks = sample_checksums(d, self._manifest)
        if checks is not None:
            keep = {f"images/left_{self.images}.png", f"images/right_{self.images}.png"}
            verify_sample(d, checks, [n for n in checks.files if not n.startswith("images/") or n in keep])

    def check(self) -> None:
        """Check every sample's files against their recorded checksums (module doc), before any is read."""
        for d in self.sample_dirs:
            self._verify(d)

    def __len__(self) -> int:
        return len(self.sample_dirs)

    def __iter__(self):
        for i in range(len(self)):
            yield self[i]

    def sample_id(self, i: int) -> str:
        return _sample_id(self.root, self.sample_dirs[i])

    def __getitem__(self, i: int) -> StereoPair:
        if not isinstance(i, (int, np.integer)) or isinstance(i, bool):
            raise TypeError(f"PlateBenchDataset index must be an int, got {type(i).__name__}")
        n = len(self)
        if not -n <= i < n:
            raise IndexError(f"index {i} is out of range: the dataset has {n} samples")
        d = self.sample_dirs[int(i) % n]
        self._verify(d)
        truth = load_field_truth(d)
        left = read_png(d / "images" / f"left_{self.images}.png")
        right = read_png(d / "images" / f"right_{self.images}.png")
        _check_pixels(d, read_json(d / "sample.json"), {f"left_{self.images}": left, f"right_{self.images}": right})
        H, W = truth.shape
        if left.shape != (H, W) or right.shape != (H, W):
            raise DatasetError(f"{d}: images are {left.shape[1]}x{left.shape[0]}, ground truth {W}x{H}")
        s = _shift_for(truth.disparity, self.min_disparity_px) if self.shift == "auto" else int(self.shift)
        if s >= W:
            raise DatasetError(f"{d}: shift {s} px leaves no column of a {W} px wide image")
        w = W - s
        disp = truth.disparity[:, s:] - s  # left columns [s, W)
        disp1 = truth.disparity_right[:, :w] - s  # right columns [0, W - s)
        # A left pixel's match must fall inside the right crop: u - d' in [-0.5, w - 0.5].
        u = np.arange(w)[None, :]
        with np.errstate(invalid="ignore"):
            inside = (u - disp >= -0.5) & (u - disp <= w - 0.5)
        nonocc = truth.nonocc[:, s:] & inside
        calib = MiddleburyCalib.for_pair(truth.pair, disp, x0_left=s, x0_right=0, width=w, height=H)
        return StereoPair(self.sample_id(int(i) % n), d, left[:, s:], right[:, :w], disp.astype(np.float32),
                          disp1.astype(np.float32), truth.mask[:, s:].copy(), nonocc,
                          truth.depth[:, s:].astype(np.float32), calib, s, self.images)
