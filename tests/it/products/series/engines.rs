//! The two engines of `penumbra series`: `horizon` (per-site horizons, strip integral) and
//! `smap-dp` (the map pipeline's model grid, DP search at each site's point) on the same sites
//! and epochs. The smap-dp engine is also checked alone against the closed form on a flat DEM.
//! Bounds are the measured differences with a margin (docs/VALIDATION.md).

use penumbra::compute::site_dp::{SmapDpSites, fraction_from_horizon_tan};
use penumbra::ephem::{self, AbCorr, Kernels};
use penumbra::illum::DiscMethod;
use penumbra::illum::LimbDarkening;
use penumbra::illum::LimbLaw;
use penumbra::illum::stats::{SUN_FULL_MIN_FRACTION, VISIBLE_MIN_FRACTION};
use penumbra::model::{ObserverHeight, Site};
use penumbra::products::series::{self, SeriesConfig, SeriesEngine};
use penumbra::terrain::{TerrainStack, synth};
use penumbra::twins::{self, DpMip, MarchGrid};

use crate::util::{assert_clean_error, files_in, kernels_dir, penumbra, shared_lola};

fn month_hourly() -> Vec<hifitime::Epoch> {
    let start = ephem::time::parse_utc("2027-01-25").unwrap();
    let stop = ephem::time::parse_utc("2027-02-25").unwrap();
    ephem::time::epoch_range(start, stop, ephem::time::parse_step("1h").unwrap()).unwrap()
}

/// The four sites of the LOLA 240 m crop tests: Shackleton, the connecting ridge, de Gerlache
/// and Malapert.
fn lola_crop_sites() -> [Site; 4] {
    [
        site("shackleton_rim", -89.9, 200.0),
        site("connecting_ridge", -89.45, 222.7),
        site("de_gerlache_rim", -88.7, 292.0),
        site("malapert", -86.0, 0.0),
    ]
}

/// The default configuration without plots or CSV files.
fn quiet() -> SeriesConfig {
    SeriesConfig {
        plots: false,
        write_csv: false,
        ..SeriesConfig::default()
    }
}

fn site(name: &str, lat_deg: f64, lon_deg: f64) -> Site {
    Site::new(name, lat_deg, lon_deg, ObserverHeight::DEFAULT).unwrap()
}

/// Both engines' fractions per site: `(sun_h, earth_h, sun_d, earth_d)`.
type Pair = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

