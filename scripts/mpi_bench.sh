#!/usr/bin/env bash
# Times the three compositing methods of `vol_app render --distributed`
# (README, "Distributed rendering (MPI)"): for ROUNDS rounds, every
# (size, P, method) once per round, interleaved so that a change of the
# machine's load hits every method alike; one --stats JSON object a line
# in target/mpi/bench.jsonl (with "round" and "load" added). Needs the MPI
# build (scripts/mpi_test.sh leaves it in target/release/vol_app).
#
#   scripts/mpi_bench.sh [ROUNDS] [SIZES...]     (default: 5 400x400 1024x1024)
set -euo pipefail
cd "$(dirname "$0")/.."
rounds=${1:-5}
shift || true
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(400x400 1024x1024)
app=target/release/vol_app
dir=target/mpi
out=$dir/bench.jsonl
mkdir -p "$dir"
[ -f "$dir/shapes_bricked.vol" ] || target/release/vol_gen --dims 96,80,64 --generator shapes \
    --layout bricked --block-size 16 --seed 3 --force -o "$dir/shapes_bricked.vol" >/dev/null
: >"$out"
for round in $(seq 1 "$rounds"); do
    for size in "${sizes[@]}"; do
        for p in 1 2 4; do
            threads=1
            [ "$p" -eq 1 ] && threads=2
            for m in gather direct-send binary-swap; do
                load=$(cut -d' ' -f1 /proc/loadavg)
                json=$(timeout 300 mpirun --oversubscribe --allow-run-as-root --bind-to none -n "$p" \
                    "$app" render "$dir/shapes_bricked.vol" --distributed --size "$size" \
                    --tf-preset shapes --step 0.5 --threads $threads --repeat 3 --stats \
                    --composite "$m")
                echo "{\"round\":$round,\"load\":$load,${json#\{}" >>"$out"
                echo "round $round $size P=$p $m: load $load, $(grep -o '"frame_ms_median":[0-9.]*' <<<"$json"), $(grep -o '"composite_ms_median":[0-9.]*' <<<"$json")"
            done
        done
    done
done
