//! 2-D tiling of the DP shadow maps for grids larger than one GPU storage binding or than GPU
//! memory (docs/gpu.md, "Large grids"): the tile plan, the per-tile bounds that decide which
//! source tiles an output tile needs, and the f32 twins of the tiled kernels
//! (`shaders/dp_tile_*.wgsl`, one function per entry point, over a [`TileSet`]).
//!
//! **Why it is exact.** The shadow cost of a cell is a minimum over the samples of its ray
//! (papers 000/003 eq. 2, `J* = min Δh/t` at the lattice-line crossings), so it decomposes over
//! any cover of the ray: `J* = min_S J*_S`, `J*_S` using the samples inside source tile `S` only.
//! The tiles partition the dual cells (the squares between four cell centres), every crossing is
//! the exit of some dual cell, and the walk works in global cell units
//! ([`super::dp::dp_cost_in`]), so a sample has the same f32 value in any tile. Each tile's walk
//! starts from the running minimum of the tiles already walked, which also prunes it
//! (`min(best, cap)`); a tile whose highest texel cannot bring the cost below the disc's cap is
//! skipped. The result equals the untiled walk's wherever the untiled `J*` is below the cap
//! (elsewhere the disc is entirely visible in both).
//!
//! **Layout.** Tile `(a, b)` of side `T` owns cells and dual cells `[aT, (a+1)T)` (the last
//! tile row or column absorbs the remainder, so every tile has a dual cell); its heights block
//! adds one row/column before and two after (clamped to the grid): every height a sample inside
//! the tile reads, f32 rounding of its position included.

use rayon::prelude::*;

use super::dp::{
    DpCellStats, DpMip, DpObserver, DpSource, dp_cap, dp_cost_in, dp_fraction_of_cost,
    dp_observer_at, dp_sweep_accumulate,
};
use super::march::MarchGrid;
use super::{HOLE_TEST_M, NODATA_FRACTION};

/// Smallest tile side, cells.
pub const MIN_TILE_CELLS: u32 = 2;
/// The twins' "nothing along the ray" cost.
const FAR_COST: f32 = 1.0e30;
/// A light whose horizontal component is below this goes straight up or down (as the twins).
const MIN_HORIZ: f64 = 1.0e-7;

/// Why a grid cannot be tiled.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TileError {
    /// The tile side is below [`MIN_TILE_CELLS`].
    #[error("a DP tile needs at least {MIN_TILE_CELLS} cells per side; {tile_cells} given")]
    TooSmall {
        /// The side asked for.
        tile_cells: u32,
    },
    /// A tile's block or output does not fit the adapter's storage binding or dispatch limits.
    #[error(
        "tiles of {tile_cells} cells need a {block_bytes} B block, over the adapter's storage \
         binding limit ({max_binding_bytes} B) or dispatch limit"
    )]
    TooBig {
        /// The side asked for (or the smallest tried).
        tile_cells: u32,
        /// The largest buffer of one block or output tile, bytes.
        block_bytes: u64,
        /// The adapter's limit, bytes.
        max_binding_bytes: u64,
    },
}

/// Tile side chosen automatically, cells: 2048² = 4.2 M invocations per dispatch (≈ 15 × the
/// 270 k resident threads of an H100, so a tile still fills the GPU), 39 MB per source block
/// (16.8 MB heights + 22.4 MB mipmap), far below every adapter's binding limit (lavapipe:
/// 128 MiB).
pub const DEFAULT_TILE_CELLS: u32 = 2048;
/// Above this many bytes of heights + mipmap the untiled kernels are not used even where the
/// binding limit would allow them (keeps the GPU memory of a map bounded on big adapters too).
pub const DEFAULT_RESIDENT_BUDGET_BYTES: u64 = 4 << 30;

/// The adapter limits that decide between the untiled and the tiled DP kernels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TileLimits {
    /// Largest storage binding (and buffer), bytes.
    pub max_binding_bytes: u64,
    /// Largest output side one dispatch covers, cells (workgroups per dimension × 8).
    pub max_dispatch_cells: u64,
}

