"""Disassembles the JIT mapping most samples fall in (OUT/ips.txt, one
sampled address per line) and writes OUT/annotated.txt (samples per
instruction), OUT/hot.txt (the 60 hottest) and OUT/mix.txt (samples by
mnemonic)."""
import collections
import glob
import os
import subprocess
import sys

out = sys.argv[1]
samples = collections.Counter(int(l.split()[0], 16) for l in open(f"{out}/ips.txt") if l.strip())
regions = []
for path in glob.glob(f"{out}/region_*.bin"):
    start = int(os.path.basename(path)[7:-4], 16)
    regions.append((start, start + os.path.getsize(path), path))
inside = lambda r: sum(c for a, c in samples.items() if r[0] <= a < r[1])
if not regions:
    sys.exit("no JIT mapping was copied")
best = max(regions, key=inside)
total = sum(samples.values())
print(f"{inside(best)} of {total} samples in the JIT mapping at {best[0]:#x} ({best[1] - best[0]} bytes)")
dis = subprocess.run(
    ["objdump", "-D", "-b", "binary", "-m", "i386:x86-64", f"--adjust-vma={best[0]:#x}", best[2]],
    capture_output=True, text=True, check=True,
).stdout
rows, mix = [], collections.Counter()
for line in dis.splitlines():
    parts = line.split("\t")
    try:
        address = int(parts[0].strip().rstrip(":"), 16)
    except ValueError:
        continue
    count = samples.get(address, 0)
    rows.append((count, line))
    if len(parts) >= 3 and parts[2].split():
        mix[parts[2].split()[0]] += count
matched = sum(c for c, _ in rows)
print(f"{matched} of them at instruction starts of the copied code")
if matched < 0.9 * inside(best):
    print("warning: the code at those addresses changed during the recording "
          "(a case ended?): choose --after and --for inside one case")
with open(f"{out}/annotated.txt", "w") as f:
    f.writelines(f"{c:6d} {l}\n" for c, l in rows)
with open(f"{out}/hot.txt", "w") as f:
    f.writelines(f"{c:6d} {l}\n" for c, l in sorted(rows, key=lambda r: -r[0])[:60])
with open(f"{out}/mix.txt", "w") as f:
    in_best = sum(mix.values()) or 1
    f.writelines(f"{m:14s} {c:7d} {100 * c / in_best:5.1f}%\n" for m, c in mix.most_common())
print(f"see {out}/hot.txt, {out}/mix.txt and {out}/annotated.txt")
