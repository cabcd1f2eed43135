//! CPU twins of the DP / maximum-mipmap kernels (`shaders/shared/dp.wgsl`, `dp_visible.wgsl`,
//! `dp_sweep.wgsl`, `dp_sites.wgsl`, `dp_points.wgsl`, `dp_points_sweep.wgsl`).

// ---------------------------------------------------------------------------------------------
// DP / maximum-mipmap kernels (`shaders/shared/dp.wgsl`, `dp_visible.wgsl`, `dp_sweep.wgsl`).
// ---------------------------------------------------------------------------------------------

use nalgebra::Vector3;
use rayon::prelude::*;

use super::march::*;
use super::{FAR_CELLS, HOLE_TEST_M, HOLE_Z_M, NODATA_FRACTION};

const DP_PI: f32 = std::f32::consts::PI;

/// The maximum mipmap of a [`MarchGrid`] as the GPU stores it (the twin of the `dp_mip` and
/// `dp_levels` buffers of `shaders/shared/dp.wgsl`): level 0 has one texel per dual cell (the max
/// of its four corner heights, holes being [`HOLE_Z_M`]), level `m` the max of 2 × 2 texels of
/// level `m − 1`, down to one texel. Same values as [`crate::shadow::dp::MaxMipmap`] (relative to
/// `z_ref_m`, `-inf` there is [`HOLE_Z_M`] here).
#[derive(Debug, Clone)]
pub struct DpMip {
    /// Per level: `[rows, cols, offset into texels, 0]`, level 0 first.
    pub levels: Vec<[u32; 4]>,
    /// Every level's texels, row-major, concatenated.
    pub texels: Vec<f32>,
}

impl DpMip {
    /// Builds every level of `grid`'s maximum mipmap.
    pub fn build(grid: &MarchGrid) -> Self {
        Self::build_block(
            &grid.heights_m,
            grid.cols as usize,
            (0, 0),
            (grid.rows as usize - 1, grid.cols as usize - 1),
        )
    }

    /// Builds the maximum mipmap of `dual_rows × dual_cols` dual cells (`dual` ≥ 1 × 1) of a
    /// block of heights (row-major, `stride` cells per row): level-0 texel (i, j) is the max of
    /// the block cells (`first.0 + i`, `first.1 + j`) .. (+1, +1), which must exist.
    pub fn build_block(
        heights_m: &[f32],
        stride: usize,
        first: (usize, usize),
        (dual_rows, dual_cols): (usize, usize),
    ) -> Self {
        let (r0, c0) = (dual_rows, dual_cols);
        let h = |r: usize, c: usize| heights_m[(first.0 + r) * stride + first.1 + c];
        let mut texels: Vec<f32> = (0..r0 * c0)
            .map(|k| {
                let (i, j) = (k / c0, k % c0);
                h(i, j)
                    .max(h(i + 1, j))
                    .max(h(i, j + 1))
                    .max(h(i + 1, j + 1))
            })
            .collect();
        let mut levels = vec![[r0 as u32, c0 as u32, 0, 0]];
        let (mut r, mut c, mut offset) = (r0, c0, 0_usize);
        while r > 1 || c > 1 {
            let (nr, nc) = (r.div_ceil(2), c.div_ceil(2));
            let next_offset = texels.len();
            for i in 0..nr {
                for j in 0..nc {
                    let mut m = HOLE_Z_M;
                    for (a, b) in [(2 * i, 2 * j), (2 * i + 1, 2 * j), (2 * i, 2 * j + 1)]
                        .into_iter()
                        .chain(std::iter::once((2 * i + 1, 2 * j + 1)))
                    {
                        if a < r && b < c {
                            m = m.max(texels[offset + a * c + b]);
                        }
                    }
                    texels.push(m);
                }
            }
            levels.push([nr as u32, nc as u32, next_offset as u32, 0]);
            (r, c, offset) = (nr, nc, next_offset);
        }
        DpMip { levels, texels }
    }
}

