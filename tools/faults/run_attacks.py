"""Attacks on a run rather than on its inputs, classified like the harness's cases
(``tools/faults/bad_inputs.py``, which runs them after its own): an interrupt (SIGINT, SIGTERM) at a
random moment of render, reconstruct, report and sweep; plug-ins that exit, raise, crash, hang or
return what is not an output, in ``compare`` and in a sweep; a full disk and a file-size limit
during a sweep and a render; a lost or damaged ``manifest.json``; a sweep killed with -9.

Each attack is one ``Outcome``: *clean* when the command did what it must (the exit status the
attack expects: 130 / 143 for a signal, 2 with one line for an error of the run, 0 with the
failure recorded where the work goes on; the dataset's state; no committed sample redone or lost),
*traceback* for any "Traceback" or "Exception ignored" on stderr, *leftovers* for temporary names
and lock files left anywhere in the scratch directory. Every attack works in its own folder under
``WORK/attacks`` (the harness's scratch directory, with its ``good`` sample), so the destructive
ones touch nothing else.
"""
from __future__ import annotations

import json
import os
import random
import resource
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

SEED = 34  # the signal moments are drawn from it: the same attacks on every run
SMALL = "[scene]\nwidth = 160\nheight = 120\n[render]\nspp = 2\n"
STATUS = {signal.SIGINT: 130, signal.SIGTERM: 143}

MISBEHAVING_PLUGINS = '''
"""Plug-ins that misbehave in every way a plug-in can (and one that works)."""
import os
import sys
import time

import numpy as np
from platebench.bench.run.plugins import Depth, Disparity, Mesh, Points


def _hw(inputs):
    return inputs.images["left_passive"].shape


def good(inputs):
    """A plane at the depth of the world origin."""
    z0 = float(inputs.rig.left.depth(np.zeros((1, 3)))[0])
    return Depth(np.full(_hw(inputs), z0), metrics={"plane_mm": z0 * 1e3})


def exits_0(inputs):
    sys.exit(0)


def exits_3(inputs):
    sys.exit(3)


def raises(inputs):
    raise ValueError("no disparity today")


def interrupts(inputs):
    raise KeyboardInterrupt


def hard_exit(inputs):
    os._exit(0)


def crashes(inputs):
    import ctypes
    ctypes.string_at(0)


def hangs(inputs):
    while True:  # deaf to everything but SIGKILL
        try:
            time.sleep(10)
        except BaseException:
            pass


def complex_map(inputs):
    return Disparity(np.full(_hw(inputs), 500.0 + 1j))


def bool_map(inputs):
    return Disparity(np.ones(_hw(inputs), bool))


def text_points(inputs):
    return Points([["a", "b", "c"]])


def object_points(inputs):
    return Points(np.array([[None, 1.0, 2.0]], dtype=object))


def wrong_type(inputs):
    return {"depth": 0.4}


def text_metric(inputs):
    return Depth(np.full(_hw(inputs), 0.4), metrics={"note": "fine"})


def bad_faces(inputs):
    import trimesh
    return Mesh(trimesh.Trimesh(vertices=np.eye(3), faces=np.array([[0, 1, 7]]), process=False))


def flat_points(inputs):
    return Points(np.zeros((5, 2)))
'''
PLUGIN_MODULE = "misbehave"
# method -> what its one-line failure must say (with a time limit of a few seconds: "hangs" is stopped by it)
FAILURES = {
    "misbehave:exits_0": "called sys.exit(0)",
    "misbehave:exits_3": "called sys.exit(3)",
    "misbehave:raises": "raised ValueError: no disparity today",
    "misbehave:interrupts": "raised KeyboardInterrupt",
    "misbehave:hard_exit": "exited with status 0",
    "misbehave:crashes": "killed by SIGSEGV",
    "misbehave:hangs": "no answer within the time limit",
    "misbehave:complex_map": "dtype complex128 (complex numbers)",
    "misbehave:bool_map": "dtype bool",
    "misbehave:text_points": "dtype <U1 (text)",
    "misbehave:object_points": "dtype object",
    "misbehave:wrong_type": "returned dict: return one of",
    "misbehave:text_metric": "metric 'note' = 'fine' (str)",
    "misbehave:bad_faces": "faces index vertices 0 to 7 of 3",
    "misbehave:flat_points": "points of shape (5, 2)",
    "numpy:save": "raised TypeError",
}
# module -> (its source, what the failure of its method "module:f" must say): each fails at import, in the plug-in's
# process, within the method's time limit, on every sample
IMPORT_FAILURES = {
    "exits_on_import": ("import sys\nsys.exit(3)\n", "cannot import module 'exits_on_import' (sys.exit(3))"),
    "dies_on_import": ("import os\nos._exit(0)\n", "exited with status 0"),
    "loops_on_import": ("while True:\n    pass\n", "no answer within the time limit"),
}


