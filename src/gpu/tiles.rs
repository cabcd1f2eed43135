//! 2-D tiled DP shadow maps on the GPU (docs/gpu.md, "Large grids"): for grids whose heights or
//! maximum mipmap exceed one storage binding (or a memory budget), the one-light DP map is
//! computed per output tile, walking the rays through one source tile at a time
//! (`shaders/dp_tile_cost.wgsl`, min-accumulating the shadow cost in a per-tile cost buffer),
//! then turned into fractions (`shaders/dp_tile_fraction.wgsl`); the soft epoch sweep likewise
//! per batch of epochs (`shaders/dp_tile_sweep_cost.wgsl`, `dp_tile_sweep_accumulate.wgsl`,
//! [`dp_sweep_tiled_gpu`]). The tile plan, the choice of source tiles and the CPU twins live in
//! [`crate::twins::dp_tiles`] (why the result is exact is explained there).
//!
//! GPU memory: the output tile's cost buffer and readback staging, `2 × 4 (T + 1)²` B, plus the
//! resident source blocks (heights `4 (T + 3)²` B + mipmap ≈ `4 · 4/3 · T²` B each) of an LRU
//! cache of at most [`DpTileOptions::cache_bytes`] (at least two blocks), whatever the grid size.

use std::collections::HashMap;
use std::rc::Rc;

use bytemuck::Pod;

use super::GpuError;
use super::context::{
    ErrorScope, GpuContext, WORKGROUP_SIZE_XY, grid_params_buffer, slot_offset, storage_init,
};
use super::dp::gpu_data::DpStep;
use super::dp::{DpBindings, DpPipelines, check_light, check_sweep_table};
pub use crate::twins::dp_tiles::{DEFAULT_RESIDENT_BUDGET_BYTES, DEFAULT_TILE_CELLS};
use crate::twins::dp_tiles::{
    TileBlock, TileBounds, TileLimits, TilePlan, TileRect, choose_tile_cells, sources_for,
    sources_for_batch, tile_bounds,
};
use crate::twins::{DpCellStats, DpMip, MarchGrid};

/// Resident source blocks kept by default, bytes (25 blocks of 2048²).
pub const DEFAULT_CACHE_BYTES: u64 = 1 << 30;

/// How a DP map or sweep is split (the `--gpu-tile-cells` option of `penumbra map`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DpTiling {
    /// Tiles of this side, cells, whatever the grid size (for tests and measurements); `None`:
    /// the untiled kernels when the heights and the mipmap each fit one storage binding and
    /// together 4 GiB, else tiles of 2048 (halved until a block fits one binding); see
    /// [`crate::twins::dp_tiles::choose_tile_cells`].
    pub tile_cells: Option<u32>,
}

impl DpTiling {
    /// The tile side for a one-light map of `grid` on `ctx`, `None` for the untiled kernel. A
    /// forced side whose block would exceed the storage binding limit or the dispatch limit is an
    /// error.
    pub fn resolve(&self, ctx: &GpuContext, grid: &MarchGrid) -> Result<Option<u32>, GpuError> {
        self.resolve_for(ctx, grid, 4)
    }

    /// As [`DpTiling::resolve`] for the soft sweep (32 B of statistics per output cell).
    pub fn resolve_sweep(
        &self,
        ctx: &GpuContext,
        grid: &MarchGrid,
    ) -> Result<Option<u32>, GpuError> {
        self.resolve_for(ctx, grid, size_of::<DpCellStats>() as u64)
    }

    fn resolve_for(
        &self,
        ctx: &GpuContext,
        grid: &MarchGrid,
        out_bytes_per_cell: u64,
    ) -> Result<Option<u32>, GpuError> {
        let tile_limits = TileLimits {
            max_binding_bytes: ctx.max_storage_binding_bytes(),
            max_dispatch_cells: u64::from(ctx.limits().max_compute_workgroups_per_dimension)
                * u64::from(WORKGROUP_SIZE_XY),
        };
        choose_tile_cells(
            grid.rows,
            grid.cols,
            tile_limits,
            self.tile_cells,
            out_bytes_per_cell,
        )
        .map_err(|e| GpuError::InvalidInput {
            kernel: "dp_tile_cost",
            message: e.to_string(),
        })
    }
}

/// Options of [`dp_visible_tiled_gpu`].
#[derive(Debug, Clone, Copy)]
pub struct DpTileOptions {
    /// Tile side, cells (output tiles and source tiles alike).
    pub tile_cells: u32,
    /// Bytes of source blocks kept resident between output tiles (LRU; at least two blocks).
    pub cache_bytes: u64,
}

