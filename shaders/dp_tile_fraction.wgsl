// Tiled DP, pass 2 (docs/gpu.md, "Large grids"): turns the output tile's shadow costs (pass 1,
// dp_tile_cost.wgsl, min over every source tile) into the visible fraction of the disc
// dp_lights[dp_step.light0] in place (radius 0: the hard mask 1/0), -1 for nodata. Dispatch:
// shared/dp_tile.wgsl. Bindings: 0, 4, 5 from shared/dp.wgsl; 6 cost in / fraction out and 7 the
// output tile's heights from shared/dp_tile.wgsl. CPU twin: `dp_tile_fraction` in
// src/twins/dp_tiles.rs.

const NODATA_FRACTION: f32 = -1.0;

@compute @workgroup_size(WORKGROUP_SIZE_X, WORKGROUP_SIZE_Y, 1)
fn dp_tile_fraction(@builtin(global_invocation_id) gid: vec3<u32>) {
    if !dp_tile_inside(gid) {
        return;
    }
    let c = dp_tile_cell(gid);
    if c.hole {
        cost[c.k] = NODATA_FRACTION;
        return;
    }
    cost[c.k] = dp_fraction_of_cost(c.obs, dp_lights[dp_step.light0], cost[c.k]);
}
