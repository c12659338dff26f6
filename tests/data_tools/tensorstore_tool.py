"""Neuroglancer precomputed interop peer for the sparseleap tests: tensorstore (Google's implementation),
run with the tests' virtual environment (.venv-peers/bin/python, made by scripts/setup).

  make OUT EXPECTED --dtype D --shape X,Y,Z --chunks X,Y,Z [--scales N] [--encoding raw|compressed_segmentation]
       [--block X,Y,Z] [--sharding identity|murmurhash3_x86_128 --preshift P --minishard M --shard S
       --minishard-index raw|gzip --data raw|gzip] [--offset X,Y,Z] [--resolution X,Y,Z] [--holes] [--labels]
       [--big-ids] [--too-big] [--gzip-files] [--seed N] [--from-zarr STORE]
      Writes a precomputed volume with tensorstore's neuroglancer_precomputed driver and, for each scale
      L, its voxels as little-endian raw bytes (x fastest) in EXPECTED.L: uint64 as uint32, the type
      sparseleap reads it as. Scale L has ceil(size / 2^L) voxels and its own data. --labels makes
      segmentation-like data (blocks of few ids); --big-ids adds ids of 2^32 - 1; --too-big (uint64)
      one id of 2^32 in the middle of scale 0, which sparseleap must refuse; --holes leaves a corner of every scale unwritten (missing
      chunks, or chunks missing from their shard), zeros in EXPECTED; --gzip-files then gzips every
      unsharded chunk file in place (tensorstore writes them raw; CloudVolume writes them gzipped).
      --from-zarr takes the data of scale L from level L of an OME-Zarr v2 store (read by tensorstore's
      zarr driver; --shape and --scales are then the store's), for benchmarks of one volume in each format.
  zarr3 OUT EXPECTED --dtype D --shape Z,Y,X --chunks Z,Y,X [--shards Z,Y,X --index start|end]
        [--compressor none|gzip|zstd|blosc] [--crc] [--holes]
      Writes a bare Zarr v3 array with tensorstore's zarr3 driver (sharding_indexed when --shards is
      given: the inner chunk is --chunks) and its voxels as raw bytes in EXPECTED.0. --holes leaves the
      first shard (or chunk) unwritten.
  raw FILE --dtype D --shape X,Y,Z [--labels] [--seed N]
      Writes the data `make` writes at scale 0 as little-endian raw bytes (for NRRD comparisons).
"""
import argparse
import os
import sys

import numpy as np


def tup(s):
    return [int(v) for v in s.split(",")] if s else None


