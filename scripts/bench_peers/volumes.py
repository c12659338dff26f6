"""Volume files for bench-peers, read into numpy exactly as sparseleap reads them.

NRRD: the raw, attached-header files `sparseleap gen` writes. OME-Zarr: level 0 of a store that
`sparseleap ingest` wrote (python3-zarr), so a NIfTI file reaches VTK through sparseleap's own
NIfTI reader. Arrays are returned x fastest (C order z, y, x), which is also vtkImageData's order.
"""
import os

import numpy as np

_NRRD_TYPES = {"unsigned char": np.uint8, "uchar": np.uint8, "uint8": np.uint8, "unsigned short": np.uint16,
               "ushort": np.uint16, "uint16": np.uint16, "float": np.float32}


def read_nrrd(path):
    with open(path, "rb") as f:
        data = f.read()
    end = data.find(b"\n\n")
    if not data.startswith(b"NRRD") or end < 0:
        raise ValueError(f"{path}: not an attached-header NRRD file")
    fields = {}
    for line in data[:end].decode("ascii", "replace").splitlines()[1:]:
        if ":" in line and not line.startswith("#"):
            k, v = line.split(":", 1)
            fields[k.strip()] = v.strip()
    if fields.get("encoding", "raw") != "raw":
        raise ValueError(f"{path}: expected raw encoding, got {fields.get('encoding')}")
    dtype = _NRRD_TYPES.get(fields.get("type"))
    if dtype is None or fields.get("dimension") != "3":
        raise ValueError(f"{path}: expected a 3-D volume of type uchar, ushort or float")
    dims = tuple(int(v) for v in fields["sizes"].split())
    spacing = tuple(float(v) for v in fields.get("spacings", "1 1 1").split())
    order = ">" if fields.get("endian") == "big" else "<"
    arr = np.frombuffer(data, dtype=np.dtype(dtype).newbyteorder(order), offset=end + 2)
    if arr.size != dims[0] * dims[1] * dims[2]:
        raise ValueError(f"{path}: {arr.size} voxels, expected {dims}")
    return arr.astype(dtype).reshape(dims[2], dims[1], dims[0]), spacing


def read_zarr(path):
    import zarr  # only needed for stores
    root = zarr.open(path, mode="r")
    arr = np.asarray(root["0"][:])
    if arr.ndim != 3:
        raise ValueError(f"{path}: level 0 is {arr.ndim}-D, expected z, y, x")
    spacing = (1.0, 1.0, 1.0)
    ms = root.attrs.get("multiscales")
    if ms:
        for t in ms[0]["datasets"][0].get("coordinateTransformations", []):
            if t.get("type") == "scale":
                spacing = tuple(float(v) for v in t["scale"][-3:][::-1])
    return arr, spacing


def read_volume(path):
    """(array shaped z, y, x; spacing x, y, z) of a NRRD file or an OME-Zarr store."""
    return read_zarr(path) if os.path.isdir(path) else read_nrrd(path)
