// Tiled DP, pass 1 (docs/gpu.md, "Large grids"): for each cell of one output tile, the shadow cost
// J* of the ray towards dp_lights[dp_step.light0] over the samples inside the bound source tile,
// min-combined with the tile's running cost (cost[k]; DP_FAR when dp_step.first_source = 1).
// Dispatch: shared/dp_tile.wgsl, once per source tile, nearest first. Bindings: 0..5 from
// shared/dp.wgsl, 6 cost (read_write) and 7 the output tile's heights from shared/dp_tile.wgsl.
// CPU twin: `dp_tile_cost` in src/twins/dp_tiles.rs.

@compute @workgroup_size(WORKGROUP_SIZE_X, WORKGROUP_SIZE_Y, 1)
fn dp_tile_cost(@builtin(global_invocation_id) gid: vec3<u32>) {
    if !dp_tile_inside(gid) {
        return;
    }
    let c = dp_tile_cell(gid);
    if c.hole {
        return;
    }
    let light = dp_lights[dp_step.light0];
    let best0 = select(cost[c.k], DP_FAR, dp_step.first_source == 1u);
    cost[c.k] = dp_cost(c.obs, light.xyz, dp_cap(light), best0);
}
