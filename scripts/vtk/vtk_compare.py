#!/usr/bin/env python3
"""Render our benchmark frame with VTK's CPU ray caster (vtkFixedPointVolumeRayCastMapper),
time it, and compare its image with ours.

Subcommands:
  render        VTK render + timing of a .vol file (SPEC §1) with our camera / TF / step
                conventions (SPEC §2-§5); optional PSNR against our PNG.
  compare       PSNR / mean absolute difference of two PNGs.
  orient-test   Writes a tiny asymmetric .vol, renders it with our binary and with VTK
                and checks that the two images agree (orientation, flips, camera).

Run with VTK_DEFAULT_OPENGL_WINDOW=vtkOSOpenGLRenderWindow for headless use (libosmesa6).
Prints one JSON line on stdout (like `vol_app render --stats`).

How the frame is set up in VTK (so that it is the same frame as ours):
  * the .vol data (z fastest) is transposed to VTK's x-fastest order, so sample (x,y,z)
    sits at world (x,y,z)·spacing with origin 0 (vtkImageData), as in SPEC §2;
  * camera: position, focal point, view-up, vertical view angle, perspective; the
    clipping range is set from the volume's corners so that nothing is clipped;
  * step TF (SPEC §4) replicated with pairs of points eps apart; opacity per world unit:
    SetScalarOpacityUnitDistance(1.0), so VTK's table holds 1-(1-a)^step as ours does;
  * SetSampleDistance(step), AutoAdjustSampleDistances off, ImageSampleDistance 1,
    LockSampleDistanceToInputSpacing off, IntermixIntersectingGeometry off, N threads.

Known systematic differences of the fixed-point mapper (see --value-scale):
  * it rounds the interpolated value to the nearest integer table entry (15-bit fixed
    point, +0x7fff before >>15), so a step at value k switches at k-0.5, while ours
    (SPEC §4, "last point <= v") switches at k.  --value-scale S multiplies the data by S
    (u16) and the TF values by S, which moves VTK's switch to k-0.5/S: a closer match
    for image checks, not the benchmark configuration (which is native u8, S=1);
  * colours/opacities/accumulation are 15-bit fixed point; early ray termination when
    the remaining transparency < 255/32768 (A > 0.992; ours: A >= 0.99);
  * samples are placed at fixed steps from the near clipping plane, not from the
    ray's entry into the box (a sub-step phase shift): different moire on the
    opaque surfaces, the main source of the remaining per-pixel differences.
Shading (--shading on) is only roughly comparable: VTK precomputes quantised per-voxel
gradient normals once (warm-up), lights with a directional headlight along the central
view direction (Blinn N·H; ours Phong R·V per ray, hence --vtk-power-factor), and gives
zero-gradient voxels (homogeneous interiors) ambient light only, while ours leaves samples
below its gradient threshold unshaded; so VTK's shaded image is much darker inside
translucent / just-entered material. The fixed-point mapper does not expose its
vtkEncodedGradientShader (ZeroNormalDiffuseIntensity) to change that.
"""

import argparse
import json
import math
import os
import statistics
import struct
import subprocess
import sys
import time

import numpy as np

# The `shapes` preset (crates/raycaster/src/transfer.rs, SPEC §4): step TF,
# its bounds just above the values the generator writes (85, 95, 100), so a
# shape of exactly 95 is red and one of 100 blue, as in the thesis's TF.
SHAPES_TF = [
    (85.001, (255 / 255, 30 / 255, 60 / 255), 0.02),
    (95.001, (10 / 255, 60 / 255, 180 / 255), 0.3),
    (100.001, (90 / 255, 210 / 255, 20 / 255), 0.6),
    (115.0, (0.0, 0.0, 0.0), 0.0),
]


def vec3(s):
    v = [float(x) for x in s.split(",")]
    if len(v) != 3:
        raise argparse.ArgumentTypeError("expected x,y,z")
    return v


def size2(s):
    w, h = s.lower().split("x")
    return int(w), int(h)


