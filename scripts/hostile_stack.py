"""Hostile variants of a valid Relume stack file, for tests and the fuzzers' seed corpus.

`with_claimed_size(data, width, height)` rewrites an OpenEXR stack's data and display
windows and its `relume/header` so that they claim `width × height` pixels, keeping the
pixel data (and the now wrong chunk offsets) as they were: what a reader must refuse before
allocating anything of the claimed size. The Rust twin is
`relume_engine::stack::hostile::with_claimed_size` (same layout rules, used by the Rust
tests); this one serves Python tests that only have the wheel.
"""

from __future__ import annotations

import json
import struct
import sys

MAGIC = b"\x76\x2f\x31\x01"


def _cstr(data: bytes, at: int) -> tuple[bytes, int]:
    end = data.index(b"\0", at)
    return data[at:end], end + 1


def with_claimed_size(data: bytes, width: int, height: int) -> bytes:
    if data[:4] != MAGIC:
        raise ValueError("not an OpenEXR file")
    at = 8
    attrs = []
    while True:
        name, at = _cstr(data, at)
        if not name:
            break
        kind, at = _cstr(data, at)
        (size,) = struct.unpack_from("<i", data, at)
        at += 4
        attrs.append([name, kind, data[at:at + size]])
        at += size
    rest = data[at:]
    window = struct.pack("<4i", 0, 0, width - 1, height - 1)
    out = bytearray(data[:8])
    for name, kind, value in attrs:
        if name in (b"dataWindow", b"displayWindow"):
            value = window
        elif name == b"relume/header":
            header = json.loads(value)
            header["width"], header["height"] = width, height
            value = json.dumps(header).encode()
        out += name + b"\0" + kind + b"\0" + struct.pack("<i", len(value)) + value
    out += b"\0" + rest
    return bytes(out)


if __name__ == "__main__":
    src, dst, w, h = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    with open(src, "rb") as f:
        crafted = with_claimed_size(f.read(), w, h)
    with open(dst, "wb") as f:
        f.write(crafted)
