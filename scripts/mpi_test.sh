#!/usr/bin/env bash
# Distributed rendering on MPI, end to end (SPEC §8 "Distributed rendering").
#
# Installs Open MPI, libclang and pkg-config with apt-get when missing (the
# `mpi` feature's rsmpi needs them to build), builds vol_app with
# `--features mpi`, and on a linear and a bricked .vol made by vol_gen:
#
#   - renders DVR (ERT off and on), MIP and iso, from outside and from
#     inside the volume, with `mpirun -n P vol_app render --distributed` for
#     P = 1, 2, 4 (oversubscribed on a 2-core machine; `--bind-to none`)
#     and each compositing method (--composite gather, direct-send,
#     binary-swap), and compares each PNG with the single-process render
#     (compare_png: PSNR >= 50 dB; DVR with ERT: at most 3 levels anywhere,
#     what the ERT threshold of 0.99 allows);
#   - binary swap with P = 3 (not a power of two): falls back to direct
#     send (the --stats say so) and still matches;
#   - balancing: occupancy (the default) from a first pass when there is
#     no macrocell cache (which rank 0 then writes), from the cache after
#     it, with --no-cache, and --balance voxels, each against the single
#     process; a headerless raw file (--raw-dims ...) read in part;
#   - checks that a missing file, and one rank failing to open its part,
#     end every rank with an error (non-zero exit, no hang: `timeout`);
#   - times --repeat 3 --stats for P = 1, 2, 4 and each method
#     (target/mpi/stats_pP.METHOD.json).
#
#   scripts/mpi_test.sh [--no-build]
#
# --no-build skips the feature build (target/release/vol_app must then be
# the MPI build). Leaves target/release/vol_app built with the feature; a
# plain `cargo build --release --workspace` puts the default one back
# (cargo keeps both builds' artifacts).
set -euo pipefail
cd "$(dirname "$0")/.."

build=1
while [ $# -gt 0 ]; do
    case "$1" in
        --no-build) build=0; shift ;;
        -h|--help) sed -n '2,27p' "$0"; exit 0 ;;
        *) echo "mpi_test: unknown option $1 (see --help)" >&2; exit 2 ;;
    esac
done

