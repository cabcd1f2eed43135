"""An outside oracle on real terrain (issue 48): SPICE's own ray caster on a DSK plate model.

The test set-up cuts a window out of the shared LOLA grid (240 m, polar stereographic), writes it
as a GeoTIFF (penumbra's only DEM: no far field), and writes from the same pixels two SPICE DSK
type-2 plate models (spiceypy `dskmi2` + `dskw02`, into tmp_path, never committed). SPICE then
casts the rays (`dskxv`), and penumbra's products are compared with them:

1. `penumbra series` at 36 pixel centres (peaks, convex rims, steep slopes, random), a month
   every 3 h: the Sun centre lit / unlit at every epoch whose oracle margin (Sun centre minus
   terrain horizon at the Sun's azimuth) exceeds 0.1 deg, and the visible fraction;
2. `penumbra map` one epoch (engines combined and dp): hard mask and soft Sun fraction;
3. `penumbra map` statistics over the same month (engines combined and horizons) at the same 36
   pixels: % of epochs with any Sun visible, average illumination.

Shared with penumbra (so that only the algorithms are compared): the kernels (`kernels/`, loaded
into spiceypy), the 1737.4 km sphere, the DEM's pixels (a DSK vertex at every pixel centre at
radius R + height, the latitude and longitude from PROJ's inverse projection, not penumbra's; a
ring of vertices on the window's outer edge with the edge pixels' heights, as penumbra extends
the edge values by half a pixel), the observer (2 m along the radial above the pixel centre), the
blocking rule (only the terrain in the window blocks; a ray leaving it is lit), a uniform Sun
disc of radius asin(696,000 km / range).

Not shared: the surface (flat triangles between the pixel centres, not penumbra's bilinear
patches and not its model-space resampling), the search (SPICE's voxel ray caster, not
penumbra's horizon scans, line sweeps, SMap or DP), no "observer's own half pixel" left out,
the Sun (its own topocentric LT+S vector from spiceypy `spkcpo` at each observer; for the
one-epoch map the crop centre's, 1e-7 rad of parallax), and the disc integral (below).

The plate model's interpolation spread is the tolerance floor. Each quad of four pixel centres
is split along both diagonals, one per DSK: DSK "low" takes the diagonal whose two plates lie
on or below the bilinear patch, DSK "high" the other (on a patch the bilinear surface differs
from the plates by -t·v·(1-u) or +t·u·(1-v), t the patch's twist, so it lies between the two).
Hence "blocked on low" implies "blocked on penumbra's bilinear surface" implies "blocked on
high", up to the millimetres of the sphere's sagitta over a plate. A verdict on which the two
DSKs agree is "stable"; fractions are compared with the interval [low, high].

Disc: 24 vertical strips of equal azimuth width across the disc (exact spherical cap bounds per
strip). Along a vertical line the blocked directions are the ones below a boundary (the terrain
is a height field), so each strip is resolved by ray casts at its top and bottom limbs and, when
cut, 8 bisection steps (1/256 of the chord): a cut disc costs about 240 rays, the fraction is
the visible solid angle (sum over strips of sin(el_top) - sin(boundary)) over the disc's.
"Any part visible" = some strip's top limb ray not blocked. The series test checks the strips
against plain sampling (1024 rays on a Vogel spiral) at 20 cut discs.

The plates round the observer count in full (penumbra leaves out terrain within half a pixel):
with the observer 2 m up, the diagonal chosen in its own four quads is most of the low / high
spread, up to 11 pp of a month's average illumination at a pixel (mean 0.5 pp).

Targets (issue 48), not tuned to penumbra's output: series lit / unlit agree at >= 99.5 % of
the stable epochs (margin > 0.1 deg on both DSKs, the same verdict); hard masks differ at
<= 0.5 % of stable pixels; soft fractions mean |df| <= 0.02 over the partial discs (either side
strictly between 0 and 1; |df| = distance to [low, high]; maps on every second row and column;
the same target for the series' fractions); map statistics within 0.5 pp of [low, high] at
every pixel. A target penumbra misses is a strict xfail whose reason holds the measured numbers.

`target/pyenv/bin/python -m pytest python/tests/test_dsk_oracle.py -q -s -p no:cacheprovider`
prints the numbers and the time of each stage.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT, pixel_sites, run_cli

spice = pytest.importorskip("spiceypy")
rasterio = pytest.importorskip("rasterio")
pd = pytest.importorskip("pandas")

from affine import Affine  # noqa: E402  (a rasterio dependency)
from rasterio.crs import CRS  # noqa: E402
from rasterio.warp import transform as warp  # noqa: E402
from rasterio.windows import Window  # noqa: E402

KERNELS = ROOT / "kernels"
KERNEL_FILES = ["naif0012.tls", "de440_moon_2000_2025.bsp", "de440_moon_2025_2050.bsp",
                "moon_pa_de421_2000_2050.bpc", "moon_080317.tf", "moon_assoc_me.tf"]
MOON_R_M = 1737400.0
SUN_R_KM = 696000.0
OBS_H_M = 2.0
# 128 x 128 pixels (30.7 km) round Shackleton, the pole inside: 33,282 plates per DSK.
WINDOW = Window(col_off=740, row_off=736, width=128, height=128)
START, STOP, STEP = "2025-02-20", "2025-03-22", "3h"  # the Sun 0.7 ... 0 deg at the pole
MAP_UTC = "2025-03-01T00:00"
N_SITES = 36
N_STRIPS = 24
N_BISECT = 8
MARGIN_DEG = 0.1
SURF = {"low": 1, "high": 2}

# Issue 48 targets.
SERIES_AGREE_MIN = 0.995
MASK_DIFF_MAX = 0.005
FRACTION_MEAN_MAX = 0.02
STATS_PP_MAX = 0.5


def _timed(label: str, t0: float) -> float:
    t = time.perf_counter()
    print(f"[dsk-oracle] {label}: {t - t0:.1f} s")
    return t


@dataclass
class Grid:
    tif: Path
    z: np.ndarray  # heights (m), the crop
    transform: Affine
    crs: CRS


class Oracle:
    """Two DSKs of the crop and the ray casts on them (SPICE state: kernels + both DSKs)."""

    def __init__(self, grid: Grid, folder: Path) -> None:
        z = grid.z.astype(np.float64)
        n_r, n_c = z.shape
        tr = grid.transform
        # Vertex columns / rows: the outer edge, every pixel centre, the other outer edge.
        xs = tr.c + tr.a * np.concatenate([[0.0], np.arange(n_c) + 0.5, [float(n_c)]])
        ys = tr.f + tr.e * np.concatenate([[0.0], np.arange(n_r) + 0.5, [float(n_r)]])
        zz = np.pad(z, 1, mode="edge")
        gx, gy = np.meshgrid(xs, ys)
        lon, lat = warp(grid.crs, CRS.from_proj4("+proj=longlat +R=1737400 +no_defs"),
                        gx.ravel().tolist(), gy.ravel().tolist())
        lat, lon = np.radians(lat), np.radians(lon)
        unit = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], 1)
        self.shape = zz.shape
        self.unit = unit
        self.verts = np.ascontiguousarray(unit * ((MOON_R_M + zz.ravel()) / 1000.0)[:, None])
        vi = np.arange(zz.size).reshape(zz.shape) + 1  # 1-based for SPICE
        a, b = vi[:-1, :-1].ravel(), vi[:-1, 1:].ravel()
        c, d = vi[1:, 1:].ravel(), vi[1:, :-1].ravel()
        # Twist of each bilinear patch (corners a, b, c, d round the quad): t > 0 puts the
        # patch below the a-c split and above the b-d split.
        t = zz[:-1, :-1] - zz[:-1, 1:] + zz[1:, 1:] - zz[1:, :-1]
        t = t.ravel()[:, None]
        ac = (np.stack([a, b, c], 1), np.stack([a, c, d], 1))
        bd = (np.stack([a, b, d], 1), np.stack([b, c, d], 1))
        plates = {
            "low": np.concatenate([np.where(t > 0, bd[k], ac[k]) for k in range(2)]),
            "high": np.concatenate([np.where(t > 0, ac[k], bd[k]) for k in range(2)]),
        }
        self.files = {}
        for name, p in plates.items():
            p = self._outward(p)
            self.files[name] = self._write(folder / f"crop_{name}.bds", SURF[name], p)
            spice.furnsh(str(self.files[name]))
        self.n_plates = len(plates["low"])
        self.rays = 0

    def _outward(self, p: np.ndarray) -> np.ndarray:
        v = self.verts
        v0, v1, v2 = v[p[:, 0] - 1], v[p[:, 1] - 1], v[p[:, 2] - 1]
        outward = (np.cross(v1 - v0, v2 - v0) * v0).sum(1) > 0
        p = np.where(outward[:, None], p, p[:, [0, 2, 1]])
        return np.ascontiguousarray(p, dtype=np.int32)

    def _write(self, path: Path, surf: int, plates: np.ndarray) -> Path:
        v = self.verts
        nv, npl = len(v), len(plates)
        voxpsz, voxlsz, worksz = 200_000, 4_000_000, 4_000_000
        spxisz = 100_007 + voxpsz + voxlsz + nv + 3 * npl // 2 + 1  # SPICE_DSK02_IXIFIX = 100007
        spaixd, spaixi = spice.dskmi2(v, plates, 1.5, 6, worksz, voxpsz, voxlsz, False, spxisz)
        lo, hi = v.min(0) - 1e-3, v.max(0) + 1e-3
        handle = spice.dskopn(str(path), "penumbra DSK oracle", 0)
        spice.dskw02(handle, 301, surf, 2, "MOON_ME", 3, np.zeros(10), lo[0], hi[0], lo[1], hi[1],
                     lo[2], hi[2], -3.2e9, 3.2e9, v, plates, spaixd, spaixi)
        spice.dskcls(handle, True)
        return path

    def vertex(self, rows, cols) -> np.ndarray:
        return (np.asarray(rows) + 1) * self.shape[1] + (np.asarray(cols) + 1)

    def observers(self, rows, cols) -> tuple[np.ndarray, np.ndarray]:
        """Observer points (km, MOON_ME) and their radial unit vectors, at pixel centres."""
        k = self.vertex(rows, cols)
        up = self.unit[k]
        return self.verts[k] + up * (OBS_H_M / 1000.0), up

    def blocked(self, surf: str, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        out = np.zeros(len(origins), dtype=bool)
        step = 20_000
        for i in range(0, len(origins), step):
            o = np.ascontiguousarray(origins[i:i + step], dtype=np.float64)
            d = np.ascontiguousarray(dirs[i:i + step], dtype=np.float64)
            xpt, found = spice.dskxv(False, "MOON", [SURF[surf]], 0.0, "MOON_ME", o, d)
            found = np.asarray(found, dtype=bool)
            # A hit must lie ahead of the observer (it stands 2 m above its own vertex).
            far = np.linalg.norm(np.asarray(xpt) - o, axis=1) > 1e-6
            out[i:i + step] = found & far
        self.rays += len(origins)
        return out

    def verticals(self, surf, obs, up, sun, d_el_deg) -> np.ndarray:
        """Blocked at the Sun's azimuth, at the Sun centre's elevation + d_el_deg."""
        el = np.arcsin(np.clip((sun * up).sum(1), -1, 1))
        h = sun - up * np.sin(el)[:, None]
        h /= np.linalg.norm(h, axis=1)[:, None]
        e = el + math.radians(d_el_deg)
        d = h * np.cos(e)[:, None] + up * np.sin(e)[:, None]
        return self.blocked(surf, obs, d)

    def discs(self, surf, obs, up, sun, radius, hint_lit) -> tuple[np.ndarray, np.ndarray]:
        """Visible fraction of uniform discs (centre `sun` unit vectors, `radius` rad) and
        whether any part is visible."""
        nd = len(obs)
        # Local north / east at each observer (any horizontal basis would do).
        z = np.array([0.0, 0.0, 1.0])
        east = np.cross(z, up)
        east /= np.linalg.norm(east, axis=1)[:, None]
        north = np.cross(up, east)
        su, sn, se = (sun * up).sum(1), (sun * north).sum(1), (sun * east).sum(1)
        el_c = np.arcsin(np.clip(su, -1, 1))
        az_c = np.arctan2(se, sn)
        x = ((np.arange(N_STRIPS) + 0.5) / N_STRIPS * 2.0 - 1.0)[None, :] * radius[:, None]
        az = az_c[:, None] + x / np.cos(el_c)[:, None]  # (nd, K)
        hn, he = np.cos(az), np.sin(az)
        hs = hn * sn[:, None] + he * se[:, None]  # h . sun
        amp = np.hypot(hs, su[:, None])
        phi = np.arctan2(su[:, None], hs)
        half = np.arccos(np.clip(np.cos(radius)[:, None] / amp, -1.0, 1.0))
        lo_el, hi_el = phi - half, phi + half  # the strip's chord of the cap
        eps = 1e-9

        def cast(ii, kk, el):
            h = (hn[ii, kk, None] * north[ii] + he[ii, kk, None] * east[ii])
            d = h * np.cos(el)[:, None] + up[ii] * np.sin(el)[:, None]
            return self.blocked(surf, obs[ii], d)

        ii = np.repeat(np.arange(nd), N_STRIPS)
        kk = np.tile(np.arange(N_STRIPS), nd)
        lo_f, hi_f = lo_el.ravel(), hi_el.ravel()
        # 1. Lit-looking discs cast each strip's bottom limb (lit: the whole strip is lit), the
        #    others its top limb (blocked: the whole strip is dark).
        bottom_first = np.asarray(hint_lit)[ii]
        b0 = cast(ii, kk, np.where(bottom_first, lo_f + eps, hi_f - eps))
        full = bottom_first & ~b0
        dark = ~bottom_first & b0
        # 2. The other limb of the strips left.
        rest = ~(full | dark)
        b1 = np.zeros_like(rest)
        b1[rest] = cast(ii[rest], kk[rest],
                        np.where(bottom_first[rest], hi_f[rest] - eps, lo_f[rest] + eps))
        dark |= rest & bottom_first & b1
        full |= rest & ~bottom_first & ~b1
        # 3. Strips with a blocked bottom and a lit top: bisect the boundary.
        cut = ~(full | dark)
        boundary = np.where(full, lo_f, hi_f)  # the blocked directions: el < boundary
        lo, hi = lo_f[cut], hi_f[cut]
        for _ in range(N_BISECT):
            mid = 0.5 * (lo + hi)
            b = cast(ii[cut], kk[cut], mid)
            lo, hi = np.where(b, mid, lo), np.where(b, hi, mid)
        boundary[cut] = 0.5 * (lo + hi)
        boundary = boundary.reshape(nd, N_STRIPS)
        vis = np.sin(hi_el) - np.sin(boundary)
        tot = np.sin(hi_el) - np.sin(lo_el)
        return vis.sum(1) / tot.sum(1), (~dark).reshape(nd, N_STRIPS).any(1)


def _sun(obs_km: np.ndarray, ets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors to the Sun (LT+S, MOON_ME) from each observer at each epoch, and the disc
    radius (rad): arrays (n_obs, n_et, 3) and (n_obs, n_et)."""
    out = np.zeros((len(obs_km), len(ets), 3))
    for i, o in enumerate(obs_km):
        for j, et in enumerate(ets):
            st, _ = spice.spkcpo("SUN", float(et), "MOON_ME", "OBSERVER", "LT+S", o.tolist(),
                                 "MOON", "MOON_ME")
            out[i, j] = st[:3]
    rng = np.linalg.norm(out, axis=2)
    return out / rng[..., None], np.arcsin(SUN_R_KM / rng)


