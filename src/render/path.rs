//! Camera paths (e.g. a descent trajectory as keyframes): a list of keyframes, each an epoch
//! and a camera pose, sampled into frames. Between two keyframes every pose parameter is
//! interpolated linearly in time; the angles that wrap (look azimuth, longitudes) go the short
//! way round, so a pose at 350 deg and one at 10 deg meet at 0 deg, not 180 deg. The frames are
//! rendered by the same per-frame routine as `penumbra render`'s epoch ranges (see
//! `products::render::render_frames`).

use hifitime::{Duration, Epoch};

use super::{RenderError, Result};

/// The most frames one path may have.
pub const MAX_FRAMES: usize = 100_000;

/// A camera pose in the parameters of `penumbra render` (angles in degrees).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CameraPose {
    /// A camera at a site, `height_m` above the ground, looking at azimuth/elevation.
    Site {
        /// Latitude, degrees.
        lat_deg: f64,
        /// East longitude, degrees.
        lon_deg: f64,
        /// Height above the ground, metres.
        height_m: f64,
        /// View azimuth, degrees from north clockwise.
        look_az_deg: f64,
        /// View elevation, degrees.
        look_el_deg: f64,
        /// Horizontal field of view, degrees.
        fov_deg: f64,
    },
    /// A camera above the sphere looking at a target point on the ground.
    Orbit {
        /// Latitude, degrees.
        lat_deg: f64,
        /// East longitude, degrees.
        lon_deg: f64,
        /// Altitude above the 1737.4 km sphere, kilometres.
        altitude_km: f64,
        /// Target latitude, degrees.
        target_lat_deg: f64,
        /// Target east longitude, degrees.
        target_lon_deg: f64,
        /// Horizontal field of view, degrees.
        fov_deg: f64,
    },
}

/// One keyframe of a camera path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keyframe {
    /// The keyframe's epoch.
    pub epoch: Epoch,
    /// The camera pose at that epoch.
    pub pose: CameraPose,
}

/// How a path is sampled into frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FrameSampling {
    /// `n` >= 2 frames evenly spaced from the first to the last keyframe, both included
    /// (`n` = 1: the first keyframe only).
    Count(usize),
    /// Frames every `step` from the first keyframe up to the last (included when it falls on
    /// the step grid).
    Step(Duration),
}

/// Linear interpolation of the angle `a_deg` -> `b_deg` the short way round, at `t` in [0, 1]:
/// `a + t * d` with `d` the difference wrapped into [-180, 180); exactly `b_deg` at `t` = 1
/// (not `a + d`, which may differ from `b_deg` by 360).
pub fn lerp_angle_deg(a_deg: f64, b_deg: f64, t: f64) -> f64 {
    if t >= 1.0 {
        return b_deg;
    }
    let d = (b_deg - a_deg + 180.0).rem_euclid(360.0) - 180.0;
    a_deg + t * d
}

fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + t * (b - a)
}

impl CameraPose {
    /// The pose a fraction `t` in [0, 1] of the way from `self` to `other` (same camera kind).
    pub fn lerp(&self, other: &CameraPose, t: f64) -> Result<CameraPose> {
        use CameraPose::{Orbit, Site};
        match (*self, *other) {
            (
                Site {
                    lat_deg: la,
                    lon_deg: lo,
                    height_m: h,
                    look_az_deg: az,
                    look_el_deg: el,
                    fov_deg: f,
                },
                Site {
                    lat_deg: la2,
                    lon_deg: lo2,
                    height_m: h2,
                    look_az_deg: az2,
                    look_el_deg: el2,
                    fov_deg: f2,
                },
            ) => Ok(Site {
                lat_deg: lerp(la, la2, t),
                lon_deg: lerp_angle_deg(lo, lo2, t),
                height_m: lerp(h, h2, t),
                look_az_deg: lerp_angle_deg(az, az2, t),
                look_el_deg: lerp(el, el2, t),
                fov_deg: lerp(f, f2, t),
            }),
            (
                Orbit {
                    lat_deg: la,
                    lon_deg: lo,
                    altitude_km: h,
                    target_lat_deg: tla,
                    target_lon_deg: tlo,
                    fov_deg: f,
                },
                Orbit {
                    lat_deg: la2,
                    lon_deg: lo2,
                    altitude_km: h2,
                    target_lat_deg: tla2,
                    target_lon_deg: tlo2,
                    fov_deg: f2,
                },
            ) => Ok(Orbit {
                lat_deg: lerp(la, la2, t),
                lon_deg: lerp_angle_deg(lo, lo2, t),
                altitude_km: lerp(h, h2, t),
                target_lat_deg: lerp(tla, tla2, t),
                target_lon_deg: lerp_angle_deg(tlo, tlo2, t),
                fov_deg: lerp(f, f2, t),
            }),
            _ => Err(RenderError::BadPath(
                "all keyframes of a path must use the same camera kind".into(),
            )),
        }
    }
}

