#!/usr/bin/env bash
# The whole GPU benchmark set in one command, on a machine that has a GPU but no cargo.
#
#   tools/gpu-bench.sh --prepare   (on the build machine) builds the release bench binary,
#                                  the release penumbra and the debug integration-test binary,
#                                  strips them and stages them in target/gpu-bench/ (git-ignored,
#                                  ~25 MB: small enough to carry to a GPU machine);
#   tools/gpu-bench.sh [DIR]       (on the GPU machine, DIR defaults to target/gpu-bench) prints
#                                  `penumbra gpu-info`, runs the GPU-vs-CPU parity tests with
#                                  no adapter is a failure, then the criterion groups of
#                                  benches/gpu.rs (GPU and CPU twin side by side), the per-site
#                                  horizons, series_engines (smap-dp on the
#                                  CPU and the GPU) and the renderer, with WGPU_BACKEND=vulkan
#                                  (the GL backend fails on NVIDIA);
#   tools/gpu-bench.sh [DIR] --only stats,sweep
#                                  runs only the named sections (list below, before `dir=`).
#
# By hand, --prepare is: `cargo bench --bench gpu --no-run` (it prints the binary path,
# target/release/deps/gpu-<hash>), `cargo build --release`, `cargo test --test it --no-run`
# (target/debug/deps/it-<hash>); copy the three files into one folder, `strip` them, carry it.
set -euo pipefail

if [[ "${1:-}" == "--prepare" ]]; then
    out=target/gpu-bench
    mkdir -p "$out"
    bench=$(cargo bench --bench gpu --no-run --message-format=json 2>/dev/null |
        sed -n 's/.*"executable":"\([^"]*\/gpu-[0-9a-f]*\)".*/\1/p' | tail -1)
    render=$(cargo bench --bench render --no-run --message-format=json 2>/dev/null |
        sed -n 's/.*"executable":"\([^"]*\/render-[0-9a-f]*\)".*/\1/p' | tail -1)
    tests=$(cargo test --test it --no-run --message-format=json 2>/dev/null |
        sed -n 's/.*"executable":"\([^"]*\/it-[0-9a-f]*\)".*/\1/p' | tail -1)
    hbench=$(cargo bench --bench gpu_horizon --no-run --message-format=json 2>/dev/null |
        sed -n 's/.*"executable":"\([^"]*\/gpu_horizon-[0-9a-f]*\)".*/\1/p' | tail -1)
    sbench=$(cargo bench --bench series --no-run --message-format=json 2>/dev/null |
        sed -n 's/.*"executable":"\([^"]*\/series-[0-9a-f]*\)".*/\1/p' | tail -1)
    cargo build --release --bin penumbra
    [[ -x "$bench" && -x "$tests" && -x "$render" ]] || { echo "gpu-bench: build failed (bench '$bench', render '$render', tests '$tests')" >&2; exit 2; }
    cp "$bench" "$out/gpu-bench"
    cp "$render" "$out/render-bench"
    # The real 1536^2 LOLA grid for the 1080p render bench (9 MB; staged, never committed).
    lola=../shared/data/lola-south-pole-moondao/ldem75s_crop_240m_pm184km.tif
    if [[ -f "$lola" ]]; then cp "$lola" "$out/"; else echo "gpu-bench: $lola absent; render bench uses the synthetic DEM" >&2; fi
    # The far field for the line sweep's whole-grid figure (issue 15: 1536^2 x 720 + far field).
    far=../shared/data/lola-south-pole-moondao/ldem75s_far_1787m_pm457km_feathered.tif
    if [[ -f "$far" ]]; then cp "$far" "$out/"; fi
    cp "$tests" "$out/it-tests"
    cp target/release/penumbra "$out/penumbra"
    if [[ -x "$hbench" ]]; then cp "$hbench" "$out/gpu-horizon-bench"; strip "$out/gpu-horizon-bench"; fi
    # The series engines (smap-dp CPU vs GPU) need the SPICE kernels (4 MB).
    if [[ -x "$sbench" ]]; then
        cp "$sbench" "$out/series-bench"; strip "$out/series-bench"
        rm -rf "$out/kernels"; cp -r kernels "$out/kernels"
    fi
    # Debug info makes them ~300 MB; stripped they are ~25 MB (the device tool carries <= 64 MiB).
    strip "$out/gpu-bench" "$out/render-bench" "$out/it-tests" "$out/penumbra"
    ls -l "$out"
    exit 0
fi


# Sections (all by default; `--only a,b` runs those, in this order): parity, criterion, fourier,
# sweep, stats, tiled, site, series, render. The whole set takes longer than one 10-minute device
# call: split it, e.g. `--only parity,stats` then `--only sweep`.
dir=target/gpu-bench
only=""
while [[ $# -gt 0 ]]; do
    case "$1" in
        --only) only=${2:?--only needs a list of sections}; shift 2 ;;
        --only=*) only=${1#--only=}; shift ;;
        -*) echo "gpu-bench: unknown option $1" >&2; exit 2 ;;
        *) dir=$1; shift ;;
    esac
