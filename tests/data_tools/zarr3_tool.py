"""Zarr v3 interop peer for the sparseleap tests: zarr-python 3, run with the tests' virtual environment
(.venv-peers/bin/python, made by scripts/setup).

  make STORE EXPECTED --dtype D --shape Z,Y,X --chunks Z,Y,X [--shards Z,Y,X] [--index start|end]
       [--no-index-crc] [--compressor C] [--crc] [--endian little|big] [--transpose [--order A,B,C]] [--keys default|v2]
       [--sep / | .] [--fill V] [--holes] [--missing] [--labels] [--ndim 3|5] [--levels N] [--bare]
      Writes an OME-Zarr (NGFF 0.5) store (or with --bare a bare array) with zarr-python 3 and, for each
      level L, the voxels as little-endian raw bytes in EXPECTED.L (labels: EXPECTED.labels.L; int16 as
      float32, the type sparseleap reads it as). Level L+1 is level L subsampled by 2. --holes sets two
      regions to the fill value, so zarr-python leaves those inner chunks empty (offset = nbytes =
      2^64-1) or whole shards unwritten; --missing also deletes every third chunk (or shard) file of
      level 0.
  dump STORE OUT
      Opens a store `sparseleap ingest --format zarr3` wrote, checks the NGFF 0.5 metadata, and writes
      every level (and labels/labels) as little-endian raw bytes to OUT.L / OUT.labels.L; prints a summary.
  convert V2STORE V3STORE [--chunks Z,Y,X] [--shards Z,Y,X] [--compressor C] [--crc]
      Copies an NGFF 0.4 / Zarr v2 store (image and labels) into NGFF 0.5 / Zarr v3, level by level.
"""
import argparse
import json
import os
import sys

import numpy as np


def compressors(name, crc):
    from zarr.codecs import BloscCodec, Crc32cCodec, GzipCodec, ZstdCodec
    out = []
    if name == "gzip":
        out.append(GzipCodec(level=5))
    elif name == "zstd":
        out.append(ZstdCodec(level=3))
    elif name.startswith("blosc-"):
        parts = name.split("-")  # blosc-CNAME[-shuffle|-bitshuffle|-noshuffle]
        out.append(BloscCodec(cname=parts[1], clevel=5, shuffle=parts[2] if len(parts) > 2 else "shuffle"))
    elif name != "none":
        raise SystemExit("unknown compressor " + name)
    if crc:
        out.append(Crc32cCodec())
    return out


def data(shape, dtype, seed):
    rng = np.random.default_rng(seed)
    z, y, x = np.meshgrid(*[np.arange(n) for n in shape], indexing="ij")
    v = (x * 7 + y * 13 + z * 29) % 251 + rng.integers(0, 3, size=shape)
    dt = np.dtype(dtype)
    if dt.kind == "f":
        return (v * 0.37 - 11.5).astype(dt)
    if dt.kind == "i":
        return (v * 97 - 12000).astype(dt)
    if dt.itemsize >= 2:
        v = v * 257 + (x % 5)
    return v.astype(dt)


def tup(s):
    return tuple(int(v) for v in s.split(",")) if s else None


def create(group_or_store, name, a, shape, dtype, fill, lead, dims):
    import zarr
    from zarr.codecs import BytesCodec, Crc32cCodec, ShardingCodec, TransposeCodec
    chunks = lead + tup(a.chunks)
    inner = compressors(a.compressor, a.crc)
    order = tup(a.order) if getattr(a, "order", None) else tuple(reversed(range(len(shape))))
    filters = [TransposeCodec(order=order)] if a.transpose else []
    serializer = BytesCodec(endian=a.endian) if np.dtype(dtype).itemsize > 1 else BytesCodec()
    kwargs = dict(shape=shape, dtype=dtype, fill_value=fill, dimension_names=dims, overwrite=True,
                  chunk_key_encoding={"name": a.keys, "separator": a.sep})
    if a.shards:
        index_codecs = [BytesCodec(endian="little")] + ([] if a.no_index_crc else [Crc32cCodec()])
        sharding = ShardingCodec(chunk_shape=chunks, codecs=filters + [serializer] + inner, index_codecs=index_codecs,
                                 index_location=a.index)
        kwargs.update(chunks=lead + tup(a.shards), serializer=sharding, compressors=None, filters=None)
    else:
        kwargs.update(chunks=chunks, serializer=serializer, compressors=inner or None, filters=filters or None)
    if name is None:
        return zarr.create_array(store=group_or_store, **kwargs)
    return group_or_store.create_array(name=name, **kwargs)


