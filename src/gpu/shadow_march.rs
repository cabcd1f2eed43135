//! GPU runners of `shaders/shadow_march.wgsl` (hard shadow) and `shaders/shadow_march_soft.wgsl`
//! (visible fraction of a disc of directions), with row-band tiling of the output.
//!
//! **Tiling (issue 7 item 4).** A ray may cross the whole grid (at 0.5° elevation it rises only
//! 8.7 m per km), so every band needs the whole height field: the heights are uploaded once into
//! one storage buffer (4 B/cell: 1.6 GB for 20,000², within an H100's 2-4 GiB storage binding
//! limit). What is tiled is everything per-cell beyond the heights: the output buffer and its
//! readback staging hold one *row band* of at most [`DEFAULT_BAND_BYTES`] (64 MiB: 4,194 rows of
//! 4,000 cells, 838 rows of 20,000) at a time, so GPU memory is heights + O(band), not
//! heights + O(grid) per output. The band also keeps each dispatch below the 65,535-workgroup
//! limit per dimension and a band's readback short enough to overlap nothing critical.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt as _;

use super::GpuError;
use super::context::{
    ErrorScope, GpuContext, buffer_layout_entry, compute_pipeline, layout_entry, sized,
    storage_init, whole,
};
use crate::twins::MarchGrid;

/// Output bytes per row band by default (64 MiB): small against any GPU, large enough that a
/// 4,096² map is one band.
pub const DEFAULT_BAND_BYTES: u64 = 64 << 20;
/// Workgroup size of the march kernels. Keep in sync with shaders/shadow_march*.wgsl.
const WORKGROUP_SIZE_XY: u32 = 8;
/// Stride of the dynamic-offset `StepParams` slots (the largest allowed
/// `min_uniform_buffer_offset_alignment`, so valid on every adapter).
pub(crate) const STEP_SLOT_BYTES: u64 = 256;

const SHADOW_MARCH_WGSL: &str = concat!(wgsl!("shared/march.wgsl"), wgsl!("shadow_march.wgsl"));
const SHADOW_MARCH_SOFT_WGSL: &str =
    concat!(wgsl!("shared/march.wgsl"), wgsl!("shadow_march_soft.wgsl"));

/// Mirrors of the WGSL structs.
pub(crate) mod gpu_data {
    use super::{Pod, Zeroable};

    /// Keep in sync with `GridParams` in shaders/shared/march.wgsl and `DpGridParams` in
    /// shaders/shared/dp.wgsl.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub(crate) struct GridParams {
        pub rows: u32,
        pub cols: u32,
        pub px_m: f32,
        pub observer_height_m: f32,
        pub x0_m: f32,
        pub y0_m: f32,
        pub z_max_m: f32,
        pub z_ref_plus_radius_m: f32,
    }
    const _: () = assert!(size_of::<GridParams>() == 32);

    impl GridParams {
        /// The uniform of `grid` (shared by the march and the DP kernels, whose WGSL structs
        /// `GridParams` and `DpGridParams` have this same layout).
        pub(crate) fn of(grid: &crate::twins::MarchGrid) -> Self {
            GridParams {
                rows: grid.rows,
                cols: grid.cols,
                px_m: grid.px_m,
                observer_height_m: grid.observer_height_m,
                x0_m: grid.x0_m,
                y0_m: grid.y0_m,
                z_max_m: grid.z_max_m,
                z_ref_plus_radius_m: grid.z_ref_plus_radius_m,
            }
        }
    }

    /// Keep in sync with `StepParams` in shaders/shared/march.wgsl.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub(crate) struct StepParams {
        pub light_index: u32,
        pub band_row0: u32,
        pub band_rows: u32,
        pub _pad: u32,
    }
    const _: () = assert!(size_of::<StepParams>() == 16);
}
use gpu_data::{GridParams, StepParams};

/// The bind group layout and pipelines of the two march kernels (built once, in
/// [`GpuContext::new`]).
pub(crate) struct MarchPipelines {
    pub(crate) layout: wgpu::BindGroupLayout,
    pub(crate) hard: wgpu::ComputePipeline,
    pub(crate) soft: wgpu::ComputePipeline,
}

impl super::context::Pipelines for MarchPipelines {
    const WHAT: &'static str = "building the shadow-march pipelines";

