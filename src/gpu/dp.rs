//! GPU DP soft shadows over maximum mipmaps: `shaders/dp_visible.wgsl` (one map: the visible
//! fraction of one disc per cell, radius 0 = hard mask), `shaders/dp_sweep.wgsl` (the soft
//! epoch sweep: Sun and Earth fractions folded into per-cell statistics, GPU-resident) and
//! `shaders/dp_sites.wgsl` (per-site horizons along a table of discs: the GPU path of
//! `series --engine smap-dp`, [`dp_sites_gpu`]), `shaders/dp_points.wgsl` and
//! `dp_points_sweep.wgsl` (one map and the soft sweep from given observers, a map's DEM pixels:
//! [`dp_points_gpu`], [`dp_points_sweep_gpu`]). All share `shaders/shared/dp.wgsl`; CPU twins:
//! `dp_visible`, `dp_sweep`, `dp_sites`, `dp_points`, `dp_points_sweep` in [`crate::twins`].
//!
//! The heights and every mipmap level are uploaded once ([`GpuDpGrid::upload`]: 4 B/cell + about
//! 4/3 × 4 B/cell), the light table once per map or sweep. Outputs are computed in row bands
//! (or chunks of points) so that output memory is bounded by the band, not the grid.

use bytemuck::{Pod, Zeroable};

use super::GpuError;
use super::context::{
    DEFAULT_BAND_BYTES, ErrorScope, GpuContext, GpuGrid, WORKGROUP_SIZE_XY, buffer_layout_entry,
    check_dispatch_cols, compute_pipeline, layout_entry, sized, slot_offset, storage_init, whole,
};
use super::shaders;
use crate::twins::{DpCellStats, DpMip, MarchGrid};
/// Epochs per dispatch of the soft sweep by default (each invocation loops over them).
pub const DEFAULT_EPOCHS_PER_DISPATCH: u32 = 16;
/// Dispatches per queue submit of the soft sweep by default.
pub const DEFAULT_DISPATCHES_PER_SUBMIT: u32 = 16;

/// Workgroup size of `shaders/dp_sites.wgsl` (along the entries). Keep in sync.
const SITES_WORKGROUP_SIZE_X: u32 = 64;
/// Workgroup size of `shaders/dp_points.wgsl` and `dp_points_sweep.wgsl`. Keep in sync.
const POINTS_WORKGROUP_SIZE_X: u32 = 64;

/// Mirrors of the WGSL structs.
pub(crate) mod gpu_data {
    use super::{Pod, Zeroable};

    /// Keep in sync with `DpStep` in shaders/shared/dp.wgsl.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Default, Pod, Zeroable)]
    pub(crate) struct DpStep {
        pub light0: u32,
        pub count: u32,
        pub band_row0: u32,
        pub band_rows: u32,
        pub band_col0: u32,
        pub band_cols: u32,
        pub src_row0: u32,
        pub src_col0: u32,
        pub hgt_row0: u32,
        pub hgt_col0: u32,
        pub hgt_rows: u32,
        pub hgt_cols: u32,
        pub first_source: u32,
        pub obs_row0: u32,
        pub obs_col0: u32,
        pub obs_cols: u32,
    }
    const _: () = assert!(size_of::<DpStep>() == 64);

    impl DpStep {
        /// A step over the whole grid as one source region (dp_visible, dp_sweep).
        pub(crate) fn whole(
            rows: u32,
            cols: u32,
            light0: u32,
            count: u32,
            band: (u32, u32),
        ) -> Self {
            DpStep {
                light0,
                count,
                band_row0: band.0,
                band_rows: band.1,
                band_col0: 0,
                band_cols: cols,
                hgt_rows: rows,
                hgt_cols: cols,
                obs_cols: cols,
                ..Default::default()
            }
        }
    }
}
use gpu_data::DpStep;