def write_plugins(folder: Path) -> dict:
    """The misbehaving plug-ins as modules in ``folder``; returns an environment with it on PYTHONPATH."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{PLUGIN_MODULE}.py").write_text(MISBEHAVING_PLUGINS)
    for name, (text, _) in IMPORT_FAILURES.items():
        (folder / f"{name}.py").write_text(text)
    env = dict(os.environ)
    env.pop("PLATEBENCH_DEBUG", None)
    env["PYTHONPATH"] = os.pathsep.join([str(folder), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


# ----------------------------------------------------------------------------- running a command
def cli_cmd(*args) -> list[str]:
    return [sys.executable, "-m", "platebench.bench.cli.main", *map(str, args)]


def handles_sigterm(pid: int) -> bool:
    """Whether process ``pid`` has a SIGTERM handler (PlateBench's; Python itself installs none), read from
    its caught-signal mask (/proc/PID/status SigCgt): before it, the signal meets its default action."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("SigCgt:"):
                return bool(int(line.split()[1], 16) & (1 << (signal.SIGTERM - 1)))
    except OSError:
        pass
    return False


@dataclass(frozen=True)
class SignalRun:
    """A command signalled at ``moment`` seconds: its exit status and stderr, whether it had finished
    first, and whether PlateBench's handlers were in place when the signal was sent."""

    rc: int
    stderr: str
    finished_first: bool
    started: bool


def signal_run(argv: list, sig: int, moment: float, cwd: Path, env: dict | None = None) -> SignalRun:
    """Run ``platebench ARGV`` and send it ``sig`` ``moment`` seconds after it started."""
    p = subprocess.Popen(cli_cmd(*argv), cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         text=True)
    time.sleep(moment)
    started = handles_sigterm(p.pid)
    finished_first = p.poll() is not None
    if not finished_first:
        p.send_signal(sig)
    _, err = p.communicate(timeout=600)
    return SignalRun(p.returncode, err, finished_first, started)


def files_of(d: Path) -> set:
    return {p.relative_to(d).as_posix() for p in Path(d).rglob("*") if p.is_file()}


def leftovers(d: Path) -> list:
    """Temporary names and lock files anywhere under ``d``."""
    from platebench.bench.io.atomic import is_temp_name  # noqa: PLC0415
    return sorted(str(p.relative_to(d)) for p in Path(d).rglob("*") if is_temp_name(p.name) or p.name.endswith(".lock"))


def half_written(out: Path, reference: Path, kind: str) -> str | None:
    """Why ``out`` (what an interrupted command left) is half-written; None when it is absent, or complete:
    a dataset whose manifest is "interrupted" or "complete" and whose committed samples all verify, or the
    same files as the ``reference`` output of a complete run."""
    from platebench.bench.sweep.dataset import read_manifest, stale_files, validate_result  # noqa: PLC0415
    if not out.exists():
        return None
    if kind == "sweep":
        m = read_manifest(out)
        if m is None:  # killed before its first manifest: only the skeleton that --resume starts again
            return "committed samples but no manifest" if any((out / "samples").glob("*/result.json")) else None
        if m["state"] not in ("interrupted", "complete"):
            return f"manifest state {m['state']}"
        bad = [e["id"] for e in m["samples"] if e["status"] != "pending"
               and not validate_result(out, e["id"], manifest_files=e["files_sha256"])]
        return f"samples {bad} do not verify" if bad else ("temporary files" if stale_files(out) else None)
    ref, got = files_of(reference), files_of(out)
    return None if got == ref else f"files differ from a complete {kind}: {sorted(ref ^ got)[:3]}"


# ----------------------------------------------------------------------------- the attacks
@dataclass(frozen=True)
class Attack:
    name: str
    run: Callable  # (folder: Path, env: dict) -> (rc, stderr, [why not clean])


def _result(rc: int, stderr: str, problems: list) -> tuple:
    return rc, stderr, [p for p in problems if p]


def _expect_one_line(r, *needles) -> str | None:
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    if r.returncode != 2 or len(lines) != 1 or not lines[0].startswith("platebench: error: "):
        return f"exit {r.returncode}, {len(lines)} stderr line(s): expected 2 and one error line"
    missing = [n for n in needles if n.lower() not in lines[0].lower()]
    return f"the error line does not say {missing[0]!r}" if missing else None


def _run(argv, folder: Path, env: dict, **kw) -> subprocess.CompletedProcess:
    return subprocess.run(cli_cmd(*argv), cwd=folder, env=env, capture_output=True, text=True, timeout=600, **kw)


def _spec(folder: Path, bends, methods=("paper",), limit=None) -> Path:
    lines = ["[sweep]", 'name = "attack"', f"methods = {json.dumps(list(methods))}"]
    if limit is not None:
        lines.append(f"method_time_limit_s = {limit}")
    path = folder / "spec.toml"
    path.write_text("\n".join(lines) + "\n[base.scene]\nwidth = 160\nheight = 120\n[base.render]\nspp = 2\n"
                    f"[grid]\nbend_deg = {json.dumps(list(bends))}\n")
    return path


def _state(ds: Path) -> dict:
    from platebench.bench.sweep.dataset import read_manifest  # noqa: PLC0415
    m = read_manifest(ds) or {}
    return {"state": m.get("state"), **(m.get("counts") or {})}


def _result_mtimes(ds: Path) -> dict:
    return {p.parent.name: p.stat().st_mtime_ns for p in (ds / "samples").glob("*/result.json")}


def _signals(command: str) -> Callable:
    """One complete run (its duration and output: the reference), then SIGINT and SIGTERM each at a moment
    drawn from the run's duration; every signalled run must end 130 / 143 with nothing half-written."""
    def attack(folder: Path, env: dict):
        good = folder.parent.parent / "good"
        (folder / "small.toml").write_text(SMALL)
        spec = _spec(folder, [20])
        argv = {"render": ["render", "--config", folder / "small.toml"], "reconstruct": ["reconstruct", good],
                "sweep": ["sweep", spec, "--workers", 1, "--no-progress"], "report": ["report", folder / "ds"]}
        if command == "report":
            _run(["sweep", spec, "--out", folder / "ds", "--workers", 0, "--no-progress"], folder, env)
        t0 = time.monotonic()
        ref = _run([*argv[command], "--out", folder / "ref"], folder, env)
        seconds = time.monotonic() - t0
        if ref.returncode:
            return _result(ref.returncode, ref.stderr, [f"the complete run failed: exit {ref.returncode}"])
        rng = random.Random(f"{SEED}-{command}")
        problems, errs, rcs = [], [], []
        for sig in (signal.SIGINT, signal.SIGTERM):
            moment = rng.uniform(0.05, 0.8 * seconds)
            out = folder / f"out-{sig.name}"
            r = signal_run([*argv[command], "--out", out], sig, moment, folder, env)
            where = f"{sig.name} at {moment:.2f} s"
            if r.finished_first:
                continue
            rcs.append(r.rc)
            errs.append(r.stderr if r.started else "")  # before start-up, Python's own default handling
            if r.started and r.rc != STATUS[sig]:
                problems.append(f"{where}: exit {r.rc}, expected {STATUS[sig]}")
            elif not r.started and r.rc not in (STATUS[sig], -sig):
                problems.append(f"{where} (before start-up): exit {r.rc}")
            problems.append(half_written(out, folder / "ref", command))
        if not rcs:
            problems.append(f"no run was still going when signalled (a complete run takes {seconds:.2f} s)")
        return _result(max(rcs, key=abs, default=0), "".join(errs), problems)
    return attack


def _plugins_in_compare(folder: Path, env: dict):
    good = folder.parent.parent / "good"
    methods = ["misbehave:good", *FAILURES]
    r = _run(["compare", good, "--methods", ",".join(methods), "--out", folder / "cmp", "--method-time-limit-s", 3],
             folder, env)
    problems = [] if r.returncode == 1 else [f"exit {r.returncode}, expected 1 (failures recorded)"]
    if r.returncode == 1:
        doc = json.loads((folder / "cmp" / "compare.json").read_text())["methods"]
        problems.append(None if doc["misbehave:good"]["status"] == "ok" else "the good plug-in did not run")
        problems += [f"{m}: {doc.get(m)}" for m, said in FAILURES.items()
                     if doc.get(m, {}).get("status") != "failed" or said not in (doc[m].get("error") or "")]
    return _result(r.returncode, r.stderr, problems)


def _plugin_fails_on_import(folder: Path, env: dict):
    methods = [f"{module}:f" for module in IMPORT_FAILURES]
    r = _run(["compare", folder.parent.parent / "good", "--methods", ",".join(methods), "--out", folder / "cmp",
              "--method-time-limit-s", 3], folder, env)
    problems = [] if r.returncode == 1 else [f"exit {r.returncode}, expected 1 (failures recorded)"]
    if r.returncode == 1:
        doc = json.loads((folder / "cmp" / "compare.json").read_text())["methods"]
        problems += [f"{m}: {doc.get(m)}" for m, (_, said) in zip(methods, IMPORT_FAILURES.values())
                     if doc.get(m, {}).get("status") != "failed" or said not in (doc[m].get("error") or "")]
    return _result(r.returncode, r.stderr, problems)


def _plugins_in_a_sweep(folder: Path, env: dict):
    methods = ["misbehave:good", "misbehave:exits_0", "misbehave:exits_3", "misbehave:hangs", "misbehave:crashes"]
    ds = folder / "ds"
    r = _run(["sweep", _spec(folder, [10], methods, limit=3), "--out", ds, "--workers", 1, "--no-progress"], folder,
             env)
    problems = [] if r.returncode == 1 else [f"exit {r.returncode}, expected 1 (failures recorded)"]
    if r.returncode == 1:
        from platebench.bench.sweep.dataset import read_results  # noqa: PLC0415
        rows = {x["method"]: x for x in read_results(ds).to_pylist()}
        st = _state(ds)
        problems.append(None if st["state"] == "complete" and st["failed"] == 1 else f"manifest {st}")
        problems += [f"{m}: {rows.get(m, {}).get('error')}" for m in methods[1:]
                     if FAILURES[m] not in (rows.get(m, {}).get("error") or "")]
    return _result(r.returncode, r.stderr, problems)


def _error_of_the_run(r, ds: Path, *needles) -> list:
    """What an error of the run must be: one line naming the dataset and the cause, the manifest
    "interrupted", no sample failed, no attempt left."""
    st = _state(ds)
    return [_expect_one_line(r, str(ds), *needles, "--resume"),
            None if st.get("state") == "interrupted" and st.get("failed") == 0 else f"manifest {st}",
            "an attempt was left" if any(p.name.startswith(".") for p in (ds / "samples").iterdir()) else None]


def _resumed(ds: Path, spec: Path, folder: Path, env: dict, n: int) -> list:
    r = _run(["sweep", spec, "--out", ds, "--workers", 0, "--no-progress", "--resume"], folder, env)
    st = _state(ds)
    return [None if r.returncode == 0 and st == {"state": "complete", "total": n, "ok": n, "failed": 0,
                                                  "pending": 0} else f"--resume: exit {r.returncode}, manifest {st}"]


def _file_size_limit(folder: Path, env: dict):
    spec, ds = _spec(folder, [0, 20]), folder / "ds"
    limit = 64 * 1024  # the images' EXR files are larger; the manifest and the tables are not
    r = _run(["sweep", spec, "--out", ds, "--workers", 0, "--no-progress"], folder, env,
             preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit)))
    return _result(r.returncode, r.stderr, _error_of_the_run(r, ds, "file too large") + _resumed(ds, spec, folder,
                                                                                                  env, 2))


