//! GPU runner of `shaders/horizon_stats.wgsl`: the horizons engine's per-cell epoch loop, one
//! invocation per cell, epochs in batches of [`EPOCHS_PER_BATCH`] with the statistics resident
//! on the GPU between them (the algorithm and the f32 twin: [`crate::twins::horizon_stats`]).
//!
//! [`GpuHorizonStats`] is a [`CellKernel`]: [`CellKernel::begin`] uploads the epochs and the
//! tables once per run; [`CellKernel::run`] uploads a block's cells and horizons (in chunks that
//! fit one storage binding), runs every batch of epochs and reads the statistics back once.

use std::sync::Arc;

use super::GpuError;
use super::context::{ErrorScope, GpuContext, KernelPipeline, storage_init};
use crate::horizon::HorizonError;
use crate::horizon::statistics::{CellKernel, KernelAcc, KernelCell, KernelShared};
use crate::twins::horizon_stats::{
    EPOCHS_PER_BATCH, HorizonStatsParams, WORKGROUP_SIZE, packed_tables,
};

/// What a run shares, resident on the GPU.
struct Resident {
    shared: Arc<KernelShared>,
    epochs: wgpu::Buffer,
    tables: wgpu::Buffer,
    index: wgpu::Buffer,
}

single_kernel! {
    /// The statistics kernel: params; cells, horizons, epochs, tables, azimuth index; the
    /// statistics.
    HorizonStatsKernel = HORIZON_STATS, 5, 1, "building the horizon_stats pipeline"
}

/// The statistics kernel on a GPU.
pub struct GpuHorizonStats<'a> {
    ctx: &'a GpuContext,
    kernel: Arc<KernelPipeline<HorizonStatsKernel>>,
    params_buf: wgpu::Buffer,
    resident: Option<Resident>,
}

impl From<GpuError> for HorizonError {
    fn from(e: GpuError) -> Self {
        HorizonError::Kernel(e.to_string())
    }
}

impl<'a> GpuHorizonStats<'a> {
    /// The kernel on `ctx` (its pipeline built on first use).
    pub fn new(ctx: &'a GpuContext) -> Result<Self, GpuError> {
        let kernel = ctx.pipelines::<KernelPipeline<HorizonStatsKernel>>()?;
        let scope = ErrorScope::push(&ctx.device);
        let params_buf = ctx.uniform_buffer(
            "penumbra horizon_stats params",
            size_of::<HorizonStatsParams>() as u64,
        );
        scope.pop("creating the horizon_stats params")?;
        Ok(GpuHorizonStats {
            ctx,
            kernel,
            params_buf,
            resident: None,
        })
    }

    /// Every batch of epochs for `cells` (fits one binding and one dispatch's grid).
    fn run_chunk(
        &self,
        r: &Resident,
        cells: &[KernelCell],
        horizons: &[f32],
    ) -> Result<Vec<KernelAcc>, GpuError> {
        let ctx = self.ctx;
        let scope = ErrorScope::push(&ctx.device);
        let cells_buf = storage_init(ctx, "penumbra horizon_stats cells", cells);
        let horizons_buf = storage_init(ctx, "penumbra horizon_stats horizons", horizons);
        let acc_bytes = (cells.len() * size_of::<KernelAcc>()) as u64;
        // wgpu zero-initialises new buffers: the statistics start empty.
        let acc = ctx.output_buffer("penumbra horizon_stats acc", acc_bytes);
        let bind_group = self.kernel.bind(
            ctx,
            &[
                &self.params_buf,
                &cells_buf,
                &horizons_buf,
                &r.epochs,
                &r.tables,
                &r.index,
                &acc,
            ],
        );
        let groups = (cells.len() as u32).div_ceil(WORKGROUP_SIZE);
        let groups_x = groups.min(ctx.limits().max_compute_workgroups_per_dimension);
        let groups_y = groups.div_ceil(groups_x);
        let n = r.shared.epochs.len();
        for begin in (0..n).step_by(EPOCHS_PER_BATCH) {
            let params = HorizonStatsParams {
                groups_x,
                ..HorizonStatsParams::new(
                    &r.shared,
                    cells.len(),
                    begin,
                    (begin + EPOCHS_PER_BATCH).min(n),
                )
            };
            ctx.queue
                .write_buffer(&self.params_buf, 0, bytemuck::bytes_of(&params));
            ctx.dispatch(
                "horizon_stats",
                &self.kernel.pipeline,
                &bind_group,
                &[],
                [groups_x, groups_y, 1],
            );
        }
        let bytes = ctx.read_back(&acc, acc_bytes, "the horizon statistics")?;
        scope.pop("running horizon_stats")?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }
}

impl CellKernel for GpuHorizonStats<'_> {
    fn begin(&mut self, shared: Arc<KernelShared>) -> Result<(), HorizonError> {
        let scope = ErrorScope::push(&self.ctx.device);
        // A run without epochs still binds a non-empty buffer.
        let epochs: &[u8] = if shared.epochs.is_empty() {
            &[0; 48]
        } else {
            bytemuck::cast_slice(&shared.epochs)
        };
        let max = self.ctx.max_storage_binding_bytes();
        if epochs.len() as u64 > max {
            return Err(HorizonError::Kernel(format!(
                "{} epochs exceed the GPU's storage binding limit ({max} B)",
                shared.epochs.len()
            )));
        }
        self.resident = Some(Resident {
            epochs: storage_init(self.ctx, "penumbra horizon_stats epochs", epochs),
            tables: storage_init(
                self.ctx,
                "penumbra horizon_stats tables",
                &packed_tables(&shared),
            ),
            index: storage_init(self.ctx, "penumbra horizon_stats index", &shared.index),
            shared,
        });
        scope.pop("uploading the horizon_stats epochs")?;
        Ok(())
    }

    fn run(
        &mut self,
        cells: &[KernelCell],
        horizons: &[f32],
    ) -> Result<Vec<KernelAcc>, HorizonError> {
        let r = self
            .resident
            .as_ref()
            .ok_or_else(|| HorizonError::Kernel("horizon_stats ran before begin".into()))?;
        let stride = r.shared.n_bands() + 1;
        // Cells per chunk: their horizons within one binding, their groups within a 2-D grid.
        let max_binding = self.ctx.max_storage_binding_bytes() as usize;
        let per_chunk = (max_binding / (4 * stride))
            .min(max_binding / size_of::<KernelAcc>())
            .clamp(1, 1 << 24);
        let mut out = Vec::with_capacity(cells.len());
        for (c, h) in cells
            .chunks(per_chunk)
            .zip(horizons.chunks(per_chunk * stride))
        {
            out.extend(self.run_chunk(r, c, h)?);
        }
        Ok(out)
    }

    fn name(&self) -> String {
        format!("horizon_stats.wgsl on {}", self.ctx.adapter_name())
    }
}
