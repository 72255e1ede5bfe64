"""Cases of the fault-injection harness (``tools/faults/bad_inputs.py``) that reproduce the measured
failure kinds of a benchmark's command line, each run as a user runs it on a tiny sample (160 x 120
px, spp 1 or 2), with what must happen instead:

* silent wrong results: a reconstruction of another sample scored, a swapped or linked image
  reconstructed, an export whose true disparities go below zero, an edited results table trusted,
  a lock check fooled by a shadowing package, a score in the wrong units without its hint;
* exit 0 on failure: a sweep or a comparison in which everything failed, a missing ``--recon``, an
  export of an interrupted dataset;
* hangs: a plug-in that loops at import, a long render signalled (it must end within 5 s), a
  plug-in's child process that outlives its command;
* data loss: ``--overwrite`` over a file the user edited inside a PlateBench output;
* tracebacks: render sizes and spp beyond one launch, deeply nested TOML, extreme plate sizes and
  angles, non-UTF-8 and non-ASCII names, OpenCV parameter ranges, minimum sizes per method, a
  deleted working directory;
* misleading messages, and example specs run from any folder.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
from pathlib import Path

import numpy as np

from tools.faults.bad_inputs import (
    Case,
    _can_mount,
    _copy,
    _do,
    _mount_tmpfs,
    _umount,
    _write,
    cli,
    register_cases,
)
from tools.faults.run_attacks import write_plugins

R = ["--width", "160", "--height", "120", "--spp", "1"]
NOT_UTF8 = os.fsdecode(b"o_\xff\xfe")  # a file name whose bytes decode to no characters
NON_ASCII = "o_\u00e9t\u00e9"


def _cli(*args, check: bool = True, env: dict | None = None):
    """A set-up step: ``platebench ARGS`` in W ({W} replaced)."""
    def step(w: Path):
        argv = [str(a).replace("{W}", str(w)) for a in args]
        p = subprocess.run(cli(*argv), cwd=w, capture_output=True, text=True, env=env)
        if check and p.returncode != 0:
            raise RuntimeError(f"{' '.join(argv[:3])}: exit {p.returncode}: {p.stderr.strip()[-300:]}")
    return step


def _plugins(w: Path) -> None:
    """The misbehaving plug-ins (``run_attacks``) and a spawning one as modules in ``W/plugins``."""
    write_plugins(w / "plugins")
    (w / "plugins" / "spawner.py").write_text(
        "import subprocess, sys, time\n"
        "def f(inputs):\n"
        "    subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(600)', 'platebench-fault-orphan'])\n"
        "    while True:\n"
        "        time.sleep(10)\n")


PLUGIN_ENV = {"PYTHONPATH": "{W}/plugins"}


def _no_orphan(w, rc, out, err):
    """None when no process of the spawning plug-in outlived the command."""
    for d in Path("/proc").iterdir():
        try:
            if d.name.isdigit() and b"platebench-fault-orphan" in (d / "cmdline").read_bytes():
                os.kill(int(d.name), signal.SIGKILL)
                return f"the plug-in's child process {d.name} outlived the command"
        except OSError:
            continue
    return None


def _read_pfm(path: Path) -> np.ndarray:
    data = path.read_bytes()
    head, rest = data.split(b"\n", 3)[:3], data.split(b"\n", 3)[3]
    w, h = map(int, head[1].split())
    scale = float(head[2])
    return np.frombuffer(rest[: w * h * 4], dtype="<f4" if scale < 0 else ">f4").reshape(h, w)


def _disparities_positive(w, rc, out, err):
    """None when every exported true disparity is at least 1 px and calib.txt's vmin is not below 0."""
    if rc != 0:
        return None
    pfms = sorted((w / "o").rglob("disp0*.pfm"))
    if not pfms:
        return "no disp0GT.pfm was exported"
    for p in pfms:
        d = _read_pfm(p)
        d = d[np.isfinite(d)]
        if d.size and d.min() < 1.0:
            return f"{p.relative_to(w)}: true disparities down to {d.min():.2f} px"
    for c in (w / "o").rglob("calib.txt"):
        keys = dict(ln.split("=", 1) for ln in c.read_text().splitlines() if "=" in ln)
        if "vmin" in keys and float(keys["vmin"]) < 0:
            return f"{c.relative_to(w)}: vmin {keys['vmin']}"
    return None


