#!/usr/bin/python3
"""Zarr interop peer for the sparseleap tests (run with Debian's /usr/bin/python3 and python3-zarr).

  make STORE EXPECTED --dtype D --shape Z,Y,X --chunks Z,Y,X --compressor C [--levels N]
       [--sep / | .] [--fill V] [--missing] [--labels] [--ndim 3|5] [--seed S]
      Writes an OME-Zarr (NGFF 0.4) store with zarr-python and, for each level L, the voxels as
      little-endian raw bytes in EXPECTED.L (labels: EXPECTED.labels.L). Level L+1 is level L
      subsampled by 2 (the reader only reads stored levels). --missing deletes every third chunk file
      of level 0, which must then read as the fill value (EXPECTED reflects that).
  dump STORE OUT
      Opens a store written by sparseleap with zarr-python, checks the NGFF metadata, and writes every
      level (and labels/labels) as little-endian raw bytes to OUT.L / OUT.labels.L; prints a summary.
  tiff DIR_OR_FILE EXPECTED --shape Z,Y,X --dtype u1|u2 [--multipage]
  nifti FILE EXPECTED --shape Z,Y,X --dtype u1|u2|i2|f4 [--spacing x,y,z]
"""
import argparse
import os
import sys

import numpy as np


def compressor(name):
    import numcodecs
    if name == "none":
        return None
    if name == "zlib":
        return numcodecs.Zlib(level=3)
    if name == "gzip":
        return numcodecs.GZip(level=3)
    if name == "zstd":
        return numcodecs.Zstd(level=3)
    if name.startswith("blosc-"):
        parts = name.split("-")  # blosc-CNAME[-shuffle|-bitshuffle|-noshuffle]
        shuffle = {"shuffle": numcodecs.Blosc.SHUFFLE, "bitshuffle": numcodecs.Blosc.BITSHUFFLE,
                   "noshuffle": numcodecs.Blosc.NOSHUFFLE}[parts[2] if len(parts) > 2 else "shuffle"]
        return numcodecs.Blosc(cname=parts[1], clevel=5, shuffle=shuffle)
    raise SystemExit("unknown compressor " + name)


def data(shape, dtype, seed):
    rng = np.random.default_rng(seed)
    z, y, x = np.meshgrid(*[np.arange(n) for n in shape], indexing="ij")
    v = (x * 7 + y * 13 + z * 29) % 251 + rng.integers(0, 3, size=shape)
    dt = np.dtype(dtype)
    if dt.kind == "f":
        return (v * 0.37 - 11.5).astype(dt)
    if dt.itemsize >= 2:
        v = v * 257 + (x % 5)
    return v.astype(dt)


