//! Bad and edge inputs through the binary, as an adversary would try them (issue 17): every case
//! must exit 2 with exactly one `penumbra: error:` line, print nothing on stdout, panic nowhere,
//! and leave no file behind. Plus interruption (SIGTERM), the single-writer lock and stale
//! temporary files.
//!
//! The table is built from classes: each numeric flag × values outside its physical bounds, each
//! bad DEM file × each command that reads a DEM, bad kernels, bad outputs, bad scenarios.

use crate::util::OutputWithin as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use penumbra::terrain::{GridGeometry, Projection, write_geotiff};

use crate::util::{files_in, kernels_dir, penumbra, penumbra_ok};

/// A case: arguments, and a word the error line must contain (empty: any clean error).
struct Case {
    args: Vec<String>,
    needle: &'static str,
}

fn case(args: &[&str], needle: &'static str) -> Case {
    Case {
        args: args.iter().map(|s| s.to_string()).collect(),
        needle,
    }
}

/// Writes the bad DEM files of the table into `dir`; returns (path, what the error says).
fn bad_dems(dir: &Path) -> Vec<(PathBuf, &'static str)> {
    let polar = Projection::LOLA_SOUTH_POLAR;
    let grid = |rows: usize, cols: usize, px: f64, x0: f64| GridGeometry {
        rows,
        cols,
        x_left_m: x0,
        y_top_m: 1000.0,
        px_x_m: px,
        px_y_m: px,
    };
    let mut out = Vec::new();
    let mut put = |name: &str, g: GridGeometry, p: Projection, z: Vec<f32>, needle| {
        let path = dir.join(name);
        write_geotiff(
            &path,
            &g,
            &p,
            &z,
            None,
            &[],
            penumbra::terrain::BandInfo::default(),
        )
        .unwrap();
        out.push((path, needle));
    };
    put(
        "one_cell.tif",
        grid(1, 1, 100.0, 0.0),
        polar,
        vec![0.0],
        "2 x 2",
    );
    put(
        "one_row.tif",
        grid(1, 9, 100.0, 0.0),
        polar,
        vec![0.0; 9],
        "2 x 2",
    );
    put(
        "one_col.tif",
        grid(9, 1, 100.0, 0.0),
        polar,
        vec![0.0; 9],
        "2 x 2",
    );
    put(
        "radii.tif",
        grid(4, 4, 100.0, 0.0),
        polar,
        vec![1_737_400.0 + 120.0; 16],
        "radii",
    );
    let mut inf = vec![10.0f32; 16];
    inf[5] = f32::INFINITY;
    put("inf.tif", grid(4, 4, 100.0, 0.0), polar, inf, "infinite");
    put(
        "huge_heights.tif",
        grid(4, 4, 100.0, 0.0),
        polar,
        vec![3.0e38; 16],
        "heights",
    );
    put(
        "deep.tif",
        grid(4, 4, 100.0, 0.0),
        polar,
        vec![-1_700_000.0; 16],
        "heights",
    );
    put(
        "huge_px.tif",
        grid(4, 4, 1e300, 0.0),
        polar,
        vec![0.0; 16],
        "pixel size",
    );
    put(
        "tiny_px.tif",
        grid(4, 4, 1e-300, 0.0),
        polar,
        vec![0.0; 16],
        "pixel size",
    );
    put(
        "far_origin.tif",
        grid(4, 4, 100.0, 1e12),
        polar,
        vec![0.0; 16],
        "edge",
    );
    put(
        "nan_origin.tif",
        grid(4, 4, 100.0, f64::NAN),
        polar,
        vec![0.0; 16],
        "edge",
    );
    for (name, k0) in [
        ("k0_zero.tif", 0.0),
        ("k0_neg.tif", -1.0),
        ("k0_nan.tif", f64::NAN),
    ] {
        put(
            name,
            grid(4, 4, 100.0, 0.0),
            Projection::PolarStereographic {
                south: true,
                lon0_deg: 0.0,
                k0,
                radius_m: 1_737_400.0,
            },
            vec![0.0; 16],
            "",
        );
    }
    put(
        "earth_radius.tif",
        grid(4, 4, 100.0, 0.0),
        Projection::PolarStereographic {
            south: true,
            lon0_deg: 0.0,
            k0: 1.0,
            radius_m: 6_371_000.0,
        },
        vec![0.0; 16],
        "",
    );
    let text = dir.join("text.tif");
    std::fs::write(&text, "this is not a TIFF").unwrap();
    out.push((text, "TIFF"));
    let empty = dir.join("empty.tif");
    std::fs::write(&empty, "").unwrap();
    out.push((empty, ""));
    // A valid file cut in half.
    let whole = dir.join("whole.tif");
    write_geotiff(
        &whole,
        &grid(64, 64, 100.0, 0.0),
        &polar,
        &vec![1.0; 64 * 64],
        None,
        &[],
        penumbra::terrain::BandInfo::default(),
    )
    .unwrap();
    let bytes = std::fs::read(&whole).unwrap();
    let cut = dir.join("truncated.tif");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    std::fs::remove_file(&whole).unwrap();
    out.push((cut, ""));
    let folder = dir.join("folder.tif");
    std::fs::create_dir(&folder).unwrap();
    out.push((folder, "folder"));
    out.push((PathBuf::from("/dev/zero"), "regular file"));
    #[cfg(unix)]
    {
        let fifo = dir.join("fifo.tif");
        let made = Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            out.push((fifo, "regular file"));
        }
    }
    out.push((dir.join("missing.tif"), "No such file"));
    out
}

