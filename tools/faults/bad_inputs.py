"""The fault-injection harness: every input a user can get wrong and every fault a run can meet,
tried as a user would, each in a fresh ``platebench`` process, and classified.

``python -m tools.faults [--json FILE] [-k SUBSTRING]`` (from the repository root; or
``python tools/faults/run.py``) makes a scratch directory with two small rendered samples, a
reconstruction and a two-sample sweep dataset (160 x 120 px), then runs each case. The cases come
from this module (configuration values and types, damaged files, unreadable or unwritable paths
run as user ``nobody`` where this runs as root, bad flags, scheduler addresses, huge ranges) and
from the modules ``bad_inputs_*`` beside it (outputs that would destroy data, datasets that lie,
generated families of bad flag values and damaged files, and the measured failure cases of
``bad_inputs_measured``); the attacks on runs (``run_attacks``: signals, plug-ins, full disks,
damaged manifests) follow.

Each case states what must happen: the exit status (``expect_rc``: 2 refused, 1 failures recorded,
0 a correct result, 130 / 143 interrupted), the words the one error line must hold (``expect``;
an item that is a tuple is satisfied by any of its words), the files that must stay as they were
(every file of the case's directory: a changed or vanished one is data loss), the outputs that
must not appear (``watch``) and, for a result, a ``check`` of its content. Each outcome has one
class (``CLASSES``, the first that applies):

* ``hang``: the command did not end within its time limit (or within ``within_s`` of a signal);
* ``traceback``: "Traceback" or "Exception ignored" on stderr;
* ``data-loss``: a file there before the command is changed or gone afterwards;
* ``exit0-on-failure``: a case that expects a non-zero status exited 0;
* ``silent-wrong``: the case's ``check`` found a wrong result;
* ``wrong-message``: another status than expected, or an error that is not one line naming what the
  case expects;
* ``leftover``: a staging name, a lock or a watched output left behind;
* ``ok``: everything as stated.

A case with ``scratch`` runs in a directory of its own (a copy of the material, the working
directory set there), so a destructive command can destroy nothing else. The cases that run as
user ``nobody`` are left out, with the reason, where ``nobody`` cannot reach this checkout
(``nobody_blocker``).

Other modules add cases without editing this one: a module ``bad_inputs_<name>.py`` beside this one
is imported by ``cases()`` and appends a function returning ``[Case, ...]`` to ``CASE_SOURCES``
(``@register_cases``). Its cases share the material ``_prepare`` makes (``{W}/good``,
``{W}/good2``, ``{W}/good_recon``, ``{W}/ds``).
"""
from __future__ import annotations

import argparse
import hashlib
import importlib
import json
import os
import pkgutil
import resource
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
NOBODY = 65534
CLASSES = ("ok", "traceback", "hang", "exit0-on-failure", "silent-wrong", "data-loss", "wrong-message", "leftover")
STATUS = {signal.SIGINT: 130, signal.SIGTERM: 143}


@dataclass
class Case:
    name: str
    args: list  # platebench arguments ({W} = the case's directory: the shared one, or its own with scratch)
    expect: tuple  # words the one error line must contain (a tuple item: any of its words); expect_rc 0: warnings
    setup: object = None  # callable(work: Path) -> None
    as_nobody: bool = False
    watch: tuple = ()  # paths (relative to W) that must not exist afterwards
    memory_gb: float = 4.0  # address-space limit of the command (a range that expands must not take the host)
    scratch: bool = False  # run in a directory of its own (a copy of the material), the working directory there
    cwd: str = ""  # the command's working directory, relative to W
    expect_rc: int = 2  # 2 refused (one line), 1 failures recorded, 0 a correct result, 130 / 143 interrupted,
    # -1 any of 0 (a correct result), 1 (a recorded failure naming ``expect``) and 2 (a one-line refusal)
    teardown: object = None  # callable(work: Path) -> None, run after the command whatever happened
    timeout_s: float = 120.0
    family: str = "base"  # the family of cases this one belongs to (the findings' table counts by it)
    check: object = None  # callable(work, rc, stdout, stderr) -> None, or why the result is wrong (silent-wrong)
    env: dict = field(default_factory=dict)  # extra environment variables ({W} replaced)
    wrap: tuple = ()  # a command line put before the platebench command ({W} replaced), e.g. a shell step
    usage: bool = False  # an argparse usage error: status 2, its last line "platebench ...: error: argument ..."
    signal: tuple = ()  # (signal, after_s, within_s): sent after_s seconds in; the command must end within_s
    stdout_to: str = ""  # a file standard output is written to (e.g. /dev/full); default captured
    python: bool = False  # args are a Python program's arguments (``python ARGS``), not platebench's
    one_line: bool = True  # expect_rc 2: the error is one line (False: detail lines may come before it)


CASE_SOURCES: list = []  # functions returning [Case, ...], added by the bad_inputs_* modules (register_cases)


def register_cases(source):
    """Add ``source`` (a function returning a list of ``Case``) to the harness; usable as a decorator."""
    CASE_SOURCES.append(source)
    return source


