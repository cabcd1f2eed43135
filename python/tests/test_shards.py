"""Sharded maps through the Python module and Dask: the bytes of the CLI's single run.

`map_shard` + `merge_shards` against `penumbra map` (no shards) on a synthetic DEM; shards made
by the CLI and by Python merge together (one job); and the Dask example on a `LocalCluster`
(two worker processes) gives the same bytes again.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path
from typing import Dict, Tuple

import numpy as np
import pytest

import penumbra

from conftest import run_cli

START, STOP, STEP = "2025-01-01", "2025-01-06", "8h"


def map_files(folder: Path) -> Dict[str, bytes]:
    files = {p.name: p.read_bytes() for p in folder.iterdir() if p.name != "run.json"}
    assert len(files) >= 20, sorted(files)
    return files


@pytest.fixture(scope="module")
def single(cli: Path, root: Path, tmp_path_factory: pytest.TempPathFactory) -> Tuple[Dict[str, bytes], Path]:
    """The CLI's single run on the synthetic DEM written as a GeoTIFF, and that GeoTIFF."""
    d = tmp_path_factory.mktemp("single")
    run_cli(cli, d, "dem", "synth", "--size", "120", "--px-m", "150", "--seed", "4", "--out", "dem.tif")
    run_cli(cli, d, "map", "--dem", "dem.tif", "--start", START, "--stop", STOP, "--step", STEP,
            "--engine", "horizons", "--azimuths", "90", "--kernels", str(root / "kernels"),
            "--out-dir", "maps")
    return map_files(d / "maps"), d / "dem.tif"


def test_python_shards_merge_to_the_cli_single_run(
    single: Tuple[Dict[str, bytes], Path], cli: Path, root: Path, tmp_path: Path
) -> None:
    want, dem = single
    t = penumbra.Terrain.open([dem])
    dirs = [tmp_path / f"p{i}" for i in range(3)]
    for i, d in enumerate(dirs):
        if i == 1:
            continue
        m = penumbra.map_shard(t, START, STOP, STEP, d, i, 3, azimuths=90,
                               kernels=root / "kernels")
        assert (m["shard"], m["shards"], m["epoch_count"]) == (i, 3, 16)
        assert m["rows"][1] - m["rows"][0] == 40
    # Shard 1 by the command line, on the same terrain: the same job, it merges.
    run_cli(cli, tmp_path, "map", "--dem", str(dem), "--start", START, "--stop", STOP, "--step", STEP,
            "--azimuths", "90", "--kernels", str(root / "kernels"), "--shard", "1/3",
            "--out-dir", str(dirs[1]))
    penumbra.merge_shards(tmp_path / "merged", list(reversed(dirs)))
    assert map_files(tmp_path / "merged") == want
    with pytest.raises(penumbra.PenumbraError, match="missing shard"):
        penumbra.merge_shards(tmp_path / "again", dirs[:2])
    with pytest.raises(penumbra.PenumbraError, match="expected I/N"):
        penumbra.map_shard(t, START, STOP, STEP, tmp_path / "x", 3, 3)


def test_dask_local_cluster_gives_the_same_bytes(
    single: Tuple[Dict[str, bytes], Path], root: Path, tmp_path: Path
) -> None:
    """The example on the synthetic DEM made in memory (`Terrain.synthetic`): the same bytes as
    the CLI's run on `dem synth`'s GeoTIFF of it."""
    if importlib.util.find_spec("dask") is None or importlib.util.find_spec("distributed") is None:
        pytest.skip('dask.distributed is not installed (pip install "dask[distributed]")')
    env = dict(os.environ, PENUMBRA_EXAMPLE_QUICK="1", PENUMBRA_KERNELS=str(root / "kernels"))
    r = subprocess.run(
        [sys.executable, str(root / "examples" / "dask_sharded_map.py"), "--out", "maps",
         "--shards", "4", "--start", START, "--stop", STOP, "--step", STEP, "--workers", "2"],
        cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    assert "merged 4 shards" in r.stdout
    # The same maps, pixel for pixel and tag for tag, except the name of the DEM each says it
    # was made from (in memory here, `dem.tif` for the CLI): every GeoTIFF and PNG says it.
    import rasterio

    got = map_files(tmp_path / "maps")
    assert sorted(got) == sorted(single[0])
    for name in (n for n in got if n.endswith(".tif")):
        with rasterio.open(tmp_path / "maps" / name) as a, rasterio.open(single[1].parent / "maps" / name) as b:
            assert np.array_equal(a.read(), b.read(), equal_nan=True), name
            ta, tb = a.tags(), b.tags()
            assert ta.pop("dem_layers").startswith("synthetic south-polar DEM"), name
            assert tb.pop("dem_layers").startswith("dem.tif (sha256:"), name
            assert ta == tb, name
