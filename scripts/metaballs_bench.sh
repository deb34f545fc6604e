#!/usr/bin/env bash
# The seed 004 metaball benchmark (Németh 2022, Table 4.1): N³ lattices of
# balls (N = 5, 10, 15, 20: 125 to 8000 balls) spanning the unit cube,
# R = 0.2, a 600×600 view. The seed states no camera; ours looks at the
# cube's centre from (1.5, 1.25, 2.8), where the cube fills about 80 % of the
# view. The lattices are written as points files in /tmp. Prints one
# markdown row per lattice: median frame time over REPEAT frames (after a
# warm-up), FPS, the per-frame candidate-list build (part of the frame),
# the file's parse time, peak RSS, and the seed's GPU figures.
#
#   scripts/metaballs_bench.sh [REPEAT] [extra vol_app render options...]
#
# e.g. scripts/metaballs_bench.sh 10 --kernel murakami --renderer serial
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
repeat="${1:-5}"
shift || true
cargo build --release --quiet -p vol_app --manifest-path "$root/Cargo.toml"
app="${CARGO_TARGET_DIR:-$root/target}/release/vol_app"
declare -A seed_fps=([125]=254 [1000]=33 [3375]=10 [8000]=4)
echo "| balls | ms/frame | FPS | lists ms | parse ms | peak RSS MB | seed FPS (iGPU) |"
echo "|---:|---:|---:|---:|---:|---:|---:|"
for n in 5 10 15 20; do
    pts="/tmp/metaballs_lattice_${n}.csv"
    awk -v n="$n" 'BEGIN {
        print "# x,y,z: a " n "^3 lattice spanning the unit cube"
        for (i = 0; i < n; i++) for (j = 0; j < n; j++) for (k = 0; k < n; k++)
            printf "%.6f,%.6f,%.6f\n", i / (n - 1), j / (n - 1), k / (n - 1)
    }' > "$pts"
    "$app" render "$pts" --mode metaballs --ball-radius 0.2 --size 600x600 \
        --camera-pos 1.5,1.25,2.8 --look-at 0.5,0.5,0.5 --fov 45 \
        --repeat "$repeat" --stats "$@" \
      | python3 -c '
import json, sys
d = json.loads(sys.stdin.read())
seed = sys.argv[1]
ms = d["frame_ms_median"]
row = (d["balls"], ms, 1000 / ms, d["lists_ms_median"], d["build_ms"], d["peak_rss_mb"], seed)
print("| %d | %.1f | %.1f | %.2f | %.2f | %.0f | %s |" % row)
' "${seed_fps[$((n * n * n))]}"
done