@dataclass
class Outcome:
    case: str
    rc: int
    lines: list
    clean: bool
    traceback: bool
    leftovers: list = field(default_factory=list)
    seconds: float = 0.0
    lost: list = field(default_factory=list)  # files there before, changed or gone after
    exit0_on_failure: bool = False
    klass: str = "ok"  # one of CLASSES
    why: str = ""  # what made the class (empty for ok)
    family: str = "base"
    expect_rc: int = 2


def _write(rel: str, data):
    def setup(w: Path):
        p = w / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data if isinstance(data, bytes) else data.encode())
    return setup


# set-up steps the families share: each takes the working directory W
def _do(*steps):
    """One set-up step made of ``steps``, run in order."""
    def setup(w: Path):
        for step in steps:
            step(w)
    return setup


def _copy(src: str, dst: str):
    """W/src copied to W/dst: a folder with its links as links, a file with its metadata."""
    def step(w: Path):
        if (w / src).is_dir():
            shutil.copytree(w / src, w / dst, symlinks=True)
        else:
            shutil.copy2(w / src, w / dst)
    return step


def _can_mount() -> bool:
    """Whether set-up steps may mount file systems (root, with ``mount`` on the PATH)."""
    return os.geteuid() == 0 and shutil.which("mount") is not None


def _mount_tmpfs(rel: str, size: str):
    """A tmpfs of ``size`` (``mount``'s spelling, e.g. "64k") mounted on W/rel."""
    def step(w: Path):
        (w / rel).mkdir(parents=True, exist_ok=True)
        subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(w / rel)], check=True,
                       capture_output=True)
    return step


def _umount(rel: str):
    """W/rel unmounted (lazily; nothing when nothing is mounted there)."""
    def step(w: Path):
        subprocess.run(["umount", "-l", str(w / rel)], capture_output=True)
    return step


