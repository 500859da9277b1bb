#!/usr/bin/env bash
# Profiles the CPU driver's JIT code while a celray command runs, down to
# its instructions: perf sees lavapipe's kernels only as anonymous
# addresses, so this also copies the process's anonymous executable
# mappings out of /proc/PID/mem while they exist and disassembles the one
# the samples fall in (docs/performance.md, "Profiling").
#
#   tools/jit-profile/run.sh [--after SECONDS] [--for SECONDS] -- celray ARGS...
#
# --after: seconds to wait before recording (skip compiles and other
# cases), --for: seconds to record. Needs perf and objdump; run as root or
# with perf_event_paranoid <= 1. Writes target/jit-profile/: perf.data,
# the mappings (region_*.bin), hot.txt (the hottest instructions),
# annotated.txt (the hottest mapping's disassembly with samples per
# instruction) and mix.txt (samples by instruction mnemonic).
set -euo pipefail
after=10
duration=5
while [ $# -gt 0 ]; do
    case "$1" in
        --after) after=$2; shift 2 ;;
        --for) duration=$2; shift 2 ;;
        --) shift; break ;;
        *) echo "unknown option $1" >&2; exit 2 ;;
    esac
done
[ $# -gt 0 ] || { echo "usage: $0 [--after S] [--for S] -- celray ARGS..." >&2; exit 2; }
cd "$(dirname "$0")/../.."
out=target/jit-profile
rm -rf "$out" && mkdir -p "$out"
"$@" > "$out/command.log" 2>&1 &
pid=$!
sleep "$after"
kill -0 "$pid" 2>/dev/null || { echo "the command ended before --after $after s" >&2; exit 1; }
perf record -F 2000 -p "$pid" -o "$out/perf.data" -- sleep "$duration" 2> "$out/perf.log" &
perf_pid=$!
# The code is copied halfway through the recording: a case that ends
# frees its kernel, and the next one may be compiled at the same address.
sleep "$(python3 -c "print($duration / 2)")"
python3 tools/jit-profile/dump.py "$pid" "$out"
wait "$perf_pid"
wait "$pid" || true
perf script -i "$out/perf.data" -F ip 2>/dev/null > "$out/ips.txt"
python3 tools/jit-profile/annotate.py "$out"
