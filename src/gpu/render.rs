//! GPU runner of `shaders/render.wgsl`: the renderer's frame on the GPU, one invocation per pixel
//! (camera ray, max-mipmap ray casting, bilinear normal, Sun + earthshine shading through
//! `brdf_per_sr`, sky discs), radiance read back as f32 and tone mapped on the CPU with
//! [`crate::render::tone_map`]. The CPU counterpart is [`crate::render::Scene::render`] with
//! [`crate::render::TraceMethod::MaxMipmap`] (the same algorithm in f64); parity is measured in
//! tests/it/gpu/render.rs.
//!
//! Per scene ([`GpuRenderScene::upload`], once): heights and the flattened maximum mipmap
//! (f32, metres relative to the mid height; holes -1e30), the level table, and the per-cell Sun
//! and Earth visible fractions (computed on the CPU by the scene's shadow engine). Per frame
//! ([`render_gpu`]): the camera uniform and the output in **row bands** of at most
//! `band_bytes` (default [`DEFAULT_BAND_BYTES`], capped by the adapter's
//! storage binding and buffer size), so images larger than one storage binding work.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt as _;

use super::GpuError;
use super::context::{
    DEFAULT_BAND_BYTES, ErrorScope, GpuContext, KernelPipeline, WORKGROUP_SIZE_XY, band_rows,
    storage_init,
};
use crate::render::{Camera, Sample, Scene};

/// Hole marker in the uploaded heights and pyramid (the shader tests `< -1e29`).
const HOLE_M: f32 = -1e30;

/// Output code of a pixel that sees black sky.
pub const CODE_SKY: f32 = -1.0;
/// Output code of a pixel inside the Sun's disc.
pub const CODE_SUN: f32 = -2.0;
/// Output code of a pixel inside the Earth's disc.
pub const CODE_EARTH: f32 = -3.0;
/// Output code of a pixel that shows the night side of the Earth's disc.
pub const CODE_EARTH_NIGHT: f32 = -4.0;

/// Mirrors of the WGSL structs.
mod gpu_data {
    use super::{Pod, Zeroable};

    /// Keep in sync with `Params` in shaders/render.wgsl.
    #[repr(C)]
    #[derive(Debug, Clone, Copy, Pod, Zeroable)]
    pub(super) struct Params {
        pub origin: [f32; 4],
        pub forward: [f32; 4],
        pub right: [f32; 4],
        pub up: [f32; 4],
        pub sun: [f32; 4],
        pub earth: [f32; 4],
        pub grid: [f32; 4],
        pub shade: [f32; 4],
        pub dims: [u32; 4],
        pub image: [u32; 4],
    }
    const _: () = assert!(size_of::<Params>() == 160);
}
use gpu_data::Params;

single_kernel! {
    /// The render kernel: params; heights, pyramid, levels, fractions; output.
    RenderKernel = RENDER, 4, 1, "building the render pipeline"
}

/// A scene uploaded to the GPU: heights, maximum mipmap, level table, visible fractions, and the
/// constants of the frame (lights, albedo, grid placement).
pub struct GpuRenderScene {
    heights: wgpu::Buffer,
    pyramid: wgpu::Buffer,
    levels: wgpu::Buffer,
    fractions: wgpu::Buffer,
    rows: u32,
    cols: u32,
    n_levels: u32,
    /// BRDF model of `shaders/shared/brdf.wgsl`: 0 Lambert, 1 Hapke (lunar 643 nm constants).
    brdf_model: u32,
    px_m: f64,
    x_left_m: f64,
    y_top_m: f64,
    z_ref_m: f64,
    z_lo_rel_m: f32,
    z_hi_rel_m: f32,
    sun: [f32; 4],
    earth: [f32; 4],
    shade: [f32; 3],
}

impl std::fmt::Debug for GpuRenderScene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuRenderScene")
            .field("rows", &self.rows)
            .field("cols", &self.cols)
            .finish_non_exhaustive()
    }
}

fn invalid(message: String) -> GpuError {
    GpuError::InvalidInput {
        kernel: "render",
        message,
    }
}