def make(a):
    import zarr
    shape = tuple(int(s) for s in a.shape.split(","))
    chunks = tuple(int(s) for s in a.chunks.split(","))
    store = zarr.DirectoryStore(a.store, dimension_separator=a.sep)
    root = zarr.group(store=store, overwrite=True)
    lead = (1,) * (a.ndim - 3)
    axes = ([{"name": "t", "type": "time"}, {"name": "c", "type": "channel"}][: a.ndim - 3] +
            [{"name": n, "type": "space", "unit": "micrometer"} for n in "zyx"])

    def write_image(group, base, fill, dtype, missing):
        datasets = []
        level = base
        for lev in range(a.levels):
            arr = group.create_dataset(str(lev), shape=lead + level.shape, chunks=lead + chunks, dtype=dtype,
                                       compressor=compressor(a.compressor), fill_value=fill, overwrite=True)
            arr[...] = level.reshape(lead + level.shape)
            expected = level.copy()
            if missing and lev == 0:
                keys = sorted(k for k in arr.store.keys() if k.startswith(arr.path + "/") and not k.endswith(".zarray"))
                for i, k in enumerate(keys):
                    if i % 3 == 0:
                        del arr.store[k]
                expected = np.asarray(arr[...]).reshape(level.shape)
            s = 2.0 ** lev
            datasets.append({"path": str(lev), "coordinateTransformations": [
                {"type": "scale", "scale": [1.0] * (a.ndim - 3) + [0.5 * s, 0.25 * s, 0.25 * s]}]})
            yield lev, expected
            level = level[::2, ::2, ::2]
        group.attrs["multiscales"] = [{"version": "0.4", "axes": axes, "datasets": datasets}]

    base = data(shape, a.dtype, a.seed)
    for lev, exp in write_image(root, base, a.fill, a.dtype, a.missing):
        exp.astype(np.dtype(a.dtype).newbyteorder("<")).tofile(a.expected + "." + str(lev))
    if a.labels:
        lg = root.create_group("labels")
        lg.attrs["labels"] = ["cells"]
        cells = lg.create_group("cells")
        lab = ((base.astype(np.int64) // 50) % 7).astype("<u2")
        for lev, exp in write_image(cells, lab, 0, "<u2", False):
            exp.astype("<u2").tofile(a.expected + ".labels." + str(lev))
        cells.attrs["image-label"] = {"version": "0.4"}


def dump(a):
    import zarr
    root = zarr.open_group(a.store, mode="r")
    out = []

    def one(group, prefix):
        ms = group.attrs["multiscales"][0]
        assert ms["version"] == "0.4", ms
        assert [ax["name"] for ax in ms["axes"]] == ["z", "y", "x"], ms["axes"]
        for lev, ds in enumerate(ms["datasets"]):
            arr = group[ds["path"]]
            v = np.asarray(arr[...])
            scale = ds["coordinateTransformations"][0]["scale"]
            out.append("%s%d %s %s %s %s" % (prefix, lev, "x".join(map(str, arr.shape)), arr.dtype.str,
                                            arr.compressor.codec_id if arr.compressor else "none",
                                            ",".join("%g" % s for s in scale)))
            v.astype(v.dtype.newbyteorder("<")).tofile(a.out + "." + prefix + str(lev))

    one(root, "")
    if "labels" in root:
        names = root["labels"].attrs["labels"]
        one(root["labels"][names[0]], "labels.")
    print("\n".join(out))


def tiff(a):
    import tifffile
    shape = tuple(int(s) for s in a.shape.split(","))
    v = data(shape, a.dtype, 3)
    if a.multipage:
        tifffile.imwrite(a.path, v, photometric="minisblack")
    else:
        os.makedirs(a.path, exist_ok=True)
        for z in range(shape[0]):
            tifffile.imwrite(os.path.join(a.path, "slice_%04d.tif" % z), v[z], photometric="minisblack")
    v.astype(np.dtype(a.dtype).newbyteorder("<")).tofile(a.expected)


def nifti(a):
    import nibabel
    shape = tuple(int(s) for s in a.shape.split(","))
    v = data(shape, a.dtype, 5)
    if np.dtype(a.dtype).kind == "i":
        v = (v.astype(np.int32) - 300).astype(a.dtype)
    img = nibabel.Nifti1Image(np.ascontiguousarray(v.transpose(2, 1, 0)), affine=np.eye(4))
    sp = [float(s) for s in a.spacing.split(",")]
    img.header.set_zooms(sp)
    img.header.set_data_dtype(np.dtype(a.dtype))
    nibabel.save(img, a.path)
    exp = v.astype(np.float32) if np.dtype(a.dtype).kind == "i" else v
    exp.astype(exp.dtype.newbyteorder("<")).tofile(a.expected)


def main():
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("make")
    m.add_argument("store")
    m.add_argument("expected")
    m.add_argument("--dtype", default="|u1")
    m.add_argument("--shape", default="20,30,40")
    m.add_argument("--chunks", default="8,8,8")
    m.add_argument("--compressor", default="none")
    m.add_argument("--levels", type=int, default=1)
    m.add_argument("--sep", default=".")
    m.add_argument("--fill", type=float, default=0)
    m.add_argument("--missing", action="store_true")
    m.add_argument("--labels", action="store_true")
    m.add_argument("--ndim", type=int, default=3)
    m.add_argument("--seed", type=int, default=1)
    d = sub.add_parser("dump")
    d.add_argument("store")
    d.add_argument("out")
    t = sub.add_parser("tiff")
    t.add_argument("path")
    t.add_argument("expected")
    t.add_argument("--shape", default="10,20,30")
    t.add_argument("--dtype", default="u1")
    t.add_argument("--multipage", action="store_true")
    n = sub.add_parser("nifti")
    n.add_argument("path")
    n.add_argument("expected")
    n.add_argument("--shape", default="10,20,30")
    n.add_argument("--dtype", default="u1")
    n.add_argument("--spacing", default="1,1,1")
    a = p.parse_args()
    {"make": make, "dump": dump, "tiff": tiff, "nifti": nifti}[a.cmd](a)


if __name__ == "__main__":
    main()
