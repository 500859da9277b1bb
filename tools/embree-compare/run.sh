#!/usr/bin/env bash
# Times Embree (Debian's libembree-dev, Embree 3) on the rays of celray's
# helmet_rays case, on this machine, right after celray traced them, and
# prints celray's closest-hit rate as a ratio to Embree's on 2 threads
# (issue 9's target: at least 0.5x). Needs ../shared/models (FlightHelmet)
# or MODELS=DIR. Run from anywhere; writes only under target/.
set -euo pipefail
cd "$(dirname "$0")/../.."
MODELS=${MODELS:-../shared/models}
if ! [ -f /usr/include/embree3/rtcore.h ]; then
    apt-get install -y libembree-dev g++ || { apt-get update && apt-get install -y libembree-dev g++; }
fi
mkdir -p target/embree-compare
g++ -O3 -march=native -std=c++17 tools/embree-compare/embree_rays.cpp -lembree3 -lpthread \
    -o target/embree-compare/embree_rays
cargo build --release --quiet
out=target/embree-compare/helmet_rays.bin
rm -f "$out"
./target/release/celray bench rays --frames 3 --json --models "$MODELS" --export-rays "$out" \
    | grep -E '"case": ?"(floor_1|helmet_rays)"' | tee target/embree-compare/celray.jsonl
./target/embree-compare/embree_rays "$out" | tee target/embree-compare/embree.jsonl
python3 - <<'PY'
import json
c = {j["case"]: j for j in map(json.loads, open("target/embree-compare/celray.jsonl"))}
e = {j["case"]: j for j in map(json.loads, open("target/embree-compare/embree.jsonl"))}
ours, theirs = c["helmet_rays"]["mrays_per_s"], e["embree_closest_2t"]["mrays_per_s"]
print(f"helmet_rays closest hit: celray {ours:.1f} Mrays/s, Embree {e['embree_setup']['embree']} "
      f"on 2 threads {theirs:.1f} Mrays/s: {ours / theirs:.2f}x (target >= 0.5x)")
PY