@pytest.fixture(scope="module")
def grid(lola: Path, tmp_path_factory) -> Grid:
    folder = tmp_path_factory.mktemp("dsk_oracle")
    with rasterio.open(lola / "ldem75s_crop_240m_pm184km.tif") as src:
        z = src.read(1, window=WINDOW)
        profile = src.profile.copy()
        tr = src.transform @ Affine.translation(WINDOW.col_off, WINDOW.row_off)
        crs = src.crs
        tags = src.tags()
    for k in ("blockxsize", "blockysize", "tiled", "compress"):
        profile.pop(k, None)
    profile.update(width=WINDOW.width, height=WINDOW.height, transform=tr)
    tif = folder / "crop.tif"
    with rasterio.open(tif, "w", **profile) as dst:
        dst.write(z, 1)
        dst.update_tags(**tags)
    assert np.isfinite(z).all() and np.abs(z).max() < 10_000  # heights in metres
    return Grid(tif, z, tr, crs)


@pytest.fixture(scope="module")
def oracle(grid: Grid):
    t0 = time.perf_counter()
    spice.kclear()
    for k in KERNEL_FILES:
        spice.furnsh(str(KERNELS / k))
    try:
        o = Oracle(grid, grid.tif.parent)
        _timed(f"two DSKs of {o.n_plates} plates written", t0)
        yield o
    finally:
        spice.kclear()


