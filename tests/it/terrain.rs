//! Terrain (issue 4): `penumbra dem info|synth` through the binary, GeoTIFF output checked with
//! GDAL, the real LOLA grids of `../shared/data/lola-south-pole-moondao/`, and bad inputs.

use crate::util::OutputWithin as _;
use crate::util::{penumbra_command, penumbra_exe, shared_lola};
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use penumbra::terrain::{
    self, GridGeometry, ModelGridSpec, Projection, TerrainStack, geotiff, resample_to_model_space,
    synth,
};

const INNER: &str = "ldem75s_crop_240m_pm184km.tif";
const FAR: &str = "ldem75s_far_1787m_pm457km_feathered.tif";
const SITE01: &str = "site01_connecting_ridge_10m.tif";

fn run(args: &[&str]) -> Output {
    penumbra_command().args(args).output_within().unwrap()
}

/// Whether the GDAL tool `tool` runs ([`crate::util::tool`]: a failure naming it, or a recorded
/// skip with `PENUMBRA_SKIP=gdal`).
fn has_tool(tool: &str) -> bool {
    crate::util::tool(tool, "gdal-bin")
}

/// Asserts the CLI failed cleanly: exit code 2, one line on stderr, no panic.
fn assert_clean_failure(out: &Output, expect_in_message: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "stderr: {stderr}");
    assert!(stderr.starts_with("penumbra: error: "), "stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "stderr: {stderr}");
    assert!(
        stderr
            .to_lowercase()
            .contains(&expect_in_message.to_lowercase()),
        "expected {expect_in_message:?} in: {stderr}"
    );
}

/// PROVENANCE.md's cross-check heights (bilinear, m): (lat, lon, site01, inner, far).
const CROSS_CHECKS: [(f64, f64, f64, f64, f64); 4] = [
    (-89.45, 222.7, 1954.9, 1948.9, 1800.3),
    (-89.3, 200.0, 940.0, 938.9, 902.1),
    (-89.6, 250.0, 647.7, 648.0, 566.5),
    (-89.5, 210.0, 1520.6, 1521.3, 1530.7),
];
/// The cross-check values are printed to 0.1 m; sampling conventions may differ by a little.
const CROSS_CHECK_TOL_M: f64 = 1.0;

