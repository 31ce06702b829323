"""The Python package against the CLI: the same bits for the same inputs, in place
fills, threads, bakes from arrays, and the errors of bad input."""

import json
import math
import sys
import tracemalloc
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import surftile
from conftest import REPO, read_grey_png, same_bits

# A region far from the origin, as the CLI takes it.
X, Y, W, H = -1_000_000_000.0, 12345.5, 96, 64

BANK_METHODS = [
    ("rpn", []),
    ("adsn", []),
    ("roller", []),
    ("quilt", []),
    ("rsgf", ["--stochastic"]),
    ("synth", []),
    ("quilting", ["--penalty", "0.2"]),
]


@pytest.fixture(scope="module")
def banks(cli, exemplar, tmp_path_factory):
    """A bank of every kind baked by the CLI: the image methods from the 128² AFM
    crop, a colour RSGF bank from a GIMP photo, and a milling bank from a preset's
    TOML."""
    path, _ = exemplar
    out = tmp_path_factory.mktemp("banks")
    made = {}
    for method, flags in BANK_METHODS:
        made[method] = out / f"{method}.bank"
        cli("bake", path, "--method", method, *flags, "--out", made[method])
    made["rsgf-colour"] = out / "crack.bank"
    cli(
        "bake", REPO / "tests/data/gimp-crack.png", "--method", "rsgf", "--stochastic",
        "--out", made["rsgf-colour"],
    )
    made["milling"] = out / "milling.bank"
    cli(
        "bake", REPO / "tiles/milling/parallel-d4-ae05.toml", "--method", "milling",
        "--spacing", "6.1", "--out", made["milling"],
    )
    return made


def cli_render(cli, tmp_path, spec, seed, *extra, step=1.0):
    out = tmp_path / "cli.npy"
    cli(
        "render", spec, "--x", X, "--y", Y, "--w", W, "--h", H, "--step", step,
        "--seed", seed, "--out", out, *extra,
    )
    return np.load(out)


SPECS = [m for m, _ in BANK_METHODS] + ["rsgf-colour", "milling"]


@pytest.mark.parametrize("kind", SPECS)
def test_bank_fills_and_heights_equal_the_cli(cli, banks, tmp_path, kind):
    spec = banks[kind]
    surface = surftile.open(spec).surface(seed=7)
    for step in (1.0, 2.5):
        expected = cli_render(cli, tmp_path, spec, 7, step=step)
        got = surface.fill(X, Y, W, H, step=step)
        assert got.dtype == np.float32
        assert got.shape == expected.shape, (kind, got.shape, expected.shape)
        assert same_bits(got, expected), f"{kind} at step {step}: fills differ"
    if kind == "rsgf-colour":
        assert surface.channels == 3 and got.shape == (H, W, 3)
    for x, y in [(12.5, -7.0), (1e9, 3.25), (-123456.75, 987.5)]:
        text = cli("sample", spec, x, y, "--seed", 7).split()[0]
        assert np.float32(surface.height(x, y)) == np.float32(float(text)), (kind, x, y)


@pytest.mark.parametrize("spec", ["parallel-d4-ae05", "rock", "cells-convex"])
def test_presets_equal_the_cli(cli, tmp_path, spec):
    surface = surftile.open(spec).surface(seed=3)
    expected = cli_render(cli, tmp_path, spec, 3)
    assert same_bits(surface.fill(X, Y, W, H), expected), spec
    xs = np.array([[12.5, 1e9], [-123456.75, 0.0]])
    ys = np.array([[-7.0, 3.25], [987.5, 0.0]])
    got = surface.height(xs, ys)
    assert got.shape == (2, 2) and got.dtype == np.float32
    for (x, y), h in zip(zip(xs.ravel(), ys.ravel()), got.ravel()):
        text = cli("sample", spec, x, y, "--seed", 3).split()[0]
        assert h == np.float32(float(text)), (spec, x, y)


