//! penumbra's integration tests: one binary, one module per area (anise/ripgrep layout).

mod blocking;
mod cli;
mod ephem;
mod fourier;
mod fuzz;
mod gpu;
mod gpu_dp;
mod gpu_fourier;
mod gpu_horizon;
mod gpu_tiles;
mod horizon;
mod horizon_sweep;
mod illum;
mod map;
mod map_horizons;
mod reliability;
mod render;
mod render_cpu;
mod render_gpu;
mod render_path;
mod resume;
mod series;
mod series_engines;
mod shadow;
mod terrain;
mod util;
