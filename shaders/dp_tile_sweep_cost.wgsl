// Tiled soft sweep, pass 1 (docs/gpu.md, "Large grids"): for each cell of one output tile and each
// epoch e of [light0, light0 + count) the shadow costs of the Sun (disc 2e) and the Earth (2e + 1)
// over the samples inside the bound source tile, min-combined with the running costs
// (cost[(2 (e - light0) + disc) * cells + k]; DP_FAR when dp_step.first_source = 1).
// Dispatch: shared/dp_tile.wgsl, once per source tile of the batch. Bindings: 0..5 from
// shared/dp.wgsl; 6 cost (2 count x cells) and 7 the output tile's heights from
// shared/dp_tile.wgsl; 8 stats (bound, unused here). CPU twin: `dp_tile_sweep_cost` in
// src/twins/dp_tiles.rs.

@compute @workgroup_size(WORKGROUP_SIZE_X, WORKGROUP_SIZE_Y, 1)
fn dp_tile_sweep_cost(@builtin(global_invocation_id) gid: vec3<u32>) {
    if !dp_tile_inside(gid) {
        return;
    }
    let c = dp_tile_cell(gid);
    if c.hole {
        return;
    }
    let cells = dp_step.band_rows * dp_step.band_cols;
    for (var q = 0u; q < 2u * dp_step.count; q++) {
        let light = dp_lights[2u * dp_step.light0 + q];
        let idx = q * cells + c.k;
        let best0 = select(cost[idx], DP_FAR, dp_step.first_source == 1u);
        cost[idx] = dp_cost(c.obs, light.xyz, dp_cap(light), best0);
    }
}
