#!/usr/bin/env bash
# The GPU machine's measurement: every figure of `platebench perf gpu --full` (host pixels and
# subnormal floats, whole sample vs raw renders, cuda vs llvm pixels, the sweep pipeline, the
# 61-plate false-boundary study), each beside its baseline, in one run (194 s on an H200 machine).
#
#   bash bench/perf/gpu_check.sh prepare   # here, once: .device/ (Mitsuba, drjit, ... for Python 3.12)
#                                          # plus the Dask and TOML-writer wheels the GPU machine lacks
#   bash bench/perf/gpu_check.sh run       # on the GPU machine, from the checkout, with .device carried:
#                                          # figures in $OUT/perf_gpu.json, the printout in $OUT/perf_gpu.log
#
# `run` stops the measurement at PERF_GPU_TIMEOUT_S (default 540 s); the JSON is written after
# each section, so a run cut short keeps what it measured. PERF_GPU_ARGS adds flags
# (e.g. "--workers 12").
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
what="${1:-}"

pin() { grep -i "^$1==" requirements.lock | sed 's/ *;.*//'; }

case "$what" in
prepare)
    if [ ! -f .device/site.tar.xz ]; then
        bundle=$(ls ../shared/tools/device-bundle ../../shared/tools/device-bundle 2>/dev/null | head -1)
        [ -n "$bundle" ] || { echo "no .device/ and no shared/tools/device-bundle beside the checkout to build it"; exit 2; }
        # the bundle tool writes .device/ in the directory it runs in (and notes it in .git/info/exclude):
        # run it on a copy of the lock, so that a git worktree (whose .git is a file) works too
        T=$(mktemp -d); cp requirements.lock "$T"/; mkdir -p "$T/.git/info"
        (cd "$T" && bash "$OLDPWD/$bundle") || exit 2
        rm -rf .device && mv "$T/.device" .device && rm -rf "$T"
    fi
    W=$(mktemp -d); S=$(mktemp -d)
    plat=(--platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64)
    # dask[distributed] and what it imports, tomli-w: at the lock's versions, for the GPU machine's Python 3.12
    for p in dask distributed cloudpickle toolz partd locket fsspec msgpack psutil tornado sortedcontainers \
             tblib zict click pyyaml importlib-metadata zipp tomli-w; do
        python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
            "${plat[@]}" -d "$W" "$(pin "$p")" 2>&1 | grep -v "^WARNING: Location" || true
    done
    for w in "$W"/*.whl; do (cd "$S" && unzip -q -o "$w"); done
    rm -rf "$S"/*.dist-info/RECORD
    tar cf - -C "$S" . | xz -4 -T0 > .device/extra.tar.xz
    rm -rf "$W" "$S"
    du -sh .device
    echo "device run: carry [\".device\"]; command: bash bench/perf/gpu_check.sh run"
    ;;
run)
    OUT="${OUT:-$(mktemp -d)}"
    [ -f .device/env.sh ] || { echo "no .device/: run 'bash bench/perf/gpu_check.sh prepare' before carrying it"; exit 2; }
    mkdir -p /tmp/pbsite && tar xJf .device/extra.tar.xz -C /tmp/pbsite
    export PYTHONPATH=/tmp/pbsite${PYTHONPATH:+:$PYTHONPATH}
    { nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader; nproc; uptime; } \
        > "$OUT/machine.txt" 2>&1
    timeout -k 10 "${PERF_GPU_TIMEOUT_S:-540}" bash .device/env.sh python3 -m platebench perf gpu --full \
        --json "$OUT/perf_gpu.json" ${PERF_GPU_ARGS:-} 2>&1 | tee "$OUT/perf_gpu.log"
    status=${PIPESTATUS[0]}
    echo "perf gpu exit status $status; figures in $OUT/perf_gpu.json"
    exit "$status"
    ;;
*)
    echo "usage: bash bench/perf/gpu_check.sh prepare|run"; exit 2 ;;
esac