/// Bind group layouts and pipelines of the DP kernels (built on first use,
/// [`GpuContext::pipelines`]).
pub(crate) struct DpPipelines {
    layout: wgpu::BindGroupLayout,
    visible: wgpu::ComputePipeline,
    sweep: wgpu::ComputePipeline,
    sites: wgpu::ComputePipeline,
    points: wgpu::ComputePipeline,
    points_sweep: wgpu::ComputePipeline,
    /// Layout of the tiled kernels: the DP bindings 0..6 plus 7 (the output tile's heights); also
    /// the layout of `sites` (7 = the site observers).
    pub(crate) tile_layout: wgpu::BindGroupLayout,
    /// `shaders/dp_tile_cost.wgsl`.
    pub(crate) tile_cost: wgpu::ComputePipeline,
    /// `shaders/dp_tile_fraction.wgsl`.
    pub(crate) tile_fraction: wgpu::ComputePipeline,
    /// Layout of the tiled sweep: `tile_layout` plus 8 (the output tile's statistics).
    pub(crate) tile_sweep_layout: wgpu::BindGroupLayout,
    /// `shaders/dp_tile_sweep_cost.wgsl`.
    pub(crate) tile_sweep_cost: wgpu::ComputePipeline,
    /// `shaders/dp_tile_sweep_accumulate.wgsl`.
    pub(crate) tile_sweep_accumulate: wgpu::ComputePipeline,
}

/// A DP bind group layout: 0 the grid parameters (uniform), 1..4 heights, mip, levels, lights
/// (read-only storage), 5 the step slots (uniform, dynamic offset), 6 the output (read-write),
/// then `extra` from binding 7 on.
fn dp_layout(
    device: &wgpu::Device,
    label: &str,
    extra: &[wgpu::BufferBindingType],
) -> wgpu::BindGroupLayout {
    use wgpu::BufferBindingType::{Storage, Uniform};
    let read = Storage { read_only: true };
    let mut entries = vec![
        layout_entry(0, Uniform),
        layout_entry(1, read),
        layout_entry(2, read),
        layout_entry(3, read),
        layout_entry(4, read),
        buffer_layout_entry(5, Uniform, true),
        layout_entry(6, Storage { read_only: false }),
    ];
    entries.extend(
        (7..)
            .zip(extra)
            .map(|(binding, ty)| layout_entry(binding, *ty)),
    );
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &entries,
    })
}

/// The buffers of a DP bind group, in [`dp_layout`] order.
pub(crate) struct DpBindings<'a> {
    /// 0: grid parameters.
    pub(crate) params: &'a wgpu::Buffer,
    /// 1: source heights.
    pub(crate) heights: &'a wgpu::Buffer,
    /// 2: source max-mipmap.
    pub(crate) mip: &'a wgpu::Buffer,
    /// 3: mip level table.
    pub(crate) levels: &'a wgpu::Buffer,
    /// 4: lights.
    pub(crate) lights: &'a wgpu::Buffer,
    /// 5: step slots (one [`DpStep`] bound, addressed by dynamic offsets).
    pub(crate) slots: &'a wgpu::Buffer,
    /// 6: output.
    pub(crate) out: &'a wgpu::Buffer,
    /// 7..: kernel-specific extras.
    pub(crate) extra: &'a [&'a wgpu::Buffer],
}

impl DpBindings<'_> {
    /// The bind group of these buffers for `layout`.
    pub(crate) fn bind_group(
        &self,
        ctx: &GpuContext,
        label: &str,
        layout: &wgpu::BindGroupLayout,
    ) -> wgpu::BindGroup {
        let mut entries = vec![
            whole(0, self.params),
            whole(1, self.heights),
            whole(2, self.mip),
            whole(3, self.levels),
            whole(4, self.lights),
            sized(5, self.slots, size_of::<DpStep>() as u64),
            whole(6, self.out),
        ];
        entries.extend((7..).zip(self.extra).map(|(binding, b)| whole(binding, b)));
        ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout,
            entries: &entries,
        })
    }
}

impl super::context::Pipelines for DpPipelines {
    const WHAT: &'static str = "building the DP pipelines";

