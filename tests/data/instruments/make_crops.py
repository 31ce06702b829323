#!/usr/bin/python3
"""Make small crops of the instrument sample files plus their expected heights.

Windows are given in coordinates of the REFERENCE npy (rows r0..r0+h-1 = y from the top,
cols c0..c0+w-1 = x); each writer maps them to the file's storage order.
"""
import hashlib
import os
import shutil
import struct
import sys

import numpy as np

SRC = "/work/shared/data/instruments/"
REF = "/work/shared/data/measured/"
OUT = "/work/main/tests/data/instruments/"
sys.path.insert(0, "/tmp/formats")

# stem: (r0, c0, h, w) in reference-npy rows/cols
WINDOWS = {
    "al3d-1": (83, 41, 128, 120),
    "plu-1": (201, 305, 120, 128),
    "sur-2": (155, 417, 120, 128),
    "opd-1": (333, 41, 120, 128),
    "di-6": (157, 211, 64, 64),
    "metropro-1": (151, 257, 120, 128),
}
EXT = {"al3d-1": "al3d", "plu-1": "plu", "sur-2": "sur", "opd-1": "opd", "di-6": "di",
       "metropro-1": "dat"}
EDITS = {}


def src(stem):
    return open(SRC + stem + "." + EXT[stem], "rb").read()


# ---------------------------------------------------------------- AL3D
def crop_al3d(stem, r0, c0, h, w):
    b = src(stem)
    ntags = int(b[69 + 20:69 + 50].split(b"\0")[0])
    H = 17 + 52 * (2 + ntags) + 256
    hdr = bytearray(b[:H])
    tags = {}
    for i in range(ntags):
        p = 121 + 52 * i
        k = bytes(hdr[p:p + 20]).split(b"\0")[0].decode("latin-1")
        tags.setdefault(k, p)

    def setv(key, val):
        p = tags[key] + 20
        v = str(val).encode()
        hdr[p:p + 30] = v + b"\0" * (30 - len(v))

    nx, ny = int(b[tags["Cols"] + 20:tags["Cols"] + 50].split(b"\0")[0]), \
        int(b[tags["Rows"] + 20:tags["Rows"] + 50].split(b"\0")[0])
    depth = int(b[tags["DepthImageOffset"] + 20:tags["DepthImageOffset"] + 50].split(b"\0")[0])
    assert depth == H
    stride = (nx * 4 + 7) // 8 * 8
    setv("Cols", w)
    setv("Rows", h)
    setv("TextureImageOffset", 0)
    setv("NumberOfPlanes", 0)
    nstride = (w * 4 + 7) // 8 * 8
    out = bytes(hdr)
    for r in range(r0, r0 + h):
        o = depth + r * stride + 4 * c0
        out += b[o:o + 4 * w] + b"\0" * (nstride - 4 * w)
    EDITS[stem] = ("header bytes 0..1261 kept (TagCount 17, DepthImageOffset 1261 unchanged); "
                   "tag values rewritten: Cols=%d, Rows=%d, TextureImageOffset=0, NumberOfPlanes=0; "
                   "texture planes dropped; f32 rows of %d bytes (no padding)" % (w, h, nstride))
    return out


# ---------------------------------------------------------------- PLU
def crop_plu(stem, r0, c0, h, w):
    b = src(stem)
    hdr = bytearray(b[:500])
    ny, nx = struct.unpack_from("<2I", b, 500)
    struct.pack_into("<I", hdr, 388, h)
    struct.pack_into("<I", hdr, 392, w)
    hdr[489] = 1
    hdr[492] = 0
    data = np.frombuffer(b, "<f4", nx * ny, 508).reshape(ny, nx)
    minmax = b[508 + 4 * nx * ny:508 + 4 * nx * ny + 8]
    out = bytes(hdr) + struct.pack("<2I", h, w) + data[r0:r0 + h, c0:c0 + w].tobytes() + minmax
    EDITS[stem] = ("header bytes 0..500 kept but u32 @388 (cal. yres)=%d, u32 @392 (cal. xres)=%d, "
                   "u8 @489 num_layers=1, u8 @492 num_images=0 (RGB image and trailing metadata "
                   "dropped; FOV fields @448..464 left as in the original); layer header ny=%d, nx=%d; "
                   "min/max 8 bytes copied from the original" % (h, w, h, w))
    return out


