// requires: shared/march.wgsl
// Soft shadow map: out[cell] = fraction of the N disc directions in `lights` that are lit (uniform
// disc, no limb darkening), -1 for nodata. Dispatch: one invocation per cell of one row band,
// workgroups (ceil(cols/8), ceil(band_rows/8)). Bindings: 0..3 from shared/march.wgsl
// (step_params.light_index unused; N = arrayLength(lights)); 4 out (f32). Precision: shared/march.wgsl;
// the fraction is (lit count) / N, exact in f32 for N < 2^24. CPU twin: `shadow_march_soft`.

const WORKGROUP_SIZE_X: u32 = 8u;
const WORKGROUP_SIZE_Y: u32 = 8u;
const NODATA_FRACTION: f32 = -1.0;

// Band-relative, row-major: index (row - band_row0) * cols + col.
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

@compute @workgroup_size(WORKGROUP_SIZE_X, WORKGROUP_SIZE_Y, 1)
fn shadow_march_soft(@builtin(global_invocation_id) gid: vec3<u32>) {
    let col = gid.x;
    let band_row = gid.y;
    if col >= grid.cols || band_row >= step_params.band_rows {
        return;
    }
    let row = step_params.band_row0 + band_row;
    let n = arrayLength(&lights);
    var lit = 0u;
    for (var k = 0u; k < n; k++) {
        let state = march_hard(row, col, lights[k].xyz);
        if state == NODATA {
            out[band_row * grid.cols + col] = NODATA_FRACTION;
            return;
        }
        lit = lit + state;
    }
    out[band_row * grid.cols + col] = f32(lit) / f32(n);
}
