//! The one CPU|GPU switch: the backend is resolved here, once per process ([`resolve`]), and each
//! question a product asks is answered on it, one file per question (statistics over an epoch
//! range, one-light maps, site horizons and the smap-dp series engine, a frame's fractions and
//! samples). Every `cfg(feature = "gpu")` arm of the products lives here (vello
//! `WgpuEngine { use_cpu }`). `--backend` decides where a computation runs, never what it
//! computes: an engine without a GPU kernel runs on the CPU, with one line that says so.

use anyhow::Context as _;

use crate::model::MapEngineKind;

pub use crate::gpu::{Backend, ResolvedBackend};

#[cfg(feature = "gpu")]
pub mod gpu_maps;
pub mod horizons;
pub mod one_light;
pub mod range;
pub mod render;
pub mod site_dp;

/// What the GPU can do for a computation, which decides what `--backend` resolves to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnGpu {
    /// A GPU kernel runs it: `gpu` and `auto` on a hardware adapter take the GPU.
    Preferred,
    /// A GPU kernel runs it when asked (`--backend gpu`); `auto` keeps the CPU, which answers it
    /// as fast (one site's horizon, the horizons engine's statistics), without probing adapters.
    WhenAsked,
    /// No GPU kernel computes `what`: it runs on the CPU, and `--backend gpu` prints one line
    /// that says so.
    Never {
        /// The computation, as the line names it (e.g. "the combined engine").
        what: &'static str,
    },
}

/// Resolves a `--backend` choice for a computation the GPU can do `on_gpu`: `cpu` is the CPU;
/// `gpu` a GPU context (an error without an adapter) unless no kernel exists; `auto` the GPU on a
/// hardware adapter, else the CPU with one warning line. The GPU context is created once and
/// shared by every later call of the process.
pub fn resolve(requested: Backend, on_gpu: OnGpu) -> anyhow::Result<ResolvedBackend> {
    match (requested, on_gpu) {
        (Backend::Cpu, _) | (Backend::Auto, OnGpu::WhenAsked | OnGpu::Never { .. }) => {
            Ok(ResolvedBackend::Cpu)
        }
        (Backend::Gpu, OnGpu::Never { what }) => {
            eprintln!("penumbra: note: {what} has no GPU kernel: it runs on the CPU");
            Ok(ResolvedBackend::Cpu)
        }
        (Backend::Gpu | Backend::Auto, _) => crate::gpu::backend::resolve_backend(requested)
            .with_context(|| format!("resolving --backend {}", requested.as_str())),
    }
}

/// How a map is computed, whatever it is asked for: the command line, a scenario's `[map]` and
/// the Python module build the same settings.
#[derive(Debug, Clone)]
pub struct MapSettings {
    /// Observer height above the ground.
    pub observer_height: crate::model::ObserverHeight,
    /// The engine; `None` for `auto` ([`auto_engine`]).
    pub engine: Option<MapEngineKind>,
    /// Where it runs (`--backend`).
    pub backend: Backend,
    /// GPU tiles of this many cells per side (≥ 2) instead of the automatic choice.
    pub gpu_tile_cells: Option<u32>,
    /// Where the rays start; `None` for the DEM pixels' own surface points.
    pub observers: Option<crate::model::ObserverPlacement>,
    /// The horizons engine: where its whole-grid horizons come from.
    pub horizons: range::HorizonsFrom,
    /// The horizons engine: the Sun's limb darkening in its mean fraction (the per-epoch engines
    /// use a uniform disc).
    pub limb: crate::illum::LimbLaw,
    /// Ground stations of the direct-to-Earth maps (`none` by default: they come from the
    /// horizons engine over an epoch range).
    pub stations: crate::comms::Stations,
    /// Elevation mask of the DSN stations and of file rows without their own, degrees.
    pub station_mask_deg: f64,
    /// A panel and its load: the maps of mean power and required battery (the horizons engine
    /// over an epoch range; none by default).
    pub power: Option<crate::illum::power::PowerConfig>,
}

impl Default for MapSettings {
    fn default() -> Self {
        MapSettings {
            observer_height: crate::model::ObserverHeight::DEFAULT,
            engine: None,
            backend: Backend::Auto,
            gpu_tile_cells: None,
            observers: None,
            horizons: range::HorizonsFrom::default(),
            limb: crate::illum::LimbLaw::default(),
            stations: crate::comms::Stations::None,
            station_mask_deg: crate::comms::DEFAULT_MASK_DEG,
            power: None,
        }
    }
}

impl MapSettings {
    /// Whether the horizons engine's epoch loop must run on the CPU (the direct-to-Earth and
    /// power statistics have no GPU kernel).
    pub fn epoch_loop_on_cpu(&self) -> bool {
        self.stations != crate::comms::Stations::None || self.power.is_some()
    }

    /// Where the rays start.
    pub fn placement(&self) -> crate::model::ObserverPlacement {
        self.observers
            .unwrap_or(crate::model::ObserverPlacement::Pixels)
    }