    fn build(device: &wgpu::Device) -> Self {
        use wgpu::BufferBindingType::Storage;
        let read = Storage { read_only: true };
        let layout = dp_layout(device, "penumbra dp layout", &[]);
        // Also the layout of dp_sites (7 = the site observers).
        let tile_layout = dp_layout(device, "penumbra dp tile layout", &[read]);
        let tile_sweep_layout = dp_layout(
            device,
            "penumbra dp tile sweep layout",
            &[read, Storage { read_only: false }],
        );
        let tile_sweep_cost =
            compute_pipeline(device, &tile_sweep_layout, &shaders::DP_TILE_SWEEP_COST);
        let tile_sweep_accumulate = compute_pipeline(
            device,
            &tile_sweep_layout,
            &shaders::DP_TILE_SWEEP_ACCUMULATE,
        );
        let visible = compute_pipeline(device, &layout, &shaders::DP_VISIBLE);
        let sweep = compute_pipeline(device, &layout, &shaders::DP_SWEEP);
        let sites = compute_pipeline(device, &tile_layout, &shaders::DP_SITES);
        let points = compute_pipeline(device, &tile_layout, &shaders::DP_POINTS);
        let points_sweep = compute_pipeline(device, &tile_layout, &shaders::DP_POINTS_SWEEP);
        let tile_cost = compute_pipeline(device, &tile_layout, &shaders::DP_TILE_COST);
        let tile_fraction = compute_pipeline(device, &tile_layout, &shaders::DP_TILE_FRACTION);
        DpPipelines {
            layout,
            visible,
            sweep,
            sites,
            points,
            points_sweep,
            tile_layout,
            tile_cost,
            tile_fraction,
            tile_sweep_layout,
            tile_sweep_cost,
            tile_sweep_accumulate,
        }
    }
}

/// A [`MarchGrid`] and its [`DpMip`] resident on the GPU, uploaded once and reused by every map
/// and every epoch.
pub struct GpuDpGrid {
    grid: GpuGrid,
    mip: wgpu::Buffer,
    levels: wgpu::Buffer,
}

impl GpuDpGrid {
    /// Uploads `grid` and `mip` (from [`DpMip::build`] of the same grid). Fails when a buffer
    /// exceeds the device's storage binding limit or the grid is too wide for one dispatch row.
    pub fn upload(ctx: &GpuContext, grid: &MarchGrid, mip: &DpMip) -> Result<Self, GpuError> {
        let max_binding = ctx.max_storage_binding_bytes();
        let biggest = (grid.heights_m.len().max(mip.texels.len()) as u64) * 4;
        if biggest > max_binding {
            return Err(GpuError::InvalidInput {
                kernel: "dp_visible",
                message: format!(
                    "the height field or its mipmap ({biggest} B) exceeds the adapter's storage \
                     binding limit ({max_binding} B); use the 2-D tiled kernels of gpu::tiles (docs/gpu.md, \
                     \"Large grids\")"
                ),
            });
        }
        check_dispatch_cols(ctx, grid.cols, "dp_visible")?;
        let scope = ErrorScope::push(&ctx.device);
        let on_gpu = GpuDpGrid {
            grid: GpuGrid::new(ctx, grid),
            mip: storage_init(ctx, "penumbra dp mipmap", &mip.texels),
            levels: storage_init(ctx, "penumbra dp mipmap levels", &mip.levels),
        };
        scope.pop("uploading the height field and its maximum mipmap")?;
        Ok(on_gpu)
    }

    /// The bind group of this grid for `layout`: the [`DpBindings`] with `lights`, `slots`, `out`
    /// and the kernel's `extra` buffers.
    fn bind_group(
        &self,
        ctx: &GpuContext,
        layout: &wgpu::BindGroupLayout,
        (lights, slots, out): (&wgpu::Buffer, &wgpu::Buffer, &wgpu::Buffer),
        extra: &[&wgpu::Buffer],
    ) -> wgpu::BindGroup {
        DpBindings {
            params: &self.grid.params,
            heights: &self.grid.heights,
            mip: &self.mip,
            levels: &self.levels,
            lights,
            slots,
            out,
            extra,
        }
        .bind_group(ctx, "penumbra dp bind group", layout)
    }

    /// A [`DpStep`] over the whole grid as one source region ([`DpStep::whole`]).
    fn step(&self, light0: u32, count: u32, band: (u32, u32)) -> DpStep {
        DpStep::whole(self.grid.rows, self.grid.cols, light0, count, band)
    }
}