def _pick_sites(z: np.ndarray) -> list[tuple[int, int]]:
    """36 pixel centres 8 px or more inside the window and 4 px or more apart: 10 highest local
    maxima (5 x 5), 8 most convex (rims and ridges: the most negative Laplacian), 8 steepest,
    10 at random."""
    n = z.shape[0]
    m = 8
    inner = np.zeros_like(z, dtype=bool)
    inner[m:n - m, m:n - m] = True
    pad = np.pad(z, 2, mode="edge")
    win = np.stack([pad[i:i + n, j:j + n] for i in range(5) for j in range(5)])
    peak = (z >= win.max(0)) & inner
    lap = (np.roll(z, 1, 0) + np.roll(z, -1, 0) + np.roll(z, 1, 1) + np.roll(z, -1, 1) - 4 * z)
    gy, gx = np.gradient(z)
    slope = np.hypot(gx, gy)
    chosen: list[tuple[int, int]] = []

    def take(score, count, mask):
        order = np.argsort(-np.where(mask, score, -np.inf), axis=None)
        for flat in order:
            r, c = divmod(int(flat), n)
            # At least 4 px from every site taken: no clusters on one ridge.
            if mask[r, c] and all(max(abs(r - a), abs(c - b)) >= 4 for a, b in chosen):
                chosen.append((r, c))
                count -= 1
            if count == 0:
                return

    take(z, 10, peak)
    take(-lap, 8, inner)
    take(slope, 8, inner)
    rng = np.random.default_rng(48)
    take(rng.random(z.shape), 10, inner)
    assert len(chosen) == N_SITES
    return chosen


