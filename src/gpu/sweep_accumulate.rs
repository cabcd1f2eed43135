//! The GPU-resident epoch sweep: for every epoch, `shaders/shadow_march.wgsl` writes the hard
//! shadow of one row band into a scratch buffer and `shaders/sweep_accumulate.wgsl` folds it into
//! per-cell [`CellStats`] (lit-epoch count, current and longest dark run, ever lit).
//!
//! The light table (one f32 unit vector per epoch, reduced on the CPU) is uploaded once; per
//! submit only the `STEP_SLOT_BYTES`-strided epoch indices of that submit are written (256 B per
//! epoch); nothing is read back until a band's last epoch. Device and pipelines come from the
//! [`GpuContext`], built once. Bands are processed one after the other (all epochs of a band,
//! then its statistics are read back), so GPU memory is heights + table + 20 B per band cell.

use bytemuck::{Pod, Zeroable};

use super::GpuError;
use super::context::{
    ErrorScope, GpuContext, Slot, compute_pipeline, sized, slots_layout, storage_init, whole,
};
use super::shadow_march::{
    GpuMarchGrid, MarchPipelines, STEP_SLOT_BYTES, band_buffer, march_bind_group, step_slots,
    write_steps,
};
use crate::twins::CellStats;

/// Epochs encoded per queue submit by default: amortises the submit overhead (about 0.1 ms) while
/// keeping each submit short enough not to trip a display watchdog.
pub const DEFAULT_EPOCHS_PER_SUBMIT: u32 = 64;
/// Workgroup size of the accumulate kernel. Keep in sync with shaders/sweep_accumulate.wgsl.
const WORKGROUP_SIZE: u32 = 64;

const SWEEP_ACCUMULATE_WGSL: &str = wgsl!("sweep_accumulate.wgsl");

/// Mirrors of the WGSL structs.
mod gpu_data {
    use super::{Pod, Zeroable};

    /// Keep in sync with `CellStats` in shaders/sweep_accumulate.wgsl (same layout as the CPU
    /// twin's [`crate::twins::CellStats`], which readback casts to).
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub(super) struct CellStatsGpu {
        pub lit_epochs: u32,
        pub dark_run_epochs: u32,
        pub longest_dark_run_epochs: u32,
        pub ever_lit: u32,
    }
    const _: () = assert!(size_of::<CellStatsGpu>() == 16);
}
use gpu_data::CellStatsGpu;
const _: () = assert!(size_of::<CellStatsGpu>() == size_of::<CellStats>());

/// Bind group layout and pipeline of the accumulate kernel (built once, in [`GpuContext::new`]).
pub(crate) struct AccumulatePipeline {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl super::context::Pipelines for AccumulatePipeline {
    const WHAT: &'static str = "building the sweep-accumulate pipeline";