    fn build(device: &wgpu::Device) -> Self {
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("penumbra march layout"),
            entries: &[
                layout_entry(0, wgpu::BufferBindingType::Uniform),
                layout_entry(1, wgpu::BufferBindingType::Storage { read_only: true }),
                layout_entry(2, wgpu::BufferBindingType::Storage { read_only: true }),
                buffer_layout_entry(3, wgpu::BufferBindingType::Uniform, true),
                layout_entry(4, wgpu::BufferBindingType::Storage { read_only: false }),
            ],
        });
        let hard = compute_pipeline(
            device,
            &layout,
            "shadow_march",
            SHADOW_MARCH_WGSL,
            "shadow_march",
        );
        let soft = compute_pipeline(
            device,
            &layout,
            "shadow_march_soft",
            SHADOW_MARCH_SOFT_WGSL,
            "shadow_march_soft",
        );
        MarchPipelines { layout, hard, soft }
    }
}

/// A [`MarchGrid`] resident on the GPU: grid uniform + heights, uploaded once and reused by
/// every map and every epoch of a sweep.
pub struct GpuMarchGrid {
    pub(crate) params: wgpu::Buffer,
    pub(crate) heights: wgpu::Buffer,
    pub(crate) rows: u32,
    pub(crate) cols: u32,
}

impl GpuMarchGrid {
    /// Uploads `grid`. Fails when the heights exceed the device's storage binding limit or the
    /// grid is wider than one dispatch row allows.
    pub fn upload(ctx: &GpuContext, grid: &MarchGrid) -> Result<Self, GpuError> {
        let heights_bytes = grid.heights_m.len() as u64 * 4;
        let limits = ctx.limits();
        if heights_bytes
            > limits
                .max_storage_buffer_binding_size
                .min(limits.max_buffer_size)
        {
            return Err(GpuError::InvalidInput {
                kernel: "shadow_march",
                message: format!(
                    "the height field ({heights_bytes} B) exceeds the adapter's storage binding \
                     limit ({} B)",
                    limits.max_storage_buffer_binding_size
                ),
            });
        }
        check_dispatch_cols(ctx, grid.cols, "shadow_march")?;
        let scope = ErrorScope::push(&ctx.device);
        let params = grid_params_buffer(ctx, "penumbra grid params", grid);
        let heights = storage_init(
            ctx,
            "penumbra heights",
            bytemuck::cast_slice(&grid.heights_m),
        );
        scope.pop("uploading the height field")?;
        Ok(GpuMarchGrid {
            params,
            heights,
            rows: grid.rows,
            cols: grid.cols,
        })
    }

    /// Rows per band for `band_bytes` of 4-byte outputs per band (at least 1, at most the grid,
    /// and within the dispatch limit).
    pub fn band_rows(&self, ctx: &GpuContext, band_bytes: u64) -> u32 {
        let by_budget = (band_bytes / (u64::from(self.cols) * 4)).max(1);
        let by_dispatch = u64::from(ctx.limits().max_compute_workgroups_per_dimension)
            * u64::from(WORKGROUP_SIZE_XY);
        by_budget.min(by_dispatch).min(u64::from(self.rows)) as u32
    }

    pub(crate) fn workgroups(&self, band_rows: u32) -> (u32, u32) {
        (
            self.cols.div_ceil(WORKGROUP_SIZE_XY),
            band_rows.div_ceil(WORKGROUP_SIZE_XY),
        )
    }
}

/// The [`GridParams`] uniform of `grid` (the march and DP kernels share its layout).
pub(crate) fn grid_params_buffer(ctx: &GpuContext, label: &str, grid: &MarchGrid) -> wgpu::Buffer {
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::bytes_of(&GridParams::of(grid)),
            usage: wgpu::BufferUsages::UNIFORM,
        })
}

/// [`GpuError::InvalidInput`] for `kernel` when `cols` columns need more workgroups than one
/// dispatch row allows.
pub(crate) fn check_dispatch_cols(
    ctx: &GpuContext,
    cols: u32,
    kernel: &'static str,
) -> Result<(), GpuError> {
    if cols.div_ceil(WORKGROUP_SIZE_XY) > ctx.limits().max_compute_workgroups_per_dimension {
        return Err(GpuError::InvalidInput {
            kernel,
            message: format!("{cols} columns exceed one dispatch row"),
        });
    }
    Ok(())
}

/// A uniform buffer of `slots` [`StepParams`] slots, [`STEP_SLOT_BYTES`] apart.
pub(crate) fn step_slots(ctx: &GpuContext, slots: u32) -> wgpu::Buffer {
    ctx.uniform_buffer("penumbra step slots", u64::from(slots) * STEP_SLOT_BYTES)
}

/// Writes `steps` into consecutive slots of `slots`.
pub(crate) fn write_steps(
    ctx: &GpuContext,
    slots: &wgpu::Buffer,
    steps: impl Iterator<Item = (u32, u32, u32)>,
) {
    let mut bytes = Vec::new();
    for (light_index, band_row0, band_rows) in steps {
        let mut slot = [0_u8; STEP_SLOT_BYTES as usize];
        let step = StepParams {
            light_index,
            band_row0,
            band_rows,
            _pad: 0,
        };
        slot[..size_of::<StepParams>()].copy_from_slice(bytemuck::bytes_of(&step));
        bytes.extend_from_slice(&slot);
    }
    ctx.queue.write_buffer(slots, 0, &bytes);
}