/// A disc for the DP kernels: unit direction (model space, normalised in f64 and rounded once)
/// in `xyz`, angular radius (rad) in `w` (0: the hard mask of the centre).
pub fn disc_light_to_f32(light_in_model: &Vector3<f64>, angular_radius_rad: f64) -> [f32; 4] {
    let [x, y, z, _] = light_to_f32(light_in_model);
    [x, y, z, angular_radius_rad as f32]
}

/// Twin of `DpObserver` in `shaders/shared/dp.wgsl`.
#[derive(Debug, Clone, Copy)]
pub struct DpObserver {
    /// Column of the observer, cell units.
    pub u0: f32,
    /// Row of the observer, cell units.
    pub v0: f32,
    /// Height of the observer relative to `z_ref_m`, metres.
    pub z0: f32,
    /// Radial up direction, model space.
    pub up: [f32; 3],
}

/// The part of the grid one DP walk sees (twin of the source-region fields of `DpStep` and of the
/// bindings 1–3 in `shaders/shared/dp.wgsl`): a maximum mipmap whose level-0 texel (0, 0) is dual
/// cell (`src_row0`, `src_col0`) of the grid, and a block of heights starting at cell
/// (`hgt_row0`, `hgt_col0`). [`DpSource::whole`] is the whole grid (what `dp_visible` and
/// `dp_sweep` bind); the 2-D tiling ([`super::dp_tiles`]) binds one tile at a time.
#[derive(Debug, Clone, Copy)]
pub struct DpSource<'a> {
    /// Heights of the block, row-major, relative to the grid's `z_ref_m`.
    pub heights_m: &'a [f32],
    /// Grid row of the block's first row.
    pub hgt_row0: u32,
    /// Grid column of the block's first column.
    pub hgt_col0: u32,
    /// Rows of the block.
    pub hgt_rows: u32,
    /// Columns of the block.
    pub hgt_cols: u32,
    /// Grid dual-cell row of the mipmap's level-0 texel row 0.
    pub src_row0: u32,
    /// Grid dual-cell column of the mipmap's level-0 texel column 0.
    pub src_col0: u32,
    /// The maximum mipmap of the region (level 0 = its dual cells).
    pub mip: &'a DpMip,
}

impl<'a> DpSource<'a> {
    /// The whole grid and its mipmap as one region.
    pub fn whole(grid: &'a MarchGrid, mip: &'a DpMip) -> Self {
        DpSource {
            heights_m: &grid.heights_m,
            hgt_row0: 0,
            hgt_col0: 0,
            hgt_rows: grid.rows,
            hgt_cols: grid.cols,
            src_row0: 0,
            src_col0: 0,
            mip,
        }
    }

    /// Twin of `dp_height`: grid cell (row, col) from the block (clamped into it).
    #[inline]
    fn height_at(&self, row: i32, col: i32) -> f32 {
        let r = (row - self.hgt_row0 as i32).clamp(0, self.hgt_rows as i32 - 1);
        let c = (col - self.hgt_col0 as i32).clamp(0, self.hgt_cols as i32 - 1);
        self.heights_m[r as usize * self.hgt_cols as usize + c as usize]
    }
}

/// Twin of `dp_surface`: the surface where the ray crosses a lattice line (`axis` 1: a row line,
/// linear along the columns; 2: a column line; 0: off the lines, bilinear). Global cell units.
fn dp_surface(grid: &MarchGrid, src: &DpSource<'_>, axis: u32, v_in: f32, u_in: f32) -> f32 {
    let rows = grid.rows as i32;
    let cols = grid.cols as i32;
    let v = v_in.clamp(0.0, (rows - 1) as f32);
    let u = u_in.clamp(0.0, (cols - 1) as f32);
    let r0 = (v.floor() as i32).min(rows - 2);
    let c0 = (u.floor() as i32).min(cols - 2);
    let fr = v - r0 as f32;
    let fc = u - c0 as f32;
    if axis == 1 {
        let k = v.round() as i32;
        return src.height_at(k, c0) * (1.0 - fc) + src.height_at(k, c0 + 1) * fc;
    } else if axis == 2 {
        let k = u.round() as i32;
        return src.height_at(r0, k) * (1.0 - fr) + src.height_at(r0 + 1, k) * fr;
    }
    let top = src.height_at(r0, c0) * (1.0 - fc) + src.height_at(r0, c0 + 1) * fc;
    let bottom = src.height_at(r0 + 1, c0) * (1.0 - fc) + src.height_at(r0 + 1, c0 + 1) * fc;
    top * (1.0 - fr) + bottom * fr
}

