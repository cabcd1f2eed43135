//! What a line samples: the per-step template on the finest layer, the coarser layers and
//! borders along the line, the refinement of concave pieces, and the integer lattice of lines.

use super::arc::LineGeometry;
use super::*;

/// One sample of the per-step template: parameter `f` in [0, 1) along the step and the bilinear
/// weights of up to four cells (flat offsets from the step's start pixel; a zero weight points at
/// the first cell, so that no read leaves the step's bounding box).
#[derive(Debug, Clone, Copy)]
pub(super) struct TemplateEntry {
    pub(super) f: f64,
    pub(super) off: [isize; 4],
    pub(super) w: [f64; 4],
    /// A crossing with a line through cell centres (else a piece midpoint).
    pub(super) crossing: bool,
}

/// The samples of one step `(d_row, d_col)` from a pixel centre, sorted: its crossings with the
/// lines through cell centres (integer rows and columns; the first is the pixel centre itself)
/// and the midpoint of every piece between two crossings (inside one bilinear patch), so that a
/// patch's height along the line is sampled at both ends and the middle as in the per-site scan.
pub(super) fn step_template(d_row: i64, d_col: i64, cols: i64) -> Vec<TemplateEntry> {
    let mut fs: Vec<f64> = vec![0.0];
    fs.extend((1..d_col.abs()).map(|j| j as f64 / d_col.abs() as f64));
    fs.extend((1..d_row.abs()).map(|j| j as f64 / d_row.abs() as f64));
    fs.sort_by(f64::total_cmp);
    fs.dedup();
    let mut all: Vec<(f64, bool)> = Vec::with_capacity(2 * fs.len());
    for (i, &f) in fs.iter().enumerate() {
        all.push((f, true));
        let next = fs.get(i + 1).copied().unwrap_or(1.0);
        all.push((0.5 * (f + next), false));
    }
    let flat = |r: i64, c: i64| (r * cols + c) as isize;
    all.into_iter()
        .map(|(f, crossing)| {
            let (row, col) = (f * d_row as f64, f * d_col as f64);
            // Snap crossings onto their grid line exactly.
            let snap = |v: f64| {
                if (v - v.round()).abs() < 1e-9 {
                    v.round()
                } else {
                    v
                }
            };
            let (row, col) = (snap(row), snap(col));
            let (r0, c0) = (row.floor(), col.floor());
            let (fr, fc) = (row - r0, col - c0);
            let (r0, c0) = (r0 as i64, c0 as i64);
            let base = flat(r0, c0);
            let w = [
                (1.0 - fr) * (1.0 - fc),
                (1.0 - fr) * fc,
                fr * (1.0 - fc),
                fr * fc,
            ];
            let cells = [
                base,
                flat(r0, c0 + 1),
                flat(r0 + 1, c0),
                flat(r0 + 1, c0 + 1),
            ];
            let off = std::array::from_fn(|k| if w[k] > 0.0 { cells[k] } else { base });
            TemplateEntry {
                f,
                off,
                w,
                crossing,
            }
        })
        .collect()
}

/// The t-range of the line inside `dem`'s outer cell edges (`−0.5 … n − 0.5` in rows and
/// columns), and the line's `(row, col) = (row_0 + t rb, col_0 + t cb)` in that grid.
pub(super) fn extent_range(dem: &Dem, geom: &LineGeometry) -> Option<((f64, f64), [f64; 4])> {
    let g = &dem.grid;
    let (x0, y0) = geom.point(0.0);
    let (row_0, col_0) = g.row_col_from_xy(x0, y0);
    let rb = -geom.ell.1 / g.px_y_m;
    let cb = geom.ell.0 / g.px_x_m;
    let (rows, cols) = (g.rows as f64, g.cols as f64);
    let mut lo = f64::NEG_INFINITY;
    let mut hi = f64::INFINITY;
    for (a, b, n) in [(row_0, rb, rows), (col_0, cb, cols)] {
        if b.abs() < 1e-15 {
            if a < -0.5 || a > n - 0.5 {
                return None;
            }
        } else {
            let (t1, t2) = ((-0.5 - a) / b, (n - 0.5 - a) / b);
            lo = lo.max(t1.min(t2));
            hi = hi.min(t1.max(t2));
        }
    }
    (lo <= hi).then_some(((lo, hi), [row_0, rb, col_0, cb]))
}