    /// The engine a map runs and the backend it runs on: the engine asked for, on the backend
    /// `--backend` resolves to for it ([`map_engine_on_gpu`]); for `auto`, the best engine where
    /// the map runs ([`auto_engine`]). `n_epochs` is the number of epochs of a range (`None` for
    /// one light).
    pub fn engine_and_backend(
        &self,
        n_epochs: Option<usize>,
    ) -> anyhow::Result<(MapEngineKind, ResolvedBackend)> {
        if let Some(p) = &self.power {
            // Bad power settings fail first, with their own message.
            p.validate()?;
            if matches!(p.panel, crate::illum::power::Panel::VerticalFixed { .. }) {
                anyhow::bail!(
                    "--panel {}: power maps take vertical-tracking, horizontal or two-axis panels \
                     (a fixed panel needs the Sun's azimuth at every epoch: use a series)",
                    p.panel.name()
                );
            }
        }
        if self.stations != crate::comms::Stations::None {
            // A bad station list fails first, with its own message.
            self.stations.resolve(self.station_mask_deg)?;
        }
        let only_horizons = [
            (
                self.stations != crate::comms::Stations::None,
                "--stations: direct-to-Earth",
            ),
            (self.power.is_some(), "--panel: power"),
        ];
        for (asked, what) in only_horizons {
            if !asked {
                continue;
            }
            if n_epochs.is_none() {
                anyhow::bail!("{what} maps need an epoch range (--start, --stop, --step)");
            }
            if let Some(other) = self.engine.filter(|&e| e != MapEngineKind::Horizons) {
                anyhow::bail!(
                    "{what} maps come from the horizons engine, not {} (use --engine horizons or \
                     auto)",
                    other.name()
                );
            }
        }
        if self.epoch_loop_on_cpu() {
            let backend = resolve(self.backend, OnGpu::WhenAsked)?;
            return Ok((MapEngineKind::Horizons, backend));
        }
        let on_gpu = match self.engine {
            Some(engine) => map_engine_on_gpu(engine, n_epochs.is_some()),
            None => OnGpu::Preferred,
        };
        let backend = resolve(self.backend, on_gpu)?;
        let Some(engine) = self.engine else {
            return Ok((self.auto_engine_noted(&backend, n_epochs), backend));
        };
        Ok((engine, backend))
    }

    /// The engine `--engine auto` runs for `n_epochs` epochs on `backend`, said on one line for
    /// a range ([`auto_engine`]).
    fn auto_engine_noted(
        &self,
        backend: &ResolvedBackend,
        n_epochs: Option<usize>,
    ) -> MapEngineKind {
        let engine = auto_engine(backend, n_epochs, &self.horizons);
        if let Some(n) = n_epochs {
            crate::note!(
                "penumbra: --engine auto: {} for {n} epochs",
                match engine {
                    MapEngineKind::Horizons =>
                        "horizons (whole-grid horizons once, then every epoch per pixel)",
                    MapEngineKind::Direct(crate::shadow::Engine::Dp) =>
                        "dp (a soft-shadow map per epoch on the GPU)",
                    _ => "combined (a soft-shadow map per epoch)",
                }
            );
        }
        engine
    }
}

/// What the GPU can do for a map of `engine` (one light, or an epoch range when `range`): the dp
/// engine runs on the GPU; the Fourier engine's one-light maps too (its horizon map built and
/// evaluated there); the horizons engine when asked (its line sweep and epoch loop); the combined
/// engine and Fourier ranges have no GPU kernel.
pub fn map_engine_on_gpu(engine: MapEngineKind, range: bool) -> OnGpu {
    use crate::shadow::Engine;
    match engine {
        MapEngineKind::Direct(Engine::Dp) => OnGpu::Preferred,
        MapEngineKind::Fourier if !range => OnGpu::Preferred,
        MapEngineKind::Horizons => OnGpu::WhenAsked,
        MapEngineKind::Fourier => OnGpu::Never {
            what: "the fourier engine over an epoch range",
        },
        MapEngineKind::Direct(Engine::Combined) => OnGpu::Never {
            what: "the combined engine",
        },
        MapEngineKind::Direct(Engine::Brute) => OnGpu::Never {
            what: "the brute-force engine",
        },
    }
}

/// The engine `--engine auto` runs on `backend` for one light (`n_epochs` `None`) or a range of
/// `n_epochs`: one light, `dp` on a GPU, else `combined`. A range: the horizons engine when its
/// horizons are given as a file (`--horizons`: the sweep is paid for, and each epoch then costs
/// it ≈ 35× less than a combined map on the CPU), or from [`AUTO_HORIZONS_MIN_EPOCHS`] epochs
/// on, whatever the backend (where a whole-grid sweep costs less than the per-epoch maps on the
/// CPU, `cargo bench --bench statistics`, docs/PERFORMANCE.md; on a GPU machine too, so that the
/// default computes the same physics on both: the per-epoch engines run on the resampled model
/// grid, the horizons engine on the DEM's own pixels); else `dp` on a GPU, `combined` on the CPU
/// (the same DP fractions: `combined` takes SMap's verdict only where it is unanimous).
pub fn auto_engine(
    backend: &ResolvedBackend,
    n_epochs: Option<usize>,
    horizons: &range::HorizonsFrom,
) -> MapEngineKind {
    use crate::shadow::Engine;
    let on_gpu = matches!(backend, ResolvedBackend::Gpu(_));
    let per_epoch = if on_gpu {
        MapEngineKind::Direct(Engine::Dp)
    } else {
        MapEngineKind::Direct(Engine::Combined)
    };
    match (n_epochs, horizons) {
        (None, _) => per_epoch,
        (Some(_), range::HorizonsFrom::File(_)) => MapEngineKind::Horizons,
        (Some(n), range::HorizonsFrom::Sweep { .. }) if n >= AUTO_HORIZONS_MIN_EPOCHS => {
            MapEngineKind::Horizons
        }
        (Some(_), range::HorizonsFrom::Sweep { .. }) => per_epoch,
    }
}

/// Fewest epochs for which `--engine auto` sweeps horizons (see [`auto_engine`]).
pub const AUTO_HORIZONS_MIN_EPOCHS: usize = 1000;