/// Bytes of the maximum mipmap texels of a `rows × cols` grid (without building it).
pub fn mip_bytes(rows: u64, cols: u64) -> u64 {
    let (mut r, mut c) = (rows.saturating_sub(1).max(1), cols.saturating_sub(1).max(1));
    let mut texels = r * c;
    while r > 1 || c > 1 {
        (r, c) = (r.div_ceil(2), c.div_ceil(2));
        texels += r * c;
    }
    4 * texels
}

/// The largest buffer one block of tiles of side `t` needs, bytes (heights `(t + 3)²`, the
/// last tile one more: `(t + 4)²` bounds both).
pub fn block_binding_bytes(t: u32) -> u64 {
    let side = u64::from(t) + 4;
    (4 * side * side).max(mip_bytes(side, side))
}

/// Tile side for a `rows × cols` grid whose output tile holds `out_bytes_per_cell` bytes per
/// cell in one binding (4 for a map, 32 for the sweep's statistics): `forced` if its blocks and
/// output fit `limits` (else [`TileError::TooBig`]); without `forced`, `None` (the untiled
/// kernels) when the heights and the mipmap each fit one binding, together fit
/// [`DEFAULT_RESIDENT_BUDGET_BYTES`] and the width fits one dispatch, else
/// [`DEFAULT_TILE_CELLS`] halved (down to 64) until everything fits.
pub fn choose_tile_cells(
    rows: u32,
    cols: u32,
    limits: TileLimits,
    forced: Option<u32>,
    out_bytes_per_cell: u64,
) -> Result<Option<u32>, TileError> {
    let out_bytes = |t: u32| (u64::from(t) + 1).pow(2) * out_bytes_per_cell;
    let needs = |t: u32| block_binding_bytes(t).max(out_bytes(t));
    let fits =
        |t: u32| needs(t) <= limits.max_binding_bytes && u64::from(t) < limits.max_dispatch_cells;
    let too_big = |t: u32| TileError::TooBig {
        tile_cells: t,
        block_bytes: needs(t),
        max_binding_bytes: limits.max_binding_bytes,
    };
    if let Some(t) = forced {
        if t < MIN_TILE_CELLS {
            return Err(TileError::TooSmall { tile_cells: t });
        }
        return if fits(t) {
            Ok(Some(t))
        } else {
            Err(too_big(t))
        };
    }
    let (r, c) = (u64::from(rows), u64::from(cols));
    let heights = 4 * r * c;
    let mip = mip_bytes(r, c);
    if heights.max(mip) <= limits.max_binding_bytes
        && heights + mip <= DEFAULT_RESIDENT_BUDGET_BYTES
        && c <= limits.max_dispatch_cells
    {
        return Ok(None);
    }
    let mut t = DEFAULT_TILE_CELLS;
    while !fits(t) && t > 64 {
        t /= 2;
    }
    if fits(t) {
        Ok(Some(t))
    } else {
        Err(too_big(t))
    }
}

/// One tile: its output cells, dual cells (the source region of its mipmap) and heights block.
/// Rows and columns are grid indices; every range is half-open.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TileRect {
    /// First output row (also the first dual-cell row).
    pub row0: u32,
    /// One past the last output row.
    pub row1: u32,
    /// First output column (also the first dual-cell column).
    pub col0: u32,
    /// One past the last output column.
    pub col1: u32,
    /// One past the last dual-cell row.
    pub dual_row1: u32,
    /// One past the last dual-cell column.
    pub dual_col1: u32,
    /// First row of the heights block.
    pub hgt_row0: u32,
    /// One past the last row of the heights block.
    pub hgt_row1: u32,
    /// First column of the heights block.
    pub hgt_col0: u32,
    /// One past the last column of the heights block.
    pub hgt_col1: u32,
}

impl TileRect {
    /// Output cells of the tile.
    pub fn cells(&self) -> usize {
        (self.row1 - self.row0) as usize * (self.col1 - self.col0) as usize
    }

    /// Cells of the heights block.
    pub fn block_cells(&self) -> usize {
        (self.hgt_row1 - self.hgt_row0) as usize * (self.hgt_col1 - self.hgt_col0) as usize
    }
}

