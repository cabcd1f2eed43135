//! Command-line habits: completions, man pages, `-q`/`-v`, ISO 8601 times with `Z` in every
//! output, the epoch forms SPICE users type.

use crate::util::{assert_clean_error, kernels_dir, penumbra, penumbra_ok};

fn stdout(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn completions_and_man_pages_cover_every_command() {
    let dir = tempfile::tempdir().unwrap();
    for shell in ["bash", "zsh", "fish", "elvish", "powershell"] {
        let o = penumbra_ok(dir.path(), &["completions", shell]);
        let text = stdout(&o);
        for word in ["horizon-map", "resume", "kernels", "quiet"] {
            assert!(text.contains(word), "{shell}: {word} missing");
        }
    }
    assert_clean_error(
        &penumbra(dir.path(), &["completions", "tcsh"]),
        "invalid value",
    );
    let o = penumbra_ok(dir.path(), &["man"]);
    let page = stdout(&o);
    assert!(
        page.contains(".TH penumbra 1"),
        "{}",
        &page[..200.min(page.len())]
    );
    assert!(page.contains("horizon\\-map"));
    penumbra_ok(dir.path(), &["man", "--out-dir", "man"]);
    let pages = crate::util::files_in(&dir.path().join("man"));
    for cmd in [
        "penumbra.1",
        "penumbra-map.1",
        "penumbra-run.1",
        "penumbra-series.1",
        "penumbra-render.1",
    ] {
        assert!(pages.contains(&cmd.to_string()), "{cmd} missing: {pages:?}");
    }
    let map_page = std::fs::read_to_string(dir.path().join("man/penumbra-map.1")).unwrap();
    assert!(map_page.contains("\\-\\-resume"), "map page lacks --resume");
}

#[test]
fn quiet_silences_progress_and_summaries_and_verbose_adds_details() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let series = |flag: Option<&str>, out: &str| {
        let mut args: Vec<&str> = flag.into_iter().collect();
        args.extend([
            "series",
            "--synthetic",
            "--site",
            "a,-89.9,0,2",
            "--start",
            "2025-01-01",
            "--stop",
            "2025-01-02",
            "--step",
            "6h",
            "--no-plots",
            "--kernels",
            k.to_str().unwrap(),
            "--out-dir",
            out,
        ]);
        penumbra_ok(dir.path(), &args)
    };
    let normal = stderr(&series(None, "n"));
    assert!(
        normal.contains("penumbra: 1 site(s) x 5 epochs"),
        "{normal}"
    );
    let quiet = stderr(&series(Some("-q"), "q"));
    assert!(quiet.is_empty(), "--quiet said: {quiet}");
    let verbose = stderr(&series(Some("--verbose"), "v"));
    assert!(verbose.contains("penumbra: kernels from"), "{verbose}");
    assert!(verbose.contains("sha256"), "{verbose}");
    // The same files whatever the verbosity.
    for f in ["a/series.csv", "stats.json"] {
        assert_eq!(
            std::fs::read(dir.path().join("n").join(f)).unwrap(),
            std::fs::read(dir.path().join("q").join(f)).unwrap(),
            "{f}"
        );
    }
    assert_clean_error(
        &penumbra(dir.path(), &["-q", "-v", "kernels"]),
        "cannot be used with",
    );
}

