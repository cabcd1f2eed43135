//! Runs a parsed command line: the glue between [`crate::cli`] and the library.

use crate::cli::{Cli, Command};

/// Runs one invocation of the tool.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Kernels => Ok(()),
        Command::Dem { command } => run_dem(command),
    }
}

/// `penumbra dem info|synth`.
fn run_dem(command: crate::cli::DemCommand) -> anyhow::Result<()> {
    use crate::cli::{DemCommand, InfoFormat};
    use crate::terrain::{self, DemInfo, synth};
    use anyhow::Context as _;
    match command {
        DemCommand::Info { file, format, at } => {
            let dem = terrain::load_dem(&file)?;
            let info = DemInfo::of(&dem);
            let stack = terrain::TerrainStack::new(vec![dem]);
            let mut points = Vec::new();
            for spec in &at {
                let (lat, lon) = spec
                    .split_once(',')
                    .and_then(|(a, b)| {
                        Some((a.trim().parse::<f64>().ok()?, b.trim().parse::<f64>().ok()?))
                    })
                    .with_context(|| format!("--at {spec:?}: expected LAT,LON in degrees"))?;
                let (h, _) = stack.height_at_lat_lon_m_checked(lat, lon)?;
                points.push((lat, lon, h));
            }
            match format {
                InfoFormat::Text => {
                    print!("{}", info.to_text());
                    for (lat, lon, h) in &points {
                        println!("height at {lat}, {lon}: {h:.3} m");
                    }
                }
                InfoFormat::Json => {
                    let mut v = serde_json::to_value(&info)?;
                    v["points"] = points
                        .iter()
                        .map(|(lat, lon, h)| serde_json::json!({"lat_deg": lat, "lon_deg": lon, "height_m": h}))
                        .collect();
                    println!("{}", serde_json::to_string_pretty(&v)?);
                }
            }
            Ok(())
        }
        DemCommand::Synth {
            size,
            px_m,
            seed,
            out,
        } => {
            let dem = synth::south_polar_dem(&synth::SynthParams {
                size_px: size,
                px_m,
                seed,
            })?;
            let (version, seed_s) = (env!("CARGO_PKG_VERSION").to_string(), seed.to_string());
            let (size_s, px_s) = (size.to_string(), px_m.to_string());
            terrain::write_dem(
                &out,
                &dem,
                &[
                    ("software", &format!("penumbra {version}")),
                    ("synth_seed", &seed_s),
                    ("synth_size_px", &size_s),
                    ("synth_px_m", &px_s),
                    ("units", "m above the 1737.4 km sphere"),
                ],
            )?;
            Ok(())
        }
    }
}

/// Formats an error chain on one line (`outer: inner: root cause`), as `main` prints it.
pub fn one_line(err: &anyhow::Error) -> String {
    format!("{err:#}").replace('\n', " ")
}