def _exists(rel: str):
    def check(w, rc, out, err):
        return None if (w / rel).exists() else f"{rel} was not written"
    return check


def _hinted(w, rc, out, err):
    doc = json.loads((w / "mm.score.json").read_text())
    return None if doc.get("hints") and "millimetres" in out else "a score in millimetres carries no hint"


def _axes_only(axis: str):
    def check(w, rc, out, err):
        rows = [r for r in (ln.split() for ln in out.splitlines()[1:]) if len(r) >= 7 and r[-1].endswith("m")
                and r[-3].lstrip("-").isdigit()]
        bad = [" ".join(r) for r in rows if r[-3] != axis]
        return f"plates of another axis listed: {bad[:2]}" if bad or not rows else None
    return check


def _lists_samples(w, rc, out, err):
    return None if rc == 0 and "0001" in out else "the example's samples were not listed"


def _results_table_edited(name: str):
    """Change a figure of the dataset's results table ``name`` (the other table removed)."""
    def step(w: Path):
        import pyarrow as pa  # noqa: PLC0415
        import pyarrow.parquet as pq  # noqa: PLC0415
        from platebench.bench.io.parquet import read_parquet  # noqa: PLC0415
        ds = w / "ds"
        if name == "results.csv":
            (ds / "results.parquet").unlink()
            lines = (ds / "results.csv").read_text().splitlines()
            head = lines[0].split(",")
            i = head.index("depth_rms_mm")
            row = lines[1].split(",")
            row[i] = "0.001"
            (ds / "results.csv").write_text("\n".join([lines[0], ",".join(row), *lines[2:]]) + "\n")
        else:
            t = read_parquet(ds / "results.parquet")
            i = t.column_names.index("depth_rms_mm")
            t = t.set_column(i, "depth_rms_mm", pa.array([0.001] * t.num_rows, t.schema.field(i).type))
            pq.write_table(t, ds / "results.parquet")
    return step