/// The tiles of a grid (row-major tile indices).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TilePlan {
    /// Tile side, cells (the last tile row/column can have one more).
    pub tile_cells: u32,
    /// Tiles down the grid.
    pub tiles_down: u32,
    /// Tiles across the grid.
    pub tiles_across: u32,
    rows: u32,
    cols: u32,
}

/// Start and end (half-open) of tile `a` along an axis of `n` cells (`n − 1` dual cells) in
/// `tiles` tiles of side `t`: (cells, dual cells).
fn axis_range(a: u32, tiles: u32, t: u32, n: u32) -> (u32, u32, u32) {
    let start = a * t;
    if a + 1 == tiles {
        (start, n, n - 1)
    } else {
        (start, start + t, start + t)
    }
}

impl TilePlan {
    /// Tiles of side `tile_cells` over a `rows × cols` grid (≥ 2 × 2).
    pub fn new(rows: u32, cols: u32, tile_cells: u32) -> Result<Self, TileError> {
        if tile_cells < MIN_TILE_CELLS {
            return Err(TileError::TooSmall { tile_cells });
        }
        Ok(TilePlan {
            tile_cells,
            tiles_down: (rows - 1).div_ceil(tile_cells),
            tiles_across: (cols - 1).div_ceil(tile_cells),
            rows,
            cols,
        })
    }

    /// Number of tiles.
    pub fn len(&self) -> usize {
        self.tiles_down as usize * self.tiles_across as usize
    }

    /// Whether the plan has no tiles (never: a grid has at least one).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Tile `index` (row-major).
    pub fn rect(&self, index: usize) -> TileRect {
        let a = index as u32 / self.tiles_across;
        let b = index as u32 % self.tiles_across;
        let (row0, row1, dual_row1) = axis_range(a, self.tiles_down, self.tile_cells, self.rows);
        let (col0, col1, dual_col1) = axis_range(b, self.tiles_across, self.tile_cells, self.cols);
        TileRect {
            row0,
            row1,
            col0,
            col1,
            dual_row1,
            dual_col1,
            hgt_row0: row0.saturating_sub(1),
            hgt_row1: (dual_row1 + 2).min(self.rows),
            hgt_col0: col0.saturating_sub(1),
            hgt_col1: (dual_col1 + 2).min(self.cols),
        }
    }

    /// The tile holding cell (row, col).
    pub fn tile_of(&self, row: u32, col: u32) -> usize {
        let a = (row / self.tile_cells).min(self.tiles_down - 1);
        let b = (col / self.tile_cells).min(self.tiles_across - 1);
        (a * self.tiles_across + b) as usize
    }

    /// The largest heights block and output tile of the plan, cells.
    pub fn max_block_and_tile_cells(&self) -> (usize, usize) {
        // The last tile row and column are the largest (they absorb the remainder).
        let r = self.rect(self.len() - 1);
        let first = self.rect(0);
        (
            r.block_cells().max(first.block_cells()),
            r.cells().max(first.cells()),
        )
    }
}

/// What the planner knows of a tile without building it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TileBounds {
    /// Highest height over the tile's dual cells (= the top texel of its mipmap), metres
    /// relative to the grid's `z_ref_m`; below −1e29 when all of them are holes.
    pub max_dual_m: f32,
    /// Lowest height of the tile's output cells that are not holes (a lower bound of their
    /// observers' heights); `+inf` when all are holes.
    pub min_cell_m: f32,
}

/// The bounds of every tile of `plan` over `grid` (one pass over the heights, rayon over tiles).
pub fn tile_bounds(grid: &MarchGrid, plan: &TilePlan) -> Vec<TileBounds> {
    let cols = grid.cols as usize;
    (0..plan.len())
        .into_par_iter()
        .map(|t| {
            let r = plan.rect(t);
            let mut max_dual_m = f32::NEG_INFINITY;
            for row in r.row0..=r.dual_row1 {
                let line = &grid.heights_m[row as usize * cols..][..cols];
                for &z in &line[r.col0 as usize..=r.dual_col1 as usize] {
                    max_dual_m = max_dual_m.max(z);
                }
            }
            let mut min_cell_m = f32::INFINITY;
            for row in r.row0..r.row1 {
                let line = &grid.heights_m[row as usize * cols..][..cols];
                for &z in &line[r.col0 as usize..r.col1 as usize] {
                    if z >= HOLE_TEST_M {
                        min_cell_m = min_cell_m.min(z);
                    }
                }
            }
            TileBounds {
                max_dual_m,
                min_cell_m,
            }
        })
        .collect()
}

