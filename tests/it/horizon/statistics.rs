//! The horizons engine of `penumbra map` (statistics over an epoch range from whole-grid
//! horizons) against oracles built differently: the per-site series at pixel centres (per-site
//! horizon scan at 0.25°, exact strip integral), and the SPICE-exact topocentric ephemeris of
//! each pixel over a flat sphere (analytic horizon: the dip).

use std::path::Path;

use penumbra::horizon::statistics::{InMemoryHorizons, StatisticsEngine, StatisticsParams};
use penumbra::horizon::{HorizonSweep, SweepParams};
use penumbra::illum::LimbDarkening;
use penumbra::terrain::TerrainStack;

use crate::util::{assert_clean_error, files_in, kernels_dir, penumbra, penumbra_ok, read_tif};

/// Sun and Earth visible fractions and the best station's elevation of the site (deg) of one
/// site's `series.csv`.
fn series_fractions(path: &Path) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut rd = csv::Reader::from_path(path).unwrap();
    let h = rd.headers().unwrap().clone();
    let col = |name: &str| h.iter().position(|c| c == name).unwrap();
    let (s, e, st) = (
        col("sun_visible_fraction"),
        col("earth_visible_fraction"),
        col("station_el_deg"),
    );
    let (mut sun, mut earth, mut station) = (Vec::new(), Vec::new(), Vec::new());
    for r in rd.records() {
        let r = r.unwrap();
        sun.push(r[s].parse().unwrap());
        earth.push(r[e].parse().unwrap());
        station.push(r[st].parse().unwrap());
    }
    (sun, earth, station)
}

fn longest_run(hidden: impl Iterator<Item = bool>) -> usize {
    let (mut best, mut run) = (0, 0);
    for h in hidden {
        run = if h { run + 1 } else { 0 };
        best = best.max(run);
    }
    best
}

