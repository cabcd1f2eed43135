//! `penumbra windows`: landing windows. Every start epoch whose stay satisfies a mission profile
//! (stay length, lit fraction, longest dark, DTE share, longest blackout) at each site of a
//! series, merged into windows of consecutive valid starts, ranked; `windows.csv`,
//! `windows.json` and `windows.ics` beside the series' own files. Definitions: `docs/power.md`,
//! "Landing windows".

use std::path::Path;

use hifitime::{Duration, Epoch};
use serde::{Deserialize, Serialize};

use super::series::{SeriesRequest, SiteOutcome};

/// A mission profile: what a stay starting at an epoch must satisfy. `None` = no condition.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Profile {
    /// Length of the stay, hours (> 0).
    pub stay_h: f64,
    /// The Sun's visible fraction at every sample of the stay ≥ this (0 … 1).
    pub min_sun_fraction: Option<f64>,
    /// % of the stay with any part of the Sun visible ≥ this.
    pub min_lit_pct: Option<f64>,
    /// Longest run without any part of the Sun within the stay ≤ this, hours.
    pub max_dark_h: Option<f64>,
    /// % of the stay with direct-to-Earth ≥ this (needs ground stations).
    pub min_dte_pct: Option<f64>,
    /// Longest run without direct-to-Earth within the stay ≤ this, hours (needs stations).
    pub max_blackout_h: Option<f64>,
    /// The Sun's centre at touchdown (the stay's first epoch) at least this high above the
    /// local horizontal, degrees.
    pub min_touchdown_sun_el_deg: Option<f64>,
    /// … and at most this high, degrees.
    pub max_touchdown_sun_el_deg: Option<f64>,
}

impl Profile {
    /// The presets: `artemis3` (156 h, 100 % lit, ≥ 50 % DTE, ≤ 48 h blackout), `clps` (240 h,
    /// ≥ 70 % lit, ≤ 48 h dark, ≥ 60 % DTE), `rover` (2,400 h, ≥ 55 % lit, ≤ 110 h dark, ≥ 50 %
    /// DTE, ≤ 200 h blackout), as LunaHorizon defines them.
    pub fn preset(name: &str) -> anyhow::Result<Self> {
        let p = |stay_h, lit, dark, dte, blackout| Profile {
            stay_h,
            min_sun_fraction: None,
            min_lit_pct: Some(lit),
            max_dark_h: dark,
            min_dte_pct: Some(dte),
            max_blackout_h: blackout,
            min_touchdown_sun_el_deg: None,
            max_touchdown_sun_el_deg: None,
        };
        Ok(match name {
            "artemis3" => p(156.0, 100.0, None, 50.0, Some(48.0)),
            "clps" => p(240.0, 70.0, Some(48.0), 60.0, None),
            "rover" => p(2400.0, 55.0, Some(110.0), 50.0, Some(200.0)),
            o => anyhow::bail!("profile '{o}': use artemis3, clps or rover"),
        })
    }

    /// A preset (or none) with the given values overriding it; without a preset `stay_h` is
    /// required. The command line and Python build their profile here.
    pub fn from_options(preset: Option<&str>, o: ProfileOptions) -> anyhow::Result<Self> {
        let mut p = match preset {
            Some(name) => Profile::preset(name)?,
            None => Profile {
                stay_h: o
                    .stay_h
                    .ok_or_else(|| anyhow::anyhow!("give a stay (--stay-h H) or a profile"))?,
                min_sun_fraction: None,
                min_lit_pct: None,
                max_dark_h: None,
                min_dte_pct: None,
                max_blackout_h: None,
                min_touchdown_sun_el_deg: None,
                max_touchdown_sun_el_deg: None,
            },
        };
        if let Some(h) = o.stay_h {
            p.stay_h = h;
        }
        let set = |slot: &mut Option<f64>, v: Option<f64>| {
            if v.is_some() {
                *slot = v;
            }
        };
        set(&mut p.min_sun_fraction, o.min_sun_fraction);
        set(&mut p.min_lit_pct, o.min_lit_pct);
        set(&mut p.max_dark_h, o.max_dark_h);
        set(&mut p.min_dte_pct, o.min_dte_pct);
        set(&mut p.max_blackout_h, o.max_blackout_h);
        set(&mut p.min_touchdown_sun_el_deg, o.min_touchdown_sun_el_deg);
        set(&mut p.max_touchdown_sun_el_deg, o.max_touchdown_sun_el_deg);
        Ok(p)
    }

