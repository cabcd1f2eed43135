use super::lookup::atan2_deg;
use super::*;
use crate::terrain::TerrainStack;

/// A small deterministic generator (xorshift) for test inputs.
pub(super) fn rng(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[test]
fn atan2_deg_matches_f64() {
    let mut r = rng(7);
    let mut worst = 0.0_f64;
    for _ in 0..200_000 {
        let (y, x) = (2.0 * r() - 1.0, 2.0 * r() - 1.0);
        let scale = 10f64.powf(8.0 * r() - 2.0);
        let (y, x) = (y * scale, x * scale);
        let got = f64::from(atan2_deg(y as f32, x as f32));
        let want = (y as f32 as f64).atan2(x as f32 as f64).to_degrees();
        let mut d = (got - want).abs();
        if d > 180.0 {
            d = 360.0 - d;
        }
        worst = worst.max(d);
    }
    // The polynomial is good to 2.2e-6°; f32 rounding of the result near ±180° (one ulp of π is
    // 1.4e-5°) dominates.
    assert!(worst < 5e-5, "worst atan2 error {worst:e} deg");
    assert_eq!(atan2_deg(0.0, 0.0), 0.0);
    assert!((atan2_deg(1.0, 0.0) - 90.0).abs() < 1e-5);
    assert!((atan2_deg(0.0, -1.0) - 180.0).abs() < 1e-5);
    assert!((atan2_deg(-1.0, 0.0) + 90.0).abs() < 1e-5);
}

#[test]
fn azimuth_lookup_interpolates_between_non_uniform_bands() {
    let mut r = rng(11);
    // Non-uniform azimuths (gaps 0.2 … 2.2 deg), starting off zero.
    let mut az = Vec::new();
    let mut a = 0.7;
    while a < 359.0 {
        az.push(a);
        a += 0.2 + 2.0 * r();
    }
    let n = az.len();
    let h: Vec<f32> = (0..n).map(|_| (10.0 * r() - 3.0) as f32).collect();
    let mut hh = h.clone();
    hh.push(h[0]);
    let lookup = AzimuthLookup::new(&az).expect("valid azimuths");
    assert_eq!(lookup.n_bands(), n);
    // Brute force: find the segment (with wrap) and interpolate in f64.
    let want = |q: f64| -> f64 {
        let q = q.rem_euclid(360.0);
        for k in 0..n {
            let (a0, a1) = (az[k], if k + 1 < n { az[k + 1] } else { az[0] + 360.0 });
            for qq in [q, q + 360.0] {
                if qq >= a0 && qq < a1 {
                    let w = (qq - a0) / (a1 - a0);
                    return f64::from(h[k]) * (1.0 - w) + f64::from(h[(k + 1) % n]) * w;
                }
            }
        }
        unreachable!("every azimuth is in a segment")
    };
    let mut worst = 0.0_f64;
    for _ in 0..100_000 {
        let q = 1000.0 * r() - 500.0;
        let got = f64::from(lookup.horizon_deg(&hh, q as f32));
        worst = worst.max((got - want(f64::from(q as f32))).abs());
    }
    // f32 azimuths (an ulp of 360° is 3e-5°) times horizon slopes of up to 50 deg/deg here.
    assert!(worst < 3e-3, "worst lookup error {worst:e} deg");
    // At the bands themselves, the band values.
    for (k, &a) in az.iter().enumerate() {
        let got = lookup.horizon_deg(&hh, a as f32);
        assert!((got - h[k]).abs() < 1e-3, "band {k}: {got} vs {}", h[k]);
    }
    assert!(AzimuthLookup::new(&[10.0, 5.0]).is_none());
    assert!(AzimuthLookup::new(&[10.0, 360.0]).is_none());
    assert!(AzimuthLookup::new(&[10.0]).is_none());
}

#[test]
fn chord_table_matches_the_strip_integral() {
    for limb in [LimbDarkening::UNIFORM, LimbDarkening::EDDINGTON] {
        let table = ChordTable::new(&limb);
        let mut worst = 0.0_f64;
        for i in 0..=20_000 {
            let x = -1.1 + 2.2 * f64::from(i) / 20_000.0;
            let want = crate::illum::chord_visible_fraction(x, &limb);
            let got = f64::from(table.fraction(x as f32));
            let want_at_f32 = crate::illum::chord_visible_fraction(f64::from(x as f32), &limb);
            worst = worst.max((got - want_at_f32).abs().min((got - want).abs()));
        }
        assert!(worst < 1e-5, "{limb:?}: worst table error {worst:e}");
        assert_eq!(table.fraction(1.0), 0.0);
        assert_eq!(table.fraction(-1.0), 1.0);
    }
}

/// A rough synthetic DEM (72² px of 150 m round the pole), its sweep (180 azimuths) and the
/// bodies every 5 h of 2027.
fn rough_terrain_year() -> (TerrainStack, InMemoryHorizons, Vec<EpochBodies>) {
    super::testing::rough_terrain_2027(72, 5, 5.0, &crate::ephem::kernels::default_kernel_dir())
}

/// The statistics parameters of the rough-terrain checks.
fn rough_terrain_params() -> StatisticsParams {
    StatisticsParams {
        limb: LimbDarkening::EDDINGTON,
        visible_min_fraction: 1e-6,
        full_min_fraction: 0.999,
    }
}

/// Every statistic of `a` equals that of `b`, bit for bit (each field named on failure).
fn assert_statistics_equal(a: &HorizonStatistics, b: &HorizonStatistics) {
    macro_rules! same {
        ($($field:ident),*) => {$(
            assert_eq!(a.$field, b.$field, stringify!($field));
        )*};
    }
    same!(
        epochs,
        nodata,
        sun_visible_count,
        sun_full_count,
        earth_visible_count,
        sun_and_earth_count,
        longest_dark_epochs,
        longest_earth_hidden_epochs
    );
    // Bit for bit: compared as bits, so that a NaN in both also counts as equal.
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    macro_rules! same_bits {
        ($($field:ident),*) => {$(
            assert_eq!(bits(&a.$field), bits(&b.$field), stringify!($field));
        )*};
    }
    same_bits!(
        sun_fraction_sum,
        irradiance_horizontal_sum_w_m2,
        irradiance_tracking_sum_w_m2
    );
    assert_eq!(a.below_sphere, b.below_sphere, "below_sphere");
}

/// Cells that never (or always) see a body skip it: the bounds must never change a result. On a
/// rough synthetic DEM (crater floors that never see the Sun, slopes that never see the Earth),
/// every statistic with the skip equals the one without, bit for bit.
#[test]
fn skipping_unseen_bodies_changes_nothing() {
    let (stack, mut horizons, bodies) = rough_terrain_year();
    let mut engine = StatisticsEngine::new(&stack, rough_terrain_params()).unwrap();
    let with = engine.run(&mut horizons, &bodies, |_| true).unwrap();
    stored_blocks_are_taken_back(&engine, &mut horizons, &bodies, &with);
    engine.skip_unseen = false;
    let without = engine.run(&mut horizons, &bodies, |_| true).unwrap();
    let never_sun = with
        .sun_visible_count
        .iter()
        .zip(&with.nodata)
        .filter(|(c, nd)| **c == 0 && !**nd)
        .count();
    let never_earth = with
        .earth_visible_count
        .iter()
        .zip(&with.nodata)
        .filter(|(c, nd)| **c == 0 && !**nd)
        .count();
    println!("{never_sun} cells never see the Sun, {never_earth} never see the Earth");
    assert!(
        never_sun > 50 && never_earth > 50,
        "the test needs cells that skip"
    );
    assert_statistics_equal(&with, &without);
}

/// The Earth's partial discs: the kernel's fraction over the band polyline (segment where it is
/// exact enough, the closed-form strip integral near 0 and 1) against the series' exact method
/// on the same horizon sampled uniformly.
#[test]
fn polyline_fraction_matches_the_exact_strip_integral() {
    use crate::illum::{Disc, DiscMethod, HorizonProfile, visible_fraction};
    let mut r = rng(23);
    let n = 720;
    let az: Vec<f64> = (0..n).map(|k| k as f64 * 360.0 / n as f64).collect();
    let h64: Vec<f64> = (0..n)
        .map(|k| {
            1.5 * (k as f64 * std::f64::consts::TAU * 5.0 / n as f64).sin() + 0.1 * (r() - 0.5)
        })
        .collect();
    let mut h: Vec<f32> = h64.iter().map(|&v| v as f32).collect();
    h.push(h[0]);
    let lookup = AzimuthLookup::new(&az).unwrap();
    let chord = ChordTable::new(&LimbDarkening::UNIFORM);
    let profile = HorizonProfile::new(&h64).unwrap();
    let (mut worst_edge, mut worst_mid, mut cases, mut whole_off) = (0.0_f64, 0.0_f64, 0_u32, 0);
    let mut sum = 0.0;
    for _ in 0..20_000 {
        let disc = Disc {
            az_deg: 360.0 * r(),
            el_deg: 4.0 * r() - 2.0,
            radius_deg: 0.9 + 0.1 * r(),
        };
        let want = visible_fraction(&profile, &disc, DiscMethod::Exact, &LimbDarkening::UNIFORM);
        let half_span = (disc.radius_deg / disc.el_deg.to_radians().cos()) as f32;
        let got = f64::from(super::kernel::polyline_fraction(
            &h,
            &lookup,
            disc.el_deg as f32,
            disc.az_deg as f32,
            disc.radius_deg as f32,
            half_span,
            &chord,
        ));
        let d = (got - want).abs();
        sum += d;
        // A disc wholly hidden is told exactly; otherwise the decisions at the thresholds (any
        // part, 1e-6; all of it, 0.999) can differ only where the segment puts in mid-range a
        // disc that is nearly hidden or nearly whole.
        if want == 0.0 {
            assert_eq!(got, 0.0, "hidden disc {disc:?} got {got}");
        }
        whole_off += usize::from((got >= 0.999) != (want >= 0.999));
        whole_off += usize::from((got > 1e-6) != (want > 1e-6));
        if !(0.02..=0.98).contains(&want) {
            worst_edge = worst_edge.max(d);
        } else {
            worst_mid = worst_mid.max(d);
        }
        cases += 1;
    }
    let mean = sum / f64::from(cases);
    println!(
        "{cases} discs on a rough horizon (±0.05° per band): mean |Δ| {mean:.1e}, max near 0 / 1 \
         {worst_edge:.2e}, in between {worst_mid:.2e}; threshold decisions differing {whole_off}"
    );
    assert!(whole_off * 1000 <= cases as usize, "{whole_off}");
    assert!(mean < 5e-3, "{mean}");
}

/// A disc across grid azimuth 0 sees the bands on both sides of it: the same horizon turned by
/// 180° gives the same fraction for the same disc turned by 180°, and both match the exact strip
/// integral. (Before, a disc whose left edge was below 0° skipped the bands inside it and took
/// the straight chord between its edges: up to 26 epochs a year of the Earth's visibility at
/// LOLA pixels, where the Earth stands near grid azimuth 0.)
#[test]
fn polyline_fraction_is_the_same_across_grid_azimuth_zero() {
    use crate::illum::{Disc, DiscMethod, HorizonProfile, visible_fraction};
    let n = 720;
    let az: Vec<f64> = (0..n).map(|k| k as f64 * 360.0 / n as f64).collect();
    // A notch 0.6° wide and 1.5° deep centred on grid azimuth 0 in a flat 1° horizon.
    let notch = |a: f64| {
        let d = (a + 180.0).rem_euclid(360.0) - 180.0;
        if d.abs() <= 0.3 { -0.5 } else { 1.0 }
    };
    let h0: Vec<f64> = az.iter().map(|&a| notch(a)).collect();
    let h180: Vec<f64> = az.iter().map(|&a| notch(a - 180.0)).collect();
    let f32s = |h: &[f64]| {
        let mut v: Vec<f32> = h.iter().map(|&x| x as f32).collect();
        v.push(v[0]);
        v
    };
    let (h0_32, h180_32) = (f32s(&h0), f32s(&h180));
    let lookup = AzimuthLookup::new(&az).unwrap();
    let chord = ChordTable::new(&LimbDarkening::UNIFORM);
    let profile = HorizonProfile::new(&h0).unwrap();
    let mut seen_through_notch = 0;
    for i in 0..=40 {
        // The disc's top (0.75°) is below the flat horizon: only the notch shows it.
        let disc = Disc {
            az_deg: -0.8 + 1.6 * f64::from(i) / 40.0,
            el_deg: -0.2,
            radius_deg: 0.95,
        };
        let half_span = (disc.radius_deg / disc.el_deg.to_radians().cos()) as f32;
        let at = |h: &[f32], a: f64| {
            super::kernel::polyline_fraction(
                h,
                &lookup,
                disc.el_deg as f32,
                a.rem_euclid(360.0) as f32,
                disc.radius_deg as f32,
                half_span,
                &chord,
            )
        };
        let (across, turned) = (at(&h0_32, disc.az_deg), at(&h180_32, disc.az_deg + 180.0));
        let want = visible_fraction(&profile, &disc, DiscMethod::Exact, &LimbDarkening::UNIFORM);
        assert!(
            (across - turned).abs() < 1e-4,
            "disc at {:.2}°: {across} across 0°, {turned} turned by 180°",
            disc.az_deg
        );
        // Only the decision matters for the Earth (any part visible).
        assert_eq!(
            across > 1e-6,
            want > 1e-6,
            "disc at {:.2}°: {across} against the strip integral's {want}",
            disc.az_deg
        );
        seen_through_notch += usize::from(want > 1e-6);
    }
    assert!(seen_through_notch >= 30, "{seen_through_notch}");
}

/// The shared sector classification decides most epochs without any per-cell geometry: it must
/// never change a result. On a rough synthetic DEM, Sun and Earth every 5 h for a year, every
/// statistic with the tables equals the one without, bit for bit.
#[test]
fn sector_tables_change_nothing() {
    let (stack, mut horizons, bodies) = rough_terrain_year();
    let mut engine = StatisticsEngine::new(&stack, rough_terrain_params()).unwrap();
    let with = engine.run(&mut horizons, &bodies, |_| true).unwrap();
    engine.sector_tables = false;
    let without = engine.run(&mut horizons, &bodies, |_| true).unwrap();
    let sometimes = with
        .sun_visible_count
        .iter()
        .zip(&with.earth_visible_count)
        .filter(|(s, e)| **s > 0 && **e > 0 && (**s as usize) < bodies.len())
        .count();
    assert!(
        sometimes > 100,
        "the test needs cells where both bodies vary"
    );
    assert_statistics_equal(&with, &without);
}

/// Hourly (blocks of 32 h: the Sun covers ≈ 17 sectors per block, so that its blocks can be
/// decided whole), bit for bit the epoch-by-epoch path.
#[test]
fn block_decisions_change_nothing() {
    let (stack, mut horizons, bodies) = super::testing::rough_terrain_2027(
        48,
        5,
        1.0,
        &crate::ephem::kernels::default_kernel_dir(),
    );
    let mut engine = StatisticsEngine::new(&stack, rough_terrain_params()).unwrap();
    let with = engine.run(&mut horizons, &bodies, |_| true).unwrap();
    engine.block_decisions = false;
    let without = engine.run(&mut horizons, &bodies, |_| true).unwrap();
    assert_statistics_equal(&with, &without);
}

/// A store that keeps every block.
#[derive(Default)]
struct Keep(std::collections::BTreeMap<(usize, usize), Vec<u8>>);

impl BlockStore for Keep {
    fn load(&mut self, rows: std::ops::Range<usize>) -> Option<Vec<u8>> {
        self.0.get(&(rows.start, rows.end)).cloned()
    }
    fn store(&mut self, rows: std::ops::Range<usize>, bytes: &[u8]) -> Result<(), String> {
        self.0.insert((rows.start, rows.end), bytes.to_vec());
        Ok(())
    }
}

/// Blocks given to a store are the run's bytes; a run given stored blocks takes them instead of
/// computing (a doctored block shows through), and computes what is missing.
fn stored_blocks_are_taken_back(
    engine: &StatisticsEngine<'_>,
    horizons: &mut dyn HorizonRows,
    bodies: &[EpochBodies],
    whole: &HorizonStatistics,
) {
    let mut keep = Keep::default();
    let first = engine
        .run_with_store(horizons, bodies, &mut keep, |_| true)
        .unwrap();
    assert!(keep.0.len() >= 2, "{} blocks", keep.0.len());
    assert_eq!(first.sun_fraction_sum, whole.sun_fraction_sum);
    // Doctor the first block's first pixel count; drop the last block.
    let (&(r0, r1), _) = keep.0.iter().next().unwrap();
    let last = *keep.0.keys().last().unwrap();
    keep.0.remove(&last);
    let cols = whole.nodata.len() / engine.fine().grid.rows;
    let mut doctored = HorizonStatistics::empty(whole.nodata.len(), whole.epochs);
    assert!(doctored.place_block_bytes(r0 * cols, (r1 - r0) * cols, &keep.0[&(r0, r1)]));
    doctored.sun_visible_count[0] = 123_456;
    keep.0.insert(
        (r0, r1),
        doctored.block_bytes(r0 * cols, (r1 - r0) * cols, (0, 0)),
    );
    let again = engine
        .run_with_store(horizons, bodies, &mut keep, |_| true)
        .unwrap();
    assert_eq!(again.sun_visible_count[0], 123_456);
    assert_eq!(again.sun_visible_count[1..], whole.sun_visible_count[1..]);
    assert_eq!(again.longest_dark_epochs, whole.longest_dark_epochs);
    assert_eq!(
        again.irradiance_tracking_sum_w_m2,
        whole.irradiance_tracking_sum_w_m2
    );
    assert!(
        keep.0.contains_key(&last),
        "the missing block was computed and stored"
    );
}

/// The below-sphere test's cut (rays above it leave the layers too far away to meet the sphere
/// beyond them) skips no ray that the exact test finds meeting it, and is tight: on a fine layer
/// inside a 256 km far field, observers 3 km below to 3 km above the sphere, every grid
/// azimuth, rays from the cut up to the geometric horizon (0° below the sphere) never meet the
/// sphere, and some rays within 0.3° below the cut do.
#[test]
fn below_sphere_cut_skips_no_ray_that_meets_the_sphere() {
    use crate::terrain::synth::{SynthParams, south_polar_dem};
    let layer = |size_px, px_m| {
        south_polar_dem(&SynthParams {
            size_px,
            px_m,
            seed: 3,
        })
        .unwrap()
    };
    let stack = TerrainStack::new(vec![layer(64, 150.0), layer(64, 4000.0)]);
    let engine = StatisticsEngine::new(&stack, rough_terrain_params()).unwrap();
    let fine = &stack.layers[0];
    let projector = UnitProjector::new(&fine.projection);
    let edges = Edges {
        extents: stack.layers.iter().map(|l| l.grid.bounds_m()).collect(),
        projector,
    };
    let (mut cut_active, mut tight) = (0, 0);
    for (row, col) in [(0, 0), (10, 50), (32, 32), (63, 5), (63, 63)] {
        let (x, y) = fine.grid.xy_from_row_col(row as f64, col as f64);
        let up = map_frame(&projector, x, y).up;
        for h_m in [-3000.0, -500.0, 100.0, 1000.0, 3000.0] {
            let r0_m = MOON_RADIUS_M + h_m;
            let beyond = engine.beyond_dem((x, y), up, r0_m, &projector);
            let horizon_deg = -(MOON_RADIUS_M / r0_m).min(1.0).acos().to_degrees();
            let cut_deg = f64::from(beyond.dip_deg);
            assert!(
                cut_deg <= horizon_deg + 1e-5,
                "{cut_deg} above {horizon_deg}"
            );
            if cut_deg < horizon_deg - 0.01 {
                cut_active += 1;
            }
            let mut below = false;
            for az in 0..360 {
                let az = az as f32;
                for k in 0..=20 {
                    // From the cut to the geometric horizon: never.
                    let el = cut_deg + (horizon_deg - cut_deg) * f64::from(k) / 20.0;
                    assert!(
                        !beyond.meets_sphere(&edges, az, el as f32),
                        "({row}, {col}) {h_m} m: az {az}, el {el} above the cut {cut_deg} meets"
                    );
                    // Just below it: sometimes.
                    let el = cut_deg - 0.3 * f64::from(k) / 20.0;
                    below |= beyond.meets_sphere(&edges, az, el as f32);
                }
            }
            tight += usize::from(below);
        }
    }
    assert!(
        cut_active >= 20,
        "{cut_active} observers with the cut below the horizon"
    );
    assert!(
        tight >= 20,
        "{tight} observers with rays meeting the sphere just below the cut"
    );
}
