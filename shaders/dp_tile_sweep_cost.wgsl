// Tiled soft sweep, pass 1 (docs/gpu.md, "Large grids"): for each cell of one output tile and each
// epoch e of [light0, light0 + count) the shadow costs of the Sun (disc 2e) and the Earth (2e + 1)
// over the samples inside the bound source tile, min-combined with the running costs
// (cost[(2 (e - light0) + disc) * cells + k]; DP_FAR when dp_step.first_source = 1).
// Dispatch: one invocation per output cell, workgroups (ceil(band_cols/8), ceil(band_rows/8)),
// once per source tile of the batch. Bindings: 0..5 from shared/dp.wgsl (1..3 = the source tile);
// 6 cost (2 count x cells, read_write); 7 the output tile's heights block; 8 stats (unused here).
// CPU twin: `dp_sweep_tiled` in src/shadow/gpu_tiles.rs.

const WORKGROUP_SIZE_X: u32 = 8u;
const WORKGROUP_SIZE_Y: u32 = 8u;

@group(0) @binding(6) var<storage, read_write> cost: array<f32>;
@group(0) @binding(7) var<storage, read> obs_heights: array<f32>;

@compute @workgroup_size(WORKGROUP_SIZE_X, WORKGROUP_SIZE_Y, 1)
fn dp_tile_sweep_cost(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= dp_step.band_cols || gid.y >= dp_step.band_rows {
        return;
    }
    let row = dp_step.band_row0 + gid.y;
    let col = dp_step.band_col0 + gid.x;
    let z_cell = obs_heights[(row - dp_step.obs_row0) * dp_step.obs_cols + (col - dp_step.obs_col0)];
    if z_cell < DP_HOLE_TEST_M {
        return;
    }
    let cells = dp_step.band_rows * dp_step.band_cols;
    let k = gid.y * dp_step.band_cols + gid.x;
    let obs = dp_observer_at(row, col, z_cell);
    for (var q = 0u; q < 2u * dp_step.count; q++) {
        let light = dp_lights[2u * dp_step.light0 + q];
        let idx = q * cells + k;
        let best0 = select(cost[idx], DP_FAR, dp_step.first_source == 1u);
        cost[idx] = dp_cost(obs, light.xyz, dp_cap(light), best0);
    }
}