pub(crate) fn check_light(light: [f32; 4], kernel: &'static str) -> Result<(), GpuError> {
    let norm2 = light[0] * light[0] + light[1] * light[1] + light[2] * light[2];
    if !(light.iter().all(|c| c.is_finite())
        && (norm2 - 1.0).abs() < 1e-3
        && (0.0..1.5).contains(&light[3]))
    {
        return Err(GpuError::InvalidInput {
            kernel,
            message: format!(
                "light {light:?} is not a unit direction with an angular radius in [0, 1.5) rad"
            ),
        });
    }
    Ok(())
}

/// GPU `dp_visible`: per cell (row-major) the visible fraction of the disc `light` (from
/// [`crate::twins::disc_light_to_f32`]; radius 0: 1 lit / 0 shadow), -1 for nodata,
/// computed in row bands of at most `band_bytes` of output (use [`DEFAULT_BAND_BYTES`]).
pub fn dp_visible_gpu(
    ctx: &GpuContext,
    grid: &GpuDpGrid,
    light: [f32; 4],
    band_bytes: u64,
) -> Result<Vec<f32>, GpuError> {
    let dp = ctx.pipelines::<DpPipelines>()?;
    check_light(light, "dp_visible")?;
    let (rows, cols) = (grid.grid.rows, grid.grid.cols);
    let band_rows = grid.grid.band_rows(ctx, 4, band_bytes);
    let scope = ErrorScope::push(&ctx.device);
    let lights = storage_init(ctx, "penumbra dp light", &[light]);
    let slots = ctx.slot_buffer(1);
    let out = ctx.output_buffer(
        "penumbra dp band",
        u64::from(band_rows) * u64::from(cols) * 4,
    );
    let bind_group = grid.bind_group(ctx, &dp.layout, (&lights, &slots, &out), &[]);
    let mut map: Vec<f32> = Vec::with_capacity(rows as usize * cols as usize);
    let mut row0 = 0;
    while row0 < rows {
        let band = band_rows.min(rows - row0);
        ctx.write_slots(&slots, &[grid.step(0, 1, (row0, band))]);
        let workgroups = [
            cols.div_ceil(WORKGROUP_SIZE_XY),
            band.div_ceil(WORKGROUP_SIZE_XY),
            1,
        ];
        ctx.dispatch("dp_visible", &dp.visible, &bind_group, &[0], workgroups);
        let bytes = ctx.read_back(&out, u64::from(band) * u64::from(cols) * 4, "a DP band")?;
        map.extend_from_slice(bytemuck::cast_slice(&bytes));
        row0 += band;
    }
    scope.pop("running dp_visible")?;
    Ok(map)
}

/// Checks point records (`[col, row, z − z_ref, min_s]`) for `kernel`: inside the lattice, with
/// a finite height and a finite, non-negative nearest distance, and fewer than 2^32; their number.
fn check_points(
    grid: &GpuDpGrid,
    points: &[[f32; 4]],
    kernel: &'static str,
) -> Result<u32, GpuError> {
    let (rows, cols) = (f64::from(grid.grid.rows - 1), f64::from(grid.grid.cols - 1));
    for o in points {
        let (col, row, z, min_s) = (f64::from(o[0]), f64::from(o[1]), o[2], o[3]);
        if !((0.0..=cols).contains(&col)
            && (0.0..=rows).contains(&row)
            && z.is_finite()
            && min_s.is_finite()
            && min_s >= 0.0)
        {
            return Err(GpuError::InvalidInput {
                kernel,
                message: format!(
                    "observer {o:?} is not inside the lattice (col, row) with a finite height and \
                     min distance"
                ),
            });
        }
    }
    u32::try_from(points.len()).map_err(|_| GpuError::InvalidInput {
        kernel,
        message: format!("{} points exceed 2^32", points.len()),
    })
}

