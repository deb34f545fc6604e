#!/usr/bin/env bash
# Measures the README's table of figures: the seed thesis's benchmark frame
# (800³ shapes, 700×700, camera 1100,1100,1100 → origin, fov 60, step 0.2,
# `shapes` TF) with each renderer, thread count, file and optimisation set.
# Prints markdown rows; medians of --repeat frames in one run.
#
#   scripts/figures.sh [REPEAT]          # default 5
#
# Needs volumes/800shapes_{linear,block16}.vol (volumes/make_benchmark_volumes.sh).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
repeat="${1:-5}"
cargo build --release --quiet -p vol_app --manifest-path "$root/Cargo.toml"
app="${CARGO_TARGET_DIR:-$root/target}/release/vol_app"
frame=(--size 700x700 --camera-pos 1100,1100,1100 --look-at 0,0,0 --fov 60 --step 0.2 --tf-preset shapes --stats)

row() {
    local file="$1" label="$2" reps="$3"
    shift 3
    # Warm the page cache so load_ms measures opening + ESS, not the disk.
    cat "$root/volumes/$file" > /dev/null
    "$app" render "$root/volumes/$file" "${frame[@]}" --repeat "$reps" "$@" | python3 -c '
import json, sys
d = json.load(sys.stdin)
label, file = sys.argv[1], sys.argv[2]
ms, n, load = d["frame_ms_median"], d["samples"], d["load_ms"]
cells = [file, label, d["renderer"], str(d["threads"]), f"{ms:.0f}", f"{n/1e6:.2f} M", f"{n/ms/1e3:.1f} M/s", f"{load:.0f}"]
print("| " + " | ".join(cells) + " |")
' "$label" "$file"
}

echo "| file | ERT / ESS | renderer | threads | ms/frame (median) | samples/frame | samples/s | open + ESS build (ms) |"
echo "|---|---|---|---|---|---|---|---|"
for file in 800shapes_linear.vol 800shapes_block16.vol; do
    row "$file" "on / on" "$repeat" --renderer serial --threads 1
    row "$file" "off / off" 1 --renderer serial --threads 1 --ert off --ess off
    for renderer in tiles object; do
        for threads in 1 2; do
            row "$file" "on / on" "$repeat" --renderer "$renderer" --threads "$threads"
        done
    done
done
