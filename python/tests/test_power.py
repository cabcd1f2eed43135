"""Solar power and battery (penumbra series --panel …, docs/power.md) against independent
computations: the Sun from SPICE on a flat sphere (closed form), a numpy integration of the
run's own irradiance columns, and a brute-force bisection of the battery capacity."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

import penumbra

from conftest import ROOT, pixel_sites, run_cli

spice = pytest.importorskip("spiceypy")
pd = pytest.importorskip("pandas")
rasterio = pytest.importorskip("rasterio")

KERNELS = ROOT / "kernels"
MOON_RADIUS_KM = 1737.4
AU_KM = 149_597_870.7
S0_W_M2 = 1360.8
POWER_BOUND_W = 0.01  # docs/power.md, docs/VALIDATION.md
SERIES = ["--start", "2025-01-01", "--stop", "2025-02-28T23:00", "--step", "1h"]


def _flat_dem(cli: Path, tmp: Path) -> Path:
    """The synthetic DEM's grid (400 × 100 m, polar stereographic) with every height 0: a bare
    sphere."""
    run_cli(cli, tmp, "dem", "synth", "--out", "s.tif")
    with rasterio.open(tmp / "s.tif") as src:
        profile = src.profile
        z = np.zeros((src.height, src.width), dtype="float32")
    with rasterio.open(tmp / "flat.tif", "w", **profile) as dst:
        dst.write(z, 1)
    return tmp / "flat.tif"


def test_power_on_a_bare_sphere_is_the_closed_form(cli: Path, tmp_path: Path) -> None:
    dem = _flat_dem(cli, tmp_path)
    lat, lon = -89.5, 30.0
    year = ["--start", "2025-01-01", "--stop", "2025-12-31T12:00", "--step", "12h"]
    run_cli(cli, tmp_path, "series", "--dem", str(dem), "--site", f"a,{lat},{lon}", *year,
            "--no-plots", "--stations", "none", "--panel", "two-axis", "--panel-area-m2", "2",
            "--panel-efficiency", "0.29", "--out-dir", "o")
    df = pd.read_csv(tmp_path / "o" / "a" / "series.csv")
    for k in ["naif0012.tls", "de440_moon_2000_2025.bsp", "de440_moon_2025_2050.bsp",
              "moon_pa_de421_2000_2050.bpc", "moon_080317.tf", "moon_assoc_me.tf"]:
        spice.furnsh(str(KERNELS / k))
    try:
        r = MOON_RADIUS_KM + 0.002
        la, lo = np.radians(lat), np.radians(lon)
        site = r * np.array([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)])
        up = site / np.linalg.norm(site)
        el, rng = [], []
        for t in df.utc:
            et = spice.str2et(t.rstrip("Z"))
            st, _ = spice.spkcpo("SUN", et, "MOON_ME", "OBSERVER", "LT+S", site.tolist(), "MOON",
                                 "MOON_ME")
            p = np.array(st[:3])
            el.append(np.degrees(np.arcsin(p @ up / np.linalg.norm(p))))
            rng.append(np.linalg.norm(p))
    finally:
        spice.kclear()
    el, rng = np.array(el), np.array(rng)
    up_all = el > 0.3  # the whole disc above a bare sphere's horizon (dip 0.003°)
    down = el < -0.4  # the whole disc (0.27°) below the dip (−0.088° at 2 m)
    assert up_all.sum() > 100 and down.sum() > 100
    want = 2.0 * 0.29 * S0_W_M2 * (AU_KM / rng) ** 2
    err = np.abs(df.power_w.to_numpy()[up_all] - want[up_all])
    print(f"power vs SPICE closed form: max {err.max():.2e} W over {up_all.sum()} lit epochs "
          f"(~{want.mean():.0f} W)")
    assert err.max() <= POWER_BOUND_W, err.max()
    assert (df.power_w.to_numpy()[down] == 0).all()


def _numpy_battery(power, load, step_h, cap):
    charge, at_epoch, empty_h, deficit, max_deficit = cap, [], 0.0, 0.0, 0.0
    for p, lw in zip(power, load):
        net = p - lw
        at_epoch.append(charge)
        if net < 0 and charge / -net < step_h:
            empty_h += step_h - charge / -net
        charge = min(max(charge + net * step_h, 0.0), cap)
        deficit = max(0.0, deficit - net * step_h)
        max_deficit = max(max_deficit, deficit)
    return np.array(at_epoch), empty_h, max_deficit


def test_power_and_battery_match_a_numpy_integration(cli: Path, tmp_path: Path) -> None:
    args = ["--synthetic", "--site", "a,-89.5,30", *SERIES, "--no-plots", "--stations", "none",
            "--panel", "vertical-fixed:90", "--panel-area-m2", "1.5", "--panel-efficiency",
            "0.3", "--load-w", "80", "--night-load-w", "40", "--battery-wh", "3000"]
    run_cli(cli, tmp_path, "series", *args, "--out-dir", "o")
    df = pd.read_csv(tmp_path / "o" / "a" / "series.csv")
    stats = json.loads((tmp_path / "o" / "stats.json").read_text())["sites"][0]
    # Power from the run's own columns, another formula: normal irradiance × the cosine of the
    # angle between the Sun and the east-facing normal.
    el, az = np.radians(df.sun_el_deg), np.radians(df.sun_az_deg)
    cosi = np.maximum(np.cos(el) * np.cos(az - np.radians(90.0)), 0.0)
    want = 1.5 * 0.3 * df.sun_irradiance_normal_w_m2 * cosi
    perr = np.abs(df.power_w - want)
    assert perr.max() <= 5e-4 * 1.5 * 0.3 + 5e-4 + 1e-6 * want.max(), perr.max()
    assert (want > 10).any() and (want == 0).any()
    load = np.where(df.sun_visible_fraction > 0, 80.0, 40.0)
    at_epoch, empty_h, required = _numpy_battery(df.power_w.to_numpy(), load, 1.0, 3000.0)
    assert np.abs(df.battery_wh - at_epoch).max() <= 1.0  # CSV power rounding, accumulated
    assert stats["hours_below_empty_h"] == pytest.approx(empty_h, abs=0.05)
    assert stats["required_battery_wh"] == pytest.approx(required, abs=1.0)
    # stats.json prints W with 2 decimals; the CSV's power_w 3.
    assert stats["mean_power_w"] == pytest.approx(df.power_w.mean(), abs=0.006)
    assert stats["required_battery_wh"] > 3000 and empty_h > 0
    # Brute force: the smallest capacity that never runs empty, by bisection on the simulator.
    lo, hi = 0.0, 4 * stats["required_battery_wh"]
    table = None
    for _ in range(25):
        mid = 0.5 * (lo + hi)
        table, s = penumbra.series(
            penumbra.Terrain.synthetic(), [("a", -89.5, 30.0, 2.0)],
            penumbra.time_range("2025-01-01", "2025-02-28T23:00", "1h"), stations="none",
            panel="vertical-fixed:90", panel_area_m2=1.5, panel_efficiency=0.3, load_w=80.0,
            night_load_w=40.0, battery_wh=mid)
        if s["sites"][0]["hours_below_empty_h"] > 0:
            lo = mid
        else:
            hi = mid
    print(f"required battery: drawdown {stats['required_battery_wh']:.3f} Wh, "
          f"bisection {hi:.3f} Wh")
    # stats.json prints Wh with 2 decimals and hours with 3: the bisection's "never empty"
    # (hours_below_empty_h == 0) misses deficits under 1.8 s, a few hundredths of a Wh.
    assert hi == pytest.approx(stats["required_battery_wh"], rel=0, abs=0.05)
    # Python and the command line: the same numbers; and a scenario's [series.power].
    assert np.allclose(table["power_w"], df.power_w, atol=5e-4)
    (tmp_path / "s.toml").write_text(
        f'name = "p"\nkernels = "{KERNELS}"\n'
        '[time]\nstart = "2025-01-01"\nstop = "2025-02-28T23:00"\nstep = "1h"\n'
        "[terrain]\nsynthetic = { size_px = 400, px_m = 100.0, seed = 1 }\n"
        '[series]\nplots = false\nstations = "none"\n'
        '[series.power]\npanel = "vertical-fixed:90"\narea_m2 = 1.5\nefficiency = 0.3\n'
        "load_w = 80.0\nnight_load_w = 40.0\nbattery_wh = 3000.0\n"
        '[[sites]]\nname = "a"\nlat_deg = -89.5\nlon_deg = 30.0\n'
    )
    run_cli(cli, tmp_path, "run", "s.toml", "--out-dir", "scn")
    sstats = json.loads((tmp_path / "scn" / "a" / "stats.json").read_text())["sites"][0]
    assert sstats["required_battery_wh"] == stats["required_battery_wh"]
    assert sstats["hours_below_empty_h"] == stats["hours_below_empty_h"]


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--panel-area-m2", "-1"], "panel area -1 is outside"),
        (["--panel-efficiency", "1.5"], "panel efficiency 1.5 is outside"),
        (["--panel", "sideways"], "panel 'sideways'"),
        (["--battery-wh", "0"], "battery capacity 0 is outside"),
        (["--load-w", "-5"], "load -5 is outside"),
    ],
)
def test_bad_power_settings_get_one_line_and_exit_2(cli: Path, tmp_path: Path, extra,
                                                   message) -> None:
    out = tmp_path / "o"
    r = subprocess.run(
        [str(cli), "series", "--synthetic", "--site", "a,-89.5,0", *SERIES, "--out-dir",
         str(out), *extra], capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0], r.stderr
    assert not out.exists()
    kw = {"--panel-area-m2": "panel_area_m2", "--panel-efficiency": "panel_efficiency",
          "--panel": "panel", "--battery-wh": "battery_wh", "--load-w": "load_w"}[extra[0]]
    value = extra[1] if kw == "panel" else float(extra[1])
    with pytest.raises(penumbra.PenumbraError, match=message.split("'")[0][:12]):
        penumbra.series(penumbra.Terrain.synthetic(), [("a", -89.5, 0.0, 2.0)],
                        penumbra.time_range("2025-01-01", "2025-01-02", "1h"), **{kw: value})


def _profile(path: Path, rows) -> Path:
    path.write_text("start_utc,stop_utc,load_w,night_load_w\n"
                    + "".join(f"{a},{b},{d},{n}\n" for a, b, d, n in rows))
    return path


PROFILE_ROWS = [("2025-01-01", "2025-01-20T06:00", 80, 40),
                ("2025-01-20T06:00", "2025-02-10", 150, 60),
                ("2025-02-10", "2025-03-01", 20, 10)]


def test_a_load_profile_drives_the_battery(cli: Path, tmp_path: Path) -> None:
    prof = _profile(tmp_path / "loads.csv", PROFILE_ROWS)
    args = ["--synthetic", "--site", "a,-89.5,30", *SERIES, "--no-plots", "--stations", "none",
            "--panel", "vertical-tracking", "--battery-wh", "5000", "--load-profile", str(prof)]
    run_cli(cli, tmp_path, "series", *args, "--out-dir", "o")
    df = pd.read_csv(tmp_path / "o" / "a" / "series.csv")
    stats = json.loads((tmp_path / "o" / "stats.json").read_text())["sites"][0]
    t = pd.to_datetime(df.utc.str.rstrip("Z"))
    lit = df.sun_visible_fraction > 0
    load = np.full(len(df), np.nan)
    for a, b, d, n in PROFILE_ROWS:
        inside = (t >= pd.Timestamp(a)) & (t < pd.Timestamp(b))
        load[inside] = np.where(lit[inside], d, n)
    assert np.isfinite(load).all()
    at_epoch, empty_h, required = _numpy_battery(df.power_w.to_numpy(), load, 1.0, 5000.0)
    print(f"load profile: required battery {stats['required_battery_wh']:.1f} Wh "
          f"(numpy {required:.1f}), empty {stats['hours_below_empty_h']:.2f} h")
    assert np.abs(df.battery_wh - at_epoch).max() <= 1.0
    assert stats["required_battery_wh"] == pytest.approx(required, abs=1.0)
    assert stats["hours_below_empty_h"] == pytest.approx(empty_h, abs=0.05)
    assert stats["load_energy_wh"] == pytest.approx(load.sum(), rel=1e-9)
    # Python reads the same file the same way.
    _, s = penumbra.series(
        penumbra.Terrain.synthetic(), [("a", -89.5, 30.0, 2.0)],
        penumbra.time_range("2025-01-01", "2025-02-28T23:00", "1h"), stations="none",
        panel="vertical-tracking", battery_wh=5000.0, load_profile=str(prof))
    assert s["sites"][0]["required_battery_wh"] == stats["required_battery_wh"]


@pytest.mark.parametrize(
    "rows, message",
    [
        ([("2025-01-01", "2025-01-20", 80, 40), ("2025-01-21", "2025-03-01", 80, 40)],
         "a gap between 2025-01-20"),
        ([("2025-01-01", "2025-01-20", 80, 40), ("2025-01-19", "2025-03-01", 80, 40)],
         "an overlap between 2025-01-19"),
        ([], "no rows (an empty profile)"),
        ([("2025-01-02", "2025-03-01", 80, 40)], "not the epoch 2025-01-01"),
        ([("2025-01-01", "2025-03-01", -3, 40)], "load -3 W is outside"),
    ],
)
def test_bad_load_profiles_get_one_line_and_exit_2(cli: Path, tmp_path: Path, rows,
                                                  message) -> None:
    prof = _profile(tmp_path / "loads.csv", rows)
    for cmd in (["series", "--site", "a,-89.5,0"], ["map", "--engine", "horizons"]):
        out = tmp_path / "o"
        r = subprocess.run(
            [str(cli), cmd[0], "--synthetic", *cmd[1:], *SERIES, "--out-dir", str(out),
             "--load-profile", str(prof)], capture_output=True, text=True)
        assert r.returncode == 2, r.stderr
        lines = [line for line in r.stderr.splitlines() if line.strip()]
        assert len(lines) == 1 and message in lines[0], r.stderr
        assert not out.exists()
    with pytest.raises(penumbra.PenumbraError, match=re.escape(message[:12])):
        penumbra.series(penumbra.Terrain.synthetic(), [("a", -89.5, 0.0, 2.0)],
                        penumbra.time_range("2025-01-01", "2025-02-28T23:00", "1h"),
                        load_profile=str(prof))


MAP_POWER_BOUND_W = (0.5, 0.005)  # max(0.5 W, 0.5 %): docs/power.md, docs/VALIDATION.md
MAP_BATTERY_BOUND = (60.0, 0.03)  # max(60 Wh, 3 %)


def test_power_maps_agree_with_series_at_20_pixels(cli: Path, tmp_path: Path) -> None:
    """A map cell (whole-grid line sweep, every pixel's epochs in the horizons engine) and a
    series at that pixel (its own horizon scan, the series pipeline, the battery stepped row by
    row): two engines, one answer. With a load profile by day and night."""
    prof = _profile(tmp_path / "loads.csv", PROFILE_ROWS)
    power = ["--panel", "vertical-tracking", "--load-profile", str(prof)]
    run_cli(cli, tmp_path, "map", "--synthetic", *SERIES, "--engine", "horizons", "--azimuths",
            "360", *power, "--out-dir", "m")
    with rasterio.open(tmp_path / "m" / "mean_power_w.tif") as src:
        p_map, tr, crs = src.read(1), src.transform, src.crs
    b_map = rasterio.open(tmp_path / "m" / "required_battery_wh.tif").read(1)
    irr = rasterio.open(tmp_path / "m" / "irradiance_tracking_w_m2.tif").read(1)
    # Mean power is the panel times the tracking irradiance of the same run.
    ok = np.isfinite(p_map)
    assert np.abs(p_map[ok] - 0.3 * irr[ok]).max() <= 1e-3 * max(1.0, float(p_map[ok].max()))
    rng = np.random.default_rng(7)
    cand = np.argwhere(ok & (p_map > 5))
    cand = cand[(cand.min(axis=1) > 20) & (cand.max(axis=1) < 380)]
    pick = cand[rng.choice(len(cand), 20, replace=False)]
    sites = pixel_sites(tr, crs, pick)
    run_cli(cli, tmp_path, "series", "--synthetic", *sites, *SERIES, "--no-plots", "--no-csv",
            "--stations", "none", *power, "--out-dir", "s")
    stats = json.loads((tmp_path / "s" / "stats.json").read_text())["sites"]
    dp, db = [], []
    for (r, c), s in zip(pick, stats):
        dp.append((p_map[r, c] - s["mean_power_w"],
                   max(MAP_POWER_BOUND_W[0], MAP_POWER_BOUND_W[1] * s["mean_power_w"])))
        db.append((b_map[r, c] - s["required_battery_wh"],
                   max(MAP_BATTERY_BOUND[0], MAP_BATTERY_BOUND[1] * s["required_battery_wh"])))
    dp, db = np.array(dp), np.array(db)
    print(f"map - series at 20 pixels: mean power |d| median {np.median(abs(dp[:, 0])):.3f} W, "
          f"max {abs(dp[:, 0]).max():.3f} W; required battery |d| median "
          f"{np.median(abs(db[:, 0])):.1f} Wh, max {abs(db[:, 0]).max():.1f} Wh")
    assert (abs(dp[:, 0]) <= dp[:, 1]).all(), dp
    assert (abs(db[:, 0]) <= db[:, 1]).all(), db
    assert np.median(abs(dp[:, 0])) <= 0.1 and np.median(abs(db[:, 0])) <= 30.0
    # Python's map_statistics: the same arrays as the command line's files.
    m = penumbra.map_statistics(
        penumbra.Terrain.synthetic(), penumbra.time_range("2025-01-01", "2025-02-28T23:00", "1h"),
        engine="horizons", azimuths=360, panel="vertical-tracking", load_profile=str(prof))
    assert np.array_equal(m["required_battery_wh"], b_map, equal_nan=True)
    assert np.array_equal(m["mean_power_w"], p_map, equal_nan=True)
    assert (m["units"]["mean_power_w"], m["units"]["required_battery_wh"]) == ("W", "W h")
