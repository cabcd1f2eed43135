// Soft epoch sweep: for the epochs [light0, light0 + count) of the light table (two entries per
// epoch: the Sun at 2e, the Earth at 2e + 1, each a unit direction + angular radius), the visible
// fractions of both discs (shared/dp.wgsl) are folded into per-cell running statistics with the
// definitions of the CPU `map::sweep`: sun_fraction_sum (Kahan-compensated f32 sum), visible =
// fraction > 1e-6 (any part of the disc), dark runs of the Sun, Earth and Sun-and-Earth counts.
// Dispatch: one invocation per cell of one row band, workgroups (ceil(cols/8), ceil(band_rows/8)),
// repeatedly with consecutive epoch ranges; nothing is read back in between. Bindings: 0..5 from
// shared/dp.wgsl; 6 stats (band-relative, read_write). CPU twin: `dp_sweep` in src/twins/dp.rs.

const WORKGROUP_SIZE_X: u32 = 8u;
const WORKGROUP_SIZE_Y: u32 = 8u;

@group(0) @binding(6) var<storage, read_write> stats: array<DpCellStats>;

@compute @workgroup_size(WORKGROUP_SIZE_X, WORKGROUP_SIZE_Y, 1)
fn dp_sweep(@builtin(global_invocation_id) gid: vec3<u32>) {
    let col = gid.x;
    let band_row = gid.y;
    if col >= dp_grid.cols || band_row >= dp_step.band_rows {
        return;
    }
    let row = dp_step.band_row0 + band_row;
    if dp_is_hole(row, col) {
        return;
    }
    let obs = dp_observer(row, col);
    let k = band_row * dp_grid.cols + col;
    var s = stats[k];
    for (var e = dp_step.light0; e < dp_step.light0 + dp_step.count; e++) {
        let fs = dp_fraction(obs, dp_lights[2u * e]);
        let fe = dp_fraction(obs, dp_lights[2u * e + 1u]);
        dp_sweep_accumulate(&s, fs, fe);
    }
    stats[k] = s;
}
