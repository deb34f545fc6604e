#!/usr/bin/env bash
# Measures vol_gen's write throughput against a raw write of the same number
# of bytes on the same disk, in the same run: `head -c N /dev/zero > file`
# (into the page cache only) and the same followed by `sync file` (on disk, as
# vol_gen's output always is: it syncs before renaming). Uses the thesis's
# 800³ shapes volume in both layouts; writes only temporary files here and
# removes them.
#
# Each timed step starts from a quiet disk (no file, `sync`, a pause), and the
# order of the raw write and vol_gen alternates between repeats: on a file
# system mounted with `discard`, deleting the previous 0.5 GB file slows the
# next write for a while.
#
#   volumes/measure_vol_gen.sh [REPEATS]    # default 3; prints medians in MB/s
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(dirname "$here")"
repeats="${1:-3}"
# --workspace: the features of a workspace build, so that the build after
# the README's `cargo build --release --workspace` recompiles nothing.
cargo build --release --quiet --workspace --bin vol_gen --manifest-path "$root/Cargo.toml"
vol_gen="${CARGO_TARGET_DIR:-$root/target}/release/vol_gen"
tmp="$here/.measure.vol"
trap 'rm -f "$tmp"' EXIT

now() { date +%s.%N; }
since() { awk -v a="$1" -v b="$(now)" 'BEGIN { print b - a }'; }
median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }
mbps() { awk -v n="$1" -v t="$2" 'BEGIN { printf "%.0f", n / 1e6 / t }'; }
settle() {
    rm -f "$tmp"
    sync
    sleep 2
}

shapes=(--dims=800,800,800 --generator shapes --seed 2 --n-of-shapes 70 --sample 100 --object-size 70)
for layout in linear block16; do
    if [[ $layout == linear ]]; then
        extra=()
        bytes=$((26 + 800 * 800 * 800))
    else
        extra=(--layout z --block-size 16)
        bytes=$((26 + 54 * 54 * 54 * 16 * 16 * 16))
    fi
    head_t=() sync_t=() gen_t=()
    raw() {
        settle
        local t0
        t0=$(now)
        head -c "$bytes" /dev/zero >"$tmp"
        head_t+=("$(since "$t0")")
        sync "$tmp"
        sync_t+=("$(since "$t0")")
    }
    gen() {
        settle
        local t0
        t0=$(now)
        "$vol_gen" "${shapes[@]}" "${extra[@]}" --quiet --output-file "$tmp"
        gen_t+=("$(since "$t0")")
        [[ $(stat -c %s "$tmp") == "$bytes" ]] || { echo "wrong size" >&2; exit 1; }
    }
    for ((i = 0; i < repeats; i++)); do
        if ((i % 2 == 0)); then raw; gen; else gen; raw; fi
        echo "  $layout run $((i + 1)): head ${head_t[-1]}s, head+sync ${sync_t[-1]}s, vol_gen ${gen_t[-1]}s" >&2
    done
    h=$(printf '%s\n' "${head_t[@]}" | median)
    s=$(printf '%s\n' "${sync_t[@]}" | median)
    g=$(printf '%s\n' "${gen_t[@]}" | median)
    printf '%-8s %11d bytes: head %5s MB/s (%ss)  head+sync %5s MB/s (%ss)  vol_gen %5s MB/s (%ss)\n' \
        "$layout" "$bytes" "$(mbps "$bytes" "$h")" "$h" "$(mbps "$bytes" "$s")" "$s" \
        "$(mbps "$bytes" "$g")" "$g"
done
