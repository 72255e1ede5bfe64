"""Generated cases of the fault-injection harness (``tools/faults/bad_inputs.py``): each kind of
damage to each file a reader takes, for each command that reads it.

A copy of the good sample (``bad``) or reconstruction (``bad_recon``) has one file damaged in one
way (``DAMAGE``): cut to half its length, overwritten with garbage, emptied, deleted, replaced by a
symbolic link to the same file of another sample, overwritten by the same file of another sample
(a swap: a valid file that does not belong), or replaced by a folder. The command must refuse it
(status 2 and one line ``platebench: error: ...`` naming the file), or, where it does not compute its
result from that file, give the undamaged input's result (a wrong result is silent-wrong). Every case
runs in a directory of its own.
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path

from tools.faults.bad_inputs import Case, register_cases

DAMAGE = ("truncate", "garbage", "empty", "delete", "link-out", "swap-in", "folder")
# the files each reader takes: (command's arguments, which copy is damaged, files)
READERS = (
    ("reconstruct", ["reconstruct", "{W}/bad", "--out", "{W}/o_file"], "sample",
     ("images/left_active.png", "images/right_active.png", "images/left_passive.png", "images/right_passive.png",
      "calib.json", "pattern.json")),
    ("evaluate", ["evaluate", "{W}/bad", "{W}/good_recon", "--out", "{W}/o_file"], "sample",
     ("gt/disp0GT.pfm", "gt/left_depth.exr", "gt/left_mask.png", "plate.ply", "boundary.npy", "sample.json")),
    ("evaluate", ["evaluate", "{W}/good", "{W}/bad_recon", "--out", "{W}/o_file"], "recon",
     ("points.csv", "recon.json", "boundary.npy")),
)


def damage(kind: str, which: str, rel: str):
    """A set-up that copies the good sample or reconstruction and damages its file ``rel`` by ``kind``."""
    def setup(w: Path):
        src, dst = (w / "good", w / "bad") if which == "sample" else (w / "good_recon", w / "bad_recon")
        other = w / ("good2" if which == "sample" else "good2_recon")
        if which == "recon" and not other.exists() and kind in ("link-out", "swap-in"):
            from tools.faults.bad_inputs import cli  # noqa: PLC0415
            import subprocess  # noqa: PLC0415
            subprocess.run(cli("reconstruct", w / "good2", "--out", other), capture_output=True, check=True)
        shutil.rmtree(dst, ignore_errors=True)
        shutil.copytree(src, dst, symlinks=True)
        p = dst / rel
        data = p.read_bytes()
        if kind == "truncate":
            p.write_bytes(data[: max(1, len(data) // 2)])
        elif kind == "garbage":
            p.write_bytes(b"\x00\xff garbage \x13" * 20)
        elif kind == "empty":
            p.write_bytes(b"")
        elif kind == "delete":
            p.unlink()
        elif kind == "link-out":
            p.unlink()
            os.symlink(other / rel, p)
        elif kind == "swap-in":
            shutil.copy2(other / rel, p)
        elif kind == "folder":
            p.unlink()
            p.mkdir()
            (p / "x").write_text("x")
    return setup


def _figures(doc):
    """A score or reconstruction record without what differs between two runs of the same work (times,
    paths)."""
    if isinstance(doc, dict):
        return {k: _figures(v) for k, v in doc.items() if not k.endswith("_s") and "time" not in k
                and k not in ("created", "written", "path", "paths", "sample_dir", "recon_dir", "out", "inputs",
                              "versions", "host", "command")}
    if isinstance(doc, list):
        return [_figures(v) for v in doc]
    return doc


def same_as_undamaged(cmd: str):
    """A check: a command that succeeded despite the damage gives the undamaged input's result (the file it
    reads is not among those it scores with), else the result is wrong."""
    def check(w: Path, rc: int, out: str, err: str):
        if rc != 0:
            return None
        import json  # noqa: PLC0415
        import subprocess  # noqa: PLC0415

        from tools.faults.bad_inputs import cli  # noqa: PLC0415
        if cmd == "reconstruct":
            got, ref = (w / "o_file" / "points.csv").read_bytes(), (w / "good_recon" / "points.csv").read_bytes()
            return None if got == ref else "the reconstruction differs from the undamaged sample's"
        subprocess.run(cli("evaluate", w / "good", w / "good_recon", "--out", w / "ref.json"), capture_output=True,
                       check=True)
        got = _figures(json.loads((w / "o_file").read_text()))
        ref = _figures(json.loads((w / "ref.json").read_text()))
        return None if got == ref else "the score differs from the undamaged pair's"
    return check


@register_cases
def file_cases() -> list[Case]:
    """Each damage of each file each reader takes (module doc): refused in one line naming the file, or,
    where the command does not score with the file, the undamaged input's result."""
    c = []
    for cmd, argv, which, files in READERS:
        for rel in files:
            for kind in DAMAGE:
                c.append(Case(f"file: {cmd} {which} {rel} {kind}", argv, (Path(rel).name,),
                              damage(kind, which, rel), scratch=True, family="damaged-file", timeout_s=90,
                              expect_rc=-1, check=same_as_undamaged(cmd)))
    return c
