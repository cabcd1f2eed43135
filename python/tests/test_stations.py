"""Ground stations' view of a lunar site (penumbra.station_elevations, series' dte columns)
against independent implementations.

The oracle for the Earth's rotation is astropy (ERFA's IAU 2006/2000A precession-nutation, IERS
UT1 − UTC and polar motion from the tables astropy ships); the site's geocentric position comes
from SPICE (spiceypy, the same kernels). penumbra uses IAU 2006/2000B, UT1 = UTC and no polar
motion: the bound below (0.01°, docs/comms.md and docs/VALIDATION.md) is the issue's requirement
and ≈ 2.5× the error budget of those simplifications.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

import penumbra

from conftest import ROOT, run_cli

spice = pytest.importorskip("spiceypy")
pytest.importorskip("astropy")

from astropy import units as u  # noqa: E402
from astropy.coordinates import (  # noqa: E402
    CIRS,
    GCRS,
    AltAz,
    CartesianRepresentation,
    EarthLocation,
)
from astropy.time import Time  # noqa: E402
from astropy.utils import iers  # noqa: E402

iers.conf.auto_download = False  # the IERS tables astropy ships; no network here

KERNELS = ROOT / "kernels"
MOON_RADIUS_KM = 1737.4
C_KM_S = 299792.458
# Near the Connecting Ridge, 1.5 km above the sphere.
SITE = (-89.45, 222.69, 1500.0)
EL_BOUND_DEG = 0.01


def _site_from_earth_km(utc: np.ndarray, site: tuple) -> np.ndarray:
    """The site's position from the Earth's centre in J2000 (km) at each epoch, light-time
    corrected for a receiver at the geocentre (SPICE, independent of penumbra's anise path)."""
    for k in [
        "naif0012.tls",
        "de440_moon_2000_2025.bsp",
        "de440_moon_2025_2050.bsp",
        "moon_pa_de421_2000_2050.bpc",
        "moon_080317.tf",
        "moon_assoc_me.tf",
    ]:
        spice.furnsh(str(KERNELS / k))
    try:
        lat, lon = np.radians(site[0]), np.radians(site[1])
        r = MOON_RADIUS_KM + site[2] / 1000.0
        site_me = r * np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
        out = []
        for t in utc:
            et = spice.str2et(str(t).replace("T", " ")[:26])
            lt = 1.28
            for _ in range(3):
                moon, _ = spice.spkpos("MOON", et - lt, "J2000", "NONE", "EARTH")
                p = np.array(moon) + np.array(spice.pxform("MOON_ME", "J2000", et - lt)) @ site_me
                lt = np.linalg.norm(p) / C_KM_S
            out.append(p)
        return np.array(out)
    finally:
        spice.kclear()


def _astropy_el_deg(utc: np.ndarray, xyz_km: np.ndarray, loc: EarthLocation) -> np.ndarray:
    t = Time(utc.astype("datetime64[ns]").astype(str), scale="utc")
    c = GCRS(CartesianRepresentation(xyz_km.T * u.km), obstime=t)
    return c.transform_to(AltAz(obstime=t, location=loc, pressure=0 * u.hPa)).alt.deg


def test_dsn_elevations_match_astropy() -> None:
    # 1,080 epochs over 90 days (every 2 h) × the three DSN complexes.
    times = penumbra.time_range("2021-01-01", "2021-03-31T22:00", "2h")
    assert len(times) >= 1000
    got = penumbra.station_elevations(SITE, times)
    assert list(got["station"]) == ["DSS-14", "DSS-43", "DSS-63"]
    xyz = _site_from_earth_km(times, SITE)
    errs = []
    for i in range(3):
        loc = EarthLocation.from_geodetic(
            got["lon_deg"][i] * u.deg, got["lat_deg"][i] * u.deg, got["height_m"][i] * u.m
        )
        want = _astropy_el_deg(times, xyz, loc)
        errs.append(np.abs(got["el_deg"][i] - want))
        # The stations see the site rise and set: the comparison covers every elevation.
        assert want.min() < -30 and want.max() > 30
    err = np.concatenate(errs)
    p99 = float(np.percentile(err, 99))
    print(f"station elevation vs astropy: p99 {p99:.5f} deg, max {err.max():.5f} deg, n {err.size}")
    assert p99 <= EL_BOUND_DEG and err.max() <= EL_BOUND_DEG, (p99, err.max())


def _stations_file(tmp: Path, rows: list) -> Path:
    p = tmp / "stations.csv"
    with p.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["name", "lat_deg", "lon_deg", "height_m", "mask_deg"])
        w.writerows(rows)
    return p


def test_a_pole_station_sees_the_declination(tmp_path: Path) -> None:
    # At the north pole the local up is the Earth's rotation axis: the site's elevation is its
    # topocentric declination on the true equator (astropy's CIRS, seen from the pole).
    f = _stations_file(tmp_path, [["pole", 90.0, 0.0, 0.0, 0.0]])
    times = penumbra.time_range("2021-06-01", "2021-06-28", "3h")
    got = penumbra.station_elevations(SITE, times, stations=str(f))["el_deg"][0]
    loc = EarthLocation.from_geodetic(0 * u.deg, 90 * u.deg, 0 * u.m)
    t = Time(times.astype("datetime64[ns]").astype(str), scale="utc")
    xyz = _site_from_earth_km(times, SITE)
    dec = (
        GCRS(CartesianRepresentation(xyz.T * u.km), obstime=t)
        .transform_to(CIRS(obstime=t, location=loc))
        .dec.deg
    )
    err = np.abs(got - dec)
    print(f"pole station vs astropy CIRS declination: max {err.max():.5f} deg, n {err.size}")
    assert err.max() <= EL_BOUND_DEG, err.max()
    # And it swings with the Moon's declination (±28° in a major standstill season), not daily.
    assert got.max() - got.min() > 30