fn both_engines(stack: &TerrainStack, sites: &[Site], config: SeriesConfig) -> Vec<Pair> {
    let kernels = Kernels::load(&kernels_dir()).unwrap();
    let epochs = month_hourly();
    let run = |engine| {
        let dir = tempfile::tempdir().unwrap();
        let cfg = SeriesConfig {
            engine,
            ..config.clone()
        };
        series::run_series(&kernels, stack, sites, &epochs, 3600.0, &cfg, dir.path())
            .unwrap()
            .outcomes
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

fn check(label: &str, sites: &[Site], pairs: &[Pair], b: &Bounds) {
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
            s.name(),
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
            failures.push(format!("{}: {d:?} (over: {over:?})", s.name()));
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
/// reproduce the closed-form circular segment (as the horizon engine does in
/// tests/it/products/series/mod.rs).
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
        engine: SeriesEngine::SmapDp,
        ..quiet()
    };
    let series::SeriesRun { outcomes, .. } = series::run_series(
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
        disc_method: DiscMethod::Exact,
        limb_darkening: LimbLaw::Eddington,
        ..quiet()
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
    let sites = lola_crop_sites();
    let config = quiet();
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
        // The default backend `auto` takes the CPU for the horizon engine always, and for
        // smap-dp without a hardware adapter; run.json says which.
        let backend = run["series_backend"].as_str().unwrap_or_default();
        if engine == "horizon" || !hardware_gpu() {
            assert!(backend.starts_with("cpu: "), "series_backend {backend:?}");
        }
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
    assert_eq!(
        csv.lines().next().unwrap(),
        format!("{},{}", series::SERIES_CSV_HEADER, series::LINK_CSV_COLUMNS)
    );
    assert_eq!(csv.lines().count(), 1 + 9);
    // A site off the finest layer is one clear error line.
    let mut bad = args("smap-dp", "x");
    bad[3] = "far,-80,0";
    assert_clean_error(&penumbra(dir.path(), &bad), "far");
    // smap-dp on the GPU: with an adapter the same files (fractions within the GPU bounds of
    // `gpu::series_smap_dp_gpu_matches_cpu`); without one a clear error line and nothing written.
    let mut on_gpu = args("smap-dp", "g");
    on_gpu.extend(["--backend", "gpu"]);
    let o = penumbra(dir.path(), &on_gpu);
    if gpu_available() {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(
            files_in(&dir.path().join("d/ridge")),
            files_in(&dir.path().join("g/ridge"))
        );
        let cpu = read_fractions(&dir.path().join("d/ridge/series.csv"));
        let gpu = read_fractions(&dir.path().join("g/ridge/series.csv"));
        assert_eq!(cpu.len(), gpu.len());
        let max = cpu
            .iter()
            .zip(&gpu)
            .map(|(a, b)| (a.0 - b.0).abs().max((a.1 - b.1).abs()))
            .fold(0.0_f64, f64::max);
        let run: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join("g/run.json")).unwrap())
                .unwrap();
        let backend = run["series_backend"].as_str().unwrap_or_default();
        assert!(
            backend.starts_with("gpu: smap-dp searches on "),
            "series_backend {backend:?}"
        );
        eprintln!("CLI smap-dp gpu vs cpu: max |Δ fraction| {max:.2e}");
        assert!(max < 0.02, "max |Δ fraction| {max}");
    } else {
        assert_clean_error(&o, "gpu");
        assert!(
            !dir.path().join("g").exists(),
            "nothing written for the GPU request"
        );
    }
    // `auto` skips a software adapter (lavapipe) or a missing one with exactly one warning line
    // and then writes the CPU engine's bytes; on a hardware adapter it runs the GPU path.
    let mut auto = args("smap-dp", "a");
    auto.extend(["--backend", "auto"]);
    let o = penumbra(dir.path(), &auto);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    if !hardware_gpu() {
        let stderr = String::from_utf8_lossy(&o.stderr);
        let warnings = stderr.lines().filter(|l| l.contains("warning")).count();
        assert_eq!(warnings, 1, "{stderr}");
        assert_eq!(
            std::fs::read(dir.path().join("a/ridge/series.csv")).unwrap(),
            std::fs::read(dir.path().join("d/ridge/series.csv")).unwrap()
        );
    }
    // An unknown engine is rejected by the parser.
    let mut bad = args("smap-dp", "y");
    bad[13] = "fourier";
    let o = penumbra(dir.path(), &bad);
    assert_eq!(o.status.code(), Some(2));
}

/// Sun and Earth fractions (columns 5 and 12) of a `series.csv`.
fn read_fractions(path: &std::path::Path) -> Vec<(f64, f64)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[4].parse().unwrap(), f[11].parse().unwrap())
        })
        .collect()
}

/// Whether a GPU context can be built (lavapipe counts): in a GPU build, no adapter fails the
/// test unless `PENUMBRA_SKIP=gpu` ([`crate::util::gpu`]); a CPU-only build has none and checks
/// the refusal instead.
fn gpu_available() -> bool {
    #[cfg(feature = "gpu")]
    {
        gpu::context().is_some()
    }
    #[cfg(not(feature = "gpu"))]
    {
        false
    }
}

/// Whether a hardware GPU adapter is available (what `--backend auto` takes).
fn hardware_gpu() -> bool {
    #[cfg(feature = "gpu")]
    {
        gpu::context().is_some_and(|c| !c.is_software())
    }
    #[cfg(not(feature = "gpu"))]
    {
        false
    }
}