/// Points per chunk of a points kernel: `budget_bytes` of `bytes_per_point` outputs, at least 1
/// and at most one dispatch.
fn points_per_chunk(ctx: &GpuContext, budget_bytes: u64, bytes_per_point: u64) -> u32 {
    let by_dispatch = u64::from(ctx.limits().max_compute_workgroups_per_dimension)
        * u64::from(POINTS_WORKGROUP_SIZE_X);
    (budget_bytes / bytes_per_point)
        .clamp(1, by_dispatch)
        .min(u64::from(u32::MAX)) as u32
}

/// GPU `dp_points`: per point record (`points[i]` from [`crate::twins::site_observer_to_f32`],
/// e.g. a DEM pixel's own observer) the visible fraction of the disc `light` (from
/// [`crate::twins::disc_light_to_f32`]; radius 0: 1 lit / 0 shadow), the observer's own
/// `min_s` cells left out; in chunks of at most `band_bytes` of output. Twin:
/// [`crate::twins::dp_points`].
pub fn dp_points_gpu(
    ctx: &GpuContext,
    grid: &GpuDpGrid,
    points: &[[f32; 4]],
    light: [f32; 4],
    band_bytes: u64,
) -> Result<Vec<f32>, GpuError> {
    let dp = ctx.pipelines::<DpPipelines>()?;
    check_light(light, "dp_points")?;
    let n = check_points(grid, points, "dp_points")?;
    if n == 0 {
        return Ok(Vec::new());
    }
    let chunk = points_per_chunk(ctx, band_bytes, 4);
    let scope = ErrorScope::push(&ctx.device);
    let lights = storage_init(ctx, "penumbra dp points light", &[light]);
    let obs = storage_init(ctx, "penumbra dp points", points);
    let slots = ctx.slot_buffer(1);
    let out = ctx.output_buffer("penumbra dp points out", u64::from(chunk.min(n)) * 4);
    let bind_group = grid.bind_group(ctx, &dp.tile_layout, (&lights, &slots, &out), &[&obs]);
    let mut values = Vec::with_capacity(points.len());
    let mut first = 0;
    while first < n {
        let count = chunk.min(n - first);
        ctx.write_slots(&slots, &[grid.step(0, 1, (first, count))]);
        let workgroups = [count.div_ceil(POINTS_WORKGROUP_SIZE_X), 1, 1];
        ctx.dispatch("dp_points", &dp.points, &bind_group, &[0], workgroups);
        let bytes = ctx.read_back(&out, u64::from(count) * 4, "DP fractions of points")?;
        values.extend_from_slice(bytemuck::cast_slice(&bytes));
        first += count;
    }
    scope.pop("running dp_points")?;
    Ok(values)
}

/// GPU soft epoch sweep from point records (`shaders/dp_points_sweep.wgsl`): the
/// [`DpCellStats`] of every point (as [`dp_sweep_gpu`] per cell) over the epochs of `lights`
/// (two discs per epoch, Sun then Earth, in time order). The table and the points are uploaded
/// once; each chunk of points (at most `options.band_bytes` of statistics) is read back after
/// its last epoch. Twin: [`crate::twins::dp_points_sweep`].
pub fn dp_points_sweep_gpu(
    ctx: &GpuContext,
    grid: &GpuDpGrid,
    points: &[[f32; 4]],
    lights: &[[f32; 4]],
    options: DpSweepOptions,
) -> Result<Vec<DpCellStats>, GpuError> {
    let dp = ctx.pipelines::<DpPipelines>()?;
    let epochs = check_sweep_table(
        lights,
        options.is_valid(),
        OPTIONS_NONZERO,
        "dp_points_sweep",
    )?;
    let n = check_points(grid, points, "dp_points_sweep")?;
    if n == 0 {
        return Ok(Vec::new());
    }
    let stats_bytes = size_of::<DpCellStats>() as u64;
    let chunk = points_per_chunk(ctx, options.band_bytes, stats_bytes).min(n);
    let scope = ErrorScope::push(&ctx.device);
    let table = storage_init(ctx, "penumbra dp points light table", lights);
    let obs = storage_init(ctx, "penumbra dp sweep points", points);
    let slots = ctx.slot_buffer(options.dispatches_per_submit);
    let stats = ctx.output_buffer(
        "penumbra dp points sweep stats",
        u64::from(chunk) * stats_bytes,
    );
    let bind_group = grid.bind_group(ctx, &dp.tile_layout, (&table, &slots, &stats), &[&obs]);
    let sweep = SoftSweep {
        grid,
        stats: &stats,
        slots: &slots,
        pipeline: &dp.points_sweep,
        bind_group: &bind_group,
        epochs,
        options,
    };
    let all = sweep.run(
        ctx,
        (n, chunk),
        |count| [count.div_ceil(POINTS_WORKGROUP_SIZE_X), 1, 1],
        u64::from,
        "DP sweep statistics of points",
    )?;
    scope.pop("running the DP epoch sweep of points")?;
    Ok(all)
}

