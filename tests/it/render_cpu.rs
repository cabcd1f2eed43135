//! Renderer, CPU path: the BRDFs (src/render/brdf.rs) against independent oracles (Lambert exactly,
//! Hapke's H approximation against Chandrasekhar's H-function solved numerically here,
//! reciprocity, energy conservation of a conservative isotropic half-space, the opposition
//! value from a separately written formula, and the WGSL twin validated by naga); the orbital
//! camera, epoch ranges with numbered frames and the float radiance TIFF through the CLI.

use std::f64::consts::PI;

use penumbra::render::brdf::{Brdf, HapkeParams, double_hg, hapke_h, hapke_r_per_sr};

use crate::util::{assert_clean_error, files_in, kernels_dir, penumbra, render_scenario};

/// Chandrasekhar's H-function for isotropic scattering with albedo `w`, at the midpoints of
/// `n` intervals of [0, 1], from the integral equation
/// `H(mu) = 1 + w/2 mu H(mu) int_0^1 H(mu') / (mu + mu') dmu'` (Chandrasekhar 1960, *Radiative
/// Transfer*, ch. V), iterated from H = 1 (monotone convergence) with the midpoint rule.
fn chandrasekhar_h(w: f64, n: usize) -> (Vec<f64>, Vec<f64>) {
    let mu: Vec<f64> = (0..n).map(|k| (k as f64 + 0.5) / n as f64).collect();
    let dmu = 1.0 / n as f64;
    let mut h = vec![1.0; n];
    for _ in 0..4000 {
        let new: Vec<f64> = mu
            .iter()
            .map(|&m| {
                let s: f64 = mu
                    .iter()
                    .zip(&h)
                    .map(|(&mp, &hp)| hp / (m + mp))
                    .sum::<f64>()
                    * dmu;
                1.0 / (1.0 - w / 2.0 * m * s)
            })
            .collect();
        let change = new
            .iter()
            .zip(&h)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        h = new;
        if change < 1e-11 {
            break;
        }
    }
    (mu, h)
}

/// H at `x` by linear interpolation of the tabulated solution (x in [1/(2n), 1 - 1/(2n)]).
fn interp(mu: &[f64], h: &[f64], x: f64) -> f64 {
    let n = mu.len();
    let k = ((x * n as f64 - 0.5).floor() as usize).min(n - 2);
    let t = (x - mu[k]) / (mu[k + 1] - mu[k]);
    h[k] * (1.0 - t) + h[k + 1] * t
}

#[test]
fn lambert_is_albedo_over_pi() {
    let brdf = Brdf::Lambert { albedo: 0.12 };
    for (ci, ce, cg) in [(1.0, 1.0, 1.0), (0.3, 0.9, 0.1), (0.01, 0.5, -0.4)] {
        assert_eq!(brdf.per_sr(ci, ce, cg), 0.12 / PI);
    }
    assert_eq!(brdf.per_sr(-0.1, 0.5, 0.0), 0.0);
    assert_eq!(brdf.per_sr(0.5, 0.0, 0.0), 0.0);
}

/// Hapke's (2002) approximation of H stays within 1 % of the exact H-function (solved here from
/// Chandrasekhar's integral equation) for w in 0.1..1; at w = 1, mu = 1 the exact value is
/// Chandrasekhar's tabulated H(1) = 2.9078.
#[test]
fn hapke_h_matches_chandrasekhar() {
    let n = 400;
    let mut worst = 0.0_f64;
    for w in [0.1, 0.32, 0.6, 0.9, 0.99] {
        let (mu, h) = chandrasekhar_h(w, n);
        for x in [0.05, 0.1, 0.25, 0.5, 0.75, 0.99] {
            let exact = interp(&mu, &h, x);
            let rel = (hapke_h(x, w) - exact).abs() / exact;
            worst = worst.max(rel);
            assert!(
                rel < 0.01,
                "w {w} x {x}: approx {} exact {exact}",
                hapke_h(x, w)
            );
        }
    }
    eprintln!("Hapke H approximation: worst relative error {worst:.2e} (w 0.1..0.99)");
    // Conservative scattering: compare the solver to Chandrasekhar's table, H(1) = 2.90781.
    let (mu, h) = chandrasekhar_h(1.0, n);
    let h1 = h[n - 1] + (h[n - 1] - h[n - 2]) * 0.5; // extrapolate half a step to mu = 1
    assert!((h1 - 2.90781).abs() < 0.01, "solver H(1) at w = 1: {h1}");
    assert!((interp(&mu, &h, 0.5) - 2.0133).abs() < 0.01);
}