/// Twin of `dp_observer` (the caller checks for holes).
pub fn dp_observer(grid: &MarchGrid, row: u32, col: u32) -> DpObserver {
    dp_observer_at(
        grid,
        row,
        col,
        grid.heights_m[(row * grid.cols + col) as usize],
    )
}

/// Twin of `dp_observer_at`: the observer of cell (row, col) whose height is `z_cell` (not a
/// hole; relative to `z_ref_m`).
pub fn dp_observer_at(grid: &MarchGrid, row: u32, col: u32, z_cell: f32) -> DpObserver {
    let x_m = grid.x0_m + col as f32 * grid.px_m;
    let y_m = grid.y0_m - row as f32 * grid.px_m;
    let up = normalize3([x_m, y_m, z_cell + grid.z_ref_plus_radius_m]);
    let u0 = (col as f32 + grid.observer_height_m * up[0] / grid.px_m)
        .clamp(0.0, (grid.cols - 1) as f32);
    let v0 = (row as f32 - grid.observer_height_m * up[1] / grid.px_m)
        .clamp(0.0, (grid.rows - 1) as f32);
    let z0 = z_cell + grid.observer_height_m * up[2];
    DpObserver { u0, v0, z0, up }
}

/// Twin of `dp_slab`: (enter, leave) distances of the ray `p + s d` through `[lo, hi]`.
fn dp_slab(p: f32, d: f32, lo: f32, hi: f32) -> (f32, f32) {
    if d > 0.0 {
        ((lo - p) / d, (hi - p) / d)
    } else if d < 0.0 {
        ((hi - p) / d, (lo - p) / d)
    } else if p >= lo && p <= hi {
        (-FAR_CELLS, FAR_CELLS)
    } else {
        (FAR_CELLS, -FAR_CELLS)
    }
}

fn dp_texel_exit(i: i32, size: f32, origin: f32, p0: f32, d: f32) -> f32 {
    if d > 0.0 {
        ((i + 1) as f32 * size + origin - p0) / d
    } else if d < 0.0 {
        (i as f32 * size + origin - p0) / d
    } else {
        FAR_CELLS
    }
}

/// Twin of `dp_cost` over the whole grid: `J* = min Δh/t` (tan units) of the ray from `obs`
/// towards `light` over every lattice-line crossing, by a stackless front-to-back walk of the
/// maximum mipmap; costs at or above `cap` may be reported as any value `>= cap`; `1e30` when
/// nothing is along the ray.
pub fn dp_cost(grid: &MarchGrid, mip: &DpMip, obs: &DpObserver, light: [f32; 3], cap: f32) -> f32 {
    dp_cost_in(
        grid,
        &DpSource::whole(grid, mip),
        obs,
        light,
        cap,
        FAR_CELLS,
    )
}

/// Twin of `dp_cost` in `shaders/shared/dp.wgsl`: the cost over the samples inside `src`,
/// min-combined with `best0` (the running min of regions already walked; `1e30` for none) and
/// pruned at `min(best, cap)`. Positions are global cell units, so a sample has the same f32 value
/// in every region containing it and `J*` of the whole ray is the min over a cover by regions.
pub fn dp_cost_in(
    grid: &MarchGrid,
    src: &DpSource<'_>,
    obs: &DpObserver,
    light: [f32; 3],
    cap: f32,
    best0: f32,
) -> f32 {
    dp_cost_in_beyond(grid, src, obs, light, cap, best0, 0.0)
}

