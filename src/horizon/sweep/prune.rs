//! Dropping the samples of a line that no look can have on its hull, once per line before the
//! looks (both senses) walk it.
//!
//! A look of observer `o` reads its horizon from the upper convex hull (about the Moon's centre,
//! in the unrolled plane) of `P(o)`, the run of samples from half a pixel beyond `o` to the line's
//! far end. Remove, one at a time from the current sequence, a sample `b` strictly below the
//! chord of its current neighbours `a` (nearer to `o`) and `c`, unless it is *protected*: the
//! nearest sample of some `P(o)`, the observers' own samples, and for looks that decide that
//! boundary in f32 (the GPU kernel, [`Boundary::F32`]) the samples on either side of it. Whenever
//! `P(o)` holds `b` it holds `c` (farther) and `a` (its nearest sample is protected, so it is `a`
//! or nearer); a point below the chord of two others of a set is no vertex of the set's hull, so
//! by induction every `P(o)` keeps its hull and every horizon stays bit-identical. The CPU looks
//! decide their boundaries in f64 exactly as this pass does ([`Boundary::F64`]). Measured
//! fractions kept: `docs/horizon.md`, "Whole-grid horizons: the line sweep".

use super::{LineObserver, LineSample};

/// How the looks that will walk the pruned line decide the boundary of their sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Boundary {
    /// In f64, as this pruning does (the CPU looks): the nearest sample of each set is protected
    /// alone.
    F64,
    /// In f32 (the GPU kernel and its twin), which may put it one sample off: the samples on
    /// either side of it are protected too (≈ 12–14 % more samples kept: module docs).
    F32,
}

/// Removes, in place, the samples the module docs allow to remove, and re-indexes `observers`: a
/// stack that pops its unprotected top while it lies below the chord from the entry under it to
/// the next sample (each pop is a removal against the current neighbours, as the module docs
/// allow), leaving the upper hull of the samples between two protected ones (the first and the
/// last sample are never popped). `samples` are in increasing `ψ`; `keep` is scratch.
pub(super) fn drop_hidden_samples(
    samples: &mut Vec<LineSample>,
    observers: &mut [LineObserver],
    theta_min_rad: f64,
    boundary: Boundary,
    keep: &mut Vec<bool>,
) {
    let n = samples.len();
    if n < 3 {
        return;
    }
    keep.clear();
    keep.resize(n, false);
    // The nearest sample of each look's set, forward the first with ψ ≥ ψo + θ and backward the
    // last with ψ ≤ ψo − θ, and for `Boundary::F32` the samples on either side of it: a look
    // that decides the boundary in f32 (the GPU kernel) may start its set one sample earlier or
    // later, and the removal stays exact for those sets too (observers in increasing ψ, so both
    // pointers only move forward).
    let mut protect = |i: usize| match boundary {
        Boundary::F64 => keep[i] = true,
        Boundary::F32 => keep[i.saturating_sub(1)..(i + 2).min(n)].fill(true),
    };
    let (mut fwd, mut bwd) = (0, 0);
    for o in observers.iter() {
        let psi_o = samples[o.sample].psi_rad;
        fwd = fwd.max(o.sample);
        while fwd < n && samples[fwd].psi_rad < psi_o + theta_min_rad {
            fwd += 1;
        }
        protect(fwd.min(n - 1));
        while bwd + 1 < n && samples[bwd + 1].psi_rad <= psi_o - theta_min_rad {
            bwd += 1;
        }
        protect(bwd);
    }
    for o in observers.iter() {
        keep[o.sample] = true;
    }
    // A stack in place (`w ≤ i`), its top two entries cached: (x, y, kept).
    let mut w = 0;
    let mut next_obs = 0;
    let mut top = (0.0, 0.0, true);
    let mut second = top;
    for i in 0..n {
        let b = samples[i];
        let k = keep[i];
        while w >= 2 && !top.2 && below_chord((second.0, second.1), (top.0, top.1), (b.x_m, b.y_m))
        {
            w -= 1;
            top = second;
            if w >= 2 {
                second = (samples[w - 2].x_m, samples[w - 2].y_m, keep[w - 2]);
            }
        }
        if next_obs < observers.len() && observers[next_obs].sample == i {
            observers[next_obs].sample = w;
            next_obs += 1;
        }
        samples[w] = b;
        keep[w] = k;
        w += 1;
        second = top;
        top = (b.x_m, b.y_m, k);
    }
    samples.truncate(w);
}

/// Is `b` strictly below the chord from `lo` to `hi` (plane coordinates, `ψ` increasing)? The
/// orientation test of the forward look (`HorizonSweep::look` pops on `cross ≥ 0`).
#[inline]
fn below_chord(lo: (f64, f64), b: (f64, f64), hi: (f64, f64)) -> bool {
    (b.0 - lo.0) * (hi.1 - b.1) - (b.1 - lo.1) * (hi.0 - b.0) > 0.0
}
