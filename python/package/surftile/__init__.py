"""surftile: infinite, deterministic surfaces, queried by coordinate.

Open a bank, a milling or model ``.toml`` or a preset, place it with a seed, and read
any region or point as numpy arrays::

    import surftile
    surface = surftile.open("rock").surface(seed=3)
    heights = surface.fill(-1e9, 0.0, 512, 512)    # float32, (512, 512)
    h = surface.height(10.5, 20.25)                # a float

The same inputs and seed give the same bits as the ``surftile`` CLI and the Rust API, on
any thread count and however a region is split. Long calls release the GIL.

Training datasets (WebDataset shards of samples with defect masks, on this machine or a
Ray cluster) are in :mod:`surftile.dataset`.
"""

from . import dataset
from ._surftile import (
    Bank,
    BankError,
    Source,
    Surface,
    __version__,
    bake,
    open,
    read,
    stats,
)

__all__ = [
    "Bank",
    "BankError",
    "Source",
    "Surface",
    "__version__",
    "bake",
    "dataset",
    "open",
    "read",
    "stats",
]
