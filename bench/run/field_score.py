"""Another program's output file scored against a sample's exact ground truth (``platebench evaluate``
with ``--disparity``, ``--depth``, ``--points`` or ``--mesh``): read by its kind
(``bench.io.method_outputs``), scored with the metrics of that kind (``evaluation.field_scores``) and
checked for plausibility (``evaluation.plausibility``: a hint when the errors lie orders of magnitude
beyond the scene). Maps are the left view at the sample's resolution; points and meshes are world
coordinates in metres."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from platebench.evaluation.field_scores import COVERAGE_RADIUS_M, OUTLIER_M

__all__ = ["KINDS", "OUTLIER_M", "COVERAGE_RADIUS_M", "FileScore", "score_file"]

KINDS = ("disparity", "depth", "points", "mesh")  # the output kinds a file is read as


@dataclass(frozen=True)
class FileScore:
    """A scored file: its score (``evaluation.field_scores``: ``DisparityScore``, ``DepthScore``,
    ``PointCloudScore`` or ``MeshScore``), the plausibility hints, the score JSON (units in every key) and
    its error map (``bench.io.error_map_files.StoredErrorMap``)."""

    score: object
    hints: tuple[str, ...]
    document: dict
    error_map: object = None


def _read(kind: str, path: Path, disparity_scale: float | None):
    from platebench.bench.io.method_outputs import (  # noqa: PLC0415
        read_depth,
        read_disparity,
        read_mesh,
        read_points,
    )
    from platebench.bench.run.plugins import Depth, Disparity, Mesh, Points  # noqa: PLC0415

    if kind == "disparity":
        return Disparity(read_disparity(path, disparity_scale))
    if kind == "depth":
        return Depth(read_depth(path))
    if kind == "points":
        return Points(read_points(path))
    return Mesh(read_mesh(path))


def score_file(kind: str, path: Path, sample_dir: Path, name: str, disparity_scale: float | None = None,
               outlier_m: float = OUTLIER_M, coverage_radius_m: float = COVERAGE_RADIUS_M) -> FileScore:
    """Score the file ``path`` of ``kind`` (``KINDS``) against ``sample_dir``'s ground truth, as method
    ``name``. ``disparity_scale``: a 16-bit PNG disparity's px = value / scale; ``outlier_m`` and
    ``coverage_radius_m`` (metres): the point-cloud metrics' thresholds. A damaged file raises its
    reader's error."""
    from platebench.bench.io.field_truth import load_field_truth  # noqa: PLC0415
    from platebench.bench.io.error_map_files import StoredErrorMap  # noqa: PLC0415
    from platebench.bench.run.plugins import score_document, score_output  # noqa: PLC0415
    from platebench.evaluation.error_maps import output_error_map  # noqa: PLC0415
    from platebench.evaluation.field_scores import score_point_cloud  # noqa: PLC0415
    from platebench.evaluation.plausibility import plausibility_hints  # noqa: PLC0415

    truth = load_field_truth(sample_dir)
    output = _read(kind, path, disparity_scale)
    what = f"{path}"
    if kind == "points":
        score = score_point_cloud(output.points, truth, what=what, outlier_m=outlier_m,
                                  coverage_radius_m=coverage_radius_m)
    else:
        score = score_output(output, truth, what)
    hints = tuple(plausibility_hints(kind, getattr(output, kind), truth))
    doc = score_document(name, kind, score, sample_dir)
    doc["input"] = str(path)
    doc["hints"] = list(hints)  # plausibility: is the file what its flag says?
    error_map = StoredErrorMap.of(kind, output_error_map(kind, getattr(output, kind), truth))
    return FileScore(score, hints, doc, error_map)
