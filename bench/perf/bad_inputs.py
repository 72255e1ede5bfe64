"""Bad inputs: every input a user can get wrong, tried as a new user would, and scored.

``python -m platebench.bench.perf.bad_inputs [--json FILE] [-k SUBSTRING]`` (or
``platebench perf bad-input``) makes a scratch directory with two small rendered samples, a
reconstruction and a two-sample sweep dataset, then runs ``platebench`` in a fresh process for
each case: bad TOML values and types, damaged files (truncated PNG/EXR/PFM/NPY, corrupt PLY,
malformed JSON structure, non-UTF-8 text), unreadable or unwritable paths (run as user
``nobody`` where this runs as root), bad flags, bad scheduler addresses, huge ranges; and, from
the modules ``bad_inputs_*`` beside this one, further classes (outputs that would destroy data,
damaged or linked datasets, sizes declared by file headers, files that are not regular files).

A case is *clean* when the command exits 2 with exactly one stderr line ``platebench: error:
...`` that names what the case expects (the file, key or value), or, for a case that expects
success with warnings (``expect_rc=0``), exits 0 with only ``platebench: warning: ...`` lines on
stderr naming what it expects. Scored across all cases: *data lost* (a file that was there
before the command is changed or gone afterwards), *tracebacks* ("Traceback" or "Exception
ignored" on stderr), *exit 0 on failure* (a case that expects a refusal exited 0), *leftovers*
(a new output, a staging directory, a lock left by a failed command). A case with ``scratch``
runs in a directory of its own (a copy of the material, the working directory set there), so a
destructive command can destroy nothing else. Goal: every case clean, and 0 of each. The cases that
run as user ``nobody`` are left out, with the reason, where ``nobody`` cannot reach this checkout
(``nobody_blocker``: a clone under a directory closed to others).

Other modules add cases without editing this one: a module ``bench/perf/bad_inputs_<name>.py``
is imported by ``cases()`` and appends a function returning ``[Case, ...]`` to ``CASE_SOURCES``
(``@register_cases``). Its cases share the material ``_prepare`` makes (``{W}/good``,
``{W}/good2``, ``{W}/good_recon``, ``{W}/ds``).
"""
from __future__ import annotations

import argparse
import hashlib
import importlib
import os
import pkgutil
import resource
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
NOBODY = 65534


@dataclass
class Case:
    name: str
    args: list  # platebench arguments ({W} = the case's directory: the shared one, or its own with scratch)
    expect: tuple  # substrings the one error line must contain (expect_rc 0: the warning lines)
    setup: object = None  # callable(work: Path) -> None
    as_nobody: bool = False
    watch: tuple = ()  # paths (relative to W) that must not exist afterwards
    memory_gb: float = 4.0  # address-space limit of the command (a range that expands must not take the host)
    scratch: bool = False  # run in a directory of its own (a copy of the material), the working directory there
    cwd: str = ""  # the command's working directory, relative to W
    expect_rc: int = 2  # 0: the command succeeds, saying what it left out in warning lines
    teardown: object = None  # callable(work: Path) -> None, run after the command whatever happened
    timeout_s: float = 120.0


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