#[test]
fn scenario_series_table_takes_an_engine_key() {
    let c: SeriesConfig = toml::from_str("engine = \"smap-dp\"").unwrap();
    assert_eq!(c.engine, SeriesEngine::SmapDp);
    let c: SeriesConfig = toml::from_str("engine = \"smap-dp\"\nbackend = \"gpu\"").unwrap();
    assert_eq!(
        (c.engine, c.backend),
        (SeriesEngine::SmapDp, penumbra::gpu::Backend::Gpu)
    );
    let c: SeriesConfig = toml::from_str("plots = false").unwrap();
    assert_eq!(c.engine, SeriesEngine::Horizon);
    let e = toml::from_str::<SeriesConfig>("engine = \"fourier\"").unwrap_err();
    assert!(e.to_string().contains("fourier"), "{e}");
}

/// The five sites of [`engines_agree_on_the_synthetic_dem`].
fn synthetic_sites() -> [Site; 5] {
    [
        site("ridge", -89.6, 0.0),
        site("plateau", -89.5, 45.0),
        site("pole", -89.95, 120.0),
        site("west", -89.7, 250.0),
        site("south", -89.45, 170.0),
    ]
}

fn synthetic_stack() -> TerrainStack {
    TerrainStack::new(vec![
        synth::south_polar_dem(&synth::SynthParams::default()).unwrap(),
    ])
}

/// Inputs of the per-site DP kernel for the synthetic sites over a month hourly: the CPU engine,
/// its f32 grid, mipmap, observers, disc table (f32) and f64 disc centres/radii, and the
/// ephemeris sites.
struct KernelInputs {
    dp: SmapDpSites,
    march: MarchGrid,
    mip: DpMip,
    observers: Vec<[f32; 4]>,
    lights: Vec<[f32; 4]>,
    discs: Vec<(f64, f64)>,
    directions: Vec<nalgebra::Vector3<f64>>,
    epochs: usize,
}

fn kernel_inputs() -> KernelInputs {
    let stack = synthetic_stack();
    let specs = synthetic_sites();
    let dp = SmapDpSites::new(&stack, &specs).unwrap();
    let sites: Vec<ephem::Site> = specs
        .iter()
        .enumerate()
        .map(|(i, s)| {
            ephem::Site::new(
                s.lat_deg(),
                s.lon_deg(),
                dp.ground_height_m(i) + s.height_above_ground_m(),
            )
            .unwrap()
        })
        .collect();
    let kernels = Kernels::load(&kernels_dir()).unwrap();
    let epochs = month_hourly();
    let table = ephem::moon_geometry_table(&kernels, &epochs).unwrap();
    let march = MarchGrid::from_height_field(&dp.grid().hf, 0.0).unwrap();
    let mip = DpMip::build(&march);
    let observers = dp.site_observers_f32(&march);
    let (lights, discs) = dp.disc_table(&table, &sites, AbCorr::LtS);
    // The f64 MOON_ME vectors of the same discs, for the CPU engine.
    let mut directions = Vec::new();
    for site in &sites {
        for geo in &table {
            let obs = ephem::topo::Observer::new(geo, site);
            for target in [&geo.sun_wrt_moon, &geo.earth_wrt_moon] {
                directions.push(ephem::topo::target_from_observer(
                    geo,
                    target,
                    &obs,
                    AbCorr::LtS,
                ));
            }
        }
    }
    KernelInputs {
        dp,
        march,
        mip,
        observers,
        lights,
        discs,
        directions,
        epochs: epochs.len(),
    }
}

/// Max and mean |a − b|.
fn max_mean(a: &[f64], b: &[f64]) -> (f64, f64) {
    let (max, sum) = a.iter().zip(b).fold((0.0_f64, 0.0), |(m, s), (x, y)| {
        ((x - y).abs().max(m), s + (x - y).abs())
    });
    (max, sum / a.len() as f64)
}

