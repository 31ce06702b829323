"""X3P files written by surftile open in an independent reader (issue 36):
SurfaceTopography (ContactEngineering, its own ISO 25178-72 reader) reads the CLI's
X3P output to the same heights, grid and physical size as the CLI's .npy output of the
same region. Skipped where SurfaceTopography is not installed, except with
SURFTILE_REQUIRE_SURFACETOPOGRAPHY=1 (as in CI), where it fails."""

import os

import numpy as np
import pytest


def _surfacetopography():
    if os.environ.get("SURFTILE_REQUIRE_SURFACETOPOGRAPHY") == "1":
        import SurfaceTopography  # noqa: F401  (fails where CI promised it)
    return pytest.importorskip("SurfaceTopography")


def test_surftile_x3p_opens_in_surfacetopography(cli, tmp_path):
    st = _surfacetopography()
    region = ["parallel-d4-ae05", "--w", "96", "--h", "40", "--x", "-7", "--spacing", "2.5"]
    cli("render", *region, "--out", str(tmp_path / "h.x3p"))
    cli("render", *region, "--out", str(tmp_path / "h.npy"))
    topo = st.open_topography(str(tmp_path / "h.x3p")).topography()
    assert topo.unit == "m"
    assert tuple(topo.nb_grid_pts) == (96, 40)
    np.testing.assert_allclose(topo.physical_sizes, (96 * 2.5e-6, 40 * 2.5e-6), rtol=1e-12)
    heights_um = np.asarray(topo.heights()).T * 1e6  # [x, y] to rows = y
    want = np.load(tmp_path / "h.npy")
    assert heights_um.shape == want.shape
    # The file holds float64 metres converted from float32 µm: equal to f32 rounding.
    np.testing.assert_array_equal(heights_um.astype(np.float32), want)


def test_converted_instrument_file_opens_in_surfacetopography(cli, tmp_path):
    """An instrument file (a Sensofar PLU crop) converted to X3P keeps its non-trivial
    spacing through SurfaceTopography's reader."""
    st = _surfacetopography()
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    plu = os.path.join(repo, "tests", "data", "instruments", "plu-1-crop.plu")
    cli("convert", plu, str(tmp_path / "p.x3p"))
    topo = st.open_topography(str(tmp_path / "p.x3p")).topography()
    dx = 1.6600000858306885e-6
    np.testing.assert_allclose(topo.physical_sizes, (128 * dx, 120 * dx), rtol=1e-12)
    want = np.load(os.path.join(repo, "tests", "data", "instruments", "plu-1-crop.npy"))
    np.testing.assert_allclose(np.asarray(topo.heights()).T * 1e6, want, rtol=1e-6)