/// Where the observers of a line stand, for the tolerance of the samples outside their span.
#[derive(Debug, Clone, Copy)]
pub(super) struct ObserverSpan {
    /// The first and last observer's `t`, map metres.
    pub(super) t_m: (f64, f64),
    /// Pieces closer than this to an observer keep their midpoint whatever its rise: an end of
    /// the piece may lie within the half pixel an observer skips, and the chord that bounds
    /// what leaving the midpoint out costs is then not there (one pixel of the finest layer).
    pub(super) near_m: f64,
}

/// Pushes `(t, h)` samples of `dem` along the line for `t` in `[t_lo, t_hi]`: both ends, every
/// crossing with a line through cell centres, and inside every piece between them the samples
/// [`refine_piece`] asks for at the piece's distance from the line's observers, skipping `t`
/// inside a `covered` range (closed). `ts` is scratch space.
pub(super) fn push_segment_samples(
    dem: &Dem,
    line_in_grid: [f64; 4],
    (t_lo, t_hi): (f64, f64),
    observers: ObserverSpan,
    covered: &[(f64, f64)],
    ts: &mut Vec<f64>,
    out: &mut Vec<(f64, f64)>,
) {
    if t_hi <= t_lo {
        return;
    }
    let [row_0, rb, col_0, cb] = line_in_grid;
    let (rows, cols) = (dem.grid.rows as f64, dem.grid.cols as f64);
    ts.clear();
    ts.extend([t_lo, t_hi]);
    for (a, b, n) in [(row_0, rb, rows), (col_0, cb, cols)] {
        if b.abs() < 1e-15 {
            continue;
        }
        let (p, q) = (a + t_lo * b, a + t_hi * b);
        let (v_lo, v_hi) = (p.min(q), p.max(q));
        let first = v_lo.ceil().max(0.0) as i64;
        let last = v_hi.floor().min(n - 1.0) as i64;
        for k in first..=last {
            let t = (k as f64 - a) / b;
            if t > t_lo && t < t_hi {
                ts.push(t);
            }
        }
    }
    // Split the pieces at the finer layers' edges, so that the coarser surface is sampled from
    // right beyond them (the per-site scan reaches it there through its piece midpoints and
    // tangent points).
    for &(a, b) in covered {
        for t in [a - EDGE_STEP_M, b + EDGE_STEP_M] {
            if t > t_lo && t < t_hi {
                ts.push(t);
            }
        }
    }
    ts.sort_by(f64::total_cmp);
    ts.dedup_by(|x, y| (*x - *y).abs() < 1e-9);
    let is_covered = |t: f64| covered.iter().any(|&(a, b)| t >= a && t <= b);
    let edge = |v: f64, n: f64| v.clamp(-0.5, n - 0.5);
    let sample = |t: f64| {
        if is_covered(t) {
            return None;
        }
        let (row, col) = (edge(row_0 + t * rb, rows), edge(col_0 + t * cb, cols));
        dem.height_at_row_col(row, col).map(|h| (t, h))
    };
    // Each piece end is sampled once (the next piece starts where this one ends).
    let mut here = ts.first().and_then(|&t| sample(t));
    for (i, &t) in ts.iter().enumerate() {
        if let Some(p) = here {
            out.push(p);
        }
        let Some(&next) = ts.get(i + 1) else { break };
        let there = sample(next);
        if let Some(mid) = sample(0.5 * (t + next)) {
            match (here, there) {
                (Some(a), Some(b)) => {
                    let (first, last) = observers.t_m;
                    let gap_m = (first - b.0).max(a.0 - last).max(0.0);
                    if gap_m < observers.near_m {
                        refine_piece(a, mid.1, b, SAG_TOLERANCE_M, |t, h| out.push((t, h)));
                        if !out.last().is_some_and(|s| s.0 > a.0) {
                            out.push(mid);
                        }
                    } else {
                        refine_piece(a, mid.1, b, sag_tolerance_m(gap_m), |t, h| out.push((t, h)));
                    }
                }
                _ => out.push(mid),
            }
        }
        here = there;
    }
}

/// Offset (map metres) of the first coarser-layer sample beyond a finer layer's edge.
pub(super) const EDGE_STEP_M: f64 = 1e-3;

/// Largest height (m) by which the terrain inside a piece may rise above the straight 3-D chord
/// between the piece's samples near an observer: inside one bilinear patch the height along a
/// straight line is the quadratic `h(u) = h_a + p u + q u²` through the piece's ends and
/// midpoint, and on the sphere a piece of length `Δ` rises `Δ² / 8R` more at its middle (the
/// bulge of the ground over its chord); `n` equal sub-pieces each rise `1 / n²` of that.
pub(super) const SAG_TOLERANCE_M: f64 = 0.02;