/// A map cell and a series site at that pixel's centre tell the same story: every statistic of
/// the horizons engine against the per-site series (another horizon algorithm, 1440 azimuths,
/// the exact strip integral) on a synthetic DEM, one year every 6 h; with the DSN, the map's
/// direct-to-Earth (any part of the Earth visible, one station flag per epoch from the grid
/// centre) against the series' own per-site stations and fractions.
#[test]
fn horizons_engine_agrees_with_series_at_pixel_centres() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let k = k.to_str().unwrap();
    penumbra_ok(
        dir.path(),
        &[
            "dem", "synth", "--size", "128", "--px-m", "100", "--seed", "3", "--out", "d.tif",
        ],
    );
    let epochs = [
        "--start",
        "2027-01-01",
        "--stop",
        "2027-12-31T18:00",
        "--step",
        "6h",
    ];
    penumbra_ok(
        dir.path(),
        &[
            &[
                "map",
                "--dem",
                "d.tif",
                "--engine",
                "horizons",
                "--backend",
                "cpu",
                "--stations",
                "dsn",
            ][..],
            &epochs,
            &["--out-dir", "maps", "--kernels", k],
        ]
        .concat(),
    );
    let dem = read_tif(dir.path(), "d.tif");
    // Pixels: the highest (peaks see the Sun below their horizontal), the steepest, and a
    // spread of others, away from the DEM's edge.
    let (rows, cols) = (dem.grid.rows, dem.grid.cols);
    let h = |r: usize, c: usize| f64::from(dem.heights_m[r * cols + c]);
    let mut by_height: Vec<(usize, usize)> = (10..rows - 10)
        .flat_map(|r| (10..cols - 10).map(move |c| (r, c)))
        .collect();
    by_height.sort_by(|a, b| h(b.0, b.1).total_cmp(&h(a.0, a.1)));
    let mut pixels: Vec<(usize, usize)> = by_height
        .iter()
        .step_by(by_height.len() / 10)
        .copied()
        .collect();
    pixels.extend(&by_height[..2]);
    let steep = by_height
        .iter()
        .max_by(|a, b| {
            let s = |&(r, c): &(usize, usize)| (h(r, c + 1) - h(r, c - 1)).abs();
            s(a).total_cmp(&s(b))
        })
        .copied()
        .unwrap();
    pixels.push(steep);
    let mut sites = Vec::new();
    for (i, &(r, c)) in pixels.iter().enumerate() {
        let (x, y) = dem.grid.xy_from_row_col(r as f64, c as f64);
        let (lat, lon) = dem.projection.lat_lon_from_xy(x, y);
        sites.push("--site".to_string());
        sites.push(format!("p{i},{lat:.10},{lon:.10},2"));
    }
    let site_args: Vec<&str> = sites.iter().map(String::as_str).collect();
    penumbra_ok(
        dir.path(),
        &[
            &["series", "--dem", "d.tif", "--no-plots"][..],
            &site_args,
            &epochs,
            &["--out-dir", "series", "--kernels", k],
        ]
        .concat(),
    );
    let maps = dir.path().join("maps");
    let band = |name: &str| read_tif(&maps, name).heights_m;
    let (m_vis, m_mean, m_earth, m_dark, m_full, m_ehid) = (
        band("sun_visible_pct.tif"),
        band("sun_illumination_pct.tif"),
        band("earth_visible_pct.tif"),
        band("longest_dark_h.tif"),
        band("sun_full_pct.tif"),
        band("longest_earth_hidden_h.tif"),
    );
    let (m_dte, m_blackout) = (band("dte_pct.tif"), band("longest_dte_blackout_h.tif"));
    let mut worst = [0.0_f64; 8];
    println!("pixel       h_m   sun% map/series   mean map/series   earth% map/series   dark h");
    for (i, &(r, c)) in pixels.iter().enumerate() {
        let (fs, fe, st) = series_fractions(&dir.path().join(format!("series/p{i}/series.csv")));
        let n = fs.len() as f64;
        let pct = |v: &[f64], t: f64| 100.0 * v.iter().filter(|&&f| f > t).count() as f64 / n;
        let s_vis = pct(&fs, 1e-6);
        let s_mean = fs.iter().sum::<f64>() / n;
        let s_earth = pct(&fe, 1e-6);
        let s_full = 100.0 * fs.iter().filter(|&&f| f >= 0.999).count() as f64 / n;
        let s_dark = 6.0 * longest_run(fs.iter().map(|&f| f <= 1e-6)) as f64;
        let s_ehid = 6.0 * longest_run(fe.iter().map(|&f| f <= 1e-6)) as f64;
        let dte: Vec<bool> = fe
            .iter()
            .zip(&st)
            .map(|(&f, &e)| f > 1e-6 && e >= 10.0)
            .collect();
        let s_dte = 100.0 * dte.iter().filter(|&&d| d).count() as f64 / n;
        let s_blackout = 6.0 * longest_run(dte.iter().map(|&d| !d)) as f64;
        let px = r * cols + c;
        let m = |v: &[f32]| f64::from(v[px]);
        println!(
            "({r:3},{c:3}) {:7.0}   {:6.2} / {:6.2}   {:.4} / {:.4}   {:6.2} / {:6.2}   {:5.0} / {:5.0}",
            h(r, c),
            m(&m_vis),
            s_vis,
            m(&m_mean) / 100.0,
            s_mean,
            m(&m_earth),
            s_earth,
            m(&m_dark),
            s_dark
        );
        let d = [
            (m(&m_vis) - s_vis).abs(),
            (m(&m_mean) / 100.0 - s_mean).abs(),
            (m(&m_earth) - s_earth).abs(),
            (m(&m_full) - s_full).abs(),
            (m(&m_dark) - s_dark).abs() / (0.02 * s_dark).max(6.0),
            (m(&m_ehid) - s_ehid).abs() / (0.02 * s_ehid).max(6.0),
            (m(&m_dte) - s_dte).abs(),
            (m(&m_blackout) - s_blackout).abs() / (0.02 * s_blackout).max(6.0),
        ];
        for (w, d) in worst.iter_mut().zip(d) {
            *w = w.max(d);
        }
    }
    println!(
        "worst: sun% {:.3} pp, mean {:.4}, earth% {:.3} pp, full% {:.3} pp, longest dark {:.3} \
         (of max(6 h, 2 %)), longest Earth-hidden {:.3}, DTE% {:.3} pp, longest DTE \
         blackout {:.3}",
        worst[0], worst[1], worst[2], worst[3], worst[4], worst[5], worst[6], worst[7]
    );
    // The tolerances: % lit within 0.5 pp, mean fraction within 0.005, longest night
    // within max(3 h, 2 %); with 6 h steps one step is the floor: the longest runs are divided
    // by max(6 h, 2 % of the series' value), so 1.0 is the bound.
    assert!(worst[0] <= 0.5, "sun visible %: {}", worst[0]);
    assert!(worst[1] <= 0.005, "mean fraction: {}", worst[1]);
    assert!(worst[2] <= 1.0, "earth visible %: {}", worst[2]);
    assert!(worst[3] <= 0.5, "sun fully visible %: {}", worst[3]);
    assert!(worst[4] <= 1.0, "longest dark: {}", worst[4]);
    assert!(worst[5] <= 1.0, "longest Earth-hidden: {}", worst[5]);
    // Direct-to-Earth: the Earth's bound (the station flag adds < 1 epoch in 1,460 here).
    assert!(worst[6] <= 1.0, "DTE %: {}", worst[6]);
    assert!(worst[7] <= 1.0, "longest DTE blackout: {}", worst[7]);
    assert!(
        m_dte.iter().any(|&v| v > 0.0) && m_dte.iter().any(|&v| v.is_finite() && v < 100.0),
        "the DTE map says something"
    );
}

