//! GPU runner of `shaders/line_sweep.wgsl`: the looks of the whole-grid line sweep, one
//! invocation per (line, look), on lines the CPU builds and packs (the data layout, the
//! precision budget and the CPU twin are in [`crate::twins::line_sweep`]).
//!
//! [`GpuLineSweep::new`] builds the pipeline and uploads the finest layer once;
//! [`GpuLineSweep::run_batch`] runs one [`LineBatch`] (one submit) and reads the `(tan el, Δψ)`
//! pairs back; [`sweep_gpu`] is a whole sweep, bands handed out as
//! [`HorizonSweep::run`] does.

use super::GpuError;
use std::sync::Arc;

use super::context::{ErrorScope, GpuContext, KernelPipeline, storage_init};
use crate::horizon::{HorizonSweep, SweepBand};
use crate::twins::line_sweep::{
    LineBatch, LineSweepParams, SweepGrid, WORKGROUP_SIZE, sweep_batched,
};

/// Largest batch, samples (the hull scratch is 32 B per sample: 256 MiB).
pub const MAX_BATCH_SAMPLES: usize = 1 << 23;

single_kernel! {
    /// The line sweep's looks: params; lines, samples, observers, heights; the hull scratch and
    /// the output.
    LineSweepKernel = LINE_SWEEP, 4, 2, "building the line_sweep pipeline"
}

/// The line-sweep pipeline and the finest layer resident on the GPU.
pub struct GpuLineSweep {
    kernel: Arc<KernelPipeline<LineSweepKernel>>,
    params: LineSweepParams,
    params_buf: wgpu::Buffer,
    heights: wgpu::Buffer,
    max_samples: usize,
}

impl GpuLineSweep {
    /// Builds the pipeline and uploads the layers of `grid` (the finest and the first coarser).
    /// Fails when they exceed the adapter's storage binding limit.
    pub fn new(ctx: &GpuContext, grid: &SweepGrid) -> Result<Self, GpuError> {
        let max_binding = ctx.max_storage_binding_bytes();
        let bytes = grid.heights_m.len() as u64 * 4;
        if bytes > max_binding {
            return Err(GpuError::InvalidInput {
                kernel: "line_sweep",
                message: format!(
                    "the finest and first coarser layers ({bytes} B) exceed the adapter's storage \
                     binding limit ({max_binding} B)"
                ),
            });
        }
        // The hull scratch (two looks × 16 B per sample) is the largest binding.
        let max_samples = usize::try_from(max_binding / 32)
            .unwrap_or(usize::MAX)
            .min(MAX_BATCH_SAMPLES);
        let kernel = ctx.pipelines::<KernelPipeline<LineSweepKernel>>()?;
        let scope = ErrorScope::push(&ctx.device);
        let params_buf = ctx.uniform_buffer(
            "penumbra line_sweep params",
            size_of::<LineSweepParams>() as u64,
        );
        let heights = storage_init(ctx, "penumbra line_sweep heights", &grid.heights_m);
        scope.pop("uploading the line_sweep heights")?;
        Ok(GpuLineSweep {
            kernel,
            params: grid.params,
            params_buf,
            heights,
            max_samples,
        })
    }

    /// The largest batch this device takes, samples.
    pub fn max_batch_samples(&self) -> usize {
        self.max_samples
    }

    /// `(tan el, Δψ)` for every observer and look of `batch`, `2 · observer + look` (as the twin
    /// [`crate::twins::line_sweep::line_sweep`]).
    pub fn run_batch(
        &self,
        ctx: &GpuContext,
        batch: &LineBatch,
    ) -> Result<Vec<[f32; 2]>, GpuError> {
        let n_out = 2 * batch.observers.len() as u64;
        if n_out == 0 {
            return Ok(Vec::new());
        }
        if batch.samples.len() > self.max_samples {
            return Err(GpuError::InvalidInput {
                kernel: "line_sweep",
                message: format!(
                    "a batch of {} samples exceeds the device's {}",
                    batch.samples.len(),
                    self.max_samples
                ),
            });
        }
        let groups = (2 * batch.lines.len() as u32).div_ceil(WORKGROUP_SIZE);
        let max_x = ctx.limits().max_compute_workgroups_per_dimension;
        let groups_x = groups.min(max_x);
        let groups_y = groups.div_ceil(groups_x);
        let params = LineSweepParams {
            n_lines: batch.lines.len() as u32,
            n_samples: batch.samples.len() as u32,
            groups_x,
            ..self.params
        };
        let scope = ErrorScope::push(&ctx.device);
        let lines = storage_init(ctx, "penumbra line_sweep lines", &batch.lines);
        let samples = storage_init(ctx, "penumbra line_sweep samples", &batch.samples);
        let observers = storage_init(ctx, "penumbra line_sweep observers", &batch.observers);
        let hull = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("penumbra line_sweep hull"),
            size: 2 * batch.samples.len() as u64 * 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let out = ctx.output_buffer("penumbra line_sweep out", n_out * 8);
        ctx.queue
            .write_buffer(&self.params_buf, 0, bytemuck::bytes_of(&params));
        let bind_group = self.kernel.bind(
            ctx,
            &[
                &self.params_buf,
                &lines,
                &samples,
                &observers,
                &self.heights,
                &hull,
                &out,
            ],
        );
        ctx.dispatch(
            "line_sweep",
            &self.kernel.pipeline,
            &bind_group,
            &[],
            [groups_x, groups_y, 1],
        );
        let bytes = ctx.read_back(&out, n_out * 8, "the line sweep's horizons")?;
        scope.pop("running line_sweep")?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }
}

/// The whole sweep with its looks on the GPU: lines built and packed on the CPU (rayon), looks
/// in batches on the GPU, bands handed to `sink` as [`HorizonSweep::run`] does. A sink error
/// converts into `E`, as do GPU errors.
pub fn sweep_gpu<E: From<GpuError>>(
    ctx: &GpuContext,
    sweep: &HorizonSweep,
    sink: impl FnMut(SweepBand<'_>) -> Result<(), E>,
    progress: impl FnMut(usize),
) -> Result<(), E> {
    let runner = GpuLineSweep::new(ctx, &SweepGrid::new(sweep))?;
    sweep_batched(
        sweep,
        runner.max_batch_samples(),
        |batch| runner.run_batch(ctx, batch).map_err(E::from),
        sink,
        progress,
    )
}