/// Random geometries (unit vectors to the light and to the viewer above a horizontal facet):
/// f(i, e, g) = f(e, i, g) for the smooth and the rough (theta_bar = 23.657 deg) model.
#[test]
fn hapke_is_reciprocal() {
    let mut seed = 0x2545_f491_u64;
    let mut rnd = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut worst = 0.0_f64;
    for params in [HapkeParams::MOON_643NM, HapkeParams::MOON_643NM.smooth()] {
        let brdf = Brdf::Hapke(params);
        for _ in 0..2000 {
            let dir = |az: f64, el: f64| [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()];
            let a = dir(rnd() * 2.0 * PI, 0.01 + rnd() * 1.55);
            let b = dir(rnd() * 2.0 * PI, 0.01 + rnd() * 1.55);
            let cos_g = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
            let f_ab = brdf.per_sr(a[2], b[2], cos_g);
            let f_ba = brdf.per_sr(b[2], a[2], cos_g);
            let rel = (f_ab - f_ba).abs() / f_ab.max(1e-30);
            worst = worst.max(rel);
            assert!(rel < 1e-9, "{params:?}: {f_ab} vs {f_ba}");
            assert!(f_ab.is_finite() && f_ab > 0.0);
        }
    }
    eprintln!("Hapke reciprocity: worst relative asymmetry {worst:.1e}");
}

/// A conservative (w = 1), isotropic (b = 0), smooth half-space without opposition effect
/// reflects all the light: int f cos e dOmega = 1 for every incidence (exact with the true H;
/// Hapke's approximation of H costs up to 1.5 % here, bound 2 %).
#[test]
fn hapke_conservative_half_space_reflects_everything() {
    let p = HapkeParams {
        w: 1.0,
        b: 0.0,
        c: 0.0,
        bs0: 0.0,
        hs: 0.07,
        bc0: 0.0,
        hc: 1.0,
        theta_bar_deg: 0.0,
        k: 1.0,
    };
    let brdf = Brdf::Hapke(p);
    let (ne, np) = (400, 90);
    for i_deg in [0.0_f64, 30.0, 60.0, 85.0] {
        let (ci, si) = (i_deg.to_radians().cos(), i_deg.to_radians().sin());
        let mut albedo = 0.0;
        for ke in 0..ne {
            let e = (ke as f64 + 0.5) / ne as f64 * PI / 2.0;
            for kp in 0..np {
                let psi = (kp as f64 + 0.5) / np as f64 * 2.0 * PI;
                let cos_g = ci * e.cos() + si * e.sin() * psi.cos();
                albedo += brdf.per_sr(ci, e.cos(), cos_g)
                    * e.cos()
                    * e.sin()
                    * (PI / 2.0 / ne as f64)
                    * (2.0 * PI / np as f64);
            }
        }
        eprintln!("w = 1, i = {i_deg} deg: directional-hemispherical albedo {albedo:.4}");
        assert!((albedo - 1.0).abs() < 0.02, "i {i_deg}: albedo {albedo}");
    }
}

/// At normal opposition (i = e = g = 0) the shadowing S is 1 and the smooth normal albedo is
/// `A_n = pi r = K w / 8 [p(0) (1 + B_S0) + H(1)^2 - 1]`, here with p(0) written out and H(1)
/// from Chandrasekhar's equation (1 % budget of the H approximation; with roughness the
/// effective cosines mu0e = mue = chi(theta_bar) lower M: measured 0.4 %).
#[test]
fn hapke_normal_albedo_at_opposition() {
    let p = HapkeParams::MOON_643NM;
    let p0 = (1.0 + p.c) / 2.0 * (1.0 - p.b * p.b) / (1.0 - p.b).powi(3)
        + (1.0 - p.c) / 2.0 * (1.0 - p.b * p.b) / (1.0 + p.b).powi(3);
    assert!((p0 - double_hg(p.b, p.c, 1.0)).abs() < 1e-12);
    let n = 400;
    let (_, h) = chandrasekhar_h(p.w, n);
    let h1 = h[n - 1] + (h[n - 1] - h[n - 2]) * 0.5;
    let want = p.w / 8.0 * (p0 * (1.0 + p.bs0) + h1 * h1 - 1.0);
    for params in [p, p.smooth()] {
        let got = PI * Brdf::Hapke(params).per_sr(1.0, 1.0, 1.0);
        eprintln!(
            "normal albedo (theta_bar {}): {got:.4}, oracle {want:.4}",
            params.theta_bar_deg
        );
        assert!((got - want).abs() / want < 0.01, "{got} vs {want}");
    }
    // Radiance factor at Sato et al.'s normalisation geometry i = g = 60, e = 0.
    let iof = PI * hapke_r_per_sr(&p, 0.5, 1.0, 0.5);
    eprintln!("I/F at i = g = 60 deg, e = 0: {iof:.4}");
    assert!(iof > 0.0 && iof < want);
}

