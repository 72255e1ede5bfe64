"""Cases of the fault-injection harness (``tools/faults/bad_inputs.py``): outputs that would destroy
what the user did not hand over, datasets that lie (files swapped, links leading out), sizes declared by file headers, and
paths that are not regular files.

Every destructive case runs in a directory of its own (``scratch``): a copy of the material, the
working directory set there. The harness counts a file there before and changed or gone after as
data lost.
"""
from __future__ import annotations

import os
import shutil
import struct
import zlib
from pathlib import Path

from tools.faults.bad_inputs import (
    Case,
    _can_mount,
    _copy,
    _do,
    _mount_tmpfs,
    _umount,
    _write,
    register_cases,
)

SMALL_RENDER = ["--width", "64", "--height", "48", "--spp", "1"]


def _file(rel: str, data: bytes | str = b"mine, not PlateBench's\n"):
    """``rel`` holds ``data`` (default: a user's note)."""
    return _write(rel, data)


def _link(rel: str, target: str):
    """``rel`` becomes a symbolic link to ``target`` (absolute, or relative to W)."""
    def step(w: Path):
        p = w / rel
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        elif os.path.lexists(p):
            p.unlink()
        p.parent.mkdir(parents=True, exist_ok=True)
        os.symlink(target if os.path.isabs(target) else w / target, p)
    return step


def _move_out(rel: str, to: str):
    """Move ``rel`` to ``to`` (outside the dataset) and leave a link to it in its place."""
    def step(w: Path):
        shutil.move(w / rel, w / to)
        os.symlink(w / to, w / rel)
    return step


def _fifo(rel: str):
    def step(w: Path):
        p = w / rel
        if os.path.lexists(p):
            p.unlink()
        os.mkfifo(p)
    return step


def _swap(a: str, b: str):
    def step(w: Path):
        tmp = w / (a + ".swap")
        os.replace(w / a, tmp)
        os.replace(w / b, w / a)
        os.replace(tmp, w / b)
    return step


def _truncate(rel: str):
    def step(w: Path):
        p = w / rel
        p.write_bytes(p.read_bytes()[:300])
    return step


def _remove(rel: str):
    def step(w: Path):
        p = w / rel
        shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()
    return step


