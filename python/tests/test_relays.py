"""Relays: a body of a user's SPK as a link target (penumbra series --relay NAME=NAIF_ID
--relay-spk FILE), against SPICE.

The SPK is written here with spiceypy (a circular polar orbit about the Moon, type 9 Lagrange
segments); the oracle for the relay's elevation and range is SPICE itself (spkcpo in MOON_ME from
the site), and the visibility rule (above the site's terrain horizon, within the range limit) is
re-applied from the run's own horizon.csv: an independent path for the geometry, the same
horizon for the blocking rule.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

import penumbra

from conftest import ROOT, run_cli

spice = pytest.importorskip("spiceypy")
pd = pytest.importorskip("pandas")

KERNELS = ROOT / "kernels"
MOON_RADIUS_KM = 1737.4
GM_MOON_KM3_S2 = 4902.800066
RELAY_ID = -999
ORBIT_RADIUS_KM = MOON_RADIUS_KM + 3000.0
EL_BOUND_DEG = 1e-4  # docs/comms.md, "Relays"
START, STOP, STEP = "2025-01-01", "2025-01-03", "10min"
SITE = ("a", -89.5, 30.0)
FRAME_KERNELS = [
    "naif0012.tls",
    "de440_moon_2000_2025.bsp",
    "de440_moon_2025_2050.bsp",
    "moon_pa_de421_2000_2050.bpc",
    "moon_080317.tf",
    "moon_assoc_me.tf",
]


def _furnsh() -> None:
    for k in FRAME_KERNELS:
        spice.furnsh(str(KERNELS / k))


@pytest.fixture(scope="module")
def relay_spk(tmp_path_factory) -> Path:
    """A circular orbit 3,000 km above the Moon, its plane holding J2000's z axis, one state a
    minute from 2024-12-31T23:00 to 2025-01-03T01:00 (SPK type 9, degree 7)."""
    path = tmp_path_factory.mktemp("relay") / "relay.bsp"
    _furnsh()
    try:
        et0 = spice.str2et("2024-12-31T23:00:00")
        et1 = spice.str2et("2025-01-03T01:00:00")
        ets = np.arange(et0, et1 + 60.0, 60.0)
        n = np.sqrt(GM_MOON_KM3_S2 / ORBIT_RADIUS_KM**3)
        u = n * (ets - et0)
        r = ORBIT_RADIUS_KM
        states = np.column_stack([r * np.cos(u), np.zeros_like(u), r * np.sin(u),
                                  -r * n * np.sin(u), np.zeros_like(u), r * n * np.cos(u)])
        h = spice.spkopn(str(path), "relay", 0)
        spice.spkw09(h, RELAY_ID, 301, "J2000", ets[0], ets[-1], "test relay", 7,
                     len(ets), states.tolist(), ets.tolist())
        spice.spkcls(h)
    finally:
        spice.kclear()
    return path


def _oracle(utc: np.ndarray, site_me_km: np.ndarray, spk: Path):
    """Elevation, azimuth (deg) and range (km) of the relay from the site, SPICE."""
    _furnsh()
    spice.furnsh(str(spk))
    try:
        up = site_me_km / np.linalg.norm(site_me_km)
        east = np.cross([0.0, 0.0, 1.0], up)
        east /= np.linalg.norm(east)
        north = np.cross(up, east)
        el, az, rng = [], [], []
        for t in utc:
            et = spice.str2et(str(t)[:19])
            st, _ = spice.spkcpo(str(RELAY_ID), et, "MOON_ME", "OBSERVER", "NONE",
                                 site_me_km.tolist(), "MOON", "MOON_ME")
            p = np.array(st[:3])
            d = np.linalg.norm(p)
            el.append(np.degrees(np.arcsin(np.dot(p, up) / d)))
            az.append(np.degrees(np.arctan2(np.dot(p, east), np.dot(p, north))) % 360.0)
            rng.append(d)
        return np.array(el), np.array(az), np.array(rng)
    finally:
        spice.kclear()


def _run(cli: Path, tmp: Path, spk: Path, *extra: str) -> Path:
    out = tmp / "s"
    run_cli(cli, tmp, "series", "--synthetic", "--site", ",".join(map(str, SITE)),
            "--start", START, "--stop", STOP, "--step", STEP, "--no-plots", "--stations", "none",
            "--relay", f"R={RELAY_ID}", "--relay-spk", str(spk), "--out-dir", str(out), *extra)
    return out


def test_relay_elevations_and_visibility_match_spice(cli: Path, tmp_path: Path,
                                                      relay_spk: Path) -> None:
    max_range_km = 4500.0
    out = _run(cli, tmp_path, relay_spk, "--relay-max-range-km", str(max_range_km))
    df = pd.read_csv(out / "a" / "series.csv")
    assert list(df.columns[-3:]) == ["relay_visible", "relay_el_deg", "relay"]
    assert "dte" not in df.columns  # --stations none: no DTE columns
    stats = json.loads((out / "stats.json").read_text())["sites"][0]
    ground_m = stats["location"]["ground_height_m"]
    lat, lon = np.radians(SITE[1]), np.radians(SITE[2])
    r = MOON_RADIUS_KM + (ground_m + 2.0) / 1000.0
    site_me = r * np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
    el, az, rng = _oracle(pd.to_datetime(df.utc).dt.strftime("%Y-%m-%dT%H:%M:%S").to_numpy(),
                          site_me, relay_spk)
    err = np.abs(df.relay_el_deg.to_numpy() - el)
    print(f"relay elevation vs SPICE spkcpo: max {err.max():.2e} deg over {err.size} epochs")
    assert err.max() <= EL_BOUND_DEG, err.max()
    # The orbit rises and sets, and comes in and out of range, over the two days.
    assert el.min() < -10 and el.max() > 10
    assert rng.min() < max_range_km < rng.max()
    # Visibility: above the terrain horizon (horizon.csv, linear in azimuth) and in range.
    hz = pd.read_csv(out / "a" / "horizon.csv")
    az_grid = np.append(hz.az_deg.to_numpy(), 360.0)
    el_grid = np.append(hz.horizon_el_deg.to_numpy(), hz.horizon_el_deg.iloc[0])
    horizon_el = np.interp(az, az_grid, el_grid)
    want = (el > horizon_el) & (rng <= max_range_km)
    clear = np.abs(el - horizon_el) > 0.01
    assert want[clear].any() and (~want[clear]).any()
    assert np.array_equal(df.relay_visible.to_numpy()[clear], want[clear].astype(int))
    # stats.json prints percentages with 2 decimals.
    assert stats["relay_pct"] == pytest.approx(100 * df.relay_visible.mean(), abs=0.0051)
    # Without stations the link is the relay alone.
    assert stats["link_pct"] == stats["relay_pct"]
    # Python: the same numbers.
    table, pstats = penumbra.series(
        penumbra.Terrain.synthetic(), [(SITE[0], SITE[1], SITE[2], 2.0)],
        penumbra.time_range(START, STOP, STEP), stations="none", relays=[f"R={RELAY_ID}"],
        relay_spks=[str(relay_spk)], relay_max_range_km=max_range_km)
    assert np.array_equal(table["relay_visible"], df.relay_visible.to_numpy())
    assert np.allclose(table["relay_el_deg"], df.relay_el_deg, atol=1e-4)
    assert pstats["sites"][0]["relay_pct"] == stats["relay_pct"]
    # A scenario: relays and relay_spks (relative to the scenario file) in [series].
    (tmp_path / "relay.bsp").write_bytes(relay_spk.read_bytes())
    (tmp_path / "s.toml").write_text(
        f'name = "r"\nkernels = "{KERNELS}"\n'
        f'[time]\nstart = "{START}"\nstop = "{STOP}"\nstep = "{STEP}"\n'
        "[terrain]\nsynthetic = { size_px = 400, px_m = 100.0, seed = 1 }\n"
        '[series]\nplots = false\nstations = "none"\nrelays = ["R=-999"]\n'
        f'relay_spks = ["relay.bsp"]\nrelay_max_range_km = {max_range_km}\n'
        f'[[sites]]\nname = "a"\nlat_deg = {SITE[1]}\nlon_deg = {SITE[2]}\n'
    )
    run_cli(cli, tmp_path, "run", "s.toml", "--out-dir", "scn")
    sdf = pd.read_csv(tmp_path / "scn" / "a" / "series.csv")
    assert np.array_equal(sdf.relay_visible.to_numpy(), df.relay_visible.to_numpy())


def test_relays_with_stations_count_any_link(cli: Path, tmp_path: Path, relay_spk: Path) -> None:
    out = tmp_path / "s"
    run_cli(cli, tmp_path, "series", "--synthetic", "--site", ",".join(map(str, SITE)),
            "--start", START, "--stop", STOP, "--step", STEP, "--no-plots",
            "--relay", f"R={RELAY_ID}", "--relay-spk", str(relay_spk), "--out-dir", str(out))
    df = pd.read_csv(out / "a" / "series.csv")
    stats = json.loads((out / "stats.json").read_text())["sites"][0]
    link = (df.dte == 1) | (df.relay_visible == 1)
    assert stats["link_pct"] == pytest.approx(100 * link.mean(), abs=0.0051)
    assert stats["link_pct"] >= max(stats["dte_pct"], stats["relay_pct"])


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--relay", "R=-12345", "--relay-spk", "{spk}"], "relay 'R' (NAIF id -12345)"),
        (["--relay", "R=abc", "--relay-spk", "{spk}"], "the NAIF id must be an integer"),
        (["--relay", "R=-999"], "give the SPK that holds the relay"),
        (["--relay", "R=-999", "--relay-spk", "{missing}"], "relay SPK"),
        (["--relay", "R=-999", "--relay-spk", "{spk}", "--relay-max-range-km", "-1"],
         "slant-range limit"),
    ],
)
def test_bad_relays_get_one_line_and_exit_2(cli: Path, tmp_path: Path, relay_spk: Path,
                                            extra, message) -> None:
    extra = [e.format(spk=relay_spk, missing=tmp_path / "nope.bsp") for e in extra]
    out = tmp_path / "o"
    r = subprocess.run(
        [str(cli), "series", "--synthetic", "--site", "a,-89.5,0", "--start", START,
         "--stop", STOP, "--step", "1h", "--out-dir", str(out), *extra],
        capture_output=True, text=True,
    )
    assert r.returncode == 2, r.stderr
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0], r.stderr
    assert not out.exists() or not any(out.rglob("*.csv")), "a half-written run"
