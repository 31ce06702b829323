"""Reads surftile dataset shards back into numpy with the standard library only.

    python python/examples/read_shards.py example-dataset

Each sample comes back as a dict: "height" (float32 array), "mask" (uint8 array, if
the dataset has masks), "shaded" (uint8, if any) and "meta" (the sample's JSON). The
same shards read with the webdataset package: docs/dataset.md.
"""

from __future__ import annotations

import glob
import io
import json
import os
import struct
import sys
import tarfile
import zlib
from typing import Dict, Iterator

import numpy as np


def decode_png8(data: bytes) -> np.ndarray:
    """An 8-bit grey, non-interlaced PNG (what surftile writes for masks and shading)."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG")
    pos, idat, width, height = 8, [], 0, 0
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + n]
        pos += 12 + n
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if (depth, colour, interlace) != (8, 0, 0):
                raise ValueError("expected an 8-bit grey, non-interlaced PNG")
        elif kind == b"IDAT":
            idat.append(body)
    raw = np.frombuffer(zlib.decompress(b"".join(idat)), np.uint8).reshape(height, width + 1)
    out = np.zeros((height, width), np.uint8)
    prev = np.zeros(width, np.int32)
    for y in range(height):
        f, line = raw[y, 0], raw[y, 1:].astype(np.int32)
        if f == 0:
            row = line
        elif f == 1:  # Sub: a running sum along the row
            row = np.cumsum(line) & 255
        elif f == 2:  # Up
            row = (line + prev) & 255
        else:  # Average and Paeth depend on the pixel to the left: one by one
            row = np.zeros(width, np.int32)
            for x in range(width):
                a = int(row[x - 1]) if x else 0
                b = int(prev[x])
                if f == 3:
                    row[x] = (line[x] + (a + b) // 2) & 255
                else:
                    c = int(prev[x - 1]) if x else 0
                    pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                    pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                    row[x] = (line[x] + pred) & 255
        out[y] = row
        prev = row
    return out


def read_shard(path: str) -> Iterator[Dict[str, object]]:
    """The samples of one shard, in order."""
    sample: Dict[str, object] = {}
    key = None
    with tarfile.open(path) as tar:
        for member in tar:
            k, ext = member.name.split(".", 1)
            if key is not None and k != key:
                yield sample
                sample = {}
            key = k
            data = tar.extractfile(member).read()
            if ext == "height.npy":
                sample["height"] = np.load(io.BytesIO(data))
            elif ext == "mask.png":
                sample["mask"] = decode_png8(data)
            elif ext == "shaded.png":
                sample["shaded"] = decode_png8(data)
            elif ext == "json":
                sample["meta"] = json.loads(data)
    if sample:
        yield sample


def read_dataset(folder: str) -> Iterator[Dict[str, object]]:
    """Every sample of a dataset folder, shard by shard."""
    for path in sorted(glob.glob(os.path.join(folder, "shard-*.tar"))):
        yield from read_shard(path)


if __name__ == "__main__":
    folder = sys.argv[1] if len(sys.argv) > 1 else "example-dataset"
    with open(os.path.join(folder, "dataset.json")) as f:
        legend = json.load(f).get("mask_legend", {})
    for s in read_dataset(folder):
        meta, h = s["meta"], s["height"]
        ids = np.unique(s["mask"]) if "mask" in s else []
        print(f"{meta['key']}  {meta['source']['path']:<18} seed {meta['seed']:>10}  "
              f"heights {h.shape} {h.mean():+.3f} ± {h.std():.3f} {meta['height_unit']}  "
              f"mask: {', '.join(legend.get(str(i), str(i)) for i in ids)}")
