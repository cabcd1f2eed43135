//! Per-site series: the whole pipeline against analytic answers, and the `series` and `run`
//! commands through the binary. The two series engines side by side are in `engines`.

mod engines;

use penumbra::ephem::{self, AbCorr, Kernels};
use penumbra::illum::DiscMethod;
use penumbra::illum::LimbLaw;
use penumbra::model::{ObserverHeight, Site};
use penumbra::products::series::{self, SeriesConfig};
use penumbra::terrain::{TerrainStack, synth};

use crate::util::{assert_clean_error, files_in, kernels_dir, penumbra, penumbra_ok, root};

/// On a flat DEM (a sphere) the horizon is the geometric dip `-acos(R / (R + h))` in every
/// direction, so the Sun's visible fraction is the circular-segment area below a straight horizon:
/// `f = (acos d - d sqrt(1 - d²)) / π` with `d = (dip - el) / r` (uniform disc). Every epoch of a
/// month is checked against that closed form, computed here from the ephemeris alone.
#[test]
fn flat_terrain_series_matches_the_closed_form_segment() {
    let kernels = Kernels::load(&kernels_dir()).unwrap();
    let dem = synth::flat(200, 200, 100.0, 0.0);
    let stack = TerrainStack::new(vec![dem]);
    let h_m = 2.0;
    let site = Site::new("flat", -89.9, 30.0, ObserverHeight::new(h_m).unwrap()).unwrap();
    let start = ephem::time::parse_utc("2027-01-25").unwrap();
    let stop = ephem::time::parse_utc("2027-02-25").unwrap();
    let epochs =
        ephem::time::epoch_range(start, stop, ephem::time::parse_step("1h").unwrap()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let config = SeriesConfig {
        limb_darkening: LimbLaw::None,
        disc_method: DiscMethod::Exact,
        plots: false,
        ..SeriesConfig::default()
    };
    let series::SeriesRun {
        outcomes, files, ..
    } = series::run_series(
        &kernels,
        &stack,
        &[site],
        &epochs,
        3600.0,
        &config,
        dir.path(),
    )
    .unwrap();
    assert!(files.contains(&"flat/series.csv".to_string()));
    let r_m = penumbra::MOON_RADIUS_M;
    let dip_deg = -(r_m / (r_m + h_m)).acos().to_degrees();
    let sites = [ephem::Site::new(-89.9, 30.0, h_m).unwrap()];
    let sky = ephem::sun_earth_series(&kernels, &sites, &epochs, AbCorr::LtS).unwrap();
    let mut partial = 0;
    let mut max_err: f64 = 0.0;
    for (k, v) in sky[0].iter().enumerate() {
        let d = ((dip_deg - v.sun.el_deg) / v.sun.radius_deg).clamp(-1.0, 1.0);
        let expected = (d.acos() - d * (1.0 - d * d).sqrt()) / std::f64::consts::PI;
        let got = outcomes[0].sun_fraction[k];
        max_err = max_err.max((got - expected).abs());
        if expected > 0.01 && expected < 0.99 {
            partial += 1;
        }
    }
    // The horizon is sampled every 0.25° and interpolated linearly; on a sphere it is constant, so
    // the remaining error is the flat-sky approximation of the disc (< 1e-4, docs/illum.md) and the
    // horizon scan's tolerance (≤ 0.002° ≈ 0.01 of a solar radius in the worst case).
    assert!(max_err < 0.01, "max |Δ fraction| {max_err}");
    assert!(
        partial > 50,
        "the test month must contain partly hidden Suns, got {partial}"
    );
    eprintln!(
        "flat terrain: max |Δ fraction| {max_err:.2e} over {} epochs ({partial} partial)",
        epochs.len()
    );
    let horizon = &outcomes[0].horizon;
    for el in &horizon.elevation_deg {
        assert!((el - dip_deg).abs() < 2e-3, "horizon {el} vs dip {dip_deg}");
    }
}

#[test]
fn series_cli_writes_every_file_and_the_combined_statistics() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    penumbra_ok(
        dir.path(),
        &[
            "series",
            "--synthetic",
            "--site",
            "ridge,-89.6,0",
            "--site",
            "plateau,-89.5,45,10",
            "--start",
            "2027-01-01",
            "--stop",
            "2027-01-15",
            "--step",
            "2h",
            "--kernels",
            k.to_str().unwrap(),
            "--out-dir",
            "res",
        ],
    );
    let res = dir.path().join("res");
    assert_eq!(
        files_in(&res),
        vec![
            "plateau",
            "ridge",
            "run.json",
            "series_long.csv",
            "sites.geojson",
            "sites.kml",
            "stats.json"
        ]
    );
    assert_eq!(
        files_in(&res.join("ridge")),
        vec![
            "dte_windows.csv",
            "dte_windows.ics",
            "dte_windows.png",
            "horizon.csv",
            "horizon.png",
            "horizon_polar.png",
            "neighbourhood.csv",
            "series.csv",
            "stats.json",
            "visibility.png"
        ]
    );
    // The DSN by default: the link columns after the series' own.
    let csv = std::fs::read_to_string(res.join("ridge/series.csv")).unwrap();
    assert_eq!(
        csv.lines().next().unwrap(),
        format!("{},{}", series::SERIES_CSV_HEADER, series::LINK_CSV_COLUMNS)
    );
    assert_eq!(csv.lines().count(), 1 + 14 * 12 + 1);
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(res.join("stats.json")).unwrap()).unwrap();
    let any = stats["combined"]["any_sun_visible_pct"].as_f64().unwrap();
    for s in stats["sites"].as_array().unwrap() {
        let pct = s["sun_visible_pct"].as_f64().unwrap();
        assert!(
            any + 1e-9 >= pct,
            "at least one site lit {any}% < one site's {pct}%"
        );
    }
    // The PNG decodes and is not blank.
    let img = image::open(res.join("ridge/horizon.png"))
        .unwrap()
        .to_luma8();
    let (lo, hi) = img
        .pixels()
        .fold((255u8, 0u8), |(lo, hi), p| (lo.min(p[0]), hi.max(p[0])));
    assert!(hi - lo > 100);
}