# --------------------------------------------------------------------------- .vol
def read_vol_header(path):
    with open(path, "rb") as f:
        hdr = f.read(26)
    if len(hdr) < 26:
        sys.exit(f"{path}: shorter than the 26-byte header")
    X, Y, Z, sx, sy, sz, layout, _ = struct.unpack("<3I3f2B", hdr)
    if layout != 1:
        sys.exit(f"{path}: layout {layout} is not linear (1); use the *_linear.vol file")
    return (X, Y, Z), (sx, sy, sz)


def load_vol_xfast(path):
    """Samples of a linear .vol as a C-contiguous array of shape (Z, Y, X): x fastest,
    VTK's order, with a[z, y, x] = sample (x, y, z)."""
    (X, Y, Z), spacing = read_vol_header(path)
    raw = np.fromfile(path, dtype=np.uint8, offset=26)
    if raw.size != X * Y * Z:
        sys.exit(f"{path}: expected {X*Y*Z} sample bytes, found {raw.size}")
    a = raw.reshape(X, Y, Z)  # a[x, y, z], z fastest (SPEC §1)
    out = np.ascontiguousarray(a.transpose(2, 1, 0))  # out[z, y, x], x fastest
    del raw, a
    return out, (X, Y, Z), spacing


def write_vol(path, data_xyz, spacing=(1.0, 1.0, 1.0)):
    """data_xyz[x, y, z] (u8) -> linear .vol (z fastest)."""
    X, Y, Z = data_xyz.shape
    with open(path, "wb") as f:
        f.write(struct.pack("<3I3f2B", X, Y, Z, *spacing, 1, 0))
        f.write(np.ascontiguousarray(data_xyz, dtype=np.uint8).tobytes())


# --------------------------------------------------------------------------- images
def read_png(path):
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64)


def compare_images(a_path, b_path):
    a, b = read_png(a_path), read_png(b_path)
    if a.shape != b.shape:
        return {"error": f"shapes differ: {a.shape} vs {b.shape}"}
    d = a - b
    mse = float(np.mean(d * d))
    psnr = float("inf") if mse == 0 else 10 * math.log10(255.0**2 / mse)
    ad = np.abs(d)
    lit = (a.max(axis=2) > 0) | (b.max(axis=2) > 0)
    return {
        "psnr_db": round(psnr, 2),
        "mean_abs_diff": round(float(ad.mean()), 3),
        "mean_abs_diff_lit_pixels": round(float(ad[lit].mean()), 3) if lit.any() else 0.0,
        "max_abs_diff": int(ad.max()),
        "pixels_diff_gt_8": int((ad.max(axis=2) > 8).sum()),
        "pixels_diff_gt_32": int((ad.max(axis=2) > 32).sum()),
        "lit_pixels": int(lit.sum()),
        # signed mean per channel over lit pixels: b - a (positive = second image brighter)
        "mean_signed_rgb_b_minus_a": [round(float(x), 2) for x in (-d[lit]).mean(axis=0)]
        if lit.any()
        else [0, 0, 0],
        "mean_rgb_a": [round(float(x), 2) for x in a[lit].mean(axis=0)] if lit.any() else [0, 0, 0],
        "mean_rgb_b": [round(float(x), 2) for x in b[lit].mean(axis=0)] if lit.any() else [0, 0, 0],
    }


