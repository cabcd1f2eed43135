//! The wgpu instance, adapter, device and queue, built once per process ([`GpuContext::new`],
//! shared by every stage that resolves to the GPU, `compute::resolve`), and each kernel family's pipelines, built on
//! first use and reused for every later call and epoch (wgpu `repeated_compute`; rerun's
//! `RenderContext::renderer::<R>()`), plus the adapter listing of `penumbra gpu-info`.
//!
//! The context knows no kernel: a kernel module implements [`Pipelines`] for its pipeline set
//! and asks for it with [`GpuContext::pipelines`], so the kernel modules import the context and
//! never the other way round. The helpers every kernel shares live here too: buffers, the one
//! dispatch path ([`GpuContext::compute_pass`], [`GpuContext::dispatch`],
//! [`GpuContext::read_back`]), the dynamic-offset step slots, bind group layouts, and the grid
//! the grid kernels read ([`GpuGrid`]).

use std::any::{Any, TypeId};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, mpsc};

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt as _;

use super::GpuError;
use super::shaders::Shader;
use crate::twins::MarchGrid;

/// Output bytes per row band by default (64 MiB): small against any GPU, large enough that a
/// 4,096² map of 4-byte values is one band. Bands bound the output and readback memory (the
/// inputs are uploaded whole) and keep each dispatch within the per-dimension workgroup limit.
pub const DEFAULT_BAND_BYTES: u64 = 64 << 20;
/// Workgroup side of the 2-D grid kernels (`dp_visible`, `dp_sweep`, `dp_tile_*`, `fourier_*`,
/// `render`). Keep in sync with their `@workgroup_size`.
pub(crate) const WORKGROUP_SIZE_XY: u32 = 8;
/// Stride of the dynamic-offset step slots (the largest allowed
/// `min_uniform_buffer_offset_alignment`, so valid on every adapter).
pub(crate) const STEP_SLOT_BYTES: u64 = 256;

/// Mirrors of the WGSL structs.
mod gpu_data {
    use super::{Pod, Zeroable};

    /// Keep in sync with `GridParams` in shaders/shared/march.wgsl and `DpGridParams` in
    /// shaders/shared/dp.wgsl (the same layout).
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub(super) struct GridParams {
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
        /// The uniform of `grid`.
        pub(super) fn of(grid: &crate::twins::MarchGrid) -> Self {
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
}

/// A kernel family's pipelines and layouts, built once per device on first use.
pub(crate) trait Pipelines: Send + Sync + 'static {
    /// What is being built, for the error message of a failed build.
    const WHAT: &'static str;
    /// Builds the pipelines on `device` (inside an error scope).
    fn build(device: &wgpu::Device) -> Self;
}

/// A ready-to-use GPU: device, queue and the pipelines built so far.
pub struct GpuContext {
    pub(crate) device: wgpu::Device,
    pub(crate) queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    limits: wgpu::Limits,
    pipelines: Mutex<HashMap<TypeId, Arc<dyn Any + Send + Sync>>>,
}

impl std::fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuContext")
            .field("adapter", &self.info.name)
            .finish_non_exhaustive()
    }
}

/// The wgpu instance for the backends allowed by `WGPU_BACKEND` (all compiled ones by default).
fn instance() -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    // Compute needs no GL: unless WGPU_BACKEND asks for one, only the primary backends (Vulkan,
    // Metal, DX12) are probed. Probing GL/EGL on a headless Linux box prints Mesa's
    // "XDG_RUNTIME_DIR is invalid" lines and finds nothing useful.
    if std::env::var_os("WGPU_BACKEND").is_none() {
        desc.backends = wgpu::Backends::PRIMARY;
    }
    wgpu::Instance::new(desc)
}