/// A rough surface tends to the smooth one as theta_bar -> 0.
#[test]
fn hapke_roughness_is_continuous_at_zero() {
    let rough = HapkeParams {
        theta_bar_deg: 0.05,
        ..HapkeParams::MOON_643NM
    };
    let smooth = HapkeParams::MOON_643NM.smooth();
    for (ci, ce, cg) in [(0.5, 1.0, 0.5), (0.2, 0.7, 0.3), (0.9, 0.3, 0.1)] {
        let a = Brdf::Hapke(rough).per_sr(ci, ce, cg);
        let b = Brdf::Hapke(smooth).per_sr(ci, ce, cg);
        assert!((a - b).abs() / b < 2e-3, "{a} vs {b}");
    }
}

/// `shaders/shared/brdf.wgsl` parses and validates with naga and declares
/// `fn brdf_per_sr(model: u32, cos_i: f32, cos_e: f32, cos_g: f32, albedo: f32) -> f32`, and its
/// Hapke constants equal `HapkeParams::MOON_643NM`.
#[test]
fn wgsl_brdf_twin_validates() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/shaders/shared/brdf.wgsl");
    let src = std::fs::read_to_string(path).unwrap();
    let module = crate::util::naga_validate("brdf.wgsl", &src);
    let (_, f) = module
        .functions
        .iter()
        .find(|(_, f)| f.name.as_deref() == Some("brdf_per_sr"))
        .expect("fn brdf_per_sr");
    let scalar = |ty: naga::Handle<naga::Type>| match module.types[ty].inner {
        naga::TypeInner::Scalar(s) => s,
        ref other => panic!("not a scalar: {other:?}"),
    };
    let args: Vec<_> = f
        .arguments
        .iter()
        .map(|a| (a.name.clone().unwrap(), scalar(a.ty)))
        .collect();
    let want = [
        ("model", naga::Scalar::U32),
        ("cos_i", naga::Scalar::F32),
        ("cos_e", naga::Scalar::F32),
        ("cos_g", naga::Scalar::F32),
        ("albedo", naga::Scalar::F32),
    ];
    assert_eq!(args.len(), want.len());
    for ((name, s), (wn, ws)) in args.iter().zip(want) {
        assert_eq!((name.as_str(), *s), (wn, ws));
    }
    assert_eq!(scalar(f.result.as_ref().unwrap().ty), naga::Scalar::F32);
    let p = HapkeParams::MOON_643NM;
    for (name, v) in [
        ("HAPKE_W", p.w),
        ("HAPKE_B", p.b),
        ("HAPKE_C", p.c),
        ("HAPKE_BS0", p.bs0),
        ("HAPKE_HS", p.hs),
        ("HAPKE_TAN_THETA", p.theta_bar_deg.to_radians().tan()),
    ] {
        let line = src
            .lines()
            .find(|l| l.starts_with(&format!("const {name}: f32 = ")))
            .unwrap_or_else(|| panic!("const {name}"));
        let got: f64 = line
            .split('=')
            .nth(1)
            .unwrap()
            .trim()
            .trim_end_matches(';')
            .parse()
            .unwrap();
        assert!((got - v).abs() < 1e-5, "{name}: wgsl {got} vs rust {v}");
    }
}

/// Arguments of an orbital view of the synthetic terrain (camera 30 km above the sphere over
/// -89.5 deg, looking at -89.6 deg, 0 E) at a lit epoch (Sun +0.93 deg at -89.6, 0).
fn orbit_args<'a>(out: &'a str, k: &'a str) -> Vec<&'a str> {
    vec![
        "render",
        "--synthetic",
        "--camera",
        "orbit",
        "--lat-deg",
        "-89.3",
        "--lon-deg",
        "0",
        "--altitude-km",
        "30",
        "--target-lat-deg",
        "-89.6",
        "--target-lon-deg",
        "0",
        "--fov-deg",
        "40",
        "--utc",
        "2027-01-20T00:00",
        "--width",
        "48",
        "--height",
        "32",
        "--out",
        out,
        "--kernels",
        k,
    ]
}