/// Fractions (uniform discs) of a `dp_sites` output.
fn fractions_of(tans: &[f32], discs: &[(f64, f64)]) -> Vec<f64> {
    tans.iter()
        .zip(discs)
        .map(|(&t, &(e_c, r))| fraction_from_horizon_tan(t, e_c, r, &LimbDarkening::UNIFORM))
        .collect()
}

/// The f32 twin of `shaders/dp_sites.wgsl` against the f64 CPU engine (`SmapDpSites::fraction`,
/// recursive DP search) on the same sites and discs: the twin's stackless walk evaluates the same
/// lattice crossings, so only f32 rounding separates them. Measured: see docs/VALIDATION.md.
#[test]
fn dp_sites_twin_matches_the_cpu_engine() {
    let k = kernel_inputs();
    let twin = twins::dp_sites(&k.march, &k.mip, &k.observers, &k.lights);
    let twin_f = fractions_of(&twin, &k.discs);
    let cpu_f: Vec<f64> = k
        .directions
        .iter()
        .zip(&k.discs)
        .enumerate()
        .map(|(n, (v, &(_, r)))| {
            k.dp.fraction(n / (2 * k.epochs), v, r, &LimbDarkening::UNIFORM)
        })
        .collect();
    let (max, mean) = max_mean(&cpu_f, &twin_f);
    let partial = cpu_f.iter().filter(|&&f| f > 0.01 && f < 0.99).count();
    eprintln!(
        "dp_sites twin vs CPU engine: {} discs ({partial} partial), max |Δ| {max:.2e}, mean {mean:.2e}",
        cpu_f.len()
    );
    assert!(partial > 100, "only {partial} partly visible discs");
    assert!(max < 2e-3 && mean < 1e-5, "max {max}, mean {mean}");
}

#[cfg(feature = "gpu")]
mod gpu {
    use penumbra::compute::site_dp::SmapDpGpu;
    use penumbra::gpu::dp::{GpuDpGrid, dp_sites_gpu};

    use super::*;

    pub(super) use crate::util::gpu as context;

    /// `shaders/dp_sites.wgsl` against its f32 twin on the same inputs (5 sites × 745 epochs ×
    /// Sun and Earth), as horizon tangents and as visible fractions.
    #[test]
    fn dp_sites_gpu_matches_twin() {
        let Some(ctx) = context() else { return };
        let k = kernel_inputs();
        let grid = GpuDpGrid::upload(ctx, &k.march, &k.mip).unwrap();
        let gpu = dp_sites_gpu(ctx, &grid, &k.observers, &k.lights).unwrap();
        let twin = twins::dp_sites(&k.march, &k.mip, &k.observers, &k.lights);
        assert_eq!(gpu.len(), twin.len());
        let (max_f, mean_f) = max_mean(
            &fractions_of(&twin, &k.discs),
            &fractions_of(&gpu, &k.discs),
        );
        // Horizon tangents where both found terrain below the cap (uncapped values agree).
        let none = 0.5 * twins::NO_HORIZON_TAN;
        let mismatched = gpu
            .iter()
            .zip(&twin)
            .filter(|(g, t)| (**g > none) != (**t > none))
            .count();
        eprintln!(
            "dp_sites GPU vs twin ({}): {} discs, fraction max |Δ| {max_f:.2e}, mean {mean_f:.2e}, \
             {mismatched} terrain/no-terrain mismatches",
            ctx.adapter_name(),
            gpu.len()
        );
        assert_eq!(mismatched, 0);
        assert!(max_f < 1e-3 && mean_f < 1e-6, "max {max_f}, mean {mean_f}");
        // Bad input is an error, not a panic or a wrong answer: a table that is not a whole
        // number of discs per site, a site off the lattice, a light that is not a unit vector.
        assert!(dp_sites_gpu(ctx, &grid, &k.observers, &k.lights[..k.lights.len() - 1]).is_err());
        let mut off = k.observers.clone();
        off[0][0] = k.march.cols as f32;
        assert!(dp_sites_gpu(ctx, &grid, &off, &k.lights).is_err());
        let mut bad = k.lights.clone();
        bad[3] = [2.0, 0.0, 0.0, 0.0];
        assert!(dp_sites_gpu(ctx, &grid, &k.observers, &bad).is_err());
    }

