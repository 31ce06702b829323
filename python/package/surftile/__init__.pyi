"""Type stubs of surftile (the native module surftile._surftile, re-exported)."""

import os
from typing import Any, Dict, List, Optional, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str

PathLike = Union[str, "os.PathLike[str]"]
ArrayLike = npt.ArrayLike

class BankError(ValueError):
    """A bank file that fails validation (magic, version, sizes, checksum, values)."""

class Surface:
    """An endless, deterministic surface. Coordinates are in surface pixels; heights in
    `height_unit` ("um", or "" where unknown)."""

    @property
    def channels(self) -> int:
        """Values per sample: 1 for heights, 3 for RGB."""
    @property
    def spacing_um(self) -> Optional[float]:
        """Pixel spacing in µm, or None where the source has none."""
    @property
    def height_unit(self) -> str:
        """Unit of the heights: "um", or "" where unknown (pixels, grey levels)."""
    @property
    def seed(self) -> int:
        """The placement seed."""
    @property
    def has_layer(self) -> bool:
        """Whether an imperfection layer lies over the surface."""
    @property
    def has_defects(self) -> bool:
        """Whether defects lie in the surface."""
    @overload
    def height(self, x: float, y: float) -> float: ...
    @overload
    def height(self, x: ArrayLike, y: ArrayLike) -> npt.NDArray[np.float32]: ...
    def height(self, x: Any, y: Any) -> Any:
        """Channel 0 at (x, y) px. Scalars give a float; arrays of broadcastable shapes
        give a float32 array of the broadcast shape. NaN coordinates give NaN."""
    def fill(
        self,
        x: float,
        y: float,
        width: int,
        height: int,
        *,
        step: float = 1.0,
        out: Optional[npt.NDArray[np.float32]] = None,
    ) -> npt.NDArray[np.float32]:
        """`width × height` samples from (x, y) px, `step` px apart: shape (height,
        width) or (height, width, channels). With `out` (C-contiguous float32 of that
        shape) writes into it and returns it."""
    def fill_with_mask(
        self,
        x: float,
        y: float,
        width: int,
        height: int,
        *,
        step: float = 1.0,
    ) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8]]:
        """Heights and the mask id of every sample (uint8, 0 clean): the imperfection
        layer's ids, the defects' (scratch 16, dent 17, pits 18) where they are set."""

class Source:
    """What `open` returns: a loaded source, placed with a seed by `surface`."""

    @property
    def info(self) -> Dict[str, Any]:
        """What `surftile info --json` prints for this source."""
    @property
    def kind(self) -> str:
        """The registry's kind: blend, toroidal, wang, rsgf, synth, quilting, milling or models."""
    @property
    def spacing_um(self) -> Optional[float]:
        """Pixel spacing in µm, or None."""
    @property
    def height_unit(self) -> str:
        """Unit of the heights: "um", or ""."""
    def surface(self, seed: int = 0) -> Surface:
        """The endless surface placed with `seed` (0 to 2^32 − 1)."""

class Bank:
    """A bank made by `bake`."""

    @property
    def info(self) -> Dict[str, Any]:
        """What `surftile info --json` prints for the saved file (without its size)."""
    @property
    def log(self) -> List[str]:
        """The bake's progress lines (for method="auto", what it picked and why)."""
    def save(self, path: PathLike) -> None:
        """Writes the bank file atomically (a temporary name, then renamed)."""
    def surface(self, seed: int = 0) -> Surface:
        """The bank's endless surface placed with `seed`."""

def open(
    spec: PathLike,
    *,
    spacing_um: Optional[float] = None,
    imperfect: Optional[PathLike] = None,
    age: Optional[float] = None,
    defects: Optional[PathLike] = None,
) -> Source:
    """Opens a bank file, a milling or model `.toml`, or a preset name; `spacing_um`
    (µm per pixel) for milling, `imperfect` (a `.toml` or dust, patina, peeling) and its
    `age`, `defects` (a `.toml` or scratches, dents, pits) under the layer."""

def bake(
    exemplar: Union[PathLike, ArrayLike],
    *,
    method: str = "auto",
    spacing_um: Optional[float] = None,
    seed: int = 0,
    **params: Any,
) -> Bank:
    """Analyses an exemplar (a path, or a (rows, cols[, channels]) array of floats or
    integers) into a bank. `params` are the CLI's `bake` flags with underscores."""

def read(path: PathLike) -> Dict[str, Any]:
    """Reads a height file (instrument formats: X3P, AL3D, PLU, SUR, OPD, Nanoscope,
    MetroPro, SDF; and npy, TIFF, PNG): {"heights": float32 (rows, cols) in µm with NaN
    where missing, "spacing_um": (x, y) or None, "unit_in_file": str or None,
    "missing": int}."""

def stats(
    a: Union[PathLike, ArrayLike],
    b: Union[PathLike, ArrayLike],
    *,
    cell: Optional[int] = None,
    level: str = "plane",
    fill_missing: bool = False,
    structure: bool = True,
) -> Dict[str, Any]:
    """The figures of `surftile stats` of `b` (a synthesis) against `a` (an exemplar)."""