def _write(rel: str, data):
    def setup(w: Path):
        p = w / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data if isinstance(data, bytes) else data.encode())
    return setup


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
            ("truncated image PNG", "images/left_active.png", "truncate", ("left_active.png", "truncated PNG")),
            ("garbage image PNG", "images/left_passive.png", "garbage", ("left_passive.png", "not a PNG")),
            ("missing image", "images/right_active.png", "delete", ("right_active.png", "missing")),
            ("pattern.json features not a list", "pattern.json", '{"features": 3}', ("pattern.json", "features")),
            ("pattern.json feature lacks keys", "pattern.json", '{"features": [{"id": 0}]}', ("pattern.json",)),
            ("pattern.json is a list", "pattern.json", "[1, 2]", ("pattern.json", "allowed a JSON object")),
            ("pattern.json truncated", "pattern.json", "truncate", ("pattern.json", "invalid JSON")),
            ("calib.json is a list", "calib.json", "[]", ("calib.json", "allowed a JSON object")),
            ("calib.json lacks left", "calib.json", '{"right": {}}', ("calib.json", "left")),
            ("calib.json not UTF-8", "calib.json", "latin1", ("calib.json", "UTF-8")),
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
            ("corrupt plate.ply", "plate.ply", "garbage", ("plate.ply", "PLY")),
            ("truncated boundary.npy", "boundary.npy", "truncate", ("boundary.npy", "truncated")),
            ("truncated disp0GT.pfm", "gt/disp0GT.pfm", "truncate", ("disp0GT.pfm", "truncated PFM")),
            ("garbage disp0GT.pfm", "gt/disp0GT.pfm", "garbage", ("disp0GT.pfm", "not a PFM")),
            ("truncated depth EXR", "gt/left_depth.exr", "truncate", ("left_depth.exr", "OpenEXR")),
            ("truncated mask PNG", "gt/left_mask.png", "truncate", ("left_mask.png", "truncated PNG")),
            ("sample.json truncated", "sample.json", "truncate", ("sample.json", "invalid JSON")),
            ("sample.json is a list", "sample.json", "[]", ("sample.json", "allowed a JSON object")),
            ("sample.json config not a table", "sample.json", '{"layout_version": 1, "config": 5}',
             ("sample.json", "config")),
    ):
        c.append(Case(name, ["evaluate", "{W}/bad", "{W}/good_recon"], expect, _damage(rel, how)))
    for name, rel, how, expect in (
            ("garbage points.csv", "recon/points.csv", "garbage", ("points.csv",)),
            ("truncated recon boundary.npy", "recon/boundary.npy", "truncate", ("boundary.npy", "truncated")),
            ("recon.json is a list", "recon/recon.json", "[]", ("recon.json", "allowed a JSON object")),
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


def _prepare(work: Path) -> None:
    """Two small samples (160 x 120, spp 2; bends 10 and 30 degrees), the first one's reconstruction and a
    two-sample sweep dataset (160 x 120, spp 1, paper's method): the material the cases copy and damage.
    Made through the CLI in a subprocess, as a user would (perf sits below the CLI's layer)."""
    cfg = work / "small.toml"
    cfg.write_text("[scene]\nwidth = 160\nheight = 120\n[render]\nspp = 2\n")
    (work / "ds.toml").write_text("[sweep]\nname = \"bad-input\"\n[base.scene]\nwidth = 160\nheight = 120\n"
                                  "[base.render]\nspp = 1\n[grid]\nbend_deg = [0, 20]\n")
    for argv in (["render", "--config", str(cfg), "--out", str(work / "good")],
                 ["render", "--config", str(cfg), "--bend-deg", "30", "--out", str(work / "good2")],
                 ["reconstruct", str(work / "good"), "--out", str(work / "good_recon")],
                 ["sweep", str(work / "ds.toml"), "--out", str(work / "ds"), "--workers", "0", "--no-progress"]):
        p = subprocess.run([sys.executable, "-m", "platebench.bench.cli.main", *argv], capture_output=True, text=True)
        if p.returncode != 0:
            raise SystemExit(f"bad_inputs: could not prepare {argv}: {p.stderr.strip()[-500:]}")


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
    finally:
        if case.teardown is not None:
            case.teardown(work)
        if case.scratch:
            shutil.rmtree(work, ignore_errors=True)


def _run(case: Case, work: Path, port: int, timeout: float) -> Outcome:
    before = _snapshot(work)
    held = _contents(work)
    args = [a.replace("{W}", str(work)).replace("{PORT}", str(port)) for a in case.args]
    cmd = [sys.executable, "-m", "platebench.bench.cli.main", *args]
    env = dict(os.environ)
    env.pop("PLATEBENCH_DEBUG", None)
    if case.as_nobody and _as_nobody():
        (work / "home").mkdir(exist_ok=True)
        os.chown(work / "home", NOBODY, NOBODY)
        env["HOME"] = str(work / "home")
        cmd = ["setpriv", f"--reuid={NOBODY}", f"--regid={NOBODY}", "--clear-groups", *cmd]
    limit = int(case.memory_gb * 2**30)
    t0 = time.monotonic()
    try:
        r = subprocess.run(cmd, cwd=work / case.cwd, env=env, capture_output=True, text=True, timeout=timeout,
                           preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (limit, limit)))
        rc, err = r.returncode, r.stderr
    except subprocess.TimeoutExpired as e:
        rc, err = 124, (e.stderr.decode() if isinstance(e.stderr, bytes) else e.stderr or "") + "\n(timed out)"
    seconds = time.monotonic() - t0
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    tb = "Traceback" in err or "Exception ignored" in err
    if case.expect_rc == 0:  # success, saying in warning lines what it left out
        named = all(any(x in ln for ln in lines) for x in case.expect)
        clean = rc == 0 and bool(lines) and all(ln.startswith("platebench: warning:") for ln in lines) and named
    else:
        named = all(x in (lines[0] if lines else "") for x in case.expect)
        clean = rc == case.expect_rc and len(lines) == 1 and lines[0].startswith("platebench: error:") and named
    after = _contents(work)
    lost = sorted(p for p, h in held.items() if after.get(p) != h)
    new = sorted(_snapshot(work) - before)
    from platebench.bench.io.atomic import is_temp_name  # noqa: PLC0415
    left = [p for p in new if is_temp_name(Path(p).name) or p.endswith(".lock")
            or any(p == w or p.startswith(w + "/") for w in case.watch)]
    left += [w for w in case.watch if (work / w).exists() and w not in left]
    if case.expect_rc == 0:  # a successful command's own output is no leftover
        left = [p for p in left if is_temp_name(Path(p).name) or p.endswith(".lock")]
    return Outcome(case.name, rc, lines, clean, tb, sorted(set(left)), seconds, lost,
                   exit0_on_failure=case.expect_rc != 0 and rc == 0)


