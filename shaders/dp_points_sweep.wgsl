// Soft epoch sweep from given observers (dp_points.wgsl's points, dp_sweep.wgsl's statistics):
// for the epochs [light0, light0 + count) of the light table (Sun at 2e, Earth at 2e + 1), the
// visible fractions of both discs seen from point i are folded into stats[i - band_row0] with
// dp_sweep_accumulate (the definitions of the CPU `map::sweep`). Dispatch: workgroups
// (ceil(band_rows / 64), 1, 1), repeatedly with consecutive epoch ranges; nothing is read back
// in between. Bindings: 0..5 from shared/dp.wgsl; 6 stats (read_write, dispatch-relative);
// 7 points. CPU twin: `dp_points_sweep` in src/twins/dp.rs.

const WORKGROUP_SIZE_X: u32 = 64u;

@group(0) @binding(6) var<storage, read_write> stats: array<DpCellStats>;
@group(0) @binding(7) var<storage, read> points: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE_X, 1, 1)
fn dp_points_sweep(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= dp_step.band_rows {
        return;
    }
    let o = points[dp_step.band_row0 + gid.x];
    let obs = dp_point_observer(o);
    var s = stats[gid.x];
    for (var e = dp_step.light0; e < dp_step.light0 + dp_step.count; e++) {
        let fs = dp_fraction_beyond(obs, dp_lights[2u * e], o.w);
        let fe = dp_fraction_beyond(obs, dp_lights[2u * e + 1u], o.w);
        dp_sweep_accumulate(&s, fs, fe);
    }
    stats[gid.x] = s;
}