/// Twin of `dp_cost_beyond` in `shaders/shared/dp.wgsl` over the whole grid: [`dp_cost`]
/// ignoring the crossings at ray distances `<= min_s` (cells) and, when `min_s > 0`, sampling the
/// bilinear surface at exactly `min_s` first (as [`crate::shadow::dp`]'s `dp_cost_beyond` for the
/// per-site series).
pub fn dp_cost_beyond(
    grid: &MarchGrid,
    mip: &DpMip,
    obs: &DpObserver,
    light: [f32; 3],
    cap: f32,
    min_s: f32,
) -> f32 {
    let whole = DpSource::whole(grid, mip);
    dp_cost_in_beyond(grid, &whole, obs, light, cap, FAR_CELLS, min_s)
}

/// Twin of `dp_cost_beyond` in `shaders/shared/dp.wgsl`: [`dp_cost_in`] ignoring the crossings
/// at ray distances `<= min_s` (cells), with the surface at exactly `min_s` as the first sample
/// when `min_s > 0`.
fn dp_cost_in_beyond(
    grid: &MarchGrid,
    src: &DpSource<'_>,
    obs: &DpObserver,
    light: [f32; 3],
    cap: f32,
    best0: f32,
    min_s: f32,
) -> f32 {
    let hor = (light[0] * light[0] + light[1] * light[1]).sqrt();
    if hor < MIN_HORIZ {
        return best0;
    }
    let mip = src.mip;
    let du = light[0] / hor;
    let dv = -light[1] / hor;
    let tan_el = light[2] / hor;
    let px = grid.px_m;
    let lv0 = mip.levels[0];
    let v_lo = src.src_row0 as f32;
    let u_lo = src.src_col0 as f32;
    let slab_v = dp_slab(obs.v0, dv, v_lo, (src.src_row0 + lv0[0]) as f32);
    let slab_u = dp_slab(obs.u0, du, u_lo, (src.src_col0 + lv0[1]) as f32);
    let s_exit = slab_v.1.min(slab_u.1).max(0.0);
    let exit_axis = if slab_v.1 <= slab_u.1 { 1 } else { 2 };
    let mut s_axis = 0_u32;
    let n_levels = mip.levels.len() as i32;
    let top = n_levels - 1;
    let max_iter = 8 * (lv0[0] + lv0[1] + 2) as i32 + 32 * n_levels;
    let mut best = best0;
    if min_s > 0.0 && min_s < s_exit {
        let z = dp_surface(grid, src, 0, obs.v0 + min_s * dv, obs.u0 + min_s * du);
        best = best.min((obs.z0 - z) / (min_s * px) + tan_el);
    }
    let mut m = top;
    let mut s = slab_v.0.max(slab_u.0).max(0.0);
    for _ in 0..max_iter {
        if s >= s_exit {
            break;
        }
        let lv = mip.levels[m as usize];
        let size = (1_u32 << m as u32) as f32;
        let sm = s + 1.0e-3 + 1.0e-6 * s;
        let i = (((obs.v0 + sm * dv - v_lo) / size).floor() as i32).clamp(0, lv[0] as i32 - 1);
        let j = (((obs.u0 + sm * du - u_lo) / size).floor() as i32).clamp(0, lv[1] as i32 - 1);
        let t_v = dp_texel_exit(i, size, v_lo, obs.v0, dv);
        let t_u = dp_texel_exit(j, size, u_lo, obs.u0, du);
        let mut s_out = t_v.min(t_u);
        let mut out_axis = if t_v <= t_u { 1 } else { 2 };
        if s_exit < s_out {
            s_out = s_exit;
            out_axis = exit_axis;
        }
        if sm > s_out {
            s_out = sm;
            out_axis = 0;
        }
        let m_z = mip.texels[(lv[2] + i as u32 * lv[1] + j as u32) as usize];
        let dz = m_z - obs.z0;
        let lb = if dz > 0.0 {
            if s > 0.0 {
                tan_el - dz / (s * px)
            } else {
                -FAR_CELLS
            }
        } else {
            tan_el - dz / (s_out * px)
        };
        if lb >= best.min(cap) {
            s = s_out;
            s_axis = out_axis;
            m = (m + 1).min(top);
        } else if m == 0 {
            if s_axis != 0 && s > min_s {
                let z = dp_surface(grid, src, s_axis, obs.v0 + s * dv, obs.u0 + s * du);
                best = best.min((obs.z0 - z) / (s * px) + tan_el);
            }
            if out_axis != 0 && s_out > min_s {
                let z = dp_surface(
                    grid,
                    src,
                    out_axis,
                    obs.v0 + s_out * dv,
                    obs.u0 + s_out * du,
                );
                best = best.min((obs.z0 - z) / (s_out * px) + tan_el);
            }
            s = s_out;
            s_axis = out_axis;
            m = (m + 1).min(top);
        } else {
            m -= 1;
        }
    }
    best
}

