"""``platebench evaluate --disparity/--depth/--points/--mesh F`` writes two files, ``F.score.json`` and the
error map ``F.error_map.npz`` beside it (``bench.io.error_map_files``): both follow the output rule
(``bench.io.outputs``) before any scoring, so an existing error map is refused without --overwrite, and
--overwrite replaces only an error map. The refusals come before the sample is read: no render here."""
from __future__ import annotations

import io
import zipfile

import numpy as np

from platebench.bench.cli.main import main


def _evaluate(capsys, tmp_path, *extra):
    sample = tmp_path / "sample"
    sample.mkdir(exist_ok=True)
    f = tmp_path / "d.pfm"
    f.write_bytes(b"Pf\n1 1\n-1\n" + np.zeros(1, "<f4").tobytes())
    code = main(["evaluate", str(sample), "--disparity", str(f), *extra])
    return code, capsys.readouterr().err


def test_an_existing_error_map_is_refused_without_overwrite(tmp_path, capsys):
    (tmp_path / "d.error_map.npz").write_bytes(b"kept")
    code, err = _evaluate(capsys, tmp_path)
    assert code == 2, err
    assert "d.error_map.npz: already exists (use --overwrite to replace it)" in err, err
    assert (tmp_path / "d.error_map.npz").read_bytes() == b"kept"
    assert not (tmp_path / "d.score.json").exists()


def test_overwrite_replaces_only_an_error_map(tmp_path, capsys):
    (tmp_path / "d.error_map.npz").write_bytes(b"not an error map")
    code, err = _evaluate(capsys, tmp_path, "--overwrite")
    assert code == 2, err
    assert "d.error_map.npz: is " in err and "not a PlateBench error map" in err, err
    buf = io.BytesIO()
    np.savez_compressed(buf, kind=np.array("disparity"), count=np.int64(0), median_m=np.float64("nan"),
                        rms_m=np.float64("nan"))
    (tmp_path / "d.error_map.npz").write_bytes(buf.getvalue())
    assert zipfile.is_zipfile(tmp_path / "d.error_map.npz")
    code, err = _evaluate(capsys, tmp_path, "--overwrite")
    assert "error map" not in err and "already exists" not in err, err  # the rule lets it through to the scoring
