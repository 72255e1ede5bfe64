"""The paper's pipeline on a sample: from memory (``RenderedSample``) or from a sample directory.

Reads only what the method may see (the four images, the stereo calibration, the projector's
feature rays and the pattern's feature table), never ground truth.
"""
from __future__ import annotations

from pathlib import Path

from platebench.bench.io.sample_files import load_inputs
from platebench.reconstruction.paper.pipeline import (
    PipelineOptions,
    Reconstruction,
    projector_feature_rays,
    reconstruct,
)
from platebench.reconstruction.paper.plate_region import ReconstructionError
from platebench.scenes.naming import IMAGE_NAMES

__all__ = ["PipelineOptions", "reconstruct_sample", "reconstruct_dir", "reconstruct_inputs", "name_the_file"]


def reconstruct_sample(sample, options: PipelineOptions | None = None) -> Reconstruction:
    """The pipeline on a ``RenderedSample`` (the calibration it was written with: the true rig, or under
    realism the rig the method is told) or a sample directory."""
    if isinstance(sample, (str, Path)):
        return reconstruct_dir(Path(sample), options)[0]
    scene = sample.scene
    rays = projector_feature_rays(scene.projector.camera, scene.projector.pattern)
    return reconstruct(sample.digital, sample.calibration_rig, rays, scene.projector.pattern,
                       options or PipelineOptions())


def reconstruct_dir(sample_dir: Path, options: PipelineOptions | None = None, calibration=None):
    """The pipeline on a written sample; ``calibration``: (rig, feature rays) estimated by
    ``platebench calibrate`` instead of the sample's calib.json. Returns (reconstruction, inputs).
    Image errors name the image file."""
    inputs = load_inputs(sample_dir)
    return reconstruct_inputs(inputs, sample_dir, options, calibration), inputs


def reconstruct_inputs(inputs, sample_dir: Path, options: PipelineOptions | None = None,
                       calibration=None) -> Reconstruction:
    """The pipeline on the inputs read from ``sample_dir`` (``bench.io.sample_files.load_inputs``);
    ``calibration`` as ``reconstruct_dir``'s. Image errors name the image file."""
    rig = inputs.calibration.rig
    rays = projector_feature_rays(inputs.calibration.projector_camera, inputs.pattern)
    if calibration is not None:
        rig, rays = calibration
    try:
        return reconstruct(inputs.images, rig, rays, inputs.pattern, options or PipelineOptions())
    except ReconstructionError as e:
        raise ReconstructionError(name_the_file(str(e), sample_dir)) from None


def name_the_file(message: str, sample_dir: Path) -> str:
    """Turn 'left_active: ...' into 'SAMPLE/images/left_active.png: ...'."""
    for name in IMAGE_NAMES:
        if message.startswith(name + ":"):
            return f"{Path(sample_dir) / 'images' / (name + '.png')}{message[len(name):]}"
    return message
