// Shared part of every dp_*.wgsl (composed before it, src/gpu/shaders.rs): the DP /
// maximum-mipmap shadow cost of one cell towards one disc and the disc's visible fraction.
// CPU twins: `dp_cost`, `dp_fraction` and friends in src/twins/dp.rs (line by line).
//
// Shadow cost (papers 000/003, eq. 2): J* = min over the ray of dh / t, dh the ray's height above
// the surface at horizontal distance t, evaluated at every crossing of the ray with the lattice
// lines joining cell centres (the brute-force reference's samples, src/shadow/brute.rs).
// Traversal: the maximum mipmap (level 0 = one texel per dual cell, max of its four corners;
// level m = max of 2x2 texels of level m-1) is walked front to back without a stack: at the ray
// position s the texel of level m containing the ray is bounded by tan(e) - (max - z0) / t
// (t the nearer end of the ray's chord through it when max > z0, else the farther end). If the
// bound cannot lower min(J*, cap) the whole chord is skipped and the walk goes up one level;
// otherwise it goes down one level; at level 0 the exact cost is evaluated where the ray enters
// and leaves the dual cell (both are lattice-line crossings). This is Algorithm 1's coarse-to-fine
// search with the exact (non-greedy) branch and bound of src/shadow/dp.rs, in a GPU-friendly
// order; the interval concatenation of the paper is not needed (the top level covers the grid).
//
// Disc occlusion (paper eq. 6-7, prism assumption, as src/shadow/mod.rs fraction_from_cost):
// e_h = atan(tan e_c - J*) (terrain only: no local-horizontal bound), d = clamp((e_c - e_h) / r, -1, 1),
// visible = (pi - acos d + d sqrt(1 - d^2)) / pi; r = 0 gives the hard mask (1 iff e_c > e_h).
//
// Source region (2-D tiling, src/gpu/tiles.rs): the walk is restricted to the rectangle of dual
// cells covered by the bound mipmap (level-0 texel (0, 0) = dual cell (src_row0, src_col0)); the
// bound heights buffer is a block of the grid starting at cell (hgt_row0, hgt_col0). Positions,
// crossing distances and sample heights are computed in GLOBAL cell units exactly as for the whole
// grid, so a sample has the same f32 value in every tile that contains it, and J* of the whole ray
// is the min over tiles of the tile-restricted J* (min is idempotent: duplicates are harmless; a
// tile's walk starts from the running min `best0`, which also prunes). dp_visible / dp_sweep bind
// the whole grid as one region (origins 0).
//
// Precision (f32): heights relative to the grid's z_ref (as shared/march.wgsl), positions in cell
// units; texel lookup uses the point 1e-3 cells (+ 1e-6 s) past s, so that f32 rounding never
// puts it back into the texel just left; a dual cell clipped by less than that is still covered
// because its entry and exit are the exit/entry of its neighbours (evaluated or bounded).

// Keep in sync with `GridParams` in src/gpu/shadow_march.rs (mod gpu_data), filled by
// `GridParams::of` (the march uniform; same layout).
struct DpGridParams {
    rows: u32,
    cols: u32,
    px_m: f32,
    observer_height_m: f32,
    x0_m: f32,
    y0_m: f32,
    z_max_m: f32,
    z_ref_plus_radius_m: f32,
}

// Keep in sync with `DpStep` in src/gpu/dp.rs (mod gpu_data).
struct DpStep {
    // First light (dp_visible) or first epoch (dp_sweep) of this dispatch, and how many epochs.
    light0: u32,
    count: u32,
    // First row of the band this dispatch writes, and its number of rows.
    band_row0: u32,
    band_rows: u32,
    // First column and number of columns of the output (dp_tile_*; the whole width otherwise).
    band_col0: u32,
    band_cols: u32,
    // The bound mipmap's level-0 texel (0, 0) is dual cell (src_row0, src_col0) of the grid.
    src_row0: u32,
    src_col0: u32,
    // The bound heights buffer holds cells [hgt_row0, hgt_row0 + hgt_rows) x
    // [hgt_col0, hgt_col0 + hgt_cols) of the grid, row-major.
    hgt_row0: u32,
    hgt_col0: u32,
    hgt_rows: u32,
    hgt_cols: u32,
    // dp_tile_cost: 1 when this is the first source tile of the output tile (costs start at
    // DP_FAR instead of the running min in the cost buffer).
    first_source: u32,
    // dp_tile_*: the observer heights block (binding 7) starts at cell (obs_row0, obs_col0),
    // rows of obs_cols cells.
    obs_row0: u32,
    obs_col0: u32,
    obs_cols: u32,
}