    /// Epoch batches of the GPU path: 7 epochs per call (107 calls for 745 epochs, the last one
    /// short) give bit-identical fractions to one call for the whole month.
    #[test]
    fn smap_dp_gpu_epoch_batches_are_seamless() {
        let Some(ctx) = context() else { return };
        let stack = synthetic_stack();
        let specs = synthetic_sites();
        let dp = SmapDpSites::new(&stack, &specs).unwrap();
        let sites: Vec<ephem::Site> = specs
            .iter()
            .enumerate()
            .map(|(i, s)| {
                ephem::Site::new(s.lat_deg(), s.lon_deg(), dp.ground_height_m(i) + 2.0).unwrap()
            })
            .collect();
        let kernels = Kernels::load(&kernels_dir()).unwrap();
        let table = ephem::moon_geometry_table(&kernels, &month_hourly()).unwrap();
        let limb = LimbLaw::default().law();
        let whole = SmapDpGpu::new(ctx, &dp)
            .unwrap()
            .fractions(&dp, &table, &sites, limb, AbCorr::LtS)
            .unwrap();
        let batched = SmapDpGpu::new(ctx, &dp)
            .unwrap()
            .with_discs_per_call(2 * 7 * sites.len())
            .fractions(&dp, &table, &sites, limb, AbCorr::LtS)
            .unwrap();
        assert_eq!(whole.len(), sites.len());
        assert!(
            whole
                .iter()
                .all(|(s, e)| s.len() == table.len() && e.len() == table.len())
        );
        assert_eq!(whole, batched);
        let lit: usize = whole
            .iter()
            .map(|(s, _)| s.iter().filter(|&&f| f > 0.0).count())
            .sum();
        assert!(lit > 100, "{lit} lit epochs");
    }

    /// One month hourly of `sites` with `engine` on `backend`.
    fn run_with(
        stack: &TerrainStack,
        sites: &[Site],
        config: SeriesConfig,
        engine: SeriesEngine,
        backend: penumbra::gpu::Backend,
    ) -> Vec<series::SiteOutcome> {
        let kernels = Kernels::load(&kernels_dir()).unwrap();
        let epochs = month_hourly();
        let dir = tempfile::tempdir().unwrap();
        let cfg = SeriesConfig {
            engine,
            backend,
            ..config
        };
        series::run_series(&kernels, stack, sites, &epochs, 3600.0, &cfg, dir.path())
            .unwrap()
            .outcomes
    }

    /// Per-epoch Sun and Earth fractions of every site, concatenated.
    fn flat(o: &[series::SiteOutcome]) -> Vec<f64> {
        o.iter()
            .flat_map(|o| o.sun_fraction.iter().chain(&o.earth_fraction).copied())
            .collect()
    }

