//! penumbra's integration tests: one binary, one module per area (anise/ripgrep layout).

mod ephem;
mod fourier;
mod gpu;
mod horizon;
mod illum;
mod map;
mod render;
mod render_gpu;
mod series;
mod shadow;
mod terrain;
mod util;