# ---------------------------------------------------------------- SUR
def crop_sur(stem, r0, c0, h, w):
    b = src(stem)
    hdr = bytearray(b[:512])
    assert hdr[:12] == b"DIGITAL SURF"
    nx, ny = struct.unpack_from("<2i", b, 108)
    psize = struct.unpack_from("<h", b, 98)[0]
    assert psize == 32 and struct.unpack_from("<HH", b, 334) == (0, 0)
    struct.pack_into("<3i", hdr, 108, w, h, w * h)
    data = np.frombuffer(b, "<i4", nx * ny, 512).reshape(ny, nx)
    out = bytes(hdr) + data[r0:r0 + h, c0:c0 + w].tobytes()
    EDITS[stem] = ("512-byte header kept but i32 @108 nx=%d, @112 ny=%d, @116 points=%d "
                   "(Zmin/Zmax @100/@104 unchanged, so the NM marker stays Zmin-2 = 89118; "
                   "comment/private sizes already 0)" % (w, h, w * h))
    return out


# ---------------------------------------------------------------- OPD
def crop_opd(stem, r0, c0, h, w):
    b = src(stem)
    import opd
    blocks = opd.parse_blocks(b)
    keep = ["PrimaryData2D", "Wavelength", "Aspect", "Pixel_size", "Raw", "Time", "Date"]
    byname = {}
    for bl in blocks:
        byname.setdefault(bl["name"], bl)
    entries = []
    payloads = []
    for name in keep:     # same relative order as the original directory
        bl = byname[name]
        if name == "Raw":
            nx, ny, el = struct.unpack_from("<HHH", b, bl["offset"])
            assert el == 4
            raw = np.frombuffer(b, "<f4", nx * ny, bl["offset"] + 6).reshape(nx, ny)  # [x][j]
            j0 = ny - r0 - h      # stored j counts from the bottom: j = ny-1-row
            sub = raw[c0:c0 + w, j0:j0 + h]
            pay = struct.pack("<HHH", w, h, 4) + np.ascontiguousarray(sub).tobytes()
        else:
            pay = b[bl["offset"]:bl["offset"] + bl["length"]]
        nm = name.encode("latin-1")
        entries.append(nm + b"\0" * (16 - len(nm)) + struct.pack("<HIH", bl["type"], len(pay), bl["attr"]))
        payloads.append(pay)
    dlen = 24 * (1 + len(entries))
    d0 = b"Directory" + b"\0" * 7 + struct.pack("<HIH", 1, dlen, 0xFFFF)
    out = b"\x01\x00" + d0 + b"".join(entries) + b"".join(payloads)
    EDITS[stem] = ("compact directory of 8 entries (Directory, PrimaryData2D, Wavelength, Aspect, "
                   "Pixel_size, Raw, Time, Date; their data copied unchanged, all other blocks "
                   "dropped); Raw array d0=nx=%d, d1=ny=%d, elsize 4, stored column by column, "
                   "bottom row first (source columns %d..%d, stored j %d..%d)"
                   % (w, h, c0, c0 + w - 1, j0, j0 + h - 1))
    return out