/// A tile's heights block and maximum mipmap, as uploaded to the GPU.
#[derive(Debug, Clone)]
pub struct TileBlock {
    /// The tile.
    pub rect: TileRect,
    /// Heights of the block (relative to `z_ref_m`, holes as `HOLE_Z_M`), row-major.
    pub heights_m: Vec<f32>,
    /// Maximum mipmap of the tile's dual cells.
    pub mip: DpMip,
}

impl TileBlock {
    /// Copies tile `rect`'s block out of `grid` and builds its mipmap.
    pub fn build(grid: &MarchGrid, rect: TileRect) -> Self {
        let cols = grid.cols as usize;
        let block_cols = (rect.hgt_col1 - rect.hgt_col0) as usize;
        let mut heights_m = Vec::with_capacity(rect.block_cells());
        for row in rect.hgt_row0..rect.hgt_row1 {
            let start = row as usize * cols + rect.hgt_col0 as usize;
            heights_m.extend_from_slice(&grid.heights_m[start..start + block_cols]);
        }
        let mip = DpMip::build_block(
            &heights_m,
            block_cols,
            (
                (rect.row0 - rect.hgt_row0) as usize,
                (rect.col0 - rect.hgt_col0) as usize,
            ),
            (
                (rect.dual_row1 - rect.row0) as usize,
                (rect.dual_col1 - rect.col0) as usize,
            ),
        );
        TileBlock {
            rect,
            heights_m,
            mip,
        }
    }

    /// The block as a DP source region.
    pub fn source(&self) -> DpSource<'_> {
        DpSource {
            heights_m: &self.heights_m,
            hgt_row0: self.rect.hgt_row0,
            hgt_col0: self.rect.hgt_col0,
            hgt_rows: self.rect.hgt_row1 - self.rect.hgt_row0,
            hgt_cols: self.rect.hgt_col1 - self.rect.hgt_col0,
            src_row0: self.rect.row0,
            src_col0: self.rect.col0,
            mip: &self.mip,
        }
    }

    /// Height of grid cell (row, col) of the tile's output (not clamped).
    pub fn cell_height_m(&self, row: u32, col: u32) -> f32 {
        let cols = (self.rect.hgt_col1 - self.rect.hgt_col0) as usize;
        self.heights_m
            [(row - self.rect.hgt_row0) as usize * cols + (col - self.rect.hgt_col0) as usize]
    }

    /// Bytes of the block's heights and mipmap texels on the GPU.
    pub fn bytes(&self) -> u64 {
        4 * (self.heights_m.len() + self.mip.texels.len()) as u64
            + 16 * self.mip.levels.len() as u64
    }
}

/// `(enter, leave)` of the ray `s ↦ s·d` (from the origin) through `[lo, hi]`, f64.
fn slab_f64(d: f64, lo: f64, hi: f64) -> (f64, f64) {
    if d > 0.0 {
        (lo / d, hi / d)
    } else if d < 0.0 {
        (hi / d, lo / d)
    } else if lo <= 0.0 && hi >= 0.0 {
        (f64::NEG_INFINITY, f64::INFINITY)
    } else {
        (f64::INFINITY, f64::NEG_INFINITY)
    }
}

