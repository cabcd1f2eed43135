//! Engine-vs-engine accuracy metrics (the harness behind `docs/shadow.md`, "Accuracy").
//!
//! * Hard masks: the share of compared cells whose lit/shadow value differs, **excluding cells
//!   within one pixel of a shadow edge of the reference** (a cell is excluded when it or one of
//!   its 8 neighbours differs in the reference mask) and nodata cells.
//! * Visible fractions: mean, 99th percentile and maximum of `|Δ fraction|` over cells valid in
//!   both.

use super::{MASK_LIT, MASK_SHADOW};

/// Result of [`compare_masks`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MaskComparison {
    /// Cells compared (valid in both, away from reference edges).
    pub compared: usize,
    /// Compared cells whose values differ.
    pub disagree: usize,
    /// Cells excluded because they are within one pixel of a reference shadow edge.
    pub near_edge: usize,
    /// Shadowed share of the compared reference cells.
    pub shadow_share: f64,
}

impl MaskComparison {
    /// Disagreeing share of the compared cells, percent.
    pub fn disagree_percent(&self) -> f64 {
        100.0 * self.disagree as f64 / self.compared.max(1) as f64
    }
}

/// Compares `test` against `reference` (both `rows × cols`, values 0/1/255).
pub fn compare_masks(reference: &[u8], test: &[u8], rows: usize, cols: usize) -> MaskComparison {
    assert_eq!(reference.len(), rows * cols, "reference size");
    assert_eq!(test.len(), rows * cols, "test size");
    let valid = |v: u8| v == MASK_LIT || v == MASK_SHADOW;
    let mut out = MaskComparison {
        compared: 0,
        disagree: 0,
        near_edge: 0,
        shadow_share: 0.0,
    };
    let mut shadow = 0usize;
    for r in 0..rows {
        for c in 0..cols {
            let k = r * cols + c;
            let (a, b) = (reference[k], test[k]);
            if !valid(a) || !valid(b) {
                continue;
            }
            let mut edge = false;
            for dr in -1i64..=1 {
                for dc in -1i64..=1 {
                    let (rr, cc) = (r as i64 + dr, c as i64 + dc);
                    if rr < 0 || cc < 0 || rr >= rows as i64 || cc >= cols as i64 {
                        continue;
                    }
                    let n = reference[rr as usize * cols + cc as usize];
                    if valid(n) && n != a {
                        edge = true;
                    }
                }
            }
            if edge {
                out.near_edge += 1;
                continue;
            }
            out.compared += 1;
            if a == MASK_SHADOW {
                shadow += 1;
            }
            if a != b {
                out.disagree += 1;
            }
        }
    }
    out.shadow_share = shadow as f64 / out.compared.max(1) as f64;
    out
}

/// Result of [`compare_fractions`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FractionComparison {
    /// Cells compared (finite in both).
    pub compared: usize,
    /// Mean |Δ fraction|.
    pub mean_abs: f64,
    /// 99th percentile of |Δ fraction|.
    pub p99_abs: f64,
    /// Largest |Δ fraction|.
    pub max_abs: f64,
    /// Cells in the penumbra (either value strictly between 0 and 1).
    pub penumbra: usize,
    /// Mean |Δ fraction| over the penumbra cells only.
    pub mean_abs_penumbra: f64,
}

/// Compares two visible-fraction maps of equal size.
pub fn compare_fractions(reference: &[f32], test: &[f32]) -> FractionComparison {
    assert_eq!(reference.len(), test.len(), "map sizes differ");
    let (mut pen_n, mut pen_sum) = (0usize, 0.0f64);
    for (&a, &b) in reference.iter().zip(test) {
        let inner = |x: f32| x > 0.0 && x < 1.0;
        if a.is_finite() && b.is_finite() && (inner(a) || inner(b)) {
            pen_n += 1;
            pen_sum += (a as f64 - b as f64).abs();
        }
    }
    let mut d: Vec<f64> = reference
        .iter()
        .zip(test)
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .map(|(&a, &b)| (a as f64 - b as f64).abs())
        .collect();
    if d.is_empty() {
        return FractionComparison {
            compared: 0,
            mean_abs: 0.0,
            p99_abs: 0.0,
            max_abs: 0.0,
            penumbra: 0,
            mean_abs_penumbra: 0.0,
        };
    }
    d.sort_by(f64::total_cmp);
    let n = d.len();
    let p99 = d[((n as f64 * 0.99).ceil() as usize).clamp(1, n) - 1];
    FractionComparison {
        compared: n,
        mean_abs: d.iter().sum::<f64>() / n as f64,
        p99_abs: p99,
        max_abs: d[n - 1],
        penumbra: pen_n,
        mean_abs_penumbra: pen_sum / pen_n.max(1) as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_are_excluded_and_interior_disagreements_counted() {
        // 5x5: left two columns shadow, rest lit.
        let (rows, cols) = (5, 5);
        let reference: Vec<u8> = (0..25).map(|k| if k % 5 < 2 { 0 } else { 1 }).collect();
        let mut test = reference.clone();
        test[4] = 0; // interior lit cell (col 4) flipped: counted
        test[7] = 0; // col 2 is next to the edge: excluded
        let cmp = compare_masks(&reference, &test, rows, cols);
        // Columns 1 and 2 are edge-adjacent: 10 excluded, 15 compared.
        assert_eq!(cmp.near_edge, 10);
        assert_eq!(cmp.compared, 15);
        assert_eq!(cmp.disagree, 1);
    }

    #[test]
    fn fraction_stats() {
        let a = vec![0.0f32; 100];
        let b: Vec<f32> = (0..100).map(|k| if k == 0 { 1.0 } else { 0.01 }).collect();
        let c = compare_fractions(&a, &b);
        assert_eq!(c.compared, 100);
        assert!((c.mean_abs - (1.0 + 99.0 * 0.01) / 100.0).abs() < 1e-6);
        assert!((c.p99_abs - 0.01).abs() < 1e-6);
        assert!((c.max_abs - 1.0).abs() < 1e-9);
    }
}
