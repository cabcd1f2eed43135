"""The GeoTIFFs penumbra writes, opened as GIS users open them (rasterio, issue 18): COG layout,
band description and unit, nodata, overviews, the run's parameters as tags, and the same pixels
as penumbra's own arrays."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import penumbra

from conftest import run_cli

rasterio = pytest.importorskip("rasterio")


def test_map_geotiffs_open_in_rasterio_with_their_metadata(cli: Path, tmp_path: Path) -> None:
    run_cli(cli, tmp_path, "dem", "synth", "--size", "300", "--px-m", "100", "--seed", "4",
            "--out", "d.tif")
    run_cli(cli, tmp_path, "map", "--dem", "d.tif", "--start", "2027-02-01", "--stop",
            "2027-02-03", "--step", "6h", "--engine", "horizons", "--azimuths", "90",
            "--out-dir", "m")
    run_cli(cli, tmp_path, "map", "--dem", "d.tif", "--utc", "2027-02-05T00:00",
            "--out-fraction", "f.tif")
    t = penumbra.Terrain.open([tmp_path / "d.tif"])
    m = penumbra.map_statistics(
        t, penumbra.time_range("2027-02-01", "2027-02-03", "6h"), engine="horizons", azimuths=90
    )
    with rasterio.open(tmp_path / "m" / "sun_illumination_pct.tif") as ds:
        assert ds.profile["tiled"] and ds.profile["blockxsize"] == 256
        assert ds.compression.name.lower() == "deflate"
        assert ds.overviews(1) == [2]
        assert ds.descriptions[0].startswith("average Sun illumination")
        assert ds.units[0] == "%"
        assert np.isnan(ds.nodata)
        tags = ds.tags()
        assert tags["epochs"] == "9" and tags["span_utc"].endswith("9 epochs")
        assert tags["software"].startswith("penumbra")
        a = ds.read(1)
        np.testing.assert_array_equal(a, m["sun_illumination_pct"])
        # The overview is the 2 x 2 mean of the valid pixels.
        ovr = ds.read(1, out_shape=(150, 150))
        full = m["sun_illumination_pct"].astype(np.float64)
        want = np.nanmean(full.reshape(150, 2, 150, 2), axis=(1, 3))
        np.testing.assert_allclose(ovr, want, rtol=1e-6, atol=1e-4)
        assert ds.crs is not None and "Stereographic" in ds.crs.to_wkt()
    with rasterio.open(tmp_path / "m" / "longest_dark_h.tif") as ds:
        assert ds.units[0] == "h"
    with rasterio.open(tmp_path / "m" / "psr_mask.tif") as ds:
        assert ds.nodata == 255 and ds.dtypes[0] == "uint8"
        assert set(np.unique(ds.read(1, out_shape=(150, 150)))) <= {0, 1, 255}
    with rasterio.open(tmp_path / "f.tif") as ds:
        tags = ds.tags()
        assert tags["epoch_utc"] == "2027-02-05T00:00:00Z"
        assert float(tags["observer_height_m"]) == 2.0
        assert -5.0 < float(tags["sun_el_deg_at_map_centre"]) < 5.0
        assert tags["engine"] == "combined"
