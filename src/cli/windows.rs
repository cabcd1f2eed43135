//! `penumbra windows`.

use clap::Args;
use penumbra::products::windows::{Profile, ProfileOptions};

use super::series::SeriesArgs;

/// Arguments of `penumbra windows`: a series (every `penumbra series` option; its files are
/// written too) and a mission profile.
#[derive(Debug, Clone, Args)]
pub struct WindowsArgs {
    /// The series the windows are found in.
    #[command(flatten)]
    pub series: SeriesArgs,
    /// A preset mission profile: artemis3 (156 h, 100 % lit, >= 50 % DTE, <= 48 h blackout),
    /// clps (240 h, >= 70 % lit, <= 48 h dark, >= 60 % DTE) or rover (2400 h, >= 55 % lit,
    /// <= 110 h dark, >= 50 % DTE, <= 200 h blackout). The options below override its values.
    #[arg(long, value_name = "NAME")]
    pub profile: Option<String>,
    /// Length of the stay, hours (required without --profile).
    #[arg(long, value_name = "H", allow_hyphen_values = true)]
    pub stay_h: Option<f64>,
    /// The Sun's visible fraction at every epoch of the stay >= F (0 … 1).
    #[arg(long, value_name = "F", allow_hyphen_values = true)]
    pub min_sun_fraction: Option<f64>,
    /// % of the stay with any part of the Sun visible >= P.
    #[arg(long, value_name = "P", allow_hyphen_values = true)]
    pub min_lit_pct: Option<f64>,
    /// Longest time without the Sun within the stay <= H hours.
    #[arg(long, value_name = "H", allow_hyphen_values = true)]
    pub max_dark_h: Option<f64>,
    /// % of the stay with direct-to-Earth >= P (needs stations, the DSN by default).
    #[arg(long, value_name = "P", allow_hyphen_values = true)]
    pub min_dte_pct: Option<f64>,
    /// Longest time without direct-to-Earth within the stay <= H hours.
    #[arg(long, value_name = "H", allow_hyphen_values = true)]
    pub max_blackout_h: Option<f64>,
    /// The Sun's centre at touchdown (a stay's first epoch) at least DEG above the local
    /// horizontal.
    #[arg(long, value_name = "DEG", allow_hyphen_values = true)]
    pub min_touchdown_sun_el_deg: Option<f64>,
    /// The Sun's centre at touchdown at most DEG above the local horizontal.
    #[arg(long, value_name = "DEG", allow_hyphen_values = true)]
    pub max_touchdown_sun_el_deg: Option<f64>,
}

/// Runs `penumbra windows`.
pub fn run(args: &WindowsArgs) -> anyhow::Result<()> {
    let profile = Profile::from_options(
        args.profile.as_deref(),
        ProfileOptions {
            stay_h: args.stay_h,
            min_sun_fraction: args.min_sun_fraction,
            min_lit_pct: args.min_lit_pct,
            max_dark_h: args.max_dark_h,
            min_dte_pct: args.min_dte_pct,
            max_blackout_h: args.max_blackout_h,
            min_touchdown_sun_el_deg: args.min_touchdown_sun_el_deg,
            max_touchdown_sun_el_deg: args.max_touchdown_sun_el_deg,
        },
    )?;
    let req = super::series::request(&args.series)?;
    penumbra::products::windows::run(&req, &profile)?;
    Ok(())
}