def data(shape_xyz, dtype, seed, labels, big_ids, too_big=False):
    """Array indexed [x, y, z]."""
    rng = np.random.default_rng(seed)
    x, y, z = np.meshgrid(*[np.arange(n) for n in shape_xyz], indexing="ij")
    dt = np.dtype(dtype)
    if labels:
        # Blocks of 3 voxels with ids from a small set, so compressed_segmentation has small tables;
        # a sprinkle of random ids exercises wider encodings.
        v = ((x // 3) * 5 + (y // 3) * 3 + (z // 3) * 7) % 11
        noise = rng.integers(0, 1000, size=shape_xyz)
        v = np.where(noise < 30, noise + 100, v).astype(np.uint64)
        if big_ids:
            v = np.where(noise == 999, np.uint64(0xFFFFFFFF), v)
        if too_big:
            v.flat[len(v.flat) // 2] = np.uint64(1) << np.uint64(32)
        return v.astype(dt)
    v = (x * 7 + y * 13 + z * 29) % 251 + rng.integers(0, 3, size=shape_xyz)
    if dt.kind == "f":
        return (v * 0.37 - 11.5).astype(dt)
    if dt.itemsize >= 2:
        v = v * 257 + (x % 5)
    return v.astype(dt)


def expected_bytes(a):
    """[x, y, z] array -> raw bytes x fastest, uint64 narrowed to uint32."""
    if a.dtype == np.uint64:
        a = a.astype(np.uint32)
    return np.ascontiguousarray(a.transpose(2, 1, 0)).astype(a.dtype.newbyteorder("<")).tobytes()


def make(args):
    import tensorstore as ts

    levels = []
    if args.from_zarr:
        while os.path.exists(os.path.join(args.from_zarr, str(len(levels)), ".zarray")):
            z = ts.open({"driver": "zarr", "kvstore": {"driver": "file", "path": os.path.join(args.from_zarr, str(len(levels)))}}).result()
            levels.append(z.read().result().transpose(2, 1, 0))
        args.scales = len(levels)
        args.shape = ",".join(str(n) for n in levels[0].shape)
    shape = tup(args.shape)
    chunks = tup(args.chunks)
    offset = tup(args.offset) or [0, 0, 0]
    res = [float(v) for v in args.resolution.split(",")]
    for level in range(args.scales):
        size = [(n + (1 << level) - 1) >> level for n in shape]
        scale = {
            "key": "s%d" % level,
            "size": size,
            "resolution": [r * (1 << level) for r in res],
            "voxel_offset": [o >> level for o in offset],
            "chunk_size": chunks,
            "encoding": args.encoding,
        }
        if args.encoding == "compressed_segmentation":
            scale["compressed_segmentation_block_size"] = tup(args.block)
        if args.sharding:
            scale["sharding"] = {
                "@type": "neuroglancer_uint64_sharded_v1",
                "hash": args.sharding,
                "preshift_bits": args.preshift,
                "minishard_bits": args.minishard,
                "shard_bits": args.shard,
                "minishard_index_encoding": args.minishard_index,
                "data_encoding": args.data,
            }
        spec = {
            "driver": "neuroglancer_precomputed",
            "kvstore": {"driver": "file", "path": os.path.abspath(args.out) + "/"},
            "scale_metadata": scale,
            "multiscale_metadata": {
                "data_type": args.dtype,
                "num_channels": 1,
                "type": "segmentation" if args.labels else "image",
            },
            "create": True,
            "open": level > 0,
        }
        store = ts.open(spec).result()
        if levels:
            if list(levels[level].shape) != size:
                raise SystemExit("level %d of %s is %s, not %s" % (level, args.from_zarr, levels[level].shape, size))
            a = np.ascontiguousarray(levels[level]).astype(args.dtype)
        else:
            a = data(size, args.dtype, args.seed + level, args.labels, args.big_ids, args.too_big and level == 0)
        if args.holes:
            # A corner left unwritten: whole chunks missing (tensorstore writes only what it is given).
            hx, hy, hz = [min(c, n) for c, n in zip(chunks, size)]
            a[:hx, :hy, :hz] = 0
            view = store.translate_to[0, 0, 0, 0]
            for sl in [
                (slice(hx, size[0]), slice(0, size[1]), slice(0, size[2])),
                (slice(0, hx), slice(hy, size[1]), slice(0, size[2])),
                (slice(0, hx), slice(0, hy), slice(hz, size[2])),
            ]:
                part = a[sl]
                if part.size:
                    view[sl + (0,)].write(part).result()
        else:
            store.translate_to[0, 0, 0, 0][:, :, :, 0].write(a).result()
        with open(args.expected + "." + str(level), "wb") as f:
            f.write(expected_bytes(a))
    if args.gzip_files:
        import gzip

        for root, _, files in os.walk(args.out):
            for name in files:
                if name != "info" and not name.endswith(".shard"):
                    path = os.path.join(root, name)
                    with open(path, "rb") as f:
                        raw_chunk = f.read()
                    with open(path, "wb") as f:
                        f.write(gzip.compress(raw_chunk))
    print("wrote", args.out, args.scales, "scales")


def zarr3(args):
    import tensorstore as ts

    shape = tup(args.shape)
    chunks = tup(args.chunks)
    codecs = [{"name": "bytes", "configuration": {"endian": "little"}}]
    if args.compressor == "gzip":
        codecs.append({"name": "gzip", "configuration": {"level": 5}})
    elif args.compressor == "zstd":
        codecs.append({"name": "zstd", "configuration": {"level": 3}})
    elif args.compressor == "blosc":
        codecs.append({"name": "blosc", "configuration": {"cname": "lz4", "clevel": 5, "shuffle": "shuffle", "typesize": np.dtype(args.dtype).itemsize}})
    elif args.compressor != "none":
        raise SystemExit("unknown compressor " + args.compressor)
    if args.crc:
        codecs.append({"name": "crc32c"})
    outer = chunks
    if args.shards:
        outer = tup(args.shards)
        codecs = [{"name": "sharding_indexed", "configuration": {
            "chunk_shape": chunks, "codecs": codecs,
            "index_codecs": [{"name": "bytes", "configuration": {"endian": "little"}}, {"name": "crc32c"}],
            "index_location": args.index}}]
    spec = {"driver": "zarr3", "kvstore": {"driver": "file", "path": os.path.abspath(args.out) + "/"},
            "metadata": {"shape": shape, "data_type": args.dtype, "dimension_names": ["z", "y", "x"],
                         "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": outer}},
                         "codecs": codecs},
            "create": True, "delete_existing": True}
    store = ts.open(spec).result()
    a = data(shape[::-1], args.dtype, args.seed, False, False).transpose(2, 1, 0)  # [z, y, x]
    if args.holes:
        hz, hy, hx = [min(c, n) for c, n in zip(outer, shape)]
        a[:hz, :hy, :hx] = 0
        for sl in [(slice(hz, None),), (slice(0, hz), slice(hy, None)), (slice(0, hz), slice(0, hy), slice(hx, None))]:
            if a[sl].size:
                store[sl].write(a[sl]).result()
    else:
        store.write(a).result()
    with open(args.expected + ".0", "wb") as f:
        f.write(np.ascontiguousarray(a).astype(a.dtype.newbyteorder("<")).tobytes())
    print("wrote", args.out)


def raw(args):
    a = data(tup(args.shape), args.dtype, args.seed, args.labels, False)
    with open(args.file, "wb") as f:
        f.write(expected_bytes(a))


def main():
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("make")
    m.add_argument("out")
    m.add_argument("expected")
    z = sub.add_parser("zarr3")
    z.add_argument("out")
    z.add_argument("expected")
    z.add_argument("--dtype", required=True)
    z.add_argument("--shape", required=True)
    z.add_argument("--chunks", required=True)
    z.add_argument("--shards", default="")
    z.add_argument("--index", default="end")
    z.add_argument("--compressor", default="none")
    z.add_argument("--crc", action="store_true")
    z.add_argument("--holes", action="store_true")
    z.add_argument("--seed", type=int, default=1)
    r = sub.add_parser("raw")
    r.add_argument("file")
    for q in (m, r):
        q.add_argument("--dtype", required=True)
        q.add_argument("--shape", required=q is r)
        q.add_argument("--labels", action="store_true")
        q.add_argument("--seed", type=int, default=1)
    m.add_argument("--chunks", required=True)
    m.add_argument("--scales", type=int, default=1)
    m.add_argument("--encoding", default="raw")
    m.add_argument("--block", default="8,8,8")
    m.add_argument("--sharding", default="")
    m.add_argument("--preshift", type=int, default=0)
    m.add_argument("--minishard", type=int, default=0)
    m.add_argument("--shard", type=int, default=0)
    m.add_argument("--minishard-index", default="raw")
    m.add_argument("--data", default="raw")
    m.add_argument("--offset", default="")
    m.add_argument("--resolution", default="4,4,8")
    m.add_argument("--holes", action="store_true")
    m.add_argument("--big-ids", action="store_true")
    m.add_argument("--gzip-files", action="store_true")
    m.add_argument("--too-big", action="store_true")
    m.add_argument("--from-zarr", default="")
    a = p.parse_args()
    {"make": make, "zarr3": zarr3, "raw": raw}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main())
