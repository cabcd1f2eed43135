// The horizons engine's epoch loop (src/horizon/statistics): one invocation per cell, the
// epochs [epoch_begin, epoch_end) in time order, the statistics kept in acc[cell] between
// dispatches (nothing is read back until the last batch). Per epoch and body: the body at the
// cell (its frame, its observer), its elevation; a disc above the cell's highest horizon or
// below its lowest is 1 or 0; the others take the horizon at their grid azimuth and the circular
// segment (the Sun, limb-darkened chord table) or the horizon polyline (the Earth, uniform).
// CPU twin, line by line: src/twins/horizon_stats.rs (the algorithm is described there).
//
// Bindings: 0 params (uniform); 1 cells; 2 horizons (stride values per cell, degrees); 3 epochs;
// 4 tables (rel_deg, inv_width, band_az_deg, chord Sun, chord Earth); 5 azimuth index; 6 acc.

const WORKGROUP_SIZE_X: u32 = 64u;
const EPOCH_CHUNK: u32 = 512u;
const MAX_POLY_POINTS: u32 = 64u;
const PI: f32 = 3.14159265358979;

struct Params {
    n_cells: u32,
    stride: u32,
    n_bands: u32,
    n_index: u32,
    epoch_begin: u32,
    epoch_end: u32,
    groups_x: u32,
    chord_bins: u32,
    a0_deg: f32,
    bins_per_deg: f32,
    visible_min: f32,
    full_min: f32,
}

struct Cell {
    up_r: vec4<f32>,        // up, r_obs_km
    east_hmin: vec4<f32>,   // grid east, h_min_deg
    north_hmax: vec4<f32>,  // grid north, h_max_deg
    dip: vec4<f32>,         // sin_dip_bound, pad
}

struct Epoch {
    sun: vec4<f32>,    // centre (km from the Moon's centre, MOON_ME), radius_deg
    earth: vec4<f32>,  // centre, radius_deg
    w: vec4<f32>,      // the Sun's normal irradiance (W/m²), pad
}

