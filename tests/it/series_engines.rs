//! The two engines of `penumbra series` (issue 7 item 3): `horizon` (per-site horizons, strip
//! integral) and `smap-dp` (the map pipeline's model grid, DP search at each site's point) on the
//! same sites and epochs. The smap-dp engine is also checked alone against the closed form on a
//! flat DEM. Bounds are the measured differences with a margin (docs/VALIDATION.md).

use penumbra::ephem::{self, AbCorr, Kernels};
use penumbra::illum::DiscMethod;
use penumbra::illum::stats::{SUN_FULL_MIN_FRACTION, VISIBLE_MIN_FRACTION};
use penumbra::series::{self, LimbLaw, SeriesConfig, SeriesEngine, SeriesSite};
use penumbra::terrain::{TerrainStack, synth};

use crate::util::{assert_clean_error, files_in, kernels_dir, penumbra, shared_lola};

fn month_hourly() -> Vec<hifitime::Epoch> {
    let start = ephem::time::parse_utc("2027-01-25").unwrap();
    let stop = ephem::time::parse_utc("2027-02-25").unwrap();
    ephem::time::epoch_range(start, stop, ephem::time::parse_step("1h").unwrap()).unwrap()
}

fn site(name: &str, lat_deg: f64, lon_deg: f64) -> SeriesSite {
    SeriesSite {
        name: name.into(),
        lat_deg,
        lon_deg,
        height_above_ground_m: 2.0,
    }
}

/// Both engines' fractions per site: `(sun_h, earth_h, sun_d, earth_d)`.
type Pair = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