@pytest.fixture(scope="module")
def site_run(cli: Path, grid: Grid, oracle: Oracle):
    """penumbra series at the 36 pixel centres, and the oracle's verdicts, fractions and
    any-part flags per site and epoch on both DSKs (shared by the series and the statistics)."""
    t0 = time.perf_counter()
    folder = grid.tif.parent
    pixels = _pick_sites(grid.z)
    run_cli(cli, folder, "series", "--dem", str(grid.tif), *pixel_sites(grid.transform, grid.crs,
            pixels), "--start", START, "--stop", STOP, "--step", STEP, "--observer-height-m",
            str(OBS_H_M), "--limb-darkening", "none", "--stations", "none",
            "--neighbourhood-m", "0", "--no-plots", "--backend", "cpu", "--out-dir", "series")
    tables = [pd.read_csv(folder / "series" / f"p{i}" / "series.csv") for i in range(len(pixels))]
    t0 = _timed(f"penumbra series, {len(pixels)} sites x {len(tables[0])} epochs", t0)
    ets = np.array([spice.str2et(u.rstrip("Z")) for u in tables[0].utc])
    rows = np.array([p[0] for p in pixels])
    cols = np.array([p[1] for p in pixels])
    obs, up = oracle.observers(rows, cols)
    sun, radius = _sun(obs, ets)
    t0 = _timed("SPICE Sun vectors", t0)
    ns, ne = len(pixels), len(ets)
    o_flat = np.repeat(obs, ne, axis=0)
    u_flat = np.repeat(up, ne, axis=0)
    s_flat = sun.reshape(-1, 3)
    r_flat = radius.ravel()
    res = {}
    for surf in SURF:
        below = oracle.verticals(surf, o_flat, u_flat, s_flat, -MARGIN_DEG)
        above = oracle.verticals(surf, o_flat, u_flat, s_flat, +MARGIN_DEG)
        frac, anyv = oracle.discs(surf, o_flat, u_flat, s_flat, r_flat, ~below)
        res[surf] = dict(below=below.reshape(ns, ne), above=above.reshape(ns, ne),
                         frac=frac.reshape(ns, ne), any=anyv.reshape(ns, ne))
    _timed(f"oracle rays, {ns} x {ne} discs x 2 DSKs ({oracle.rays} rays so far)", t0)
    pen_el = np.array([t.sun_el_deg.to_numpy() for t in tables])
    pen_hz = np.array([t.sun_horizon_el_deg.to_numpy() for t in tables])
    pen_f = np.array([t.sun_visible_fraction.to_numpy() for t in tables])
    # The oracle's Sun elevation against penumbra's (both above the observer's radial plane).
    el = np.degrees(np.arcsin((sun * up[:, None, :]).sum(2)))
    assert np.abs(el - pen_el).max() < 1e-5, np.abs(el - pen_el).max()
    return dict(pixels=pixels, ets=ets, oracle=res, pen_lit=pen_el > pen_hz, pen_f=pen_f,
                sun_el=el, obs=obs, up=up, sun=sun, radius=radius, o=oracle)


