"""Errors of the run, not of its samples, and a dataset's recovery.

* A full disk (ENOSPC), a read-only output (EROFS) or a file-size limit (EFBIG) during a sweep is an
  error of the RUN: one line, exit 2, the manifest "interrupted", no sample counted as failed; once
  the cause is gone ``--resume`` finishes the sweep without redoing a committed sample. A full disk
  during ``render`` (OpenEXR's RuntimeError) is one line too, with nothing left behind.
  Real file systems: a small tmpfs in a user namespace (``unshare -rm``), remounted bigger or
  read-only; and the process's own RLIMIT_FSIZE, which needs no namespace.
* A sweep killed with -9 reads "interrupted" in ``platebench report``, not "running".
* A lost or damaged ``manifest.json`` is rebuilt by ``--resume`` from the samples' own ``result.json``
  files and checksums (said so; only what cannot be verified is made again), and ``--overwrite``
  replaces such a dataset; a folder that holds anything a sweep does not write is still refused.
"""
from __future__ import annotations

import json
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import tomli_w

from platebench.bench.sweep.dataset import RESULT, read_manifest, read_results, stale_files, validate_result
from test_reliability import cli_cmd, n_committed, wait_for

REPO = Path(__file__).resolve().parents[1]
SMALL = {"scene": {"width": 160, "height": 120}, "render": {"spp": 2, "seed": 11}}
PY = sys.executable


def write_spec(path: Path, bends, name="errors") -> Path:
    path.write_text(tomli_w.dumps({"sweep": {"name": name}, "base": SMALL, "grid": {"bend_deg": list(bends)}}))
    return path


def cli(*args, timeout=300, **kw):
    return subprocess.run([PY, "-m", "platebench.bench.cli.main", *map(str, args)], cwd=REPO, capture_output=True,
                          text=True, timeout=timeout, **kw)


def mtimes(out: Path) -> dict:
    return {p.parent.name: p.stat().st_mtime_ns for p in (out / "samples").glob(f"*/{RESULT}")}


def userns_tmpfs() -> bool:
    return shutil.which("unshare") is not None and subprocess.run(
        ["unshare", "-rm", "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt"], capture_output=True).returncode == 0


def in_namespace(script: str, timeout=600) -> dict:
    """Run ``script`` (sh) in a private mount namespace; it prints one JSON object per line, merged here."""
    r = subprocess.run(["unshare", "-rm", "sh", "-ec", script], cwd=REPO, capture_output=True, text=True,
                       timeout=timeout)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    out = {}
    for line in r.stdout.splitlines():
        if line.startswith("{"):
            out.update(json.loads(line))
    return out


STEP = '''{py} - "$@" <<'PYEOF'
import json, subprocess, sys
r = subprocess.run([{py!r}, "-m", "platebench.bench.cli.main", *sys.argv[1:]], capture_output=True, text=True)
print(json.dumps({{{key!r}: {{"rc": r.returncode, "stdout": r.stdout, "stderr": r.stderr}}}}))
PYEOF
'''


def step(key: str, *args) -> str:
    """A line of sh that runs ``platebench ARGS`` and prints its outcome as JSON under ``key``."""
    return STEP.format(py=PY, key=key).replace('"$@"', " ".join(f"'{a}'" for a in map(str, args)))


def state_of(d: Path, key: str) -> str:
    code = (f"import json; from platebench.bench.sweep.dataset import read_manifest; m = read_manifest({str(d)!r}); "
            f"print(json.dumps({{{key!r}: m and {{'state': m['state'], 'counts': m['counts']}}}}))")
    return f"{PY} -c \"{code}\"\n"


def listing(key: str, d: Path) -> str:
    """A line of sh that prints the names in ``d`` as JSON under ``key``."""
    return f"{PY} -c \"import json, os; print(json.dumps({{'{key}': sorted(os.listdir('{d}'))}}))\"\n"


def one_line(r: dict, *needles) -> str:
    lines = [ln for ln in r["stderr"].splitlines() if ln.strip()]
    assert r["rc"] == 2 and len(lines) == 1 and lines[0].startswith("platebench: error: "), r
    assert "Traceback" not in r["stderr"] and all(n.lower() in lines[0].lower() for n in needles), (needles, lines)
    return lines[0]


needs_tmpfs = pytest.mark.skipif(not userns_tmpfs(), reason="no user namespaces (unshare -rm) to mount a small "
                                 "tmpfs; the RLIMIT_FSIZE test covers the same path without one")


# ----------------------------------------------------------------------------- a full or read-only output
@pytest.fixture
def on_tmpfs(tmp_path):
    """(mount point, a 3-sample spec, the dataset path under the mount point)."""
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    return mnt, write_spec(tmp_path / "s.toml", [0, 10, 20]), mnt / "ds"