struct Acc {
    sun_fraction_sum: f32,
    irradiance_horizontal_sum: f32,
    irradiance_tracking_sum: f32,
    sun_visible: u32,
    sun_full: u32,
    earth_visible: u32,
    sun_and_earth: u32,
    dark_run: u32,
    dark_max: u32,
    earth_hidden_run: u32,
    earth_hidden_max: u32,
    low_lit: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> cells: array<Cell>;
@group(0) @binding(2) var<storage, read> horizons: array<f32>;
@group(0) @binding(3) var<storage, read> epochs: array<Epoch>;
@group(0) @binding(4) var<storage, read> tables: array<f32>;
@group(0) @binding(5) var<storage, read> az_index: array<u32>;
@group(0) @binding(6) var<storage, read_write> acc: array<Acc>;

// atan(a) for a in [0, 1] (src/horizon/statistics/lookup.rs, `atan_unit`).
fn atan_unit(a: f32) -> f32 {
    let t = a * a;
    var p = -4.05443e-3;
    p = p * t + 2.1862457e-2;
    p = p * t + -5.591159e-2;
    p = p * t + 9.642142e-2;
    p = p * t + -1.3908607e-1;
    p = p * t + 1.994656e-1;
    p = p * t + -3.332986e-1;
    p = p * t + 9.999934e-1;
    return a * p;
}

// atan2(y, x) in degrees (`atan2_deg`).
fn atan2_deg(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    let lo = min(ax, ay);
    let hi = max(max(ax, ay), 1.17549435e-38);
    var r = atan_unit(lo / hi);
    if ay > ax {
        r = 1.5707964 - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 {
        r = -r;
    }
    return r * (180.0 / PI);
}

fn rel(k: u32) -> f32 {
    return tables[k];
}

fn inv_width(k: u32) -> f32 {
    return tables[params.n_bands + 1u + k];
}

fn band_az(k: u32) -> f32 {
    return tables[2u * params.n_bands + 1u + k];
}

fn chord(earth: bool, x: f32) -> f32 {
    let bins = params.chord_bins;
    let base = 3u * params.n_bands + 1u + select(0u, bins + 1u, earth);
    let t = (clamp(x, -1.0, 1.0) + 1.0) * (f32(bins) * 0.5);
    let i = u32(clamp(i32(t), 0, i32(bins) - 1));
    let f = t - f32(i);
    let a = tables[base + i];
    let b = tables[base + i + 1u];
    return a + f * (b - a);
}

// The band segment holding grid azimuth az_deg (x) and the azimuth relative to the first
// band in [0, 360) (y, bitcast).
fn segment(az_deg: f32) -> vec2<u32> {
    let r0 = az_deg - params.a0_deg;
    let r = r0 - 360.0 * floor(r0 * (1.0 / 360.0));
    let last = i32(params.n_index) - 1;
    let j = u32(clamp(i32(r * params.bins_per_deg), 0, last));
    let k0 = az_index[j];
    let k = min(k0 + select(0u, 1u, r >= rel(k0 + 1u)), params.n_bands - 1u);
    return vec2<u32>(k, bitcast<u32>(r));
}

fn horizon_at(h0: u32, az_deg: f32) -> f32 {
    let s = segment(az_deg);
    let k = s.x;
    let w = (bitcast<f32>(s.y) - rel(k)) * inv_width(k);
    let a = horizons[h0 + k];
    let b = horizons[h0 + k + 1u];
    return a + w * (b - a);
}

fn half_chord_integral(r: f32, u: f32) -> f32 {
    let x = clamp(u / r, -1.0, 1.0);
    return 0.5 * (u * sqrt(max(r * r - u * u, 0.0)) + r * r * asin(x));
}

fn uniform_piece(r: f32, u0: f32, u1: f32, a: f32, b: f32) -> f32 {
    let um = 0.5 * (u0 + u1);
    let s_m = sqrt(max(r * r - um * um, 0.0));
    let g_m = a + b * um;
    let int_s = half_chord_integral(r, u1) - half_chord_integral(r, u0);
    if g_m >= s_m {
        return 0.0;
    } else if g_m <= -s_m {
        return 2.0 * int_s;
    }
    return int_s - (a * (u1 - u0) + 0.5 * b * (u1 * u1 - u0 * u0));
}

fn line_piece(r: f32, p0: vec2<f32>, p1: vec2<f32>) -> f32 {
    let u0 = p0.x;
    let u1 = p1.x;
    let b = (p1.y - p0.y) / (u1 - u0);
    let a = p0.y - b * u0;
    let qa = 1.0 + b * b;
    let qb = 2.0 * a * b;
    let qc = a * a - r * r;
    let disc = qb * qb - 4.0 * qa * qc;
    var cuts = array<f32, 4>(u0, u1, u1, u1);
    var n = 1u;
    if disc > 0.0 {
        let sq = sqrt(disc);
        let q = -0.5 * (qb + select(sq, -sq, qb < 0.0));
        var x1: f32;
        var x2: f32;
        if q != 0.0 {
            x1 = q / qa;
            x2 = qc / q;
        } else {
            x1 = -sq / (2.0 * qa);
            x2 = sq / (2.0 * qa);
        }
        if x1 > x2 {
            let t = x1;
            x1 = x2;
            x2 = t;
        }
        if x1 > u0 && x1 < u1 {
            cuts[n] = x1;
            n += 1u;
        }
        if x2 > u0 && x2 < u1 {
            cuts[n] = x2;
            n += 1u;
        }
    }
    cuts[n] = u1;
    n += 1u;
    var sum = 0.0;
    for (var i = 0u; i + 1u < n; i++) {
        if cuts[i + 1u] > cuts[i] {
            sum += uniform_piece(r, cuts[i], cuts[i + 1u], a, b);
        }
    }
    return sum;
}

fn polyline_fraction(h0: u32, el: f32, az: f32, r: f32, half_span: f32, earth: bool) -> f32 {
    let az_from = az - half_span;
    let left = horizon_at(h0, az_from) - el;
    let right = horizon_at(h0, az + half_span) - el;
    let slope = (right - left) / (2.0 * r);
    let m = 0.5 * (left + right);
    let seg = chord(earth, m / sqrt(1.0 + slope * slope) / r);
    var points: array<vec2<f32>, MAX_POLY_POINTS>;
    var n = 0u;
    let nb = params.n_bands;
    let k0 = segment(az_from).x;
    let u_per_deg = r / half_span;
    var k = (k0 + 1u) % nb;
    while n < MAX_POLY_POINTS {
        let x = band_az(k) - az_from;
        let d = x - 360.0 * floor(x * (1.0 / 360.0));
        if d >= 2.0 * half_span || k == k0 {
            break;
        }
        points[n] = vec2<f32>(-r + d * u_per_deg, horizons[h0 + k] - el);
        n += 1u;
        k = (k + 1u) % nb;
    }
    var off_chord = 0.0;
    for (var i = 0u; i < n; i++) {
        let p = points[i];
        off_chord = max(off_chord, abs(p.y - (left + slope * (p.x + r))));
    }
    if off_chord <= 0.01 * r {
        return seg;
    }
    var some_visible = false;
    var some_hidden = false;
    var prev = vec2<f32>(-r, left);
    for (var i = 0u; i <= n; i++) {
        var p = vec2<f32>(r, right);
        if i < n {
            p = points[i];
        }
        if p.x > prev.x {
            let b = (p.y - prev.y) / (p.x - prev.x);
            let a = prev.y - b * prev.x;
            let q = sqrt(1.0 + b * b);
            let ut = clamp(-b * r / q, prev.x, p.x);
            some_visible = some_visible || (sqrt(max(r * r - ut * ut, 0.0)) - (a + b * ut) > 0.0);
            let ub = clamp(b * r / q, prev.x, p.x);
            some_hidden = some_hidden || (a + b * ub + sqrt(max(r * r - ub * ub, 0.0)) > 0.0);
        }
        prev = p;
    }
    if !some_visible {
        return 0.0;
    }
    if !some_hidden {
        return 1.0;
    }
    if !earth || (seg >= 0.02 && seg <= 0.98) {
        return seg;
    }
    var total = 0.0;
    prev = vec2<f32>(-r, left);
    for (var i = 0u; i <= n; i++) {
        var p = vec2<f32>(r, right);
        if i < n {
            p = points[i];
        }
        if p.x > prev.x {
            total += line_piece(r, prev, p);
        }
        prev = p;
    }
    return clamp(total / (PI * r * r), 0.0, 1.0);
}

// The body at pos_km (from the Moon's centre), angular radius r, from cell c: (sin el, cos el,
// visible fraction).
fn body_at(c: Cell, h0: u32, pos_km: vec3<f32>, r: f32, earth: bool) -> vec3<f32> {
    let vz = dot(c.up_r.xyz, pos_km) - c.up_r.w;
    let vx = dot(c.east_hmin.xyz, pos_km);
    let vy = dot(c.north_hmax.xyz, pos_km);
    let hxy = sqrt(vx * vx + vy * vy);
    let inv_len = 1.0 / sqrt(hxy * hxy + vz * vz);
    let sin_el = vz * inv_len;
    let cos_el = hxy * inv_len;
    let el = atan2_deg(vz, hxy);
    var fraction = 0.0;
    if el - r >= c.north_hmax.w {
        fraction = 1.0;
    } else if el + r <= c.east_hmin.w {
        fraction = 0.0;
    } else {
        let a = atan2_deg(vx, vy);
        let az = select(a, a + 360.0, a < 0.0);
        var half_span = 180.0;
        if cos_el > 1e-3 {
            half_span = min(r / cos_el, 180.0);
        }
        if earth && half_span < 90.0 {
            fraction = polyline_fraction(h0, el, az, r, half_span, earth);
        } else {
            let left = horizon_at(h0, az - half_span) - el;
            let right = horizon_at(h0, az + half_span) - el;
            let m = 0.5 * (left + right);
            let k = (right - left) / (2.0 * r);
            fraction = chord(earth, m / sqrt(1.0 + k * k) / r);
        }
    }
    return vec3<f32>(sin_el, cos_el, fraction);
}

@compute @workgroup_size(WORKGROUP_SIZE_X, 1, 1)
fn horizon_stats(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * params.groups_x * WORKGROUP_SIZE_X;
    if i >= params.n_cells {
        return;
    }
    let c = cells[i];
    let h0 = i * params.stride;
    var s = acc[i];
    var sum = 0.0;
    var irr_h = 0.0;
    var irr_t = 0.0;
    for (var j = params.epoch_begin; j < params.epoch_end; j++) {
        let e = epochs[j];
        let sun = body_at(c, h0, e.sun.xyz, e.sun.w, false);
        let earth = body_at(c, h0, e.earth.xyz, e.earth.w, true);
        let fs = sun.z;
        let fe = earth.z;
        let sun_up = fs > params.visible_min;
        let earth_up = fe > params.visible_min;
        sum += fs;
        let flux = e.w.x * fs;
        irr_h += flux * max(sun.x, 0.0);
        irr_t += flux * sun.y;
        s.sun_visible += select(0u, 1u, sun_up);
        s.sun_full += select(0u, 1u, fs >= params.full_min);
        s.earth_visible += select(0u, 1u, earth_up);
        s.sun_and_earth += select(0u, 1u, sun_up && earth_up);
        s.dark_run = select(s.dark_run + 1u, 0u, sun_up);
        s.dark_max = max(s.dark_max, s.dark_run);
        s.earth_hidden_run = select(s.earth_hidden_run + 1u, 0u, earth_up);
        s.earth_hidden_max = max(s.earth_hidden_max, s.earth_hidden_run);
        s.low_lit += select(0u, 1u, sun_up && sun.x < c.dip.x);
        if (j + 1u) % EPOCH_CHUNK == 0u || j + 1u == params.epoch_end {
            s.sun_fraction_sum += sum;
            s.irradiance_horizontal_sum += irr_h;
            s.irradiance_tracking_sum += irr_t;
            sum = 0.0;
            irr_h = 0.0;
            irr_t = 0.0;
        }
    }
    acc[i] = s;
}
