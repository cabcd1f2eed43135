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
        # How the map was made, in the file itself (the DEM's sha256 by hashlib).
        import hashlib
        sha = hashlib.sha256((tmp_path / "d.tif").read_bytes()).hexdigest()
        assert float(tags["observer_height_m"]) == 2.0 and tags["engine"] == "horizons"
        assert tags["limb_darkening"] == "eddington"
        assert tags["dem_layers"] == f"d.tif (sha256:{sha[:12]})"
        assert "sha256:" in tags["kernels"] and ".bsp" in tags["kernels"]
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


def _haversine_m(lat1, lon1, lat2, lon2) -> np.ndarray:
    """Great-circle distance on the 1737.4 km sphere (numpy, not penumbra)."""
    p1, p2 = np.radians(lat1), np.radians(lat2)
    dl = np.radians(np.asarray(lon2) - lon1)
    h = np.sin((p2 - p1) / 2) ** 2 + np.cos(p1) * np.cos(p2) * np.sin(dl / 2) ** 2
    return 2 * 1737400.0 * np.arcsin(np.sqrt(h))


def test_neighbourhood_is_every_pixel_centre_within_the_radius_and_equals_series_there(
    cli: Path, tmp_path: Path
) -> None:
    """The neighbourhood's pixels against PROJ (rasterio): the same set of pixel centres within
    the radius (numpy haversine), each value equal to `series` run at that pixel centre."""
    import csv
    import json

    from rasterio.crs import CRS
    from rasterio.warp import transform as warp

    from conftest import pixel_sites

    run_cli(cli, tmp_path, "dem", "synth", "--size", "200", "--px-m", "100", "--seed", "3",
            "--out", "d.tif")
    rng = ["--start", "2027-03-01", "--stop", "2027-03-31", "--step", "3h"]
    site_lat, site_lon = -89.62, 35.0
    run_cli(cli, tmp_path, "series", "--dem", "d.tif", "--site", f"s,{site_lat},{site_lon}",
            *rng, "--no-plots", "--neighbourhood-m", "260", "--out-dir", "n")
    rows = list(csv.DictReader(open(tmp_path / "n" / "s" / "neighbourhood.csv")))
    assert rows[0]["point"] == "site"
    pixels = rows[1:]
    moon = CRS.from_proj4("+proj=longlat +R=1737400 +no_defs")
    with rasterio.open(tmp_path / "d.tif") as ds:
        t, crs = ds.transform, ds.crs
        # Every pixel centre of the grid, to lat/lon by PROJ; those within 260 m of the site.
        r, c = np.mgrid[0:ds.height, 0:ds.width]
        xs = (t.c + t.a * (c + 0.5)).ravel()
        ys = (t.f + t.e * (r + 0.5)).ravel()
        lon, lat = (np.array(v) for v in warp(crs, moon, xs, ys))
    d = _haversine_m(site_lat, site_lon, lat, lon)
    inside = np.flatnonzero(d <= 260.0)
    assert len(pixels) == len(inside) >= 20
    want = sorted(zip(np.round(d[inside], 1), np.round(lat[inside], 6)))
    got = sorted((float(p["distance_m"]), float(p["lat_deg"])) for p in pixels)
    for (dw, lw), (dg, lg) in zip(want, got):
        assert abs(dw - dg) <= 0.11 and abs(lw - lg) <= 2e-6, ((dw, lw), (dg, lg))
    # Each pixel's value is series' value at that pixel centre (sites placed by PROJ).
    cells = [(int(i) // 200, int(i) % 200) for i in inside]
    run_cli(cli, tmp_path, "series", "--dem", "d.tif", *pixel_sites(t, crs, cells), *rng,
            "--no-plots", "--no-csv", "--neighbourhood-m", "0", "--out-dir", "px")
    stats = json.loads((tmp_path / "px" / "stats.json").read_text())["sites"]
    by_pos = {round(float(p["distance_m"]), 1): float(p["sun_visible_pct"]) for p in pixels}
    for s, i in zip(stats, inside):
        assert abs(by_pos[round(float(d[i]), 1)] - s["sun_visible_pct"]) <= 0.006, s["site"]


def test_geojson_sites_honour_their_crs_and_any_letter_case(cli: Path, tmp_path: Path) -> None:
    """A GeoJSON in lunar polar stereographic metres (IAU_2015:30135, coordinates from PROJ)
    with `Name`/`Height_M` gives the sites at their latitude and longitude; a CRS penumbra
    cannot read is refused in one line; sites.geojson gives them back in degrees."""
    import json
    import subprocess

    from rasterio.crs import CRS
    from rasterio.warp import transform as warp

    moon = CRS.from_proj4("+proj=longlat +R=1737400 +no_defs")
    stere = CRS.from_proj4("+proj=stere +lat_0=-90 +lon_0=0 +k=1 +x_0=0 +y_0=0 +R=1737400 +units=m +no_defs")
    lat, lon = [-89.6, -89.7], [20.0, 250.0]
    xs, ys = warp(moon, stere, lon, lat)
    doc = {
        "type": "FeatureCollection",
        "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:IAU_2015::30135"}},
        "features": [
            {"type": "Feature", "geometry": {"type": "Point", "coordinates": [x, y]},
             "properties": {"Name": f"site{i}", "Height_M": 5.0}}
            for i, (x, y) in enumerate(zip(xs, ys))
        ],
    }
    (tmp_path / "s.geojson").write_text(json.dumps(doc))
    run_cli(cli, tmp_path, "series", "--synthetic", "--sites", "s.geojson", "--utc",
            "2027-01-01T00:00", "--no-plots", "--out-dir", "o")
    stats = json.loads((tmp_path / "o" / "stats.json").read_text())["sites"]
    for s, la, lo in zip(stats, lat, lon):
        loc = s["location"]
        assert abs(loc["lat_deg"] - la) < 1e-6 and abs((loc["lon_deg"] - lo + 180) % 360 - 180) < 1e-6
        assert loc["height_above_ground_m"] == 5.0
    out = json.loads((tmp_path / "o" / "sites.geojson").read_text())
    assert out["type"] == "FeatureCollection" and len(out["features"]) == 2
    for f, s in zip(out["features"], stats):
        lo_out, la_out = f["geometry"]["coordinates"]
        assert abs(la_out - s["location"]["lat_deg"]) < 1e-9
        assert f["properties"]["sun_visible_pct"] == s["sun_visible_pct"]
    assert "<Placemark><name>site0</name>" in (tmp_path / "o" / "sites.kml").read_text()
    # A CRS it cannot read (Earth's web Mercator): one line, exit 2, nothing written.
    doc["crs"]["properties"]["name"] = "EPSG:3857"
    (tmp_path / "bad.geojson").write_text(json.dumps(doc))
    r = subprocess.run([str(cli), "series", "--synthetic", "--sites", "bad.geojson", "--utc",
                        "2027-01-01T00:00", "--out-dir", "bad"], cwd=tmp_path,
                       capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "EPSG:3857" in r.stderr and not (tmp_path / "bad").exists()
