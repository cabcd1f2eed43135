#!/usr/bin/env python3
"""Rank candidate landing sites along the Connecting Ridge by sunlight, night and Earth visibility.

Candidates every ~1 km on the line from the Connecting Ridge toward the Shackleton rim, 2 m above
the ground, on the real LOLA 240 m grid with its far-field layer; one year hourly (2027). The
table (CSV) ranks them by % of time any part of the Sun is visible, then by the longest night;
with matplotlib installed a bar chart is written beside it.

    python3 examples/rank_sites.py [--out ranking.csv] [--data ../shared/data/lola-south-pole-moondao]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any, Dict, List, Tuple

import numpy as np

import penumbra

HERE = Path(__file__).resolve().parent
# The shared LOLA grids: $PENUMBRA_SHARED/data/..., else ../shared beside the repository.
DATA = (Path(os.environ.get("PENUMBRA_SHARED", HERE.parent.parent / "shared"))
        / "data" / "lola-south-pole-moondao")


def candidates(n: int) -> List[Tuple[str, float, float, float]]:
    """`n` sites from the Connecting Ridge (-89.4455, -137.31) toward the Shackleton rim."""
    a, b = np.array([-89.4455, -137.31]), np.array([-89.62, -150.0])
    return [
        (f"c{i:02d}", float(lat), float(lon), 2.0)
        for i, (lat, lon) in enumerate(a + (b - a) * f for f in np.linspace(0.0, 1.0, n))
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DATA, help="folder of the LOLA grids")
    ap.add_argument("--out", type=Path, default=Path("ranking.csv"), help="output table (CSV)")
    args = ap.parse_args()
    quick = os.environ.get("PENUMBRA_EXAMPLE_QUICK") == "1"

    terrain = penumbra.Terrain.open([
        args.data / "ldem75s_crop_240m_pm184km.tif",
        args.data / "ldem75s_far_1787m_pm457km_feathered.tif",
    ])
    sites = candidates(6 if quick else 20)
    times = penumbra.time_range("2027-01-01", "2027-01-31T23:00" if quick else "2027-12-31T23:00",
                                "6h" if quick else "1h")
    _, stats = penumbra.series(
        terrain, sites, times,
        progress=lambda done, total: print(f"\r{done}/{total} sites", end="", flush=True),
    )
    print()
    by_name: Dict[str, Dict[str, Any]] = {s["site"]: s for s in stats["sites"]}
    ranked = sorted(
        sites,
        key=lambda s: (-by_name[s[0]]["sun_visible_pct"], by_name[s[0]]["longest_dark_h"]),
    )
    with open(args.out, "w") as f:
        f.write("rank,site,lat_deg,lon_deg,sun_visible_pct,sun_mean_visible_fraction,"
                "longest_dark_h,earth_visible_pct,sun_and_earth_pct\n")
        for rank, (name, lat, lon, _h) in enumerate(ranked, 1):
            s = by_name[name]
            f.write(f"{rank},{name},{lat:.5f},{lon:.4f},{s['sun_visible_pct']:.2f},"
                    f"{s['sun_mean_visible_fraction']:.4f},{s['longest_dark_h']:.0f},"
                    f"{s['earth_visible_pct']:.2f},{s['sun_and_earth_pct']:.2f}\n")
    best = by_name[ranked[0][0]]
    print(f"best site {ranked[0][0]} ({ranked[0][1]:.4f}, {ranked[0][2]:.3f}): "
          f"Sun visible {best['sun_visible_pct']:.1f} % of the time, longest night "
          f"{best['longest_dark_h']:.0f} h, Earth visible {best['earth_visible_pct']:.1f} %")
    print(f"table: {args.out}")
    try:
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(figsize=(8, 4))
    names = [s[0] for s in ranked]
    ax.bar(names, [by_name[n]["sun_visible_pct"] for n in names], label="Sun visible, %")
    ax.bar(names, [by_name[n]["earth_visible_pct"] for n in names], alpha=0.5,
           label="Earth visible, %")
    ax.set_ylabel("% of time")
    ax.set_title(f"Candidates along the Connecting Ridge, {str(times[0])[:10]} .. {str(times[-1])[:10]}")
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out.with_suffix(".png"), dpi=100)
    print(f"plot: {args.out.with_suffix('.png')}")


if __name__ == "__main__":
    main()