impl GpuRenderScene {
    /// Uploads `scene` (its height field, maximum mipmap and per-cell visible fractions). Fails
    /// when a buffer exceeds the adapter's storage binding limit or the field is all holes.
    pub fn upload(ctx: &GpuContext, scene: &Scene) -> Result<Self, GpuError> {
        let caster = scene.caster();
        let hf = caster.height_field();
        let (z_min_m, z_max_m) = caster.z_range_m();
        if !(z_min_m.is_finite() && z_max_m.is_finite()) {
            return Err(invalid("the height field has no data".into()));
        }
        let z_ref_m = 0.5 * (z_min_m + z_max_m);
        let rel = |z: f32| {
            if z.is_finite() {
                (f64::from(z) - z_ref_m) as f32
            } else {
                HOLE_M
            }
        };
        let heights: Vec<f32> = hf.z_m.iter().map(|&z| rel(z)).collect();
        let pyr = caster.pyramid();
        let texels: Vec<f32> = pyr.texels.iter().map(|&z| rel(z)).collect();
        let levels: Vec<[u32; 4]> = pyr
            .levels
            .iter()
            .map(|&(r, c, off)| [r as u32, c as u32, off as u32, 0])
            .collect();
        let (sun_f, earth_f) = scene.fractions();
        let frac = |f: f32| if f.is_finite() { f } else { -1.0 };
        let fractions: Vec<[f32; 2]> = sun_f
            .iter()
            .zip(earth_f)
            .map(|(&s, &e)| [frac(s), frac(e)])
            .collect();
        let limit = ctx.max_storage_binding_bytes();
        let biggest = (fractions.len() * 8).max(texels.len() * 4) as u64;
        if biggest > limit || texels.len() > u32::MAX as usize {
            return Err(invalid(format!(
                "the height field ({} x {} cells) needs a {biggest} B buffer, over the \
                 adapter's storage binding limit ({limit} B)",
                hf.rows, hf.cols
            )));
        }
        let lights = scene.lights();
        let unit = |v: [f64; 3], r: f64| [v[0] as f32, v[1] as f32, v[2] as f32, r.sin() as f32];
        let scope = ErrorScope::push(&ctx.device);
        let out = GpuRenderScene {
            heights: storage_init(ctx, "penumbra render heights", &heights),
            pyramid: storage_init(ctx, "penumbra render pyramid", &texels),
            levels: storage_init(ctx, "penumbra render levels", &levels),
            fractions: storage_init(ctx, "penumbra render fractions", &fractions),
            rows: hf.rows as u32,
            cols: hf.cols as u32,
            n_levels: levels.len() as u32,
            brdf_model: match scene.brdf() {
                crate::render::Brdf::Lambert { .. } => 0,
                crate::render::Brdf::Hapke(_) => 1,
            },
            px_m: hf.px_m,
            x_left_m: hf.x_left_m,
            y_top_m: hf.y_top_m,
            z_ref_m,
            z_lo_rel_m: (z_min_m - 1.0 - z_ref_m) as f32,
            z_hi_rel_m: (z_max_m + 1.0 - z_ref_m) as f32,
            sun: unit(lights.sun, lights.sun_radius_rad),
            earth: unit(lights.earth, lights.earth_radius_rad),
            shade: [
                crate::SOLAR_CONSTANT_W_M2 as f32,
                lights.earth_irradiance_w_m2() as f32,
                scene.albedo() as f32,
            ],
        };
        scope.pop("uploading the render scene")?;
        Ok(out)
    }
}

/// Options of [`render_gpu`].
#[derive(Debug, Clone, Copy)]
pub struct RenderGpuOptions {
    /// Output bytes per row band (4 B per pixel); capped by the adapter's limits.
    pub band_bytes: u64,
}

impl Default for RenderGpuOptions {
    fn default() -> Self {
        RenderGpuOptions {
            band_bytes: DEFAULT_BAND_BYTES,
        }
    }
}

