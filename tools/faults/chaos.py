"""Chaos benchmark: a 20-sample Dask sweep whose scheduler, workers and sweep process are killed at
random moments, resumed after each kill, and checked (not a timed test; a script that reproduces).

``python -m tools.faults.chaos [--rounds 10] [--samples 20] [--seed 0]`` (from the repository
root). Each round starts ``platebench sweep SPEC --scheduler ADDR [--resume]``
in a fresh process on a real ``LoopbackCluster`` (127.0.0.1), waits until it commits a sample, then a random 0-6 s, then kill -9s a
random victim by PID: the scheduler (the cluster is restarted), one worker (its nanny too; a new
worker joins), or the sweep process. After the sweep process has ended, the dataset is checked:

* *lost*: at the end, samples without a valid committed result (goal 0);
* *redone*: a committed sample whose ``result.json`` changed afterwards (goal 0);
* *duplicated rows*: rows of results.csv beyond one per sample and method (goal 0);
* *corrupt files*: committed samples whose files do not match their checksums (goal 0);
* *wrong "complete"*: a manifest that reads "complete" while a sample is missing or invalid (goal 0).

When a dataset completes, the next round starts a new one. A final ``--resume`` without kills
finishes the last dataset. Prints a table per round and the totals (JSON with ``--json``).
"""
from __future__ import annotations

import argparse
import csv
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import tomli_w

from platebench.bench.sweep.dataset import RESULT, read_manifest, stale_files, validate_result
from platebench.bench.sweep.executors import LoopbackCluster

VICTIMS = ("scheduler", "worker", "sweep")


def _spec(path: Path, n: int) -> Path:
    path.write_text(tomli_w.dumps({"sweep": {"name": "chaos"},
                                   "base": {"scene": {"width": 240, "height": 180}, "render": {"spp": 4, "seed": 3}},
                                   "grid": {"bend_deg": [round(i * 60.0 / max(n - 1, 1), 3) for i in range(n)]}}))
    return path


def _committed(out: Path) -> dict:
    return {p.parent.name: p.stat().st_mtime_ns for p in (out / "samples").glob(f"*/{RESULT}")} \
        if (out / "samples").is_dir() else {}


def _check(out: Path, n: int, seen: dict) -> dict:
    """Check the dataset after a round; ``seen`` (sample -> first committed mtime) is updated."""
    now = _committed(out)
    redone = sum(1 for s, t in now.items() if s in seen and seen[s] != t)
    for s, t in now.items():
        seen.setdefault(s, t)
    ids = [f"{i:04d}" for i in range(n)]
    corrupt = sum(1 for s in now if validate_result(out, s) is None)
    valid = sum(1 for s in ids if validate_result(out, s) is not None)
    dup = 0
    if (out / "results.csv").is_file():
        with open(out / "results.csv", newline="") as f:
            counts = Counter((r["sample_id"], r["method"]) for r in csv.DictReader(f))
        dup = sum(c - 1 for c in counts.values() if c > 1)
    m = read_manifest(out) or {}
    wrong_complete = int(m.get("state") == "complete" and valid != n)
    return {"committed": len(now), "valid": valid, "redone": redone, "corrupt": corrupt, "duplicated_rows": dup,
            "wrong_complete": wrong_complete, "state": m.get("state")}