impl GpuContext {
    /// Picks the high-performance adapter (honouring `WGPU_BACKEND`) and requests a device with
    /// the adapter's own limits (so that large height fields fit in one storage binding); the
    /// pipelines are built on first use. Returns [`GpuError::NoAdapter`] rather than panicking
    /// when no adapter exists.
    pub fn new() -> Result<Self, GpuError> {
        let instance = instance();
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
        .map_err(|e| GpuError::NoAdapter {
            reason: e.to_string(),
        })?;
        let info = adapter.get_info();
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("penumbra device"),
            required_features: wgpu::Features::empty(),
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::RequestDevice {
            adapter: info.name.clone(),
            source: Box::new(e),
        })?;
        // Errors are caught with error scopes around every kernel call; anything that escapes
        // them is a bug, reported on stderr instead of wgpu's default panic.
        device.on_uncaptured_error(std::sync::Arc::new(|e: wgpu::Error| {
            eprintln!("penumbra: GPU error outside an error scope: {e}");
        }));
        Ok(GpuContext {
            device,
            queue,
            info,
            limits,
            pipelines: Mutex::new(HashMap::new()),
        })
    }

    /// The pipelines `P`, built on the first call (a failed build is an error, and is tried
    /// again on the next call).
    pub(crate) fn pipelines<P: Pipelines>(&self) -> Result<Arc<P>, GpuError> {
        let mut built = self
            .pipelines
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(p) = built.get(&TypeId::of::<P>())
            && let Ok(p) = Arc::clone(p).downcast::<P>()
        {
            return Ok(p);
        }
        let scope = ErrorScope::push(&self.device);
        let p = Arc::new(P::build(&self.device));
        scope.pop(P::WHAT)?;
        built.insert(TypeId::of::<P>(), p.clone());
        Ok(p)
    }

    /// The adapter's name (e.g. `llvmpipe (LLVM 15.0.7, 256 bits)` for lavapipe).
    pub fn adapter_name(&self) -> &str {
        &self.info.name
    }

    /// Whether the adapter is a software rasteriser on the CPU (lavapipe/llvmpipe, WARP,
    /// SwiftShader): correct, but slower than the CPU engines (see docs/gpu.md).
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// The adapter's backend and device type, e.g. `Vulkan Cpu`.
    pub fn adapter_kind(&self) -> String {
        format!("{:?} {:?}", self.info.backend, self.info.device_type)
    }

    /// The largest storage-buffer binding this device allows, bytes (the binding limit that
    /// decides between the untiled and the tiled DP kernels).
    pub fn max_storage_binding_bytes(&self) -> u64 {
        self.limits
            .max_storage_buffer_binding_size
            .min(self.limits.max_buffer_size)
    }

    /// The device limits (the adapter's own).
    pub(crate) fn limits(&self) -> &wgpu::Limits {
        &self.limits
    }

    /// A uniform buffer of `size` bytes, filled later with `queue.write_buffer`.
    pub(crate) fn uniform_buffer(&self, label: &str, size: u64) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// A storage buffer of `size` bytes that a kernel writes, [`Self::clear`] zeroes and
    /// [`Self::read_back`] copies out (wgpu zero-initialises it).
    pub(crate) fn output_buffer(&self, label: &str, size: u64) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// A uniform buffer of `slots` (at least one) step slots, [`STEP_SLOT_BYTES`] apart, each
    /// bound at a dynamic offset and filled by [`Self::write_slots`].
    pub(crate) fn slot_buffer(&self, slots: u32) -> wgpu::Buffer {
        self.uniform_buffer(
            "penumbra step slots",
            u64::from(slots.max(1)) * STEP_SLOT_BYTES,
        )
    }

    /// Writes `steps` into consecutive slots of `slots` (queue writes land before the next
    /// submit and after the earlier ones, so no wait is needed).
    pub(crate) fn write_slots<T: Pod>(&self, slots: &wgpu::Buffer, steps: &[T]) {
        let mut bytes = Vec::with_capacity(steps.len() * STEP_SLOT_BYTES as usize);
        for step in steps {
            let mut slot = [0_u8; STEP_SLOT_BYTES as usize];
            slot[..size_of::<T>()].copy_from_slice(bytemuck::bytes_of(step));
            bytes.extend_from_slice(&slot);
        }
        self.queue.write_buffer(slots, 0, &bytes);
    }

    /// Encodes one compute pass, recorded by `record`, and submits it: the one place that
    /// encodes dispatches.
    pub(crate) fn compute_pass(
        &self,
        label: &str,
        record: impl FnOnce(&mut wgpu::ComputePass<'_>),
    ) {
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(label),
                timestamp_writes: None,
            });
            record(&mut pass);
        }
        self.queue.submit([encoder.finish()]);
    }

    /// Encodes one compute pass of `pipeline` over `workgroups` (x, y, z) with `bind_group` at
    /// the dynamic `offsets`, and submits it.
    pub(crate) fn dispatch(
        &self,
        label: &str,
        pipeline: &wgpu::ComputePipeline,
        bind_group: &wgpu::BindGroup,
        offsets: &[u32],
        workgroups: [u32; 3],
    ) {
        self.compute_pass(label, |pass| {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind_group, offsets);
            pass.dispatch_workgroups(workgroups[0], workgroups[1], workgroups[2]);
        });
    }

    /// Zeroes `buffer` (an [`Self::output_buffer`]) in its own submit.
    pub(crate) fn clear(&self, label: &str, buffer: &wgpu::Buffer) {
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
        encoder.clear_buffer(buffer, 0, None);
        self.queue.submit([encoder.finish()]);
    }

    /// Copies `size` bytes of `src` into a fresh mappable buffer, waits, and returns them.
    pub(crate) fn read_back(
        &self,
        src: &wgpu::Buffer,
        size: u64,
        what: &'static str,
    ) -> Result<Vec<u8>, GpuError> {
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("penumbra readback staging"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("penumbra readback"),
            });
        encoder.copy_buffer_to_buffer(src, 0, &staging, 0, size);
        self.queue.submit([encoder.finish()]);
        let (tx, rx) = mpsc::channel();
        staging.map_async(wgpu::MapMode::Read, .., move |r| {
            tx.send(r).ok();
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Readback {
                what,
                message: e.to_string(),
            })?;
        rx.recv()
            .map_err(|e| GpuError::Readback {
                what,
                message: e.to_string(),
            })?
            .map_err(|e| GpuError::Readback {
                what,
                message: e.to_string(),
            })?;
        let bytes = {
            let view = staging
                .get_mapped_range(..)
                .map_err(|e| GpuError::Readback {
                    what,
                    message: e.to_string(),
                })?;
            view.to_vec()
        };
        staging.unmap();
        Ok(bytes)
    }
}

