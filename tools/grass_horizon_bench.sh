#!/usr/bin/env bash
# Whole-grid horizons, GRASS r.horizon against penumbra's line sweep, on the same DEM, in one run
# (issue 15 item 4). Prints both wall times and the throughput in pixel-azimuths per second.
#
#   tools/grass_horizon_bench.sh DEM.tif AZIMUTHS [PENUMBRA]
#
# Needs Debian's grass-core (`apt-get install grass-core`) and GDAL's tools. GRASS is given the
# DEM in its own projected CRS (its curvature model is the Earth's; the speed is what is compared)
# with `step = 360 / AZIMUTHS` and its default distance; penumbra sweeps the same grid (one layer)
# exactly on the sphere, `--azimuths AZIMUTHS`. Both run with every core they use: r.horizon is
# single-threaded in 8.2, penumbra uses rayon (set RAYON_NUM_THREADS=1 for a per-core figure).
set -euo pipefail
dem=$(realpath "$1"); az=$2; pen=$(realpath "${3:-target/release/penumbra}")
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
rows=$(gdalinfo "$dem" | sed -n 's/^Size is \([0-9]*\), \([0-9]*\)/\2/p')
cols=$(gdalinfo "$dem" | sed -n 's/^Size is \([0-9]*\), \([0-9]*\)/\1/p')
step=$(python3 -c "print(360/$az)")
grass -c "$dem" "$work/loc" -e >/dev/null 2>&1
t0=$(date +%s.%N)
grass "$work/loc/PERMANENT" --exec r.in.gdal --q input="$dem" output=dem >/dev/null 2>&1
t1=$(date +%s.%N)
grass "$work/loc/PERMANENT" --exec r.horizon --q elevation=dem step="$step" output=hor >/dev/null 2>&1
t2=$(date +%s.%N)
"$pen" horizon-map sweep --dem "$dem" --azimuths "$az" --out "$work/pen.tif" 2>"$work/pen.log"
t3=$(date +%s.%N)
python3 - "$rows" "$cols" "$az" "$t0" "$t1" "$t2" "$t3" "$work/pen.log" <<'PY'
import sys, re
rows, cols, az = map(int, sys.argv[1:4]); t0, t1, t2, t3 = map(float, sys.argv[4:8])
log = open(sys.argv[8]).read()
dirs = int(re.search(r"x (\d+) directions", log).group(1))
g, p = t2 - t1, t3 - t2
print(f"grid {rows} x {cols}, {az} azimuths requested")
print(f"GRASS r.horizon: {g:.1f} s, {rows*cols*az/g/1e6:.2f} M pixel-azimuths/s (1 thread)")
print(f"penumbra sweep:  {p:.1f} s, {rows*cols*dirs/p/1e6:.2f} M pixel-azimuths/s ({dirs} exact directions)")
print(f"ratio (penumbra/GRASS throughput): {rows*cols*dirs/p / (rows*cols*az/g):.2f}")
PY