/// The orbital camera sees lit terrain around its target: the centre pixel is terrain (not sky)
/// and many pixels are lit.
#[test]
fn cli_orbit_camera_sees_the_target() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let out = penumbra(dir.path(), &orbit_args("o.png", k.to_str().unwrap()));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(dir.path().join("o.png")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (48, 32));
    let grey = |p: &image::Rgb<u8>| p[0] == p[1] && p[1] == p[2];
    let lit = img.pixels().filter(|p| grey(p) && p[0] > 20).count();
    eprintln!("orbit view: {lit} of {} pixels are lit terrain", 48 * 32);
    assert!(lit > 48 * 32 / 4, "only {lit} lit pixels");
}

/// Bad orbit input: a camera below the terrain, a missing altitude, fov 0 -> exit 2, one line,
/// no file.
#[test]
fn cli_orbit_bad_inputs_exit_2_without_file() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let ks = k.to_str().unwrap().to_string();
    for (flag, value, needle) in [
        ("--altitude-km", "-8", "inside the terrain"),
        ("--fov-deg", "0", "fov"),
        ("--fov-deg", "180", "fov"),
        ("--width", "0", "image size"),
    ] {
        let mut args = orbit_args("bad.png", &ks);
        let i = args.iter().position(|a| *a == flag).unwrap();
        args[i + 1] = value;
        let out = penumbra(dir.path(), &args);
        assert_clean_error(&out, needle);
        assert!(
            files_in(dir.path()).is_empty(),
            "{flag} {value}: files left"
        );
    }
    let mut args = orbit_args("bad.png", &ks);
    let i = args.iter().position(|a| *a == "--altitude-km").unwrap();
    args.drain(i..i + 2);
    assert_clean_error(&penumbra(dir.path(), &args), "--altitude-km");
    assert!(files_in(dir.path()).is_empty());
}

/// `--start/--stop/--step` writes numbered frames with their own epochs, and `--out-radiance`
/// writes numbered 32-bit float TIFFs whose values decode back to a radiance image consistent
/// with the PNG: sky pixels (black) have radiance 0 and lit pixels radiance > 0.
#[test]
fn cli_epoch_range_writes_numbered_frames_and_radiance() {
    let dir = tempfile::tempdir().unwrap();
    let k = kernels_dir();
    let mut args = orbit_args("seq.png", k.to_str().unwrap());
    let i = args.iter().position(|a| *a == "--utc").unwrap();
    args.splice(
        i..i + 2,
        [
            "--start",
            "2027-01-20T00:00",
            "--stop",
            "2027-01-20T12:00",
            "--step",
            "6h",
            "--out-radiance",
            "rad.tif",
        ],
    );
    let out = penumbra(dir.path(), &args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut names = files_in(dir.path());
    names.sort();
    assert_eq!(
        names,
        [
            "rad_0000.tif",
            "rad_0001.tif",
            "rad_0002.tif",
            "seq.run.json",
            "seq_0000.png",
            "seq_0001.png",
            "seq_0002.png"
        ]
    );
    // The provenance lists exactly the files written, and the epochs.
    let prov: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("seq.run.json")).unwrap()).unwrap();
    let mut listed: Vec<String> = prov["outputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    listed.sort();
    let mut written = names.clone();
    written.retain(|n| n != "seq.run.json");
    assert_eq!(listed, written);
    assert_eq!(prov["epoch_count"], 3);
    assert_eq!(prov["epoch_start_utc"], "2027-01-20T00:00:00Z");
    for (k, want_utc) in [
        "2027-01-20T00:00:00Z",
        "2027-01-20T06:00:00Z",
        "2027-01-20T12:00:00Z",
    ]
    .iter()
    .enumerate()
    {
        let bytes = std::fs::read(dir.path().join(format!("seq_{k:04}.png"))).unwrap();
        let utc = crate::util::png_text(&bytes, "penumbra:epoch_utc");
        assert_eq!(utc.as_deref(), Some(*want_utc));
        let rgb = image::load_from_memory(&bytes).unwrap().to_rgb8();
        let mut dec = tiff::decoder::Decoder::new(
            std::fs::File::open(dir.path().join(format!("rad_{k:04}.tif"))).unwrap(),
        )
        .unwrap();
        assert_eq!(dec.dimensions().unwrap(), (48, 32));
        let tiff::decoder::DecodingResult::F32(rad) = dec.read_image().unwrap() else {
            panic!("not f32")
        };
        let max_l = rad.iter().copied().fold(0.0_f32, f32::max);
        let mut lit = 0;
        for (p, l) in rgb.pixels().zip(&rad) {
            if p[0] == p[1] && p[1] == p[2] && p[0] > 20 {
                assert!(*l > 0.0);
                lit += 1;
            }
            if p.0 == [0, 0, 0] {
                assert!(
                    l.is_nan() || *l < 0.01 * max_l,
                    "black pixel with radiance {l} (max {max_l})"
                );
            }
        }
        assert!(lit > 100, "frame {k}: {lit} lit pixels");
        // Sky is nodata (NaN), declared; the unit and the frame's epoch are in the metadata.
        let md = dec
            .get_tag_ascii_string(tiff::tags::Tag::Unknown(42112))
            .unwrap();
        assert!(md.contains("W m-2 sr-1") && md.contains(want_utc), "{md}");
        assert_eq!(
            dec.get_tag_ascii_string(tiff::tags::Tag::Unknown(42113))
                .unwrap(),
            "nan"
        );
    }
}

