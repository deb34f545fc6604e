#!/usr/bin/env bash
# Generates the seed thesis's benchmark volumes (thesis §5.1: "shapes" volumes
# of 800³ and 2000³ voxels, linear and in bricks of 16) into this directory.
# Builds vol_gen in release mode first; files that already exist are skipped
# (delete one to regenerate it). The volumes are gitignored.
#
#   volumes/make_benchmark_volumes.sh              # 800³ linear + block16 (1.2 GB)
#   volumes/make_benchmark_volumes.sh --with-2000  # also 2000³ block16 (9.8 GB)
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(dirname "$here")"
with_2000=0
for arg in "$@"; do
    case "$arg" in
        --with-2000) with_2000=1 ;;
        -h | --help)
            sed -n '2,8p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
            exit 0
            ;;
        *)
            echo "make_benchmark_volumes.sh: unknown argument '$arg' (try --help)" >&2
            exit 2
            ;;
    esac
done

# --workspace: the features of a workspace build, so that the build after
# the README's `cargo build --release --workspace` recompiles nothing.
cargo build --release --quiet --workspace --bin vol_gen --manifest-path "$root/Cargo.toml"
vol_gen="${CARGO_TARGET_DIR:-$root/target}/release/vol_gen"

# The thesis README's parameters.
shapes=(--generator shapes --seed 2 --n-of-shapes 70 --sample 100 --object-size 70)

generate() {
    local name="$1"
    shift
    if [[ -e "$here/$name" ]]; then
        echo "skip $name (exists)"
        return
    fi
    echo "generate $name"
    "$vol_gen" "$@" --output-file "$here/$name"
}

generate 800shapes_linear.vol --dims=800,800,800 "${shapes[@]}"
generate 800shapes_block16.vol --dims=800,800,800 "${shapes[@]}" --layout z --block-size 16
if ((with_2000)); then
    generate 2000shapes_block16.vol --dims=2000,2000,2000 "${shapes[@]}" --layout z --block-size 16
fi