impl DpTileOptions {
    /// Tiles of `tile_cells` with the default cache.
    pub fn new(tile_cells: u32) -> Self {
        DpTileOptions {
            tile_cells,
            cache_bytes: DEFAULT_CACHE_BYTES,
        }
    }
}

/// What a tiled run did (for the docs' cost figures and the tests).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TileRunStats {
    /// Output tiles.
    pub output_tiles: usize,
    /// Cost dispatches (one per output tile and source tile walked).
    pub source_dispatches: usize,
    /// Most source tiles one output tile needed.
    pub max_sources: usize,
    /// Source blocks uploaded (cache misses).
    pub uploads: usize,
    /// Largest resident block bytes at once (cache, excluding blocks still in flight).
    pub peak_cache_bytes: u64,
}

/// The map of [`dp_visible_tiled_gpu`] and what the run did.
#[derive(Debug, Clone)]
pub struct TiledMap {
    /// Per cell (row-major) the visible fraction (radius 0: 1 lit / 0 shadow), -1 for nodata.
    pub values: Vec<f32>,
    /// Tiles, dispatches, uploads.
    pub stats: TileRunStats,
}

/// One tile's heights block and mipmap on the GPU.
struct GpuTileBlock {
    rect: TileRect,
    heights: wgpu::Buffer,
    mip: wgpu::Buffer,
    levels: wgpu::Buffer,
    bytes: u64,
}

impl GpuTileBlock {
    fn upload(ctx: &GpuContext, block: &TileBlock) -> Self {
        let DpMip { levels, texels } = &block.mip;
        GpuTileBlock {
            rect: block.rect,
            heights: storage_init(ctx, "penumbra dp tile heights", &block.heights_m),
            mip: storage_init(ctx, "penumbra dp tile mipmap", texels),
            levels: storage_init(ctx, "penumbra dp tile mipmap levels", levels),
            bytes: block.bytes(),
        }
    }
}

/// LRU cache of uploaded source blocks.
struct BlockCache {
    /// Blocks built on the host (heights copy + mipmap), each once per call: re-uploading an
    /// evicted block then costs only the transfer. Host memory ≈ 1.3 × the grid's heights.
    host: Vec<Option<TileBlock>>,
    blocks: HashMap<usize, (Rc<GpuTileBlock>, u64)>,
    bytes: u64,
    cap_bytes: u64,
    clock: u64,
}

impl BlockCache {
    /// An empty cache for `tiles` output tiles holding at most `cap_bytes` of GPU blocks.
    fn new(tiles: usize, cap_bytes: u64) -> Self {
        BlockCache {
            host: vec![None; tiles],
            blocks: HashMap::new(),
            bytes: 0,
            cap_bytes,
            clock: 0,
        }
    }

    fn get(
        &mut self,
        ctx: &GpuContext,
        grid: &MarchGrid,
        plan: &TilePlan,
        tile: usize,
        stats: &mut TileRunStats,
    ) -> Rc<GpuTileBlock> {
        self.clock += 1;
        if let Some((block, used)) = self.blocks.get_mut(&tile) {
            *used = self.clock;
            return Rc::clone(block);
        }
        let host = self.host[tile].get_or_insert_with(|| TileBlock::build(grid, plan.rect(tile)));
        let block = Rc::new(GpuTileBlock::upload(ctx, host));
        stats.uploads += 1;
        self.bytes += block.bytes;
        self.blocks.insert(tile, (Rc::clone(&block), self.clock));
        while self.bytes > self.cap_bytes && self.blocks.len() > 2 {
            let oldest = self
                .blocks
                .iter()
                .filter(|(t, _)| **t != tile)
                .min_by_key(|(_, (_, used))| *used)
                .map(|(t, _)| *t);
            let Some(oldest) = oldest else { break };
            if let Some((evicted, _)) = self.blocks.remove(&oldest) {
                self.bytes -= evicted.bytes;
            }
        }
        stats.peak_cache_bytes = stats.peak_cache_bytes.max(self.bytes);
        block
    }
}

/// The dispatch parameters of output tile `o` (whose block `own` holds the observers) walking
/// source tile `s`.
fn tile_step(
    o: TileRect,
    own: TileRect,
    s: TileRect,
    first: bool,
    light0: u32,
    count: u32,
) -> DpStep {
    DpStep {
        light0,
        count,
        band_row0: o.row0,
        band_rows: o.row1 - o.row0,
        band_col0: o.col0,
        band_cols: o.col1 - o.col0,
        src_row0: s.row0,
        src_col0: s.col0,
        hgt_row0: s.hgt_row0,
        hgt_col0: s.hgt_col0,
        hgt_rows: s.hgt_row1 - s.hgt_row0,
        hgt_cols: s.hgt_col1 - s.hgt_col0,
        first_source: u32::from(first),
        obs_row0: own.hgt_row0,
        obs_col0: own.hgt_col0,
        obs_cols: own.hgt_col1 - own.hgt_col0,
    }
}