/// The float radiance TIFF holds exactly the in-memory radiance of a rendered frame (the golden
/// scene: values vary, some pixels are shadowed or sky).
#[test]
fn radiance_tiff_round_trips_the_frame() {
    let (w, h) = (32, 24);
    let rad = golden_scene_radiance();
    let bytes = penumbra::render::encode_f32_tiff(&rad, w, h, &[("k", "v")]).unwrap();
    let mut dec = tiff::decoder::Decoder::new(std::io::Cursor::new(bytes)).unwrap();
    assert_eq!(dec.dimensions().unwrap(), (w, h));
    let tiff::decoder::DecodingResult::F32(back) = dec.read_image().unwrap() else {
        panic!("not f32")
    };
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&back), bits(&rad));
    let lit = rad.iter().filter(|l| **l > 0.0).count();
    let sky = rad.iter().filter(|l| l.is_nan()).count();
    eprintln!(
        "radiance TIFF: {lit} of {} pixels > 0, {sky} sky (NaN)",
        rad.len()
    );
    assert!(lit > 0 && lit < rad.len() && sky > 10);
}

/// The synthetic scene of the golden image: a 64 x 64 grid of 10 m cells with sine hills of
/// +-20 m, Sun at 8 deg elevation from azimuth ~37 deg, Earth at 8 deg from the south, Hapke
/// BRDF; a 32 x 24 view from (-300, -300, 150) m looking north-east 15 deg down.
fn golden_scene_radiance() -> Vec<f32> {
    use nalgebra::{Matrix3, Vector3};
    use penumbra::render::{Camera, Lights, Scene, radiance_image};
    let mut hf = penumbra::terrain::HeightField::flat(64, 64, 10.0);
    for row in 0..64 {
        for col in 0..64 {
            hf.z_m[row * 64 + col] =
                (20.0 * (row as f64 / 7.0).sin() * (col as f64 / 5.0).cos()) as f32;
        }
    }
    let el = 8.0_f64.to_radians();
    let lights = Lights {
        sun: [el.cos() * 0.6, el.cos() * 0.8, el.sin()],
        sun_radius_rad: 0.267_f64.to_radians(),
        earth: [0.0, -el.cos(), el.sin()],
        earth_radius_rad: 0.95_f64.to_radians(),
    };
    let scene = Scene::new(&hf, lights, penumbra::shadow::Engine::Combined)
        .unwrap()
        .with_brdf(Brdf::default());
    let cam = Camera::from_az_el_deg(
        Vector3::new(-300.0, -300.0, 150.0),
        &Matrix3::identity(),
        45.0,
        -15.0,
        60.0,
    )
    .unwrap();
    radiance_image(&scene.render(&cam, 32, 24).unwrap())
}

/// Golden image: the radiance of [`golden_scene_radiance`] against the committed
/// `tests/fixtures/render_golden_32x24.tif` (float radiance, W m^-2 sr^-1): max |diff| <= 1e-3
/// W m^-2 sr^-1 (f32 rounding and libm differences only) and mean |diff| <= 1e-5.
/// `PENUMBRA_BLESS=1` rewrites the fixture.
#[test]
fn golden_image_matches() {
    let path = crate::util::fixture("render_golden_32x24.tif");
    let rad = golden_scene_radiance();
    if std::env::var_os("PENUMBRA_BLESS").is_some() {
        let bytes = penumbra::render::encode_f32_tiff(&rad, 32, 24, &[]).unwrap();
        std::fs::write(&path, bytes).unwrap();
        eprintln!("blessed {}", path.display());
        return;
    }
    let mut dec = tiff::decoder::Decoder::new(std::fs::File::open(&path).unwrap()).unwrap();
    assert_eq!(dec.dimensions().unwrap(), (32, 24));
    let tiff::decoder::DecodingResult::F32(want) = dec.read_image().unwrap() else {
        panic!("not f32")
    };
    let diffs: Vec<f64> = rad
        .iter()
        .zip(&want)
        .map(|(a, b)| {
            // Sky is NaN now; the fixture (written before) holds 0 there.
            if a.is_nan() {
                assert_eq!(*b, 0.0, "sky where the golden image has terrain");
                0.0
            } else {
                f64::from((a - b).abs())
            }
        })
        .collect();
    let max = diffs.iter().copied().fold(0.0, f64::max);
    let mean = diffs.iter().sum::<f64>() / diffs.len() as f64;
    eprintln!("golden image: max |diff| {max:.2e}, mean {mean:.2e} W m^-2 sr^-1");
    assert!(max <= 1e-3 && mean <= 1e-5, "max {max} mean {mean}");
    // The golden image is not trivial: lit terrain, shadowed terrain and sky.
    assert!(want.iter().any(|l| *l > 1.0));
    assert!(want.iter().filter(|l| **l == 0.0).count() > 10);
}

