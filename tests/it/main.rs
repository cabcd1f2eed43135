//! penumbra's integration tests: one binary whose modules mirror `src/` (anise/ripgrep layout),
//! so the tests of `src/<floor>/<file>.rs` are in `tests/it/<floor>/<file>.rs`:
//!
//! - `gpu/`: one file per kernel of `src/gpu/` (the f32 twin against the f64 engines, the GPU
//!   against the twin, the `--backend gpu` CLI); `gpu/mod.rs` validates every shader with naga.
//! - `horizon/` (scan; `sweep`, `statistics`), `shadow/` (engines; `fourier`), `render/`
//!   (renderer and `penumbra render`; `brdf`, `path`), `ephem`, `terrain`, `illum`: the CPU
//!   engines, and the commands that are thin shells over them.
//! - `products/`: `map/` (with `shard`) and `series/` (with `engines`), products without a
//!   lower floor of their own.
//! - `cli`, `blocking`, `reliability`, `resume`: cross-cutting suites at the top; they
//!   test one rule over every engine, command or reader (clap habits, the blocking rule, bad
//!   input and signals, kill and resume), so no single floor owns them. Mutated files are in
//!   the `fuzz` test binary (`tests/fuzz/`), a process of its own.
//!
//! Every run of the binary, fixture and shared data path goes through `util` (ripgrep
//! `tests/util.rs`). Run a floor by its path: `cargo test --release --test it gpu::dp`.

mod blocking;
mod cli;
mod ephem;
mod gpu;
mod horizon;
mod illum;
mod products;
mod reliability;
mod render;
mod resume;
mod shadow;
mod terrain;
mod util;
