//! Camera paths (`render::path`, scenario `[[render.paths]]`): pose interpolation against
//! hand-computed values, a path run's frames and their PNG epochs, bad keyframes.

use hifitime::{Duration, Epoch};
use penumbra::render::path::{CameraPose, FrameSampling, Keyframe, lerp_angle_deg, path_frames};

use crate::util::{assert_clean_error, files_in, penumbra, png_text, render_scenario};

fn utc(text: &str) -> Epoch {
    penumbra::ephem::time::parse_utc(text).unwrap()
}

fn site(lat: f64, lon: f64, h: f64, az: f64, el: f64, fov: f64) -> CameraPose {
    CameraPose::Site {
        lat_deg: lat,
        lon_deg: lon,
        height_m: h,
        look_az_deg: az,
        look_el_deg: el,
        fov_deg: fov,
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9
}

/// Angles go the short way round: 350 -> 10 passes 0 (not 180), 10 -> 350 likewise backwards,
/// 170 -> -170 passes 180. Values worked by hand.
#[test]
fn angles_interpolate_the_short_way() {
    assert!(close(lerp_angle_deg(350.0, 10.0, 0.5), 360.0));
    assert!(close(lerp_angle_deg(350.0, 10.0, 0.25), 355.0));
    assert!(close(lerp_angle_deg(10.0, 350.0, 0.75), -5.0));
    assert!(close(lerp_angle_deg(170.0, -170.0, 0.5), 180.0));
    assert!(close(lerp_angle_deg(20.0, 100.0, 0.5), 60.0));
    assert!(
        close(lerp_angle_deg(0.0, 180.0, 1.0), 180.0)
            || close(lerp_angle_deg(0.0, 180.0, 1.0), -180.0)
    );
}

/// Three site keyframes at 00:00, 04:00 and 06:00; frames every hour. At 01:00 (t = 1/4 of the
/// first segment): lat -89.6 + 0.2/4 = -89.55, lon 350 + 20/4 = 355, height 100 - 80/4 = 80,
/// az 350 + 40/4 = 360, el -10 + 8/4 = -8, fov 60 - 20/4 = 55. At 05:00 (midpoint of the second
/// segment): lat (-89.4 - 89.0)/2 = -89.2, lon 10 + (-30)/2 = -5, height 25, az 30 + (-60)/2 =
/// 0, el -1, fov 45.
#[test]
fn poses_match_hand_computed_midpoints() {
    let kf = [
        Keyframe {
            epoch: utc("2027-01-20T00:00:00"),
            pose: site(-89.6, 350.0, 100.0, 350.0, -10.0, 60.0),
        },
        Keyframe {
            epoch: utc("2027-01-20T04:00:00"),
            pose: site(-89.4, 10.0, 20.0, 30.0, -2.0, 40.0),
        },
        Keyframe {
            epoch: utc("2027-01-20T06:00:00"),
            pose: site(-89.0, -20.0, 30.0, 330.0, 0.0, 50.0),
        },
    ];
    let frames = path_frames(&kf, FrameSampling::Step(Duration::from_seconds(3600.0))).unwrap();
    assert_eq!(frames.len(), 7);
    for (k, (e, _)) in frames.iter().enumerate() {
        assert_eq!(
            *e,
            utc("2027-01-20T00:00:00") + Duration::from_seconds(3600.0 * k as f64)
        );
    }
    let want_1h = [-89.55, 355.0, 80.0, 360.0, -8.0, 55.0];
    let want_5h = [-89.2, -5.0, 25.0, 0.0, -1.0, 45.0];
    for (k, want) in [(1, want_1h), (5, want_5h)] {
        let CameraPose::Site {
            lat_deg,
            lon_deg,
            height_m,
            look_az_deg,
            look_el_deg,
            fov_deg,
        } = frames[k].1
        else {
            panic!("site pose expected")
        };
        let got = [
            lat_deg,
            lon_deg,
            height_m,
            look_az_deg,
            look_el_deg,
            fov_deg,
        ];
        for (g, w) in got.iter().zip(want) {
            assert!(close(*g, w), "frame {k}: got {got:?}, want {want:?}");
        }
    }
    // The keyframes themselves are reproduced exactly.
    assert_eq!(frames[0].1, kf[0].pose);
    assert_eq!(frames[4].1, kf[1].pose);
    assert_eq!(frames[6].1, kf[2].pose);
    // A count of 4 over 6 h: every 2 h.
    let four = path_frames(&kf, FrameSampling::Count(4)).unwrap();
    let hours: Vec<f64> = four
        .iter()
        .map(|(e, _)| (*e - kf[0].epoch).to_seconds() / 3600.0)
        .collect();
    assert_eq!(hours, [0.0, 2.0, 4.0, 6.0]);
}

/// An orbit path's midpoint: lon 170 -> -170 meets at 180, target lon 350 -> 10 at 360,
/// altitude (30 + 5) / 2 = 17.5 km. Mixed camera kinds are refused.
#[test]
fn orbit_midpoint_and_mixed_kinds() {
    let a = CameraPose::Orbit {
        lat_deg: -89.0,
        lon_deg: 170.0,
        altitude_km: 30.0,
        target_lat_deg: -89.6,
        target_lon_deg: 350.0,
        fov_deg: 40.0,
    };
    let b = CameraPose::Orbit {
        lat_deg: -89.5,
        lon_deg: -170.0,
        altitude_km: 5.0,
        target_lat_deg: -89.8,
        target_lon_deg: 10.0,
        fov_deg: 50.0,
    };
    let CameraPose::Orbit {
        lat_deg,
        lon_deg,
        altitude_km,
        target_lat_deg,
        target_lon_deg,
        fov_deg,
    } = a.lerp(&b, 0.5).unwrap()
    else {
        panic!("orbit pose expected")
    };
    let got = [
        lat_deg,
        lon_deg,
        altitude_km,
        target_lat_deg,
        target_lon_deg,
        fov_deg,
    ];
    let want = [-89.25, 180.0, 17.5, -89.7, 360.0, 45.0];
    for (g, w) in got.iter().zip(want) {
        assert!(close(*g, w), "got {got:?}, want {want:?}");
    }
    let s = site(-89.6, 0.0, 10.0, 0.0, 0.0, 60.0);
    assert!(a.lerp(&s, 0.5).is_err());
}

/// A 3-frame site path (keyframes 00:00 and 02:00, height 10 -> 30 m, az 340 -> 20) writes
/// 3 numbered PNGs whose epochs are 00:00, 01:00, 02:00 and whose camera metadata carries the
/// interpolated pose (height 20 m, az 360 at the middle frame).
#[test]
fn scenario_path_writes_interpolated_frames() {
    let dir = tempfile::tempdir().unwrap();
    let paths = r#"
[[render.paths]]
out = "walk.png"
frames = 3
width = 16
height = 12
keyframes = [
  { utc = "2027-01-20T00:00:00", lat_deg = -89.6, lon_deg = 0.0, height_m = 10.0, look_az_deg = 340.0, look_el_deg = -2.0 },
  { utc = "2027-01-20T02:00:00", lat_deg = -89.6, lon_deg = 0.0, height_m = 30.0, look_az_deg = 20.0, look_el_deg = -2.0 },
]
"#;
    let rdir =
        crate::util::run_scenario_ok(dir.path(), &render_scenario("p", "2027-01-20T01:00", paths))
            .join("render");
    assert_eq!(
        files_in(&rdir),
        ["walk_0000.png", "walk_0001.png", "walk_0002.png"]
    );
    for (k, want) in [
        "2027-01-20T00:00:00Z",
        "2027-01-20T01:00:00Z",
        "2027-01-20T02:00:00Z",
    ]
    .iter()
    .enumerate()
    {
        let f = rdir.join(format!("walk_{k:04}.png"));
        assert_eq!(
            png_text(&std::fs::read(&f).unwrap(), "penumbra:epoch_utc").as_deref(),
            Some(*want)
        );
        let img = image::open(&f).unwrap();
        assert_eq!((img.width(), img.height()), (16, 12));
    }
    let cam = png_text(
        &std::fs::read(rdir.join("walk_0001.png")).unwrap(),
        "penumbra:camera",
    )
    .unwrap();
    assert!(cam.contains("height_m=20 "), "{cam}");
    assert!(cam.contains("look_az_deg=360 "), "{cam}");
}

/// Bad paths fail before anything runs: one error line, exit 2, no output folder at all.
#[test]
fn bad_keyframes_are_clean_errors_without_files() {
    let k = |t: &str| format!("{{ utc = \"{t}\", lat_deg = -89.6, lon_deg = 0.0 }}");
    let cases = [
        (
            format!(
                "[[render.paths]]\nout = \"x.png\"\nframes = 2\nkeyframes = [{}, {}]\n",
                k("2027-01-20T02:00:00"),
                k("2027-01-20T02:00:00")
            ),
            "keyframe times must increase",
        ),
        (
            format!(
                "[[render.paths]]\nout = \"x.png\"\nframes = 2\nkeyframes = [{}, {}]\n",
                k("2027-01-20T02:00:00"),
                k("2027-01-20T01:00:00")
            ),
            "keyframe times must increase",
        ),
        (
            format!(
                "[[render.paths]]\nout = \"x.png\"\nframes = 2\nkeyframes = [{}]\n",
                k("2027-01-20T02:00:00")
            ),
            "at least 2 keyframes",
        ),
        (
            format!(
                "[[render.paths]]\nout = \"x.png\"\nframes = 2\nkeyframes = [{}, {{ utc = \"2027-01-21\", lat_deg = -89.6, lon_deg = 0.0, zoom = 2 }}]\n",
                k("2027-01-20T02:00:00")
            ),
            "zoom",
        ),
        (
            format!(
                "[[render.paths]]\nout = \"x.png\"\nframes = 2\nspeed = 1\nkeyframes = [{}, {}]\n",
                k("2027-01-20T01:00:00"),
                k("2027-01-20T02:00:00")
            ),
            "speed",
        ),
        (
            format!(
                "[[render.paths]]\nout = \"x.png\"\nkeyframes = [{}, {}]\n",
                k("2027-01-20T01:00:00"),
                k("2027-01-20T02:00:00")
            ),
            "frames = N or step",
        ),
    ];
    for (paths, needle) in cases {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("s.toml"),
            render_scenario("p", "2027-01-20T01:00", &paths),
        )
        .unwrap();
        let out = penumbra(dir.path(), &["run", "s.toml"]);
        assert_clean_error(&out, needle);
        assert!(!dir.path().join("res").exists(), "{needle}: files written");
    }
}
