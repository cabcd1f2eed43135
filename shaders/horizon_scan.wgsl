// Per-site terrain horizons: one invocation per (azimuth, site) scans the great circle that leaves
// the observer with that azimuth over every DEM layer of the stack (native polar stereographic
// grids, finest layer with a surface wins) and writes the largest tan(elevation) and the ground
// angle where it occurs. The same sampling as the CPU exact scan (src/horizon/scan.rs): every
// crossing of a line through cell centres, of a layer's outer edge or of a finer layer's outer
// edge, and inside every bilinear patch piece the midpoint and the tangent point of the piece's
// quadratic height profile.
// Dispatch: workgroups (ceil(n_az / 64), n_sites); gid.x = azimuth, gid.y = site - site0.
// Bindings: 0 params (uniform), 1 heights (all layers, row-major, concatenated), 2 sites,
// 3 azimuths (sin, cos) computed in f64 on the CPU, 4 out (tan el, ground angle rad) per
// site * n_az + az. CPU twin: `horizon_scan` (one invocation: `scan_azimuth`) in
// src/twins/horizon_scan.rs.
//
// Precision budget (f32): the path point u(theta) = up + d sin(theta) - up (1 - cos(theta)) is a
// unit vector with ~1e-9 absolute error in its small components (0.003-0.03 m on the map); the
// polar stereographic denominator 1 -/+ u.z is ~2 at the projection's own pole (no
// cancellation); sin and 1 - cos of the small ground angle are Taylor series (WGSL only promises
// 2^-11 absolute error for sin/cos); the elevation is formed as
// tan = ((h - h_obs) - (R + h)(1 - cos theta)) / ((R + h) sin theta), with heights in metres above
// the sphere (ulp <= 0.5 mm), never as a difference of two radii. atan is taken on the CPU.
// Holes are stored as HOLE_Z_M (no NaN on the GPU).

const WORKGROUP_SIZE: u32 = 64u;
const MAX_LAYERS: u32 = 4u;
const MOON_RADIUS_M: f32 = 1737400.0;
// Heights below this are holes (stored as -1e30 m); also "no sample" for heights and tangents.
const HOLE_TEST_M: f32 = -1.0e29;
const NO_SAMPLE: f32 = -1.0e30;
// Cells of the finest layer at the segment start per path segment (as the CPU scan).
const SEGMENT_CELLS: f32 = 8.0;
// A fractional index this close outside an outer edge is moved onto it (cells).
const SNAP_EPS: f32 = 1.0e-3;
// Loop guards (never reached on valid input: a 20,000-cell path has 2,500 segments).
const MAX_SEGMENTS: u32 = 1000000u;
const MAX_PIECES: u32 = 1000000u;
const FAR_T: f32 = 1.0e30;
// Below this ground angle (rad) sin and 1 - cos are Taylor series; above, the built-ins.
const SERIES_MAX_RAD: f32 = 0.6;

// Keep in sync with `LayerParams` in src/twins/horizon_scan.rs.
struct Layer {
    rows: u32,
    cols: u32,
    // First cell of this layer in `heights`.
    offset: u32,
    // 1: south polar stereographic, 0: north.
    south: u32,
    px_x_m: f32,
    px_y_m: f32,
    x_left_m: f32,
    y_top_m: f32,
    sin_lon0: f32,
    cos_lon0: f32,
    two_r_k0_m: f32,
    // min(px_x_m, px_y_m): sets the segment length.
    px_min_m: f32,
}

// Keep in sync with `ScanParams` in src/twins/horizon_scan.rs.
struct ScanParams {
    n_layers: u32,
    n_sites: u32,
    n_az: u32,
    // First site of this dispatch: invocation (az, s) scans sites[site0 + s].
    site0: u32,
    layers: array<Layer, MAX_LAYERS>,
}

// Keep in sync with `SiteParams` in src/twins/horizon_scan.rs.
struct Site {
    // MOON_ME unit vectors of the observer's radial, north and east directions (w unused).
    up: vec4<f32>,
    north: vec4<f32>,
    east: vec4<f32>,
    // Observer height above the sphere: ground + observer height, metres.
    obs_m: f32,
    theta_min_rad: f32,
    theta_max_rad: f32,
    _pad: f32,
}