fn table(dems: &[(PathBuf, &'static str)], good_dem: &Path, k: &Path) -> Vec<Case> {
    let k = k.to_str().unwrap();
    let d = good_dem.to_str().unwrap();
    let mut cases = Vec::new();
    // --- every command that reads a DEM, with every bad DEM -------------------------------------
    for (dem, needle) in dems {
        let dem = dem.to_str().unwrap();
        let commands: Vec<Vec<&str>> = vec![
            vec!["dem", "info", dem],
            vec![
                "horizon",
                "--dem",
                dem,
                "--lat-deg",
                "-89.9",
                "--lon-deg",
                "0",
            ],
            vec![
                "map",
                "--dem",
                dem,
                "--sun-az-deg",
                "10",
                "--sun-el-deg",
                "2",
                "--out-mask",
                "m.tif",
            ],
            vec![
                "series",
                "--dem",
                dem,
                "--site",
                "a,-89.9,0,2",
                "--utc",
                "2025-01-01",
                "--kernels",
                k,
                "--out-dir",
                "s",
            ],
            vec![
                "horizon-map",
                "build",
                "--dem",
                dem,
                "--out",
                "h.tif",
                "--backend",
                "cpu",
            ],
            vec!["horizon-map", "sweep", "--dem", dem, "--out", "h.tif"],
            vec![
                "render",
                "--dem",
                dem,
                "--lat-deg",
                "-89.9",
                "--lon-deg",
                "0",
                "--utc",
                "2025-01-01",
                "--kernels",
                k,
                "--backend",
                "cpu",
                "--out",
                "r.png",
            ],
            vec![
                "map",
                "--dem",
                dem,
                "--engine",
                "horizons",
                "--start",
                "2025-01-01",
                "--stop",
                "2025-01-02",
                "--step",
                "6h",
                "--kernels",
                k,
                "--out-dir",
                "m",
            ],
        ];
        for c in commands {
            cases.push(case(&c, needle));
        }
    }
    // --- numbers outside their bounds, per flag -------------------------------------------------
    let non_numbers = ["nan", "inf", "-inf", "abc", "", "1e999", "0x10"];
    let ephem = ["ephem", "--kernels", k, "--utc", "2025-01-01"];
    for (flag, bad) in [
        ("--lat-deg", &["91", "-90.5", "1e308"][..]),
        ("--lon-deg", &["1e9", "-361", "1e308"][..]),
        ("--height-m", &["1e308", "-1e6", "200000"][..]),
    ] {
        for v in bad.iter().chain(&non_numbers) {
            let mut args: Vec<&str> = ephem.to_vec();
            let (lat, lon) = ("-89", "0");
            if flag != "--lat-deg" {
                args.extend(["--lat-deg", lat]);
            }
            if flag != "--lon-deg" {
                args.extend(["--lon-deg", lon]);
            }
            args.extend([flag, v]);
            cases.push(case(&args, ""));
        }
    }
    for utc in [
        "2024-13-01",
        "2024-02-30",
        "x",
        "2024-01-01T25:00",
        "2024-01-01T12:60",
        "2016-12-30T23:59:60",
        "",
        "1e308",
        "2024-01-01T00:00:00.1234567890",
        "1899-01-01",
        "2199-01-01",
        "-2024-01-01",
        "2024-01-01T00:00:00+25:00",
    ] {
        cases.push(case(
            &[
                "ephem",
                "--kernels",
                k,
                "--lat-deg",
                "-89",
                "--lon-deg",
                "0",
                "--utc",
                utc,
            ],
            "",
        ));
    }
    for step in [
        "0h", "-1h", "nanh", "1x", "", "1e308h", "h", "1e-12s", "infh",
    ] {
        cases.push(case(
            &[
                "ephem",
                "--kernels",
                k,
                "--lat-deg",
                "-89",
                "--lon-deg",
                "0",
                "--start",
                "2025-01-01",
                "--stop",
                "2025-01-02",
                "--step",
                step,
            ],
            "",
        ));
    }
    // stop before start; a range of 10^8 epochs
    cases.push(case(
        &[
            "ephem",
            "--kernels",
            k,
            "--lat-deg",
            "-89",
            "--lon-deg",
            "0",
            "--start",
            "2025-02-01",
            "--stop",
            "2025-01-01",
            "--step",
            "1h",
        ],
        "before",
    ));
    cases.push(case(
        &[
            "ephem",
            "--kernels",
            k,
            "--lat-deg",
            "-89",
            "--lon-deg",
            "0",
            "--start",
            "2001-01-01",
            "--stop",
            "2049-01-01",
            "--step",
            "1s",
        ],
        "limit",
    ));
    let one_light = ["map", "--dem", d, "--out-mask", "m.tif", "--backend", "cpu"];
    for (flags, bad) in [
        (
            ["--sun-az-deg", "--sun-el-deg"],
            &["91", "-91", "1e308"][..],
        ),
        (["--sun-el-deg", "--sun-az-deg"], &[][..]),
    ] {
        for v in bad.iter().chain(&non_numbers) {
            let mut args = one_light.to_vec();
            args.extend([flags[0], "10", flags[1], v]);
            cases.push(case(&args, ""));
        }
    }
    for (flag, bad) in [
        ("--observer-height-m", &["-1", "1e308"][..]),
        ("--sun-radius-deg", &["0", "-1", "10", "1e308"][..]),
    ] {
        for v in bad.iter().chain(&non_numbers) {
            let mut args = one_light.to_vec();
            args.extend(["--sun-az-deg", "10", "--sun-el-deg", "2", flag, v]);
            cases.push(case(&args, ""));
        }
    }
    let range_map = [
        "map",
        "--dem",
        d,
        "--engine",
        "horizons",
        "--kernels",
        k,
        "--start",
        "2025-01-01",
        "--stop",
        "2025-01-02",
        "--step",
        "6h",
        "--out-dir",
        "m",
    ];
    for (flag, bad) in [
        ("--azimuths", &["0", "3", "100001", "-1", "4294967296"][..]),
        ("--max-step", &["0", "65", "-1"][..]),
        ("--observer-height-m", &["-1"][..]),
    ] {
        for v in bad.iter().chain(&non_numbers) {
            let mut args = range_map.to_vec();
            args.extend([flag, v]);
            cases.push(case(&args, ""));
        }
    }
    let hm = [
        "horizon-map",
        "build",
        "--dem",
        d,
        "--out",
        "h.tif",
        "--backend",
        "cpu",
    ];
    for v in ["0", "31", "7201", "100000", "4294967295", "-1"] {
        let mut args = hm.to_vec();
        args.extend(["--azimuths", v]);
        cases.push(case(&args, ""));
    }
    for v in ["0", "3", "100001", "-1"] {
        cases.push(case(
            &[
                "horizon-map",
                "sweep",
                "--dem",
                d,
                "--out",
                "h.tif",
                "--azimuths",
                v,
            ],
            "",
        ));
    }
    for v in ["0", "-1", "7", "1e-9", "400"].iter().chain(&non_numbers) {
        cases.push(case(
            &[
                "horizon",
                "--dem",
                d,
                "--lat-deg",
                "-89.9",
                "--lon-deg",
                "0",
                "--az-step-deg",
                v,
            ],
            "",
        ));
    }
    for (flag, v) in [
        ("--lat-deg", "-91"),
        ("--lat-deg", "nan"),
        ("--lon-deg", "inf"),
        ("--observer-height-m", "-5"),
        ("--observer-height-m", "1e308"),
        ("--observer-height-m", "nan"),
    ] {
        let mut args = vec!["horizon", "--dem", d];
        if flag != "--lat-deg" {
            args.extend(["--lat-deg", "-89.9"]);
        }
        if flag != "--lon-deg" {
            args.extend(["--lon-deg", "0"]);
        }
        args.extend([flag, v]);
        cases.push(case(&args, ""));
    }
    // a site outside the DEM
    cases.push(case(
        &["horizon", "--dem", d, "--lat-deg", "-80", "--lon-deg", "0"],
        "",
    ));
    for site in [
        "a,-91,0,2",
        "a,nan,0,2",
        "a,-89,inf,2",
        "a,-89.9,0,1e308",
        "a,-89.9,0,-1",
        "bad name,-89.9,0,2",
        ",-89.9,0,2",
        "a,-89.9",
        "a,-89.9,0,2,5",
        "a,x,0,2",
        "a/../../b,-89.9,0,2",
    ] {
        cases.push(case(
            &[
                "series",
                "--dem",
                d,
                "--site",
                site,
                "--utc",
                "2025-01-01",
                "--kernels",
                k,
                "--out-dir",
                "s",
            ],
            "",
        ));
    }
    let render = [
        "render",
        "--dem",
        d,
        "--lat-deg",
        "-89.9",
        "--lon-deg",
        "0",
        "--utc",
        "2025-01-01",
        "--kernels",
        k,
        "--backend",
        "cpu",
        "--out",
        "r.png",
    ];
    for (flag, bad) in [
        ("--width", &["0", "16385", "-1", "4294967296"][..]),
        ("--height", &["0", "100000"][..]),
        ("--fov-deg", &["0", "180", "-5"][..]),
        ("--exposure", &["0", "-1"][..]),
        ("--height-m", &["1e308", "-5"][..]),
        ("--look-el-deg", &["91", "-91"][..]),
    ] {
        for v in bad.iter().chain(&non_numbers[..4]) {
            let mut args = render.to_vec();
            args.extend([flag, v]);
            cases.push(case(&args, ""));
        }
    }
    for alt in ["1e9", "inf", "nan", "-8", "0"] {
        let mut args = render.to_vec();
        args.extend(["--camera", "orbit", "--altitude-km", alt]);
        cases.push(case(&args, ""));
    }
    {
        let mut args = render.to_vec();
        args.extend(["--brdf", "lambert", "--albedo", "2"]);
        cases.push(case(&args, "albedo"));
        let mut args = render.to_vec();
        args.extend(["--albedo", "0.2"]);
        cases.push(case(&args, "albedo"));
    }
    // a year of frames at one minute
    cases.push(case(
        &[
            "render",
            "--dem",
            d,
            "--lat-deg",
            "-89.9",
            "--lon-deg",
            "0",
            "--start",
            "2025-01-01",
            "--stop",
            "2026-01-01",
            "--step",
            "1m",
            "--kernels",
            k,
            "--backend",
            "cpu",
            "--out",
            "r.png",
        ],
        "frames",
    ));
    // --- outputs ---------------------------------------------------------------------------------
    let light = [
        "map",
        "--dem",
        d,
        "--utc",
        "2025-01-01",
        "--kernels",
        k,
        "--backend",
        "cpu",
    ];
    for extra in [
        &["--out-fraction", "f.tif", "--out-mask", "f.tif"][..],
        &["--out-fraction", "f.tif", "--out-mask", "./x/../f.tif"][..],
        &["--out-fraction", "-", "--out-mask", "m.tif"][..],
        &["--out-mask", "/dev/null"][..],
        &["--out-mask", "."][..],
        &["--out-mask", "no/such/folder/m.tif"][..],
        &["--out-mask", ""][..],
    ] {
        let mut args = light.to_vec();
        args.extend(extra);
        cases.push(case(&args, ""));
    }
    cases.push(case(
        &[
            "map",
            "--dem",
            d,
            "--sun-az-deg",
            "10",
            "--sun-el-deg",
            "2",
            "--out-earth-fraction",
            "e.tif",
        ],
        "epoch",
    ));
    {
        let mut args = render.to_vec();
        args.extend(["--out-radiance", "r.png"]);
        cases.push(case(&args, "same file"));
        let mut args = render.to_vec();
        args.extend(["--out-radiance", "r.run.json"]);
        cases.push(case(&args, "same file"));
    }
    cases.push(case(
        &[
            "horizon-map",
            "sweep",
            "--dem",
            d,
            "--out",
            "h.tif",
            "--distance-out",
            "h.tif",
        ],
        "same file",
    ));
    // --- kernels ---------------------------------------------------------------------------------
    let bsp = format!("{k}/de440_moon_2000_2025.bsp");
    for kern in [
        "/nonexistent",
        bsp.as_str(),
        "/dev/zero",
        "/dev/null",
        d, // a DEM is not a meta-kernel
    ] {
        cases.push(case(
            &[
                "ephem",
                "--lat-deg",
                "-89",
                "--lon-deg",
                "0",
                "--utc",
                "2025-01-01",
                "--kernels",
                kern,
            ],
            "",
        ));
    }
    // --- series numbers --------------------------------------------------------------------------
    let series = [
        "series",
        "--dem",
        d,
        "--site",
        "a,-89.9,0,2",
        "--utc",
        "2025-01-01",
        "--kernels",
        k,
        "--out-dir",
        "s",
    ];
    for (flag, bad) in [
        ("--az-step-deg", &["0", "-1", "7", "1e-9"][..]),
        ("--observer-height-m", &["-1", "1e308"][..]),
    ] {
        for v in bad.iter().chain(&non_numbers) {
            let mut args = series.to_vec();
            args.extend([flag, v]);
            cases.push(case(&args, ""));
        }
    }
    for kern in ["/nonexistent", bsp.as_str(), "/dev/zero"] {
        let mut args = series.to_vec();
        args.extend(["--kernels", kern]);
        cases.push(case(&args, ""));
    }
    for dir in ["--sun-dir-body"] {
        for v in [
            "0,0,0",
            "nan,0,1",
            "inf,0,0",
            "1,2",
            "a,b,c",
            "1e308,1e308,1e308",
        ] {
            let mut args = one_light.to_vec();
            args.extend([dir, v]);
            cases.push(case(&args, ""));
        }
    }
    for kern in ["/nonexistent", bsp.as_str(), "/dev/zero"] {
        let mut args = range_map.to_vec();
        args.extend(["--kernels", kern]);
        cases.push(case(&args, ""));
        let mut args = render.to_vec();
        args.extend(["--kernels", kern]);
        cases.push(case(&args, ""));
    }
    for (cmd, flag, v) in [
        (&hm[..], "--out", "-"),
        (&hm[..], "--out", "/dev/null"),
        (&render[..], "--look-az-deg", "nan"),
        (&render[..], "--look-az-deg", "inf"),
        (&render[..], "--out", "-"),
        (&one_light[..], "--gpu-tile-cells", "0"),
        (&one_light[..], "--gpu-tile-cells", "-1"),
        (&one_light[..], "--engine", "bogus"),
        (&one_light[..], "--backend", "bogus"),
        (&series[..], "--engine", "bogus"),
        (&series[..], "--backend", "bogus"),
        (&series[..], "--abcorr", "bogus"),
        (&series[..], "--limb-darkening", "bogus"),
        (&series[..], "--out-dir", "/dev/null"),
        (&range_map[..], "--out-dir", "/dev/null"),
        (&range_map[..], "--horizons", "/dev/zero"),
        (&range_map[..], "--horizons", "/nonexistent.tif"),
    ] {
        let mut args = cmd.to_vec();
        args.extend([flag, v]);
        if cmd[0] == "map" && flag != "--engine" && cmd.len() == one_light.len() {
            args.extend(["--sun-az-deg", "10", "--sun-el-deg", "2"]);
        }
        cases.push(case(&args, ""));
    }
    // --- horizon-map files -----------------------------------------------------------------------
    for (dem, _) in dems {
        cases.push(case(&["horizon-map", "info", dem.to_str().unwrap()], ""));
    }
    cases
}

/// Scenarios with one fault each: found before any stage writes a file.
fn bad_scenarios(dir: &Path, good_dem: &Path, k: &Path) -> Vec<Case> {
    let head = format!(
        "name = \"t\"\noutput_dir = \"out\"\nkernels = \"{}\"\n",
        k.display()
    );
    let time = "[time]\nstart = \"2025-01-01\"\nstop = \"2025-01-02\"\nstep = \"6h\"\n";
    let site = "[[sites]]\nname = \"a\"\nlat_deg = -89.9\nlon_deg = 0.0\n";
    let terrain = format!("[terrain]\nlayers = [\"{}\"]\n", good_dem.display());
    let view = |extra: &str| {
        format!(
            "[render]\n[[render.views]]\nout = \"v.png\"\nlat_deg = -89.9\nlon_deg = 0.0\nutc = \"2025-01-01\"\n{extra}\n"
        )
    };
    let variants: Vec<(String, &'static str)> = vec![
        (format!("{head}{time}"), "sites"),
        (format!("{head}{site}"), "time"),
        (
            format!(
                "{head}[time]\nstart = \"2025-13-01\"\nstop = \"2025-01-02\"\nstep = \"6h\"\n{site}"
            ),
            "start",
        ),
        (
            format!(
                "{head}[time]\nstart = \"2025-01-01\"\nstop = \"2025-01-02\"\nstep = \"0h\"\n{site}"
            ),
            "step",
        ),
        (
            format!(
                "{head}[time]\nstart = \"2025-01-03\"\nstop = \"2025-01-02\"\nstep = \"6h\"\n{site}"
            ),
            "before",
        ),
        (
            format!("{head}{time}[[sites]]\nname = \"a/b\"\nlat_deg = -89.9\nlon_deg = 0.0\n"),
            "site name",
        ),
        (
            format!("{head}{time}[[sites]]\nname = \"a\"\nlat_deg = -91.0\nlon_deg = 0.0\n"),
            "latitude",
        ),
        (
            format!(
                "{head}{time}[[sites]]\nname = \"a\"\nlat_deg = -89.0\nlon_deg = 0.0\nheight_above_ground_m = 1e308\n"
            ),
            "height",
        ),
        (format!("{head}{time}{site}{site}"), "twice"),
        (
            format!("{head}{time}{site}[map]\nstep = \"1d\"\n"),
            "terrain",
        ),
        (
            format!("{head}{time}{site}{terrain}[map]\nstep = \"1d\"\nengine = \"magic\"\n"),
            "engine",
        ),
        (
            format!("{head}{time}{site}{terrain}[map]\nstep = \"0d\"\n"),
            "step",
        ),
        (
            format!("{head}{time}{site}{terrain}[map]\nstep = \"1d\"\nobserver_height_m = -2.0\n"),
            "observer_height_m",
        ),
        (
            format!(
                "{head}{time}{site}{terrain}[map]\nstep = \"1d\"\nengine = \"horizons\"\nazimuths = 2\n"
            ),
            "azimuths",
        ),
        (
            format!(
                "{head}{time}{site}{terrain}[map]\nstep = \"1d\"\nhorizons_file = \"nowhere.tif\"\n"
            ),
            "horizons_file",
        ),
        (
            format!("{head}{time}{site}{terrain}[series]\naz_step_deg = 7.0\n"),
            "az_step_deg",
        ),
        (
            format!("{head}{time}{site}{terrain}{}", view(""))
                .replace("out = \"v.png\"", "out = \"../../x.png\""),
            "output name",
        ),
        (
            format!("{head}{time}{site}{terrain}{}", view(""))
                .replace("out = \"v.png\"", "out = \"/tmp/x.png\""),
            "output name",
        ),
        (
            format!("{head}{time}{site}{terrain}{}", view(""))
                .replace("out = \"v.png\"", "out = \"\""),
            "output name",
        ),
        (
            format!("{head}{time}{site}{terrain}{}", view(""))
                .replace("out = \"v.png\"", "out = \"v.txt\""),
            ".png",
        ),
        (
            format!(
                "{head}{time}{site}{terrain}{}",
                view("out_radiance = \"../r.tif\"")
            ),
            "output name",
        ),
        (
            format!(
                "{head}{time}{site}{terrain}{}{}",
                view(""),
                view("").replace("[render]\n", "")
            ),
            "same file",
        ),
        (
            format!("{head}{time}{site}{terrain}{}", view("width = 0")),
            "size",
        ),
        (
            format!("{head}{time}{site}{terrain}{}", view("fov_deg = 190.0")),
            "fov",
        ),
        (
            format!("{head}{time}{site}{terrain}{}", view("exposure = -1.0")),
            "exposure",
        ),
        (
            format!("{head}{time}{site}{terrain}{}", view("albedo = 0.3")),
            "albedo",
        ),
        (
            format!(
                "{head}{time}{site}{terrain}{}",
                view("utc = \"x\"").replace("utc = \"2025-01-01\"\n", "")
            ),
            "",
        ),
        (
            format!("{head}{time}{site}{terrain}{}", view("height_m = 1e308")),
            "height",
        ),
        (
            format!(
                "{head}{time}{site}[terrain]\nsynthetic = {{ size_px = 1, px_m = 100.0, seed = 1 }}\n"
            ),
            "size_px",
        ),
        (
            format!(
                "{head}{time}{site}[terrain]\nsynthetic = {{ size_px = 64, px_m = 1e300, seed = 1 }}\n"
            ),
            "px_m",
        ),
        (
            format!(
                "{head}{time}{site}[terrain]\nlayers = [\"{}\"]\n",
                dir.join("missing.tif").display()
            ),
            "missing.tif",
        ),
        (
            format!("name = \"t\"\noutput_dir = \"\"\n{time}{site}"),
            "output_dir",
        ),
        (format!("{head}{time}{site}bogus = 1\n"), "bogus"),
        ("not = [toml".to_string(), ""),
    ];
    variants
        .into_iter()
        .enumerate()
        .map(|(i, (text, needle))| {
            let path = dir.join(format!("bad{i}.toml"));
            std::fs::write(&path, text).unwrap();
            Case {
                args: vec!["run".into(), path.display().to_string()],
                needle,
            }
        })
        .collect()
}

/// Runs one case in a fresh folder and checks the contract.
fn check(case: &Case, cwd: &Path) -> Result<(), String> {
    let out = penumbra(
        cwd,
        &case.args.iter().map(String::as_str).collect::<Vec<_>>(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    let error_lines: Vec<&&str> = lines
        .iter()
        .filter(|l| !l.contains("warning") && !l.contains("adapter"))
        .collect();
    let mut problems = Vec::new();
    if out.status.code() != Some(2) {
        problems.push(format!("exit {:?}", out.status.code()));
    }
    if error_lines.len() != 1 || !error_lines[0].starts_with("penumbra: error: ") {
        problems.push(format!("{} error lines", error_lines.len()));
    }
    if stderr.contains("panicked") || stderr.contains("RUST_BACKTRACE") {
        problems.push("panic".into());
    }
    if !out.stdout.is_empty() {
        problems.push(format!("{} bytes on stdout", out.stdout.len()));
    }
    if !stderr.to_lowercase().contains(&case.needle.to_lowercase()) {
        problems.push(format!("no '{}'", case.needle));
    }
    let left = files_in(cwd);
    if !left.is_empty() {
        problems.push(format!("left {left:?}"));
    }
    if problems.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "{:?}: {} | {}",
            case.args,
            problems.join(", "),
            stderr.trim()
        ))
    }
}

#[test]
fn bad_inputs_exit_2_with_one_line_and_no_file() {
    let inputs = tempfile::tempdir().unwrap();
    let dems = bad_dems(inputs.path());
    let good = inputs.path().join("good.tif");
    penumbra_ok(
        inputs.path(),
        &[
            "dem",
            "synth",
            "--size",
            "40",
            "--px-m",
            "100",
            "--seed",
            "1",
            "--out",
            good.to_str().unwrap(),
        ],
    );
    let mut cases = table(&dems, &good, &kernels_dir());
    let scenarios = inputs.path().join("scenarios");
    std::fs::create_dir(&scenarios).unwrap();
    cases.extend(bad_scenarios(&scenarios, &good, &kernels_dir()));
    let runs = tempfile::tempdir().unwrap();
    let failures: Vec<String> = cases
        .iter()
        .enumerate()
        .filter_map(|(i, c)| {
            let cwd = runs.path().join(format!("case{i}"));
            std::fs::create_dir(&cwd).unwrap();
            check(c, &cwd).err()
        })
        .collect();
    println!("{} bad-input cases through the binary", cases.len());
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
    assert!(cases.len() >= 500, "only {} cases", cases.len());
}

/// A second writer into a run folder is refused while the first lives; a lock left by a dead
/// process is taken over, with the temporary files killed runs left behind.
#[test]
fn a_run_folder_has_one_writer() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    std::fs::create_dir(&out).unwrap();
    // This test process is alive: its pid holds the lock.
    std::fs::write(
        out.join(".penumbra.lock"),
        format!("{}\n", std::process::id()),
    )
    .unwrap();
    let k = kernels_dir();
    let args = [
        "series",
        "--synthetic",
        "--site",
        "a,-89.9,0,2",
        "--utc",
        "2025-01-01",
        "--no-plots",
        "--kernels",
        k.to_str().unwrap(),
        "--out-dir",
        "s",
    ];
    let o = penumbra(dir.path(), &args);
    crate::util::assert_clean_error(&o, "another penumbra run");
    // A dead owner (pid above Linux's pid_max) and a stale temp file from a killed run.
    std::fs::write(out.join(".penumbra.lock"), "4194305\n").unwrap();
    std::fs::write(out.join(".penumbra-dead.tmp"), "half").unwrap();
    penumbra_ok(dir.path(), &args);
    let left = files_in(&out);
    assert!(left.contains(&"run.json".to_string()), "{left:?}");
    assert!(
        !left.iter().any(|f| f.starts_with(".penumbra")),
        "lock or temp file left: {left:?}"
    );
}