// Observer of one cell: position in cell units, height (m, relative to z_ref), radial up.
struct DpObserver {
    u0: f32,
    v0: f32,
    z0: f32,
    up: vec3<f32>,
}

const DP_HOLE_TEST_M: f32 = -1.0e29;
const DP_FAR: f32 = 1.0e30;
const DP_MIN_HORIZ: f32 = 1.0e-7;
const DP_PI: f32 = 3.14159265358979;

@group(0) @binding(0) var<uniform> dp_grid: DpGridParams;
@group(0) @binding(1) var<storage, read> dp_heights: array<f32>;
// Every mipmap level, concatenated; holes as -1e30.
@group(0) @binding(2) var<storage, read> dp_mip: array<f32>;
// Per level: (rows, cols, offset into dp_mip, 0); level 0 first.
@group(0) @binding(3) var<storage, read> dp_levels: array<vec4<u32>>;
// Per light: unit direction (model space) in xyz, angular radius (rad) in w.
@group(0) @binding(4) var<storage, read> dp_lights: array<vec4<f32>>;
@group(0) @binding(5) var<uniform> dp_step: DpStep;

// Height of grid cell (row, col) from the bound heights block (clamped into the block, which
// the tiling makes large enough that the clamp never acts: docs/gpu.md, "Large grids").
fn dp_height(row: i32, col: i32) -> f32 {
    let r = clamp(row - i32(dp_step.hgt_row0), 0, i32(dp_step.hgt_rows) - 1);
    let c = clamp(col - i32(dp_step.hgt_col0), 0, i32(dp_step.hgt_cols) - 1);
    return dp_heights[u32(r) * dp_step.hgt_cols + u32(c)];
}

// Surface height where the ray crosses a lattice line (as brute.rs line_height): on a row line
// (axis 1: v = k) linear along u between (k, c0) and (k, c0 + 1); on a column line (axis 2)
// linear along v; off the lines (axis 0: only a forced step) the bilinear interpolant. Holes
// (-1e30) with a non-zero weight give a far-below value (no terrain).
fn dp_surface(axis: u32, v_in: f32, u_in: f32) -> f32 {
    let rows = i32(dp_grid.rows);
    let cols = i32(dp_grid.cols);
    let v = clamp(v_in, 0.0, f32(rows - 1));
    let u = clamp(u_in, 0.0, f32(cols - 1));
    let r0 = min(i32(floor(v)), rows - 2);
    let c0 = min(i32(floor(u)), cols - 2);
    let fr = v - f32(r0);
    let fc = u - f32(c0);
    if axis == 1u {
        let k = i32(round(v));
        return dp_height(k, c0) * (1.0 - fc) + dp_height(k, c0 + 1) * fc;
    } else if axis == 2u {
        let k = i32(round(u));
        return dp_height(r0, k) * (1.0 - fr) + dp_height(r0 + 1, k) * fr;
    }
    let top = dp_height(r0, c0) * (1.0 - fc) + dp_height(r0, c0 + 1) * fc;
    let bottom = dp_height(r0 + 1, c0) * (1.0 - fc) + dp_height(r0 + 1, c0 + 1) * fc;
    return top * (1.0 - fr) + bottom * fr;
}

// The observer of cell (row, col) of height z_cell (not a hole), clamped into the lattice like
// src/shadow/mod.rs observer_at.
fn dp_observer_at(row: u32, col: u32, z_cell: f32) -> DpObserver {
    let x_m = dp_grid.x0_m + f32(col) * dp_grid.px_m;
    let y_m = dp_grid.y0_m - f32(row) * dp_grid.px_m;
    let up = normalize(vec3<f32>(x_m, y_m, z_cell + dp_grid.z_ref_plus_radius_m));
    let u0 = clamp(f32(col) + dp_grid.observer_height_m * up.x / dp_grid.px_m, 0.0, f32(dp_grid.cols - 1u));
    let v0 = clamp(f32(row) - dp_grid.observer_height_m * up.y / dp_grid.px_m, 0.0, f32(dp_grid.rows - 1u));
    let z0 = z_cell + dp_grid.observer_height_m * up.z;
    return DpObserver(u0, v0, z0, up);
}

