// Fourier horizon-map build (paper 001 §3.2, the CPU engine src/shadow/fourier.rs): one
// invocation per cell of one row band. For each azimuth theta_n = 2 pi n / N of this dispatch
// (n = az0 .. az0 + az_count) it marches the horizontal ray over every crossing with the lattice
// lines of cell centres (the DDA of shared/march.wgsl, the surface convention of the brute-force
// engine), keeps the largest tan of the terrain's elevation seen from the observer, from the bare
// sphere's horizon up (fb_sphere_floor_tan), takes atan, and folds the sample straight into the truncated DFT:
// acc_k += alpha_n (cos k theta_n, -sin k theta_n). No per-azimuth samples are stored; the
// partial sums live in `coeffs` between dispatches (azimuth chunks keep each dispatch short).
// The last dispatch multiplies by the eq. 3 weights (1/N for k = 0, 2/N else).
//
// Dispatch: workgroups (ceil(cols / 8), ceil(band_rows / 8)); gid.x = col, gid.y = band row.
// Bindings: 0 grid and 1 heights from shared/march.wgsl; 4 (sin, cos)
// of 2 pi m / N for m = 0 .. N - 1, computed in f64 on the CPU (the azimuth directions and the DFT
// twiddles, index k n mod N: no large-argument sin/cos on the GPU); 5 build params; 6 coeffs
// (band-relative cell * 2K + 2k + {0: Re, 1: Im}, f32; HOLE_COEFF for every value of a hole).
// CPU twin: `fourier_build` in src/twins/fourier.rs (line by line).
//
// Precision (f32): heights relative to z_ref and cell-unit positions as in shared/march.wgsl;
// tan el = (z - z0) / t_m with t_m >= ~1 cell; atan per the WGSL accuracy rules (a few ulp on a
// hardware GPU); the DFT sums N terms of |alpha| <= pi/2 in f32 (error ~ N * 6e-8 * |alpha|,
// below 1e-5 rad at N = 720, against the f16 storage ulp of 1e-4 .. 5e-4 rad).

const FB_WORKGROUP_X: u32 = 8u;
const FB_WORKGROUP_Y: u32 = 8u;
// Most partial sums one invocation holds: 2 * 32 complex coefficients (K <= 32).
const FB_MAX_VALUES: u32 = 64u;
// A crossing this close outside the lattice (cells) is clamped onto its edge line, as the CPU
// engine's march (tolerance 1e-9 there, in f64): a ray that runs along an edge row or column
// (observer clamped onto the edge, axis-aligned azimuth) must sample it. 1e-3 cells is above the
// f32 ulp of positions up to 8,192 cells.
const FB_EDGE_TOL_CELLS: f32 = 1.0e-3;
// Written for every value of a hole cell (no NaN on the GPU).
const HOLE_COEFF: f32 = -1.0e30;

// Keep in sync with `FourierBuildParams` in src/twins/fourier.rs.
struct FourierBuildParams {
    band_row0: u32,
    band_rows: u32,
    // N, the number of azimuths of the whole build.
    n_az: u32,
    // The azimuths of this dispatch: az0 .. az0 + az_count.
    az0: u32,
    az_count: u32,
    // K, complex coefficients kept (2 K <= FB_MAX_VALUES).
    n_coeffs: u32,
    // Crossings farther than this (cells of horizontal travel) are not sampled.
    max_distance_cells: f32,
    // 1: this dispatch holds the last azimuths; apply the weights.
    last: u32,
}

@group(0) @binding(4) var<storage, read> fb_sincos: array<vec2<f32>>;
@group(0) @binding(5) var<uniform> fb: FourierBuildParams;
@group(0) @binding(6) var<storage, read_write> fb_coeffs: array<f32>;

// Largest tan(elevation) of the terrain along the horizontal ray from (u0, v0, z0) with grid
// direction (du, dv) (unit), at least `start_tan`. Crossings from dda_next of shared/march.wgsl
// (clamped within FB_EDGE_TOL_CELLS of the edge lines); stops at the grid edge, beyond max_distance_cells, or once no sample can beat the best: (z_max - z0) / t <= best.
const FB_MOON_RADIUS_M: f32 = 1737400.0;