/// Options of [`dp_sweep_gpu`].
#[derive(Debug, Clone, Copy)]
pub struct DpSweepOptions {
    /// Epochs one invocation loops over per dispatch.
    pub epochs_per_dispatch: u32,
    /// Dispatches encoded per queue submit.
    pub dispatches_per_submit: u32,
    /// Bytes of statistics (32 B per cell) per row band.
    pub band_bytes: u64,
}

impl Default for DpSweepOptions {
    fn default() -> Self {
        DpSweepOptions {
            epochs_per_dispatch: DEFAULT_EPOCHS_PER_DISPATCH,
            dispatches_per_submit: DEFAULT_DISPATCHES_PER_SUBMIT,
            band_bytes: DEFAULT_BAND_BYTES,
        }
    }
}

impl DpSweepOptions {
    /// Whether the epochs per dispatch and the dispatches per submit are non-zero.
    fn is_valid(&self) -> bool {
        self.epochs_per_dispatch > 0 && self.dispatches_per_submit > 0
    }
}

/// What [`check_sweep_table`] says of invalid [`DpSweepOptions`].
const OPTIONS_NONZERO: &str = "non-zero epochs per dispatch / dispatches per submit";

/// GPU soft epoch sweep: the [`DpCellStats`] of every cell (row-major) over the epochs of
/// `lights` (two discs per epoch, Sun then Earth, from
/// [`crate::twins::disc_light_to_f32`], in time order). The table is uploaded once;
/// nothing is read back until a band's last epoch. Twin:
/// [`crate::twins::dp_sweep`].
pub fn dp_sweep_gpu(
    ctx: &GpuContext,
    grid: &GpuDpGrid,
    lights: &[[f32; 4]],
    options: DpSweepOptions,
) -> Result<Vec<DpCellStats>, GpuError> {
    let dp = ctx.pipelines::<DpPipelines>()?;
    let epochs = check_sweep_table(lights, options.is_valid(), OPTIONS_NONZERO, "dp_sweep")?;
    let (rows, cols) = (grid.grid.rows, grid.grid.cols);
    let stats_bytes = size_of::<DpCellStats>() as u64;
    let band_rows = grid.grid.band_rows(ctx, stats_bytes, options.band_bytes);
    let scope = ErrorScope::push(&ctx.device);
    // Uploaded once for the whole sweep.
    let table = storage_init(ctx, "penumbra dp light table", lights);
    let slots = ctx.slot_buffer(options.dispatches_per_submit);
    let band_cells = u64::from(band_rows) * u64::from(cols);
    let stats = ctx.output_buffer("penumbra dp sweep stats", band_cells * stats_bytes);
    let bind_group = grid.bind_group(ctx, &dp.layout, (&table, &slots, &stats), &[]);
    let sweep = SoftSweep {
        grid,
        stats: &stats,
        slots: &slots,
        pipeline: &dp.sweep,
        bind_group: &bind_group,
        epochs,
        options,
    };
    let all = sweep.run(
        ctx,
        (rows, band_rows),
        |band| {
            [
                cols.div_ceil(WORKGROUP_SIZE_XY),
                band.div_ceil(WORKGROUP_SIZE_XY),
                1,
            ]
        },
        |band| u64::from(band) * u64::from(cols),
        "DP sweep statistics",
    )?;
    scope.pop("running the DP epoch sweep")?;
    Ok(all)
}

