// Shared part of fourier_build.wgsl (composed before it, src/gpu/shaders.rs): the grid bindings
// 0 and 1 and the 2-D DDA over the lattice lines (`dda_start`, `dda_next`). CPU twin: `Dda` in
// src/twins/march.rs (line by line).
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

// Keep in sync with `GridParams` in src/gpu/context.rs (mod gpu_data).
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

// Heights below this are holes (stored as -1e30 m).
const HOLE_TEST_M: f32 = -1.0e29;
const FAR_CELLS: f32 = 1.0e30;

@group(0) @binding(0) var<uniform> grid: GridParams;
@group(0) @binding(1) var<storage, read> heights: array<f32>;

fn height_at(row: i32, col: i32) -> f32 {
    return heights[u32(row) * grid.cols + u32(col)];
}

// One axis of the 2-D DDA: the next lattice line, the step to the line after it, and the ray
// parameter t (cells of horizontal travel) to reach it and between two lines.
struct DdaAxis {
    line: i32,
    step: i32,
    t_max: f32,
    t_delta: f32,
}

// The DDA of the horizontal ray (u0, v0) + t (du, dv) in grid units (direction unit).
struct Dda {
    u: DdaAxis,
    v: DdaAxis,
    u0: f32,
    v0: f32,
    du: f32,
    dv: f32,
}

// One crossing of the ray with a lattice line: its t (cells) and the surface height there.
struct DdaCrossing {
    // false: the ray has left the lattice (t and z_surf are not set).
    inside: bool,
    t: f32,
    z_surf: f32,
}

// DDA set-up on one axis (position p0, direction component d): the next lattice line and t.
fn dda_axis(p0: f32, d: f32) -> DdaAxis {
    var a = DdaAxis(0, 0, FAR_CELLS, FAR_CELLS);
    if d > 0.0 {
        a.line = i32(floor(p0)) + 1;
        a.step = 1;
        a.t_delta = 1.0 / d;
        a.t_max = (f32(a.line) - p0) * a.t_delta;
    } else if d < 0.0 {
        a.line = i32(ceil(p0)) - 1;
        a.step = -1;
        a.t_delta = -1.0 / d;
        a.t_max = (p0 - f32(a.line)) * a.t_delta;
    }
    return a;
}

// The DDA of the ray (u0, v0) + t (du, dv), before its first crossing.
fn dda_start(u0: f32, v0: f32, du: f32, dv: f32) -> Dda {
    return Dda(dda_axis(u0, du), dda_axis(v0, dv), u0, v0, du, dv);
}

// Advances the DDA to the next crossing with a lattice line u = k or v = k and samples the
// surface there (linear between the two lattice heights on that line). A crossing at most
// `edge_tol_cells` outside the lattice is clamped onto its edge line.
fn dda_next(dda: ptr<function, Dda>, edge_tol_cells: f32) -> DdaCrossing {
    let rows = i32(grid.rows);
    let cols = i32(grid.cols);
    var c = DdaCrossing(false, 0.0, 0.0);
    if (*dda).u.t_max < (*dda).v.t_max {
        c.t = (*dda).u.t_max;
        let line_u = (*dda).u.line;
        if line_u < 0 || line_u > cols - 1 {
            return c;
        }
        let v = (*dda).v0 + c.t * (*dda).dv;
        if v < -edge_tol_cells || v > f32(rows - 1) + edge_tol_cells {
            return c;
        }
        let vc = clamp(v, 0.0, f32(rows - 1));
        let r0 = min(i32(floor(vc)), rows - 2);
        let w = vc - f32(r0);
        c.z_surf = height_at(r0, line_u) * (1.0 - w) + height_at(r0 + 1, line_u) * w;
        (*dda).u.t_max = (*dda).u.t_max + (*dda).u.t_delta;
        (*dda).u.line = line_u + (*dda).u.step;
    } else {
        c.t = (*dda).v.t_max;
        let line_v = (*dda).v.line;
        if line_v < 0 || line_v > rows - 1 {
            return c;
        }
        let u = (*dda).u0 + c.t * (*dda).du;
        if u < -edge_tol_cells || u > f32(cols - 1) + edge_tol_cells {
            return c;
        }
        let uc = clamp(u, 0.0, f32(cols - 1));
        let c0 = min(i32(floor(uc)), cols - 2);
        let w = uc - f32(c0);
        c.z_surf = height_at(line_v, c0) * (1.0 - w) + height_at(line_v, c0 + 1) * w;
        (*dda).v.t_max = (*dda).v.t_max + (*dda).v.t_delta;
        (*dda).v.line = line_v + (*dda).v.step;
    }
    c.inside = true;
    return c;
}
