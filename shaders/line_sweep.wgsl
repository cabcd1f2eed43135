// Whole-grid horizons, the looks of the line sweep: one invocation per (line, look). The CPU
// builds every line's samples as its own sweep does (src/horizon/sweep/) and packs them in f32
// (src/twins/line_sweep.rs, which also holds the CPU twin of this kernel, line by line, and the
// precision budget). Per observer, from the far end of the look toward the near end: every
// sample at least half a pixel ahead joins the upper convex hull (Graham's scan, pure
// orientation tests in the line-local frame x = r sin psi, y = r cos psi - R); the tangent from
// the observer's eye is found by binary search on the elevations of the hull vertices, which,
// like the two points of the observer's own half-pixel piece (bilinear reads of the finest
// layer, else of the first coarser one: at the grid's edge the piece reaches past it), are evaluated relative to the observer on the unrolled cone. Writes (tan el, dpsi) per observer
// and look; NO_SAMPLE where the look sees no terrain.
// Dispatch: workgroups (groups_x, groups_y); invocation id = gid.x + gid.y * groups_x * 64,
// line = id / 2, look = id % 2 (0 forward, toward increasing t; 1 backward).
// Bindings: 0 params (uniform), 1 lines, 2 samples, 3 observers, 4 heights (finest layer, then
// the first coarser layer, holes as -1e30), 5 hull (read_write scratch: 2 * n_samples vertices, one slice per line and
// look), 6 out (2 per observer).

const WORKGROUP_SIZE: u32 = 64u;
const MOON_RADIUS_M: f32 = 1737400.0;
// Heights below this are holes (stored as -1e30 m); also "no terrain seen".
const HOLE_TEST_M: f32 = -1.0e29;
const NO_SAMPLE: f32 = -1.0e30;
// Most hull vertices the tangent climbs from the binary search's vertex.
const CLIMB_STEPS: u32 = 64u;

// Keep in sync with `LineSweepParams` in src/twins/line_sweep.rs.
struct Params {
    n_lines: u32,
    n_samples: u32,
    rows: u32,
    cols: u32,
    px_x_m: f32,
    px_y_m: f32,
    theta_min_rad: f32,
    observer_height_m: f32,
    px_m: f32,
    groups_x: u32,
    // The first coarser layer (0 rows: none), stored in `heights` after the finest layer, and
    // its fractional (row, col) as row0 + row * row_scale, col0 + col * col_scale of the
    // finest layer's (row, col).
    coarse_rows: u32,
    coarse_cols: u32,
    coarse_row0: f32,
    coarse_col0: f32,
    coarse_row_scale: f32,
    coarse_col_scale: f32,
}

// Keep in sync with `LineRecord` in src/twins/line_sweep.rs.
struct Line {
    sample_start: u32,
    sample_count: u32,
    obs_start: u32,
    obs_count: u32,
    l_m: f32,
    inv_two_rho_c: f32,
    ell_x: f32,
    ell_y: f32,
    looks: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// Keep in sync with `SampleRecord` in src/twins/line_sweep.rs.
struct Sample {
    x_m: f32,
    y_m: f32,
    psi_hi: f32,
    psi_lo: f32,
    h_m: f32,
}

// Keep in sync with `ObserverRecord` in src/twins/line_sweep.rs.
struct Observer {
    sample: u32,
    pixel: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> lines: array<Line>;
@group(0) @binding(2) var<storage, read> samples: array<Sample>;
@group(0) @binding(3) var<storage, read> observers: array<Observer>;
@group(0) @binding(4) var<storage, read> heights: array<f32>;
// (x, y, sample index as f32 (exact below 2^24), unused) per hull vertex.
@group(0) @binding(5) var<storage, read_write> hull: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> out: array<vec2<f32>>;

var<private> best_tan: f32;
var<private> best_dpsi: f32;

fn sin_series(t: f32) -> f32 {
    let t2 = t * t;
    return t * (1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0))));
}

fn one_minus_cos_series(t: f32) -> f32 {
    let t2 = t * t;
    return t2 / 2.0 * (1.0 - t2 / 12.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0 * (1.0 - t2 / 90.0))));
}

fn tan_series(a: f32) -> f32 {
    let a2 = a * a;
    return a * (1.0 + a2 / 3.0 * (1.0 + 0.4 * a2));
}

// tan of the elevation of a point dpsi (> 0) ahead of an eye h_eye_m above the sphere.
fn tan_rel(dpsi: f32, h_p_m: f32, h_eye_m: f32) -> f32 {
    let r_p = MOON_RADIUS_M + h_p_m;
    let x = r_p * sin_series(dpsi);
    let y = (h_p_m - h_eye_m) - r_p * one_minus_cos_series(dpsi);
    return y / x;
}

fn dpsi_of(p: Sample, o: Sample) -> f32 {
    return (p.psi_hi - o.psi_hi) + (p.psi_lo - o.psi_lo);
}

// (tan el, dpsi) of hull vertex h (an index into `hull`) from the observer's eye.
fn tan_at(h: u32, base: u32, so: Sample, sign: f32, h_eye: f32) -> vec2<f32> {
    let p = samples[base + u32(hull[h].z)];
    let dpsi = sign * dpsi_of(p, so);
    return vec2<f32>(tan_rel(dpsi, p.h_m, h_eye), dpsi);
}

fn offer(tan_el: f32, dpsi: f32) {
    if tan_el > best_tan {
        best_tan = tan_el;
        best_dpsi = dpsi;
    }
}