@pytest.mark.parametrize("spec,layer", [("rock", "dust"), ("cells-convex", "peeling")])
def test_imperfection_layer_and_mask_equal_the_cli(cli, tmp_path, spec, layer):
    mask_png = tmp_path / "mask.png"
    expected = cli_render(
        cli, tmp_path, spec, 5, "--imperfect", layer, "--age", 1.5, "--mask", mask_png
    )
    surface = surftile.open(spec, imperfect=layer, age=1.5).surface(seed=5)
    assert surface.has_layer
    heights, mask = surface.fill_with_mask(X, Y, W, H)
    assert mask.dtype == np.uint8 and mask.shape == (H, W)
    assert same_bits(heights, expected)
    assert np.array_equal(mask, read_grey_png(mask_png))
    assert mask.any(), "the layer marks no sample: the comparison would be vacuous"
    assert same_bits(surface.fill(X, Y, W, H), expected)


@pytest.mark.parametrize("layer", [None, "dust"])
def test_defects_and_their_mask_equal_the_cli(cli, tmp_path, layer):
    # Dents every few hundred µm of a milled surface drawn at 4 µm a pixel, alone and
    # under dust: heights and mask ids as `render --defects … --mask` writes them.
    x, y, w, h = -3000.0, 7.5, 200, 150
    mask_png = tmp_path / "mask.png"
    extra = ["--imperfect", layer] if layer else []
    out = tmp_path / "h.npy"
    cli("render", "parallel-d4-ae05", "--x", x, "--y", y, "--w", w, "--h", h,
        "--spacing", 4, "--seed", 6, "--defects", "dents", *extra,
        "--mask", mask_png, "--out", out)
    surface = surftile.open("parallel-d4-ae05", spacing_um=4.0, defects="dents",
                            imperfect=layer).surface(seed=6)
    assert surface.has_defects and surface.has_layer == bool(layer)
    heights, mask = surface.fill_with_mask(x, y, w, h)
    assert same_bits(heights, np.load(out))
    assert np.array_equal(mask, read_grey_png(mask_png))
    assert (mask == 17).any(), "no dent in the region: the comparison would be vacuous"
    info = surftile.open("parallel-d4-ae05", defects="dents").info
    assert info["defects"]["kinds"] == ["dent"]
    with pytest.raises(ValueError, match="scratches, dents, pits"):
        surftile.open("parallel-d4-ae05", defects="dentz")


def test_a_source_without_a_layer_has_an_all_zero_mask():
    heights, mask = surftile.open("rock").surface(1).fill_with_mask(0.0, 0.0, 8, 4)
    assert mask.shape == (4, 8) and not mask.any()
    assert same_bits(heights, surftile.open("rock").surface(1).fill(0.0, 0.0, 8, 4))


def test_out_is_written_in_place(banks):
    surface = surftile.open(banks["rpn"]).surface(seed=2)
    out = np.full((H, W), np.nan, np.float32)
    address = out.__array_interface__["data"][0]
    got = surface.fill(X, Y, W, H, out=out)
    assert got is out
    assert out.__array_interface__["data"][0] == address
    assert same_bits(out, surface.fill(X, Y, W, H))
    colour = surftile.open(banks["rsgf-colour"]).surface(seed=2)
    out3 = np.zeros((H, W, 3), np.float32)
    assert colour.fill(X, Y, W, H, out=out3) is out3
    assert same_bits(out3, colour.fill(X, Y, W, H))


def test_out_allocates_no_second_output_buffer(banks):
    surface = surftile.open(banks["rpn"]).surface(seed=2)
    side = 1024
    out = np.empty((side, side), np.float32)
    surface.fill(0.0, 0.0, side, side, out=out)  # warm up
    tracemalloc.start()
    surface.fill(0.0, 0.0, side, side, out=out)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    # numpy reports its data buffers to tracemalloc: a second output would be 4 MiB.
    assert peak < out.nbytes // 16, f"peak {peak} bytes traced for a {out.nbytes}-byte fill"
    tracemalloc.start()
    surface.fill(0.0, 0.0, side, side)
    _, peak_new = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert peak_new >= out.nbytes, "tracemalloc does not see numpy's buffers"


