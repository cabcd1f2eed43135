//! The shader table: for every kernel in `shaders/`, the `shaders/shared/*.wgsl` parts it is
//! composed of (in order, the kernel file last) and the composed WGSL, embedded at compile time so
//! that the binary is self-contained. The pipelines are built from it and the naga test
//! (tests/it/gpu/mod.rs) validates every entry, so what runs is what is validated (vello's shader
//! table). Always compiled: the CPU-only build still validates the shaders.

/// One compute shader of `shaders/`.
#[derive(Debug, Clone, Copy)]
pub struct Shader {
    /// The kernel file's stem, also its one entry point (`dp_visible` for
    /// `shaders/dp_visible.wgsl`).
    pub name: &'static str,
    /// The shared parts composed before the kernel file, paths under `shaders/`.
    pub parts: &'static [&'static str],
    /// The composed WGSL: the parts, then the kernel file.
    pub source: &'static str,
}

/// `NAME = "stem" ["shared/part.wgsl", …];` for each kernel: a [`Shader`] constant per kernel
/// and [`SHADERS`], the list of them all.
macro_rules! shader_table {
    ($($konst:ident = $name:literal [$($part:literal),*];)*) => {
        $(
            #[doc = concat!("`shaders/", $name, ".wgsl`.")]
            pub const $konst: Shader = Shader {
                name: $name,
                parts: &[$($part),*],
                source: concat!(
                    $(include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/shaders/", $part)),)*
                    include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/shaders/", $name, ".wgsl"))
                ),
            };
        )*
        /// Every kernel of `shaders/`.
        pub const SHADERS: &[Shader] = &[$($konst),*];
    };
}

shader_table! {
    DP_POINTS = "dp_points" ["shared/dp.wgsl"];
    DP_POINTS_SWEEP = "dp_points_sweep" ["shared/dp.wgsl"];
    DP_SITES = "dp_sites" ["shared/dp.wgsl"];
    DP_SWEEP = "dp_sweep" ["shared/dp.wgsl"];
    DP_TILE_COST = "dp_tile_cost" ["shared/dp.wgsl", "shared/dp_tile.wgsl"];
    DP_TILE_FRACTION = "dp_tile_fraction" ["shared/dp.wgsl", "shared/dp_tile.wgsl"];
    DP_TILE_SWEEP_ACCUMULATE = "dp_tile_sweep_accumulate" ["shared/dp.wgsl", "shared/dp_tile.wgsl"];
    DP_TILE_SWEEP_COST = "dp_tile_sweep_cost" ["shared/dp.wgsl", "shared/dp_tile.wgsl"];
    DP_VISIBLE = "dp_visible" ["shared/dp.wgsl"];
    FOURIER_BUILD = "fourier_build" ["shared/march.wgsl"];
    FOURIER_EVAL = "fourier_eval" [];
    HORIZON_SCAN = "horizon_scan" ["shared/bilinear.wgsl"];
    HORIZON_STATS = "horizon_stats" [];
    LINE_SWEEP = "line_sweep" ["shared/bilinear.wgsl"];
    RENDER = "render" ["shared/brdf.wgsl"];
}
