// DP soft-shadow map: out[cell] = visible fraction of the disc dp_lights[dp_step.light0] (unit
// direction + angular radius; radius 0 gives the hard mask 1/0), -1 for nodata. Dispatch: one
// invocation per cell of one row band, workgroups (ceil(cols/8), ceil(band_rows/8)). Bindings:
// 0..5 from shared/dp.wgsl; 6 out (f32, band-relative). Precision: shared/dp.wgsl.
// CPU twin: `dp_visible` in src/twins/dp.rs.

const WORKGROUP_SIZE_X: u32 = 8u;
const WORKGROUP_SIZE_Y: u32 = 8u;
const NODATA_FRACTION: f32 = -1.0;

// Band-relative, row-major: index (row - band_row0) * cols + col.
@group(0) @binding(6) var<storage, read_write> out: array<f32>;

@compute @workgroup_size(WORKGROUP_SIZE_X, WORKGROUP_SIZE_Y, 1)
fn dp_visible(@builtin(global_invocation_id) gid: vec3<u32>) {
    let col = gid.x;
    let band_row = gid.y;
    if col >= dp_grid.cols || band_row >= dp_step.band_rows {
        return;
    }
    let row = dp_step.band_row0 + band_row;
    if dp_is_hole(row, col) {
        out[band_row * dp_grid.cols + col] = NODATA_FRACTION;
        return;
    }
    let obs = dp_observer(row, col);
    out[band_row * dp_grid.cols + col] = dp_fraction(obs, dp_lights[dp_step.light0]);
}
