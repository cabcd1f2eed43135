"""penumbra: sunlight and earthlight at the lunar poles (Python bindings of the Rust library).

Every number comes from the Rust library, the same code as the ``penumbra`` command line:
SPICE-exact ephemerides (the shipped kernels by default; ``kernels=`` takes a kernel folder or a
SPICE meta-kernel ``.tm``), LOLA terrain with near and far-field
layers, horizons, per-site series and statistics, whole-grid map statistics.

>>> import penumbra
>>> t = penumbra.Terrain.synthetic(size_px=200)
>>> times = penumbra.time_range("2027-01-01", "2027-01-31", "1h")
>>> table, stats = penumbra.series(t, [("a", -89.7, 0.0, 2.0)], times)

Units are in every name (``_deg``, ``_m``, ``_km``, ``_w_m2``); times are UTC, given as ISO
strings, lists of them, or numpy ``datetime64`` arrays (``time_range`` builds one); azimuths are
from local north, clockwise; elevations above the plane normal to the radial direction; a site's
or an observer's height (``height_above_ground_m``, ``observer_height_m``) is above the ground,
ground and terrain heights (``ground_height_m``, ``Terrain.heights_m``) above the 1737.4 km
sphere. The names are the command line's (``--observer-height-m`` → ``observer_height_m``,
``--width-px`` → ``width_px``); older names stay accepted. Bad arguments raise ``PenumbraError`` (a ``ValueError``) with the
command line's one-line message. Long calls release the GIL, accept a ``progress(done, total)``
callback where noted and stop on Ctrl-C between chunks of work.
"""

from __future__ import annotations

from typing import Any, Dict

from ._penumbra import (
    PenumbraError,
    Terrain,
    __version__,
    ephem,
    horizon,
    landing_windows,
    map_light,
    map_shard,
    map_statistics,
    merge_shards,
    render,
    run_scenario,
    series,
    station_elevations,
    time_range,
    write_geotiff,
)

__all__ = [
    "PenumbraError",
    "Terrain",
    "__version__",
    "ephem",
    "horizon",
    "landing_windows",
    "map_light",
    "map_shard",
    "map_statistics",
    "merge_shards",
    "render",
    "run_scenario",
    "series",
    "station_elevations",
    "time_range",
    "to_pandas",
    "write_geotiff",
]


def to_pandas(table: Dict[str, Any]) -> Any:
    """A ``pandas.DataFrame`` of a ``series`` table (needs pandas: ``pip install pandas``)."""
    try:
        import pandas as pd
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("to_pandas needs pandas: pip install pandas") from e
    return pd.DataFrame(table)