/// The share of a unit disc's light above the chord `y = d` (d > 0: above the centre) for the
/// limb law `I(μ) = c0 + c1 μ`, by quadrature built here (not the library's closed form): each
/// row y carries `c0·2a + c1·πa²/2` (a = √(1 − y²): the row's length and the integral of
/// `√(a² − x²)`), summed over 20,000 midpoint rows, divided by the disc's `π(c0 + 2c1/3)`.
fn disc_above_chord(d: f64, c0: f64, c1: f64) -> f64 {
    let d = d.clamp(-1.0, 1.0);
    let n = 20_000;
    let dy = (1.0 - d) / n as f64;
    let sum: f64 = (0..n)
        .map(|k| {
            let y = d + (k as f64 + 0.5) * dy;
            let a2 = (1.0 - y * y).max(0.0);
            c0 * 2.0 * a2.sqrt() + c1 * std::f64::consts::PI * a2 / 2.0
        })
        .sum();
    sum * dy / (std::f64::consts::PI * (c0 + 2.0 * c1 / 3.0))
}

/// The engine over a flat sphere, where every interior pixel's horizon is the dip
/// `−acos(R / (R + h))` in every direction: each pixel's statistics against the SPICE-exact
/// topocentric Sun and Earth at that pixel (`ephem::sun_earth_series`, f64) and the disc's
/// share above the dip by this file's own quadrature ([`disc_above_chord`]).
#[test]
fn flat_sphere_statistics_follow_each_pixels_own_sky() {
    let h_obs = 2.0;
    // 24 km square, 180 km from the pole (the local vertical is tilted 6° from the pole's).
    let dem = penumbra::terrain::synth::square_dem_at(
        240,
        100.0,
        (-120_000.0, 135_000.0),
        "flat",
        |_, _| 0.0,
    );
    let stack = TerrainStack::new(vec![dem.clone()]);
    let sweep = HorizonSweep::new(
        &stack,
        SweepParams {
            observer_height_m: h_obs,
            azimuths: 16,
            max_step: 3,
        },
    )
    .unwrap();
    let mut horizons = InMemoryHorizons::sweep(&sweep, |_| true).unwrap();
    let kernels = penumbra::ephem::Kernels::load(&kernels_dir()).unwrap();
    let epochs = penumbra::ephem::time::epoch_range(
        penumbra::ephem::time::parse_utc("2027-01-01").unwrap(),
        penumbra::ephem::time::parse_utc("2027-12-31").unwrap(),
        hifitime::Duration::from_hours(6.0),
    )
    .unwrap();
    let bodies = penumbra::horizon::statistics::EpochBodies::over_dem(
        &dem,
        &kernels,
        &epochs,
        penumbra::ephem::AbCorr::LtS,
    )
    .unwrap();
    let limb = LimbDarkening::EDDINGTON;
    let engine = StatisticsEngine::new(
        &stack,
        StatisticsParams {
            limb,
            visible_min_fraction: 1e-6,
            full_min_fraction: 0.999,
        },
    )
    .unwrap();
    let stats = engine.run(&mut horizons, &bodies, |_| true).unwrap();
    let r = penumbra::MOON_RADIUS_M;
    let dip_deg = -(r / (r + h_obs)).acos().to_degrees();
    let mut worst_mean = 0.0_f64;
    let mut worst_counts = 0_u32;
    for (row, col) in [(100, 100), (120, 60), (60, 170), (180, 180), (119, 120)] {
        let (x, y) = dem.grid.xy_from_row_col(row as f64, col as f64);
        let (lat, lon) = dem.projection.lat_lon_from_xy(x, y);
        let site = penumbra::ephem::Site::new(lat, lon, h_obs).unwrap();
        let sky = penumbra::ephem::sun_earth_series(
            &kernels,
            &[site],
            &epochs,
            penumbra::ephem::AbCorr::LtS,
        )
        .unwrap();
        let (mut sum, mut vis, mut earth) = (0.0, 0_u32, 0_u32);
        for v in &sky[0] {
            let f = disc_above_chord(
                (dip_deg - v.sun.el_deg) / v.sun.radius_deg,
                limb.c0,
                limb.c1,
            );
            let fe = disc_above_chord((dip_deg - v.earth.el_deg) / v.earth.radius_deg, 1.0, 0.0);
            sum += f;
            vis += u32::from(f > 1e-6);
            earth += u32::from(fe > 1e-6);
        }
        let px = row * dem.grid.cols + col;
        let n = epochs.len() as f64;
        let d_mean = (stats.sun_fraction_sum[px] / n - sum / n).abs();
        let d_counts = stats.sun_visible_count[px].abs_diff(vis)
            + stats.earth_visible_count[px].abs_diff(earth);
        println!(
            "({row},{col}) lat {lat:.4}: mean {:.6} vs {:.6}, Sun visible {} vs {vis}, Earth {} vs {earth}",
            stats.sun_fraction_sum[px] / n,
            sum / n,
            stats.sun_visible_count[px],
            stats.earth_visible_count[px]
        );
        worst_mean = worst_mean.max(d_mean);
        worst_counts = worst_counts.max(d_counts);
    }
    // f32 geometry and the horizons' 0.01° quantisation: 0.0046° on the dip here.
    assert!(worst_mean < 1e-3, "mean fraction off by {worst_mean}");
    assert!(
        worst_counts <= 2,
        "visible counts off by {worst_counts} epochs"
    );
}