/// The source tiles output tile `out` needs for the disc `light` (`xyz` unit direction, `w`
/// angular radius, as uploaded): `out` itself first, then, nearest first along the light, every
/// tile that a ray from one of `out`'s observers reaches and whose highest texel could bring a
/// cost below the disc's cap (the same lower bound as one texel of the walk, with the nearest
/// distance from `out` to the tile and the lowest observer of `out`; a margin of 1e-5 in tan
/// units and 5 cm keeps f32 rounding on the safe side).
pub fn sources_for(
    grid: &MarchGrid,
    plan: &TilePlan,
    bounds: &[TileBounds],
    out: usize,
    light: [f32; 4],
) -> Vec<usize> {
    let mut sources = vec![out];
    let [lx, ly, lz, r] = light.map(f64::from);
    let hor = (lx * lx + ly * ly).sqrt();
    let observers_m = f64::from(bounds[out].min_cell_m) - 0.05;
    if hor < MIN_HORIZ || !observers_m.is_finite() {
        return sources;
    }
    let (du, dv, tan_el) = (lx / hor, -ly / hor, lz / hor);
    let cap = if r > 0.0 {
        let e_low = lz.atan2(hor) - r;
        if e_low > -0.5 * std::f64::consts::PI + 1e-6 {
            tan_el - e_low.tan()
        } else {
            f64::INFINITY
        }
    } else {
        0.0
    };
    let margin = 1e-5 * (1.0 + cap.abs().min(1e6) + tan_el.abs());
    let o = plan.rect(out);
    // Observers stand within observer_height_m / px_m cells of their cell centre.
    let e = f64::from(grid.observer_height_m) / f64::from(grid.px_m) + 0.01;
    let (ou0, ou1) = (f64::from(o.col0) - e, f64::from(o.col1 - 1) + e);
    let (ov0, ov1) = (f64::from(o.row0) - e, f64::from(o.row1 - 1) + e);
    let mut found: Vec<(f64, usize)> = Vec::new();
    for (s, &b) in bounds.iter().enumerate() {
        if s == out {
            continue;
        }
        if b.max_dual_m < HOLE_TEST_M {
            continue;
        }
        let t = plan.rect(s);
        // The set of ray offsets from an observer of `out` to a point of `s` is the box
        // s − out (Minkowski difference); the ray reaches `s` iff it meets that box.
        let (u_in, u_out) = slab_f64(
            du,
            f64::from(t.col0) - ou1 - 1e-3,
            f64::from(t.dual_col1) - ou0 + 1e-3,
        );
        let (v_in, v_out) = slab_f64(
            dv,
            f64::from(t.row0) - ov1 - 1e-3,
            f64::from(t.dual_row1) - ov0 + 1e-3,
        );
        let t_near = u_in.max(v_in).max(0.0);
        if u_out.min(v_out) < t_near {
            continue;
        }
        let dz = f64::from(b.max_dual_m) - observers_m;
        let t_m = t_near * f64::from(grid.px_m);
        let lower_bound = if dz <= 0.0 {
            tan_el
        } else if t_m > 0.0 {
            tan_el - dz / t_m
        } else {
            f64::NEG_INFINITY
        };
        if lower_bound >= cap + margin {
            continue;
        }
        found.push((t_near, s));
    }
    found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    sources.extend(found.into_iter().map(|(_, s)| s));
    sources
}

/// Every tile of a plan with its block, built up front (fine for tests, not for big grids): what
/// the twins of the tiled kernels read.
#[derive(Debug)]
pub struct TileSet {
    /// The plan.
    pub plan: TilePlan,
    /// Per tile, the bounds that choose its source tiles.
    pub bounds: Vec<TileBounds>,
    /// Per tile, its heights block and mipmap.
    pub blocks: Vec<TileBlock>,
}

impl TileSet {
    /// Tiles of side `tile_cells` over `grid`, every block built (rayon over tiles).
    pub fn build(grid: &MarchGrid, tile_cells: u32) -> Result<Self, TileError> {
        let plan = TilePlan::new(grid.rows, grid.cols, tile_cells)?;
        let bounds = tile_bounds(grid, &plan);
        let blocks = (0..plan.len())
            .into_par_iter()
            .map(|t| TileBlock::build(grid, plan.rect(t)))
            .collect();
        Ok(TileSet {
            plan,
            bounds,
            blocks,
        })
    }
}

/// Twin of `dp_tile_cell` in `shaders/shared/dp_tile.wgsl`: the output tile of cell (row, col)
/// and the cell's observer, its height read from that tile's block; `None` for a hole.
pub fn dp_tile_cell(
    grid: &MarchGrid,
    tiles: &TileSet,
    row: u32,
    col: u32,
) -> Option<(usize, DpObserver)> {
    let out = tiles.plan.tile_of(row, col);
    let z_cell = tiles.blocks[out].cell_height_m(row, col);
    if z_cell < HOLE_TEST_M {
        return None;
    }
    Some((out, dp_observer_at(grid, row, col, z_cell)))
}