/// Angular bound (radians) of what [`refine_piece`] may leave out of a sample far from every
/// observer on its line: the tolerance grows with the distance to the nearest observer, so that
/// no observer's horizon can drop by more than this (5.7e-4°), on top of [`SAG_TOLERANCE_M`].
pub(super) const SAG_TOLERANCE_RAD: f64 = 1e-5;

/// The sag tolerance (m) of a piece `gap_m` map metres from the nearest observer on its line:
/// ground distances are shorter than map distances by at most the scale factor (≤ 1.02 on a
/// ±457 km map), covered by the factor 0.95.
pub(super) fn sag_tolerance_m(gap_m: f64) -> f64 {
    SAG_TOLERANCE_M.max(0.95 * SAG_TOLERANCE_RAD * gap_m)
}

/// Emits the interior samples of the piece from `a` to `b` (`(t, h)`, t in map metres) with
/// midpoint height `h_mid`: as many equal steps of the exact quadratic as keep the rise of each
/// sub-piece over its chord (height and bulge, see [`SAG_TOLERANCE_M`]) under `tolerance_m`.
/// None when the whole piece stays within it: a sample that rises less than `tolerance_m` above
/// the chord of its neighbours changes no horizon by more than `tolerance_m` over its distance,
/// as the elevation along a straight chord peaks at an end. The per-site scan samples the
/// tangent point instead, which depends on the observer.
pub(super) fn refine_piece(
    a: (f64, f64),
    h_mid: f64,
    b: (f64, f64),
    tolerance_m: f64,
    mut emit: impl FnMut(f64, f64),
) {
    let q = 2.0 * (a.1 - 2.0 * h_mid + b.1);
    let dt = b.0 - a.0;
    // Rise of the middle over the 3-D chord (map metres overstate the ground's: conservative).
    let rise = dt * dt / (8.0 * MOON_RADIUS_M) - 0.25 * q;
    if rise <= tolerance_m {
        return;
    }
    let n = ((rise / tolerance_m).sqrt().ceil() as usize).clamp(2, 512);
    if n == 2 {
        emit(0.5 * (a.0 + b.0), h_mid);
        return;
    }
    let p = b.1 - a.1 - q;
    for k in 1..n {
        let u = k as f64 / n as f64;
        emit(a.0 + u * (b.0 - a.0), a.1 + p * u + q * u * u);
    }
}

/// The canonical line direction of a step and whether the step is its forward sense.
pub(super) fn canonical_of(dcol: i32, dnorth: i32) -> ((i32, i32), bool) {
    if dcol > 0 || (dcol == 0 && dnorth > 0) {
        ((dcol, dnorth), true)
    } else {
        ((-dcol, -dnorth), false)
    }
}

/// The range of `m` with `0 <= a + m b <= n − 1`; `None` when empty (b = 0 and a outside).
pub(super) fn m_range(a: i64, b: i64, n: i64) -> Option<(i64, i64)> {
    if b == 0 {
        return (0..n).contains(&a).then_some((i64::MIN / 4, i64::MAX / 4));
    }
    let (p, q) = (div_ceil_i(-a, b), div_floor_i(n - 1 - a, b));
    Some(if b > 0 {
        (p, q)
    } else {
        (div_ceil_i(n - 1 - a, b), div_floor_i(-a, b))
    })
}

fn div_floor_i(a: i64, b: i64) -> i64 {
    let d = a / b;
    if (a % b != 0) && ((a < 0) != (b < 0)) {
        d - 1
    } else {
        d
    }
}

fn div_ceil_i(a: i64, b: i64) -> i64 {
    let d = a / b;
    if (a % b != 0) && ((a < 0) == (b < 0)) {
        d + 1
    } else {
        d
    }
}

/// `(g, x, y)` with `a x + b y = g = gcd(a, b)` (up to sign).
pub(super) fn ext_gcd(a: i64, b: i64) -> (i64, i64, i64) {
    if b == 0 {
        (a, 1, 0)
    } else {
        let (g, x, y) = ext_gcd(b, a % b);
        (g, y, x - (a / b) * y)
    }
}

pub(super) fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// Grid azimuth of step `(dcol, dnorth)` on cells `px_x_m` × `px_y_m`, degrees in [0, 360).
pub(super) fn grid_az_deg(dcol: i32, dnorth: i32, px_x_m: f64, px_y_m: f64) -> f64 {
    (f64::from(dcol) * px_x_m)
        .atan2(f64::from(dnorth) * px_y_m)
        .to_degrees()
        .rem_euclid(360.0)
}

/// Smallest |a − b| on the circle, degrees.
pub(super) fn ang_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}
