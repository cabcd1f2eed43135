// Tiled soft sweep, pass 2 (docs/gpu.md, "Large grids"): for each cell of one output tile, the
// epochs [light0, light0 + count) in time order: the Sun's and the Earth's visible fractions from
// the batch's costs (pass 1, dp_tile_sweep_cost.wgsl) folded into the cell's statistics with the
// definitions of dp_sweep.wgsl. Dispatch: one invocation per output cell, workgroups
// (ceil(band_cols/8), ceil(band_rows/8)), once per batch. Bindings: 0, 4, 5 from shared/dp.wgsl;
// 6 cost (read); 7 the output tile's heights block; 8 stats (output-tile-relative, read_write).
// CPU twin: `dp_sweep_tiled` in src/shadow/gpu_tiles.rs.

const WORKGROUP_SIZE_X: u32 = 8u;
const WORKGROUP_SIZE_Y: u32 = 8u;

@group(0) @binding(6) var<storage, read_write> cost: array<f32>;
@group(0) @binding(7) var<storage, read> obs_heights: array<f32>;
@group(0) @binding(8) var<storage, read_write> stats: array<DpCellStats>;

@compute @workgroup_size(WORKGROUP_SIZE_X, WORKGROUP_SIZE_Y, 1)
fn dp_tile_sweep_accumulate(@builtin(global_invocation_id) gid: vec3<u32>) {
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
    var s = stats[k];
    for (var q = 0u; q < dp_step.count; q++) {
        let e = dp_step.light0 + q;
        let fs = dp_fraction_of_cost(obs, dp_lights[2u * e], cost[(2u * q) * cells + k]);
        let fe = dp_fraction_of_cost(obs, dp_lights[2u * e + 1u], cost[(2u * q + 1u) * cells + k]);
        dp_sweep_accumulate(&s, fs, fe);
    }
    stats[k] = s;
}
