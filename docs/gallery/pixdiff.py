#!/usr/bin/env python3
"""Compares two renders of one pose: the share of pixels whose largest channel differs by more
than 8/255, and the largest difference. Python alone (zlib): 8-bit RGB or RGBA PNGs, not
interlaced, as grotto-client --screenshot writes them.

  python3 docs/gallery/pixdiff.py A.png B.png [--overlay OUT.png]

--overlay writes B in grey at 60 % with the pixels over the threshold in red."""
import struct
import sys
import zlib

THRESHOLD = 8


def read_png(path):
    """(width, height, rows of RGB bytes)."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        sys.exit(f"{path}: not a PNG")
    at, idat, header = 8, [], None
    while at < len(data):
        (length,) = struct.unpack(">I", data[at : at + 4])
        kind, body = data[at + 4 : at + 8], data[at + 8 : at + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        at += 12 + length
    width, height, depth, colour, _, _, interlace = header
    if depth != 8 or colour not in (2, 6) or interlace:
        sys.exit(f"{path}: only 8-bit RGB or RGBA, not interlaced")
    step = 3 if colour == 2 else 4
    stride = width * step
    raw = zlib.decompress(b"".join(idat))
    rows, prior = [], bytearray(stride)
    for y in range(height):
        kind = raw[y * (stride + 1)]
        row = bytearray(raw[y * (stride + 1) + 1 : (y + 1) * (stride + 1)])
        for i in range(stride):
            left = row[i - step] if i >= step else 0
            up = prior[i]
            if kind == 1:
                row[i] = (row[i] + left) & 255
            elif kind == 2:
                row[i] = (row[i] + up) & 255
            elif kind == 3:
                row[i] = (row[i] + ((left + up) >> 1)) & 255
            elif kind == 4:
                corner = prior[i - step] if i >= step else 0
                pa, pb, pc = abs(up - corner), abs(left - corner), abs(left + up - 2 * corner)
                row[i] = (row[i] + (left if pa <= pb and pa <= pc else up if pb <= pc else corner)) & 255
        prior = row
        if step == 4:
            row = bytearray(b for i, b in enumerate(row) if i % 4 != 3)
        rows.append(bytes(row))
    return width, height, rows


def write_png(path, width, height, rows):
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    raw = b"".join(b"\0" + bytes(r) for r in rows)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 9)))
        f.write(chunk(b"IEND", b""))


def main():
    args = sys.argv[1:]
    overlay = None
    if "--overlay" in args:
        i = args.index("--overlay")
        overlay = args[i + 1]
        del args[i : i + 2]
    if len(args) != 2:
        sys.exit(__doc__)
    wa, ha, a = read_png(args[0])
    wb, hb, b = read_png(args[1])
    if (wa, ha) != (wb, hb):
        sys.exit("the pictures differ in size")
    over, largest, out = 0, 0, []
    for ra, rb in zip(a, b):
        line = bytearray()
        for x in range(wa):
            d = max(abs(ra[3 * x + k] - rb[3 * x + k]) for k in range(3))
            largest = max(largest, d)
            if d > THRESHOLD:
                over += 1
                line += b"\xff\x00\x00"
            else:
                grey = (rb[3 * x] + rb[3 * x + 1] + rb[3 * x + 2]) // 5
                line += bytes((grey, grey, grey))
        out.append(line)
    print(f"{100 * over / (wa * ha):.2f} % {largest}")
    if overlay:
        write_png(overlay, wa, ha, out)


if __name__ == "__main__":
    main()