/// A compute-stage buffer entry of a bind group layout (`has_dynamic_offset` for the uniform
/// slots addressed by dynamic offsets).
pub(crate) fn buffer_layout_entry(
    binding: u32,
    ty: wgpu::BufferBindingType,
    has_dynamic_offset: bool,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset,
            min_binding_size: None,
        },
        count: None,
    }
}

/// [`buffer_layout_entry`] without a dynamic offset.
pub(crate) fn layout_entry(
    binding: u32,
    ty: wgpu::BufferBindingType,
) -> wgpu::BindGroupLayoutEntry {
    buffer_layout_entry(binding, ty, false)
}

/// A bind group entry binding the whole of `buffer`.
pub(crate) fn whole(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// A bind group entry binding the first `size` bytes of `buffer` (one slot of a buffer addressed
/// by dynamic offsets, or the used part of a larger buffer).
pub(crate) fn sized(binding: u32, buffer: &wgpu::Buffer, size: u64) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer,
            offset: 0,
            size: wgpu::BufferSize::new(size),
        }),
    }
}

/// Validation + out-of-memory error scopes around a group of GPU calls, turned into
/// [`GpuError::Device`] when popped.
pub(crate) struct ErrorScope {
    validation: wgpu::ErrorScopeGuard,
    oom: wgpu::ErrorScopeGuard,
}

impl ErrorScope {
    /// Pushes the scopes.
    pub(crate) fn push(device: &wgpu::Device) -> Self {
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        ErrorScope { validation, oom }
    }

    /// Pops the scopes (innermost first) and reports the first error.
    pub(crate) fn pop(self, action: &'static str) -> Result<(), GpuError> {
        let oom = pollster::block_on(self.oom.pop());
        let validation = pollster::block_on(self.validation.pop());
        match oom.or(validation) {
            Some(e) => Err(GpuError::Device {
                action,
                message: e.to_string(),
            }),
            None => Ok(()),
        }
    }
}