def _interval_distance(x, a, b):
    return np.maximum(0.0, np.maximum(np.minimum(a, b) - x, x - np.maximum(a, b)))


def test_series_lit_unlit_agrees_with_dsk_ray_casting(site_run) -> None:
    o = site_run["oracle"]
    # Margin > 0.1 deg on a DSK: the Sun's vertical is blocked at both el - 0.1 and el + 0.1,
    # or at neither; stable: both DSKs say so, and the same.
    verdicts = []
    for surf in SURF:
        b, a = o[surf]["below"], o[surf]["above"]
        verdicts.append(np.where(b == a, (~a).astype(int), -1))  # 1 lit, 0 dark, -1 no margin
    stable = (verdicts[0] >= 0) & (verdicts[0] == verdicts[1])
    oracle_lit = verdicts[0] == 1
    agree = (site_run["pen_lit"] == oracle_lit)[stable]
    n_sites, n_epochs = stable.shape
    frac_ok = agree.mean()
    lit_share = oracle_lit[stable].mean()
    misses = (stable & (site_run["pen_lit"] != oracle_lit)).sum(1)
    print(f"\n[dsk-oracle] series lit/unlit: {agree.sum()} / {agree.size} stable epochs agree "
          f"({100 * frac_ok:.3f} %; {n_sites} sites x {n_epochs} epochs, "
          f"{100 * (1 - stable.mean()):.2f} % left out: margin <= {MARGIN_DEG} deg or low/high "
          f"disagree; {100 * lit_share:.1f} % lit); most misses at one site {misses.max()}")
    assert stable.mean() > 0.5 and 0.05 < lit_share < 0.95
    assert frac_ok >= SERIES_AGREE_MIN, frac_ok