/// Earthshine: `Lights::earth_irradiance_w_m2` against a direct integration of the light of a
/// Lambert sphere (albedo = Bond albedo 0.306, lit by the solar constant) over the Earth's
/// surface, seen from the Moon at 384,400 km, for elongations 180 (full Earth), 120, 90 and
/// 30 deg. The formula `p S (R/d)^2 Phi(alpha)` is the far-field limit; at d = 60 R the nearer
/// half of the lit disc is up to 2 R/d closer, which the direct sum sees (measured +1.2 % at
/// full Earth; for a thin crescent, where part of the lit limb is hidden at finite distance,
/// +11 % of a tiny value, 1.1e-4 W/m^2 at 30 deg), so the bound is 3 % of the value or 0.2 % of
/// the full-Earth irradiance, whichever is larger (integration grid 600 x 1200).
#[test]
fn earthshine_matches_an_integrated_lambert_sphere() {
    use penumbra::render::{EARTH_BOND_ALBEDO, Lights};
    let (r_km, d_km) = (6378.1366_f64, 384_400.0_f64);
    let s = penumbra::SOLAR_CONSTANT_W_M2;
    let earth = [1.0, 0.0, 0.0];
    for elong_deg in [180.0_f64, 120.0, 90.0, 30.0] {
        let el = elong_deg.to_radians();
        let sun = [el.cos(), el.sin(), 0.0];
        let lights = Lights {
            sun,
            sun_radius_rad: 0.00465,
            earth,
            earth_radius_rad: (r_km / d_km).asin(),
        };
        let got = lights.earth_irradiance_w_m2();
        // Oracle: sum over surface elements of the Earth (centre at d * earth).
        let (nt, np) = (600, 1200);
        let mut e = 0.0;
        for it in 0..nt {
            let th = (it as f64 + 0.5) / nt as f64 * PI;
            for ip in 0..np {
                let ph = (ip as f64 + 0.5) / np as f64 * 2.0 * PI;
                let n = [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()];
                let cos_sun = n[0] * sun[0] + n[1] * sun[1] + n[2] * sun[2];
                if cos_sun <= 0.0 {
                    continue;
                }
                let p = [d_km + r_km * n[0], r_km * n[1], r_km * n[2]];
                let dist = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                let to_moon = [-p[0] / dist, -p[1] / dist, -p[2] / dist];
                let cos_obs = n[0] * to_moon[0] + n[1] * to_moon[1] + n[2] * to_moon[2];
                if cos_obs <= 0.0 {
                    continue;
                }
                let radiance = EARTH_BOND_ALBEDO * s * cos_sun / PI;
                let d_area = r_km * r_km * th.sin() * (PI / nt as f64) * (2.0 * PI / np as f64);
                // Irradiance on a surface facing the Earth: cos of arrival ~ -to_moon . earth.
                e += radiance * cos_obs * d_area / (dist * dist) * (-to_moon[0]);
            }
        }
        eprintln!("elongation {elong_deg} deg: earthshine {got:.5} W/m^2, integrated {e:.5}");
        let bound = (0.03 * e).max(0.002 * penumbra::render::FULL_EARTH_IRRADIANCE_W_M2);
        assert!((got - e).abs() <= bound, "{got} vs {e}");
    }
}

