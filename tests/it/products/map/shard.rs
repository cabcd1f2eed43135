//! Sharded maps: `penumbra map --shard I/N` then `penumbra merge` gives the bytes of one
//! `penumbra map` run (N = 1, 3, 4, 7; a synthetic DEM with a nodata hole and the real LOLA
//! 240 m crop with its far field), refuses what it must (other jobs, holes, repeats, damaged
//! or unfinished shards), and a killed shard re-run alone gives the same merged maps.

use crate::util::OutputWithin as _;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::util::{assert_clean_error, kernels_dir, penumbra, penumbra_ok, shared_lola};

/// Every file of a map folder (name → bytes) but run.json, and run.json's fields that describe
/// the result (not the command line, the wall time or the shards).
fn map_files(dir: &Path) -> (BTreeMap<String, Vec<u8>>, serde_json::Value) {
    let mut files = BTreeMap::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        if name != "run.json" {
            assert!(p.is_file(), "{} is not a file", p.display());
            files.insert(name, std::fs::read(&p).unwrap());
        }
    }
    let run: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("run.json")).unwrap()).unwrap();
    let keep = [
        "kernels",
        "dem_layers",
        "dem_files",
        "epoch_start_utc",
        "epoch_stop_utc",
        "epoch_count",
        "outputs",
        "map_rays_blocked_beyond_dem",
    ];
    let record = keep
        .iter()
        .map(|k| (k.to_string(), run[*k].clone()))
        .collect::<serde_json::Map<_, _>>();
    (files, serde_json::Value::Object(record))
}

/// Runs the single map and the sharded ones (merged from the shards given in a scrambled
/// order) for every N, and asserts the same bytes.
fn assert_shards_match(dir: &Path, map_args: &[&str], counts: &[usize]) {
    let single = dir.join("single");
    let mut args = map_args.to_vec();
    let single_s = single.to_str().unwrap();
    args.extend(["--out-dir", single_s]);
    penumbra_ok(dir, &args);
    let (want, want_run) = map_files(&single);
    assert!(want.len() >= 20, "{:?}", want.keys());
    for &n in counts {
        let mut parts: Vec<PathBuf> = Vec::new();
        for i in 0..n {
            let part = dir.join(format!("n{n}/part{i}"));
            let shard = format!("{i}/{n}");
            let mut args = map_args.to_vec();
            args.extend([
                "--shard",
                &shard,
                "--out-dir",
                part.to_str().unwrap(),
                "--quiet",
            ]);
            penumbra_ok(dir, &args);
            parts.push(part);
        }
        // Any order.
        parts.reverse();
        parts.rotate_left(n / 2);
        let merged = dir.join(format!("n{n}/merged"));
        let mut args = vec!["merge", "--out-dir", merged.to_str().unwrap()];
        args.extend(parts.iter().map(|p| p.to_str().unwrap()));
        penumbra_ok(dir, &args);
        let (got, got_run) = map_files(&merged);
        assert_eq!(
            got.keys().collect::<Vec<_>>(),
            want.keys().collect::<Vec<_>>()
        );
        for (name, bytes) in &want {
            assert!(got[name] == *bytes, "N = {n}: {name} differs");
        }
        assert_eq!(got_run, want_run, "N = {n}: run.json");
        let run: serde_json::Value =
            serde_json::from_slice(&std::fs::read(merged.join("run.json")).unwrap()).unwrap();
        assert_eq!(run["shards"].as_array().unwrap().len(), n);
    }
}

/// The synthetic DEM (120² at 150 m) with a 5 × 7 nodata hole, as a GeoTIFF in `dir`.
fn holed_dem(dir: &Path) -> PathBuf {
    let path = dir.join("dem.tif");
    penumbra_ok(
        dir,
        &[
            "dem",
            "synth",
            "--size",
            "120",
            "--px-m",
            "150",
            "--seed",
            "4",
            "--out",
            path.to_str().unwrap(),
        ],
    );
    let mut dem = penumbra::terrain::read_geotiff(&path).unwrap();
    for r in 40..45 {
        for c in 70..77 {
            dem.heights_m[r * 120 + c] = f32::NAN;
        }
    }
    penumbra::terrain::write_geotiff(
        &path,
        &dem.grid,
        &dem.projection,
        &dem.heights_m,
        Some(f32::NAN),
        &[],
        penumbra::terrain::BandInfo::default(),
    )
    .unwrap();
    path
}

