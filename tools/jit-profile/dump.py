"""Copies the anonymous executable mappings of process PID (lavapipe's JIT
code) into OUT/region_<start>.bin; used by run.sh while the process runs."""
import sys

pid, out = int(sys.argv[1]), sys.argv[2]
with open(f"/proc/{pid}/maps") as maps, open(f"/proc/{pid}/mem", "rb") as mem:
    for line in maps:
        fields = line.split()
        anonymous = len(fields) < 6 or fields[5].startswith("[anon")
        if "x" not in fields[1] or not anonymous:
            continue
        start, end = (int(a, 16) for a in fields[0].split("-"))
        if end - start > 64 << 20:
            continue
        mem.seek(start)
        with open(f"{out}/region_{start:x}.bin", "wb") as f:
            f.write(mem.read(end - start))