/// After a source dispatch: reclaim finished work; when the cache is full wait for the GPU, so
/// that evicted blocks still referenced by queued dispatches are freed and in-flight memory stays
/// bounded too.
fn settle(ctx: &GpuContext, cache: &BlockCache) {
    let wait = if cache.bytes >= cache.cap_bytes {
        wgpu::PollType::wait_indefinitely()
    } else {
        wgpu::PollType::Poll
    };
    ctx.device.poll(wait).ok();
}

/// The kernels of one tiled run: `cost` once per source tile (own tile first), then `finish`
/// on the output tile, both with `layout`, writing `out`, with `extra` bound after the output
/// tile's heights.
struct TileKernels<'a> {
    layout: &'a wgpu::BindGroupLayout,
    cost: &'a wgpu::ComputePipeline,
    finish: &'a wgpu::ComputePipeline,
    out: &'a wgpu::Buffer,
    extra: &'a [&'a wgpu::Buffer],
}

/// What the tiled map and the tiled sweep share: the tile plan (checked against the device) and
/// the tiles' bounds, then inside one error scope the grid uniform, the light table, one step
/// slot per source tile plus one, and the LRU cache of source blocks; and the run's counters.
struct TiledRun<'a> {
    ctx: &'a GpuContext,
    grid: &'a MarchGrid,
    plan: TilePlan,
    bounds: Vec<TileBounds>,
    /// Cells of the largest output tile.
    max_tile_cells: usize,
    scope: ErrorScope,
    params: wgpu::Buffer,
    lights: wgpu::Buffer,
    slots: wgpu::Buffer,
    cache: BlockCache,
    stats: TileRunStats,
}

impl<'a> TiledRun<'a> {
    /// Plans tiles of `tile_cells` over `grid` (`out_bytes_per_cell` of output per cell, errors
    /// reported for `kernel`) and uploads what every output tile needs, `lights` included.
    fn new(
        ctx: &'a GpuContext,
        grid: &'a MarchGrid,
        lights: &[[f32; 4]],
        (tile_cells, cache_bytes): (u32, u64),
        out_bytes_per_cell: u64,
        kernel: &'static str,
    ) -> Result<Self, GpuError> {
        let plan = tile_plan(grid, tile_cells, kernel)?;
        DpTiling {
            tile_cells: Some(tile_cells),
        }
        .resolve_for(ctx, grid, out_bytes_per_cell)?;
        let bounds = tile_bounds(grid, &plan);
        let (_, max_tile_cells) = plan.max_block_and_tile_cells();
        let scope = ErrorScope::push(&ctx.device);
        Ok(TiledRun {
            ctx,
            grid,
            bounds,
            max_tile_cells,
            params: grid_params_buffer(ctx, "penumbra dp tile grid params", grid),
            lights: storage_init(ctx, "penumbra dp tile lights", lights),
            slots: ctx.slot_buffer(plan.len() as u32 + 1),
            cache: BlockCache::new(plan.len(), cache_bytes),
            stats: TileRunStats {
                output_tiles: plan.len(),
                ..Default::default()
            },
            plan,
            scope,
        })
    }

    /// The block of output tile `out` (from the cache).
    fn own_block(&mut self, out: usize) -> Rc<GpuTileBlock> {
        self.cache
            .get(self.ctx, self.grid, &self.plan, out, &mut self.stats)
    }

    /// The bind group of `k` walking source block `src` for the observers of block `obs`.
    fn bind_group(
        &self,
        k: &TileKernels<'_>,
        src: &GpuTileBlock,
        obs: &GpuTileBlock,
    ) -> wgpu::BindGroup {
        let mut extra = vec![&obs.heights];
        extra.extend_from_slice(k.extra);
        DpBindings {
            params: &self.params,
            heights: &src.heights,
            mip: &src.mip,
            levels: &src.levels,
            lights: &self.lights,
            slots: &self.slots,
            out: k.out,
            extra: &extra,
        }
        .bind_group(self.ctx, "penumbra dp tile bind group", k.layout)
    }