/// Checks the light table of a soft sweep (Sun and Earth discs for at least one epoch, each a
/// valid disc) and that the run's options are valid (`options_valid`, else the error says
/// "and `nonzero`"); the number of epochs.
pub(crate) fn check_sweep_table(
    lights: &[[f32; 4]],
    options_valid: bool,
    nonzero: &str,
    kernel: &'static str,
) -> Result<u32, GpuError> {
    if lights.is_empty() || !lights.len().is_multiple_of(2) || !options_valid {
        return Err(GpuError::InvalidInput {
            kernel,
            message: format!(
                "the light table needs Sun and Earth discs for at least one epoch (and {nonzero})"
            ),
        });
    }
    for &l in lights {
        check_light(l, kernel)?;
    }
    u32::try_from(lights.len() / 2).map_err(|_| GpuError::InvalidInput {
        kernel,
        message: format!("{} epochs exceed 2^32", lights.len() / 2),
    })
}

/// One soft sweep: the grid, the statistics buffer the epochs fold into, the step slots, the
/// kernel's pipeline and bind group, and the epochs with their batching.
struct SoftSweep<'a> {
    grid: &'a GpuDpGrid,
    stats: &'a wgpu::Buffer,
    slots: &'a wgpu::Buffer,
    pipeline: &'a wgpu::ComputePipeline,
    bind_group: &'a wgpu::BindGroup,
    epochs: u32,
    options: DpSweepOptions,
}

impl SoftSweep<'_> {
    /// The statistics of `total` items (rows of the grid, or points), `chunk` items at a time:
    /// per chunk of `count` items the statistics are cleared, every epoch is folded in
    /// (dispatches of `workgroups(count)`) and the `cells(count)` statistics are read back.
    fn run(
        &self,
        ctx: &GpuContext,
        (total, chunk): (u32, u32),
        workgroups: impl Fn(u32) -> [u32; 3],
        cells: impl Fn(u32) -> u64,
        what: &'static str,
    ) -> Result<Vec<DpCellStats>, GpuError> {
        let stats_bytes = size_of::<DpCellStats>() as u64;
        let mut all = Vec::with_capacity(cells(total) as usize);
        let mut first = 0;
        while first < total {
            let count = chunk.min(total - first);
            self.fold_epochs(ctx, (first, count), workgroups(count));
            let bytes = ctx.read_back(self.stats, cells(count) * stats_bytes, what)?;
            all.extend_from_slice(bytemuck::cast_slice(&bytes));
            first += count;
        }
        Ok(all)
    }

    /// Clears the statistics, then folds all epochs in for the items `band`, in dispatches of
    /// `options.epochs_per_dispatch` epochs submitted `options.dispatches_per_submit` at a time;
    /// nothing is read back.
    fn fold_epochs(&self, ctx: &GpuContext, band: (u32, u32), [x, y, z]: [u32; 3]) {
        let (epochs, options) = (self.epochs, self.options);
        let per_submit = options.dispatches_per_submit as usize;
        ctx.clear("penumbra dp sweep clear", self.stats);
        let mut first = 0_u32;
        while first < epochs {
            let mut steps = Vec::with_capacity(per_submit);
            while first < epochs && steps.len() < per_submit {
                let count = options.epochs_per_dispatch.min(epochs - first);
                steps.push(self.grid.step(first, count, band));
                first += count;
            }
            ctx.write_slots(self.slots, &steps);
            ctx.compute_pass("penumbra dp sweep batch", |pass| {
                pass.set_pipeline(self.pipeline);
                for j in 0..steps.len() {
                    pass.set_bind_group(0, self.bind_group, &[slot_offset(j)]);
                    pass.dispatch_workgroups(x, y, z);
                }
            });
            // Reclaim finished submissions without waiting, so staging memory stays bounded.
            ctx.device.poll(wgpu::PollType::Poll).ok();
        }
    }
}

