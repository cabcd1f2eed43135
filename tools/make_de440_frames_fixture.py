#!/usr/bin/env python3
"""Write a tiny kernel set with the DE440 lunar frame ids, and its SPICE reference.

Why
---
Issue 18: penumbra must load any lunar PCK/FK set, not only the DE421 one it ships
(``MOON_PA_DE421`` 31006 from a binary PCK, ``MOON_ME_DE421`` 31007 from ``moon_080317.tf``).
NAIF's DE440 set names its frames ``MOON_PA_DE440`` (31008, ``moon_pa_de440_200625.bpc``) and
``MOON_ME_DE440_ME421`` (31009, ``moon_de440_220930.tf``). The real DE440 lunar PCK (12 MB) is
not on PyPI, so this script builds a stand-in that exercises the same frame ids and chain:

``tests/fixtures/kernels-de440-frames/moon_pa_de440_ids.bpc``
    The shipped DE421 orientation records (``kernels/moon_pa_de421_2000_2050.bpc``) overlapping
    2025-03-10 .. 2025-03-20 TDB, rewritten with ``pckw02`` under frame class id 31008. (The
    angles are DE421's; only the frame ids are DE440's.)

``tests/fixtures/kernels-de440-frames/moon_de440_frames.tf``
    The frame definitions of NAIF's ``moon_de440_220930.tf``: 31008 (PCK class 2), 31009 (TK,
    ANGLES (67.8526, 78.6944, 0.2785) arcsec about axes (3, 2, 1) relative to MOON_PA_DE440),
    and the aliases MOON_PA 31010 / MOON_ME 31011 (identity MATRIX). The DE421 kernel's
    MOON_ME_DE421 angles are (67.92, 78.56, 0.30) arcsec: the two ME frames differ by ~0.15
    arcsec, which the test uses to show which one penumbra applied.

``tests/fixtures/spice_reference_de440_frames.csv``
    The oracle: ``spkcpo(target, et, 'MOON_ME_DE440_ME421', 'OBSERVER', abcorr, obs, 'MOON',
    'MOON_ME_DE440_ME421')`` with the shipped ``de440_moon_2025_2050.bsp``, ``naif0012.tls`` and the
    two files above, for 3 sites x 5 epochs x {SUN, EARTH} x {LT+S, NONE}; az/el in the site's
    ENU frame as in ``tools/make_spice_fixture.py``. The same rows evaluated in
    ``MOON_ME_DE421`` with the shipped DE421 set are written as ``*_de421_*`` columns.

Run: ``pip install spiceypy==8.3.0 numpy; python3 tools/make_de440_frames_fixture.py``
(deterministic; prints the sha256 of what it wrote).
"""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import numpy as np
import spiceypy as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from make_kernels import read_bpc_type2_segments  # noqa: E402
from make_spice_fixture import az_el_deg, load, site_in_moon_me_km  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
KERNELS = REPO / "kernels"
OUT_DIR = REPO / "tests" / "fixtures" / "kernels-de440-frames"
BPC_OUT = OUT_DIR / "moon_pa_de440_ids.bpc"
FK_OUT = OUT_DIR / "moon_de440_frames.tf"
CSV_OUT = REPO / "tests" / "fixtures" / "spice_reference_de440_frames.csv"

SPAN_TDB = ("2025 MAR 10 00:00:00 TDB", "2025 MAR 20 00:00:00 TDB")
SITES = [
    ("connecting_ridge", -89.45, -137.3, 1955.0),
    ("malapert", -85.99, 2.93, 5100.0),
    ("equator", 0.0, 0.0, 0.0),
]
EPOCHS_UTC = [
    "2025-03-11T00:00:00",
    "2025-03-13T06:30:00",
    "2025-03-15T12:00:00",
    "2025-03-17T18:45:00",
    "2025-03-19T23:00:00",
]