#[test]
fn every_output_writes_utc_with_z() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let o = penumbra_ok(
        dir.path(),
        &[
            "ephem",
            "--lat-deg",
            "-89.9",
            "--lon-deg",
            "0",
            "--start",
            "2025-01-01",
            "--stop",
            "2025-01-01T02:00",
            "--step",
            "1h",
            "--kernels",
            k.to_str().unwrap(),
        ],
    );
    let csv = stdout(&o);
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 3);
    assert!(rows[2].starts_with("2025-01-01T02:00:00Z,"), "{}", rows[2]);
    penumbra_ok(
        dir.path(),
        &[
            "series",
            "--synthetic",
            "--site",
            "a,-89.9,0,2",
            "--start",
            "2025-01-01",
            "--stop",
            "2025-01-01T12:00",
            "--step",
            "6h",
            "--no-plots",
            "--kernels",
            k.to_str().unwrap(),
            "--out-dir",
            "s",
        ],
    );
    let series = std::fs::read_to_string(dir.path().join("s/a/series.csv")).unwrap();
    assert!(
        series
            .lines()
            .nth(1)
            .unwrap()
            .starts_with("2025-01-01T00:00:00Z,")
    );
    let run: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("s/run.json")).unwrap())
            .unwrap();
    assert_eq!(run["epoch_start_utc"], "2025-01-01T00:00:00Z");
    assert_eq!(run["epoch_stop_utc"], "2025-01-01T12:00:00Z");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("s/stats.json")).unwrap())
            .unwrap();
    assert!(stats.to_string().contains("2025-01-01T00:00:00Z"));
}

/// DOY, SPICE month names, UTC offsets and TDB give the same rows as the plain UTC form (the
/// TDB form within the CSV's precision: its instant is 0.2 ms from the UTC one).
#[test]
fn epochs_in_spice_forms_give_the_same_ephemerides() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let row = |utc: &str| {
        let o = penumbra(
            dir.path(),
            &[
                "ephem",
                "--lat-deg",
                "-89.9",
                "--lon-deg",
                "0",
                "--utc",
                utc,
                "--kernels",
                k.to_str().unwrap(),
            ],
        );
        assert!(o.status.success(), "{utc}: {}", stderr(&o));
        stdout(&o).lines().nth(1).unwrap().to_string()
    };
    let want = row("2024-02-01T12:00:00");
    for form in [
        "2024-032T12:00",
        "2024 FEB 01 12:00:00",
        "2024-feb-01 12:00",
        "2024-02-01T14:00+02:00",
        "2024-02-01T07:00-05:00",
    ] {
        assert_eq!(row(form), want, "{form}");
    }
    let tdb = row("2024-02-01T12:01:09.184 TDB");
    let fields = |r: &str| -> Vec<f64> {
        r.split(',')
            .skip(1)
            .map(|x| x.parse::<f64>().unwrap())
            .collect()
    };
    for (a, b) in fields(&tdb).iter().zip(fields(&want)) {
        assert!((a - b).abs() <= 1e-6 * b.abs().max(1.0), "{tdb} vs {want}");
    }
    assert_clean_error(
        &penumbra(
            dir.path(),
            &[
                "ephem",
                "--lat-deg",
                "-89.9",
                "--lon-deg",
                "0",
                "--utc",
                "2023-366",
            ],
        ),
        "day of year 366",
    );
}

/// Help written for users: no rustdoc link syntax, no internal paper numbers, and no flag name
/// with two meanings (`--height-m` was "above the sphere" in `ephem` and "above the ground" in
/// `render`; the visible names are now `--height-above-sphere-m` and `--observer-height-m`, the
/// old ones hidden aliases).
#[test]
fn help_is_for_users_and_flag_names_have_one_meaning() {
    let dir = tempfile::tempdir().unwrap();
    let commands: &[&[&str]] = &[
        &[],
        &["ephem"],
        &["kernels"],
        &["run"],
        &["horizon"],
        &["map"],
        &["series"],
        &["dem", "info"],
        &["dem", "synth"],
        &["gpu-info"],
        &["render"],
        &["horizon-map", "build"],
        &["horizon-map", "sweep"],
        &["horizon-map", "info"],
        &["completions"],
        &["man"],
    ];
    for cmd in commands {
        let mut args = cmd.to_vec();
        args.push("--help");
        let help = stdout(&penumbra_ok(dir.path(), &args));
        for bad in [
            "[`",
            "paper 0",
            "papers 0",
            "--height-m <",
            "--width <",
            "--height <",
        ] {
            assert!(
                !help.contains(bad),
                "penumbra {cmd:?} --help shows {bad:?}:\n{help}"
            );
        }
    }
    let render = stdout(&penumbra_ok(dir.path(), &["render", "--help"]));
    for flag in ["--observer-height-m", "--width-px", "--height-px"] {
        assert!(render.contains(flag), "render --help lacks {flag}");
    }
    // The old names still work: the same row from both spellings.
    let k = kernels_dir();
    let row = |flag: &str| {
        stdout(&penumbra_ok(
            dir.path(),
            &[
                "ephem",
                "--lat-deg",
                "-89.9",
                "--lon-deg",
                "0",
                flag,
                "1957",
                "--utc",
                "2025-01-01",
                "--kernels",
                k.to_str().unwrap(),
            ],
        ))
    };
    assert_eq!(row("--height-m"), row("--height-above-sphere-m"));
}

