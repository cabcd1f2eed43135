//
// One invocation per pixel: the camera ray, max-mipmap ray casting through the height field
// (the GPU twin of src/render/cast.rs `RayCaster::cast_mipmap`), the bilinear surface normal,
// shading with the per-cell Sun/Earth visible fractions (bilinear lookup), earthshine, and the
// sky discs (src/render/mod.rs `Scene::sample`). Output: radiance W/(m^2 sr) per pixel, or a
// negative class code for rays that hit no terrain (-1 sky, -2 Sun disc, -3 Earth disc).
//
// Units: u = fractional column, v = fractional row (cell centres at integers, v grows south),
// heights in metres relative to the grid's mid height (`heights`, `pyramid`); the ray parameter
// t is metres along the unit model-space direction. Holes are stored as HOLE (-1e30).

struct Params {
    origin: vec4<f32>,   // camera u, v, z (relative), -
    forward: vec4<f32>,  // model space unit vectors of the camera
    right: vec4<f32>,
    up: vec4<f32>,
    sun: vec4<f32>,      // unit vector to the Sun, w = sin(angular radius)
    earth: vec4<f32>,    // unit vector to the Earth, w = sin(angular radius)
    grid: vec4<f32>,     // px_m, z_lo (min - 1 m), z_hi (max + 1 m), tan(fov / 2)
    shade: vec4<f32>,    // Sun irradiance W/m^2, Earth irradiance W/m^2, albedo, height / width
    dims: vec4<u32>,     // rows, cols, pyramid levels, BRDF model
    image: vec4<u32>,    // width, height, first row of this band, rows in this band
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> heights: array<f32>;
@group(0) @binding(2) var<storage, read> pyramid: array<f32>;
// Per level: rows, cols, offset of the first texel, -.
@group(0) @binding(3) var<storage, read> levels: array<vec4<u32>>;
// Per cell: Sun and Earth visible fractions (negative = no value).
@group(0) @binding(4) var<storage, read> fractions: array<vec2<f32>>;
@group(0) @binding(5) var<storage, read_write> radiance: array<f32>;

const HOLE_TEST: f32 = -1e29;
const PATCH_BISECTIONS: i32 = 24;

// Cell height with indices clamped into the grid.
fn cell_z(r: i32, c: i32) -> f32 {
    let rr = clamp(r, 0, i32(params.dims.x) - 1);
    let cc = clamp(c, 0, i32(params.dims.y) - 1);
    return heights[u32(rr) * params.dims.y + u32(cc)];
}

fn texel(m: u32, i: i32, j: i32) -> f32 {
    let l = levels[m];
    let ii = clamp(i, 0, i32(l.x) - 1);
    let jj = clamp(j, 0, i32(l.y) - 1);
    return pyramid[l.z + u32(ii) * l.y + u32(jj)];
}

// Nudge (cells) putting a point on a texel boundary into the texel ahead: above the f32
// resolution of the coordinate.
fn nudge(x: f32) -> f32 {
    return 1e-3 + 5e-7 * abs(x);
}

fn texel_index(x: f32, dx: f32, size: f32) -> i32 {
    var n = x;
    if (dx > 0.0) {
        n = x + nudge(x);
    } else if (dx < 0.0) {
        n = x - nudge(x);
    }
    return i32(floor(n / size));
}

fn texel_exit(o: f32, d: f32, k: i32, size: f32) -> f32 {
    if (d > 0.0) {
        return (f32(k + 1) * size - o) / d;
    } else if (d < 0.0) {
        return (f32(k) * size - o) / d;
    }
    return 3.4e38;
}

// Ray / box: (t_in, t_out), t_out < t_in when missed.
fn clip(o: vec3<f32>, d: vec3<f32>) -> vec2<f32> {
    let lo = vec3<f32>(-0.5, -0.5, params.grid.y);
    let hi = vec3<f32>(f32(params.dims.y) - 0.5, f32(params.dims.x) - 0.5, params.grid.z);
    var t0 = -3.4e38;
    var t1 = 3.4e38;
    for (var k = 0; k < 3; k++) {
        if (abs(d[k]) < 1e-15) {
            if (o[k] < lo[k] || o[k] > hi[k]) {
                return vec2<f32>(1.0, -1.0);
            }
        } else {
            let a = (lo[k] - o[k]) / d[k];
            let b = (hi[k] - o[k]) / d[k];
            t0 = max(t0, min(a, b));
            t1 = min(t1, max(a, b));
        }
    }
    return vec2<f32>(t0, t1);
}

// Exact first crossing with the bilinear patch of dual cell (i, j) on [ta, tb]; -1 if none.
fn patch_hit(o: vec3<f32>, d: vec3<f32>, i: i32, j: i32, ta: f32, tb: f32) -> f32 {
    let z00 = cell_z(i, j);
    let z01 = cell_z(i, j + 1);
    let z10 = cell_z(i + 1, j);
    let z11 = cell_z(i + 1, j + 1);
    if (min(min(z00, z01), min(z10, z11)) < HOLE_TEST) {
        return -1.0;
    }
    let a = z01 - z00;
    let b = z10 - z00;
    let c = z00 - z01 - z10 + z11;
    let start = o + ta * d;
    let pu = start.x - f32(j);
    let pv = start.y - f32(i);
    let len = tb - ta;
    let qa = -c * d.x * d.y;
    let qb = d.z - (a * d.x + b * d.y + c * (pu * d.y + d.x * pv));
    var cuts = array<f32, 3>(0.0, len, len);
    if (qa != 0.0) {
        let s_v = -qb / (2.0 * qa);
        if (s_v > 0.0 && s_v < len) {
            cuts[1] = s_v;
        }
    }
    if (patch_f(start, d, pu, pv, z00, a, b, c, 0.0) <= 0.0) {
        return ta;
    }
    for (var k = 0; k < 2; k++) {
        var lo = cuts[k];
        var hi = cuts[k + 1];
        if (hi > lo && patch_f(start, d, pu, pv, z00, a, b, c, hi) <= 0.0) {
            for (var n = 0; n < PATCH_BISECTIONS; n++) {
                let mid = 0.5 * (lo + hi);
                if (patch_f(start, d, pu, pv, z00, a, b, c, mid) <= 0.0) {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            return ta + hi;
        }
    }
    return -1.0;
}

// Ray height minus surface height at ta + s.
fn patch_f(start: vec3<f32>, d: vec3<f32>, pu: f32, pv: f32, z00: f32, a: f32, b: f32, c: f32,
           s: f32) -> f32 {
    let fu = clamp(pu + d.x * s, 0.0, 1.0);
    let fv = clamp(pv + d.y * s, 0.0, 1.0);
    return start.z + d.z * s - (z00 + a * fu + b * fv + c * fu * fv);
}

// Max-mipmap casting: ray parameter of the first hit, or -1.
fn cast_ray(o: vec3<f32>, d: vec3<f32>) -> f32 {
    let box = clip(o, d);
    let t_out = box.y;
    var t = max(box.x, 0.0);
    if (t_out < t) {
        return -1.0;
    }
    let top = params.dims.z - 1u;
    var level = top;
    let speed = max(abs(d.x), abs(d.y));
    var budget = 64u * (params.dims.x + params.dims.y + 16u) * (top + 1u);
    loop {
        if (t >= t_out || budget == 0u) {
            break;
        }
        budget -= 1u;
        let p = o + t * d;
        let size = f32(1u << level);
        let j = texel_index(p.x, d.x, size);
        let i = texel_index(p.y, d.y, size);
        var min_dt = 1e-6 * abs(t);
        if (speed > 0.0) {
            min_dt = max(min_dt, nudge(max(abs(p.x), abs(p.y))) / speed);
        }
        let t_exit = max(
            min(min(texel_exit(o.x, d.x, j, size), texel_exit(o.y, d.y, i, size)), t_out),
            t + min_dt);
        let z_low = min(p.z, o.z + t_exit * d.z);
        if (z_low > texel(level, i, j)) {
            t = t_exit;
            level = min(level + 1u, top);
        } else if (level > 0u) {
            level -= 1u;
        } else {
            let th = patch_hit(o, d, i, j, t, t_exit);
            if (th >= 0.0) {
                return th;
            }
            t = t_exit;
            level = min(1u, top);
        }
    }
    return -1.0;
}

// Bilinear height at (u, v): (z, 1) or (0, 0) outside the grid or next to a hole (as
// render::bilinear without skip_nan).
fn surface_z(u: f32, v: f32) -> vec2<f32> {
    let rows = f32(params.dims.x);
    let cols = f32(params.dims.y);
    if (!(v >= -0.5 && u >= -0.5 && v <= rows - 0.5 && u <= cols - 0.5)) {
        return vec2<f32>(0.0, 0.0);
    }
    let r = clamp(v, 0.0, rows - 1.0);
    let c = clamp(u, 0.0, cols - 1.0);
    let r0 = i32(floor(r));
    let c0 = i32(floor(c));
    let fr = r - f32(r0);
    let fc = c - f32(c0);
    let w = vec4<f32>((1.0 - fr) * (1.0 - fc), (1.0 - fr) * fc, fr * (1.0 - fc), fr * fc);
    let z = vec4<f32>(cell_z(r0, c0), cell_z(r0, c0 + 1), cell_z(r0 + 1, c0),
                      cell_z(r0 + 1, c0 + 1));
    var acc = 0.0;
    for (var k = 0; k < 4; k++) {
        if (z[k] < HOLE_TEST) {
            if (w[k] > 0.0) {
                return vec2<f32>(0.0, 0.0);
            }
        } else {
            acc += w[k] * z[k];
        }
    }
    return vec2<f32>(acc, 1.0);
}

// Bilinear visible fractions at (u, v), missing corners left out (weights renormalised).
fn fractions_at(u: f32, v: f32) -> vec2<f32> {
    let rows = f32(params.dims.x);
    let cols = f32(params.dims.y);
    let r = clamp(v, 0.0, rows - 1.0);
    let c = clamp(u, 0.0, cols - 1.0);
    let r0 = i32(floor(r));
    let c0 = i32(floor(c));
    let r1 = min(r0 + 1, i32(params.dims.x) - 1);
    let c1 = min(c0 + 1, i32(params.dims.y) - 1);
    let fr = r - f32(r0);
    let fc = c - f32(c0);
    let cols_u = params.dims.y;
    var f = array<vec2<f32>, 4>(
        fractions[u32(r0) * cols_u + u32(c0)], fractions[u32(r0) * cols_u + u32(c1)],
        fractions[u32(r1) * cols_u + u32(c0)], fractions[u32(r1) * cols_u + u32(c1)]);
    var w = array<f32, 4>((1.0 - fr) * (1.0 - fc), (1.0 - fr) * fc, fr * (1.0 - fc), fr * fc);
    var acc = vec2<f32>(0.0);
    var wsum = vec2<f32>(0.0);
    for (var k = 0; k < 4; k++) {
        let ok = vec2<f32>(step(vec2<f32>(0.0), f[k]));
        acc += w[k] * ok * f[k];
        wsum += w[k] * ok;
    }
    return select(vec2<f32>(0.0), acc / max(wsum, vec2<f32>(1e-30)), wsum > vec2<f32>(0.0));
}

// Unit normal from central differences one cell each side (one-sided at edges), as
// Scene::normal_at. Returns w = 0 when the surface is undefined at (u, v).
fn normal_at(u: f32, v: f32) -> vec4<f32> {
    let px = params.grid.x;
    let z = surface_z(u, v);
    if (z.y == 0.0) {
        return vec4<f32>(0.0);
    }
    let zx0 = surface_z(u - 1.0, v);
    let zx1 = surface_z(u + 1.0, v);
    let zy0 = surface_z(u, v + 1.0); // y - px
    let zy1 = surface_z(u, v - 1.0); // y + px
    var dzdx = 0.0;
    if (zx0.y > 0.0 && zx1.y > 0.0) {
        dzdx = (zx1.x - zx0.x) / (2.0 * px);
    } else if (zx1.y > 0.0) {
        dzdx = (zx1.x - z.x) / px;
    } else if (zx0.y > 0.0) {
        dzdx = (z.x - zx0.x) / px;
    }
    var dzdy = 0.0;
    if (zy0.y > 0.0 && zy1.y > 0.0) {
        dzdy = (zy1.x - zy0.x) / (2.0 * px);
    } else if (zy1.y > 0.0) {
        dzdy = (zy1.x - z.x) / px;
    } else if (zy0.y > 0.0) {
        dzdy = (z.x - zy0.x) / px;
    }
    return vec4<f32>(normalize(vec3<f32>(-dzdx, -dzdy, 1.0)), 1.0);
}

// Radiance of one light: brdf * E_normal * cos_i (0 when the light is behind the surface).
fn light_term(n: vec3<f32>, l: vec3<f32>, view: vec3<f32>, e_normal: f32) -> f32 {
    let cos_i = dot(n, l);
    if (cos_i <= 0.0 || e_normal <= 0.0) {
        return 0.0;
    }
    let cos_e = dot(n, view);
    let cos_g = dot(l, view);
    return brdf_per_sr(params.dims.w, cos_i, cos_e, cos_g, params.shade.z) * e_normal * cos_i;
}

@compute @workgroup_size(8, 8, 1)
fn render(@builtin(global_invocation_id) gid: vec3<u32>) {
    let width = params.image.x;
    let height = params.image.y;
    let col = gid.x;
    let band_row = gid.y;
    if (col >= width || band_row >= params.image.w) {
        return;
    }
    let row = params.image.z + band_row;
    let t_fov = params.grid.w;
    let su = (2.0 * (f32(col) + 0.5) / f32(width) - 1.0) * t_fov;
    let sv = (1.0 - 2.0 * (f32(row) + 0.5) / f32(height)) * t_fov * params.shade.w;
    let dir = normalize(params.forward.xyz + su * params.right.xyz + sv * params.up.xyz);
    let px = params.grid.x;
    let o = params.origin.xyz;
    let d = vec3<f32>(dir.x / px, -dir.y / px, dir.z);
    var out = -1.0;
    let th = cast_ray(o, d);
    var shaded = false;
    if (th >= 0.0) {
        let p = o + th * d;
        let n = normal_at(p.x, p.y);
        if (n.w > 0.0) {
            let f = fractions_at(p.x, p.y);
            let view = -dir;
            out = light_term(n.xyz, params.sun.xyz, view, params.shade.x * f.x)
                + light_term(n.xyz, params.earth.xyz, view, params.shade.y * f.y);
            shaded = true;
        }
    }
    if (!shaded) {
        // Angles to the disc centres via |dir x l| (exact for small angles in f32).
        if (dot(dir, params.sun.xyz) > 0.0 && length(cross(dir, params.sun.xyz)) <= params.sun.w) {
            out = -2.0;
        } else if (dot(dir, params.earth.xyz) > 0.0
                   && length(cross(dir, params.earth.xyz)) <= params.earth.w) {
            // The Earth's phase (CPU twin: Scene::earth_point_is_day): the point where the ray
            // meets the Earth's sphere (unit distance, radius sin r) is day when its outward
            // normal faces the Sun.
            let e = params.earth.xyz;
            let sin_r = params.earth.w;
            let cos_r2 = 1.0 - sin_r * sin_r;
            let de = dot(dir, e);
            let t = de - sqrt(max(de * de - cos_r2, 0.0));
            let n_earth = (t * dir - e) / sin_r;
            out = select(-4.0, -3.0, dot(n_earth, params.sun.xyz) > 0.0);
        }
    }
    radiance[band_row * width + col] = out;
}
