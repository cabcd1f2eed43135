#!/usr/bin/env python3
"""Map cells against per-site series at the same pixel centres (issue [1/7] acceptance).

A map cell and a series site at that pixel centre must tell the same story: this script picks
N pixel centres of the finest DEM layer (half of them peaks, ridges and rims: local maxima of the
height in a 7 x 7 window and the steepest pixels; half at random), runs `penumbra series` at
those centres and `penumbra map` over the same epochs, and compares per pixel:

* % of epochs with any part of the Sun visible (map `sun_visible_pct.tif` vs the series'
  `sun_fraction > 1e-6`), the mean Sun visible fraction (map `sun_illumination_pct.tif` / 100,
  uniform disc, vs the series' uniform-disc fraction), Earth visible %, longest darkness (h);
* per epoch (with --epochs-check K one-light maps at K epochs): the Sun-centre mask against the
  series' `sun_el > horizon` on epochs whose margin |el - horizon| exceeds 0.1 deg.

Needs GDAL's Python bindings (`python3-gdal`) and numpy. Prints one table and a JSON summary.

  /usr/bin/python3 tools/map_vs_series.py --penumbra target/release/penumbra --synthetic \
      --start 2027-01-01 --stop 2027-12-31T23:00 --step 6h --sites 50
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np
from osgeo import gdal

R_M = 1737400.0


def lat_lon_of_pixel(gt, row, col):
    """Planetocentric lat / east lon (deg) of a pixel centre of a south polar stereographic grid
    (lon0 = 0, k0 = 1, R = 1737.4 km: the LOLA convention and penumbra's synthetic DEM)."""
    x = gt[0] + (col + 0.5) * gt[1]
    y = gt[3] + (row + 0.5) * gt[5]
    rho = math.hypot(x, y)
    colat = 2.0 * math.atan(rho / (2.0 * R_M))
    lat = -(90.0 - math.degrees(colat))
    lon = math.degrees(math.atan2(x, y)) % 360.0
    return lat, lon


def pick_pixels(z, n, seed):
    rng = np.random.default_rng(seed)
    rows, cols = z.shape
    m = 8  # stay off the outer 8 pixels (the map's own margin is tested elsewhere)
    valid = np.isfinite(z)
    inner = np.zeros_like(valid)
    inner[m:rows - m, m:cols - m] = True
    cand = valid & inner
    # Peaks / ridges / rims: local maxima in 7 x 7 and the steepest cells.
    from numpy.lib.stride_tricks import sliding_window_view
    zp = np.pad(np.where(valid, z, -np.inf), 3, constant_values=-np.inf)
    win = sliding_window_view(zp, (7, 7)).max(axis=(2, 3))
    peaks = np.argwhere(cand & (z >= win))
    gy, gx = np.gradient(np.where(valid, z, np.nanmean(z)))
    slope = np.hypot(gx, gy)
    steep = np.argwhere(cand & (slope >= np.quantile(slope[cand], 0.98)))
    picked = []
    for pool, k in [(peaks, n // 3), (steep, n // 6)]:
        if len(pool):
            idx = rng.choice(len(pool), size=min(k, len(pool)), replace=False)
            picked += [tuple(p) for p in pool[idx]]
    allc = np.argwhere(cand)
    while len(picked) < n:
        p = tuple(allc[rng.integers(len(allc))])
        if p not in picked:
            picked.append(p)
    return picked


def parse_step_h(step):
    units = {"s": 1 / 3600, "m": 1 / 60, "h": 1.0, "d": 24.0}
    return float(step[:-1]) * units[step[-1]]


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"failed: {' '.join(cmd)}\n{r.stderr}")
    return r


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--penumbra", default="target/release/penumbra")
    ap.add_argument("--dem", action="append", default=[])
    ap.add_argument("--synthetic", action="store_true")
    ap.add_argument("--start", required=True)
    ap.add_argument("--stop", required=True)
    ap.add_argument("--step", required=True)
    ap.add_argument("--sites", type=int, default=50)
    ap.add_argument("--engine", default="combined")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--extra-site", action="append", default=[],
                    help="NAME,LAT,LON: also compare the pixel containing this point")
    ap.add_argument("--backend", default="cpu", choices=["cpu", "gpu"],
                    help="the map's backend (the series always runs on the CPU)")
    ap.add_argument("--map-arg", action="append", default=[],
                    help="an extra argument for `penumbra map` (repeat), e.g. --map-arg=--horizons=h.tif")
    ap.add_argument("--series-limb", default="none",
                    help="limb darkening of the series (and of the horizons engine's map): none "
                         "(the per-epoch engines' uniform disc) or eddington")
    ap.add_argument("--workdir")
    args = ap.parse_args()
    work = args.workdir or tempfile.mkdtemp(prefix="map-vs-series-")
    os.makedirs(work, exist_ok=True)
    terrain = ["--synthetic"] if args.synthetic else sum((["--dem", d] for d in args.dem), [])
    epochs = ["--start", args.start, "--stop", args.stop, "--step", args.step]

    if args.synthetic:
        dem_path = os.path.join(work, "synth.tif")
        run([args.penumbra, "dem", "synth", "--size", "400", "--px-m", "100", "--seed", "1",
             "--out", dem_path])
    else:
        dem_path = sorted(args.dem, key=lambda p: gdal.Open(p).GetGeoTransform()[1])[0]
    ds = gdal.Open(dem_path)
    gt = ds.GetGeoTransform()
    z = ds.GetRasterBand(1).ReadAsArray().astype(np.float64)
    nd = ds.GetRasterBand(1).GetNoDataValue()
    if nd is not None:
        z[z == nd] = np.nan
    pixels = pick_pixels(z, args.sites, args.seed)
    for spec in args.extra_site:
        name, lat, lon = spec.split(",")
        lat, lon = float(lat), float(lon)
        # invert the projection
        colat = math.radians(90.0 + lat)
        rho = 2.0 * R_M * math.tan(colat / 2.0)
        x, y = rho * math.sin(math.radians(lon)), rho * math.cos(math.radians(lon))
        col = int((x - gt[0]) / gt[1])
        row = int((y - gt[3]) / gt[5])
        pixels.append((row, col))
    sites = []
    for k, (row, col) in enumerate(pixels):
        lat, lon = lat_lon_of_pixel(gt, row, col)
        sites.append((f"p{k:03d}", row, col, lat, lon))

    limb = ["--limb-darkening", args.series_limb] if args.engine == "horizons" else []
    t_map = run([args.penumbra, "map", *terrain, *epochs, "--engine", args.engine, *limb,
                 *args.map_arg, "--backend", args.backend, "--out-dir", os.path.join(work, "map")]).stderr
    site_args = sum((["--site", f"{n},{lat:.10f},{lon:.10f},2"] for n, _, _, lat, lon in sites), [])
    run([args.penumbra, "series", *terrain, *site_args, *epochs, "--no-plots",
         "--limb-darkening", args.series_limb,
         "--out-dir", os.path.join(work, "series")])

    def band(name):
        d = gdal.Open(os.path.join(work, "map", name))
        return d.GetRasterBand(1).ReadAsArray().astype(np.float64)

    m_vis = band("sun_visible_pct.tif")
    m_mean = band("sun_illumination_pct.tif") / 100.0
    m_earth = band("earth_visible_pct.tif")
    m_dark = band("longest_dark_h.tif")
    has_extra = os.path.exists(os.path.join(work, "map", "sun_full_pct.tif"))
    m_full = band("sun_full_pct.tif") if has_extra else None
    m_ehid = band("longest_earth_hidden_h.tif") if has_extra else None
    step_h = None
    rows_out = []
    for name, row, col, lat, lon in sites:
        with open(os.path.join(work, "series", name, "series.csv")) as f:
            rd = list(csv.DictReader(f))
        if step_h is None:
            step_h = parse_step_h(args.step)
        fs = np.array([float(r["sun_visible_fraction"]) for r in rd])
        fe = np.array([float(r["earth_visible_fraction"]) for r in rd])
        vis = 100.0 * np.mean(fs > 1e-6)
        ev = 100.0 * np.mean(fe > 1e-6)
        def longest(hidden):
            best, run_len = 0, 0
            for h in hidden:
                run_len = run_len + 1 if h else 0
                best = max(best, run_len)
            return best
        dark = longest(fs <= 1e-6)
        ehid = longest(fe <= 1e-6)
        full = 100.0 * np.mean(fs >= 0.999)
        rows_out.append(dict(site=name, row=int(row), col=int(col), lat=lat, lon=lon,
                             height_m=float(z[row, col]),
                             map_sun_pct=m_vis[row, col], series_sun_pct=vis,
                             map_mean=m_mean[row, col], series_mean=float(np.mean(fs)),
                             map_earth_pct=m_earth[row, col], series_earth_pct=ev,
                             map_dark_h=m_dark[row, col],
                             series_dark_h=dark * step_h,
                             map_full_pct=m_full[row, col] if has_extra else float("nan"),
                             series_full_pct=full,
                             map_earth_hidden_h=m_ehid[row, col] if has_extra else float("nan"),
                             series_earth_hidden_h=ehid * step_h))
    d_sun = np.array([r["map_sun_pct"] - r["series_sun_pct"] for r in rows_out])
    d_mean = np.array([r["map_mean"] - r["series_mean"] for r in rows_out])
    d_earth = np.array([r["map_earth_pct"] - r["series_earth_pct"] for r in rows_out])
    d_dark = np.array([r["map_dark_h"] - r["series_dark_h"] for r in rows_out])
    print(f"{'site':6} {'row':>5} {'col':>5} {'h_m':>7} {'sun% map':>9} {'series':>7} "
          f"{'mean map':>9} {'series':>7} {'earth% map':>10} {'series':>7} {'dark h map':>10} {'series':>7}")
    for r in rows_out:
        print(f"{r['site']:6} {r['row']:5d} {r['col']:5d} {r['height_m']:7.0f} "
              f"{r['map_sun_pct']:9.2f} {r['series_sun_pct']:7.2f} {r['map_mean']:9.4f} "
              f"{r['series_mean']:7.4f} {r['map_earth_pct']:10.2f} {r['series_earth_pct']:7.2f} "
              f"{r['map_dark_h']:10.0f} {r['series_dark_h']:7.0f}")
    summary = dict(
        sites=len(rows_out), engine=args.engine, epochs=f"{args.start}..{args.stop}/{args.step}",
        sun_pct_abs_diff_max=float(np.max(np.abs(d_sun))),
        sun_pct_abs_diff_mean=float(np.mean(np.abs(d_sun))),
        sites_sun_pct_within_0_5pp=int(np.sum(np.abs(d_sun) <= 0.5)),
        mean_fraction_abs_diff_max=float(np.max(np.abs(d_mean))),
        sites_mean_within_0_005=int(np.sum(np.abs(d_mean) <= 0.005)),
        earth_pct_abs_diff_max=float(np.max(np.abs(d_earth))),
        sites_earth_pct_within_0_5pp=int(np.sum(np.abs(d_earth) <= 0.5)),
        longest_dark_h_abs_diff_max=float(np.max(np.abs(d_dark))),
        sites_dark_within_max_3h_2pct=int(np.sum(np.abs(d_dark) <= np.maximum(
            3.0, 0.02 * np.array([r["series_dark_h"] for r in rows_out])))),
        sun_pct_mean_diff=float(np.mean(d_sun)),
        mean_fraction_mean_diff=float(np.mean(d_mean)),
        workdir=work,
    )
    if has_extra:
        d_full = np.array([r["map_full_pct"] - r["series_full_pct"] for r in rows_out])
        d_ehid = np.array([r["map_earth_hidden_h"] - r["series_earth_hidden_h"] for r in rows_out])
        summary.update(
            full_pct_abs_diff_max=float(np.max(np.abs(d_full))),
            sites_full_pct_within_0_5pp=int(np.sum(np.abs(d_full) <= 0.5)),
            earth_hidden_h_abs_diff_max=float(np.max(np.abs(d_ehid))),
            sites_earth_hidden_within_max_3h_2pct=int(np.sum(np.abs(d_ehid) <= np.maximum(
                3.0, 0.02 * np.array([r["series_earth_hidden_h"] for r in rows_out])))),
        )
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
