// Shared by shadow_march.wgsl and shadow_march_soft.wgsl (prepended by the Rust side and by the
// naga test): the grid bindings 0..3 and `march_hard`, the 2-D DDA ray march of one cell towards
// one light direction. CPU twin: `march_hard` in src/shadow/gpu_twins.rs (line by line).
//
// Surface: the bilinear interpolant of the cell-centre heights. In grid units (u = col, v = row,
// cell centres at integers) the ray is tested at every crossing of a lattice line u = k or
// v = k, where the surface is the linear interpolation of the two lattice heights on that line.
// The interior maximum of the (quadratic) bilinear surface between two crossings is not tested.
//
// Precision budget (f32): heights are relative to the grid's local origin z_ref (|z| <= ~10 km,
// ulp <= 1 mm); positions are in cell units (<= 2^24 cells exact); the light vector is reduced
// to an f32 unit vector on the CPU (error ~6e-8 rad, i.e. 0.6 mm of ray height per 10 km).
// Holes are stored as HOLE_Z_M (no NaN on the GPU: WGSL does not promise NaN semantics).

// Keep in sync with `GridParams` in src/gpu/shadow_march.rs (mod gpu_data).
struct GridParams {
    rows: u32,
    cols: u32,
    px_m: f32,
    observer_height_m: f32,
    // Model x/y (m) of the centre of cell (0, 0): only used for the radial "up" direction.
    x0_m: f32,
    y0_m: f32,
    // Highest terrain height of the grid (relative to z_ref): a ray above it is lit.
    z_max_m: f32,
    // z_ref + Moon radius (m): up = normalize(x, y, z + z_ref + R).
    z_ref_plus_radius_m: f32,
}

// Keep in sync with `StepParams` in src/gpu/shadow_march.rs (mod gpu_data).
struct StepParams {
    // Index into `lights` (the epoch in a sweep; 0 for a single map).
    light_index: u32,
    // First row of the band this dispatch writes, and its number of rows.
    band_row0: u32,
    band_rows: u32,
    _pad: u32,
}

const LIT: u32 = 1u;
const SHADOW: u32 = 0u;
const NODATA: u32 = 255u;
// Heights below this are holes (stored as -1e30 m).
const HOLE_TEST_M: f32 = -1.0e29;
const FAR_CELLS: f32 = 1.0e30;
// A light with a horizontal component below this goes straight up or down.
const MIN_HORIZ: f32 = 1.0e-7;

@group(0) @binding(0) var<uniform> grid: GridParams;
@group(0) @binding(1) var<storage, read> heights: array<f32>;
@group(0) @binding(2) var<storage, read> lights: array<vec4<f32>>;
@group(0) @binding(3) var<uniform> step_params: StepParams;

fn height_at(row: i32, col: i32) -> f32 {
    return heights[u32(row) * grid.cols + u32(col)];
}

// 1 lit, 0 shadow, 255 nodata for cell (row, col) and light direction `light` (model space).
fn march_hard(row: u32, col: u32, light: vec3<f32>) -> u32 {
    let rows = i32(grid.rows);
    let cols = i32(grid.cols);
    let z_cell = heights[row * grid.cols + col];
    if z_cell < HOLE_TEST_M {
        return NODATA;
    }
    // Observer: observer_height_m above the surface along the radial direction.
    let x_m = grid.x0_m + f32(col) * grid.px_m;
    let y_m = grid.y0_m - f32(row) * grid.px_m;
    let up = normalize(vec3<f32>(x_m, y_m, z_cell + grid.z_ref_plus_radius_m));
    let u0 = f32(col) + grid.observer_height_m * up.x / grid.px_m;
    let v0 = f32(row) - grid.observer_height_m * up.y / grid.px_m;
    let z0 = z_cell + grid.observer_height_m * up.z;
    let horiz_len = sqrt(light.x * light.x + light.y * light.y);
    if horiz_len < MIN_HORIZ {
        return select(SHADOW, LIT, light.z > 0.0);
    }
    // Direction in grid units (rows grow southwards) and ray rise per cell of horizontal travel.
    let du = light.x / horiz_len;
    let dv = -light.y / horiz_len;
    let rise_m_per_cell = light.z / horiz_len * grid.px_m;
    // DDA set-up: next lattice line on each axis and the ray parameter t (cells) to reach it.
    var line_u = 0;
    var step_u = 0;
    var t_max_u = FAR_CELLS;
    var t_delta_u = FAR_CELLS;
    if du > 0.0 {
        line_u = i32(floor(u0)) + 1;
        step_u = 1;
        t_delta_u = 1.0 / du;
        t_max_u = (f32(line_u) - u0) * t_delta_u;
    } else if du < 0.0 {
        line_u = i32(ceil(u0)) - 1;
        step_u = -1;
        t_delta_u = -1.0 / du;
        t_max_u = (u0 - f32(line_u)) * t_delta_u;
    }
    var line_v = 0;
    var step_v = 0;
    var t_max_v = FAR_CELLS;
    var t_delta_v = FAR_CELLS;
    if dv > 0.0 {
        line_v = i32(floor(v0)) + 1;
        step_v = 1;
        t_delta_v = 1.0 / dv;
        t_max_v = (f32(line_v) - v0) * t_delta_v;
    } else if dv < 0.0 {
        line_v = i32(ceil(v0)) - 1;
        step_v = -1;
        t_delta_v = -1.0 / dv;
        t_max_v = (v0 - f32(line_v)) * t_delta_v;
    }
    let max_steps = rows + cols + 4;
    for (var i = 0; i < max_steps; i++) {
        var t = 0.0;
        var z_surf = 0.0;
        if t_max_u < t_max_v {
            t = t_max_u;
            if line_u < 0 || line_u > cols - 1 {
                return LIT;
            }
            let v = v0 + t * dv;
            if v < 0.0 || v > f32(rows - 1) {
                return LIT;
            }
            let r0 = min(i32(floor(v)), rows - 2);
            let w = v - f32(r0);
            z_surf = height_at(r0, line_u) * (1.0 - w) + height_at(r0 + 1, line_u) * w;
            t_max_u = t_max_u + t_delta_u;
            line_u = line_u + step_u;
        } else {
            t = t_max_v;
            if line_v < 0 || line_v > rows - 1 {
                return LIT;
            }
            let u = u0 + t * du;
            if u < 0.0 || u > f32(cols - 1) {
                return LIT;
            }
            let c0 = min(i32(floor(u)), cols - 2);
            let w = u - f32(c0);
            z_surf = height_at(line_v, c0) * (1.0 - w) + height_at(line_v, c0 + 1) * w;
            t_max_v = t_max_v + t_delta_v;
            line_v = line_v + step_v;
        }
        let z_ray = z0 + t * rise_m_per_cell;
        if z_ray > grid.z_max_m {
            return LIT;
        }
        if z_surf > z_ray {
            return SHADOW;
        }
    }
    return LIT;
}