/// What `penumbra gpu-info` prints for one adapter.
#[derive(Debug, Clone)]
pub struct AdapterSummary {
    /// Adapter name.
    pub name: String,
    /// Backend (Vulkan, Gl, ...).
    pub backend: String,
    /// Device type (DiscreteGpu, Cpu, ...).
    pub device_type: String,
    /// Driver name and version.
    pub driver: String,
    /// Largest storage-buffer binding, bytes (bounds the height field in one binding).
    pub max_storage_buffer_binding_size: u64,
    /// Largest buffer, bytes.
    pub max_buffer_size: u64,
    /// Largest compute workgroup along x.
    pub max_compute_workgroup_size_x: u32,
    /// Most invocations in one workgroup.
    pub max_compute_invocations_per_workgroup: u32,
    /// Most workgroups along one dispatch dimension.
    pub max_compute_workgroups_per_dimension: u32,
}

/// Every adapter wgpu finds for the backends allowed by `WGPU_BACKEND` (empty: none).
pub fn adapter_report() -> Vec<AdapterSummary> {
    let instance = instance();
    let backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::all());
    pollster::block_on(instance.enumerate_adapters(backends))
        .into_iter()
        .map(|a| {
            let info = a.get_info();
            let limits = a.limits();
            AdapterSummary {
                name: info.name,
                backend: format!("{:?}", info.backend),
                device_type: format!("{:?}", info.device_type),
                driver: format!("{} {}", info.driver, info.driver_info)
                    .trim()
                    .to_string(),
                max_storage_buffer_binding_size: limits.max_storage_buffer_binding_size,
                max_buffer_size: limits.max_buffer_size,
                max_compute_workgroup_size_x: limits.max_compute_workgroup_size_x,
                max_compute_invocations_per_workgroup: limits.max_compute_invocations_per_workgroup,
                max_compute_workgroups_per_dimension: limits.max_compute_workgroups_per_dimension,
            }
        })
        .collect()
}

/// A kernel with one pipeline whose bindings are a uniform (0), then [`Self::READS`] read-only
/// storage buffers, then [`Self::READ_WRITES`] read-write ones, none at a dynamic offset; its
/// [`KernelPipeline`] is built on first use ([`GpuContext::pipelines`]).
pub(crate) trait SingleKernel: Send + Sync + 'static {
    /// The shader.
    const SHADER: Shader;
    /// Read-only storage buffers, bindings 1 ..= `READS`.
    const READS: u32;
    /// Read-write storage buffers, after the read-only ones.
    const READ_WRITES: u32;
    /// What building the pipeline is, for its error message.
    const WHAT: &'static str;
}

/// The bind group layout and pipeline of the [`SingleKernel`] `K`.
pub(crate) struct KernelPipeline<K> {
    pub(crate) layout: wgpu::BindGroupLayout,
    pub(crate) pipeline: wgpu::ComputePipeline,
    kernel: std::marker::PhantomData<fn() -> K>,
}

impl<K: SingleKernel> Pipelines for KernelPipeline<K> {
    const WHAT: &'static str = K::WHAT;

    fn build(device: &wgpu::Device) -> Self {
        use wgpu::BufferBindingType::{Storage, Uniform};
        let types = std::iter::once(Uniform)
            .chain((0..K::READS).map(|_| Storage { read_only: true }))
            .chain((0..K::READ_WRITES).map(|_| Storage { read_only: false }));
        let entries: Vec<_> = (0..)
            .zip(types)
            .map(|(b, ty)| layout_entry(b, ty))
            .collect();
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(K::SHADER.name),
            entries: &entries,
        });
        let pipeline = compute_pipeline(device, &layout, &K::SHADER);
        KernelPipeline {
            layout,
            pipeline,
            kernel: std::marker::PhantomData,
        }
    }
}

impl<K: SingleKernel> KernelPipeline<K> {
    /// The bind group of `buffers`, bound whole at bindings 0, 1, … in this order.
    pub(crate) fn bind(&self, ctx: &GpuContext, buffers: &[&wgpu::Buffer]) -> wgpu::BindGroup {
        let entries: Vec<_> = (0..)
            .zip(buffers)
            .map(|(binding, buffer)| whole(binding, buffer))
            .collect();
        ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(K::SHADER.name),
            layout: &self.layout,
            entries: &entries,
        })
    }
}

