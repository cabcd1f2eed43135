//! `penumbra map` through the binary: georeferencing read back by GDAL, analytic lights, bad input.
//! Sharded maps are in `shard`.

mod shard;

use crate::util::OutputWithin as _;
use crate::util::{assert_clean_error, files_in, kernels_dir, penumbra, penumbra_ok, read_tif};

/// `gdalinfo -json -stats` of `path`, or `None` when GDAL is not installed (a failure unless
/// `PENUMBRA_SKIP=gdal`); a failure of gdalinfo itself fails the test.
fn gdalinfo_json(path: &std::path::Path) -> Option<serde_json::Value> {
    if !crate::util::tool("gdalinfo", "gdal-bin") {
        return None;
    }
    let out = std::process::Command::new("gdalinfo")
        .args(["-json", "-stats"])
        .arg(path)
        .output_within()
        .expect("run gdalinfo");
    assert!(out.status.success(), "gdalinfo {}: {out:?}", path.display());
    Some(serde_json::from_slice(&out.stdout).expect("gdalinfo's JSON"))
}

/// Runs `penumbra map --synthetic --engine <engine> --sun-az-deg 135 --sun-el-deg <el_deg>`
/// with the output options `outputs` in `dir` and asserts that it succeeded.
fn map_synthetic_az135(dir: &std::path::Path, engine: &str, el_deg: &str, outputs: &[&str]) {
    let mut args = vec![
        "map",
        "--synthetic",
        "--engine",
        engine,
        "--sun-az-deg",
        "135",
        "--sun-el-deg",
        el_deg,
    ];
    args.extend_from_slice(outputs);
    penumbra_ok(dir, &args);
}

/// The hard mask of the brute-force reference (the tests' oracle, a library engine) on the
/// synthetic DEM of `--synthetic` for a Sun at azimuth 135° and `el_deg` at the map centre, per
/// DEM pixel from the pixels' own observers 2 m up: what `map_synthetic_az135` maps.
fn brute_mask_synthetic_az135(el_deg: f64) -> Vec<f32> {
    use penumbra::model::{MapEngine, MapEngineKind, MapGrid};
    let dem = penumbra::terrain::synth::south_polar_dem(
        &penumbra::terrain::synth::SynthParams::default(),
    )
    .unwrap();
    let grid = MapGrid::new(&penumbra::terrain::TerrainStack::new(vec![dem])).unwrap();
    let observers = grid.pixel_observers(2.0);
    let brute = MapEngine::new(
        MapEngineKind::Direct(penumbra::shadow::Engine::Brute),
        &grid,
        2.0,
    )
    .unwrap();
    brute
        .hard_mask_on_dem(
            &grid,
            Some(&observers),
            2.0,
            grid.light_from_az_el_deg(135.0, el_deg),
        )
        .unwrap()
        .into_iter()
        .map(f32::from)
        .collect()
}

#[test]
fn one_light_maps_carry_the_dem_georeferencing_and_obey_the_horizon() {
    let dir = tempfile::tempdir().unwrap();
    // Sun 30° up with the combined engine (SMap's hard mask), against the brute-force reference;
    // Sun 5° below the horizon: almost everything dark (not an error).
    for (engine, el, name) in [("combined", "30", "high"), ("combined", "-5", "below")] {
        let (mask, fraction) = (format!("{name}_mask.tif"), format!("{name}_frac.tif"));
        map_synthetic_az135(
            dir.path(),
            engine,
            el,
            &["--out-mask", &mask, "--out-fraction", &fraction],
        );
    }
    // SMap agrees with brute force on the DEM grid (the tolerance: 0.3% of pixels).
    let read = |name: &str| read_tif(dir.path(), name);
    let smap = read("high_mask.tif");
    let brute = brute_mask_synthetic_az135(30.0);
    assert_eq!(smap.heights_m.len(), brute.len());
    let differ = smap
        .heights_m
        .iter()
        .zip(&brute)
        .filter(|(a, b)| a != b)
        .count();
    let pct = 100.0 * differ as f64 / smap.heights_m.len() as f64;
    assert!(
        pct <= 0.3,
        "SMap vs brute force: {pct:.3}% of pixels differ"
    );
    let lit = smap.heights_m.iter().filter(|&&v| v == 1.0).count() as f64;
    assert!(
        lit / smap.heights_m.len() as f64 > 0.5,
        "a 30° Sun lights most of the DEM"
    );
    let dem = dir.path().join("dem.tif");
    penumbra_ok(
        dir.path(),
        &["dem", "synth", "--out", dem.to_str().unwrap()],
    );
    let Some(dem_info) = gdalinfo_json(&dem) else {
        return;
    };
    for name in [
        "high_mask.tif",
        "high_frac.tif",
        "below_mask.tif",
        "below_frac.tif",
    ] {
        let info = gdalinfo_json(&dir.path().join(name)).expect("gdalinfo reads the map");
        assert_eq!(info["geoTransform"], dem_info["geoTransform"], "{name}");
        assert_eq!(info["size"], dem_info["size"], "{name}");
        let wkt = info["coordinateSystem"]["wkt"].as_str().unwrap();
        assert!(wkt.contains("Polar") || wkt.contains("polar"), "{wkt}");
    }
    let mean = |name: &str| -> f64 {
        let info = gdalinfo_json(&dir.path().join(name)).unwrap();
        info["bands"][0]["mean"].as_f64().unwrap()
    };
    assert!(
        mean("high_frac.tif") > 0.5,
        "30° Sun lights most cells: {}",
        mean("high_frac.tif")
    );
    // A Sun 5° below the horizontal at the centre: only terrain blocks (docs/ARCHITECTURE.md), so
    // the cells lit are those whose rays leave this 40 km DEM above its terrain (edges, summits
    // facing out; the run warns that the Moon beyond the DEM would block them): 5.6 % measured.
    let (below_frac, below_mask) = (mean("below_frac.tif"), mean("below_mask.tif"));
    eprintln!("Sun at -5°: mean fraction {below_frac:.4}, mean mask {below_mask:.4}");
    assert!(
        below_frac < 0.1 && below_mask < 0.1,
        "a Sun 5° below the horizon lights almost nothing: {below_frac} {below_mask}"
    );
}