/// Checks a keyframe list: at least 2 keyframes, strictly increasing epochs, one camera kind.
fn check_keyframes(keyframes: &[Keyframe]) -> Result<()> {
    if keyframes.len() < 2 {
        return Err(RenderError::BadPath(format!(
            "a camera path needs at least 2 keyframes, got {}",
            keyframes.len()
        )));
    }
    for (k, w) in keyframes.windows(2).enumerate() {
        if w[1].epoch <= w[0].epoch {
            return Err(RenderError::BadPath(format!(
                "keyframe {} ({}) is not after keyframe {} ({}): keyframe times must increase",
                k + 1,
                crate::ephem::time::format_utc(w[1].epoch),
                k,
                crate::ephem::time::format_utc(w[0].epoch)
            )));
        }
        w[0].pose.lerp(&w[1].pose, 0.0)?;
    }
    Ok(())
}

/// The pose at `epoch` (clamped to the keyframes' span), interpolated linearly between the two
/// keyframes around it (a keyframe's own epoch gives its pose exactly).
fn pose_at(keyframes: &[Keyframe], epoch: Epoch) -> Result<CameraPose> {
    check_keyframes(keyframes)?;
    let k = keyframes
        .windows(2)
        .position(|w| epoch < w[1].epoch)
        .unwrap_or(keyframes.len() - 2);
    let (a, b) = (&keyframes[k], &keyframes[k + 1]);
    let t = ((epoch - a.epoch).to_seconds() / (b.epoch - a.epoch).to_seconds()).clamp(0.0, 1.0);
    a.pose.lerp(&b.pose, t)
}

/// The frames of a path: (epoch, pose) pairs sampled as `sampling` says.
pub fn path_frames(
    keyframes: &[Keyframe],
    sampling: FrameSampling,
) -> Result<Vec<(Epoch, CameraPose)>> {
    check_keyframes(keyframes)?;
    let first = keyframes[0].epoch;
    let last = keyframes[keyframes.len() - 1].epoch;
    let span_s = (last - first).to_seconds();
    let epochs: Vec<Epoch> = match sampling {
        FrameSampling::Count(0) => {
            return Err(RenderError::BadPath("frames must be >= 1".into()));
        }
        FrameSampling::Count(n) if n > MAX_FRAMES => {
            return Err(RenderError::BadPath(format!(
                "{n} frames: at most {MAX_FRAMES}"
            )));
        }
        FrameSampling::Count(1) => vec![first],
        FrameSampling::Count(n) => (0..n)
            .map(|i| first + Duration::from_seconds(span_s * i as f64 / (n - 1) as f64))
            .collect(),
        FrameSampling::Step(step) => {
            let step_s = step.to_seconds();
            if step_s.is_nan() || step_s <= 0.0 {
                return Err(RenderError::BadPath("the frame step must be > 0".into()));
            }
            let n = (span_s / step_s + 1e-9).floor() as usize + 1;
            if n > MAX_FRAMES {
                return Err(RenderError::BadPath(format!(
                    "{n} frames: the step is too small for the path's span"
                )));
            }
            (0..n).map(|i| first + step * i as f64).collect()
        }
    };
    epochs
        .into_iter()
        .map(|e| Ok((e, pose_at(keyframes, e)?)))
        .collect()
}
