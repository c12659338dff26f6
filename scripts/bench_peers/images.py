"""Images for bench-peers: sparseleap's EXR, PSNR in linear colour, sRGB encoding, PNG output.

Debian 12 has no Python OpenEXR binding (python3-openexr does not exist; OpenImageIO's would pull in
about a hundred packages), so read_exr() reads the one layout sparseleap writes (core/util/image.cpp):
scan-line, ZIP compression (16 lines per chunk), 32-bit float channels, no tiles or multi-part.
Anything else is refused with the reason, never misread.
"""
import struct
import zlib

import numpy as np


def _attributes(data, path):
    """Header attributes {name: (type, bytes)} and the offset just past the header."""
    if data[:4] != b"\x76\x2f\x31\x01":
        raise ValueError(f"{path}: not an OpenEXR file")
    version = struct.unpack_from("<I", data, 4)[0]
    if version & 0xFFFFFF00 & ~0x400:  # 0x200 tiled, 0x800 deep, 0x1000 multi-part; 0x400 long names
        raise ValueError(f"{path}: tiled, deep or multi-part EXR (flags {version:#x}) is not supported")
    attrs, pos = {}, 8
    while data[pos] != 0:
        name_end = data.index(b"\0", pos)
        type_end = data.index(b"\0", name_end + 1)
        size = struct.unpack_from("<i", data, type_end + 1)[0]
        value = data[type_end + 5:type_end + 5 + size]
        attrs[data[pos:name_end].decode()] = (data[name_end + 1:type_end].decode(), value)
        pos = type_end + 5 + size
    return attrs, pos + 1


def _channels(value):
    """Channel names and pixel types from a chlist attribute (names sorted, as EXR stores them)."""
    out, pos = [], 0
    while value[pos] != 0:
        end = value.index(b"\0", pos)
        ptype = struct.unpack_from("<i", value, end + 1)[0]
        out.append((value[pos:end].decode(), ptype))
        pos = end + 1 + 16  # pixel type, pLinear + 3 reserved bytes, x and y sampling
    return out


def read_exr(path):
    """{channel: float32 array (height, width)} of a ZIP-compressed scan-line EXR; row 0 at the top."""
    with open(path, "rb") as f:
        data = f.read()
    attrs, pos = _attributes(data, path)
    compression = attrs["compression"][1][0]
    if compression != 3:  # 3 = ZIP_COMPRESSION, 16 scan lines per chunk
        raise ValueError(f"{path}: EXR compression {compression} is not supported (only ZIP, 3)")
    chans = _channels(attrs["channels"][1])
    if any(t != 2 for _, t in chans):  # 2 = FLOAT
        raise ValueError(f"{path}: only 32-bit float channels are supported")
    x0, y0, x1, y1 = struct.unpack("<4i", attrs["dataWindow"][1])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    lines_per_chunk = 16
    nchunks = (h + lines_per_chunk - 1) // lines_per_chunk
    offsets = struct.unpack_from(f"<{nchunks}Q", data, pos)
    img = np.empty((h, len(chans), w), dtype="<f4")
    for off in offsets:
        y, size = struct.unpack_from("<ii", data, off)
        n = min(lines_per_chunk, y1 + 1 - y)
        raw = np.frombuffer(zlib.decompress(data[off + 8:off + 8 + size]), dtype=np.uint8)
        if raw.size != n * len(chans) * w * 4:
            raise ValueError(f"{path}: chunk at line {y} has {raw.size} bytes, expected {n * len(chans) * w * 4}")
        # Undo ZIP's predictor (byte deltas + 128) and its split of even and odd bytes into two halves.
        t = raw.astype(np.int64)
        t[1:] -= 128
        t = (np.cumsum(t) % 256).astype(np.uint8)
        half = (t.size + 1) // 2
        b = np.empty_like(t)
        b[0::2], b[1::2] = t[:half], t[half:]
        img[y - y0:y - y0 + n] = b.view("<f4").reshape(n, len(chans), w)
    return {name: img[:, c, :].astype(np.float32) for c, (name, _) in enumerate(chans)}


def linear_to_srgb(x):
    """The sRGB encoding sparseleap's PNGs use (core/util/image.cpp), on [0, 1] clamped values."""
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def psnr(a, b):
    """PSNR in dB of two linear RGB images in [0, 1] (peak 1); inf when they are equal."""
    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return float("inf") if mse == 0.0 else 10.0 * np.log10(1.0 / mse)