# --------------------------------------------------------------------------- VTK
def vtk_render(args, log=lambda *a: print(*a, file=sys.stderr)):
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkOSOpenGLRenderWindow")
    import vtk
    from vtk.util import numpy_support

    t0 = time.perf_counter()
    data, dims, spacing = load_vol_xfast(args.volume)
    S = args.value_scale
    if S != 1:
        data = data.astype(np.uint16) * np.uint16(S)
    load_s = time.perf_counter() - t0
    log(f"loaded {dims} spacing {spacing} dtype {data.dtype} in {load_s:.1f} s")

    vtk.vtkMultiThreader.SetGlobalMaximumNumberOfThreads(args.threads)
    vtk.vtkMultiThreader.SetGlobalDefaultNumberOfThreads(args.threads)

    flat = data.ravel()
    arr = numpy_support.numpy_to_vtk(
        flat, deep=0, array_type=vtk.VTK_UNSIGNED_CHAR if S == 1 else vtk.VTK_UNSIGNED_SHORT
    )
    img = vtk.vtkImageData()
    img.SetDimensions(*dims)
    img.SetSpacing(*spacing)
    img.SetOrigin(0, 0, 0)
    img.GetPointData().SetScalars(arr)
    vmin, vmax = arr.GetRange()

    # Step TF: RGBA of the last point whose value <= v; transparent below the first.
    eps = 1e-3
    ctf = vtk.vtkColorTransferFunction()
    otf = vtk.vtkPiecewiseFunction()
    lo = min(vmin, SHAPES_TF[0][0] * S) - 1.0
    ctf.AddRGBPoint(lo, 0, 0, 0)
    otf.AddPoint(lo, 0.0)
    prev_c, prev_a = (0.0, 0.0, 0.0), 0.0
    for v, c, a in SHAPES_TF:
        v = v * S
        ctf.AddRGBPoint(v - eps, *prev_c)
        otf.AddPoint(v - eps, prev_a)
        ctf.AddRGBPoint(v, *c)
        otf.AddPoint(v, a)
        prev_c, prev_a = c, a
    hi = max(vmax, SHAPES_TF[-1][0] * S) + 1.0
    ctf.AddRGBPoint(hi, *prev_c)
    otf.AddPoint(hi, prev_a)
    ctf.ClampingOn()
    otf.ClampingOn()

    prop = vtk.vtkVolumeProperty()
    prop.SetColor(ctf)
    prop.SetScalarOpacity(otf)
    prop.SetScalarOpacityUnitDistance(1.0)
    prop.SetInterpolationTypeToLinear()
    prop.SetIndependentComponents(1)
    if args.shading == "on":
        prop.ShadeOn()
        prop.SetAmbient(args.ka)
        prop.SetDiffuse(args.kd)
        prop.SetSpecular(args.ks)
        # Ours: Phong R·V = cos 2θ for a headlight; VTK: Blinn N·H = cos θ (H = L).
        # cos(2θ)^n ≈ cos(θ)^(4n) near the highlight, hence 4× the exponent.
        prop.SetSpecularPower(args.shininess * args.vtk_power_factor)
    else:
        prop.ShadeOff()

    mapper = vtk.vtkFixedPointVolumeRayCastMapper()
    mapper.SetInputData(img)
    mapper.SetBlendModeToComposite()
    mapper.SetSampleDistance(args.step)
    mapper.AutoAdjustSampleDistancesOff()
    mapper.SetImageSampleDistance(1.0)
    mapper.SetLockSampleDistanceToInputSpacing(False)
    mapper.IntermixIntersectingGeometryOff()
    mapper.SetNumberOfThreads(args.threads)

    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)

    ren = vtk.vtkRenderer()
    ren.SetBackground(0, 0, 0)
    ren.AddVolume(volume)
    ren.TwoSidedLightingOn()
    # Headlight. VTK's volume shader takes the ambient term from the light's ambient
    # colour, which defaults to black (no ambient at all): make it white so that
    # ka means what it means in ours. VTK treats the light as directional (along the
    # central view direction), ours uses each ray's own direction.
    light = vtk.vtkLight()
    light.SetLightTypeToHeadlight()
    light.SetAmbientColor(1, 1, 1)
    light.SetDiffuseColor(1, 1, 1)
    light.SetSpecularColor(1, 1, 1)
    light.SetIntensity(1.0)
    ren.AddLight(light)
    win = vtk.vtkRenderWindow()
    win.SetOffScreenRendering(1)
    win.SetMultiSamples(0)
    win.AddRenderer(ren)
    W, H = args.size
    win.SetSize(W, H)

    cam = ren.GetActiveCamera()
    cam.SetPosition(*args.camera_pos)
    cam.SetFocalPoint(*args.look_at)
    cam.SetViewUp(*args.up)
    cam.SetViewAngle(args.fov)
    cam.ParallelProjectionOff()
    # Clipping range from the box's corners (distance along the view direction):
    # generous on both sides, so that nothing of the volume is clipped.
    p = np.array(args.camera_pos, dtype=float)
    d = np.array(args.look_at, dtype=float) - p
    d /= np.linalg.norm(d)
    ext = [(0.0, (n - 1) * s) for n, s in zip(dims, spacing)]
    depths = [
        float(np.dot(np.array([x, y, z]) - p, d))
        for x in ext[0] for y in ext[1] for z in ext[2]
    ]
    near = max(0.01, min(depths) * 0.9)
    far = max(depths) * 1.1 + 1.0
    cam.SetClippingRange(near, far)
    log(f"clipping range {near:.1f}..{far:.1f} (box depths {min(depths):.1f}..{max(depths):.1f})")

    # Count ray-casting passes (to be sure that every timed frame re-casts all rays)
    # and time the casting alone (TimeToDraw also holds the per-frame set-up and the
    # display of the image as an OpenGL texture).
    casts = [0]
    cast_t = [0.0, 0.0]

    def on_start(*_):
        casts[0] += 1
        cast_t[0] = time.perf_counter()

    def on_end(*_):
        cast_t[1] = (time.perf_counter() - cast_t[0]) * 1000

    mapper.AddObserver(vtk.vtkCommand.VolumeMapperRenderStartEvent, on_start)
    mapper.AddObserver(vtk.vtkCommand.VolumeMapperRenderEndEvent, on_end)

    # Warm-up: builds the TF tables, the min-max (space-leaping) volume and, with
    # shading, the encoded gradients. Not timed as a frame.
    t = time.perf_counter()
    for _ in range(max(1, args.warmup)):
        win.Render()
    warm_s = time.perf_counter() - t
    log(f"warm-up render {warm_s:.2f} s; clipping range now {cam.GetClippingRange()}")

    wall, draw, cast = [], [], []
    for i in range(args.repeat):
        before = casts[0]
        t = time.perf_counter()
        win.Render()
        wall.append((time.perf_counter() - t) * 1000)
        draw.append(mapper.GetTimeToDraw() * 1000)
        cast.append(cast_t[1])
        if casts[0] != before + 1:
            log(f"WARNING: render {i} cast rays {casts[0]-before} times (expected 1)")
        log(f"  frame {i}: wall {wall[-1]:.1f} ms, mapper TimeToDraw {draw[-1]:.1f} ms, "
            f"ray casting {cast[-1]:.1f} ms")

    w2i = vtk.vtkWindowToImageFilter()
    w2i.SetInput(win)
    w2i.SetInputBufferTypeToRGB()
    w2i.ReadFrontBufferOff()
    w2i.Update()
    writer = vtk.vtkPNGWriter()
    writer.SetFileName(args.out)
    writer.SetInputConnection(w2i.GetOutputPort())
    writer.Write()

    res = {
        "vtk_version": vtk.vtkVersion.GetVTKVersion(),
        "mapper": "vtkFixedPointVolumeRayCastMapper",
        "width": W,
        "height": H,
        "threads": mapper.GetNumberOfThreads(),
        "shading": args.shading,
        "value_scale": S,
        "frame_ms_median": round(statistics.median(draw), 2),
        "frame_ms": [round(x, 2) for x in draw],
        "cast_ms_median": round(statistics.median(cast), 2),
        "wall_ms_median": round(statistics.median(wall), 2),
        "wall_ms": [round(x, 2) for x in wall],
        "warmup_renders": max(1, args.warmup),
        "warmup_s": round(warm_s, 3),
        "load_s": round(load_s, 3),
        "ray_cast_passes": casts[0],
        "out": args.out,
    }
    return res