@group(0) @binding(0) var<uniform> params: ScanParams;
@group(0) @binding(1) var<storage, read> heights: array<f32>;
@group(0) @binding(2) var<storage, read> sites: array<Site>;
@group(0) @binding(3) var<storage, read> azimuths: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read_write> out: array<vec2<f32>>;

// Per-invocation state: the two ends of the current segment on every layer, the observer and
// the running maximum.
var<private> seg_a: array<vec2<f32>, MAX_LAYERS>;
var<private> seg_b: array<vec2<f32>, MAX_LAYERS>;
var<private> obs_m: f32;
var<private> best_tan: f32;
var<private> best_theta: f32;

fn sin_small(t: f32) -> f32 {
    if t >= SERIES_MAX_RAD {
        return sin(t);
    }
    let t2 = t * t;
    return t * (1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0))));
}

fn one_minus_cos_small(t: f32) -> f32 {
    if t >= SERIES_MAX_RAD {
        return 1.0 - cos(t);
    }
    let t2 = t * t;
    return t2 / 2.0 * (1.0 - t2 / 12.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0 * (1.0 - t2 / 90.0))));
}

// Nodata-aware bilinear height at fractional (row, col) of layer l (shared/bilinear.wgsl).
fn height_at(l: u32, row: f32, col: f32) -> f32 {
    let layer = params.layers[l];
    return layer_height(layer.offset, layer.rows, layer.cols, row, col);
}

// Fractional (row, col) on layer l of the unit radial vector u (polar stereographic, as
// UnitProjector::xy_from_unit then GridGeometry::row_col_from_xy).
fn row_col(l: u32, u: vec3<f32>) -> vec2<f32> {
    let layer = params.layers[l];
    let e = u.y * layer.cos_lon0 - u.x * layer.sin_lon0;
    let n = u.x * layer.cos_lon0 + u.y * layer.sin_lon0;
    var x = 0.0;
    var y = 0.0;
    if layer.south == 1u {
        let f = layer.two_r_k0_m / (1.0 - u.z);
        x = f * e;
        y = f * n;
    } else {
        let f = layer.two_r_k0_m / (1.0 + u.z);
        x = f * e;
        y = -f * n;
    }
    return vec2<f32>((layer.y_top_m - y) / layer.px_y_m - 0.5, (x - layer.x_left_m) / layer.px_x_m - 0.5);
}

fn inside_extent(l: u32, rc: vec2<f32>) -> bool {
    let layer = params.layers[l];
    return rc.x >= -0.5 && rc.y >= -0.5 && rc.x <= f32(layer.rows) - 0.5 && rc.y <= f32(layer.cols) - 0.5;
}

// Whether the box spanned by the segment on layer l misses the layer's outer edges.
fn segment_misses(l: u32) -> bool {
    let layer = params.layers[l];
    let a = seg_a[l];
    let b = seg_b[l];
    return max(a.x, b.x) < -0.5 || max(a.y, b.y) < -0.5 || min(a.x, b.x) > f32(layer.rows) - 0.5
        || min(a.y, b.y) > f32(layer.cols) - 0.5;
}

fn snap_to_edge(v: f32, n: f32) -> f32 {
    if v < -0.5 && v > -0.5 - SNAP_EPS {
        return -0.5;
    }
    if v > n - 0.5 && v < n - 0.5 + SNAP_EPS {
        return n - 0.5;
    }
    return v;
}

// The next line strictly beyond v in direction dir (+1 / -1) among the lines of an axis of n
// cells: the outer edges -0.5 and n - 0.5 and the centre lines 0 .. n - 1; FAR_T when none.
fn next_line(v: f32, dir: f32, n: f32) -> f32 {
    if dir > 0.0 {
        if v < -0.5 {
            return -0.5;
        }
        if v < 0.0 {
            return 0.0;
        }
        if v < n - 1.0 {
            return floor(v) + 1.0;
        }
        if v < n - 0.5 {
            return n - 0.5;
        }
        return FAR_T;
    }
    if v > n - 0.5 {
        return n - 0.5;
    }
    if v > n - 1.0 {
        return n - 1.0;
    }
    if v > 0.0 {
        return ceil(v) - 1.0;
    }
    if v > -0.5 {
        return -0.5;
    }
    return -FAR_T;
}