    /// Checks every number; `has_dte`: the run has ground stations.
    pub fn validate(&self, has_dte: bool) -> anyhow::Result<()> {
        let in_range = |what: &str, v: Option<f64>, lo: f64, hi: f64| -> anyhow::Result<()> {
            if let Some(v) = v
                && !(v.is_finite() && v >= lo && v <= hi)
            {
                anyhow::bail!("{what} {v} is outside [{lo}, {hi}]");
            }
            Ok(())
        };
        if !(self.stay_h.is_finite() && self.stay_h > 0.0) {
            anyhow::bail!("stay {} h: give a positive length (--stay-h)", self.stay_h);
        }
        in_range("minimum Sun fraction", self.min_sun_fraction, 0.0, 1.0)?;
        in_range("minimum lit %", self.min_lit_pct, 0.0, 100.0)?;
        in_range("minimum DTE %", self.min_dte_pct, 0.0, 100.0)?;
        in_range("longest dark (h)", self.max_dark_h, 0.0, f64::MAX)?;
        in_range("longest blackout (h)", self.max_blackout_h, 0.0, f64::MAX)?;
        in_range(
            "minimum touchdown Sun elevation (deg)",
            self.min_touchdown_sun_el_deg,
            -90.0,
            90.0,
        )?;
        in_range(
            "maximum touchdown Sun elevation (deg)",
            self.max_touchdown_sun_el_deg,
            -90.0,
            90.0,
        )?;
        if let (Some(lo), Some(hi)) = (self.min_touchdown_sun_el_deg, self.max_touchdown_sun_el_deg)
            && lo > hi
        {
            anyhow::bail!(
                "touchdown Sun elevation: the minimum {lo} deg is above the maximum {hi} deg"
            );
        }
        if !has_dte && (self.min_dte_pct.is_some() || self.max_blackout_h.is_some()) {
            anyhow::bail!(
                "the profile asks for direct-to-Earth (DTE % or blackout) but the run has no ground stations (--stations none)"
            );
        }
        Ok(())
    }
}

/// The values that override a preset ([`Profile::from_options`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct ProfileOptions {
    /// Length of the stay, hours.
    pub stay_h: Option<f64>,
    /// Minimum Sun fraction at every sample.
    pub min_sun_fraction: Option<f64>,
    /// Minimum lit %.
    pub min_lit_pct: Option<f64>,
    /// Longest dark, hours.
    pub max_dark_h: Option<f64>,
    /// Minimum DTE %.
    pub min_dte_pct: Option<f64>,
    /// Longest blackout, hours.
    pub max_blackout_h: Option<f64>,
    /// Lowest Sun elevation at touchdown, degrees.
    pub min_touchdown_sun_el_deg: Option<f64>,
    /// Highest Sun elevation at touchdown, degrees.
    pub max_touchdown_sun_el_deg: Option<f64>,
}

/// The figures of one stay.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StayFigures {
    /// Smallest visible Sun fraction.
    pub sun_fraction_min: f64,
    /// % of the stay with any part of the Sun visible.
    pub lit_pct: f64,
    /// Longest run without the Sun, hours.
    pub longest_dark_h: f64,
    /// % of the stay with DTE (`NaN` without stations).
    pub dte_pct: f64,
    /// Longest run without DTE, hours (`NaN` without stations).
    pub longest_blackout_h: f64,
    /// The Sun's elevation at touchdown (the stay's first sample), degrees.
    pub touchdown_sun_el_deg: f64,
}

/// The samples of a stay of `stay_h` hours with samples `step_s` apart: each sample holds for
/// one step, so a stay covers `ceil(stay / step)` samples.
pub fn stay_samples(stay_h: f64, step_s: f64) -> usize {
    ((stay_h * 3600.0 / step_s) - 1e-9).ceil().max(1.0) as usize
}

/// The length of the longest run of `pred` over `0..m`.
fn longest(m: usize, pred: impl Fn(usize) -> bool) -> usize {
    crate::illum::stats::longest_run(m, pred).map_or(0, |r| r.len)
}

