#!/usr/bin/env bash
# Coverage-guided fuzzing of penumbra's readers: cargo-fuzz (libFuzzer) over the targets in
# fuzz/fuzz_targets/, each seeded with the fixtures the blind CI fuzzer (tests/fuzz) uses.
#
#   tools/fuzz-coverage.sh [SECONDS_PER_TARGET] [TARGET ...]     (default 60 s, every target)
#
# Needs a nightly toolchain (`rustup toolchain install nightly`) and `cargo install cargo-fuzz`;
# without them it says so and exits 2 (CI runs the blind fuzzer only: a fresh CI machine has
# one stable toolchain). Sanitizer: none (safe Rust: what is sought is a panic, an abort, a hang
# over 10 s or more than 4 GiB). A finding is left in fuzz/artifacts/<target>/ and the script
# exits 1. The corpus grows in fuzz/corpus/<target>/ (ignored by git). Prints, per target, the
# inputs run, the coverage (libFuzzer's `cov` edges) and the corpus size.
set -euo pipefail
cd "$(dirname "$0")/.."
secs="${1:-60}"
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(geotiff horizon_map scenario kernel_texts sites pds)
if ! rustup run nightly rustc --version >/dev/null 2>&1; then
  echo "fuzz-coverage: no nightly toolchain (rustup toolchain install nightly)" >&2; exit 2
fi
if ! cargo fuzz --version >/dev/null 2>&1; then
  echo "fuzz-coverage: no cargo-fuzz (cargo install cargo-fuzz)" >&2; exit 2
fi
fx=tests/fixtures/fuzz
seeds() {
  case "$1" in
    geotiff) echo $fx/dem_f32.tif $fx/dem_i16_deflate_tiled.tif $fx/dem_u16_lzw.tif ;;
    horizon_map) echo $fx/horizon_map.tif ;;
    scenario) echo $fx/scenario.toml scenarios/south-pole-demo.toml ;;
    kernel_texts) echo $fx/set.tm kernels/naif0012.tls kernels/moon_080317.tf \
      tests/fixtures/kernels-de440-frames/moon_de440_frames.tf ;;
    sites) echo $fx/sites.csv $fx/sites.geojson ;;
    pds) echo $fx/pds3_attached.img $fx/pds4_seed.xml ;;
    *) echo "fuzz-coverage: unknown target $1" >&2; exit 2 ;;
  esac
}
status=0
(cd fuzz && cargo +nightly fuzz build -O -s none)
for t in "${targets[@]}"; do
  mkdir -p "fuzz/corpus/$t"
  for s in $(seeds "$t"); do cp -n "$s" "fuzz/corpus/$t/" 2>/dev/null || true; done
  log="fuzz/fuzz-$t.log"
  if (cd fuzz && cargo +nightly fuzz run -O -s none "$t" "corpus/$t" -- \
        -max_total_time="$secs" -timeout=10 -rss_limit_mb=4096 -print_final_stats=1) >"$log" 2>&1; then
    verdict=ok
  else
    verdict="FINDING (see $log, fuzz/artifacts/$t/)"; status=1
  fi
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo ?)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || echo ?)
  files=$(ls "fuzz/corpus/$t" | wc -l)
  echo "$t: $runs inputs in ${secs} s, cov $cov edges, corpus $files files: $verdict"
done
exit $status