need=()
command -v mpirun >/dev/null 2>&1 || need+=(openmpi-bin)
dpkg -s libopenmpi-dev >/dev/null 2>&1 || need+=(libopenmpi-dev)
dpkg -s libclang-dev >/dev/null 2>&1 || need+=(libclang-dev)
command -v pkg-config >/dev/null 2>&1 || need+=(pkg-config)
if [ ${#need[@]} -gt 0 ]; then
    echo "== mpi_test: installing ${need[*]}"
    sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${need[@]}" >/dev/null
fi

if [ $build -eq 1 ]; then
    echo "== mpi_test: build (release, vol_app with --features mpi)"
    # The whole workspace with the feature added: every other crate keeps
    # the default build's features, so only vol_app and rsmpi compile.
    cargo build --release --workspace --features vol_app/mpi
    cargo build --release -p raycaster --example compare_png
fi

app=target/release/vol_app
gen=target/release/vol_gen
compare=target/release/examples/compare_png
dir=target/mpi
mkdir -p "$dir"
mpirun_() {
    local n=$1
    shift
    timeout 300 mpirun --oversubscribe --allow-run-as-root --bind-to none -n "$n" "$@"
}

"$gen" --dims 96,80,64 --generator shapes --layout linear --seed 3 --force -o "$dir/shapes_linear.vol" >/dev/null
"$gen" --dims 96,80,64 --generator shapes --layout bricked --block-size 16 --seed 3 --force -o "$dir/shapes_bricked.vol" >/dev/null

common=(--size 160x128 --tf-preset shapes --step 0.5 --threads 1)
inside=(--camera-pos 40,35,30 --look-at 10,60,0 --fov 80)
checks=0
methods=(gather direct-send binary-swap)
run_case() {
    local name=$1 limit=$2 file=$3
    shift 3
    "$app" render "$file" "${common[@]}" "$@" --out "$dir/$name.single.png"
    for m in "${methods[@]}"; do
        for p in 1 2 4; do
            mpirun_ "$p" "$app" render "$file" --distributed "${common[@]}" "$@" \
                --composite "$m" --out "$dir/$name.$m.p$p.png"
            # shellcheck disable=SC2086
            "$compare" "$dir/$name.single.png" "$dir/$name.$m.p$p.png" $limit
            checks=$((checks + 1))
        done
    done
}

for layout in linear bricked; do
    f="$dir/shapes_$layout.vol"
    echo "== mpi_test: $layout, distributed against single-process (P = 1, 2, 4)"
    run_case "$layout-dvr" "--min-psnr 50" "$f" --mode dvr --ert off
    run_case "$layout-dvr-ert" "--min-psnr 0 --max-diff 3" "$f" --mode dvr
    run_case "$layout-mip" "--min-psnr 50" "$f" --mode mip
    run_case "$layout-iso" "--min-psnr 50" "$f" --mode iso --iso 97
    run_case "$layout-dvr-inside" "--min-psnr 50" "$f" --mode dvr --ert off "${inside[@]}"
    run_case "$layout-iso-inside" "--min-psnr 50" "$f" --mode iso --iso 97 "${inside[@]}"
done

echo "== mpi_test: binary swap with P = 3 (not a power of two: falls back to direct send)"
f="$dir/shapes_linear.vol"
for c in "dvr|--min-psnr 50|--mode dvr --ert off" "mip|--min-psnr 50|--mode mip" \
    "iso|--min-psnr 50|--mode iso --iso 97" "dvr-inside|--min-psnr 50|--mode dvr --ert off ${inside[*]}"; do
    IFS='|' read -r name limit opts <<<"$c"
    # shellcheck disable=SC2086
    mpirun_ 3 "$app" render "$f" --distributed "${common[@]}" $opts --composite binary-swap \
        --out "$dir/linear-$name.binary-swap.p3.png" --stats >"$dir/p3.json"
    grep -q '"compositing":"direct-send"' "$dir/p3.json"
    grep -q '"composite_requested":"binary-swap"' "$dir/p3.json"
    # shellcheck disable=SC2086
    "$compare" "$dir/linear-$name.single.png" "$dir/linear-$name.binary-swap.p3.png" $limit
    checks=$((checks + 1))
done
# P = 4 does run binary swap (the stats say which method ran).
mpirun_ 4 "$app" render "$f" --distributed "${common[@]}" --composite binary-swap --stats >"$dir/p4.json"
grep -q '"compositing":"binary-swap"' "$dir/p4.json"
checks=$((checks + 1))

echo "== mpi_test: balancing (occupancy from the cache or a first pass; voxels)"
f="$dir/shapes_bricked.vol"
cache="$f.m4.rcidx"
rm -f "$cache"
# No cache yet: the ranks' first pass finds the macrocell ranges, rank 0
# writes the cache, and the next run reads it.
mpirun_ 2 "$app" render "$f" --distributed "${common[@]}" --mode dvr --ert off \
    --out "$dir/bal-first.png" --stats >"$dir/bal.json"
grep -q '"balance_ranges":"first pass"' "$dir/bal.json"
test -s "$cache"
"$compare" "$dir/bricked-dvr.single.png" "$dir/bal-first.png" --min-psnr 50
mpirun_ 4 "$app" render "$f" --distributed "${common[@]}" --mode dvr --ert off \
    --out "$dir/bal-cache.png" --stats >"$dir/bal.json"
grep -q '"balance_ranges":"cache"' "$dir/bal.json"
"$compare" "$dir/bricked-dvr.single.png" "$dir/bal-cache.png" --min-psnr 50
# --no-cache: the first pass again, and no cache read.
mpirun_ 3 "$app" render "$f" --distributed "${common[@]}" --mode iso --iso 97 --no-cache \
    --out "$dir/bal-nocache.png" --stats >"$dir/bal.json"
grep -q '"balance_ranges":"first pass"' "$dir/bal.json"
"$compare" "$dir/bricked-iso.single.png" "$dir/bal-nocache.png" --min-psnr 50
mpirun_ 4 "$app" render "$f" --distributed "${common[@]}" --mode mip --balance voxels \
    --out "$dir/bal-voxels.png" --stats >"$dir/bal.json"
grep -q '"balance":"voxels"' "$dir/bal.json"
"$compare" "$dir/bricked-mip.single.png" "$dir/bal-voxels.png" --min-psnr 50
checks=$((checks + 4))

echo "== mpi_test: a headerless raw file read in part (the linear .vol's samples after its 26-byte header)"
raw=(--raw-dims 96,80,64 --raw-type u8 --raw-offset 26 --raw-order zfast)
mpirun_ 3 "$app" render "$dir/shapes_linear.vol" "${raw[@]}" --distributed "${common[@]}" \
    --mode dvr --ert off --out "$dir/raw.p3.png"
"$compare" "$dir/linear-dvr.single.png" "$dir/raw.p3.png" --min-psnr 50
checks=$((checks + 1))

echo "== mpi_test: failures end every rank (no hang)"
expect_failure() {
    local what=$1
    shift
    set +e
    "$@" >"$dir/fail.out" 2>"$dir/fail.err"
    local code=$?
    set -e
    if [ $code -eq 0 ] || [ $code -eq 124 ]; then
        echo "mpi_test: $what: exit $code (expected an error, not success or a hang)" >&2
        cat "$dir/fail.err" >&2
        exit 1
    fi
    echo "$what: exit $code: $(grep -m1 'vol_app' "$dir/fail.err" || head -1 "$dir/fail.err")"
    checks=$((checks + 1))
}
timeout_=60
expect_failure "missing file" timeout $timeout_ mpirun --oversubscribe --allow-run-as-root -n 2 \
    "$app" render "$dir/no_such_file.vol" --distributed --out "$dir/never.png"
grep -q no_such_file.vol "$dir/fail.err"
expect_failure "rank 1 cannot open its part" timeout $timeout_ mpirun --oversubscribe --allow-run-as-root \
    -x VOL_APP_DISTRIBUTED_FAIL_RANK=1 -n 4 \
    "$app" render "$dir/shapes_linear.vol" --distributed --out "$dir/never.png"

echo "== mpi_test: frame times (bricked, 400x400, --tf-preset shapes --step 0.5, --repeat 3 --stats)"
for p in 1 2 4; do
    threads=1
    [ "$p" -eq 1 ] && threads=2
    for m in "${methods[@]}"; do
        mpirun_ "$p" "$app" render "$dir/shapes_bricked.vol" --distributed --size 400x400 \
            --tf-preset shapes --step 0.5 --threads $threads --repeat 3 --stats \
            --composite "$m" >"$dir/stats_p$p.$m.json"
        cat "$dir/stats_p$p.$m.json"
    done
done
"$app" render "$dir/shapes_bricked.vol" --size 400x400 --tf-preset shapes --step 0.5 \
    --threads 2 --repeat 3 --stats >"$dir/stats_single.json"
cat "$dir/stats_single.json"

echo "mpi_test: OK ($checks checks)"