// Start value of `horizon_tan` (tan above the model x/y plane): the bare sphere's horizon, the dip
// sqrt(2 h / R) below the observer's local horizontal (h: its height above the sphere). Fourier
// profiles need a finite, smooth floor (a -90 degree step where no terrain lies along a ray would
// ring through the truncated DFT); it differs from "no terrain beyond the outermost layer" only on
// rays that meet the sphere beyond the grid, which the map products flag.
fn fb_sphere_floor_tan(x_m: f32, y_m: f32, z0: f32, up: vec3<f32>, sc: vec2<f32>) -> f32 {
    let tan_local = -(up.x * sc.x + up.y * sc.y) / up.z;
    let h = z0 + (grid.z_ref_plus_radius_m - FB_MOON_RADIUS_M)
        + (x_m * x_m + y_m * y_m) / (2.0 * FB_MOON_RADIUS_M);
    let dip = sqrt(2.0 * max(h, 0.0) / FB_MOON_RADIUS_M);
    return tan(atan(tan_local) - dip);
}

fn horizon_tan(u0: f32, v0: f32, z0: f32, du: f32, dv: f32, start_tan: f32) -> f32 {
    var best = start_tan;
    var dda = dda_start(u0, v0, du, dv);
    let max_steps = i32(grid.rows) + i32(grid.cols) + 4;
    for (var i = 0; i < max_steps; i++) {
        let c = dda_next(&dda, FB_EDGE_TOL_CELLS);
        if !c.inside {
            return best;
        }
        if c.t > fb.max_distance_cells {
            return best;
        }
        let t_m = c.t * grid.px_m;
        // Holes are -1e30 m: their samples never win.
        best = max(best, (c.z_surf - z0) / t_m);
        // Beyond t no sample rises above (z_max - z0) / t' (t' >= t): the bound at t when the
        // top is above the observer, else 0 (approached as t' grows).
        if max((grid.z_max_m - z0) / t_m, 0.0) <= best {
            return best;
        }
    }
    return best;
}

@compute @workgroup_size(FB_WORKGROUP_X, FB_WORKGROUP_Y, 1)
fn fourier_build(@builtin(global_invocation_id) gid: vec3<u32>) {
    let col = gid.x;
    let band_row = gid.y;
    if col >= grid.cols || band_row >= fb.band_rows {
        return;
    }
    let row = fb.band_row0 + band_row;
    let per = 2u * fb.n_coeffs;
    let base = (band_row * grid.cols + col) * per;
    let z_cell = heights[row * grid.cols + col];
    if z_cell < HOLE_TEST_M {
        for (var i = 0u; i < per; i++) {
            fb_coeffs[base + i] = HOLE_COEFF;
        }
        return;
    }
    // Observer: observer_height_m above the surface along the radial direction, kept inside
    // the lattice (as the CPU engine's observer_at).
    let x_m = grid.x0_m + f32(col) * grid.px_m;
    let y_m = grid.y0_m - f32(row) * grid.px_m;
    let up = normalize(vec3<f32>(x_m, y_m, z_cell + grid.z_ref_plus_radius_m));
    let u0 = clamp(f32(col) + grid.observer_height_m * up.x / grid.px_m, 0.0, f32(grid.cols - 1u));
    let v0 = clamp(f32(row) - grid.observer_height_m * up.y / grid.px_m, 0.0, f32(grid.rows - 1u));
    let z0 = z_cell + grid.observer_height_m * up.z;
    var acc: array<f32, FB_MAX_VALUES>;
    if fb.az0 > 0u {
        for (var i = 0u; i < per; i++) {
            acc[i] = fb_coeffs[base + i];
        }
    }
    for (var a = 0u; a < fb.az_count; a++) {
        let n = fb.az0 + a;
        // (sin, cos) of the azimuth: east, north components; rows grow southwards.
        let sc = fb_sincos[n];
        let alpha = atan(horizon_tan(u0, v0, z0, sc.x, -sc.y, fb_sphere_floor_tan(x_m, y_m, z0, up, sc)));
        var m = 0u;
        for (var k = 0u; k < fb.n_coeffs; k++) {
            let tw = fb_sincos[m];
            acc[2u * k] = acc[2u * k] + alpha * tw.y;
            acc[2u * k + 1u] = acc[2u * k + 1u] - alpha * tw.x;
            m = m + n;
            if m >= fb.n_az {
                m = m - fb.n_az;
            }
        }
    }
    if fb.last == 1u {
        let w0 = 1.0 / f32(fb.n_az);
        let w = 2.0 / f32(fb.n_az);
        acc[0] = acc[0] * w0;
        acc[1] = acc[1] * w0;
        for (var i = 2u; i < per; i++) {
            acc[i] = acc[i] * w;
        }
    }
    for (var i = 0u; i < per; i++) {
        fb_coeffs[base + i] = acc[i];
    }
}