done
sections="parity criterion fourier sweep stats tiled site series render"
for s in ${only//,/ }; do
    [[ " $sections " == *" $s "* ]] || { echo "gpu-bench: unknown section '$s' (sections: $sections)" >&2; exit 2; }
done
want() { [[ -z "$only" || ",$only," == *",$1,"* ]]; }
for f in penumbra gpu-bench render-bench it-tests; do
    [[ -x "$dir/$f" ]] || { echo "gpu-bench: $dir/$f is missing; run tools/gpu-bench.sh --prepare where cargo exists" >&2; exit 2; }
done
export WGPU_BACKEND=${WGPU_BACKEND:-vulkan}
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
lola_hm="$dir/ldem75s_crop_240m_pm184km.tif"
far_hs="$dir/ldem75s_far_1787m_pm457km_feathered.tif"
# bounded SECONDS WHAT PATTERN CMD…: runs CMD for at most SECONDS (0 skips it), printing its
# lines that match PATTERN (and errors, warnings); says so when it did not finish.
bounded() {
    local t=$1 what=$2 pattern=$3
    shift 3
    [[ "$t" == 0 ]] && return 0
    timeout "$t" "$@" 2>&1 | grep -E "$pattern|error|warning" || echo "  $what did not finish within $t s"
}

if want parity; then
    echo "== penumbra gpu-info"
    "$dir/penumbra" gpu-info
    echo "== GPU-vs-CPU parity (no adapter is a failure)"
    "$dir/it-tests" gpu --nocapture --test-threads=1 2>&1 |
        grep -E "adapter|differ|gpu vs|GPU vs|max \|Δ\||equal stats|test result|FAILED|panicked" || true
fi
if want criterion; then
    echo "== criterion: dp_soft, fourier_build, fourier_eval, dp_tiled (512^2), line_sweep"
    "$dir/gpu-bench" --bench 2>&1 | grep -Ev "^\s*$|Warming up|Collecting|Analyzing|Benchmarking .*: (Warming|Collecting|Analyzing)"
fi
if want fourier; then
    # Issue 7 target: horizon maps 1536^2 x 720 azimuths in < 5 s on an H100 (the real 240 m LOLA
    # grid, whole-grid rays, 16 coefficients). The printed "in X s" is the build alone (no DEM load,
    # no TIFF write). The CPU build of the same map is the ratio's denominator; it takes minutes, so
    # it is bounded (PENUMBRA_BENCH_FOURIER_CPU_TIMEOUT_S, default 600 s; 0 skips it).
    echo "== horizon-map build 1536^2 x 720 azimuths (target < 5 s on an H100), gpu then cpu"
    if [[ -f "$lola_hm" ]]; then
        tmp_hm=$(mktemp -d)
        "$dir/penumbra" horizon-map build --dem "$lola_hm" --azimuths 720 --backend gpu \
            --out "$tmp_hm/hm_gpu.tif" 2>&1 | grep -E "horizon map|error|warning" || true
        bounded "${PENUMBRA_BENCH_FOURIER_CPU_TIMEOUT_S:-600}" "cpu build" "horizon map" \
            "$dir/penumbra" horizon-map build --dem "$lola_hm" --azimuths 720 --backend cpu \
            --out "$tmp_hm/hm_cpu.tif"
        rm -rf "$tmp_hm"
    else
        echo "gpu-bench: $lola_hm absent (run --prepare where ../shared/data exists); skipped"
    fi
fi
if want sweep; then
    # Issue 15 target: horizons at all cells, 1536^2 x 720 azimuths, 240 m grid + far field, < 20 s.
    # The GPU runs the hulls and tangents (line_sweep.wgsl), the CPU builds the lines; the printed
    # "in X s" includes writing the 2.6 GB int16 BigTIFF. The CPU sweep's ratio comes from 90
    # azimuths (bounded by PENUMBRA_BENCH_SWEEP_CPU_TIMEOUT_S, default 300 s; 0 skips it).
    echo "== horizon-map sweep 1536^2 + far field: gpu 720 az (target < 20 s), gpu and cpu 90 az"
    if [[ -f "$lola_hm" && -f "$far_hs" ]]; then
        tmp_hs=$(mktemp -d)
        "$dir/penumbra" horizon-map sweep --dem "$lola_hm" --dem "$far_hs" --backend gpu \
            --out "$tmp_hs/hs_gpu.tif" 2>&1 | grep -E "horizons|error|warning" || true
        rm -f "$tmp_hs/hs_gpu.tif"
        for be in gpu cpu; do
            t=300
            [[ "$be" == cpu ]] && t=${PENUMBRA_BENCH_SWEEP_CPU_TIMEOUT_S:-300}
            bounded "$t" "$be sweep" "horizons" "$dir/penumbra" horizon-map sweep \
                --dem "$lola_hm" --dem "$far_hs" --azimuths 90 --backend "$be" \
                --out "$tmp_hs/hs90_$be.tif"
        done
        rm -rf "$tmp_hs"
    else
        echo "gpu-bench: $lola_hm or $far_hs absent (run --prepare where ../shared/data exists); skipped"
    fi
fi
if want stats; then
    # Issue 15 target: a 1-year hourly statistics map of the 1536^2 grid + far field from a horizon
    # file (< 60 s end to end on the 2-core CI machine). The horizons come from a 90-azimuth GPU sweep
    # written here (the 720-azimuth file is 2.6 GB and its sweep is the "sweep" section); the map
    # runs the statistics' epoch loop on the GPU, then on the CPU (all cores) for the ratio
    # (PENUMBRA_BENCH_STATS_CPU_TIMEOUT_S, default 300 s; 0 skips it).
    echo "== map --engine horizons 1536^2 + far field, 2025 hourly (8,760 epochs), 90-az horizons: gpu, cpu"
    if [[ -f "$lola_hm" && -f "$far_hs" ]]; then
        tmp_st=$(mktemp -d)
        "$dir/penumbra" horizon-map sweep --dem "$lola_hm" --dem "$far_hs" --azimuths 90 \
            --backend gpu --out "$tmp_st/hz90.tif" 2>&1 | grep -E "horizons|error|warning" || true
        for be in gpu cpu; do
            t=300
            [[ "$be" == cpu ]] && t=${PENUMBRA_BENCH_STATS_CPU_TIMEOUT_S:-300}
            echo "  backend $be:"
            bounded "$t" "$be map" "statistics" "$dir/penumbra" map --dem "$lola_hm" \
                --dem "$far_hs" --engine horizons --horizons "$tmp_st/hz90.tif" \
                --start 2025-01-01 --stop 2025-12-31T23:00 --step 1h --backend "$be" \
                --out-dir "$tmp_st/m_$be"
        done
        rm -rf "$tmp_st"
    else
        echo "gpu-bench: $lola_hm or $far_hs absent (run --prepare where ../shared/data exists); skipped"
    fi
fi
if want tiled; then
    # 2-D tiled DP map on a 20,000^2 synthetic grid (400 M cells, 20 m: 400 km), generated in the
    # bench: whole-grid kernel (if the adapter's storage binding holds 1.6 GB heights + 2.1 GB
    # mipmap) vs tiles of 2048 (docs/gpu.md, "Large grids"); the run's tile statistics are printed.
    echo "== criterion: dp_tiled 20000^2 (one-light DP soft map, untiled vs tiles of 2048)"
    PENUMBRA_BENCH_TILED_N=${PENUMBRA_BENCH_TILED_N:-20000} PENUMBRA_BENCH_TILE_CELLS=2048 \
        "$dir/gpu-bench" --bench dp_tiled 2>&1 |
        grep -Ev "^\s*$|Warming up|Collecting|Analyzing|Benchmarking .*: (Warming|Collecting|Analyzing)"
fi
if want site; then
    if [[ -x "$dir/gpu-horizon-bench" ]]; then
        # Per-site horizons, 100 sites: 360 azimuths, then the CLI default 1440 (0.25 deg).
        echo "== criterion: site_horizons (100 sites x 360 az, then x 1440 az)"
        for step in 1 0.25; do
            PENUMBRA_BENCH_AZ_STEP_DEG=$step "$dir/gpu-horizon-bench" --bench 2>&1 |
                grep -Ev "^\s*$|Warming up|Collecting|Analyzing|Benchmarking .*: (Warming|Collecting|Analyzing)"
        done
    fi
fi
if want series; then
    if [[ -x "$dir/series-bench" ]]; then
        # series --engine smap-dp: CPU (rayon) vs GPU (dp_sites.wgsl), 1/10/100 sites x 192 epochs,
        # next to the horizon engine.
        echo "== criterion: series_engines (horizon, smap_dp, smap_dp_gpu)"
        PENUMBRA_BENCH_KERNELS=${PENUMBRA_BENCH_KERNELS:-$dir/kernels} "$dir/series-bench" --bench series_engines 2>&1 |
            grep -Ev "^\s*$|Warming up|Collecting|Analyzing|Benchmarking .*: (Warming|Collecting|Analyzing)"
    fi
fi
if want render; then
    "$dir/it-tests" gpu::render:: --nocapture --test-threads=1 2>&1 |
        grep -E "adapter|silhouette|flat plane|Sun disc|test result|FAILED|panicked" || true
    echo "== criterion: render_1080p (GPU frame time, target < 10 ms on an H100; CPU mipmap and uniform)"
    if [[ -f "$dir/ldem75s_crop_240m_pm184km.tif" ]]; then
        export PENUMBRA_RENDER_BENCH_DEM=${PENUMBRA_RENDER_BENCH_DEM:-$dir/ldem75s_crop_240m_pm184km.tif}
    fi
    "$dir/render-bench" --bench render_1080p 2>&1 | grep -Ev "^\s*$|Warming up|Collecting|Analyzing|Benchmarking .*: (Warming|Collecting|Analyzing)"
fi
