// DP map from given observers (a map pixel stands where a series site at its centre stands):
// out[i] = visible fraction of the disc dp_lights[dp_step.light0] (unit direction + angular
// radius; radius 0 gives the hard mask 1/0) seen from point i, i in [band_row0,
// band_row0 + band_rows) of this dispatch, out indexed from band_row0. Points are records
// (col, row, z relative to z_ref in m, min_s in cells) at fractional positions (a DEM pixel's own
// surface point, observer height included); the crossings within min_s cells are the observer's
// own ground (shared/dp.wgsl dp_fraction_beyond). Only points with data are uploaded: no nodata
// here. Dispatch: workgroups (ceil(band_rows / 64), 1, 1). Bindings: 0..5 from shared/dp.wgsl;
// 6 out (f32, dispatch-relative); 7 points. CPU twin: `dp_points` in src/twins/dp.rs.

const WORKGROUP_SIZE_X: u32 = 64u;

@group(0) @binding(6) var<storage, read_write> out: array<f32>;
@group(0) @binding(7) var<storage, read> points: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE_X, 1, 1)
fn dp_points(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= dp_step.band_rows {
        return;
    }
    let o = points[dp_step.band_row0 + gid.x];
    out[gid.x] = dp_fraction_beyond(dp_point_observer(o), dp_lights[dp_step.light0], o.w);
}