/// A site's samples: the Sun's visible fraction, its elevation and direct-to-Earth (with
/// stations), one per epoch.
#[derive(Debug, Clone, Copy)]
pub struct SiteSamples<'a> {
    /// The Sun's visible fraction.
    pub sun: &'a [f64],
    /// The Sun's centre's elevation above the local horizontal, degrees.
    pub sun_el_deg: &'a [f64],
    /// Direct-to-Earth (`None` without stations).
    pub dte: Option<&'a [bool]>,
}

/// The figures of the stay of `m` samples starting at sample `k`.
pub fn stay_figures(x: SiteSamples<'_>, k: usize, m: usize, step_h: f64) -> StayFigures {
    let SiteSamples {
        sun,
        sun_el_deg,
        dte,
    } = x;
    let s = &sun[k..k + m];
    let lit = s.iter().filter(|&&f| f > 0.0).count();
    let (dte_pct, longest_blackout_h) = match dte {
        Some(d) => {
            let d = &d[k..k + m];
            (
                100.0 * d.iter().filter(|&&x| x).count() as f64 / m as f64,
                longest(m, |i| !d[i]) as f64 * step_h,
            )
        }
        None => (f64::NAN, f64::NAN),
    };
    StayFigures {
        sun_fraction_min: s.iter().copied().fold(f64::INFINITY, f64::min),
        lit_pct: 100.0 * lit as f64 / m as f64,
        longest_dark_h: longest(m, |i| s[i] <= 0.0) as f64 * step_h,
        dte_pct,
        longest_blackout_h,
        touchdown_sun_el_deg: sun_el_deg[k],
    }
}

/// Whether a stay's figures satisfy `p`.
pub fn satisfies(p: &Profile, f: &StayFigures) -> bool {
    p.min_sun_fraction.is_none_or(|v| f.sun_fraction_min >= v)
        && p.min_lit_pct.is_none_or(|v| f.lit_pct >= v - 1e-9)
        && p.max_dark_h.is_none_or(|v| f.longest_dark_h <= v + 1e-9)
        && p.min_dte_pct.is_none_or(|v| f.dte_pct >= v - 1e-9)
        && p.max_blackout_h
            .is_none_or(|v| f.longest_blackout_h <= v + 1e-9)
        && p.min_touchdown_sun_el_deg
            .is_none_or(|v| f.touchdown_sun_el_deg >= v)
        && p.max_touchdown_sun_el_deg
            .is_none_or(|v| f.touchdown_sun_el_deg <= v)
}

/// A landing window: consecutive valid start epochs at a site and the worst figures among them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Window {
    /// The site.
    pub site: String,
    /// Rank at the site (1 = the most valid starts; ties by the earlier window).
    pub rank: usize,
    /// First valid start (UTC, ISO 8601).
    pub first_start_utc: String,
    /// Last valid start (UTC).
    pub last_start_utc: String,
    /// Number of valid starts.
    pub starts: usize,
    /// Length of the stay, hours.
    pub stay_h: f64,
    /// Worst (smallest) Sun fraction over the window's stays.
    pub min_sun_fraction: f64,
    /// Worst lit %.
    pub min_lit_pct: f64,
    /// Worst longest dark, hours.
    pub max_dark_h: f64,
    /// Worst DTE % (`null` without stations).
    pub min_dte_pct: Option<f64>,
    /// Worst longest blackout, hours (`null` without stations).
    pub max_blackout_h: Option<f64>,
    /// Lowest Sun elevation at touchdown among the window's starts, degrees.
    pub min_touchdown_sun_el_deg: f64,
    /// Highest, degrees.
    pub max_touchdown_sun_el_deg: f64,
    #[serde(skip)]
    first: usize,
    #[serde(skip)]
    last: usize,
}