def cmd_render(args):
    res = vtk_render(args)
    if args.ours:
        res["compare"] = compare_images(args.ours, args.out)
    print(json.dumps(res))


def cmd_compare(args):
    print(json.dumps(compare_images(args.a, args.b)))


def cmd_orient_test(args):
    """Tiny asymmetric volume: three blocks of different TF classes at different
    corners; rendered by both from an oblique camera. A flip or axis swap shows as a
    large difference."""
    X, Y, Z = 48, 40, 32
    v = np.zeros((X, Y, Z), dtype=np.uint8)
    v[30:44, 4:12, 4:14] = 90  # red-ish: x high, y low, z low
    v[4:14, 26:36, 6:12] = 97  # blue: x low, y high
    v[8:20, 6:14, 20:30] = 105  # green: z high
    v[36:44, 30:38, 22:30] = 90  # red: x,y,z high
    path = os.path.join(args.tmp, "orient_test.vol")
    write_vol(path, v)
    ours = os.path.join(args.tmp, "orient_ours.png")
    theirs = os.path.join(args.tmp, "orient_vtk.png")
    cam = ",".join(str(x) for x in args.camera_pos)
    cmd = [args.ours_bin, "render", path, "--size", "200x160", "--camera-pos", cam,
           "--look-at", "20,18,14", "--fov", "50", "--step", "0.2", "--tf-preset", "shapes",
           "--shading", "off", "--threads", "2", "--out", ours]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    ns = argparse.Namespace(volume=path, out=theirs, size=(200, 160), camera_pos=args.camera_pos,
                            look_at=[20, 18, 14], up=[0, 1, 0], fov=50.0, step=0.2, shading="off",
                            threads=2, repeat=1, value_scale=16, ka=0.3, kd=0.7, ks=0.25,
                            shininess=20, vtk_power_factor=4.0, warmup=1)
    vtk_render(ns, log=lambda *a: None)
    c = compare_images(ours, theirs)
    # Also the vertically flipped VTK image, to show which orientation matches.
    from PIL import Image

    flipped = os.path.join(args.tmp, "orient_vtk_flipped.png")
    Image.open(theirs).transpose(Image.FLIP_TOP_BOTTOM).save(flipped)
    cf = compare_images(ours, flipped)
    ok = c["psnr_db"] > cf["psnr_db"] and c["psnr_db"] > 30
    print(json.dumps({"orientation_ok": ok, "as_written": c, "flipped": cf,
                      "images": [ours, theirs]}))
    sys.exit(0 if ok else 1)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)

    r = sub.add_parser("render", help="VTK render + timing (+ PSNR against --ours)")
    r.add_argument("volume", help="linear .vol file (SPEC §1)")
    r.add_argument("--out", default="/tmp/vtk.png", help="VTK image (PNG)")
    r.add_argument("--ours", help="our PNG of the same frame, to compare against")
    r.add_argument("--size", type=size2, default=(700, 700), help="WxH")
    r.add_argument("--camera-pos", type=vec3, default=[1100, 1100, 1100])
    r.add_argument("--look-at", type=vec3, default=[0, 0, 0])
    r.add_argument("--up", type=vec3, default=[0, 1, 0])
    r.add_argument("--fov", type=float, default=60.0, help="vertical view angle, degrees")
    r.add_argument("--step", type=float, default=0.2, help="sample distance, world units")
    r.add_argument("--shading", choices=["on", "off"], default="off")
    r.add_argument("--ka", type=float, default=0.3)
    r.add_argument("--kd", type=float, default=0.7)
    r.add_argument("--ks", type=float, default=0.25)
    r.add_argument("--shininess", type=float, default=20, help="our Phong exponent")
    r.add_argument("--vtk-power-factor", type=float, default=4.0,
                   help="VTK specular power = shininess × this (Blinn vs Phong, see code)")
    r.add_argument("--threads", type=int, default=2)
    r.add_argument("--repeat", type=int, default=5, help="timed renders after the warm-up")
    r.add_argument("--warmup", type=int, default=2,
                   help="untimed renders first (the first builds tables / min-max volume / gradients)")
    r.add_argument("--value-scale", type=int, default=1,
                   help="multiply data (as u16) and TF values by this; 1 = native u8 "
                        "(benchmark); 16 = closer match of the step thresholds")
    r.set_defaults(func=cmd_render)

    c = sub.add_parser("compare", help="PSNR / mean abs diff of two PNGs")
    c.add_argument("a")
    c.add_argument("b")
    c.set_defaults(func=cmd_compare)

    o = sub.add_parser("orient-test", help="tiny asymmetric volume rendered by both")
    o.add_argument("--ours-bin", default="/tmp/vol_app_bench")
    o.add_argument("--tmp", default="/tmp")
    o.add_argument("--camera-pos", type=vec3, default=[70, 55, 90])
    o.set_defaults(func=cmd_orient_test)

    args = ap.parse_args()
    args.func(args)


if __name__ == "__main__":
    main()