@pytest.mark.render
@needs_tmpfs
def test_a_full_disk_stops_the_sweep_and_resume_finishes_it_once_space_is_freed(on_tmpfs):
    mnt, spec, ds = on_tmpfs
    res = in_namespace(f"mount -t tmpfs -o size=1m tmpfs {mnt}\n"
                       + step("full", "sweep", spec, "--out", ds, "--workers", 1, "--no-progress")
                       + state_of(ds, "after_full")
                       + listing("committed", ds / "samples")
                       + f"mount -o remount,size=64m {mnt}\n"
                       + step("resumed", "sweep", spec, "--out", ds, "--workers", 1, "--no-progress", "--resume")
                       + state_of(ds, "after_resume")
                       + listing("left", mnt))
    one_line(res["full"], str(ds), "no space left on device", "none of them counted as failed", "--resume")
    st = res["after_full"]
    assert st["state"] == "interrupted" and st["counts"]["failed"] == 0, st
    done_before = [s for s in res["committed"] if not s.startswith(".")]
    assert res["committed"] == done_before and len(done_before) < 3  # no attempt left behind
    assert res["resumed"]["rc"] == 0, res["resumed"]
    assert f"{len(done_before)} of 3 samples already done" in res["resumed"]["stderr"] or not done_before
    assert res["after_resume"] == {"state": "complete", "counts": {"total": 3, "ok": 3, "failed": 0, "pending": 0}}
    assert res["left"] == ["ds"]


@pytest.mark.render
@needs_tmpfs
def test_a_read_only_output_stops_the_sweep_and_resume_finishes_it(on_tmpfs, tmp_path):
    mnt, spec, ds = on_tmpfs
    first = ds / "samples" / "0000" / RESULT
    res = in_namespace(
        f"mount -t tmpfs -o size=64m tmpfs {mnt}\nmkdir {ds}\nmount --bind {ds} {ds}\n"
        f"{PY} -m platebench.bench.cli.main sweep {spec} --out {ds} --workers 1 --no-progress "
        f"> {tmp_path}/ro.out 2> {tmp_path}/ro.err & pid=$!\n"
        f"while [ ! -e {first} ]; do sleep 0.02; done\n"
        # the dataset's mount made read-only under the running sweep (between two of its writes)
        f"until mount -o remount,bind,ro {ds} 2>/dev/null; do sleep 0.01; done\n"
        f"rc=0; wait $pid || rc=$?\n"
        f"{PY} -c \"import json; print(json.dumps({{'ro': {{'rc': $rc, "
        f"'stderr': open('{tmp_path}/ro.err').read()}}}}))\"\n"
        + state_of(ds, "after_ro")
        + f"{PY} -c \"import json; from platebench.bench.sweep.dataset import RESULT; from pathlib import Path; "
          f"print(json.dumps({{'mtimes': {{p.parent.name: p.stat().st_mtime_ns for p in Path('{ds}/samples')."
          f"glob('*/' + RESULT)}}}}))\"\n"
        f"mount -o remount,bind,rw {ds}\n"
        + step("resumed", "sweep", spec, "--out", ds, "--workers", 1, "--no-progress", "--resume")
        + state_of(ds, "after_resume")
        + f"{PY} -c \"import json; from pathlib import Path; print(json.dumps({{'still': {{p.parent.name: "
          f"p.stat().st_mtime_ns for p in Path('{ds}/samples').glob('*/result.json')}}}}))\"\n")
    if res["ro"]["rc"] == 0:
        pytest.skip("the sweep finished before its output became read-only")
    one_line(res["ro"], str(ds), "read-only file system", "--resume")
    assert res["after_ro"]["state"] == "interrupted" and res["after_ro"]["counts"]["failed"] == 0
    assert res["resumed"]["rc"] == 0, res["resumed"]
    assert res["after_resume"]["state"] == "complete" and res["after_resume"]["counts"]["ok"] == 3
    assert {k: res["still"][k] for k in res["mtimes"]} == res["mtimes"]  # committed samples not redone


@pytest.mark.render
@needs_tmpfs
def test_a_full_disk_during_render_is_one_line_and_leaves_nothing(on_tmpfs):
    mnt, _, _ = on_tmpfs
    res = in_namespace(f"mount -t tmpfs -o size=200k tmpfs {mnt}\n"
                       + step("render", "render", "--out", mnt / "s", "--width", 160, "--height", 120, "--spp", 1)
                       + listing("left", mnt))
    one_line(res["render"], "no space left on device")
    assert res["left"] == []