/// SIGTERM during a long map: exit 143, one line, no temporary file, no lock, no run.json.
#[cfg(unix)]
#[test]
fn sigterm_leaves_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let child = crate::util::penumbra_command()
        .current_dir(dir.path())
        .args([
            "map",
            "--synthetic",
            "--engine",
            "horizons",
            "--start",
            "2025-01-01",
            "--stop",
            "2025-12-31",
            "--step",
            "1h",
            "--kernels",
            k.to_str().unwrap(),
            "--out-dir",
            "m",
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let pid = child.id().to_string();
    let killed = Command::new("kill").args(["-TERM", &pid]).status().unwrap();
    assert!(killed.success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_ne!(
        out.status.code(),
        Some(0),
        "the run finished before the signal: nothing was checked (make the run longer)"
    );
    assert_eq!(out.status.code(), Some(143), "{stderr}");
    assert!(stderr.contains("interrupted by SIGTERM"), "{stderr}");
    let folder = dir.path().join("m");
    let left = files_in(&folder);
    // The checkpoints of finished parts stay, for `--resume`.
    assert!(
        !left
            .iter()
            .any(|f| (f.starts_with(".penumbra") && f != ".penumbra-resume") || f == "run.json"),
        "{left:?}"
    );
}

/// Without XDG_RUNTIME_DIR (cron, Docker, Slurm), a GPU probe prints no Mesa/Wayland noise.
#[test]
fn no_xdg_runtime_dir_noise_without_a_session() {
    let dir = tempfile::tempdir().unwrap();
    let out = crate::util::penumbra_command()
        .current_dir(dir.path())
        .env_remove("XDG_RUNTIME_DIR")
        .args(["gpu-info", "--backend", "auto"])
        .output_within()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("XDG_RUNTIME_DIR"), "{stderr}");
}

/// Property (proptest): any combination of flags and values, good or bad, either succeeds or
/// exits 2 with one `penumbra: error:` line, never panics and never runs away (each run is on a
/// 40² DEM over at most two days, so a success is quick). `PENUMBRA_CLI_CASES` sets the count.
#[test]
fn any_argument_combination_succeeds_or_exits_2_with_one_line() {
    use proptest::prelude::*;
    use proptest::test_runner::{Config, TestRunner};
    let inputs = tempfile::tempdir().unwrap();
    let dem = inputs.path().join("d.tif");
    penumbra_ok(
        inputs.path(),
        &[
            "dem",
            "synth",
            "--size",
            "40",
            "--px-m",
            "100",
            "--seed",
            "1",
            "--out",
            dem.to_str().unwrap(),
        ],
    );
    let k = kernels_dir();
    let (dem, k) = (
        dem.to_str().unwrap().to_string(),
        k.to_str().unwrap().to_string(),
    );
    let commands: Vec<Vec<String>> = [
        vec!["ephem"],
        vec!["horizon"],
        vec!["series", "--no-plots"],
        vec!["map"],
        vec![
            "render",
            "--width",
            "32",
            "--height",
            "24",
            "--backend",
            "cpu",
        ],
        vec!["horizon-map", "sweep", "--azimuths", "8", "--max-step", "2"],
        vec!["dem", "info"],
        vec!["kernels"],
    ]
    .into_iter()
    .map(|v| v.into_iter().map(String::from).collect())
    .collect();
    let flags: Vec<(&str, Vec<String>)> = vec![
        (
            "--dem",
            vec![dem.clone(), "/dev/null".into(), "x.tif".into()],
        ),
        ("--kernels", vec![k.clone(), "/nope".into()]),
        (
            "--lat-deg",
            ["-89.9", "-89.5", "-91", "nan", "0"]
                .map(String::from)
                .to_vec(),
        ),
        (
            "--lon-deg",
            ["0", "45", "1e9", "inf"].map(String::from).to_vec(),
        ),
        (
            "--utc",
            [
                "2025-01-01",
                "2025-13-01",
                "2016-12-31T23:59:60",
                "2199-01-01",
            ]
            .map(String::from)
            .to_vec(),
        ),
        ("--start", ["2025-01-01", "x"].map(String::from).to_vec()),
        (
            "--stop",
            ["2025-01-02", "2024-12-31"].map(String::from).to_vec(),
        ),
        ("--step", ["12h", "0h", "1x"].map(String::from).to_vec()),
        (
            "--site",
            ["a,-89.9,0,2", "b,-91,0,2", "a b,-89.9,0,2"]
                .map(String::from)
                .to_vec(),
        ),
        (
            "--observer-height-m",
            ["2", "-1", "1e308"].map(String::from).to_vec(),
        ),
        (
            "--height-m",
            ["2", "1e308", "nan"].map(String::from).to_vec(),
        ),
        ("--sun-az-deg", ["10", "nan"].map(String::from).to_vec()),
        ("--sun-el-deg", ["2", "91"].map(String::from).to_vec()),
        (
            "--engine",
            ["smap", "dp", "horizons", "bogus", "horizon"]
                .map(String::from)
                .to_vec(),
        ),
        (
            "--out-mask",
            ["m.tif", "/dev/null", "o.tif"].map(String::from).to_vec(),
        ),
        (
            "--out-fraction",
            ["f.tif", "o.tif"].map(String::from).to_vec(),
        ),
        ("--out-dir", ["o", "/dev/null"].map(String::from).to_vec()),
        (
            "--out",
            ["o.tif", "o.png", "o.csv", "-"].map(String::from).to_vec(),
        ),
        ("--az-step-deg", ["1", "7", "0"].map(String::from).to_vec()),
        ("--backend", ["cpu", "bogus"].map(String::from).to_vec()),
        (
            "--format",
            ["csv", "json", "xml"].map(String::from).to_vec(),
        ),
        ("--bogus", vec![]),
    ];
    let n_flags = flags.len();
    let strategy = (
        0..commands.len(),
        prop::collection::vec((0..n_flags, 0usize..8), 0..8),
        any::<bool>(),
    );
    let cases: u32 = std::env::var("PENUMBRA_CLI_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300);
    let mut runner = TestRunner::new(Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    });
    let runs = tempfile::tempdir().unwrap();
    let counter = std::sync::atomic::AtomicUsize::new(0);
    let successes = std::sync::atomic::AtomicUsize::new(0);
    let result = runner.run(&strategy, |(cmd, picks, with_site)| {
        let mut args: Vec<String> = commands[cmd].clone();
        if with_site && (args[0] == "dem") {
            args.push(dem.clone());
        }
        for (f, v) in picks {
            let (flag, values) = &flags[f];
            args.push(flag.to_string());
            if !values.is_empty() {
                args.push(values[v % values.len()].clone());
            }
        }
        let i = counter.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let cwd = runs.path().join(format!("p{i}"));
        std::fs::create_dir(&cwd).unwrap();
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = penumbra(&cwd, &refs);
        let stderr = String::from_utf8_lossy(&out.stderr);
        prop_assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        match out.status.code() {
            Some(0) => {
                successes.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
            Some(2) => {
                let errors: Vec<&str> = stderr
                    .lines()
                    .filter(|l| l.starts_with("penumbra: error:") || l.starts_with("error"))
                    .collect();
                prop_assert_eq!(errors.len(), 1, "{:?}: {}", args, stderr);
            }
            other => prop_assert!(false, "{args:?}: exit {other:?}: {stderr}"),
        }
        Ok(())
    });
    println!(
        "{} argument combinations, {} succeeded",
        counter.load(std::sync::atomic::Ordering::Relaxed),
        successes.load(std::sync::atomic::Ordering::Relaxed)
    );
    if let Err(e) = result {
        panic!("{e}");
    }
}

/// `penumbra ephem … | head -1`: the reader leaving is not an error (exit 0, nothing on
/// stderr); `--out -` is standard output, not a file named `-`.
#[cfg(unix)]
#[test]
fn a_closed_pipe_is_not_an_error_and_dash_is_stdout() {
    use std::io::{BufRead as _, BufReader};
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let mut child = crate::util::penumbra_command()
        .current_dir(dir.path())
        .args([
            "ephem",
            "--lat-deg",
            "-89",
            "--lon-deg",
            "0",
            "--start",
            "2025-01-01",
            "--stop",
            "2025-03-01",
            "--step",
            "1m",
            "--out",
            "-",
            "--kernels",
        ])
        .arg(&k)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    // The reader is dropped here: the pipe closes with ~85,000 rows still to write.
    assert!(first.starts_with("utc,sun_az_deg"), "{first}");
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stderr.trim().is_empty(), "{stderr}");
    assert!(files_in(dir.path()).is_empty(), "a file named '-'?");
}