def stored_files(arr_dir):
    out = []
    for root, _, files in os.walk(arr_dir):
        out += [os.path.join(root, f) for f in files if f != "zarr.json"]
    return sorted(out)


def make(a):
    import zarr
    shape = tup(a.shape)
    lead = (1,) * (a.ndim - 3)
    names = ["t", "c"][: a.ndim - 3] + ["z", "y", "x"]
    axes = ([{"name": "t", "type": "time"}, {"name": "c", "type": "channel"}][: a.ndim - 3] +
            [{"name": n, "type": "space", "unit": "micrometer"} for n in "zyx"])
    fill = float(a.fill) if np.dtype(a.dtype).kind == "f" or a.fill == "NaN" else int(a.fill)
    if a.fill == "NaN":
        fill = float("nan")

    def write_image(group, path, base, fill, dtype, missing, holes):
        datasets = []
        level = base.copy()
        if holes:
            z, y, x = level.shape
            level[: z // 2, : y // 2, : x // 3] = fill
            level[:, y - y // 3 :, :] = fill
        for lev in range(1 if a.bare else a.levels):
            name = None if a.bare else str(lev)
            arr = create(group, name, a, lead + level.shape, dtype, fill, lead, names)
            arr[...] = level.reshape(lead + level.shape)
            if missing and lev == 0:
                files = stored_files(os.path.join(path, "" if a.bare else name))
                for i, f in enumerate(files):
                    if i % 3 == 0:
                        os.remove(f)
            expected = np.asarray(arr[...]).reshape(level.shape)
            s = 2.0 ** lev
            datasets.append({"path": str(lev), "coordinateTransformations": [
                {"type": "scale", "scale": [1.0] * (a.ndim - 3) + [0.5 * s, 0.25 * s, 0.25 * s]}]})
            yield lev, expected
            level = level[::2, ::2, ::2]
        if not a.bare:
            group.attrs["ome"] = {"version": "0.5", "multiscales": [{"axes": axes, "datasets": datasets}]}

    def out_type(dtype):
        return np.dtype("<f4") if np.dtype(dtype).kind == "i" else np.dtype(dtype).newbyteorder("<")

    base = data(shape, a.dtype, a.seed)
    root = a.store if a.bare else zarr.open_group(a.store, mode="w", zarr_format=3)
    for lev, exp in write_image(root, a.store, base, fill, a.dtype, a.missing, a.holes):
        exp.astype(out_type(a.dtype)).tofile(a.expected + "." + str(lev))
    if a.labels:
        lg = root.create_group("labels")
        lg.attrs["ome"] = {"version": "0.5", "labels": ["cells"]}
        cells = lg.create_group("cells")
        lab = ((base.astype(np.int64) // 50) % 7).astype("uint16")
        for lev, exp in write_image(cells, os.path.join(a.store, "labels", "cells"), lab, 0, "uint16", False, False):
            exp.astype("<u2").tofile(a.expected + ".labels." + str(lev))
        cells.attrs["ome"] = dict(cells.attrs["ome"], **{"image-label": {"version": "0.5"}})


def convert(a):
    import zarr
    src = zarr.open_group(a.v2, mode="r", zarr_format=2)
    dst = zarr.open_group(a.v3, mode="w", zarr_format=3)
    a.transpose, a.endian, a.keys, a.sep, a.index, a.no_index_crc = False, "little", "default", "/", "end", False

    def one(sg, dg):
        ms = sg.attrs["multiscales"][0]
        for ds in ms["datasets"]:
            arr = sg[ds["path"]]
            a.chunks = a.chunks_arg or ",".join(map(str, arr.chunks))
            out = create(dg, ds["path"], a, arr.shape, arr.dtype, arr.fill_value or 0, (), ["z", "y", "x"])
            out[...] = arr[...]
        ms = dict(ms)
        ms.pop("version", None)
        return ms

    dst.attrs["ome"] = {"version": "0.5", "multiscales": [one(src, dst)]}
    if "labels" in src:
        names = src["labels"].attrs["labels"]
        lg = dst.create_group("labels")
        lg.attrs["ome"] = {"version": "0.5", "labels": list(names)}
        for n in names:
            cg = lg.create_group(n)
            extra = {k: v for k, v in src["labels"][n].attrs.asdict().items() if k not in ("multiscales", "image-label")}
            cg.attrs.update(extra)
            cg.attrs["ome"] = {"version": "0.5", "multiscales": [one(src["labels"][n], cg)],
                               "image-label": {"version": "0.5"}}


def dump(a):
    import zarr
    root = zarr.open_group(a.store, mode="r", zarr_format=3)
    out = []

    def one(group, prefix):
        ome = group.attrs["ome"]
        assert ome["version"] == "0.5", ome
        ms = ome["multiscales"][0]
        assert [ax["name"] for ax in ms["axes"]] == ["z", "y", "x"], ms["axes"]
        for lev, ds in enumerate(ms["datasets"]):
            arr = group[ds["path"]]
            assert list(arr.metadata.dimension_names) == ["z", "y", "x"], arr.metadata.dimension_names
            v = np.asarray(arr[...])
            scale = ds["coordinateTransformations"][0]["scale"]
            out.append("%s%d %s %s shards=%s chunks=%s %s" % (prefix, lev, "x".join(map(str, arr.shape)), arr.dtype.str,
                                                           arr.shards, arr.chunks, ",".join("%g" % s for s in scale)))
            v.astype(v.dtype.newbyteorder("<")).tofile(a.out + "." + prefix + str(lev))

    one(root, "")
    if "labels" in root:
        names = root["labels"].attrs["ome"]["labels"]
        one(root["labels"][names[0]], "labels.")
    print("\n".join(out))


def main():
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("make")
    m.add_argument("store")
    m.add_argument("expected")
    m.add_argument("--dtype", required=True)
    m.add_argument("--shape", required=True)
    m.add_argument("--chunks", required=True)
    m.add_argument("--shards")
    m.add_argument("--index", default="end")
    m.add_argument("--no-index-crc", action="store_true")
    m.add_argument("--compressor", default="none")
    m.add_argument("--crc", action="store_true")
    m.add_argument("--endian", default="little")
    m.add_argument("--transpose", action="store_true")
    m.add_argument("--order", help="the transpose order (default: reversed axes)")
    m.add_argument("--keys", default="default")
    m.add_argument("--sep", default="/")
    m.add_argument("--fill", default="0")
    m.add_argument("--holes", action="store_true")
    m.add_argument("--missing", action="store_true")
    m.add_argument("--labels", action="store_true")
    m.add_argument("--ndim", type=int, default=3)
    m.add_argument("--levels", type=int, default=3)
    m.add_argument("--bare", action="store_true")
    m.add_argument("--seed", type=int, default=1)
    d = sub.add_parser("dump")
    d.add_argument("store")
    d.add_argument("out")
    c = sub.add_parser("convert")
    c.add_argument("v2")
    c.add_argument("v3")
    c.add_argument("--chunks", dest="chunks_arg")
    c.add_argument("--shards")
    c.add_argument("--compressor", default="none")
    c.add_argument("--crc", action="store_true")
    a = p.parse_args()
    {"make": make, "dump": dump, "convert": convert}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main())