/// Twin of one cell of `shaders/dp_tile_cost.wgsl` over its dispatches: the shadow cost `J*` of
/// the ray from `obs` towards the centre of `light` as the min over the source tiles `sources`,
/// walked in that order, each from the running min.
pub fn dp_tile_cost(
    grid: &MarchGrid,
    tiles: &TileSet,
    sources: &[usize],
    obs: &DpObserver,
    light: [f32; 4],
) -> f32 {
    let cap = dp_cap(light);
    let l = [light[0], light[1], light[2]];
    sources.iter().fold(FAR_COST, |best, &s| {
        dp_cost_in(grid, &tiles.blocks[s].source(), obs, l, cap, best)
    })
}

/// Twin of one cell of `shaders/dp_tile_fraction.wgsl`: the visible fraction of the disc
/// `light` from the cell's cost `j` (radius 0: 1 lit / 0 shadow), [`NODATA_FRACTION`] for a hole
/// (`obs` = `None`).
pub fn dp_tile_fraction(obs: Option<&DpObserver>, light: [f32; 4], j: f32) -> f32 {
    match obs {
        Some(obs) => dp_fraction_of_cost(obs, light, j),
        None => NODATA_FRACTION,
    }
}

/// The tiled GPU pass 1 over the whole grid ([`dp_tile_cost`] per cell over the source tiles of
/// [`sources_for`]): per cell (row-major) the shadow cost towards the centre of `light`, `NaN`
/// for holes. Tiles of side `tile_cells`.
pub fn dp_costs_tiled(
    grid: &MarchGrid,
    tile_cells: u32,
    light: [f32; 4],
) -> Result<Vec<f32>, TileError> {
    let tiles = TileSet::build(grid, tile_cells)?;
    let sources: Vec<Vec<usize>> = (0..tiles.plan.len())
        .map(|t| sources_for(grid, &tiles.plan, &tiles.bounds, t, light))
        .collect();
    let cols = grid.cols as usize;
    let mut costs = vec![f32::NAN; grid.cells()];
    costs
        .par_chunks_mut(cols)
        .enumerate()
        .for_each(|(row, line)| {
            for (col, c) in line.iter_mut().enumerate() {
                if let Some((out, obs)) = dp_tile_cell(grid, &tiles, row as u32, col as u32) {
                    *c = dp_tile_cost(grid, &tiles, &sources[out], &obs, light);
                }
            }
        });
    Ok(costs)
}

/// Twin of the tiled GPU map (`dp_tile_cost` over the source tiles, then `dp_tile_fraction`):
/// per cell the visible fraction of the disc `light` (radius 0: 1 lit / 0 shadow),
/// [`NODATA_FRACTION`] for holes.
pub fn dp_visible_tiled(
    grid: &MarchGrid,
    tile_cells: u32,
    light: [f32; 4],
) -> Result<Vec<f32>, TileError> {
    let costs = dp_costs_tiled(grid, tile_cells, light)?;
    let cols = grid.cols as usize;
    Ok(costs
        .par_iter()
        .enumerate()
        .map(|(k, &j)| {
            let (row, col) = ((k / cols) as u32, (k % cols) as u32);
            let obs = (!j.is_nan()).then(|| dp_observer_at(grid, row, col, grid.heights_m[k]));
            dp_tile_fraction(obs.as_ref(), light, j)
        })
        .collect())
}

/// The source tiles of output tile `out` for a batch of lights: the union of
/// [`sources_for`] over `lights` (one list per batch of the tiled sweep), `out` first, then in
/// order of first appearance. Walking a tile that a light cannot use costs one texel test.
pub fn sources_for_batch(
    grid: &MarchGrid,
    plan: &TilePlan,
    bounds: &[TileBounds],
    out: usize,
    lights: &[[f32; 4]],
) -> Vec<usize> {
    let mut seen = vec![false; plan.len()];
    let mut union = Vec::new();
    for &light in lights {
        for s in sources_for(grid, plan, bounds, out, light) {
            if !seen[s] {
                seen[s] = true;
                union.push(s);
            }
        }
    }
    if union.is_empty() {
        union.push(out);
    }
    union
}