def test_series_fraction_matches_dsk_disc_sampling(site_run) -> None:
    o = site_run["oracle"]
    fl, fh = o["low"]["frac"], o["high"]["frac"]
    pen = site_run["pen_f"]
    d = _interval_distance(pen, fl, fh)
    raw = np.abs(pen - 0.5 * (fl + fh))
    cut = ((fl > 1e-9) & (fh < 1 - 1e-9)) | ((pen > 1e-9) & (pen < 1 - 1e-9))
    spread = np.abs(fl - fh)
    print(f"\n[dsk-oracle] series fraction: {d.size} site-epochs, mean |df| to [low, high] "
          f"{d.mean():.5f} (raw to the mid {raw.mean():.5f}), max {d.max():.4f}; "
          f"{cut.sum()} partial: mean {d[cut].mean():.4f}, raw {raw[cut].mean():.4f}, "
          f"p99 {np.percentile(d[cut], 99):.4f}; plate spread mean {spread[cut].mean():.4f}")
    assert cut.sum() >= 100
    # The strips against plain disc sampling: 1024 rays on a Vogel spiral (its own error for a
    # disc cut by a line is ~ N^-3/4 = 0.006), at 20 cut discs on the high DSK.
    o = site_run["o"]
    i_s, i_e = np.nonzero((fh > 0.05) & (fh < 0.95))
    pick = np.linspace(0, len(i_s) - 1, 20).astype(int)
    n_ray = 1024
    k = np.arange(n_ray) + 0.5
    worst = 0.0
    for j in pick:
        s0 = site_run["sun"][i_s[j], i_e[j]]
        rho = np.sqrt(k / n_ray) * site_run["radius"][i_s[j], i_e[j]]
        th = k * math.pi * (3.0 - math.sqrt(5.0))
        a = np.cross(s0, [0.0, 0.0, 1.0])
        a /= np.linalg.norm(a)
        b = np.cross(s0, a)
        dirs = (np.cos(rho)[:, None] * s0 + np.sin(rho)[:, None]
                * (np.cos(th)[:, None] * a + np.sin(th)[:, None] * b))
        origin = np.repeat(site_run["obs"][i_s[j]][None, :], n_ray, axis=0)
        spiral = 1.0 - o.blocked("high", origin, dirs).mean()
        worst = max(worst, abs(spiral - fh[i_s[j], i_e[j]]))
    print(f"[dsk-oracle] oracle strips vs a 1024-ray spiral at 20 cut discs: max |df| {worst:.4f}")
    assert worst <= 0.01, worst
    assert d[cut].mean() <= FRACTION_MEAN_MAX, d[cut].mean()


