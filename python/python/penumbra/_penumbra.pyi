"""Type stubs of penumbra's Rust extension module (see ``penumbra/__init__.py``)."""

from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

Times = Union[str, Sequence[Any], npt.NDArray[np.datetime64]]
Path = Union[str, PathLike[str]]
GeoTransform = Tuple[float, float, float, float, float, float]
Progress = Callable[[int, int], Any]

class PenumbraError(ValueError):
    """A bad argument or input: the message is the command line's one error line."""

class Terrain:
    """DEM layers (the finest with data wins at each point) or the synthetic DEM."""

    @staticmethod
    def open(paths: Sequence[Path]) -> Terrain: ...
    @staticmethod
    def synthetic(size_px: int = 400, px_m: float = 100.0, seed: int = 1, far_field: bool = False) -> Terrain: ...
    @property
    def layers(self) -> List[str]: ...
    @property
    def shape(self) -> Tuple[int, int]: ...
    @property
    def transform(self) -> GeoTransform: ...
    @property
    def crs_wkt(self) -> str: ...
    @property
    def crs_proj(self) -> str: ...
    def heights_m(self) -> npt.NDArray[np.float32]: ...
    def height_m(self, lat_deg: Any, lon_deg: Any) -> Any: ...

def time_range(start: str, stop: str, step: str) -> npt.NDArray[np.datetime64]: ...
def ephem(
    sites: Sequence[Tuple[float, float, float]],
    times: Times,
    kernels: Optional[Path] = None,
    abcorr: str = "lt+s",
) -> Dict[str, npt.NDArray[Any]]: ...
def station_elevations(
    site: Tuple[float, float, float],
    times: Times,
    stations: str = "dsn",
    station_mask_deg: float = 10.0,
    kernels: Optional[Path] = None,
) -> Dict[str, npt.NDArray[Any]]: ...
def horizon(
    terrain: Terrain,
    lat_deg: float,
    lon_deg: float,
    observer_height_m: float = 2.0,
    az_step_deg: float = 0.25,
    method: str = "fast",
) -> Dict[str, Any]: ...
def series(
    terrain: Terrain,
    sites: Sequence[Union[Tuple[str, float, float], Tuple[str, float, float, float]]],
    times: Times,
    kernels: Optional[Path] = None,
    abcorr: str = "lt+s",
    limb_darkening: str = "eddington",
    disc_method: str = "exact",
    az_step_deg: float = 0.25,
    horizon_method: str = "fast",
    stations: str = "dsn",
    station_mask_deg: float = 10.0,
    relays: Sequence[str] = (),
    relay_spks: Sequence[Path] = (),
    relay_max_range_km: Optional[float] = None,
    panel: Optional[str] = None,
    panel_area_m2: Optional[float] = None,
    panel_efficiency: Optional[float] = None,
    panel_degradation_pct_per_year: Optional[float] = None,
    load_w: Optional[float] = None,
    night_load_w: Optional[float] = None,
    battery_wh: Optional[float] = None,
    battery_start_pct: Optional[float] = None,
    load_profile: Optional[Path] = None,
    neighbourhood_m: Optional[float] = None,
    out_dir: Optional[Path] = None,
    progress: Optional[Progress] = None,
) -> Tuple[Dict[str, npt.NDArray[Any]], Dict[str, Any]]: ...
def landing_windows(
    table: Dict[str, npt.NDArray[Any]],
    profile: Optional[str] = None,
    stay_h: Optional[float] = None,
    min_sun_fraction: Optional[float] = None,
    min_lit_pct: Optional[float] = None,
    max_dark_h: Optional[float] = None,
    min_dte_pct: Optional[float] = None,
    max_blackout_h: Optional[float] = None,
    min_touchdown_sun_el_deg: Optional[float] = None,
    max_touchdown_sun_el_deg: Optional[float] = None,
) -> List[Dict[str, Any]]: ...
def map_statistics(
    terrain: Terrain,
    times: Times,
    engine: str = "auto",
    observer_height_m: float = 2.0,
    kernels: Optional[Path] = None,
    abcorr: str = "lt+s",
    horizons: Optional[Path] = None,
    azimuths: int = 720,
    max_step: int = 16,
    limb_darkening: str = "eddington",
    stations: str = "none",
    station_mask_deg: float = 10.0,
    panel: Optional[str] = None,
    panel_area_m2: Optional[float] = None,
    panel_efficiency: Optional[float] = None,
    panel_degradation_pct_per_year: Optional[float] = None,
    load_w: Optional[float] = None,
    night_load_w: Optional[float] = None,
    load_profile: Optional[Path] = None,
    progress: Optional[Progress] = None,
) -> Dict[str, Any]: ...
def map_light(
    terrain: Terrain,
    utc: Optional[str] = None,
    sun_az_deg: Optional[float] = None,
    sun_el_deg: Optional[float] = None,
    sun_radius_deg: float = 0.2666,
    engine: str = "auto",
    observer_height_m: float = 2.0,
    kernels: Optional[Path] = None,
    abcorr: str = "lt+s",
) -> Dict[str, Any]: ...
def map_shard(
    terrain: Terrain,
    start: str,
    stop: str,
    step: str,
    out_dir: Path,
    shard: int,
    shards: int,
    observer_height_m: float = 2.0,
    kernels: Optional[Path] = None,
    abcorr: str = "lt+s",
    horizons: Optional[Path] = None,
    azimuths: int = 720,
    max_step: int = 16,
    limb_darkening: str = "eddington",
    stations: str = "none",
    station_mask_deg: float = 10.0,
    resume: bool = False,
) -> Dict[str, Any]: ...
def merge_shards(out_dir: Path, shard_dirs: Sequence[Path]) -> None: ...
def write_geotiff(
    path: Path,
    array: npt.NDArray[Any],
    terrain: Terrain,
    description: str,
    unit: str = "",
    metadata: Optional[Dict[str, str]] = None,
) -> None: ...
def render(
    terrain: Terrain,
    utc: str,
    lat_deg: float,
    lon_deg: float,
    camera: str = "site",
    height_m: float = 2.0,
    look_az_deg: float = 0.0,
    look_el_deg: float = 0.0,
    altitude_km: Optional[float] = None,
    target_lat_deg: Optional[float] = None,
    target_lon_deg: Optional[float] = None,
    fov_deg: float = 60.0,
    width: int = 640,
    height: int = 400,
    brdf: str = "hapke",
    exposure: Union[float, str, None] = None,
    kernels: Optional[Path] = None,
    abcorr: str = "lt+s",
    backend: str = "auto",
    observer_height_m: Optional[float] = None,
    width_px: Optional[int] = None,
    height_px: Optional[int] = None,
    annotate: bool = True,
) -> Tuple[npt.NDArray[np.uint8], npt.NDArray[np.float32]]: ...
def run_scenario(
    path: Path,
    out_dir: Optional[Path] = None,
    kernels: Optional[Path] = None,
    resume: bool = False,
) -> None: ...
