#!/usr/bin/env bash
# Compares two builds of vol_app on the README's benchmark frame in
# alternating rounds (A, B, A, B, ...), the only comparison these shared,
# noisy machines allow, and checks that both render the same image.
#
#   scripts/ab_frames.sh BIN_A BIN_B [ROUNDS] [-- extra render options]
#
#   scripts/ab_frames.sh /tmp/vol_app_old target/release/vol_app
#   scripts/ab_frames.sh /tmp/old /tmp/new 4 -- --renderer serial --threads 1 --repeat 5
#
# Copy a build aside (cp target/release/vol_app /tmp/vol_app_old) before
# rebuilding, so that each side stays what it was. Defaults: 3 rounds,
# the bricked file (volumes/800shapes_block16.vol; VOL=... for another),
# unshaded (SHADING=on for shaded), `--renderer tiles --threads 2
# --repeat 7`. Prints each run's median frame time (ms) and the samples.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [ $# -lt 2 ]; then
    sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
fi
a="$1"
b="$2"
shift 2
rounds=3
if [ $# -gt 0 ] && [ "$1" != "--" ]; then
    rounds="$1"
    shift
fi
[ $# -gt 0 ] && [ "$1" = "--" ] && shift
extra=("$@")
[ ${#extra[@]} -eq 0 ] && extra=(--renderer tiles --threads 2 --repeat 7)
vol="${VOL:-$root/volumes/800shapes_block16.vol}"
for bin in "$a" "$b"; do
    [ -x "$bin" ] || { echo "ab_frames.sh: $bin: not an executable" >&2; exit 2; }
done
[ -f "$vol" ] || { echo "ab_frames.sh: $vol: missing (volumes/make_benchmark_volumes.sh makes it)" >&2; exit 2; }
case "$rounds" in *[!0-9]* | "") echo "ab_frames.sh: rounds must be a number, not '$rounds'" >&2; exit 2 ;; esac
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
frame=(--size 700x700 --camera-pos 1100,1100,1100 --look-at 0,0,0 --fov 60 --step 0.2
    --tf-preset shapes --shading "${SHADING:-off}" --stats)
for r in $(seq "$rounds"); do
    for side in A B; do
        bin="$a"
        [ "$side" = B ] && bin="$b"
        "$bin" render "$vol" "${frame[@]}" "${extra[@]}" --out "$out/$side.png" |
            tail -1 | python3 -c '
import json, sys
d = json.loads(sys.stdin.read())
print("round {} {}: {:8.2f} ms  {} samples  ({})".format(
    sys.argv[1], sys.argv[2], d["frame_ms_median"], d["samples"], sys.argv[3]))
' "$r" "$side" "$bin"
    done
    cmp -s "$out/A.png" "$out/B.png" || { echo "ab_frames.sh: the two builds' images differ" >&2; exit 1; }
done
echo "images identical"
