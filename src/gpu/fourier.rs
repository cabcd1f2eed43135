//! Fourier-compressed horizon maps (paper 001) on the GPU: the build (`shaders/fourier_build.wgsl`,
//! [`build_horizon_map_gpu`]) and the evaluation of one light (`shaders/fourier_eval.wgsl`,
//! [`GpuHorizonMap`]). CPU twins and the shared data layout: [`crate::twins::fourier`]; the
//! CPU engine: [`crate::shadow::fourier`]. The result of the build is a [`HorizonMap`] identical
//! in layout to the CPU engine's (f16 coefficients, NaN for holes, same metadata).
//!
//! **Build.** One invocation per cell marches the cell's N azimuths and folds each sample into
//! the K DFT sums in registers (no N-sample intermediate buffer, no second pass; neighbouring
//! invocations march the same azimuth, so their rays stay coherent). Memory is bounded twice:
//! the output is produced in **row bands** of at most `band_bytes` (default
//! [`DEFAULT_BAND_BYTES`] = 64 MiB: 2K × 4 B = 128 B per cell at K = 16, so 524,288 cells per
//! band, 341 rows of a 1536-column grid), and each band's azimuths are split into dispatches of
//! `azimuths_per_dispatch` (default [`DEFAULT_AZIMUTHS_PER_DISPATCH`]) so that no single dispatch
//! runs long (watchdogs, lavapipe); the partial sums stay in the band buffer between dispatches.
//! The heights are a [`GpuGrid`] upload (4 B/cell, once).
//!
//! **Evaluation.** [`GpuHorizonMap::upload`] packs each complex coefficient's two f16 into one
//! u32 (the stored values, converted exactly by `unpack2x16float`) in row bands that each fit one
//! storage binding; [`GpuHorizonMap::visible_fraction`] runs one light (any number of times per
//! upload).

use wgpu::util::DeviceExt as _;

use super::GpuError;
use super::context::{
    DEFAULT_BAND_BYTES, ErrorScope, GpuContext, GpuGrid, KernelPipeline, WORKGROUP_SIZE_XY,
    band_rows, check_dispatch_cols, compute_pipeline, layout_entry, storage_init, whole,
};
use super::shaders;
use crate::shadow::ShadowError;
use crate::shadow::fourier::{HorizonMap, HorizonMapMeta, HorizonMapParams};
use crate::terrain::HeightField;
use crate::twins::fourier::{
    FourierBuildParams, FourierEvalParams, MAX_GPU_COEFFS, azimuth_table, build_dispatches,
    horizon_map_from_f32, pack_coeffs,
};
use crate::twins::{MarchGrid, MarchGridError, NODATA_FRACTION};

/// Azimuths per build dispatch by default: 16 azimuths of a 1536² grid are ~38 M rays, well
/// under a second on a data-centre GPU, and a 256² test grid stays a few seconds on lavapipe.
pub const DEFAULT_AZIMUTHS_PER_DISPATCH: u32 = 16;