def test_threads_filling_pieces_give_the_whole(banks):
    bands = [(r, min(r + 16, 256)) for r in range(0, 256, 16)]
    for kind in ("rsgf", "synth", "quilting", "roller", "rpn"):
        surface = surftile.open(banks[kind]).surface(seed=11)
        whole = surface.fill(X, Y, 256, 256)
        pieces = np.full_like(whole, np.nan)

        def fill(band):
            r0, r1 = band
            surface.fill(X, Y + r0, 256, r1 - r0, out=pieces[r0:r1])

        with ThreadPoolExecutor(max_workers=4) as pool:
            list(pool.map(fill, bands))
        assert same_bits(pieces, whole), kind
        # Single points solve a model's neighbourhood cold (milliseconds for RSGF and
        # synth), so points are checked on the bank kinds that look texels up.
        if kind not in ("roller", "rpn"):
            continue

        def points(band):
            r0, r1 = band
            yy, xx = np.mgrid[r0:r1, 0:256]
            return surface.height(X + xx, Y + yy)

        with ThreadPoolExecutor(max_workers=4) as pool:
            rows = list(pool.map(points, bands))
        assert same_bits(np.concatenate(rows), whole), kind


def test_heights_broadcast_and_nan_gives_nan():
    surface = surftile.open("rock").surface(seed=1)
    xs = np.linspace(-5.0, 5.0, 7)
    got = surface.height(xs[None, :], np.array([[0.0], [2.0], [4.0]]))
    assert got.shape == (3, 7) and got.dtype == np.float32
    assert got[2, 3] == np.float32(surface.height(xs[3], 4.0))
    scalar = surface.height(1.5, 2.5)
    assert isinstance(scalar, float)
    assert math.isnan(surface.height(float("nan"), 0.0))
    arr = surface.height(np.array([np.nan, 1.0]), 0.0)
    assert math.isnan(arr[0]) and not math.isnan(arr[1])


def test_bake_from_an_array_equals_the_bake_from_npy(exemplar, tmp_path):
    path, data = exemplar
    for method, params in [("rpn", {}), ("roller", {}), ("rsgf", {"stochastic": True})]:
        from_file = surftile.bake(path, method=method, seed=4, **params)
        from_array = surftile.bake(data, method=method, seed=4, **params)
        a = from_file.surface(3).fill(X, Y, W, H)
        b = from_array.surface(3).fill(X, Y, W, H)
        assert same_bits(a, b), method
        ia, ib = from_file.info, from_array.info
        assert ia["exemplar"].pop("source") == str(path)
        ib["exemplar"].pop("source")
        assert ia == ib, method
    # Integer arrays convert as the .npy reader converts them. (A ramp along x, as this
    # used before, is what a photo's flat field removes: the bake saw a constant image,
    # which it now refuses.)
    x, y = np.arange(128)[None, :], np.arange(128)[:, None]
    grey = (np.load(path) * 0 + (37 * x + 11 * y) % 251).astype(np.uint8)
    np.save(tmp_path / "grey.npy", grey)
    a = surftile.bake(tmp_path / "grey.npy", method="rpn").surface(0).fill(0.0, 0.0, 32, 32)
    b = surftile.bake(grey, method="rpn").surface(0).fill(0.0, 0.0, 32, 32)
    assert a.std() > 1.0, a.std()
    assert same_bits(a, b)


def test_a_python_bake_writes_the_cli_bank(cli, exemplar, tmp_path):
    path, _ = exemplar
    cli("bake", path, "--method", "synth", "--k", 3, "--seed", 9, "--out", tmp_path / "cli.bank")
    bank = surftile.bake(str(path), method="synth", k=3, seed=9)
    bank.save(tmp_path / "py.bank")
    assert (tmp_path / "py.bank").read_bytes() == (tmp_path / "cli.bank").read_bytes()
    auto = surftile.bake(str(path))
    assert auto.log and auto.log[0].startswith("auto: "), auto.log
    assert auto.info["method"] == "rpn", auto.log


def test_quilting_keywords_write_the_cli_bank(cli, exemplar, tmp_path):
    path, _ = exemplar
    out = tmp_path / "cli.bank"
    cli("bake", path, "--method", "quilting", "--block", 32, "--penalty", 0.3, "--out", out)
    bank = surftile.bake(str(path), method="quilting", block=32, penalty=0.3)
    bank.save(tmp_path / "py.bank")
    assert (tmp_path / "py.bank").read_bytes() == out.read_bytes()
    assert "block=32 overlap=8" in bank.info["bake"], bank.info["bake"]
    with pytest.raises(ValueError, match=r"penalty = -1: expected 0 to 100"):
        surftile.bake(str(path), method="quilting", penalty=-1)
    with pytest.raises(ValueError, match=r"quilting"):
        surftile.bake(str(path), method="rsgf", penalty=0.2)
    # edges= sets the wrap as --edges does; wrapped and bounded banks differ.
    cli("bake", path, "--method", "quilting", "--penalty", 0.3, "--edges", "wrap",
        "--out", tmp_path / "cli-wrap.bank")
    for edges, name in (("wrap", "py-wrap.bank"), ("reflect", "py-inside.bank")):
        surftile.bake(str(path), method="quilting", penalty=0.3, edges=edges).save(
            tmp_path / name)
    wrapped = (tmp_path / "py-wrap.bank").read_bytes()
    assert wrapped == (tmp_path / "cli-wrap.bank").read_bytes()
    assert wrapped != (tmp_path / "py-inside.bank").read_bytes()


