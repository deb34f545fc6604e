#!/usr/bin/env bash
# Measures the README's table of figures: the seed thesis's benchmark frame
# (800³ shapes, 700×700, camera 1100,1100,1100 → origin, fov 60, step 0.2,
# `shapes` TF) with each renderer, thread count, file and optimisation set.
# Prints markdown rows; medians of --repeat frames in one run.
#
#   scripts/figures.sh [REPEAT] [--with-2000]   # REPEAT default 5
#
# Needs volumes/800shapes_{linear,block16}.vol (volumes/make_benchmark_volumes.sh).
# --with-2000 adds the opening of volumes/2000shapes_block16.vol
# (`make_benchmark_volumes.sh --with-2000`, 9.2 GiB): open time without the
# macrocell cache, when building and writing it, and with it, and the peak
# RSS after one frame (camera 2750,2750,2750 → origin); medians of REPEAT
# interleaved runs, the file in the page cache.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
repeat=5
with_2000=0
for arg in "$@"; do
    case "$arg" in
        --with-2000) with_2000=1 ;;
        *[!0-9]* | "")
            echo "figures.sh: unknown argument '$arg' (usage: figures.sh [REPEAT] [--with-2000])" >&2
            exit 2
            ;;
        *) repeat="$arg" ;;
    esac
done
cargo build --release --quiet -p vol_app --manifest-path "$root/Cargo.toml"
app="${CARGO_TARGET_DIR:-$root/target}/release/vol_app"
frame=(--camera-pos 1100,1100,1100 --look-at 0,0,0 --fov 60 --step 0.2 --tf-preset shapes --stats)

row() {
    local file="$1" label="$2" reps="$3"
    shift 3
    # Warm the page cache so load_ms measures opening + ESS, not the disk;
    # --no-cache: building the macrocell grid, not reading its cache.
    cat "$root/volumes/$file" > /dev/null
    "$app" render "$root/volumes/$file" "${frame[@]}" --no-cache --repeat "$reps" "$@" | python3 -c '
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
    row "$file" "on / on" "$repeat" --size 700x700 --renderer serial --threads 1
    row "$file" "off / off" 1 --size 700x700 --renderer serial --threads 1 --ert off --ess off
    for renderer in tiles object; do
        for threads in 1 2; do
            row "$file" "on / on" "$repeat" --size 700x700 --renderer "$renderer" --threads "$threads"
        done
    done
    row "$file" "on / on, unshaded" "$repeat" --size 700x700 --renderer tiles --threads 2 --shading off
    # Pure sampling throughput on one core: nothing skipped, no shading,
    # the centre 350×350 of the frame (AVX2, then the portable loop).
    row "$file" "off / off, unshaded, 350×350" 3 --size 350x350 --renderer serial --threads 1 \
        --ert off --ess off --shading off
    RAYCASTER_SIMD=portable row "$file" "same, portable loop" 3 --size 350x350 --renderer serial \
        --threads 1 --ert off --ess off --shading off
done

if ((with_2000)); then
    big="$root/volumes/2000shapes_block16.vol"
    if [[ ! -e "$big" ]]; then
        echo "figures.sh: $big is missing (volumes/make_benchmark_volumes.sh --with-2000)" >&2
        exit 1
    fi
    view=(--size 700x700 --camera-pos 2750,2750,2750 --look-at 0,0,0 --tf-preset shapes --stats)
    cat "$big" > /dev/null
    results="$(mktemp)"
    trap 'rm -f "$results"' EXIT
    for ((i = 0; i < repeat; i++)); do
        # Interleaved, so that a disturbance of the machine hits all three.
        "$app" render "$big" "${view[@]}" --no-cache | sed 's/^/no-cache /' >> "$results"
        rm -f "$big".m*.rcidx
        "$app" render "$big" "${view[@]}" | sed 's/^/build /' >> "$results"
        "$app" render "$big" "${view[@]}" | sed 's/^/cached /' >> "$results"
    done
    echo
    echo "| 2000shapes_block16.vol (9.2 GiB), warm | open (load_ms, median) | frame (ms) | peak RSS after one frame |"
    echo "|---|---|---|---|"
    python3 - "$results" "$(stat -c %s "$big")" <<'PY'
import json, statistics, sys
runs = {}
for line in open(sys.argv[1]):
    kind, text = line.split(" ", 1)
    runs.setdefault(kind, []).append(json.loads(text))
size_mb = int(sys.argv[2]) / (1 << 20)
labels = {"no-cache": "`--no-cache` (macrocell grid built)",
          "build": "no cache yet (built and written)",
          "cached": "with the cache"}
for kind in ["no-cache", "build", "cached"]:
    r = runs[kind]
    load = statistics.median(d["load_ms"] for d in r)
    frame = statistics.median(d["frame_ms_median"] for d in r)
    rss = statistics.median(d["peak_rss_mb"] for d in r)
    loads = ", ".join(f"{d['load_ms']:.0f}" for d in r)
    print(f"| {labels[kind]} | {load:.0f} ms ({loads}) | {frame:.0f} | {rss:.0f} MB ({100 * rss / size_mb:.1f} % of the file) |")
PY
fi