    /// smap-dp GPU vs CPU on the real LOLA 240 m crop (1536², the four sites of
    /// [`engines_agree_on_the_lola_crop`]); skipped when the shared grid is absent.
    #[test]
    fn series_smap_dp_gpu_matches_cpu_on_the_lola_crop() {
        if context().is_none() {
            return;
        }
        let Some(path) = shared_lola("ldem75s_crop_240m_pm184km.tif") else {
            return;
        };
        let stack = TerrainStack::load(&[path]).unwrap();
        let sites = lola_crop_sites();
        let config = quiet();
        let cpu = run_with(
            &stack,
            &sites,
            config.clone(),
            SeriesEngine::SmapDp,
            penumbra::gpu::Backend::Cpu,
        );
        let gpu = run_with(
            &stack,
            &sites,
            config,
            SeriesEngine::SmapDp,
            penumbra::gpu::Backend::Gpu,
        );
        let (max, mean) = max_mean(&flat(&cpu), &flat(&gpu));
        eprintln!(
            "lola-240m smap-dp gpu vs cpu: per-epoch fraction max |Δ| {max:.2e}, mean {mean:.2e}"
        );
        for (c, g) in cpu.iter().zip(&gpu) {
            let d = differences(&(
                c.sun_fraction.clone(),
                c.earth_fraction.clone(),
                g.sun_fraction.clone(),
                g.earth_fraction.clone(),
            ));
            eprintln!(
                "lola-240m smap-dp gpu vs cpu {:>16}: |Δ| lit {:.2} pp, sun {:.1e}, earth {:.1e}, earth vis {:.2} pp",
                c.site.name(),
                d[0],
                d[1],
                d[2],
                d[3]
            );
            assert!(
                d[0] <= 0.2 && d[1] <= 2e-4 && d[2] <= 2e-4 && d[3] <= 0.2,
                "{}: {d:?}",
                c.site.name()
            );
        }
        // Measured: max 1.95e-3, mean 7.9e-6 (docs/VALIDATION.md).
        assert!(max < 1e-2 && mean < 5e-5, "max {max}, mean {mean}");
    }

    /// The whole series: smap-dp on the GPU against smap-dp on the CPU (same sites, same month,
    /// Eddington limb darkening) and against the horizon engine (the CPU smap-dp bounds).
    #[test]
    fn series_smap_dp_gpu_matches_cpu() {
        if context().is_none() {
            return;
        }
        let stack = synthetic_stack();
        let sites = synthetic_sites();
        let config = SeriesConfig {
            disc_method: DiscMethod::Exact,
            limb_darkening: LimbLaw::Eddington,
            engine: SeriesEngine::SmapDp,
            ..quiet()
        };
        let run = |engine, backend| run_with(&stack, &sites, config.clone(), engine, backend);
        let cpu = run(SeriesEngine::SmapDp, penumbra::gpu::Backend::Cpu);
        let gpu = run(SeriesEngine::SmapDp, penumbra::gpu::Backend::Gpu);
        let horizon = run(SeriesEngine::Horizon, penumbra::gpu::Backend::Cpu);
        let pairs = |a: &[series::SiteOutcome], b: &[series::SiteOutcome]| -> Vec<Pair> {
            a.iter()
                .zip(b)
                .map(|(a, b)| {
                    (
                        a.sun_fraction.clone(),
                        a.earth_fraction.clone(),
                        b.sun_fraction.clone(),
                        b.earth_fraction.clone(),
                    )
                })
                .collect()
        };
        let (max, mean) = max_mean(&flat(&cpu), &flat(&gpu));
        eprintln!("smap-dp gpu vs cpu: per-epoch fraction max |Δ| {max:.2e}, mean {mean:.2e}");
        assert!(max < 2e-3 && mean < 1e-5, "max {max}, mean {mean}");
        check(
            "smap-dp gpu vs cpu",
            &sites,
            &pairs(&cpu, &gpu),
            &Bounds {
                sun_lit_pct: 0.2,
                sun_mean: 1e-4,
                earth_mean: 1e-4,
                earth_visible_pct: 0.2,
                big_epochs_pct: 0.0,
            },
        );
        check(
            "horizon vs smap-dp gpu",
            &sites,
            &pairs(&horizon, &gpu),
            &Bounds {
                sun_lit_pct: 0.5,
                sun_mean: 0.005,
                earth_mean: 0.005,
                earth_visible_pct: 1.5,
                big_epochs_pct: 1.5,
            },
        );
    }
}
