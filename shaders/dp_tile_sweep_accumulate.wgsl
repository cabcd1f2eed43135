// Tiled soft sweep, pass 2 (docs/gpu.md, "Large grids"): for each cell of one output tile, the
// epochs [light0, light0 + count) in time order: the Sun's and the Earth's visible fractions from
// the batch's costs (pass 1, dp_tile_sweep_cost.wgsl) folded into the cell's statistics with the
// definitions of dp_sweep.wgsl. Dispatch: shared/dp_tile.wgsl, once per batch. Bindings: 0, 4, 5
// from shared/dp.wgsl; 6 cost (read) and 7 the output tile's heights from shared/dp_tile.wgsl;
// 8 stats (output-tile-relative, read_write). CPU twin: `dp_tile_sweep_accumulate` in
// src/twins/dp_tiles.rs.

@group(0) @binding(8) var<storage, read_write> stats: array<DpCellStats>;

@compute @workgroup_size(WORKGROUP_SIZE_X, WORKGROUP_SIZE_Y, 1)
fn dp_tile_sweep_accumulate(@builtin(global_invocation_id) gid: vec3<u32>) {
    if !dp_tile_inside(gid) {
        return;
    }
    let c = dp_tile_cell(gid);
    if c.hole {
        return;
    }
    let cells = dp_step.band_rows * dp_step.band_cols;
    var s = stats[c.k];
    for (var q = 0u; q < dp_step.count; q++) {
        let e = dp_step.light0 + q;
        let fs = dp_fraction_of_cost(c.obs, dp_lights[2u * e], cost[(2u * q) * cells + c.k]);
        let fe = dp_fraction_of_cost(c.obs, dp_lights[2u * e + 1u], cost[(2u * q + 1u) * cells + c.k]);
        dp_sweep_accumulate(&s, fs, fe);
    }
    stats[c.k] = s;
}