def _damage(rel: str, how: str):
    """Copy the good sample/recon to a new name and damage one file in it."""
    def setup(w: Path):
        kind = "recon" if rel.startswith("recon/") else "sample"
        src = w / ("good_recon" if kind == "recon" else "good")
        dst = w / ("bad_recon" if kind == "recon" else "bad")
        shutil.rmtree(dst, ignore_errors=True)
        shutil.copytree(src, dst)
        p = dst / rel.split("/", 1)[1] if kind == "recon" else dst / rel
        data = p.read_bytes()
        if how == "truncate":
            p.write_bytes(data[: max(1, len(data) // 2)])
        elif how == "garbage":
            p.write_bytes(b"\x00\xff garbage \x13" * 20)
        elif how == "delete":
            p.unlink()
        elif how == "latin1":
            p.write_bytes(b"\xff\xfe" + data)
        else:
            p.write_bytes(how.encode())
    return setup


def _chmod(rel: str, mode: int):
    def setup(w: Path):
        (w / rel).chmod(mode)
    return setup


def _both(*fs):
    def setup(w: Path):
        for f in fs:
            f(w)
    return setup


TOML_BASE = "[scene]\nwidth = 64\nheight = 48\n"


def cases() -> list[Case]:
    """Every case: this module's, then those the ``bad_inputs_*`` modules register (module doc)."""
    here = Path(__file__).resolve().parent
    for info in sorted(pkgutil.iter_modules([str(here)]), key=lambda m: m.name):
        if info.name.startswith("bad_inputs_"):
            importlib.import_module(f"{__package__}.{info.name}")
    return base_cases() + [c for source in CASE_SOURCES for c in source()]


def base_cases() -> list[Case]:
    tiny = ["--width", "64", "--height", "48", "--spp", "1"]
    c = []
    # --- configuration values and types (render --config)
    for name, text, expect in (
            ("toml spp = inf", "[render]\nspp = inf\n", ("render.spp = inf", "integer 1 to 65536")),
            ("toml seed = inf", "[render]\nseed = inf\n", ("render.seed = inf", "0 to 2^31-1")),
            ("toml spp = nan", "[render]\nspp = nan\n", ("render.spp = nan", "integer")),
            ("toml spp = \"16\"", "[render]\nspp = \"16\"\n", ("render.spp = '16'", "integer 1 to 65536")),
            ("toml width = 160.5", "[scene]\nwidth = 160.5\n", ("scene.width = 160.5", "integer 16 to 8192")),
            ("toml width = \"160\"", "[scene]\nwidth = \"160\"\n", ("scene.width = '160'", "integer")),
            ("toml distance_m = \"0.4\"", "[scene]\ndistance_m = \"0.4\"\n", ("scene.distance_m", "finite number")),
            ("toml distance_m = inf", "[scene]\ndistance_m = inf\n", ("scene.distance_m = inf", "finite number")),
            ("toml bit_depth = 12", "[sensor]\nbit_depth = 12\n", ("bit_depth = 12", "8 or 16")),
            ("toml gamma = true", "[sensor]\ngamma = true\n", ("sensor.gamma = True", "finite number")),
            ("toml angle_rad = nan", "[plate]\nlength_m = 0.1\nwidth_m = 0.07\n[plate.deformation]\nfamily = "
             "\"cylinder\"\nangle_rad = nan\n", ("plate.deformation.angle_rad = nan", "finite number")),
            ("toml length_m = \"a\"", "[plate]\nlength_m = \"a\"\nwidth_m = 0.07\n", ("plate.length_m = 'a'",
                                                                                     "finite number")),
            ("toml unknown key", "[scene]\nwdth = 3\n", ("scene.wdth", "allowed keys")),
            ("toml distortion k4", "[scene.distortion]\nk4 = 0.1\n", ("scene.distortion.k4", "allowed keys")),
            ("toml distortion k1 = \"a\"", "[scene.distortion]\nk1 = \"a\"\n",
             ("scene.distortion.k1 = 'a'", "finite number")),
            ("toml distortion folds", "[scene.distortion]\nk1 = -3.0\n", ("distortion", "one-to-one")),
            ("toml fy_px = 0", "[scene]\nfy_px = 0.0\n", ("scene.fy_px = 0.0", "10.0 to 100000.0")),
            ("toml line_jitter_px = 9", "[sensor]\nline_jitter_px = 9.0\n", ("line_jitter_px = 9.0", "0 to 5 px")),
            ("toml scene not a table", "scene = 3\n", ("scene = 3", "not a table")),
            ("toml syntax error", "[scene\nwidth = 3\n", ("cfg.toml", "invalid TOML")),
    ):
        c.append(Case(name, ["render", "--config", "{W}/cfg.toml", "--out", "{W}/o_render", *tiny], ("cfg.toml",
                      *expect), _write("cfg.toml", text), watch=("o_render",)))
    c.append(Case("toml not UTF-8", ["render", "--config", "{W}/cfg.toml", "--out", "{W}/o_render"],
                  ("cfg.toml", "not UTF-8"), _write("cfg.toml", b"[scene]\nname = \"\xff\xfe\"\n"), watch=("o_render",)))
    c.append(Case("config missing", ["render", "--config", "{W}/none.toml", "--out", "{W}/o_render"],
                  ("none.toml", "missing"), watch=("o_render",)))
    c.append(Case("config is a directory", ["render", "--config", "{W}", "--out", "{W}/o_render"],
                  ("is a directory",), watch=("o_render",)))
    c.append(Case("config unreadable", ["render", "--config", "{W}/secret.toml", "--out", "{W}/pub/o"],
                  ("secret.toml", "permission denied"), _both(_write("secret.toml", TOML_BASE),
                                                              _chmod("secret.toml", 0o600)), as_nobody=True,
                  watch=("pub/o",)))
    # --- flags
    for name, flags, expect in (("--width 10", ["--width", "10"], ("scene.width = 10", "16 to 8192")),
                                ("--spp 0", ["--spp", "0"], ("spp = 0", "1 to 65536")),
                                ("--bend-deg nan", ["--bend-deg", "nan"], ("--bend-deg = nan", "0 to 350")),
                                ("--grid 4x4", ["--grid", "4x4"], ("--grid", "ROWSxCOLS@SQUARE_PX"))):
        c.append(Case(name, ["render", "--out", "{W}/o_render", *tiny, *flags], expect, watch=("o_render",)))
    # --- output targets
    c.append(Case("render --out under a file", ["render", "--out", "{W}/afile/s", *tiny], ("afile",),
                  _write("afile", "x")))
    c.append(Case("render --out is a file", ["render", "--out", "{W}/afile", "--overwrite", *tiny],
                  ("afile", "not a directory"), _write("afile", "x")))
    c.append(Case("render --out exists", ["render", "--out", "{W}/good", *tiny], ("good", "already exists")))
    c.append(Case("render --out unwritable", ["render", "--out", "{W}/ro/s", *tiny], ("ro", "permission denied"),
                  _both(lambda w: (w / "ro").mkdir(exist_ok=True), _chmod("ro", 0o755)), as_nobody=True))
    c.append(Case("reconstruct --out unwritable", ["reconstruct", "{W}/good", "--out", "{W}/ro/r"],
                  ("ro", "permission denied"), _both(lambda w: (w / "ro").mkdir(exist_ok=True), _chmod("ro", 0o755)),
                  as_nobody=True))
    c.append(Case("sweep --out unwritable", ["sweep", "{W}/spec.toml", "--out", "{W}/ro/ds", "--workers", "0"],
                  ("ro", "permission denied"), _both(_write("spec.toml", "[base.scene]\nwidth = 64\nheight = 48\n"
                                                     "[grid]\nbend_deg = [0]\n"),
                                              lambda w: (w / "ro").mkdir(exist_ok=True), _chmod("ro", 0o755)),
                  as_nobody=True))
    c.append(Case("demo --out is a file", ["demo", "--quick", "--out", "{W}/afile", "--overwrite"],
                  ("afile", "not a directory"), _write("afile", "x")))
    # --- sweep specs and executors
    spec_ok = "[base.scene]\nwidth = 64\nheight = 48\n[grid]\nbend_deg = [0]\n"
    for name, text, expect in (
            ("spec spp = inf", "[base.render]\nspp = inf\n[grid]\nbend_deg = [0]\n", ("render.spp = inf",)),
            ("spec huge range", "[grid]\nbend_deg = {start = 0, stop = 1e12, step = 1e-3}\n",
             ("grid.bend_deg", "allowed at most 100000")),
            ("spec width 160.5 axis", "[grid]\nwidth_px = [160.5]\n", ("grid.width_px = 160.5", "integer")),
            ("spec not UTF-8", b"[grid]\nbend_deg = [0]\n# \xff\n", ("spec.toml", "not UTF-8")),
    ):
        c.append(Case(name, ["sweep", "{W}/spec.toml", "--out", "{W}/o_ds", "--workers", "0"], ("spec.toml", *expect),
                      _write("spec.toml", text), watch=("o_ds",)))
    c.append(Case("spec unreadable", ["sweep", "{W}/secret.toml", "--out", "{W}/pub/ds"], ("secret.toml",
                  "permission denied"), _both(_write("secret.toml", spec_ok), _chmod("secret.toml", 0o600)),
                  as_nobody=True, watch=("pub/ds",)))
    for name, addr, expect in (("--scheduler without port", "tcp://127.0.0.1", ("tcp://HOST:PORT",)),
                               ("--scheduler not an address", "localhost", ("tcp://HOST:PORT",)),
                               ("--scheduler closed port", "tcp://127.0.0.1:9", ("cannot reach",)),
                               ("--scheduler not Dask", "tcp://127.0.0.1:{PORT}", ("within 1 s",))):
        c.append(Case(name, ["sweep", "{W}/spec.toml", "--out", "{W}/o_ds", "--scheduler", addr,
                             "--connect-timeout-s", "1"], expect, _write("spec.toml", spec_ok), watch=("o_ds",)))
    c.append(Case("--workers -1", ["sweep", "{W}/spec.toml", "--out", "{W}/o_ds", "--workers", "-1"],
                  ("--workers = -1", "0 to 256"), _write("spec.toml", spec_ok), watch=("o_ds",)))
    # --- damaged samples (reconstruct reads images, calib.json, pattern.json)
    for name, rel, how, expect in (
            ("truncated image PNG", "images/left_active.png", "truncate", ("left_active.png",)),
            ("garbage image PNG", "images/left_passive.png", "garbage", ("left_passive.png",)),
            ("missing image", "images/right_active.png", "delete", ("right_active.png", "missing")),
            ("pattern.json features not a list", "pattern.json", '{"features": 3}', ("pattern.json",)),
            ("pattern.json feature lacks keys", "pattern.json", '{"features": [{"id": 0}]}', ("pattern.json",)),
            ("pattern.json is a list", "pattern.json", "[1, 2]", ("pattern.json",)),
            ("pattern.json truncated", "pattern.json", "truncate", ("pattern.json",)),
            ("calib.json is a list", "calib.json", "[]", ("calib.json",)),
            ("calib.json lacks left", "calib.json", '{"right": {}}', ("calib.json",)),
            ("calib.json not UTF-8", "calib.json", "latin1", ("calib.json",)),
    ):
        c.append(Case(name, ["reconstruct", "{W}/bad", "--out", "{W}/o_recon"], expect, _damage(rel, how),
                      watch=("o_recon",)))
    c.append(Case("sample unreadable", ["reconstruct", "{W}/good_ro", "--out", "{W}/pub/r"],
                  ("calib.json", "permission denied"),
                  _both(lambda w: shutil.copytree(w / "good", w / "good_ro", dirs_exist_ok=True),
                        _chmod("good_ro/calib.json", 0o600)), as_nobody=True, watch=("pub/r",)))
    c.append(Case("reconstruct missing sample", ["reconstruct", "{W}/nothing", "--out", "{W}/o_recon"],
                  ("nothing", "missing"), watch=("o_recon",)))
    # --- damaged ground truth and reconstructions (evaluate reads them)
    for name, rel, how, expect in (
            ("corrupt plate.ply", "plate.ply", "garbage", ("plate.ply",)),
            ("truncated boundary.npy", "boundary.npy", "truncate", ("boundary.npy",)),
            ("truncated disp0GT.pfm", "gt/disp0GT.pfm", "truncate", ("disp0GT.pfm",)),
            ("garbage disp0GT.pfm", "gt/disp0GT.pfm", "garbage", ("disp0GT.pfm",)),
            ("truncated depth EXR", "gt/left_depth.exr", "truncate", ("left_depth.exr",)),
            ("truncated mask PNG", "gt/left_mask.png", "truncate", ("left_mask.png",)),
            ("sample.json truncated", "sample.json", "truncate", ("sample.json",)),
            ("sample.json is a list", "sample.json", "[]", ("sample.json",)),
            ("sample.json config not a table", "sample.json", '{"layout_version": 1, "config": 5}',
             ("sample.json",)),
    ):
        c.append(Case(name, ["evaluate", "{W}/bad", "{W}/good_recon"], expect, _damage(rel, how)))
    for name, rel, how, expect in (
            ("garbage points.csv", "recon/points.csv", "garbage", ("points.csv",)),
            ("truncated recon boundary.npy", "recon/boundary.npy", "truncate", ("boundary.npy",)),
            ("recon.json is a list", "recon/recon.json", "[]", ("recon.json",)),
    ):
        c.append(Case(name, ["evaluate", "{W}/good", "{W}/bad_recon"], expect, _damage(rel, how)))
    c.append(Case("study --bend 0:1e12:1e-3", ["study", "false-boundary", "--bend", "0:1e12:1e-3", "--out",
                                                "{W}/o_study"], ("--bend", "allowed at most"), watch=("o_study",)))
    for name, value, expect in (("study --perturb 30,0", "30,0", ("--perturb axis = 30", "allowed -10 to 10")),
                                ("study --perturb 1,500", "1,500", ("--perturb distance = 500", "allowed -50 to 50")),
                                ("study --perturb 1", "1", ("--perturb = '1'", "AXIS_DEG,DISTANCE_MM")),
                                ("study --perturb nan,0", "nan,0", ("--perturb axis = nan", "allowed -10 to 10"))):
        c.append(Case(name, ["study", "false-boundary", "--perturb", value, "--out", "{W}/o_study"], expect,
                      watch=("o_study",)))
    c.append(Case("study --seed -1", ["study", "false-boundary", "--seed", "-1", "--out", "{W}/o_study"],
                  ("--seed = -1", "allowed an integer 0 to 2^31-1"), watch=("o_study",)))
    return c


MATERIAL = ("good", "good2", "good_recon", "ds", "small.toml", "ds.toml")  # what _prepare makes, scratch copies


def cli(*args) -> list[str]:
    """The command line that runs ``platebench ARGS`` in a fresh process: the ``platebench`` script
    installed beside this Python (as a user runs it), else the module through this Python."""
    script = Path(sys.executable).parent / "platebench"
    head = [str(script)] if script.is_file() else [sys.executable, "-m", "platebench.bench.cli.main"]
    return [*head, *map(str, args)]


def _session(sid: int) -> list[int]:
    """The processes of session ``sid`` (read from /proc; empty where there is none)."""
    out = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        if len(fields) > 3 and int(fields[3]) == sid and fields[0] != "Z":
            out.append(int(d.name))
    return out


def _prepare(work: Path) -> None:
    """Two small samples (160 x 120, spp 2; bends 10 and 30 degrees), the first one's reconstruction and a
    two-sample sweep dataset (160 x 120, spp 1, paper's method): the material the cases copy and damage.
    Made through the CLI in a subprocess, as a user would."""
    cfg = work / "small.toml"
    cfg.write_text("[scene]\nwidth = 160\nheight = 120\n[render]\nspp = 2\n")
    (work / "ds.toml").write_text("[sweep]\nname = \"bad-input\"\n[base.scene]\nwidth = 160\nheight = 120\n"
                                  "[base.render]\nspp = 1\n[grid]\nbend_deg = [0, 20]\n")
    for argv in (["render", "--config", str(cfg), "--out", str(work / "good")],
                 ["render", "--config", str(cfg), "--bend-deg", "30", "--out", str(work / "good2")],
                 ["reconstruct", str(work / "good"), "--out", str(work / "good_recon")],
                 ["sweep", str(work / "ds.toml"), "--out", str(work / "ds"), "--workers", "0", "--no-progress"]):
        p = subprocess.run(cli(*argv), capture_output=True, text=True)
        if p.returncode != 0:
            raise SystemExit(f"faults: could not prepare {argv}: {p.stderr.strip()[-500:]}")


def _snapshot(work: Path) -> set:
    return {str(p.relative_to(work)) for p in work.rglob("*")}


def _contents(work: Path) -> dict:
    """relative path -> sha256 of every file under ``work`` (a link: its target text), for data loss."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(work):
        for name in filenames + [d for d in dirnames if os.path.islink(os.path.join(dirpath, d))]:
            p = Path(dirpath) / name
            rel = str(p.relative_to(work))
            if p.is_symlink():
                out[rel] = "link:" + os.readlink(p)
                continue
            if not p.is_file():  # a FIFO or a device a case made: not read
                out[rel] = "special"
                continue
            try:
                out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
            except OSError:
                out[rel] = "unreadable"
    return out


def _scratch(work: Path, name: str) -> Path:
    """A directory of its own for a destructive case: copies of the material, nothing else."""
    d = work / "scratch" / "".join(ch if ch.isalnum() else "_" for ch in name)
    shutil.rmtree(d, ignore_errors=True)
    d.mkdir(parents=True)
    for m in MATERIAL:
        src = work / m
        if src.is_dir():
            shutil.copytree(src, d / m, symlinks=True)
        elif src.is_file():
            shutil.copy2(src, d / m)
    return d


def _as_nobody() -> bool:
    return os.geteuid() == 0 and shutil.which("setpriv") is not None


def nobody_blocker() -> str | None:
    """Why the cases that run as user ``nobody`` cannot run here, or None when they can: this process
    must be root with ``setpriv``, and ``nobody`` must reach the Python and the package it runs (a
    checkout under a directory closed to others, such as a ``mktemp -d`` folder, is not reachable)."""
    if os.geteuid() != 0:
        return "not running as root: the unreadable/unwritable cases need to switch to user nobody"
    if shutil.which("setpriv") is None:
        return "setpriv is not installed: the unreadable/unwritable cases cannot switch to user nobody"
    probe = subprocess.run(["setpriv", f"--reuid={NOBODY}", f"--regid={NOBODY}", "--clear-groups", sys.executable,
                            "-c", "import platebench.bench.cli.main"], capture_output=True, text=True, cwd="/",
                           timeout=120)
    if probe.returncode == 0:
        return None
    for path in (Path(sys.executable), REPO):
        for d in reversed([path, *path.parents]):
            if d.is_dir() and not (d.stat().st_mode & 0o001):
                return (f"user nobody cannot enter {d} (mode {d.stat().st_mode & 0o777:o}), which holds "
                        f"{'the Python' if path != REPO else 'the checkout'} {path}")
    last = (probe.stderr.strip().splitlines() or ["no output"])[-1]
    return f"user nobody cannot run {sys.executable} with this package ({last[:200]})"


def run_case(case: Case, work: Path, port: int, timeout: float | None = None) -> Outcome:
    if case.scratch:
        work = _scratch(work, case.name)
    try:
        if case.setup is not None:
            case.setup(work)
        return _run(case, work, port, timeout or case.timeout_s)
    except Exception as e:  # noqa: BLE001  (a case whose own set-up fails is reported, not raised)
        return Outcome(case.name, -1, [f"the case itself failed: {type(e).__name__}: {e}"], False, False,
                       klass="wrong-message", why=f"set-up failed: {type(e).__name__}: {e}", family=case.family,
                       expect_rc=case.expect_rc)
    finally:
        if case.teardown is not None:
            case.teardown(work)
        if case.scratch:
            shutil.rmtree(work, ignore_errors=True)
        else:  # what a case made in the shared directory (counted as a leftover above) misleads no later case
            for w in case.watch:
                p = work / w
                shutil.rmtree(p, ignore_errors=True) if p.is_dir() and not p.is_symlink() else \
                    p.unlink(missing_ok=True)


def _command(case: Case, work: Path, port: int) -> list[str]:
    def fill(a):
        return str(a).replace("{W}", str(work)).replace("{PORT}", str(port))
    args = [fill(a) for a in case.args]
    cmd = [sys.executable, *args] if case.python else cli(*args)
    return [fill(a) for a in case.wrap] + cmd


def _kill_group(p: subprocess.Popen) -> None:
    try:
        os.killpg(p.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def _execute(case: Case, cmd: list, cwd: Path, env: dict, timeout: float) -> tuple[int, str, str, bool, str]:
    """(status, stdout, stderr, hung, why) of the case's command, in a session of its own (a hang is
    killed with all its processes)."""
    limit = int(case.memory_gb * 2**30)
    sink = open(case.stdout_to, "w") if case.stdout_to else subprocess.PIPE  # noqa: SIM115
    try:
        p = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=sink, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL,
                             start_new_session=True, encoding="utf-8", errors="replace",
                             preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (limit, limit)))
    finally:
        if case.stdout_to:
            sink.close()
    why = ""
    try:
        if case.signal:
            sig, after_s, within_s = case.signal
            try:
                out, err = p.communicate(timeout=after_s)
                return p.returncode, out or "", err or "", False, f"ended before the {sig.name} at {after_s} s"
            except subprocess.TimeoutExpired:
                pass
            p.send_signal(sig)
            t0 = time.monotonic()
            try:
                out, err = p.communicate(timeout=within_s)
            except subprocess.TimeoutExpired:
                _kill_group(p)
                out, err = p.communicate()
                return 124, out or "", (err or "") + "\n(timed out)", True, \
                    f"still running {within_s} s after {sig.name}"
            why = f"ended {time.monotonic() - t0:.1f} s after {sig.name}"
        else:
            out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        _kill_group(p)
        out, err = p.communicate()
        return 124, out or "", (err or "") + "\n(timed out)", True, f"no end within {timeout:.0f} s"
    deadline = time.monotonic() + 3.0  # what the command left running in its session outlives it: a hang
    while _session(p.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    alive = _session(p.pid)
    _kill_group(p)
    if alive:
        return p.returncode, out or "", err or "", True, f"processes {alive[:5]} outlived the command"
    return p.returncode, out or "", err or "", False, why


def _named(line: str, expect: tuple) -> list:
    """The expected words (a tuple item: any of its words) that ``line`` lacks."""
    low = line.lower()
    return [x for x in expect if not (any(a.lower() in low for a in x) if isinstance(x, tuple) else x.lower() in low)]


def _run(case: Case, work: Path, port: int, timeout: float) -> Outcome:
    before = _snapshot(work)
    held = _contents(work)
    cmd = _command(case, work, port)
    env = dict(os.environ)
    env.pop("PLATEBENCH_DEBUG", None)
    env.update({k: str(v).replace("{W}", str(work)) for k, v in case.env.items()})
    if case.as_nobody and _as_nobody():
        (work / "home").mkdir(exist_ok=True)
        os.chown(work / "home", NOBODY, NOBODY)
        env["HOME"] = str(work / "home")
        cmd = ["setpriv", f"--reuid={NOBODY}", f"--regid={NOBODY}", "--clear-groups", *cmd]
    t0 = time.monotonic()
    rc, out, err, hung, note = _execute(case, cmd, work / case.cwd, env, timeout)
    seconds = time.monotonic() - t0
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    tb = "Traceback" in err or "Exception ignored" in err or "Fatal Python error" in err
    if case.usage:  # argparse: usage lines, then "platebench CMD: error: argument FLAG: ..."
        missing = _named(lines[-1] if lines else "", case.expect)
        clean = rc == 2 and bool(lines) and ": error: argument" in lines[-1] and not missing
        wrong = "" if clean else f"exit {rc}, last line {(lines or [''])[-1][:120]!r}" + \
            (f", lacks {missing}" if missing else "")
    elif case.expect_rc == 0:  # success; its warnings or its summary, when expected, name what they must
        said = lines + out.splitlines()
        missing = [x for x in case.expect if all(_named(ln, (x,)) for ln in said)] if case.expect else []
        clean = rc == 0 and not missing
        wrong = "" if clean else f"exit {rc}" + (f", no line says {missing}" if missing else "")
    elif case.expect_rc == 2:
        missing = _named(lines[0] if case.one_line and lines else "\n".join(lines), case.expect)
        clean = rc == 2 and (len(lines) == 1 or not case.one_line) and bool(lines) \
            and lines[-1].startswith("platebench: error:") and not missing
        wrong = "" if clean else (f"exit {rc}, {len(lines)} stderr line(s)" +
                                  (f", the error line lacks {missing}" if missing else ""))
    elif case.expect_rc == -1:  # any of: a correct result, a recorded failure naming it, a one-line refusal
        text = "\n".join(lines) + "\n" + out
        missing = _named(lines[0] if rc == 2 and lines else text, case.expect)
        clean = rc == 0 or (rc == 1 and not missing) or (rc == 2 and len(lines) == 1 and not missing
                                                        and lines[0].startswith("platebench: error:"))
        wrong = "" if clean else f"exit {rc}, {len(lines)} stderr line(s)" + (f", lacks {missing}" if missing else "")
    else:  # 1: failures recorded; 130 / 143: interrupted (stderr and stdout together must say it)
        text = "\n".join(lines) + "\n" + out
        missing = [x for x in case.expect if _named(text, (x,))]
        clean = rc == case.expect_rc and not missing
        wrong = "" if clean else f"exit {rc}, expected {case.expect_rc}" + (f", nothing says {missing}" if missing
                                                                             else "")
    problem = None
    if case.check is not None and not hung:
        try:
            problem = case.check(work, rc, out, err)
        except Exception as e:  # noqa: BLE001  (a check that cannot read the result: the result is wrong)
            problem = f"the check could not read the result: {type(e).__name__}: {e}"
    after = _contents(work)
    lost = sorted(p for p, h in held.items() if after.get(p) != h)
    new = sorted(_snapshot(work) - before)
    from platebench.bench.io.atomic import is_temp_name  # noqa: PLC0415
    left = [p for p in new if is_temp_name(Path(p).name) or p.endswith(".lock")
            or any(p == w or p.startswith(w + "/") for w in case.watch)]
    left += [w for w in case.watch if (work / w).exists() and w not in left]
    if case.expect_rc == 0:  # a successful command's own output is no leftover
        left = [p for p in left if is_temp_name(Path(p).name) or p.endswith(".lock")]
    exit0 = case.expect_rc not in (0, -1) and rc == 0
    klass, why = classify(hung, tb, lost, exit0, problem, clean, left)
    if klass == "hang":
        why = note
    elif klass == "wrong-message":
        why = wrong
    return Outcome(case.name, rc, lines or ([out.strip().splitlines()[0]] if out.strip() else []), klass == "ok",
                   tb, sorted(set(left)), seconds, lost, exit0_on_failure=exit0, klass=klass, why=why,
                   family=case.family, expect_rc=case.expect_rc)


def classify(hung: bool, tb: bool, lost: list, exit0: bool, problem: str | None, clean: bool,
             left: list) -> tuple[str, str]:
    """(class, why) of an outcome: the first of ``CLASSES`` after "ok" that applies (module doc), else ok."""
    if hung:
        return "hang", ""
    if tb:
        return "traceback", "a traceback on stderr"
    if lost:
        return "data-loss", f"changed or gone: {lost[:3]}"
    if exit0:
        return "exit0-on-failure", "exit 0 where a failure was expected"
    if problem:
        return "silent-wrong", problem
    if not clean:
        return "wrong-message", ""
    if left:
        return "leftover", f"left behind: {left[:3]}"
    return "ok", ""


def run_all(select: str | None = None, work: Path | None = None, as_nobody: bool = True, say=None,
            attacks: bool = True, only: set | None = None) -> list[Outcome]:
    """Run every case (``select``: those whose name contains it; ``only``: those named in it; ``as_nobody``
    False: leave out the cases that run as user nobody; ``attacks`` False: leave out the attacks on runs) in
    ``work`` (default a scratch directory, removed afterwards). ``say``: called with a progress line after
    each case."""
    own = work is None
    work = Path(tempfile.mkdtemp(prefix="platebench-faults-")) if own else Path(work)
    os.chmod(work, 0o755)
    (work / "pub").mkdir(exist_ok=True)
    os.chmod(work / "pub", 0o777)
    srv = socket.socket()  # a listening port that is not a Dask scheduler
    srv.bind(("127.0.0.1", 0))
    srv.listen(16)
    try:
        _prepare(work)
        for p in work.rglob("*"):
            os.chmod(p, 0o755 if p.is_dir() else 0o644)
        os.chmod(work / "pub", 0o777)
        chosen = [c for c in cases() if not (select and select not in c.name) and (as_nobody or not c.as_nobody)
                  and (only is None or c.name in only)]
        out = []
        for i, case in enumerate(chosen, 1):
            out.append(run_case(case, work, srv.getsockname()[1]))
            if say:
                o = out[-1]
                say(f"[{i}/{len(chosen)}] {o.klass:16s} {o.seconds:6.1f} s  {case.name}"
                    + (f"  ({o.why[:100]})" if o.why else ""))
        if not attacks:
            return out
        from tools.faults.run_attacks import run_attacks  # noqa: PLC0415  (signals, plug-ins, full disks)
        return out + run_attacks(select, work, say=say)
    finally:
        srv.close()
        if own:
            shutil.rmtree(work, ignore_errors=True)


def table(outcomes: list[Outcome]) -> str:
    rows = [f"{'case':52s} {'exit':>4s} {'class':16s} first line of stderr, or why"]
    for o in outcomes:
        rows.append(f"{o.case[:52]:52s} {o.rc:4d} {o.klass:16s} {(o.why or (o.lines[0] if o.lines else ''))[:150]}")
    rows.append(summary(outcomes))
    return "\n".join(rows)


def counts(outcomes: list[Outcome]) -> dict:
    """Outcomes per class (every class of ``CLASSES``, zeros included)."""
    return {k: sum(o.klass == k for o in outcomes) for k in CLASSES}


def summary(outcomes: list[Outcome]) -> str:
    return f"cases {len(outcomes)}: " + ", ".join(f"{k} {n}" for k, n in counts(outcomes).items())


def failed(o: Outcome) -> bool:
    """Whether an outcome misses what its case states (module doc)."""
    return o.klass != "ok"


def main(argv: list[str] | None = None) -> int:
    # A harness started in the background (``cmd &``, nohup) inherits SIGINT ignored, and so would every
    # command it runs: give them the default disposition a user's terminal gives, so that the signal
    # attacks test the command, not the harness's start.
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    p = argparse.ArgumentParser(prog="python -m tools.faults", description=__doc__.split("\n\n")[0])
    p.add_argument("-k", dest="select", help="only cases whose name contains this")
    p.add_argument("--json", type=Path, help="also write the counts and every outcome as JSON here")
    p.add_argument("--list", action="store_true", help="list the cases (family, name) and run nothing")
    p.add_argument("--no-attacks", action="store_true", help="leave out the attacks on runs (signals, plug-ins, "
                   "full disks, manifests)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.add_argument("--rerun", type=Path, metavar="JSON", help="run again only the cases that were not ok in this "
                   "earlier --json output, and write (with --json) its outcomes with theirs replaced")
    args = p.parse_args(argv)
    if args.list:
        from tools.faults.run_attacks import attacks  # noqa: PLC0415
        chosen = [c for c in cases() if not (args.select and args.select not in c.name)]
        for c in chosen:
            print(f"{c.family:14s} {c.name}")
        extra = [a for a in attacks() if not (args.select and args.select not in a.name)]
        for a in extra:
            print(f"{'attack':14s} {a.name}")
        print(f"{len(chosen) + len(extra)} cases")
        return 0
    blocker = nobody_blocker()
    say = None if args.quiet else (lambda line: print(line, file=sys.stderr, flush=True))
    t0 = time.monotonic()
    earlier = json.loads(args.rerun.read_text()) if args.rerun else None
    if earlier is None:
        outcomes = run_all(args.select, as_nobody=blocker is None, say=say, attacks=not args.no_attacks)
    else:
        again = {o["case"] for o in earlier["outcomes"] if o["klass"] != "ok"}
        from tools.faults.run_attacks import attacks as attack_list  # noqa: PLC0415
        redo = {o.case: o for o in run_all(as_nobody=blocker is None, say=say, attacks=False, only=again)}
        names = {a.name for a in attack_list()} & again
        if names:
            work = Path(tempfile.mkdtemp(prefix="platebench-faults-"))
            try:
                _prepare(work)
                from tools.faults.run_attacks import run_attacks  # noqa: PLC0415
                redo.update({o.case: o for o in run_attacks(names, work, say=say)})
            finally:
                shutil.rmtree(work, ignore_errors=True)
        outcomes = [redo.get(o["case"]) or Outcome(**o) for o in earlier["outcomes"]]
    wall = time.monotonic() - t0
    print(table(outcomes))
    print(f"wall time {wall:.0f} s")
    if blocker:
        print(f"left out: the {sum(c.as_nobody for c in cases())} cases run as user nobody ({blocker})")
    if args.json:
        doc = {"generator": "tools/faults", "cases": len(outcomes), "counts": counts(outcomes),
               "wall_s": round(wall, 1), "left_out": blocker,
               "rerun_of": None if earlier is None else {"counts": earlier["counts"], "wall_s": earlier["wall_s"],
                                                         "cases_run_again": sum(o["klass"] != "ok"
                                                                                for o in earlier["outcomes"])},
               "families": {f: sum(o.family == f for o in outcomes) for f in sorted({o.family for o in outcomes})},
               "outcomes": [asdict(o) for o in outcomes]}
        args.json.write_text(json.dumps(doc, indent=1, default=str))
    return 0 if not any(failed(o) for o in outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