    /// Writes the step slots of output tile `out` (block `own`) for the epochs
    /// `[first, first + count)` and dispatches the passes of `k` over `sources`, counting them.
    fn passes(
        &mut self,
        k: &TileKernels<'_>,
        out: usize,
        own: &Rc<GpuTileBlock>,
        sources: &[usize],
        (first, count): (u32, u32),
    ) {
        let o = self.plan.rect(out);
        self.stats.source_dispatches += sources.len();
        self.stats.max_sources = self.stats.max_sources.max(sources.len());
        let mut steps: Vec<DpStep> = sources
            .iter()
            .enumerate()
            .map(|(j, &s)| tile_step(o, own.rect, self.plan.rect(s), j == 0, first, count))
            .collect();
        steps.push(tile_step(o, own.rect, o, false, first, count));
        self.ctx.write_slots(&self.slots, &steps);
        let workgroups = [
            (o.col1 - o.col0).div_ceil(WORKGROUP_SIZE_XY),
            (o.row1 - o.row0).div_ceil(WORKGROUP_SIZE_XY),
            1,
        ];
        for (j, &s) in sources.iter().enumerate() {
            let src = if s == out {
                Rc::clone(own)
            } else {
                self.cache
                    .get(self.ctx, self.grid, &self.plan, s, &mut self.stats)
            };
            let group = self.bind_group(k, &src, own);
            self.ctx
                .dispatch("dp_tile", k.cost, &group, &[slot_offset(j)], workgroups);
            settle(self.ctx, &self.cache);
        }
        let group = self.bind_group(k, own, own);
        let finish_slot = [slot_offset(sources.len())];
        self.ctx
            .dispatch("dp_tile", k.finish, &group, &finish_slot, workgroups);
    }

    /// Reads output tile `out` back from `buffer` into the grid-sized `dst`.
    fn read_tile<T: Pod>(
        &self,
        buffer: &wgpu::Buffer,
        out: usize,
        dst: &mut [T],
        what: &'static str,
    ) -> Result<(), GpuError> {
        let o = self.plan.rect(out);
        let bytes = self
            .ctx
            .read_back(buffer, (o.cells() * size_of::<T>()) as u64, what)?;
        scatter_tile(
            dst,
            self.grid.cols as usize,
            o,
            &bytemuck::pod_collect_to_vec(&bytes),
        );
        Ok(())
    }

    /// Pops the error scope (`action` names the run) and returns the counters.
    fn finish(self, action: &'static str) -> Result<TileRunStats, GpuError> {
        self.scope.pop(action)?;
        Ok(self.stats)
    }
}

/// Copies the row-major `values` of output tile `o` into the grid-sized `dst` of `cols` columns.
fn scatter_tile<T: Copy>(dst: &mut [T], cols: usize, o: TileRect, values: &[T]) {
    let band_cols = (o.col1 - o.col0) as usize;
    for (r, line) in values.chunks_exact(band_cols).enumerate() {
        let start = (o.row0 as usize + r) * cols + o.col0 as usize;
        dst[start..start + line.len()].copy_from_slice(line);
    }
}

/// The [`TilePlan`] of `grid` for `tile_cells`, its error as [`GpuError::InvalidInput`] of
/// `kernel`.
fn tile_plan(
    grid: &MarchGrid,
    tile_cells: u32,
    kernel: &'static str,
) -> Result<TilePlan, GpuError> {
    TilePlan::new(grid.rows, grid.cols, tile_cells).map_err(|e| GpuError::InvalidInput {
        kernel,
        message: e.to_string(),
    })
}

/// GPU tiled `dp_visible`: per cell (row-major) the visible fraction of the disc `light` (from
/// [`crate::twins::disc_light_to_f32`]; radius 0: 1 lit / 0 shadow), -1 for nodata,
/// computed output tile by output tile over the source tiles of
/// [`crate::twins::dp_tiles::sources_for`] (own tile first, then nearest first along the
/// light). Only the heights as a host array are needed, never the whole grid on the GPU. Twin:
/// [`crate::twins::dp_tiles::dp_visible_tiled`].
pub fn dp_visible_tiled_gpu(
    ctx: &GpuContext,
    grid: &MarchGrid,
    light: [f32; 4],
    options: DpTileOptions,
) -> Result<TiledMap, GpuError> {
    let dp = ctx.pipelines::<DpPipelines>()?;
    check_light(light, "dp_tile_cost")?;
    let tiling = (options.tile_cells, options.cache_bytes);
    let mut run = TiledRun::new(ctx, grid, &[light], tiling, 4, "dp_tile_cost")?;
    let cost = ctx.output_buffer("penumbra dp tile cost", run.max_tile_cells as u64 * 4);
    let kernels = TileKernels {
        layout: &dp.tile_layout,
        cost: &dp.tile_cost,
        finish: &dp.tile_fraction,
        out: &cost,
        extra: &[],
    };
    let mut map = vec![0.0_f32; grid.cells()];
    for out in 0..run.plan.len() {
        let sources = sources_for(grid, &run.plan, &run.bounds, out, light);
        let own = run.own_block(out);
        run.passes(&kernels, out, &own, &sources, (0, 1));
        run.read_tile(&cost, out, &mut map, "a DP tile")?;
    }
    let stats = run.finish("running the tiled DP map")?;
    Ok(TiledMap { values: map, stats })
}