def test_an_equator_station_sees_the_moon_rise_every_24_8_hours(tmp_path: Path) -> None:
    f = _stations_file(tmp_path, [["equator", 0.0, 0.0, 0.0, 0.0]])
    times = penumbra.time_range("2021-01-01", "2021-01-29", "5min")
    el = penumbra.station_elevations(SITE, times, stations=str(f))["el_deg"][0]
    rises = np.flatnonzero((el[:-1] < 0) & (el[1:] >= 0))
    gaps_h = np.diff(rises) * 5 / 60
    assert len(gaps_h) >= 25
    print(f"equator station: {len(gaps_h)} rise-to-rise gaps, mean {gaps_h.mean():.3f} h, "
          f"{gaps_h.min():.2f} .. {gaps_h.max():.2f} h")
    # A lunar day: 24 h 50 min on average (24.84 h), each between 24.3 and 25.5 h.
    assert 24.7 < gaps_h.mean() < 25.0, gaps_h
    assert gaps_h.min() > 24.3 and gaps_h.max() < 25.5, gaps_h


def test_series_dte_is_the_joint_condition(cli: Path, tmp_path: Path) -> None:
    # series.csv's dte column = Earth's centre above the terrain horizon AND a station above its
    # mask, per epoch; the statistics count the same samples; Python gives the same numbers.
    out = tmp_path / "s"
    args = ["series", "--synthetic", "--site", "a,-89.5,0", "--start", "2025-01-01",
            "--stop", "2025-01-31T23:00", "--step", "1h", "--no-plots", "--out-dir", str(out)]
    run_cli(cli, tmp_path, *args)
    import pandas as pd

    df = pd.read_csv(out / "a" / "series.csv")
    centre = df.earth_el_deg > df.earth_horizon_el_deg
    station = df.station_el_deg >= 10.0
    assert (df.dte == (centre & station).astype(int)).all()
    stats = json.loads((out / "stats.json").read_text())["sites"][0]
    # stats.json prints percentages with 2 decimals.
    assert stats["dte_pct"] == pytest.approx(100 * df.dte.mean(), abs=0.0051)
    assert stats["station_pct"] == pytest.approx(100 * station.mean(), abs=0.0051)
    windows = pd.read_csv(out / "a" / "dte_windows.csv")
    assert len(windows) == stats["dte_windows"]
    assert windows.duration_h.sum() == pytest.approx(df.dte.sum(), abs=1e-9)
    ics = (out / "a" / "dte_windows.ics").read_text()
    assert ics.count("BEGIN:VEVENT") == len(windows)
    # Python, same inputs.
    terrain = penumbra.Terrain.synthetic()
    table, pstats = penumbra.series(terrain, [("a", -89.5, 0.0, 2.0)], penumbra.time_range(
        "2025-01-01", "2025-01-31T23:00", "1h"))
    assert np.array_equal(table["dte"], df.dte.to_numpy())
    assert np.allclose(table["station_el_deg"], df.station_el_deg, atol=1e-4)
    assert pstats["sites"][0]["dte_pct"] == stats["dte_pct"]


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--station-mask-deg", "-5"], "elevation mask -5 deg is outside [0, 90)"),
        (["--stations", "{bad_lat}"], "latitude 95 deg is outside [-90, 90]"),
        (["--stations", "{empty}"], "no stations"),
        (["--stations", "{missing}"], "stations file"),
    ],
)
def test_bad_stations_get_one_line_and_exit_2(cli: Path, tmp_path: Path, extra, message) -> None:
    import subprocess

    bad_lat = _stations_file(tmp_path, [["x", 95.0, 0.0, 0.0, 10.0]])
    empty = tmp_path / "empty.csv"
    empty.write_text("name,lat_deg,lon_deg,height_m\n")
    files = {"bad_lat": bad_lat, "empty": empty, "missing": tmp_path / "nope.csv"}
    extra = [e.format(**files) for e in extra]
    out = tmp_path / "o"
    r = subprocess.run(
        [str(cli), "series", "--synthetic", "--site", "a,-89.5,0", "--start", "2025-01-01",
         "--stop", "2025-01-02", "--step", "1h", "--out-dir", str(out), *extra],
        capture_output=True, text=True,
    )
    assert r.returncode == 2, r.stderr
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0], r.stderr
    assert not out.exists() or not any(out.rglob("*.csv")), "a half-written run"
    with pytest.raises(penumbra.PenumbraError, match=message.split(" (")[0].split("{")[0][:20]):
        penumbra.station_elevations(SITE, penumbra.time_range("2025-01-01", "2025-01-02", "1h"),
                                    stations=extra[-1] if extra[0] == "--stations" else "dsn",
                                    station_mask_deg=-5.0 if extra[0] != "--stations" else 10.0)
