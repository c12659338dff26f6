"""NIfTI interop peer for the sparseleap tests: nibabel (python3-nibabel), run with Debian's /usr/bin/python3.

  write FILE EXPECTED --shape Z,Y,X --dtype u1|i1|u2|i2|u4|f4 [--version 1|2] [--spacing x,y,z]
        [--scaled] [--big-endian] [--affine ras|lps|las]
      Writes a NIfTI-1 or NIfTI-2 image with nibabel: a single file for FILE.nii or FILE.nii.gz, a
      .hdr/.img pair for FILE.hdr, FILE.img, FILE.hdr.gz or FILE.img.gz. With --scaled the data are
      floats that nibabel stores as DTYPE with a scl_slope/scl_inter of its choosing. The voxels (x
      fastest) go to EXPECTED as little-endian raw bytes of the type sparseleap reads them as: the
      stored type for u1/u2/u4/f4, float32 for i1/i2, and float32 of slope * v + inter (computed in
      double from the stored v and the header's slope and inter) when scaled.
"""
import argparse

import numpy as np


def set_slope_inter(path, slope, inter):
    """Writes scl_slope and scl_inter into the saved header's bytes (NIfTI-1: float32 at 112 and 116;
    NIfTI-2: float64 at 176 and 184), in the header's byte order."""
    import gzip
    import struct

    hdr_path = path
    for img_ext, hdr_ext in ((".img", ".hdr"), (".img.gz", ".hdr.gz")):
        if path.endswith(img_ext):
            hdr_path = path[: -len(img_ext)] + hdr_ext
    opener = gzip.open if hdr_path.endswith(".gz") else open
    raw = bytearray(opener(hdr_path, "rb").read())
    little = struct.unpack("<i", raw[:4])[0] in (348, 540)
    size = struct.unpack(("<" if little else ">") + "i", raw[:4])[0]
    fmt, at = ("f", (112, 116)) if size == 348 else ("d", (176, 184))
    for offset, value in zip(at, (slope, inter)):
        struct.pack_into(("<" if little else ">") + fmt, raw, offset, value)
    with opener(hdr_path, "wb") as f:
        f.write(bytes(raw))


def main():
    import nibabel

    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="cmd", required=True)
    w = sub.add_parser("write")
    w.add_argument("path")
    w.add_argument("expected")
    w.add_argument("--shape", default="10,20,30")
    w.add_argument("--dtype", default="u1")
    w.add_argument("--version", type=int, default=1)
    w.add_argument("--spacing", default="1,1,1")
    w.add_argument("--scaled", action="store_true")
    w.add_argument("--big-endian", action="store_true")
    w.add_argument("--affine", default="ras")
    a = p.parse_args()

    z, y, x = (int(s) for s in a.shape.split(","))
    dtype = np.dtype(a.dtype)
    rng = np.random.default_rng(7)
    info = np.iinfo(dtype) if dtype.kind in "iu" else None
    if info is not None:
        lo, hi = max(info.min, -30000), min(info.max, 70000)
        v = rng.integers(lo, hi, size=(z, y, x), endpoint=True).astype(dtype)
    else:
        v = (rng.standard_normal((z, y, x)) * 100).astype(dtype)
    sign = {"ras": (1, 1, 1), "lps": (-1, -1, 1), "las": (-1, 1, 1)}[a.affine]
    sp = [float(s) for s in a.spacing.split(",")]
    affine = np.diag([sign[0] * sp[0], sign[1] * sp[1], sign[2] * sp[2], 1.0])
    pair = a.path.endswith((".hdr", ".img", ".hdr.gz", ".img.gz"))
    cls = {(1, False): nibabel.Nifti1Image, (2, False): nibabel.Nifti2Image,
           (1, True): nibabel.Nifti1Pair, (2, True): nibabel.Nifti2Pair}[(a.version, pair)]
    hdr_cls = nibabel.Nifti1Header if a.version == 1 else nibabel.Nifti2Header
    hdr = hdr_cls(endianness=">" if a.big_endian else "<")
    img = cls(np.ascontiguousarray(v.transpose(2, 1, 0)), affine=affine, header=hdr)
    img.header.set_zooms(sp)
    img.header.set_data_dtype(dtype)
    nibabel.save(img, a.path)
    if a.scaled:
        # nibabel writes data of the stored type unscaled (scl_slope NaN): set a slope and an inter in
        # the saved header itself, then check that nibabel reads them (it moves them to dataobj).
        set_slope_inter(a.path, 37.5, -1e5)
        back = nibabel.load(a.path)
        slope, inter = float(back.dataobj.slope), float(back.dataobj.inter)
        assert (slope, inter) == (37.5, -1e5), (slope, inter)
        exp = (v.astype(np.float64) * slope + inter).astype(np.float32)
    elif dtype.kind == "i":
        exp = v.astype(np.float32)
    else:
        exp = v
    exp.astype(exp.dtype.newbyteorder("<")).tofile(a.expected)


if __name__ == "__main__":
    main()