/// Options of [`dp_sweep_tiled_gpu`].
#[derive(Debug, Clone, Copy)]
pub struct DpTileSweepOptions {
    /// Tile side, cells.
    pub tile_cells: u32,
    /// Bytes of source blocks kept resident (LRU; at least two blocks).
    pub cache_bytes: u64,
    /// Epochs per batch: the cost buffer holds `2 × epochs_per_batch` costs per output cell.
    pub epochs_per_batch: u32,
}

impl DpTileSweepOptions {
    /// Tiles of `tile_cells`, the default cache, 8 epochs per batch (cost buffer 64 B per
    /// output cell: 268 MB for a 2048² tile).
    pub fn new(tile_cells: u32) -> Self {
        DpTileSweepOptions {
            tile_cells,
            cache_bytes: DEFAULT_CACHE_BYTES,
            epochs_per_batch: 8,
        }
    }
}

/// GPU tiled soft epoch sweep: the [`DpCellStats`] of every cell (row-major) over the epochs of
/// `lights` (Sun at `2e`, Earth at `2e + 1`, from
/// [`crate::twins::disc_light_to_f32`], in time order), computed output tile by output
/// tile: per batch of epochs the costs are min-accumulated over the batch's source tiles
/// ([`crate::twins::dp_tiles::sources_for_batch`]) in a `[2 × batch × tile cells]` buffer, then
/// folded into the tile's statistics in time order; the statistics are read back once per output
/// tile. GPU memory: `32 (T+1)²` B of statistics (+ as much staging) + `8 B × epochs_per_batch ×
/// (T+1)²` of costs + the light table (32 B/epoch) + the block cache. Twin:
/// [`crate::twins::dp_tiles::dp_sweep_tiled`].
pub fn dp_sweep_tiled_gpu(
    ctx: &GpuContext,
    grid: &MarchGrid,
    lights: &[[f32; 4]],
    options: DpTileSweepOptions,
) -> Result<(Vec<DpCellStats>, TileRunStats), GpuError> {
    let dp = ctx.pipelines::<DpPipelines>()?;
    let kernel = "dp_tile_sweep_cost";
    let valid = options.epochs_per_batch > 0;
    let epochs = check_sweep_table(lights, valid, "a non-zero batch", kernel)?;
    let stats_bytes = size_of::<DpCellStats>() as u64;
    let tiling = (options.tile_cells, options.cache_bytes);
    let mut run = TiledRun::new(ctx, grid, lights, tiling, stats_bytes, kernel)?;
    let tile_cells = run.max_tile_cells as u64;
    // The cost buffer (8 B per cell and epoch) must fit one binding too.
    let batch = options
        .epochs_per_batch
        .min((ctx.max_storage_binding_bytes() / (8 * tile_cells)).max(1) as u32);
    let cost = ctx.output_buffer(
        "penumbra dp tile sweep cost",
        tile_cells * 2 * u64::from(batch) * 4,
    );
    let tile_stats = ctx.output_buffer("penumbra dp tile sweep stats", tile_cells * stats_bytes);
    let kernels = TileKernels {
        layout: &dp.tile_sweep_layout,
        cost: &dp.tile_sweep_cost,
        finish: &dp.tile_sweep_accumulate,
        out: &cost,
        extra: &[&tile_stats],
    };
    let mut all = vec![DpCellStats::default(); grid.cells()];
    for out in 0..run.plan.len() {
        let own = run.own_block(out);
        ctx.clear("penumbra dp tile sweep clear", &tile_stats);
        let mut first = 0_u32;
        while first < epochs {
            let count = batch.min(epochs - first);
            let batch_lights = &lights[2 * first as usize..2 * (first + count) as usize];
            let sources = sources_for_batch(grid, &run.plan, &run.bounds, out, batch_lights);
            run.passes(&kernels, out, &own, &sources, (first, count));
            // The next batch rewrites the step slots: queue writes land before later submits
            // and after earlier ones, so no wait is needed.
            first += count;
        }
        run.read_tile(&tile_stats, out, &mut all, "DP tile statistics")?;
    }
    let stats = run.finish("running the tiled DP sweep")?;
    Ok((all, stats))
}