/// The march bind group: grid, heights, lights, step slots (dynamic), output.
pub(crate) fn march_bind_group(
    ctx: &GpuContext,
    layout: &wgpu::BindGroupLayout,
    grid: &GpuMarchGrid,
    lights: &wgpu::Buffer,
    slots: &wgpu::Buffer,
    out: &wgpu::Buffer,
) -> wgpu::BindGroup {
    ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("penumbra march bind group"),
        layout,
        entries: &[
            whole(0, &grid.params),
            whole(1, &grid.heights),
            whole(2, lights),
            sized(3, slots, size_of::<StepParams>() as u64),
            whole(4, out),
        ],
    })
}

/// A storage buffer for one band of 4-byte outputs.
pub(crate) fn band_buffer(
    ctx: &GpuContext,
    label: &str,
    cells: u64,
    extra: wgpu::BufferUsages,
) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: cells.max(1) * 4,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | extra,
        mapped_at_creation: false,
    })
}

/// Runs `pipeline` band by band over the grid and returns the whole map (row-major, 4-byte
/// cells), reading each band back before the next one is computed.
fn run_banded<T: Pod>(
    ctx: &GpuContext,
    grid: &GpuMarchGrid,
    pipeline: &wgpu::ComputePipeline,
    lights: &[[f32; 4]],
    light_index: u32,
    band_bytes: u64,
    action: &'static str,
) -> Result<Vec<T>, GpuError> {
    let band_rows = grid.band_rows(ctx, band_bytes);
    let cols = u64::from(grid.cols);
    let scope = ErrorScope::push(&ctx.device);
    let lights_buf = storage_init(ctx, "penumbra lights", bytemuck::cast_slice(lights));
    let slots = step_slots(ctx, 1);
    let out = band_buffer(
        ctx,
        "penumbra march band",
        u64::from(band_rows) * cols,
        wgpu::BufferUsages::empty(),
    );
    let march = ctx.pipelines::<MarchPipelines>()?;
    let bind_group = march_bind_group(ctx, &march.layout, grid, &lights_buf, &slots, &out);
    let mut map: Vec<T> = Vec::with_capacity(grid.rows as usize * grid.cols as usize);
    let mut row0 = 0;
    while row0 < grid.rows {
        let rows = band_rows.min(grid.rows - row0);
        write_steps(ctx, &slots, std::iter::once((light_index, row0, rows)));
        let (gx, gy) = grid.workgroups(rows);
        ctx.dispatch(action, pipeline, &bind_group, &[0], [gx, gy, 1]);
        let bytes = ctx.read_back(&out, u64::from(rows) * cols * 4, "a shadow band")?;
        map.extend_from_slice(bytemuck::cast_slice(&bytes));
        row0 += rows;
    }
    scope.pop(action)?;
    Ok(map)
}

/// GPU `shadow_march`: the hard-shadow map (1 lit, 0 shadow, 255 nodata; row-major) of the
/// light `light` (from [`crate::twins::light_to_f32`]), computed in row bands of at
/// most `band_bytes` of output (use [`DEFAULT_BAND_BYTES`]).
pub fn shadow_march_gpu(
    ctx: &GpuContext,
    grid: &GpuMarchGrid,
    light: [f32; 4],
    band_bytes: u64,
) -> Result<Vec<u32>, GpuError> {
    let march = ctx.pipelines::<MarchPipelines>()?;
    run_banded(
        ctx,
        grid,
        &march.hard,
        &[light],
        0,
        band_bytes,
        "running shadow_march",
    )
}

/// GPU `shadow_march_soft`: per cell the fraction of `disc_dirs` (from
/// [`crate::twins::sun_disc_directions`]) that is lit, -1 for nodata.
pub fn shadow_march_soft_gpu(
    ctx: &GpuContext,
    grid: &GpuMarchGrid,
    disc_dirs: &[[f32; 4]],
    band_bytes: u64,
) -> Result<Vec<f32>, GpuError> {
    let march = ctx.pipelines::<MarchPipelines>()?;
    if disc_dirs.is_empty() {
        return Err(GpuError::InvalidInput {
            kernel: "shadow_march_soft",
            message: "no disc directions".into(),
        });
    }
    run_banded(
        ctx,
        grid,
        &march.soft,
        disc_dirs,
        0,
        band_bytes,
        "running shadow_march_soft",
    )
}
