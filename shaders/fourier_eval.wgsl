// Fourier horizon-map evaluation (paper 001 eqs. 3, 6, 7; the CPU engine's `hard_mask` and
// `visible_fraction` in src/shadow/fourier.rs): one invocation per cell of one row band.
// out = the visible fraction of a uniform disc of angular radius radius_rad (the circular segment
// above the straight horizon through the disc's left and right edge azimuths), or with radius 0
// the hard test "light elevation > horizon at the light's azimuth" as 1 / 0; -1 for holes.
//
// Dispatch: workgroups (ceil(cols / 8), ceil(band_rows / 8)). Bindings: 0 params; 1 the band's
// coefficients, one u32 per complex coefficient holding the two f16 of the stored map (low half
// Re X_k, high half Im X_k; unpack2x16float converts exactly); a hole has Re X_0 = -65504
// (f16::MIN; no NaN on the GPU); 2 out (f32, band-relative).
// CPU twin: `fourier_eval` in src/twins/fourier.rs (line by line).
//
// Precision (f32): cos k theta and sin k theta come from the (cos, sin) of theta (f64 on the CPU)
// by the rotation recurrence (error ~ k * 1e-7), not from sin/cos of large arguments (WGSL
// promises an accuracy only on [-pi, pi]).

const FE_WORKGROUP_X: u32 = 8u;
const FE_WORKGROUP_Y: u32 = 8u;
const FE_NODATA_FRACTION: f32 = -1.0;
// Re X_0 of a hole is f16::MIN (-65504); a real one is an angle in [-pi/2, pi/2].
const FE_HOLE_TEST: f32 = -60000.0;
const FE_PI: f32 = 3.14159265358979;

// Keep in sync with `FourierEvalParams` in src/twins/fourier.rs.
struct FourierEvalParams {
    rows: u32,
    cols: u32,
    n_coeffs: u32,
    band_row0: u32,
    band_rows: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    // (cos, sin) of the light's azimuth and of the disc's left and right edge azimuths.
    mid: vec2<f32>,
    left: vec2<f32>,
    right: vec2<f32>,
    // The light's elevation above the model x/y plane and the disc's angular radius, radians.
    el_rad: f32,
    radius_rad: f32,
}

@group(0) @binding(0) var<uniform> fe: FourierEvalParams;
@group(0) @binding(1) var<storage, read> fe_coeffs: array<u32>;
@group(0) @binding(2) var<storage, read_write> fe_out: array<f32>;

// Paper 001 eq. 3 at the azimuth whose (cos, sin) is cs: sum of Re X_k cos k theta -
// Im X_k sin k theta over the cell's coefficients starting at `base`.
fn fe_series(base: u32, cs: vec2<f32>) -> f32 {
    var c = 1.0;
    var s = 0.0;
    var sum = 0.0;
    for (var k = 0u; k < fe.n_coeffs; k++) {
        let x = unpack2x16float(fe_coeffs[base + k]);
        sum = sum + (x.x * c - x.y * s);
        let c_next = c * cs.x - s * cs.y;
        s = s * cs.x + c * cs.y;
        c = c_next;
    }
    return sum;
}

@compute @workgroup_size(FE_WORKGROUP_X, FE_WORKGROUP_Y, 1)
fn fourier_eval(@builtin(global_invocation_id) gid: vec3<u32>) {
    let col = gid.x;
    let band_row = gid.y;
    if col >= fe.cols || band_row >= fe.band_rows {
        return;
    }
    let cell = band_row * fe.cols + col;
    let base = cell * fe.n_coeffs;
    if unpack2x16float(fe_coeffs[base]).x < FE_HOLE_TEST {
        fe_out[cell] = FE_NODATA_FRACTION;
        return;
    }
    let mid = fe_series(base, fe.mid);
    let r = fe.radius_rad;
    if r <= 0.0 {
        fe_out[cell] = select(0.0, 1.0, fe.el_rad > mid);
        return;
    }
    let left = fe_series(base, fe.left) - fe.el_rad;
    let right = fe_series(base, fe.right) - fe.el_rad;
    // The line through (-r, left) and (r, right); its signed distance from the disc centre
    // (positive: above the centre), eq. 6, then the circular segment above it, eq. 7.
    let m = 0.5 * (left + right);
    let k = (right - left) / (2.0 * r);
    let d = m / sqrt(1.0 + k * k);
    let x = d / r;
    var f = 0.0;
    if x <= -1.0 {
        f = 1.0;
    } else if x < 1.0 {
        f = (acos(x) - x * sqrt(1.0 - x * x)) / FE_PI;
    }
    fe_out[cell] = f;
}
