#!/usr/bin/env bash
# Times our renderer and VTK's CPU ray caster (vtkFixedPointVolumeRayCastMapper) on the
# benchmark frame, back to back, and compares the images (PSNR).
#
#   scripts/vtk/run.sh                       # one run, shading off
#   RUNS=3 SHADING="off on" scripts/vtk/run.sh
#
# Environment:
#   BIN      our binary (default /tmp/vol_app_bench; copied from target/release/vol_app
#            when missing, so a rebuild of the tree does not change it mid-run)
#   VOL      volume (default volumes/800shapes_linear.vol; VTK needs the linear layout)
#   BRICKED  the same voxels in bricks, which ours also renders in each run (default
#            volumes/800shapes_block16.vol, the README's benchmark frame, when it
#            exists; empty: linear only). Its image must equal the linear one's.
#   RUNS     repetitions of the pair (default 1)      REPEAT  timed frames (default 5)
#   SHADING  "off", "on" or "off on" (default off)    THREADS (default 2)
#   RENDERER ours: tiles (default), object or serial
#   OUT      output folder (default /tmp/vtk_bench)
#   SAVE_PNGS=1  also copy the last images to scripts/vtk/{ours,vtk}.png if < 300 KB
# Both sides run under `nice -n -10` when allowed.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
BIN="${BIN:-/tmp/vol_app_bench}"
VOL="${VOL:-$ROOT/volumes/800shapes_linear.vol}"
BRICKED="${BRICKED-$ROOT/volumes/800shapes_block16.vol}"
[ -n "$BRICKED" ] && [ ! -f "$BRICKED" ] && BRICKED=""
RUNS="${RUNS:-1}"
REPEAT="${REPEAT:-5}"
SHADING="${SHADING:-off}"
THREADS="${THREADS:-2}"
RENDERER="${RENDERER:-tiles}"
OUT="${OUT:-/tmp/vtk_bench}"
mkdir -p "$OUT"

# ---- dependencies -------------------------------------------------------------------
if ! python3 -c 'import vtk, numpy, PIL' 2>/dev/null; then
    echo "installing vtk, numpy, pillow (pip)" >&2
    python3 -m pip install --quiet vtk numpy pillow
fi
if ! dpkg -s libosmesa6 >/dev/null 2>&1; then
    echo "installing libosmesa6 (apt)" >&2
    (apt-get update -qq && apt-get install -y -qq libosmesa6) >&2
fi
export VTK_DEFAULT_OPENGL_WINDOW=vtkOSOpenGLRenderWindow

if [ ! -x "$BIN" ]; then
    [ -x "$ROOT/target/release/vol_app" ] || { echo "no $BIN and no target/release/vol_app (build it first)" >&2; exit 1; }
    cp "$ROOT/target/release/vol_app" "$BIN"
fi
[ -f "$VOL" ] || { echo "missing $VOL (volumes/make_benchmark_volumes.sh makes it)" >&2; exit 1; }

NICE=()
if nice -n -10 true 2>/dev/null; then NICE=(nice -n -10); fi

CAM=(--size 700x700 --camera-pos 1100,1100,1100 --look-at 0,0,0 --fov 60 --step 0.2)

echo "VTK $(python3 -c 'import vtk; print(vtk.vtkVersion.GetVTKVersion())'), nice: ${NICE[*]:-none}, threads $THREADS, $(nproc) cores"
SUMMARY="$OUT/summary.txt"
: > "$SUMMARY"
for run in $(seq 1 "$RUNS"); do
    for sh in $SHADING; do
        tag="run${run}_shading_${sh}"
        load_before="$(cut -d' ' -f1 /proc/loadavg)"
        "${NICE[@]}" "$BIN" render "$VOL" "${CAM[@]}" --tf-preset shapes --shading "$sh" \
            --threads "$THREADS" --renderer "$RENDERER" --repeat "$REPEAT" --stats \
            --out "$OUT/ours_$tag.png" > "$OUT/ours_$tag.json"
        bricked_json=""
        if [ -n "$BRICKED" ]; then
            bricked_json="$OUT/ours_bricked_$tag.json"
            "${NICE[@]}" "$BIN" render "$BRICKED" "${CAM[@]}" --tf-preset shapes --shading "$sh" \
                --threads "$THREADS" --renderer "$RENDERER" --repeat "$REPEAT" --stats \
                --out "$OUT/ours_bricked_$tag.png" > "$bricked_json"
            cmp -s "$OUT/ours_$tag.png" "$OUT/ours_bricked_$tag.png" \
                || { echo "$BRICKED renders another image than $VOL" >&2; exit 1; }
        fi
        "${NICE[@]}" python3 "$HERE/vtk_compare.py" render "$VOL" "${CAM[@]}" --shading "$sh" \
            --threads "$THREADS" --repeat "$REPEAT" --out "$OUT/vtk_$tag.png" \
            --ours "$OUT/ours_$tag.png" > "$OUT/vtk_$tag.json" 2> "$OUT/vtk_$tag.log"
        load_after="$(cut -d' ' -f1 /proc/loadavg)"
        python3 - "$OUT/ours_$tag.json" "$OUT/vtk_$tag.json" "$tag" "$load_before" "$load_after" "$bricked_json" <<'EOF' | tee -a "$SUMMARY"
import json, sys
last = lambda path: json.loads(open(path).read().strip().splitlines()[-1])
ours, vtk = last(sys.argv[1]), last(sys.argv[2])
o, v = ours["frame_ms_median"], vtk["frame_ms_median"]
c = vtk.get("compare", {})
bricked = ""
if sys.argv[6]:
    b = last(sys.argv[6])["frame_ms_median"]
    bricked = f" | ours bricked {b:.1f} ms (same image) = {b/v:.3f}x VTK"
print(f"{sys.argv[3]}: ours {o:.1f} ms {ours['frame_ms']} | VTK {v:.1f} ms {vtk['frame_ms']} "
      f"(cast only {vtk.get('cast_ms_median', 0):.1f}, wall {vtk['wall_ms_median']:.1f}) | VTK/ours {v/o:.2f}x, "
      f"ours = {o/v:.3f}x VTK{bricked} | PSNR {c.get('psnr_db')} dB, MAD {c.get('mean_abs_diff')} "
      f"| load {sys.argv[4]}->{sys.argv[5]}")
EOF
    done
done

if [ "${SAVE_PNGS:-0}" = 1 ]; then
    last_tag="run${RUNS}_shading_$(echo "$SHADING" | awk '{print $1}')"
    for side in ours vtk; do
        f="$OUT/${side}_$last_tag.png"
        if [ "$(stat -c %s "$f")" -lt 307200 ]; then cp "$f" "$HERE/$side.png"; fi
    done
fi
echo "images and JSON in $OUT; summary in $SUMMARY"