/// Raw kernel output of a `width` x `height` frame (row-major, row 0 at the top): radiance
/// W/(m² sr) >= 0 for terrain, else [`CODE_SKY`], [`CODE_SUN`], [`CODE_EARTH`] or [`CODE_EARTH_NIGHT`].
pub fn render_radiance_gpu(
    ctx: &GpuContext,
    scene: &GpuRenderScene,
    camera: &Camera,
    width: u32,
    height: u32,
    options: RenderGpuOptions,
) -> Result<Vec<f32>, GpuError> {
    let render = ctx.pipelines::<KernelPipeline<RenderKernel>>()?;
    crate::render::check_size(width, height).map_err(|e| invalid(e.to_string()))?;
    let band_rows = band_rows(ctx, height, width, 4, options.band_bytes);
    if width.div_ceil(WORKGROUP_SIZE_XY) > ctx.limits().max_compute_workgroups_per_dimension {
        return Err(invalid(format!("{width} px exceed one dispatch row")));
    }
    let px = scene.px_m;
    let p = camera.pos_model_m;
    let v4 = |v: nalgebra::Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32, 0.0];
    let mut params = Params {
        origin: [
            ((p.x - scene.x_left_m) / px - 0.5) as f32,
            ((scene.y_top_m - p.y) / px - 0.5) as f32,
            (p.z - scene.z_ref_m) as f32,
            0.0,
        ],
        forward: v4(camera.forward_model),
        right: v4(camera.right_model),
        up: v4(camera.up_model),
        sun: scene.sun,
        earth: scene.earth,
        grid: [
            px as f32,
            scene.z_lo_rel_m,
            scene.z_hi_rel_m,
            (camera.fov_deg.to_radians() / 2.0).tan() as f32,
        ],
        shade: [
            scene.shade[0],
            scene.shade[1],
            scene.shade[2],
            (f64::from(height) / f64::from(width)) as f32,
        ],
        dims: [scene.rows, scene.cols, scene.n_levels, scene.brdf_model],
        image: [width, height, 0, band_rows],
    };
    let scope = ErrorScope::push(&ctx.device);
    let uniform = ctx
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("penumbra render params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
    let band_bytes = u64::from(band_rows) * u64::from(width) * 4;
    let output = ctx.output_buffer("penumbra render output band", band_bytes);
    let bind_group = render.bind(
        ctx,
        &[
            &uniform,
            &scene.heights,
            &scene.pyramid,
            &scene.levels,
            &scene.fractions,
            &output,
        ],
    );
    let mut all = Vec::with_capacity(width as usize * height as usize);
    let mut row0 = 0;
    while row0 < height {
        let rows = band_rows.min(height - row0);
        params.image = [width, height, row0, rows];
        ctx.queue
            .write_buffer(&uniform, 0, bytemuck::bytes_of(&params));
        ctx.dispatch(
            "penumbra render band",
            &render.pipeline,
            &bind_group,
            &[],
            [
                width.div_ceil(WORKGROUP_SIZE_XY),
                rows.div_ceil(WORKGROUP_SIZE_XY),
                1,
            ],
        );
        let bytes = ctx.read_back(
            &output,
            u64::from(rows) * u64::from(width) * 4,
            "render radiance",
        )?;
        all.extend_from_slice(bytemuck::cast_slice::<u8, f32>(&bytes));
        row0 += rows;
    }
    scope.pop("rendering a frame")?;
    Ok(all)
}

/// Converts the kernel output to [`Sample`]s (for [`crate::render::tone_map`]).
pub fn samples_from_radiance(radiance: &[f32]) -> Vec<Sample> {
    radiance
        .iter()
        .map(|&l| {
            if l >= 0.0 {
                Sample::Terrain {
                    radiance_w_m2_sr: l,
                }
            } else if l == CODE_SUN {
                Sample::Sun
            } else if l == CODE_EARTH {
                Sample::Earth
            } else if l == CODE_EARTH_NIGHT {
                Sample::EarthNight
            } else {
                Sample::Sky
            }
        })
        .collect()
}

/// A `width` x `height` frame of `scene` seen by `camera` on the GPU, as [`Sample`]s
/// (row-major, row 0 at the top), like [`Scene::render`] on the CPU.
pub fn render_gpu(
    ctx: &GpuContext,
    scene: &GpuRenderScene,
    camera: &Camera,
    width: u32,
    height: u32,
    options: RenderGpuOptions,
) -> Result<Vec<Sample>, GpuError> {
    render_radiance_gpu(ctx, scene, camera, width, height, options)
        .map(|l| samples_from_radiance(&l))
}
