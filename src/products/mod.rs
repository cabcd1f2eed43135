//! One product pipeline per job: `ephem`, `kernels`, `dem`, `horizon`, `series`, `map`, `render`,
//! `horizon-map`, `gpu-info` (the scenario runner, [`crate::scenario`], drives several).
//!
//! Each pipeline takes a typed request whose values are already parsed ([`crate::model`]'s
//! `ObserverHeight`, `Site`, `Epochs`; the aberration correction, the backend) and writes its
//! files. The command line (`src/cli/`, in the binary), the scenario files and the Python module
//! build the same requests; the library knows neither clap nor argv.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context as _;

use crate::ephem::Kernels;
use crate::terrain::{TerrainStack, synth::SynthParams};

pub mod dem;
pub mod ephem;
pub mod gpu_info;
pub mod horizon;
pub mod horizon_map;
pub mod kernels;
pub mod map;
pub mod mast;
pub mod render;
pub mod series;
pub mod windows;

/// Where the terrain comes from: DEM files (finest first) or the built-in synthetic DEM.
#[derive(Debug, Clone, PartialEq)]
pub enum TerrainSource {
    /// DEM GeoTIFF layers; the finest with data is used at each point.
    Dems(Vec<PathBuf>),
    /// penumbra's synthetic south-polar DEM with these parameters.
    Synthetic(SynthParams),
    /// The synthetic DEM and its far field ([`synthetic_stack_with_far_field`]): two layers,
    /// no ray leaving the terrain.
    SyntheticWithFarField(SynthParams),
}

impl TerrainSource {
    /// Loads the terrain; returns the stack and one description per layer for provenance.
    pub fn load(&self) -> anyhow::Result<(TerrainStack, Vec<String>)> {
        match self {
            TerrainSource::Synthetic(params) => {
                let (stack, what) = synthetic_stack(params)?;
                Ok((stack, vec![what]))
            }
            TerrainSource::SyntheticWithFarField(params) => {
                let (stack, what) = synthetic_stack_with_far_field(params)?;
                Ok((stack, what))
            }
            TerrainSource::Dems(paths) => {
                let stack = load_stack(paths)?;
                detail_terrain(&stack);
                Ok((
                    stack,
                    paths.iter().map(|p| p.display().to_string()).collect(),
                ))
            }
        }
    }
}

/// A product's inputs, loaded once: every terrain layer and, when the run has epochs, the kernels
/// (checked to cover its first and last epoch), with their provenance.
pub struct Inputs {
    /// Every terrain layer, finest first.
    pub stack: TerrainStack,
    /// The kernels (`None` for a run without epochs).
    pub kernels: Option<Kernels>,
    /// The run's provenance so far: the kernels, the DEM layers (and, when asked, the DEM
    /// files' sizes and sha256), the epochs.
    pub provenance: crate::output::Provenance,
}

/// Whether [`Inputs::load`] records the DEM files' sizes and sha256 (for a `run.json`; reading
/// a large DEM twice costs seconds).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DemFiles {
    /// Recorded.
    Record,
    /// Not recorded.
    Skip,
}

impl Inputs {
    /// Loads `terrain` (recording its files as `dem_files` says), and `kernels` when `epochs`
    /// is not empty (the terrain first: its errors come before the kernels').
    pub fn load(
        terrain: &TerrainSource,
        kernels: &KernelSource,
        epochs: &[hifitime::Epoch],
        dem_files: DemFiles,
    ) -> anyhow::Result<Self> {
        let (stack, dem_layers) = terrain.load()?;
        let mut provenance = crate::output::Provenance::new();
        provenance.dem_layers = dem_layers;
        if dem_files == DemFiles::Record {
            provenance.dem_files = terrain.dem_files()?;
        }
        provenance.set_epochs(epochs);
        let kernels = match (epochs.first(), epochs.last()) {
            (Some(&first), Some(&last)) => {
                let k = kernels.load()?;
                crate::ephem::moon_geometry_table(&k, &[first, last])?;
                provenance.kernels = k.files.clone();
                Some(k)
            }
            _ => None,
        };
        Ok(Inputs {
            stack,
            kernels,
            provenance,
        })
    }
}

/// `--verbose`: the terrain layers read.
pub fn detail_terrain(stack: &TerrainStack) {
    for (i, l) in stack.layers.iter().enumerate() {
        crate::detail!(
            "penumbra: terrain layer {i}: {} ({} x {} px at {} m)",
            l.name,
            l.grid.rows,
            l.grid.cols,
            l.grid.px_x_m
        );
    }
}

/// `--verbose`: the kernel files loaded.
pub fn detail_kernels(kernels: &Kernels) {
    crate::detail!("penumbra: kernels from {}", kernels.source().display());
    for f in &kernels.files {
        crate::detail!(
            "penumbra:   {} ({}, {} bytes, sha256 {})",
            f.path.display(),
            f.kind,
            f.size_bytes,
            f.sha256
        );
    }
}

