#!/usr/bin/env python3
"""Measures shimmer over a slow pan (docs/GALLERY.md, "Fine detail, ambient occlusion and
columns"): renders FRAMES pictures of one pose with the yaw stepped by STEP degrees (a fraction
of a pixel) and prints the mean over pixels and frame triples of |I(k-1) - 2 I(k) + I(k+1)| of
luma, /255. A smooth, well-filtered picture changes almost linearly over sub-pixel steps, so the
figure stays near zero; detail finer than the pixels (aliasing) changes erratically and raises
it. Python alone (zlib), about 10 s a 1080p frame on llvmpipe.

  python3 docs/gallery/flicker.py BUILD_DIR x,y,z,yaw,pitch [client flags...]
      env: SEED (7), SIZE (1920x1080), FRAMES (5), STEP (0.02)

GALLERY's figures: BUILD_DIR build, pose 44.46,63.92,33.41,20,-15 (seed 7's hall floor), with
and without --no-fine-detail."""
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pixdiff import read_png  # noqa: E402


def luma(path):
    _, _, rows = read_png(path)
    out = []
    for r in rows:
        out.extend(0.2126 * r[i] + 0.7152 * r[i + 1] + 0.0722 * r[i + 2] for i in range(0, len(r), 3))
    return out


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    build, pose, flags = sys.argv[1], sys.argv[2].split(","), sys.argv[3:]
    seed = os.environ.get("SEED", "7")
    width, height = os.environ.get("SIZE", "1920x1080").split("x")
    frames, step = int(os.environ.get("FRAMES", "5")), float(os.environ.get("STEP", "0.02"))
    x, y, z, yaw, pitch = (float(v) for v in pose)
    lumas = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(frames):
            png = os.path.join(tmp, f"{k}.png")
            at = f"{x},{y},{z},{yaw + k * step},{pitch}"
            subprocess.run([os.path.join(build, "bin", "grotto-client"), "--gl", "egl", "--device", "none",
                            "--seed", seed, "--width", width, "--height", height, "--tess-max", "8",
                            "--frames", "2", "--wait", "120", "--no-motion-blur", "--mode", "fly",
                            "--pose", at, "--screenshot", png, *flags],
                           check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            lumas.append(luma(png))
    total, count = 0.0, 0
    for k in range(1, frames - 1):
        a, b, c = lumas[k - 1], lumas[k], lumas[k + 1]
        total += sum(abs(a[i] - 2 * b[i] + c[i]) for i in range(len(b)))
        count += len(b)
    print(f"mean |second temporal difference| {total / count:.3f}/255 over {frames} frames, "
          f"yaw steps of {step} degrees")


if __name__ == "__main__":
    main()
