"""surftile.read (issue 36): instrument files read to the heights SurfaceTopography
gives (the expected .npy files beside the crops in tests/data/instruments, cut from its
conversion), with spacing, unit and missing points; form removal by name in stats."""

from pathlib import Path

import numpy as np
import pytest

import surftile

DATA = Path(__file__).resolve().parents[2] / "tests" / "data" / "instruments"


@pytest.mark.parametrize(
    "name, dx, unit, missing",
    [
        ("al3d-1-crop.al3d", 0.438027, "m", 0),
        ("plu-1-crop.plu", 1.6600000858306885, "µm", 0),
        ("sur-2-crop.sur", 3.4840002190321684, "mm", 39),
        ("opd-1-crop.opd", 0.19673303177114576, "nm", 95),
        ("di-6-crop.di", 0.01953125, "nm", 0),
        ("metropro-1-crop.dat", 1.0982520279867458, "m", 0),
    ],
)
def test_instrument_crops_read_to_the_reference(name, dx, unit, missing):
    got = surftile.read(DATA / name)
    want = np.load(DATA / (name.rsplit(".", 1)[0] + ".npy"))
    assert got["heights"].dtype == np.float32
    assert got["heights"].shape == want.shape
    assert np.array_equal(np.isnan(got["heights"]), np.isnan(want))
    scale = np.nanmax(np.abs(want))
    assert np.nanmax(np.abs(got["heights"] - want)) <= 1e-5 * scale
    assert got["spacing_um"] == pytest.approx((dx, dx), rel=1e-9)
    assert got["unit_in_file"] == unit
    assert got["missing"] == missing


def test_read_refuses_a_truncated_file_in_one_line(tmp_path):
    data = (DATA / "plu-1-crop.plu").read_bytes()
    cut = tmp_path / "cut.plu"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(Exception) as e:
        surftile.read(cut)
    message = str(e.value)
    assert "cut.plu" in message and "truncated" in message and "\n" not in message


def test_stats_takes_polynomial_form_removal():
    a = surftile.read(DATA / "plu-1-crop.plu")["heights"]
    y, x = np.mgrid[0 : a.shape[0], 0 : a.shape[1]]
    bowl = a + 1e-3 * ((x - 60.0) ** 2 + (y - 50.0) ** 2)
    plane = surftile.stats(a, bowl, level="plane", structure=False)
    poly2 = surftile.stats(a, bowl, level="poly:2", structure=False)
    # poly:2 removes the added bowl (and A's own quadratic form alike); a plane cannot.
    assert poly2["b"]["sq"] < plane["b"]["sq"]
    with pytest.raises(ValueError):
        surftile.stats(a, bowl, level="poly:99")