#[test]
fn epoch_range_writes_every_statistic_and_preview() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    penumbra_ok(
        dir.path(),
        &[
            "map",
            "--synthetic",
            "--start",
            "2027-02-01",
            "--stop",
            "2027-02-03",
            "--step",
            "12h",
            "--out-dir",
            "maps",
            "--kernels",
            k.to_str().unwrap(),
        ],
    );
    let files = files_in(&dir.path().join("maps"));
    for f in [
        "sun_illumination_pct.tif",
        "sun_illumination_pct.png",
        "longest_dark_h.tif",
        "psr_mask.tif",
        "psr_mask.png",
        "earth_visible_pct.tif",
        "sun_and_earth_pct.tif",
        "run.json",
    ] {
        assert!(files.contains(&f.to_string()), "{f} missing: {files:?}");
    }
    let img = image::open(dir.path().join("maps/sun_illumination_pct.png")).unwrap();
    assert!(img.width() >= 400 && img.height() >= 300);
}

#[test]
fn bad_light_input_is_a_clean_error() {
    let dir = tempfile::tempdir().unwrap();
    for (dir_arg, needle) in [
        ("0,0,0", "non-zero"),
        ("nan,1,0", "finite"),
        ("1,2", "three"),
    ] {
        let out = penumbra(
            dir.path(),
            &[
                "map",
                "--synthetic",
                "--sun-dir-body",
                dir_arg,
                "--out-mask",
                "m.tif",
            ],
        );
        assert_clean_error(&out, needle);
    }
    let out = penumbra(
        dir.path(),
        &[
            "map",
            "--synthetic",
            "--sun-az-deg",
            "10",
            "--sun-el-deg",
            "2",
        ],
    );
    assert_clean_error(&out, "nothing to write");
    assert!(files_in(dir.path()).is_empty(), "nothing half-written");
}

/// The Fourier horizon-map engine (paper 001) against the brute-force reference on the DEM grid:
/// the truncated DFT smooths each cell's horizon, which moves shadow edges by a cell or two.
/// Measured 0.32% of pixels at 5° on the synthetic DEM (docs/shadow.md has the per-field table);
/// the bound leaves room for the 1.6% seen on rougher fields.
#[test]
fn fourier_engine_map_agrees_with_brute_force() {
    let dir = tempfile::tempdir().unwrap();
    map_synthetic_az135(dir.path(), "fourier", "5", &["--out-mask", "fourier.tif"]);
    let f = read_tif(dir.path(), "fourier.tif");
    let b = brute_mask_synthetic_az135(5.0);
    assert_eq!(f.heights_m.len(), b.len());
    let differ = f.heights_m.iter().zip(&b).filter(|(x, y)| x != y).count();
    let pct = 100.0 * differ as f64 / f.heights_m.len() as f64;
    eprintln!("fourier vs brute force: {pct:.3}% of pixels differ");
    assert!(
        pct < 2.0,
        "fourier vs brute force: {pct:.3}% of pixels differ"
    );
}

#[test]
fn gpu_maps_start_at_the_pixels_and_say_so() {
    // On the GPU too the rays start at the DEM pixels by default (`dp_points.wgsl`), and the
    // GeoTIFF's metadata says where they started; `--observers cells` still gives the model
    // cells. A build without the GPU: one error line and no file.
    let dir = tempfile::tempdir().unwrap();
    let map = |observers: &[&str], name: &str| {
        let mut args = vec![
            "map",
            "--synthetic",
            "--sun-az-deg",
            "10",
            "--sun-el-deg",
            "3",
            "--out-mask",
            name,
            "--backend",
            "gpu",
        ];
        args.extend_from_slice(observers);
        crate::util::penumbra(dir.path(), &args)
    };
    let out = map(&[], "m.tif");
    if cfg!(not(feature = "gpu")) {
        // A build without the GPU: one error line, no file.
        crate::util::assert_clean_error(&out, "--backend");
        assert!(!dir.path().join("m.tif").exists());
        return;
    }
    #[cfg(feature = "gpu")]
    if crate::util::gpu().is_none() {
        return;
    }
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = |name: &str| {
        String::from_utf8_lossy(&std::fs::read(dir.path().join(name)).unwrap()).into_owned()
    };
    let words = |p: penumbra::model::ObserverPlacement| p.describe().to_string();
    assert!(text("m.tif").contains(&words(penumbra::model::ObserverPlacement::Pixels)));
    let out = map(&["--observers", "cells"], "c.tif");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text("c.tif").contains(&words(penumbra::model::ObserverPlacement::Cells)));
}