/// The windows of one site: its samples from `start` every `step_s`.
pub fn site_windows(
    site: &str,
    x: SiteSamples<'_>,
    start: Epoch,
    step_s: f64,
    p: &Profile,
) -> Vec<Window> {
    let m = stay_samples(p.stay_h, step_s);
    let step_h = step_s / 3600.0;
    let n = x.sun.len().min(x.sun_el_deg.len());
    let dte = x.dte;
    let mut out: Vec<Window> = Vec::new();
    if m > n {
        return out;
    }
    let at = |k: usize| {
        crate::ephem::time::format_iso(start + Duration::from_seconds(k as f64 * step_s))
    };
    for k in 0..=n - m {
        let f = stay_figures(x, k, m, step_h);
        if !satisfies(p, &f) {
            continue;
        }
        match out.last_mut() {
            Some(w) if w.last + 1 == k => {
                w.last = k;
                w.starts += 1;
                w.last_start_utc = at(k);
                w.min_sun_fraction = w.min_sun_fraction.min(f.sun_fraction_min);
                w.min_lit_pct = w.min_lit_pct.min(f.lit_pct);
                w.max_dark_h = w.max_dark_h.max(f.longest_dark_h);
                w.min_dte_pct = w.min_dte_pct.map(|v| v.min(f.dte_pct));
                w.max_blackout_h = w.max_blackout_h.map(|v| v.max(f.longest_blackout_h));
                w.min_touchdown_sun_el_deg = w.min_touchdown_sun_el_deg.min(f.touchdown_sun_el_deg);
                w.max_touchdown_sun_el_deg = w.max_touchdown_sun_el_deg.max(f.touchdown_sun_el_deg);
            }
            _ => out.push(Window {
                site: site.to_string(),
                rank: 0,
                first_start_utc: at(k),
                last_start_utc: at(k),
                starts: 1,
                stay_h: m as f64 * step_h,
                min_sun_fraction: f.sun_fraction_min,
                min_lit_pct: f.lit_pct,
                max_dark_h: f.longest_dark_h,
                min_dte_pct: dte.map(|_| f.dte_pct),
                max_blackout_h: dte.map(|_| f.longest_blackout_h),
                min_touchdown_sun_el_deg: f.touchdown_sun_el_deg,
                max_touchdown_sun_el_deg: f.touchdown_sun_el_deg,
                first: k,
                last: k,
            }),
        }
    }
    let mut order: Vec<usize> = (0..out.len()).collect();
    order.sort_by(|&a, &b| out[b].starts.cmp(&out[a].starts).then(a.cmp(&b)));
    for (r, i) in order.into_iter().enumerate() {
        out[i].rank = r + 1;
    }
    out
}

/// The windows of every site of a series run (its outcomes: Sun fractions and DTE flags).
pub fn run_windows(
    outcomes: &[SiteOutcome],
    start: Epoch,
    step_s: f64,
    profile: &Profile,
) -> Vec<Window> {
    outcomes
        .iter()
        .flat_map(|o| {
            let x = SiteSamples {
                sun: &o.sun_fraction,
                sun_el_deg: &o.sun_el_deg,
                dte: (!o.dte.is_empty()).then_some(o.dte.as_slice()),
            };
            site_windows(o.site.name(), x, start, step_s, profile)
        })
        .collect()
}

/// A scenario's `[windows]` table: a preset and/or the values that override it (as
/// `penumbra windows`), found in the scenario's series (needs `[series]`).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindowsSpec {
    /// `artemis3`, `clps` or `rover`.
    pub profile: Option<String>,
    /// Length of the stay, hours.
    pub stay_h: Option<f64>,
    /// Minimum Sun fraction at every sample.
    pub min_sun_fraction: Option<f64>,
    /// Minimum lit %.
    pub min_lit_pct: Option<f64>,
    /// Longest dark, hours.
    pub max_dark_h: Option<f64>,
    /// Minimum DTE %.
    pub min_dte_pct: Option<f64>,
    /// Longest blackout, hours.
    pub max_blackout_h: Option<f64>,
    /// Lowest Sun elevation at touchdown, degrees.
    pub min_touchdown_sun_el_deg: Option<f64>,
    /// Highest Sun elevation at touchdown, degrees.
    pub max_touchdown_sun_el_deg: Option<f64>,
}