#[test]
fn sharded_maps_merge_to_the_single_run_bytes_on_a_synthetic_dem() {
    let tmp = tempfile::tempdir().unwrap();
    let dem = holed_dem(tmp.path());
    let kernels = kernels_dir();
    let args = [
        "map",
        "--dem",
        dem.to_str().unwrap(),
        "--start",
        "2025-01-01",
        "--stop",
        "2025-01-20",
        "--step",
        "8h",
        "--engine",
        "horizons",
        "--azimuths",
        "90",
        "--kernels",
        kernels.to_str().unwrap(),
    ];
    assert_shards_match(tmp.path(), &args, &[1, 3, 4, 7]);
    // The hole is nodata in the merged maps as in the single run (checked above byte for
    // byte); and the statistics are not trivially empty.
    let lit = crate::util::read_tif(&tmp.path().join("n4/merged"), "sun_visible_pct.tif");
    assert!(lit.heights_m[42 * 120 + 72].is_nan());
    let some_lit = lit.heights_m.iter().filter(|v| **v > 0.0).count();
    assert!(some_lit > 1000, "{some_lit} lit pixels");
}

#[test]
fn sharded_maps_merge_to_the_single_run_bytes_on_the_lola_crop() {
    let (Some(crop), Some(far)) = (
        shared_lola("ldem75s_crop_240m_pm184km.tif"),
        shared_lola("ldem75s_far_1787m_pm457km_feathered.tif"),
    ) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let kernels = kernels_dir();
    let args = [
        "map",
        "--dem",
        crop.to_str().unwrap(),
        "--dem",
        far.to_str().unwrap(),
        "--start",
        "2025-03-01",
        "--stop",
        "2025-03-03",
        "--step",
        "6h",
        "--engine",
        "horizons",
        "--azimuths",
        "16",
        "--max-step",
        "2",
        "--kernels",
        kernels.to_str().unwrap(),
    ];
    assert_shards_match(tmp.path(), &args, &[1, 3, 4, 7]);
}

fn synthetic_args<'a>(stop: &'a str, kernels: &'a str) -> Vec<&'a str> {
    vec![
        "map",
        "--synthetic",
        "--start",
        "2025-01-01",
        "--stop",
        stop,
        "--step",
        "12h",
        "--azimuths",
        "24",
        "--max-step",
        "2",
        "--kernels",
        kernels,
        "--quiet",
    ]
}

fn run_shard(cwd: &Path, stop: &str, shard: &str, out: &Path) -> std::process::Output {
    let k = kernels_dir();
    let mut args = synthetic_args(stop, k.to_str().unwrap());
    args.extend(["--shard", shard, "--out-dir", out.to_str().unwrap()]);
    penumbra(cwd, &args)
}

#[test]
fn merge_refuses_other_jobs_holes_repeats_damage_and_unfinished_shards() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let p = |s: &str| d.join(s);
    for i in 0..3 {
        let out = run_shard(d, "2025-01-03", &format!("{i}/3"), &p(&format!("a{i}")));
        assert!(out.status.success(), "{out:?}");
    }
    // Another job: other epochs.
    assert!(run_shard(d, "2025-01-04", "1/3", &p("b1")).status.success());
    let merge = |dirs: &[&str]| {
        let out = p("merged");
        let mut args = vec!["merge", "--out-dir", out.to_str().unwrap()];
        let dirs: Vec<String> = dirs.iter().map(|s| p(s).display().to_string()).collect();
        args.extend(dirs.iter().map(String::as_str));
        penumbra(d, &args)
    };
    assert_clean_error(
        &merge(&["a0", "b1", "a2"]),
        "different jobs (epochs differ)",
    );
    assert_clean_error(&merge(&["a0", "a2"]), "missing shard(s) 1 of 3");
    assert_clean_error(&merge(&["a0", "a1", "a1", "a2"]), "given twice");
    assert_clean_error(&merge(&["a0", "a1", "nowhere"]), "no such folder");
    assert!(!p("merged").exists(), "a refused merge leaves no folder");
    // A damaged copy.
    let data = p("a1/shard.pnbstat");
    let mut bytes = std::fs::read(&data).unwrap();
    let keep = bytes.clone();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x10;
    std::fs::write(&data, &bytes).unwrap();
    assert_clean_error(&merge(&["a0", "a1", "a2"]), "does not match the sha256");
    std::fs::write(&data, &bytes[..mid]).unwrap();
    assert_clean_error(&merge(&["a0", "a1", "a2"]), "re-run that shard");
    std::fs::write(&data, &keep).unwrap();
    // An unfinished shard (no manifest) and a folder that is no shard.
    std::fs::rename(p("a1/shard.json"), p("a1/shard.json.bak")).unwrap();
    assert_clean_error(&merge(&["a0", "a1", "a2"]), "no shard.json");
    std::fs::rename(p("a1/shard.json.bak"), p("a1/shard.json")).unwrap();
    assert!(merge(&["a2", "a0", "a1"]).status.success());
    // Bad shard arguments.
    let k = kernels_dir();
    for (shard, needle) in [
        ("3/3", "expected I/N"),
        ("1/0", "expected I/N"),
        ("x", "expected I/N"),
    ] {
        assert_clean_error(&run_shard(d, "2025-01-03", shard, &p("bad")), needle);
    }
    let mut args = synthetic_args("2025-01-03", k.to_str().unwrap());
    args.extend(["--engine", "combined", "--shard", "0/2", "--out-dir"]);
    let bad = p("bad");
    args.push(bad.to_str().unwrap());
    assert_clean_error(&penumbra(d, &args), "horizons engine");
    assert_clean_error(
        &run_shard(d, "2025-01-03", "0/401", &p("bad")),
        "at most one shard per row",
    );
}