def _interrupted_dataset(w: Path) -> None:
    """An 8-sample sweep dataset interrupted (SIGINT) once its first samples are committed."""
    (w / "eight.toml").write_text("[base.scene]\nwidth = 160\nheight = 120\n[base.render]\nspp = 1\n"
                                  "[grid]\nbend_deg = [0, 10, 20, 30, 40, 50, 60, 70]\n")
    p = subprocess.Popen(cli("sweep", w / "eight.toml", "--out", w / "ds8", "--workers", "0", "--no-progress"),
                         cwd=w, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    import time  # noqa: PLC0415
    deadline = time.monotonic() + 300
    while p.poll() is None and time.monotonic() < deadline and \
            len(list((w / "ds8" / "samples").glob("*/result.json"))) < 2:
        time.sleep(0.05)
    p.send_signal(signal.SIGINT)
    p.wait(timeout=120)


def _deleted_cwd() -> dict:
    """A case's keywords that run its command from a working directory deleted under it."""
    return {"wrap": ("sh", "-c", 'mkdir -p gone && cd gone && rmdir ../gone && exec "$@"', "sh")}


def _full_tmpfs(rel: str):
    """A 64 KiB tmpfs mounted on W/rel and filled up."""
    def fill(w: Path):
        try:
            with open(w / rel / "filler", "wb") as f:
                while True:
                    f.write(b"\0" * 4096)
                    f.flush()
        except OSError:  # the disk is full: what the case needs
            pass
    return _do(_mount_tmpfs(rel, "64k"), fill)


def _silent_wrong() -> list[Case]:
    far = _do(_cli("render", "--out", "{W}/far", *R, "--distance-m", "0.6", "--bend-deg", "60"),
              _cli("reconstruct", "{W}/far", "--out", "{W}/rfar"))
    results_api = ("-c", "import sys, platebench\ntry:\n    platebench.results(sys.argv[1])\nexcept Exception as e:\n"
                   "    print('platebench: error:', e, file=sys.stderr)\n    sys.exit(2)\n", "{W}/ds")
    return [
        Case("measured: compare --recon of another sample", ["compare", "good", "--methods", "paper", "--recon",
                                                             "rfar", "--out", "o"], ("not made from",), far,
             scratch=True, watch=("o",)),
        Case("measured: evaluate a reconstruction of another sample", ["evaluate", "good", "rfar", "--out", "o.json"],
             ("not made from",), far, scratch=True, watch=("o.json",)),
        Case("measured: reconstruct an image swapped in from another sample", ["reconstruct", "s", "--out", "o"],
             ("left_passive.png",), _do(_copy("good", "s"), _copy("good2/images/left_passive.png",
                                                                   "s/images/left_passive.png")),
             scratch=True, watch=("o",)),
        Case("measured: reconstruct a symlinked image", ["reconstruct", "s", "--out", "o"],
             ("left_passive.png", "symbolic link"),
             _do(_copy("good", "s"), lambda w: (w / "s/images/left_passive.png").unlink(),
                 lambda w: os.symlink(w / "good2/images/left_passive.png", w / "s/images/left_passive.png")),
             scratch=True, watch=("o",)),
        Case("measured: export --shift 63 (below the smallest disparity)", ["export", "ds", "--format", "middlebury",
                                                                            "--shift", "63", "--out", "o"],
             ("--shift",), scratch=True, watch=("o",)),
        Case("measured: export --shift auto keeps disparities >= 1 px", ["export", "ds", "--format", "middlebury",
                                                                         "--shift", "auto", "--out", "o"], (),
             scratch=True, expect_rc=0, check=_disparities_positive),
        Case("measured: export --shift 61 keeps disparities >= 1 px", ["export", "ds", "--format", "middlebury",
                                                                       "--shift", "61", "--out", "o"], (),
             scratch=True, expect_rc=0, check=_disparities_positive),
        Case("measured: report of an edited results.csv", ["report", "ds", "--out", "o"], ("results.csv",),
             _results_table_edited("results.csv"), scratch=True, watch=("o",)),
        Case("measured: report of an edited results.parquet", ["report", "ds", "--out", "o"], ("results.parquet",),
             _results_table_edited("results.parquet"), scratch=True, watch=("o",)),
        Case("measured: platebench.results() of an edited results.parquet", list(results_api), ("results.parquet",),
             _results_table_edited("results.parquet"), scratch=True, python=True),
        Case("measured: platebench.results() of an edited results.csv", list(results_api), ("results.csv",),
             _results_table_edited("results.csv"), scratch=True, python=True),
        Case("measured: info --check-lock with a shadowing numpy-99.0.dist-info", ["info", "--check-lock"],
             ("numpy", "shadowed"), _write("fake/numpy-99.0.dist-info/METADATA",
                                           "Metadata-Version: 2.1\nName: numpy\nVersion: 99.0\n"),
             scratch=True, env={"PYTHONPATH": "{W}/fake"}, one_line=False),
        Case("measured: a score in millimetres carries its hint", ["evaluate", "good", "--points", "mm.csv"], (),
             lambda w: np.savetxt(w / "mm.csv", np.loadtxt(w / "good_recon/points.csv", delimiter=",",
                                                           skiprows=1)[:, -3:] * 1000, delimiter=",",
                                  header="x,y,z", comments=""),
             scratch=True, expect_rc=0, check=_hinted),
    ]


def _exit0() -> list[Case]:
    spec = ("[sweep]\nmethods = [\"misbehave:raises\"]\n[base.scene]\nwidth = 160\nheight = 120\n[base.render]\n"
            "spp = 1\n[grid]\nbend_deg = [0, 10, 20]\n")
    return [
        Case("measured: a sweep in which every sample fails", ["sweep", "fail.toml", "--out", "o", "--workers", "0",
                                                               "--no-progress"], ("failed",),
             _do(_plugins, _write("fail.toml", spec)), scratch=True, expect_rc=1, env=PLUGIN_ENV, timeout_s=300),
        Case("measured: compare in which every method fails", ["compare", "good", "--methods",
                                                               "misbehave:raises,misbehave:exits_3", "--out", "o",
                                                               "--method-time-limit-s", "20"], ("failed",),
             _plugins, scratch=True, expect_rc=1, env=PLUGIN_ENV),
        Case("measured: compare --recon nonexist", ["compare", "good", "--methods", "paper", "--recon", "nonexist",
                                                    "--out", "o"], ("nonexist",), scratch=True, watch=("o",)),
        Case("measured: export of an interrupted dataset", ["export", "ds8", "--format", "middlebury", "--out", "o"],
             ("--allow-incomplete",), _interrupted_dataset, scratch=True, watch=("o",), timeout_s=300),
        Case("measured: export --allow-incomplete of an interrupted dataset says so",
             ["export", "ds8", "--format", "middlebury", "--out", "o", "--allow-incomplete"],
             (("of 8", "incomplete", "interrupted"),), _interrupted_dataset, scratch=True, expect_rc=0,
             timeout_s=300),
    ]


def _hangs() -> list[Case]:
    loop_spec = ("[sweep]\nmethods = [\"loops_on_import:f\"]\nmethod_time_limit_s = 5\n[base.scene]\nwidth = 160\n"
                 "height = 120\n[base.render]\nspp = 1\n[grid]\nbend_deg = [0]\n")
    big = ["--width", "160", "--height", "120"]
    return [
        Case("measured: compare with a plug-in that loops at import", ["compare", "good", "--methods",
                                                                       "loops_on_import:f", "--out", "o",
                                                                       "--method-time-limit-s", "5"],
             ("no answer within the time limit",), _plugins, scratch=True, expect_rc=1, env=PLUGIN_ENV,
             timeout_s=90),
        Case("measured: sweep with a plug-in that loops at import", ["sweep", "loop.toml", "--out", "o", "--workers",
                                                                     "0", "--no-progress"], ("failed",),
             _do(_plugins, _write("loop.toml", loop_spec)), scratch=True, expect_rc=1, env=PLUGIN_ENV, timeout_s=120),
        Case("measured: render --spp 8192, SIGINT at 4 s", ["render", "--out", "o", *big, "--spp", "8192"],
             (("interrupted", "SIGINT", "Ctrl-C"),), scratch=True, expect_rc=130, signal=(signal.SIGINT, 4.0, 5.0), watch=("o",)),
        Case("measured: render --spp 65536, SIGTERM at 8 s", ["render", "--out", "o", *big, "--spp", "65536"],
             ("SIGTERM",), scratch=True, expect_rc=143, signal=(signal.SIGTERM, 8.0, 5.0), watch=("o",)),
        Case("measured: render --spp 65536, SIGINT at 3 s", ["render", "--out", "o", *big, "--spp", "65536"],
             (("interrupted", "SIGINT", "Ctrl-C"),), scratch=True, expect_rc=130, signal=(signal.SIGINT, 3.0, 5.0), watch=("o",)),
        Case("measured: sense --spp 65536, SIGTERM at 8 s", ["sense", "--out", "o", *big, "--spp", "65536"],
             ("SIGTERM",), scratch=True, expect_rc=143, signal=(signal.SIGTERM, 8.0, 5.0), watch=("o",)),
        Case("measured: sweep at spp 65536, SIGTERM at 8 s", ["sweep", "big.toml", "--out", "o", "--workers", "0",
                                                              "--no-progress"], ("SIGTERM",),
             _write("big.toml", "[base.scene]\nwidth = 160\nheight = 120\n[base.render]\nspp = 65536\n"
                    "[grid]\nbend_deg = [0, 10]\n"), scratch=True, expect_rc=143, signal=(signal.SIGTERM, 8.0, 10.0)),
        Case("measured: a plug-in's child process does not outlive compare", ["compare", "good", "--methods",
                                                                              "spawner:f", "--out", "o",
                                                                              "--method-time-limit-s", "3"],
             ("no answer within the time limit",), _plugins, scratch=True, expect_rc=1, env=PLUGIN_ENV,
             check=_no_orphan, timeout_s=90),
    ]


def _data_loss() -> list[Case]:
    c = []
    edits = (("render", "good", "calib.json", ["render", "--out", "good", "--overwrite", *R]),
             ("render", "good", "images/left_active.png", ["render", "--out", "good", "--overwrite", *R]),
             ("render", "good", "sample.json", ["render", "--out", "good", "--overwrite", *R]),
             ("reconstruct", "good_recon", "recon.json", ["reconstruct", "good", "--out", "good_recon",
                                                          "--overwrite"]),
             ("reconstruct", "good_recon", "points.csv", ["reconstruct", "good", "--out", "good_recon",
                                                          "--overwrite"]),
             ("sweep", "ds", "results.csv", ["sweep", "ds.toml", "--out", "ds", "--overwrite", "--workers", "0",
                                             "--no-progress"]),
             ("sweep", "ds", "samples/0000/result.json", ["sweep", "ds.toml", "--out", "ds", "--overwrite",
                                                          "--workers", "0", "--no-progress"]))
    for cmd, folder, rel, argv in edits:
        c.append(Case(f"measured: {cmd} --overwrite over an edited {rel}", argv,
                      ((Path(rel).name, "not a PlateBench"),),
                      _write(f"{folder}/{rel}", '{"edited": true}\n'), scratch=True))
    c.append(Case("measured: compare --overwrite over an edited compare.json",
                  ["compare", "good", "--methods", "sgbm", "--out", "cmp", "--overwrite"], ("compare.json",),
                  _do(_cli("compare", "good", "--methods", "sgbm", "--out", "cmp"),
                      _write("cmp/compare.json", '{"edited": true}\n')), scratch=True))
    c.append(Case("measured: report --overwrite over an edited index.html",
                  ["report", "good", "--out", "rep", "--overwrite"], ("index.html",),
                  _do(_cli("report", "good", "--out", "rep"), _write("rep/index.html", "<p>my notes</p>\n")),
                  scratch=True))
    return c


def _tracebacks() -> list[Case]:
    deep = "a = " + "[" * 50000 + "]" * 50000 + "\n"
    c = [Case("measured: render --width 2048 --height 2048 --spp 1025 renders (SIGTERM at 20 s)",
              ["render", "--out", "o", "--width", "2048", "--height", "2048", "--spp", "1025"], ("SIGTERM",),
              scratch=True, expect_rc=143, signal=(signal.SIGTERM, 20.0, 5.0), watch=("o",), memory_gb=16.0)]
    for cmd, argv in (("render", ["render", "--config", "deep.toml", "--out", "o", *R]),
                      ("sense", ["sense", "--config", "deep.toml", "--out", "o", *R]),
                      ("calibrate", ["calibrate", "--config", "deep.toml", "--out", "o", *R]),
                      ("sweep", ["sweep", "deep.toml", "--out", "o"])):
        c.append(Case(f"measured: {cmd} of a TOML nested 50000 deep", argv, ("deep.toml", "nested"),
                      _write("deep.toml", deep), scratch=True, watch=("o",)))
    for key in ("length_m", "width_m"):
        for v in ("1e300", "1e-300", "0.0", "-0.1", "inf"):
            other = "width_m = 0.07" if key == "length_m" else "length_m = 0.1"
            c.append(Case(f"measured: render a plate of {key} = {v}", ["render", "--config", "p.toml", "--out", "o",
                                                                       *R], ("p.toml", key),
                          _write("p.toml", f"[plate]\n{key} = {v}\n{other}\n"), scratch=True, watch=("o",)))
    c.append(Case("measured: sweep of a plate of length_m = 1e300", ["sweep", "p.toml", "--out", "o", "--workers", "0"],
                  ("p.toml", "length_m"), _write("p.toml", "[base.plate]\nlength_m = 1e300\nwidth_m = 0.07\n"
                                                           "[grid]\nbend_deg = [0, 10]\n"), scratch=True, watch=("o",)))
    c.append(Case("measured: sweep --dry-run of a plate of length_m = 1e300", ["sweep", "p.toml", "--dry-run"],
                  ("p.toml", "length_m"), _write("p.toml", "[base.plate]\nlength_m = 1e300\nwidth_m = 0.07\n"
                                                           "[grid]\nbend_deg = [0, 10]\n"), scratch=True))
    c.append(Case("measured: sweep grid bend_deg = [1e-12]", ["sweep", "b.toml", "--out", "o", "--workers", "0"],
                  ("bend_deg",), _write("b.toml", "[base.scene]\nwidth = 160\nheight = 120\n[grid]\n"
                                                  "bend_deg = [1e-12]\n"), scratch=True, watch=("o",)))
    for cmd, argv in (("render", ["render", *R, "--out"]), ("reconstruct", ["reconstruct", "good", "--out"]),
                      ("compare", ["compare", "good", "--methods", "sgbm", "--out"]),
                      ("evaluate", ["evaluate", "good", "good_recon", "--out"]),
                      ("export", ["export", "ds", "--format", "kitti", "--out"]), ("report", ["report", "ds", "--out"]),
                      ("sweep", ["sweep", "ds.toml", "--workers", "0", "--out"]), ("sense", ["sense", *R, "--out"]),
                      ("calibrate", ["calibrate", *R, "--out"]),
                      ("study", ["study", "false-boundary", "--limit", "1", "--out"])):
        c.append(Case(f"measured: {cmd} --out a non-UTF-8 name", [*argv, NOT_UTF8], ("not UTF-8",), scratch=True,
                      watch=(NOT_UTF8,)))
    c.append(Case("measured: render --config a non-UTF-8 name", ["render", "--config", NOT_UTF8, "--out", "o", *R],
                  ("not UTF-8",), _write(NOT_UTF8, "[scene]\nwidth = 160\n"), scratch=True, watch=("o",)))
    for name, flags in (("sgbm", ["--min-depth-mm", "100", "--max-depth-mm", "110"]),
                        ("sgbm-passive", ["--min-depth-mm", "100", "--max-depth-mm", "110"]),
                        ("sgbm", ["--min-depth-mm", "1", "--max-depth-mm", "1000000"])):
        c.append(Case(f"measured: compare --methods {name} {' '.join(flags)}",
                      ["compare", "good", "--methods", name, *flags, "--out", "o"], (f"{name}:",), scratch=True,
                      watch=("o",)))
    c.append(Case("measured: compare --methods phase-opencv on a 160 x 120 sample",
                  ["compare", "good", "--methods", "phase-opencv", "--out", "o"], ("phase-opencv", "recorded"),
                  scratch=True, expect_rc=1))  # OpenCV's phase map refuses these captures: a recorded failure
    tiny = _cli("render", "--out", "{W}/tiny", "--width", "64", "--height", "48", "--spp", "1")
    for m in ("paper", "graycode", "graycode-subpx", "phase", "sgbm", "phase-opencv", "sgbm-passive"):
        c.append(Case(f"measured: compare --methods {m} on a 64 x 48 sample",
                      ["compare", "tiny", "--methods", m, "--out", "o"], (m,), tiny, scratch=True, expect_rc=-1))
    for cmd, argv in (("render", ["render", "--out", "o", *R]), ("info", ["info"]),
                      ("sweep --example --dry-run", ["sweep", "--example", "bend_sweep", "--dry-run"]),
                      ("report", ["report", "{W}/good", "--out", "{W}/o"]),
                      ("reconstruct", ["reconstruct", "{W}/good", "--out", "{W}/o"])):
        c.append(Case(f"measured: {cmd} from a deleted working directory", argv, ("working directory",),
                      scratch=True, **_deleted_cwd()))
    ascii_env = {"LC_ALL": "C", "PYTHONIOENCODING": "ascii"}
    for cmd, argv, made in (("render", ["render", *R, "--out", NON_ASCII], NON_ASCII),
                            ("reconstruct", ["reconstruct", "good", "--out", NON_ASCII], NON_ASCII),
                            ("report", ["report", "good", "--out", NON_ASCII], f"{NON_ASCII}/index.html"),
                            ("evaluate", ["evaluate", "good", "good_recon", "--out", f"{NON_ASCII}.json"],
                             f"{NON_ASCII}.json"),
                            ("export", ["export", "ds", "--format", "kitti", "--out", NON_ASCII], NON_ASCII)):
        c.append(Case(f"measured: {cmd} to a non-ASCII name under LC_ALL=C PYTHONIOENCODING=ascii", argv, (),
                      scratch=True, expect_rc=0, env=ascii_env, check=_exists(made)))
    return c


def _messages() -> list[Case]:
    c = [
        Case("measured: compare --methods nosuchmethod after a comparison", ["compare", "good", "--methods",
                                                                             "nosuchmethod"], ("unknown method",),
             _cli("compare", "good", "--methods", "sgbm"), scratch=True),
        Case("measured: compare --methods nosuchmethod on a fresh sample", ["compare", "good", "--methods",
                                                                            "nosuchmethod"], ("unknown method",),
             scratch=True, watch=("good/compare",)),
        Case("measured: evaluate with the arguments swapped", ["evaluate", "good_recon", "good"], ("swapped",),
             scratch=True),
        Case("measured: an over-long PFM is not called truncated", ["evaluate", "good", "--disparity", "long.pfm"],
             ("long.pfm", "longer"),
             lambda w: (w / "long.pfm").write_bytes((w / "good/gt/disp0GT.pfm").read_bytes() + b"\0" * 76800),
             scratch=True),
        Case("measured: the distortion error names the size given", ["render", "--config", "d.toml", "--out", "o",
                                                                     *R], ("160x120",),
             _write("d.toml", "[scene.distortion]\nk1 = -3.0\n"), scratch=True, watch=("o",)),
        Case("measured: render > /dev/full keeps its status and its output", ["render", "--out", "o", *R], (),
             scratch=True, expect_rc=0, stdout_to="/dev/full", check=_exists("o/sample.json")),
        Case("measured: sweep --example bend_sweep --dry-run from any folder",
             ["sweep", "--example", "bend_sweep", "--dry-run"], (), scratch=True, expect_rc=0, cwd="good",
             check=_lists_samples),
        Case("measured: study --axes 0 --families cylinder runs only axis-0 plates",
             ["study", "false-boundary", "--axes", "0", "--families", "cylinder", "--dry-run", "--out", "st"], (),
             expect_rc=0, check=_axes_only("0")),
        Case("measured: study --axes 30 runs only axis-30 cylinders",
             ["study", "false-boundary", "--axes", "30", "--families", "cylinder", "--dry-run", "--out", "st"], (),
             expect_rc=0, check=_axes_only("30")),
    ]
    if _can_mount():
        c.append(Case("measured: a full disk under the lock names the path", ["render", "--out", "full/o", *R],
                      ("full", "no space left"), _full_tmpfs("full"), scratch=True, teardown=_umount("full")))
    return c


@register_cases
def measured_cases() -> list[Case]:
    """The measured failure kinds (module doc), each with what must happen instead."""
    c = _silent_wrong() + _exit0() + _hangs() + _data_loss() + _tracebacks() + _messages()
    for x in c:
        x.family = "measured"
    return c