// The observer of cell (row, col) of the whole-grid heights buffer (dp_visible, dp_sweep).
fn dp_observer(row: u32, col: u32) -> DpObserver {
    return dp_observer_at(row, col, dp_heights[row * dp_grid.cols + col]);
}

// Distances (cells) at which the ray p + s d enters (x) and leaves (y) the slab [lo, hi] along
// one axis; (-DP_FAR, DP_FAR) when d = 0 and p is inside, an empty range when outside.
fn dp_slab(p: f32, d: f32, lo: f32, hi: f32) -> vec2<f32> {
    if d > 0.0 {
        return vec2<f32>((lo - p) / d, (hi - p) / d);
    } else if d < 0.0 {
        return vec2<f32>((hi - p) / d, (lo - p) / d);
    }
    if p >= lo && p <= hi {
        return vec2<f32>(-DP_FAR, DP_FAR);
    }
    return vec2<f32>(DP_FAR, -DP_FAR);
}

// Texel index along one axis of the point p, direction-aware, texel size `size` cells.
fn dp_texel_index(p: f32, size: f32) -> i32 {
    return i32(floor(p / size));
}

// Distance (cells) from the observer to the far side of texel `i` (of a mipmap whose texel 0
// starts at grid line `origin`) along one axis. Integer-valued lines, so the result is the same
// f32 in every tiling.
fn dp_texel_exit(i: i32, size: f32, origin: f32, p0: f32, d: f32) -> f32 {
    if d > 0.0 {
        return (f32(i + 1) * size + origin - p0) / d;
    } else if d < 0.0 {
        return (f32(i) * size + origin - p0) / d;
    }
    return DP_FAR;
}

// J* (tan units) of the ray from `obs` towards `light` (unit) over the samples inside the bound
// source region, min-combined with `best0` (the running min of earlier regions, DP_FAR for the
// first) and pruned at min(best, cap): costs at or above that may be reported as any value
// >= it; DP_FAR when nothing is along the ray and best0 = DP_FAR.
fn dp_cost(obs: DpObserver, light: vec3<f32>, cap: f32, best0: f32) -> f32 {
    return dp_cost_beyond(obs, light, cap, best0, 0.0);
}