/// Horizons read from a `horizon-map sweep` GeoTIFF give the very same maps as a sweep in
/// memory; a horizon map that does not fit the request is a clean error that writes nothing.
#[test]
fn horizons_from_a_file_equal_the_sweep_in_memory_and_bad_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let k = k.to_str().unwrap();
    let d = dir.path();
    penumbra_ok(
        d,
        &[
            "dem", "synth", "--size", "64", "--px-m", "200", "--out", "a.tif",
        ],
    );
    penumbra_ok(
        d,
        &[
            "dem", "synth", "--size", "60", "--px-m", "200", "--out", "b.tif",
        ],
    );
    penumbra_ok(
        d,
        &[
            "horizon-map",
            "sweep",
            "--dem",
            "a.tif",
            "--azimuths",
            "90",
            "--max-step",
            "6",
            "--out",
            "h.tif",
        ],
    );
    let epochs = [
        "--start",
        "2027-03-01",
        "--stop",
        "2027-04-01",
        "--step",
        "3h",
    ];
    let map = |extra: &[&str], out: &str| {
        penumbra(
            d,
            &[
                &[
                    "map",
                    "--dem",
                    "a.tif",
                    "--engine",
                    "horizons",
                    "--backend",
                    "cpu",
                ][..],
                &epochs,
                extra,
                &["--out-dir", out, "--kernels", k],
            ]
            .concat(),
        )
    };
    assert!(map(&["--horizons", "h.tif"], "from_file").status.success());
    assert!(
        map(&["--azimuths", "90", "--max-step", "6"], "in_memory")
            .status
            .success()
    );
    for name in [
        "sun_illumination_pct.tif",
        "sun_visible_pct.tif",
        "sun_full_pct.tif",
        "longest_dark_h.tif",
        "earth_visible_pct.tif",
        "longest_earth_hidden_h.tif",
        "sun_and_earth_pct.tif",
        "irradiance_horizontal_w_m2.tif",
        "irradiance_tracking_w_m2.tif",
    ] {
        let a = read_tif(&d.join("from_file"), name).heights_m;
        let b = read_tif(&d.join("in_memory"), name).heights_m;
        assert!(
            a.iter()
                .zip(&b)
                .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan())),
            "{name} differs"
        );
    }
    // The PSR masks: the same pixels (the files' tags differ by design: the run from a file
    // names the horizons file among its inputs).
    let psr_a = read_tif(&d.join("from_file"), "psr_mask.tif").heights_m;
    let psr_b = read_tif(&d.join("in_memory"), "psr_mask.tif").heights_m;
    assert!(
        psr_a
            .iter()
            .zip(&psr_b)
            .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
    );

    // `--engine auto` with a horizons file uses it on the GPU too (it once ran a soft-shadow
    // map per epoch there, ignoring the file): the same statistics as the CPU's.
    #[cfg(feature = "gpu")]
    if crate::util::gpu().is_some() {
        let out = penumbra(
            d,
            &[
                &[
                    "map",
                    "--dem",
                    "a.tif",
                    "--horizons",
                    "h.tif",
                    "--backend",
                    "gpu",
                ][..],
                &epochs,
                &["--out-dir", "auto_gpu", "--kernels", k],
            ]
            .concat(),
        );
        let note = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{note}");
        assert!(note.contains("--engine auto: horizons"), "{note}");
        let a = read_tif(&d.join("from_file"), "sun_visible_pct.tif").heights_m;
        let b = read_tif(&d.join("auto_gpu"), "sun_visible_pct.tif").heights_m;
        let worst = a
            .iter()
            .zip(&b)
            .filter(|(x, y)| !(x.is_nan() && y.is_nan()))
            .map(|(x, y)| (x - y).abs())
            .fold(0.0_f32, f32::max);
        assert!(
            worst <= 0.5,
            "Sun visible %: GPU vs CPU differ by {worst} pp"
        );
    }

    // Another grid, another observer height, not a horizon map, one light: clean errors.
    let out = penumbra(
        d,
        &[
            &[
                "map",
                "--dem",
                "b.tif",
                "--engine",
                "horizons",
                "--horizons",
                "h.tif",
            ][..],
            &epochs,
            &["--out-dir", "bad1", "--kernels", k],
        ]
        .concat(),
    );
    assert_clean_error(&out, "not the finest layer");
    let out = map(
        &["--horizons", "h.tif", "--observer-height-m", "10"],
        "bad2",
    );
    assert_clean_error(&out, "observer 2 m above the ground");
    let out = map(&["--horizons", "a.tif"], "bad3");
    assert_clean_error(&out, "not a penumbra horizon map");
    let out = penumbra(
        d,
        &[
            "map",
            "--dem",
            "a.tif",
            "--engine",
            "horizons",
            "--utc",
            "2027-03-01",
            "--out-mask",
            "m.tif",
            "--kernels",
            k,
        ],
    );
    assert_clean_error(&out, "epoch range");
    for bad in ["bad1", "bad2", "bad3"] {
        assert!(!d.join(bad).exists() || files_in(&d.join(bad)).is_empty());
    }
    assert!(!d.join("m.tif").exists());
}
