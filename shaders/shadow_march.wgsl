// requires: shared/march.wgsl
// Hard shadow map: out[cell] = 1 lit, 0 shadow, 255 nodata for the light lights[step_params.light_index].
// Dispatch: one invocation per cell of one row band, workgroups (ceil(cols/8), ceil(band_rows/8)).
// Bindings: 0 grid, 1 heights, 2 lights, 3 step_params (dynamic offset) from shared/march.wgsl; 4 out.
// Precision budget: see shared/march.wgsl (f32 heights relative to z_ref, f32 light on the CPU).
// CPU twin: `shadow_march` in src/shadow/gpu_twins.rs.

const WORKGROUP_SIZE_X: u32 = 8u;
const WORKGROUP_SIZE_Y: u32 = 8u;

// Band-relative, row-major: index (row - band_row0) * cols + col.
@group(0) @binding(4) var<storage, read_write> out: array<u32>;

@compute @workgroup_size(WORKGROUP_SIZE_X, WORKGROUP_SIZE_Y, 1)
fn shadow_march(@builtin(global_invocation_id) gid: vec3<u32>) {
    let col = gid.x;
    let band_row = gid.y;
    if col >= grid.cols || band_row >= step_params.band_rows {
        return;
    }
    let light = lights[step_params.light_index].xyz;
    out[band_row * grid.cols + col] = march_hard(step_params.band_row0 + band_row, col, light);
}
