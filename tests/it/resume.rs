//! Kill a run part-way, resume it: the outputs are the bytes of an uninterrupted run.
//!
//! A scenario with every stage (series of two sites, an hourly-style map by the horizons engine
//! in 16 blocks of rows, a 4-frame render sequence) is killed at chosen checkpoints (the test
//! hook `PENUMBRA_TEST_EXIT_AFTER_CHECKPOINTS` exits as a kill would: no clean-up) and by real
//! SIGKILLs at moments through the run, then resumed with `--resume`. Every output file must
//! equal the uninterrupted run's byte for byte; `run.json` too, but for the command line and
//! the wall time.

use crate::util::OutputWithin as _;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Output;

use crate::util::{assert_clean_error, kernels_dir, penumbra_ok};

/// The scenario: 96² synthetic DEM at 200 m, January 2025 every 12 h (63 epochs).
fn scenario(step: &str) -> String {
    format!(
        r#"name = "resume"
output_dir = "res"
kernels = "{}"
[time]
start = "2025-01-01"
stop = "2025-02-01"
step = "{step}"
[terrain]
synthetic = {{ size_px = 96, px_m = 200.0, seed = 3 }}
[series]
plots = true
[map]
step = "{step}"
engine = "horizons"
azimuths = 180
[[sites]]
name = "a"
lat_deg = -89.8
lon_deg = 0.0
[[sites]]
name = "b"
lat_deg = -89.85
lon_deg = 90.0
[[render.views]]
out = "seq.png"
camera = "orbit"
lat_deg = -89.5
lon_deg = 0.0
altitude_km = 30.0
target_lat_deg = -89.9
target_lon_deg = 0.0
fov_deg = 40.0
start = "2025-01-20T00:00:00"
stop = "2025-01-20T18:00:00"
step = "6h"
width = 64
height = 40
"#,
        kernels_dir().display()
    )
}

fn run(dir: &Path, out: &str, resume: bool, exit_after: Option<u32>) -> Output {
    let mut cmd = crate::util::penumbra_command();
    cmd.current_dir(dir)
        .args(["run", "s.toml", "--out-dir", out]);
    if resume {
        cmd.arg("--resume");
    }
    if let Some(n) = exit_after {
        cmd.env("PENUMBRA_TEST_EXIT_AFTER_CHECKPOINTS", n.to_string());
    }
    cmd.output_within().expect("the penumbra binary runs")
}

/// Every file under `dir` (relative path → bytes); run.json without its command line and wall
/// time.
fn contents(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                let rel = p.strip_prefix(root).unwrap().display().to_string();
                let mut bytes = std::fs::read(&p).unwrap();
                if rel == "run.json" {
                    let mut v: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
                    let o = v.as_object_mut().unwrap();
                    o.remove("wall_time_s");
                    o.remove("command_line");
                    bytes = serde_json::to_vec(&v).unwrap();
                }
                out.insert(rel, bytes);
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

fn assert_same(full: &BTreeMap<String, Vec<u8>>, dir: &Path, what: &str) {
    let got = contents(dir);
    let names = |m: &BTreeMap<String, Vec<u8>>| m.keys().cloned().collect::<Vec<_>>();
    assert_eq!(names(&got), names(full), "{what}: other files");
    for (name, bytes) in full {
        assert!(got[name] == *bytes, "{what}: {name} differs");
    }
}

/// Kills at checkpoints through every stage (series done, map blocks 1, 8 and 16, the map
/// done, render frames 1 and 3, the render done), then `--resume`: the same bytes each time.
#[test]
fn a_run_killed_at_any_checkpoint_resumes_to_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("s.toml"), scenario("12h")).unwrap();
    let o = run(dir.path(), "full", false, None);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let full = contents(&dir.path().join("full"));
    assert!(full.contains_key("map/sun_illumination_pct.tif"));
    assert!(full.contains_key("render/seq_0003.png"));
    assert!(full.contains_key("a/series.csv"));
    // Checkpoints: 1 series, 2..=17 map blocks, 18 map, 19..=22 frames, 23 render.
    for n in [1, 2, 9, 17, 18, 19, 21, 22] {
        let out = format!("k{n}");
        let o = run(dir.path(), &out, false, Some(n));
        assert_eq!(
            o.status.code(),
            Some(137),
            "checkpoint {n}: the run was not killed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let res = dir.path().join(&out);
        assert!(!res.join("run.json").exists(), "checkpoint {n}: run.json");
        let o = run(dir.path(), &out, true, None);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains(&format!("{n} finished part(s) kept")),
            "checkpoint {n}: {err}"
        );
        assert_same(&full, &res, &format!("killed after checkpoint {n}"));
    }
}

