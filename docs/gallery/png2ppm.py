#!/usr/bin/env python3
"""Writes a PNG that grotto-client --screenshot made as binary PPM on stdout (Python alone), for
cjpeg: python3 docs/gallery/png2ppm.py A.png | cjpeg -quality 85 > A.jpg. The gallery keeps its
1920x1080 pictures as JPEG (a tenth of the PNG's size)."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pixdiff import read_png  # noqa: E402

width, height, rows = read_png(sys.argv[1])
out = sys.stdout.buffer
out.write(b"P6\n%d %d\n255\n" % (width, height))
for row in rows:
    out.write(bytes(row))