/// The compute pipeline of `shader` (its entry point is its name) with the one bind group
/// `layout`.
pub(crate) fn compute_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    shader: &Shader,
) -> wgpu::ComputePipeline {
    let label = Some(shader.name);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label,
        source: wgpu::ShaderSource::Wgsl(shader.source.into()),
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label,
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label,
        layout: Some(&pipeline_layout),
        module: &module,
        entry_point: Some(shader.name),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// Uploads `data` as a read-only storage buffer.
pub(crate) fn storage_init<T: Pod>(ctx: &GpuContext, label: &str, data: &[T]) -> wgpu::Buffer {
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::cast_slice(data),
            usage: wgpu::BufferUsages::STORAGE,
        })
}

/// The dynamic offset of step slot `slot` ([`GpuContext::slot_buffer`]).
pub(crate) fn slot_offset(slot: usize) -> u32 {
    slot as u32 * STEP_SLOT_BYTES as u32
}

/// Rows per band of a `rows` × `cols` grid for `bytes_per_cell` of output per cell within
/// `band_bytes`: at least 1, at most `rows`, within one storage binding and within the dispatch
/// limit of the 2-D kernels.
pub(crate) fn band_rows(
    ctx: &GpuContext,
    rows: u32,
    cols: u32,
    bytes_per_cell: u64,
    band_bytes: u64,
) -> u32 {
    let max_bytes = band_bytes.min(ctx.max_storage_binding_bytes());
    let by_budget = (max_bytes / (u64::from(cols) * bytes_per_cell)).max(1);
    let by_dispatch =
        u64::from(ctx.limits().max_compute_workgroups_per_dimension) * u64::from(WORKGROUP_SIZE_XY);
    by_budget.min(by_dispatch).min(u64::from(rows)) as u32
}

/// [`GpuError::InvalidInput`] for `kernel` when `cols` columns need more workgroups of the 2-D
/// kernels than one dispatch row allows.
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

/// The `GridParams` uniform of `grid` (`shaders/shared/march.wgsl`; `DpGridParams` of
/// `shaders/shared/dp.wgsl` has the same layout).
pub(crate) fn grid_params_buffer(ctx: &GpuContext, label: &str, grid: &MarchGrid) -> wgpu::Buffer {
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::bytes_of(&gpu_data::GridParams::of(grid)),
            usage: wgpu::BufferUsages::UNIFORM,
        })
}

/// A [`MarchGrid`] resident on the GPU: the grid uniform (binding 0 of the grid kernels) and the
/// heights (binding 1), uploaded once and reused by every map and every epoch.
pub struct GpuGrid {
    pub(crate) params: wgpu::Buffer,
    pub(crate) heights: wgpu::Buffer,
    pub(crate) rows: u32,
    pub(crate) cols: u32,
}

impl GpuGrid {
    /// Uploads `grid` for `kernel`. Fails when the heights exceed the device's storage binding
    /// limit or the grid is wider than one dispatch row allows.
    pub fn upload(
        ctx: &GpuContext,
        grid: &MarchGrid,
        kernel: &'static str,
    ) -> Result<Self, GpuError> {
        let heights_bytes = grid.heights_m.len() as u64 * 4;
        if heights_bytes > ctx.max_storage_binding_bytes() {
            return Err(GpuError::InvalidInput {
                kernel,
                message: format!(
                    "the height field ({heights_bytes} B) exceeds the adapter's storage binding \
                     limit ({} B)",
                    ctx.limits().max_storage_buffer_binding_size
                ),
            });
        }
        check_dispatch_cols(ctx, grid.cols, kernel)?;
        let scope = ErrorScope::push(&ctx.device);
        let on_gpu = Self::new(ctx, grid);
        scope.pop("uploading the height field")?;
        Ok(on_gpu)
    }

    /// Uploads `grid` without checks (the caller has checked it and holds an error scope).
    pub(crate) fn new(ctx: &GpuContext, grid: &MarchGrid) -> Self {
        GpuGrid {
            params: grid_params_buffer(ctx, "penumbra grid params", grid),
            heights: storage_init(ctx, "penumbra heights", &grid.heights_m),
            rows: grid.rows,
            cols: grid.cols,
        }
    }

    /// Rows per band of this grid ([`band_rows`]).
    pub(crate) fn band_rows(&self, ctx: &GpuContext, bytes_per_cell: u64, band_bytes: u64) -> u32 {
        band_rows(ctx, self.rows, self.cols, bytes_per_cell, band_bytes)
    }
}
