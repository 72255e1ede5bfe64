"""Readers verify (bench/io/verify.py, bench/io/images.py, bench/files.py): a dataset's files are what
its records say, nothing is followed out of it, sizes come from file headers before anything is
allocated, and only regular files are read. The datasets are copies of one small real render
(``small_sample_dir``), laid out as ``platebench sweep`` lays them, with the manifest's checksums."""
from __future__ import annotations

import base64

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import record_tables

from platebench.bench.cli.main import main
from platebench.bench.io.dataset_reader import PlateBenchDataset
from platebench.bench.io.images import DatasetError, check_ply, exr_size, load_npy, read_pfm, read_png, write_pfm, write_png
from platebench.bench.io.method_outputs import read_disparity, read_points
from platebench.bench.io.outputs import STAMP
from platebench.bench.report.thumbs import thumbnail_png
from tools.faults.bad_inputs_outputs import (
    _PLY_HUGE,
    _PLY_LYING,
    _exr_declaring,
    _npy_declaring,
    _png_declaring,
)

pytestmark = pytest.mark.render
REPO = Path(__file__).resolve().parents[1]


def sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def files_of(d: Path) -> dict:
    return {p.relative_to(d).as_posix(): sha(p) for p in sorted(d.rglob("*")) if p.is_file()}


def make_dataset(root: Path, sample: Path) -> Path:
    """Two samples as a sweep lays them out (samples/<id>/sample, manifest with every file's checksum,
    results.csv): 0000 the render, 0001 the render with its left images and disparity changed, so
    that the two differ where a swap would show."""
    samples = []
    for i in range(2):
        d = root / "samples" / f"{i:04d}" / "sample"
        shutil.copytree(sample, d)
        (d / STAMP).unlink()
        if i == 1:
            shutil.copy2(d / "images" / "right_passive.png", d / "images" / "left_passive.png")
            shutil.copy2(d / "images" / "right_active.png", d / "images" / "left_active.png")
            disp = read_pfm(d / "gt" / "disp0GT.pfm")
            disp[np.isfinite(disp)] += 2e-4  # bytes that differ, within the truth files' agreement (tol)
            write_pfm(d / "gt" / "disp0GT.pfm", disp)
            meta = json.loads((d / "sample.json").read_text())
            meta["images"] = {}  # its pixels differ from the render's own record now
            (d / "sample.json").write_text(json.dumps(meta))
        samples.append({"id": f"{i:04d}", "index": i, "status": "ok",
                        "files_sha256": {f"sample/{k}": v for k, v in files_of(d).items()}})
    (root / "manifest.json").write_text(json.dumps({"format": "platebench-sweep", "version": 1, "state": "complete",
                                                    "samples": samples}))
    (root / "results.csv").write_text("sample_id,index,method,status\n0000,0,paper,ok\n0001,1,paper,ok\n")
    record_tables(root)
    return root


def export(capsys, *args) -> tuple[int, str]:
    code = main(["export", *map(str, args)])
    return code, capsys.readouterr().err


def swap(a: Path, b: Path) -> None:
    tmp = a.with_name(a.name + ".swap")
    os.replace(a, tmp)
    os.replace(b, a)
    os.replace(tmp, b)


@pytest.mark.parametrize("rel", ["images/left_passive.png", "gt/disp0GT.pfm"])
def test_files_swapped_between_samples_are_refused_naming_the_sample(small_sample_dir, tmp_path, capsys, rel):
    ds = make_dataset(tmp_path / "ds", small_sample_dir)
    code, err = export(capsys, ds, "--format", "middlebury", "--out", tmp_path / "mb")
    assert code == 0, err  # the dataset as written exports
    swap(ds / "samples" / "0000" / "sample" / rel, ds / "samples" / "0001" / "sample" / rel)
    code, err = export(capsys, ds, "--format", "middlebury", "--out", tmp_path / "mb2")
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "sample 0000" in lines[0] and rel in lines[0] and "checksum" in lines[0]
    assert not (tmp_path / "mb2").exists()
    with pytest.raises(DatasetError, match="sample 0000"):
        PlateBenchDataset(ds)[0]
    with pytest.raises(DatasetError, match="sample 0001"):
        PlateBenchDataset(ds)[1]