def _png_declaring(width: int, height: int) -> bytes:
    """A small PNG whose header declares ``width`` x ``height`` 8-bit grey pixels (its data: one row)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * (width + 1)))
            + chunk(b"IEND", b""))


def _npy_declaring(shape: tuple) -> bytes:
    header = repr({"descr": "<f8", "fortran_order": False, "shape": shape}).encode()
    header += b" " * (63 - (10 + len(header)) % 64) + b"\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header + b"\0" * 64


def _exr_declaring(width: int, height: int) -> bytes:
    """The start of an OpenEXR header whose data window is ``width`` x ``height``."""
    window = struct.pack("<4i", 0, 0, width - 1, height - 1)
    return (b"\x76\x2f\x31\x01" + struct.pack("<I", 2) + b"dataWindow\0box2i\0" + struct.pack("<i", 16) + window
            + b"\0" + b"\0" * 64)


_PLY_HUGE = b"ply\nformat ascii 1.0\nelement vertex 1000000000000\nproperty float x\nproperty float y\n" \
            b"property float z\nend_header\n0 0 0\n"
_PLY_LYING = b"ply\nformat binary_little_endian 1.0\nelement vertex 50000000\nproperty float x\nproperty float y\n" \
             b"property float z\nend_header\n" + b"\0" * 12


@register_cases
def output_cases() -> list[Case]:
    """--out that would replace what the user did not hand over (module doc)."""
    c = []
    victim = _file("victim/precious.txt")
    for cmd, args in (("render", ["render", *SMALL_RENDER]), ("reconstruct", ["reconstruct", "good"]),
                      ("compare", ["compare", "good", "--methods", "sgbm"]),
                      ("export", ["export", "ds", "--format", "middlebury"]),
                      ("calibrate", ["calibrate", *SMALL_RENDER]), ("sense", ["sense", *SMALL_RENDER]),
                      ("study", ["study", "false-boundary", "--limit", "1"]),
                      ("sweep", ["sweep", "ds.toml", "--workers", "0"]), ("report", ["report", "good"]),
                      ("demo", ["demo", "--quick"])):
        c.append(Case(f"{cmd} --overwrite a user's folder", [*args, "--out", "victim", "--overwrite"],
                      ("victim", "precious.txt"), victim, scratch=True))
    c.append(Case("evaluate --out a user's file", ["evaluate", "good", "good_recon", "--out", "notes.txt"],
                  ("notes.txt", "already exists"), _file("notes.txt"), scratch=True))
    c.append(Case("evaluate --overwrite a user's file", ["evaluate", "good", "good_recon", "--out", "notes.txt",
                                                         "--overwrite"],
                  ("notes.txt", "not a PlateBench score"), _file("notes.txt"), scratch=True))
    c.append(Case("perf --json a user's file", ["perf", "reconstruct", "--json", "notes.txt", "--overwrite"],
                  ("notes.txt", "not a PlateBench perf figures"), _file("notes.txt"), scratch=True))
    sub = _do(lambda w: (w / "sub").mkdir(), lambda w: shutil.copytree(w / "good", w / "sub" / "s"),
              lambda w: shutil.copy2(w / "ds.toml", w / "sub" / "spec.toml"))
    note = "mine, not PlateBench's\n"
    for name, args, expect, setup, cwd in (
            ("render --out . --overwrite", ["render", *SMALL_RENDER, "--out", ".", "--overwrite"], ("working directory",),
             None, ""),
            ("render --out the cwd's parent", ["render", *SMALL_RENDER, "--out", "..", "--overwrite"],
             ("working directory",), sub, "sub"),
            ("render --out /", ["render", *SMALL_RENDER, "--out", "/", "--overwrite"], ("file-system root",), None, ""),
            ("reconstruct --out its sample", ["reconstruct", "good", "--out", "good", "--overwrite"],
             ("good", "is the input"), None, ""),
            ("reconstruct --out inside its sample", ["reconstruct", "good", "--out", "good/images", "--overwrite"],
             ("good/images", "inside the input"), None, ""),
            ("reconstruct --out its sample, other spelling", ["reconstruct", "{W}/good", "--out", "sub/../good/",
                                                              "--overwrite"], ("is the input",), sub, ""),
            ("reconstruct --out a folder holding it", ["reconstruct", "sub/s", "--out", "sub", "--overwrite"],
             ("sub", "holds the input"), sub, ""),
            ("reconstruct --out a sample", ["reconstruct", "good", "--out", "good2", "--overwrite"],
             ("good2", "not a PlateBench reconstruction"), None, ""),
            ("reconstruct --out a linked recon", ["reconstruct", "good", "--out", "link", "--overwrite"],
             ("link", "symbolic link"), _link("link", "good_recon"), ""),
            ("reconstruct --out a file", ["reconstruct", "good", "--out", "afile", "--overwrite"],
             ("afile", "not a directory"), _file("afile"), ""),
            ("compare --out its sample", ["compare", "good", "--out", "good", "--overwrite"], ("good", "is the input"),
             None, ""),
            ("compare --out its --recon", ["compare", "good", "--recon", "good_recon", "--out", "good_recon",
                                           "--overwrite"], ("good_recon", "is the input"), None, ""),
            ("export --out its dataset", ["export", "ds", "--format", "middlebury", "--out", "ds", "--overwrite"],
             ("ds", "is the input"), None, ""),
            ("export --out inside its dataset", ["export", "ds", "--format", "kitti", "--out", "ds/samples/k"],
             ("ds/samples/k", "inside the input"), None, ""),
            ("evaluate --out the sample's sample.json", ["evaluate", "good", "good_recon", "--out",
                                                         "good/sample.json"], ("good/sample.json", "inside the input"),
             None, ""),
            ("evaluate --out the ground truth", ["evaluate", "good", "--disparity", "good/gt/disp0GT.pfm", "--out",
                                                 "good/gt/disp0GT.pfm", "--overwrite"], ("disp0GT.pfm",), None, ""),
            ("evaluate --out the sample", ["evaluate", "good", "good_recon", "--out", "good"],
             ("good: is the input",), None, ""),
            ("evaluate --out points.csv", ["evaluate", "good", "good_recon", "--out", "good_recon/points.csv",
                                           "--overwrite"], ("good_recon/points.csv", "inside the input"), None, ""),
            ("evaluate --out a folder", ["evaluate", "good", "good_recon", "--out", "adir", "--overwrite"],
             ("adir", "is a directory"), lambda w: (w / "adir").mkdir(), ""),
            ("report --out its input", ["report", "ds", "--out", "ds", "--overwrite"], ("ds", "is the input"), None, ""),
            ("report --out inside its input", ["report", "ds", "--out", "ds/samples", "--overwrite"],
             ("ds/samples", "inside the input"), None, ""),
            ("sweep --out the folder of its spec", ["sweep", "sub/spec.toml", "--out", "sub", "--overwrite"],
             ("sub", "holds the input"), sub, ""),
            ("sweep --overwrite the working directory", ["sweep", "../ds.toml", "--out", ".", "--overwrite",
                                                         "--workers", "0"], ("working directory",), None, "ds"),
            ("sweep --overwrite a dataset with a note", ["sweep", "ds.toml", "--out", "ds", "--overwrite",
                                                         "--workers", "0"], ("notes.txt", "did not write"),
             _file("ds/notes.txt", note), ""),
            ("render --overwrite a sample with a note", ["render", *SMALL_RENDER, "--out", "good", "--overwrite"],
             ("good", "images/notes.txt", "did not write"), _file("good/images/notes.txt", note), ""),
            ("render beside a user's lock-named file", ["render", *SMALL_RENDER, "--out", "o"], (".o.lock",),
             _file(".o.lock", note), ""),
            ("study beside a user's journal-named file", ["study", "false-boundary", "--limit", "1", "--out", "o"],
             ("o.journal.jsonl", "not a study journal"), _file("o.journal.jsonl", note), ""),
    ):
        c.append(Case(name, args, expect, setup, scratch=True, cwd=cwd, watch=("o",)))
    for x in c:
        x.family = "outputs"
    return c


@register_cases
def reader_cases() -> list[Case]:
    """Datasets that lie, sizes declared by headers, paths that are not regular files."""
    s0, s1 = "ds/samples/0000/sample", "ds/samples/0001/sample"
    c = [
        Case("export: images swapped between samples", ["export", "ds", "--format", "middlebury", "--out", "o"],
             ("0000", "left_passive.png", "checksum"),
             _swap(f"{s0}/images/left_passive.png", f"{s1}/images/left_passive.png"), scratch=True, watch=("o",)),
        Case("export: disp0GT swapped between samples", ["export", "ds", "--format", "middlebury", "--out", "o"],
             ("disp0GT.pfm", "checksum"), _swap(f"{s0}/gt/disp0GT.pfm", f"{s1}/gt/disp0GT.pfm"), scratch=True,
             watch=("o",)),
        Case("export: images swapped between two renders", ["export", "both", "--format", "middlebury", "--out", "o"],
             ("left_passive.png", "checksum"),
             _do(lambda w: (w / "both").mkdir(), lambda w: shutil.move(w / "good", w / "both" / "a"),
                 lambda w: shutil.move(w / "good2", w / "both" / "b"),
                 _swap("both/a/images/left_passive.png", "both/b/images/left_passive.png")), scratch=True,
             watch=("o",)),
        Case("export: a sample folder replaced by a link", ["export", "ds", "--format", "middlebury", "--out", "o"],
             ("ds/samples/0001", "symbolic link"), _move_out("ds/samples/0001", "elsewhere"), scratch=True,
             watch=("o",)),
        Case("export: a sample folder gone", ["export", "ds", "--format", "middlebury", "--out", "o"],
             ("0001", "missing"), _remove(s1), scratch=True, watch=("o",)),
        Case("report: an image linked out of the dataset", ["report", "ds"],
             ("left_passive.png", "symbolic link"), _link(f"{s0}/images/left_passive.png", "/etc/hostname"),
             scratch=True, expect_rc=0),
        Case("report: a sample folder gone", ["report", "ds"], ("0001", "missing"), _remove("ds/samples/0001"),
             scratch=True, expect_rc=0),
        Case("report: a truncated PNG", ["report", "good"], ("left_passive.png", "truncated PNG"),
             _do(_truncate("good/images/left_passive.png"), _remove("good/.platebench-output.json")),
             scratch=True, expect_rc=0),
        Case("evaluate: PNG declaring 30000 x 30000", ["evaluate", "good", "--disparity", "{W}/bomb.png",
                                                       "--disparity-scale", "256"],
             ("bomb.png", "30000 x 30000"), _file("bomb.png", _png_declaring(30000, 30000)), scratch=True),
        Case("evaluate: NPY declaring (100000, 100000)", ["evaluate", "good", "--depth", "{W}/big.npy"],
             ("big.npy", "(100000, 100000)"), _file("big.npy", _npy_declaring((100000, 100000))), scratch=True),
        Case("evaluate: EXR declaring 100000 x 100000", ["evaluate", "good", "--depth", "{W}/big.exr"],
             ("big.exr", "100000 x 100000"), _file("big.exr", _exr_declaring(100000, 100000)), scratch=True),
        Case("evaluate: PFM declaring 60000 x 60000", ["evaluate", "good", "--disparity", "{W}/big.pfm"],
             ("big.pfm", "60000 x 60000"), _file("big.pfm", b"Pf\n60000 60000\n-1\n" + b"\0" * 64), scratch=True),
        Case("evaluate: ASCII PLY declaring 10^12 vertices", ["evaluate", "good", "--points", "{W}/huge.ply"],
             ("huge.ply", "1000000000000 vertex"), _file("huge.ply", _PLY_HUGE), scratch=True),
        Case("evaluate: binary PLY longer than its file", ["evaluate", "good", "--mesh", "{W}/lying.ply"],
             ("lying.ply", "truncated"), _file("lying.ply", _PLY_LYING), scratch=True),
        Case("render --config /dev/zero", ["render", "--config", "/dev/zero", "--out", "o"],
             ("/dev/zero", "not a regular file"), watch=("o",)),
        Case("render --config /dev/urandom", ["render", "--config", "/dev/urandom", "--out", "o"],
             ("/dev/urandom", "not a regular file"), watch=("o",)),
        Case("render --config a FIFO", ["render", "--config", "{W}/fifo.toml", "--out", "o"],
             ("fifo.toml", "FIFO"), _fifo("fifo.toml"), scratch=True, watch=("o",), timeout_s=30),
        Case("render --config of 5 MB", ["render", "--config", "{W}/big.toml", "--out", "o"],
             ("big.toml", "too large"), _file("big.toml", b"# padding\n" * 500_000), scratch=True, watch=("o",)),
        Case("sweep /dev/urandom", ["sweep", "/dev/urandom", "--out", "o"], ("/dev/urandom", "not a regular file"),
             watch=("o",)),
        Case("sweep a FIFO spec", ["sweep", "{W}/fifo.toml", "--out", "o"], ("fifo.toml", "FIFO"),
             _fifo("fifo.toml"), scratch=True, watch=("o",), timeout_s=30),
        Case("evaluate --disparity a FIFO", ["evaluate", "good", "--disparity", "{W}/d.pfm"], ("d.pfm", "FIFO"),
             _fifo("d.pfm"), scratch=True, timeout_s=30),
        Case("reconstruct: calib.json a FIFO", ["reconstruct", "good", "--out", "o"], ("calib.json", "FIFO"),
             _fifo("good/calib.json"), scratch=True, watch=("o",), timeout_s=30),
        Case("evaluate --out names no staging file", ["evaluate", "good", "good_recon", "--out", "good_recon"],
             ("good_recon: is the input",), scratch=True),
        Case("export: a failure during the export stands alone", ["export", "ds", "--format", "middlebury",
                                                                       "--shift", "159", "--out", "o"],
             ("no plate pixel",), scratch=True, watch=("o",)),
    ]
    if _can_mount():
        c.append(Case("report: a full disk names the path", ["report", "good", "--out", "full/report"],
                      ("full/report", "no space left"),
                      _do(_mount_tmpfs("full", "48k"), _file("full/filler", b"\0" * 40_000)), scratch=True,
                      teardown=_umount("full")))
    for x in c:
        x.family = "readers"
    return c