// Ray parameter of line `line` on an axis going from va with slope dv (FAR_T when never).
fn line_t(line: f32, va: f32, dv: f32) -> f32 {
    if dv == 0.0 || abs(line) >= FAR_T {
        return FAR_T;
    }
    return (line - va) / dv;
}

fn tan_elevation(h_m: f32, theta: f32) -> f32 {
    let rho = MOON_RADIUS_M + h_m;
    return ((h_m - obs_m) - rho * one_minus_cos_small(theta)) / (rho * sin_small(theta));
}

fn offer(tan_el: f32, theta: f32) {
    if tan_el > best_tan {
        best_tan = tan_el;
        best_theta = theta;
    }
}

// Height of layer l at segment parameter t, or NO_SAMPLE when a finer layer (bit k of
// `finer`) has a surface there or layer l has none.
fn sample(l: u32, finer: u32, t: f32) -> f32 {
    for (var k = 0u; k < l; k++) {
        if (finer & (1u << k)) != 0u {
            let rc = seg_a[k] + t * (seg_b[k] - seg_a[k]);
            if height_at(k, rc.x, rc.y) >= HOLE_TEST_M {
                return NO_SAMPLE;
            }
        }
    }
    let layer = params.layers[l];
    let rc = seg_a[l] + t * (seg_b[l] - seg_a[l]);
    return height_at(l, snap_to_edge(rc.x, f32(layer.rows)), snap_to_edge(rc.y, f32(layer.cols)));
}

// The first crossing after t (and before 1) of the outer edge of a finer layer (bit k of
// `finer`), FAR_T when none: layer l's surface starts there, and is sampled right at it.
fn next_finer_edge(l: u32, finer: u32, t: f32) -> f32 {
    var best = FAR_T;
    for (var k = 0u; k < l; k++) {
        if (finer & (1u << k)) != 0u {
            let va = seg_a[k];
            let dv = seg_b[k] - va;
            let n = vec2<f32>(f32(params.layers[k].rows), f32(params.layers[k].cols));
            for (var axis = 0u; axis < 2u; axis++) {
                for (var e = 0u; e < 2u; e++) {
                    let edge = select(-0.5, n[axis] - 0.5, e == 1u);
                    let te = line_t(edge, va[axis], dv[axis]);
                    if te > t && te < 1.0 && te < best {
                        best = te;
                    }
                }
            }
        }
    }
    return best;
}