/// Errors of the GPU horizon maps.
#[derive(Debug, thiserror::Error)]
pub enum GpuFourierError {
    /// A build parameter, the light or the disc radius is invalid (as on the CPU).
    #[error(transparent)]
    Shadow(#[from] ShadowError),
    /// The height field cannot be marched (too small, too large, bad observer height).
    #[error(transparent)]
    Grid(#[from] MarchGridError),
    /// The GPU failed (device, validation, readback, limits).
    #[error(transparent)]
    Gpu(#[from] GpuError),
}

/// Bind group layout and pipeline of the Fourier build (bindings 0 and 1 of shared/march.wgsl,
/// then 4..6).
pub(crate) struct FourierBuildPipeline {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl super::context::Pipelines for FourierBuildPipeline {
    const WHAT: &'static str = "building the Fourier pipelines";

    fn build(device: &wgpu::Device) -> Self {
        use wgpu::BufferBindingType::{Storage, Uniform};
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("penumbra fourier_build layout"),
            entries: &[
                layout_entry(0, Uniform),
                layout_entry(1, Storage { read_only: true }),
                layout_entry(4, Storage { read_only: true }),
                layout_entry(5, Uniform),
                layout_entry(6, Storage { read_only: false }),
            ],
        });
        let pipeline = compute_pipeline(device, &layout, &shaders::FOURIER_BUILD);
        FourierBuildPipeline { layout, pipeline }
    }
}

single_kernel! {
    /// The Fourier evaluation: params; packed coefficients; output.
    FourierEvalKernel = FOURIER_EVAL, 1, 1, "building the Fourier pipelines"
}

/// How the GPU build splits its work (the result does not depend on it, bit for bit).
#[derive(Debug, Clone, Copy)]
pub struct GpuBuildOptions {
    /// Output bytes per row band (2K × 4 B per cell).
    pub band_bytes: u64,
    /// Azimuths per dispatch.
    pub azimuths_per_dispatch: u32,
}

impl Default for GpuBuildOptions {
    fn default() -> Self {
        GpuBuildOptions {
            band_bytes: DEFAULT_BAND_BYTES,
            azimuths_per_dispatch: DEFAULT_AZIMUTHS_PER_DISPATCH,
        }
    }
}

/// Builds the horizon map of `hf` on the GPU with the default [`GpuBuildOptions`]: the same
/// map as [`HorizonMap::build_with`] (layout, metadata, f16 storage) within the bounds measured in
/// docs/gpu.md.
pub fn build_horizon_map_gpu(
    ctx: &GpuContext,
    hf: &HeightField,
    params: &HorizonMapParams,
) -> Result<HorizonMap, GpuFourierError> {
    build_horizon_map_gpu_with(ctx, hf, params, &GpuBuildOptions::default())
}

/// [`build_horizon_map_gpu`] with explicit band and dispatch sizes.
pub fn build_horizon_map_gpu_with(
    ctx: &GpuContext,
    hf: &HeightField,
    params: &HorizonMapParams,
    opts: &GpuBuildOptions,
) -> Result<HorizonMap, GpuFourierError> {
    let fourier = ctx.pipelines::<FourierBuildPipeline>()?;
    params.check()?;
    if params.n_coeffs > MAX_GPU_COEFFS {
        return Err(ShadowError::InvalidParameter {
            name: "n_coeffs",
            reason: "the GPU build keeps at most 32 coefficients",
        }
        .into());
    }
    if params.n_azimuths > u32::MAX as usize / 2 {
        return Err(ShadowError::InvalidParameter {
            name: "n_azimuths",
            reason: "too many azimuths for the GPU build",
        }
        .into());
    }
    let march = MarchGrid::from_height_field(hf, params.observer_height_m)?;
    let grid = GpuGrid::upload(ctx, &march, "fourier_build")?;
    let per = 2 * params.n_coeffs as u64;
    let cols = u64::from(march.cols);
    let band_rows = grid.band_rows(ctx, per * 4, opts.band_bytes);
    let dispatches = build_dispatches(
        march.rows,
        params.n_azimuths as u32,
        params.n_coeffs as u32,
        params.max_distance_cells,
        band_rows,
        opts.azimuths_per_dispatch,
    );
    let scope = ErrorScope::push(&ctx.device);
    let sincos = storage_init(
        ctx,
        "penumbra fourier sincos",
        &azimuth_table(params.n_azimuths),
    );
    let fb_buf = ctx.uniform_buffer(
        "penumbra fourier_build params",
        size_of::<FourierBuildParams>() as u64,
    );
    let out = ctx.output_buffer(
        "penumbra fourier_build band",
        u64::from(band_rows) * cols * per * 4,
    );
    let bind_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("penumbra fourier_build bind group"),
        layout: &fourier.layout,
        entries: &[
            whole(0, &grid.params),
            whole(1, &grid.heights),
            whole(4, &sincos),
            whole(5, &fb_buf),
            whole(6, &out),
        ],
    });
    let mut values: Vec<f32> = Vec::with_capacity(march.cells() * per as usize);
    for fb in &dispatches {
        // write_buffer is ordered before the next submit: one uniform serves every dispatch.
        ctx.queue.write_buffer(&fb_buf, 0, bytemuck::bytes_of(fb));
        ctx.dispatch(
            "fourier_build",
            &fourier.pipeline,
            &bind_group,
            &[],
            [
                march.cols.div_ceil(WORKGROUP_SIZE_XY),
                fb.band_rows.div_ceil(WORKGROUP_SIZE_XY),
                1,
            ],
        );
        if fb.last == 1 {
            let bytes = ctx.read_back(
                &out,
                u64::from(fb.band_rows) * cols * per * 4,
                "a horizon-map band",
            )?;
            values.extend_from_slice(bytemuck::cast_slice(&bytes));
        }
    }
    scope.pop("running fourier_build")?;
    Ok(horizon_map_from_f32(
        HorizonMapMeta::for_height_field(hf, params),
        &values,
    ))
}

/// A horizon map's coefficients resident on the GPU (packed f16 pairs, in row bands), ready to
/// evaluate any number of lights.
pub struct GpuHorizonMap {
    meta: HorizonMapMeta,
    rows: u32,
    cols: u32,
    /// (first row, rows, packed coefficients) per band.
    bands: Vec<(u32, u32, wgpu::Buffer)>,
    params: wgpu::Buffer,
    out: wgpu::Buffer,
    bind_groups: Vec<wgpu::BindGroup>,
}

impl GpuHorizonMap {
    /// The metadata of the uploaded map.
    pub fn meta(&self) -> &HorizonMapMeta {
        &self.meta
    }