# ---------------------------------------------------------------- DI
def crop_di(stem, r0, c0, h, w):
    b = src(stem)
    end = b.find(b"\\*File list end")
    lines = b[:end].decode("latin-1").split("\r\n")
    assert lines[-1] == ""
    lines = lines[:-1]
    H = None
    # split into sections
    secs = []
    for ln in lines:
        if ln.startswith("\\*"):
            secs.append([ln])
        else:
            secs[-1].append(ln)
    for ln in secs[0]:
        if ln.startswith("\\Data length:"):
            H = int(ln.split(":")[1])
    nimg = 0
    out_secs = []
    nx = ny = None
    for s in secs:
        name = s[0][2:].strip().lower()
        if name == "ciao image list":
            nimg += 1
            if nimg > 1:
                continue          # drop images 1..3
            new = [s[0]]
            for ln in s[1:]:
                k, _, v = ln.partition(": ")
                kl = k.lower()
                if kl == "\\samps/line":
                    nx = int(v); ln = "%s: %d" % (k, w)
                elif kl == "\\number of lines":
                    ny = int(v); ln = "%s: %d" % (k, h)
                elif kl == "\\data length":
                    ln = "%s: %d" % (k, w * h * 2)
                elif kl == "\\data offset":
                    off = int(v); ln = "%s: %d" % (k, H)
                elif kl == "\\bytes/pixel":
                    assert v.strip() == "2"
                elif kl == "\\scan size":
                    sx, sy, u = v.split()
                    assert (sx, sy, u) == ("10", "10", "~m")
                    ln = "%s: %s %s %s" % (k, repr(10 * w / 512), repr(10 * h / 512), u)
                elif kl == "\\valid data len x":
                    ln = "%s: %d" % (k, w)
                elif kl == "\\valid data len y":
                    ln = "%s: %d" % (k, h)
                new.append(ln)
            out_secs.append(new)
        elif name == "ciao scan list":
            new = [s[0]]
            for ln in s[1:]:
                k, _, v = ln.partition(": ")
                kl = k.lower()
                if kl == "\\samps/line":
                    ln = "%s: %d" % (k, w)
                elif kl == "\\lines":
                    ln = "%s: %d" % (k, h)
                elif kl == "\\scan size":
                    assert v == "10000 nm"
                    ln = "%s: %s nm" % (k, repr(10000 * w / 512).rstrip("0").rstrip("."))
                new.append(ln)
            out_secs.append(new)
        else:
            out_secs.append(s)
    text = "\r\n".join(ln for s in out_secs for ln in s) + "\r\n" + "\\*File list end\r\n"
    hdr = text.encode("latin-1") + b"\x1a"
    assert len(hdr) <= H
    hdr += b"\0" * (H - len(hdr))
    raw = np.frombuffer(b, "<i2", nx * ny, off).reshape(ny, nx)
    L0 = ny - r0 - h          # first stored line is the bottom of the image
    out = hdr + raw[L0:L0 + h, c0:c0 + w].tobytes()
    EDITS[stem] = ("header kept at %d bytes (File list Data length), text re-padded with NUL after "
                   "0x1A; images 1..3 (Height retrace, Phase, Amplitude Error) and their Ciao image "
                   "list sections dropped; image 0: Samps/line=%d, Number of lines=%d, Data "
                   "length=%d, Data offset=%d, Scan Size=`%s %s ~m`, Valid data len X/Y=%d/%d; "
                   "Ciao scan list: Samps/line=%d, Lines=%d, Scan Size=`%s nm`; stored lines %d..%d"
                   % (H, w, h, w * h * 2, H, repr(10 * w / 512), repr(10 * h / 512), w, h, w, h,
                      repr(10000 * w / 512).rstrip("0").rstrip("."), L0, L0 + h - 1))
    return out


# ---------------------------------------------------------------- MetroPro
def crop_metropro(stem, r0, c0, h, w):
    b = src(stem)
    hs = struct.unpack_from(">I", b, 6)[0]
    hdr = bytearray(b[:hs])
    acw, ach, nb = struct.unpack_from(">HHH", b, 52)
    acn = struct.unpack_from(">I", b, 60)[0]
    nx, ny = struct.unpack_from(">HH", b, 68)
    struct.pack_into(">HHH", hdr, 52, 0, 0, 0)
    struct.pack_into(">I", hdr, 60, 0)
    struct.pack_into(">HHI", hdr, 68, w, h, 4 * w * h)
    data = np.frombuffer(b, ">i4", nx * ny, hs + acn).reshape(ny, nx)
    out = bytes(hdr) + data[r0:r0 + h, c0:c0 + w].tobytes()
    EDITS[stem] = ("834-byte header kept but ac_width @52=0, ac_height @54=0, ac_n_buckets @56=0, "
                   "ac_n_bytes @60=0 (intensity frame dropped), cn_width @68=%d, cn_height @70=%d, "
                   "cn_n_bytes @72=%d (cn_org_x/y left as in the original)" % (w, h, 4 * w * h))
    return out