// Samples layer l along the current segment (ground angles theta_a .. theta_b).
fn scan_layer_segment(l: u32, theta_a: f32, theta_b: f32, include_start: bool) {
    if segment_misses(l) {
        return;
    }
    var finer = 0u;
    for (var k = 0u; k < l; k++) {
        if !segment_misses(k) {
            finer = finer | (1u << k);
        }
    }
    let layer = params.layers[l];
    let rows = f32(layer.rows);
    let cols = f32(layer.cols);
    let va = seg_a[l];
    let dv = seg_b[l] - va;
    let d_theta = theta_b - theta_a;
    let dir = sign(dv);
    var line_r = next_line(va.x, dir.x, rows);
    var line_c = next_line(va.y, dir.y, cols);
    var t_r = line_t(line_r, va.x, dv.x);
    var t_c = line_t(line_c, va.y, dv.y);
    var t_e = next_finer_edge(l, finer, 0.0);
    var t0 = 0.0;
    var prev = sample(l, finer, 0.0);
    if include_start && prev >= HOLE_TEST_M {
        offer(tan_elevation(prev, theta_a), theta_a);
    }
    for (var i = 0u; i < MAX_PIECES; i++) {
        var t1 = 1.0;
        if t_r < t1 {
            t1 = t_r;
        }
        if t_c < t1 {
            t1 = t_c;
        }
        if t_e < t1 {
            t1 = t_e;
        }
        let at_edge = t_e == t1;
        if at_edge {
            t_e = next_finer_edge(l, finer, t1);
        }
        if t_r == t1 {
            line_r = next_line(line_r, dir.x, rows);
            t_r = line_t(line_r, va.x, dv.x);
        }
        if t_c == t1 {
            line_c = next_line(line_c, dir.y, cols);
            t_c = line_t(line_c, va.y, dv.y);
        }
        if t1 > t0 {
            var next = sample(l, finer, t1);
            if at_edge && next < HOLE_TEST_M {
                // The finer layer's border is clamped, so it has a surface at its edge.
                next = sample(l, 0u, t1);
            }
            let th1 = theta_a + t1 * d_theta;
            if next >= HOLE_TEST_M {
                offer(tan_elevation(next, th1), th1);
            }
            let tm = 0.5 * (t0 + t1);
            let hm = sample(l, finer, tm);
            if hm >= HOLE_TEST_M {
                let thm = theta_a + tm * d_theta;
                let tan_m = tan_elevation(hm, thm);
                offer(tan_m, thm);
                // The quadratic height profile inside one bilinear patch: where it is concave,
                // sample the point where its slope equals the line of sight's (CPU exact scan).
                if prev >= HOLE_TEST_M && next >= HOLE_TEST_M {
                    let q = 2.0 * (prev - 2.0 * hm + next);
                    if q < 0.0 {
                        let p = next - prev - q;
                        let ds_m = (t1 - t0) * d_theta * MOON_RADIUS_M;
                        let m = ds_m * (tan_m + thm);
                        let u = (m - p) / (2.0 * q);
                        if u > 0.0 && u < 1.0 && abs(u - 0.5) > 1.0e-3 {
                            let tv = t0 + u * (t1 - t0);
                            let hv = sample(l, finer, tv);
                            if hv >= HOLE_TEST_M {
                                let thv = theta_a + tv * d_theta;
                                offer(tan_elevation(hv, thv), thv);
                            }
                        }
                    }
                }
            }
            prev = next;
            t0 = t1;
        }
        if t1 >= 1.0 {
            break;
        }
    }
}

// The path point at ground angle theta along d from up, projected on every layer into `ends`.
fn place(site: Site, d: vec3<f32>, theta: f32, to_b: bool) {
    let up = site.up.xyz;
    let u = up + d * sin_small(theta) - up * one_minus_cos_small(theta);
    for (var l = 0u; l < params.n_layers; l++) {
        if to_b {
            seg_b[l] = row_col(l, u);
        } else {
            seg_a[l] = row_col(l, u);
        }
    }
}

// Segment length (rad): SEGMENT_CELLS cells of the finest layer containing the start, else of
// the coarsest layer.
fn segment_length_rad() -> f32 {
    var px = params.layers[params.n_layers - 1u].px_min_m;
    for (var l = 0u; l < params.n_layers; l++) {
        if inside_extent(l, seg_a[l]) {
            px = params.layers[l].px_min_m;
            break;
        }
    }
    return SEGMENT_CELLS * px / MOON_RADIUS_M;
}

@compute @workgroup_size(WORKGROUP_SIZE, 1, 1)
fn horizon_scan(@builtin(global_invocation_id) gid: vec3<u32>) {
    let az = gid.x;
    if az >= params.n_az || gid.y >= params.n_sites {
        return;
    }
    let s = params.site0 + gid.y;
    let site = sites[s];
    let sc = azimuths[az];
    let d = site.north.xyz * sc.y + site.east.xyz * sc.x;
    obs_m = site.obs_m;
    best_tan = NO_SAMPLE;
    best_theta = 0.0;
    var theta = site.theta_min_rad;
    place(site, d, theta, false);
    var first = true;
    for (var i = 0u; i < MAX_SEGMENTS; i++) {
        if !(theta < site.theta_max_rad) {
            break;
        }
        let theta_b = min(theta + segment_length_rad(), site.theta_max_rad);
        place(site, d, theta_b, true);
        for (var l = 0u; l < params.n_layers; l++) {
            scan_layer_segment(l, theta, theta_b, first);
        }
        first = false;
        seg_a = seg_b;
        theta = theta_b;
    }
    out[s * params.n_az + az] = vec2<f32>(best_tan, best_theta);
}
