#!/usr/bin/env bash
# Smoke test of the interactive viewer on a virtual X server.
#
# Starts the release build of `vol_app` (the viewer) under Xvfb with software
# OpenGL, takes screenshots until the canvas shows a rendered volume (many
# colours, neither blank nor uniform), saves the screenshot as PNG and exits
# 0; exits 1 if that does not happen within the timeout.
#
#   scripts/viewer_smoke.sh [--out PNG] [--timeout SECONDS] [--settle SECONDS] [--no-build] [-- VOL_APP_ARGS...]
#
# The viewer shows a fast reduced preview first and refines it; the
# screenshot is retaken --settle seconds (default 5) after the first
# rendered frame, when the refinement to full resolution has had time to
# finish.
#
# Without VOL_APP_ARGS the viewer opens its built-in demo volume. The README's
# screenshot:
#   scripts/viewer_smoke.sh --out docs/viewer.png -- \
#       ../shared/data/interop/shapes_96x80x64_block16.vol --tf-preset shapes
#
# Needs (and installs with apt-get when missing, as root): xvfb, x11-apps
# (xwd), Mesa's software OpenGL and the X11 client libraries winit loads.
set -euo pipefail
cd "$(dirname "$0")/.."

out=target/viewer_smoke.png
timeout=60
settle=5
settled=0
build=1
while [ $# -gt 0 ]; do
    case "$1" in
        --out) out=$2; shift 2 ;;
        --timeout) timeout=$2; shift 2 ;;
        --settle) settle=$2; shift 2 ;;
        --no-build) build=0; shift ;;
        --) shift; break ;;
        -h|--help) sed -n '2,23p' "$0"; exit 0 ;;
        *) echo "viewer_smoke: unknown option $1 (see --help)" >&2; exit 2 ;;
    esac
done
app_args=("$@")
width=1280
height=800
started=$(date +%s.%N)

# --- system packages --------------------------------------------------------
packages=(xvfb x11-apps libgl1 libegl1 libgl1-mesa-dri libglx-mesa0 libegl-mesa0
          libxkbcommon-x11-0 libxcursor1 libxrandr2 libxi6 libx11-xcb1)
missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "== installing ${missing[*]}"
    sudo=""
    [ "$(id -u)" -ne 0 ] && sudo=sudo
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# --- build -------------------------------------------------------------------
if [ "$build" = 1 ]; then
    echo "== cargo build --release -p vol_app"
    cargo build --release -p vol_app
fi
bin=target/release/vol_app
[ -x "$bin" ] || { echo "viewer_smoke: $bin not found (build it, or drop --no-build)" >&2; exit 1; }

# --- virtual display, clean settings ----------------------------------------
work=$(mktemp -d)
display=""
for n in $(seq 90 140); do
    if [ ! -e "/tmp/.X11-unix/X$n" ] && [ ! -e "/tmp/.X$n-lock" ]; then display=":$n"; break; fi
done
[ -n "$display" ] || { echo "viewer_smoke: no free X display number" >&2; exit 1; }
xvfb_pid=""
app_pid=""
cleanup() {
    [ -n "$app_pid" ] && kill "$app_pid" 2>/dev/null || true
    [ -n "$xvfb_pid" ] && kill "$xvfb_pid" 2>/dev/null || true
    wait 2>/dev/null || true
    rm -rf "$work"
}
trap cleanup EXIT
Xvfb "$display" -screen 0 "${width}x${height}x24" -nolisten tcp >"$work/xvfb.log" 2>&1 &
xvfb_pid=$!
for _ in $(seq 50); do [ -e "/tmp/.X11-unix/X${display#:}" ] && break; sleep 0.1; done

echo "== vol_app ${app_args[*]:-(demo volume)} on $display"
env -u WAYLAND_DISPLAY DISPLAY="$display" HOME="$work" XDG_DATA_HOME="$work/data" \
    XDG_CONFIG_HOME="$work/config" LIBGL_ALWAYS_SOFTWARE=1 \
    "$bin" "${app_args[@]}" >"$work/app.log" 2>&1 &
app_pid=$!

# --- wait for a rendered frame ------------------------------------------------
mkdir -p "$(dirname "$out")"
deadline=$(( $(date +%s) + timeout ))
verdict="no screenshot taken"
while [ "$(date +%s)" -lt "$deadline" ]; do
    sleep 0.5
    if ! kill -0 "$app_pid" 2>/dev/null; then
        echo "viewer_smoke: vol_app exited early:" >&2
        cat "$work/app.log" >&2
        exit 1
    fi
    xwd -root -silent -display "$display" >"$work/shot.xwd" 2>/dev/null || continue
    if verdict=$(python3 - "$work/shot.xwd" "$out" <<'PY'
import struct, sys, zlib

def read_xwd(path):
    data = open(path, "rb").read()
    h = struct.unpack(">25I", data[:100])
    header_size, bpp, bpl = h[0], h[11], h[12]
    width, height, ncolors, byte_order = h[4], h[5], h[19], h[7]
    masks = h[14:17]
    if bpp != 32:
        raise SystemExit(f"unsupported XWD depth {bpp}")
    pixels = data[header_size + 12 * ncolors:]
    order = "<" if byte_order == 0 else ">"
    shifts = [(m & -m).bit_length() - 1 for m in masks]
    rows = []
    for y in range(height):
        row = pixels[y * bpl: y * bpl + 4 * width]
        vals = struct.unpack(f"{order}{width}I", row)
        rows.append(bytes(b for v in vals for b in ((v >> shifts[0]) & 255, (v >> shifts[1]) & 255, (v >> shifts[2]) & 255)))
    return width, height, rows

def write_png(path, width, height, rows):
    raw = b"".join(b"\0" + r for r in rows)
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    open(path, "wb").write(png)

w, h, rows = read_xwd(sys.argv[1])
# Surely canvas: right of the left panel (at most half the window wide),
# below the top edge and above the status line.
x0, x1, y0, y1 = int(0.55 * w), w - 10, 40, h - 40
colours, lit, total = set(), 0, 0
for y in range(y0, y1, 2):
    r = rows[y]
    for x in range(x0, x1, 2):
        px = r[3 * x: 3 * x + 3]
        colours.add(px)
        lit += max(px) > 24
        total += 1
frac = lit / total
ok = len(colours) >= 200 and 0.02 < frac < 0.98
print(f"canvas: {len(colours)} colours, {100 * frac:.1f}% lit")
if ok:
    write_png(sys.argv[2], w, h, rows)
sys.exit(0 if ok else 1)
PY
    ); then
        if [ "$settled" = 0 ] && [ "$settle" != 0 ]; then
            echo "== first frame: $verdict; waiting ${settle} s for the refinement"
            settled=1
            sleep "$settle"
            deadline=$(( deadline + settle ))
            continue
        fi
        elapsed=$(python3 -c "import time; print(f'{time.time() - $started:.1f}')")
        echo "== $verdict"
        echo "viewer_smoke: OK, screenshot $out (${elapsed} s in all)"
        exit 0
    fi
done
echo "viewer_smoke: no rendered volume on the canvas within ${timeout} s ($verdict)" >&2
echo "--- vol_app output:" >&2
cat "$work/app.log" >&2
exit 1
