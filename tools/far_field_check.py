#!/usr/bin/env python3
"""Does the far-field layer do its job in maps? (issue [1/7] acceptance)

Runs `penumbra map --start --stop --step` three times over the same epochs: (a) a crop of the
240 m grid alone, (b) the crop plus the far-field layer, (c) the full 240 m grid plus the far
field (the reference: the crop's terrain is identical, the reference has the true terrain
between the crop's edge and the far field's resolution). Compares `sun_visible_pct` (% of time
any part of the Sun is visible) and `sun_illumination_pct` (time-mean visible fraction, %) over
the cells deep inside the crop (a margin of --margin-px pixels left out).

  gdal_translate -srcwin 568 568 400 400 $D/ldem75s_crop_240m_pm184km.tif /tmp/crop96.tif
  /usr/bin/python3 tools/far_field_check.py --crop /tmp/crop96.tif \
      --full $D/ldem75s_crop_240m_pm184km.tif --far $D/ldem75s_far_1787m_pm457km_feathered.tif \
      --start 2025-01-01 --stop 2025-12-31 --step 5d
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from osgeo import gdal


def run_map(pen, dems, args, out):
    cmd = [pen, "map", *sum((["--dem", d] for d in dems), []), "--start", args.start, "--stop",
           args.stop, "--step", args.step, "--engine", args.engine, "--backend", "cpu",
           "--out-dir", out]
    t0 = time.time()
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(r.stderr)
    return time.time() - t0, r.stderr


def read(path):
    d = gdal.Open(path)
    return d.GetRasterBand(1).ReadAsArray().astype(np.float64), d.GetGeoTransform()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--penumbra", default="target/release/penumbra")
    ap.add_argument("--crop", required=True)
    ap.add_argument("--full", required=True)
    ap.add_argument("--far", required=True)
    ap.add_argument("--start", required=True)
    ap.add_argument("--stop", required=True)
    ap.add_argument("--step", required=True)
    ap.add_argument("--engine", default="dp")
    ap.add_argument("--margin-px", type=int, default=50)
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="far-field-")
    cases = {"crop": [args.crop], "crop+far": [args.crop, args.far],
             "full+far": [args.full, args.far]}
    res = {}
    for name, dems in cases.items():
        out = os.path.join(work, name)
        t, log = run_map(args.penumbra, dems, args, out)
        res[name] = dict(dir=out, wall_s=t, log=log.strip().splitlines()[:2])
    _, gt_c = read(args.crop)
    _, gt_f = read(args.full)
    # Offset of the crop inside the full grid (same pixel size and alignment).
    c0 = int(round((gt_c[0] - gt_f[0]) / gt_f[1]))
    r0 = int(round((gt_c[3] - gt_f[3]) / gt_f[5]))
    summary = {}
    for band in ["sun_visible_pct", "sun_illumination_pct"]:
        a = {k: read(os.path.join(v["dir"], band + ".tif"))[0] for k, v in res.items()}
        n = a["crop"].shape[0]
        m = args.margin_px
        inner = (slice(m, n - m), slice(m, n - m))
        ref = a["full+far"][r0 + m:r0 + n - m, c0 + m:c0 + n - m]
        for k in ["crop", "crop+far"]:
            d = a[k][inner] - ref
            summary[f"{band}: {k} - full+far"] = dict(
                mean_abs_pp=float(np.nanmean(np.abs(d))), mean_pp=float(np.nanmean(d)),
                p99_abs_pp=float(np.nanpercentile(np.abs(d), 99)),
                cells=int(np.isfinite(d).sum()))
    summary["wall_s"] = {k: round(v["wall_s"], 1) for k, v in res.items()}
    summary["grids"] = {k: v["log"] for k, v in res.items()}
    summary["epochs"] = f"{args.start}..{args.stop} every {args.step}, engine {args.engine}"
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
