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
    /// Observer height above the ground (radial).
    pub observer_height: crate::model::ObserverHeight,
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
    crate::output::guard::check_output_target("--out", &req.out, false)
        .map_err(anyhow::Error::msg)?;
    let (stack, _) = req.terrain.load()?;
    let grid = crate::model::MapGrid::new(&stack)?;
    let hf = &grid.hf;
    let params = HorizonMapParams {
        observer_height_m: req.observer_height.m(),
        n_azimuths: req.azimuths,
        max_distance_cells: req.max_distance_cells.unwrap_or(hf.rows + hf.cols),
        n_coeffs: crate::shadow::fourier::DEFAULT_COEFFS,
    };
    params.check()?;
    // Resolved after the input checks: bad input is one error line, with no warning.
    let backend = crate::compute::resolve(req.backend, crate::compute::OnGpu::Preferred)?;
    let t0 = std::time::Instant::now();
    let map = crate::compute::horizons::horizon_map(&backend, hf, &params)?;
    map.write_tiff(&req.out)?;
    crate::note!(
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

/// What `penumbra horizon-map sweep` computes: exact whole-grid horizons by the line sweep
/// ([`crate::horizon::sweep`]) on the finest layer's grid, every layer included.
#[derive(Debug, Clone)]
pub struct HorizonSweepRequest {
    /// The terrain (every layer; one polar stereographic map).
    pub terrain: TerrainSource,
    /// Observer height above the ground (radial).
    pub observer_height: crate::model::ObserverHeight,
    /// Requested azimuths (uniform in grid azimuth).
    pub azimuths: usize,
    /// Largest step component of a sweep direction.
    pub max_step: u32,
    /// Output GeoTIFF of horizon elevations: one int16 band per direction, centi-degrees.
    pub out: PathBuf,
    /// Optional GeoTIFF of the distance to the horizon point: one float16 band per direction, km.
    pub distance_out: Option<PathBuf>,
    /// Compute backend: the CPU sweep, or its looks on the GPU.
    pub backend: Backend,
}

pub use crate::horizon::statistics::HORIZON_NODATA_I16;

/// Runs the sweep and streams the bands into the GeoTIFF(s) (written atomically).
pub fn sweep(req: &HorizonSweepRequest) -> anyhow::Result<()> {
    let mut outputs: Vec<(&str, &std::path::Path)> = vec![("--out", &req.out)];
    if let Some(d) = &req.distance_out {
        outputs.push(("--distance-out", d));
    }
    for (flag, path) in &outputs {
        crate::output::guard::check_output_target(flag, path, false).map_err(anyhow::Error::msg)?;
    }
    crate::output::guard::check_distinct_outputs(&outputs).map_err(anyhow::Error::msg)?;
    use crate::horizon::{HorizonSweep, SweepParams};
    use crate::terrain::geotiff::{BandSample, MultiBandTiff};

    let inputs = crate::products::Inputs::load(
        &req.terrain,
        &crate::products::KernelSource::default(),
        &[],
        crate::products::DemFiles::Record,
    )?;
    let stack = inputs.stack;
    let layers = crate::output::MadeWith::new(&inputs.provenance, f64::NAN, "", "", "")
        .layers
        .join("; ");
    let backend = crate::compute::resolve(req.backend, crate::compute::OnGpu::Preferred)?;
    let params = SweepParams {
        observer_height_m: req.observer_height.m(),
        azimuths: req.azimuths,
        max_step: req.max_step,
    };
    let sweep = HorizonSweep::new(&stack, params)?;
    let dem = sweep.grid_dem();
    let dirs = sweep.directions();
    let descriptions: Vec<String> = dirs
        .iter()
        .map(|d| {
            format!(
                "grid_az_deg={} step=({},{})",
                d.grid_az_deg, d.dcol, d.dnorth
            )
        })
        .collect();
    let worst_miss = dirs.iter().map(|d| d.target_error_deg).fold(0.0, f64::max);
    let version = env!("CARGO_PKG_VERSION");
    let h = format!("{}", req.observer_height);
    let ms = format!("{}", req.max_step);
    let metadata = [
        ("penumbra_version", version),
        (
            "penumbra_product",
            crate::horizon::statistics::HORIZON_PRODUCT,
        ),
        ("units", "centi-degrees above the local horizontal"),
        (
            "azimuth_convention",
            "band grid_az_deg: from map +y (grid north), clockwise; local azimuth = grid_az_deg + grid convergence at the pixel",
        ),
        ("observer_height_m", h.as_str()),
        ("max_step", ms.as_str()),
        ("dem_layers", layers.as_str()),
    ];
    let mut el_tif = MultiBandTiff::create(
        &req.out,
        &dem.grid,
        &dem.projection,
        BandSample::I16,
        &descriptions,
        &HORIZON_NODATA_I16.to_string(),
        &metadata,
    )?;
    let mut dist_tif = match &req.distance_out {
        Some(path) => Some(MultiBandTiff::create(
            path,
            &dem.grid,
            &dem.projection,
            BandSample::F16,
            &descriptions,
            "nan",
            &[
                ("penumbra_version", version),
                (
                    "penumbra_product",
                    "distance to the horizon point (line sweep)",
                ),
                ("units", "km (ground distance)"),
                ("observer_height_m", h.as_str()),
                ("max_step", ms.as_str()),
                ("dem_layers", layers.as_str()),
            ],
        )?),
        None => None,
    };
    let t0 = std::time::Instant::now();
    let progress = super::progress_bar(
        dirs.len(),
        "penumbra: sweep [{bar:40}] {pos}/{len} bands, {elapsed} (eta {eta})",
    );
    crate::compute::horizons::run_sweep(
        &backend,
        &sweep,
        |band| -> anyhow::Result<()> {
            let words: Vec<u16> = band
                .elevation_deg
                .iter()
                .map(|&e| crate::horizon::statistics::horizon_centideg(e) as u16)
                .collect();
            el_tif.write_band(band.index, &words)?;
            if let Some(t) = dist_tif.as_mut() {
                let words: Vec<u16> = band
                    .distance_m
                    .iter()
                    .map(|&d| half::f16::from_f32(d / 1000.0).to_bits())
                    .collect();
                t.write_band(band.index, &words)?;
            }
            Ok(())
        },
        |done| progress.set_position(done as u64),
    )?;
    progress.finish_and_clear();
    el_tif.finish()?;
    if let Some(t) = dist_tif {
        t.finish()?;
    }
    let secs = t0.elapsed().as_secs_f64();
    let pixel_az = (dem.grid.rows * dem.grid.cols * dirs.len()) as f64;
    crate::note!(
        "penumbra: horizons {} x {} x {} directions (requested {}, max step {}, largest miss {:.2} deg) in {:.1} s ({:.2} M pixel-azimuths/s, {}) -> {}",
        dem.grid.rows,
        dem.grid.cols,
        dirs.len(),
        req.azimuths,
        req.max_step,
        worst_miss,
        secs,
        pixel_az / secs / 1e6,
        backend.describe(),
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