def test_ragged_keyword_writes_the_cli_bank(cli, tmp_path):
    ice = REPO / "tests/data/etr-ice01.png"
    out = tmp_path / "cli.bank"
    cli("bake", ice, "--method", "synth", "--ragged", 0.25, "--out", out)
    bank = surftile.bake(str(ice), method="synth", ragged=0.25)
    bank.save(tmp_path / "py.bank")
    assert (tmp_path / "py.bank").read_bytes() == out.read_bytes()
    assert "ragged=0.25" in bank.info["bake"], bank.info["bake"]
    with pytest.raises(ValueError, match=r"ragged = 0.75: expected a probability from 0 to 0.5"):
        surftile.bake(str(ice), method="synth", ragged=0.75)


def test_edges_keyword_writes_the_cli_bank(cli, tmp_path):
    mud = REPO / "tests/data/gimp-dried-mud.png"
    for edges in ("reflect", "wrap"):
        out = tmp_path / f"{edges}.bank"
        cli("bake", mud, "--method", "rsgf", "--stochastic", "--edges", edges, "--out", out)
        bank = surftile.bake(str(mud), method="rsgf", stochastic=True, edges=edges)
        bank.save(tmp_path / f"py-{edges}.bank")
        assert (tmp_path / f"py-{edges}.bank").read_bytes() == out.read_bytes(), edges
        assert f"wrap_edges={str(edges == 'wrap').lower()}" in bank.info["bake"], bank.info["bake"]
    with pytest.raises(ValueError, match=r"edges.*auto, reflect, wrap"):
        surftile.bake(str(mud), method="rsgf", stochastic=True, edges="sideways")


def test_repeat_window_keyword_writes_the_cli_bank(cli, tmp_path):
    mud = REPO / "tests/data/gimp-dried-mud.png"
    out = tmp_path / "cli.bank"
    cli("bake", mud, "--method", "rsgf", "--stochastic", "--repeat-window", 1024, "--out", out)
    bank = surftile.bake(str(mud), method="rsgf", stochastic=True, repeat_window=1024)
    bank.save(tmp_path / "py.bank")
    assert (tmp_path / "py.bank").read_bytes() == out.read_bytes()
    assert any("self-repetition within 1024²" in line for line in bank.log), bank.log
    with pytest.raises(ValueError, match=r"repeat_window.*at least 32"):
        surftile.bake(str(mud), method="rsgf", stochastic=True, repeat_window=8)
    off = tmp_path / "cli-off.bank"
    cli("bake", mud, "--method", "rsgf", "--stochastic", "--repeat-window", "off", "--out", off)
    surftile.bake(str(mud), method="rsgf", stochastic=True, repeat_window="off").save(
        tmp_path / "py-off.bank"
    )
    assert (tmp_path / "py-off.bank").read_bytes() == off.read_bytes()
    with pytest.raises(ValueError, match=r"repeat_window.*auto, off or the window's side"):
        surftile.bake(str(mud), method="rsgf", stochastic=True, repeat_window="sometimes")