/// Twin of `dp_cap`: the cost at or above which the disc `light` (`xyz` unit direction, `w`
/// angular radius) is entirely visible, `tan e_c − tan(e_c − r)`; 0 for the hard mask.
pub fn dp_cap(light: [f32; 4]) -> f32 {
    let r = light[3];
    let hor = (light[0] * light[0] + light[1] * light[1]).sqrt();
    let e_c = light[2].atan2(hor);
    let mut cap = 0.0;
    if r > 0.0 {
        let e_low = e_c - r;
        cap = if e_low > -0.5 * DP_PI + 1.0e-6 {
            light[2] / hor.max(MIN_HORIZ) - e_low.tan()
        } else {
            FAR_CELLS
        };
    }
    cap
}

/// Twin of `dp_fraction`: visible fraction of the disc `light` (`xyz` unit direction, `w`
/// angular radius) from `obs` under the prism assumption (paper 000/003 eq. 6–7, as
/// [`crate::shadow::disc_fraction_above_edge`]); radius 0 gives 1 (lit) or 0 (shadow).
pub fn dp_fraction(grid: &MarchGrid, mip: &DpMip, obs: &DpObserver, light: [f32; 4]) -> f32 {
    let j = dp_cost(
        grid,
        mip,
        obs,
        [light[0], light[1], light[2]],
        dp_cap(light),
    );
    dp_fraction_of_cost(obs, light, j)
}

/// Twin of `dp_fraction_of_cost`: the visible fraction of the disc `light` from `obs` given the
/// shadow cost `j` of the ray towards its centre (`1e30`: nothing along the ray).
pub fn dp_fraction_of_cost(_obs: &DpObserver, light: [f32; 4], j: f32) -> f32 {
    let l = [light[0], light[1], light[2]];
    let r = light[3];
    let hor = (l[0] * l[0] + l[1] * l[1]).sqrt();
    let e_c = l[2].atan2(hor);
    let mut e_h = -0.5 * DP_PI;
    if hor >= MIN_HORIZ {
        if j < 0.5 * FAR_CELLS {
            e_h = (l[2] / hor - j).atan();
        }
    } else if l[2] < 0.0 {
        e_h = 0.5 * DP_PI;
    }
    let clearance = e_c - e_h;
    if r <= 0.0 {
        return if clearance > 0.0 { 1.0 } else { 0.0 };
    }
    let d = (clearance / r).clamp(-1.0, 1.0);
    (DP_PI - d.acos() + d * (1.0 - d * d).sqrt()) / DP_PI
}

fn dp_is_hole(grid: &MarchGrid, row: u32, col: u32) -> bool {
    grid.heights_m[(row * grid.cols + col) as usize] < HOLE_TEST_M
}

