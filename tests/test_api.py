"""The facade: ``import platebench`` and the six functions README shows, on a small real render."""
from __future__ import annotations

import pytest

import platebench
from platebench.bench.config import SampleConfig, SceneParams
from platebench.evaluation.score import Score
from platebench.scenes.scene_spec import RenderSettings

pytestmark = pytest.mark.render


def test_render_reconstruct_score_in_memory_and_on_files(tmp_path):
    cfg = SampleConfig(scene=SceneParams(width=480, height=360), render=RenderSettings(spp=4))
    sample = platebench.render(cfg)
    rec = platebench.reconstruct(sample)
    score = platebench.score(sample, rec)
    assert isinstance(score, Score)
    assert score.points.count == 16 and score.paper_bound.met
    assert score.points.stats.depth.rms < 5e-4  # metres (0.13 mm measured at 480 x 360, spp 4)

    from platebench.bench.io.recon_files import image_checksums, write_reconstruction
    from platebench.bench.io.sample_files import write_sample
    sdir = write_sample(tmp_path / "s", sample)
    rdir = write_reconstruction(tmp_path / "r", platebench.reconstruct(sdir), sdir, image_checksums(sample.digital))
    on_files = platebench.score(sdir, rdir)
    assert on_files.points.count == 16
    assert on_files.points.stats.depth.rms == pytest.approx(score.points.stats.depth.rms, rel=1e-6)
    with pytest.raises(TypeError, match="both"):
        platebench.score(sdir, rec)


def test_render_refuses_what_is_not_a_config():
    with pytest.raises(TypeError, match="SampleConfig"):
        platebench.render(42)


def test_the_dataset_class_is_on_the_facade_and_loaded_lazily():
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-c", "import sys, platebench; a = 'trimesh' in sys.modules; "
                        "d = platebench.PlateBenchDataset; print(a, d.__name__)"], capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.split() == ["False", "PlateBenchDataset"], r.stderr
