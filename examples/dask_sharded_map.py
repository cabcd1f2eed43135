#!/usr/bin/env python3
"""A whole-grid illumination map as shards on a Dask cluster, merged into one run's files.

Each shard (a block of rows of the finest DEM layer) runs ``penumbra.map_shard`` on a Dask
worker, which opens the terrain itself and writes its partial into ``OUT.parts/shard-I``;
``penumbra.merge_shards`` then writes the maps of the whole job into ``OUT``: the bytes of one
``penumbra map --start … --stop … --step … --engine horizons`` run. A shard that fails is
retried by Dask and resumes its finished blocks of rows. By default a ``LocalCluster`` on this
machine; give ``--scheduler tcp://host:8786`` for a running cluster (the workers need penumbra,
the DEMs and the kernels at the same paths).

    python3 examples/dask_sharded_map.py --out maps --shards 4 \\
        --dem ../shared/data/lola-south-pole-moondao/ldem75s_crop_240m_pm184km.tif \\
        --start 2027-01-01 --stop 2028-01-01 --step 1h

Without ``--dem`` the synthetic DEM is used. Needs ``pip install "dask[distributed]"``.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import penumbra


def run_shard(
    dems: Optional[Sequence[str]],
    synthetic: Dict[str, Any],
    out_dir: str,
    shard: int,
    shards: int,
    options: Dict[str, Any],
) -> Dict[str, Any]:
    """One shard on a worker: open the terrain there, compute, return the shard's manifest."""
    terrain = (
        penumbra.Terrain.open([Path(d) for d in dems])
        if dems
        else penumbra.Terrain.synthetic(**synthetic)
    )
    # resume=True: a retried shard keeps the blocks of rows it had finished.
    return penumbra.map_shard(
        terrain, out_dir=Path(out_dir), shard=shard, shards=shards, resume=True, **options
    )


def sharded_map(
    client: Any,
    out: Path,
    shards: int,
    dems: Optional[Sequence[str]] = None,
    synthetic: Optional[Dict[str, Any]] = None,
    **options: Any,
) -> List[Dict[str, Any]]:
    """Runs the `shards` shards of a map through `client` and merges them into `out`; returns
    the shards' manifests (rows, wall time, peak memory)."""
    parts = Path(f"{out}.parts")
    dirs = [parts / f"shard-{i}" for i in range(shards)]
    futures = [
        client.submit(
            run_shard, dems, synthetic or {}, str(d), i, shards, options, retries=2, pure=False
        )
        for i, d in enumerate(dirs)
    ]
    manifests: List[Dict[str, Any]] = client.gather(futures)
    penumbra.merge_shards(out, dirs)
    return manifests


def main() -> None:
    from dask.distributed import Client, LocalCluster

    quick = os.environ.get("PENUMBRA_EXAMPLE_QUICK") == "1"
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("--out", type=Path, default=Path("maps"), help="output folder of the maps")
    ap.add_argument("--shards", type=int, default=4, help="number of shards (blocks of rows)")
    ap.add_argument("--dem", action="append", help="DEM layer (repeat; default: synthetic)")
    ap.add_argument("--start", default="2027-01-01")
    ap.add_argument("--stop", default="2027-01-03" if quick else "2027-02-01")
    ap.add_argument("--step", default="1h")
    ap.add_argument("--azimuths", type=int, default=90 if quick else 720)
    ap.add_argument("--scheduler", help="address of a running Dask scheduler")
    ap.add_argument("--workers", type=int, default=2, help="LocalCluster workers")
    args = ap.parse_args()
    options: Dict[str, Any] = {
        "start": args.start,
        "stop": args.stop,
        "step": args.step,
        "azimuths": args.azimuths,
    }
    synthetic = {"size_px": 120, "px_m": 150.0, "seed": 4} if quick else {}
    if args.scheduler:
        client = Client(args.scheduler)
    else:
        client = Client(LocalCluster(n_workers=args.workers, threads_per_worker=1))
    with client:
        manifests = sharded_map(client, args.out, args.shards, args.dem, synthetic, **options)
    for m in manifests:
        print(
            f"shard {m['shard']}/{m['shards']}: rows {m['rows'][0]}..{m['rows'][1]}, "
            f"{m['wall_time_s']:.1f} s, peak {(m['peak_rss_bytes'] or 0) / 1e6:.0f} MB"
        )
    print(f"merged {len(manifests)} shards -> {args.out}")


if __name__ == "__main__":
    main()
