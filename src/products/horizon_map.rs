//! `penumbra horizon-map build|info`: Fourier-compressed horizon maps (paper 001).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::TerrainSource;
use crate::gpu::Backend;
use crate::shadow::fourier::{HorizonMap, HorizonMapParams};

/// What `penumbra horizon-map build` builds.
#[derive(Debug, Clone)]
pub struct HorizonMapBuildRequest {
    /// The terrain (every layer, on the map grid).
    pub terrain: TerrainSource,
    /// Observer height above the ground (radial), metres.
    pub observer_height_m: f64,
    /// Number of sampled azimuths before the DFT (at least 32).
    pub azimuths: usize,
    /// Longest horizon ray, cells; `None` for the grid's rows + columns.
    pub max_distance_cells: Option<usize>,
    /// Output TIFF.
    pub out: PathBuf,
    /// Compute backend of the build.
    pub backend: Backend,
}

/// Builds the horizon map and writes it as a multi-page TIFF (atomically).
pub fn build(req: &HorizonMapBuildRequest) -> anyhow::Result<()> {
    let (stack, _) = req.terrain.load()?;
    let grid = crate::model::MapGrid::new(&stack)?;
    let hf = &grid.hf;
    let params = HorizonMapParams {
        observer_height_m: req.observer_height_m,
        n_azimuths: req.azimuths,
        max_distance_cells: req.max_distance_cells.unwrap_or(hf.rows + hf.cols),
        n_coeffs: crate::shadow::fourier::DEFAULT_COEFFS,
    };
    params.check()?;
    // Resolved after the input checks: bad input is one error line, with no warning.
    let backend = crate::compute::resolve(req.backend)?;
    let t0 = std::time::Instant::now();
    let map = crate::compute::horizons::horizon_map(&backend, hf, &params)?;
    map.write_tiff(&req.out)?;
    eprintln!(
        "penumbra: horizon map {} x {} ({} azimuths, {} coefficients) on {} in {:.1} s -> {}",
        hf.rows,
        hf.cols,
        req.azimuths,
        map.meta.n_coeffs,
        backend.describe(),
        t0.elapsed().as_secs_f64(),
        req.out.display()
    );
    Ok(())
}

/// The description of a horizon-map TIFF: geometry, parameters, mean coefficient amplitudes.
pub fn info(file: &Path) -> anyhow::Result<String> {
    let map = HorizonMap::read_tiff(file)?;
    let m = &map.meta;
    let mut out = String::new();
    writeln!(out, "file: {}", file.display())?;
    writeln!(
        out,
        "grid: {} rows x {} cols at {} m",
        m.rows, m.cols, m.px_m
    )?;
    writeln!(
        out,
        "model origin: lat {:.6} deg, lon {:.6} deg; x_left {} m, y_top {} m",
        m.centre_lat_deg, m.centre_lon_deg, m.x_left_m, m.y_top_m
    )?;
    writeln!(
        out,
        "observer height: {} m; azimuths: {}; max distance: {} cells",
        m.observer_height_m, m.n_azimuths, m.max_distance_cells
    )?;
    writeln!(out, "coefficients: {} complex (f16)", m.n_coeffs)?;
    let amps: Vec<String> = map
        .mean_amplitudes_rad()
        .iter()
        .map(|a| format!("{:.4}", a.to_degrees()))
        .collect();
    writeln!(out, "mean |X_k| (deg): {}", amps.join(" "))?;
    Ok(out)
}
