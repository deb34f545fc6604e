#!/usr/bin/env bash
# The time-series figures of the README (issue 13): a 128³ × 150-frame f32
# plume (values 0.99..1.5, the seed thesis's rocket-engine range) packed
# with every codec, with and without half floats and difference frames;
# the size of each as a percentage of the raw samples; decode times per
# frame (examples/vseq_decode.rs: sequential and random access); and
# playback at 640×480 with decoding overlapped (vol_app render --frames
# --stats), from the .vseq files and from the directory of raw frames.
#
#   scripts/sequence_bench.sh            # everything (about 10 minutes)
#   FRAMES=30 scripts/sequence_bench.sh  # a shorter sequence
set -euo pipefail
cd "$(dirname "$0")/.."
FRAMES=${FRAMES:-150}
DIMS=${DIMS:-128,128,128}
DIR=${DIR:-volumes/plume}
ROUNDS=${ROUNDS:-2}
cargo build --release -q --workspace --bin vol_app --bin vol_gen
cargo build --release -q -p raycaster --example vseq_decode
BIN=target/release
if [ ! -e "$DIR/frame_0000.nrrd" ]; then
    "$BIN/vol_gen" --dims "$DIMS" --generator plume --frames "$FRAMES" --seed 1 -o "$DIR/" --force
fi
echo "== sizes (percent of the raw f32 samples) and decode ms per frame"
for f16 in "" "--f16"; do
    for codec in none lz4 zstd; do
        for key in 1 10; do
            out="$DIR.$codec${f16:+.f16}.k$key.vseq"
            size=$("$BIN/vol_app" pack "$DIR" -o "$out" --codec "$codec" $f16 --key-interval "$key" --force --json)
            dec=$("$BIN/examples/vseq_decode" "$out" "$ROUNDS")
            echo "{\"pack\":$size,\"decode\":$dec}"
        done
    done
done
echo "== zstd level 19, f16, key frames every 10"
out="$DIR.zstd19.f16.k10.vseq"
"$BIN/vol_app" pack "$DIR" -o "$out" --codec zstd --level 19 --f16 --key-interval 10 --force --json
"$BIN/examples/vseq_decode" "$out" "$ROUNDS"
echo "== playback, 640x480, object renderer, decoding on its own thread"
play() {
    "$BIN/vol_app" render "$1" --frames 0.. --size 640x480 --tf-preset ramp --stats \
        | python3 -c 'import json,sys; s=json.load(sys.stdin); print(json.dumps({k: s[k] for k in ["frames","fps","decode_ms_median","build_ms_median","render_ms_median","wait_ms_median"]}))'
}
for src in "$DIR" "$DIR.lz4.k1.vseq" "$DIR.lz4.f16.k1.vseq" "$DIR.zstd.f16.k10.vseq"; do
    echo "$src: $(play "$src")"
done
