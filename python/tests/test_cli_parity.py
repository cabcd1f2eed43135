"""The module's numbers against the command line's files on the same inputs (the same Rust code
path: equal to the files' printed precision, GeoTIFFs byte for byte), and the ephemeris against
SPICE itself (spiceypy) when it is installed."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

import penumbra

from conftest import run_cli

SITES = [("ridge", -89.6, 0.0, 2.0), ("summit", -89.6, 20.0, 2.0), ("plateau", -89.5, 45.0, 10.0)]


def test_series_equals_the_cli(cli: Path, tmp_path: Path) -> None:
    args = ["--start", "2027-01-18", "--stop", "2027-01-22", "--step", "1h"]
    site_args = sum((["--site", f"{n},{la},{lo},{h}"] for n, la, lo, h in SITES), [])
    run_cli(cli, tmp_path, "series", "--synthetic", *site_args, *args, "--no-plots",
            "--neighbourhood-m", "0", "--out-dir", "s")
    table, stats = penumbra.series(
        penumbra.Terrain.synthetic(), SITES,
        penumbra.time_range("2027-01-18", "2027-01-22", "1h"),
    )
    # stats.json: the same statistics, to the same printed precision (JSON floats round-trip).
    cli_stats = json.loads((tmp_path / "s" / "stats.json").read_text())
    assert stats == cli_stats
    # series.csv: every column to the CSV's printed decimals.
    n = len(table["utc"]) // len(SITES)
    for i, (name, *_rest) in enumerate(SITES):
        rows = list(csv.DictReader(open(tmp_path / "s" / name / "series.csv")))
        assert len(rows) == n
        for col in rows[0]:
            if col == "utc":
                # The CSV writes ISO 8601 UTC with the zone (Z); the table holds datetime64 UTC.
                got = [str(t)[:19] + "Z" for t in table["utc"][i * n:(i + 1) * n]]
                assert got == [r["utc"] for r in rows]
                continue
            mine = table[col][i * n:(i + 1) * n]
            if col in ("station", "relay"):
                assert list(mine) == [r[col] for r in rows], col
                continue
            want = np.array([float(r[col]) for r in rows])
            # The CSV's printed decimals: 3 for irradiance, 4 for link elevations, else 6.
            tol = 5.01e-4 if "irradiance" in col else 5.01e-5 if col.endswith("_el_deg") and (
                col.startswith(("station", "relay"))) else 5.01e-7
            assert np.allclose(mine, want, rtol=0, atol=tol, equal_nan=True), col


def test_cli_scenario_and_python_write_the_same_files(cli: Path, tmp_path: Path) -> None:
    """One site and one set of options through the three doors (`penumbra series`, a scenario's
    `[series]`, `penumbra.series(out_dir=…)`), on the synthetic DEM with its far field: the same
    files, byte for byte, neighbourhood included (run.json differs by design: it records the
    command line)."""
    site = ("ridge", -89.6, 0.0, 2.0)
    run_cli(cli, tmp_path, "series", "--synthetic-far-field", "--site", ",".join(map(str, site)),
            "--start", "2027-01-18", "--stop", "2027-01-22", "--step", "1h", "--no-plots",
            "--neighbourhood-m", "250", "--out-dir", "cli")
    (tmp_path / "s.toml").write_text(f"""
