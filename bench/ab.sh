#!/usr/bin/env bash
# bench/ab.sh: two septa binaries on one volume at the same time, one thread
# each, so that whatever else the machine does slows both alike. On a shared
# 2-core machine the same binary's wall time drifts by 10-20 % from one run
# to the next (and more over an hour); run side by side, both see the same
# machine. The same binary on both sides gave CPU ratios of 0.94-1.04, so
# repeat with A and B swapped before trusting a change under 10 %. Whole
# volumes, natively: where instructions.sh would take an hour under callgrind.
#
#   bench/ab.sh A_BINARY B_BINARY VOLUME [EXTRA SEPTA FLAGS...]
#
# Prints, per binary: wall and CPU seconds, peak RSS, and from its manifest
# the output triangles, edges within [0.8 h, 1.33 h], triangles with the
# smallest angle >= 20 degrees and the Hausdorff distance in voxels (the
# remeshing quality; none with --no-remesh); then B's CPU time against A's.
# The outputs are written under a new temporary directory, removed at the end
# (set KEEP=1 to keep it). Both binaries take the same EXTRA flags, so a
# setting can be compared on one binary too: give it twice and put the
# setting in an environment variable that only B sees, e.g.
#   B_ENV="SOME_VAR=1" bench/ab.sh target/release/septa target/release/septa VOL
set -euo pipefail
[ $# -ge 3 ] || { sed -n '2,20p' "$0"; exit 2; }
a=$1; b=$2; vol=$3; shift 3
for bin in "$a" "$b"; do
    [ -x "$bin" ] || { echo "ab.sh: $bin is not an executable" >&2; exit 2; }
done
[ -r "$vol" ] || { echo "ab.sh: cannot read $vol" >&2; exit 2; }
dir=$(mktemp -d "${TMPDIR:-/tmp}/septa-ab.XXXXXX")
[ "${KEEP:-0}" = 1 ] || trap 'rm -rf "$dir"' EXIT

run() { # NAME BINARY ENV [EXTRA SEPTA FLAGS...]
    local name=$1 bin=$2 envs=$3
    shift 3
    # shellcheck disable=SC2086
    env RAYON_NUM_THREADS=1 $envs /usr/bin/time -f "%e %U %M" -o "$dir/$name.time" \
        "$bin" -q extract "$vol" -o "$dir/$name" --no-preview "$@" 2>"$dir/$name.err" ||
        { echo "ab.sh: $name failed:" >&2; cat "$dir/$name.err" >&2; return 1; }
}
run a "$a" "${A_ENV:-}" "$@" &
pid=$!
run b "$b" "${B_ENV:-}" "$@"
wait "$pid"

python3 - "$dir" <<'PY'
import json, sys
d = sys.argv[1]
cpu = {}
for name in "ab":
    wall, user, rss = open(f"{d}/{name}.time").read().split()[-3:]
    cpu[name] = float(user)
    m = json.load(open(f"{d}/{name}/manifest.json"))
    q = m.get("quality") or {}
    line = f"{name.upper()}  {float(wall):7.2f} s wall  {float(user):7.2f} s CPU  {int(rss) / 1024:6.0f} MB"
    if q:
        line += (f"  {q['triangles']:>10,} triangles  {100 * q['edges']['within_range']:5.2f} % in range"
                 f"  {100 * q['angles']['min_ge_20']:5.2f} % >= 20 deg"
                 f"  Hausdorff {q['distance']['hausdorff_voxels']:.3f} vx")
    print(line)
print(f"B / A CPU: {cpu['b'] / cpu['a']:.3f}")
PY