#[test]
fn a_killed_shard_rerun_alone_gives_the_same_merged_maps() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let p = |s: &str| d.join(s);
    for i in 0..3 {
        assert!(
            run_shard(d, "2025-01-05", &format!("{i}/3"), &p(&format!("a{i}")))
                .status
                .success()
        );
    }
    let merge = |dirs: &[&str], out: &str| {
        let out = p(out);
        let mut args = vec!["merge", "--out-dir", out.to_str().unwrap()];
        let dirs: Vec<String> = dirs.iter().map(|s| p(s).display().to_string()).collect();
        args.extend(dirs.iter().map(String::as_str));
        penumbra(d, &args)
    };
    assert!(merge(&["a0", "a1", "a2"], "want").status.success());
    // Shard 1 killed after two blocks of rows: no manifest, merge refuses it and says how to
    // go on.
    let k = kernels_dir();
    let mut args = synthetic_args("2025-01-05", k.to_str().unwrap());
    let out = p("a1");
    args.extend(["--shard", "1/3", "--out-dir", out.to_str().unwrap()]);
    let killed = crate::util::penumbra_command()
        .args(&args)
        .env("PENUMBRA_TEST_EXIT_AFTER_CHECKPOINTS", "2")
        .output_within()
        .unwrap();
    assert_eq!(killed.status.code(), Some(137), "{killed:?}");
    assert!(!p("a1/shard.json").exists());
    assert_clean_error(&merge(&["a0", "a1", "a2"], "got"), "with --resume");
    // Re-run only that shard, resuming its finished blocks.
    args.push("--resume");
    penumbra_ok(d, &args);
    assert!(merge(&["a0", "a1", "a2"], "got").status.success());
    let (want, _) = map_files(&p("want"));
    let (got, _) = map_files(&p("got"));
    assert_eq!(want, got);
}

#[test]
fn a_map_too_big_for_memory_is_refused_and_fits_in_shards() {
    // Synthetic 400² with 24 azimuths (24 directions): whole-grid arrays ≈ 0.6 MB terrain +
    // 160,000 px × (2 · 24 + 85) B ≈ 21.9 MB; a shard of 8 ≈ 3.3 MB.
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let k = kernels_dir();
    let budget = |args: &[&str]| {
        crate::util::penumbra_command()
            .args(args)
            .current_dir(d)
            .env("PENUMBRA_MEMORY_BUDGET_GB", "0.01")
            .output_within()
            .unwrap()
    };
    let mut whole = synthetic_args("2025-01-02", k.to_str().unwrap());
    whole.extend(["--engine", "horizons", "--out-dir", "whole"]);
    assert_clean_error(&budget(&whole), "split the map into shards");
    let mut shard = synthetic_args("2025-01-02", k.to_str().unwrap());
    shard.extend(["--shard", "0/2", "--out-dir", "s0"]);
    assert_clean_error(&budget(&shard), "split the map into more shards");
    let mut shard = synthetic_args("2025-01-02", k.to_str().unwrap());
    shard.extend(["--shard", "7/8", "--out-dir", "s7"]);
    let out = budget(&shard);
    assert!(out.status.success(), "{out:?}");
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("s7/shard.json")).unwrap()).unwrap();
    let arrays = m["arrays_bytes"].as_u64().unwrap();
    assert!(arrays < 10 << 20, "{arrays}");
    // The statement is of the right size: the measured peak is above the arrays and within the
    // process's own overhead (binary, kernels, thread stacks) of them.
    if let Some(peak) = m["peak_rss_bytes"].as_u64() {
        assert!(
            peak > arrays && peak < arrays + (200 << 20),
            "{peak} vs {arrays}"
        );
    }
}
