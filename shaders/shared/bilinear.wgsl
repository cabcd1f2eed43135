// fragment: uses `heights`, NO_SAMPLE and HOLE_TEST_M of the kernels it is composed with, so it
// is validated within those kernels only.
// Nodata-aware bilinear heights of row-major layers stored one after another in `heights`
// (composed before horizon_scan.wgsl and line_sweep.wgsl, src/gpu/shaders.rs, which bind
// `heights: array<f32>` and define NO_SAMPLE and HOLE_TEST_M). CPU twin:
// `twins::bilinear_with_holes`; f64 original: `Dem::height_at_row_col`.

// Height of cell (row, col) of the layer stored from `heights[base]` with `rows` x `cols`
// cells; NO_SAMPLE outside it.
fn layer_cell(base: u32, rows: u32, cols: u32, row: i32, col: i32) -> f32 {
    if row < 0 || col < 0 || row >= i32(rows) || col >= i32(cols) {
        return NO_SAMPLE;
    }
    return heights[base + u32(row) * cols + u32(col)];
}

// Bilinear height at fractional (row, col) of that layer: NO_SAMPLE outside the outer cell
// edges, when the nearest centre is a hole, or with no valid corner; else the weighted mean of
// the valid corners (edge values extended within the outer half cell).
fn layer_height(base: u32, n_rows: u32, n_cols: u32, row: f32, col: f32) -> f32 {
    let rows = f32(n_rows);
    let cols = f32(n_cols);
    if !(row >= -0.5 && col >= -0.5 && row <= rows - 0.5 && col <= cols - 0.5) {
        return NO_SAMPLE;
    }
    let r = clamp(row, 0.0, rows - 1.0);
    let c = clamp(col, 0.0, cols - 1.0);
    let r0 = max(min(i32(floor(r)), i32(n_rows) - 2), 0);
    let c0 = max(min(i32(floor(c)), i32(n_cols) - 2), 0);
    let fr = r - f32(r0);
    let fc = c - f32(c0);
    let rn = i32(clamp(floor(row + 0.5), 0.0, rows - 1.0));
    let cn = i32(clamp(floor(col + 0.5), 0.0, cols - 1.0));
    if layer_cell(base, n_rows, n_cols, rn, cn) < HOLE_TEST_M {
        return NO_SAMPLE;
    }
    var sum = 0.0;
    var wsum = 0.0;
    for (var dr = 0; dr < 2; dr++) {
        let wr = select(1.0 - fr, fr, dr == 1);
        for (var dc = 0; dc < 2; dc++) {
            let w = wr * select(1.0 - fc, fc, dc == 1);
            if w <= 0.0 {
                continue;
            }
            let h = layer_cell(base, n_rows, n_cols, r0 + dr, c0 + dc);
            if h >= HOLE_TEST_M {
                sum = sum + w * h;
                wsum = wsum + w;
            }
        }
    }
    if wsum > 0.0 {
        return sum / wsum;
    }
    return NO_SAMPLE;
}