@pytest.fixture(scope="module")
def map_oracle(grid: Grid, oracle: Oracle):
    """The oracle at every pixel for one epoch: centre verdicts on both DSKs (hard mask) and
    the disc fraction on every second pixel of every second row."""
    t0 = time.perf_counter()
    n_r, n_c = grid.z.shape
    rows = np.repeat(np.arange(n_r), n_c)
    cols = np.tile(np.arange(n_c), n_r)
    obs, up = oracle.observers(rows, cols)
    centre, _ = oracle.observers(np.array([n_r // 2]), np.array([n_c // 2]))
    et = spice.str2et(MAP_UTC)
    s, radius = _sun(centre, np.array([et]))
    sun = np.repeat(s.reshape(1, 3), len(obs), axis=0)
    lit = {surf: ~oracle.blocked(surf, obs, sun) for surf in SURF}
    sub = (rows % 2 == 0) & (cols % 2 == 0)
    rad = np.full(sub.sum(), float(radius[0, 0]))
    frac = {}
    for surf in SURF:
        frac[surf], _ = oracle.discs(surf, obs[sub], up[sub], sun[sub], rad, lit[surf][sub])
    el_c = np.degrees(np.arcsin((sun[0] * up[len(up) // 2]).sum()))
    _timed(f"oracle map at {MAP_UTC} (Sun {el_c:.2f} deg at the centre): {len(obs)} px hard, "
           f"{sub.sum()} px soft, both DSKs ({oracle.rays} rays so far)", t0)
    shape = grid.z.shape
    return dict(lit={k: v.reshape(shape) for k, v in lit.items()}, sub=sub.reshape(shape),
                frac={k: v.reshape(n_r // 2, n_c // 2) for k, v in frac.items()})


@pytest.fixture(scope="module")
def light_maps(cli: Path, grid: Grid):
    """`penumbra map` at MAP_UTC per engine (run once each): (hard mask, Sun fraction)."""
    done: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def get(engine: str):
        if engine not in done:
            t0 = time.perf_counter()
            folder = grid.tif.parent / f"map_{engine}"
            folder.mkdir()
            run_cli(cli, folder, "map", "--dem", str(grid.tif), "--utc", MAP_UTC, "--engine",
                    engine, "--backend", "cpu", "--observer-height-m", str(OBS_H_M),
                    "--out-fraction", "f.tif", "--out-mask", "m.tif")
            with rasterio.open(folder / "m.tif") as ds:
                mask = ds.read(1)
            with rasterio.open(folder / "f.tif") as ds:
                f = ds.read(1).astype(np.float64)
            done[engine] = (mask, f)
            _timed(f"penumbra map --engine {engine} at {MAP_UTC}", t0)
        return done[engine]

    return get


def _ring(shape, width: int) -> np.ndarray:
    """Pixels within `width` px of the window's edge."""
    r, c = np.indices(shape)
    return (r < width) | (c < width) | (r >= shape[0] - width) | (c >= shape[1] - width)


# Measured at 2025-03-01T00:00 (Sun 0.67 deg at the centre; the numbers the tests print).
# The hard masks passed once the maps marched their near field (16 px) on the DEM's own lattice,
# its outer half pixel included (src/model/near_field.rs): 0.073 % (combined) and 0.061 % (dp) of
# the stable pixels off, none on the outermost ring (before: 0.996 % / 0.935 %, 123 on the ring).
# The soft fractions still miss the mean on the partial pixels near the window's edge: rays that
# run along the edge beyond the near field cross the outer half-pixel strip, which the model grid
# (a hole past it) does not hold; a DEM with a far-field layer has no such strip. Inside the
# window they are within the target.
SOFT_XFAIL = {
    "combined": "soft Sun fraction, 85 partial px (of 4,096): mean |df| to [low, high] 0.0267 > "
                "0.02, p99 0.66, max 0.66, all of the large ones within 10 px of the window's "
                "last row or column (rays along the edge beyond the 16 px near field); the 59 "
                "partial px >= 18 px from the last row / column: mean 0.0056, p99 0.054 "
                "(before the near field on the DEM lattice: 0.0485 overall, 0.0175 inside)",
    "dp": "soft Sun fraction, 85 partial px (of 4,096): mean |df| to [low, high] 0.0267 > 0.02, "
          "p99 0.66 (edge strip beyond the near field); the 59 partial px >= 18 px from the last "
          "row / column: mean 0.0056, p99 0.054",
}


@pytest.mark.parametrize("engine", ["combined", "dp"])
def test_one_light_hard_mask_matches_dsk_ray_casting(engine: str, map_oracle, light_maps) -> None:
    mask, _ = light_maps(engine)
    lo, hi = map_oracle["lit"]["low"], map_oracle["lit"]["high"]
    valid = mask != 255
    stable = (lo == hi) & valid
    wrong = stable & ((mask == 1) != hi)
    rate = wrong.sum() / stable.sum()
    ring = _ring(mask.shape, 1)
    inner = stable & ~ring
    rr, cc = np.nonzero(wrong)
    print(f"\n[dsk-oracle] map {engine} hard mask at {MAP_UTC}: differs at {wrong.sum()} of "
          f"{stable.sum()} stable px ({100 * rate:.3f} %; penumbra lit / oracle dark "
          f"{(wrong & (mask == 1)).sum()}); {(~stable & valid).sum()} px left out (low/high "
          f"differ); {100 * hi[stable].mean():.1f} % lit; on the outermost ring "
          f"{(wrong & ring).sum()}, inside it {(wrong & ~ring).sum()} of {inner.sum()} "
          f"({100 * (wrong & ~ring).sum() / inner.sum():.3f} %); first "
          f"{[(int(a), int(b)) for a, b in zip(rr, cc)][:6]}")
    assert 0.05 < hi[stable].mean() < 0.95
    assert rate <= MASK_DIFF_MAX, rate


@pytest.mark.parametrize("engine", [
    pytest.param(e, marks=pytest.mark.xfail(strict=True, reason=SOFT_XFAIL[e]))
    for e in ("combined", "dp")])
def test_one_light_soft_fraction_matches_dsk_disc_sampling(engine: str, map_oracle,
                                                           light_maps) -> None:
    _, f = light_maps(engine)
    pen = f[::2, ::2]
    fl, fh = map_oracle["frac"]["low"], map_oracle["frac"]["high"]
    ok = np.isfinite(pen)
    d = np.where(ok, _interval_distance(pen, fl, fh), 0.0)
    cut = ok & (((fl > 1e-9) & (fh < 1 - 1e-9)) | ((pen > 1e-9) & (pen < 1 - 1e-9)))
    rr, cc = np.indices(pen.shape)
    far = cut & (rr < pen.shape[0] - 9) & (cc < pen.shape[1] - 9)  # >= 18 px from the end
    worst = np.argsort(-(d * cut), axis=None)[:5]
    rows = [(2 * int(i // pen.shape[1]), 2 * int(i % pen.shape[1]),
             round(float(pen.flat[i]), 3), round(float(fl.flat[i]), 3),
             round(float(fh.flat[i]), 3)) for i in worst]
    print(f"\n[dsk-oracle] map {engine} soft Sun fraction at {MAP_UTC} on {ok.sum()} px (every "
          f"2nd row and column): mean |df| to [low, high] {d[ok].mean():.5f}, max "
          f"{d[ok].max():.4f}; {cut.sum()} partial px: mean {d[cut].mean():.4f}, p99 "
          f"{np.percentile(d[cut], 99):.4f}; {far.sum()} of them >= 18 px from the last row / "
          f"column: mean {d[far].mean():.4f}, p99 {np.percentile(d[far], 99):.4f}; plate spread "
          f"mean {np.abs(fl - fh)[cut].mean():.4f}; worst (row, col, penumbra, low, high) {rows}")
    assert cut.sum() >= 50
    assert d[cut].mean() <= FRACTION_MEAN_MAX, d[cut].mean()


STATS_XFAIL = ("map --engine combined, 36 px x 241 epochs: average illumination 0.654 pp from "
               "[low, high] at (118, 84) (36.49 % vs 35.84 %; 9 px from the window's last row: "
               "the edge strip beyond the near field), 35 / 36 within 0.5 pp; Sun visible % max "
               "0.415 pp (36 / 36); `--engine horizons` passes at the same pixels (max 0.000 pp "
               "and 0.019 pp)")


@pytest.mark.parametrize("engine", [
    pytest.param("combined", marks=pytest.mark.xfail(strict=True, reason=STATS_XFAIL)),
    "horizons"])
def test_map_statistics_match_dsk_ray_casting(engine: str, cli: Path, grid: Grid, site_run,
                                              tmp_path: Path) -> None:
    t0 = time.perf_counter()
    run_cli(cli, tmp_path, "map", "--dem", str(grid.tif), "--start", START, "--stop", STOP,
            "--step", STEP, "--engine", engine, "--backend", "cpu", "--observer-height-m",
            str(OBS_H_M), "--limb-darkening", "none", "--out-dir", "m")
    _timed(f"penumbra map statistics --engine {engine}", t0)
    rows = [p[0] for p in site_run["pixels"]]
    cols = [p[1] for p in site_run["pixels"]]
    with rasterio.open(tmp_path / "m" / "sun_visible_pct.tif") as ds:
        assert ds.tags()["epochs"] == str(len(site_run["ets"]))
        vis = ds.read(1).astype(np.float64)[rows, cols]
    with rasterio.open(tmp_path / "m" / "sun_illumination_pct.tif") as ds:
        ill = ds.read(1).astype(np.float64)[rows, cols]
    o = site_run["oracle"]
    out = []
    for name, pen, key in (("Sun visible %", vis, "any"), ("average illumination %", ill, "frac")):
        a = 100.0 * o["low"][key].mean(1)
        b = 100.0 * o["high"][key].mean(1)
        d = _interval_distance(pen, a, b)
        raw = np.abs(pen - 0.5 * (a + b))
        out.append((name, d))
        bad = [(site_run["pixels"][k], round(float(pen[k]), 2), round(float(a[k]), 2),
                round(float(b[k]), 2)) for k in np.argsort(-d)[:3] if d[k] > STATS_PP_MAX]
        print(f"\n[dsk-oracle] map {engine} {name} at {len(pen)} px over "
              f"{len(site_run['ets'])} epochs: max {d.max():.3f} pp to [low, high] (mean "
              f"{d.mean():.3f}; raw to the mid max {raw.max():.3f}, mean {raw.mean():.3f}; "
              f"low/high spread max {np.abs(a - b).max():.3f}, mean "
              f"{np.abs(a - b).mean():.3f} pp); "
              f"within {STATS_PP_MAX} pp: {(d <= STATS_PP_MAX).sum()} / {len(d)}; beyond "
              f"(pixel, penumbra, low, high): {bad}")
    for name, d in out:
        assert d.max() <= STATS_PP_MAX, (name, d.max())