def _namespace_ok() -> bool:
    return shutil.which("unshare") is not None and subprocess.run(
        ["unshare", "-rm", "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt"], capture_output=True).returncode == 0


_FULL_DISK_DRIVER = """
import json, os, subprocess, sys
from platebench.bench.sweep.dataset import read_manifest
argv, resume, mnt, out = json.loads(sys.argv[1])
def state():
    m = read_manifest(os.path.join(mnt, "ds")) or {}
    names = os.listdir(os.path.join(mnt, "ds", "samples")) if os.path.isdir(os.path.join(mnt, "ds", "samples")) else []
    return [m.get("state"), m.get("counts"), names]
r = subprocess.run(argv, capture_output=True, text=True)
doc = {"rc": r.returncode, "stderr": r.stderr, "state": state(), "left": os.listdir(mnt)}
if resume:
    subprocess.run(["mount", "-o", "remount,size=64m", mnt], check=True)
    doc["resume_rc"] = subprocess.run(resume, capture_output=True).returncode
    doc["resumed"] = state()
open(out, "w").write(json.dumps(doc))
"""


def _full_disk(command: str) -> Callable:
    """A small tmpfs (a user namespace: 1 MiB under a sweep, which fills it, 200 KiB under a render) ; then,
    for the sweep, more space and --resume. Without user namespaces, a file-size limit (RLIMIT_FSIZE:
    EFBIG) stands in for it."""
    def attack(folder: Path, env: dict):
        (folder / "small.toml").write_text(SMALL)
        if not _namespace_ok():
            if command == "sweep":
                return _file_size_limit(folder, env)
            limit = 64 * 1024
            r = _run(["render", "--config", folder / "small.toml", "--out", folder / "s"], folder, env,
                     preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit)))
            return _result(r.returncode, r.stderr, [_expect_one_line(r, "file too large"),
                                                    "output left" if (folder / "s").exists() else None])
        mnt = folder / "mnt"
        mnt.mkdir()
        spec = _spec(folder, [0, 10, 20])
        argv = cli_cmd(*(["sweep", spec, "--out", mnt / "ds", "--workers", 1, "--no-progress"] if command == "sweep"
                         else ["render", "--config", folder / "small.toml", "--out", mnt / "s"]))
        resume = cli_cmd("sweep", spec, "--out", mnt / "ds", "--workers", 1, "--no-progress", "--resume") \
            if command == "sweep" else None
        (folder / "driver.py").write_text(_FULL_DISK_DRIVER)
        job = json.dumps([argv, resume, str(mnt), str(folder / "outcome.json")])
        size = "1m" if command == "sweep" else "200k"
        ns = subprocess.run(["unshare", "-rm", "sh", "-ec", f"mount -t tmpfs -o size={size} tmpfs {mnt}\n"
                             f"exec {sys.executable} {folder / 'driver.py'} '{job}'"], cwd=folder, env=env,
                            capture_output=True, text=True, timeout=600)
        if ns.returncode:
            return _result(ns.returncode, ns.stderr, [f"the namespace failed: {ns.stderr.strip()[-200:]}"])
        doc = json.loads((folder / "outcome.json").read_text())
        r = subprocess.CompletedProcess([], doc["rc"], "", doc["stderr"])
        if command == "render":
            return _result(r.returncode, r.stderr, [_expect_one_line(r, "no space left on device"),
                                                    f"left on the disk: {doc['left']}" if doc["left"] else None])
        (st, counts, names), (st2, counts2, _) = doc["state"], doc["resumed"]
        return _result(r.returncode, r.stderr, [
            _expect_one_line(r, "no space left on device", "none of them counted as failed", "--resume"),
            None if st == "interrupted" and counts["failed"] == 0 else f"manifest {st} {counts}",
            "an attempt was left" if any(n.startswith(".") for n in names) else None,
            None if doc["resume_rc"] == 0 and st2 == "complete" and counts2["ok"] == 3
            else f"after --resume: exit {doc['resume_rc']}, {st2} {counts2}"])
    return attack


