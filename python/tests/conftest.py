"""Shared fixtures: the repository, the CLI binary (to compare against), the shared LOLA data."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SHARED = Path(os.environ.get("PENUMBRA_SHARED", ROOT.parent / "shared"))
LOLA = SHARED / "data" / "lola-south-pole-moondao"


def missing(need: str, what: str, provide: str) -> None:
    """No hollow pass (as tests/it/util.rs `missing`): a missing prerequisite fails the test
    naming it, unless PENUMBRA_SKIP (comma-separated: gpu, gdal, lola, tools) lists it; then
    the test is skipped, and pytest's summary counts it."""
    allowed = need in [k.strip() for k in os.environ.get("PENUMBRA_SKIP", "").split(",")]
    if allowed:
        pytest.skip(f"{what} is missing (PENUMBRA_SKIP={need})")
    pytest.fail(f"missing {what}: {provide} (or PENUMBRA_SKIP={need} to skip)", pytrace=False)


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def cli() -> Path:
    """The command line built from the same sources (`cargo build --release`)."""
    exe = Path(os.environ.get("PENUMBRA_CLI", ROOT / "target" / "release" / "penumbra"))
    if not exe.is_file():
        pytest.skip(f"the penumbra binary {exe} is absent (cargo build --release)")
    return exe


def run_cli(cli: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env.pop("PENUMBRA_KERNELS", None)
    env.setdefault("XDG_RUNTIME_DIR", "/tmp")
    r = subprocess.run([str(cli), *args], cwd=cwd, capture_output=True, text=True, env=env)
    assert r.returncode == 0, f"penumbra {' '.join(args)} failed: {r.stderr}"
    return r


@pytest.fixture(scope="session")
def lola() -> Path:
    crop = LOLA / "ldem75s_crop_240m_pm184km.tif"
    if not crop.is_file():
        missing(
            "lola",
            f"the shared LOLA grid {crop}",
            "set PENUMBRA_SHARED to the folder that holds data/lola-south-pole-moondao/",
        )
    return LOLA


def pixel_sites(transform, crs, pixels) -> list[str]:
    """`--site pI,LAT,LON` flags at the centres of raster `pixels` ((row, col) pairs), the
    latitudes and longitudes from PROJ (rasterio) on the 1737.4 km sphere, not from penumbra."""
    from rasterio.crs import CRS
    from rasterio.warp import transform as warp

    xs = [transform.c + transform.a * (c + 0.5) for _, c in pixels]
    ys = [transform.f + transform.e * (r + 0.5) for r, _ in pixels]
    lon, lat = warp(crs, CRS.from_proj4("+proj=longlat +R=1737400 +no_defs"), xs, ys)
    return [a for i, (la, lo) in enumerate(zip(lat, lon))
            for a in ("--site", f"p{i},{la:.9f},{lo:.9f}")]