def test_bake_log_says_when_blocks_would_repeat(tmp_path):
    # The stone wall enlarged 4× (stones of 100–200 px) scales to blocks whose copies
    # recur within 1024²: by default they are capped, and Bank.log says which block
    # repeat_window="off" keeps; with "off", it says once what the default cap would be.
    # The wall as photographed keeps 40-px blocks and no such line.
    wall = REPO / "tests/data/gimp-stone33.png"
    grey = surftile.read(str(wall))["heights"].mean(axis=2)
    big = np.repeat(np.repeat(grey, 4, axis=0), 4, axis=1).astype(np.float32)
    np.save(tmp_path / "wall4.npy", big)
    capped = surftile.bake(str(tmp_path / "wall4.npy"), method="rsgf", stochastic=True)
    blocks = [line for line in capped.log if line.startswith("blocks of ")]
    assert len(blocks) == 1 and "--repeat-window off keeps" in blocks[0], capped.log
    bank = surftile.bake(
        str(tmp_path / "wall4.npy"), method="rsgf", stochastic=True, repeat_window="off"
    )
    advice = [line for line in bank.log if line.startswith("self-repetition within 1024²")]
    assert len(advice) == 1 and "--repeat-window auto (1024) caps them at" in advice[0], bank.log
    cap = int(advice[0].split("caps them at ")[1].split(" px")[0])
    assert blocks[0].startswith(f"blocks of {cap} px"), (blocks, advice)
    photo = surftile.bake(str(wall), method="rsgf", stochastic=True)
    assert not any(line.startswith("self-repetition within") for line in photo.log), photo.log


def test_info_equals_the_cli(cli, banks):
    for spec in (banks["roller"], banks["milling"], "rock", "parallel-d4-ae05"):
        assert surftile.open(spec).info == json.loads(cli("info", "--json", spec)), spec
    src = surftile.open(banks["rpn"])
    assert src.kind == src.info["kind"]
    assert surftile.open("parallel-d4-ae05").surface().height_unit == "um"


def test_stats_equal_the_cli(cli, exemplar, banks, tmp_path):
    path, data = exemplar
    out = tmp_path / "synth.npy"
    cli("render", banks["synth"], "--w", 160, "--h", 160, "--out", out)
    expected = json.loads(cli("stats", path, out))
    assert surftile.stats(path, out) == expected
    from_arrays = surftile.stats(data, np.load(out))
    for key in ("w1", "psd_error", "structure"):
        assert expected[key] is not None
        assert from_arrays[key] == expected[key], key
    quick = surftile.stats(path, out, structure=False, cell=32)
    assert quick.get("structure") is None and quick["cell"] == 32