/// `[[render.views]]` in a scenario renders through `penumbra render`: a site view (one frame)
/// and an orbital sequence (numbered frames) land in `<output_dir>/render/` with the epochs in
/// their metadata; an unknown view key is an error naming the key, with no render output.
#[test]
fn scenario_render_views() {
    let dir = tempfile::tempdir().unwrap();
    let views = r#"
[[render.views]]
out = "site.png"
lat_deg = -89.6
lon_deg = 0.0
height_m = 10.0
look_az_deg = 20.0
look_el_deg = -2.0
utc = "2027-01-20T00:00:00"
width = 24
height = 16

[[render.views]]
out = "seq.png"
camera = "orbit"
lat_deg = -89.6
lon_deg = 0.0
altitude_km = 20.0
fov_deg = 30.0
start = "2027-01-20T00:00:00"
stop = "2027-01-20T06:00:00"
step = "6h"
width = 16
height = 12
"#;
    let rdir =
        crate::util::run_scenario_ok(dir.path(), &render_scenario("r", "2027-01-20T02:00", views))
            .join("render");
    assert_eq!(
        files_in(&rdir),
        ["seq_0000.png", "seq_0001.png", "site.png"]
    );
    let img = image::open(rdir.join("site.png")).unwrap();
    assert_eq!((img.width(), img.height()), (24, 16));
    let bytes = std::fs::read(rdir.join("seq_0001.png")).unwrap();
    let utc = crate::util::png_text(&bytes, "penumbra:epoch_utc");
    assert_eq!(utc.as_deref(), Some("2027-01-20T06:00:00Z"));

    let dir = tempfile::tempdir().unwrap();
    let bad = "[[render.views]]\nout = \"x.png\"\nlat_deg = -89.6\nlon_deg = 0.0\nfrobnicate = 1\nutc = \"2027-01-20\"\n";
    std::fs::write(
        dir.path().join("s.toml"),
        render_scenario("r", "2027-01-20T02:00", bad),
    )
    .unwrap();
    let out = penumbra(dir.path(), &["run", "s.toml"]);
    assert_clean_error(&out, "frobnicate");
    assert!(!dir.path().join("res/render").exists());
}

/// Reads a rendered sequence's frame `k`: the PNG's grey levels, its exposure metadata and the
/// radiance TIFF.
fn frame_levels_and_radiance(
    dir: &std::path::Path,
    k: usize,
) -> (Vec<u8>, String, String, Vec<f32>) {
    let bytes = std::fs::read(dir.join(format!("seq_{k:04}.png"))).unwrap();
    let exposure = crate::util::png_text(&bytes, "penumbra:exposure").unwrap();
    let mode = crate::util::png_text(&bytes, "penumbra:exposure_mode").unwrap();
    let grey: Vec<u8> = image::load_from_memory(&bytes)
        .unwrap()
        .to_rgb8()
        .pixels()
        .map(|p| p[0])
        .collect();
    let mut dec = tiff::decoder::Decoder::new(
        std::fs::File::open(dir.join(format!("rad_{k:04}.tif"))).unwrap(),
    )
    .unwrap();
    let tiff::decoder::DecodingResult::F32(rad) = dec.read_image().unwrap() else {
        panic!("not f32")
    };
    (grey, exposure, mode, rad)
}