/// Twin of `shaders/dp_visible.wgsl`: per cell of `band` the visible fraction of the disc
/// `lights[light_index]` ([`disc_light_to_f32`]), [`NODATA_FRACTION`] for a hole. Rayon over rows.
pub fn dp_visible(
    grid: &MarchGrid,
    mip: &DpMip,
    lights: &[[f32; 4]],
    light_index: u32,
    band: RowBand,
) -> Vec<f32> {
    let cols = grid.cols as usize;
    let light = lights[light_index as usize];
    let mut out = vec![NODATA_FRACTION; band.rows as usize * cols];
    out.par_chunks_mut(cols)
        .enumerate()
        .for_each(|(band_row, out_row)| {
            let row = band.row0 + band_row as u32;
            for (col, o) in out_row.iter_mut().enumerate() {
                if !dp_is_hole(grid, row, col as u32) {
                    let obs = dp_observer(grid, row, col as u32);
                    *o = dp_fraction(grid, mip, &obs, light);
                }
            }
        });
    out
}

/// A disc fraction above this counts as visible (as `map::VISIBLE_MIN_FRACTION`).
pub const DP_VISIBLE_MIN_FRACTION: f32 = 1e-6;

/// Running per-cell statistics of the soft epoch sweep (twin of `DpCellStats` in
/// `shaders/shared/dp.wgsl`); the definitions are those of the CPU `map::sweep`.
// Keep in sync with shaders/shared/dp.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DpCellStats {
    /// Sum of the Sun's visible fraction over the epochs (Kahan-compensated f32).
    pub sun_fraction_sum: f32,
    /// Kahan compensation of `sun_fraction_sum`.
    pub sun_fraction_comp: f32,
    /// Epochs with any part of the Sun visible (fraction > 1e-6).
    pub sun_visible_epochs: u32,
    /// The dark run (Sun entirely hidden) still going on at the last epoch folded in.
    pub dark_run_epochs: u32,
    /// Longest run of consecutive epochs with the Sun entirely hidden.
    pub longest_dark_run_epochs: u32,
    /// Epochs with any part of the Earth visible.
    pub earth_visible_epochs: u32,
    /// Epochs with both (partly) visible.
    pub sun_and_earth_epochs: u32,
    /// Padding to 32 bytes.
    pub _pad: u32,
}
const _: () = assert!(size_of::<DpCellStats>() == 32);

/// Twin of `dp_sweep_accumulate` in `shaders/shared/dp.wgsl` (the loop body of `dp_sweep.wgsl`
/// and `dp_tile_sweep_accumulate.wgsl`): folds one epoch's Sun and Earth fractions.
pub fn dp_sweep_accumulate(fs: f32, fe: f32, s: &mut DpCellStats) {
    let y = fs - s.sun_fraction_comp;
    let t = s.sun_fraction_sum + y;
    s.sun_fraction_comp = (t - s.sun_fraction_sum) - y;
    s.sun_fraction_sum = t;
    let sun_up = fs > DP_VISIBLE_MIN_FRACTION;
    let earth_up = fe > DP_VISIBLE_MIN_FRACTION;
    if sun_up {
        s.sun_visible_epochs += 1;
        s.dark_run_epochs = 0;
    } else {
        s.dark_run_epochs += 1;
        s.longest_dark_run_epochs = s.longest_dark_run_epochs.max(s.dark_run_epochs);
    }
    if earth_up {
        s.earth_visible_epochs += 1;
    }
    if sun_up && earth_up {
        s.sun_and_earth_epochs += 1;
    }
}

/// Twin of the whole soft sweep: `lights` holds two discs per epoch (Sun at `2e`, Earth at
/// `2e + 1`, from [`disc_light_to_f32`]); per cell of `band` every epoch is folded in time order.
/// Holes keep zero statistics. Rayon over rows.
pub fn dp_sweep(
    grid: &MarchGrid,
    mip: &DpMip,
    lights: &[[f32; 4]],
    band: RowBand,
) -> Vec<DpCellStats> {
    let cols = grid.cols as usize;
    let mut stats = vec![DpCellStats::default(); band.rows as usize * cols];
    stats
        .par_chunks_mut(cols)
        .enumerate()
        .for_each(|(band_row, stats_row)| {
            let row = band.row0 + band_row as u32;
            for (col, s) in stats_row.iter_mut().enumerate() {
                if dp_is_hole(grid, row, col as u32) {
                    continue;
                }
                let obs = dp_observer(grid, row, col as u32);
                for pair in lights.chunks_exact(2) {
                    let fs = dp_fraction(grid, mip, &obs, pair[0]);
                    let fe = dp_fraction(grid, mip, &obs, pair[1]);
                    dp_sweep_accumulate(fs, fe, s);
                }
            }
        });
    stats
}