impl TerrainSource {
    /// The DEM files with sizes and sha256, for provenance (none for the synthetic DEM).
    pub fn dem_files(&self) -> anyhow::Result<Vec<crate::output::InputFile>> {
        match self {
            TerrainSource::Synthetic(_) | TerrainSource::SyntheticWithFarField(_) => Ok(Vec::new()),
            TerrainSource::Dems(paths) => paths
                .iter()
                .map(|p| Ok(crate::output::InputFile::of(p)?))
                .collect(),
        }
    }
}

/// Loads DEM layers (GeoTIFF) into a terrain stack, finest first.
pub fn load_stack(paths: &[PathBuf]) -> anyhow::Result<TerrainStack> {
    if paths.is_empty() {
        anyhow::bail!("no DEM given (use --dem FILE, repeatable)");
    }
    let stack = TerrainStack::load(paths)?;
    require_polar_stereographic(&stack)?;
    Ok(stack)
}

/// Refuses a stack with an equirectangular layer, up front for every product. The readers take
/// equirectangular DEMs (`penumbra dem info` shows them), but the exact line sweep, the horizons
/// map engine and the GPU horizon scan follow straight lines of a polar stereographic map, so a
/// product would work or fail depending on its engine (and `--engine auto` on the epoch count).
pub fn require_polar_stereographic(stack: &TerrainStack) -> anyhow::Result<()> {
    if let Some(layer) = stack.layers.iter().find(|l| {
        !matches!(
            l.projection,
            crate::terrain::Projection::PolarStereographic { .. }
        )
    }) {
        anyhow::bail!(
            "DEM {}: equirectangular; penumbra's products need polar stereographic DEMs (the \
             horizon sweep follows straight map lines): reproject it first, e.g. `gdalwarp \
             -t_srs IAU_2015:30135 -r bilinear in.tif out.tif` for the south pole",
            layer.name
        );
    }
    Ok(())
}

/// The built-in synthetic DEM as a one-layer stack, and its description for provenance.
pub fn synthetic_stack(params: &SynthParams) -> anyhow::Result<(TerrainStack, String)> {
    let dem = crate::terrain::synth::south_polar_dem(params)?;
    let what = format!(
        "synthetic south-polar DEM ({} x {} px at {} m, seed {})",
        params.size_px, params.size_px, params.px_m, params.seed
    );
    Ok((TerrainStack::new(vec![dem]), what))
}

/// The built-in synthetic DEM and its far field
/// ([`crate::terrain::synth::south_polar_far_field`]) as a two-layer stack, and one
/// description per layer for provenance. (Per-epoch map engines build one model grid at the
/// near pixel over every layer: 16 M cells for the default's ±200 km far field.)
pub fn synthetic_stack_with_far_field(
    params: &SynthParams,
) -> anyhow::Result<(TerrainStack, Vec<String>)> {
    let (near, what) = synthetic_stack(params)?;
    let far = crate::terrain::synth::south_polar_far_field(&near.layers[0], params)?;
    let far_what = format!(
        "synthetic far field ({} x {} px at {} m, seed {})",
        far.grid.rows, far.grid.cols, far.grid.px_x_m, params.seed
    );
    let mut layers = near.layers;
    layers.push(far);
    Ok((TerrainStack::new(layers), vec![what, far_what]))
}

/// Where the SPICE kernels come from: a folder or a meta-kernel (`.tm`), or the default search
/// ([`crate::ephem::kernels::default_kernel_dir`]: `$PENUMBRA_KERNELS`, else the set built into
/// penumbra).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct KernelSource {
    /// The kernel folder or meta-kernel; `None` for the default search.
    pub dir: Option<PathBuf>,
}

impl KernelSource {
    /// The folder that will be read.
    pub fn dir(&self) -> PathBuf {
        self.dir
            .clone()
            .unwrap_or_else(crate::ephem::kernels::default_kernel_dir)
    }

    /// Loads the kernels.
    pub fn load(&self) -> anyhow::Result<Kernels> {
        let kernels = Kernels::load(&self.dir()).context("loading SPICE kernels")?;
        detail_kernels(&kernels);
        Ok(kernels)
    }
}

/// Formats an error chain on one line (`outer: inner: root cause`), as the binary prints it.
pub fn one_line(err: &anyhow::Error) -> String {
    // The context chain, each cause once: error types that print their source in their own
    // message (`reading DEM x: <io error>`) would otherwise show it twice.
    let mut out = err.to_string();
    let mut last = out.clone();
    for cause in err.chain().skip(1) {
        let text = cause.to_string();
        if let Some(rest) = text.strip_prefix(last.as_str()) {
            // `writing x` then `writing x: why`: only the new part.
            out.push_str(rest);
        } else if !out.contains(&text) {
            out.push_str(": ");
            out.push_str(&text);
        }
        last = text;
    }
    out.replace('\n', " ")
}

/// Writes to `out` atomically (temporary file, then rename), or to stdout.
pub fn write_output(
    out: Option<&Path>,
    fill: impl FnOnce(&mut dyn Write) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    match out {
        Some(path) => crate::output::write_atomic(path, fill)
            .with_context(|| format!("writing {}", path.display())),
        None => {
            let stdout = std::io::stdout();
            let mut lock = stdout.lock();
            fill(&mut lock)?;
            lock.flush().ok();
            Ok(())
        }
    }
}

pub(crate) use crate::output::progress_bar;