/// Frames of a sequence share one exposure by default (`--exposure sequence`): every frame's
/// terrain pixel has grey level `srgb(tone_curve(e · L))` of its own radiance with the same `e`
/// (no flicker), recomputed here from the radiance TIFF with the documented formula, and `e`
/// puts the brightest frame's 99th-percentile radiance near `x = 1.4` (within the 10 % a
/// quarter-size pre-render allows). `--exposure auto` gives each frame exactly `1.4 / p99` of its
/// own radiance. Earthshine-only radiance stays black by default (the exposure is never brighter
/// than for level ground under a 1° Sun) and looks lit at `auto`. The tone curve keeps lit
/// terrain's shading: on the demo's ridge view (the issue's scene: lit terrain at levels 178–205)
/// the 5th–95th percentile spread of lit terrain levels is ≥ 1.4× the old Reinhard curve's at the
/// old automatic exposure (99th percentile → x = 2).
#[test]
fn sequences_have_one_exposure_and_shading_survives_the_tone_curve() {
    use penumbra::render::{
        AUTO_EXPOSED_P99, DAYLIGHT_FLOOR_RADIANCE_W_M2_SR, Exposure, Sample, srgb_level,
        tone_curve, tone_map,
    };
    let k = kernels_dir();
    let p99 = |rad: &[f32]| {
        let mut lit: Vec<f64> = rad
            .iter()
            .filter(|l| l.is_finite() && **l > 0.0)
            .map(|l| f64::from(*l))
            .collect();
        lit.sort_by(f64::total_cmp);
        lit[((lit.len() - 1) as f64 * 0.99).round() as usize]
    };
    let run = |extra: &[&str]| {
        let dir = tempfile::tempdir().unwrap();
        let mut args = orbit_args("seq.png", k.to_str().unwrap());
        let i = args.iter().position(|a| *a == "--utc").unwrap();
        args.splice(
            i..i + 2,
            [
                "--start",
                "2027-01-20T00:00",
                "--stop",
                "2027-01-21T00:00",
                "--step",
                "12h",
                "--out-radiance",
                "rad.tif",
            ],
        );
        args.extend_from_slice(extra);
        let out = penumbra(dir.path(), &args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        dir
    };
    let seq = run(&[]);
    let frames: Vec<_> = (0..3)
        .map(|k| frame_levels_and_radiance(seq.path(), k))
        .collect();
    let e: f64 = frames[0].1.parse().unwrap();
    let brightest = frames.iter().map(|f| p99(&f.3)).fold(0.0, f64::max);
    let want = AUTO_EXPOSED_P99 / brightest.max(DAYLIGHT_FLOOR_RADIANCE_W_M2_SR);
    assert!(
        (e / want - 1.0).abs() < 0.1,
        "exposure {e}, full-size frames say {want}"
    );
    for (k, (grey, exposure, mode, rad)) in frames.iter().enumerate() {
        assert_eq!(mode, "sequence");
        assert_eq!(
            *exposure, frames[0].1,
            "frame {k}: one exposure per sequence"
        );
        for (g, l) in grey.iter().zip(rad) {
            if l.is_finite() {
                let want = srgb_level(tone_curve(e * f64::from(*l)));
                assert!(
                    (i32::from(*g) - i32::from(want)).abs() <= 1,
                    "frame {k}: radiance {l} gives level {g}, the curve says {want}"
                );
            }
        }
    }
    // Per-frame automatic exposure: each frame its own value.
    let auto = run(&["--exposure", "auto"]);
    for k in 0..3 {
        let (_, exposure, mode, rad) = frame_levels_and_radiance(auto.path(), k);
        assert_eq!(mode, "auto");
        assert_eq!(exposure, format!("{:.6e}", AUTO_EXPOSED_P99 / p99(&rad)));
    }

    // Shading on the demo's ridge view, one frame.
    let dir = tempfile::tempdir().unwrap();
    let out = penumbra(
        dir.path(),
        &[
            "render",
            "--synthetic",
            "--camera",
            "site",
            "--lat-deg",
            "-89.6",
            "--lon-deg",
            "0",
            "--height-m",
            "10",
            "--look-az-deg",
            "20",
            "--look-el-deg",
            "-2",
            "--fov-deg",
            "60",
            "--utc",
            "2027-01-20T00:00:00",
            "--width",
            "160",
            "--height-px",
            "100",
            "--out",
            "v.png",
            "--out-radiance",
            "v.tif",
            "--kernels",
            k.to_str().unwrap(),
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut dec =
        tiff::decoder::Decoder::new(std::fs::File::open(dir.path().join("v.tif")).unwrap())
            .unwrap();
    let tiff::decoder::DecodingResult::F32(rad) = dec.read_image().unwrap() else {
        panic!("not f32")
    };
    let grey: Vec<u8> = image::open(dir.path().join("v.png"))
        .unwrap()
        .to_rgb8()
        .pixels()
        .map(|p| p[0])
        .collect();
    let top = p99(&rad);
    let (mut new, mut old) = (Vec::new(), Vec::new());
    for (g, l) in grey.iter().zip(&rad) {
        if l.is_finite() && *l > 0.0 {
            new.push(f64::from(*g));
            let x = 2.0 / top * f64::from(*l);
            old.push(f64::from(srgb_level(x / (1.0 + x))));
        }
    }
    let spread = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
        (q(0.05), q(0.95))
    };
    let (n5, n95) = spread(&mut new);
    let (o5, o95) = spread(&mut old);
    eprintln!(
        "ridge view, lit terrain levels p5..p95: {n5}..{n95} now, {o5}..{o95} with the old curve"
    );
    assert!(n95 - n5 >= 1.4 * (o95 - o5), "{n5}..{n95} vs {o5}..{o95}");

    // Earthshine only (1.7e-6 W m-2 sr-1): black by default, lit at auto.
    let night = [Sample::Terrain {
        radiance_w_m2_sr: 1.7e-6,
    }];
    assert_eq!(tone_map(&night, Exposure::Sequence.value(&night))[0], 0);
    assert!(tone_map(&night, Exposure::Auto.value(&night))[0] > 200);
    // Flags and scenario values: sequence, auto, a number; anything else refused.
    assert_eq!("Sequence".parse::<Exposure>(), Ok(Exposure::Sequence));
    assert_eq!("0.5".parse::<Exposure>(), Ok(Exposure::Fixed(0.5)));
    for bad in ["0", "-1", "nan", "inf", "bright"] {
        assert!(bad.parse::<Exposure>().is_err(), "{bad}");
    }
}