@pytest.mark.render
def test_a_file_size_limit_stops_the_sweep_and_resume_finishes_it(tmp_path):
    """EFBIG from the process's RLIMIT_FSIZE (Python ignores SIGXFSZ): a write refused by the system, no
    namespace needed. In-process (--workers 0: the tmpfs tests use a pool worker)."""
    spec = write_spec(tmp_path / "s.toml", [0, 20])
    ds = tmp_path / "ds"
    limit = 64 * 1024  # the images' EXR files are larger; the manifest and the tables are not
    r = cli("sweep", spec, "--out", ds, "--workers", 0, "--no-progress",
            preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit)))
    one_line({"rc": r.returncode, "stderr": r.stderr}, str(ds), "file too large", "none of them counted as failed")
    m = read_manifest(ds)
    assert m["state"] == "interrupted" and m["counts"]["failed"] == 0 and m["counts"]["pending"] == 2
    assert not stale_files(ds) and not any(p.name.startswith(".") for p in (ds / "samples").iterdir())
    r = cli("sweep", spec, "--out", ds, "--workers", 0, "--no-progress", "--resume")
    assert r.returncode == 0, r.stderr
    assert read_manifest(ds)["counts"] == {"total": 2, "ok": 2, "failed": 0, "pending": 0}


# ----------------------------------------------------------------------------- killed, lost, damaged
@pytest.mark.render
def test_killed_sweep_reports_interrupted_and_a_lost_or_damaged_manifest_is_rebuilt(tmp_path):
    spec = write_spec(tmp_path / "s.toml", [0, 15, 30])
    ds = tmp_path / "ds"
    p = subprocess.Popen(cli_cmd("sweep", spec, "--out", ds, "--workers", 1, "--no-progress"), cwd=REPO,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_for(lambda: n_committed(ds) >= 1, proc=p)
    finally:
        p.kill()  # -9, as a crash or the OOM killer would
        p.wait()
    assert json.loads((ds / "manifest.json").read_text())["state"] == "running"  # as the killed writer left it
    r = cli("report", ds, "--out", tmp_path / "rep")
    assert r.returncode == 0, r.stderr
    html = (tmp_path / "rep" / "index.html").read_text()
    assert "interrupted (the sweep that was writing it is gone (killed)" in html and ">running<" not in html

    # the manifest lost: --resume rebuilds it from the samples' result.json files, redoing none of them
    (ds / "manifest.json").unlink()
    before = mtimes(ds)
    assert before, "the sweep was killed before its first sample"
    r = cli("sweep", spec, "--out", ds, "--workers", 0, "--no-progress", "--resume")
    assert r.returncode == 0, r.stderr
    assert "manifest.json is missing or damaged: rebuilding it from its" in r.stderr
    assert f"resume: {len(before)} of 3 samples already done" in r.stderr
    assert {k: mtimes(ds)[k] for k in before} == before
    m = read_manifest(ds)
    assert m["state"] == "complete" and all(validate_result(ds, e["id"], manifest_files=e["files_sha256"])
                                            for e in m["samples"])

    # truncated, with one sample's image damaged too: that one (only) is made again
    data = (ds / "manifest.json").read_bytes()
    (ds / "manifest.json").write_bytes(data[: len(data) // 3])
    img = ds / "samples" / "0001" / "sample" / "images" / "left_active.png"
    img.write_bytes(img.read_bytes()[:200])
    before = mtimes(ds)
    r = cli("sweep", spec, "--out", ds, "--workers", 0, "--no-progress", "--resume")
    assert r.returncode == 0, r.stderr
    assert "rebuilding it from its 3 samples" in r.stderr and "1 whose files no longer match" in r.stderr
    after = mtimes(ds)
    assert after["0000"] == before["0000"] and after["0002"] == before["0002"] and after["0001"] != before["0001"]
    assert read_manifest(ds)["counts"]["ok"] == 3
    rows = read_results(ds).to_pylist()
    assert [x["sample_id"] for x in rows] == ["0000", "0001", "0002"]

    # another spec cannot adopt these samples without their manifest
    (ds / "manifest.json").unlink()
    r = cli("sweep", write_spec(tmp_path / "o.toml", [0, 45, 90]), "--out", ds, "--workers", 0, "--resume")
    assert r.returncode == 2 and "sample 0001 (2 in all) is not one of this spec's" in r.stderr, r.stderr
    # --overwrite replaces it (a dataset by its samples) ...
    other = write_spec(tmp_path / "one.toml", [45])
    r = cli("sweep", other, "--out", ds, "--workers", 0, "--no-progress", "--overwrite")
    assert r.returncode == 0, r.stderr
    assert "replacing the dataset, recognised by its 3 samples" in r.stderr
    assert read_manifest(ds)["counts"]["ok"] == 1 and not stale_files(ds)
    # ... but not a folder that holds what no sweep writes
    (ds / "manifest.json").unlink()
    (ds / "precious.txt").write_text("mine")
    r = cli("sweep", other, "--out", ds, "--workers", 0, "--overwrite")
    assert r.returncode == 2 and "'precious.txt', which no sweep writes: refusing" in r.stderr, r.stderr
    assert (ds / "precious.txt").read_text() == "mine" and (ds / "samples" / "0000" / RESULT).exists()
