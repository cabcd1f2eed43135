//! The solar panel, load and battery options of `penumbra series` and `penumbra map`.

use std::path::PathBuf;

use clap::Args;

/// A solar panel on the site's mast, its load and its battery ([`penumbra::illum::power`]).
#[derive(Debug, Args, Clone, Default)]
pub struct PowerArgs {
    /// Power: the orientation of a solar panel on the mast (its centre at the observer height):
    /// vertical-tracking (the polar default), horizontal, vertical-fixed:AZ_DEG or two-axis.
    /// Any power option turns power on: series add power_w (and battery_wh with --battery-wh)
    /// to series.csv and mean_power_w, required_battery_wh to stats.json; maps add
    /// mean_power_w.tif and required_battery_wh.tif (docs/power.md).
    #[arg(long, value_name = "PANEL")]
    pub panel: Option<String>,
    /// Panel area, m² (default 1).
    #[arg(long, value_name = "M2", allow_hyphen_values = true)]
    pub panel_area_m2: Option<f64>,
    /// Panel efficiency, 0 … 1 (default 0.30).
    #[arg(long, value_name = "FRACTION", allow_hyphen_values = true)]
    pub panel_efficiency: Option<f64>,
    /// Linear loss of panel efficiency per year, % (default 0).
    #[arg(long, value_name = "PCT", allow_hyphen_values = true)]
    pub panel_degradation_pct_per_year: Option<f64>,
    /// Load, W (default 100), while any part of the Sun is visible (and at night without
    /// --night-load-w).
    #[arg(long, value_name = "W", allow_hyphen_values = true)]
    pub load_w: Option<f64>,
    /// Load while the Sun is entirely hidden, W.
    #[arg(long, value_name = "W", allow_hyphen_values = true)]
    pub night_load_w: Option<f64>,
    /// A time-varying load instead of --load-w / --night-load-w: a CSV file with the header
    /// start_utc,stop_utc,load_w[,night_load_w], one row per interval [start, stop), each row
    /// starting where the one before stops, covering every epoch.
    #[arg(long, value_name = "FILE")]
    pub load_profile: Option<PathBuf>,
    /// Battery capacity, Wh (series): adds battery_wh (the charge at each epoch) to series.csv
    /// and min_battery_wh, hours_below_empty_h to stats.json.
    #[arg(long, value_name = "WH", allow_hyphen_values = true)]
    pub battery_wh: Option<f64>,
    /// Battery charge at the first epoch, % of the capacity (default 100).
    #[arg(long, value_name = "PCT", allow_hyphen_values = true)]
    pub battery_start_pct: Option<f64>,
}

impl PowerArgs {
    /// The panel, load and battery of these options; `None` when none is given.
    pub fn config(&self) -> anyhow::Result<Option<penumbra::illum::power::PowerConfig>> {
        use penumbra::illum::power::{PowerConfig, PowerOptions};
        Ok(PowerConfig::from_options(&PowerOptions {
            panel: self.panel.as_deref(),
            area_m2: self.panel_area_m2,
            efficiency: self.panel_efficiency,
            degradation_pct_per_year: self.panel_degradation_pct_per_year,
            load_w: self.load_w,
            night_load_w: self.night_load_w,
            battery_wh: self.battery_wh,
            battery_start_pct: self.battery_start_pct,
            load_profile: self.load_profile.as_deref(),
        })?)
    }
}