def test_a_render_changed_after_the_fact_is_refused_by_its_stamp_and_its_pixels(small_sample_dir, tmp_path):
    d = tmp_path / "s"
    shutil.copytree(small_sample_dir, d)
    assert PlateBenchDataset(d)[0].left.shape == (360, 480)
    shutil.copy2(d / "images" / "right_passive.png", d / "images" / "left_passive.png")
    with pytest.raises(DatasetError, match=r"left_passive.png: differs from the checksum .*platebench-output.json"):
        PlateBenchDataset(d)[0]
    (d / STAMP).unlink()  # no stamp: sample.json's record of the pixels still tells
    with pytest.raises(DatasetError, match="left_passive.png: its pixels differ from those sample.json records"):
        PlateBenchDataset(d)[0]


def test_links_in_a_dataset_are_refused(small_sample_dir, tmp_path, capsys):
    ds = make_dataset(tmp_path / "ds", small_sample_dir)
    moved = tmp_path / "elsewhere"
    shutil.move(ds / "samples" / "0001", moved)
    os.symlink(moved, ds / "samples" / "0001")
    code, err = export(capsys, ds, "--format", "middlebury", "--out", tmp_path / "mb")
    assert code == 2 and err.count("\n") == 1 and "samples/0001: is a symbolic link inside the dataset" in err
    with pytest.raises(DatasetError, match="symbolic link"):
        PlateBenchDataset(ds)
    (ds / "samples" / "0001").unlink()  # the sample is gone, the manifest says it is done
    with pytest.raises(DatasetError, match="sample 0001 is done in .*manifest.json but its folder is missing"):
        PlateBenchDataset(ds)
    assert not (tmp_path / "mb").exists()