/// GPU `dp_sites`: for every site `i` (`observers[i]` from
/// [`crate::twins::site_observer_to_f32`]) and each of its `lights.len() /
/// observers.len()` discs (`lights[i * per_site + k]`, from
/// [`crate::twins::disc_light_to_f32`]; a negative radius asks for the uncapped
/// horizon), the tangent of the terrain horizon's elevation along the disc's azimuth, indexed like
/// `lights` ([`crate::twins::NO_HORIZON_TAN`] when no terrain lies along the ray).
/// One upload of the table, one dispatch per (site chunk, entry chunk) of at most the dispatch
/// limit, one read-back. Callers bound the table (the series engine batches its epochs). Twin:
/// [`crate::twins::dp_sites`].
pub fn dp_sites_gpu(
    ctx: &GpuContext,
    grid: &GpuDpGrid,
    observers: &[[f32; 4]],
    lights: &[[f32; 4]],
) -> Result<Vec<f32>, GpuError> {
    let dp = ctx.pipelines::<DpPipelines>()?;
    let invalid = |message: String| GpuError::InvalidInput {
        kernel: "dp_sites",
        message,
    };
    if observers.is_empty() || lights.is_empty() || !lights.len().is_multiple_of(observers.len()) {
        return Err(invalid(format!(
            "{} discs for {} sites: the table needs the same number of discs (at least one) per site",
            lights.len(),
            observers.len()
        )));
    }
    check_points(grid, observers, "dp_sites")?;
    for &l in lights {
        let norm2 = l[0] * l[0] + l[1] * l[1] + l[2] * l[2];
        if !(l.iter().all(|c| c.is_finite()) && (norm2 - 1.0).abs() < 1e-3 && l[3] < 1.5) {
            return Err(invalid(format!(
                "light {l:?} is not a unit direction with an angular radius < 1.5 rad (or negative)"
            )));
        }
    }
    let per_site = u32::try_from(lights.len() / observers.len())
        .map_err(|_| invalid(format!("{} discs per site exceed 2^32", lights.len())))?;
    let n_sites = u32::try_from(observers.len())
        .map_err(|_| invalid(format!("{} sites exceed 2^32", observers.len())))?;
    let max_binding = ctx.max_storage_binding_bytes();
    let table_bytes = std::mem::size_of_val(lights) as u64;
    if table_bytes > max_binding {
        return Err(invalid(format!(
            "the disc table ({table_bytes} B) exceeds the adapter's storage binding limit \
             ({max_binding} B); pass fewer epochs per call"
        )));
    }
    let max_groups = ctx.limits().max_compute_workgroups_per_dimension;
    let entries_per_dispatch = max_groups.saturating_mul(SITES_WORKGROUP_SIZE_X);
    let mut steps = Vec::new();
    let mut site0 = 0;
    while site0 < n_sites {
        let sites = max_groups.min(n_sites - site0);
        let mut k0 = 0;
        while k0 < per_site {
            let count = entries_per_dispatch.min(per_site - k0);
            steps.push((
                // The whole grid is the one source region; band = the sites of this dispatch.
                grid.step(k0, per_site, (site0, sites)),
                count.div_ceil(SITES_WORKGROUP_SIZE_X),
            ));
            k0 += count;
        }
        site0 += sites;
    }
    let out_bytes = lights.len() as u64 * 4;
    let scope = ErrorScope::push(&ctx.device);
    let table = storage_init(ctx, "penumbra dp sites lights", lights);
    let obs = storage_init(ctx, "penumbra dp sites observers", observers);
    let out = ctx.output_buffer("penumbra dp sites out", out_bytes);
    let slots = ctx.slot_buffer(steps.len() as u32);
    let step_values: Vec<DpStep> = steps.iter().map(|s| s.0).collect();
    ctx.write_slots(&slots, &step_values);
    let bind_group = grid.bind_group(ctx, &dp.tile_layout, (&table, &slots, &out), &[&obs]);
    ctx.compute_pass("dp_sites", |pass| {
        pass.set_pipeline(&dp.sites);
        for (j, (step, groups_x)) in steps.iter().enumerate() {
            pass.set_bind_group(0, &bind_group, &[slot_offset(j)]);
            pass.dispatch_workgroups(*groups_x, step.band_rows, 1);
        }
    });
    let bytes = ctx.read_back(&out, out_bytes, "per-site DP horizons")?;
    scope.pop("running dp_sites")?;
    Ok(bytemuck::pod_collect_to_vec(&bytes))
}
