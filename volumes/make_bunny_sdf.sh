#!/usr/bin/env bash
# Writes volumes/bunny_sdf.nrrd: the signed distance field (f32, negative
# inside, mesh units) of the Stanford bunny in tests/data/bunny.ply, on
# 129x129x101 voxels (the seed thesis's 128x128x100 cells), with vol_gen's
# default margin of 3 voxels. Builds vol_gen in release mode first;
# overwrites an existing file. Extra arguments go to vol_gen (e.g. --quiet).
#
#   volumes/make_bunny_sdf.sh
#   vol_app render volumes/bunny_sdf.nrrd --mode iso --iso 0 --out bunny.png
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(dirname "$here")"
case "${1:-}" in
    -h | --help)
        sed -n '2,9p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
        exit 0
        ;;
esac

# --workspace: the features of a workspace build, so that the build after
# the README's `cargo build --release --workspace` recompiles nothing.
cargo build --release --quiet --workspace --bin vol_gen --manifest-path "$root/Cargo.toml"
vol_gen="${CARGO_TARGET_DIR:-$root/target}/release/vol_gen"

"$vol_gen" --dims 129,129,101 --generator mesh --mesh "$root/tests/data/bunny.ply" \
    --output-file "$here/bunny_sdf.nrrd" --force "$@"