fn info_json(path: &Path, at: &[(f64, f64)]) -> serde_json::Value {
    let mut args = vec![
        "dem".to_string(),
        "info".into(),
        path.display().to_string(),
        "--format".into(),
        "json".into(),
    ];
    for (lat, lon) in at {
        args.push("--at".into());
        args.push(format!("{lat},{lon}"));
    }
    let out = penumbra_command().args(&args).output_within().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn dem_info_reports_the_lola_crop_and_provenance_heights() {
    let Some(inner) = shared_lola(INNER) else {
        return;
    };
    let mut at: Vec<(f64, f64)> = CROSS_CHECKS.iter().map(|c| (c.0, c.1)).collect();
    at.push((-85.99, 2.93)); // Malapert: inner 5121
    at.push((-89.67, 129.8)); // Shackleton floor: ~ -2783
    let v = info_json(&inner, &at);
    assert_eq!(
        (v["cols"].as_u64(), v["rows"].as_u64()),
        (Some(1536), Some(1536))
    );
    assert_eq!(
        (v["px_x_m"].as_f64(), v["px_y_m"].as_f64()),
        (Some(240.0), Some(240.0))
    );
    assert_eq!(v["projection"], "polar stereographic (south)");
    assert!(
        v["proj"]
            .as_str()
            .unwrap()
            .contains("+proj=stere +lat_0=-90")
    );
    assert!(v["proj"].as_str().unwrap().contains("+R=1737400"));
    let b: Vec<f64> = v["bounds_xy_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(b, vec![-184320.0, -184320.0, 184320.0, 184320.0]);
    assert_eq!(v["nodata_count"].as_u64(), Some(0));
    // PROVENANCE.md: "axes reach ~83.9 S, corners ~81.4 S".
    assert!((v["lat_max_deg"].as_f64().unwrap() - -81.42).abs() < 0.01);
    let pts = v["points"].as_array().unwrap();
    // PROVENANCE.md gives Malapert as 5121 (whole metres) and the Shackleton floor as
    // "~ -2783" (approximate), so that one gets 2 m.
    let expected: Vec<(f64, f64)> = CROSS_CHECKS
        .iter()
        .map(|c| (c.3, CROSS_CHECK_TOL_M))
        .chain([(5121.0, CROSS_CHECK_TOL_M), (-2783.0, 2.0)])
        .collect();
    assert_eq!(pts.len(), expected.len());
    for (p, (want, tol)) in pts.iter().zip(&expected) {
        let h = p["height_m"].as_f64().unwrap();
        assert!((h - want).abs() < *tol, "{p} vs {want}");
    }
    // The text format says the same.
    let out = run(&["dem", "info", inner.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("size: 1536 x 1536 px"), "{text}");
    assert!(text.contains("pixel size: 240 x 240 m"), "{text}");
    assert!(text.contains("bounds x: -184320 .. 184320 m"), "{text}");
}

#[test]
fn provenance_heights_match_in_the_far_field_and_site01_grids() {
    let (Some(far), Some(site)) = (shared_lola(FAR), shared_lola(SITE01)) else {
        return;
    };
    let at: Vec<(f64, f64)> = CROSS_CHECKS.iter().map(|c| (c.0, c.1)).collect();
    let v = info_json(&site, &at);
    assert_eq!(v["px_x_m"].as_f64(), Some(10.0));
    for (p, c) in v["points"].as_array().unwrap().iter().zip(&CROSS_CHECKS) {
        assert!(
            (p["height_m"].as_f64().unwrap() - c.2).abs() < CROSS_CHECK_TOL_M,
            "{p}"
        );
    }
    let mut at_far = at.clone();
    at_far.push((-85.99, 2.93)); // Malapert: far 5043
    let v = info_json(&far, &at_far);
    let want: Vec<f64> = CROSS_CHECKS.iter().map(|c| c.4).chain([5043.0]).collect();
    for (p, w) in v["points"].as_array().unwrap().iter().zip(&want) {
        assert!(
            (p["height_m"].as_f64().unwrap() - w).abs() < CROSS_CHECK_TOL_M,
            "{p}"
        );
    }
}

#[test]
fn lat_lon_to_xy_round_trip_is_below_a_millimetre_on_the_lola_projection() {
    let Some(inner) = shared_lola(INNER) else {
        return;
    };
    let dem = terrain::load_dem(&inner).unwrap();
    let p = dem.projection;
    let mut worst_m: f64 = 0.0;
    for i in 0..200 {
        let lat = -90.0 + 8.5 * f64::from(i) / 200.0;
        let lon = -180.0 + 359.9 * f64::from(i * 37 % 200) / 200.0;
        let (x, y) = p.xy_from_lat_lon(lat, lon);
        let (lat2, lon2) = p.lat_lon_from_xy(x, y);
        // Distance on the sphere between (lat, lon) and (lat2, lon2), metres.
        let a = penumbra::frames::site_in_moon_me_km(lat, lon, 0.0);
        let b = penumbra::frames::site_in_moon_me_km(lat2, lon2, 0.0);
        worst_m = worst_m.max((a - b).norm() * 1e3);
        let (x2, y2) = p.xy_from_lat_lon(lat2, lon2);
        worst_m = worst_m.max((x - x2).hypot(y - y2));
    }
    assert!(worst_m < 1e-3, "worst round trip {worst_m} m");
}

#[test]
fn reading_the_1536_dem_peaks_below_one_and_a_half_times_its_size() {
    let Some(inner) = shared_lola(INNER) else {
        return;
    };
    let time = Path::new("/usr/bin/time");
    if !time.exists() {
        crate::util::missing("tools", "/usr/bin/time", "apt-get install time");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let tiny = dir.path().join("tiny.tif");
    assert!(
        run(&[
            "dem",
            "synth",
            "--size",
            "4",
            "--out",
            tiny.to_str().unwrap()
        ])
        .status
        .success()
    );
    let peak_kib = |file: &Path| -> f64 {
        let out = Command::new(time)
            .args(["-f", "%M"])
            .arg(penumbra_exe())
            .args(["dem", "info"])
            .arg(file)
            .output_within()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        err.trim().lines().last().unwrap().trim().parse().unwrap()
    };
    let base_kib = peak_kib(&tiny);
    let big_kib = peak_kib(&inner);
    let dem_kib = (1536.0 * 1536.0 * 4.0) / 1024.0;
    let ratio = (big_kib - base_kib) / dem_kib;
    println!(
        "peak RSS {big_kib} KiB, baseline {base_kib} KiB, DEM {dem_kib} KiB, ratio {ratio:.3}"
    );
    assert!(ratio < 1.5, "ratio {ratio}");
}

#[test]
fn resampling_the_lola_stack_into_model_space_lands_on_the_surface() {
    let (Some(inner), Some(far), Some(site)) =
        (shared_lola(INNER), shared_lola(FAR), shared_lola(SITE01))
    else {
        return;
    };
    let stack = TerrainStack::load(&[far, inner, site]).unwrap();
    assert_eq!(stack.layers[0].px_m(), 10.0, "finest first");
    let spec = ModelGridSpec {
        centre_lat_deg: -89.45,
        centre_lon_deg: 222.7,
        rows: 128,
        cols: 128,
        px_m: 1000.0,
        rotation_rad: 0.0,
    };
    let (hf, stats) = resample_to_model_space(&stack, &spec).unwrap();
    assert_eq!(stats.holes, 0);
    assert_eq!(stats.unconverged, 0);
    println!("{stats:?}");
    let frame = terrain::ModelFrame::of(&hf);
    let mut worst_m: f64 = 0.0;
    for row in (0..hf.rows).step_by(7) {
        for col in (0..hf.cols).step_by(5) {
            let (x, y) = hf.xy_from_row_col(row as f64, col as f64);
            let z = f64::from(hf.z_at(row as isize, col as isize).unwrap());
            let (lat, lon, h) = frame.lat_lon_height_from_model(&nalgebra::Vector3::new(x, y, z));
            let (dem_h, _) = stack.height_at_lat_lon_m(lat, lon).unwrap();
            worst_m = worst_m.max((h - dem_h).abs());
        }
    }
    println!("LOLA stack -> model space: worst residual {worst_m:.2e} m");
    // f32 storage of z (|z| up to ~5 km here: ulp 0.5 mm) bounds the residual.
    assert!(worst_m < 2e-3, "worst residual {worst_m} m");
}

fn gdal_json(path: &Path) -> serde_json::Value {
    let out = Command::new("gdalinfo")
        .args(["-json", "-proj4"])
        .arg(path)
        .output_within()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn gdal_value(path: &Path, col: usize, row: usize) -> f64 {
    let out = Command::new("gdallocationinfo")
        .arg("-valonly")
        .arg(path)
        .args([col.to_string(), row.to_string()])
        .output_within()
        .unwrap();
    String::from_utf8_lossy(&out.stdout).trim().parse().unwrap()
}

#[test]
fn synth_geotiff_reads_back_in_gdal_with_the_same_georeferencing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("synth.tif");
    let o = run(&[
        "dem",
        "synth",
        "--size",
        "64",
        "--px-m",
        "250",
        "--seed",
        "3",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (ours, items) = geotiff::read_geotiff_with_metadata(&out).unwrap();
    // Our own reader round-trips exactly what the generator made.
    let direct = synth::south_polar_dem(&synth::SynthParams {
        size_px: 64,
        px_m: 250.0,
        seed: 3,
    })
    .unwrap();
    assert_eq!(ours.heights_m, direct.heights_m);
    assert_eq!(ours.grid, direct.grid);
    assert!(items.iter().any(|(k, v)| k == "synth_seed" && v == "3"));
    if !has_tool("gdalinfo") {
        return;
    }
    let v = gdal_json(&out);
    let proj4 = v["coordinateSystem"]["proj4"].as_str().unwrap();
    for want in [
        "+proj=stere",
        "+lat_0=-90",
        "+lon_0=0",
        "+k=1",
        "+R=1737400",
        "+units=m",
    ] {
        assert!(proj4.contains(want), "{proj4} lacks {want}");
    }
    let gt: Vec<f64> = v["geoTransform"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(gt, vec![-8000.0, 250.0, 0.0, 8000.0, 0.0, -250.0]);
    assert_eq!(v["size"], serde_json::json!([64, 64]));
    assert_eq!(v["metadata"][""]["synth_seed"], "3");
    for &(col, row) in &[(0, 0), (63, 0), (0, 63), (31, 32), (17, 50)] {
        let g = gdal_value(&out, col, row);
        let ours = f64::from(ours.heights_m[row * 64 + col]);
        // gdallocationinfo prints 15 significant digits of the f32 value.
        assert!(
            (g - ours).abs() <= 1e-9 * ours.abs().max(1.0),
            "({col},{row}) {g} vs {ours}"
        );
    }
}

#[test]
fn u8_u16_equirectangular_and_nodata_read_back_in_gdal() {
    if !has_tool("gdalinfo") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let grid = GridGeometry {
        rows: 5,
        cols: 7,
        x_left_m: 1000.0,
        y_top_m: -2000.0,
        px_x_m: 30.0,
        px_y_m: 20.0,
    };
    let eqc = Projection::Equirectangular {
        lon0_deg: 180.0,
        lat_ts_deg: 0.0,
        radius_m: 1_737_400.0,
    };
    let p16 = dir.path().join("u16.tif");
    let v16: Vec<u16> = (0..35).map(|i| i * 1000 + 7).collect();
    terrain::write_geotiff(
        &p16,
        &grid,
        &eqc,
        &v16,
        Some(7),
        &[],
        terrain::BandInfo::default(),
    )
    .unwrap();
    let v = gdal_json(&p16);
    let proj4 = v["coordinateSystem"]["proj4"].as_str().unwrap();
    assert!(
        proj4.contains("+proj=eqc") && proj4.contains("+lon_0=180") && proj4.contains("+R=1737400"),
        "{proj4}"
    );
    assert_eq!(v["bands"][0]["type"], "UInt16");
    assert_eq!(v["bands"][0]["noDataValue"].as_f64(), Some(7.0));
    let gt: Vec<f64> = v["geoTransform"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(gt, vec![1000.0, 30.0, 0.0, -2000.0, 0.0, -20.0]);
    assert_eq!(gdal_value(&p16, 3, 2), f64::from(v16[2 * 7 + 3]));
    let p8 = dir.path().join("u8.tif");
    let v8: Vec<u8> = (0..35).map(|i| i * 7).collect();
    terrain::write_geotiff(
        &p8,
        &grid,
        &Projection::LOLA_SOUTH_POLAR,
        &v8,
        Some(255),
        &[],
        terrain::BandInfo::default(),
    )
    .unwrap();
    let v = gdal_json(&p8);
    assert_eq!(v["bands"][0]["type"], "Byte");
    assert_eq!(gdal_value(&p8, 6, 4), f64::from(v8[4 * 7 + 6]));
}

#[test]
fn gdal_written_tiled_lzw_int16_pixel_is_point_with_scale_reads_correctly() {
    if !has_tool("gdal_translate") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("src.tif");
    let dem = synth::south_polar_dem(&synth::SynthParams {
        size_px: 40,
        px_m: 100.0,
        seed: 5,
    })
    .unwrap();
    terrain::write_dem(&src, &dem, &[]).unwrap();
    for (name, opts) in [
        (
            "tiled_lzw_i16_point.tif",
            &[
                "-ot",
                "Int16",
                "-co",
                "TILED=YES",
                "-co",
                "BLOCKXSIZE=16",
                "-co",
                "BLOCKYSIZE=16",
                "-co",
                "COMPRESS=LZW",
                "-mo",
                "AREA_OR_POINT=Point",
                "-a_scale",
                "0.5",
                "-a_offset",
                "10",
            ][..],
        ),
        (
            "strips_deflate_u16.tif",
            &[
                "-ot",
                "UInt16",
                "-scale",
                "-3000",
                "5000",
                "0",
                "60000",
                "-co",
                "COMPRESS=DEFLATE",
                "-co",
                "BLOCKYSIZE=3",
                "-a_nodata",
                "0",
            ][..],
        ),
        (
            "tiled_deflate_f32.tif",
            &[
                "-co",
                "TILED=YES",
                "-co",
                "BLOCKXSIZE=16",
                "-co",
                "BLOCKYSIZE=16",
                "-co",
                "COMPRESS=DEFLATE",
            ][..],
        ),
        // Float64 and Int32 (issue 18), with the predictors GDAL users set.
        (
            "tiled_deflate_pred3_f64.tif",
            &[
                "-ot",
                "Float64",
                "-co",
                "TILED=YES",
                "-co",
                "COMPRESS=DEFLATE",
                "-co",
                "PREDICTOR=3",
            ][..],
        ),
        (
            "strips_lzw_pred2_i32_scaled.tif",
            &[
                "-ot",
                "Int32",
                "-scale",
                "-3000",
                "5000",
                "-300000",
                "500000",
                "-a_scale",
                "0.01",
                "-co",
                "COMPRESS=LZW",
                "-co",
                "PREDICTOR=2",
            ][..],
        ),
        (
            "cog_f32.tif",
            &["-of", "COG", "-co", "BLOCKSIZE=16", "-co", "PREDICTOR=YES"][..],
        ),
        // ZSTD (decoded by penumbra with the pure-Rust ruzstd), every predictor.
        (
            "tiled_zstd_pred3_f32.tif",
            &[
                "-co",
                "TILED=YES",
                "-co",
                "BLOCKXSIZE=16",
                "-co",
                "BLOCKYSIZE=16",
                "-co",
                "COMPRESS=ZSTD",
                "-co",
                "PREDICTOR=3",
            ][..],
        ),
        (
            "strips_zstd_pred2_i16_scaled.tif",
            &[
                "-ot",
                "Int16",
                "-scale",
                "-3000",
                "5000",
                "-12000",
                "20000",
                "-a_scale",
                "0.25",
                "-co",
                "COMPRESS=ZSTD",
                "-co",
                "PREDICTOR=2",
                "-co",
                "BLOCKYSIZE=7",
            ][..],
        ),
        (
            "tiled_zstd_f64.tif",
            &[
                "-ot",
                "Float64",
                "-co",
                "TILED=YES",
                "-co",
                "BLOCKXSIZE=32",
                "-co",
                "BLOCKYSIZE=16",
                "-co",
                "COMPRESS=ZSTD",
            ][..],
        ),
        (
            "cog_zstd_u16.tif",
            &[
                "-of",
                "COG",
                "-ot",
                "UInt16",
                "-scale",
                "-3000",
                "5000",
                "0",
                "60000",
                "-co",
                "BLOCKSIZE=32",
                "-co",
                "COMPRESS=ZSTD",
                "-co",
                "PREDICTOR=YES",
            ][..],
        ),
    ] {
        let dst = dir.path().join(name);
        let out = Command::new("gdal_translate")
            .arg("-q")
            .args(opts)
            .arg(&src)
            .arg(&dst)
            .output_within()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let back = terrain::read_geotiff(&dst).unwrap();
        assert_eq!(
            back.grid, dem.grid,
            "{name}: pixel-is-point must shift back to the same grid"
        );
        assert_eq!(back.projection, Projection::LOLA_SOUTH_POLAR, "{name}");
        let v = gdal_json(&dst);
        let scale = v["bands"][0]["scale"].as_f64().unwrap_or(1.0);
        let offset = v["bands"][0]["offset"].as_f64().unwrap_or(0.0);
        let nodata = v["bands"][0]["noDataValue"].as_f64();
        for &(col, row) in &[(0, 0), (39, 0), (17, 16), (16, 17), (39, 39), (5, 33)] {
            let raw = gdal_value(&dst, col, row);
            let ours = back.heights_m[row * 40 + col];
            if Some(raw) == nodata {
                assert!(ours.is_nan(), "{name} ({col},{row})");
            } else {
                let want = raw * scale + offset;
                assert!(
                    (f64::from(ours) - want).abs() <= 1e-6 * want.abs().max(1.0),
                    "{name} ({col},{row}): {ours} vs {want}"
                );
            }
        }
    }
}

#[test]
fn bad_inputs_fail_with_one_line_and_exit_code_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let good = d.join("good.tif");
    assert!(
        run(&[
            "dem",
            "synth",
            "--size",
            "32",
            "--out",
            good.to_str().unwrap()
        ])
        .status
        .success()
    );
    let arg = |p: &Path| p.to_str().unwrap().to_string();

    // Missing file.
    assert_clean_failure(
        &run(&["dem", "info", &arg(&d.join("missing.tif"))]),
        "missing.tif",
    );
    // Truncated: the first half of a valid file.
    let bytes = std::fs::read(&good).unwrap();
    let truncated = d.join("truncated.tif");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    assert_clean_failure(&run(&["dem", "info", &arg(&truncated)]), "truncated");
    // Not a TIFF.
    let text = d.join("notes.tif");
    std::fs::write(&text, "these are not the pixels you are looking for\n").unwrap();
    assert_clean_failure(&run(&["dem", "info", &arg(&text)]), "not a TIFF");
    // Unsupported sample format: uint32 (float64 and int32 are read: see
    // gdal_written_float64_int32_and_predictors_read_back).
    let u32_path = d.join("u32.tif");
    let mut buf = Cursor::new(Vec::new());
    tiff::encoder::TiffEncoder::new(&mut buf)
        .unwrap()
        .write_image::<tiff::encoder::colortype::Gray32>(2, 2, &[1, 2, 3, 4])
        .unwrap();
    std::fs::write(&u32_path, buf.into_inner()).unwrap();
    assert_clean_failure(&run(&["dem", "info", &arg(&u32_path)]), "32-bit unsigned");
    // LERC (no pure-Rust decoder): one line that says how to convert.
    if has_tool("gdal_translate") {
        let lerc = d.join("lerc.tif");
        let o = Command::new("gdal_translate")
            .args(["-q", "-co", "COMPRESS=LERC"])
            .arg(&good)
            .arg(&lerc)
            .output_within()
            .unwrap();
        assert!(o.status.success());
        assert_clean_failure(&run(&["dem", "info", &arg(&lerc)]), "COMPRESS=DEFLATE");
    }
    // No georeferencing at all: a plain float32 TIFF.
    let plain = d.join("plain.tif");
    let mut buf = Cursor::new(Vec::new());
    tiff::encoder::TiffEncoder::new(&mut buf)
        .unwrap()
        .write_image::<tiff::encoder::colortype::Gray32Float>(2, 2, &[1.0, 2.0, 3.0, 4.0])
        .unwrap();
    std::fs::write(&plain, buf.into_inner()).unwrap();
    assert_clean_failure(&run(&["dem", "info", &arg(&plain)]), "GeoKeyDirectory");
    // Unknown CRS: EPSG:3031 (Antarctic polar stereographic on WGS 84).
    let earth = d.join("earth.tif");
    let mut buf = Cursor::new(Vec::new());
    {
        let mut enc = tiff::encoder::TiffEncoder::new(&mut buf).unwrap();
        let mut img = enc
            .new_image::<tiff::encoder::colortype::Gray32Float>(2, 2)
            .unwrap();
        let t = img.encoder();
        use tiff::tags::Tag;
        t.write_tag(Tag::ModelPixelScaleTag, &[10.0, 10.0, 0.0][..])
            .unwrap();
        t.write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0][..])
            .unwrap();
        t.write_tag(
            Tag::GeoKeyDirectoryTag,
            &[
                1u16, 1, 0, 3, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, 3031,
            ][..],
        )
        .unwrap();
        img.write_data(&[1.0, 2.0, 3.0, 4.0]).unwrap();
    }
    std::fs::write(&earth, buf.into_inner()).unwrap();
    assert_clean_failure(&run(&["dem", "info", &arg(&earth)]), "EPSG:3031");
    // All nodata.
    let holes = d.join("holes.tif");
    let grid = GridGeometry {
        rows: 3,
        cols: 3,
        x_left_m: 0.0,
        y_top_m: 0.0,
        px_x_m: 1.0,
        px_y_m: 1.0,
    };
    terrain::write_geotiff(
        &holes,
        &grid,
        &Projection::LOLA_SOUTH_POLAR,
        &[f32::NAN; 9],
        Some(f32::NAN),
        &[],
        terrain::BandInfo::default(),
    )
    .unwrap();
    assert_clean_failure(
        &run(&["dem", "info", &arg(&holes)]),
        "every pixel is nodata",
    );
    // A site outside every layer (the synthetic DEM covers 89.3 S .. the pole).
    assert_clean_failure(
        &run(&["dem", "info", &arg(&good), "--at", "-80,0"]),
        "no DEM layer covers",
    );
    // Bad synth parameters, and an output folder that does not exist: no partial file left.
    assert_clean_failure(
        &run(&[
            "dem",
            "synth",
            "--size",
            "0",
            "--out",
            &arg(&d.join("x.tif")),
        ]),
        "invalid terrain parameter",
    );
    assert_clean_failure(
        &run(&[
            "dem",
            "synth",
            "--size",
            "8",
            "--out",
            &arg(&d.join("nope/x.tif")),
        ]),
        "nope",
    );
    let leftovers: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(".penumbra-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

/// GDAL's COG validator (`validate_cloud_optimized_geotiff.py`, python3-gdal), run by the system
/// Python; `None` (with a printed reason) when it is not installed.
fn cog_validator() -> Option<PathBuf> {
    let script = Command::new("/usr/bin/python3")
        .args([
            "-c",
            "import osgeo_utils.samples.validate_cloud_optimized_geotiff as v; print(v.__file__)",
        ])
        .output_within()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| PathBuf::from(String::from_utf8_lossy(&o.stdout).trim()));
    if script.is_none() {
        crate::util::missing(
            "gdal",
            "GDAL's validate_cloud_optimized_geotiff",
            "apt-get install python3-gdal",
        );
    }
    script
}

/// Every GeoTIFF penumbra writes (DEM, one-light maps, statistics maps) is a valid COG to GDAL's
/// own validator (full check: block leaders and trailers), tiled, Deflate with a predictor, with
/// overviews, a band description, a unit, nodata and the run's parameters as metadata.
#[test]
fn every_geotiff_output_is_a_cloud_optimized_geotiff_with_its_metadata() {
    if !has_tool("gdalinfo") {
        return;
    }
    let Some(validator) = cog_validator() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let k = crate::util::kernels_dir();
    let k = k.to_str().unwrap();
    let dem = d.join("dem.tif");
    let dem_s = dem.to_str().unwrap();
    assert!(
        run(&["-q", "dem", "synth", "--size", "300", "--out", dem_s])
            .status
            .success()
    );
    let one = |flag: &str, name: &str| {
        let o = run(&[
            "-q",
            "map",
            "--dem",
            dem_s,
            "--utc",
            "2025-01-20T06:00",
            "--kernels",
            k,
            flag,
            d.join(name).to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    one("--out-fraction", "fraction.tif");
    one("--out-mask", "mask.tif");
    let maps = d.join("maps");
    let o = run(&[
        "-q",
        "map",
        "--dem",
        dem_s,
        "--start",
        "2025-01-01",
        "--stop",
        "2025-01-03",
        "--step",
        "6h",
        "--engine",
        "horizons",
        "--azimuths",
        "90",
        "--kernels",
        k,
        "--out-dir",
        maps.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut tifs = vec![dem.clone(), d.join("fraction.tif"), d.join("mask.tif")];
    let stats = crate::util::files_with_extension(&maps, "tif");
    assert!(stats.len() >= 9, "{stats:?}");
    tifs.extend(stats);
    for tif in &tifs {
        let name = tif.file_name().unwrap().to_string_lossy().to_string();
        let v = Command::new("/usr/bin/python3")
            .arg(&validator)
            .arg("--full-check=yes")
            .arg(tif)
            .output_within()
            .unwrap();
        let said =
            String::from_utf8_lossy(&v.stdout).to_string() + &String::from_utf8_lossy(&v.stderr);
        assert!(
            v.status.success() && said.contains("is a valid cloud optimized GeoTIFF"),
            "{name}: {said}"
        );
        assert!(!said.to_lowercase().contains("warning"), "{name}: {said}");
        let j = gdal_json(tif);
        let band = &j["bands"][0];
        assert_eq!(j["metadata"]["IMAGE_STRUCTURE"]["LAYOUT"], "COG", "{name}");
        assert_eq!(
            j["metadata"]["IMAGE_STRUCTURE"]["COMPRESSION"], "DEFLATE",
            "{name}"
        );
        assert!(
            j["metadata"]["IMAGE_STRUCTURE"]["PREDICTOR"].is_string(),
            "{name}"
        );
        assert_eq!(band["block"], serde_json::json!([256, 256]), "{name}");
        assert_eq!(
            band["overviews"].as_array().map(Vec::len),
            Some(1),
            "{name}: 300 px -> 150"
        );
        assert!(
            !band["description"].as_str().unwrap_or("").is_empty(),
            "{name}: no description"
        );
        // (a DEM without holes declares none)
        assert!(
            name == "dem.tif" || band.get("noDataValue").is_some(),
            "{name}: no nodata"
        );
        let md = &j["metadata"][""];
        assert!(
            md["software"].as_str().unwrap().starts_with("penumbra"),
            "{name}"
        );
        let unit = band["unit"].as_str().unwrap_or("");
        match name.as_str() {
            "dem.tif" => assert_eq!(unit, "m"),
            "fraction.tif" | "mask.tif" => {
                assert_eq!(md["epoch_utc"], "2025-01-20T06:00:00Z", "{name}");
                for item in [
                    "engine",
                    "rays_from",
                    "observer_height_m",
                    "sun_az_deg_at_map_centre",
                    "sun_el_deg_at_map_centre",
                    "kernels",
                ] {
                    assert!(md[item].is_string(), "{name}: no {item}");
                }
            }
            n if n.ends_with("_pct.tif") => assert_eq!(unit, "%", "{name}"),
            n if n.ends_with("_h.tif") => assert_eq!(unit, "h", "{name}"),
            n if n.ends_with("_w_m2.tif") => assert_eq!(unit, "W m-2", "{name}"),
            _ => {}
        }
        if tif.starts_with(&maps) {
            assert!(
                md["span_utc"].as_str().unwrap().contains("9 epochs"),
                "{name}: {md}"
            );
        }
        // Every product names its layers with their sha256 (the DEM itself is the input).
        if name != "dem.tif" {
            let layers = md["dem_layers"].as_str().unwrap_or("");
            assert!(
                layers.starts_with("dem.tif (sha256:")
                    && layers.len() == "dem.tif (sha256:".len() + 13,
                "{name}: dem_layers '{layers}'"
            );
        }
    }
    // The values GDAL reads are ours, pixel for pixel (the DEM: floating-point predictor).
    let ours = terrain::read_geotiff(&dem).unwrap();
    for &(col, row) in &[
        (0, 0),
        (299, 0),
        (150, 150),
        (255, 256),
        (299, 299),
        (17, 280),
    ] {
        let g = gdal_value(&dem, col, row);
        assert_eq!(g as f32, ours.heights_m[row * 300 + col], "({col},{row})");
    }
}

/// A PDS3 label for a `cols` x `rows` south-polar stereographic DEM centred on the pole.
fn pds3_label(
    cols: usize,
    rows: usize,
    px_m: f64,
    pointer: &str,
    record_bytes: usize,
    sample: (&str, u32),
    scale_offset: (f64, f64),
) -> String {
    format!(
        "PDS_VERSION_ID = \"PDS3\"\r\n/* made by penumbra's tests */\r\nRECORD_TYPE = FIXED_LENGTH\r\n\
         RECORD_BYTES = {record_bytes}\r\n^IMAGE = {pointer}\r\nOBJECT = IMAGE\r\n  NAME = HEIGHT\r\n\
         LINES = {rows}\r\n  LINE_SAMPLES = {cols}\r\n  SAMPLE_TYPE = {}\r\n  SAMPLE_BITS = {}\r\n\
         UNIT = METER\r\n  SCALING_FACTOR = {}\r\n  OFFSET = {}\r\n  MISSING_CONSTANT = -32768\r\n\
         END_OBJECT = IMAGE\r\nOBJECT = IMAGE_MAP_PROJECTION\r\n  MAP_PROJECTION_TYPE = \"POLAR STEREOGRAPHIC\"\r\n\
         A_AXIS_RADIUS = 1737.4 <KM>\r\n  B_AXIS_RADIUS = 1737.4 <KM>\r\n  C_AXIS_RADIUS = 1737.4 <KM>\r\n\
         CENTER_LATITUDE = -90 <DEG>\r\n  CENTER_LONGITUDE = 0 <DEG>\r\n  MAP_PROJECTION_ROTATION = 0.0\r\n\
         MAP_SCALE = {px_m} <METERS/PIXEL>\r\n  LINE_PROJECTION_OFFSET = {} <PIXEL>\r\n\
         SAMPLE_PROJECTION_OFFSET = {} <PIXEL>\r\nEND_OBJECT = IMAGE_MAP_PROJECTION\r\nEND\r\n",
        sample.0,
        sample.1,
        scale_offset.0,
        scale_offset.1,
        rows as f64 / 2.0 - 0.5,
        cols as f64 / 2.0 - 0.5,
    )
}

/// PDS3 DEMs as LOLA ships them (16-bit integers × 0.5 + OFFSET 1737400 = radii, detached
/// label) and with an attached label (float32 heights) are read natively: the same grid as
/// GDAL's PDS driver, heights = GDAL's raw × scale + offset − 1737400 m, within half a metre of
/// the DEM they were made from. GDAL's own conversion of the label to GeoTIFF gives radii, which
/// penumbra refuses with the fix.
#[test]
fn pds3_dems_read_natively_as_gdal_reads_them() {
    if !has_tool("gdalinfo") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let dem = synth::south_polar_dem(&synth::SynthParams {
        size_px: 40,
        px_m: 100.0,
        seed: 3,
    })
    .unwrap();
    let (rows, cols) = (dem.grid.rows, dem.grid.cols);
    // LOLA style: LSB int16, 0.5 m, OFFSET = radius, detached label; one hole.
    let mut raw = Vec::new();
    for (i, h) in dem.heights_m.iter().enumerate() {
        let v: i16 = if i == 41 {
            -32768
        } else {
            (f64::from(*h) / 0.5).round() as i16
        };
        raw.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(d.join("ldem.img"), &raw).unwrap();
    std::fs::write(
        d.join("ldem.lbl"),
        pds3_label(
            cols,
            rows,
            100.0,
            "\"ldem.img\"",
            cols * 2,
            ("LSB_INTEGER", 16),
            (0.5, 1737400.0),
        ),
    )
    .unwrap();
    // Attached label: float32 heights after a label padded to whole records.
    let rb = cols * 4;
    let probe = pds3_label(cols, rows, 100.0, "99", rb, ("PC_REAL", 32), (1.0, 0.0));
    let label_records = probe.len().div_ceil(rb);
    let pointer = format!("{:>2}", label_records + 1);
    let mut label = pds3_label(cols, rows, 100.0, &pointer, rb, ("PC_REAL", 32), (1.0, 0.0));
    assert_eq!(label.len(), probe.len());
    label.push_str(&" ".repeat(label_records * rb - label.len()));
    let mut attached = label.into_bytes();
    for h in &dem.heights_m {
        attached.extend_from_slice(&h.to_le_bytes());
    }
    std::fs::write(d.join("attached.img"), &attached).unwrap();

    for (file, tol_m) in [
        ("ldem.lbl", 0.25),
        ("ldem.img", 0.25),
        ("attached.img", 0.0),
    ] {
        let path = d.join(file);
        let ours = terrain::load_dem(&path).unwrap();
        assert_eq!(ours.projection, Projection::LOLA_SOUTH_POLAR, "{file}");
        let gdal_path = if file == "ldem.img" {
            d.join("ldem.lbl")
        } else {
            path.clone()
        };
        let j = gdal_json(&gdal_path);
        let gt: Vec<f64> = j["geoTransform"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert_eq!(
            (
                ours.grid.x_left_m,
                ours.grid.px_x_m,
                ours.grid.y_top_m,
                -ours.grid.px_y_m
            ),
            (gt[0], gt[1], gt[3], gt[5]),
            "{file}: grid vs GDAL's geotransform"
        );
        assert_eq!(ours.grid, dem.grid, "{file}: the grid the DEM was made on");
        let scale = j["bands"][0]["scale"].as_f64().unwrap_or(1.0);
        let offset = j["bands"][0]["offset"].as_f64().unwrap_or(0.0);
        for &(col, row) in &[(0, 0), (1, 1), (39, 0), (17, 23), (39, 39)] {
            let h = ours.heights_m[row * cols + col];
            if (row, col) == (1, 1) && file != "attached.img" {
                assert!(h.is_nan(), "{file}: MISSING_CONSTANT is a hole");
                continue;
            }
            let want = gdal_value(&gdal_path, col, row) * scale + offset
                - if offset > 1e6 { 1_737_400.0 } else { 0.0 };
            assert!(
                (f64::from(h) - want).abs() < 1e-3,
                "{file} ({col},{row}): {h} vs GDAL {want}"
            );
            let made = f64::from(dem.heights_m[row * cols + col]);
            assert!(
                (f64::from(h) - made).abs() <= tol_m,
                "{file} ({col},{row}): {h} vs {made}"
            );
        }
    }
    // GDAL's conversion of the LOLA-style label keeps OFFSET: radii, refused with the fix.
    if has_tool("gdal_translate") {
        let tif = d.join("radii.tif");
        let o = Command::new("gdal_translate")
            .args(["-q", "-unscale", "-ot", "Float32"])
            .arg(d.join("ldem.lbl"))
            .arg(&tif)
            .output_within()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_clean_failure(&run(&["dem", "info", tif.to_str().unwrap()]), "radii");
    }
}

/// A PDS4 label (2-D image, polar stereographic on the 1737.4 km sphere, pole-centred grid)
/// written by hand from the PDS4 Cartography dictionary, for an image file `file`.
fn pds4_label(file: &str, cols: usize, rows: usize, px_m: f64, element: &str) -> String {
    let (x0, y0) = (-(cols as f64) * px_m / 2.0, rows as f64 * px_m / 2.0);
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<Product_Observational xmlns="http://pds.nasa.gov/pds4/pds/v1" xmlns:cart="http://pds.nasa.gov/pds4/cart/v1">
  <Observation_Area><Discipline_Area><cart:Cartography>
    <cart:Spatial_Reference_Information><cart:Horizontal_Coordinate_System_Definition><cart:Planar>
      <cart:Map_Projection>
        <cart:map_projection_name>Polar Stereographic</cart:map_projection_name>
        <cart:Polar_Stereographic>
          <cart:longitude_of_central_meridian unit="deg">0</cart:longitude_of_central_meridian>
          <cart:latitude_of_projection_origin unit="deg">-90</cart:latitude_of_projection_origin>
          <cart:scale_factor_at_projection_origin>1</cart:scale_factor_at_projection_origin>
        </cart:Polar_Stereographic>
      </cart:Map_Projection>
      <cart:Planar_Coordinate_Information><cart:Coordinate_Representation>
        <cart:pixel_resolution_x unit="m/pixel">{px_m}</cart:pixel_resolution_x>
        <cart:pixel_resolution_y unit="m/pixel">{px_m}</cart:pixel_resolution_y>
      </cart:Coordinate_Representation></cart:Planar_Coordinate_Information>
      <cart:Geo_Transformation>
        <cart:upperleft_corner_x unit="m">{x0}</cart:upperleft_corner_x>
        <cart:upperleft_corner_y unit="m">{y0}</cart:upperleft_corner_y>
      </cart:Geo_Transformation>
    </cart:Planar>
    <cart:Geodetic_Model>
      <cart:a_axis_radius unit="m">1737400</cart:a_axis_radius>
      <cart:b_axis_radius unit="m">1737400</cart:b_axis_radius>
      <cart:c_axis_radius unit="m">1737400</cart:c_axis_radius>
    </cart:Geodetic_Model>
    </cart:Horizontal_Coordinate_System_Definition></cart:Spatial_Reference_Information>
  </cart:Cartography></Discipline_Area></Observation_Area>
  <File_Area_Observational>
    <File><file_name>{file}</file_name></File>
    <Array_2D_Image>
      <offset unit="byte">0</offset>
      <axes>2</axes>
      <axis_index_order>Last Index Fastest</axis_index_order>
      <Element_Array>{element}</Element_Array>
      <Axis_Array><axis_name>Line</axis_name><elements>{rows}</elements><sequence_number>1</sequence_number></Axis_Array>
      <Axis_Array><axis_name>Sample</axis_name><elements>{cols}</elements><sequence_number>2</sequence_number></Axis_Array>
      <Special_Constants><missing_constant>-32768</missing_constant></Special_Constants>
    </Array_2D_Image>
  </File_Area_Observational>
</Product_Observational>
"#
    )
}

/// PDS3 and PDS4 DEMs made by hand, read without GDAL: heights known in closed form
/// (`h = 0.5 · (7 row − 3 col + 40)` m on a 24 × 20 grid of 50 m cells centred on the south
/// pole, one hole) stored as LOLA stores them (16-bit integers × 0.5 + OFFSET 1737400 m = radii,
/// least- and most-significant byte first), and as float32 heights (PDS3 attached label, MSB).
/// penumbra must give every height exactly (they are multiples of 0.5 m), the hole as NaN, and
/// the pole-centred grid the labels describe (x from −600 m, y from +500 m, 50 m cells).
#[test]
fn pds3_and_pds4_dems_read_without_gdal() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (cols, rows, px_m) = (24usize, 20usize, 50.0);
    let hole = 5 * cols + 7;
    let h = |i: usize| 0.5 * (7.0 * (i / cols) as f64 - 3.0 * (i % cols) as f64 + 40.0);
    let radius_code = |i: usize| -> i16 {
        if i == hole {
            -32768
        } else {
            (h(i) / 0.5).round() as i16
        }
    };
    let n = cols * rows;
    let lsb: Vec<u8> = (0..n).flat_map(|i| radius_code(i).to_le_bytes()).collect();
    let msb: Vec<u8> = (0..n).flat_map(|i| radius_code(i).to_be_bytes()).collect();
    // PDS3, detached label, LSB int16 radii (as LOLA's LDEM products).
    std::fs::write(d.join("lsb.img"), &lsb).unwrap();
    let lsb_label = pds3_label(
        cols,
        rows,
        px_m,
        "\"lsb.img\"",
        cols * 2,
        ("LSB_INTEGER", 16),
        (0.5, 1737400.0),
    );
    std::fs::write(d.join("lsb.lbl"), &lsb_label).unwrap();
    // PDS3, detached label, MSB int16 radii.
    std::fs::write(d.join("msb.img"), &msb).unwrap();
    std::fs::write(
        d.join("msb.lbl"),
        lsb_label
            .replace("lsb.img", "msb.img")
            .replace("LSB_INTEGER", "MSB_INTEGER"),
    )
    .unwrap();
    // PDS3, attached label, MSB float32 heights (IEEE_REAL), the hole as the missing constant.
    let rb = cols * 4;
    let probe = pds3_label(cols, rows, px_m, "99", rb, ("IEEE_REAL", 32), (1.0, 0.0));
    let label_records = probe.len().div_ceil(rb);
    let mut attached = pds3_label(
        cols,
        rows,
        px_m,
        &format!("{:>2}", label_records + 1),
        rb,
        ("IEEE_REAL", 32),
        (1.0, 0.0),
    )
    .into_bytes();
    attached.resize(label_records * rb, b' ');
    for i in 0..n {
        let v = if i == hole { -32768.0_f32 } else { h(i) as f32 };
        attached.extend_from_slice(&v.to_be_bytes());
    }
    std::fs::write(d.join("attached.img"), &attached).unwrap();
    // PDS4, MSB and LSB int16 radii.
    std::fs::write(d.join("p4msb.img"), &msb).unwrap();
    let element = "<data_type>SignedMSB2</data_type><scaling_factor>0.5</scaling_factor>\
                   <value_offset>1737400</value_offset>";
    std::fs::write(
        d.join("p4msb.xml"),
        pds4_label("p4msb.img", cols, rows, px_m, element),
    )
    .unwrap();
    std::fs::write(d.join("p4lsb.img"), &lsb).unwrap();
    std::fs::write(
        d.join("p4lsb.xml"),
        pds4_label(
            "p4lsb.img",
            cols,
            rows,
            px_m,
            &element.replace("SignedMSB2", "SignedLSB2"),
        ),
    )
    .unwrap();

    for file in [
        "lsb.lbl",
        "lsb.img",
        "msb.lbl",
        "attached.img",
        "p4msb.xml",
        "p4lsb.xml",
    ] {
        let dem = terrain::load_dem(&d.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(dem.projection, Projection::LOLA_SOUTH_POLAR, "{file}");
        let g = &dem.grid;
        assert_eq!(
            (g.cols, g.rows, g.x_left_m, g.y_top_m, g.px_x_m, g.px_y_m),
            (cols, rows, -600.0, 500.0, px_m, px_m),
            "{file}: grid"
        );
        for i in 0..n {
            let got = dem.heights_m[i];
            if i == hole {
                assert!(
                    got.is_nan(),
                    "{file}: the missing constant is a hole, got {got}"
                );
            } else {
                assert_eq!(f64::from(got), h(i), "{file}: sample {i}");
            }
        }
    }
}

/// Equirectangular DEMs are read (`dem info`) but refused up front by every product, with one
/// line that says why and how to reproject: before, `map` ran at 12 h steps and failed hourly
/// (`--engine auto` switched to the line sweep, which needs a polar stereographic map).
#[test]
fn equirectangular_dems_are_refused_up_front_by_every_product() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let r = 1_737_400.0_f64;
    let grid = GridGeometry {
        rows: 40,
        cols: 40,
        x_left_m: -2000.0,
        y_top_m: r * (-85.0_f64).to_radians(),
        px_x_m: 100.0,
        px_y_m: 100.0,
    };
    let eqc = Projection::Equirectangular {
        lon0_deg: 0.0,
        lat_ts_deg: 0.0,
        radius_m: r,
    };
    let dem = d.join("eqc.tif");
    let z: Vec<f32> = (0..1600).map(|i| (i % 40) as f32).collect();
    terrain::write_geotiff(
        &dem,
        &grid,
        &eqc,
        &z,
        None,
        &[],
        terrain::BandInfo::default(),
    )
    .unwrap();
    let dem_s = dem.to_str().unwrap();
    let info = run(&["dem", "info", dem_s]);
    assert!(
        info.status.success(),
        "{}",
        String::from_utf8_lossy(&info.stderr)
    );
    assert!(String::from_utf8_lossy(&info.stdout).contains("equirectangular"));
    let k = crate::util::kernels_dir();
    let k = k.to_str().unwrap();
    let out = |name: &str| d.join(name).display().to_string();
    let time = [
        "--start",
        "2025-01-01",
        "--stop",
        "2025-01-03",
        "--kernels",
        k,
    ];
    let (o1, o2, o3, o4) = (out("s"), out("m12"), out("m1"), out("h.csv"));
    let mut series = vec![
        "series",
        "--dem",
        dem_s,
        "--site",
        "a,-85.01,0.02,2",
        "--step",
        "6h",
        "--out-dir",
        &o1,
    ];
    series.extend(time);
    let mut map12 = vec!["map", "--dem", dem_s, "--step", "12h", "--out-dir", &o2];
    map12.extend(time);
    let mut map1 = vec!["map", "--dem", dem_s, "--step", "1h", "--out-dir", &o3];
    map1.extend(time);
    let horizon = vec![
        "horizon",
        "--dem",
        dem_s,
        "--lat-deg",
        "-85.01",
        "--lon-deg",
        "0.02",
        "--out",
        &o4,
    ];
    for args in [series, map12, map1, horizon] {
        let o = run(&args);
        assert_clean_failure(&o, "equirectangular");
        assert!(
            String::from_utf8_lossy(&o.stderr).contains("gdalwarp"),
            "{args:?}: the line says how to reproject"
        );
        assert!(!d.join("s").exists() && !d.join("m12").exists() && !d.join("m1").exists());
        assert!(!d.join("h.csv").exists());
    }
    // A scenario naming the DEM: the same line.
    std::fs::write(
        d.join("eqc.toml"),
        format!(
            "name = \"e\"\noutput_dir = \"sc\"\nkernels = \"{k}\"\n[time]\nstart = \"2025-01-01\"\n\
             stop = \"2025-01-02\"\nstep = \"6h\"\n[[sites]]\nname = \"a\"\nlat_deg = -85.01\n\
             lon_deg = 0.02\n[terrain]\nlayers = [\"eqc.tif\"]\n[series]\n"
        ),
    )
    .unwrap();
    let o = run(&["run", d.join("eqc.toml").to_str().unwrap()]);
    assert_clean_failure(&o, "equirectangular");
}

/// GeoTIFF keys can only name EPSG codes, so penumbra writes the IAU Moon (2015) sphere CRSs
/// (`IAU_2015:30135` south polar stereographic here) as GDAL itself writes them for
/// `gdal_translate -a_srs IAU_2015:30135`: GDAL reads the same CRS (WKT equal, character for
/// character) from penumbra's DEM as from GDAL's own re-tagged copy of it.
#[test]
fn the_crs_is_iau_2015_30135_as_gdal_writes_it() {
    if !has_tool("gdal_translate") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let ours = dir.path().join("ours.tif");
    let theirs = dir.path().join("gdal.tif");
    crate::util::penumbra_ok(
        dir.path(),
        &[
            "dem",
            "synth",
            "--size",
            "64",
            "--out",
            ours.to_str().unwrap(),
        ],
    );
    let st = std::process::Command::new("gdal_translate")
        .args(["-q", "-a_srs", "IAU_2015:30135"])
        .arg(&ours)
        .arg(&theirs)
        .status()
        .unwrap();
    assert!(st.success());
    let wkt = |p: &Path| {
        let out = std::process::Command::new("gdalinfo")
            .arg("-json")
            .arg(p)
            .output()
            .unwrap();
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["coordinateSystem"]["wkt"].as_str().unwrap().to_string()
    };
    let (a, b) = (wkt(&ours), wkt(&theirs));
    assert!(
        a.contains("Moon (2015) - Sphere / Ocentric / South Polar"),
        "{a}"
    );
    assert_eq!(a, b);
    assert_eq!(
        penumbra::terrain::geotiff::iau_2015_crs(&penumbra::terrain::Projection::LOLA_SOUTH_POLAR)
            .map(|c| c.0),
        Some(30135)
    );
}

/// PDS4 DEMs (XML label + image) as GDAL's PDS4 driver writes them from penumbra's synthetic DEM:
/// float32 heights (a 3-D image of one band), and LOLA-style int16 × 0.5 + `value_offset`
/// 1737400 m (radii) with a missing constant. penumbra reads the grid GDAL reads (geotransform
/// from `gdalinfo -json`) and heights = GDAL's raw × scale + offset (− 1737400 m for radii) at 6
/// pixels.
#[test]
fn pds4_dems_read_natively_as_gdal_reads_them() {
    if !has_tool("gdal_translate") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let src = d.join("synth.tif");
    let o = run(&[
        "dem",
        "synth",
        "--size",
        "48",
        "--px-m",
        "100",
        "--out",
        src.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let translate = |args: &[&str], out: &str| {
        let o = Command::new("gdal_translate")
            .args(["-q", "-of", "PDS4"])
            .args(args)
            .arg(&src)
            .arg(d.join(out))
            .output_within()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        d.join(out)
    };
    let float = translate(&[], "f.xml");
    // Heights h -> raw 2h (int16), declared as radii: raw × 0.5 + 1737400.
    let radii = translate(
        &[
            "-ot",
            "Int16",
            "-scale",
            "-1000",
            "1000",
            "-2000",
            "2000",
            "-a_scale",
            "0.5",
            "-a_offset",
            "1737400",
            "-a_nodata",
            "-32768",
        ],
        "r.xml",
    );
    let label = std::fs::read_to_string(&radii).unwrap();
    assert!(
        label.contains("scaling_factor") && label.contains("value_offset"),
        "{label}"
    );
    for (xml, scale, offset) in [(&float, 1.0, 0.0), (&radii, 0.5, 1_737_400.0)] {
        let dem = penumbra::terrain::load_dem(xml).unwrap_or_else(|e| panic!("{e}"));
        let info = Command::new("gdalinfo")
            .arg("-json")
            .arg(xml)
            .output_within()
            .unwrap();
        let v: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
        let gt: Vec<f64> = v["geoTransform"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        let g = &dem.grid;
        assert_eq!((g.rows, g.cols), (48, 48));
        for (ours, theirs) in [
            (g.x_left_m, gt[0]),
            (g.px_x_m, gt[1]),
            (g.y_top_m, gt[3]),
            (-g.px_y_m, gt[5]),
        ] {
            assert!(
                (ours - theirs).abs() < 1e-6,
                "{}: {ours} vs GDAL {theirs}",
                xml.display()
            );
        }
        assert_eq!(
            dem.projection,
            penumbra::terrain::Projection::LOLA_SOUTH_POLAR
        );
        for &(col, row) in &[(0, 0), (47, 0), (20, 24), (31, 7), (0, 47), (47, 47)] {
            let want = gdal_value(xml, col, row) * scale + offset
                - if offset > 1e6 { 1_737_400.0 } else { 0.0 };
            let h = f64::from(dem.heights_m[row * 48 + col]);
            assert!(
                (h - want).abs() < 1e-3,
                "{} ({col},{row}): {h} vs GDAL {want}",
                xml.display()
            );
        }
    }
}