FK_TEXT = r"""KPL/FK

Lunar frames with the ids of NAIF's DE440 set (moon_de440_220930.tf), for penumbra's tests.
Written by tools/make_de440_frames_fixture.py. The definitions of 31008..31011 are those of
moon_de440_220930.tf (W. Bachman, NAIF, 2022-09-30); only this comment differs.

   MOON_PA              MOON_PA_DE440           FIXED   31010
   MOON_ME              MOON_ME_DE440_ME421     FIXED   31011
   MOON_PA_DE440        ICRF/J2000              PCK     31008
   MOON_ME_DE440_ME421  MOON_PA_DE440           FIXED   31009

\begindata

      FRAME_MOON_PA_DE440           = 31008
      FRAME_31008_NAME              = 'MOON_PA_DE440'
      FRAME_31008_CLASS             = 2
      FRAME_31008_CLASS_ID          = 31008
      FRAME_31008_CENTER            = 301

      FRAME_MOON_ME_DE440_ME421     = 31009
      FRAME_31009_NAME              = 'MOON_ME_DE440_ME421'
      FRAME_31009_CLASS             = 4
      FRAME_31009_CLASS_ID          = 31009
      FRAME_31009_CENTER            = 301
      TKFRAME_31009_SPEC            = 'ANGLES'
      TKFRAME_31009_RELATIVE        = 'MOON_PA_DE440'
      TKFRAME_31009_ANGLES          = (   67.8526   78.6944   0.2785 )
      TKFRAME_31009_AXES            = (   3,        2,        1      )
      TKFRAME_31009_UNITS           = 'ARCSECONDS'

      FRAME_MOON_PA                 = 31010
      FRAME_31010_NAME              = 'MOON_PA'
      FRAME_31010_CLASS             = 4
      FRAME_31010_CLASS_ID          = 31010
      FRAME_31010_CENTER            = 301
      TKFRAME_31010_SPEC            = 'MATRIX'
      TKFRAME_31010_RELATIVE        = 'MOON_PA_DE440'
      TKFRAME_31010_MATRIX          = ( 1 0 0
                                        0 1 0
                                        0 0 1 )

      FRAME_MOON_ME                 = 31011
      FRAME_31011_NAME              = 'MOON_ME'
      FRAME_31011_CLASS             = 4
      FRAME_31011_CLASS_ID          = 31011
      FRAME_31011_CENTER            = 301
      TKFRAME_31011_SPEC            = 'MATRIX'
      TKFRAME_31011_RELATIVE        = 'MOON_ME_DE440_ME421'
      TKFRAME_31011_MATRIX          = ( 1 0 0
                                        0 1 0
                                        0 0 1 )

\begintext
"""


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def write_bpc() -> int:
    """DE421 records over SPAN_TDB, relabelled 31006 -> 31008; returns the record count."""
    sp.kclear()
    sp.furnsh(str(KERNELS / "naif0012.tls"))
    et0, et1 = (sp.str2et(s) for s in SPAN_TDB)
    segs = read_bpc_type2_segments(KERNELS / "moon_pa_de421_2000_2050.bpc")
    if BPC_OUT.exists():
        BPC_OUT.unlink()
    h = sp.pckopn(str(BPC_OUT), "penumbra DE440-id test PCK", 0)
    total = 0
    try:
        for s in segs:
            first, last = max(et0, s["et_first"]), min(et1, s["et_last"])
            if first >= last:
                continue
            i0 = max(int(np.floor((first - s["init"]) / s["intlen"])), 0)
            i1 = min(int(np.ceil((last - s["init"]) / s["intlen"])), s["records"].shape[0])
            recs = s["records"][i0:i1]
            ncoef = (s["rsize"] - 2) // 3
            sp.pckw02(h, 31008, s["base_frame"], first, last, "MOON_PA_DE440 ids, DE421 data",
                      s["intlen"], i1 - i0, ncoef - 1, recs[:, 2:].ravel(),
                      s["init"] + i0 * s["intlen"])
            total += i1 - i0
    finally:
        sp.pckcls(h)
    return total


def rows(frame: str, files: list[Path]) -> list[tuple]:
    load(files)
    out = []
    for name, lat, lon, h in SITES:
        obs = site_in_moon_me_km(lat, lon, h)
        for utc in EPOCHS_UTC:
            et = sp.str2et(utc)
            for tgt in ("SUN", "EARTH"):
                for ab in ("LT+S", "NONE"):
                    st, _lt = sp.spkcpo(tgt, et, frame, "OBSERVER", ab, obs, "MOON", frame)
                    pos = np.array(st[:3])
                    az, el = az_el_deg(pos, lat, lon)
                    out.append((name, lat, lon, h, utc, tgt, ab, float(np.linalg.norm(pos)), az, el))
    return out


def main() -> int:
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    n = write_bpc()
    FK_OUT.write_text(FK_TEXT)
    spk = KERNELS / "de440_moon_2025_2050.bsp"
    lsk = KERNELS / "naif0012.tls"
    de440 = rows("MOON_ME_DE440_ME421", [spk, lsk, BPC_OUT, FK_OUT])
    de421 = rows("MOON_ME_DE421", [spk, lsk, KERNELS / "moon_pa_de421_2000_2050.bpc",
                                   KERNELS / "moon_080317.tf"])
    lines = [
        "# SPICE reference for the DE440 frame ids: spkcpo(target, et, 'MOON_ME_DE440_ME421',",
        "# 'OBSERVER', abcorr, obs, 'MOON', 'MOON_ME_DE440_ME421') with kernels/de440_moon_2025_2050.bsp,",
        "# kernels/naif0012.tls and tests/fixtures/kernels-de440-frames/ (see tools/make_de440_frames_fixture.py);",
        "# az_de421_deg/el_de421_deg: the same in MOON_ME_DE421 with the shipped DE421 set.",
        f"# {BPC_OUT.name} sha256 {sha256(BPC_OUT)}; {FK_OUT.name} sha256 {sha256(FK_OUT)}",
        "site,lat_deg,lon_deg,height_m,utc,target,abcorr,range_km,az_deg,el_deg,az_de421_deg,el_de421_deg",
    ]
    for a, b in zip(de440, de421):
        assert a[:7] == b[:7]
        lines.append(",".join([*(str(v) for v in a[:7]), f"{a[7]:.9f}", f"{a[8]:.12f}",
                               f"{a[9]:.12f}", f"{b[8]:.12f}", f"{b[9]:.12f}"]))
    CSV_OUT.write_text("\n".join(lines) + "\n")
    shift = max(
        3600 * max(abs((a[8] - b[8] + 180) % 360 - 180) * np.cos(np.radians(a[9])), abs(a[9] - b[9]))
        for a, b in zip(de440, de421)
    )
    print(f"{BPC_OUT} ({n} records, {BPC_OUT.stat().st_size} B) sha256 {sha256(BPC_OUT)}")
    print(f"{FK_OUT} sha256 {sha256(FK_OUT)}")
    print(f"{CSV_OUT}: {len(de440)} rows; max DE440-ME vs DE421-ME direction difference {shift:.3f} arcsec")
    return 0


if __name__ == "__main__":
    sys.exit(main())
