// fragment: uses dp_step, DpObserver and dp_observer_at of shared/dp.wgsl, so it is validated
// within the dp_tile_*.wgsl kernels only.
// Shared part of the tiled DP kernels dp_tile_*.wgsl (composed after shared/dp.wgsl,
// src/gpu/shaders.rs; docs/gpu.md, "Large grids"): the workgroup size, bindings 6 (`cost`,
// output-tile-relative) and 7 (the output tile's heights block, whose cells are the observers),
// and the cell of one invocation. Dispatch: one invocation per output cell, workgroups
// (ceil(band_cols / 8), ceil(band_rows / 8)); bindings 1..3 are the source tile's heights block
// and mipmap. CPU twin: `dp_tile_cell` in src/twins/dp_tiles.rs.

const WORKGROUP_SIZE_X: u32 = 8u;
const WORKGROUP_SIZE_Y: u32 = 8u;

// Output-tile-relative, row-major: index (row - band_row0) * band_cols + (col - band_col0).
@group(0) @binding(6) var<storage, read_write> cost: array<f32>;
@group(0) @binding(7) var<storage, read> obs_heights: array<f32>;

// The output-tile cell of one invocation.
struct DpTileCell {
    // Output-tile-relative index (into `cost`, and into the statistics of the tiled sweep).
    k: u32,
    // The cell is a hole (its height is below DP_HOLE_TEST_M; `obs` is then not set).
    hole: bool,
    obs: DpObserver,
}

// Whether invocation `gid` lies inside the output tile of this dispatch.
fn dp_tile_inside(gid: vec3<u32>) -> bool {
    return gid.x < dp_step.band_cols && gid.y < dp_step.band_rows;
}

// The cell of invocation `gid` (inside the output tile) and its observer, from the tile's block.
fn dp_tile_cell(gid: vec3<u32>) -> DpTileCell {
    let row = dp_step.band_row0 + gid.y;
    let col = dp_step.band_col0 + gid.x;
    let k = gid.y * dp_step.band_cols + gid.x;
    let z_cell = obs_heights[(row - dp_step.obs_row0) * dp_step.obs_cols + (col - dp_step.obs_col0)];
    if z_cell < DP_HOLE_TEST_M {
        return DpTileCell(k, true, DpObserver());
    }
    return DpTileCell(k, false, dp_observer_at(row, col, z_cell));
}