impl WindowsSpec {
    /// The profile of this table.
    pub fn profile(&self) -> anyhow::Result<Profile> {
        Profile::from_options(
            self.profile.as_deref(),
            ProfileOptions {
                stay_h: self.stay_h,
                min_sun_fraction: self.min_sun_fraction,
                min_lit_pct: self.min_lit_pct,
                max_dark_h: self.max_dark_h,
                min_dte_pct: self.min_dte_pct,
                max_blackout_h: self.max_blackout_h,
                min_touchdown_sun_el_deg: self.min_touchdown_sun_el_deg,
                max_touchdown_sun_el_deg: self.max_touchdown_sun_el_deg,
            },
        )
    }
}

/// Refuses a stay longer than a series of `n` samples `step_s` apart.
pub fn check_stay(profile: &Profile, n: usize, step_s: f64) -> anyhow::Result<()> {
    if stay_samples(profile.stay_h, step_s) > n {
        anyhow::bail!(
            "stay of {} h is longer than the period ({} epochs of {} s)",
            profile.stay_h,
            n,
            step_s
        );
    }
    Ok(())
}

/// The CSV header of `windows.csv`.
pub const WINDOWS_CSV_HEADER: &str = "site,rank,first_start_utc,last_start_utc,starts,stay_h,min_sun_fraction,min_lit_pct,max_dark_h,min_dte_pct,max_blackout_h,min_touchdown_sun_el_deg,max_touchdown_sun_el_deg";

/// The series the windows were found in: its first epoch, the step and the number of samples, and
/// its sites in order (the timeline's rows).
#[derive(Debug, Clone, Copy)]
pub struct SeriesSpan<'a> {
    /// First epoch.
    pub start: Epoch,
    /// Seconds between samples.
    pub step_s: f64,
    /// Samples per site.
    pub samples: usize,
    /// The sites, in order.
    pub sites: &'a [String],
}

/// Writes `windows.csv`, `windows.json`, `windows.ics` and (with `plot`) the timeline
/// `windows.png` into `out_dir`; returns their names.
pub fn write_files(
    out_dir: &Path,
    windows: &[Window],
    profile: &Profile,
    span: SeriesSpan<'_>,
    plot: bool,
) -> anyhow::Result<Vec<String>> {
    let SeriesSpan { start, step_s, .. } = span;
    let opt = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:.3}"));
    crate::output::write_atomic(&out_dir.join("windows.csv"), |w| -> anyhow::Result<()> {
        writeln!(w, "{WINDOWS_CSV_HEADER}")?;
        for x in windows {
            let name = crate::products::series::csv_field(&x.site);
            writeln!(
                w,
                "{name},{},{},{},{},{:.3},{:.6},{:.3},{:.3},{},{},{:.3},{:.3}",
                x.rank,
                x.first_start_utc,
                x.last_start_utc,
                x.starts,
                x.stay_h,
                x.min_sun_fraction,
                x.min_lit_pct,
                x.max_dark_h,
                opt(x.min_dte_pct),
                opt(x.max_blackout_h),
                x.min_touchdown_sun_el_deg,
                x.max_touchdown_sun_el_deg
            )?;
        }
        Ok(())
    })?;
    let json = serde_json::json!({ "profile": profile, "windows": windows });
    crate::output::write_atomic(&out_dir.join("windows.json"), |w| -> anyhow::Result<()> {
        serde_json::to_writer_pretty(&mut *w, &json)?;
        writeln!(w)?;
        Ok(())
    })?;
    // The calendar: one event per window, from its first start to the end of its last stay.
    let events: Vec<crate::comms::IcsEvent> = windows
        .iter()
        .map(|x| {
            let first = start + Duration::from_seconds(x.first as f64 * step_s);
            let span_s = (x.last - x.first) as f64 * step_s + x.stay_h * 3600.0;
            crate::comms::IcsEvent {
                start: first,
                end: first + Duration::from_seconds(span_s),
                id: format!("landing-{}-{}", x.site, x.rank),
                summary: format!(
                    "Landing window {} #{} ({} starts, {:.0} h stay)",
                    x.site, x.rank, x.starts, x.stay_h
                ),
            }
        })
        .collect();
    crate::comms::write_ics(&out_dir.join("windows.ics"), "landing windows", &events)?;
    let mut files = vec![
        "windows.csv".into(),
        "windows.json".into(),
        "windows.ics".into(),
    ];
    if plot && span.samples > 0 && !span.sites.is_empty() {
        write_timeline(&out_dir.join("windows.png"), windows, profile, span)?;
        files.push("windows.png".into());
    }
    Ok(files)
}

