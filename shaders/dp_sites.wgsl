// Per-site DP horizons for `penumbra series --engine smap-dp` on the GPU: one invocation per
// (site, entry), entry k of site i being the disc dp_lights[i * dp_step.count + k] (unit direction
// in model space in xyz, angular radius in w; w < 0: no cap, the exact horizon). The output is the
// tangent of the terrain horizon's elevation along the light's azimuth, tan(e_h) = tan(e_c) - J*
// (J* from dp_cost_beyond, pruned at the disc's full-visibility cap), or -DP_FAR when no terrain
// sample lies along the ray. The disc weighting (limb darkening, chord fraction) is done on the
// CPU in f64 (src/series_dp.rs), identical to the CPU engine. Sites are fractional points (not
// cell centres): site_observers[i] = (col, row, z relative to z_ref in m, min_s in cells); the
// crossings within min_s of the observer are its own ground and the surface at exactly min_s is
// the first sample (src/shadow/dp.rs dp_cost_beyond). No local-horizontal floor (a site on a rim
// sees below its horizontal plane, as in the horizon engine).
// Dispatch: workgroups (ceil(entries / 64), sites); the DpStep fields are reused: light0 = first
// entry of this dispatch, count = entries per site, band_row0 = first site of this dispatch,
// band_rows = sites in this dispatch. Bindings: 0..5 from shared/dp.wgsl; 6 out (f32, indexed
// like dp_lights); 7 site_observers. CPU twin: `dp_sites` in src/twins/dp.rs.

const WORKGROUP_SIZE_X: u32 = 64u;

@group(0) @binding(6) var<storage, read_write> out: array<f32>;
@group(0) @binding(7) var<storage, read> site_observers: array<vec4<f32>>;

// tan(e_h) of the terrain along the azimuth of `light` seen from `obs`, -DP_FAR for none.
fn dp_site_horizon_tan(obs: DpObserver, light: vec4<f32>, min_s: f32) -> f32 {
    let l = light.xyz;
    let r = light.w;
    let hor = sqrt(l.x * l.x + l.y * l.y);
    if hor < DP_MIN_HORIZ {
        return -DP_FAR;
    }
    let tan_el = l.z / hor;
    var cap = DP_FAR;
    if r >= 0.0 {
        let e_low = atan2(l.z, hor) - r;
        if e_low > -0.5 * DP_PI + 1.0e-6 {
            cap = tan_el - tan(e_low);
        }
    }
    let j = dp_cost_beyond(obs, l, cap, DP_FAR, min_s);
    if j >= 0.5 * DP_FAR {
        return -DP_FAR;
    }
    return tan_el - j;
}

@compute @workgroup_size(WORKGROUP_SIZE_X, 1, 1)
fn dp_sites(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = dp_step.light0 + gid.x;
    if k >= dp_step.count || gid.y >= dp_step.band_rows {
        return;
    }
    let site = dp_step.band_row0 + gid.y;
    let o = site_observers[site];
    let obs = dp_point_observer(o);
    let index = site * dp_step.count + k;
    out[index] = dp_site_horizon_tan(obs, dp_lights[index], o.w);
}