_TEMPLATE = "template-dataset"


def _dataset(folder: Path, env: dict) -> tuple[Path, Path]:
    """(a complete 3-sample dataset in ``folder``, its spec): a copy of one made once per scratch directory."""
    template = folder.parent / _TEMPLATE
    spec = _spec(folder, [0, 15, 30])
    if not (template / "manifest.json").exists():
        _run(["sweep", spec, "--out", template, "--workers", 0, "--no-progress"], folder, env)
    shutil.copytree(template, folder / "ds")
    return folder / "ds", spec


def _manifest_lost(folder: Path, env: dict):
    ds, spec = _dataset(folder, env)
    before = _result_mtimes(ds)
    (ds / "manifest.json").unlink()
    r = _run(["sweep", spec, "--out", ds, "--workers", 0, "--no-progress", "--resume"], folder, env)
    return _result(r.returncode, r.stderr, [
        None if r.returncode == 0 else f"exit {r.returncode}",
        None if "rebuilding it from its 3 samples" in r.stderr else "did not say it rebuilt the manifest",
        None if _result_mtimes(ds) == before else "samples were made again",
        None if _state(ds)["state"] == "complete" else f"manifest {_state(ds)}"])


def _manifest_damaged(folder: Path, env: dict):
    ds, spec = _dataset(folder, env)
    data = (ds / "manifest.json").read_bytes()
    (ds / "manifest.json").write_bytes(data[: len(data) // 2])
    img = ds / "samples" / "0001" / "sample" / "images" / "left_active.png"
    img.write_bytes(img.read_bytes()[:100])
    before = _result_mtimes(ds)
    r = _run(["sweep", spec, "--out", ds, "--workers", 0, "--no-progress", "--resume"], folder, env)
    after = _result_mtimes(ds)
    redone = sorted(k for k in before if after.get(k) != before[k])
    return _result(r.returncode, r.stderr, [
        None if r.returncode == 0 else f"exit {r.returncode}",
        None if redone == ["0001"] else f"made again: {redone}, expected only the damaged 0001",
        None if _state(ds)["ok"] == 3 else f"manifest {_state(ds)}"])


def _manifest_lost_overwrite(folder: Path, env: dict):
    ds, spec = _dataset(folder, env)
    (ds / "manifest.json").unlink()
    r = _run(["sweep", spec, "--out", ds, "--workers", 0, "--no-progress", "--overwrite"], folder, env)
    problems = [None if r.returncode == 0 and _state(ds)["ok"] == 3 else f"exit {r.returncode}, {_state(ds)}"]
    (ds / "manifest.json").unlink()
    (ds / "precious.txt").write_text("mine")
    r2 = _run(["sweep", spec, "--out", ds, "--workers", 0, "--overwrite"], folder, env)
    problems += [_expect_one_line(r2, "precious.txt", "refusing"),
                 None if (ds / "precious.txt").exists() and len(_result_mtimes(ds)) == 3 else "data lost"]
    return _result(r.returncode, r.stderr + r2.stderr, problems)


def _killed_sweep_report(folder: Path, env: dict):
    """kill -9 a sweep once a sample is committed: the report says "interrupted", and --resume finishes the
    dataset (taking over the killed sweep's lock, sweeping its attempts) without redoing that sample."""
    spec, ds = _spec(folder, [0, 15, 30]), folder / "ds"
    p = subprocess.Popen(cli_cmd("sweep", spec, "--out", ds, "--workers", 1, "--no-progress"), cwd=folder, env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 300
    while not _result_mtimes(ds) and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    p.kill()
    p.wait()
    before = _result_mtimes(ds)
    r = _run(["report", ds, "--out", folder / "rep"], folder, env)
    html = (folder / "rep" / "index.html").read_text() if r.returncode == 0 else ""
    problems = [None if r.returncode == 0 else f"report: exit {r.returncode}",
                None if "interrupted (the sweep that was writing it is gone" in html and ">running<" not in html
                else "the report does not say interrupted"]
    problems += _resumed(ds, spec, folder, env, 3)
    after = _result_mtimes(ds)
    problems.append(None if all(after.get(k) == v for k, v in before.items()) else "a committed sample was redone")
    return _result(r.returncode, r.stderr, problems)


def attacks() -> list[Attack]:
    out = [Attack(f"signal during {c}", _signals(c)) for c in ("render", "reconstruct", "report", "sweep")]
    out += [Attack("plug-ins misbehave in compare", _plugins_in_compare),
            Attack("plug-in fails at import (compare)", _plugin_fails_on_import),
            Attack("plug-ins misbehave in a sweep", _plugins_in_a_sweep),
            Attack("full disk during a sweep", _full_disk("sweep")),
            Attack("full disk during render", _full_disk("render")),
            Attack("file size limit during a sweep", _file_size_limit),
            Attack("manifest deleted: --resume", _manifest_lost),
            Attack("manifest truncated: --resume", _manifest_damaged),
            Attack("manifest deleted: --overwrite", _manifest_lost_overwrite),
            Attack("sweep killed -9: report", _killed_sweep_report)]
    return out


def _klass(rc: int, tb: bool, problems: list) -> tuple[str, str]:
    """The harness's class of an attack's outcome (``bad_inputs.CLASSES``) and why."""
    if tb:
        return "traceback", "a traceback on stderr"
    lost = [p for p in problems if "data lost" in p or "redone" in p or "lost" in p]
    if lost:
        return "data-loss", lost[0]
    if rc == 0 and any("expected 1" in p or "expected 2" in p for p in problems):
        return "exit0-on-failure", problems[0]
    return ("wrong-message", problems[0]) if problems else ("ok", "")


def run_attacks(select: str | None, work: Path, say=None) -> list:
    """The attacks whose name contains ``select`` (a set: whose name is in it; all: None), each in
    ``work/attacks/<n>``, as the harness's outcomes (``bad_inputs.Outcome``); ``say``: called with a
    progress line after each."""
    from tools.faults.bad_inputs import Outcome  # noqa: PLC0415
    root = Path(work) / "attacks"
    env = write_plugins(root / "plugins")
    outcomes = []
    chosen = [(i, a) for i, a in enumerate(attacks())  # select: a substring of the name, or a set of names
              if not select or (select in a.name if isinstance(select, str) else a.name in select)]
    for n, (i, a) in enumerate(chosen, 1):
        folder = root / f"{i:02d}"
        folder.mkdir(parents=True)
        t0 = time.monotonic()
        try:
            rc, err, problems = a.run(folder, env)
        except subprocess.TimeoutExpired as e:
            rc, err, problems = 124, "", [f"hang: {e}"]
        except Exception as e:  # noqa: BLE001  (the harness reports it as the attack's outcome)
            rc, err, problems = -1, "", [f"the attack itself failed: {type(e).__name__}: {e}"]
        tb = "Traceback" in err or "Exception ignored" in err
        lines = problems or [ln for ln in err.splitlines() if ln.strip()][:1] or ["(nothing on stderr)"]
        klass, why = ("hang", problems[0]) if rc == 124 and problems and problems[0].startswith("hang") \
            else _klass(rc, tb, problems)
        left = leftovers(folder)
        if klass == "ok" and left:
            klass, why = "leftover", f"left behind: {left[:3]}"
        outcomes.append(Outcome(a.name, rc, lines, klass == "ok", tb, left, time.monotonic() - t0,
                                klass=klass, why=why, family="attack", expect_rc=-1))
        if say:
            say(f"[attack {n}/{len(chosen)}] {klass:16s} {outcomes[-1].seconds:6.1f} s  {a.name}"
                + (f"  ({why[:100]})" if why else ""))
    return outcomes