/// The timeline of the windows: one row per site, a bar over each window's valid touchdown
/// epochs (from its first start to one step after its last).
fn write_timeline(
    path: &Path,
    windows: &[Window],
    profile: &Profile,
    span: SeriesSpan<'_>,
) -> anyhow::Result<()> {
    const COLOURS: [(u8, u8, u8); 4] = [
        (31, 119, 180),
        (214, 39, 40),
        (44, 160, 44),
        (148, 103, 189),
    ];
    let on: Vec<Vec<bool>> = span
        .sites
        .iter()
        .map(|site| {
            let mut on = vec![false; span.samples];
            for w in windows.iter().filter(|w| &w.site == site) {
                on[w.first..=w.last.min(span.samples - 1)].fill(true);
            }
            on
        })
        .collect();
    let rows: Vec<crate::illum::plot::WindowRow<'_>> = span
        .sites
        .iter()
        .zip(&on)
        .enumerate()
        .map(|(i, (site, on))| crate::illum::plot::WindowRow {
            label: site,
            on,
            rgb: COLOURS[i % COLOURS.len()],
        })
        .collect();
    let height = (120 + 45 * rows.len()).min(2000) as u32;
    crate::illum::plot::write_windows_plot(
        path,
        &format!(
            "Landing windows: valid touchdown epochs ({:.0} h stay, {} window(s))",
            profile.stay_h,
            windows.len()
        ),
        span.start,
        span.step_s,
        &rows,
        (1400, height.max(260)),
    )?;
    Ok(())
}

/// Runs `penumbra windows`: the series of `req` (its files included), then the windows of
/// `profile` at each site.
pub fn run(req: &SeriesRequest, profile: &Profile) -> anyhow::Result<Vec<Window>> {
    let t0 = std::time::Instant::now();
    let has_dte = req
        .config
        .stations
        .resolve(req.config.station_mask_deg)?
        .is_some();
    profile.validate(has_dte)?;
    let step_s = req.epochs.step_s();
    check_stay(profile, req.epochs.epochs().len(), step_s)?;
    let (run, mut prov, _lock) = super::series::execute(req)?;
    let start = req.epochs.epochs()[0];
    let windows = run_windows(&run.outcomes, start, step_s, profile);
    let sites: Vec<String> = run
        .outcomes
        .iter()
        .map(|o| o.site.name().to_string())
        .collect();
    let span = SeriesSpan {
        start,
        step_s,
        samples: req.epochs.epochs().len(),
        sites: &sites,
    };
    prov.outputs.extend(write_files(
        &req.out_dir,
        &windows,
        profile,
        span,
        req.config.plots,
    )?);
    crate::note!(
        "penumbra: {} landing window(s) of {} h stays at {} site(s)",
        windows.len(),
        profile.stay_h,
        run.outcomes.len()
    );
    super::series::finish(req, prov, t0)?;
    Ok(windows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_merge_consecutive_valid_starts() {
        // 10 samples of 1 h; a 3 h stay needs 3 lit samples in a row.
        let sun = [0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 1.0, 1.0, 1.0, 0.5];
        let p = Profile {
            stay_h: 3.0,
            min_sun_fraction: Some(0.9),
            min_lit_pct: None,
            max_dark_h: None,
            min_dte_pct: None,
            max_blackout_h: None,
            min_touchdown_sun_el_deg: None,
            max_touchdown_sun_el_deg: None,
        };
        let t0 = Epoch::from_gregorian_utc_at_midnight(2025, 1, 1);
        let el = [0.5; 10];
        let x = SiteSamples {
            sun: &sun,
            sun_el_deg: &el,
            dte: None,
        };
        let w = site_windows("a", x, t0, 3600.0, &p);
        assert_eq!(w.len(), 2);
        assert_eq!(
            (w[0].first, w[0].last, w[0].starts, w[0].rank),
            (1, 2, 2, 1)
        );
        assert_eq!((w[1].first, w[1].last, w[1].rank), (6, 6, 2));
        assert_eq!(stay_samples(3.0, 3600.0), 3);
        assert_eq!(stay_samples(2.5, 3600.0), 3);
    }
}
