// Tiled DP, pass 2 (docs/gpu.md, "Large grids"): turns the output tile's shadow costs (pass 1,
// dp_tile_cost.wgsl, min over every source tile) into the visible fraction of the disc
// dp_lights[dp_step.light0] in place (radius 0: the hard mask 1/0), -1 for nodata. Dispatch: one
// invocation per output cell, workgroups (ceil(band_cols/8), ceil(band_rows/8)). Bindings: 0, 4,
// 5 from shared/dp.wgsl; 6 cost in / fraction out (output-tile-relative); 7 the output tile's
// heights block. CPU twin: `dp_visible_tiled` in src/shadow/gpu_tiles.rs.

const WORKGROUP_SIZE_X: u32 = 8u;
const WORKGROUP_SIZE_Y: u32 = 8u;
const NODATA_FRACTION: f32 = -1.0;

@group(0) @binding(6) var<storage, read_write> cost: array<f32>;
@group(0) @binding(7) var<storage, read> obs_heights: array<f32>;

@compute @workgroup_size(WORKGROUP_SIZE_X, WORKGROUP_SIZE_Y, 1)
fn dp_tile_fraction(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= dp_step.band_cols || gid.y >= dp_step.band_rows {
        return;
    }
    let row = dp_step.band_row0 + gid.y;
    let col = dp_step.band_col0 + gid.x;
    let k = gid.y * dp_step.band_cols + gid.x;
    let z_cell = obs_heights[(row - dp_step.obs_row0) * dp_step.obs_cols + (col - dp_step.obs_col0)];
    if z_cell < DP_HOLE_TEST_M {
        cost[k] = NODATA_FRACTION;
        return;
    }
    let obs = dp_observer_at(row, col, z_cell);
    cost[k] = dp_fraction_of_cost(obs, dp_lights[dp_step.light0], cost[k]);
}