// ---------------------------------------------------------------------------------------------
// Per-site DP horizons (`shaders/dp_sites.wgsl`, the GPU path of `series --engine smap-dp`).
// ---------------------------------------------------------------------------------------------

/// `dp_site_horizon_tan` / [`dp_sites`] output when no terrain sample lies along the ray.
pub const NO_HORIZON_TAN: f32 = -FAR_CELLS;

/// A site observer for [`dp_sites`] as the GPU reads it: `[col, row, z_m − z_ref_m, min_s]`
/// (fractional cell units; `min_s` cells of own ground skipped, as
/// [`crate::compute::site_dp::MIN_DISTANCE_CELLS`]).
pub fn site_observer_to_f32(
    grid: &MarchGrid,
    row: f64,
    col: f64,
    z_m: f64,
    min_s_cells: f64,
) -> [f32; 4] {
    [
        col as f32,
        row as f32,
        (z_m - grid.z_ref_m) as f32,
        min_s_cells as f32,
    ]
}

/// Twin of `dp_site_horizon_tan` in `shaders/dp_sites.wgsl`: the tangent of the terrain
/// horizon's elevation along the azimuth of `light` (`xyz` unit direction, `w` angular radius;
/// `w < 0`: no cap) seen from `obs`, `tan(e_c) − J*` with `J*` pruned at the disc's
/// full-visibility cap, or [`NO_HORIZON_TAN`].
pub fn dp_site_horizon_tan(
    grid: &MarchGrid,
    mip: &DpMip,
    obs: &DpObserver,
    light: [f32; 4],
    min_s: f32,
) -> f32 {
    let l = [light[0], light[1], light[2]];
    let r = light[3];
    let hor = (l[0] * l[0] + l[1] * l[1]).sqrt();
    if hor < MIN_HORIZ {
        return -FAR_CELLS;
    }
    let tan_el = l[2] / hor;
    let mut cap = FAR_CELLS;
    if r >= 0.0 {
        let e_low = l[2].atan2(hor) - r;
        if e_low > -0.5 * DP_PI + 1.0e-6 {
            cap = tan_el - e_low.tan();
        }
    }
    let j = dp_cost_beyond(grid, mip, obs, l, cap, min_s);
    if j >= 0.5 * FAR_CELLS {
        return -FAR_CELLS;
    }
    tan_el - j
}

/// Twin of `shaders/dp_sites.wgsl`: for every site `i` (from [`site_observer_to_f32`]) and entry
/// `k` of its `lights.len() / observers.len()` discs (`lights[i * per_site + k]`), the horizon
/// tangent of [`dp_site_horizon_tan`], indexed like `lights`. Rayon over sites.
pub fn dp_sites(
    grid: &MarchGrid,
    mip: &DpMip,
    observers: &[[f32; 4]],
    lights: &[[f32; 4]],
) -> Vec<f32> {
    if observers.is_empty() {
        return Vec::new();
    }
    let per_site = lights.len() / observers.len();
    let mut out = vec![NO_HORIZON_TAN; observers.len() * per_site];
    out.par_chunks_mut(per_site.max(1))
        .zip(observers.par_iter())
        .enumerate()
        .for_each(|(i, (out_site, o))| {
            let obs = dp_point_observer(o);
            for (k, t) in out_site.iter_mut().enumerate() {
                *t = dp_site_horizon_tan(grid, mip, &obs, lights[i * per_site + k], o[3]);
            }
        });
    out
}

