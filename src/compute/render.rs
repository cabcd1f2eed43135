//! A frame's shadow fractions and samples on the resolved backend (see docs/render.md).

use crate::render::{Camera, Lights, Sample, Scene};
use crate::terrain::HeightField;

use super::ResolvedBackend;

/// Where the per-cell Sun and Earth visible fractions of a frame come from: the CPU shadow
/// engine, or (when the render backend resolved to the GPU) the GPU DP kernel on a grid
/// uploaded once, so that a GPU frame does not wait on the CPU engine.
pub struct SceneFractions<'a> {
    backend: &'a ResolvedBackend,
    hf: &'a HeightField,
    #[cfg(feature = "gpu")]
    on_gpu: Option<super::gpu_maps::GpuSceneFractions>,
}

impl<'a> SceneFractions<'a> {
    /// Prepares `hf` on `backend` (uploads it and its DP mipmap on the GPU).
    pub fn new(backend: &'a ResolvedBackend, hf: &'a HeightField) -> anyhow::Result<Self> {
        Ok(SceneFractions {
            backend,
            hf,
            #[cfg(feature = "gpu")]
            on_gpu: match backend {
                ResolvedBackend::Gpu(ctx) => {
                    Some(super::gpu_maps::GpuSceneFractions::upload(ctx, hf)?)
                }
                ResolvedBackend::Cpu => None,
            },
        })
    }

    /// The scene of one frame: `Engine::Combined` on the CPU (what [`Scene::new`] does), the DP
    /// kernel on the GPU.
    pub fn scene(&self, lights: Lights) -> anyhow::Result<Scene<'a>> {
        match self.backend {
            ResolvedBackend::Cpu => Ok(Scene::new(
                self.hf,
                lights,
                crate::shadow::Engine::Combined,
            )?),
            #[cfg(feature = "gpu")]
            ResolvedBackend::Gpu(ctx) => {
                let Some(on_gpu) = &self.on_gpu else {
                    anyhow::bail!("internal: a GPU backend without its uploaded grid")
                };
                let (sun, earth) = on_gpu.fractions(ctx, &lights)?;
                Ok(Scene::with_fractions(self.hf, lights, sun, earth))
            }
            #[cfg(not(feature = "gpu"))]
            ResolvedBackend::Gpu(ctx) => match **ctx {},
        }
    }
}

/// The samples of a `width` × `height` frame of `scene` seen by `camera` on `backend`.
pub fn render_samples(
    backend: &ResolvedBackend,
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
) -> anyhow::Result<Vec<Sample>> {
    Ok(match backend {
        ResolvedBackend::Cpu => scene.render(camera, width, height)?,
        #[cfg(feature = "gpu")]
        ResolvedBackend::Gpu(ctx) => {
            use crate::gpu::render::{GpuRenderScene, RenderGpuOptions, render_gpu};
            let gpu_scene = GpuRenderScene::upload(ctx, scene)?;
            render_gpu(
                ctx,
                &gpu_scene,
                camera,
                width,
                height,
                RenderGpuOptions::default(),
            )?
        }
        #[cfg(not(feature = "gpu"))]
        ResolvedBackend::Gpu(ctx) => match **ctx {},
    })
}
