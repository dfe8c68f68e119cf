#!/usr/bin/env bash
# bench/instructions.sh: instructions executed by `septa extract` on one volume,
# counted by valgrind's callgrind on one thread: the same count on every run,
# where wall time on a shared 2-core machine varies by ±10 % and more. For
# A/B tests of a change to a hot loop (same output expected: compare the
# PLY files the two runs leave with `cmp`).
#
#   bench/instructions.sh VOLUME OUT_DIR [EXTRA SEPTA FLAGS...]
#
# Prints the total and the 20 functions with the most instructions of their
# own (inlined code counted in the function it was inlined into), and leaves
# OUT_DIR/callgrind.out for callgrind_annotate (e.g. `--tree=caller` for who
# calls what, or `--auto=yes FILE.rs` for costs per source line).
#
# A volume that runs in about a second natively takes about a minute here:
#   target/release/septa phantom -o /tmp/ph48n.nii.gz --size 48 --noise 0.01 -q
#   bench/instructions.sh /tmp/ph48n.nii.gz /tmp/ir_before
#
# Instructions are not time (cache misses and divisions cost more than their
# count), so confirm a real gain with a timed run before claiming one.
# Needs valgrind (Debian: apt-get install valgrind) and python3.
set -euo pipefail
[ $# -ge 2 ] || { sed -n '2,22p' "$0"; exit 2; }
vol=$1; out=$2; shift 2
bin=${SEPTA:-./target/release/septa}
[ -x "$bin" ] || { echo "instructions.sh: $bin not found; run cargo build --release first" >&2; exit 2; }
command -v valgrind >/dev/null || { echo "instructions.sh: valgrind not found" >&2; exit 2; }
[ -e "$out" ] && { echo "instructions.sh: $out exists; give a new directory" >&2; exit 2; }
mkdir -p "$out"
RAYON_NUM_THREADS=1 valgrind --tool=callgrind --callgrind-out-file="$out/callgrind.out" \
  "$bin" extract "$vol" -o "$out/mesh" -q "$@" 2>"$out/valgrind.log"
callgrind_annotate --threshold=100 --auto=no "$out/callgrind.out" | python3 -c '
import re, sys, collections
own, total = collections.Counter(), None
for line in sys.stdin:
    m = re.match(r"\s*([\d,]+) \(\s*[\d.]+%\)\s+(\S.*)$", line)
    if not m:
        continue
    n, where = int(m.group(1).replace(",", "")), m.group(2)
    if "PROGRAM TOTALS" in where:
        total = n
        continue
    # "file:function [binary]": the same function appears once per file it
    # has code inlined from
    fn = re.sub(r" \[.*\]$", "", where.split(":", 1)[1] if ":" in where else where)
    own[fn] += n
print(f"instructions: {total:,}")
for fn, n in own.most_common(20):
    print(f"{100 * n / total:6.2f} %  {fn[:140]}")
'
