#!/usr/bin/env python3
"""How much a solar-array mast buys: one site at mast heights from 2 to 20 m.

The Connecting Ridge site on the real LOLA 240 m grid with its far-field layer, one year hourly
(2027): % of time any part of the Sun is visible, the mean visible fraction and the longest night
per height (CSV).

    python3 examples/mast_heights.py [--out mast.csv] [--data ../shared/data/lola-south-pole-moondao]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import penumbra

HERE = Path(__file__).resolve().parent
# The shared LOLA grids: $PENUMBRA_SHARED/data/..., else ../shared beside the repository.
DATA = (Path(os.environ.get("PENUMBRA_SHARED", HERE.parent.parent / "shared"))
        / "data" / "lola-south-pole-moondao")
SITE = (-89.4455, -137.3137)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DATA, help="folder of the LOLA grids")
    ap.add_argument("--out", type=Path, default=Path("mast.csv"), help="output table (CSV)")
    args = ap.parse_args()
    quick = os.environ.get("PENUMBRA_EXAMPLE_QUICK") == "1"

    terrain = penumbra.Terrain.open([
        args.data / "ldem75s_crop_240m_pm184km.tif",
        args.data / "ldem75s_far_1787m_pm457km_feathered.tif",
    ])
    heights = [2.0, 5.0, 10.0, 20.0] if quick else [2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 15.0, 20.0]
    times = penumbra.time_range("2027-01-01", "2027-02-28T18:00" if quick else "2027-12-31T23:00",
                                "6h" if quick else "1h")
    sites = [(f"mast_{h:g}m", SITE[0], SITE[1], h) for h in heights]
    _, stats = penumbra.series(terrain, sites, times)
    with open(args.out, "w") as f:
        f.write("height_m,sun_lit_pct,sun_mean_visible_fraction,longest_dark_h,earth_visible_pct\n")
        for h, s in zip(heights, stats["sites"]):
            f.write(f"{h:g},{s['sun_visible_pct']:.3f},{s['sun_mean_visible_fraction']:.4f},"
                    f"{s['longest_dark_h']:.0f},{s['earth_visible_pct']:.2f}\n")
            print(f"{h:5.1f} m: Sun visible {s['sun_visible_pct']:6.2f} %, "
                  f"longest night {s['longest_dark_h']:5.0f} h")
    print(f"table: {args.out}")


if __name__ == "__main__":
    main()