def test_report_warns_of_what_it_leaves_out_and_never_follows_a_link_out(small_sample_dir, tmp_path, capsys):
    ds = make_dataset(tmp_path / "ds", small_sample_dir)
    secret = tmp_path / "secret.png"  # a picture outside the dataset, like none of the sample's own
    write_png(secret, 255 - read_png(small_sample_dir / "images" / "left_active.png"))
    img = ds / "samples" / "0000" / "sample" / "images" / "left_passive.png"
    img.unlink()
    os.symlink(secret, img)
    shutil.rmtree(ds / "samples" / "0001")
    assert main(["report", str(ds)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err and all(ln.startswith("platebench: warning: ") for ln in err)
    assert any("left_passive.png is a symbolic link" in ln for ln in err)
    assert any("the folder of sample 0001 is missing" in ln for ln in err)
    text = (ds / "report" / "index.html").read_text()
    assert 'images/left_passive.png"' not in text  # neither linked nor thumbnailed: only named in the note
    # thumbnails are embedded: the other images of sample 0000 are shown, the linked file's pixels are not
    shown = base64.b64encode(thumbnail_png(ds / "samples" / "0000" / "sample" / "images" / "left_active.png"))
    hidden = base64.b64encode(thumbnail_png(secret))
    assert shown.decode() in text and hidden.decode() not in text
    # a truncated PNG of a render without a stamp: said, not shown
    s = tmp_path / "s"
    shutil.copytree(small_sample_dir, s)
    (s / STAMP).unlink()
    png = s / "images" / "right_active.png"
    png.write_bytes(png.read_bytes()[:400])
    assert main(["report", str(s)]) == 0
    err = capsys.readouterr().err
    assert "right_active.png: truncated PNG" in err and err.count("\n") == 1


def test_report_never_follows_a_linked_folder_out_of_its_input(small_sample_dir, tmp_path, capsys):
    top = tmp_path / "top"
    top.mkdir()
    shutil.copytree(small_sample_dir, top / "a")
    shutil.copytree(small_sample_dir, tmp_path / "outside")
    os.symlink(tmp_path / "outside", top / "b")
    assert main(["report", str(top)]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "b is a symbolic link" in err and "not followed" in err, err
    text = (top / "report" / "index.html").read_text()
    assert "outside" not in text.replace(f"(to {tmp_path / 'outside'})", "") and 'href="../a/"' in text


def test_sizes_come_from_headers_before_anything_is_allocated(tmp_path):
    cases = {"bomb.png": _png_declaring(30000, 30000), "big.npy": _npy_declaring((100000, 100000)),
             "big.pfm": b"Pf\n60000 60000\n-1\n" + b"\0" * 64, "huge.ply": _PLY_HUGE, "lying.ply": _PLY_LYING,
             "big.exr": _exr_declaring(100000, 100000)}
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
    assert len(cases["bomb.png"]) < 100_000
    with pytest.raises(DatasetError, match="declares a 30000 x 30000 PNG"):
        read_png(tmp_path / "bomb.png")
    with pytest.raises(DatasetError, match="declares a 30000 x 30000 PNG"):
        read_disparity(tmp_path / "bomb.png", 256.0)
    with pytest.raises(DatasetError, match=r"declares shape \(100000, 100000\)"):
        load_npy(tmp_path / "big.npy")
    with pytest.raises(DatasetError, match="declares a 60000 x 60000 PFM"):
        read_pfm(tmp_path / "big.pfm")
    with pytest.raises(DatasetError, match="declares 1000000000000 vertex"):
        read_points(tmp_path / "huge.ply")
    with pytest.raises(DatasetError, match="declares 50000000 vertex, which need at least 600000000 bytes"):
        check_ply(tmp_path / "lying.ply")
    with pytest.raises(DatasetError, match="declares a 100000 x 100000 OpenEXR"):
        exr_size(tmp_path / "big.exr")
    # a real file of each kind still reads
    np.save(tmp_path / "ok.npy", np.zeros((4, 3)))
    assert load_npy(tmp_path / "ok.npy").shape == (4, 3)


def test_only_regular_files_are_read_and_a_fifo_is_named_as_one(tmp_path):
    fifo = tmp_path / "f.toml"
    os.mkfifo(fifo)
    for argv, needle in ((["render", "--config", "/dev/zero", "--out", tmp_path / "o"], "/dev/zero: is a character "
                                                                                       "device, not a regular file"),
                         (["sweep", "/dev/urandom", "--out", tmp_path / "o"], "/dev/urandom: is a character device"),
                         (["render", "--config", fifo, "--out", tmp_path / "o"], "f.toml: is a FIFO"),
                         (["sweep", fifo, "--out", tmp_path / "o"], "f.toml: is a FIFO")):
        p = subprocess.run([sys.executable, "-m", "platebench.bench.cli.main", *map(str, argv)], cwd=REPO,
                           capture_output=True, text=True, timeout=60)
        assert p.returncode == 2 and p.stderr.count("\n") == 1 and needle in p.stderr, p.stderr
    (tmp_path / "big.toml").write_bytes(b"# padding\n" * 500_000)
    from platebench.bench.config import ConfigError
    from platebench.bench.io.config_files import load_config
    with pytest.raises(ConfigError, match="too large for a configuration file"):
        load_config(tmp_path / "big.toml")
    png = tmp_path / "d.png"
    os.mkfifo(png)
    with pytest.raises(DatasetError, match="d.png: is a FIFO"):
        read_png(png)
    with pytest.raises(DatasetError, match="d.png: is a FIFO"):
        read_disparity(png, 256.0)
    assert not (tmp_path / "o").exists()


def test_a_failure_during_export_stands_alone_on_stderr(small_sample_dir, tmp_path, capsys):
    ds = make_dataset(tmp_path / "ds", small_sample_dir)
    code, err = export(capsys, ds, "--format", "middlebury", "--shift", "479", "--out", tmp_path / "mb")
    assert code == 2 and err.count("\n") == 1 and "no plate pixel with a true disparity" in err, err
    assert not (tmp_path / "mb").exists()


@pytest.mark.skipif(os.geteuid() != 0 or shutil.which("mount") is None, reason="mounting a small tmpfs needs root")
def test_a_full_disk_during_report_names_the_path(small_sample_dir, tmp_path):
    full = tmp_path / "full"
    full.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=48k", "tmpfs", str(full)], check=True)
    try:
        (full / "filler").write_bytes(b"\0" * 40_000)
        p = subprocess.run([sys.executable, "-m", "platebench.bench.cli.main", "report", str(small_sample_dir),
                            "--out", str(full / "report")], cwd=REPO, capture_output=True, text=True, timeout=120)
        assert p.returncode == 2 and p.stderr.count("\n") == 1, p.stderr
        assert f"{full / 'report'}/" in p.stderr and "no space left on device" in p.stderr, p.stderr
        assert sorted(x.name for x in full.iterdir()) == ["filler"]
    finally:
        subprocess.run(["umount", "-l", str(full)], capture_output=True)