/// Twin of `dp_point_observer` in `shaders/shared/dp.wgsl`: the observer of a point record
/// `[col, row, z_m − z_ref_m, min_s]` ([`site_observer_to_f32`]).
pub fn dp_point_observer(o: &[f32; 4]) -> DpObserver {
    DpObserver {
        u0: o[0],
        v0: o[1],
        z0: o[2],
        up: [0.0, 0.0, 1.0],
    }
}

/// Twin of `dp_fraction_beyond` in `shaders/shared/dp.wgsl`: [`dp_fraction`] leaving out the
/// crossings within `min_s` cells of the observer (its own ground) and sampling the surface at
/// exactly `min_s` first.
pub fn dp_fraction_beyond(
    grid: &MarchGrid,
    mip: &DpMip,
    obs: &DpObserver,
    light: [f32; 4],
    min_s: f32,
) -> f32 {
    let l = [light[0], light[1], light[2]];
    let j = dp_cost_beyond(grid, mip, obs, l, dp_cap(light), min_s);
    dp_fraction_of_cost(obs, light, j)
}

// ---------------------------------------------------------------------------------------------
// DP maps and sweeps from given observers (`shaders/dp_points.wgsl`, `dp_points_sweep.wgsl`: a
// map's DEM pixels on the GPU).
// ---------------------------------------------------------------------------------------------

/// The point records of a map's DEM pixels ([`crate::model::MapGrid::pixel_observers`]) for
/// [`dp_points`] / `dp_points.wgsl`: `(pixel index, record)` of every pixel with data, its own
/// half pixel ([`crate::shadow::OWN_HALF_PIXEL_CELLS`]) left out as the CPU engines do.
pub fn pixel_point_records(
    grid: &MarchGrid,
    observers: &[Option<crate::shadow::Observer>],
) -> (Vec<usize>, Vec<[f32; 4]>) {
    pixel_point_records_from(grid, observers, crate::shadow::OWN_HALF_PIXEL_CELLS)
}

/// [`pixel_point_records`] with the terrain nearer than `min_s` cells left out (the maps: the
/// near field is the DEM lattice's, `crate::model::MapGrid::near_field_costs`).
pub fn pixel_point_records_from(
    grid: &MarchGrid,
    observers: &[Option<crate::shadow::Observer>],
    min_s: f64,
) -> (Vec<usize>, Vec<[f32; 4]>) {
    observers
        .iter()
        .enumerate()
        .filter_map(|(i, o)| {
            let o = o.as_ref()?;
            Some((i, site_observer_to_f32(grid, o.row, o.col, o.z_m, min_s)))
        })
        .unzip()
}

/// Twin of `shaders/dp_points.wgsl`: per point record ([`site_observer_to_f32`]) the visible
/// fraction of the disc `light` ([`disc_light_to_f32`]; radius 0: 1 lit / 0 shadow). Rayon over
/// points.
pub fn dp_points(grid: &MarchGrid, mip: &DpMip, points: &[[f32; 4]], light: [f32; 4]) -> Vec<f32> {
    points
        .par_iter()
        .map(|o| dp_fraction_beyond(grid, mip, &dp_point_observer(o), light, o[3]))
        .collect()
}

/// Twin of `shaders/dp_points_sweep.wgsl` over the whole table: per point record the
/// [`DpCellStats`] of `lights` (two discs per epoch, Sun at `2e`, Earth at `2e + 1`, folded in
/// time order). Rayon over points.
pub fn dp_points_sweep(
    grid: &MarchGrid,
    mip: &DpMip,
    points: &[[f32; 4]],
    lights: &[[f32; 4]],
) -> Vec<DpCellStats> {
    points
        .par_iter()
        .map(|o| {
            let obs = dp_point_observer(o);
            let mut s = DpCellStats::default();
            for pair in lights.chunks_exact(2) {
                let fs = dp_fraction_beyond(grid, mip, &obs, pair[0], o[3]);
                let fe = dp_fraction_beyond(grid, mip, &obs, pair[1], o[3]);
                dp_sweep_accumulate(fs, fe, &mut s);
            }
            s
        })
        .collect()
}