name = "parity"
output_dir = "scn"
[time]
start = "2027-01-18T00:00:00"
stop = "2027-01-22T00:00:00"
step = "1h"
[terrain]
synthetic = {{ size_px = 400, px_m = 100.0, seed = 1, far_field = true }}
[series]
plots = false
neighbourhood_m = 250.0
[[sites]]
name = "{site[0]}"
lat_deg = {site[1]}
lon_deg = {site[2]}
height_above_ground_m = {site[3]}
""")
    run_cli(cli, tmp_path, "run", "s.toml")
    _, stats = penumbra.series(
        penumbra.Terrain.synthetic(far_field=True), [site],
        penumbra.time_range("2027-01-18", "2027-01-22", "1h"),
        neighbourhood_m=250.0, out_dir=tmp_path / "py",
    )
    files = ["stats.json", "series_long.csv", "ridge/series.csv", "ridge/horizon.csv",
             "ridge/stats.json", "ridge/neighbourhood.csv", "ridge/dte_windows.csv"]
    for f in files:
        want = (tmp_path / "cli" / f).read_bytes()
        assert (tmp_path / "scn" / f).read_bytes() == want, f"scenario {f}"
        assert (tmp_path / "py" / f).read_bytes() == want, f"python {f}"
    hood = stats["sites"][0]["neighbourhood"]
    assert hood["radius_m"] == 250.0 and hood["pixels"] >= 15
    # The neighbourhood's rows are pixel centres within the radius, the site first.
    rows = list(csv.DictReader(open(tmp_path / "py" / "ridge" / "neighbourhood.csv")))
    assert rows[0]["point"] == "site" and len(rows) == hood["pixels"] + 1
    assert all(0 < float(r["distance_m"]) <= 250.0 for r in rows[1:])
    assert hood["sun_visible_pct"]["min"] <= hood["sun_visible_pct"]["here"] <= hood["sun_visible_pct"]["max"]


def test_map_statistics_equal_the_cli_geotiffs_byte_for_byte(cli: Path, tmp_path: Path) -> None:
    rng = ["--start", "2027-02-01", "--stop", "2027-02-11", "--step", "6h"]
    run_cli(cli, tmp_path, "dem", "synth", "--size", "120", "--px-m", "150", "--seed", "4",
            "--out", "d.tif")
    run_cli(cli, tmp_path, "map", "--dem", "d.tif", "--engine", "horizons", "--azimuths", "90",
            "--max-step", "6", *rng, "--backend", "cpu", "--out-dir", "m")
    t = penumbra.Terrain.open([tmp_path / "d.tif"])
    m = penumbra.map_statistics(
        t, penumbra.time_range("2027-02-01", "2027-02-11", "6h"), engine="horizons",
        azimuths=90, max_step=6,
    )
    names = [k for k, v in m.items() if isinstance(v, np.ndarray)]
    assert "sun_illumination_pct" in names and "psr_mask" in names and len(names) == 10
    for name in names:
        assert m[name].shape == t.shape
        assert m[name].dtype == (np.uint8 if name == "psr_mask" else np.float32)
        out = tmp_path / f"py_{name}.tif"
        penumbra.write_geotiff(out, m[name], t, m["descriptions"][name], m["units"][name],
                               m["metadata"])
        assert out.read_bytes() == (tmp_path / "m" / f"{name}.tif").read_bytes(), name
    assert m["transform"] == t.transform


def test_ephem_equals_the_cli(cli: Path, tmp_path: Path) -> None:
    r = run_cli(cli, tmp_path, "ephem", "--lat-deg", "-89.45", "--lon-deg", "-137.3",
                "--height-m", "1957", "--start", "2027-03-01", "--stop", "2027-03-03",
                "--step", "3h", "--out", "e.csv")
    rows = list(csv.DictReader(open(tmp_path / "e.csv")))
    e = penumbra.ephem([(-89.45, -137.3, 1957.0)], penumbra.time_range("2027-03-01", "2027-03-03", "3h"))
    for col in ("sun_az_deg", "sun_el_deg", "earth_az_deg", "earth_el_deg", "sun_range_km"):
        want = np.array([float(x[col]) for x in rows])
        decimals = len(rows[0][col].split(".")[1]) if "." in rows[0][col] else 0
        assert np.allclose(e[col][0], want, rtol=0, atol=0.51 * 10.0 ** -decimals), col
    assert r.returncode == 0


def test_ephem_agrees_with_spice(root: Path) -> None:
    spice = pytest.importorskip("spiceypy")
    k = root / "kernels"
    spice.kclear()
    for f in sorted(k.iterdir()):
        if f.suffix in (".tls", ".bsp", ".bpc", ".tf"):
            spice.furnsh(str(f))
    lat, lon, h = -89.45, -137.3, 1957.0
    times = penumbra.time_range("2026-06-01", "2026-06-03", "4h")
    e = penumbra.ephem([(lat, lon, h)], times)
    r = (1737.4 + h / 1000.0)
    cl, sl = math.cos(math.radians(lat)), math.sin(math.radians(lat))
    co, so = math.cos(math.radians(lon)), math.sin(math.radians(lon))
    up = np.array([cl * co, cl * so, sl])
    east = np.array([-so, co, 0.0])
    north = np.cross(up, east)
    worst = 0.0
    try:
        for j, t in enumerate(times):
            et = spice.str2et(str(t)[:19].replace("T", " ") + " UTC")
            for body, prefix in (("SUN", "sun"), ("EARTH", "earth")):
                pos, _ = spice.spkcpo(body, et, "MOON_ME", "OBSERVER", "LT+S", r * up, "MOON", "MOON_ME")
                pos = np.array(pos)[:3]
                el = math.degrees(math.atan2(pos @ up, math.hypot(pos @ east, pos @ north)))
                az = math.degrees(math.atan2(pos @ east, pos @ north)) % 360.0
                d_az = (e[f"{prefix}_az_deg"][0, j] - az + 180.0) % 360.0 - 180.0
                worst = max(worst, abs(e[f"{prefix}_el_deg"][0, j] - el),
                            abs(d_az) * math.cos(math.radians(el)))
    finally:
        spice.kclear()
    # The Rust side agrees with SPICE to < 0.01 arcsec (docs/VALIDATION.md).
    assert worst * 3600.0 < 0.01, f"worst {worst * 3600.0:.2e} arcsec"


def test_render_equals_the_cli_png(cli: Path, tmp_path: Path) -> None:
    args = ["--lat-deg", "-89.6", "--lon-deg", "0", "--height-m", "10", "--look-az-deg", "20",
            "--look-el-deg", "-1", "--fov-deg", "70", "--utc", "2027-01-20T00:00",
            "--width", "120", "--height", "80", "--backend", "cpu"]
    run_cli(cli, tmp_path, "render", "--synthetic", *args, "--out", "f.png")
    img, radiance = penumbra.render(
        penumbra.Terrain.synthetic(), "2027-01-20T00:00", -89.6, 0.0, height_m=10.0,
        look_az_deg=20.0, look_el_deg=-1.0, fov_deg=70.0, width=120, height=80, backend="cpu",
    )
    assert img.shape == (80, 120, 3) and img.dtype == np.uint8
    assert radiance.shape == (80, 120) and radiance.dtype == np.float32
    # Looking 1 deg down with a 70 deg field: the top row is sky, which is NaN (no terrain).
    assert np.isnan(radiance[0]).all() and np.nanmax(radiance) > 0
    image = pytest.importorskip("PIL.Image")
    cli_img = np.asarray(image.open(tmp_path / "f.png").convert("RGB"))
    assert np.array_equal(cli_img, img)


def test_map_light_equals_the_cli_geotiffs_byte_for_byte(cli: Path, tmp_path: Path) -> None:
    run_cli(cli, tmp_path, "dem", "synth", "--size", "100", "--px-m", "150", "--seed", "2",
            "--out", "d.tif")
    run_cli(cli, tmp_path, "map", "--dem", "d.tif", "--utc", "2027-02-05T00:00", "--backend",
            "cpu", "--out-fraction", "f.tif", "--out-mask", "m.tif", "--out-earth-fraction", "e.tif")
    t = penumbra.Terrain.open([tmp_path / "d.tif"])
    m = penumbra.map_light(t, utc="2027-02-05T00:00")
    for name, cli_file in (("sun_fraction", "f.tif"), ("sun_mask", "m.tif"), ("earth_fraction", "e.tif")):
        out = tmp_path / f"py_{name}.tif"
        penumbra.write_geotiff(out, m[name], t, m["descriptions"][name], metadata=m["metadata"])
        assert out.read_bytes() == (tmp_path / cli_file).read_bytes(), name
    assert m["sun_mask"].dtype == np.uint8 and m["sun_fraction"].dtype == np.float32
    lit = m["sun_mask"] == 1
    assert lit.any() and np.all(m["sun_fraction"][lit] > 0.0)
