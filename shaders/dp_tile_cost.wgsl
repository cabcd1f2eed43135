// Tiled DP, pass 1 (docs/gpu.md, "Large grids"): for each cell of one output tile, the shadow cost
// J* of the ray towards dp_lights[dp_step.light0] over the samples inside the bound source tile,
// min-combined with the tile's running cost (cost[k]; DP_FAR when dp_step.first_source = 1).
// Dispatch: one invocation per output cell, workgroups (ceil(band_cols/8), ceil(band_rows/8)),
// once per source tile, nearest first. Bindings: 0..5 from shared/dp.wgsl (1..3 = the source
// tile's heights block and mipmap); 6 cost (output-tile-relative, read_write); 7 the output
// tile's heights block (observers). CPU twin: `dp_costs_tiled` in src/shadow/gpu_tiles.rs.

const WORKGROUP_SIZE_X: u32 = 8u;
const WORKGROUP_SIZE_Y: u32 = 8u;

// Output-tile-relative, row-major: index (row - band_row0) * band_cols + (col - band_col0).
@group(0) @binding(6) var<storage, read_write> cost: array<f32>;
@group(0) @binding(7) var<storage, read> obs_heights: array<f32>;

@compute @workgroup_size(WORKGROUP_SIZE_X, WORKGROUP_SIZE_Y, 1)
fn dp_tile_cost(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= dp_step.band_cols || gid.y >= dp_step.band_rows {
        return;
    }
    let row = dp_step.band_row0 + gid.y;
    let col = dp_step.band_col0 + gid.x;
    let z_cell = obs_heights[(row - dp_step.obs_row0) * dp_step.obs_cols + (col - dp_step.obs_col0)];
    if z_cell < DP_HOLE_TEST_M {
        return;
    }
    let k = gid.y * dp_step.band_cols + gid.x;
    let obs = dp_observer_at(row, col, z_cell);
    let light = dp_lights[dp_step.light0];
    let best0 = select(cost[k], DP_FAR, dp_step.first_source == 1u);
    cost[k] = dp_cost(obs, light.xyz, dp_cap(light), best0);
}