def run_all(select: str | None = None, work: Path | None = None, as_nobody: bool = True) -> list[Outcome]:
    """Run every case (``select``: those whose name contains it; ``as_nobody`` False: leave out the cases
    that run as user nobody) in ``work`` (default a scratch directory, removed afterwards)."""
    own = work is None
    work = Path(tempfile.mkdtemp(prefix="platebench-badinput-")) if own else Path(work)
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
        out = []
        for case in cases():
            if (select and select not in case.name) or (case.as_nobody and not as_nobody):
                continue
            out.append(run_case(case, work, srv.getsockname()[1]))
        from platebench.bench.perf.run_attacks import run_attacks  # noqa: PLC0415  (signals, plug-ins, full disks)
        return out + run_attacks(select, work)
    finally:
        srv.close()
        if own:
            shutil.rmtree(work, ignore_errors=True)


def table(outcomes: list[Outcome]) -> str:
    rows = [f"{'case':44s} {'exit':>4s} {'clean':>5s} {'tb':>3s} {'lost':>4s} {'left':>4s}  first line of stderr"]
    for o in outcomes:
        rows.append(f"{o.case[:44]:44s} {o.rc:4d} {'yes' if o.clean else 'NO':>5s} {'YES' if o.traceback else '-':>3s} "
                    f"{len(o.lost):4d} {len(o.leftovers):4d}  {(o.lines[0] if o.lines else '')[:150]}")
    n = len(outcomes)
    rows.append(f"bad inputs tried {n}, handled cleanly {sum(o.clean for o in outcomes)}, data lost "
                f"{sum(bool(o.lost) for o in outcomes)}, tracebacks {sum(o.traceback for o in outcomes)}, exit 0 on "
                f"failure {sum(o.exit0_on_failure for o in outcomes)}, leftovers {sum(bool(o.leftovers) for o in outcomes)}")
    return "\n".join(rows)


def failed(o: Outcome) -> bool:
    """Whether an outcome misses the goal (module doc)."""
    return not o.clean or o.traceback or bool(o.leftovers) or bool(o.lost) or o.exit0_on_failure


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m platebench.bench.perf.bad_inputs", description=__doc__.split("\n\n")[0])
    p.add_argument("-k", dest="select", help="only cases whose name contains this")
    p.add_argument("--json", type=Path, help="also write the outcomes as JSON here")
    args = p.parse_args(argv)
    blocker = nobody_blocker()
    outcomes = run_all(args.select, as_nobody=blocker is None)
    print(table(outcomes))
    if blocker:
        print(f"left out: the {sum(c.as_nobody for c in cases())} cases run as user nobody ({blocker})")
    if args.json:
        from platebench.bench.io.atomic import write_json  # noqa: PLC0415
        write_json(args.json, {"generator": "platebench perf", "target": "bad-input",
                               "figures": [o.__dict__ for o in outcomes]})
    return 0 if not any(failed(o) for o in outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