/// Twin of one cell of `shaders/dp_tile_sweep_cost.wgsl` over its dispatches: the costs
/// ([`dp_tile_cost`]) of every disc of `batch` (Sun at `2e`, Earth at `2e + 1`) over `sources`.
pub fn dp_tile_sweep_cost(
    grid: &MarchGrid,
    tiles: &TileSet,
    sources: &[usize],
    obs: &DpObserver,
    batch: &[[f32; 4]],
) -> Vec<f32> {
    batch
        .iter()
        .map(|&light| dp_tile_cost(grid, tiles, sources, obs, light))
        .collect()
}

/// Twin of one cell of `shaders/dp_tile_sweep_accumulate.wgsl`: folds the epochs of `batch`
/// (discs in pairs, Sun then Earth) into `stats` in time order, from their `costs`.
pub fn dp_tile_sweep_accumulate(
    obs: &DpObserver,
    batch: &[[f32; 4]],
    costs: &[f32],
    stats: &mut DpCellStats,
) {
    for (pair, cost) in batch.chunks_exact(2).zip(costs.chunks_exact(2)) {
        let fs = dp_fraction_of_cost(obs, pair[0], cost[0]);
        let fe = dp_fraction_of_cost(obs, pair[1], cost[1]);
        dp_sweep_accumulate(fs, fe, stats);
    }
}