def test_bad_input_raises_the_named_exceptions(banks, tmp_path):
    surface = surftile.open(banks["rpn"]).surface()
    with pytest.raises(ValueError, match=r"invalid width = -3: expected a positive number of samples"):
        surface.fill(0.0, 0.0, -3, 4)
    with pytest.raises(ValueError, match=r"invalid out = a non-contiguous array"):
        surface.fill(0.0, 0.0, 4, 4, out=np.zeros((4, 8), np.float32)[:, ::2])
    with pytest.raises(ValueError, match=r"invalid out = an array of dtype float64"):
        surface.fill(0.0, 0.0, 4, 4, out=np.zeros((4, 4)))
    with pytest.raises(ValueError, match=r"invalid out = an array of shape \[4, 5\]"):
        surface.fill(0.0, 0.0, 4, 4, out=np.zeros((4, 5), np.float32))
    with pytest.raises(ValueError, match=r"invalid out = a read-only array"):
        ro = np.zeros((4, 4), np.float32)
        ro.flags.writeable = False
        surface.fill(0.0, 0.0, 4, 4, out=ro)
    with pytest.raises(ValueError, match=r"invalid out = a list"):
        surface.fill(0.0, 0.0, 4, 4, out=[0.0] * 16)
    with pytest.raises(ValueError, match=r"invalid region = from \(NaN"):
        surface.fill(float("nan"), 0.0, 4, 4)
    with pytest.raises(ValueError, match=r"invalid step = 0"):
        surface.fill(0.0, 0.0, 4, 4, step=0.0)
    with pytest.raises(ValueError, match=r"too large: .*over the limit"):
        surface.fill(0.0, 0.0, 1 << 20, 1 << 20)
    with pytest.raises(FileNotFoundError, match=r"no such file"):
        surftile.open(tmp_path / "missing.bank")
    with pytest.raises(FileNotFoundError, match=r"missing\.bank: no such file"):
        surftile.open("missing.bank")
    with pytest.raises(IsADirectoryError):  # an OSError: a folder is no bank
        surftile.open(tmp_path)
    with pytest.raises(FileNotFoundError, match=r"no-folder"):
        surftile.bake(np.random.default_rng(0).normal(size=(64, 64)), method="rpn").save(
            tmp_path / "no-folder" / "b.bank"
        )
    assert not (tmp_path / "no-folder").exists()
    with pytest.raises(ValueError, match=r"invalid source = no-such-preset"):
        surftile.open("no-such-preset")
    corrupt = tmp_path / "corrupt.bank"
    data = bytearray(banks["rpn"].read_bytes())
    data[len(data) // 2] ^= 0xFF
    corrupt.write_bytes(bytes(data))
    with pytest.raises(surftile.BankError, match=r"^bank .*corrupt\.bank"):
        surftile.open(corrupt)
    assert issubclass(surftile.BankError, ValueError)
    with pytest.raises(ValueError, match=r"invalid seed = -1"):
        surftile.open("rock").surface(seed=-1)
    with pytest.raises(ValueError, match=r"NaN"):
        nan = np.ones((64, 64), np.float32)
        nan[3, 4] = np.nan
        surftile.bake(nan, method="rpn")
    with pytest.raises(ValueError, match=r"invalid exemplar = an array of shape \[4, 4, 4, 4\]"):
        surftile.bake(np.zeros((4, 4, 4, 4)), method="rpn")
    with pytest.raises(ValueError, match=r"invalid exemplar = an empty array of shape \[0, 5\]"):
        surftile.bake(np.zeros((0, 5)), method="rpn")
    with pytest.raises(ValueError, match=r"too large: exemplar: an array of 1×40000000 pixels"):
        surftile.bake(np.broadcast_to(np.float32(0), (1, 40_000_000)), method="rpn")
    with pytest.raises(ValueError, match=r"invalid exemplar = an array of dtype complex128"):
        surftile.bake(np.zeros((64, 64), complex), method="rpn")
    with pytest.raises(ValueError, match=r"invalid keyword = blok: expected one of"):
        surftile.bake(np.zeros((64, 64)), method="rsgf", blok=3)
    with pytest.raises(ValueError, match=r"invalid method = \"gauss\""):
        surftile.bake(np.zeros((64, 64)), method="gauss")
    with pytest.raises(ValueError, match=r"invalid bank_size = -2"):
        surftile.bake(np.zeros((64, 64)), method="rpn", bank_size=-2)
    with pytest.raises(ValueError, match=r"invalid level = \"flat\""):
        surftile.stats(np.zeros((8, 8)), np.zeros((8, 8)), level="flat")
    with pytest.raises(ValueError, match=r"invalid age"):
        surftile.open("rock", age=2.0)


def _longest_pause_of_python_while(work):
    """Runs `work` in a thread and returns the longest gap (s) between two steps of a
    Python loop on this thread meanwhile, and how long the work took: a call that kept
    the GIL would stop the loop for all of its duration."""
    import threading
    import time

    done = []
    t = threading.Thread(target=lambda: done.append(work()))
    start = time.perf_counter()
    t.start()
    last, gap = time.perf_counter(), 0.0
    while t.is_alive():
        time.sleep(0.001)  # needs the GIL back to return
        now = time.perf_counter()
        gap, last = max(gap, now - last), now
    t.join()
    assert done, "the work failed"
    return gap, time.perf_counter() - start


def test_long_calls_release_the_gil():
    surface = surftile.open("rock").surface(seed=1)
    rng = np.random.default_rng(1)
    xs, ys = rng.uniform(-1e6, 1e6, (2, 100_000))
    afm = np.load(REPO / "tiles" / "di-6.npy")[:256, :256].copy()
    for name, work in [
        ("fill", lambda: surface.fill(0.0, 0.0, 4096, 4096)),
        ("height", lambda: surface.height(xs, ys)),
        ("bake", lambda: surftile.bake(afm, method="synth")),
        ("stats", lambda: surftile.stats(afm, afm)),
    ]:
        # A short switch interval, so that a released GIL comes back within about a
        # millisecond and the calls can be short on a fast machine.
        interval = sys.getswitchinterval()
        sys.setswitchinterval(0.0005)
        try:
            gap, took = _longest_pause_of_python_while(work)
        finally:
            sys.setswitchinterval(interval)
        assert took > 0.02, f"{name} took {took:.3f} s: too short to tell"
        assert gap < took / 3, f"{name}: Python stopped for {gap:.3f} s of {took:.3f} s"
        print(f"{name}: {took:.3f} s, longest pause {gap:.4f} s")