fn both_engines(stack: &TerrainStack, sites: &[SeriesSite], config: SeriesConfig) -> Vec<Pair> {
    let kernels = Kernels::load(&kernels_dir()).unwrap();
    let epochs = month_hourly();
    let run = |engine| {
        let dir = tempfile::tempdir().unwrap();
        let cfg = SeriesConfig { engine, ..config };
        series::run_series(&kernels, stack, sites, &epochs, 3600.0, &cfg, dir.path())
            .unwrap()
            .0
    };
    let h = run(SeriesEngine::Horizon);
    let d = run(SeriesEngine::SmapDp);
    h.into_iter()
        .zip(d)
        .map(|(h, d)| {
            (
                h.sun_fraction,
                h.earth_fraction,
                d.sun_fraction,
                d.earth_fraction,
            )
        })
        .collect()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

fn pct(v: &[f64], pred: impl Fn(f64) -> bool) -> f64 {
    100.0 * v.iter().filter(|&&x| pred(x)).count() as f64 / v.len() as f64
}

/// Per-site differences between the engines: (|Δ % Sun visible|, |Δ mean Sun fraction|,
/// |Δ mean Earth fraction|, |Δ % Earth visible|, share of epochs with |Δ Sun fraction| > 0.1).
fn differences(p: &Pair) -> [f64; 5] {
    let (sh, eh, sd, ed) = p;
    let lit = |x: f64| x > VISIBLE_MIN_FRACTION;
    let big = sh
        .iter()
        .zip(sd)
        .filter(|(a, b)| (*a - *b).abs() > 0.1)
        .count();
    [
        (pct(sh, lit) - pct(sd, lit)).abs(),
        (mean(sh) - mean(sd)).abs(),
        (mean(eh) - mean(ed)).abs(),
        (pct(eh, lit) - pct(ed, lit)).abs(),
        100.0 * big as f64 / sh.len() as f64,
    ]
}

/// Bounds of [`differences`], in order.
struct Bounds {
    sun_lit_pct: f64,
    sun_mean: f64,
    earth_mean: f64,
    earth_visible_pct: f64,
    big_epochs_pct: f64,
}

fn check(label: &str, sites: &[SeriesSite], pairs: &[Pair], b: &Bounds) {
    let mut partial_sites = 0;
    let mut failures = Vec::new();
    for (s, p) in sites.iter().zip(pairs) {
        let d = differences(p);
        let lit = |x: f64| x > VISIBLE_MIN_FRACTION;
        let full = |x: f64| x >= SUN_FULL_MIN_FRACTION;
        eprintln!(
            "{label} {:>10}: Sun lit {:5.1}% / {:5.1}%, full {:5.1}% / {:5.1}%, mean {:.4} / {:.4}; \
             Earth vis {:5.1}% / {:5.1}%, mean {:.4} / {:.4}; |Δ| lit {:.2} pp, sun {:.4}, \
             earth {:.4}, earth vis {:.2} pp, epochs |Δf|>0.1: {:.2}%",
            s.name,
            pct(&p.0, lit),
            pct(&p.2, lit),
            pct(&p.0, full),
            pct(&p.2, full),
            mean(&p.0),
            mean(&p.2),
            pct(&p.1, lit),
            pct(&p.3, lit),
            mean(&p.1),
            mean(&p.3),
            d[0],
            d[1],
            d[2],
            d[3],
            d[4],
        );
        if pct(&p.0, lit) > 5.0 && pct(&p.0, lit) < 95.0 {
            partial_sites += 1;
        }
        let over = [
            d[0] > b.sun_lit_pct,
            d[1] > b.sun_mean,
            d[2] > b.earth_mean,
            d[3] > b.earth_visible_pct,
            d[4] > b.big_epochs_pct,
        ];
        if over.iter().any(|&o| o) {
            failures.push(format!("{}: {d:?} (over: {over:?})", s.name));
        }
    }
    assert!(
        failures.is_empty(),
        "{label}: bounds exceeded: {failures:?}"
    );
    // The comparison means something only if the Sun rises and sets at some sites.
    assert!(
        partial_sites >= 2,
        "{label}: only {partial_sites} sites are partly lit"
    );
}

/// On a flat DEM the horizon is the geometric dip in every direction; the smap-dp engine must
/// reproduce the closed-form circular segment (as the horizon engine does in tests/it/series.rs).
#[test]
fn smap_dp_on_flat_terrain_matches_the_closed_form_segment() {
    let kernels = Kernels::load(&kernels_dir()).unwrap();
    let stack = TerrainStack::new(vec![synth::flat(200, 200, 100.0, 0.0)]);
    let h_m = 2.0;
    let s = site("flat", -89.9, 30.0);
    let epochs = month_hourly();
    let dir = tempfile::tempdir().unwrap();
    let config = SeriesConfig {
        limb_darkening: LimbLaw::None,
        plots: false,
        write_csv: false,
        engine: SeriesEngine::SmapDp,
        ..SeriesConfig::default()
    };
    let (outcomes, _) = series::run_series(
        &kernels,
        &stack,
        std::slice::from_ref(&s),
        &epochs,
        3600.0,
        &config,
        dir.path(),
    )
    .unwrap();
    let r_m = penumbra::MOON_RADIUS_M;
    let dip_deg = -(r_m / (r_m + h_m)).acos().to_degrees();
    let sites = [ephem::Site::new(-89.9, 30.0, h_m).unwrap()];
    let sky = ephem::sun_earth_series(&kernels, &sites, &epochs, AbCorr::LtS).unwrap();
    let (mut max_err, mut partial) = (0.0_f64, 0);
    for (k, v) in sky[0].iter().enumerate() {
        let d = ((dip_deg - v.sun.el_deg) / v.sun.radius_deg).clamp(-1.0, 1.0);
        let expected = (d.acos() - d * (1.0 - d * d).sqrt()) / std::f64::consts::PI;
        max_err = max_err.max((outcomes[0].sun_fraction[k] - expected).abs());
        if expected > 0.01 && expected < 0.99 {
            partial += 1;
        }
    }
    eprintln!("smap-dp flat: max |Δ fraction| {max_err:.2e}, {partial} partial epochs");
    assert!(partial > 50, "{partial} partial epochs");
    // The DP horizon on a sphere is the dip sampled at 100 m crossings; the disc edge is the
    // chord at the centre azimuth's horizon, exact for a constant horizon.
    assert!(max_err < 2e-3, "max |Δ fraction| {max_err}");
}

/// A month hourly on the synthetic DEM (400² at 100 m around the pole), five sites including one
/// on a ridge: the engines agree within the measured bounds.
#[test]
fn engines_agree_on_the_synthetic_dem() {
    let stack = TerrainStack::new(vec![
        synth::south_polar_dem(&synth::SynthParams::default()).unwrap(),
    ]);
    let sites = [
        site("ridge", -89.6, 0.0),
        site("plateau", -89.5, 45.0),
        site("pole", -89.95, 120.0),
        site("west", -89.7, 250.0),
        site("south", -89.45, 170.0),
    ];
    let config = SeriesConfig {
        plots: false,
        write_csv: false,
        disc_method: DiscMethod::Exact,
        limb_darkening: LimbLaw::Eddington,
        ..SeriesConfig::default()
    };
    let pairs = both_engines(&stack, &sites, config);
    check(
        "synthetic",
        &sites,
        &pairs,
        &Bounds {
            sun_lit_pct: 0.5,
            sun_mean: 0.005,
            earth_mean: 0.005,
            earth_visible_pct: 1.5,
            big_epochs_pct: 1.5,
        },
    );
}

/// The same on the real LOLA 240 m crop (finest layer only for both engines, so the far field is
/// the same), four sites around Shackleton and the connecting ridge.
#[test]
fn engines_agree_on_the_lola_crop() {
    let Some(path) = shared_lola("ldem75s_crop_240m_pm184km.tif") else {
        return;
    };
    let stack = TerrainStack::load(&[path]).unwrap();
    let sites = [
        site("shackleton_rim", -89.9, 200.0),
        site("connecting_ridge", -89.45, 222.7),
        site("de_gerlache_rim", -88.7, 292.0),
        site("malapert", -86.0, 0.0),
    ];
    let config = SeriesConfig {
        plots: false,
        write_csv: false,
        ..SeriesConfig::default()
    };
    let pairs = both_engines(&stack, &sites, config);
    check(
        "lola-240m",
        &sites,
        &pairs,
        &Bounds {
            sun_lit_pct: 3.0,
            sun_mean: 0.025,
            earth_mean: 0.045,
            earth_visible_pct: 4.5,
            big_epochs_pct: 6.0,
        },
    );
}

#[test]
fn series_cli_smap_dp_writes_the_same_files_and_records_the_engine() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let args = |engine: &'static str, out: &'static str| {
        vec![
            "series",
            "--synthetic",
            "--site",
            "ridge,-89.6,0",
            "--start",
            "2027-01-01",
            "--stop",
            "2027-01-03",
            "--step",
            "6h",
            "--kernels",
            k.to_str().unwrap(),
            "--engine",
            engine,
            "--out-dir",
            out,
        ]
    };
    for (engine, out) in [("horizon", "h"), ("smap-dp", "d")] {
        let o = penumbra(dir.path(), &args(engine, out));
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let run: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join(out).join("run.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(run["series_engine"], engine);
    }
    assert_eq!(
        files_in(&dir.path().join("h")),
        files_in(&dir.path().join("d"))
    );
    assert_eq!(
        files_in(&dir.path().join("h/ridge")),
        files_in(&dir.path().join("d/ridge"))
    );
    let csv = std::fs::read_to_string(dir.path().join("d/ridge/series.csv")).unwrap();
    assert_eq!(csv.lines().next().unwrap(), series::SERIES_CSV_HEADER);
    assert_eq!(csv.lines().count(), 1 + 9);
    // A site off the finest layer is one clear error line.
    let mut bad = args("smap-dp", "x");
    bad[3] = "far,-80,0";
    assert_clean_error(&penumbra(dir.path(), &bad), "far");
    // smap-dp has no GPU path: asking for the GPU is one clear error line, nothing written.
    let mut bad = args("smap-dp", "g");
    bad.extend(["--backend", "gpu"]);
    assert_clean_error(&penumbra(dir.path(), &bad), "CPU only");
    assert!(
        !dir.path().join("g").exists(),
        "nothing written for the GPU request"
    );
    // An unknown engine is rejected by the parser.
    let mut bad = args("smap-dp", "y");
    bad[13] = "fourier";
    let o = penumbra(dir.path(), &bad);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn scenario_series_table_takes_an_engine_key() {
    let c: SeriesConfig = toml::from_str("engine = \"smap-dp\"").unwrap();
    assert_eq!(c.engine, SeriesEngine::SmapDp);
    let c: SeriesConfig = toml::from_str("plots = false").unwrap();
    assert_eq!(c.engine, SeriesEngine::Horizon);
    let e = toml::from_str::<SeriesConfig>("engine = \"fourier\"").unwrap_err();
    assert!(e.to_string().contains("fourier"), "{e}");
}
