"""Is a copy of the benchmark the published split? Checksums recorded at build, compared at verify.

A built copy (``platebench benchmark build``) is a sweep dataset whose spec is the split's definition.
``verify_benchmark`` tells whether it is the split, sample by sample:

1. **Whole and intact**: the dataset was made from this split's definition (its sha256), every one of
   the split's samples is there, and every sample's files match the checksums recorded when they
   were written (``bench.io.verify``). A copy that fails here is never scored.
2. **Ground truth byte for byte** against the checksums shipped with the package
   (``splits/<name>.sha256.json``): the truth files of every sample (``TRUTH_FILES``: the exact maps of
   ``gt/``, the plate's mesh and outline).
3. **Images**: byte for byte when the copy was rendered with the renderer variant the checksums were
   recorded with; on another variant (another device's arithmetic), each image's block means
   (``BLOCKS`` blocks, as fractions of the image's full scale) must lie within
   ``tol.benchmark_block_frac`` of the recorded ones, and the largest difference is printed.

Where no checksums are shipped for a split (a split file of one's own), only step 1 is made, and the
report says so.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from platebench.bench.benchmark.split import Split, split_checksums_path
from platebench.bench.io.images import DatasetError
from platebench.bench.io.layout import SAMPLE, SAMPLES
from platebench.bench.io.outputs import file_sha256
from platebench.errors import UserValueError
from platebench.tolerances import tol

__all__ = ["CHECKSUMS_FORMAT", "TRUTH_FILES", "BLOCKS", "VerifyReport", "checksums_of", "verify_benchmark",
           "check_built", "NotTheSplitError"]

CHECKSUMS_FORMAT = "platebench-benchmark-checksums"
TRUTH_FILES = ("gt/", "plate.ply", "boundary.npy")  # a folder (ending in /) or a file of a sample
BLOCKS = (6, 8)  # (rows, columns) of the blocks whose mean DN describes an image across variants


class NotTheSplitError(UserValueError):
    """A dataset is not a whole, intact build of the split (one line: what is wrong)."""


@dataclass(frozen=True)
class VerifyReport:
    """What ``verify_benchmark`` found. ``is_split``: every check passed (the copy is the split)."""

    split: str
    samples: int
    checked_truth: bool  # checksums were shipped for this split
    truth_differ: tuple[str, ...] = ()  # "sample/file" of truth files that differ
    images_bytes_equal: int = 0  # images equal byte for byte
    images_within_noise: int = 0  # images within the block-mean limit (another variant)
    images_differ: tuple[str, ...] = ()  # "sample/file" beyond the limit
    max_block_frac: float = 0.0  # the largest block-mean difference seen (another variant), of full scale
    variant: str = ""  # the copy's renderer variant
    recorded_variant: str = ""  # the variant the checksums were recorded with
    notes: tuple[str, ...] = field(default=())

    @property
    def is_split(self) -> bool:
        return self.checked_truth and not self.truth_differ and not self.images_differ


def _truth_files(sample_dir: Path) -> list[str]:
    out = []
    for t in TRUTH_FILES:
        if t.endswith("/"):
            d = sample_dir / t
            out += sorted(f"{t}{p.name}" for p in d.iterdir() if p.is_file()) if d.is_dir() else []
        elif (sample_dir / t).is_file():
            out.append(t)
    return out


def _image_files(sample_dir: Path) -> list[str]:
    d = sample_dir / "images"
    return sorted(f"images/{p.name}" for p in d.iterdir() if p.suffix == ".png") if d.is_dir() else []


def block_means(png: Path) -> np.ndarray:
    """(BLOCKS) float64 mean of an image's blocks (the image cut into BLOCKS[0] x BLOCKS[1] parts), as a
    fraction of its full scale (255 for 8-bit, 65535 for 16-bit images)."""
    from platebench.bench.io.images import read_png  # noqa: PLC0415
    raw = np.asarray(read_png(png))
    img = raw.astype(np.float64) / float(np.iinfo(raw.dtype).max)
    rows = np.array_split(np.arange(img.shape[0]), BLOCKS[0])
    cols = np.array_split(np.arange(img.shape[1]), BLOCKS[1])
    return np.array([[img[np.ix_(r, c)].mean() for c in cols] for r in rows])


def _variant(sample_dir: Path) -> str:
    try:
        return str(json.loads((sample_dir / "sample.json").read_text()).get("variant", ""))
    except (OSError, ValueError):
        return ""


def check_built(dataset: Path, split: Split) -> dict:
    """Step 1 of the module doc: raise ``NotTheSplitError`` unless ``dataset`` is a whole, intact build
    of ``split``; returns its manifest."""
    from platebench.bench.io.verify import dataset_manifest, sample_checksums, verify_sample  # noqa: PLC0415
    dataset = Path(dataset)
    if not dataset.is_dir():
        raise NotTheSplitError(f"{dataset}: not a folder: build the benchmark first (platebench benchmark build)")
    manifest = dataset_manifest(dataset)
    if manifest is None:
        raise NotTheSplitError(f"{dataset}: no sweep manifest: not a built benchmark")
    text = manifest.get("spec_text") or ""
    if hashlib.sha256(text.encode()).hexdigest() != split.sha256:
        raise NotTheSplitError(f"{dataset} was not built from split {split.name} (its definition's sha256 "
                               f"{split.sha256[:12]} is not the dataset's)")
    entries = {s.get("id"): s for s in manifest.get("samples") or [] if isinstance(s, dict)}
    missing = [s.sample_id for s in split.samples if not (dataset / SAMPLES / s.sample_id / SAMPLE / "sample.json")
               .is_file() or s.sample_id not in entries]
    if missing:
        raise NotTheSplitError(f"{dataset}: {len(missing)} of the split's {len(split.samples)} samples are not built "
                               f"({missing[0]}, ...): finish it with platebench benchmark build --resume")
    for s in split.samples:
        d = dataset / SAMPLES / s.sample_id / SAMPLE
        try:
            verify_sample(d, sample_checksums(d, manifest), then="the benchmark copy is not intact")
        except DatasetError as e:
            raise NotTheSplitError(str(e)) from None
    return manifest


def checksums_of(dataset: Path, split: Split) -> dict:
    """The checksums document of a built ``dataset`` (what ``splits/<name>.sha256.json`` holds)."""
    dataset = Path(dataset)
    samples, variants = {}, set()
    for s in split.samples:
        d = dataset / SAMPLES / s.sample_id / SAMPLE
        variants.add(_variant(d))
        samples[s.sample_id] = {
            "truth": {f: file_sha256(d / f) for f in _truth_files(d)},
            "images": {f: file_sha256(d / f) for f in _image_files(d)},
            "image_blocks": {f: np.round(block_means(d / f), 5).tolist() for f in _image_files(d)},
        }
    if len(variants) != 1:
        raise UserValueError(f"the samples were rendered with {len(variants)} renderer variants: allowed one")
    return {"format": CHECKSUMS_FORMAT, "split": split.name, "split_sha256": split.sha256,
            "variant": variants.pop(), "blocks": list(BLOCKS), "samples": samples}


def _recorded(split: Split) -> dict | None:
    p = split_checksums_path(split)
    if not p.is_file():
        return None
    doc = json.loads(p.read_text())
    if doc.get("format") != CHECKSUMS_FORMAT or doc.get("split_sha256") != split.sha256:
        raise UserValueError(f"{p.name}: not the checksums of split {split.name} (its definition changed: record "
                             "them again)")
    return doc


def verify_benchmark(dataset: Path, split: Split, progress=None) -> VerifyReport:
    """The three steps of the module doc; raises ``NotTheSplitError`` at step 1."""
    check_built(dataset, split)
    recorded = _recorded(split)
    dataset = Path(dataset)
    variant = _variant(dataset / SAMPLES / split.samples[0].sample_id / SAMPLE)
    if recorded is None:
        return VerifyReport(split.name, len(split.samples), False, variant=variant,
                            notes=(f"no checksums are shipped for split {split.name}: the copy is whole and intact, "
                                   "its ground truth and images were not compared",))
    same_variant = variant == recorded["variant"]
    truth_differ, images_differ = [], []
    bytes_equal = within = 0
    worst = 0.0
    for s in split.samples:
        d = dataset / SAMPLES / s.sample_id / SAMPLE
        rec = recorded["samples"].get(s.sample_id) or {}
        have = set(_truth_files(d))
        for f in sorted(have | set(rec.get("truth", {}))):
            if f not in have or f not in rec.get("truth", {}) or file_sha256(d / f) != rec["truth"][f]:
                truth_differ.append(f"{s.sample_id}/{f}")
        for f in _image_files(d):
            if rec.get("images", {}).get(f) == file_sha256(d / f):
                bytes_equal += 1
                continue
            ref = rec.get("image_blocks", {}).get(f)
            if same_variant or ref is None:
                images_differ.append(f"{s.sample_id}/{f}")
                continue
            diff = float(np.max(np.abs(block_means(d / f) - np.asarray(ref))))
            worst = max(worst, diff)
            if diff <= tol.benchmark_block_frac:
                within += 1
            else:
                images_differ.append(f"{s.sample_id}/{f}")
        if progress:
            progress()
    return VerifyReport(split.name, len(split.samples), True, tuple(truth_differ), bytes_equal, within,
                        tuple(images_differ), worst, variant, recorded["variant"])
