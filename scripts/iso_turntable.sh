#!/usr/bin/env bash
# The seed thesis's isosurface benchmark (seed 001, Table 5.12): a 36-frame
# turntable (10° per frame about the vertical y axis) at 1280×1024 of the
# bunny's distance field on 128×128×100 cells, one primary ray per pixel.
# Prints one markdown row per configuration: mean over the 36 frames of the
# median frame time (--repeat REPEAT), the share of pixels whose ray enters
# the grid and hits the surface, and cells visited per entering ray.
#
#   scripts/iso_turntable.sh [REPEAT] [DISTANCE]   # REPEAT default 3
#
# DISTANCE is the camera's distance from the grid's centre in world units
# (the field's mesh units); the default, 20, puts 49% of the pixels' rays
# into the grid on average, as in the seed's set-up. Needs
# volumes/bunny_sdf.nrrd (volumes/make_bunny_sdf.sh). Extra configurations
# can be given in ISO_CONFIGS, one per line ("label|options").
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
repeat="${1:-3}"
distance="${2:-20}"
vol="$root/volumes/bunny_sdf.nrrd"
if [[ ! -f "$vol" ]]; then
    echo "iso_turntable.sh: $vol is missing: run volumes/make_bunny_sdf.sh first" >&2
    exit 2
fi
cargo build --release --quiet -p vol_app --manifest-path "$root/Cargo.toml"
app="${CARGO_TARGET_DIR:-$root/target}/release/vol_app"
centre=$("$app" info "$vol" --json | python3 -c '
import json, sys
d = json.load(sys.stdin)
dims, sp = d["dims"], d["spacing"]
print(",".join(str((n - 1) * s / 2) for n, s in zip(dims, sp)))')
configs="${ISO_CONFIGS:-shaded, headlight|--shading on
shaded, one light with shadows|--shading on --light 0.6,1,0.4 --shadows on
unshaded|--shading off}"
echo "| configuration | ms/frame (mean of 36) | rays entering | hits | cells per entering ray |"
echo "|---|---|---|---|---|"
while IFS='|' read -r label opts; do
    # shellcheck disable=SC2086
    python3 - "$app" "$vol" "$centre" "$distance" "$repeat" "$label" $opts <<'EOF'
import json, math, subprocess, sys
app, vol, centre, dist, repeat, label, *opts = sys.argv[1:]
c = [float(x) for x in centre.split(",")]
dist, repeat = float(dist), int(repeat)
ms, enter, hits, cells, pixels = [], 0, 0, 0, 0
for k in range(36):
    a = math.radians(10 * k)
    pos = (c[0] + dist * math.sin(a), c[1], c[2] + dist * math.cos(a))
    out = subprocess.run(
        [app, "render", vol, "--mode", "iso", "--iso", "0", "--size", "1280x1024",
         "--camera-pos", ",".join(f"{x:.6f}" for x in pos),
         "--look-at", centre, "--repeat", str(repeat), "--stats", *opts],
        check=True, capture_output=True, text=True).stdout
    s = json.loads(out)
    ms.append(s["frame_ms_median"])
    enter += s["rays_in_volume"]
    hits += s["covered"]
    cells += s["samples"]
    pixels += s["width"] * s["height"]
print(f"| {label} | {sum(ms) / len(ms):.1f} | {100 * enter / pixels:.0f}% "
      f"| {100 * hits / pixels:.1f}% | {cells / max(enter, 1):.2f} |")
EOF
done <<< "$configs"