/// Twin of the tiled GPU soft sweep (`dp_tile_sweep_cost` over the source tiles of each batch of
/// `epochs_per_batch` epochs, then `dp_tile_sweep_accumulate`): the [`DpCellStats`] of every
/// cell (row-major) over the epochs of `lights` (Sun at `2e`, Earth at `2e + 1`), holes zero.
/// Same result as the untiled [`super::dp::dp_sweep`] (the costs are equal, see the
/// module docs).
pub fn dp_sweep_tiled(
    grid: &MarchGrid,
    tile_cells: u32,
    lights: &[[f32; 4]],
    epochs_per_batch: usize,
) -> Result<Vec<DpCellStats>, TileError> {
    let tiles = TileSet::build(grid, tile_cells)?;
    let batch_lights = 2 * epochs_per_batch.max(1);
    let sources: Vec<Vec<Vec<usize>>> = (0..tiles.plan.len())
        .map(|t| {
            lights
                .chunks(batch_lights)
                .map(|batch| sources_for_batch(grid, &tiles.plan, &tiles.bounds, t, batch))
                .collect()
        })
        .collect();
    let cols = grid.cols as usize;
    let mut stats = vec![DpCellStats::default(); grid.cells()];
    stats
        .par_chunks_mut(cols)
        .enumerate()
        .for_each(|(row, line)| {
            for (col, st) in line.iter_mut().enumerate() {
                let Some((out, obs)) = dp_tile_cell(grid, &tiles, row as u32, col as u32) else {
                    continue;
                };
                for (batch, batch_sources) in lights.chunks(batch_lights).zip(&sources[out]) {
                    let costs = dp_tile_sweep_cost(grid, &tiles, batch_sources, &obs, batch);
                    dp_tile_sweep_accumulate(&obs, batch, &costs, st);
                }
            }
        });
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tiles partition the cells and the dual cells; blocks hold every height a tile's samples
    /// can read (one row/column before, two after).
    #[test]
    fn plan_partitions_cells_and_dual_cells() {
        for (rows, cols, t) in [(256, 256, 64), (256, 256, 50), (65, 130, 64), (2, 9, 2)] {
            let plan = TilePlan::new(rows, cols, t).unwrap();
            let mut cell_hits = vec![0_u8; (rows * cols) as usize];
            let mut dual_hits = vec![0_u8; ((rows - 1) * (cols - 1)) as usize];
            for k in 0..plan.len() {
                let r = plan.rect(k);
                assert!(r.dual_row1 > r.row0 && r.dual_col1 > r.col0, "{r:?}");
                for row in r.row0..r.row1 {
                    for col in r.col0..r.col1 {
                        cell_hits[(row * cols + col) as usize] += 1;
                        assert_eq!(plan.tile_of(row, col), k);
                    }
                }
                for row in r.row0..r.dual_row1 {
                    for col in r.col0..r.dual_col1 {
                        dual_hits[(row * (cols - 1) + col) as usize] += 1;
                    }
                }
                assert_eq!(r.hgt_row0, r.row0.saturating_sub(1));
                assert_eq!(r.hgt_row1, (r.dual_row1 + 2).min(rows));
                assert!(r.hgt_row1 >= r.row1 && r.hgt_col1 >= r.col1);
            }
            assert!(cell_hits.iter().all(|&h| h == 1));
            assert!(dual_hits.iter().all(|&h| h == 1));
        }
        assert_eq!(
            TilePlan::new(10, 10, 1),
            Err(TileError::TooSmall { tile_cells: 1 })
        );
    }

    /// The mipmap size formula counts the texels `DpMip::build` makes; the automatic choice
    /// keeps grids that fit one binding untiled and tiles the rest (lavapipe's 128 MiB limit,
    /// a 4 GiB limit, 20,000² at 20 m).
    #[test]
    fn automatic_tile_choice_follows_the_binding_limit() {
        use crate::terrain::HeightField;
        use crate::twins::{DpMip, MarchGrid};
        for (rows, cols) in [(2, 2), (37, 37), (65, 130), (200, 7)] {
            let grid =
                MarchGrid::from_height_field(&HeightField::flat(rows, cols, 20.0), 2.0).unwrap();
            let texels = DpMip::build(&grid).texels.len() as u64;
            assert_eq!(mip_bytes(rows as u64, cols as u64), 4 * texels);
        }
        let lavapipe = TileLimits {
            max_binding_bytes: 128 << 20,
            max_dispatch_cells: 65_535 * 8,
        };
        let big = TileLimits {
            max_binding_bytes: (4 << 30) - 1,
            ..lavapipe
        };
        // 5,300²: 112 MB heights, 150 MB mipmap > 128 MiB: tiled on lavapipe only; 5,000²
        // (133 MB mipmap) still fits.
        assert_eq!(
            choose_tile_cells(5300, 5300, lavapipe, None, 4),
            Ok(Some(2048))
        );
        assert_eq!(choose_tile_cells(5300, 5300, big, None, 4), Ok(None));
        assert_eq!(choose_tile_cells(5000, 5000, lavapipe, None, 4), Ok(None));
        assert_eq!(choose_tile_cells(4096, 4096, lavapipe, None, 4), Ok(None));
        // 20,000²: 1.6 GB + 2.1 GB fits a 4 GiB binding and the 4 GiB budget; 30,000² does not.
        assert_eq!(choose_tile_cells(20_000, 20_000, big, None, 4), Ok(None));
        assert_eq!(
            choose_tile_cells(30_000, 30_000, big, None, 4),
            Ok(Some(2048))
        );
        assert_eq!(
            choose_tile_cells(20_000, 20_000, lavapipe, None, 4),
            Ok(Some(2048))
        );
        let tiny = TileLimits {
            max_binding_bytes: 1 << 20,
            ..lavapipe
        };
        // 1 MiB binding: 2048 → 1024 → 512 (block 1.4 MB > 1 MiB) → 256 (359 kB).
        assert_eq!(
            choose_tile_cells(20_000, 20_000, tiny, None, 4),
            Ok(Some(256))
        );
        assert_eq!(choose_tile_cells(100, 100, tiny, Some(50), 4), Ok(Some(50)));
        assert!(matches!(
            choose_tile_cells(100, 100, tiny, Some(4096), 4),
            Err(TileError::TooBig { .. })
        ));
        assert_eq!(
            choose_tile_cells(100, 100, tiny, Some(1), 4),
            Err(TileError::TooSmall { tile_cells: 1 })
        );
        // The sweep's 32 B of statistics per cell: 2049² × 32 B = 134.3 MB > 128 MiB, so
        // lavapipe gets tiles of 1024 for a sweep.
        assert_eq!(
            choose_tile_cells(20_000, 20_000, lavapipe, None, 32),
            Ok(Some(1024))
        );
    }
}