MAKERS = {"al3d-1": crop_al3d, "plu-1": crop_plu, "sur-2": crop_sur, "opd-1": crop_opd,
          "di-6": crop_di, "metropro-1": crop_metropro}
MOD = {"al3d-1": "al3d", "plu-1": "plu", "sur-2": "sur", "opd-1": "opd", "di-6": "di",
       "metropro-1": "metropro"}


def main():
    import importlib
    os.makedirs(OUT, exist_ok=True)
    rows = []
    ok_all = True
    for stem, (r0, c0, h, w) in WINDOWS.items():
        data = MAKERS[stem](stem, r0, c0, h, w)
        fn = OUT + stem + "-crop." + EXT[stem]
        open(fn, "wb").write(data)
        ref = np.load(REF + stem + ".npy")
        assert ref.dtype == np.float32
        assert r0 + h <= ref.shape[0] and c0 + w <= ref.shape[1]
        exp = np.ascontiguousarray(ref[r0:r0 + h, c0:c0 + w])
        np.save(OUT + stem + "-crop.npy", exp)
        # verify
        m = importlib.import_module(MOD[stem])
        hc, dx, dy, unit, info = m.read(fn)
        h0, dx0, dy0, unit0, _ = m.read(SRC + stem + "." + EXT[stem])
        e = np.load(OUT + stem + "-crop.npy").astype(np.float64)
        shape_ok = hc.shape == e.shape == (h, w)
        nan_ok = shape_ok and np.array_equal(np.isnan(hc), np.isnan(e))
        d = ~np.isnan(e)
        rel = float(np.max(np.abs(hc[d] - e[d])) / np.max(np.abs(e[d]))) if shape_ok else float("inf")
        sp_ok = dx == dx0 and dy == dy0 and unit == unit0
        size_ok = len(data) <= 65536
        same_as_orig_crop = np.array_equal(hc, h0[r0:r0 + h, c0:c0 + w], equal_nan=True)
        ok = shape_ok and nan_ok and rel <= 1e-5 and sp_ok and size_ok and same_as_orig_crop
        ok_all &= ok
        rows.append(dict(stem=stem, file=os.path.basename(fn), size=len(data), h=h, w=w, r0=r0, c0=c0,
                         dx=dx, dy=dy, unit=unit, nan=int(np.isnan(e).sum()), rel=rel, ok=ok,
                         sp_ok=sp_ok, same=same_as_orig_crop,
                         md5=hashlib.md5(data).hexdigest(),
                         md5npy=hashlib.md5(open(OUT + stem + "-crop.npy", "rb").read()).hexdigest()))
    shutil.copyfile(SRC + "sdf-1.sdf", OUT + "sdf-1.sdf")
    sdf = open(OUT + "sdf-1.sdf", "rb").read()
    import sdf as sdfmod
    hs, sdx, sdy, sunit, _ = sdfmod.read(OUT + "sdf-1.sdf")
    print("%-22s %6s %9s %-22s %-22s %-4s %4s %9s %s" % ("file", "bytes", "grid w×h", "dx µm", "dy µm",
                                                        "unit", "NaN", "max rel", "check"))
    for r in rows:
        print("%-22s %6d %4d×%-4d %-22r %-22r %-4s %4d %9.2e %s (spacing==orig %s, ==orig-file crop %s)"
              % (r["file"], r["size"], r["w"], r["h"], r["dx"], r["dy"], r["unit"], r["nan"], r["rel"],
                 "PASS" if r["ok"] else "FAIL", r["sp_ok"], r["same"]))
    print("%-22s %6d %4d×%-4d %-22r %-22r %-4s %4d" % ("sdf-1.sdf", len(sdf), hs.shape[1], hs.shape[0],
                                                       sdx, sdy, sunit, int(np.isnan(hs).sum())))
    print("OVERALL", "PASS" if ok_all else "FAIL")
    import json
    json.dump(dict(rows=rows, edits=EDITS, sdf=dict(size=len(sdf), md5=hashlib.md5(sdf).hexdigest(),
                                                    shape=hs.shape, dx=sdx, dy=sdy, unit=sunit,
                                                    values=hs.tolist())),
              open("/tmp/mkcrops/result.json", "w"), indent=1, default=str)
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