#[test]
fn sites_come_from_csv_or_geojson_with_spaces_in_names() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let k = kernels_dir();
    std::fs::write(
        d.join("sites.csv"),
        "# candidate sites\nname,lat_deg,lon_deg,height_m\nConnecting Ridge (east),-89.9,10,2\n\
         rim 2,-89.85,200,\n",
    )
    .unwrap();
    std::fs::write(
        d.join("sites.geojson"),
        r#"{"type": "FeatureCollection", "features": [
  {"type": "Feature", "geometry": {"type": "Point", "coordinates": [10, -89.9]},
   "properties": {"name": "Connecting Ridge (east)", "height_m": 2}},
  {"type": "Feature", "geometry": {"type": "Point", "coordinates": [200, -89.85, 1234]},
   "properties": {"name": "rim 2"}}]}"#,
    )
    .unwrap();
    let series = |extra: &[&str], out: &str| {
        let mut args = vec![
            "series",
            "--synthetic",
            "--start",
            "2025-01-01",
            "--stop",
            "2025-01-02",
            "--step",
            "6h",
            "--no-plots",
            "--observer-height-m",
            "3",
            "--kernels",
            k.to_str().unwrap(),
            "--out-dir",
            out,
        ];
        args.extend(extra);
        penumbra(d, &args)
    };
    for (file, out) in [("sites.csv", "c"), ("sites.geojson", "g")] {
        let o = series(&["--sites", file], out);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    // The same sites as flags (the oracle: the flag parser, not the file readers).
    let o = series(
        &[
            "--site",
            "Connecting Ridge (east),-89.9,10,2",
            "--site",
            "rim 2,-89.85,200,3",
        ],
        "f",
    );
    assert!(o.status.success(), "{}", stderr(&o));
    for name in ["Connecting Ridge (east)", "rim 2"] {
        let want = std::fs::read(d.join("f").join(name).join("series.csv")).unwrap();
        assert!(want.len() > 100);
        for out in ["c", "g"] {
            let got = std::fs::read(d.join(out).join(name).join("series.csv")).unwrap();
            assert!(got == want, "{out}/{name}/series.csv differs");
        }
    }
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("c/stats.json")).unwrap()).unwrap();
    assert_eq!(stats["schema"], "penumbra-stats/1");
    let run: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("c/run.json")).unwrap()).unwrap();
    assert_eq!(run["schema"], "penumbra-run/1");
    // Each site's location in stats.json; the tidy long table holds every site's rows after the
    // site's columns, and is listed in run.json.
    let loc = &stats["sites"][1]["location"];
    assert_eq!(stats["sites"][1]["site"], "rim 2");
    assert_eq!(
        (loc["lat_deg"].as_f64(), loc["lon_deg"].as_f64()),
        (Some(-89.85), Some(200.0))
    );
    assert_eq!(loc["height_above_ground_m"].as_f64(), Some(3.0));
    assert!(run["outputs"].to_string().contains("series_long.csv"));
    let mut long = csv::Reader::from_path(d.join("c/series_long.csv")).unwrap();
    let header = long.headers().unwrap().clone();
    let per_site_header = std::fs::read_to_string(d.join("f/rim 2/series.csv")).unwrap();
    let per_site_header = per_site_header.lines().next().unwrap();
    assert_eq!(
        header.iter().collect::<Vec<_>>().join(","),
        format!("site,lat_deg,lon_deg,height_above_ground_m,ground_height_m,{per_site_header}")
    );
    let long_rows: Vec<csv::StringRecord> = long.records().map(Result::unwrap).collect();
    let mut n = 0;
    for (name, lat, ground) in [
        (
            "Connecting Ridge (east)",
            "-89.9",
            &stats["sites"][0]["location"]["ground_height_m"],
        ),
        ("rim 2", "-89.85", &loc["ground_height_m"]),
    ] {
        let mut per_site =
            csv::Reader::from_path(d.join("f").join(name).join("series.csv")).unwrap();
        for want in per_site.records() {
            let got = &long_rows[n];
            n += 1;
            assert_eq!((&got[0], &got[1]), (name, lat));
            let g: f64 = got[4].parse().unwrap();
            assert!((g - ground.as_f64().unwrap()).abs() < 1e-3);
            assert_eq!(
                got.iter().skip(5).collect::<Vec<_>>(),
                want.unwrap().iter().collect::<Vec<_>>()
            );
        }
    }
    assert_eq!(n, long_rows.len());
    assert_eq!(n, 2 * 5, "5 epochs (the stop is included) at 2 sites");
    // A scenario takes the same table as `sites_file` (relative to the scenario).
    std::fs::write(
        d.join("s.toml"),
        format!(
            "name = \"s\"\noutput_dir = \"sc\"\nkernels = \"{}\"\nsites_file = \"sites.geojson\"\n\
             [time]\nstart = \"2025-01-01\"\nstop = \"2025-01-02\"\nstep = \"6h\"\n\
             [terrain]\nsynthetic = {{ size_px = 100, px_m = 100.0, seed = 1 }}\n[series]\nplots = false\n",
            k.display()
        ),
    )
    .unwrap();
    let o = penumbra(d, &["run", "s.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let long = std::fs::read_to_string(d.join("sc/series_long.csv")).unwrap();
    assert_eq!(long.lines().count(), 1 + 10);
    assert!(
        long.lines()
            .nth(1)
            .unwrap()
            .starts_with("Connecting Ridge (east),-89.9,10,2,")
    );
    assert!(
        long.lines()
            .nth(6)
            .unwrap()
            .starts_with("rim 2,-89.85,200,2,")
    );
    // Bad files and names: one line each, naming the problem.
    for (name, text, needle) in [
        ("a.csv", "name,lat\nx,-89.9\n", "must name columns"),
        (
            "b.csv",
            "name,lat_deg,lon_deg\nx,-89.9,east\n",
            "line 2: longitude 'east'",
        ),
        (
            "c.csv",
            "name,lat_deg,lon_deg\nRidge,-89.9,0\nridge,-89.8,0\n",
            "differ in more than letter case",
        ),
        (
            "d.csv",
            "name,lat_deg,lon_deg\n../x,-89.9,0\n",
            "site name '../x'",
        ),
        ("e.csv", "name,lat_deg,lon_deg\n", "no sites"),
        (
            "f.geojson",
            r#"{"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": {"type": "LineString", "coordinates": [[0, -89], [1, -89]]}, "properties": {"name": "x"}}]}"#,
            "feature 0: its geometry is not a Point",
        ),
        (
            "g.geojson",
            r#"{"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": {"type": "Point", "coordinates": [0, -89.9]}, "properties": {}}]}"#,
            "no properties.name",
        ),
        ("h.json", "{not json", "not JSON"),
    ] {
        std::fs::write(d.join(name), text).unwrap();
        assert_clean_error(&series(&["--sites", name], "bad"), needle);
    }
    assert_clean_error(&series(&["--sites", "absent.csv"], "bad"), "absent.csv");
    assert_clean_error(
        &series(&["--site", "a/b,-89.9,0"], "bad"),
        "site name 'a/b'",
    );
}
