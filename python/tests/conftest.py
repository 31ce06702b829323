"""Shared fixtures: the repository, the CLI the package is compared with, and a small
reader of the CLI's 8-bit grey mask PNGs (written here, so that the comparison does not
read them with the code under test)."""

import os
import shutil
import struct
import subprocess
import zlib
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]


def _cli_path():
    given = os.environ.get("SURFTILE_BIN")
    if given:
        return Path(given)
    for profile in ("release", "debug"):
        p = REPO / "target" / profile / "surftile"
        if p.exists():
            return p
    if shutil.which("cargo") is None:
        pytest.fail("no surftile CLI: set SURFTILE_BIN or build it with cargo build --release")
    subprocess.run(
        ["cargo", "build", "--release", "--bin", "surftile"], cwd=REPO, check=True
    )
    return REPO / "target" / "release" / "surftile"


@pytest.fixture(scope="session")
def cli():
    """Runs the surftile CLI with the given arguments; returns its stdout, and fails the
    test with its stderr when it exits non-zero."""
    exe = _cli_path()

    def run(*args):
        r = subprocess.run(
            [str(exe), *map(str, args)], capture_output=True, text=True, cwd=REPO
        )
        if r.returncode != 0:
            pytest.fail(f"surftile {' '.join(map(str, args))} failed: {r.stderr}")
        return r.stdout

    return run


@pytest.fixture(scope="session")
def exemplar(tmp_path_factory):
    """A 128² crop of the bundled AFM map (tiles/di-6.npy) as .npy, and its array."""
    data = np.load(REPO / "tiles" / "di-6.npy")[:128, :128].copy()
    path = tmp_path_factory.mktemp("ex") / "di6-128.npy"
    np.save(path, data)
    return path, data


def read_grey_png(path):
    """An 8-bit grey, non-interlaced PNG as a uint8 array (PNG filters 0–4)."""
    raw = Path(path).read_bytes()
    assert raw[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat = 8, b""
    while pos < len(raw):
        (n,) = struct.unpack(">I", raw[pos : pos + 4])
        kind, body = raw[pos + 4 : pos + 8], raw[pos + 8 : pos + 8 + n]
        pos += 12 + n
        if kind == b"IHDR":
            w, h, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert (depth, colour, interlace) == (8, 0, 0)
        elif kind == b"IDAT":
            idat += body
    data = zlib.decompress(idat)
    out = np.zeros((h, w), np.int32)
    prev = np.zeros(w, np.int32)
    for y in range(h):
        f = data[y * (w + 1)]
        line = np.frombuffer(data, np.uint8, w, y * (w + 1) + 1).astype(np.int32)
        cur = np.zeros(w, np.int32)
        for x in range(w):
            a = cur[x - 1] if x else 0
            b = prev[x]
            c = prev[x - 1] if x else 0
            if f == 0:
                pred = 0
            elif f == 1:
                pred = a
            elif f == 2:
                pred = b
            elif f == 3:
                pred = (a + b) // 2
            else:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            cur[x] = (line[x] + pred) & 255
        out[y] = cur
        prev = cur
    return out.astype(np.uint8)


def same_bits(a, b):
    """Whether two float32 arrays hold the same bits (NaN included)."""
    a, b = np.asarray(a, np.float32), np.asarray(b, np.float32)
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))