// The stack's height at fractional (row, col) of the finest layer: the finest layer's, else
// (outside it or in a hole) the first coarser layer's.
fn height_at(row: f32, col: f32) -> f32 {
    let h = layer_height(0u, params.rows, params.cols, row, col);
    if h >= HOLE_TEST_M || params.coarse_rows == 0u {
        return h;
    }
    return layer_height(
        params.rows * params.cols,
        params.coarse_rows,
        params.coarse_cols,
        params.coarse_row0 + row * params.coarse_row_scale,
        params.coarse_col0 + col * params.coarse_col_scale,
    );
}

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn line_sweep(@builtin(global_invocation_id) gid: vec3<u32>) {
    let id = gid.x + gid.y * params.groups_x * WORKGROUP_SIZE;
    let line_i = id / 2u;
    let look = id % 2u;
    if line_i >= params.n_lines {
        return;
    }
    let line = lines[line_i];
    if (line.looks & (1u << look)) == 0u {
        return;
    }
    let forward = look == 0u;
    let sign = select(-1.0, 1.0, forward);
    let n = line.sample_count;
    let base = line.sample_start;
    // This invocation's hull slice.
    let hb = look * params.n_samples + base;
    let th = params.theta_min_rad;
    let h_obs = params.observer_height_m;
    var hull_len = 0u;
    var next = 0u;
    for (var k = 0u; k < line.obs_count; k++) {
        let kk = select(k, line.obs_count - 1u - k, forward);
        let ob = observers[line.obs_start + kk];
        let so = samples[base + ob.sample];
        // Every sample at least half a pixel ahead joins the hull.
        loop {
            if next >= n {
                break;
            }
            let qi = select(next, n - 1u - next, forward);
            let q = samples[base + qi];
            if sign * dpsi_of(q, so) < th {
                break;
            }
            let qx = sign * q.x_m;
            let qy = q.y_m;
            loop {
                if hull_len < 2u {
                    break;
                }
                let c = hull[hb + hull_len - 2u];
                let b = hull[hb + hull_len - 1u];
                let cross = (b.x - qx) * (c.y - b.y) - (b.y - qy) * (c.x - b.x);
                if cross >= 0.0 {
                    hull_len = hull_len - 1u;
                } else {
                    break;
                }
            }
            hull[hb + hull_len] = vec4<f32>(qx, qy, f32(qi), 0.0);
            hull_len = hull_len + 1u;
            next = next + 1u;
        }
        let h_eye = so.h_m + h_obs;
        best_tan = NO_SAMPLE;
        best_dpsi = 0.0;
        // The observer's own piece: half a pixel out, and midway to the first sample passed.
        let tau_o = tan_series(so.psi_hi * line.inv_two_rho_c);
        let dt_dpsi = line.l_m * (1.0 + tau_o * tau_o) * line.inv_two_rho_c;
        var dpsi_first = th + params.px_m / dt_dpsi;
        if next > 0u {
            let fi = select(next - 1u, n - next, forward);
            dpsi_first = sign * dpsi_of(samples[base + fi], so);
        }
        let row_o = f32(ob.pixel / params.cols);
        let col_o = f32(ob.pixel % params.cols);
        for (var j = 0u; j < 2u; j++) {
            let dpsi = select(0.5 * (th + dpsi_first), th, j == 0u);
            let dt = sign * dpsi * dt_dpsi;
            let row = row_o - dt * line.ell_y / params.px_y_m;
            let col = col_o + dt * line.ell_x / params.px_x_m;
            let h = height_at(row, col);
            if h >= HOLE_TEST_M {
                offer(tan_rel(dpsi, h, h_eye), dpsi);
            }
        }
        let slot = 2u * (line.obs_start + kk) + look;
        if hull_len == 0u {
            out[slot] = vec2<f32>(best_tan, best_dpsi);
            continue;
        }
        // The tangent from the observer's eye: binary search on the elevations themselves
        // (relative to the observer, precise), not on orientations in the f32 hull frame.
        var lo = 0u;
        var hi = hull_len - 1u;
        loop {
            if lo >= hi {
                break;
            }
            let mid = (lo + hi + 1u) / 2u;
            if tan_at(hb + mid - 1u, base, so, sign, h_eye).x > tan_at(hb + mid, base, so, sign, h_eye).x {
                hi = mid - 1u;
            } else {
                lo = mid;
            }
        }
        // A short climb corrects a landing that rounding of the hull (a vertex kept or dropped
        // by mistake) left beside the best vertex.
        var cur = tan_at(hb + lo, base, so, sign, h_eye);
        var farther = vec2<f32>(NO_SAMPLE, 0.0);
        if lo > 0u {
            farther = tan_at(hb + lo - 1u, base, so, sign, h_eye);
        }
        var nearer = vec2<f32>(NO_SAMPLE, 0.0);
        if lo + 1u < hull_len {
            nearer = tan_at(hb + lo + 1u, base, so, sign, h_eye);
        }
        if farther.x > cur.x && farther.x >= nearer.x {
            cur = farther;
            var i = lo - 1u;
            loop {
                if !(i > 0u && i + CLIMB_STEPS > lo) {
                    break;
                }
                let t = tan_at(hb + i - 1u, base, so, sign, h_eye);
                if t.x <= cur.x {
                    break;
                }
                cur = t;
                i = i - 1u;
            }
        } else if nearer.x > cur.x {
            cur = nearer;
            var i = lo + 1u;
            loop {
                if !(i + 1u < hull_len && i < lo + CLIMB_STEPS) {
                    break;
                }
                let t = tan_at(hb + i + 1u, base, so, sign, h_eye);
                if t.x <= cur.x {
                    break;
                }
                cur = t;
                i = i + 1u;
            }
        }
        offer(cur.x, cur.y);
        out[slot] = vec2<f32>(best_tan, best_dpsi);
    }
}