def run_chaos(rounds: int = 10, samples: int = 20, seed: int = 0, workdir: Path | None = None,
              say=print) -> dict:
    rng = random.Random(seed)
    work = Path(workdir or tempfile.mkdtemp(prefix="platebench-chaos-"))
    spec = _spec(work / "chaos.toml", samples)
    repo = Path(__file__).resolve().parents[2]
    totals = Counter()
    table = []
    cluster = LoopbackCluster(n_workers=2, log_dir=None).start()
    datasets = 1
    out = work / f"ds{datasets}"
    seen: dict = {}
    try:
        for rnd in range(1, rounds + 1):
            if _check(out, samples, seen)["state"] == "complete":
                totals["lost"] += samples - _check(out, samples, seen)["valid"]
                datasets += 1
                out, seen = work / f"ds{datasets}", {}
            resume = ["--resume"] if out.exists() else []
            cmd = [sys.executable, "-m", "platebench.bench.cli.main", "sweep", str(spec), "--out", str(out),
                   "--scheduler", cluster.address, "--no-progress", "--worker-timeout-s", "30", *resume]
            sweep = subprocess.Popen(cmd, cwd=repo, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            victim = rng.choice(VICTIMS)
            delay = rng.uniform(0.0, 6.0)
            t0 = time.monotonic()
            n0 = len(_committed(out))
            while sweep.poll() is None and len(_committed(out)) == n0 and time.monotonic() - t0 < 120:
                time.sleep(0.05)  # the sweep is under way once it commits a sample: kill mid-sweep
            time.sleep(delay)
            delay += time.monotonic() - t0 - delay
            killed = sweep.poll() is None
            if killed:
                if victim == "scheduler":
                    os.killpg(cluster.scheduler.pid, signal.SIGKILL)
                elif victim == "worker":
                    i = rng.randrange(len(cluster.workers))
                    while cluster.workers[i].poll() is not None:
                        i = (i + 1) % len(cluster.workers)
                    cluster.kill_worker(i)
                    cluster.start_worker()
                else:
                    sweep.send_signal(signal.SIGKILL)
            try:
                _, err = sweep.communicate(timeout=600)
            except subprocess.TimeoutExpired:
                sweep.kill()
                _, err = sweep.communicate()
                totals["hung"] += 1
            if victim == "scheduler" and killed:
                cluster.close()
                cluster = LoopbackCluster(n_workers=2).start()
            tb = int("Traceback" in err)
            c = _check(out, samples, seen)
            for k in ("redone", "corrupt", "duplicated_rows", "wrong_complete"):
                totals[k] += c[k]
            totals["tracebacks"] += tb
            last = (err.strip().splitlines() or [""])[-1]
            row = {"round": rnd, "dataset": datasets, "victim": victim if killed else "-", "after_s": round(delay, 1),
                   "exit": sweep.returncode, **c, "traceback": tb, "last_line": last[:110]}
            table.append(row)
            say(f"round {rnd:2d} ds{datasets} kill {row['victim']:9s} at {delay:4.1f} s  exit {sweep.returncode:4d}  "
                f"committed {c['committed']:2d}/{samples}  state {str(c['state']):11s}  redone {c['redone']}  "
                f"corrupt {c['corrupt']}  dup rows {c['duplicated_rows']}  wrong complete {c['wrong_complete']}"
                + (f"  | {last[:90]}" if sweep.returncode not in (0, -9) else ""))
        # finish the last dataset without kills
        r = subprocess.run([sys.executable, "-m", "platebench.bench.cli.main", "sweep", str(spec), "--out", str(out),
                            "--scheduler", cluster.address, "--no-progress", "--resume"], cwd=repo,
                           capture_output=True, text=True, timeout=900)
        c = _check(out, samples, seen)
        for k in ("redone", "corrupt", "duplicated_rows", "wrong_complete"):
            totals[k] += c[k]
        totals["lost"] += samples - c["valid"]
        totals["final_exit"] = r.returncode
        totals["leftovers"] = sum(len(stale_files(work / f"ds{i}")) for i in range(1, datasets + 1))
        say(f"final resume ds{datasets}: exit {r.returncode}, {c['valid']}/{samples} valid, state {c['state']}")
    finally:
        cluster.close()
    summary = {"rounds": rounds, "samples_per_dataset": samples, "datasets": datasets,
               "kills": dict(Counter(row["victim"] for row in table)),
               "samples_lost": totals["lost"], "samples_redone": totals["redone"],
               "duplicated_rows": totals["duplicated_rows"], "corrupt_files": totals["corrupt"],
               "wrong_complete": totals["wrong_complete"], "tracebacks": totals["tracebacks"],
               "hung": totals["hung"], "leftovers": totals["leftovers"], "final_exit": totals["final_exit"],
               "rounds_table": table, "workdir": str(work)}
    return summary


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tools.faults.chaos", description=__doc__.split("\n\n")[0])
    p.add_argument("--rounds", type=int, default=10)
    p.add_argument("--samples", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workdir", type=Path)
    p.add_argument("--json", type=Path)
    args = p.parse_args(argv)
    s = run_chaos(args.rounds, args.samples, args.seed, args.workdir)
    print(f"chaos: {s['rounds']} rounds, {s['datasets']} dataset(s) of {s['samples_per_dataset']} samples, "
          f"kills {s['kills']}")
    print(f"samples lost {s['samples_lost']}, redone {s['samples_redone']}, duplicated rows {s['duplicated_rows']}, "
          f"corrupt files {s['corrupt_files']}, wrong \"complete\" {s['wrong_complete']}, tracebacks "
          f"{s['tracebacks']}, hung {s['hung']}, leftovers {s['leftovers']}")
    if args.json:
        from platebench.bench.io.atomic import write_json  # noqa: PLC0415
        write_json(args.json, {"generator": "tools/faults chaos", "figures": s})
    bad = sum(s[k] for k in ("samples_lost", "samples_redone", "duplicated_rows", "corrupt_files", "wrong_complete",
                             "hung"))
    return 0 if bad == 0 and s["final_exit"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