// dp_cost ignoring the crossings at ray distances <= min_s (cells) and, when min_s > 0, sampling
// the bilinear surface at exactly min_s first (as src/shadow/dp.rs dp_cost_beyond: the per-site
// series engine, dp_sites.wgsl, skips the observer's own half cell; it binds the whole grid as
// one region). With min_s = 0 this is dp_cost: every evaluated crossing lies at s > 0.
fn dp_cost_beyond(obs: DpObserver, light: vec3<f32>, cap: f32, best0: f32, min_s: f32) -> f32 {
    let hor = sqrt(light.x * light.x + light.y * light.y);
    if hor < DP_MIN_HORIZ {
        return best0;
    }
    let du = light.x / hor;
    let dv = -light.y / hor;
    let tan_el = light.z / hor;
    let px = dp_grid.px_m;
    let lv0 = dp_levels[0];
    let v_lo = f32(dp_step.src_row0);
    let u_lo = f32(dp_step.src_col0);
    let slab_v = dp_slab(obs.v0, dv, v_lo, f32(dp_step.src_row0 + lv0.x));
    let slab_u = dp_slab(obs.u0, du, u_lo, f32(dp_step.src_col0 + lv0.y));
    let s_exit = max(min(slab_v.y, slab_u.y), 0.0);
    // Which lattice line the ray is on at s (and at s_out): 0 none, 1 a row line, 2 a column line.
    // The crossing where the ray enters a region is not sampled here: it is the exit of the
    // neighbouring region's last dual cell (or the observer itself).
    let exit_axis = select(2u, 1u, slab_v.y <= slab_u.y);
    var s_axis = 0u;
    let n_levels = i32(arrayLength(&dp_levels));
    let top = n_levels - 1;
    let max_iter = 8 * i32(lv0.x + lv0.y + 2u) + 32 * n_levels;
    var best = best0;
    if min_s > 0.0 && min_s < s_exit {
        let z = dp_surface(0u, obs.v0 + min_s * dv, obs.u0 + min_s * du);
        best = min(best, (obs.z0 - z) / (min_s * px) + tan_el);
    }
    var m = top;
    var s = max(max(slab_v.x, slab_u.x), 0.0);
    for (var it = 0; it < max_iter; it++) {
        if s >= s_exit {
            break;
        }
        let lv = dp_levels[m];
        let size = f32(1u << u32(m));
        let sm = s + 1.0e-3 + 1.0e-6 * s;
        let i = clamp(dp_texel_index(obs.v0 + sm * dv - v_lo, size), 0, i32(lv.x) - 1);
        let j = clamp(dp_texel_index(obs.u0 + sm * du - u_lo, size), 0, i32(lv.y) - 1);
        let t_v = dp_texel_exit(i, size, v_lo, obs.v0, dv);
        let t_u = dp_texel_exit(j, size, u_lo, obs.u0, du);
        var s_out = min(t_v, t_u);
        var out_axis = select(2u, 1u, t_v <= t_u);
        // Strict: where a texel ends exactly at the region's edge its own crossing rule (as in
        // the whole grid) decides the line, so the sample is the same f32 in every tiling.
        if s_exit < s_out {
            s_out = s_exit;
            out_axis = exit_axis;
        }
        if sm > s_out {
            s_out = sm;
            out_axis = 0u;
        }
        let m_z = dp_mip[lv.z + u32(i) * lv.y + u32(j)];
        let dz = m_z - obs.z0;
        var lb = tan_el;
        if dz > 0.0 {
            lb = select(-DP_FAR, tan_el - dz / (s * px), s > 0.0);
        } else {
            lb = tan_el - dz / (s_out * px);
        }
        if lb >= min(best, cap) {
            s = s_out;
            s_axis = out_axis;
            m = min(m + 1, top);
        } else if m == 0 {
            if s_axis != 0u && s > min_s {
                let z = dp_surface(s_axis, obs.v0 + s * dv, obs.u0 + s * du);
                best = min(best, (obs.z0 - z) / (s * px) + tan_el);
            }
            if out_axis != 0u && s_out > min_s {
                let z = dp_surface(out_axis, obs.v0 + s_out * dv, obs.u0 + s_out * du);
                best = min(best, (obs.z0 - z) / (s_out * px) + tan_el);
            }
            s = s_out;
            s_axis = out_axis;
            m = min(m + 1, top);
        } else {
            m = m - 1;
        }
    }
    return best;
}

// The pruning cap of the disc `light` (xyz unit direction, w angular radius): a cost at or
// above it leaves the whole disc visible (tan e_c - tan(e_c - r)); 0 for the hard mask.
fn dp_cap(light: vec4<f32>) -> f32 {
    let l = light.xyz;
    let r = light.w;
    let hor = sqrt(l.x * l.x + l.y * l.y);
    let e_c = atan2(l.z, hor);
    var cap = 0.0;
    if r > 0.0 {
        let e_low = e_c - r;
        cap = select(DP_FAR, l.z / max(hor, DP_MIN_HORIZ) - tan(e_low), e_low > -0.5 * DP_PI + 1.0e-6);
    }
    return cap;
}

// Visible fraction of the disc `light` (xyz unit direction, w angular radius, rad) from `obs`
// given the shadow cost `j` of the ray towards its centre (DP_FAR: nothing along the ray; unused
// when the light has no horizontal component).
fn dp_fraction_of_cost(obs: DpObserver, light: vec4<f32>, j: f32) -> f32 {
    let l = light.xyz;
    let r = light.w;
    let hor = sqrt(l.x * l.x + l.y * l.y);
    let e_c = atan2(l.z, hor);
    var e_h = -0.5 * DP_PI;
    if hor >= DP_MIN_HORIZ {
        // Only terrain makes a horizon (no local-horizontal bound; docs/ARCHITECTURE.md).
        if j < 0.5 * DP_FAR {
            e_h = atan(l.z / hor - j);
        }
    } else if l.z < 0.0 {
        // Straight down: the observer's own ground.
        e_h = 0.5 * DP_PI;
    }
    let clearance = e_c - e_h;
    if r <= 0.0 {
        return select(0.0, 1.0, clearance > 0.0);
    }
    let d = clamp(clearance / r, -1.0, 1.0);
    return (DP_PI - acos(d) + d * sqrt(1.0 - d * d)) / DP_PI;
}