    /// Uploads `map` in row bands of at most `band_bytes` of coefficients (4 B per complex
    /// coefficient; use [`DEFAULT_BAND_BYTES`]).
    pub fn upload(
        ctx: &GpuContext,
        map: &HorizonMap,
        band_bytes: u64,
    ) -> Result<Self, GpuFourierError> {
        let eval = ctx.pipelines::<KernelPipeline<FourierEvalKernel>>()?;
        let (rows, cols, nk) = (map.meta.rows, map.meta.cols, map.meta.n_coeffs);
        if rows == 0 || cols == 0 || nk == 0 || map.coeffs.len() != rows * cols * 2 * nk {
            return Err(GpuError::InvalidInput {
                kernel: "fourier_eval",
                message: format!(
                    "the map is {rows} x {cols} cells with {nk} coefficients and {} values",
                    map.coeffs.len()
                ),
            }
            .into());
        }
        let (rows, cols) = (rows as u32, cols as u32);
        check_dispatch_cols(ctx, cols, "fourier_eval")?;
        let packed = pack_coeffs(map);
        let band_rows = band_rows(ctx, rows, cols, 4 * nk as u64, band_bytes);
        let scope = ErrorScope::push(&ctx.device);
        let params = ctx.uniform_buffer(
            "penumbra fourier_eval params",
            size_of::<FourierEvalParams>() as u64,
        );
        let out = ctx.output_buffer(
            "penumbra fourier_eval band",
            u64::from(band_rows) * u64::from(cols) * 4,
        );
        let mut bands = Vec::new();
        let mut row0 = 0;
        while row0 < rows {
            let n = band_rows.min(rows - row0);
            let (a, b) = (
                row0 as usize * cols as usize * nk,
                (row0 + n) as usize * cols as usize * nk,
            );
            let buf = ctx
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("penumbra fourier coefficients"),
                    contents: bytemuck::cast_slice(&packed[a..b]),
                    usage: wgpu::BufferUsages::STORAGE,
                });
            bands.push((row0, n, buf));
            row0 += n;
        }
        let bind_groups = bands
            .iter()
            .map(|(_, _, buf)| eval.bind(ctx, &[&params, buf, &out]))
            .collect();
        scope.pop("uploading the horizon map")?;
        Ok(GpuHorizonMap {
            meta: map.meta.clone(),
            rows,
            cols,
            bands,
            params,
            out,
            bind_groups,
        })
    }

    /// Per cell (row-major) the visible fraction of a uniform disc of angular radius
    /// `angular_radius_rad` centred on `light_in_model` (paper 001 eqs. 6–7), or with radius 0
    /// the hard test as 1 / 0; [`NODATA_FRACTION`] (−1) for holes. The GPU twin of
    /// [`crate::shadow::fourier::visible_fraction`].
    pub fn visible_fraction(
        &self,
        ctx: &GpuContext,
        light_in_model: [f64; 3],
        angular_radius_rad: f64,
    ) -> Result<Vec<f32>, GpuFourierError> {
        let eval = ctx.pipelines::<KernelPipeline<FourierEvalKernel>>()?;
        let base = FourierEvalParams::new(&self.meta, light_in_model, angular_radius_rad)?;
        let scope = ErrorScope::push(&ctx.device);
        let mut values: Vec<f32> = Vec::with_capacity(self.rows as usize * self.cols as usize);
        for ((row0, rows, _), bind_group) in self.bands.iter().zip(&self.bind_groups) {
            let fe = FourierEvalParams {
                band_row0: *row0,
                band_rows: *rows,
                ..base
            };
            ctx.queue
                .write_buffer(&self.params, 0, bytemuck::bytes_of(&fe));
            ctx.dispatch(
                "fourier_eval",
                &eval.pipeline,
                bind_group,
                &[],
                [
                    self.cols.div_ceil(WORKGROUP_SIZE_XY),
                    rows.div_ceil(WORKGROUP_SIZE_XY),
                    1,
                ],
            );
            let bytes = ctx.read_back(
                &self.out,
                u64::from(*rows) * u64::from(self.cols) * 4,
                "a horizon-map evaluation band",
            )?;
            values.extend_from_slice(bytemuck::cast_slice(&bytes));
        }
        scope.pop("running fourier_eval")?;
        Ok(values)
    }

    /// The hard mask of the light's centre: 1 lit, 0 shadow, 255 nodata (the GPU twin of
    /// [`crate::shadow::fourier::hard_mask`]).
    pub fn hard_mask(
        &self,
        ctx: &GpuContext,
        light_in_model: [f64; 3],
    ) -> Result<Vec<u8>, GpuFourierError> {
        Ok(self
            .visible_fraction(ctx, light_in_model, 0.0)?
            .into_iter()
            .map(|f| {
                if f <= NODATA_FRACTION + 0.5 {
                    crate::shadow::MASK_NODATA
                } else if f > 0.5 {
                    crate::shadow::MASK_LIT
                } else {
                    crate::shadow::MASK_SHADOW
                }
            })
            .collect())
    }
}