/// A resumed run killed again, then resumed again; and a last resume of a complete folder.
#[test]
fn a_resumed_run_can_be_killed_and_resumed_again() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("s.toml"), scenario("12h")).unwrap();
    penumbra_ok(dir.path(), &["run", "s.toml", "--out-dir", "full"]);
    let full = contents(&dir.path().join("full"));
    assert_eq!(
        run(dir.path(), "r", false, Some(3)).status.code(),
        Some(137)
    );
    assert_eq!(run(dir.path(), "r", true, Some(6)).status.code(), Some(137));
    assert_eq!(
        run(dir.path(), "r", true, Some(12)).status.code(),
        Some(137)
    );
    let o = run(dir.path(), "r", true, None);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("21 finished part(s) kept"));
    assert_same(&full, &dir.path().join("r"), "killed three times");
    // Nothing to resume in a complete folder: it is run again, to the same bytes.
    let o = run(dir.path(), "r", true, None);
    assert!(String::from_utf8_lossy(&o.stderr).contains("nothing to resume"));
    assert_same(&full, &dir.path().join("r"), "resumed when complete");
}

/// Real SIGKILLs at moments spread through the run (wherever they land: inside a write, a
/// block, a frame), then `--resume`.
#[cfg(unix)]
#[test]
fn sigkill_at_moments_through_the_run_then_resume() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("s.toml"), scenario("12h")).unwrap();
    let t0 = std::time::Instant::now();
    penumbra_ok(dir.path(), &["run", "s.toml", "--out-dir", "full"]);
    let whole = t0.elapsed();
    let full = contents(&dir.path().join("full"));
    for (i, fraction) in [0.15, 0.35, 0.55, 0.75, 0.9].into_iter().enumerate() {
        let out = format!("s{i}");
        let mut child = crate::util::penumbra_command()
            .current_dir(dir.path())
            .args(["run", "s.toml", "--out-dir", &out])
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(whole.mul_f64(fraction));
        child.kill().unwrap(); // SIGKILL
        child.wait().unwrap();
        let o = run(dir.path(), &out, true, None);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_same(
            &full,
            &dir.path().join(&out),
            &format!("SIGKILL at {fraction}"),
        );
    }
}

/// `--resume` refuses a folder whose unfinished run had other parameters (one line, exit 2);
/// a run without `--resume` discards those checkpoints and starts over.
#[test]
fn resume_refuses_a_run_with_other_parameters() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("s.toml"), scenario("12h")).unwrap();
    assert_eq!(
        run(dir.path(), "r", false, Some(4)).status.code(),
        Some(137)
    );
    std::fs::write(dir.path().join("s.toml"), scenario("24h")).unwrap();
    let o = run(dir.path(), "r", true, None);
    assert_clean_error(&o, "other inputs or parameters");
    let o = run(dir.path(), "r", false, None);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("discarding the checkpoints"));
    let left = crate::util::files_in(&dir.path().join("r"));
    assert!(
        !left.iter().any(|f| f.starts_with(".penumbra")),
        "checkpoints, lock or temp files left: {left:?}"
    );
    // The 24 h run is a 24 h run: 32 epochs.
    let run_json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("r").join("run.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(run_json["epoch_count"], 32);
}

/// `map --resume` over an epoch range: killed in the middle of the horizons engine's blocks.
#[test]
fn a_killed_map_range_resumes_to_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    penumbra_ok(
        dir.path(),
        &[
            "dem", "synth", "--size", "80", "--px-m", "200", "--out", "d.tif",
        ],
    );
    let args = |out: &'static str| {
        vec![
            "map".to_string(),
            "--dem".into(),
            "d.tif".into(),
            "--engine".into(),
            "horizons".into(),
            "--azimuths".into(),
            "120".into(),
            "--start".into(),
            "2025-01-01".into(),
            "--stop".into(),
            "2025-01-10".into(),
            "--step".into(),
            "6h".into(),
            "--kernels".into(),
            k.display().to_string(),
            "--out-dir".into(),
            out.into(),
        ]
    };
    let go = |out: &'static str, extra: &[&str], exit_after: Option<u32>| {
        let mut cmd = crate::util::penumbra_command();
        cmd.current_dir(dir.path()).args(args(out)).args(extra);
        if let Some(n) = exit_after {
            cmd.env("PENUMBRA_TEST_EXIT_AFTER_CHECKPOINTS", n.to_string());
        }
        cmd.output_within().unwrap()
    };
    assert!(go("full", &[], None).status.success());
    let full = contents(&dir.path().join("full"));
    assert_eq!(go("r", &[], Some(7)).status.code(), Some(137));
    let o = go("r", &["--resume"], None);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("7 finished part(s) kept"));
    assert_same(&full, &dir.path().join("r"), "map killed after block 7");
    // Other arguments: refused.
    assert_eq!(go("q", &[], Some(2)).status.code(), Some(137));
    let o = go("q", &["--resume", "--observer-height-m", "5"], None);
    assert_clean_error(&o, "other inputs or parameters");
}