// Visible fraction of the disc `light` from `obs` over the whole bound region.
fn dp_fraction(obs: DpObserver, light: vec4<f32>) -> f32 {
    let j = dp_cost(obs, light.xyz, dp_cap(light), DP_FAR);
    return dp_fraction_of_cost(obs, light, j);
}

// The observer of a point record (col, row, z relative to z_ref in m, min_s in cells) of
// dp_sites.wgsl, dp_points.wgsl and dp_points_sweep.wgsl: a fractional position, not a cell
// centre (e.g. a DEM pixel's own surface point in the model grid).
fn dp_point_observer(o: vec4<f32>) -> DpObserver {
    return DpObserver(o.x, o.y, o.z, vec3<f32>(0.0, 0.0, 1.0));
}

// Visible fraction of the disc `light` from `obs`, the crossings within `min_s` cells of the
// observer left out and the surface at exactly min_s sampled first (dp_cost_beyond): the
// observer's own half pixel is its ground, as in the per-site horizon engine.
fn dp_fraction_beyond(obs: DpObserver, light: vec4<f32>, min_s: f32) -> f32 {
    let j = dp_cost_beyond(obs, light.xyz, dp_cap(light), DP_FAR, min_s);
    return dp_fraction_of_cost(obs, light, j);
}

// Whether cell (row, col) is a hole.
fn dp_is_hole(row: u32, col: u32) -> bool {
    return dp_heights[row * dp_grid.cols + col] < DP_HOLE_TEST_M;
}

// A disc fraction above this counts as visible (as `map::VISIBLE_MIN_FRACTION`).
const VISIBLE_MIN_FRACTION: f32 = 1.0e-6;

// Running per-cell statistics of the soft epoch sweeps (dp_sweep.wgsl,
// dp_tile_sweep_accumulate.wgsl). Keep in sync with `DpCellStats` in src/twins/dp.rs.
struct DpCellStats {
    sun_fraction_sum: f32,
    sun_fraction_comp: f32,
    sun_visible_epochs: u32,
    dark_run_epochs: u32,
    longest_dark_run_epochs: u32,
    earth_visible_epochs: u32,
    sun_and_earth_epochs: u32,
    _pad: u32,
}

// Folds one epoch's Sun (`fs`) and Earth (`fe`) visible fractions into `s` with the definitions
// of the CPU `map::sweep`: Kahan-compensated f32 sum of the Sun's fraction, visible = fraction
// > 1e-6, dark runs of the Sun, Earth and Sun-and-Earth counts. CPU twin: `dp_sweep_accumulate`
// in src/twins/dp.rs (line by line).
fn dp_sweep_accumulate(s: ptr<function, DpCellStats>, fs: f32, fe: f32) {
    // Kahan summation of the Sun's fraction.
    let y = fs - (*s).sun_fraction_comp;
    let t = (*s).sun_fraction_sum + y;
    (*s).sun_fraction_comp = (t - (*s).sun_fraction_sum) - y;
    (*s).sun_fraction_sum = t;
    let sun_up = fs > VISIBLE_MIN_FRACTION;
    let earth_up = fe > VISIBLE_MIN_FRACTION;
    if sun_up {
        (*s).sun_visible_epochs += 1u;
        (*s).dark_run_epochs = 0u;
    } else {
        (*s).dark_run_epochs += 1u;
        (*s).longest_dark_run_epochs = max((*s).longest_dark_run_epochs, (*s).dark_run_epochs);
    }
    if earth_up {
        (*s).earth_visible_epochs += 1u;
    }
    if sun_up && earth_up {
        (*s).sun_and_earth_epochs += 1u;
    }
}