    fn build(device: &wgpu::Device) -> Self {
        let layout = slots_layout(
            device,
            "penumbra accumulate layout",
            &[Slot::Read, Slot::ReadWrite],
        );
        let pipeline = compute_pipeline(
            device,
            &layout,
            "sweep_accumulate",
            SWEEP_ACCUMULATE_WGSL,
            "sweep_accumulate",
        );
        AccumulatePipeline { layout, pipeline }
    }
}

/// Options of [`sweep_stats_gpu`].
#[derive(Debug, Clone, Copy)]
pub struct SweepOptions {
    /// Epochs encoded per queue submit.
    pub epochs_per_submit: u32,
    /// Bytes of 4-byte per-cell outputs per row band (the scratch shadow band; the statistics
    /// take 4 times as much).
    pub band_bytes: u64,
}

impl Default for SweepOptions {
    fn default() -> Self {
        SweepOptions {
            epochs_per_submit: DEFAULT_EPOCHS_PER_SUBMIT,
            band_bytes: super::shadow_march::DEFAULT_BAND_BYTES / 4,
        }
    }
}

/// Accumulate workgroups for `cells`: 1-D, folded into y beyond the per-dimension limit.
fn accumulate_workgroups(cells: u64, max_per_dim: u32) -> (u32, u32) {
    let groups = cells.div_ceil(u64::from(WORKGROUP_SIZE)).max(1);
    let gx = groups.min(u64::from(max_per_dim));
    (gx as u32, groups.div_ceil(gx) as u32)
}

/// GPU epoch sweep: the [`CellStats`] of every cell (row-major) over the epochs of `lights`
/// (one f32 model-space unit vector per epoch, in time order). Twin:
/// [`crate::twins::sweep_stats`].
pub fn sweep_stats_gpu(
    ctx: &GpuContext,
    grid: &GpuMarchGrid,
    lights: &[[f32; 4]],
    options: SweepOptions,
) -> Result<Vec<CellStats>, GpuError> {
    let march = ctx.pipelines::<MarchPipelines>()?;
    let accumulate = ctx.pipelines::<AccumulatePipeline>()?;
    if lights.is_empty() || options.epochs_per_submit == 0 {
        return Err(GpuError::InvalidInput {
            kernel: "sweep_accumulate",
            message: "no epochs (or zero epochs per submit)".into(),
        });
    }
    let epochs = u32::try_from(lights.len()).map_err(|_| GpuError::InvalidInput {
        kernel: "sweep_accumulate",
        message: format!("{} epochs exceed 2^32", lights.len()),
    })?;
    let band_rows = grid.band_rows(ctx, options.band_bytes);
    let cols = u64::from(grid.cols);
    let per_submit = options.epochs_per_submit;
    let scope = ErrorScope::push(&ctx.device);
    // Uploaded once for the whole sweep.
    let lights_buf = storage_init(ctx, "penumbra light table", bytemuck::cast_slice(lights));
    let slots = step_slots(ctx, per_submit);
    let band_cells = u64::from(band_rows) * cols;
    let scratch = band_buffer(
        ctx,
        "penumbra sweep scratch",
        band_cells,
        wgpu::BufferUsages::empty(),
    );
    let stats = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("penumbra sweep stats"),
        size: band_cells.max(1) * size_of::<CellStatsGpu>() as u64,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let march_bg = march_bind_group(ctx, &march.layout, grid, &lights_buf, &slots, &scratch);
    let mut all: Vec<CellStats> = Vec::with_capacity(grid.rows as usize * grid.cols as usize);
    let mut row0 = 0;
    while row0 < grid.rows {
        let rows = band_rows.min(grid.rows - row0);
        let cells = u64::from(rows) * cols;
        // The last band may be shorter: bind exactly its cells so arrayLength() is right.
        let accumulate_bg = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("penumbra accumulate bind group"),
            layout: &accumulate.layout,
            entries: &[sized(0, &scratch, cells * 4), whole(1, &stats)],
        });
        let (march_gx, march_gy) = grid.workgroups(rows);
        let (acc_gx, acc_gy) =
            accumulate_workgroups(cells, ctx.limits().max_compute_workgroups_per_dimension);
        let mut clear = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("penumbra sweep clear"),
            });
        clear.clear_buffer(&stats, 0, None);
        ctx.queue.submit([clear.finish()]);
        let mut first = 0_u32;
        while first < epochs {
            let count = per_submit.min(epochs - first);
            write_steps(ctx, &slots, (first..first + count).map(|e| (e, row0, rows)));
            let mut encoder = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("penumbra sweep batch"),
                });
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("penumbra sweep batch"),
                    timestamp_writes: None,
                });
                for j in 0..count {
                    pass.set_pipeline(&march.hard);
                    pass.set_bind_group(0, &march_bg, &[j * STEP_SLOT_BYTES as u32]);
                    pass.dispatch_workgroups(march_gx, march_gy, 1);
                    pass.set_pipeline(&accumulate.pipeline);
                    pass.set_bind_group(0, &accumulate_bg, &[]);
                    pass.dispatch_workgroups(acc_gx, acc_gy, 1);
                }
            }
            ctx.queue.submit([encoder.finish()]);
            // Reclaim finished submissions without waiting, so staging memory stays bounded.
            ctx.device.poll(wgpu::PollType::Poll).ok();
            first += count;
        }
        let bytes = ctx.read_back(
            &stats,
            cells * size_of::<CellStatsGpu>() as u64,
            "sweep statistics",
        )?;
        let band: &[CellStatsGpu] = bytemuck::cast_slice(&bytes);
        all.extend(band.iter().map(|s| CellStats {
            lit_epochs: s.lit_epochs,
            dark_run_epochs: s.dark_run_epochs,
            longest_dark_run_epochs: s.longest_dark_run_epochs,
            ever_lit: s.ever_lit,
        }));
        row0 += rows;
    }
    scope.pop("running the epoch sweep")?;
    Ok(all)
}