#[test]
fn series_bad_input_is_a_clean_error_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let k = k.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        // Off the DEM (the synthetic DEM spans 20 km around the pole).
        (vec!["--site", "far,-85.0,0"], "outside"),
        (vec!["--site", "neg,-89.6,0,-1"], "height"),
        (vec!["--site", "bad/name,-89.6,0"], "site name"),
        (vec!["--site", "x,-89.6"], "--site"),
    ];
    for (extra, needle) in cases {
        let mut args = vec![
            "series",
            "--synthetic",
            "--start",
            "2027-01-01",
            "--stop",
            "2027-01-02",
            "--step",
            "1h",
            "--kernels",
            k,
            "--out-dir",
            "res",
        ];
        args.extend(extra.iter());
        let out = penumbra(dir.path(), &args);
        assert_clean_error(&out, needle);
        assert!(!dir.path().join("res").exists(), "{extra:?} wrote output");
    }
    let out = penumbra(
        dir.path(),
        &[
            "series",
            "--synthetic",
            "--site",
            "a,-89.6,0",
            "--start",
            "2027-01-02",
            "--stop",
            "2027-01-01",
            "--step",
            "1h",
            "--kernels",
            k,
            "--out-dir",
            "res",
        ],
    );
    assert_clean_error(&out, "before start");
    assert!(!dir.path().join("res").exists());
}

#[test]
fn the_demo_scenario_runs_as_the_readme_says() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = root().join("scenarios/south-pole-demo.toml");
    penumbra_ok(
        dir.path(),
        &["run", scenario.to_str().unwrap(), "--out-dir", "demo"],
    );
    let res = dir.path().join("demo");
    let files = files_in(&res);
    for f in [
        "run.json",
        "stats.json",
        "terrain_synthetic.tif",
        "ridge",
        "massif-summit",
    ] {
        assert!(files.contains(&f.to_string()), "{f} missing: {files:?}");
    }
    let run: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(res.join("run.json")).unwrap()).unwrap();
    assert_eq!(run["epoch_count"], 8760);
    assert!(run["dem_layers"][0].as_str().unwrap().contains("synthetic"));
    // The hourly maps of the horizons engine.
    let map = files_in(&res.join("map"));
    for f in [
        "sun_illumination_pct.tif",
        "sun_full_pct.tif",
        "longest_earth_hidden_h.tif",
        "irradiance_horizontal_w_m2.tif",
        "psr_mask.tif",
        "mean_power_w.tif",
        "required_battery_wh.tif",
    ] {
        assert!(map.contains(&f.to_string()), "map/{f} missing: {map:?}");
    }
    // The panel at each site and the landing windows ([series.power], [windows]).
    for f in ["windows.csv", "windows.ics", "windows.png"] {
        assert!(files.contains(&f.to_string()), "{f} missing: {files:?}");
    }
    assert!(files_in(&res.join("ridge")).contains(&"power.png".to_string()));
    assert!(
        run["backend"].as_str().unwrap().contains("horizons engine"),
        "{}",
        run["backend"]
    );
    // The demo's camera path ([[render.paths]], 3 frames).
    let render = files_in(&res.join("render"));
    for f in ["descent_0000.png", "descent_0001.png", "descent_0002.png"] {
        assert!(render.contains(&f.to_string()), "{f} missing: {render:?}");
    }
}
